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

from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import Point32, PointStamped, PolygonStamped, TwistStamped
from hypothesis import example, given, HealthCheck, settings, strategies as st
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
         'node commands': 0, 'core commands': 0, 'checked commands': 0, 'law commands': 0}
SAFETY = SafetyParams()
VEHICLE = VehicleParams()

adversarial = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1e-300, -1e-300, 1e300, float('nan'), float('inf'),
                     -float('inf'), 0.99, 1.01]),
    st.floats(-100.0, 100.0))
stamps = st.one_of(st.integers(0, 10**12), st.sampled_from([0, 1, 2**62]))
# the node's clock: mostly small steps forwards, some long ones, some back (a jump)
clock_steps = st.one_of(*[st.integers(0, 20_000_000)] * 6, st.integers(0, 600_000_000),
                        st.integers(-2_000_000_000, 0))
message = st.one_of(
    st.tuples(st.just('lateral_error'), stamps, adversarial, adversarial),
    st.tuples(st.just('yaw'), stamps, adversarial, adversarial, adversarial),
    st.tuples(st.just('velocity'), stamps, adversarial, adversarial),
    st.tuples(st.just('road_curvature'), stamps, adversarial, adversarial),
    st.tuples(st.just('tick'), stamps))
# and believable values (so that the law runs and its commands get checked)
believable = st.one_of(
    st.tuples(st.just('lateral_error'), stamps, st.floats(0.0, 30.0), st.floats(-3.0, 3.0)),
    st.tuples(st.just('yaw'), stamps, st.floats(-0.5, 0.5), st.floats(-1.0, 1.0),
              st.floats(-5.0, 5.0)),
    st.tuples(st.just('velocity'), stamps, st.floats(0.0, 45.0), st.floats(-2.0, 2.0)),
    st.tuples(st.just('road_curvature'), stamps, st.floats(-0.1, 0.1), st.floats(-0.01, 0.01)))
SAMPLES = {'lateral_error': LateralErrorSample, 'yaw': YawSample,
           'velocity': VelocitySample, 'road_curvature': CurvatureSample}


@settings(max_examples=EXAMPLES, deadline=None, database=None,
          suppress_health_check=list(HealthCheck))
@given(st.lists(st.tuples(st.one_of(message, believable, believable), clock_steps,
                          st.sampled_from([True, True, True, False])), max_size=30),
       st.sampled_from(['paper', 'exact', 'fixed']),
       st.sampled_from(['imu', 'differentiate', 'zero']))
# dev-sc52: the angle limit took the speed read at the lateral error's stamp (align_inputs),
# between a speed of 0 and one of 18 m/s: a command over the limit at the newest speed
@example(sequence=[(('lateral_error', 0, 0.0, 0.0), 0, True),
                   (('lateral_error', 0, 0.0, 0.0), 0, True),
                   (('velocity', 0, 0.0, 0.0), 0, True),
                   (('yaw', 0, 0.0, 0.0, 0.0), 200000001, True),
                   (('lateral_error', 0, 0.0, 0.0), 0, True),
                   (('lateral_error', 0, 0.0, 0.0), 0, True),
                   (('tick', 0), 2, True),
                   (('lateral_error', 1, 0.0, 3.0), 0, True),
                   (('lateral_error', 0, 0.0, 6.0), 0, True),
                   (('velocity', 0, 18.0, 1.0), 0, True),
                   (('tick', 0), 0, True)], schedule='fixed', acceleration='imu')
def test_no_input_sequence_gives_a_bad_command(sequence, schedule, acceleration):
    core = SteeringController(VEHICLE, ControllerParams(schedule=schedule), acceleration,
                              True, SAFETY)
    CASES['sequences'] += 1
    invariants = Invariants(core)
    now = 10**12
    for item, step, near in sequence:
        CASES['messages'] += 1
        now = max(0, now + step)
        name, stamp = item[0], item[1]
        if near:                        # a stamp near the clock, so that inputs pass
            stamp = max(0, now - stamp % 250_000_000)
        if name == 'tick':
            command = core.safe_command(now) if core.stale(now) else core.compute(now)
        else:
            accepted = core.accept(name, SAMPLES[name](stamp, *item[2:]), now) is None
            invariants.delivered(name, stamp, now, accepted)
            command = core.compute(now) if name == 'lateral_error' and accepted else None
        if command is not None:
            CASES['core commands'] += 1
            invariants.check(command, now)


class Invariants:
    """
    The safety contract, checked at every command in the order they are sent.

    - finite; within ``max_steering_angle``; within the speed's angle limit or moving
      towards it at the rate limit;
    - the rate limit on the node's clock: ``|change| <= max_steering_rate x (time
      since it on the node's clock)`` from the last command sent at an earlier clock
      reading (the answers at one reading share one step), with no exception (a clock
      going back or a time jump allows no change), and the published rate is that
      change over that time; on the stamps (the newest so far), from the previous
      command; where the two windows do not meet (the rate was lowered), it holds;
    - no command from stale data: an answer of the law uses only samples delivered
      within ``input_timeout`` of now and stamped within ``input_timeout`` of now
      (judged here from the test's own record of what it delivered and when), and the
      stamps each input used advance.
    """

    def __init__(self, core):
        self.core = core
        self.previous = None            # (now, angle)
        self.ref = None                 # (now, angle): the last at an earlier reading
        self.arrivals = {}              # (input, stamp) -> node clock of the last delivery
        self.used = {}                  # input -> the last stamp an answer used
        self.time_jumps = core.time_jumps
        self.newest = None              # the newest command stamp so far
        self.hold_next = False          # the next command holds the previous angle

    def delivered(self, name, stamp, now, accepted):
        """Record the node clock at which a sample was delivered, if accepted."""
        if accepted:
            self.arrivals[(name, stamp)] = now

    def check(self, command, now):
        """Check one command published at ``now`` on the node's clock."""
        core, safety = self.core, self.core.safety
        CASES['checked commands'] += 1
        angle, rate = command.steering, command.steering_rate
        assert math.isfinite(angle) and math.isfinite(rate)
        assert abs(angle) <= safety.max_steering_angle + 1e-12
        jumped = core.time_jumps != self.time_jumps or self.hold_next
        self.hold_next = False
        if jumped:                  # stamps restart; the first command after it holds
            self.time_jumps, self.used, self.newest = core.time_jumps, {}, None
        rate_limit = safety.max_steering_rate
        if self.previous is not None:
            then, before = self.previous
            if jumped or now < then:        # the angle sent, no time on the clock yet
                self.ref = (now, before)
                if now < then:
                    self.newest = None      # the node's clock went back
            elif now > then:                # a new reading: the last command is the ref
                self.ref = (then, before)
        low, high = -math.inf, math.inf
        if self.ref is not None:
            since = (now - self.ref[0]) * 1e-9
            low, high = self.ref[1] - rate_limit * since, self.ref[1] + rate_limit * since
            if since > 0.0:
                assert abs(rate - (angle - self.ref[1]) / since) <= 1e-9 * max(1.0, abs(rate))
            else:
                assert rate == 0.0
        if self.previous is not None and self.newest is not None:
            # also on the stamps (the newest so far): a recording obeys the limit
            span = rate_limit * max(0, command.stamp_ns - self.newest) * 1e-9
            low, high = max(low, self.previous[1] - span), min(high, self.previous[1] + span)
        if low > high:                  # the rate was lowered within one reading: hold
            assert angle == self.previous[1], (self.ref, self.previous, now, angle)
        else:
            assert low - 1e-12 <= angle <= high + 1e-12, (self.ref, self.previous, now, angle)
        v_x = core.velocity.v_x if core.velocity else 0.0
        cap = angle_limit(v_x, VEHICLE.wheelbase, safety)
        if abs(angle) > cap + 1e-12:        # only while moving towards it at the rate
            assert self.previous is not None, (angle, cap)
            edge = self.previous[1] if low > high else (low if angle > 0.0 else high)
            assert abs(angle - edge) <= 1e-12, (angle, cap, low, high)
        stamp = command.stamp_ns
        self.newest = stamp if self.newest is None else max(self.newest, stamp)
        if command.law is not None:
            CASES['law commands'] += 1
            timeout = safety.input_timeout * 1e9
            for name in ('lateral_error', 'yaw', 'velocity'):
                sample = getattr(core, {'lateral_error': 'lateral'}.get(name, name))
                arrived = self.arrivals.get((name, sample.stamp_ns))
                assert arrived is not None and 0 <= now - arrived <= timeout, (name, now, arrived)
                assert now - sample.stamp_ns <= timeout, (name, now, sample.stamp_ns)
                assert sample.stamp_ns >= self.used.get(name, -1), name
                self.used[name] = sample.stamp_ns
        self.previous = (now, angle)


@pytest.fixture(scope='module')
def node():
    from lookahead_control.ros.controller_node import ControllerNode
    from rclpy.parameter import Parameter
    ctx = Context()
    rclpy.init(context=ctx)
    # on a fake clock: sim time, set by the test
    controller = ControllerNode(context=ctx, parameter_overrides=[
        Parameter('use_sim_time', value=True)])
    controller.trigger_configure()
    controller.trigger_activate()
    yield controller
    controller.destroy_node()
    rclpy.try_shutdown(context=ctx)


frames = st.sampled_from(['base_link'] * 8 + ['', 'map'])
# stamps around the node's clock (now + offset [s]) and anywhere a Time can hold
offsets = st.one_of(st.floats(-0.05, 0.0), st.floats(-0.05, 0.0), st.floats(-0.05, 0.0),
                    st.floats(-1.5, 0.3), st.sampled_from([-1e6, 1e6, -0.2, 0.1]))


def mostly(plausible):
    """Plausible values most of the time (so commands come out), adversarial else."""
    return st.one_of(*[plausible] * 7, adversarial)


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


node_clock = st.one_of(*[st.integers(0, 20_000_000)] * 6, st.integers(0, 400_000_000),
                       st.integers(-1_500_000_000, 0))
runtime = st.tuples(st.just('param'), st.sampled_from([
    ('safety.max_steering_rate', 0.2), ('safety.max_steering_rate', 5.0),
    ('safety.input_timeout', 0.1), ('safety.input_timeout', 0.2),
    ('safety.max_steering_angle', 0.3), ('safety.max_steering_angle', 0.6),
    ('controller.natural_frequency', 6.0), ('controller.natural_frequency', 3.0),
    ('wait_for_matching_stamps', True), ('wait_for_matching_stamps', False),
    ('safety.max_curvature_points', 2), ('safety.max_curvature_points', 256)]))
node_item = st.one_of(step, step, step, single, single,
                      st.tuples(st.just('clock'), node_clock), runtime)


@settings(max_examples=NODE_EXAMPLES, deadline=None, database=None,
          suppress_health_check=list(HealthCheck))
@given(st.lists(node_item, max_size=24))
# an answer to inputs 0.125 s old, then input_timeout lowered to 0.1 s: the watchdog's
# command continues the answers' stamps (0.125 s behind), it answers no measurement (this
# check failed about one full run in six when hypothesis found it)
@example(sequence=[('step', 'base_link', -0.125, ('watchdog',), ('watchdog',), ('watchdog',)),
                   ('param', ('safety.input_timeout', 0.1)), ('clock', 60_000_000),
                   ('watchdog',)])
def test_no_message_sequence_makes_the_node_raise_or_command_badly(node, sequence):
    from lookahead_control.ros.controller_node import ALL_SPECS
    from rclpy.parameter import Parameter
    from rclpy.time import Time
    core = node.core
    node.set_parameters_atomically([
        Parameter(s.name, value=s.default) for s in ALL_SPECS
        if s.name.startswith('safety.') or s.name == 'wait_for_matching_stamps'])
    core.reset()
    node._pending_stamp = None
    clock = [node.get_clock().now().nanoseconds or 1000 * 10**9]
    node.get_clock().set_ros_time_override(Time(nanoseconds=clock[0]))
    invariants = Invariants(core)
    widest = [core.safety.input_timeout]      # the widest input_timeout so far
    if core._rate_angle is not None:
        # the node keeps the angle it last sent (an earlier example's) as the rate
        # limit's reference; after the reset its first command holds it (a checker that
        # started empty saw a first command beyond the speed's limit: make test, idle)
        invariants.previous, invariants.hold_next = (clock[0], core._rate_angle), True
    accept = core.accept

    def spy_accept(name, sample, now=None):
        reason = accept(name, sample, now)
        invariants.delivered(name, sample.stamp_ns, now, reason is None)
        return reason

    def publish(msg):
        CASES['node commands'] += 1
        stamp, angle = conv.from_steering(msg)
        command = core.last
        assert (command.stamp_ns, command.steering, command.steering_rate) == (
            stamp, angle, msg.velocity[0])
        invariants.check(command, clock[0])
        widest[0] = max(widest[0], core.safety.input_timeout)
        if command.law is not None:
            # never an answer to a measurement older than input_timeout
            assert clock[0] - stamp <= core.safety.input_timeout * 1e9
        else:
            # a watchdog command continues the answers' stamps: behind the clock by at
            # most the age its inputs were accepted at (input_timeout may have fallen)
            assert clock[0] - stamp <= widest[0] * 1e9

    core.accept = spy_accept
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
            if item[0] == 'watchdog':
                # stale inputs are an ERROR that names them
                assert node.stale_inputs == core.stale(now_ns)
                status = node.diagnostics()
                assert (status.level == DiagnosticStatus.ERROR) == bool(node.stale_inputs)
                assert all(name in status.message for name in node.stale_inputs)
        else:
            callbacks[item[0]](_ros_message(item, now_ns))

    try:
        for item in sequence:
            if item[0] == 'clock':
                clock[0] = max(1, clock[0] + item[1])
                node.get_clock().set_ros_time_override(Time(nanoseconds=clock[0]))
                continue
            if item[0] == 'param':
                result = node.set_parameters([Parameter(item[1][0], value=item[1][1])])[0]
                # refused only when it contradicts another (the angle below safe_angle)
                assert result.successful or result.reason
                continue
            if item[0] != 'step':
                deliver(item, clock[0])
                continue
            _, frame, offset, *parts = item
            for name, part in zip(('yaw', 'velocity', 'lateral_error'), parts):
                values = part[3:] if part[0] == name else _plausible[name]
                deliver((name, frame, offset, *values), clock[0])
    finally:
        core.accept = accept


def test_zz_report_the_fuzz_count():
    print(f"\nfuzz: core {CASES['sequences']} sequences, {CASES['messages']} samples; "
          f"{CASES['core commands']} commands; node {CASES['node sequences']} sequences, "
          f"{CASES['node messages']} messages, "
          f"{CASES['node commands']} commands; {CASES['checked commands']} commands "
          f"checked ({CASES['law commands']} from the law); 0 exceptions, 0 violations")
    assert CASES['sequences'] >= EXAMPLES or CASES['sequences'] == 0
    assert CASES['node sequences'] >= NODE_EXAMPLES or CASES['node sequences'] == 0
    # the sequences reach the law, not only the input checks
    assert CASES['node commands'] > 0 or CASES['node sequences'] == 0
    assert CASES['law commands'] > 0 or CASES['checked commands'] == 0
    assert CASES['core commands'] > 0 or CASES['sequences'] == 0
