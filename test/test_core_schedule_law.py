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

"""Schedules, control law and zero dynamics against independent expectations."""

from dataclasses import replace
import math

from lookahead_control.core.control_law import arc_offset, LateralState, steering_law
from lookahead_control.core.params import ControllerParams, VehicleParams
from lookahead_control.core.schedule import exact_look_ahead, look_ahead, paper_look_ahead
from lookahead_control.core.zero_dynamics import steady_relative_yaw, zero_dynamics
import numpy as np
from numpy.testing import assert_allclose
import pytest
from sim_plant.vehicle_model import derivatives, PlantParams

VEHICLE = VehicleParams()
SMALL_ANGLE = PlantParams(kinematics='small_angle')


@pytest.mark.parametrize('speed,expected', [(10.0, 1.96), (20.0, 10.61), (30.0, 25.84),
                                            (37.0, 40.14)])
def test_paper_schedule_matches_model_md(speed, expected):
    # model.md: eq. 26 with Table 1 gives 1.96 / 10.61 / 25.84 / 40.14 m (2 decimals)
    d_v, _ = paper_look_ahead(speed, 0.0, VEHICLE)
    assert d_v == pytest.approx(expected, abs=0.01)


def test_paper_schedule_rate_is_8_eta_v_a():
    _, rate = paper_look_ahead(30.0, 2.0, VEHICLE)
    eta = 1485.0 * 1.1 / (80000.0 * 2.68)
    assert rate == pytest.approx(8 * eta * 30.0 * 2.0)
    # where d_s binds the distance is constant
    assert paper_look_ahead(10.0, 2.0, VEHICLE)[1] == 0.0


@pytest.mark.parametrize('speed', [15.0, 20.0, 30.0, 37.0])
def test_exact_schedule_gives_equal_real_roots(speed):
    d_v, _ = exact_look_ahead(speed, 0.0, VEHICLE)
    zd = zero_dynamics(VEHICLE, speed, d_v)
    assert zd.damping_ratio == pytest.approx(1.0, abs=1e-9)
    assert zd.roots[0] == pytest.approx(zd.roots[1], abs=1e-4)


@pytest.mark.parametrize('mode', ['paper', 'exact'])
def test_schedule_rate_is_derivative_along_speed(mode):
    ctl = ControllerParams(schedule=mode)
    v, a, h = 27.0, 1.3, 1e-6
    d_plus, _ = look_ahead(v + a * h, a, VEHICLE, ctl)
    d_minus, _ = look_ahead(v - a * h, a, VEHICLE, ctl)
    _, rate = look_ahead(v, a, VEHICLE, ctl)
    assert rate == pytest.approx((d_plus - d_minus) / (2 * h), rel=1e-6)


def test_fixed_schedule_and_clamp():
    d_v, rate = look_ahead(37.0, 3.0, VEHICLE, ControllerParams(schedule='fixed'))
    assert (d_v, rate) == (1.96, 0.0)
    d_v, rate = look_ahead(37.0, 3.0, VEHICLE, ControllerParams(max_look_ahead=30.0))
    assert (d_v, rate) == (30.0, 0.0)


def test_schedule_vectorizes():
    speeds = np.array([10.0, 20.0, 30.0, 37.0])
    d_v, rate = paper_look_ahead(speeds, np.full(4, 1.0), VEHICLE)
    scalar = [paper_look_ahead(float(v), 1.0, VEHICLE) for v in speeds]
    assert_allclose(d_v, [s[0] for s in scalar])
    assert_allclose(rate, [s[1] for s in scalar])


def test_left_lateral_error_steers_right():
    for mode in ('paper', 'fixed'):
        out = steering_law(LateralState(0.5, 0.0, 0.0, 0.0, 25.0, 0.0, 0.0, 0.0), VEHICLE,
                           ControllerParams(schedule=mode))
        assert out.steering < 0.0   # REP-103: positive delta steers left
        out = steering_law(LateralState(-0.5, 0.0, 0.0, 0.0, 25.0, 0.0, 0.0, 0.0), VEHICLE,
                           ControllerParams(schedule=mode))
        assert out.steering > 0.0


def test_straight_road_zero_error_commands_zero():
    for mode in ('paper', 'exact', 'fixed'):
        out = steering_law(LateralState(0.0, 0.0, 0.0, 0.0, 30.0, 1.0, 0.0, 0.0), VEHICLE,
                           ControllerParams(schedule=mode))
        assert out.steering == 0.0
        assert out.error == 0.0


def test_arc_offset_exact_and_approx():
    # eq. 3 by its textbook form vs the numerically safe form
    rho, d = -1.0 / 400.0, 40.0
    radius = 1.0 / abs(rho)
    exact = math.copysign(radius - math.sqrt(radius ** 2 - d ** 2), rho)
    assert arc_offset(rho, d, 0.0, exact=True) == pytest.approx(exact, rel=1e-12)
    assert arc_offset(rho, d, 0.0, exact=False) == pytest.approx(rho * d * d / 2)
    assert arc_offset(0.0, d, 0.1, exact=True) == 0.0


def _closed_loop_rhs(x, v, ctl, rho=0.0, a=0.0):
    state = LateralState(x[1], x[2], x[3], x[4], v, a, rho, 0.0)
    out = steering_law(state, VEHICLE, ctl)
    return derivatives(tuple(x), out.steering, v, a, rho, VEHICLE, SMALL_ANGLE), out


@pytest.mark.parametrize('speed,mode', [(15.0, 'fixed'), (25.0, 'fixed'), (37.0, 'fixed'),
                                        (25.0, 'paper'), (37.0, 'paper'),
                                        (30.0, 'exact')])
def test_zero_dynamics_roots_are_closed_loop_eigenvalues(speed, mode):
    ctl = ControllerParams(schedule=mode, natural_frequency=2.5, damping_ratio=0.8)
    # Jacobian of the full closed loop in [y_cg, eps_r, v_y, r] (linear: exact FD)
    jac = np.zeros((4, 4))
    for j in range(4):
        dx = np.zeros(6)
        dx[1 + j] = 1e-6
        plus, _ = _closed_loop_rhs(dx, speed, ctl)
        minus, _ = _closed_loop_rhs(-dx, speed, ctl)
        jac[:, j] = (np.array(plus[1:5]) - np.array(minus[1:5])) / 2e-6
    eig = np.sort_complex(np.linalg.eigvals(jac))
    d_v, _ = look_ahead(speed, 0.0, VEHICLE, ctl)
    zd = zero_dynamics(VEHICLE, speed, float(d_v))
    designed = np.roots([1.0, ctl.k_d, ctl.k_p])
    expected = np.sort_complex(np.concatenate([designed, zd.roots]))
    assert_allclose(eig, expected, atol=1e-5)


@pytest.mark.parametrize('mode', ['fixed', 'paper'])
def test_f_v_matches_numerical_second_derivative(mode):
    # Arbitrary steering, accelerating vehicle on an arc. The law takes d^2 d_v/dt^2 as
    # 0 (as the paper does); for eq. 26 it is 8 eta a_x^2, added here as a known term.
    ctl = ControllerParams(schedule=mode)
    vehicle = replace(VEHICLE, d_s=6.0)   # the fixed schedule looks 6 m ahead
    rho, h = 1.0 / 150.0, 1e-3
    d2d = 8.0 * VEHICLE.eta * 1.5 ** 2 if mode == 'paper' else 0.0
    x = (0.0, 0.3, 0.02, 0.1, 0.05, 0.0)

    def speed(t):
        return 22.0 + 1.5 * t

    def steer(t):
        return 0.02 * math.sin(3.0 * t)

    def rhs(t, x):
        return derivatives(x, steer(t), speed(t), 1.5, rho, VEHICLE, SMALL_ANGLE)

    from sim_plant.vehicle_model import rk4_step
    ts, ys, outs = [], [], []
    for k in range(400):
        t = k * h
        out = steering_law(LateralState(x[1], x[2], x[3], x[4], speed(t), 1.5, rho, 0.0),
                           vehicle, ctl)
        ts.append(t)
        ys.append(out.y_v)
        outs.append(out.f_v + out.beta_1 * steer(t) + d2d * x[2])
        x = rk4_step(rhs, t, x, h)
    ys = np.array(ys)
    second = (ys[2:] - 2 * ys[1:-1] + ys[:-2]) / h ** 2
    assert_allclose(second, np.array(outs)[1:-1], rtol=0, atol=2e-4)
    assert np.max(np.abs(second)) > 0.1   # the test exercises a real motion


def test_steady_relative_yaw_formula():
    eta = 1485.0 * 1.1 / (80000.0 * 2.68)
    assert steady_relative_yaw(VEHICLE, 30.0, -1 / 400) == pytest.approx(
        (eta * 900.0 - 1.58) * (-1 / 400))


def test_fixed_schedule_uses_the_vehicles_d_s():
    # issue 12 item 13: one source of d_s; 'fixed' used a controller default of 1.96 m
    vehicle = replace(VEHICLE, d_s=2.5)
    d_v, rate = look_ahead(20.0, 1.0, vehicle, ControllerParams(schedule='fixed'))
    assert (d_v, rate) == (2.5, 0.0)
    assert not hasattr(ControllerParams(), 'fixed_look_ahead')
    with pytest.raises(TypeError):
        ControllerParams(schedule='fixed', fixed_look_ahead=2.5)   # type: ignore[call-arg]
    # eq. 26 and eq. 24 are floored at the same d_s (raw eq. 26 at 5 m/s: -1.35 m)
    for mode in ('paper', 'exact'):
        d_v, rate = look_ahead(5.0, 1.0, vehicle, ControllerParams(schedule=mode))
        assert (d_v, rate) == (2.5, 0.0)
    # a d_s above the clamp is clamped like the other schedules
    clamped = ControllerParams(schedule='fixed', max_look_ahead=2.0)
    d_v, _ = look_ahead(20.0, 0.0, vehicle, clamped)
    assert d_v == 2.0


def test_lateral_state_has_no_silent_physical_defaults():
    # issue 12 item 13: a caller who forgets the curvature must not lose the feedforward
    with pytest.raises(TypeError):
        LateralState(0.0, 0.0, 0.0, 0.0, 25.0)   # type: ignore[call-arg]
    with pytest.raises(TypeError):
        LateralState(0.0, 0.0, 0.0, 0.0, 25.0, 0.0, 0.01)   # type: ignore[call-arg]
    assert LateralState._field_defaults == {}
