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


"""The controller node with reference cg_compensated: parameters, law, resets (no DDS)."""

import math

from conftest import feed
from lookahead_control.core.lane_keeping import CgCompensatedLaw, LaneKeepingParams, loop_gains
import pytest
from rclpy.parameter import Parameter

MS = 1_000_000


def _feed(node, stamp, y=0.1, v_x=30.0, rho=-0.0025):
    # straight and level apart from the lateral error (no yaw, no v_y, d = 0)
    feed(node, stamp, y=y, d=0.0, eps=0.0, r=0.0, v_x=v_x, v_y=0.0, rho=rho)


def test_node_selects_the_lane_keeping_law_by_parameter(context):
    from lookahead_control.ros.controller_node import ControllerNode
    node = ControllerNode(context=context, parameter_overrides=[
        Parameter('use_sim_time', value=True), Parameter('law', value='cg_compensated'),
        Parameter('lane_keeping.integral_gain', value=0.5),
        Parameter('lane_keeping.state_filter', value='none')])
    try:
        node.trigger_configure()
        node.trigger_activate()
        law = node.core.law
        assert isinstance(law, CgCompensatedLaw)
        assert law.settings == LaneKeepingParams(integral_gain=0.5, state_filter='none')
        assert law.state_filter is None
        for k in range(11):
            _feed(node, (1000 + 10 * k) * MS)
        assert law.integral == pytest.approx(0.5 * 0.1 * 0.1)
        # a low-speed w_n above natural_frequency is capped (w_n constant), as
        # low_speed_integral_gain is at integral_gain; outside its range it is refused
        taken = node.set_parameters([Parameter('lane_keeping.low_speed_frequency',
                                               value=50.0)])[0]
        assert taken.successful
        assert loop_gains(node.core.law.settings, 5.0) == pytest.approx((49.0, 14.0))
        refused = node.set_parameters([Parameter('lane_keeping.low_speed_frequency',
                                                 value=500.0)])[0]
        assert not refused.successful and 'low_speed_frequency' in refused.reason
        refused = node.set_parameters([Parameter('lane_keeping.max_gap', value=0.0)])[0]
        assert not refused.successful
        # the integral gain's speed schedule: declared with its range, its two speeds
        # checked together (the law keeps running on the old settings)
        for name, low, high in (('integral_speed', 0.01, 100.0),
                                ('low_speed_integral_gain', 0.0, 5.0),
                                ('low_integral_speed', 0.0, 100.0)):
            descriptor = node.describe_parameter(f'lane_keeping.{name}')
            assert descriptor.description and descriptor.floating_point_range
            assert (descriptor.floating_point_range[0].from_value,
                    descriptor.floating_point_range[0].to_value) == (low, high), name
        refused = node.set_parameters([Parameter('lane_keeping.low_integral_speed',
                                                 value=35.0)])[0]
        assert not refused.successful
        assert ('lane_keeping.low_integral_speed = 35.0 m/s is not below '
                'lane_keeping.integral_speed = 30.0 m/s') in refused.reason
        assert node.core.law.settings.low_integral_speed == 15.0
        ok = node.set_parameters_atomically([
            Parameter('lane_keeping.integral_speed', value=40.0),
            Parameter('lane_keeping.low_integral_speed', value=35.0)])
        assert ok.successful
        assert node.core.law.settings.low_integral_speed == 35.0
        ok = node.set_parameters([Parameter('law', value='paper')])[0]
        assert ok.successful
        _feed(node, 1200 * MS)             # applied between two control steps
        assert node.core.law_name == 'paper' and node.core.last.law.y_ref == 0.0
    finally:
        node.destroy_node()


def test_the_applied_parameters_log_names_the_running_law_s_gains():
    # probe20: the log printed the paper law's w_n = 3 while cg_compensated ran (7)
    from lookahead_control.core.lane_keeping import LaneKeepingParams
    from lookahead_control.core.params import ControllerParams
    from lookahead_control.ros.controller_node import applied_summary
    controller, lane_keeping = ControllerParams(), LaneKeepingParams()
    assert controller.natural_frequency != lane_keeping.natural_frequency
    line = applied_summary('cg_compensated', controller, lane_keeping)
    assert f'w_n={lane_keeping.natural_frequency:g}, zeta={lane_keeping.damping_ratio:g}' \
        in line, line
    line = applied_summary('paper', controller, lane_keeping)
    assert f'w_n={controller.natural_frequency:g}, zeta={controller.damping_ratio:g}' in line
    assert 'capped' not in line + applied_summary('cg_compensated', controller, lane_keeping)
    # a low-speed integral gain above integral_gain runs as integral_gain (before: the
    # log said nothing of it, the parameter read 0.5)
    above = LaneKeepingParams(low_speed_integral_gain=0.5)
    assert applied_summary('cg_compensated', controller, above).endswith(
        '; k_i 0.3 1/s at every speed: low_speed_integral_gain is capped at integral_gain')
    assert 'capped' not in applied_summary('paper', controller, above)
    # dev-wnflat: a natural_frequency below a set low-speed w_n (3 rad/s) caps it: w_n 2
    # at every speed, and the line says so; before, the file was refused
    lower = LaneKeepingParams(natural_frequency=2.0, low_speed_frequency=3.0)
    assert loop_gains(lower, 10.0) == loop_gains(lower, 37.0) == pytest.approx((4.0, 4.0))
    assert applied_summary('cg_compensated', controller, lower).endswith(
        '; w_n 2 rad/s at every speed: low_speed_frequency is capped at natural_frequency')
    # dev-approach: the default low-speed w_n is the default natural_frequency (w_n
    # constant): a lowered natural_frequency alone is that constant w_n, not told
    alone = LaneKeepingParams(natural_frequency=2.0)
    assert loop_gains(alone, 10.0) == pytest.approx((4.0, 4.0))
    assert 'capped' not in applied_summary('cg_compensated', controller, alone)
    both = LaneKeepingParams(natural_frequency=2.0, low_speed_frequency=3.0,
                             low_speed_integral_gain=0.5)
    assert applied_summary('cg_compensated', controller, both).endswith(
        'low_speed_frequency is capped at natural_frequency; k_i 0.3 1/s at every speed: '
        'low_speed_integral_gain is capped at integral_gain')


def test_a_force_share_without_the_state_filter_is_told():
    # dev-probe91: side_force (default 1) with state_filter none was accepted and had no
    # effect (its force estimate is the Kalman filter's), with nothing in the log
    from lookahead_control.core.lane_keeping import LaneKeepingParams
    from lookahead_control.core.params import ControllerParams
    from lookahead_control.ros.controller_node import applied_summary
    controller = ControllerParams()
    line = applied_summary('cg_compensated', controller, LaneKeepingParams(state_filter='none'))
    assert line.endswith("; side_force runs as 0: its force estimate is the state filter's "
                         '(state_filter none)'), line
    both = LaneKeepingParams(state_filter='none', force_feedforward=0.5)
    assert applied_summary('cg_compensated', controller, both).endswith(
        '; side_force and force_feedforward run as 0: their force estimates are the state '
        "filter's (state_filter none)")
    alone = LaneKeepingParams(state_filter='none', side_force=0.0, force_feedforward=1.0)
    assert applied_summary('cg_compensated', controller, alone).endswith(
        "; force_feedforward runs as 0: its force estimate is the state filter's "
        '(state_filter none)')
    # nothing to tell: both shares 0, the filter on, or another law
    for quiet, law in ((LaneKeepingParams(state_filter='none', side_force=0.0), 'cg_compensated'),
                       (LaneKeepingParams(force_feedforward=1.0), 'cg_compensated'),
                       (LaneKeepingParams(state_filter='none'), 'paper')):
        assert 'runs as 0' not in applied_summary(law, controller, quiet)


def test_filter_settings_without_the_state_filter_are_told_where_they_act():
    # dev-probe93: with state_filter none the filter_* settings act only on the curvature
    # estimate, which runs while road_curvature is not received; set and untold before
    from lookahead_control.core.lane_keeping import LaneKeepingParams
    from lookahead_control.core.params import ControllerParams
    from lookahead_control.ros.controller_node import applied_summary
    controller = ControllerParams()
    one = LaneKeepingParams(state_filter='none', side_force=0.0, filter_lateral_noise=0.05)
    assert applied_summary('cg_compensated', controller, one).endswith(
        '; filter_lateral_noise acts only on the curvature estimate, which runs while '
        'road_curvature is not received (state_filter none)')
    two = LaneKeepingParams(state_filter='none', side_force=0.0, filter_delay=0.05,
                            filter_curvature_drift=1.0)
    assert applied_summary('cg_compensated', controller, two).endswith(
        '; filter_delay, filter_curvature_drift act only on the curvature estimate, which '
        'runs while road_curvature is not received (state_filter none)')
    for quiet in (LaneKeepingParams(filter_lateral_noise=0.05),       # the filter on
                  LaneKeepingParams(state_filter='none', side_force=0.0)):  # defaults
        assert 'curvature estimate' not in applied_summary('cg_compensated', controller, quiet)


def _active_node_keeping_debug(context):
    """Return an active controller node on sim time and the list its ~/debug goes to."""
    from lookahead_control.ros.controller_node import ControllerNode
    node = ControllerNode(context=context, parameter_overrides=[
        Parameter('use_sim_time', value=True)])
    sent = []
    node.trigger_configure()
    node.trigger_activate()
    node._debug_pub.get_subscription_count = lambda: 1
    node._debug_pub.publish = sent.append
    return node, sent


def test_the_debug_topic_says_when_the_law_runs_on_its_curvature_estimate(context):
    # before, nothing recorded told whether the default law received the curvature or
    # estimated it: a bag holding a curvature the controller never got (remapped) was
    # re-run on it, 20 mrad off, unexplained
    from lookahead_control.ros import conversions as conv
    from rclpy.time import Time
    node, sent = _active_node_keeping_debug(context)
    try:
        assert node.core.law_name == 'cg_compensated'
        for k in range(1, 101):             # 1 s with the curvature, 1 s without
            stamp = k * 10 * MS
            node.get_clock().set_ros_time_override(Time(nanoseconds=stamp))
            node.on_yaw(conv.to_yaw(stamp, 'base_link', 0.01, 0.075, 0.0))
            node.on_velocity(conv.to_velocity(stamp, 'base_link', 30.0, 0.0, 0.075))
            if k <= 50:
                node.on_curvature(conv.to_curvature(stamp, 'base_link',
                                                    [(0.0, 0.0025), (5.0, 0.0025)]))
            node.on_lateral_error(conv.to_lateral_error(stamp, 'base_link', 1.96, 0.05))
        assert len(sent) == 100
        values = [dict(zip(m.name, m.position)) for m in sent]
        flags = [v['curvature_estimated'] for v in values]
        # lost once stamped more than input_timeout (0.2 s) before the lateral error
        assert flags == [0.0] * 70 + [1.0] * 30, flags
        # any law's judgment, for the offline re-run
        assert [v['curvature_received'] for v in values] == [1.0 - f for f in flags]
        assert values[40]['rho_used'] == pytest.approx(0.0025)
        law = node.core.law
        assert values[-1]['compliance_scale'] == pytest.approx(law.compliance() / law.vehicle.eta)
        assert values[-1]['compliance_memory'] == pytest.approx(
            law.estimator.memory() / law.vehicle.eta)
        # and in /diagnostics, for the operator: what the car taught the law
        told = {kv.key: kv.value for kv in node.diagnostics().values}
        assert told['compliance scale [x model]'] == f"{values[-1]['compliance_scale']:.3f}"
        assert told['compliance memory [x model]'] == f"{values[-1]['compliance_memory']:.3f}"
        # the memory learns only while the tyres are loaded: it has moved off 1, less
        # than the estimate, inside the estimate's range
        assert 1 / 3 < values[-1]['compliance_scale'] < values[-1]['compliance_memory'] < 1.0
        assert values[-1]['integral'] == node.core.law.integral != 0.0
        assert all(math.isfinite(x) for v in values for x in v.values())
        # the paper law has no such state: its debug message is as before
        assert node.set_parameters([Parameter('law', value='paper')])[0].successful
        node.on_lateral_error(conv.to_lateral_error(101 * 10 * MS, 'base_link', 1.96, 0.05))
        assert 'curvature_estimated' not in sent[-1].name and 'd_v' in sent[-1].name
        assert not any(kv.key.startswith('compliance') for kv in node.diagnostics().values)
        assert dict(zip(sent[-1].name, sent[-1].position))['curvature_received'] == 0.0
    finally:
        node.destroy_node()


def test_a_capped_low_speed_w_n_is_told_at_startup(context):
    # dev-probe33: a params file lowering natural_frequency below the low-speed w_n (or
    # raising low_speed_frequency above it) ran capped with nothing in the startup log;
    # only a run-time set logged the note. The configure line now carries it
    from lookahead_control.ros.controller_node import ControllerNode
    for overrides, note in (
            ([Parameter('lane_keeping.natural_frequency', value=2.0),
              Parameter('lane_keeping.low_speed_frequency', value=3.0)],
             'w_n 2 rad/s at every speed: low_speed_frequency is capped at natural_frequency'),
            ([Parameter('lane_keeping.natural_frequency', value=2.0)], None),
            ([Parameter('lane_keeping.low_speed_frequency', value=9.0)],
             'w_n 7 rad/s at every speed: low_speed_frequency is capped at natural_frequency'),
            ([Parameter('lane_keeping.state_filter', value='none')],
             "side_force runs as 0: its force estimate is the state filter's "
             '(state_filter none)'),
            ([], None)):
        node = ControllerNode(context=context, parameter_overrides=[
            Parameter('use_sim_time', value=True), *overrides])
        logged = []
        try:
            logger = node.get_logger()
            info = logger.info
            logger.info = lambda text, **kw: (logged.append(text), info(text, **kw))[1]
            node.trigger_configure()
            line = next(text for text in logged if text.startswith('configured: '))
            if note is None:
                assert 'capped' not in line and 'runs as 0' not in line, line
            else:
                assert line.endswith(f'; {note}'), line
        finally:
            node.destroy_node()


def test_the_law_s_own_clips_are_counted_and_told(context):
    # dev-course: with the demand band on by default, a run where the law's command was
    # held at the band (or the CG's offset clipped to the approach heading) said so
    # nowhere: now ~/debug carries both flags per answer and /diagnostics counts them
    # (told at OK: they are the law's design, not a fault)
    from lookahead_control.ros import conversions as conv
    from rclpy.time import Time
    node, sent = _active_node_keeping_debug(context)
    try:

        def answer(stamp: int, y_cg: float, eps_r: float) -> None:
            node.get_clock().set_ros_time_override(Time(nanoseconds=stamp))
            node.on_yaw(conv.to_yaw(stamp, 'base_link', eps_r, 0.0, 0.0))
            node.on_velocity(conv.to_velocity(stamp, 'base_link', 30.0, 0.0, 0.0))
            node.on_curvature(conv.to_curvature(stamp, 'base_link', [(0.0, 0.0), (5.0, 0.0)]))
            node.on_lateral_error(conv.to_lateral_error(stamp, 'base_link', 1.96,
                                                        y_cg + 1.96 * eps_r))
        # on the lane: neither clip
        for k in range(1, 11):
            answer(k * 10 * MS, 0.0, 0.0)
        quiet = node.diagnostics()
        assert 'capped' not in quiet.message and 'clipped' not in quiet.message
        # 4.5 m off (the safety layer refuses lateral errors beyond 5 m), heading 0.1 rad
        # away at 30 m/s: beyond the approach clip (0.1 rad: 4.1 m at 30 m/s) and the
        # loop asks for more than the band's -88 mrad
        for k in range(11, 71):
            answer(k * 10 * MS, 4.5, 0.1)
        values = [dict(zip(m.name, m.position)) for m in sent]
        assert [v['demand_capped'] for v in values[:10]] == [0.0] * 10
        assert [v['approach_clipped'] for v in values[:10]] == [0.0] * 10
        assert values[-1]['demand_capped'] == 1.0
        assert values[-1]['approach_clipped'] == 1.0
        capped = sum(v['demand_capped'] for v in values)
        clipped = sum(v['approach_clipped'] for v in values)
        status = node.diagnostics()
        assert f'demand capped: {capped:.0f} (lane_keeping.demand_limit)' in status.message
        assert (f'approach clipped: {clipped:.0f} (lane_keeping.approach_heading)'
                in status.message)
        counts = {kv.key: kv.value for kv in status.values}
        assert counts['demand_capped'] == f'{capped:.0f}'
        # counted since the last report: the next one, with no answer between, is quiet
        again = node.diagnostics()
        assert 'demand capped' not in again.message and 'approach' not in again.message
        assert {kv.key: kv.value for kv in again.values}['demand_capped'] == f'{capped:.0f}'
    finally:
        node.destroy_node()
