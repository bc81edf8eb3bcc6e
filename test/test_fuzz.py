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
Property-based fuzzing of the controller: no exception, no bad command.

Two targets: the checked core (samples), and the node's message callbacks (ROS messages,
malformed ones included, in a private context, with the watchdog and the timer in the
sequence). ``FUZZ_EXAMPLES`` sets the number of core sequences (default 10^4, ``make
fuzz``: 10^5); the node gets a fifth of that.
"""

import math
import os

from geometry_msgs.msg import Point32, PointStamped, PolygonStamped, TwistStamped
from hypothesis import given, HealthCheck, settings, strategies as st
from lookahead_control.core.controller import SteeringController
from lookahead_control.core.params import ControllerParams, VehicleParams
from lookahead_control.core.safety import angle_limit, SafetyParams
from lookahead_control.ros import conversions as conv
from lookahead_control.ros.conversions import (CurvatureSample, LateralErrorSample, VelocitySample,
                                               YawSample)
import pytest
import rclpy
from rclpy.context import Context
from sensor_msgs.msg import Imu

EXAMPLES = int(os.environ.get('FUZZ_EXAMPLES', '10000'))
NODE_EXAMPLES = max(1, EXAMPLES // 5)
CASES = {'sequences': 0, 'messages': 0, 'node sequences': 0, 'node messages': 0,
         'node commands': 0}
SAFETY = SafetyParams()
VEHICLE = VehicleParams()

adversarial = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1e-300, -1e-300, 1e300, float('nan'), float('inf'),
                     -float('inf'), 0.99, 1.01]),
    st.floats(-100.0, 100.0))
stamps = st.one_of(st.integers(0, 10**12), st.sampled_from([0, 1, 2**62]))
message = st.one_of(
    st.tuples(st.just('lateral_error'), stamps, adversarial, adversarial),
    st.tuples(st.just('yaw'), stamps, adversarial, adversarial, adversarial),
    st.tuples(st.just('velocity'), stamps, adversarial, adversarial),
    st.tuples(st.just('road_curvature'), stamps, adversarial, adversarial),
    st.tuples(st.just('tick'), stamps))
SAMPLES = {'lateral_error': LateralErrorSample, 'yaw': YawSample,
           'velocity': VelocitySample, 'road_curvature': CurvatureSample}


@settings(max_examples=EXAMPLES, deadline=None, database=None,
          suppress_health_check=list(HealthCheck))
@given(st.lists(message, max_size=30),
       st.sampled_from(['paper', 'exact', 'fixed']),
       st.sampled_from(['imu', 'differentiate', 'zero']))
def test_no_input_sequence_gives_a_bad_command(sequence, schedule, acceleration):
    core = SteeringController(VEHICLE, ControllerParams(schedule=schedule), acceleration,
                              True, SAFETY)
    CASES['sequences'] += 1
    limits = OutputLimits()
    for item in sequence:
        CASES['messages'] += 1
        name, stamp = item[0], item[1]
        if name == 'tick':
            command = core.safe_command(stamp) if core.stale(stamp) else core.compute()
        else:
            core.accept(name, SAMPLES[name](stamp, *item[2:]), stamp)
            command = core.compute() if name == 'lateral_error' else None
        if command is None:
            continue
        assert math.isfinite(command.steering_rate)
        limits.check(command.stamp_ns, command.steering,
                     core.velocity.v_x if core.velocity else 0.0, core.time_jumps)


class OutputLimits:
    """The output contract, checked command by command in the order they are sent."""

    def __init__(self):
        self.latest = None
        self.angle = None
        self.time_jumps = 0

    def check(self, stamp, angle, v_x, time_jumps):
        """
        Check one command.

        Finite; within the angle limit at the current speed; and moved no more than the
        rate limit allows since the newest command so far (nothing for an older stamp,
        nothing for the first after a time jump: stamps restart there). The one
        exception: the angle limit falls faster than the rate (the speed rose), and the
        command sits on it.
        """
        cap = angle_limit(v_x, VEHICLE.wheelbase, SAFETY)
        assert math.isfinite(angle) and abs(angle) <= cap + 1e-12
        if time_jumps != self.time_jumps:
            self.time_jumps, self.latest = time_jumps, stamp
        if self.angle is not None:
            dt = max(0, stamp - self.latest) * 1e-9
            on_falling_cap = abs(abs(angle) - cap) < 1e-12 and abs(angle) < abs(self.angle)
            assert on_falling_cap or \
                abs(angle - self.angle) <= SAFETY.max_steering_rate * dt + 1e-9, \
                (stamp, angle, self.latest, self.angle)
        self.latest = stamp if self.latest is None else max(self.latest, stamp)
        self.angle = angle


@pytest.fixture(scope='module')
def node():
    from lookahead_control.ros.controller_node import ControllerNode
    ctx = Context()
    rclpy.init(context=ctx)
    controller = ControllerNode(context=ctx)
    controller.trigger_configure()
    controller.trigger_activate()
    yield controller
    controller.destroy_node()
    rclpy.try_shutdown(context=ctx)


frames = st.sampled_from(['base_link'] * 8 + ['', 'map'])
# stamps around the node's clock (now + offset [s]) and anywhere a Time can hold
offsets = st.one_of(st.floats(-0.05, 0.0), st.floats(-1.5, 0.3),
                    st.sampled_from([-1e6, 1e6]))


def mostly(plausible):
    """Plausible values most of the time (so commands come out), adversarial else."""
    return st.one_of(plausible, plausible, plausible, adversarial)


points = st.lists(st.tuples(mostly(st.floats(-10.0, 100.0)), mostly(st.floats(-0.1, 0.1))),
                  max_size=5)
single = st.one_of(
    st.tuples(st.just('lateral_error'), frames, offsets, mostly(st.floats(0.0, 30.0)),
              mostly(st.floats(-3.0, 3.0))),
    st.tuples(st.just('yaw'), frames, offsets, mostly(st.floats(-0.5, 0.5)),
              mostly(st.floats(0.8, 1.0)), mostly(st.floats(-1.0, 1.0)),
              mostly(st.floats(-5.0, 5.0))),
    st.tuples(st.just('velocity'), frames, offsets, mostly(st.floats(0.0, 45.0)),
              mostly(st.floats(-2.0, 2.0))),
    st.tuples(st.just('road_curvature'), frames, offsets, points),
    st.tuples(st.sampled_from(['watchdog', 'timer', 'diagnostics'])))
# a vehicle bridge's step: yaw, velocity, then lateral error, with one stamp
step = st.tuples(st.just('step'), frames, offsets, single, single, single)
node_message = st.one_of(single, step)


def _ros_message(item, now_ns):
    name, frame, offset = item[0], item[1], item[2]
    stamp = conv.ns_to_stamp(min(max(now_ns + int(offset * 1e9), 0), 2**31 * 10**9 - 1))
    if name == 'lateral_error':
        msg = PointStamped()
        msg.point.x, msg.point.y = item[3], item[4]
    elif name == 'yaw':
        msg = Imu()
        msg.orientation.z, msg.orientation.w = item[3], item[4]   # not always unit
        msg.angular_velocity.z, msg.linear_acceleration.x = item[5], item[6]
    elif name == 'velocity':
        msg = TwistStamped()
        msg.twist.linear.x, msg.twist.linear.y = item[3], item[4]
    else:
        msg = PolygonStamped()
        # float32 fields: what does not fit is what a sender could not have sent
        msg.polygon.points = [Point32(x=_f32(x), y=_f32(y)) for x, y in item[3]]
    msg.header.stamp, msg.header.frame_id = stamp, frame
    return msg


_plausible = {'yaw': (0.01, 1.0, 0.02, 0.0), 'velocity': (25.0, 0.1),
              'lateral_error': (1.96, 0.5)}


def _f32(value):
    return value if not math.isfinite(value) or abs(value) < 3e38 else math.copysign(
        float('inf'), value)


@settings(max_examples=NODE_EXAMPLES, deadline=None, database=None,
          suppress_health_check=list(HealthCheck))
@given(st.lists(node_message, max_size=20))
def test_no_message_sequence_makes_the_node_raise_or_command_badly(node, sequence):
    node.core.reset()
    limits = OutputLimits()

    def publish(msg):
        CASES['node commands'] += 1
        stamp, angle = conv.from_steering(msg)
        assert math.isfinite(msg.velocity[0])
        limits.check(stamp, angle, node.core.velocity.v_x if node.core.velocity else 0.0,
                     node.core.time_jumps)

    node._steering_pub.publish = publish
    callbacks = {'lateral_error': node.on_lateral_error, 'yaw': node.on_yaw,
                 'velocity': node.on_velocity, 'road_curvature': node.on_curvature,
                 'watchdog': node.on_watchdog, 'timer': node.on_timer,
                 'diagnostics': node.on_diagnostics}
    CASES['node sequences'] += 1

    def deliver(item, now_ns):
        CASES['node messages'] += 1
        if len(item) == 1:
            callbacks[item[0]]()
        else:
            callbacks[item[0]](_ros_message(item, now_ns))

    for item in sequence:
        now_ns = node.get_clock().now().nanoseconds
        if item[0] != 'step':
            deliver(item, now_ns)
            continue
        _, frame, offset, *parts = item
        for name, part in zip(('yaw', 'velocity', 'lateral_error'), parts):
            values = part[3:] if part[0] == name else _plausible[name]
            deliver((name, frame, offset, *values), now_ns)


def test_zz_report_the_fuzz_count():
    print(f"\nfuzz: core {CASES['sequences']} sequences, {CASES['messages']} samples; "
          f"node {CASES['node sequences']} sequences, {CASES['node messages']} messages, "
          f"{CASES['node commands']} commands; 0 exceptions, 0 commands out of limits")
    assert CASES['sequences'] >= EXAMPLES or CASES['sequences'] == 0
    assert CASES['node sequences'] >= NODE_EXAMPLES or CASES['node sequences'] == 0
    # the sequences reach the law, not only the input checks
    assert CASES['node commands'] > 0 or CASES['node sequences'] == 0
