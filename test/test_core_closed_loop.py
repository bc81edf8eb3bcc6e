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

"""Plants and the offline closed loop against analytic expectations."""

import math

from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
from lookahead_control.core.zero_dynamics import steady_relative_yaw
import numpy as np
from numpy.testing import assert_allclose
import pytest
from sim_plant.closed_loop_sim import advance, linear_plant_stepper, plant_derivatives, run
from sim_plant.road import Road, Segment
from sim_plant.scenario import InitialState, paper_scenario, Scenario
from sim_plant.speed_profile import speed_at, SpeedProfile
from sim_plant.vehicle_model import actuator_rate, axle_forces, fiala_force, PlantParams

VEHICLE = VehicleParams()
SMALL_ANGLE = PlantParams(kinematics='small_angle')


def _arc_scenario(speed, duration, rho=-1 / 400, y0=0.0, accel=0.0):
    road = Road([Segment('arc', 5000.0, rho, rho)])
    return Scenario('arc', duration, road, SpeedProfile(speed, accel, 0.0, duration),
                    InitialState(lateral_error=y0))


@pytest.mark.parametrize('zeta', [0.6, 1.0, 1.5])
def test_error_follows_designed_second_order_dynamics(zeta):
    ctl = ControllerParams(schedule='paper', natural_frequency=2.0, damping_ratio=zeta)
    speed, rho, y0 = 30.0, -1 / 400, 0.5
    result = run(_arc_scenario(speed, 6.0, rho, y0), VEHICLE, ctl, SMALL_ANGLE,
                 dt=0.001, control_period=0.0)
    d_v = result['d_v'][0]
    e0, de0 = y0, -d_v * speed * rho      # y_v' = v_y + v eps + d_v (r - v rho)
    # analytic solution of e'' + 2 zeta w e' + w^2 e = 0
    w, t = 2.0, result.time
    if zeta < 1:
        wd = w * math.sqrt(1 - zeta ** 2)
        expected = np.exp(-zeta * w * t) * (e0 * np.cos(wd * t)
                                            + (de0 + zeta * w * e0) / wd * np.sin(wd * t))
    elif zeta == 1:
        expected = (e0 + (de0 + w * e0) * t) * np.exp(-w * t)
    else:
        s1 = -w * (zeta - math.sqrt(zeta ** 2 - 1))
        s2 = -w * (zeta + math.sqrt(zeta ** 2 - 1))
        c2 = (de0 - s1 * e0) / (s2 - s1)
        expected = (e0 - c2) * np.exp(s1 * t) + c2 * np.exp(s2 * t)
    assert_allclose(result['error'], expected, atol=1e-7)


def test_sampled_loop_stays_close_to_the_continuous_one():
    ctl = ControllerParams()
    scenario = _arc_scenario(25.0, 5.0, y0=0.3)
    cont = run(scenario, VEHICLE, ctl, SMALL_ANGLE, dt=0.001, control_period=0.0)
    zoh = run(scenario, VEHICLE, ctl, SMALL_ANGLE, dt=0.001, control_period=0.01)
    assert_allclose(zoh['y_cg'], cont['y_cg'][::10], atol=5e-3)


@pytest.mark.parametrize('speed', [20.0, 30.0, 37.0])
def test_steady_relative_yaw_on_an_arc(speed):
    rho = -1 / 400
    result = run(_arc_scenario(speed, 25.0, rho), VEHICLE, ControllerParams(), SMALL_ANGLE)
    expected = steady_relative_yaw(VEHICLE, speed, rho)
    assert result['eps_r'][-1] == pytest.approx(expected, rel=1e-4)
    assert abs(result['error'][-1]) < 1e-6
    # the exact Frenet kinematics land within 1 % of the small-angle value
    exact = run(_arc_scenario(speed, 25.0, rho), VEHICLE, ControllerParams())
    assert exact['eps_r'][-1] == pytest.approx(expected, rel=1e-2)


def test_straight_road_with_zero_error_stays_at_zero():
    scenario = Scenario('straight', 5.0, Road([Segment('straight', 1000.0)]),
                        SpeedProfile(30.0))
    for plant in (PlantParams(), PlantParams(model='nonlinear')):
        result = run(scenario, VEHICLE, ControllerParams(), plant)
        for name in ('y_cg', 'eps_r', 'v_y', 'r', 'steering_cmd'):
            assert np.max(np.abs(result[name])) == 0.0


def test_left_offset_is_removed_by_steering_right():
    result = run(Scenario('straight', 8.0, Road([Segment('straight', 1000.0)]),
                          SpeedProfile(20.0), InitialState(lateral_error=0.5)),
                 VEHICLE, ControllerParams(), PlantParams(model='nonlinear'))
    assert result['steering_cmd'][0] < 0.0
    assert abs(result['y_cg'][-1]) < 0.01


def test_batch_equals_single_runs():
    scenario = _arc_scenario(20.0, 4.0, y0=0.2, accel=1.0)
    speeds = np.array([12.0, 20.0, 33.0])
    errors = np.array([0.2, -0.4, 0.0])
    for plant in (PlantParams(), PlantParams(model='nonlinear')):
        batch = run(scenario, VEHICLE, ControllerParams(), plant, initial_speed=speeds,
                    initial_error=errors)
        for i, (v, y) in enumerate(zip(speeds, errors)):
            single = run(scenario, VEHICLE, ControllerParams(), plant,
                         initial_speed=float(v), initial_error=float(y))
            for name in ('y_cg', 'eps_r', 'steering_cmd', 'd_v'):
                assert_allclose(batch[name][:, i], single[name], rtol=1e-12, atol=1e-14)


def test_fiala_is_linear_for_small_slip_and_saturates():
    c, limit = 80000.0, 7000.0
    assert fiala_force(1e-5, c, limit) == pytest.approx(-c * 1e-5, rel=1e-3)
    assert fiala_force(0.5, c, limit) == -limit
    assert fiala_force(-0.5, c, limit) == limit
    slips = np.linspace(-0.3, 0.3, 601)
    forces = fiala_force(slips, c, limit)
    assert np.all(np.abs(forces) <= limit + 1e-9)
    assert np.all(np.diff(forces) <= 1e-9)      # monotone, continuous at the limit


def test_nonlinear_model_matches_linear_at_small_angles():
    args = (25.0, 0.01, 0.005, 0.002)
    lin = axle_forces(VEHICLE, PlantParams(), *args)
    nonlin = axle_forces(VEHICLE, PlantParams(model='nonlinear'), *args)
    assert_allclose(nonlin, lin, rtol=2e-2)


def test_actuator_limits():
    plant = PlantParams(model='nonlinear', steering_time_constant=0.1,
                        max_steering_angle=0.5, max_steering_rate=0.8)
    assert actuator_rate(plant, 0.0, 10.0) == 0.8           # rate limit
    assert actuator_rate(plant, 0.5, 10.0) == 0.0           # angle limit
    assert actuator_rate(plant, 0.0, 0.01) == pytest.approx(0.1)   # first-order lag


def test_road_curvature_profile():
    road = Road([Segment('straight', 10.0), Segment('clothoid', 20.0, 0.0, 0.01),
                 Segment('arc', 30.0, 0.01, 0.01)])
    assert road.curvature(5.0) == (0.0, 0.0)
    assert road.curvature(20.0) == pytest.approx((0.005, 0.0005))
    assert road.curvature(45.0) == pytest.approx((0.01, 0.0))
    assert road.curvature(500.0) == (0.01, 0.0)
    s = np.array([5.0, 20.0, 45.0, 500.0])
    rho, slope = road.curvature(s)
    assert_allclose(rho, [0.0, 0.005, 0.01, 0.01])
    assert_allclose(slope, [0.0, 0.0005, 0.0, 0.0])


def test_cached_curvature_function_equals_the_curvature():
    road = Road([Segment('straight', 10.0), Segment('clothoid', 20.0, 0.0, 0.01),
                 Segment('arc', 30.0, 0.01, 0.01), Segment('clothoid', 5.0, 0.01, -0.02)])
    rho = road.curvature_function()
    rng = np.random.default_rng(8)
    # the segment ends, then walks forward, backward and jumping
    points = [-5.0, 0.0, 10.0, 30.0, 60.0, 65.0, 64.999, 9.999, -1e-9, 1e9]
    points += list(np.cumsum(rng.uniform(0.0, 0.4, 300)) - 5.0)
    points += list(rng.uniform(-10.0, 80.0, 300)) + list(rng.uniform(-10.0, 80.0, 300))[::-1]
    for s in map(float, points):
        assert rho(s) == road.curvature(s)[0], s


@pytest.mark.parametrize('kinematics', ['exact', 'small_angle'])
@pytest.mark.parametrize('accel', [0.0, 2.5])
def test_linear_plant_stepper_equals_the_generic_integrator_bit_for_bit(kinematics, accel):
    scenario = paper_scenario(25.0)
    scenario = Scenario(scenario.name, scenario.duration, scenario.road,
                        SpeedProfile(25.0, accel, 1.0, 4.0), scenario.initial)
    plant = PlantParams(kinematics=kinematics)
    step = linear_plant_stepper(scenario, VEHICLE, plant, 25.0, accel)
    rng = np.random.default_rng(9)
    x = (0.0, 0.3, 0.01, 0.0, 0.0, 0.0)
    for k in range(600):        # along the paper's road (straight, then the curve), 6 s
        command = float(rng.uniform(-0.05, 0.05))
        rhs = plant_derivatives(scenario, VEHICLE, plant, command, 25.0, accel)
        expected = advance(rhs, x, k * 0.01, 0.001, 10, plant, command)
        x = step(x, k * 0.01, 0.001, 10, command)
        assert x == expected, k
    assert x[0] > 100.0          # well into the curve
    with pytest.raises(ValueError, match="plant.model = 'nonlinear'"):
        linear_plant_stepper(scenario, VEHICLE, PlantParams(model='nonlinear'), 25.0, 0.0)


def test_speed_profile_float_path_equals_the_array_path():
    rng = np.random.default_rng(5)
    for _ in range(2000):
        start, duration = (float(v) for v in rng.uniform(0.0, 5.0, 2))
        t = float(rng.choice([rng.uniform(-1.0, 10.0), start, start + duration]))
        v, a = float(rng.uniform(1.0, 40.0)), float(rng.uniform(-3.0, 3.0))
        scalar = speed_at(t, v, a, start, duration)
        array = speed_at(np.array([t]), np.array([v]), np.array([a]), start, duration)
        assert type(scalar[0]) is float and type(scalar[1]) is float
        assert scalar == (array[0][0], array[1][0])


def test_speed_profile_and_bad_steps():
    profile = SpeedProfile(20.0, 2.0, 1.0, 3.0)
    assert profile.at(0.5) == (20.0, 0.0)
    assert profile.at(2.0) == (22.0, 2.0)
    assert profile.at(10.0) == (26.0, 0.0)
    with pytest.raises(ParameterError, match='whole multiple'):
        run(paper_scenario(20.0, 1.0), VEHICLE, ControllerParams(), dt=0.003,
            control_period=0.01)


def test_paper_scenario_shows_the_paper_effect():
    # Fig. 4 vs Fig. 5: at 37 m/s the fixed look-down d_v leaves the relative yaw
    # under-damped, the eq. 26 schedule damps it; tracking at the CG gets worse.
    from lookahead_control.analysis.metrics import run_metrics
    fixed = run(paper_scenario(37.0), VEHICLE, ControllerParams(schedule='fixed'))
    sched = run(paper_scenario(37.0), VEHICLE, ControllerParams(schedule='paper'))
    m_fixed = run_metrics(fixed.time, fixed.channels, VEHICLE.d_s)
    m_sched = run_metrics(sched.time, sched.channels, VEHICLE.d_s)
    assert m_fixed['yaw_overshoot'] > 0.3
    assert m_sched['yaw_overshoot'] < 0.1
    assert m_sched['peak_cg_error_m'] > m_fixed['peak_cg_error_m']


class _Absurd:
    """Positive feedback with gain 1e4 above 25 m/s: the linear plant overflows."""

    def reset(self):
        pass

    def step(self, state, preview, dt):
        from lookahead_control.core.laws import output
        gain = np.where(np.asarray(state.v_x) > 25.0, 1.0e4, 0.0)
        return output(gain * (state.y_cg + state.eps_r))


def test_a_run_whose_linear_plant_overflows_diverges_alone_without_warnings():
    import warnings
    straight = Scenario('straight', 3.0, Road([Segment('straight', 2000.0)]),
                        SpeedProfile(20.0), InitialState(relative_yaw=0.01))
    with warnings.catch_warnings():
        warnings.simplefilter('error')          # no overflow warnings escape the runner
        batch = run(straight, VEHICLE, _Absurd(), dt=0.005,
                    initial_speed=np.array([10.0, 37.0]))
        slow = run(straight, VEHICLE, _Absurd(), dt=0.005, initial_speed=10.0)
        fast = run(straight, VEHICLE, _Absurd(), dt=0.005, initial_speed=37.0)
        # saturating tyres keep the nonlinear plant finite: far off the road, no divergence
        tyres = run(straight, VEHICLE, _Absurd(), PlantParams(model='nonlinear'), dt=0.005,
                    initial_speed=37.0)
    assert math.isnan(batch.diverged_at[0]) and math.isnan(slow.diverged_at)
    assert 1.0 < fast.diverged_at < 3.0 and batch.diverged_at[1] == fast.diverged_at
    assert math.isnan(tyres.diverged_at) and np.max(np.abs(tyres['y_cg'])) > 5.0
    for name in batch.channels:
        assert np.array_equal(batch[name][:, 0], slow[name]), name
        assert np.array_equal(batch[name][:, 1], fast[name], equal_nan=True), name
        ok = fast.time <= fast.diverged_at
        assert np.all(np.isfinite(fast[name][ok])) and np.all(np.isnan(fast[name][~ok]))
