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

"""Converters without DDS; nodes with a private context, callbacks called directly."""

import math

from lookahead_control.core.control_law import LateralState, steering_law
from lookahead_control.core.params import ControllerParams, VehicleParams
from lookahead_control.ros import conversions as conv
import pytest
import rclpy
from rclpy.context import Context
from rclpy.parameter import Parameter


def test_message_round_trips():
    stamp = 12_345_678_901
    assert conv.stamp_to_ns(conv.ns_to_stamp(stamp)) == stamp
    assert conv.from_lateral_error(conv.to_lateral_error(stamp, 'base_link', 1.96, 0.3)) \
        == (stamp, 1.96, 0.3)
    yaw = conv.from_yaw(conv.to_yaw(stamp, 'base_link', -0.02, 0.1, 0.5))
    assert yaw.stamp_ns == stamp
    assert yaw.relative_yaw == pytest.approx(-0.02, abs=1e-15)
    assert (yaw.yaw_rate, yaw.accel_x) == (0.1, 0.5)
    assert conv.from_velocity(conv.to_velocity(stamp, 'b', 30.0, -0.2, 0.1)) == (
        stamp, 30.0, -0.2)
    assert conv.from_steering(conv.to_steering(stamp, -0.01, 0.2)) == (stamp, -0.01)
    values = conv.from_named_values(conv.to_named_values(stamp, [('a', 1.0), ('b', 2.0)]))
    assert values == {'a': 1.0, 'b': 2.0}


def test_quaternion_yaw_is_rep103():
    for yaw in (-3.0, -0.5, 0.0, 0.01, 1.5):
        assert conv.quaternion_to_yaw(*conv.yaw_to_quaternion(yaw)) == pytest.approx(yaw)


def test_curvature_preview_interpolates_at_the_cg():
    msg = conv.to_curvature(0, 'b', [(-5.0, 0.0), (5.0, 0.01), (10.0, 0.02)])
    sample = conv.from_curvature(msg)
    assert (sample.rho, sample.slope) == pytest.approx((0.005, 0.001))
    assert conv.from_curvature(conv.to_curvature(0, 'b', [(0.0, -0.0025)])).rho == -0.0025
    assert conv.from_curvature(conv.to_curvature(0, 'b', [])).rho == 0.0


def test_steering_without_the_joint_is_refused():
    msg = conv.to_named_values(0, [('rear_steer', 0.1), ('x', 0.0)])
    assert conv.from_steering(msg) is None


@pytest.fixture
def context():
    ctx = Context()
    rclpy.init(context=ctx)
    yield ctx
    rclpy.try_shutdown(context=ctx)


def _feed(node, stamp, y=0.5, d=1.96, eps=0.01, r=0.02, v_x=25.0, v_y=0.1, rho=-0.0025):
    node.on_yaw(conv.to_yaw(stamp, 'base_link', eps, r, 0.0 - v_y * r))
    node.on_velocity(conv.to_velocity(stamp, 'base_link', v_x, v_y, r))
    node.on_curvature(conv.to_curvature(stamp, 'base_link', [(0.0, rho), (5.0, rho)]))
    node.on_lateral_error(conv.to_lateral_error(stamp, 'base_link', d, y))


def test_controller_node_answers_each_lateral_error(context):
    from lookahead_control.ros.controller_node import ControllerNode
    node = ControllerNode(context=context)
    try:
        node.trigger_configure()
        node.trigger_activate()
        _feed(node, 10_000_000)
        command = node.core.last
        assert command is not None and command.stamp_ns == 10_000_000
        # the same numbers straight into the law: y_cg = 0.5 - 1.96 * 0.01
        expected = steering_law(LateralState(0.5 - 1.96 * 0.01, 0.01, 0.1, 0.02, 25.0, 0.0,
                                             -0.0025, 0.0), VehicleParams(), ControllerParams())
        assert command.steering == pytest.approx(expected.steering, rel=1e-12)
        assert node.published == 1
    finally:
        node.destroy_node()


def test_inactive_controller_publishes_nothing(context):
    from lookahead_control.ros.controller_node import ControllerNode
    node = ControllerNode(context=context)
    try:
        node.trigger_configure()
        _feed(node, 1)
        assert node.published == 0
        node.trigger_activate()
        _feed(node, 2)
        node.trigger_deactivate()
        _feed(node, 3)
        assert node.published == 1
    finally:
        node.destroy_node()


def test_controller_waits_for_inputs(context):
    from lookahead_control.ros.controller_node import ControllerNode
    node = ControllerNode(context=context)
    try:
        node.trigger_configure()
        node.trigger_activate()
        node.on_lateral_error(conv.to_lateral_error(1, 'base_link', 0.0, 0.2))
        assert node.published == 0
        assert node.core.missing() == ['yaw', 'velocity']
    finally:
        node.destroy_node()


def test_matching_stamps_hold_the_answer_until_inputs_catch_up(context):
    from lookahead_control.ros.controller_node import ControllerNode
    node = ControllerNode(context=context, parameter_overrides=[
        Parameter('wait_for_matching_stamps', value=True)])
    try:
        node.trigger_configure()
        node.trigger_activate()
        _feed(node, 100)
        assert node.published == 1
        node.on_lateral_error(conv.to_lateral_error(200, 'base_link', 1.96, 0.4))
        assert node.published == 0 + 1          # yaw, velocity, curvature still at 100
        node.on_yaw(conv.to_yaw(200, 'base_link', 0.01, 0.02, 0.0))
        node.on_velocity(conv.to_velocity(200, 'base_link', 25.0, 0.1, 0.02))
        assert node.published == 1
        node.on_curvature(conv.to_curvature(200, 'base_link', [(0.0, 0.0)]))
        assert node.published == 2 and node.core.last.stamp_ns == 200
    finally:
        node.destroy_node()


def test_parameter_changes_applied_or_refused(context):
    from lookahead_control.ros.controller_node import ControllerNode
    node = ControllerNode(context=context)
    try:
        node.trigger_configure()
        node.trigger_activate()
        refused = node.set_parameters([Parameter('controller.natural_frequency',
                                                 value=-1.0)])[0]
        assert not refused.successful and 'natural_frequency' in refused.reason
        refused = node.set_parameters([Parameter('controller.schedule', value='magic')])[0]
        assert not refused.successful and "'magic'" in refused.reason
        refused = node.set_parameters([Parameter('vehicle.mass', value=float('nan'))])[0]
        assert not refused.successful
        assert node.core.params.schedule == 'paper'
        _feed(node, 1)
        paper = node.core.last.law.d_v
        ok = node.set_parameters([Parameter('controller.schedule', value='fixed')])[0]
        assert ok.successful
        _feed(node, 2)       # applied between two control steps
        assert node.core.params.schedule == 'fixed'
        assert node.core.last.law.d_v == 1.96 != paper
    finally:
        node.destroy_node()


def test_sim_plant_node_publishes_the_contract(context, tmp_path):
    from sim_plant.sim_plant_node import SimPlantNode
    node = SimPlantNode(context=context, parameter_overrides=[
        Parameter('speed', value=20.0)])
    received = {}
    try:
        for name in ('lateral_error', 'yaw', 'velocity', 'road_curvature'):
            pub = getattr(node, {'lateral_error': 'pub_lateral', 'yaw': 'pub_yaw',
                                 'velocity': 'pub_velocity',
                                 'road_curvature': 'pub_curvature'}[name])
            pub.publish = (lambda n: (lambda msg: received.__setitem__(n, msg)))(name)
        node.x = (0.0, 0.3, 0.01, 0.0, 0.0, 0.0)
        stamp = node.publish_measurements()
        assert stamp == 0
        lateral = conv.from_lateral_error(received['lateral_error'])
        assert lateral.distance == 1.96
        assert lateral.value == pytest.approx(0.3 + 1.96 * 0.01)
        assert conv.from_velocity(received['velocity']).v_x == 20.0
        assert conv.from_yaw(received['yaw']).relative_yaw == pytest.approx(0.01)
        # lockstep: an answer with the awaited stamp advances exactly one step
        node.waiting_stamp = 0
        node.on_steering(conv.to_steering(0, -0.01, 0.0))
        assert node.k == 1 and node.command == -0.01
        node.on_steering(conv.to_steering(0, float('nan'), 0.0))
        assert node.rejected == 1 and node.k == 1
        assert math.isclose(node.x[5], -0.01)
    finally:
        node.destroy_node()


def test_sim_plant_starts_once_connected_for_the_settle_time(context, monkeypatch):
    from sim_plant import sim_plant_node
    node = sim_plant_node.SimPlantNode(context=context, parameter_overrides=[
        Parameter('settle', value=0.3)])
    now = [100.0]
    monkeypatch.setattr(sim_plant_node.time, 'monotonic', lambda: now[0])
    sent = []
    node.publish_measurements = lambda: sent.append(node.k) or 0
    link = [True]
    node.connected = lambda: link[0]
    try:
        node.on_poll()                  # connected: the settle time starts
        now[0] += 0.2
        node.on_poll()
        link[0], now[0] = False, now[0] + 0.2
        node.on_poll()                  # the link dropped: it starts again
        link[0], now[0] = True, now[0] + 0.01
        node.on_poll()
        now[0] += 0.29
        node.on_poll()
        assert sent == [] and node.waiting_stamp is None
        now[0] += 0.02
        node.on_poll()                  # 0.31 s connected: step 0 goes out
        assert sent == [0] and node.waiting_stamp == 0
    finally:
        node.destroy_node()


def test_controller_keeps_the_clock_subscription_of_use_sim_time(context):
    # regression: an attribute named like rclpy's Node._subscriptions dropped /clock
    from lookahead_control.ros.controller_node import ControllerNode
    node = ControllerNode(context=context, parameter_overrides=[
        Parameter('use_sim_time', value=True), Parameter('mode', value='timer')])
    try:
        node.trigger_configure()
        topics = {sub.topic_name for sub in node.subscriptions}
        assert {'/clock', '/lateral_error', '/yaw', '/velocity'} <= topics
        assert len(list(node.timers)) == 3      # control, watchdog, diagnostics
    finally:
        node.destroy_node()


def test_bad_inputs_are_refused_counted_and_never_used(context):
    from diagnostic_msgs.msg import DiagnosticStatus
    from lookahead_control.ros.controller_node import ControllerNode
    node = ControllerNode(context=context)
    try:
        node.trigger_configure()
        node.trigger_activate()
        _feed(node, 10_000_000)
        good = node.core.last
        node.on_yaw(conv.to_yaw(20_000_000, 'base_link', float('nan'), 0.0, 0.0))
        node.on_velocity(conv.to_velocity(20_000_000, 'base_link', 1e4, 0.0, 0.0))
        node.on_lateral_error(conv.to_lateral_error(20_000_000, 'map', 1.96, 0.5))
        node.on_lateral_error(conv.to_lateral_error(5_000_000, 'base_link', 1.96, 0.5))
        node.on_lateral_error(conv.to_lateral_error(20_000_000, 'base_link', 1.96,
                                                    float('inf')))
        assert sum(node.core.rejected.values()) == 5
        assert node.core.last is good and node.published == 1
        status = node.diagnostics()
        assert status.level == DiagnosticStatus.WARN and 'rejected: 5' in status.message
        assert node.diagnostics().level == DiagnosticStatus.OK     # nothing new since
    finally:
        node.destroy_node()


def test_stale_inputs_hold_then_ramp_and_resume_without_a_jump(context):
    from diagnostic_msgs.msg import DiagnosticStatus
    from lookahead_control.ros.controller_node import ControllerNode
    node = ControllerNode(context=context, parameter_overrides=[
        Parameter('safety.max_steering_rate', value=0.1)])
    core = node.core
    try:
        node.trigger_configure()
        node.trigger_activate()
        now = node.get_clock().now().nanoseconds
        _feed(node, now)
        start = core.last.steering
        assert start < -0.01
        # 0.3 s without inputs (timeout 0.2 s): hold for 0.5 s, then ramp at 0.1 rad/s
        angles = []
        for k in range(1, 21):
            t = now + int(0.1e9) * k
            if core.stale(t):
                angles.append(core.safe_command(t).steering)
        assert len(angles) == 18 and angles[0] == start     # stale from 0.3 s on
        assert all(a == start for a in angles[:5])
        assert all(0 <= b - a <= 0.1 * 0.1 + 1e-12 for a, b in zip(angles, angles[1:]))
        assert angles[-1] == 0.0 or angles[-1] > start
        node.stale_inputs = ['lateral_error']
        assert node.diagnostics().level == DiagnosticStatus.ERROR
        # inputs return: the rate limit carries the command back, no jump
        t = now + int(2.2e9)
        _feed(node, t)
        assert abs(core.last.steering - angles[-1]) <= 0.1 * 0.2 + 1e-12
    finally:
        node.destroy_node()


def test_now_ns_reads_the_nodes_clock_system_and_simulated(context):
    from lookahead_control.ros.node_main import now_ns
    from rclpy.node import Node
    from rclpy.time import Time
    node = Node('clock_probe', context=context)
    try:
        before = node.get_clock().now().nanoseconds
        read = now_ns(node)
        assert before <= read <= node.get_clock().now().nanoseconds
        node.set_parameters([Parameter('use_sim_time', value=True)])
        clock = node.get_clock()
        assert now_ns(node) == clock.now().nanoseconds == 0      # no /clock yet
        clock.set_ros_time_override(Time(nanoseconds=1_234_567_891))
        assert now_ns(node) == clock.now().nanoseconds == 1_234_567_891
    finally:
        node.destroy_node()
