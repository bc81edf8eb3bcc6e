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
import math
from pathlib import Path
import sys
import time
from typing import Any, Optional, Sequence

from lookahead_control.bags.recorder_node import message_class
from lookahead_control.bags.rosbag_io import bag_reader
from lookahead_control.bags.run_data import load_run, rerun
from lookahead_control.core.cli import assignments, run_tool, ToolError, write_json
from lookahead_control.ros import conversions as conv
import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.utilities import remove_ros_args
from rosgraph_msgs.msg import Clock as ClockMsg
import yaml

EXIT_CHECK_FAILED = 1


def offline(args: argparse.Namespace) -> int:
    """
    Re-run the controller core on a bag's inputs and compare with its steering.

    :param args: the parsed command line.
    :return: 0, or 1 if ``--check`` failed.
    """
    # override values as YAML: numbers, booleans, strings
    overrides = {k: yaml.safe_load(v) for k, v in assignments(args.param, '-p').items()}
    run = load_run(args.bag, assignments(args.topic, '--topic'))
    result = rerun(run, overrides, args.order)
    report = {'bag': str(args.bag), 'order': result.order, 'compared': result.compared,
              'recorded': len(run.steering.by_stamp()), 'recomputed': len(result.commands),
              'max_diff_rad': result.max_diff, 'rms_diff_rad': result.rms_diff,
              'overrides': overrides}
    print(f'replay: {args.bag}: {result.compared} commands compared ({result.order} '
          f'order): max |diff| {result.max_diff:.3g} rad, RMS {result.rms_diff:.3g} rad')
    if args.json:
        write_json(Path(args.json), report)
    if args.check is not None:
        if result.compared == 0:
            print('replay: check failed: no command to compare', file=sys.stderr)
            return EXIT_CHECK_FAILED
        if not result.max_diff <= args.check:
            print(f'replay: check failed: max |diff| {result.max_diff:.3g} rad > '
                  f'{args.check:g} rad', file=sys.stderr)
            return EXIT_CHECK_FAILED
    return 0


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
    rclpy.init(args=ros_args)
    node = Node('replay')
    published = 0
    try:
        conns = [c for c in reader.connections
                 if (not args.topics or c.topic in args.topics)
                 and not (args.clock and c.topic == '/clock')]
        if not conns:
            raise ToolError(f'{args.bag}: none of the topics {args.topics} is in the bag')
        pubs = {c.id: node.create_publisher(message_class(c.msgtype), c.topic, qos_of(c))
                for c in conns}
        clock = node.create_publisher(ClockMsg, '/clock', 10) if args.clock else None
        clock_period = int(1e9 / args.clock) if args.clock else 0
        # start once every topic has a matched subscriber, or after --wait seconds
        end = time.monotonic() + args.wait
        while (time.monotonic() < end and rclpy.ok()
               and not all(pub.get_subscription_count() for pub in pubs.values())):
            rclpy.spin_once(node, timeout_sec=0.05)
        start_wall = time.monotonic()
        start_bag: Optional[int] = None
        next_clock = 0
        for conn, stamp, data in reader.messages(connections=conns):
            if not rclpy.ok():
                break
            start_bag = stamp if start_bag is None else start_bag
            delay = start_wall + (stamp - start_bag) * 1e-9 / args.rate - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            if clock is not None and stamp >= next_clock:
                clock.publish(ClockMsg(clock=conv.ns_to_stamp(stamp)))
                next_clock = stamp + clock_period
            pubs[conn.id].publish(bytes(data))
            published += 1
        print(f'replay: {args.bag}: published {published} messages on {len(conns)} topics '
              f'in {time.monotonic() - start_wall:.2f} s')
    except KeyboardInterrupt:
        print(f'replay: interrupted after {published} messages', file=sys.stderr)
    finally:
        reader.close()
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
    p = argparse.ArgumentParser(prog='replay', description='play a bag over DDS, or '
                                're-run the controller on it offline (--offline)')
    p.add_argument('bag', type=Path)
    p.add_argument('--rate', type=float, default=1.0, help='playback rate factor')
    p.add_argument('--topics', nargs='*', default=[], help='only these topics')
    p.add_argument('--clock', type=float, nargs='?', const=100.0, default=0.0,
                   metavar='HZ', help='publish /clock from the bag time (default 100 Hz)')
    p.add_argument('--wait', type=float, default=5.0,
                   help='longest wait for a subscriber on every topic before playing [s]')
    p.add_argument('--offline', action='store_true',
                   help='re-run the controller core on the inputs instead of publishing')
    p.add_argument('-p', '--param', action='append', default=[], metavar='NAME=VALUE',
                   help='offline: override a recorded controller parameter')
    p.add_argument('--topic', action='append', default=[], metavar='ROLE=TOPIC',
                   help='offline: contract topic names in the bag (lateral_error=/x)')
    p.add_argument('--order', choices=('stamp', 'receive'), default=None,
                   help='offline: input order (default: as the recorded node worked)')
    p.add_argument('--check', type=float, default=None, metavar='TOL',
                   help='offline: exit 1 if any |recorded - recomputed| > TOL [rad]')
    p.add_argument('--json', type=Path, default=None, help='offline: write the report')
    args = p.parse_args(remove_ros_args(full)[1:])
    if args.offline or args.check is not None:
        if args.check is not None and not (args.check >= 0.0 and math.isfinite(args.check)):
            raise ToolError(f'--check {args.check}: must be a finite tolerance >= 0')
        return offline(args)
    return play(args, full)


def entry() -> int:
    """Entry point of ``replay``."""
    return run_tool(main)


if __name__ == '__main__':
    sys.exit(entry())
