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

"""The preview of the drift term's state terms along the lane (lane_keeping.state_preview)."""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

from lane_keeping_node_checks import check_run_time_parameter
from lookahead_control.core.control_law import drift_term, LateralState
from lookahead_control.core.lane_keeping import (cg_compensated_law, CgCompensatedLaw,
                                                 LaneKeepingParams)
from lookahead_control.core.lane_keeping_stability import rate_gain
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
from lookahead_control.core.schedule import look_ahead
from lookahead_control.tools.compare import (DELAY, DT, load_scenarios, NONLINEAR,
                                             PREVIEW_DISTANCE)
import numpy as np
import pytest
from sim_plant.closed_loop_sim import run
from sim_plant.vehicle_model import PlantParams

VEHICLE = VehicleParams()
CONTROLLER = ControllerParams()


def _on_the_lane(v, k=0.0, rho0=0.0):
    """
    Return the slope in the curvature of the drift term's state terms on the lane.

    Through ``drift_term`` itself: the states of a steady turn with the CG on the lane
    (``r = v rho``, ``v_y = l_2 r - v alpha_r(v^2 rho)``, rear slip ``alpha_r(a) = eta a
    (1 + k a)``), no road terms, at the curvature ``rho0``. The state terms are quadratic
    in the curvature, so the central difference is exact for any step.

    :return: ``(F_rho, beta_1, d_v)``.
    """
    d_v = look_ahead(v, 0.0, VEHICLE, CONTROLLER)[0]

    def state_terms(rho):
        a = v * v * rho
        v_y = VEHICLE.l2 * v * rho - v * VEHICLE.eta * a * (1.0 + k * a)
        return drift_term(LateralState(0.0, 0.0, v_y, v * rho, v, 0.0, 0.0, 0.0), VEHICLE,
                          d_v, 0.0, v)

    (f_up, beta_1), (f_down, _) = state_terms(rho0 + 1.0), state_terms(rho0 - 1.0)
    return (f_up - f_down) / 2.0, beta_1, d_v


def test_the_preview_is_the_state_terms_taken_t_ahead_along_the_lane():
    # f_v + g T F_rho rho_ff': the state terms of the states T later on the lane; the
    # reference and its error are the law's without it
    state = LateralState(y_cg=0.1, eps_r=0.01, v_y=0.2, r=0.05, v_x=30.0, rho=0.002,
                         rho_rate=1e-4, a_x=1.5)
    args = (state, VEHICLE, CONTROLLER, 0.0021, 2e-4, 0.0023, 3e-4)
    base = cg_compensated_law(*args, rate_feedforward=True)
    f_rho, beta_1, _ = _on_the_lane(30.0)
    assert f_rho < 0.0
    for g in (0.5, 1.0, 2.0):
        led = cg_compensated_law(*args, rate_feedforward=True, state_preview=g,
                                 lead_time=0.07)
        assert led.steering - base.steering == pytest.approx(-g * 0.07 * f_rho * 3e-4 / beta_1,
                                                             rel=1e-9)
        assert led.f_v - base.f_v == pytest.approx(g * 0.07 * f_rho * 3e-4, rel=1e-9)
        assert (led.y_ref, led.error, led.error_rate) == (base.y_ref, base.error,
                                                          base.error_rate)
        clipped = cg_compensated_law(*args, rate_feedforward=True, state_preview=g,
                                     lead_time=0.07, lead_ff_rate=1e-4)
        assert clipped.steering - base.steering == pytest.approx(
            -g * 0.07 * f_rho * 1e-4 / beta_1, rel=1e-9)
    # on a loaded curve the rear slip alpha_r(a) is not linear: the states move along the
    # lane with its slope, the tangent compliance, not the secant (dev-probe32: the secant
    # left F_rho 10 % short at 37 m/s on R 400 m); with alpha_r(a) = eta a (1 + k a)
    k, rho0, v = 0.05, 0.0025, 30.0
    f_rho = _on_the_lane(v, k, rho0)[0]
    a0 = v * v * rho0
    secant, tangent = VEHICLE.eta * (1.0 + k * a0), VEHICLE.eta * (1.0 + 2.0 * k * a0)
    loaded = {'rate_feedforward': True, 'compliance': secant,
              'tangent_compliance': tangent}
    soft = cg_compensated_law(*args, **loaded)
    led = cg_compensated_law(*args, **loaded, state_preview=1.0, lead_time=0.07)
    assert led.steering - soft.steering == pytest.approx(-0.07 * f_rho * 3e-4 / beta_1,
                                                         rel=1e-6)
    # arrays (a batch) as floats
    batch = cg_compensated_law(state._replace(v_x=np.array([30.0, 30.0])), VEHICLE,
                               CONTROLLER, 0.0021, 2e-4, 0.0023, np.array([3e-4, 3e-4]),
                               rate_feedforward=True, state_preview=1.0, lead_time=0.07)
    one = cg_compensated_law(*args, rate_feedforward=True, state_preview=1.0,
                             lead_time=0.07)
    assert np.array_equal(batch.steering, np.full(2, one.steering))


@pytest.mark.parametrize('v', [20.0, 30.0, 37.0])
def test_it_is_a_third_of_the_road_rate_term_at_highway_speed(v):
    # what the preview amounts to against the drift term's road-rate term d_v v_x rho':
    # 0.35-0.37 of it at 20-37 m/s with T = 70 ms (the first version of this lead, a fixed
    # share 0.35 of that term, dev-ratelead, was this at highway speed and wrong at 10 m/s,
    # 0.87, and for any other T or car)
    f_rho, _, d_v = _on_the_lane(v)
    assert -f_rho * 0.07 / (d_v * v) == pytest.approx(0.36, abs=0.015)


def test_share_0_is_the_law_before_it():
    # S3 at 30 m/s on the noise-free goal plant, every other setting the default: the
    # figures of the code before the lead (2dfcd0d), to 1e-12 (a reduction's rounding
    # may differ between CPUs); likewise with the preview but no feedforward_preview.
    # Without the compliance memory (0 is the estimator before it, dev-memory) and the
    # polygon as received (curvature_smoothing 0, the law before it), without the side
    # force (side_force 0, dev-sc36)
    scen = load_scenarios(['s3_s_bend'])['s3_s_bend']
    for settings in (LaneKeepingParams(state_preview=0.0, compliance_memory=0.0,
                                       curvature_smoothing=0.0, side_force=0.0),
                     LaneKeepingParams(feedforward_preview=0.0, state_preview=3.0,
                                       side_force=0.0)):
        law = CgCompensatedLaw(VEHICLE, CONTROLLER, settings)
        result = run(scen, VEHICLE, law, NONLINEAR, dt=DT, preview_distance=PREVIEW_DISTANCE,
                     delay=DELAY, initial_speed=30.0)
        if settings.feedforward_preview > 0.0:
            peak = float(np.max(np.abs(result['y_cg'])))
            # (dev-sc34: the integral sums the measured y_cg; before, 0.052598083926804234)
            assert peak == pytest.approx(0.05250500751610007, rel=1e-12)
            assert float(np.sum(result['steering_cmd'])) == pytest.approx(
                0.005322603843678664, rel=1e-12)   # before dev-sc34: 0.005332470358732522
        else:
            same = run(scen, VEHICLE, CgCompensatedLaw(VEHICLE, CONTROLLER, dataclasses.replace(
                settings, state_preview=0.0)), NONLINEAR, dt=DT,
                preview_distance=PREVIEW_DISTANCE, delay=DELAY, initial_speed=30.0)
            assert np.array_equal(result['steering_cmd'], same['steering_cmd'])


def test_a_curvature_step_in_the_map_leads_by_at_most_the_jerk_limit():
    # a step of 0.01 1/m in the preview is an impulse of curvature rate: the preview sees
    # the rate clipped to max_lateral_jerk / v_x^2, as the rate feedforward does
    v = 30.0
    distances = np.arange(0.0, 100.0, 5.0)
    preview = SimpleNamespace(distances=distances,
                              curvatures=np.where(distances >= 5.0, 0.01, 0.0))
    state = LateralState(0.0, 0.0, 0.0, 0.0, v, 0.0, 0.0, 0.0)
    # (the demand band off: a step to 9 m/s^2 at 30 m/s reaches it, and the preview is
    # what is tested; the polygon as received: curvature_smoothing 0)
    settings = LaneKeepingParams(state_filter='none', demand_limit=0.0,
                                 curvature_smoothing=0.0)
    steer = {}
    for g in (0.0, 1.0):
        law = CgCompensatedLaw(VEHICLE, CONTROLLER,
                               dataclasses.replace(settings, state_preview=g))
        steer[g] = float(law.step(state, preview, 0.01).steering)
    f_rho, beta_1, _ = _on_the_lane(v)        # at the CG's curvature 0: the model's eta
    most = settings.max_lateral_jerk / (v * v)
    lead = -settings.feedforward_preview * f_rho * most / beta_1
    assert steer[1.0] - steer[0.0] == pytest.approx(lead, rel=1e-9)
    unclipped = lead * (v * 0.01 / 5.0) / most                  # the slope unclipped
    assert unclipped > 5.0 * (steer[1.0] - steer[0.0])


def test_the_estimated_curvature_s_rate_gain_includes_the_preview():
    # while no road_curvature arrives the preview acts on the estimate's rate: feedback,
    # so the stability tools' rate gain must contain it
    for v in (10.0, 37.0):
        base = rate_gain(VEHICLE, CONTROLLER, LaneKeepingParams(state_preview=0.0), v)
        led = rate_gain(VEHICLE, CONTROLLER, LaneKeepingParams(state_preview=1.0), v)
        f_rho, beta_1, _ = _on_the_lane(v)
        assert led - base == pytest.approx(-0.07 * f_rho / beta_1, rel=1e-9)


def _peak(settings, scenario, speed, plant=NONLINEAR, delay=DELAY):
    scen = load_scenarios([scenario])[scenario]
    law = CgCompensatedLaw(VEHICLE, CONTROLLER, settings)
    result = run(scen, VEHICLE, law, plant, dt=DT, preview_distance=PREVIEW_DISTANCE,
                 delay=delay, initial_speed=speed)
    return float(np.max(np.abs(result['y_cg'])))


@pytest.mark.parametrize('scenario,speed', [('s2_curve_entry', 37.0), ('s3_s_bend', 20.0),
                                            ('s3_s_bend', 37.0)])
def test_on_the_design_plant_with_a_70_ms_delay_the_whole_preview_is_the_best(scenario,
                                                                              speed):
    # the linear single-track plant, exact states, linear tyres, the steering 70 ms late
    # (a transport delay, T_ff = 70 ms): the share that best cancels the clothoids' CG
    # error is the derivation's 1 (S2 at 37 m/s: 2.00 / 1.41 / 0.96 / 1.28 cm for
    # 0 / 0.5 / 1 / 1.5; S3 at 20 and 37 m/s: 4.63 / 3.25 / 2.01 / 2.44, 4.01 / 2.83 /
    # 1.81 / 2.31)
    base = LaneKeepingParams(design_friction=0.0, state_filter='none',
                             compliance_time_constant=0.0, integral_gain=0.0)
    peaks = {g: _peak(dataclasses.replace(base, state_preview=g), scenario, speed,
                      PlantParams(), 0.07) for g in (0.0, 0.5, 1.0, 1.5)}
    assert peaks[1.0] < min(peaks[0.5], peaks[1.5]), peaks
    assert peaks[1.0] < 0.6 * peaks[0.0], peaks


def test_on_the_noise_free_goal_plant_the_default_takes_a_third_off_the_clothoids():
    # nonlinear plant, 50 ms actuator, 20 ms delay, 37 m/s (docs/lane_keeping.md,
    # "Preview of the drift term's state terms"): without it 2.67 / 5.89 / 5.70 cm on
    # S2-S4, with the default 1.59 / 3.35 / 4.52 cm (the polygon as received, as then)
    peaks = {(g, s): _peak(LaneKeepingParams(state_preview=g, curvature_smoothing=0.0), s,
                           37.0)
             for g in (0.0, 1.0) for s in ('s2_curve_entry', 's3_s_bend', 's4_lane_change')}
    assert LaneKeepingParams().state_preview == 1.0
    assert peaks[0.0, 's2_curve_entry'] > 0.025 and peaks[1.0, 's2_curve_entry'] < 0.019
    assert peaks[0.0, 's3_s_bend'] > 0.055 and peaks[1.0, 's3_s_bend'] < 0.04
    assert peaks[0.0, 's4_lane_change'] > 0.055 and peaks[1.0, 's4_lane_change'] < 0.05


@pytest.mark.parametrize('value', [-0.1, 3.5, math.nan, math.inf])
def test_a_bad_setting_is_refused_naming_it(value):
    with pytest.raises(ParameterError, match='lane_keeping.state_preview'):
        LaneKeepingParams(state_preview=value)


def test_the_node_takes_it_at_run_time_and_refuses_it_out_of_range(context):
    check_run_time_parameter(context, 'state_preview', 3.0, 'previewed', 0.8, 3.5)


def test_the_bench_prints_the_law_s_runs(capsys):
    # python -m bench.state_preview: its noise-free row is the offline runner's run
    from bench.state_preview import main
    assert main(['--share', '0.5', '--speeds', '37', '--no-corners']) == 0
    row = next(line for line in capsys.readouterr().out.splitlines()
               if line.startswith('| 0.5 | 37 m/s |'))
    peaks = [float(v) for v in row.split('|')[3].split('/')]
    direct = _peak(LaneKeepingParams(state_preview=0.5), 's2_curve_entry', 37.0)
    assert peaks[1] == pytest.approx(100.0 * direct, abs=0.005)
