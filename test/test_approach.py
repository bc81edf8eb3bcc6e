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


"""Engaged off the lane: the approach heading (lane_keeping.approach_heading, dev-approach)."""

from __future__ import annotations

from dataclasses import replace

from engaged_runs import engaged_off_the_lane as _lost
from lookahead_control.core import lane_keeping_stability as stability
from lookahead_control.core.config import load_vehicle
from lookahead_control.core.control_law import LateralState
from lookahead_control.core.lane_keeping import (approach_error, approach_limit,
                                                 CgCompensatedLaw, integral_gain_at,
                                                 LaneKeepingParams, loop_gains)
from lookahead_control.core.params import ControllerParams
from lookahead_control.core.schedule import look_ahead
from lookahead_control.tools.compare import load_scenarios, NONLINEAR
import numpy as np
import pytest
from sim_plant.closed_loop_sim import run
from sim_plant.vehicle_model import PlantParams

VEHICLE = load_vehicle(None)
CONTROLLER = ControllerParams()
#: the previous default (dev-wnflat): w_n falling to 3 rad/s below 12.9 m/s, no clip,
#: no demand limit
OLD = LaneKeepingParams(low_speed_frequency=3.0, approach_heading=0.0, demand_limit=0.0,
                        side_force=0.0)
#: w_n 7 at every speed without the clip (f8dd7e1, withdrawn: it lost the lane from
#: 1.2-2 m off at 4-12 m/s, dev-probe33), as it was: no demand limit
UNCLIPPED = LaneKeepingParams(low_speed_frequency=7.0, approach_heading=0.0,
                              demand_limit=0.0, side_force=0.0)
SPEEDS = [5.0, 7.0, 10.0, 12.0, 15.0, 20.0, 25.0, 30.0]


def test_the_default_w_n_is_5_up_to_21_mps_with_a_0_1_rad_approach():
    settings = LaneKeepingParams()
    assert (settings.low_speed_frequency, settings.approach_heading) == (5.0, 0.1)
    for v in (4.0, 10.0, 20.0):
        assert loop_gains(settings, v) == pytest.approx((25.0, 10.0))
    assert loop_gains(settings, 37.0) == pytest.approx((49.0, 14.0))


def test_an_approach_heading_that_would_crawl_or_not_clip_is_refused():
    # dev-probe35: 1e-6 rad left the car 1 m off after 30 s; 1.0 rad is no clip at all
    # (w_n 7 without it lost the lane); 0.2 rad lost the CommonRoad car from 2 m with 50 ms
    from lookahead_control.core.params import ParameterError
    for bad, said in ((1e-6, 'crawling'), (0.01, '0.02-0.15 rad'), (0.16, 'out of range'),
                      (1.0, 'out of range')):
        with pytest.raises(ParameterError, match=said):
            LaneKeepingParams(approach_heading=bad)
    for good in (0.0, 0.02, 0.15):
        assert LaneKeepingParams(approach_heading=good).approach_heading == good


@pytest.mark.parametrize('speed,clip', [(10.0, 0.482), (20.0, 1.632), (37.0, 5.071)])
def test_approach_limit_hand_values(speed, clip):
    # b = heading (d_v + k_d v_x / k_p): Table 1 d_v 1.96 / 10.61 / 40.14 m, k_d / k_p
    # = 14 / 49
    d_v = float(look_ahead(speed, 0.0, VEHICLE, CONTROLLER)[0])
    assert approach_limit(0.1, d_v, speed, 49.0, 14.0) == pytest.approx(clip, abs=1e-3)
    assert approach_limit(0.0, d_v, speed, 49.0, 14.0) == float('inf')


def test_approach_error_clips_only_the_offset_part():
    # error = offset + heading part; inside the clip unchanged, outside the offset part
    # at the clip, the heading part kept (scalars and arrays alike)
    assert approach_error(0.3, 0.2, 0.5) == pytest.approx(0.3)
    assert approach_error(2.4, 3.0, 0.5) == pytest.approx(2.4 - 3.0 + 0.5)
    assert approach_error(-3.5, -3.0, 0.5) == pytest.approx(-3.5 + 3.0 - 0.5)
    out = approach_error(np.array([0.3, 2.4]), np.array([0.2, 3.0]), np.array([0.5, 0.5]))
    assert out == pytest.approx([0.3, -0.1])
    assert approach_error(2.4, 3.0, float('inf')) == 2.4


def test_far_off_the_lane_the_car_closes_at_the_approach_heading():
    # the design plant without actuator, engaged 8 m off: the relative heading settles at
    # -approach_heading (the equilibrium k_p (b + d_v eps_r) + k_d v_x eps_r = 0 that
    # approach_limit solves); the old law asked for the whole offset (eps_r -0.62 rad at
    # 10 m/s)
    scenario = replace(load_scenarios(['s0_straight'])['s0_straight'], duration=3.0)
    speeds = np.array([10.0, 20.0])
    for settings, lo, hi in ((LaneKeepingParams(state_filter='none'), -0.1005, -0.0995),
                             (replace(OLD, state_filter='none'), -1.0, -0.3)):
        law = CgCompensatedLaw(VEHICLE, CONTROLLER, settings)
        result = run(scenario, VEHICLE, law, None, initial_speed=speeds, initial_error=8.0,
                     dt=0.001)
        at = np.searchsorted(result.time, 1.5)
        heading = result['eps_r'][at]
        if settings.approach_heading > 0.0:
            assert np.all((heading > lo) & (heading < hi)), heading
        else:
            assert np.min(result['eps_r'][:at], axis=0)[0] < hi


@pytest.mark.parametrize('offset', [1.2, 2.0, 4.0])
def test_engaged_metres_off_the_default_comes_back_where_the_unclipped_w_n_7_did_not(offset):
    # goal plant without noise, 20 ms: the default recovers from 1.2-4 m at 5-30 m/s with
    # at most 6.2 cm of overshoot (the previous default: 7.3 cm, 4 m at 5 m/s); w_n 7
    # without the clip slewed the wheel into a growing oscillation (dev-probe33), w_n 5
    # without it from 3 m at 10 m/s
    lost, over = _lost(LaneKeepingParams(), NONLINEAR, SPEEDS, offset)
    assert lost == [] and np.max(over) < 0.07, over
    lost, _ = _lost(UNCLIPPED, NONLINEAR, [10.0], offset)
    assert lost == [10.0]


def test_engaged_6_m_off_at_4_mps_the_car_arrives_at_0_4_mps():
    # 0.1 rad at 4 m/s: 0.4 m/s toward the lane, 6 m in about 16 s; no overshoot (3.2 cm
    # at 5 m/s)
    lost, over = _lost(LaneKeepingParams(), NONLINEAR, [4.0, 5.0], 6.0, seconds=30.0)
    assert lost == [] and np.max(over) < 0.05, over


def test_engaged_4_m_off_at_30_mps_with_100_ms_of_delay():
    # found in dev-approach: the previous default diverged here (the CG 500 m off); the
    # approach heading brings it back with 6.4 cm of overshoot
    speeds = [10.0, 20.0, 25.0, 30.0]
    lost, over = _lost(LaneKeepingParams(), NONLINEAR, speeds, 4.0, delay=0.1)
    assert lost == [] and np.max(over) < 0.09, over
    lost, _ = _lost(OLD, NONLINEAR, speeds, 4.0, delay=0.1)
    assert lost == [30.0]


def test_100_ms_of_delay_near_the_lane_with_a_heading_error():
    # dev-probe35: w_n 7 at every speed (with the approach heading, 78625d8) went into a
    # limit cycle at the wheel's limits or off the road with 100 ms of delay from small
    # offsets and a 0.1 rad heading error (10 m/s 0.3 m: +-2.2 m; 20 m/s 0.6 m: 355 m);
    # the default (w_n 5 below 21.4 m/s) comes back, as the previous default did
    speeds, offsets = [10.0, 13.0, 20.0, 25.0], [0.3, 1.0, 0.6, 2.0]
    lost, _ = _lost(LaneKeepingParams(), NONLINEAR, speeds, offsets, seconds=30.0,
                    delay=0.1, heading=0.1)
    assert lost == []
    lost, _ = _lost(replace(UNCLIPPED, approach_heading=0.1), NONLINEAR, speeds, offsets,
                    seconds=30.0, delay=0.1, heading=0.1)
    assert lost == speeds


def test_the_independent_car_near_the_lane_with_a_heading_error_and_50_ms():
    # dev-probe35: on the CommonRoad car with 50 ms and a 0.1 rad heading error w_n 7 at
    # every speed spun from 0.3-1 m at 10-20 m/s; the default comes back
    from sim_plant.commonroad_plant import controller_vehicle
    car = controller_vehicle(2)
    plant = PlantParams(model='commonroad_mb', vehicle_id=2)
    speeds, offsets = [10.0, 15.0, 20.0], [0.3, 1.0, 1.0]
    lost, _ = _lost(LaneKeepingParams(), plant, speeds, offsets, car, car, 0.002, 25.0,
                    0.05, heading=0.1)
    assert lost == []
    lost, _ = _lost(replace(UNCLIPPED, approach_heading=0.1), plant, speeds, offsets, car,
                    car, 0.002, 25.0, 0.05, heading=0.1)
    assert lost != []


def test_engaged_4_m_off_on_softer_tyres_low_friction_and_50_ms():
    # C x0.7, mass x1.2, mu 0.7, 50 ms: overshoot at most 14.4 cm (30 m/s); the previous
    # default 48 cm at 15 m/s
    soft = replace(VEHICLE, c_f=VEHICLE.c_f * 0.7, c_r=VEHICLE.c_r * 0.7,
                   mass=VEHICLE.mass * 1.2)
    plant = replace(NONLINEAR, friction=0.7)
    lost, over = _lost(LaneKeepingParams(), plant, SPEEDS, 4.0, vehicle=soft, delay=0.05)
    assert lost == [] and np.max(over) < 0.16, over
    _, before = _lost(OLD, plant, SPEEDS, 4.0, vehicle=soft, delay=0.05)
    assert np.max(before) > 0.4


@pytest.mark.parametrize('delay', [0.02, 0.05])
def test_engaged_3_m_off_on_the_independent_car(delay):
    # the CommonRoad multi-body BMW at 5-25 m/s: back with at most 7.6 cm of overshoot;
    # without the clip w_n 7 spun it (dev-probe33; 2.5 m at 15-20 m/s, dev-probe34)
    from sim_plant.commonroad_plant import controller_vehicle
    car = controller_vehicle(2)
    plant = PlantParams(model='commonroad_mb', vehicle_id=2)
    speeds = [5.0, 7.0, 10.0, 15.0, 20.0, 25.0]
    lost, over = _lost(LaneKeepingParams(), plant, speeds, 3.0, car, car, 0.002, 15.0, delay)
    assert lost == [] and np.max(over) < 0.085, over
    if delay == 0.05:
        lost, _ = _lost(UNCLIPPED, plant, [10.0], 1.0, car, car, 0.002, 15.0, delay)
        assert lost == [10.0]


def test_the_integral_and_its_band_clock_stand_while_the_offset_is_clipped():
    # 3 m off for 3 s (longer than integral_band_time): with the clip the integral and the
    # band's clock stay at 0 (before, the clock ran out after 2 s and the integral wound to
    # its 0.5 m clamp during the approach: 18-30 cm of overshoot at 30 m/s)
    for settings, clocked in ((LaneKeepingParams(state_filter='none'), False),
                              (replace(UNCLIPPED, state_filter='none'), True)):
        law = CgCompensatedLaw(VEHICLE, CONTROLLER, settings)
        law.reset()
        for _ in range(300):
            law.step(LateralState(3.0, 0.0, 0.0, 0.0, 20.0, 0.0, 0.0, 0.0), None, 0.01)
        assert (law.outside_time > 2.0) is clocked
        assert (law.integral != 0.0) is clocked
    batch = CgCompensatedLaw(VEHICLE, CONTROLLER, LaneKeepingParams(state_filter='none'))
    batch.reset()
    for _ in range(300):
        batch.step(LateralState(np.array([3.0, 0.1]), np.zeros(2), np.zeros(2), np.zeros(2),
                                np.full(2, 20.0), np.zeros(2), np.zeros(2), np.zeros(2)),
                   None, 0.01)
    assert list(batch.clipped) == [True, False]
    assert batch.integral[0] == 0.0 and batch.integral[1] != 0.0


@pytest.mark.parametrize('v_x', [10.0, 37.0])
def test_the_approach_loop_of_the_stability_check_is_the_law_far_off_the_lane(v_x):
    # the law's steering differentiated numerically 8 m off the lane (clipped at 0.60 /
    # 5.07 m): the gains the check uses, feedback_gain with k_i = 0 and no y_cg gain;
    # 0.2 m off (inside the clip) the y_cg gain is back
    import copy
    # (the demand band off: 8 m off it holds the command, and the check is the loop's)
    settings = LaneKeepingParams(state_filter='none', compliance_time_constant=0.0,
                                 demand_limit=0.0)
    gains = stability.feedback_gain(VEHICLE, CONTROLLER, replace(settings, integral_gain=0.0),
                                    v_x)
    running = stability.feedback_gain(VEHICLE, CONTROLLER, settings, v_x)
    # inside, the integral runs: its rate k_i y_cg in the reference's rate, and the law
    # integrates within the step (k_I k_i dt more)
    inside = running[0] + running[4] * integral_gain_at(settings, v_x) * 0.01
    for y0, y_gain in ((8.0, 0.0), (0.2, inside)):
        law = CgCompensatedLaw(VEHICLE, CONTROLLER, settings)
        base = [y0, 0.001, 0.01, 0.002]
        for _ in range(5):
            law.step(LateralState(*base, v_x, 0.0, 0.0, 0.0), None, 0.01)

        def steering(x):
            twin = copy.deepcopy(law)
            return float(twin.step(LateralState(*x, v_x, 0.0, 0.0, 0.0), None, 0.01).steering)
        h = 1e-6
        slopes = [(steering(base[:i] + [base[i] + h] + base[i + 1:])
                   - steering(base[:i] + [base[i] - h] + base[i + 1:])) / (2 * h)
                  for i in range(4)]
        assert slopes[1:] == pytest.approx(list(gains[1:4]), rel=1e-5, abs=1e-7)
        assert slopes[0] == pytest.approx(y_gain, rel=1e-5, abs=1e-7)


def test_the_approach_loop_is_checked_over_the_mismatch_grid():
    # the sampled loop with the CG offset clipped and the integral held, without y_cg:
    # stable over 486 mismatch cases on exact states and on the filter's estimate
    settings = LaneKeepingParams()
    exact = stability.robust_check(VEHICLE, CONTROLLER, settings, approach=True)
    filtered = stability.robust_check(VEHICLE, CONTROLLER, settings, approach=True,
                                      filtered=True)
    assert exact.holds and filtered.holds and exact.cases == 486
    assert 0.99 < exact.max_radius < 0.996 and 0.99 < filtered.max_radius < 0.996


def test_the_approach_loop_drops_only_the_closing_mode():
    # in the coordinates of the estimate's error the plant's y_cg drives nothing (a unit
    # column) and nothing drives the held integral (a unit row): two eigenvalues exactly
    # 1, the rest the reduced matrix's spectrum (C_f x0.7, mass x1.2, 20 ms, 15 m/s)
    settings = LaneKeepingParams()
    plant = replace(VEHICLE, c_f=VEHICLE.c_f * 0.7, mass=VEHICLE.mass * 1.2)
    kwargs = {'plant': plant, 'delay_steps': 2, 'approach': True}
    reduced = stability.filtered_loop(VEHICLE, CONTROLLER, settings, 15.0, **kwargs)
    full = stability.filtered_loop(VEHICLE, CONTROLLER, settings, 15.0, closing_mode=True,
                                   **kwargs)
    n = full.shape[0]
    assert n == reduced.shape[0] + 2
    plant_states = 5                    # y_cg, eps_r, v_y, r and the actuator's angle
    unit = np.eye(n)
    assert full[:, 0] == pytest.approx(unit[:, 0], abs=1e-12)
    # the integral, right after the plant
    assert full[plant_states, :] == pytest.approx(unit[plant_states, :], abs=1e-12)
    rest = np.sort_complex(np.linalg.eigvals(reduced))
    every = np.linalg.eigvals(full)
    ones = np.abs(every - 1.0) < 1e-9
    assert np.count_nonzero(ones) == 2
    assert np.sort_complex(every[~ones]) == pytest.approx(rest, abs=1e-9)
    assert np.max(np.abs(rest)) < 1.0
    assert stability.discrete_radius(VEHICLE, CONTROLLER, settings, 15.0, plant=plant,
                                     delay_steps=2, approach=True) < 1.0


def test_the_stability_tool_reports_the_approach_row(capsys):
    from lookahead_control.tools.lane_keeping_tool import stability_main
    assert stability_main(['--samples', '28']) == 0
    out = capsys.readouterr().out
    assert 'approach (CG offset clipped, integral held) | 0.99' in out
    assert 'in the approach HOLDS' in out
    assert 'with Q loaded' in out     # wn5 before the schedule of Q (dev-sc31)
