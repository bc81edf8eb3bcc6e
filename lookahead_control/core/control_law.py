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
The input-output linearizing steering law (paper eq. 9-15, ``docs/model.md``).

Output ``y_v = y_cg + d_v eps_r``; with ``beta_1 = C_f (1/m + l_1 d_v / I_z)`` and
``beta_2 = C_r (1/m - l_2 d_v / I_z)``, ``y_v'' = f_v + beta_1 delta`` and the law

    delta = (-f_v - k_p (y_v - y_ref) - k_d (y_v' - y_ref')) / beta_1

makes ``e = y_v - y_ref`` obey ``e'' + k_d e' + k_p e = 0``. Everything works on floats
(one command, microseconds) and on numpy arrays (a batch of runs).
"""

from __future__ import annotations

from typing import NamedTuple

from lookahead_control.core import numeric as xp
from lookahead_control.core.numeric import Real
from lookahead_control.core.params import ControllerParams, VehicleParams
from lookahead_control.core.schedule import look_ahead


class LateralState(NamedTuple):
    """
    What the law needs to know about the vehicle and the road (REP-103 signs, SI units).

    Every field is required: there is no physical default, so a caller who has no curvature
    or acceleration says so by passing 0 explicitly. Floats or numpy arrays of one shape.

    :param y_cg: lateral offset of the CG from the lane centre line, measured along the
        road normal, + when the CG is left of the centre line [m].
    :param eps_r: relative yaw, vehicle yaw minus road tangent yaw, + CCW [rad].
    :param v_y: body-frame lateral velocity of the CG, + left [m/s].
    :param r: yaw rate, + CCW [rad/s].
    :param v_x: body-frame longitudinal speed of the CG [m/s].
    :param a_x: dv_x/dt, the time derivative of v_x [m/s^2]; not an accelerometer
        reading (which is dv_x/dt - v_y r).
    :param rho: curvature of the lane centre line at the vehicle, + for a left turn [1/m].
    :param rho_rate: d rho / dt along the vehicle's travel, v_x d rho/ds (0 on arcs and
        straights) [1/(m s)].
    """

    y_cg: Real
    eps_r: Real
    v_y: Real
    r: Real
    v_x: Real
    a_x: Real
    rho: Real
    rho_rate: Real


class LawOutput(NamedTuple):
    """
    One evaluation of the law, with the intermediate values worth logging.

    :param steering: front-wheel steering angle delta, + left [rad].
    :param d_v: look-ahead distance in use [m].
    :param d_v_rate: its time derivative [m/s].
    :param y_v: look-ahead output y_cg + d_v eps_r [m].
    :param y_v_rate: its time derivative (eq. 9) [m/s].
    :param y_ref: the reference y_v is regulated to (0, y_o or d_v eps_ss) [m].
    :param error: regulated error e = y_v - y_ref [m].
    :param error_rate: its time derivative [m/s].
    :param f_v: drift term of y_v'' [m/s^2].
    :param beta_1: input gain of y_v'' [m/(s^2 rad)].
    """

    steering: Real
    d_v: Real
    d_v_rate: Real
    y_v: Real
    y_v_rate: Real
    y_ref: Real
    error: Real
    error_rate: Real
    f_v: Real
    beta_1: Real


def error_at(y_cg: Real, eps_r: Real, distance: Real) -> Real:
    """
    Return the lateral error of a point ``distance`` ahead of the CG (eq. 5).

    :param y_cg: lateral error of the CG [m].
    :param eps_r: relative yaw [rad].
    :param distance: distance ahead of the CG along the vehicle axis [m].
    :return: ``y_cg + distance * eps_r`` [m].
    """
    return y_cg + distance * eps_r


def cg_error_from(measured: Real, eps_r: Real, distance: Real) -> Real:
    """
    Return the CG lateral error from an error measured ``distance`` ahead of the CG.

    :param measured: lateral error measured at the sensor [m].
    :param eps_r: relative yaw [rad].
    :param distance: sensor distance ahead of the CG (negative behind it) [m].
    :return: ``measured - distance * eps_r`` [m].
    """
    return measured - distance * eps_r


def arc_offset(rho: Real, d_v: Real, eps_r: Real, exact: bool) -> Real:
    """
    Return y_o, the lane's offset from its tangent at the look-ahead distance.

    Exact (eq. 3): ``sign(rho) (R - sqrt(R^2 - (d_v cos eps_r)^2))``, written as
    ``rho x^2 / (1 + sqrt(1 - rho^2 x^2))`` so that it is finite at ``rho = 0``; where the
    look-ahead point lies beyond the circle (``|rho| x > 1``) it saturates at ``R``.
    Approximate (eq. 4): ``rho d_v^2 / 2``.

    :param rho: curvature [1/m].
    :param d_v: look-ahead distance [m].
    :param eps_r: relative yaw [rad].
    :param exact: eq. 3 if true, else eq. 4.
    :return: y_o [m].
    """
    if not exact:
        return 0.5 * rho * d_v * d_v
    x = d_v * xp.cos(eps_r)
    return rho * x * x / (1.0 + xp.sqrt(xp.maximum(1.0 - rho * rho * x * x, 0.0 * x)))


def axle_gains(vehicle: VehicleParams, d_v: Real) -> tuple[Real, Real]:
    """
    Return ``(beta_1, beta_2)``: each axle's cornering stiffness as ``y_v''`` per slip.

    :param vehicle: vehicle parameters.
    :param d_v: look-ahead distance [m].
    :return: ``beta_1 = C_f (1/m + l_1 d_v / I_z)``, ``beta_2 = C_r (1/m - l_2 d_v / I_z)``
        [m/(s^2 rad)].
    """
    m, iz = vehicle.mass, vehicle.yaw_inertia
    return (vehicle.c_f * (1.0 / m + vehicle.l1 * d_v / iz),
            vehicle.c_r * (1.0 / m - vehicle.l2 * d_v / iz))


def drift_term(state: LateralState, vehicle: VehicleParams, d_v: Real, d_v_rate: Real,
               v_x: Real) -> tuple[Real, Real]:
    """
    Return ``(f_v, beta_1)`` of ``y_v'' = f_v + beta_1 delta`` (model.md, eq. 11-13).

    :param state: vehicle and road state.
    :param vehicle: vehicle parameters.
    :param d_v: look-ahead distance [m].
    :param d_v_rate: dd_v/dt [m/s] (d^2 d_v/dt^2 is taken as 0, as in the paper).
    :param v_x: the (floored) speed to divide by [m/s].
    :return: ``(f_v [m/s^2], beta_1 [m/(s^2 rad)])``.
    """
    beta_1, beta_2 = axle_gains(vehicle, d_v)
    v_y, r, eps_r, rho = state.v_y, state.r, state.eps_r, state.rho
    a_x = state.a_x
    f_v = (-(beta_1 * (v_y + vehicle.l1 * r) + beta_2 * (v_y - vehicle.l2 * r)) / v_x
           - v_x * v_x * rho + a_x * eps_r
           - d_v * (a_x * rho + v_x * state.rho_rate)
           + 2.0 * d_v_rate * (r - v_x * rho))
    return f_v, beta_1


def steering_law(state: LateralState, vehicle: VehicleParams,
                 controller: ControllerParams) -> LawOutput:
    """
    Evaluate the linearizing law (eq. 15) with the scheduled look-ahead (eq. 26).

    :param state: vehicle and road state.
    :param vehicle: vehicle parameters.
    :param controller: gains, schedule and reference.
    :return: the steering angle and the intermediate values.
    """
    v_x = xp.maximum(state.v_x, controller.min_speed)
    d_v, d_v_rate = look_ahead(v_x, state.a_x, vehicle, controller)
    eps_r, rho = state.eps_r, state.rho
    y_v = state.y_cg + d_v * eps_r
    y_v_rate = state.v_y + v_x * eps_r + d_v * (state.r - v_x * rho) + d_v_rate * eps_r
    if controller.reference == 'lane_tangent':
        y_ref: Real = 0.0 * y_v
        y_ref_rate: Real = 0.0 * y_v
    elif controller.reference == 'cg_compensated':
        # y_ref = d_v eps_ss, eps_ss = (eta v_x^2 - l_2) rho: the CG's equilibrium on an
        # arc is the lane (docs/lane_keeping.md; the stateful law adds preview, the
        # compliance estimate and the integral: core/lane_keeping.py)
        gain = vehicle.eta * v_x * v_x - vehicle.l2
        y_ref = d_v * gain * rho
        y_ref_rate = (d_v_rate * gain * rho + d_v * (2.0 * vehicle.eta * v_x * state.a_x * rho
                                                     + gain * state.rho_rate))
    else:
        y_ref = arc_offset(rho, d_v, eps_r, controller.reference == 'arc_exact')
        # d/dt of rho d_v^2 / 2, the same for both forms to first order in eps_r
        y_ref_rate = rho * d_v * d_v_rate + 0.5 * state.rho_rate * d_v * d_v
    f_v, beta_1 = drift_term(state, vehicle, d_v, d_v_rate, v_x)
    error = y_v - y_ref
    error_rate = y_v_rate - y_ref_rate
    steering = (-f_v - controller.k_p * error - controller.k_d * error_rate) / beta_1
    return LawOutput(steering, d_v, d_v_rate, y_v, y_v_rate, y_ref, error, error_rate,
                     f_v, beta_1)
