# Copyright 2026 The lookahead_control Authors
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""
The ``record`` executable: a rosbag2 MCAP recorder for machines without rosbag2.

Subscribes to the selected topics as they appear (serialized, type-agnostic), with a
QoS each publisher can match, and writes them with :class:`~lookahead_control.bags.
BagWriter`. It asks the described nodes for their parameters, stores them and the
scenario in the bag, counts what arrived against the publishers' sequence numbers and
finalizes the bag on SIGINT or SIGTERM. ``record --recover BAG`` salvages a bag whose
recorder was killed.
"""

from __future__ import annotations

from dataclasses import dataclass
import datetime
import functools
import importlib
from pathlib import Path
import re
import sys
from typing import Any, Callable, Optional, Sequence, Union

from lookahead_control.bags.rosbag_io import (BagError, BagWriter, FULL_NODE_NAME,
                                              NODE_NAME_RULE, PARAMETERS_KEY, qos_from_ints,
                                              RECORDER_KEY, recover, SCENARIO_KEY)
from lookahead_control.core.cli import ArgumentParser, number, run_tool, ToolError
from lookahead_control.core.config import ConfigError, source_config_dir
from lookahead_control.ros.node_main import (build_or_destroy, end_process, now_ns,
                                             program_arguments, rcl_reason, RCLError,
                                             run_node, tool_arguments)
from rcl_interfaces.srv import GetParameters, ListParameters
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import InvalidHandle
from rclpy.node import Node
from rclpy.parameter import parameter_value_to_python
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
import yaml

DEFAULT_DESCRIBE = ('/controller', '/sim_plant')
# topics whose publishers send only on an event (a parameter set, a log line, a lifecycle
# transition): silence there is normal and is not named in the summary
EVENT_TOPICS = ('/parameter_events', '/rosout')
EVENT_SUFFIXES = ('/transition_event',)


@dataclass
class TopicStats:
    """
    What arrived on one topic, and the publishers' sequence numbers seen.

    A writer numbers its messages from 1 and they arrive in order: a number that does
    not grow is a new writer (a publisher restarted), whose count starts again. The
    writers before the current one are summed in the ``earlier_*`` fields.
    """

    received: int = 0
    first_seq: Optional[int] = None     # of the current writer
    last_seq: Optional[int] = None
    publishers: int = 0
    writer_received: int = 0            # from the current writer
    earlier_published: int = 0
    earlier_dropped: int = 0
    earlier_before_first: int = 0

    def count(self, seq: Optional[int]) -> None:
        """
        Count one message received.

        :param seq: its publication sequence number (None if the middleware gives none).
        """
        self.received += 1
        if seq is None:
            return
        if self.first_seq is None or self.last_seq is None:
            self.first_seq = seq
        elif seq <= self.last_seq:
            # before: min/max over all, so a restarted publisher's 1..600 after 4..300
            # said 600 published of 887 received, and hid its drops
            self.earlier_published += self.last_seq
            self.earlier_dropped += self._writer_dropped()
            self.earlier_before_first += self.first_seq - 1
            self.first_seq, self.writer_received = seq, 0
        self.last_seq = seq
        self.writer_received += 1

    def _writer_dropped(self) -> int:
        """Return the current writer's messages lost after its first one received."""
        if self.first_seq is None or self.last_seq is None:
            return 0
        return max(0, self.last_seq - self.first_seq + 1 - self.writer_received)

    def dropped(self) -> Optional[int]:
        """Return the messages lost (None when the sequence cannot tell: many writers)."""
        if self.publishers != 1 or self.first_seq is None or self.last_seq is None:
            return None
        return self.earlier_dropped + self._writer_dropped()

    def before_first(self) -> Optional[int]:
        """
        Return the messages published before the first one received (of each writer).

        A writer numbers its messages from 1; a recorder that subscribed (or matched)
        after the publisher started misses the first ``first_seq - 1`` of them. None when
        the sequence cannot tell (many writers, nothing received).
        """
        if self.publishers != 1 or self.first_seq is None:
            return None
        return self.earlier_before_first + self.first_seq - 1

    def published(self) -> Optional[int]:
        """Return how many messages the writers numbered (None: the numbers cannot tell)."""
        if self.dropped() is None or self.last_seq is None:
            return None
        return self.earlier_published + self.last_seq


def message_class(msgtype: str) -> Any:
    """
    Return the Python class of ``pkg/msg/Type``.

    :param msgtype: the ROS type name.
    :return: the class.
    :raises ImportError: the package is not installed.
    """
    package, _, name = msgtype.split('/')
    return getattr(importlib.import_module(f'{package}.msg'), name)


def qos_as_ints(profile: QoSProfile) -> dict[str, int]:
    """
    Return an rclpy QoS profile as rmw enum numbers and nanoseconds.

    :param profile: the profile.
    :return: the numbers :func:`~lookahead_control.bags.qos_from_ints` takes.
    """
    return {'history': int(profile.history), 'depth': int(profile.depth),
            'reliability': int(profile.reliability), 'durability': int(profile.durability),
            'liveliness': int(profile.liveliness),
            'deadline_ns': profile.deadline.nanoseconds,
            'lifespan_ns': profile.lifespan.nanoseconds,
            'lease_ns': profile.liveliness_lease_duration.nanoseconds}


def matching_qos(offered: Sequence[QoSProfile]) -> QoSProfile:
    """
    Return a subscription QoS every offered profile matches, reliable where possible.

    :param offered: the publishers' profiles.
    :return: reliable unless a publisher is best effort; transient local only if all
        publishers are; deep history so bursts are not dropped.
    """
    reliable = all(p.reliability == ReliabilityPolicy.RELIABLE for p in offered)
    latched = bool(offered) and all(p.durability == DurabilityPolicy.TRANSIENT_LOCAL
                                    for p in offered)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                      reliability=ReliabilityPolicy.RELIABLE if reliable
                      else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched
                      else DurabilityPolicy.VOLATILE)


class RecorderNode(Node):
    """Records the selected topics into one bag."""

    def __init__(self, bag: Union[BagWriter, Callable[[], BagWriter]],
                 topics: Sequence[str] = (), regex: Optional[str] = None,
                 describe: Sequence[str] = DEFAULT_DESCRIBE, **kwargs: Any) -> None:
        """
        Start discovering topics.

        :param bag: the bag to write, or what opens it once the topic names are resolved
            (a name refused makes no bag).
        :param topics: topic names to record, relative ones in the node's namespace (with
            ``regex`` empty: all topics).
        :param regex: record topics whose full name matches it.
        :param describe: nodes whose parameters are stored in the bag.
        :param kwargs: passed to ``Node``.
        :raises ConfigError: a topic name ROS refuses, in the node's namespace.
        """
        super().__init__('recorder', **kwargs)
        build_or_destroy(lambda: self._build(bag, topics, regex, describe), super().destroy_node)

    def _build(self, bag: Union[BagWriter, Callable[[], BagWriter]], topics: Sequence[str],
               regex: Optional[str], describe: Sequence[str]) -> None:
        """Resolve the topic names and start discovering (``__init__``'s parameters)."""
        # relative names in the recorder's namespace, as ros2 bag record resolves them:
        # before, `record talk` never matched /talk and recorded nothing, silently.
        # Resolved by rcl in the namespace the node has: before, names were checked in
        # '/' (`{ns}/talk` under __ns:=/car_b was refused) and one too long in the real
        # namespace was a traceback after the bag was made
        self.topics: set[str] = set()
        for topic in topics:
            try:
                self.topics.add(self.resolve_topic_name(topic))
            except RCLError as err:
                reason = rcl_reason(err).removeprefix('failed to resolve name: ')
                raise ConfigError(f'topic {topic!r}: not a ROS topic name (letters, digits '
                                  "and _ between single '/'; a relative name is resolved in "
                                  f"the recorder's namespace): {reason}") from err
        self.bag = bag if isinstance(bag, BagWriter) else bag()
        self.regex = re.compile(regex) if regex else None
        self.stats: dict[str, TopicStats] = {}
        self._subs: dict[str, Any] = {}
        self.remapped: dict[str, str] = {}      # topic -> where a subscription to it goes
        self.unrecordable: dict[str, str] = {}  # topic -> its type, not importable here
        self.recorded_type: dict[str, str] = {}     # topic -> the type subscribed
        self.other_types: dict[str, list[str]] = {}  # topic -> types not subscribed
        self.parameters: dict[str, dict[str, Any]] = {}
        self._asked: set[str] = set()           # seen in the graph
        self._pending: set[str] = set()         # a request on its way
        self._param_clients: dict[str, tuple[Any, Any]] = {}
        self.to_describe = list(describe)
        self.create_timer(0.1, self.discover, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(f'recording to {self.bag.path}')

    def wanted(self, topic: str) -> bool:
        """Return True if ``topic`` is selected."""
        if self.regex is not None and self.regex.fullmatch(topic):
            return True
        if self.topics:
            return topic in self.topics
        return self.regex is None

    def discover(self) -> None:
        """Subscribe to new selected topics; ask new described nodes for parameters."""
        for topic, types in self.get_topic_names_and_types():
            if topic in self.stats:
                self._note_other_types(topic, types)
            if topic in self._subs or not self.wanted(topic):
                continue
            target = self.resolve_topic_name(topic)
            # before the publishers' QoS: get_publishers_info_by_topic remaps the name, so
            # a topic remapped to one without publishers was skipped without a word
            # (dev-probe65); count_publishers does not remap
            if target != topic:
                if self.count_publishers(topic) > 0:
                    # a remapping (--ros-args -r, a launch SetRemap) applies to the
                    # recorder's own subscriptions: before, one to /talk with -r
                    # /talk:=/car_b/talk received /car_b/talk's messages and wrote them
                    # as /talk
                    self.get_logger().warn(f'{topic}: not recorded: a remapping sends a '
                                           f'subscription to it to {target} (remap the '
                                           'nodes, not the recorder)')
                    self._subs[topic] = None
                    self.remapped[topic] = target
                continue
            infos = self.get_publishers_info_by_topic(topic)
            if not infos:
                continue
            try:
                cls = message_class(types[0])
                self.bag.add_topic(topic, types[0],
                                   [qos_from_ints(qos_as_ints(i.qos_profile)) for i in infos])
            except (ImportError, AttributeError, BagError) as err:
                if self.bag.error is not None:
                    return          # the bag failed: the node stops, main reports it
                self.get_logger().warn(f'{topic}: not recorded: {err}')
                self._subs[topic] = None
                # before: in the log only; the summary said nothing of a named topic
                # whose type is not installed here
                self.unrecordable[topic] = types[0]
                continue
            self.stats[topic] = TopicStats()
            self.recorded_type[topic] = types[0]
            self._note_other_types(topic, types)
            # two arguments: rclpy passes the message info (publication sequence number)
            callback: Any = functools.partial(self.on_message, topic)
            qos = matching_qos([i.qos_profile for i in infos])
            self._subs[topic] = self.create_subscription(cls, topic, callback, qos, raw=True)
            # as rosbag2 does: a run that records nothing on a topic then tells a topic
            # never subscribed (never in the graph) from one subscribed but never fed
            reliable = qos.reliability == ReliabilityPolicy.RELIABLE
            self.get_logger().info(
                f'subscribed to {topic} ({types[0]}, {len(infos)} publisher(s), '
                f'{"reliable" if reliable else "best effort"})')
        for topic, stats in self.stats.items():
            stats.publishers = max(stats.publishers, self.count_publishers(topic))
        self._describe_new_nodes()

    def _note_other_types(self, topic: str, types: Sequence[str]) -> None:
        """
        Warn of the types of ``topic`` besides the one recorded, each once.

        One subscription takes one type: the others' messages never arrive (before, such
        a topic was only 'nothing received' in the summary, dev-probe65).

        :param topic: a subscribed topic.
        :param types: its types in the graph now.
        """
        known = self.other_types.setdefault(topic, [])
        new = [t for t in types if t != self.recorded_type[topic] and t not in known]
        if new:
            known.extend(new)
            self.get_logger().warn(f'{topic}: published as {len(known) + 1} types: '
                                   f'recording {self.recorded_type[topic]} only, not '
                                   f'{", ".join(known)}')

    def on_message(self, topic: str, data: bytes, info: dict[str, Any]) -> None:
        """Write one serialized message with its receive time."""
        try:
            self.bag.write(topic, now_ns(self), data)
        except BagError:
            return              # the bag failed: the node stops, main reports it
        self.stats[topic].count(info.get('publication_sequence_number'))

    # -- run description ------------------------------------------------------------

    def _describe_new_nodes(self) -> None:
        """
        Ask each described node for its parameters once its services are matched.

        A request sent before the service is discovered can be lost (the node's name
        shows in the graph before its services do; under load by seconds): the clients
        are made once and asked only when ready, and a failed request is asked again at
        the next poll.
        """
        present = {(ns.rstrip('/') + '/' + name) for name, ns in
                   self.get_node_names_and_namespaces()}
        for target in self.to_describe:
            if target not in present or target in self.parameters or target in self._pending:
                continue
            self._asked.add(target)
            if target not in self._param_clients:
                self._param_clients[target] = (
                    self.create_client(ListParameters, f'{target}/list_parameters'),
                    self.create_client(GetParameters, f'{target}/get_parameters'))
            lister, getter = self._param_clients[target]
            if not (lister.service_is_ready() and getter.service_is_ready()):
                continue
            self._pending.add(target)
            future = lister.call_async(ListParameters.Request(depth=0))
            future.add_done_callback(lambda f, t=target: self._got_names(t, f))

    def _got_names(self, target: str, future: Future) -> None:
        response = future.result()
        if response is None:
            self._pending.discard(target)       # ask again at the next poll
            return
        names = list(response.result.names)
        request = GetParameters.Request(names=names)
        self._param_clients[target][1].call_async(request).add_done_callback(
            lambda f: self._got_values(target, names, f))

    def _got_values(self, target: str, names: list[str], future: Future) -> None:
        response = future.result()
        self._pending.discard(target)
        if response is None:
            return                              # ask again at the next poll
        values = [parameter_value_to_python(v) for v in response.values]
        self.parameters[target] = dict(sorted(zip(names, values)))
        text = yaml.safe_dump({node: {'ros__parameters': params}
                               for node, params in self.parameters.items()})
        scenario = self.parameters[target].get('scenario_file')
        try:
            self.bag.describe(PARAMETERS_KEY, text)
            if scenario is not None:
                path = Path(scenario) if scenario else (
                    source_config_dir() / 'scenarios' / 'paper_r400.yaml')
                try:
                    scenario_text = path.read_text()
                except OSError as err:
                    self.get_logger().warn(f'scenario {path} not stored: {err}')
                else:
                    # per node (a bag of several simulators, each its scenario) and the
                    # last one read (what bags before the per-node key hold)
                    self.bag.describe(SCENARIO_KEY + target, scenario_text)
                    self.bag.describe(SCENARIO_KEY, scenario_text)
        except BagError:
            return              # the bag failed: the node stops, main reports it
        self.get_logger().info(f'stored the parameters of {target}')

    # -- end ------------------------------------------------------------------------

    def report(self) -> dict[str, dict[str, Optional[int]]]:
        """
        Return what arrived per topic, against what its publisher numbered.

        ``dropped``: gaps after the first message received; ``before_first``: messages
        published before it (the recorder subscribed late); ``published``: the last
        sequence number, all of them. None where the sequence cannot tell.
        """
        out: dict[str, dict[str, Optional[int]]] = {}
        for topic, stats in sorted(self.stats.items()):
            dropped = stats.dropped()
            out[topic] = {'received': stats.received, 'dropped': dropped,
                          'before_first': stats.before_first(),
                          'published': stats.published()}
        return out

    def drain(self) -> int:
        """
        Write the messages received by the middleware but not yet taken.

        On a loaded machine the recorder's callbacks run behind its subscriptions: when
        it is stopped, the end of the run (the last steps' ground truth, or all of it)
        is still queued in its readers, and finalizing the bag without taking it loses it.

        At most a reader's depth per topic: what was queued when it stopped. Publishers
        that go on (another run on the same domain) refill the reader as fast as it is
        taken: an orphaned recorder, left by a SIGKILLed closed_loop, drained for an hour
        at 60 % CPU instead of finalizing.

        :return: how many messages were written.
        """
        written = 0
        for topic, sub in list(self._subs.items()):
            if sub is None:
                continue
            for _ in range(int(sub.qos_profile.depth) or 1000):
                try:
                    with sub.handle:
                        taken = sub.handle.take_message(sub.msg_type, sub.raw)
                except InvalidHandle:
                    taken = None
                if taken is None:
                    break
                data, info = taken
                self.on_message(topic, data, info)
                written += 1
        return written

    def destroy_node(self) -> None:
        """Finalize the bag (also on SIGINT / SIGTERM) and report."""
        if not self.bag.closed:
            if self.bag.error is None:
                self.drain()
            report = self.report()
            try:
                self.bag.describe(RECORDER_KEY, yaml.safe_dump(report))
                self.bag.close()
            except BagError:
                super().destroy_node()
                return          # main reports the failure
            total = sum(r['received'] or 0 for r in report.values())
            dropped = sum(r['dropped'] or 0 for r in report.values())
            late = ', '.join(f'{r["before_first"]} on {t}' for t, r in report.items()
                             if r['before_first'])
            missing = [n for n in self.to_describe if n in self._asked
                       and n not in self.parameters]
            # a node named with --describe (not a default one: a real vehicle has no
            # /sim_plant) that never showed: misspelt, or in another namespace
            unseen = [n for n in self.to_describe if n not in self._asked
                      and n not in DEFAULT_DESCRIBE]
            # a topic named on the command line that never had a publisher: misspelt, in
            # another namespace or domain, or its publisher never discovered
            absent = sorted(t for t in self.topics if t not in self._subs)
            # subscribed (a publisher was in the graph) and never delivered one message:
            # a publisher that sent nothing, or one the middleware never delivered
            # (Fast DDS 2.14's shared memory after a SIGKILL, dev-sc30): before, only the
            # total said it, a run lost without a word on which topic
            unfed = [f'{t} (up to {self.stats[t].publishers} publisher(s) at once)'
                     for t, r in report.items() if not r['received']
                     and t not in EVENT_TOPICS and not t.endswith(EVENT_SUFFIXES)]
            clashing = [f'{t} ({", ".join(u)})' for t, u in sorted(self.other_types.items())
                        if u]
            moved = [f'{t} -> {u}' for t, u in sorted(self.remapped.items())]
            untyped = [f'{t} ({u})' for t, u in sorted(self.unrecordable.items())]
            print(f'record: {self.bag.path}: {total} messages on {len(report)} topics, '
                  f'{dropped} dropped'
                  + (f'; subscribed late: missed the first {late}' if late else '')
                  + (f'; no parameters from {", ".join(missing)}' if missing else '')
                  + (f'; never saw {", ".join(unseen)} (--describe): no parameters'
                     if unseen else '')
                  + (f'; no publisher of {", ".join(absent)} ever seen: not recorded'
                     if absent else '')
                  + (f'; subscribed, nothing received on {", ".join(unfed)}'
                     if unfed else '')
                  + (f'; not recorded, another type on: {", ".join(clashing)}'
                     if clashing else '')
                  + (f'; not recorded, remapped: {", ".join(moved)}' if moved else '')
                  + (f'; not recorded, type not installed: {", ".join(untyped)}'
                     if untyped else ''),
                  file=sys.stderr)
        super().destroy_node()


def default_bag_name() -> str:
    """Return ``bags/run_<local date and time>``."""
    return 'bags/run_' + datetime.datetime.now().strftime('%Y%m%d_%H%M%S')


def main(argv: Optional[Sequence[str]] = None) -> int:
    """
    Record until SIGINT / SIGTERM, or recover a bag with ``--recover``.

    :param argv: command-line arguments (ROS arguments after ``--ros-args``).
    :return: exit code.
    """
    full = list(sys.argv if argv is None else argv)
    p = ArgumentParser(prog='record', description='record topics into a rosbag2 MCAP bag '
                       '(stop with Ctrl-C or SIGTERM: the bag is finalized)')
    p.add_argument('topics', nargs='*', help='topics to record (default: all)')
    p.add_argument('-o', '--output', type=Path, help='bag directory (default: '
                   'bags/run_<date>_<time>)')
    p.add_argument('-e', '--regex', help='also record topics matching this regex')
    p.add_argument('--describe', nargs='*', default=list(DEFAULT_DESCRIBE), metavar='NODE',
                   help='nodes whose parameters are stored in the bag (default: '
                   f'{" ".join(DEFAULT_DESCRIBE)}; none: --describe alone)')
    p.add_argument('--chunk-interval', type=number(0.0, 60.0, low_open=True, unit='s'),
                   default=None, metavar='S',
                   help='longest time a message waits in memory before it is written [s] '
                   '(default 0.5)')
    p.add_argument('--recover', type=Path, metavar='BAG',
                   help='rewrite a truncated bag into a readable one and exit')
    # before, a file holding only a string played, a directory or a malformed file gave
    # rcl's raw message, and record let rcl's parser read a pipe before the node
    with tool_arguments(full, 'record') as checked:
        return _main(p, checked)


def recover_bag(bag: Path, prog: str) -> int:
    """
    Recover a bag and say what was done.

    :param bag: the bag directory.
    :param prog: the tool that says it (``record --recover`` or ``recover``).
    :return: 0.
    """
    result = recover(bag)
    if result.complete or result.original is None:
        print(f'{prog}: {result.bag} is complete ({result.messages} messages on '
              f'{result.topics} topics): nothing to recover, left as it is')
        return 0
    print(f'{prog}: recovered {result.messages} messages on {result.topics} topics '
          f'into {result.bag} (original kept as {result.original.name})')
    return 0


def _main(p: ArgumentParser, full: list[str]) -> int:
    args = p.parse_args(program_arguments(full))
    if args.recover is not None:
        given = [name for name, used in (
            ('topics', args.topics), ('-o', args.output), ('-e', args.regex),
            ('--chunk-interval', args.chunk_interval is not None),
            ('--describe', args.describe != list(DEFAULT_DESCRIBE))) if used]
        if given:
            raise ToolError(f'{", ".join(given)}: not with --recover (it rewrites a bag '
                            'and exits)')
        return recover_bag(args.recover, 'record')
    if args.regex is not None:
        try:
            re.compile(args.regex)
        except re.error as err:
            raise ToolError(f'-e {args.regex!r}: not a regular expression: {err}') from err
    if args.describe and args.describe != list(DEFAULT_DESCRIBE):
        # before: only a leading / was checked; /car_b/controller/ (a typo) was never
        # matched by a node, and the bag silently lacked its parameters
        bad = [n for n in args.describe if not FULL_NODE_NAME.fullmatch(n)]
        if bad:
            raise ToolError(f'--describe {bad[0]!r}: {NODE_NAME_RULE}')
    made: list[BagWriter] = []

    def open_bag() -> BagWriter:
        # made by the node once it has resolved the topic names (a refused one: no bag)
        made.append(BagWriter(args.output or Path(default_bag_name()),
                              0.5 if args.chunk_interval is None else args.chunk_interval))
        return made[-1]

    try:
        code = run_node('record', full, lambda: RecorderNode(open_bag, args.topics,
                                                             args.regex, args.describe),
                        lambda node: node.bag.error is not None)
    finally:
        for bag in made:
            bag.close()     # once; after a write error the bag is already aborted
    for bag in made:
        if bag.error is not None:
            raise bag.error
    return code


def entry() -> int:
    """Entry point of ``record``."""
    return end_process(run_tool(main))


def recover_entry() -> int:
    """Entry point of ``recover``: ``recover BAG``."""
    def recover_main(argv: Optional[Sequence[str]] = None) -> int:
        p = ArgumentParser(prog='recover', description='rewrite a bag whose recorder was '
                           'killed into a readable one (a complete bag is left alone; the '
                           'original file is kept as <name>.mcap.truncated)')
        p.add_argument('bag', type=Path, help='the bag directory')
        args = p.parse_args(argv)
        # its own name in its lines (dev-probe93: they said 'record:')
        return recover_bag(args.bag, 'recover')
    return run_tool(recover_main)


if __name__ == '__main__':
    sys.exit(entry())
