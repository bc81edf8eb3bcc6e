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

"""Metric definitions against independent calculations (issue 12 item 9)."""

import math

from lookahead_control.analysis.metrics import (curvature_step, QUANTITIES, run_metrics,
                                                step_metrics)
from lookahead_control.core.params import ControllerParams, VehicleParams
from lookahead_control.core.schedule import look_ahead
from lookahead_control.core.zero_dynamics import zero_dynamics
import numpy as np
import pytest
from sim_plant.closed_loop_sim import run
from sim_plant.road import Road, Segment
from sim_plant.scenario import InitialState, paper_scenario, Scenario
from sim_plant.speed_profile import SpeedProfile
from sim_plant.vehicle_model import PlantParams

VEHICLE = VehicleParams()
TIME = np.arange(0.0, 20.0, 0.01)


def _second_order_step(zeta, w=3.0, t=TIME):
    wd = w * math.sqrt(1.0 - zeta ** 2)
    return 1.0 - np.exp(-zeta * w * t) * (np.cos(wd * t) + zeta / math.sqrt(1.0 - zeta ** 2)
                                          * np.sin(wd * t))


def _settling_by_brute_force(t, y, final, band):
    outside = np.nonzero(np.abs(y - final) > band)[0]
    return t[outside[-1] + 1]


@pytest.mark.parametrize('zeta', [0.1, 0.2, 0.35, 0.5, 0.7, 0.77])
def test_step_metrics_of_second_order_steps_with_known_zeta(zeta):
    t = np.arange(0.0, 40.0, 0.01)
    y = -0.02 * _second_order_step(zeta, t=t)     # a negative step of 0.02 rad
    m = step_metrics(t, y, 0.0)
    overshoot = math.exp(-math.pi * zeta / math.sqrt(1.0 - zeta ** 2))
    assert m.overshoot == pytest.approx(overshoot, rel=1e-3)
    assert m.damping_ratio == pytest.approx(zeta, abs=2e-3)
    assert m.final == pytest.approx(-0.02, rel=1e-4)
    assert m.settling_time == pytest.approx(
        _settling_by_brute_force(t, y, -0.02, 0.02 * 0.02), abs=0.011)
    assert m.note == ''


def test_overdamped_step_has_no_damping_ratio_but_says_why():
    w = 3.0
    y = 1.0 - np.exp(-w * TIME) * (1.0 + w * TIME)       # zeta = 1
    m = step_metrics(TIME, y, 0.0)
    assert m.overshoot == 0.0
    assert math.isnan(m.damping_ratio) and 'monotonic' in m.note
    y = _second_order_step(0.9)                           # overshoot 0.15 %
    m = step_metrics(TIME, y, 0.0)
    assert m.overshoot == pytest.approx(math.exp(-math.pi * 0.9 / math.sqrt(0.19)), rel=1e-2)
    assert math.isnan(m.damping_ratio) and 'zeta > 0.78' in m.note


@pytest.mark.parametrize('zeta', [0.15, 0.3, 0.6])
@pytest.mark.parametrize('final', [0.0, 1e-6, -3e-5])
def test_response_with_a_final_value_near_zero(zeta, final):
    # the relative yaw of the paper's car at about 14.4 m/s: a pulse that returns to
    # (nearly) its start; the old ratio divided by the final value (overshoot 36.6, 492,
    # damping ratio -0.75)
    w = 2.0
    sigma, wd = zeta * w, w * math.sqrt(1.0 - zeta ** 2)
    x = final + 0.01 * np.exp(-sigma * TIME) * np.sin(wd * TIME) - final * np.exp(
        -sigma * TIME) * np.cos(wd * TIME)
    m = step_metrics(TIME, x, 0.0)
    assert math.isnan(m.overshoot) and 'pulse, not a step' in m.note
    assert m.damping_ratio == pytest.approx(zeta, abs=2e-3)
    top = math.atan2(wd, sigma) / wd                  # where the pulse peaks
    assert m.excursion == pytest.approx(0.01 * math.exp(-sigma * top) * wd / w, rel=1e-2)


def test_damping_with_measurement_noise():
    rng = np.random.default_rng(7)
    y = _second_order_step(0.3) + rng.normal(0.0, 0.005, TIME.size)
    m = step_metrics(TIME, y, 0.0)
    assert m.damping_ratio == pytest.approx(0.3, abs=0.03)


def test_two_modes_are_not_reported_as_one_damping_ratio():
    # a fast well-damped mode and a slow real one: the two extrema come from different
    # modes; their ratio is no damping ratio
    x = (0.5 * np.exp(-5.0 * TIME) * np.sin(10.0 * TIME)
         - 0.3 * np.exp(-1.0 * TIME) * np.sin(1.5 * TIME))
    m = step_metrics(TIME, x, 0.0)
    assert math.isnan(m.damping_ratio) and 'not second-order' in m.note


def test_short_and_unsettled_responses_are_empty_with_a_reason():
    m = step_metrics(TIME[:150], np.ones(150), 0.0)
    assert math.isnan(m.overshoot) and math.isnan(m.damping_ratio) and 'too short' in m.note
    y = np.sin(3.0 * TIME)                                   # never settles
    m = step_metrics(TIME, y, 0.0)
    assert math.isnan(m.damping_ratio) and 'not settled' in m.note


@pytest.mark.parametrize('schedule,speed', [('fixed', 20.0), ('fixed', 30.0),
                                            ('fixed', 37.0)])
def test_damping_of_the_free_zero_dynamics_equals_its_eigenvalues(schedule, speed):
    # Start with y_v = 0 and dy_v/dt = 0 on a straight road: the law keeps e = 0, so
    # eps_r is the free response of the zero dynamics, whose damping ratio comes from
    # the eigenvalues of its 2x2 system (an independent calculation).
    ctl = ControllerParams(schedule=schedule)
    d_v = float(look_ahead(speed, 0.0, VEHICLE, ctl)[0])
    eps0 = 0.01
    scenario = Scenario('free', 12.0, Road([Segment('straight', 2000.0)]),
                        SpeedProfile(speed), InitialState(-d_v * eps0, eps0, -speed * eps0))
    result = run(scenario, VEHICLE, ctl, PlantParams(kinematics='small_angle'), dt=0.001,
                 control_period=0.001)
    m = step_metrics(result.time, result['eps_r'], 0.0)
    expected = zero_dynamics(VEHICLE, speed, d_v).damping_ratio
    assert m.damping_ratio == pytest.approx(expected, abs=0.005)
    assert m.overshoot == pytest.approx(
        math.exp(-math.pi * expected / math.sqrt(1.0 - expected ** 2)), rel=0.01)


@pytest.mark.parametrize('plant', ['linear', 'nonlinear'])
@pytest.mark.parametrize('speed', [10.0, 14.4, 20.0, 37.0])
def test_paper_scenario_metrics_are_never_misleading(plant, speed):
    # issue 12 item 9: the nonlinear plant at 20 m/s gave yaw_damping -0.028 and the
    # paper's car near 14.4 m/s an overshoot of 30-492
    for schedule in ('fixed', 'paper'):
        result = run(paper_scenario(speed), VEHICLE, ControllerParams(schedule=schedule),
                     PlantParams(model=plant))
        row = run_metrics(result.time, result.channels, VEHICLE.d_s)
        zeta, overshoot = row['yaw_damping_ratio'], row['yaw_overshoot']
        assert (0.0 <= zeta < 1.0) or (math.isnan(zeta) and 'damping:' in row['notes'])
        assert (0.0 <= overshoot < 1.0 / 0.25) or (math.isnan(overshoot)
                                                   and 'overshoot:' in row['notes'])
        assert row['yaw_excursion_rad'] > 0.0
        # the wheel angle the plant reports beside the command: the nonlinear
        # actuator is rate limited to 0.8 rad/s, the command is not
        assert row['peak_steering_rate_rad_per_s'] <= (
            0.8 + 1e-9 if plant == 'nonlinear' else math.inf)
        if plant == 'linear':
            assert row['peak_steering_rad'] == row['peak_steering_cmd_rad']


def test_paper_effect_survives_the_new_definitions():
    fixed = run(paper_scenario(37.0), VEHICLE, ControllerParams(schedule='fixed'))
    sched = run(paper_scenario(37.0), VEHICLE, ControllerParams(schedule='paper'))
    m_fixed = run_metrics(fixed.time, fixed.channels, VEHICLE.d_s)
    m_sched = run_metrics(sched.time, sched.channels, VEHICLE.d_s)
    assert m_fixed['yaw_overshoot'] > 0.5 > 0.05 > m_sched['yaw_overshoot']
    assert m_fixed['yaw_damping_ratio'] < 0.3 < 0.7 < m_sched['yaw_damping_ratio']


def test_curvature_step_detection():
    t = np.arange(0.0, 10.0, 0.01)
    rho = np.where(t >= 2.0, -0.0025, 0.0)
    assert curvature_step(t, rho)[:2] == (pytest.approx(2.0), pytest.approx(9.99))
    clothoid = np.clip((t - 2.0) * 1e-3, 0.0, None)
    step, _, why = curvature_step(t, clothoid)
    assert step is None and 'gradually' in why
    assert curvature_step(t, np.full(t.size, 0.01))[2].startswith('no curvature step')


def test_too_short_runs_give_no_metrics_but_counts_and_a_reason():
    t = np.array([0.0, 0.01, 0.02])
    names = ('y_cg', 'eps_r', 'rho', 'd_v', 'y_ref', 'steering_cmd', 'steering')
    channels = {name: np.zeros(3) for name in names}
    row = run_metrics(t, channels, 1.96)
    assert all(math.isnan(v) for k, v in row.items() if k not in ('notes', 'd_v_final_m'))
    assert '3 steps' in row['notes']


def test_every_quantity_has_a_symbol_and_a_unit():
    for name, q in QUANTITIES.items():
        assert q.symbol and q.unit and q.label and q.meaning, name


def test_a_missing_wheel_angle_sample_does_not_inflate_its_rate():
    t = np.arange(0.0, 2.0, 0.01)
    wheel = 0.5 * t                                   # 0.5 rad/s
    wheel[50:53] = np.nan                             # three samples not recorded
    channels = {name: np.zeros(t.size) for name in ('y_cg', 'eps_r', 'rho', 'd_v',
                                                    'y_ref', 'steering_cmd')}
    channels['steering'] = wheel
    row = run_metrics(t, channels, 1.96)
    assert row['peak_steering_rate_rad_per_s'] == pytest.approx(0.5)
    assert row['peak_steering_rad'] == pytest.approx(0.5 * t[-1])


def test_plot_lines_are_distinguishable():
    # issue 12 item 11: more than 10 runs reused the colours of the first ten
    from lookahead_control.analysis.plotting import line_styles
    styles = line_styles(25)
    assert len({(s['color'], s['linestyle']) for s in styles}) == 25


def _wander(seed, size, rms):
    # a slow random wander (the noise's effect through a closed loop is low-pass): white
    # noise through a 1 s moving average, scaled to the given RMS
    white = np.random.default_rng(seed).normal(0.0, 1.0, size + 100)
    slow = np.convolve(white, np.ones(100) / 100.0, mode='valid')[:size]
    return slow * rms / float(np.sqrt(np.mean(slow ** 2)))


def test_a_noisy_step_with_its_noise_free_twin_has_an_overshoot():
    # zeta 0.6 (9.5 % overshoot, settled after about 2.3 s of 20) plus a slow wander of
    # 2 % of the step: the 2 % band of the excursion is not held to the end, so without
    # the twin nothing is measured; with it the overshoot is the twin's within 3 x 2 %
    clean = _second_order_step(0.6)
    noisy = clean + _wander(5, clean.size, 0.02)
    alone = step_metrics(TIME, noisy, 0.0)
    assert math.isnan(alone.overshoot) and 'not settled' in alone.note
    m = step_metrics(TIME, noisy, 0.0, noise_free=clean)
    exact = math.exp(-math.pi * 0.6 / math.sqrt(1.0 - 0.36))
    assert exact - 0.06 <= m.overshoot <= exact + 0.06
    assert 'noise effect' in m.note and math.isfinite(m.settling_time)
    # the twin itself (no noise) is measured as without it
    assert step_metrics(TIME, clean, 0.0, noise_free=clean).overshoot == pytest.approx(
        step_metrics(TIME, clean, 0.0).overshoot, abs=1e-12)


def test_the_twin_does_not_make_an_unsettled_response_settled():
    # zeta 0.05 over 20 s (envelope still 5 % at the end) plus a small wander
    clean = _second_order_step(0.05)
    noisy = clean + _wander(6, clean.size, 0.002)
    m = step_metrics(TIME, noisy, 0.0, noise_free=clean)
    assert math.isnan(m.overshoot) and 'not settled within the band' in m.note


def test_noise_larger_than_the_goal_leaves_the_overshoot_unmeasured():
    # a wander of 4 % rms: 3 x 4 % is over a tenth of the step, the overshoot would be
    # the noise's
    clean = _second_order_step(0.6)
    noisy = clean + _wander(7, clean.size, 0.04)
    m = step_metrics(TIME, noisy, 0.0, noise_free=clean)
    assert math.isnan(m.overshoot) and 'would measure the noise' in m.note
    bad = clean.copy()
    bad[500] = math.nan
    assert math.isnan(step_metrics(TIME, noisy, 0.0, noise_free=bad).overshoot)


def test_a_response_drowned_in_noise_is_not_measured_and_does_not_raise():
    # the league crashed (IndexError, 16 'failed' rows) where 3 x the noise's effect
    # exceeded the whole excursion: no sample lies outside the settling band (here the
    # noise shifts the whole response: its effect is large, its own excursion small)
    clean = 0.01 * _second_order_step(0.6)
    noisy = clean + 0.05 + _wander(8, clean.size, 0.0001)
    m = step_metrics(TIME, noisy, 0.0, noise_free=clean)
    assert math.isnan(m.overshoot) and 'would measure the noise' in m.note


def test_the_twin_does_not_make_a_response_settle_before_its_noise_free_twin():
    # probe15: zeta 0.6 settles (2 % band) after about 2.3 s without noise; a bounded
    # noise of 3 % rms widens the band to 9 %, which the noisy run enters earlier. Old
    # code: settled after 1.78 s, before the response itself (1.99 s).
    clean = _second_order_step(0.6)
    noise = np.random.default_rng(8).uniform(-1.0, 1.0, clean.size) * 0.03 * math.sqrt(3.0)
    twin = step_metrics(TIME, clean, 0.0)
    m = step_metrics(TIME, clean + noise, 0.0, noise_free=clean)
    assert math.isfinite(twin.settling_time) and math.isfinite(m.settling_time)
    assert m.settling_time >= twin.settling_time - 0.02
