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

"""Baseline laws against hand-computed values, scipy, and the plant's own equilibrium."""

import math

from lookahead_control.core.baselines import (baseline_law, BASELINE_NAMES, BaselineParams,
                                              discretize, error_model, gain_table, lane_path,
                                              lqr, lqr_gain, LqrParams, pure_pursuit,
                                              pure_pursuit_look_ahead, PurePursuitParams,
                                              solve_dare, stanley, StanleyParams)
from lookahead_control.core.control_law import LateralState
from lookahead_control.core.laws import Law, NO_PREVIEW, Preview
from lookahead_control.core.params import ParameterError, VehicleParams
import numpy as np
from numpy.testing import assert_allclose
import pytest
from scipy.linalg import solve_discrete_are
from scipy.signal import cont2discrete
from sim_plant.closed_loop_sim import run
from sim_plant.scenario import paper_scenario
from sim_plant.vehicle_model import derivatives, PlantParams

VEHICLE = VehicleParams()
L = VEHICLE.wheelbase
STRAIGHT = (np.array([0.0, 300.0]), np.array([0.0, 0.0]))


def arc(rho):
    """Return a constant-curvature preview."""
    return np.array([0.0, 300.0]), np.array([rho, rho])


def plant_equilibrium(v_x, rho):
    """Return (v_y, delta) of the linear plant turning at r = v_x rho (numerical solve)."""
    plant = PlantParams(kinematics='small_angle')

    def residual(v_y, delta):
        dx = derivatives((0.0, 0.0, 0.0, v_y, v_x * rho, delta), delta, v_x, 0.0, rho,
                         VEHICLE, plant)
        return np.array([dx[3], dx[4]])

    base = residual(0.0, 0.0)
    jac = np.column_stack([residual(1.0, 0.0) - base, residual(0.0, 1.0) - base])
    return np.linalg.solve(jac, -base)


# -- LQR -----------------------------------------------------------------------------------

@pytest.mark.parametrize('speed', [1.0, 10.0, 20.0, 37.0, 70.0])
@pytest.mark.parametrize('weights', [(0.05, 0.0, 1.0, 0.0, 1.0), (0.3, 0.01, 1.0, 0.1, 2.0),
                                     (10.0, 0.0, 0.0, 0.0, 0.1)])
def test_riccati_matches_scipy(speed, weights):
    ad, bd = discretize(*error_model(VEHICLE, speed), 0.01)
    q, r = np.diag(weights[:4]), np.array([[weights[4]]])
    expected = solve_discrete_are(ad, bd, q, r)
    assert_allclose(solve_dare(ad, bd, q, r), expected, rtol=1e-9, atol=1e-9)
    params = LqrParams(*weights)
    gain = np.linalg.solve(r + bd.T @ expected @ bd, bd.T @ expected @ ad)
    assert_allclose(lqr_gain(VEHICLE, params, speed), gain, rtol=1e-8)


def test_riccati_refuses_an_unstabilizable_pair():
    a = np.diag([1.5, 0.5])
    b = np.array([[0.0], [1.0]])
    with pytest.raises(ValueError, match='no convergence'):
        solve_dare(a, b, np.eye(2), np.eye(1))


@pytest.mark.parametrize('speed', [5.0, 37.0])
def test_error_model_is_the_plants_linearization(speed):
    # x = [e1, e1', e2, e2'] with e1' = v_y + v e2, e2' = r (straight road): map to the
    # plant state, take the plant's small-angle derivatives, map back
    a, b = error_model(VEHICLE, speed)
    plant = PlantParams(kinematics='small_angle')

    def error_rates(x, delta):
        e1, e1_rate, e2, e2_rate = x
        v_y, r = e1_rate - speed * e2, e2_rate
        d = derivatives((0.0, e1, e2, v_y, r, delta), delta, speed, 0.0, 0.0, VEHICLE, plant)
        return np.array([d[1], d[3] + speed * d[2], d[2], d[4]])

    columns = [error_rates(np.eye(4)[i], 0.0) for i in range(4)]
    assert_allclose(np.column_stack(columns), a, rtol=1e-12, atol=1e-9)
    assert_allclose(error_rates(np.zeros(4), 1.0), b[:, 0], rtol=1e-12)


def test_discretization_is_apollos_bilinear_a_and_b_times_t():
    a, b = error_model(VEHICLE, 20.0)
    ad, bd = discretize(a, b, 0.01)
    ad_ref = cont2discrete((a, b, np.eye(4), np.zeros((4, 1))), 0.01, method='bilinear')[0]
    assert_allclose(ad, ad_ref, rtol=1e-12, atol=1e-14)
    assert_allclose(bd, b * 0.01)


def test_gain_table_interpolates_linearly_in_speed():
    params = LqrParams()
    speeds, gains = gain_table(VEHICLE, params)
    assert speeds[0] == params.min_speed and speeds[-1] == params.max_speed
    assert_allclose(gains[40], lqr_gain(VEHICLE, params, float(speeds[40]))[0], rtol=1e-12)
    out = lqr(1.0, 0.0, 0.0, 0.0, 0.5 * (speeds[40] + speeds[41]), 0.0, VEHICLE, params)
    assert out.k_lateral == pytest.approx(0.5 * (gains[40, 0] + gains[41, 0]), rel=1e-12)


@pytest.mark.parametrize('speed', [10.0, 20.0, 37.0])
def test_lqr_feedforward_gives_the_plants_steady_steering(speed):
    # on an arc, with the CG on the lane, at the plant's equilibrium: -K x + ff must be the
    # steering that holds the equilibrium (e_1' = e_2' = 0, e_2 = eps_ss)
    rho = -1.0 / 400.0
    v_y, delta = plant_equilibrium(speed, rho)
    eps = math.atan2(-v_y, speed)           # v_y cos e + v sin e = 0: e_1' = 0 exactly
    eps_ss = (VEHICLE.eta * speed ** 2 - VEHICLE.l2) * rho
    assert eps == pytest.approx(eps_ss, rel=2e-3)   # the model's steady yaw (small angles)
    out = lqr(0.0, eps, v_y, speed * rho, speed, rho, VEHICLE, LqrParams())
    k3 = np.interp(speed, *[gain_table(VEHICLE, LqrParams())[i] if i == 0 else
                            gain_table(VEHICLE, LqrParams())[1][:, 2] for i in range(2)])
    # exact up to the small-angle difference between eps and eps_ss, weighted by K_3
    assert out.steering == pytest.approx(delta, abs=k3 * abs(eps - eps_ss) + 1e-12)
    assert out.lateral_rate == pytest.approx(0.0, abs=1e-12)
    assert out.heading_rate == 0.0


def test_lqr_lateral_rate_modes():
    # v_y = 0.5, e_2 = 0.01, v = 20: kinematic e_1' = 0.5 cos .01 + 20 sin .01; Apollo's
    # v sin e_2 misses the 0.5 m/s
    kin = lqr(0.0, 0.01, 0.5, 0.0, 20.0, 0.0, VEHICLE, LqrParams())
    apollo = lqr(0.0, 0.01, 0.5, 0.0, 20.0, 0.0, VEHICLE, LqrParams(lateral_rate='apollo'))
    assert kin.lateral_rate == pytest.approx(0.5 * math.cos(0.01) + 20.0 * math.sin(0.01))
    assert apollo.lateral_rate == pytest.approx(20.0 * math.sin(0.01))


def test_lqr_hand_computed_feedback():
    params = LqrParams(feedforward=False)
    k = lqr_gain(VEHICLE, params, 20.0)[0]
    out = lqr(0.2, -0.01, 0.1, 0.03, 20.0, 0.001, VEHICLE, params)
    x = [0.2, 0.1 * math.cos(-0.01) + 20.0 * math.sin(-0.01), -0.01, 0.03 - 20.0 * 0.001]
    assert out.steering == pytest.approx(-float(np.dot(k, x)), rel=1e-12)


# -- pure pursuit --------------------------------------------------------------------------

def test_pure_pursuit_look_ahead_is_autowares():
    params = PurePursuitParams(velocity_ratio=2.4, min_look_ahead=4.35, max_look_ahead=15.0)
    assert pure_pursuit_look_ahead(1.0, 0.0, 0.0, params) == 4.35          # min binds
    assert pure_pursuit_look_ahead(4.0, 0.3, 0.0, params) == pytest.approx(9.6)
    # past the 0.5 m threshold: + 3.6 |e|; curvature: - 120 |rho|
    assert pure_pursuit_look_ahead(4.0, -0.6, 0.01, params) == pytest.approx(
        9.6 + 2.16 - 1.2)
    assert pure_pursuit_look_ahead(30.0, 0.0, 0.0, params) == 15.0         # max binds


def test_pure_pursuit_on_a_straight_lane_by_hand():
    # rear axle at (-l2, 0.5), heading along the lane; look-ahead 1.4 * 20 + 3.6 * 0.5 =
    # 29.8 m; target at lateral -0.5: curvature -2 * 0.5 / 29.8^2
    out = pure_pursuit(0.5, 0.0, 20.0, *STRAIGHT, VEHICLE, PurePursuitParams())
    assert out.look_ahead == pytest.approx(29.8)
    assert out.target_lateral == pytest.approx(-0.5, rel=1e-9)
    assert out.steering == pytest.approx(math.atan(-L / 29.8 ** 2), rel=1e-7)


@pytest.mark.parametrize('rho', [0.04, -1.0 / 400.0])
def test_pure_pursuit_rear_axle_on_an_arc_steers_its_curvature(rho):
    # rear axle on the arc and tangent to it: every target on the circle gives curvature
    # rho (the chord property), so delta = atan(L rho). The CG's foot point is the
    # origin: the rear axle is the angle a behind, tan a = l2 R (R = 1/|rho|).
    radius = 1.0 / abs(rho)
    a = math.atan(VEHICLE.l2 / radius)
    y_cg = math.copysign(1.0, rho) * (radius * (1.0 - math.cos(a)) - VEHICLE.l2 * math.sin(a))
    eps_r = -math.copysign(a, rho)
    out = pure_pursuit(y_cg, eps_r, 15.0, *arc(rho), VEHICLE, PurePursuitParams())
    # the target is interpolated on a chord of the 0.5 m-spaced lane points: it lies inside
    # the circle by at most h^2 |rho| / 8, which moves the curvature by < 3e-4 of itself
    assert out.curvature == pytest.approx(rho, rel=3e-4)
    assert out.steering == pytest.approx(math.atan(L * rho), rel=3e-4)


def test_lane_path_on_an_arc_is_exact():
    rho = 0.04
    path = lane_path(*arc(rho), 60.0)
    s = np.arange(path.x.shape[0]) * path.step
    assert_allclose(path.x, np.sin(rho * s) / rho, atol=1e-9)
    assert_allclose(path.y, (1.0 - np.cos(rho * s)) / rho, atol=1e-9)
    assert_allclose(path.heading, rho * s, atol=1e-12)


# -- Stanley -------------------------------------------------------------------------------

def test_stanley_on_a_straight_lane_by_hand():
    y, e, r, v = 0.5, 0.01, 0.02, 20.0
    out = stanley(y, e, r, v, *STRAIGHT, VEHICLE, StanleyParams())
    e_fa = y + VEHICLE.l1 * math.sin(e)
    assert out.front_error == pytest.approx(e_fa, rel=1e-12)
    assert out.steering == pytest.approx(-e - math.atan(1.5 * e_fa / 21.0) - 0.1 * r,
                                         rel=1e-12)


@pytest.mark.parametrize('speed', [10.0, 37.0])
def test_stanley_holds_the_front_axle_on_an_arc(speed):
    # the single-track steady state with the front axle on the lane: the front axle moves
    # along the lane, so the body points -atan((v_y + l1 r) / v) off the lane tangent there;
    # Stanley's heading + steady-state yaw terms must give the equilibrium steering
    rho = -1.0 / 400.0
    v_y, delta = plant_equilibrium(speed, rho)
    r = speed * rho
    radius = 1.0 / rho                           # signed: centre at (0, radius)

    def lane(s):
        return radius * math.sin(s / radius), radius * (1.0 - math.cos(s / radius)), s / radius

    def cg_x(s_front):
        fx, fy, th = lane(s_front)
        heading = th - math.atan2(v_y + VEHICLE.l1 * r, speed)
        return fx - VEHICLE.l1 * math.cos(heading), fy - VEHICLE.l1 * math.sin(heading), heading

    low, high = 0.0, 2.0 * VEHICLE.l1             # bisection: the CG's foot point at s = 0
    for _ in range(100):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if cg_x(mid)[0] < 0.0 else (low, mid)
    _, y_cg, heading = cg_x(low)
    out = stanley(y_cg, heading, r, speed, *arc(rho), VEHICLE, StanleyParams())
    assert abs(out.front_error) < 1e-4
    assert out.path_yaw_rate == pytest.approx(r, rel=1e-9)
    assert out.steering == pytest.approx(delta, rel=2e-3)
    without = stanley(y_cg, heading, r, speed, *arc(rho), VEHICLE,
                      StanleyParams(steady_yaw_gain=0.0))
    assert abs(without.steering - delta) > 0.3 * abs(delta)     # the term matters


# -- every law: batch = floats, finite at the edges ----------------------------------------

def _laws():
    pp, st, lq = PurePursuitParams(), StanleyParams(), LqrParams()
    return {
        'pure_pursuit': lambda y, e, vy, r, v, d, c: pure_pursuit(y, e, v, d, c, VEHICLE, pp),
        'stanley': lambda y, e, vy, r, v, d, c: stanley(y, e, r, v, d, c, VEHICLE, st),
        'lqr': lambda y, e, vy, r, v, d, c: lqr(y, e, vy, r, v, c[0], VEHICLE, lq),
    }


@pytest.mark.parametrize('name', ['pure_pursuit', 'stanley', 'lqr'])
def test_batch_equals_one_run_at_a_time(name):
    law = _laws()[name]
    rng = np.random.default_rng(3)
    n = 7
    y, e, vy = rng.normal(0, 0.5, n), rng.normal(0, 0.05, n), rng.normal(0, 0.3, n)
    r, v = rng.normal(0, 0.05, n), rng.uniform(0.0, 40.0, n)
    d = np.array([-5.0, 0.0, 20.0, 50.0, 120.0])
    c = rng.normal(0, 0.01, (5, n))
    batch = law(y, e, vy, r, v, d, c)
    for i in range(n):
        one = law(float(y[i]), float(e[i]), float(vy[i]), float(r[i]), float(v[i]), d,
                  c[:, i])
        assert isinstance(one.steering, float)
        assert_allclose(batch.steering[i], one.steering, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize('name', ['pure_pursuit', 'stanley', 'lqr'])
@pytest.mark.parametrize('case', [(0.0, 0.0, 0.0, 0.0, 0.0), (100.0, 1.5, 9.0, 2.0, 0.0),
                                  (-100.0, -3.0, -9.0, -2.0, 70.0), (0.3, 0.0, 0.0, 0.0, 1e-9)])
def test_finite_at_standstill_and_huge_errors(name, case):
    out = _laws()[name](*case, *arc(0.1))
    assert math.isfinite(out.steering)
    assert all(math.isfinite(float(v)) for v in out)


def test_parameters_check_themselves():
    with pytest.raises(ParameterError, match='pure_pursuit.min_look_ahead'):
        PurePursuitParams(min_look_ahead=20.0, max_look_ahead=10.0)
    with pytest.raises(ParameterError, match='stanley.gain'):
        StanleyParams(gain=-1.0)
    with pytest.raises(ParameterError, match='lqr.lateral_rate'):
        LqrParams(lateral_rate='v_sin')
    with pytest.raises(ParameterError, match='lqr.r'):
        LqrParams(r=0.0)
    with pytest.raises(ParameterError, match='preview'):
        lane_path([0.0, 1.0], [0.0], 10.0)


# -- as laws: the interface, the runner -----------------------------------------------------

@pytest.mark.parametrize('name', BASELINE_NAMES)
def test_law_matches_its_function_and_reads_an_empty_preview_as_the_curvature_at_the_cg(name):
    law = baseline_law(name, VEHICLE, BaselineParams())
    assert isinstance(law, Law)
    law.reset()
    state = LateralState(0.3, 0.01, 0.1, 0.02, 25.0, 0.0, -0.0025, 0.0)
    held = law.step(state, Preview(np.array([0.0]), np.array([-0.0025])), 0.01)
    assert law.step(state, NO_PREVIEW, 0.01) == held
    direct = _laws()[name](0.3, 0.01, 0.1, 0.02, 25.0, np.array([0.0]), np.array([-0.0025]))
    assert held.steering == direct.steering
    assert all(math.isfinite(float(v)) for v in held)


@pytest.mark.parametrize('name', BASELINE_NAMES)
def test_runner_batch_equals_single_runs(name):
    law = baseline_law(name, VEHICLE, BaselineParams())
    scenario = paper_scenario(20.0, 4.0)
    speeds = np.array([10.0, 30.0])
    batch = run(scenario, VEHICLE, law, initial_speed=speeds, preview_distance=60.0)
    for i, speed in enumerate(speeds):
        one = run(scenario, VEHICLE, law, initial_speed=float(speed), preview_distance=60.0)
        for channel in ('y_cg', 'steering_cmd', 'error'):
            assert_allclose(batch[channel][:, i], one[channel], rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize('name,bound', [('stanley', 0.10), ('lqr', 0.03)])
def test_stanley_and_lqr_track_the_paper_curve_on_the_linear_plant(name, bound):
    # the paper's 400 m curve at 10-37 m/s: both have curvature feedforward, so the CG
    # stays within a few centimetres and settles near the lane (measured: Stanley 8.6 cm,
    # LQR 2.0 cm peak at 37 m/s)
    law = baseline_law(name, VEHICLE, BaselineParams())
    result = run(paper_scenario(37.0, 12.0), VEHICLE, law,
                 initial_speed=np.array([10.0, 20.0, 30.0, 37.0]), preview_distance=100.0)
    assert np.max(np.abs(result['y_cg'])) < bound
    assert np.max(np.abs(result['y_cg'][-1])) < 0.5 * bound
