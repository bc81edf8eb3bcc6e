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
The benchmarks' helper processes: baselines (echo, pong, counter) and drivers.

``python -m bench.nodes ROLE ...``. Baselines use the same message types, QoS, executor
and spin loop as the real nodes and do nothing else, so the ratio is what the
controller, simulator or recorder add.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time
from typing import Any, Iterator

from geometry_msgs.msg import PointStamped, PolygonStamped, TwistStamped
from lookahead_control.ros import conversions as conv
from lookahead_control.ros.controller_node import qos
from lookahead_control.ros.node_main import make_executor, spin_until
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState

INPUTS = (('lateral_error', PointStamped), ('yaw', Imu), ('velocity', TwistStamped),
          ('road_curvature', PolygonStamped))
PREVIEW = [(5.0 * i, -0.0025) for i in range(11)]     # sim_plant's default preview
TRUTH_NAMES = [f'v{i}' for i in range(12)]             # as many as sim_plant's


def _answerer(name: str, with_clock: bool) -> Node:
    node = Node(name)
    if with_clock:                  # the controller on sim time also takes /clock
        node.create_subscription(Clock, '/clock', lambda msg: None, 10)
    steering = node.create_publisher(JointState, 'steering', qos('reliable'))

    def answer(msg: PointStamped) -> None:
        steering.publish(conv.to_steering(conv.stamp_to_ns(msg.header.stamp), 0.0, 0.0))

    for topic, kind in INPUTS:
        node.create_subscription(kind, topic, answer if topic == 'lateral_error'
                                 else (lambda msg: None), qos('reliable'))
    return node


def echo(args: argparse.Namespace) -> None:
    """Republish each lateral error as a steering message with its stamp, nothing else."""
    _spin(_answerer('echo', False), args.executor)


def pong(args: argparse.Namespace) -> None:
    """Answer each lockstep step like the controller does, computing nothing."""
    _spin(_answerer('pong', True), args.executor)


def _step_publishers(node: Node, truth: str, answers: bool = False) -> dict[str, Any]:
    """Create the publishers of a step's messages (and of the controller's answers)."""
    reliable = qos('reliable')
    pubs: dict[str, Any] = {name: node.create_publisher(kind, name, reliable)
                            for name, kind in INPUTS}
    if answers:
        pubs['steering'] = node.create_publisher(JointState, 'steering', reliable)
        pubs['debug'] = node.create_publisher(JointState, '/controller/debug', reliable)
    pubs['truth'] = node.create_publisher(JointState, truth, reliable)
    pubs['clock'] = node.create_publisher(Clock, '/clock', 10)
    return pubs


def ping(args: argparse.Namespace) -> None:
    """Lockstep like sim_plant: publish a step's messages, wait for the answer, repeat."""
    node = Node('ping')
    reliable = qos('reliable')
    pubs = _step_publishers(node, '~/ground_truth')
    state = {'k': 0, 'start': 0.0, 'end': 0.0}

    def publish_step() -> None:
        _publish_step(pubs, state['k'] * 10_000_000)

    def on_answer(msg: JointState) -> None:
        if conv.stamp_to_ns(msg.header.stamp) != state['k'] * 10_000_000:
            return
        state['k'] += 1
        if state['k'] >= args.steps:
            state['end'] = time.monotonic()
            return
        publish_step()

    sub = node.create_subscription(JointState, 'steering', on_answer, reliable)
    executor = make_executor(args.executor)
    executor.add_node(node)
    spin_until(executor, lambda: all(pubs[n].get_subscription_count() > 0 for n, _ in INPUTS)
               and sub.get_publisher_count() > 0)
    state['start'] = time.monotonic()
    publish_step()
    spin_until(executor, lambda: state['end'] > 0.0, 0.1)
    wall = state['end'] - state['start']
    print(json.dumps({'steps': args.steps, 'wall_s': wall, 'steps_per_s': args.steps / wall}))


def driver(args: argparse.Namespace) -> None:
    """Publish yaw, velocity, lateral error at a rate; time each steering answer."""
    node = Node('latency_driver')
    reliable = qos('reliable')
    pubs = {name: node.create_publisher(kind, name, reliable) for name, kind in INPUTS[:3]}
    sent: dict[int, int] = {}
    latencies: list[float] = []

    def on_answer(msg: JointState) -> None:
        stamp = conv.stamp_to_ns(msg.header.stamp)
        if stamp in sent:
            latencies.append((time.perf_counter_ns() - sent.pop(stamp)) * 1e-3)

    sub = node.create_subscription(JointState, 'steering', on_answer, reliable)
    executor = make_executor('events')
    executor.add_node(node)
    spin_until(executor, lambda: all(p.get_subscription_count() > 0 for p in pubs.values())
               and sub.get_publisher_count() > 0)
    spin_until_time(executor, 0.5)
    count = int(args.rate * args.seconds)
    done = threading.Event()

    def publish() -> None:
        for _ in _paced(args.rate, count):
            stamp = node.get_clock().now().nanoseconds
            pubs['yaw'].publish(conv.to_yaw(stamp, 'base_link', 0.01, 0.02, 0.0))
            pubs['velocity'].publish(conv.to_velocity(stamp, 'base_link', 25.0, 0.1, 0.02))
            sent[stamp] = time.perf_counter_ns()
            pubs['lateral_error'].publish(conv.to_lateral_error(stamp, 'base_link', 1.96,
                                                                0.3))
        done.set()

    thread = threading.Thread(target=publish)
    thread.start()
    spin_until(executor, done.is_set, 0.01)
    spin_until_time(executor, 1.0)            # drain
    thread.join()
    print(json.dumps({'sent': count, 'received': len(latencies), 'lost': len(sent),
                      'latency_us': latencies}))


def blast(args: argparse.Namespace) -> None:
    """Publish every contract topic at a rate (for the recorder), then print counts."""
    node = Node('blast')
    pubs = _step_publishers(node, '/sim_plant/ground_truth', answers=True)
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline and not all(
            p.get_subscription_count() >= args.subscribers for p in pubs.values()):
        rclpy.spin_once(node, timeout_sec=0.05)
    time.sleep(1.0)
    count = int(args.rate * args.seconds)
    start = time.perf_counter()
    for _ in _paced(args.rate, count):
        _publish_step(pubs, node.get_clock().now().nanoseconds)
    print(json.dumps({'per_topic': count, 'topics': len(pubs),
                      'wall_s': time.perf_counter() - start}), flush=True)
    time.sleep(2.0)


def counter(args: argparse.Namespace) -> None:
    """Count raw messages of the topics blast publishes, like the recorder minus writing."""
    node = Node('counter')
    counts: dict[str, int] = {}
    topics = [n for n, _ in INPUTS] + ['steering', '/controller/debug',
                                       '/sim_plant/ground_truth', '/clock']
    kinds = [k for _, k in INPUTS] + [JointState, JointState, JointState, Clock]
    for topic, kind in zip(topics, kinds):
        counts[topic] = 0

        def on_message(data: bytes, info: Any, topic: str = topic) -> None:
            counts[topic] += 1

        node.create_subscription(kind, topic, on_message, qos('reliable') if kind is not Clock
                                 else 10, raw=True)
    try:
        _spin(node, 'single_threaded')
    finally:
        print(json.dumps(counts), file=sys.stderr, flush=True)


def _publish_step(pubs: dict[str, Any], stamp: int) -> None:
    """Publish one step of the contract topics in ``pubs``, in sim_plant's order."""
    values = [(n, 0.0) for n in TRUTH_NAMES]
    pubs['yaw'].publish(conv.to_yaw(stamp, 'base_link', 0.0, 0.0, 0.0))
    pubs['velocity'].publish(conv.to_velocity(stamp, 'base_link', 30.0, 0.0, 0.0))
    pubs['road_curvature'].publish(conv.to_curvature(stamp, 'base_link', PREVIEW))
    pubs['truth'].publish(conv.to_named_values(stamp, values))
    pubs['lateral_error'].publish(conv.to_lateral_error(stamp, 'base_link', 1.96, 0.1))
    if 'steering' in pubs:
        pubs['steering'].publish(conv.to_steering(stamp, 0.0, 0.0))
        pubs['debug'].publish(conv.to_named_values(stamp, values))
    pubs['clock'].publish(Clock(clock=conv.ns_to_stamp(stamp)))


def _paced(rate: float, count: int) -> Iterator[int]:
    """Yield 0 .. count-1, the k-th at k / rate seconds from now."""
    start = time.perf_counter()
    for k in range(count):
        time.sleep(max(0.0, start + k / rate - time.perf_counter()))
        yield k


def spin_until_time(executor: Any, seconds: float) -> None:
    """Spin for a while."""
    end = time.monotonic() + seconds
    spin_until(executor, lambda: time.monotonic() >= end, 0.01)


def _spin(node: Node, kind: str) -> None:
    executor = make_executor(kind)
    executor.add_node(node)
    try:
        spin_until(executor, lambda: False)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass


def main() -> None:
    """Run one role until done or interrupted."""
    p = argparse.ArgumentParser()
    p.add_argument('role', choices=('echo', 'pong', 'ping', 'driver', 'blast', 'counter'))
    p.add_argument('--executor', default='events')
    p.add_argument('--steps', type=int, default=1000)
    p.add_argument('--rate', type=float, default=100.0)
    p.add_argument('--seconds', type=float, default=5.0)
    p.add_argument('--subscribers', type=int, default=1)
    args = p.parse_args()
    rclpy.init()
    try:
        globals()[args.role](args)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
