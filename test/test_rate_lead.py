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

"""The lead on the curvature rate (lane_keeping.rate_lead)."""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

from lookahead_control.core.control_law import LateralState
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

VEHICLE = VehicleParams()
CONTROLLER = ControllerParams()


def _beta_1(d_v):
    # written out again: beta_1 = C_f (1/m + l_1 d_v / I_z)
    return VEHICLE.c_f * (1.0 / VEHICLE.mass + VEHICLE.l1 * d_v / VEHICLE.yaw_inertia)


def test_the_lead_is_the_drift_term_s_road_terms_once_more_times_the_share():
    # steering += g d_v (v_x rho_ff' + a_x rho_ff) / beta_1: the lane's kinematics in
    # f_v (-d_v (a_x rho + v_x rho')) taken a share g more, at the drift term's curvature
    state = LateralState(y_cg=0.1, eps_r=0.01, v_y=0.2, r=0.05, v_x=30.0, rho=0.002,
                         rho_rate=1e-4, a_x=1.5)
    args = (state, VEHICLE, CONTROLLER, 0.0021, 2e-4, 0.0023, 3e-4)
    base = cg_compensated_law(*args, rate_feedforward=True)
    d_v = look_ahead(30.0, 1.5, VEHICLE, CONTROLLER)[0]
    for g in (0.3, 1.0):
        led = cg_compensated_law(*args, rate_feedforward=True, rate_lead=g)
        extra = g * d_v * (30.0 * 3e-4 + 1.5 * 0.0023) / _beta_1(d_v)
        assert led.steering - base.steering == pytest.approx(extra, rel=1e-9)
        assert base.f_v - led.f_v == pytest.approx(extra * _beta_1(d_v), rel=1e-9)
        # the reference and its error are the law's without the lead
        assert (led.y_ref, led.error, led.error_rate) == (base.y_ref, base.error,
                                                          base.error_rate)
        clipped = cg_compensated_law(*args, rate_feedforward=True, rate_lead=g,
                                     lead_ff_rate=1e-4)
        extra = g * d_v * (30.0 * 1e-4 + 1.5 * 0.0023) / _beta_1(d_v)
        assert clipped.steering - base.steering == pytest.approx(extra, rel=1e-9)


def test_share_0_is_the_law_before_it():
    # S3 at 30 m/s on the noise-free goal plant, every other setting the default: the
    # figures of the code before the lead (2dfcd0d), to 1e-12 (a reduction's rounding
    # may differ between CPUs)
    scen = load_scenarios(['s3_s_bend'])['s3_s_bend']
    law = CgCompensatedLaw(VEHICLE, CONTROLLER, LaneKeepingParams(rate_lead=0.0))
    result = run(scen, VEHICLE, law, NONLINEAR, dt=DT, preview_distance=PREVIEW_DISTANCE,
                 delay=DELAY, initial_speed=30.0)
    peak = float(np.max(np.abs(result['y_cg'])))
    assert peak == pytest.approx(0.052598083926804234, rel=1e-12)
    assert float(np.sum(result['steering_cmd'])) == pytest.approx(0.005332470358732522,
                                                                  rel=1e-12)


def test_a_curvature_step_in_the_map_leads_by_at_most_the_jerk_limit():
    # a step of 0.01 1/m in the preview is an impulse of curvature rate: the lead sees
    # the rate clipped to max_lateral_jerk / v_x^2, as the rate feedforward does
    v = 30.0
    preview = SimpleNamespace(distances=np.arange(0.0, 100.0, 5.0),
                              curvatures=np.where(np.arange(0.0, 100.0, 5.0) >= 5.0,
                                                  0.01, 0.0))
    state = LateralState(0.0, 0.0, 0.0, 0.0, v, 0.0, 0.0, 0.0)
    settings = LaneKeepingParams(state_filter='none', feedforward_preview=0.07)
    steer = {}
    for g in (0.0, 0.5):
        law = CgCompensatedLaw(VEHICLE, CONTROLLER, dataclasses.replace(settings,
                                                                        rate_lead=g))
        steer[g] = float(law.step(state, preview, 0.01).steering)
    d_v = look_ahead(v, 0.0, VEHICLE, CONTROLLER)[0]
    most = settings.max_lateral_jerk / (v * v)
    assert steer[0.5] - steer[0.0] == pytest.approx(0.5 * d_v * v * most / _beta_1(d_v),
                                                    rel=1e-9)
    unclipped = 0.5 * d_v * v * 0.01 / 5.0 * v / _beta_1(d_v)       # the slope unclipped
    assert unclipped > 5.0 * (steer[0.5] - steer[0.0])


def test_the_estimated_curvature_s_rate_gain_includes_the_lead():
    # while no road_curvature arrives the lead acts on the estimate's rate: feedback,
    # so the stability tools' rate gain must contain it
    for v in (10.0, 37.0):
        base = rate_gain(VEHICLE, CONTROLLER, LaneKeepingParams(rate_lead=0.0), v)
        led = rate_gain(VEHICLE, CONTROLLER, LaneKeepingParams(rate_lead=0.5), v)
        d_v = look_ahead(v, 0.0, VEHICLE, CONTROLLER)[0]
        assert led - base == pytest.approx(0.5 * d_v * v / _beta_1(d_v), rel=1e-9)


@pytest.mark.parametrize('v', [20.0, 30.0, 37.0])
def test_the_default_is_the_drift_term_s_state_terms_previewed_along_the_lane(v):
    # why 0.35: the drift term's state terms -(beta_1 (v_y + l_1 r) + beta_2 (v_y - l_2
    # r)) / v_x are evaluated on the states the lagging steering has not moved yet; held
    # on the lane (r = v_x rho, v_y = -v_x eps_ss) they move with rho, so the steering
    # they give is T_ff rho' late. Taking them T_ff ahead is a lead T_ff |F_rho| rho' on
    # f_v, the share |F_rho| T_ff / (d_v v_x) of the road-rate term: 0.35-0.37 at
    # 20-37 m/s (written out again here from the single-track model)
    m, iz, l1, l2 = VEHICLE.mass, VEHICLE.yaw_inertia, VEHICLE.l1, VEHICLE.l2
    d_v = look_ahead(v, 0.0, VEHICLE, CONTROLLER)[0]
    beta_1 = _beta_1(d_v)
    beta_2 = VEHICLE.c_r * (1.0 / m - l2 * d_v / iz)
    eps_ss = VEHICLE.eta * v * v - l2                   # per unit curvature
    v_y, r = -v * eps_ss, v
    f_rho = -(beta_1 * (v_y + l1 * r) + beta_2 * (v_y - l2 * r)) / v
    settings = LaneKeepingParams()
    share = abs(f_rho) * settings.feedforward_preview / (d_v * v)
    assert settings.rate_lead == pytest.approx(share, abs=0.03)


def _peaks(settings, speed=37.0):
    out = {}
    for scenario in ('s2_curve_entry', 's3_s_bend', 's4_lane_change'):
        scen = load_scenarios([scenario])[scenario]
        law = CgCompensatedLaw(VEHICLE, CONTROLLER, settings)
        result = run(scen, VEHICLE, law, NONLINEAR, dt=DT, preview_distance=PREVIEW_DISTANCE,
                     delay=DELAY, initial_speed=speed)
        out[scenario] = float(np.max(np.abs(result['y_cg'])))
    return out


def test_on_the_noise_free_goal_plant_the_default_lead_takes_a_third_off_the_clothoids():
    # nonlinear plant, 50 ms actuator, 20 ms delay, 37 m/s (docs/lane_keeping.md, "The
    # curvature-rate lead"): without the lead 2.67 / 5.89 / 5.70 cm on S2-S4, with the
    # default 0.35 1.74 / 3.68 / 4.45 cm
    without, led = _peaks(LaneKeepingParams(rate_lead=0.0)), _peaks(LaneKeepingParams())
    assert without['s2_curve_entry'] > 0.025 and led['s2_curve_entry'] < 0.02
    assert without['s3_s_bend'] > 0.055 and led['s3_s_bend'] < 0.042
    assert without['s4_lane_change'] > 0.055 and led['s4_lane_change'] < 0.05


@pytest.mark.parametrize('value', [-0.1, 2.5, math.nan, math.inf])
def test_a_bad_setting_is_refused_naming_it(value):
    with pytest.raises(ParameterError, match='lane_keeping.rate_lead'):
        LaneKeepingParams(rate_lead=value)


def test_the_node_takes_it_at_run_time_and_refuses_it_out_of_range(context):
    from lookahead_control.ros.controller_node import ControllerNode
    from rclpy.parameter import Parameter
    node = ControllerNode(context=context)
    try:
        descriptor = node.describe_parameters(['lane_keeping.rate_lead'])[0]
        assert descriptor.floating_point_range[0].to_value == 2.0
        assert 'lead' in descriptor.description
        ok = node.set_parameters([Parameter('lane_keeping.rate_lead', value=0.8)])[0]
        assert ok.successful, ok.reason
        assert node.core.lane_keeping.rate_lead == 0.8
        refused = node.set_parameters([Parameter('lane_keeping.rate_lead', value=2.5)])[0]
        assert not refused.successful
        assert node.core.lane_keeping.rate_lead == 0.8
    finally:
        node.destroy_node()
