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
Probe of law ``cg_compensated`` (issue 14): each test is one finding or one claim checked.

Findings (the tests fail on the code before the fix): the timer re-evaluating the same
measurement restarted the law; a lost ``road_curvature`` stayed in the law's preview;
the node gave the law no preview unless ``use_curvature_preview`` was set. Claims that
held are checked against values worked out independently (by hand from the
single-track equations, Fiala's force by root finding).
"""

import dataclasses
import math

from lookahead_control.core.control_law import LateralState
from lookahead_control.core.controller import SteeringController
from lookahead_control.core.lane_keeping import (CgCompensatedLaw, LaneKeepingParams,
                                                 steady_relative_yaw)
from lookahead_control.core.laws import Preview
from lookahead_control.core.params import ControllerParams, VehicleParams
from lookahead_control.core.safety import SafetyParams
from lookahead_control.core.samples import (CurvatureSample, LateralErrorSample,
                                            VelocitySample, YawSample)
from lookahead_control.ros import conversions as conv
import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.time import Time

VEHICLE = VehicleParams()
MS = 1_000_000
GRAVITY = 9.81
# the law on its raw inputs: these tests check its integral and restarts to the digit
RAW = LaneKeepingParams(state_filter='none')
NO_LEARNING = LaneKeepingParams(integral_gain=0.0, compliance_time_constant=0.0,
                                state_filter='none')


def _core(law='cg_compensated', use_preview=False, lane_keeping=RAW):
    return SteeringController(VEHICLE, ControllerParams(), 'zero', use_preview,
                              SafetyParams(), law, lane_keeping=lane_keeping)


def _feed(core, stamp, y=0.1, rho=-1 / 400, slope=0.0, curvature=True):
    samples = [('yaw', YawSample(stamp, 0.0, 0.0, 0.0)),
               ('velocity', VelocitySample(stamp, 30.0, 0.0)),
               ('road_curvature', CurvatureSample(stamp, rho, slope)),
               ('lateral_error', LateralErrorSample(stamp, 0.0, y))]
    for name, sample in samples:
        if name != 'road_curvature' or curvature:
            assert core.accept(name, sample, stamp) is None


def test_timer_faster_than_the_measurements_does_not_restart_the_law():
    # timer mode at 100 Hz, lateral error at 50 Hz: every other step sees the same
    # stamp (dt = 0). Old code: dt = 0 was a time jump, the integral and the estimate
    # restarted at every second step (integral 0 after it, 102 resets in 2 s).
    core = _core()
    for k in range(100):
        stamp = (1000 + 20 * k) * MS
        _feed(core, stamp)
        first = core.compute(stamp)
        after_first = core.law.integral
        second = core.compute(stamp + 10 * MS)
        assert core.law.integral == after_first
        assert second.law.steering == first.law.steering
    assert core.law.integral == pytest.approx(0.3 * 0.1 * 99 * 0.02)
    assert core.law.resets == 1


def test_same_instant_again_advances_nothing():
    law = CgCompensatedLaw(VEHICLE, ControllerParams(), RAW)
    s = LateralState(0.2, 0.01, 0.3, 0.02, 30.0, 0.0, -0.005, 0.0)
    for _ in range(50):
        law.step(s, None, 0.01)
    kept = (law.integral, law.compliance(), law.estimator.filtered)
    again = law.step(s, None, 0.0)
    assert (law.integral, law.compliance(), law.estimator.filtered) == kept
    assert again.steering == law.step(s, None, 0.0).steering
    law.step(s, None, -0.01)                       # going back is still a time jump
    assert law.integral == 0.0 and law.estimator.energy == 0.0 and law.resets == 1


@pytest.mark.parametrize('law', ['cg_compensated', 'pure_pursuit'])
def test_lost_curvature_leaves_no_trace_in_the_preview(law):
    # docs/safety.md: a lost road_curvature means curvature 0 (no feed-forward). Old
    # code: the state's rho was 0 but the preview kept the last curvature, so
    # cg_compensated still fed R = 100 m forward (f_v = 9, 0.09 rad on a straight
    # state), pure pursuit steered 0.017 rad. (dev-rho: cg_compensated now estimates a
    # lost curvature, here the straight the yaw rate 0 says, and blends the switch-over
    # out over lane_keeping.curvature_blend: 0 here to see the estimate at once.)
    core = _core(law, lane_keeping=dataclasses.replace(NO_LEARNING, curvature_blend=0.0))
    for k in range(10):
        _feed(core, (1000 + 10 * k) * MS, y=0.0, rho=-0.01)
        core.compute((1000 + 10 * k) * MS)
    for k in range(10, 60):
        stamp = (1000 + 10 * k) * MS
        _feed(core, stamp, y=0.0, rho=-0.01, curvature=False)
        command = core.compute(stamp)
    assert core.curvature_lost(1590 * MS)
    assert core.preview(1590 * MS).curvatures.tolist() == [0.0]
    if law == 'cg_compensated':
        assert core.law.curvature_estimated()
        assert abs(command.law.steering) < 1e-3 and abs(command.law.f_v) < 0.05
    else:
        assert command.law.steering == 0.0
        assert command.law.f_v == 0.0


def test_node_gives_the_law_its_preview_without_use_curvature_preview():
    # lane_keeping.feedforward_preview looks 0.07 s ahead; the node reduced the
    # polygon to the curvature at the CG unless use_curvature_preview was set (a
    # paper-law switch, false by default): S1 / S2 / S3 at 37 m/s on the nonlinear
    # plant with 20 ms delay and noise gave 26.8 / 18.0 / 37.5 cm instead of the
    # documented 7.1 / 4.6 / 8.3. Now the law's own settings decide.
    outputs = []
    for use_preview in (False, True):
        core = _core(use_preview=use_preview, lane_keeping=NO_LEARNING)
        _feed(core, 1000 * MS, rho=-0.001, slope=-1e-4)
        outputs.append(core.compute(1000 * MS).law)
    assert outputs[0].f_v == outputs[1].f_v
    assert outputs[0].steering == outputs[1].steering
    core = _core(use_preview=False, lane_keeping=NO_LEARNING)
    _feed(core, 1000 * MS, rho=-0.001, slope=-1e-4)
    assert core.preview().at(10.0) == pytest.approx(-0.002)


def test_paper_law_still_ignores_the_preview_without_the_switch():
    outputs = []
    for slope in (0.0, -1e-4):
        core = _core('paper', use_preview=False)
        _feed(core, 1000 * MS, rho=-0.001, slope=slope)
        outputs.append(core.compute(1000 * MS).law.steering)
    assert outputs[0] == outputs[1]


def test_steady_relative_yaw_by_hand_from_the_axle_forces():
    # steady turn, CG on the arc: r = v rho, F_r = m a_y l_1 / L, alpha_r = F_r / C_r,
    # v_y = l_2 r - v alpha_r, and y_cg' = v_y + v eps_r = 0
    v, rho = 37.0, -1 / 400
    a_y, r = v * v * rho, v * rho
    alpha_r = VEHICLE.mass * a_y * VEHICLE.l1 / VEHICLE.wheelbase / VEHICLE.c_r
    eps = -(VEHICLE.l2 * r - v * alpha_r) / v
    assert steady_relative_yaw(VEHICLE, v, rho) == pytest.approx(eps, rel=1e-12)


def _fiala_rear_slip(force, limit):
    # rear slip (tan) of the plant's Fiala axle (sim_plant.vehicle_model) carrying
    # ``force``, by bisection on C z - C^2 |z| z / (3 F_max) + C^3 z^3 / (27 F_max^2)
    c = VEHICLE.c_r

    def f(z):
        return c * z - c * c * abs(z) * z / (3 * limit) + c ** 3 * z ** 3 / (27 * limit ** 2)
    lo, hi = 0.0, 3 * limit / c
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(mid) < abs(force) else (lo, mid)
    return math.copysign(0.5 * (lo + hi), force)


def test_compliance_estimate_on_a_fiala_steady_turn_matches_the_hand_value():
    # 37 m/s on R = 400 m (0.35 g), friction 1: the Fiala rear axle's secant compliance
    # is 1.146 eta and eps_ss 3.8 mrad off the model's (docs/lane_keeping.md); the
    # estimate settles at its prior-weighted value (c a^2 + p^2 eta) / (a^2 + p^2)
    v, rho = 37.0, -1 / 400
    a_y, r = v * v * rho, v * rho
    force = VEHICLE.mass * a_y * VEHICLE.l1 / VEHICLE.wheelbase
    limit = VEHICLE.mass * GRAVITY / VEHICLE.wheelbase * VEHICLE.l1
    alpha_r = _fiala_rear_slip(force, limit)
    secant = alpha_r / a_y
    assert secant / VEHICLE.eta == pytest.approx(1.146, abs=1e-3)
    v_y = VEHICLE.l2 * r - v * alpha_r
    eps = -v_y / v
    assert (eps - steady_relative_yaw(VEHICLE, v, rho)) * 1e3 == pytest.approx(-3.8, abs=0.01)
    law = CgCompensatedLaw(VEHICLE, ControllerParams(), RAW)
    turn = LateralState(0.0, eps, v_y, r, v, 0.0, rho, 0.0)
    for k in range(1000):
        out = law.step(turn, None, 0.0 if k == 0 else 0.01)
    # the relative yaw the law's reference asks for is the Fiala plant's (the model's
    # is 3.8 mrad off); with the prior the estimate settles at (c a^2 + p^2 eta) / (a^2
    # + p^2): 0.08 mrad off
    assert abs(out.y_ref / out.d_v - eps) < 1e-4
    prior = LaneKeepingParams().compliance_prior ** 2
    expected = (secant * a_y ** 2 + prior * VEHICLE.eta) / (a_y ** 2 + prior)
    assert abs(steady_relative_yaw(VEHICLE, v, rho, expected) - eps) < 1e-4


def test_float_and_one_element_batch_agree_bit_for_bit():
    settings = LaneKeepingParams(reference_preview=0.3, rate_feedforward=True)
    single = CgCompensatedLaw(VEHICLE, ControllerParams(), settings)
    batch = CgCompensatedLaw(VEHICLE, ControllerParams(), settings)
    rng = np.random.default_rng(1)
    distances = np.array([0.0, 10.0, 30.0, 60.0])
    for k in range(1500):
        t = 0.01 * k
        rho = -1 / 400 * min(1.0, max(0.0, (t - 3.0) / 3.0))
        values = [0.05 * math.sin(t) + 0.03 * rng.normal(), 0.01 * math.cos(t),
                  0.1 * math.sin(2 * t), 30 * rho + 0.01 * rng.normal(),
                  30 + 5 * math.sin(0.1 * t), 0.5 * math.cos(0.1 * t), rho, 1e-3 * rng.normal()]
        curvatures = rho * np.array([1.0, 1.1, 1.2, 0.5])
        dt = 0.0 if k == 0 else (1.0 if k == 700 else (0.0 if k == 900 else 0.01))
        a = single.step(LateralState(*values), Preview(distances, curvatures), dt)
        b = batch.step(LateralState(*(np.array([x]) for x in values)),
                       Preview(distances, curvatures.reshape(-1, 1)), dt)
        for name in a._fields:
            assert np.asarray(getattr(b, name)).shape == (1,)
            assert float(getattr(a, name)) == float(getattr(b, name)[0]), (k, name)
    assert single.integral == batch.integral[0]


# -- the node (private context, fake sim clock, callbacks called directly) ---------------

S = 1_000_000_000


def _node(context, *overrides):
    from lookahead_control.ros.controller_node import ControllerNode
    node = ControllerNode(context=context, parameter_overrides=[
        Parameter('use_sim_time', value=True), Parameter('law', value='cg_compensated'),
        Parameter('lane_keeping.state_filter', value='none'), *overrides])
    node.trigger_configure()
    node.trigger_activate()
    return node


def _send(node, stamp, y=0.3, rho=-0.0025):
    node.get_clock().set_ros_time_override(Time(nanoseconds=stamp))
    node.on_yaw(conv.to_yaw(stamp, 'base_link', 0.0, 0.0, 0.0))
    node.on_velocity(conv.to_velocity(stamp, 'base_link', 30.0, 0.0, 0.0))
    node.on_curvature(conv.to_curvature(stamp, 'base_link', [(0.0, rho), (5.0, rho)]))
    node.on_lateral_error(conv.to_lateral_error(stamp, 'base_link', 0.0, y))
    return node.core.last


def test_an_unrelated_parameter_change_keeps_the_integral(context):
    # old code: any parameter set rebuilt the law, so raising a diagnostics threshold
    # threw away the integral (here 0.3 m of reference shift) and the estimate
    node = _node(context)
    try:
        stamp = 100 * S
        for _ in range(200):
            stamp += 10 * MS
            _send(node, stamp)
        law, integral = node.core.law, node.core.law.integral
        assert integral > 0.1
        assert node.set_parameters([Parameter('safety.latency_warn', value=0.08)])[0].successful
        stamp += 10 * MS
        _send(node, stamp)
        assert node.core.law is law and law.integral > integral
        # a setting of the law itself takes effect at once, from a fresh law
        assert node.set_parameters([Parameter('lane_keeping.integral_gain',
                                              value=0.6)])[0].successful
        assert node.core.law is not law and node.core.law.settings.integral_gain == 0.6
    finally:
        node.destroy_node()


def test_a_reference_the_law_cannot_use_is_refused_with_one_line(context):
    # old code: the on-set check passed, the post-set callback raised ParameterError
    # out of set_parameters (in a running node: out of the parameter service), and the
    # parameter stayed set while the old law ran on
    node = _node(context)
    try:
        result = node.set_parameters([Parameter('controller.reference',
                                                value='arc_exact')])[0]
        assert not result.successful
        assert 'controller.reference' in result.reason and '\n' not in result.reason
        assert node.get_parameter('controller.reference').value == 'lane_tangent'
        assert node.set_parameters([Parameter('law', value='paper')])[0].successful
        assert node.set_parameters([Parameter('controller.reference',
                                              value='arc_exact')])[0].successful
        result = node.set_parameters([Parameter('law', value='cg_compensated')])[0]
        assert not result.successful and 'cg_compensated' in result.reason
        assert node.core.law_name == 'paper'
    finally:
        node.destroy_node()


def test_switching_laws_while_active_stays_within_the_rate_limit(context):
    node = _node(context)
    try:
        stamp = 100 * S
        for _ in range(100):
            stamp += 10 * MS
            last = _send(node, stamp).steering
        for target in ('paper', 'cg_compensated', 'stanley', 'cg_compensated'):
            assert node.set_parameters([Parameter('law', value=target)])[0].successful
            for _ in range(30):
                stamp += 10 * MS
                command = _send(node, stamp)
                assert abs(command.steering - last) <= 5.0 * 0.01 + 1e-12
                assert math.isfinite(command.steering) and abs(command.steering) <= 0.6
                last = command.steering
            assert node.core.law_name == target
    finally:
        node.destroy_node()


def test_a_bad_input_in_a_batch_run_restarts_it_as_one_run_restarts():
    # old code: after a NaN input one run restarts its estimator filters at the next
    # sample (reset), a batch's run restarted them at 0: a transient in the regressor
    # (compliance 0.0072 -> 0.0040 s^2/m) and up to 8 mrad of different steering for
    # the rest of the run (299 of 300 steps differed)
    rho, v = -1 / 400, 30.0
    one, batch, clean = (CgCompensatedLaw(VEHICLE, ControllerParams()) for _ in range(3))
    for k in range(400):
        y = math.nan if k == 200 else 0.02
        values = [y, -0.015, 0.3, v * rho, v, 0.0, rho, 0.0]
        dt = 0.0 if k == 0 else 0.01
        a = one.step(LateralState(*values), None, dt)
        pair = LateralState(*(np.array([x, 0.02 if i == 0 else x])
                              for i, x in enumerate(values)))
        b = batch.step(pair, None, dt)
        c = clean.step(LateralState(0.02, *values[1:]), None, dt)
        if k == 200:
            assert math.isnan(a.steering) and math.isnan(b.steering[0])
        else:
            assert b.steering[0] == a.steering, k
        assert b.steering[1] == c.steering, k
    assert batch.compliance()[0] == one.compliance()


def test_params_file_has_every_lane_keeping_parameter_at_its_default():
    # docs/lane_keeping.md sends the user to the lane_keeping.* parameters; the
    # shipped params file had none of them (and did not list cg_compensated as a law)
    import yaml
    from lookahead_control.core.param_schema import LANE_KEEPING_SPECS
    from pathlib import Path
    document = yaml.safe_load((Path(__file__).resolve().parents[1] / 'config'
                               / 'controller.yaml').read_text())['/**']['ros__parameters']
    for spec in LANE_KEEPING_SPECS:
        group, name = spec.name.split('.')
        assert document[group][name] == spec.default, spec.name
        assert type(document[group][name]) is type(spec.default), spec.name


def test_timer_mode_node_integrates_between_measurements(context):
    # the node in timer mode at 100 Hz with a 50 Hz lateral error (old code: the
    # integral restarted at every tick that saw no new measurement: 0 after 2 s)
    node = _node(context, Parameter('mode', value='timer'))
    try:
        stamp = 100 * S
        for _ in range(100):
            stamp += 20 * MS
            _send(node, stamp)
            node.on_timer()
            node.get_clock().set_ros_time_override(Time(nanoseconds=stamp + 10 * MS))
            node.on_timer()
        assert node.core.law.integral == pytest.approx(0.3 * 0.3 * 99 * 0.02)
    finally:
        node.destroy_node()


def test_integral_is_frozen_while_the_safety_layer_cuts_the_command():
    # at 37 m/s the node's angle limit is atan(30 m/s^2 L / v^2) = 0.059 rad, far below
    # lane_keeping.steering_limit (0.5 rad): old code integrated on while the command
    # was cut (1.5 m off for 1 s: 0.45 m of the 0.5 m clamp, wound up). (The demand band
    # off: it holds the law's command at 74 mrad, and the cut is what is tested.)
    def run(y):
        core = _core(lane_keeping=dataclasses.replace(RAW, demand_limit=0.0))
        for k in range(100):
            stamp = (1000 + 10 * k) * MS
            for name, sample in (('yaw', YawSample(stamp, 0.0, 0.0, 0.0)),
                                 ('velocity', VelocitySample(stamp, 37.0, 0.0)),
                                 ('lateral_error', LateralErrorSample(stamp, 0.0, y))):
                assert core.accept(name, sample, stamp) is None
            command = core.compute(stamp)
        return core, command
    core, command = run(3.0)
    assert command.saturated and abs(float(command.law.steering)) > 0.1
    assert core.law.integral == 0.0
    core, command = run(0.3)                  # within the limits: integrates as before
    assert not command.saturated
    assert core.law.integral == pytest.approx(0.3 * 0.3 * 0.99)


def test_an_integral_at_its_clamp_feeds_no_rate_forward():
    # old code: the integral's rate k_i y_cg entered y_ref' also while the clamp held
    # the integral still: with integral_limit 0 the law steered 8.6 % harder on y_cg
    # (-4.14 against -3.82 mrad at 10 cm, 37 m/s) than with integral_gain 0
    s = LateralState(0.1, 0.0, 0.0, 0.0, 37.0, 0.0, 0.0, 0.0)
    outputs = []
    for settings in (LaneKeepingParams(integral_gain=0.0, state_filter='none'),
                     LaneKeepingParams(integral_limit=0.0, state_filter='none')):
        law = CgCompensatedLaw(VEHICLE, ControllerParams(), settings)
        for k in range(5):
            out = law.step(s, None, 0.0 if k == 0 else 0.01)
        outputs.append(out)
    assert outputs[1].steering == outputs[0].steering
    law = CgCompensatedLaw(VEHICLE, ControllerParams(),
                           LaneKeepingParams(integral_limit=0.2, state_filter='none'))
    for _ in range(2000):       # 0.4 m: inside integral_band (0.5 m), the clamp holds it
        law.step(LateralState(0.4, 0.0, 0.0, 0.0, 30.0, 0.0, 0.0, 0.0), None, 0.01)
    held = law.integral
    assert held == 0.2
    out = law.step(LateralState(0.4, 0.0, 0.0, 0.0, 30.0, 0.0, 0.0, 0.0), None, 0.01)
    assert law.integral == held and out.y_ref == -held
    law.step(LateralState(-0.4, 0.0, 0.0, 0.0, 30.0, 0.0, 0.0, 0.0), None, 0.01)
    assert law.integral == pytest.approx(held - 0.3 * 0.4 * 0.01)  # back inside: moves


def test_slow_lateral_errors_restart_the_law_and_diagnostics_say_so(context):
    # a lateral error at 2 Hz (0.5 s apart, max_gap 0.25 s) restarted the law at every
    # message, silently: /diagnostics said ok while the integral never acted
    from diagnostic_msgs.msg import DiagnosticStatus
    node = _node(context)
    try:
        stamp = 100 * S
        for _ in range(50):             # 100 Hz: no restart
            stamp += 10 * MS
            _send(node, stamp)
        node.diagnostics()
        assert node.core.law_restarts == 0 and node.core.law.integral > 0.0
        for _ in range(5):              # 2 Hz
            stamp += 500 * MS
            _send(node, stamp)
        status = node.diagnostics()
        assert node.core.law_restarts == 5 and node.core.law.integral == 0.0
        assert status.level == DiagnosticStatus.WARN
        assert 'law restarts: 5' in status.message and 'max_gap 0.25 s: 5' in status.message
        assert 'non-finite' not in status.message
        values = {v.key: v.value for v in status.values}
        assert values['law_restarts'] == '5' and values['law_restarts_gap'] == '5'
        stamp += 10 * MS
        _send(node, stamp)
        assert 'law restarts' not in node.diagnostics().message     # since the last report
    finally:
        node.destroy_node()


def test_a_law_restart_on_a_non_finite_output_is_reported_as_such(context, monkeypatch):
    # probe15: a restart because the law's output was not finite was counted, but
    # /diagnostics explained every restart as a lateral-error gap beyond max_gap; the
    # scalar path also left the 'cut' flag of the failed step in place
    import lookahead_control.core.lane_keeping as lane_keeping
    from diagnostic_msgs.msg import DiagnosticStatus
    real = lane_keeping.cg_compensated_law
    broken = {'on': False}

    def law(*args, **kwargs):
        out = real(*args, **kwargs)
        return out._replace(steering=math.nan) if broken['on'] else out

    monkeypatch.setattr(lane_keeping, 'cg_compensated_law', law)
    node = _node(context)
    try:
        stamp = 100 * S
        for _ in range(50):
            stamp += 10 * MS
            _send(node, stamp)
        node.diagnostics()
        assert node.core.law.integral > 0.0
        broken['on'] = True
        stamp += 10 * MS
        command = _send(node, stamp)
        assert math.isfinite(command.steering)
        broken['on'] = False
        status = node.diagnostics()
        assert node.core.law_restarts == 1 and node.core.law.integral == 0.0
        assert status.level == DiagnosticStatus.WARN
        assert 'law restarts: 1 (a non-finite law output: 1;' in status.message
        assert 'max_gap' not in status.message
        values = {v.key: v.value for v in status.values}
        assert values['law_restarts_non_finite'] == '1' and 'law_restarts_gap' not in values
    finally:
        node.destroy_node()


def test_a_polygon_stamped_apart_from_the_lateral_error_is_read_at_its_time():
    # dev-probe117: a lane camera's lateral error is 50-120 ms old when it arrives, a
    # map's polygon is of now; the polygon's distances are from the CG at its own stamp.
    # The delay-aware law predicts from the lateral error's stamp, and it read the road
    # at the polygon's own time (a camera 80 ms late beside a fresh map, 37 m/s: S1 /
    # S2 15.5 / 20.0 cm noise-free); now moved by v_x times the polygon's age
    from lookahead_control.core.samples import curvature_from_points
    polygon = ((0.0, 0.0), (5.0, 0.01), (10.0, 0.01), (20.0, 0.0))

    def read(core, age_ns, points=polygon):
        core.reset()
        core.accept('velocity', VelocitySample(1_000_000_000, 30.0, 0.0))
        core.accept('road_curvature', curvature_from_points(1_000_000_000 - age_ns, points))
        core.accept('yaw', YawSample(1_000_000_000, 0.0, 0.0, 0.0))
        core.accept('lateral_error', LateralErrorSample(1_000_000_000, 0.0, 0.1))
        state = core.state()
        return state.rho, state.rho_rate, core.preview().distances.tolist()

    predicting = _core(use_preview=True, lane_keeping=LaneKeepingParams(
        delay_prediction=True, filter_delay=0.1))
    for age, at, rho, slope in ((100_000_000, 3.0, 0.006, 0.002),     # 0.1 s older
                                (0, 0.0, 0.0, 0.002),                 # same stamp
                                (-100_000_000, -3.0, 0.0, 0.002),     # 0.1 s newer
                                (-900_000_000, -6.0, 0.0, 0.002)):    # beyond 0.2 s
        got_rho, got_rate, distances = read(predicting, age)
        assert got_rho == pytest.approx(rho, abs=1e-15)
        assert got_rate == pytest.approx(30.0 * slope, abs=1e-15)
        assert distances == pytest.approx([x - at for x, _ in polygon])
    # a polygon of one point is a curvature held ahead: as it is
    assert read(predicting, 100_000_000, ((0.0, 0.004),))[0] == 0.004
    # without the prediction the law takes its state for the present: the polygon is
    # read where the car was at the yaw sample's stamp (dev-sc53, curvature_at_yaw_stamp:
    # 0.1 s on, 3 m), as stamped with curvature_at_yaw_stamp false (before dev-sc53)
    got_rho, got_rate, distances = read(_core(use_preview=True), 100_000_000)
    assert (got_rho, got_rate) == pytest.approx((0.006, 30.0 * 0.002), abs=1e-15)
    assert distances == pytest.approx([x - 3.0 for x, _ in polygon])
    as_stamped = _core(use_preview=True)
    as_stamped.configure(as_stamped.vehicle, as_stamped.params, 'zero', True,
                         curvature_at_yaw_stamp=False)
    assert read(as_stamped, 100_000_000) == (0.0, 30.0 * 0.002, [x for x, _ in polygon])


def test_a_timer_between_a_slower_camera_s_frames_does_not_freeze_the_integral():
    # dev-probe117: a 25 Hz camera under a 100 Hz timer, the yaw rate at 100 Hz; at the
    # ticks between frames the lateral error's stamp stands, the rate limit on the stamps
    # held the command and counted it limited, and the integral froze on it (S2 at 37 m/s
    # on the CommonRoad car: the CG 11.4 cm off for good, the integral 0)
    core = _core()
    limited, sent = 0, None
    for tick in range(400):
        now = 1_000_000_000 + tick * 10 * MS
        r = 0.02 * math.sin(0.3 * tick)
        core.accept('yaw', YawSample(now, 0.0, r, 0.0), now)
        core.accept('velocity', VelocitySample(now, 30.0, 0.0), now)
        if tick % 4 == 0:
            core.accept('lateral_error', LateralErrorSample(now, 0.0, 0.2), now)
        command = core.compute(now)
        limited += command.rate_limited
        if tick % 4:            # the same frame again: held on the stamps, as before
            assert command.steering == sent
        sent = command.steering
    assert limited == 0
    assert core.law.integral == pytest.approx(0.3 * 0.2 * 99 * 0.04, rel=1e-9)
