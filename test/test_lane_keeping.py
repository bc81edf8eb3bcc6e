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


"""The CG-compensated look-ahead law and its stability checks."""

from dataclasses import replace
import math
import re

from lookahead_control.core import lane_keeping_stability as stability
from lookahead_control.core.control_law import LateralState, steering_law
from lookahead_control.core.controller import SteeringController
from lookahead_control.core.estimator import brush_shape, GRAVITY
from lookahead_control.core.lane_keeping import (cg_compensated_law, CgCompensatedLaw,
                                                 integral_gain_at, LaneKeepingParams,
                                                 loop_gains, preview_curvature,
                                                 steady_relative_yaw)
from lookahead_control.core.laws import Preview
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
from lookahead_control.core.safety import SafetyParams
from lookahead_control.core.samples import (CurvatureSample, LateralErrorSample,
                                            VelocitySample, YawSample)
from lookahead_control.core.schedule import look_ahead
from lookahead_control.core.zero_dynamics import system_matrix
import numpy as np
import pytest
from scipy.linalg import solve_continuous_lyapunov
from sim_plant.closed_loop_sim import run
from sim_plant.scenario import paper_scenario
from sim_plant.vehicle_model import PlantParams

VEHICLE = VehicleParams()
CONTROLLER = ControllerParams()
EMPTY = Preview(np.zeros(0), np.zeros(0))
#: the w_n schedule that was the default until dev-approach (3 rad/s at and below 90 / 7
#: m/s, 7 at and above 30, linear in the speed between; the default is now w_n 7 at every
#: speed), named where a test is about it; the certificate's sharp, robust and scheduled
#: Q were searched for it
W_N_SCHEDULE = LaneKeepingParams(frequency_speed=30.0, low_speed_frequency=3.0)
#: w_n 7 reached at 20 m/s (an option of dev-wnflat: without the approach heading it
#: lost the lane from 2.5-3 m off at 15-25 m/s on the CommonRoad car)
WN20 = LaneKeepingParams(frequency_speed=20.0, low_speed_frequency=3.0)
#: the k_i speed schedule (0.05 1/s at and below 15 m/s; the default is k_i constant),
#: with the w_n schedule it was searched for
SCHEDULED = LaneKeepingParams(low_speed_integral_gain=0.05, low_speed_frequency=3.0)


def state(y_cg=0.0, eps_r=0.0, v_y=0.0, r=0.0, v_x=37.0, a_x=0.0, rho=0.0, rho_rate=0.0):
    return LateralState(y_cg, eps_r, v_y, r, v_x, a_x, rho, rho_rate)


def test_loop_gains_scheduled_on_speed():
    # frequency_speed 20: w_n 7 at and above 20 m/s, 7 v / 20 below, not below 3
    assert loop_gains(WN20, 20.0) == loop_gains(WN20, 37.0) == pytest.approx((49.0, 14.0))
    assert loop_gains(WN20, 10.0) == pytest.approx((3.5 ** 2, 7.0))
    assert loop_gains(WN20, 5.0) == pytest.approx((9.0, 6.0))
    # the default since dev-approach: w_n 5 up to 30 * 5 / 7 m/s, 7 from 30 m/s
    assert loop_gains(LaneKeepingParams(), 5.0) == pytest.approx((25.0, 10.0))
    assert loop_gains(LaneKeepingParams(), 25.0) == pytest.approx(((7 * 25 / 30) ** 2,
                                                                  2 * 7 * 25 / 30))
    # a low-speed w_n above natural_frequency is capped: w_n constant
    assert loop_gains(LaneKeepingParams(low_speed_frequency=9.0), 5.0) == pytest.approx(
        (49.0, 14.0))
    settings = W_N_SCHEDULE
    assert loop_gains(settings, 37.0) == pytest.approx((49.0, 14.0))
    assert loop_gains(settings, 15.0) == pytest.approx((3.5 ** 2, 7.0))
    assert loop_gains(settings, 5.0) == pytest.approx((9.0, 6.0))
    assert loop_gains(settings, np.array([5.0, 37.0]))[0] == pytest.approx([9.0, 49.0])


def test_integral_gain_scheduled_on_speed():
    # k_lo = 0.05 at and below 15 m/s, 0.3 at and above 30, linear between:
    # 0.05 + 0.25 (v - 15) / 15
    settings = LaneKeepingParams(integral_gain=0.3, integral_speed=30.0,
                                 low_speed_integral_gain=0.05, low_integral_speed=15.0)
    for v, k_i in ((3.0, 0.05), (10.0, 0.05), (15.0, 0.05), (18.0, 0.1),
                   (20.0, 0.05 + 0.25 / 3), (22.5, 0.175), (27.0, 0.25), (30.0, 0.3),
                   (37.0, 0.3)):
        assert integral_gain_at(settings, v) == pytest.approx(k_i, rel=1e-12), v
    assert integral_gain_at(settings, np.array([10.0, 22.5, 37.0])) == pytest.approx(
        [0.05, 0.175, 0.3])
    # another ramp: 0.2 at and below 10 m/s to 1.0 at and above 20 m/s
    other = LaneKeepingParams(integral_gain=1.0, integral_speed=20.0,
                              low_speed_integral_gain=0.2, low_integral_speed=10.0)
    assert [integral_gain_at(other, v) for v in (5.0, 12.5, 15.0, 25.0)] == pytest.approx(
        [0.2, 0.4, 0.6, 1.0])
    # the low-speed gain is capped at integral_gain: 0 switches the integral off at
    # every speed, a low-speed gain of integral_gain or more keeps k_i constant
    off = LaneKeepingParams(integral_gain=0.0, low_speed_integral_gain=0.05)
    assert [integral_gain_at(off, v) for v in (5.0, 20.0, 37.0)] == [0.0, 0.0, 0.0]
    flat = LaneKeepingParams(integral_gain=0.3, low_speed_integral_gain=0.5)
    assert [integral_gain_at(flat, v) for v in (5.0, 20.0, 37.0)] == pytest.approx([0.3] * 3)


def test_the_default_integral_gain_is_constant_and_the_schedule_one_setting_away():
    # the schedule (low_speed_integral_gain 0.05) took the S0 rebound share at 10 / 20 m/s
    # from 53 / 56 % to 88 / 88 % of 64 seeds on the goal plant, but on the CommonRoad
    # multi-body plant under the same delay and noise it left the steady error at 10 m/s
    # at 2 cm (0 % of 16 seeds met 1 cm; constant: 88-94 %) and a 1 kN crosswind at
    # 10 m/s 5.3 cm off 10 s after it came (constant: 0.4 cm): docs/lane_keeping.md
    settings = LaneKeepingParams()
    for v_x in (5.0, 10.0, 15.0, 20.0, 30.0, 37.0):
        assert integral_gain_at(settings, v_x) == pytest.approx(0.3)
    assert integral_gain_at(SCHEDULED, 37.0) == integral_gain_at(SCHEDULED, 30.0) == 0.3
    assert integral_gain_at(SCHEDULED, 10.0) < integral_gain_at(SCHEDULED, 20.0) < 0.3


def test_the_default_constant_integral_gain_against_the_schedule():
    # the default (low_speed_integral_gain = integral_gain): k_i 0.3 at every speed, the
    # law's integral and steering as before the schedule (k_i y_cg t) at 10, 20 and 37 m/s;
    # the schedule differs below integral_speed only
    old = LaneKeepingParams(state_filter='none')
    new = LaneKeepingParams(state_filter='none', low_speed_integral_gain=0.05)
    for v_x in (10.0, 20.0, 37.0):
        laws = [CgCompensatedLaw(VEHICLE, CONTROLLER, s) for s in (old, new)]
        for _ in range(100):
            outs = [law.step(state(y_cg=0.2, v_x=v_x), EMPTY, 0.01) for law in laws]
        assert laws[0].integral == pytest.approx(0.3 * 0.2 * 1.0), v_x
        assert laws[1].integral == pytest.approx(
            integral_gain_at(new, v_x) * 0.2 * 1.0), v_x
        if v_x < new.integral_speed:
            assert laws[1].integral < laws[0].integral
            assert outs[0].steering != outs[1].steering
        else:
            assert outs[0].steering == pytest.approx(outs[1].steering, rel=1e-12)


def test_steady_relative_yaw_matches_model_md():
    # model.md: -22.1 mrad at 37 m/s on a right curve of R = 400 m; 0 at 14.4 m/s
    assert steady_relative_yaw(VEHICLE, 37.0, -1 / 400) == pytest.approx(-0.0221, abs=5e-5)
    assert steady_relative_yaw(VEHICLE, math.sqrt(VEHICLE.l2 / VEHICLE.eta),
                               0.01) == pytest.approx(0.0, abs=1e-12)


def test_zero_dynamics_untouched_by_the_reference():
    # without integral, the closed loop's eigenvalues are the y_v loop's double root at
    # -w_n and the zero dynamics of the paper's law (zero_dynamics.py, independent)
    settings = LaneKeepingParams(integral_gain=0.0)
    for v in (12.0, 20.0, 37.0):
        a = stability.closed_loop_matrix(VEHICLE, CONTROLLER, settings, v)
        d_v = look_ahead(v, 0.0, VEHICLE, CONTROLLER)[0]
        w_n = math.sqrt(loop_gains(settings, v)[0])           # 3 at 12 m/s, 7 at 37
        expected = np.concatenate([[-w_n] * 2, [0.0],
                                   np.linalg.eigvals(system_matrix(VEHICLE, v, d_v))])
        got = np.linalg.eigvals(a)
        for root in expected:
            assert np.min(np.abs(got - root)) < 1e-4 * max(1.0, abs(root))


@pytest.mark.parametrize('speed', [20.0, 37.0])
def test_cg_settles_on_the_lane_of_the_design_plant(speed):
    # linear plant, no estimator, no integral: the CG equilibrium is exactly 0 (model.md);
    # the paper's law parks it at -d_v eps_ss (0.89 m outside at 37 m/s); linear tyres:
    # a constant compliance (design_friction 0)
    settings = LaneKeepingParams(integral_gain=0.0, compliance_time_constant=0.0,
                                 design_friction=0.0)
    scenario = paper_scenario(speed, duration=14.0)
    result = run(scenario, VEHICLE, CgCompensatedLaw(VEHICLE, CONTROLLER, settings))
    assert abs(result['y_cg'][-1]) < 1e-3
    paper = run(scenario, VEHICLE, CONTROLLER)
    d_v = look_ahead(speed, 0.0, VEHICLE, CONTROLLER)[0]
    offset = -d_v * steady_relative_yaw(VEHICLE, speed, -1 / 400)
    assert paper['y_cg'][-1] == pytest.approx(offset, rel=0.02)


def test_nonlinear_plant_delay_steady_error_centimetre():
    # Fiala tyres (eps_ss 3.8 mrad off the model at 0.35 g), 50 ms actuator, 20 ms delay:
    # the estimate and the integral bring the CG to the lane (paper law: 1.08 m)
    scenario = paper_scenario(37.0, duration=14.0)
    result = run(scenario, VEHICLE, CgCompensatedLaw(VEHICLE, CONTROLLER),
                 PlantParams(model='nonlinear'), delay=0.02)
    assert abs(result['y_cg'][-1]) < 0.01
    assert np.max(np.abs(result['y_cg'])) < 0.10


def test_engaged_in_a_curve_s_steady_state_the_fresh_law_answers_the_steady_angle():
    # dev-probe91 saw a fresh law's first answers peak at 0.032 rad against 0.0136 steady
    # on a 400 m curve at 30 m/s, fed measurements that were no steady state of the car
    # (the CG on the lane with no relative yaw nor sideslip). Fed the steady state the
    # nonlinear plant settles in under the default law (20 s closed loop, 20 ms delay:
    # y_cg -1.2e-5 m, eps_r -0.014702 rad, v_y 0.4411 m/s, r -0.0750082 rad/s, wheel
    # -0.014838 rad), the fresh node core answers that wheel angle from its first answer:
    # its filter, integral and actuator model start without a kick
    steady, d_s, rho = -0.014838, 1.96, -1.0 / 400.0
    eps_r, v_y, yaw_rate = -0.014702, 0.4411, -0.0750082
    core = SteeringController(VEHICLE, CONTROLLER, 'imu', True, SafetyParams(),
                              law='cg_compensated')
    answers = []
    for k in range(300):
        stamp = 100_000_000_000 + 10_000_000 * k
        for name, sample in (
                ('yaw', YawSample(stamp, eps_r, yaw_rate, 0.0)),
                ('velocity', VelocitySample(stamp, 30.0, v_y)),
                ('road_curvature', CurvatureSample(stamp, rho, 0.0, ((0.0, rho), (50.0, rho)))),
                ('lateral_error', LateralErrorSample(stamp, d_s, -1.2e-5 + d_s * eps_r))):
            assert core.accept(name, sample, stamp) is None, name
        answers.append(core.compute(stamp).steering)
    assert np.all(np.abs(np.array(answers) - steady) < 0.03 * abs(steady)), \
        (min(answers), max(answers))


def test_preview_interpolation_hand_values():
    d = np.array([0.0, 10.0, 20.0])
    k = np.array([0.0, 0.01, 0.01])
    assert preview_curvature(d, k, 5.0, 0.0, 0.0) == pytest.approx((0.005, 0.001))
    assert preview_curvature(d, k, 15.0, 0.0, 0.0) == pytest.approx((0.01, 0.0))
    assert preview_curvature(d, k, 50.0, 0.0, 0.0) == pytest.approx((0.01, 0.0))
    batch = np.stack([k, -k], axis=1)
    rho, slope = preview_curvature(d, batch, np.array([5.0, 5.0]), np.zeros(2), np.zeros(2))
    assert rho == pytest.approx([0.005, -0.005]) and slope == pytest.approx([0.001, -0.001])


@pytest.mark.parametrize('polygon', [
    (np.zeros(0), np.zeros(0)),                                 # empty
    (np.array([0.0, 10.0]), np.array([0.0, math.nan])),       # NaN curvature
    (np.array([0.0, math.inf]), np.array([0.0, 0.01])),       # non-finite distance
    (np.array([10.0, 0.0]), np.array([0.0, 0.01])),           # not increasing
    (None, None),
])
def test_unusable_preview_falls_back_to_the_cg_curvature(polygon):
    assert preview_curvature(*polygon, 5.0, 0.002, 1e-4) == pytest.approx((0.0025, 1e-4))
    law = CgCompensatedLaw(VEHICLE, CONTROLLER)
    out = law.step(state(rho=0.002, rho_rate=37.0 * 1e-4), Preview(*polygon)
                   if polygon[0] is not None else None, 0.01)
    assert math.isfinite(out.steering)


def test_integral_resets_on_time_jumps_and_bad_input():
    law = CgCompensatedLaw(VEHICLE, CONTROLLER, LaneKeepingParams(state_filter='none'))
    for _ in range(100):
        law.step(state(y_cg=0.2), EMPTY, 0.01)
    assert law.integral == pytest.approx(0.3 * 0.2 * 1.0)
    for dt in (-0.01, 5.0, math.nan):
        law.step(state(y_cg=0.2), EMPTY, 0.01)
        assert law.integral != 0.0
        law.step(state(y_cg=0.2), EMPTY, dt)
        assert law.integral == 0.0 and law.estimator.energy == 0.0
    law.step(state(y_cg=0.2), EMPTY, 0.01)
    out = law.step(state(y_cg=math.nan), EMPTY, 0.01)
    assert math.isnan(out.steering)            # the safety layer refuses it; not kept
    assert law.integral == 0.0 and law.estimator.moment == 0.0
    assert law.last_steering == 0.0
    fresh = CgCompensatedLaw(VEHICLE, CONTROLLER)
    fresh.step(state(y_cg=0.1), EMPTY, 0.0)
    assert law.step(state(y_cg=0.1), EMPTY, 0.0).steering == fresh.step(
        state(y_cg=0.1), EMPTY, 0.0).steering


def test_integral_anti_windup():
    settings = LaneKeepingParams(integral_limit=0.2)
    law = CgCompensatedLaw(VEHICLE, CONTROLLER, settings)
    for _ in range(2000):                                      # 20 s at 0.4 m: clamped
        law.step(state(y_cg=0.4), EMPTY, 0.01)
    assert law.integral == pytest.approx(0.2)
    # saturating command (without the approach heading, which would clip the offset):
    # at steering_limit (the demand limit off, the default), and at the demand band
    # (demand_limit 14 m/s^2, dev-demand)
    for settings in (LaneKeepingParams(approach_heading=0.0),
                     LaneKeepingParams(approach_heading=0.0, demand_limit=14.0)):
        law = CgCompensatedLaw(VEHICLE, CONTROLLER, settings)
        law.step(state(y_cg=-30.0), EMPTY, 0.01)
        assert (abs(law.last_steering) >= law.settings.steering_limit) != law.capped
        frozen = law.integral
        for _ in range(100):
            law.step(state(y_cg=-30.0), EMPTY, 0.01)
        assert law.integral == frozen


def test_the_integral_is_frozen_while_the_cg_error_is_outside_its_band():
    # a metre-sized error is a transient for the feedback: integrated, it overshot the
    # lane by 15-45 cm for seconds (dev-probe16)
    # (integral_band_time 0: held for as long as the error is outside; the demand band
    # off: 3 m off it holds the command, and the integral with it, a step longer)
    law = CgCompensatedLaw(VEHICLE, CONTROLLER,
                           LaneKeepingParams(state_filter='none', integral_band_time=0.0,
                                             demand_limit=0.0))
    off = CgCompensatedLaw(VEHICLE, CONTROLLER,
                           LaneKeepingParams(state_filter='none', integral_gain=0.0,
                                             demand_limit=0.0))
    assert law.settings.integral_band == 0.5
    for y in (0.6, -0.5, 3.0):
        for _ in range(100):
            out = law.step(state(y_cg=y), EMPTY, 0.01)
            # held: no k_i y_cg in the reference's rate either (the law without it)
            assert out.steering == off.step(state(y_cg=y), EMPTY, 0.01).steering
        assert law.integral == 0.0
    for _ in range(100):
        law.step(state(y_cg=0.4), EMPTY, 0.01)
    assert law.integral == pytest.approx(0.3 * 0.4 * 1.0)
    # 0: integrates at any error (the law before the band)
    law = CgCompensatedLaw(VEHICLE, CONTROLLER,
                           LaneKeepingParams(state_filter='none', integral_band=0.0))
    for _ in range(100):
        law.step(state(y_cg=0.6), EMPTY, 0.01)
    assert law.integral == pytest.approx(0.3 * 0.6 * 1.0)
    with pytest.raises(ParameterError, match='integral_band'):
        LaneKeepingParams(integral_band=-0.1)


def test_an_error_standing_outside_the_band_is_integrated_after_the_band_time():
    # dev-probe20: old code held the integral for as long as |y_cg| >= integral_band: a
    # model error that put the CG outside the band at once was never removed
    law = CgCompensatedLaw(VEHICLE, CONTROLLER, LaneKeepingParams(state_filter='none'))
    assert law.settings.integral_band_time == 2.0
    for _ in range(190):                        # 1.9 s at 0.6 m: held
        law.step(state(y_cg=0.6), EMPTY, 0.01)
    assert law.integral == 0.0
    for _ in range(110):                        # from 2 s on (+- a step): 0.3 x 0.6 m/s
        law.step(state(y_cg=0.6), EMPTY, 0.01)
    assert law.integral == pytest.approx(0.3 * 0.6 * 1.0, abs=0.3 * 0.6 * 0.011)
    held = law.integral
    law.step(state(y_cg=0.4), EMPTY, 0.01)       # back inside: the time starts again
    assert law.outside_time == 0.0
    for _ in range(100):                        # 1 s at -0.7 m: held again
        law.step(state(y_cg=-0.7), EMPTY, 0.01)
    assert law.integral == pytest.approx(held + 0.3 * 0.4 * 0.01)
    law.step(state(y_cg=-0.7), EMPTY, 0.5)       # a time jump restarts it
    assert law.outside_time == 0.0 and law.integral == 0.0
    # a batch: each run its own time
    batch = CgCompensatedLaw(VEHICLE, CONTROLLER, LaneKeepingParams(state_filter='none'))
    for k in range(300):
        y = np.array([0.6, 0.6 if k < 150 else 0.2])
        batch.step(state(y_cg=y), EMPTY, 0.01)
    assert batch.integral[0] == pytest.approx(0.3 * 0.6 * 1.0, abs=0.3 * 0.6 * 0.011)
    assert batch.integral[1] == pytest.approx(0.3 * 0.2 * 1.5)
    assert list(batch.outside_time) == pytest.approx([3.0, 0.0])
    with pytest.raises(ParameterError, match='integral_band_time'):
        LaneKeepingParams(integral_band_time=-1.0)


def _standing_crosswind(force, band_time, side_force=0.0):
    """
    Return the CG error under a crosswind stepped on at 2 s (goal plant, 37 m/s).

    The integral's band alone: without the side force in the reference (dev-sc36) unless
    ``side_force`` says.
    """
    import dataclasses
    from lookahead_control.tools.compare import load_scenarios
    from sim_plant.sensors import NoiseParams
    scenario = dataclasses.replace(load_scenarios(['s0_straight'])['s0_straight'],
                                   duration=20.0)
    law = CgCompensatedLaw(VEHICLE, CONTROLLER,
                           LaneKeepingParams(integral_band_time=band_time,
                                             side_force=side_force))
    return run(scenario, VEHICLE, law, PlantParams(model='nonlinear'), initial_speed=37.0,
               initial_error=0.0, dt=0.001, delay=0.02, preview_distance=100.0,
               noise=NoiseParams(), seed=1,
               disturbance=lambda t: (force if t >= 2.0 else 0.0, 0.0))['y_cg']


def test_a_crosswind_that_puts_the_cg_outside_the_band_at_once_is_removed():
    # dev-probe20: 3 kN stepped on at 37 m/s (a strong gust or bank, 2 m/s^2): the CG
    # goes 0.54 m off; old code (held while outside, integral_band_time 0) kept it there
    # for good (0.545 m in the last second, 19-20 s); now 0.217 m, as integrating at
    # any error (the integral at its clamp); 2.95 kN: 0.20 m either way
    y = _standing_crosswind(3000.0, 2.0)
    assert abs(y[-100:].mean()) < 0.25
    assert abs(_standing_crosswind(3000.0, 0.0)[-100:].mean()) > 0.5
    # the default takes the force into the reference (side_force, dev-sc36): the CG does
    # not stand outside the band, and the integral's band matters no more here
    assert abs(_standing_crosswind(3000.0, 0.0, side_force=1.0)[-100:].mean()) < 0.02


def test_the_band_description_says_what_0_does():
    # dev-probe20: old '0: never' (--help, the descriptor) and '0: never' (the shipped
    # YAML) read as 'never integrates', the opposite of what 0 does; a tiny band is the
    # one that (nearly) never integrates
    from pathlib import Path
    from lookahead_control.core.param_schema import LANE_KEEPING_SPECS
    spec, = (s for s in LANE_KEEPING_SPECS if s.name == 'lane_keeping.integral_band')
    assert '0: no band, it integrates at any error [m]' in spec.description
    text = (Path(__file__).resolve().parent.parent / 'config' / 'controller.yaml').read_text()
    line, = (x for x in text.splitlines() if 'integral_band:' in x)
    assert '0: no band' in line and 'never' not in line


@pytest.mark.parametrize('v_x', [10.0, 37.0])
def test_the_held_loop_of_the_stability_check_is_the_law_outside_the_band(v_x):
    # the law's steering, differentiated numerically at a CG error outside the band
    # (0.8 m), against the gains the stability check uses for the held integral
    # (feedback_gain with k_i = 0); inside (0.2 m) it has the k_i k_d term
    import copy
    import dataclasses
    # (without the approach heading: at 10 m/s its clip, 0.48 m, is inside 0.8 m; the
    # approach loop has its own test in test_approach.py)
    settings = LaneKeepingParams(state_filter='none', compliance_time_constant=0.0,
                                 approach_heading=0.0)
    held = stability.feedback_gain(VEHICLE, CONTROLLER,
                                   dataclasses.replace(settings, integral_gain=0.0), v_x)
    running = stability.feedback_gain(VEHICLE, CONTROLLER, settings, v_x)
    for y0, gains in ((0.8, held), (0.2, running)):
        law = CgCompensatedLaw(VEHICLE, CONTROLLER, settings)
        base = [y0, 0.001, 0.01, 0.002]
        for _ in range(5):
            law.step(LateralState(*base, v_x, 0.0, 0.0, 0.0), EMPTY, 0.01)

        def steering(x, shift=0.0):
            twin = copy.deepcopy(law)
            twin.integral = twin.integral + shift
            return float(twin.step(LateralState(*x, v_x, 0.0, 0.0, 0.0), EMPTY, 0.01).steering)
        h = 1e-6
        slopes = [(steering(base[:i] + [base[i] + h] + base[i + 1:])
                   - steering(base[:i] + [base[i] - h] + base[i + 1:])) / (2 * h)
                  for i in range(4)]
        slopes.append((steering(base, h) - steering(base, -h)) / (2 * h))
        # inside, the law integrates within the step: k_I k_i dt more on y_cg (k_i at v_x)
        extra = gains[4] * integral_gain_at(settings, v_x) * 0.01 if y0 < 0.5 else 0.0
        expected = np.asarray(gains, dtype=float).ravel() + np.array([extra, 0, 0, 0, 0])
        assert np.allclose(slopes, expected, rtol=1e-5, atol=1e-7)
    assert not np.allclose(held, running)


def _engaged_off_centre(speed, band, **settings):
    """Engage the default law 1.75 m off the lane centre (goal plant, straight road)."""
    from lookahead_control.tools.compare import load_scenarios
    from sim_plant.sensors import NoiseParams
    scenario = load_scenarios(['s0_straight'])['s0_straight']
    law = CgCompensatedLaw(VEHICLE, CONTROLLER,
                           LaneKeepingParams(integral_band=band, **settings))
    return run(scenario, VEHICLE, law, PlantParams(model='nonlinear'), initial_speed=speed,
               initial_error=1.75, dt=0.001, delay=0.02, preview_distance=100.0,
               noise=NoiseParams(), seed=1)['y_cg']


@pytest.mark.parametrize('speed, bound', [(20.0, 0.08), (37.0, 0.12)])
def test_a_car_engaged_half_a_lane_off_does_not_overshoot_the_centre(speed, bound):
    # measured: 2.8 / 8.3 cm past the centre at 20 / 37 m/s (4.3 at 20 with k_i 0.3 at
    # every speed, before dev-kisched); integrating at any error with k_i 0.3 at every
    # speed (integral_band 0, the law before) 37.2 / 40.2 cm (with the k_i schedule
    # 18.1 cm at 20 m/s)
    y = _engaged_off_centre(speed, 0.5)
    assert y[0] == pytest.approx(1.75) and abs(y[-100:]).max() < 0.05
    assert -y.min() < bound
    # (the law before: no approach heading, whose clip holds the integral too)
    assert -_engaged_off_centre(speed, 0.0, low_speed_integral_gain=0.3,
                                approach_heading=0.0).min() > 0.3


def test_speed_from_37_to_3_freezes_learning_and_stays_finite():
    law = CgCompensatedLaw(VEHICLE, CONTROLLER)
    for v in np.linspace(37.0, 3.0, 500):
        out = law.step(state(y_cg=0.05, r=0.01, v_y=0.01, v_x=float(v), rho=-1 / 400),
                       EMPTY, 0.01)
        assert math.isfinite(out.steering)
    held = law.integral
    law.step(state(y_cg=0.05, v_x=3.0), EMPTY, 0.01)
    assert law.integral == held
    eta = VEHICLE.eta
    assert eta / 3.0 <= law.compliance() <= 3.0 * eta


def test_compliance_estimate_recovers_a_softer_rear_axle():
    # steady cornering of a plant with C_r 30 % lower: alpha_r = (l_2 r - v_y) / v_x
    soft = 0.7 * VEHICLE.c_r
    v, a_y = 30.0, 3.0
    r = a_y / v
    alpha = VEHICLE.mass * VEHICLE.l1 / (soft * VEHICLE.wheelbase) * a_y
    v_y = VEHICLE.l2 * r - v * alpha
    # the fast estimate's own fit (the memory it falls back to: test_estimator.py)
    law = CgCompensatedLaw(VEHICLE, CONTROLLER, LaneKeepingParams(compliance_memory=0.0))
    for _ in range(1000):
        law.step(state(v_y=v_y, r=r, v_x=v, rho=r / v), EMPTY, 0.01)
    prior = law.settings.compliance_prior ** 2
    truth = VEHICLE.eta / 0.7
    # the regressor is shaped (brush, design friction 1): phi = a_y s(a_y / g); the
    # scale fits alpha_r = c_hat phi: (alpha phi + p^2 eta) / (phi^2 + p^2)
    phi = a_y * brush_shape(a_y / GRAVITY)[0]
    expected = (truth * a_y * phi + prior * VEHICLE.eta) / (phi * phi + prior)
    assert law.compliance() == pytest.approx(expected, rel=1e-3)
    # a linear-tyre design (design_friction 0): the secant compliance itself
    law = CgCompensatedLaw(VEHICLE, CONTROLLER, LaneKeepingParams(design_friction=0.0,
                                                                  compliance_memory=0.0))
    for _ in range(1000):
        law.step(state(v_y=v_y, r=r, v_x=v, rho=r / v), EMPTY, 0.01)
    expected = (a_y * a_y * truth + prior * VEHICLE.eta) / (a_y * a_y + prior)
    assert law.compliance() == pytest.approx(expected, rel=1e-3)


def test_batch_equals_single_runs():
    speeds = np.array([12.0, 25.0, 37.0])
    errors = np.array([0.1, -0.2, 0.05])
    batch = CgCompensatedLaw(VEHICLE, CONTROLLER)
    singles = [CgCompensatedLaw(VEHICLE, CONTROLLER) for _ in speeds]
    d = np.array([0.0, 20.0, 40.0])
    k = np.array([0.0, -0.0025, -0.0025])
    for _ in range(50):
        out = batch.step(state(y_cg=errors, v_x=speeds, r=0.01 + 0 * speeds),
                         Preview(d, np.repeat(k[:, None], 3, axis=1)), 0.01)
        for i, law in enumerate(singles):
            one = law.step(state(y_cg=float(errors[i]), v_x=float(speeds[i]), r=0.01),
                           Preview(d, k), 0.01)
            assert out.steering[i] == pytest.approx(one.steering, rel=1e-12, abs=1e-15)


def test_paper_reference_modes_unchanged():
    s = state(y_cg=0.1, eps_r=0.01, rho=-1 / 400)
    with pytest.raises(ParameterError, match='cg_compensated or lane_tangent'):
        CgCompensatedLaw(VEHICLE, ControllerParams(reference='arc_approx'))
    assert steering_law(s, VEHICLE, CONTROLLER).steering == pytest.approx(
        steering_law(s, VEHICLE, ControllerParams()).steering)


def test_settings_validate():
    with pytest.raises(ParameterError, match='integral_gain'):
        LaneKeepingParams(integral_gain=-1.0)
    with pytest.raises(ParameterError, match=r'lane_keeping\.low_speed_integral_gain = -0\.1'):
        LaneKeepingParams(low_speed_integral_gain=-0.1)
    with pytest.raises(ParameterError, match=r'lane_keeping\.integral_speed = 0\.0'):
        LaneKeepingParams(integral_speed=0.0)
    with pytest.raises(ParameterError, match=r'lane_keeping\.low_integral_speed = -1\.0'):
        LaneKeepingParams(low_integral_speed=-1.0)
    for low, high in ((30.0, 30.0), (31.0, 30.0)):
        with pytest.raises(ParameterError) as error:
            LaneKeepingParams(low_integral_speed=low, integral_speed=high)
        assert str(error.value) == (
            f'lane_keeping.low_integral_speed = {low!r} m/s is not below '
            f'lane_keeping.integral_speed = {high!r} m/s; the integral gain moves from '
            'low_speed_integral_gain to integral_gain between them, so it must be lower')
    with pytest.raises(ParameterError, match='max_gap'):
        LaneKeepingParams(max_gap=0.0)


def test_feedback_gain_is_the_law_with_its_acceleration_terms():
    # K(v, a) against the law itself on unit states (straight road, integral I as the
    # offset -I with rate -k_i y_cg): the old K ignored a_x, which the law's d_v rate
    # and drift terms use (A(v, a) = A_0 + a A_1); k_i is the scheduled gain at v
    # (0.05 at 10.5 and 12 m/s, 0.2167 at 25, 0.3 at 37)
    settings = LaneKeepingParams()
    for v, a in ((12.0, 3.5), (25.0, -3.5), (37.0, 2.0), (10.5, 3.5)):
        k_i = integral_gain_at(settings, v)
        a_0 = stability.closed_loop_matrix(VEHICLE, CONTROLLER, settings, v)
        assert a_0[4, 0] == k_i and a_0[4, 1:].tolist() == [0.0] * 4
        gains = loop_gains(settings, v)
        k = stability.feedback_gain(VEHICLE, CONTROLLER, settings, v, a)
        for i in range(5):
            x = np.eye(5)[i]
            s = state(y_cg=x[0], eps_r=x[1], v_y=x[2], r=x[3], v_x=v, a_x=a)
            out = cg_compensated_law(s, VEHICLE, CONTROLLER, 0.0, 0.0, 0.0, 0.0,
                                     offset=x[4], offset_rate=k_i * x[0], gains=gains)
            assert k[i] == pytest.approx(out.steering, rel=1e-12, abs=1e-12)
    a_0 = stability.closed_loop_matrix(VEHICLE, CONTROLLER, settings, 20.0)
    a_1 = stability.closed_loop_matrix(VEHICLE, CONTROLLER, settings, 20.0, a_x=1.0)
    assert np.max(np.abs(a_1 - a_0)) > 1.0      # the acceleration moves A a lot


def test_schedule_kinks_by_hand():
    # d_v leaves its floor where 4 eta v^2 - l_2 = d_s; w_n leaves 3 at 30 * 3 / 7, 7 at 30;
    # the schedule's k_i leaves 0.05 at 15 m/s and reaches 0.3 at 30 (one kink with w_n's)
    floor = math.sqrt((VEHICLE.d_s + VEHICLE.l2) / (4.0 * VEHICLE.eta))
    kinks = stability.schedule_kinks(VEHICLE, CONTROLLER, SCHEDULED, 10.0, 37.0)
    assert kinks == pytest.approx([floor, 90.0 / 7.0, 15.0, 30.0], abs=1e-9)
    assert floor == pytest.approx(10.78, abs=0.005)
    # a constant k_i (the default) has none; another ramp has its own two
    flat = W_N_SCHEDULE
    assert stability.schedule_kinks(VEHICLE, CONTROLLER, flat, 10.0, 37.0) == pytest.approx(
        [floor, 90.0 / 7.0, 30.0], abs=1e-9)
    # frequency_speed 20: w_n leaves 3 at 20 * 3 / 7 = 8.6 m/s, below the envelope, and 7
    # at 20; a constant w_n (the low-speed one capped) has its two clamps at one speed
    assert stability.schedule_kinks(VEHICLE, CONTROLLER, WN20, 10.0,
                                    37.0) == pytest.approx([floor, 20.0], abs=1e-9)
    capped = LaneKeepingParams(low_speed_frequency=9.0)
    assert stability.schedule_kinks(VEHICLE, CONTROLLER, capped, 10.0,
                                    37.0) == pytest.approx([floor, 30.0], abs=1e-9)
    ramp = replace(SCHEDULED, low_integral_speed=20.0, integral_speed=25.0)
    assert stability.schedule_kinks(VEHICLE, CONTROLLER, ramp, 10.0, 37.0) == pytest.approx(
        [floor, 90.0 / 7.0, 20.0, 25.0, 30.0], abs=1e-9)


def test_certificate_lyapunov_against_scipy():
    # P and dP/dv of the certificate against scipy's solver and a central difference of
    # its solutions (away from kinks), in the coordinates u = S x built here by hand:
    # u = [y_cg + (1 - s) I, eps_r, v_y, r, s I], s = sqrt(k_i(v) / 0.3); S = I at 36 m/s,
    # a constant S at 11.5 (k_i 0.05), and at 20 m/s (k_i 0.05 + 0.25 * 5 / 15 = 2 / 15,
    # k_i' = 1 / 60) the coordinates move: dP/dv also has G^T P + P G with
    # G = (k_i' / 2 k_i) (E_55 - E_15), k_i' / 2 k_i = 1 / 16
    weight = stability.lyapunov_weight()
    settings = SCHEDULED

    def change(speed):
        scale = math.sqrt(integral_gain_at(settings, speed) / 0.3)
        matrix = np.eye(5)
        matrix[0, 4], matrix[4, 4] = 1.0 - scale, scale
        return matrix

    def reference(speed):
        a = stability.closed_loop_matrix(VEHICLE, CONTROLLER, settings, speed)
        a_u = change(speed) @ a @ np.linalg.inv(change(speed))
        return solve_continuous_lyapunov(a_u.T, -weight)
    assert change(36.0) == pytest.approx(np.eye(5), abs=1e-15)
    for v, rate in ((11.5, 0.0), (20.0, 1.0 / 16.0), (36.0, 0.0)):
        p, p_v, n = stability.lyapunov_rate(VEHICLE, CONTROLLER, settings, v, 1.0, weight)
        assert stability.integral_coordinates(settings, v) == pytest.approx(change(v),
                                                                            rel=1e-12)
        # S^-1 in closed form (dev-sc39) is numpy's inverse
        a_v = stability.closed_loop_matrix(VEHICLE, CONTROLLER, settings, v)
        assert stability.loop_in_coordinates(VEHICLE, CONTROLLER, settings, v) == \
            pytest.approx(change(v) @ a_v @ np.linalg.inv(change(v)), rel=1e-12, abs=1e-12)
        assert p == pytest.approx(reference(v), rel=1e-9, abs=1e-9)
        assert stability.lyapunov_matrix(VEHICLE, CONTROLLER, settings, v, weight) == \
            pytest.approx(change(v).T @ reference(v) @ change(v), rel=1e-9, abs=1e-9)
        g = np.zeros((5, 5))
        g[4, 4], g[0, 4] = rate, -rate
        central = (reference(v + 1e-3) - reference(v - 1e-3)) / 2e-3 + g.T @ p + p @ g
        assert p_v == pytest.approx(central, rel=1e-5, abs=1e-6 * np.max(np.abs(p_v)))
        left = stability.lyapunov_rate(VEHICLE, CONTROLLER, settings, v, -1.0, weight)
        assert left[2] == pytest.approx(n, rel=1e-6, abs=1e-6 * np.max(np.abs(n)))
    with pytest.raises(ValueError, match='positive definite'):
        stability.lyapunov_weight(((1.0,) * 5,) * 5)
    # no integral at low speed: S is singular, as numpy says
    with pytest.raises(np.linalg.LinAlgError):
        stability.loop_in_coordinates(VEHICLE, CONTROLLER, replace(
            settings, low_speed_integral_gain=0.0), 10.0)


def test_every_q_on_one_grid_is_each_q_on_its_own(monkeypatch):
    # certificate() makes the loop's matrices at a grid point once for all its Q (3.7
    # times faster than once per Q): each Q's result is the one of certificate(q=Q)
    # alone to the bit, and the one returned is the smallest bound
    for settings, a_error in ((LaneKeepingParams(), 1.0), (SCHEDULED, 3.5)):
        alone = {name: stability.certificate(VEHICLE, CONTROLLER, settings, samples=21,
                                             q=weight, a_error=a_error)
                 for name, weight in stability.CERTIFICATE_WEIGHTS.items()}
        with monkeypatch.context() as patch:
            patch.setattr(stability, 'CERTIFICATE_SCHEDULES', {})
            best = stability.certificate(VEHICLE, CONTROLLER, settings, samples=21,
                                         a_error=a_error)
        assert best._replace(weight='given') == alone[best.weight]
        assert best.between == min(c.between for c in alone.values())
        # with the schedules their knots are grid speeds of every Q: a schedule's result
        # is its own run's, and the smallest bound is still returned
        scheduled = {name: stability.certificate(VEHICLE, CONTROLLER, settings, samples=21,
                                                 q_knots=knots, a_error=a_error)
                     for name, knots in stability.CERTIFICATE_SCHEDULES.items()}
        best = stability.certificate(VEHICLE, CONTROLLER, settings, samples=21,
                                     a_error=a_error)
        assert best.weight == ('loaded' if settings == LaneKeepingParams() else 'scheduled')
        if best.weight in scheduled:
            assert best._replace(weight='given') == scheduled[best.weight]
        assert best.between <= min(c.between for c in scheduled.values())
    with pytest.raises(ValueError, match='positive definite'):
        stability.certificate(VEHICLE, CONTROLLER, LaneKeepingParams(), samples=21,
                              q=((1.0,) * 5,) * 5)


def test_certificate_refusals_and_edges_do_not_depend_on_the_calls_before():
    # dev-probe37, against a first version that kept each envelope's grid (lru_cache):
    # samples 2.0 after a call with 2 returned a result (the same cache key) where a
    # fresh process raised, and the memory grew with samples (12 KB a point, 8 grids
    # kept); now nothing is kept
    settings = LaneKeepingParams()
    # the 2 grid speeds, the 3 kinks and the loaded schedule's 2 knots
    assert stability.certificate(VEHICLE, CONTROLLER, settings, samples=2).speeds == 7
    with pytest.raises(TypeError):
        stability.certificate(VEHICLE, CONTROLLER, settings, samples=2.0)
    # infinite bounds are refused in one line (were numpy's LinAlgError)
    for kwargs, blamed in (({'a_max': math.inf}, 'a_max = inf'),
                           ({'v_max': math.inf}, 'speed envelope [10.0, inf]')):
        with pytest.raises(ValueError, match=re.escape(blamed)):
            stability.certificate(VEHICLE, CONTROLLER, settings, samples=3, **kwargs)
    # an envelope within 1e-6 m/s of a kink is the kink, both sides (was numpy's
    # "zero-size array to reduction operation maximum")
    narrow = stability.certificate(VEHICLE, CONTROLLER, settings, 29.9999999, 30.0000001,
                                   samples=3)
    assert narrow.speeds == 1 and narrow.kinks == (30.0,) and narrow.holds
    assert narrow.between == narrow.max_norm < 1.0


CONSTANT_K_I = W_N_SCHEDULE   # k_i 0.3 at every speed (the default)


def test_certificate_holds_to_3_5_m_s2_with_the_scheduled_integral_gain():
    # the scheduled k_i falls to 0.05 1/s at and below 15 m/s: the integral's root is
    # about -k_i there (-0.0504), the test runs in the coordinates u = S(v) x and holds
    # with the same sharp Q: 0.730 at 37 m/s (where k_i is 0.3, as before), kinks at the
    # schedule's 15 m/s too; it fails above 3.5 / 0.73 = 4.8 m/s^2 as before
    settings = SCHEDULED
    cert = stability.certificate(VEHICLE, CONTROLLER, settings, samples=136)
    assert -0.06 < cert.max_real_eig < -0.04 and cert.holds and cert.weight == 'sharp'
    assert cert.max_norm == pytest.approx(0.730, abs=0.005)
    assert cert.max_norm_speed == 37.0 and 15.0 in cert.kinks
    assert cert.max_norm < cert.between < 0.8 and cert.speeds == 138
    assert not stability.certificate(VEHICLE, CONTROLLER, settings, a_max=4.8,
                                     samples=136).holds
    # the robust Q (found for a constant k_i) does not hold on the schedule
    robust = stability.certificate(VEHICLE, CONTROLLER, settings, samples=136,
                                   q=stability.CERTIFICATE_Q_ROBUST)
    assert not robust.holds and robust.max_norm > 1.5


@pytest.fixture
def constant_q(monkeypatch):
    """Try only the constant Q of CERTIFICATE_WEIGHTS (their figures before dev-sc31)."""
    monkeypatch.setattr(stability, 'CERTIFICATE_SCHEDULES', {})


def test_certificate_holds_to_3_5_m_s2(constant_q):
    # the Section 4 test with A's acceleration terms and the optimized Q: 0.730 at
    # 3.5 m/s^2 on the grid, at the w_n kink; bounded between grid points (k_i constant:
    # the figures of the law before the schedule, unchanged)
    settings = CONSTANT_K_I
    cert = stability.certificate(VEHICLE, CONTROLLER, settings, samples=136)
    assert cert.max_real_eig < -0.3 and cert.holds
    assert cert.max_norm == pytest.approx(0.730, abs=0.005)
    assert cert.max_norm_speed == pytest.approx(90.0 / 7.0)
    assert cert.max_norm < cert.between < 0.8 and cert.speeds == 138
    assert cert.weight == 'sharp'
    robust = stability.certificate(VEHICLE, CONTROLLER, settings, samples=136,
                                   q=stability.CERTIFICATE_Q_ROBUST)
    assert robust.holds and robust.max_norm == pytest.approx(0.924, abs=0.005)
    # the value is linear in a_max: it fails above 3.5 / 0.73 = 4.8 m/s^2
    assert not stability.certificate(VEHICLE, CONTROLLER, settings, a_max=4.8,
                                     samples=136).holds
    # the previous test's diagonal scaling S (Q = S^-2), with the acceleration terms the
    # old test left out, certifies only 0.74 m/s^2
    old = np.diag(1.0 / np.array((1.0, 0.0807, 2.31, 1.69, 1.06)) ** 2)
    cert = stability.certificate(VEHICLE, CONTROLLER, settings, samples=136,
                                 q=tuple(map(tuple, old)))
    assert not cert.holds and cert.max_norm == pytest.approx(4.75, abs=0.03)


def test_certificate_with_an_error_in_the_law_s_acceleration(constant_q):
    # the law's a_x (IMU, grade, differentiated speed) off the true v' by up to
    # a_error: the vertices (+-a_max, a +- a_error); 0 gives the exact test's value
    # (k_i constant: the figures before the schedule)
    settings = CONSTANT_K_I
    sharp = stability.CERTIFICATE_Q
    exact = stability.certificate(VEHICLE, CONTROLLER, settings, samples=55, q=sharp)
    cert = stability.certificate(VEHICLE, CONTROLLER, settings, samples=271, a_error=1.0,
                                 q=sharp)
    assert cert.holds and exact.max_norm < cert.max_norm == pytest.approx(0.944, abs=0.005)
    assert not stability.certificate(VEHICLE, CONTROLLER, settings, samples=271,
                                     a_error=1.2, q=sharp).holds
    # by hand at one speed: the largest eigenvalue of Q^-1 (a P_v + a_hat M) over a
    # dense set of (a, a_hat) is the vertices' (the matrix is affine in both)
    weight = stability.lyapunov_weight()
    _, p_v, n = stability.lyapunov_rate(VEHICLE, CONTROLLER, settings, 90.0 / 7.0, 1.0,
                                        weight)
    inverse = np.linalg.inv(np.linalg.cholesky(weight))
    top = max(float(np.max(np.linalg.eigvalsh(
        inverse @ (a * p_v + a_hat * (n - p_v)) @ inverse.T)))
        for a in np.linspace(-3.5, 3.5, 15) for a_hat in a + np.linspace(-1.0, 1.0, 9))
    assert top == pytest.approx(cert.max_norm, abs=1e-9)
    # acceleration_source zero (a_hat = 0, inside a_error = a_max): not with the sharp
    # Q, but with the robust one (the default tries both and takes the smaller bound)
    assert not stability.certificate(VEHICLE, CONTROLLER, settings, samples=55,
                                     a_error=3.5, q=sharp).holds
    cert = stability.certificate(VEHICLE, CONTROLLER, settings, samples=271, a_error=3.5)
    assert cert.holds and cert.weight == 'robust'
    assert cert.max_norm == pytest.approx(0.957, abs=0.005) and cert.between < 0.98
    with pytest.raises(ValueError, match='a_error'):
        stability.certificate(VEHICLE, CONTROLLER, settings, a_error=float('nan'))


def test_certificate_with_an_acceleration_error_and_the_scheduled_integral_gain():
    # the schedule: the sharp Q holds to an error of 1.4 m/s^2 (1.5 fails);
    # acceleration_source zero (a_error 3.5) holds with the Q searched for the schedule,
    # value 0.861 (4.5 fails), not with the robust one
    settings = SCHEDULED
    sharp = stability.CERTIFICATE_Q
    assert stability.certificate(VEHICLE, CONTROLLER, settings, samples=271, a_error=1.4,
                                 q=sharp).holds
    assert not stability.certificate(VEHICLE, CONTROLLER, settings, samples=271,
                                     a_error=1.5, q=sharp).holds
    cert = stability.certificate(VEHICLE, CONTROLLER, settings, samples=271, a_error=3.5)
    assert cert.holds and cert.weight == 'scheduled'
    assert cert.max_norm == pytest.approx(0.861, abs=0.005) and cert.between < 0.88
    assert not stability.certificate(VEHICLE, CONTROLLER, settings, samples=271,
                                     a_error=3.5, q=stability.CERTIFICATE_Q_ROBUST).holds
    assert not stability.certificate(VEHICLE, CONTROLLER, settings, samples=271,
                                     a_error=4.5).holds
    # and the scheduled Q does not certify the constant k_i: both are needed
    assert not stability.certificate(VEHICLE, CONTROLLER, CONSTANT_K_I, samples=55,
                                     a_error=3.5,
                                     q=stability.CERTIFICATE_Q_SCHEDULED).holds


def test_certificate_of_w_n_7_from_20_mps(constant_q):
    # dev-wnflat's option frequency_speed 20 (w_n 7 from 20 m/s, not the default): the
    # sharp Q certifies it as the default schedule, 0.730 at 37 m/s (bound 0.743:
    # 4.7 m/s^2); an a_x error up to 1 m/s^2 (robust_wn20: 0.871; sharp 0.914; the
    # default schedule 0.957 with sharp)
    settings = WN20
    cert = stability.certificate(VEHICLE, CONTROLLER, settings, samples=271)
    assert cert.holds and cert.weight == 'sharp' and cert.max_real_eig < -0.3
    assert cert.max_norm == pytest.approx(0.730, abs=0.005) and cert.max_norm_speed == 37.0
    assert cert.between < 0.75 and 20.0 in cert.kinks
    assert not stability.certificate(VEHICLE, CONTROLLER, settings, a_max=4.8,
                                     samples=271).holds
    cert = stability.certificate(VEHICLE, CONTROLLER, settings, samples=271, a_error=1.0)
    assert cert.holds and cert.between == pytest.approx(0.871, abs=0.005)
    assert cert.weight == 'robust_wn20'
    # the law's a_x off by up to 3.5 m/s^2 (acceleration_source zero): the robust Q
    # fails (1.066 at 10 m/s, where w_n is 3.5 here); the one searched for this schedule
    # holds (0.903, at the d_v floor's kink)
    assert not stability.certificate(VEHICLE, CONTROLLER, settings, samples=271,
                                     a_error=3.5, q=stability.CERTIFICATE_Q_ROBUST).holds
    cert = stability.certificate(VEHICLE, CONTROLLER, settings, samples=271, a_error=3.5)
    assert cert.holds and cert.weight == 'robust_wn20'
    assert cert.between == pytest.approx(0.903, abs=0.005)
    assert cert.max_norm_speed == pytest.approx(10.7777, abs=1e-3)
    assert not stability.certificate(VEHICLE, CONTROLLER, settings, samples=271,
                                     a_max=4.0, a_error=4.0).holds
    # w_n 7 down to 10 m/s (low_speed_frequency 7, an option since dev-approach) is
    # certified by none of those Qs (sharp: 2.28 at the d_v floor's kink, 10.78 m/s),
    # only by the one searched for it
    flat = LaneKeepingParams(low_speed_frequency=7.0)
    for name in ('sharp', 'robust', 'scheduled', 'robust_wn20', 'wn5', 'wn5_robust'):
        assert not stability.certificate(VEHICLE, CONTROLLER, flat, samples=55,
                                         q=stability.CERTIFICATE_WEIGHTS[name]).holds
    assert stability.certificate(VEHICLE, CONTROLLER, flat, samples=55).weight == 'flat'


def test_certificate_edge_settings():
    # w_n constant (low = natural frequency): its two kinks are one (with k_i's at 30
    # m/s); no integral: a zero eigenvalue, so no P > 0: the value is infinite, not a pass
    flat = replace(SCHEDULED, natural_frequency=3.0)
    assert stability.schedule_kinks(VEHICLE, CONTROLLER, flat, 10.0, 37.0) == pytest.approx(
        [math.sqrt((VEHICLE.d_s + VEHICLE.l2) / (4.0 * VEHICLE.eta)), 15.0, 30.0])
    cert = stability.certificate(VEHICLE, CONTROLLER, LaneKeepingParams(integral_gain=0.0),
                                 samples=11)
    assert cert.max_real_eig == 0.0 and cert.max_norm == math.inf and not cert.holds
    # nor at low speed only (low_speed_integral_gain 0: no integral at and below 15 m/s)
    cert = stability.certificate(VEHICLE, CONTROLLER,
                                 LaneKeepingParams(low_speed_integral_gain=0.0), samples=11)
    assert cert.max_real_eig == 0.0 and cert.max_norm == math.inf and not cert.holds
    # an envelope between two kinks
    cert = stability.certificate(VEHICLE, CONTROLLER, SCHEDULED, 36.99, 37.0,
                                 samples=3)
    assert cert.kinks == () and cert.holds and cert.speeds == 3


def test_certificate_between_grid_points():
    # the bound from 28 speeds covers every value on a grid 100 times denser
    settings = W_N_SCHEDULE
    coarse = stability.certificate(VEHICLE, CONTROLLER, settings, samples=28,
                                   q=stability.CERTIFICATE_Q)
    weight = stability.lyapunov_weight()
    inverse = np.linalg.inv(np.linalg.cholesky(weight))
    worst = 0.0
    for v in np.linspace(10.0, 37.0, 2701)[1:-1]:
        for side in (-1.0, 1.0):
            n = stability.lyapunov_rate(VEHICLE, CONTROLLER, settings, float(v), side,
                                        weight, 1e-5)[2]
            worst = max(worst, 3.5 * float(np.max(np.abs(np.linalg.eigvalsh(
                inverse @ n @ inverse.T)))))
    assert worst <= coarse.between < 0.9
    assert worst == pytest.approx(coarse.max_norm, abs=0.01)


def _worst_case_run(weight, a_max=3.5, seconds=12.0, dt=0.002, seed=3, start=None,
                    a_error=0.0, settings=W_N_SCHEDULE):
    # the adversary: at every step the acceleration (+-a_max, speed kept in 10-37 m/s)
    # and the law's a_x (a +- a_error) that make V = x^T P(v) x largest at the step's
    # end; RK4 on x' = A(v, a_hat) x, v' = a
    rng = np.random.default_rng(seed)
    x = rng.normal(size=5) * np.array([0.5, 0.02, 0.3, 0.05, 0.2])
    v = 12.0
    if start is not None:
        v, x = start

    def lyap(speed, state_):
        # V = u^T P_u u in the certificate's coordinates u = S(v) x (a callable weight:
        # a speed schedule of Q)
        change = stability.integral_coordinates(settings, speed)
        a = stability.closed_loop_matrix(VEHICLE, CONTROLLER, settings, speed)
        a_u = change @ a @ np.linalg.inv(change)
        u = change @ state_
        q = weight(speed) if callable(weight) else weight
        return float(u @ solve_continuous_lyapunov(a_u.T, -q) @ u)

    def step(speed, acc, state_, law_acc):
        def f(t, z):
            return stability.closed_loop_matrix(VEHICLE, CONTROLLER, settings,
                                                speed + acc * t, a_x=law_acc) @ z
        k1 = f(0.0, state_)
        k2 = f(dt / 2, state_ + dt / 2 * k1)
        k3 = f(dt / 2, state_ + dt / 2 * k2)
        k4 = f(dt, state_ + dt * k3)
        return state_ + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    values = [lyap(v, x)]
    switches = 0
    last = 0.0
    for _ in range(int(seconds / dt)):
        options = [(acc, acc + err) for acc in (a_max, -a_max)
                   for err in {a_error, -a_error} if 10.0 <= v + acc * dt <= 37.0]
        runs = [(lyap(v + acc * dt, step(v, acc, x, law)), acc, law)
                for acc, law in options]
        value, acc, law = max(runs)
        x, v = step(v, acc, x, law), v + acc * dt
        switches += acc != last
        last = acc
        values.append(value)
    return np.array(values), switches


def test_lyapunov_function_decreases_under_the_worst_speed_profile():
    values, switches = _worst_case_run(stability.lyapunov_weight())
    assert switches > 2                          # a bang-bang profile, not a ramp
    assert np.all(np.diff(values) < 0.0)
    assert values[-1] < 0.05 * values[0]
    # the simulation can fail: with Q = I (value 116 at 3.5 m/s^2, at 37 m/s) V rises
    # from the state where x^T N x is largest
    n = stability.lyapunov_rate(VEHICLE, CONTROLLER, W_N_SCHEDULE, 36.0, 1.0,
                                np.eye(5))[2]
    eig, vec = np.linalg.eigh(n)
    x = vec[:, int(np.argmax(np.abs(eig)))]
    values, _ = _worst_case_run(np.eye(5), seconds=0.2, start=(36.0, x))
    assert values[1] > values[0]


def test_lyapunov_function_decreases_with_an_acceleration_error():
    # the law's a_x off by up to 1 m/s^2 (certified with the sharp Q), and by up to
    # 3.5 m/s^2 (a_hat = 0 among them; the Q of the default k_i schedule): V decreases
    # at every step
    values, _ = _worst_case_run(stability.lyapunov_weight(), seconds=4.0, a_error=1.0,
                                seed=5)
    assert np.all(np.diff(values) < 0.0)
    robust = stability.lyapunov_weight(stability.CERTIFICATE_Q_SCHEDULED)
    values, _ = _worst_case_run(robust, seconds=4.0, a_error=3.5, seed=6)
    assert np.all(np.diff(values) < 0.0)


def _worst_case_from_the_peak(settings, q, a_error):
    # the adversary choosing the acceleration and the law's a_x within a_error of it at
    # every step, started at 10.8 m/s (the d_v floor's kink) on the state where x^T N x is
    # largest: V falls at every step
    weight = stability.lyapunov_weight(q)
    n = stability.lyapunov_rate(VEHICLE, CONTROLLER, settings, 10.8, 1.0, weight)[2]
    eig, vec = np.linalg.eigh(n)
    x = vec[:, int(np.argmax(np.abs(eig)))]
    values, switches = _worst_case_run(weight, seconds=4.0, a_error=a_error,
                                       start=(10.8, x), settings=settings)
    assert switches > 2 and np.all(np.diff(values) < 0.0) and values[-1] < 0.5 * values[0]


def test_lyapunov_function_decreases_for_w_n_7_from_20_mps_with_an_acceleration_error():
    # frequency_speed 20 (w_n 7 from 20 m/s) with its robust Q, the law's a_x within
    # 3.5 m/s^2
    _worst_case_from_the_peak(WN20, stability.CERTIFICATE_Q_ROBUST_WN20, 3.5)


@pytest.mark.parametrize(
    'low,names,exact,worst_speed,fails,grade,holds_to,fails_at,robust,certified', [
        # the default since dev-approach (w_n 5 up to 21.4 m/s): wn5 0.757 (4.6 m/s^2),
        # worst at the d_v floor's kink; the law's a_x off by up to 1 m/s^2 (a 10 %
        # grade) 0.981 (1.1 fails); the law's a_x 0 (acceleration_source zero): |a_x| <=
        # 3.37 m/s^2 only (wn5_robust 1.038 at 3.5 m/s^2)
        (5.0, ('wn5', 'wn5', 'wn5_robust'), 0.757, 10.7777, 4.7, 0.981, 1.0, 1.1, 1.038,
         3.37),
        # w_n 7 at every speed (an option): flat 0.829 (4.2 m/s^2) at 37 m/s; flat_grade
        # 0.913 at 1 m/s^2, to 1.2 (1.4 fails); flat_robust 1.134: 3.05 m/s^2
        (7.0, ('flat', 'flat_grade', 'flat_robust'), 0.829, 37.0, 4.3, 0.913, 1.2, 1.4,
         1.134, 3.05)])
def test_certificate_of_the_low_speed_w_n_since_dev_approach(
        low, names, exact, worst_speed, fails, grade, holds_to, fails_at, robust, certified,
        constant_q):
    settings = LaneKeepingParams(low_speed_frequency=low)

    def check(**kwargs):
        return stability.certificate(VEHICLE, CONTROLLER, settings, samples=271, **kwargs)
    cert = check()
    assert cert.holds and cert.weight == names[0] and cert.max_real_eig < -0.3
    assert cert.between == pytest.approx(exact, abs=0.003)
    assert cert.max_norm_speed == pytest.approx(worst_speed, abs=1e-3)
    assert not check(a_max=fails).holds
    cert = check(a_error=1.0)
    assert cert.holds and cert.weight == names[1]
    assert cert.between == pytest.approx(grade, abs=0.003)
    assert check(a_error=holds_to).holds and not check(a_error=fails_at).holds
    cert = check(a_error=3.5)
    assert not cert.holds and cert.weight == names[2]
    assert cert.between == pytest.approx(robust, abs=0.003)
    assert check(a_max=certified, a_error=certified).holds
    if low < 7.0:       # w_n leaves 5 rad/s at 30 * 5 / 7 m/s
        assert check().kinks[1] == pytest.approx(30.0 * 5.0 / 7.0)


def test_the_loaded_schedule_of_q_certifies_the_law_s_a_x_0():
    # dev-sc31: the constant Q's certified the default with acceleration_source zero (the
    # law's a_x 0, an error up to a_max) to 3.37 m/s^2 only (wn5_robust 1.038); the
    # loaded schedule holds at 3.5 (0.788), for w_n 7 at every speed and from 20 m/s too
    for settings, exact, zero in ((LaneKeepingParams(), 0.612, 0.788),
                                  (LaneKeepingParams(low_speed_frequency=7.0), 0.614, 0.790),
                                  (WN20, 0.612, 0.878)):
        cert = stability.certificate(VEHICLE, CONTROLLER, settings)
        assert cert.holds and cert.weight == 'loaded'
        assert cert.between == pytest.approx(exact, abs=0.003)
        cert = stability.certificate(VEHICLE, CONTROLLER, settings, a_error=3.5)
        assert cert.holds and cert.weight == 'loaded'
        assert cert.between == pytest.approx(zero, abs=0.003)
    # not the k_i schedule (an option): its own constant Q still does
    cert = stability.certificate(VEHICLE, CONTROLLER, SCHEDULED, a_error=3.5)
    assert cert.weight == 'scheduled'


def test_lyapunov_function_decreases_with_the_loaded_schedule_and_the_law_s_a_x_0():
    # the adversary against dev-sc31's schedule of Q (V = x^T P(v) x, P(v) from Q(v)),
    # the law's a_x within 3.5 m/s^2 of the true one (a_hat = 0 among them), started
    # inside the blend, at the upper knot and at 37 m/s (the worst value) on the
    # direction where the test's value is attained (the generalized eigenvector of
    # (N, Q)): V falls at every step
    from scipy.linalg import eigh
    settings = LaneKeepingParams()

    def run(knots, speed):
        knots = stability.weight_schedule(knots)
        q, q_v = stability._weight_at(knots, speed, -1.0)
        n = stability.lyapunov_rate(VEHICLE, CONTROLLER, settings, speed, -1.0, q,
                                    weight_rate=q_v)[2]
        eig, vec = eigh(n, q)
        x = vec[:, int(np.argmax(np.abs(eig)))]
        return _worst_case_run(lambda v: stability._weight_at(knots, v)[0], seconds=2.0,
                               a_error=3.5, start=(speed, x), settings=settings)[0]
    for speed in (20.0, 24.0, 36.9):
        values = run(stability.CERTIFICATE_SCHEDULES['loaded'], speed)
        assert np.all(np.diff(values) < 0.0) and values[-1] < 0.8 * values[0], speed
    # the run can fail: the same two Q blended within 1 m/s (certificate 5.5) make V
    # rise inside the blend
    steep = ((23.0, stability.CERTIFICATE_Q_LOW), (24.0, stability.CERTIFICATE_Q_HIGH))
    values = run(steep, 23.5)
    assert values[1] > values[0]


def test_lyapunov_function_decreases_for_the_default_with_a_grade():
    # the default (w_n 5 below 21.4 m/s) with wn5, the law's a_x within 1 m/s^2; and w_n 7
    # at every speed with flat_grade
    _worst_case_from_the_peak(LaneKeepingParams(), stability.CERTIFICATE_Q_WN5, 1.0)
    _worst_case_from_the_peak(LaneKeepingParams(low_speed_frequency=7.0),
                              stability.CERTIFICATE_Q_FLAT_GRADE, 1.0)


def test_robust_over_the_sweep_ranges():
    result = stability.robust_check(VEHICLE, CONTROLLER, LaneKeepingParams())
    assert result.holds and result.cases == 486
    # a plant ten times stiffer than the model is outside: the check sees it diverge
    stiff = VehicleParams(c_f=10 * VEHICLE.c_f, c_r=10 * VEHICLE.c_r)
    assert stability.discrete_radius(VEHICLE, CONTROLLER, LaneKeepingParams(), 37.0,
                                     plant=stiff) > 1.0


def test_discrete_radius_against_continuous_eigenvalues():
    # no lag, no delay, a short period: radius = exp(period * max real eigenvalue)
    settings = LaneKeepingParams()
    a = stability.closed_loop_matrix(VEHICLE, CONTROLLER, settings, 30.0)
    expected = math.exp(1e-4 * float(np.max(np.linalg.eigvals(a).real)))
    radius = stability.discrete_radius(VEHICLE, CONTROLLER, settings, 30.0, period=1e-4,
                                       lag=0.0, delay_steps=0)
    assert radius == pytest.approx(expected, abs=1e-6)
    assert stability.expm(np.array([[0.0, 1.0], [-1.0, 0.0]]) * math.pi) == pytest.approx(
        -np.eye(2), abs=1e-9)


# -- the controller core (the node's state machine) with reference cg_compensated --------

MS = 1_000_000


def _core(law='cg_compensated'):
    # the law on its raw inputs (state_filter: none): the integral checked to the digit.
    # _feed's car does not turn (r = 0) on the map's arc: the map check's fallback would
    # drop the map (test_map_fallback.py), off here
    return SteeringController(VEHICLE, ControllerParams(), 'zero', True, SafetyParams(),
                              law, lane_keeping=LaneKeepingParams(state_filter='none',
                                                                  map_fallback=0.0))


def _feed(core, stamp, y, rho=-1 / 400):
    for name, sample in (('yaw', YawSample(stamp, 0.0, 0.0, 0.0)),
                         ('velocity', VelocitySample(stamp, 30.0, 0.0)),
                         ('road_curvature', CurvatureSample(stamp, rho, 0.0)),
                         ('lateral_error', LateralErrorSample(stamp, 0.0, y))):
        assert core.accept(name, sample, stamp) is None
    return core.compute()


def test_stateless_cg_compensated_reference():
    # y_ref = d_v eps_ss: on the arc with y_cg = eps_r = 0 the error is -d_v eps_ss
    s = state(v_x=30.0, rho=-1 / 400)
    out = steering_law(s, VEHICLE, ControllerParams(reference='cg_compensated'))
    d_v = look_ahead(30.0, 0.0, VEHICLE, CONTROLLER)[0]
    assert out.y_ref == pytest.approx(d_v * steady_relative_yaw(VEHICLE, 30.0, -1 / 400))
    assert out.error == pytest.approx(-out.y_ref)


def test_controller_runs_the_stateful_law_and_resets_it():
    core = _core()
    for k in range(100):
        command = _feed(core, (1000 + 10 * k) * MS, 0.1)
    law = core.law
    assert isinstance(law, CgCompensatedLaw)
    assert law.integral == pytest.approx(0.3 * 0.1 * 0.99)
    # the brush-shaped compliance at the arc's 2.25 m/s^2 (no slip measured: scale eta)
    secant = VEHICLE.eta * brush_shape(2.25 / GRAVITY)[0]
    assert command.law.y_ref == pytest.approx(
        look_ahead(30.0, 0.0, VEHICLE, CONTROLLER)[0]
        * steady_relative_yaw(VEHICLE, 30.0, -1 / 400, secant) - law.integral)
    # stale inputs: the watchdog's command restarts the law
    assert core.safe_command(3000 * MS) is not None
    assert law.integral == 0.0
    _feed(core, 3010 * MS, 0.1)
    _feed(core, 3020 * MS, 0.1)
    assert law.integral == pytest.approx(0.3 * 0.1 * 0.01)
    # a time jump (replay restart) resets the inputs and the law
    _feed(core, 0, 0.1)
    assert core.time_jumps == 1 and law.integral == 0.0
    # a step longer than max_gap (a lost stretch of messages) restarts it too (the
    # first command after the jump holds the last angle: a cut command, so the
    # integral waits one step, docs/lane_keeping.md)
    _feed(core, 10 * MS, 0.1)
    _feed(core, 20 * MS, 0.1)
    assert law.integral > 0.0
    _feed(core, 600 * MS, 0.1)
    assert law.integral == 0.0


def test_controller_paper_law_unchanged():
    core = _core('paper')
    command = _feed(core, 1000 * MS, 0.1)
    expected = steering_law(state(y_cg=0.1, v_x=30.0, rho=-1 / 400), VEHICLE,
                            ControllerParams())
    assert command.law.steering == expected.steering


def test_stability_tool_verdicts(capsys, tmp_path):
    from lookahead_control.tools.lane_keeping_tool import stability_main
    # the paper's 3.5 m/s^2 holds (exit 0); 5.5 m/s^2 fails (exit 1) (the default with
    # the loaded schedule of Q since dev-sc31; with the wn5 Q 4.33, 4.8 failed)
    assert stability_main(['--samples', '55', '--json', str(tmp_path / 's.json')]) == 0
    out = capsys.readouterr().out
    assert 'certificate HOLDS; robust check HOLDS' in out
    assert '| largest certified \\|a_x\\| [m/s^2] | 5.39' in out    # 5.72 on 271 speeds
    assert 'with Q loaded (linear in v_x between its knots at 14, 24 m/s)' in out
    assert stability_main(['--samples', '55', '--a-max', '5.5', '--shipped-q-only']) == 1
    assert 'certificate DOES NOT HOLD' in capsys.readouterr().out
    assert (tmp_path / 's.json').stat().st_size > 100
    # an envelope within 1e-6 m/s of a kink (w_n's at 30 m/s) is that one speed: "1
    # speed" (before: "1 speeds")
    assert stability_main(['--samples', '2', '--v-min', '29.9999999',
                           '--v-max', '30.0000001']) == 0
    out = capsys.readouterr().out
    assert 'checked at 1 speed (' in out and '1 speeds' not in out


def test_reference_rate_uses_the_tangent_compliance():
    # y_ref = d_v (alpha_r(v^2 rho) - l_2 rho): on a clothoid at constant speed its rate
    # is d_v (c_t v^2 - l_2) rho' with the tangent c_t, not the secant c (by hand)
    from lookahead_control.core.lane_keeping import cg_compensated_law
    s = state(v_x=30.0, rho=-1 / 400)
    d_v = look_ahead(30.0, 0.0, VEHICLE, CONTROLLER)[0]
    secant, tangent = 1.2 * VEHICLE.eta, 1.5 * VEHICLE.eta
    out = cg_compensated_law(s, VEHICLE, CONTROLLER, -1 / 400, -1e-4, -1 / 400, 0.0,
                             compliance=secant, tangent_compliance=tangent)
    assert out.y_ref == pytest.approx(d_v * (secant * 900.0 - VEHICLE.l2) * (-1 / 400))
    rate = out.y_v_rate - out.error_rate
    assert rate == pytest.approx(d_v * (tangent * 900.0 - VEHICLE.l2) * -1e-4)


def test_rate_feedforward_sees_at_most_the_jerk_limit():
    # a curvature step of 1/400 within one 5 m preview segment at 37 m/s: rate
    # 37 * 0.0025 / 5 = 0.0185 1/(m s), lateral jerk 25 m/s^3; the feedforward's lead
    # -(v I_z eta / (m l_1) + (eta v^2 - l_2) l_2 / v) multiplies at most 10 / 37^2
    # (the polygon as received: curvature_smoothing 0)
    law = CgCompensatedLaw(VEHICLE, CONTROLLER, LaneKeepingParams(design_friction=0.0,
                                                                  compliance_time_constant=0.0,
                                                                  integral_gain=0.0,
                                                                  curvature_smoothing=0.0))
    step = Preview(np.array([0.0, 5.0, 100.0]), np.array([0.0, -0.0025, -0.0025]))
    out = law.step(state(), step, 0.01)
    v, eta = 37.0, VEHICLE.eta
    lead = -(v * VEHICLE.yaw_inertia * eta / (VEHICLE.mass * VEHICLE.l1)
             + (eta * v * v - VEHICLE.l2) * VEHICLE.l2 / v)
    d_v = look_ahead(v, 0.0, VEHICLE, CONTROLLER)[0]
    assert out.y_ref == pytest.approx(d_v * lead * (-10.0 / v ** 2))
    # the reference's rate keeps the full step rate (measured: clipping it too costs S1)
    rate = out.y_v_rate - out.error_rate
    assert rate == pytest.approx(d_v * (eta * v * v - VEHICLE.l2) * (-0.0185), rel=1e-9)
    # without the clip the lead sees all of it
    free = CgCompensatedLaw(VEHICLE, CONTROLLER, LaneKeepingParams(
        design_friction=0.0, compliance_time_constant=0.0, integral_gain=0.0,
        max_lateral_jerk=0.0, curvature_smoothing=0.0))
    assert free.step(state(), step, 0.01).y_ref == pytest.approx(d_v * lead * -0.0185)


def test_curve_entry_on_the_fiala_plant_at_37_mps():
    # the S2 (clothoid into R = 400 m) at 37 m/s on the nonlinear (Fiala) plant
    # with its 50 ms actuator, ideal sensors: the brush compliance and the rate
    # feedforward keep the CG within 3 cm (2.3 cm measured; the constant compliance
    # without rate feedforward: 4.5 cm); the CG ends on the lane
    from lookahead_control.tools.compare import load_scenarios
    scenario = load_scenarios(['s2_curve_entry'])['s2_curve_entry']
    result = run(scenario, VEHICLE, CgCompensatedLaw(VEHICLE, CONTROLLER),
                 PlantParams(model='nonlinear'), initial_speed=37.0, dt=0.005,
                 preview_distance=100.0)
    assert np.max(np.abs(result['y_cg'])) < 0.03
    assert abs(result['y_cg'][-1]) < 0.005
    old = LaneKeepingParams(design_friction=0.0, rate_feedforward=False, compliance_memory=0.0,
                            curvature_smoothing=0.0)
    before = run(scenario, VEHICLE, CgCompensatedLaw(VEHICLE, CONTROLLER, old),
                 PlantParams(model='nonlinear'), initial_speed=37.0, dt=0.005,
                 preview_distance=100.0)
    assert np.max(np.abs(before['y_cg'])) > 0.04


# -- the node's laws get the road_curvature polygon, as the offline runner gives it ----

CURVE_AHEAD = ((0.0, 0.0), (1.0, -1 / 400), (10.0, -1 / 400), (50.0, -1 / 400))


@pytest.mark.parametrize('law', ['cg_compensated', 'stanley', 'pure_pursuit'])
def test_controller_gives_the_laws_the_polygon_ahead(law):
    # the lead's demo: a ROS run of cg_compensated differed from the offline runner by
    # 0.094 rad where the curve came into the preview: the node handed the laws only the
    # curvature at the CG (the polygon was reduced to curvature and slope on receipt)
    from lookahead_control.core.baselines import baseline_law, BaselineParams
    from lookahead_control.core.laws import preview_from_points
    from lookahead_control.core.samples import curvature_from_points
    core = _core(law)
    stamp = 1000 * MS
    sample = curvature_from_points(stamp, list(reversed(CURVE_AHEAD)))
    assert sample.ahead == CURVE_AHEAD and sample.rho == 0.0
    for name, s in (('yaw', YawSample(stamp, 0.0, 0.0, 0.0)),
                    ('velocity', VelocitySample(stamp, 30.0, 0.0)),
                    ('road_curvature', sample),
                    ('lateral_error', LateralErrorSample(stamp, 0.0, 0.0))):
        assert core.accept(name, s, stamp) is None
    preview = core.preview(stamp)
    np.testing.assert_array_equal(preview.distances, [0.0, 1.0, 10.0, 50.0])
    command = core.compute(stamp)
    fresh = (CgCompensatedLaw(VEHICLE, ControllerParams()) if law == 'cg_compensated'
             else baseline_law(law, VEHICLE, BaselineParams()))
    expected = fresh.step(state(v_x=30.0), preview_from_points(CURVE_AHEAD), 0.0)
    assert command.law.steering == expected.steering
    # the curve 1 m ahead already steers (the curvature at the CG is still 0)
    assert command.law.steering < -1e-3


def test_a_lost_curvature_gives_no_preview_and_a_bad_point_is_refused():
    core = _core()
    stamp = 1000 * MS
    from lookahead_control.core.samples import curvature_from_points
    assert core.accept('road_curvature', curvature_from_points(stamp, CURVE_AHEAD),
                       stamp) is None
    assert core.preview(stamp).distances.size == 4
    later = stamp + int(2 * SafetyParams().input_timeout * 1e9)
    assert core.curvature_lost(later) and not core.preview(later).curvatures.any()
    # a point far ahead that is not finite, or beyond the believable curvature: refused
    for bad, why in (((60.0, math.nan),), 'not finite'), (((60.0, 0.5),), '> 0.2'):
        reason = core.accept('road_curvature',
                             curvature_from_points(later, CURVE_AHEAD + bad), later)
        assert reason is not None and why in reason and 'point 4' in reason, reason


@pytest.mark.parametrize('polygon, why', [
    ([(0.0, 0.001), (math.nan, 0.1), (50.0, 0.002)], 'point 1 = (nan, 0.1) is not finite'),
    ([(0.0, 0.001), (50.0, 0.002), (math.nan, 0.1)], 'point 2 = (nan, 0.1) is not finite'),
    ([(0.0, 0.001), (10.0, 0.001), (10.0, math.nan)], 'point 2 = (10.0, nan) is not finite'),
    ([(0.0, 0.001), (10.0, 0.001), (60.0, 5.0), (60.0, 0.001)], 'point 2 = 5 > 0.2'),
    ([(0.0, 0.001), (10.0, 0.001), (60.0, 0.001), (60.0, -5.0)], 'point 2 = 5 > 0.2'),
])
def test_no_point_of_the_polygon_is_dropped_unchecked(polygon, why):
    # probe7: a point with a NaN distance, or one at a repeated distance, was dropped
    # by the conversion before the safety check saw it: the message was accepted (a
    # curvature of 5 1/m or a NaN let through), though every point is to be checked
    from lookahead_control.core.samples import curvature_from_points
    core = _core()
    stamp = 1000 * MS
    reason = core.accept('road_curvature', curvature_from_points(stamp, polygon), stamp)
    assert reason is not None and why in reason, reason


def test_points_at_one_distance_keep_the_sharpest_mirror_symmetric():
    # probe7: of points at one distance the tuple sort kept the smallest curvature (the
    # one most to the right), whatever the message order: a polygon and its mirror image
    # gave samples that were not mirror images
    from lookahead_control.core.laws import preview_from_points
    from lookahead_control.core.samples import curvature_from_points
    for polygon in ([(0.0, 0.001), (10.0, 0.002), (10.0, -0.003), (20.0, 0.0)],
                    [(0.0, 0.001), (10.0, 0.003), (10.0, -0.002), (20.0, 0.0)],
                    [(0.0, 0.001), (10.0, 0.002), (10.0, -0.002), (20.0, 0.0)]):
        mirror = [(x, -k) for x, k in polygon]
        a, b = curvature_from_points(0, polygon), curvature_from_points(0, mirror)
        assert b.ahead == tuple((x, -k) for x, k in a.ahead)
        assert (b.rho, b.slope) == (-a.rho, -a.slope)
        kept = a.ahead[1][1]
        assert abs(kept) == 0.003 or kept == polygon[1][1]      # sharpest, else first
        np.testing.assert_array_equal(preview_from_points(polygon).curvatures,
                                      [k for _, k in a.ahead])
