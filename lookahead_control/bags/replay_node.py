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
The ``replay`` executable: play a bag over DDS, or re-run the controller offline.

``replay BAG`` republishes the bag's topics with their recorded timing (``--rate``,
``--topics``, ``--clock`` publishes ``/clock`` from the bag's time), like
``ros2 bag play --clock``, so a controller, changed or not, can be driven by recorded
data. ``replay BAG --offline`` feeds the recorded inputs straight into the controller
core with the bag's parameters (or ``-p name=value`` overrides) and reports recorded
vs re-computed steering; ``--check TOL`` exits 1 above the tolerance.
"""

from __future__ import annotations

import argparse
from pathlib import Path
import sys
import time
from typing import Any, Mapping, Optional, Sequence

from lookahead_control.bags.recorder_node import message_class
from lookahead_control.bags.rosbag_io import bag_reader, described_nodes
from lookahead_control.bags.run_data import (as_it_ran, CONTROLLER_NODE, load_run,
                                             NODE_PARAMS_BEFORE, ran_law, Rerun, rerun,
                                             RunData)
from lookahead_control.core import interrupts
from lookahead_control.core.cli import (ArgumentParser, assignments, number, output_file,
                                        run_tool, ToolError, write_json)
from lookahead_control.core.config import ConfigError, rcl_param_value
from lookahead_control.ros import conversions as conv
from lookahead_control.ros.node_main import (parameter_reason, program_arguments,
                                             rcl_log_held, tool_arguments)
import numpy as np
import rclpy
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock as ClockMsg

EXIT_CHECK_FAILED = 1


def per_input(counts: Mapping[str, int]) -> str:
    """
    Return counts per input as text.

    :param counts: input -> count.
    :return: e.g. ``'velocity 2, yaw 451'`` (by name).
    """
    return ', '.join(f'{name} {count}' for name, count in sorted(counts.items()))


def offline(args: argparse.Namespace) -> int:
    """
    Re-run the controller core on a bag's inputs and compare with its steering.

    :param args: the parsed command line.
    :return: 0, or 1 if ``--check`` failed.
    """
    # override values as rcl reads -p: numbers, booleans, strings
    overrides: dict[str, Any] = {}
    for name, text in assignments(args.param, '-p').items():
        try:
            overrides[name] = rcl_param_value(text)
        except ConfigError as err:
            raise ToolError(f'-p {name}={text}: {err}') from err
    node = CONTROLLER_NODE if args.node is None else args.node     # '' is refused
    run = load_run(args.bag, assignments(args.topic, '--topic'), node, diagnostics=None)
    result = rerun(run, overrides, args.order)
    report = {'bag': str(args.bag), 'node': run.controller_node, 'order': result.order,
              'compared': result.compared,
              'recorded': len(run.steering.by_stamp()), 'recomputed': len(result.commands),
              'max_diff_rad': result.max_diff, 'rms_diff_rad': result.rms_diff,
              'curvature_estimated': result.estimated,
              'curvature_dropped': result.dropped, 'overrides': overrides}
    report['curvature_judgment_followed'] = result.followed
    report['curvature_judged_otherwise_on_stamps'] = result.judged_otherwise
    report['law_switches_followed'] = result.law_switches
    report['parameter_sets_followed'] = result.parameter_sets
    report['parameter_sets_unmarked'] = result.parameter_sets_unmarked
    report['parameter_sets_before_bag'] = result.parameter_sets_before_bag
    report['inputs_while_inactive'] = result.inactive_skipped
    report['answers_lost_next_to_inactive'] = result.inactive_lost
    report['inputs_coalesced'] = result.coalesced_skipped
    report['answers_lost_next_to_coalesced'] = result.coalesced_lost
    report['inputs_not_received'] = result.unreceived_skipped
    report['inputs_refused'] = result.refused
    report['inputs_repeated'] = result.repeated
    report['commands_not_finite'] = result.not_finite
    report['checks_told'] = result.told
    report['runs_in_bag'] = result.runs
    report['inputs_off_their_run'] = result.strays
    report['inputs_off_to_the_end'] = list(result.strays_to_end)
    report['parameters_recorded'] = bool(run.controller_params)
    filled = as_it_ran(run.controller_params, overrides)
    report['parameters_as_it_ran'] = filled
    print(f'replay: {args.bag}: {result.compared} commands compared ({result.order} '
          f'order): max |diff| {result.max_diff:.3g} rad, RMS {result.rms_diff:.3g} rad')
    if result.runs > 1:
        # dev-probe111: two runs of a simulator in one bag were re-run interleaved in stamp
        # order, half the commands compared and the rest told as recorded twice
        print(f'replay: the bag holds {result.runs} runs (the input stamps start again '
              f'{result.runs - 1} time(s), as when a simulator is started again under one '
              'recorder): they are re-run one after the other, the core reset at each '
              'start, and a stamp that several runs have is compared in the last of them. '
              "The node judged a new run's first inputs against its clock before that "
              'clock went back (refused as old); the re-run has no clock and takes them, '
              'so the first answers after a start, and a stateful law after them, can '
              'differ')
    if result.strays:
        print(f'replay: {sum(result.strays.values())} input(s) came stamped more than 1 s '
              f'off their run, alone ({per_input(result.strays)}; sent late, or stamped '
              'ahead): the node refused them against its clock, and the re-run leaves them '
              'out')
        if result.strays_to_end:
            # dev-probe115: a yaw driver whose clock jumped 2 s back for good: 450
            # commands off with nothing saying why
            print(f'replay: {", ".join(result.strays_to_end)} stayed off to the end of the '
                  'bag (a sensor clock that jumped for good): the node took none of it from '
                  'there, went stale and held, then ramped its command; the re-run, without '
                  'a clock, does not model that: it steers on the last one taken and '
                  'differs from there')
    if result.not_finite:
        print(f'replay: {result.not_finite} of the {result.compared} compared commands are '
              'not finite (NaN or inf) in the bag or the re-run: max |diff| is nan')
    # the law needs every input: a bag without one has lateral errors and no answer
    # (before: "0 commands compared ... nan rad", exit 0, dev-probe93)
    missing = [role for role in ('yaw', 'velocity') if not len(run.inputs.get(role, ()))]
    if missing and not result.commands:
        print(f'replay: the re-run answered none of the {len(run.inputs["lateral_error"])} '
              f'lateral errors: the bag has no {" and no ".join(missing)} messages (the '
              "controller's inputs; --topic ROLE=NAME remaps)")
    joined, first_diff = late_join(run, result, bool(overrides))
    report['answers_before_bag'] = joined
    if joined:
        # dev-probe93: a recorder started 3 s into a run re-ran 3.86 mrad apart, unsaid
        print(f"replay: the bag's first answer of {run.controller_node} was its answer "
              f'{joined + 1}, and the re-run differs by up to {first_diff:.3g} rad over its '
              f'first {START_ANSWERS} answers: the controller ran before the bag began (a '
              'recorder started after it, a deactivation or a new configuration in '
              'between); the re-run starts the law and the output limits fresh, the '
              "recorded ones had run on (its integral, filter, estimates, the rate limit's "
              'last angle)')
    if not run.controller_params:
        # a recorder that joined late, or not asked (--describe): the re-run is the
        # default controller, which is not what ran
        print(f'replay: the bag has no {run.controller_node} parameters (recorded of: '
              f'{", ".join(described_nodes(Path(args.bag))) or "no node"}): the re-run '
              'uses the default vehicle, law and safety parameters, the law its debug '
              'names where it has one (-p NAME=VALUE sets one)')
    schedule = {k: v for k, v in filled.items() if k not in NODE_PARAMS_BEFORE}
    if schedule:
        # a bag from before the integral gain's speed schedule: the law ran with k_i
        # constant, which the schedule's defaults would not re-run
        print(f'replay: the bag predates {", ".join(schedule)} (the speed schedule of '
              'lane_keeping.integral_gain): the re-run keeps k_i constant as it ran ('
              f'{", ".join(f"{k}={v!r}" for k, v in schedule.items())}; -p NAME=VALUE sets '
              'another)')
    if 'align_inputs' in filled:
        # a controller from before dev-sc52 read the newest yaw and velocity samples
        print('replay: the bag predates align_inputs: the re-run reads the newest yaw and '
              "velocity samples as the node did (align_inputs='never'; -p "
              "align_inputs=with_prediction or always reads them at the lateral error's "
              'stamp)')
    if 'curvature_at_yaw_stamp' in filled:
        # a controller from before dev-sc53 read the curvature polygon as stamped
        print('replay: the bag predates curvature_at_yaw_stamp: the re-run reads the '
              'curvature polygon as stamped, as the node did (curvature_at_yaw_stamp=false; '
              '-p curvature_at_yaw_stamp=true reads one older than the yaw sample taken where '
              'the car was at its stamp)')
    if 'lane_keeping.hold_preview' in filled and \
            ran_law({**run.controller_params, **overrides}) == 'cg_compensated':
        # a controller from before dev-sc55 added no share of its answer period (the
        # other laws have none: nothing to say, dev-probe129)
        print('replay: the bag predates lane_keeping.hold_preview: the re-run adds no share '
              'of the answer period to the feedforward preview, as the law ran '
              '(lane_keeping.hold_preview=0; -p lane_keeping.hold_preview=0.5 adds half of '
              'it beyond 10 ms, the default since)')
    if 'lane_keeping.frequency_lag' in filled and \
            ran_law({**run.controller_params, **overrides}) == 'cg_compensated':
        # a controller from before dev-sc56 did not cut w_n at a slow answer period
        print('replay: the bag predates lane_keeping.frequency_lag: the re-run keeps w_n '
              'at every answer period, as the law ran (lane_keeping.frequency_lag=0; -p '
              'lane_keeping.frequency_lag=0.2 cuts it beyond 10 ms, the default since)')
    if result.estimated:
        dropped = (f'; in {result.dropped} of them it was received and dropped: the map '
                   'check found it far off the yaw rate, lane_keeping.map_fallback'
                   if result.dropped else '')
        print(f'replay: the law ran on its curvature estimate in {result.estimated} of '
              f'{len(result.commands)} answers (road_curvature not in the bag, or stamped '
              f'more than safety.input_timeout before the lateral error: lost{dropped})')
    if result.judged_otherwise:
        print("replay: the re-run took the recorded controller's own judgment of the "
              f'curvature (its {run.controller_node}/debug) in {result.followed} '
              f'answers; on the stamps alone {result.judged_otherwise} would have gone '
              "otherwise (one or two at a switch-over: the node's clock; many: a "
              'road_curvature in the bag that the controller did not receive, remapped or '
              'a QoS mismatch)')
    if result.refused:
        # a node older than a check used what the re-run refuses (dev-probe56: bags with
        # a zero quaternion or empty polygons re-ran 18.7 and 29.2 mrad apart, unsaid)
        print(f"replay: the re-run's input checks refused {sum(result.refused.values())} "
              f'input(s) ({per_input(result.refused)}; last: {result.last_refusal}), as the '
              'node does; a node older than a check (an orientation that is no unit '
              'quaternion, an empty road_curvature: since dev-sections) used them, and the '
              're-run differs there')
    if result.repeated:
        print(f'replay: {result.repeated} input(s) repeat the stamp of the one before them '
              '(the same message recorded twice: two recorders on one domain, or a '
              'publisher that sent it again); the node does not use a repeated stamp, and '
              'neither does the re-run')
    if result.told:
        # dev-sc49: a bag of a lateral error in cm re-ran without a word of what the
        # node's checks had told; the recorded /diagnostics: analyze's report
        seconds = [f'{name} {value:.2f} s' for name, value in result.told.items()
                   if name not in ('time_jumps', 'law_restarts')]
        events = [f'{name} {value:g}' for name, value in result.told.items()
                  if name in ('time_jumps', 'law_restarts')]
        print("replay: the re-run's checks found, as the node's /diagnostics names them: "
              + ', '.join(seconds + events) + ' (docs/safety.md; what the recorded '
              "controller told: analyze's report; the re-run has no clock and never goes "
              'stale: where inputs stopped for longer than lane_keeping.max_gap it counts a '
              'law restart the node, gone stale first, did not)')
    if result.law_switches:
        print(f'replay: the law was set at run time: the re-run switched it where the '
              f'recorded controller did ({result.law_switches} switches, '
              f'{run.controller_node}/debug law:<name>)')
    if result.parameter_sets:
        print(f'replay: {result.parameter_sets} parameter set(s) at run time (recorded '
              f'/parameter_events of {run.controller_node}) applied where the recorded '
              f'controller did ({run.controller_node}/debug parameter_sets)')
    if result.inactive_skipped:
        print(f'replay: {run.controller_node} was deactivated and activated again: '
              f'{result.inactive_skipped} lateral error(s) it received while inactive are '
              f'not re-run, as it did not answer them ({run.controller_node}/debug '
              'activations)')
    if result.inactive_lost:
        print(f'replay: the bag lost {result.inactive_lost} answer(s) of '
              f'{run.controller_node} next to a deactivation ({run.controller_node}/debug '
              'answers): those inputs were answered, which ones the bag does not say; '
              'the re-run skips them and is not exact there')
    if result.unreceived_skipped:
        print(f'replay: {result.unreceived_skipped} lateral error(s) of the bag '
              f'{run.controller_node} left unanswered between two answers it numbered one '
              'after the other (its reader fell behind and lost them, or it refused them) '
              f'are not re-run, as it did not answer them ({run.controller_node}/debug '
              'answers)')
    if result.coalesced_skipped or result.coalesced_lost:
        print(f'replay: {run.controller_node} answered lateral errors faster than its '
              f'max_answer_rate_hz only by the newest of each period: '
              f'{result.coalesced_skipped} it left unanswered are not re-run '
              f'({run.controller_node}/debug coalesced); a deferred answer read the yaw '
              'and velocity of its own moment, the re-run those received before the lateral '
              'error (not exact there)'
              + (f'; the bag lost {result.coalesced_lost} answer(s) there'
                 if result.coalesced_lost else ''))
    if result.parameter_sets_before_bag:
        # a recorder started after a set: its values are the bag's parameters
        print(f'replay: {run.controller_node} had applied '
              f'{result.parameter_sets_before_bag} parameter set(s) before the recorded '
              '/parameter_events begin (a recorder started after them): the re-run '
              "starts from the bag's parameters and numbers the recorded sets after them")
    if result.parameter_sets_unmarked:
        # a bag from before the marker: which answer a set preceded is not known
        print(f'replay: {result.parameter_sets_unmarked} parameter set(s) at run time are '
              f'on /parameter_events but {run.controller_node}/debug has no '
              'parameter_sets (an older bag): the re-run keeps the start-up values but '
              'the law (law:<name>)')
    if args.json:
        write_json(Path(args.json), report)         # NaN (nothing compared) as null
    if args.check is not None:
        if result.compared == 0:
            why = (f' (no {" and no ".join(missing)} in the bag)'
                   if missing and not result.commands else '')
            print(f'replay: check failed: no command to compare{why}', file=sys.stderr)
            return EXIT_CHECK_FAILED
        if result.not_finite:
            print(f'replay: check failed: {result.not_finite} compared command(s) not '
                  'finite', file=sys.stderr)
            return EXIT_CHECK_FAILED
        if not result.max_diff <= args.check:
            print(f'replay: check failed: max |diff| {result.max_diff:.3g} rad > '
                  f'{args.check:g} rad', file=sys.stderr)
            return EXIT_CHECK_FAILED
    return 0


#: the re-run's first answers in which a bag that begins after the controller's first
#: answer is looked at for the controller's earlier state (1 s at 100 Hz)
START_ANSWERS = 100


def late_join(run: RunData, rerun_result: Rerun, overridden: bool = False
              ) -> tuple[int, float]:
    """
    Return the recorded controller's answers before the bag's, if the re-run differs there.

    The debug's first ``answers`` count says how many answers came before the bag's
    first; they moved the controller's state only if the re-run differs over its first
    :data:`START_ANSWERS` compared commands (a debug subscription matched late, its
    inputs in the bag, re-runs equal there).

    :param run: the run.
    :param rerun_result: its re-run.
    :param overridden: the re-run has ``-p`` values: it differs by them (dev-probe95: a
        late debug subscription and ``-p vehicle.mass=2500`` were taken for a late start).
    :return: ``(answers before the bag's first, largest |difference| of those commands)``;
        ``(0, 0.0)`` when the bag starts with the first answer, has no debug count, the
        re-run is equal there, or ``overridden``.
    """
    if overridden:
        return 0, 0.0
    answers = run.debug.values.get('answers')
    known = np.zeros(0, dtype=bool) if answers is None else np.isfinite(answers)
    if not known.any():
        return 0, 0.0
    assert answers is not None
    first = int(np.argmin(np.where(known, run.debug.stamp_ns, np.iinfo(np.int64).max)))
    before = int(answers[first]) - 1
    recorded = run.steering.by_stamp()
    compared = sorted(stamp for stamp in rerun_result.commands if stamp in recorded)
    if before < 1 or not compared:
        return 0, 0.0
    difference = max(abs(recorded[stamp]['angle'] - rerun_result.commands[stamp].steering)
                     for stamp in compared[:START_ANSWERS])
    return (before, difference) if difference > 0.0 else (0, 0.0)


def qos_of(connection: Any) -> QoSProfile:
    """
    Return the QoS to replay a connection with (its first offered profile).

    :param connection: a rosbags connection.
    :return: the profile; reliable, volatile, depth 100 when nothing was recorded.
    """
    offered = getattr(connection.ext, 'offered_qos_profiles', None) or []
    if not offered:
        return QoSProfile(depth=100)
    first = offered[0]
    reliability = (ReliabilityPolicy.BEST_EFFORT if first.reliability.value == 2
                   else ReliabilityPolicy.RELIABLE)
    durability = (DurabilityPolicy.TRANSIENT_LOCAL if first.durability.value == 1
                  else DurabilityPolicy.VOLATILE)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=max(int(first.depth), 100),
                      reliability=reliability, durability=durability)


def play(args: argparse.Namespace, ros_args: list[str]) -> int:
    """
    Publish a bag's messages with their recorded timing.

    :param args: the parsed command line.
    :param ros_args: ROS arguments (remaps apply to the replayed topics).
    :return: 0.
    """
    if not args.rate > 0.0:
        raise ToolError(f'--rate {args.rate}: must be > 0')
    reader = bag_reader(args.bag)
    present = {c.topic for c in reader.connections}
    missing = sorted(set(args.topics) - present)
    if missing:
        reader.close()
        raise ToolError(f'--topics: {args.bag} has no {", ".join(missing)} (has: '
                        f'{", ".join(sorted(present))})')
    conns = [c for c in reader.connections
             if (not args.topics or c.topic in args.topics)
             and not (args.clock and c.topic == '/clock')]
    if not conns:
        reader.close()
        raise ToolError(f'{args.bag}: nothing to publish')
    node: Optional[Node] = None
    published = 0
    # every exit from here on shuts the context down: a Ctrl-C while the context or the
    # node was being created left it up, and the interpreter's exit waited on it (a suite
    # under load)
    try:
        with rcl_log_held():
            # rclpy's signal handling off: with it, Ctrl-C invalidated the context first
            # and the next publish ended in a traceback ("publisher's context is invalid",
            # exit 1; dev-probe61); now it is the KeyboardInterrupt below, as SIGTERM's
            rclpy.init(args=ros_args, signal_handler_options=SignalHandlerOptions.NO)
        try:
            node = Node('replay')
        except (InvalidParameterTypeException, InvalidParameterValueException) as err:
            # '-p use_sim_time:=7': rclpy's words, one line (was a traceback; dev-probe61)
            raise ToolError(parameter_reason(err)) from err
        pubs = {c.id: node.create_publisher(message_class(c.msgtype), c.topic, qos_of(c))
                for c in conns}
        clock = node.create_publisher(ClockMsg, '/clock', 10) if args.clock else None
        clock_period = int(1e9 / args.clock) if args.clock else 0
        # start once every topic has a matched subscriber, or after --wait seconds
        end = time.monotonic() + args.wait
        while (time.monotonic() < end and rclpy.ok()
               and not all(pub.get_subscription_count() for pub in pubs.values())):
            interrupts.raise_if_received()
            rclpy.spin_once(node, timeout_sec=0.05)
        alone = [c.topic for c in conns if not pubs[c.id].get_subscription_count()]
        if alone:
            print(f'replay: after --wait {args.wait:g} s, {len(alone)} of {len(conns)} '
                  'topics have no subscriber; playing anyway', file=sys.stderr)
        start_wall = time.monotonic()
        clocks = 0
        start_bag: Optional[int] = None
        next_clock = 0
        for conn, stamp, data in reader.messages(connections=conns):
            # a Ctrl-C a lazy import swallowed stops the play too
            interrupts.raise_if_received()
            if not rclpy.ok():
                break
            start_bag = stamp if start_bag is None else start_bag
            delay = start_wall + (stamp - start_bag) * 1e-9 / args.rate - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            if clock is not None and stamp >= next_clock:
                clock.publish(ClockMsg(clock=conv.ns_to_stamp(stamp)))
                next_clock = stamp + clock_period
                clocks += 1
            pubs[conn.id].publish(bytes(data))
            published += 1
        print(f'replay: {args.bag}: published {published} messages on {len(conns)} topics '
              f'at {args.rate:g}x in {time.monotonic() - start_wall:.2f} s'
              + (f', and {clocks} on /clock at {args.clock:g} Hz' if clock else ''))
    except KeyboardInterrupt as stop:
        # SIGTERM (Terminated) was 'interrupted' and exit 0, as if played (dev-probe56)
        word = 'terminated' if isinstance(stop, interrupts.Terminated) else 'interrupted'
        print(f'replay: {word} after {published} messages', file=sys.stderr)
        return interrupts.exit_code(stop)
    finally:
        reader.close()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    """
    Parse the command line and play or re-run.

    :param argv: the command line (ROS arguments after ``--ros-args``).
    :return: exit code.
    """
    full = list(sys.argv if argv is None else ['replay', *argv])
    p = ArgumentParser(prog='replay', description='play a bag over DDS, or re-run the '
                       'controller core on it offline (--offline)')
    p.add_argument('bag', type=Path, help='the bag directory')
    play_only = p.add_argument_group('playing over DDS')
    play_only.add_argument('--rate', type=number(0.0, 1000.0, low_open=True, unit='x'),
                           default=None, metavar='FACTOR',
                           help='playback speed factor [-] (default 1)')
    play_only.add_argument('--topics', nargs='+', default=None, metavar='TOPIC',
                           help='publish only these topics (default: all)')
    play_only.add_argument('--clock', type=number(0.0, 10000.0, low_open=True, unit='Hz'),
                           nargs='?', const=100.0, default=None, metavar='HZ',
                           help='also publish /clock from the bag time at HZ [Hz] '
                           '(default off; without a value 100 Hz)')
    play_only.add_argument('--wait', type=number(0.0, 3600.0, unit='s'), default=None,
                           metavar='S', help='longest wait for a subscriber on every topic '
                           'before playing [s] (default 5)')
    offline_only = p.add_argument_group('re-running offline (--offline)')
    offline_only.add_argument('--offline', action='store_true',
                              help='re-run the controller core (input checks, law, '
                              'low-speed hold, output limits) on the recorded inputs and '
                              'compare with the recorded steering, instead of publishing')
    offline_only.add_argument('-p', '--param', action='append', default=[],
                              metavar='NAME=VALUE', help='override a recorded controller '
                              'parameter (vehicle.*, controller.*, safety.*); clock-driven '
                              'ones (watchdog, timer) are refused')
    offline_only.add_argument('--node', default=None, metavar='NAME',
                              help='the controller node whose run to re-run (default '
                              '/controller): its recorded parameters, its NAME/debug and '
                              'the contract topics in its namespace (/car_b/controller: '
                              '/car_b/lateral_error, ...; --topic overrides one)')
    offline_only.add_argument('--topic', action='append', default=[], metavar='ROLE=TOPIC',
                              help='contract topic names in the bag (lateral_error=/x; a relative '
                              "name is in the node's namespace, ~/x under its name)")
    offline_only.add_argument('--order', choices=('stamp', 'receive'), default=None,
                              help='input order (default: as the recorded node worked)')
    offline_only.add_argument('--check', type=number(0.0, unit='rad'), default=None,
                              metavar='TOL', help='exit 1 if any |recorded - recomputed| '
                              'steering > TOL [rad]; implies --offline')
    offline_only.add_argument('--json', type=output_file('.json'), default=None,
                              metavar='FILE', help='write the comparison as JSON (a .json '
                              'file: an earlier one is replaced, no other file)')
    # before, a file holding only a string played, a directory or a malformed file gave
    # rcl's raw message, and record let rcl's parser read a pipe before the node
    with tool_arguments(full, 'replay') as checked:
        return _main(p, checked)


def _main(p: ArgumentParser, full: list[str]) -> int:
    args = p.parse_args(program_arguments(full))
    offline_run = args.offline or args.check is not None
    played = [name for name, value in (('--rate', args.rate), ('--topics', args.topics),
                                       ('--clock', args.clock), ('--wait', args.wait))
              if value is not None]
    offline_given = [name for name, value in (
        ('-p', args.param), ('--topic', args.topic), ('--order', args.order),
        ('--node', args.node is not None),
        ('--json', args.json)) if value]
    if offline_run:
        if played:
            raise ToolError(f'{", ".join(played)}: only for playing over DDS, not with '
                            '--offline')
        return offline(args)
    if offline_given:
        raise ToolError(f'{", ".join(offline_given)}: only with --offline')
    args.rate = 1.0 if args.rate is None else args.rate
    args.wait = 5.0 if args.wait is None else args.wait
    args.clock = args.clock or 0.0
    args.topics = args.topics or []
    return play(args, full)


def entry() -> int:
    """Entry point of ``replay``."""
    return run_tool(main)


if __name__ == '__main__':
    sys.exit(entry())
