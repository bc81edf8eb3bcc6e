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
The relative yaw that keeps the CG on the lane: the exact inverse of the zero dynamics.

With the CG held on the lane centre (``y_cg = 0`` at all times) the single-track model
has ``v_y = -v_x eps_r`` and the lateral acceleration ``v_x^2 rho``; eliminating the front
force from the yaw equation leaves (rear compliance ``c``, the rear slip per lateral
acceleration; ``c = eta`` for the linear tyre) ::

    eps' = r - v_x rho
    tau^2 r' = eps_ss(rho) - eps - (l_2 / v_x) (r - v_x rho),   tau^2 = I_z c / (m l_1)

Its equilibrium on an arc is ``eps_ss = (c v_x^2 - l_2) rho`` and its first-order
truncation is the CG-compensated law's rate feedforward ``eps_ss - (v_x I_z c / (m l_1) +
(c v_x^2 - l_2) l_2 / v_x) rho'``. Its own mode is the zero dynamics of the CG output (8.6
rad/s, damping ratio 0.18 at 37 m/s, Table 1): with the CG on the lane the relative yaw
rings on a curvature step. ``damping`` raises that ratio by a term on ``eps' - eps_ss'``,
which leaves the first-order truncation as it is.

Floats or numpy arrays of one shape; the integration is the trapezoidal rule (A-stable at
any speed and step) with the inputs held over the step.
"""

from __future__ import annotations

import math

from lookahead_control.core import numeric as xp
from lookahead_control.core.numeric import Real
from lookahead_control.core.params import VehicleParams

#: [s] longest sub-step of the trapezoidal rule (accuracy: 8.6 rad/s is 0.017 rad a step)
SUBSTEP = 0.002


def model_terms(vehicle: VehicleParams, v_x: Real, rho: Real, compliance: Real,
                damping: float, eps_ss_rate: Real) -> tuple[Real, Real, Real]:
    """
    Return ``(tau^2, B, u)`` of ``tau^2 r' = u - eps - B r`` (with ``eps' = r - v_x rho``).

    :param vehicle: the law's model (I_z, m, l_1, l_2).
    :param v_x: speed [m/s] (positive).
    :param rho: curvature [1/m].
    :param compliance: rear slip per lateral acceleration ``c`` [s^2/m].
    :param damping: the damping ratio to raise the model's to (0: its own).
    :param eps_ss_rate: ``eps_ss'`` for the added damping [rad/s].
    :return: ``tau^2`` [s^2], the damping coefficient ``B`` [s] and the input ``u`` [rad].
    """
    tau2 = vehicle.yaw_inertia * compliance / (vehicle.mass * vehicle.l1)
    own = vehicle.l2 / v_x
    extra = xp.maximum(2.0 * damping * xp.sqrt(tau2) - own, 0.0 * own) if damping > 0.0 \
        else 0.0 * own
    eps_ss = (compliance * v_x * v_x - vehicle.l2) * rho
    coefficient = own + extra
    return tau2, coefficient, eps_ss + coefficient * v_x * rho + extra * eps_ss_rate


def rates(vehicle: VehicleParams, v_x: Real, rho: Real, compliance: Real, eps: Real, r: Real,
          damping: float = 0.0, eps_ss_rate: Real = 0.0) -> tuple[Real, Real]:
    """
    Return ``(eps', r')`` of the relative yaw with the CG held on the lane.

    :param vehicle: the law's model.
    :param v_x: speed [m/s] (positive).
    :param rho: curvature [1/m].
    :param compliance: rear compliance ``c`` [s^2/m].
    :param eps: relative yaw [rad].
    :param r: yaw rate [rad/s].
    :param damping: see :func:`model_terms`.
    :param eps_ss_rate: see :func:`model_terms`.
    :return: their time derivatives [rad/s, rad/s^2].
    """
    tau2, coefficient, u = model_terms(vehicle, v_x, rho, compliance, damping, eps_ss_rate)
    return r - v_x * rho, (u - eps - coefficient * r) / tau2


def equilibrium(vehicle: VehicleParams, v_x: Real, rho: Real,
                compliance: Real) -> tuple[Real, Real]:
    """
    Return ``(eps_ss, v_x rho)``: the model at rest on an arc of curvature ``rho``.

    :param vehicle: the law's model.
    :param v_x: speed [m/s].
    :param rho: curvature [1/m].
    :param compliance: rear compliance [s^2/m].
    :return: relative yaw [rad] and yaw rate [rad/s].
    """
    return (compliance * v_x * v_x - vehicle.l2) * rho, v_x * rho


def advance(vehicle: VehicleParams, v_x: Real, rho: Real, compliance: Real,
            state: tuple[Real, Real], dt: float, damping: float = 0.0,
            eps_ss_rate: Real = 0.0) -> tuple[Real, Real]:
    """
    Integrate the model over ``dt`` with its inputs held (trapezoidal rule).

    :param vehicle: the law's model.
    :param v_x: speed [m/s] (positive).
    :param rho: curvature [1/m].
    :param compliance: rear compliance [s^2/m].
    :param state: ``(eps, r)`` at the start.
    :param dt: the step [s] (0: unchanged).
    :param damping: see :func:`model_terms`.
    :param eps_ss_rate: see :func:`model_terms`.
    :return: ``(eps, r)`` at its end.
    """
    eps, r = state
    if dt <= 0.0:
        return eps, r
    tau2, coefficient, u = model_terms(vehicle, v_x, rho, compliance, damping, eps_ss_rate)
    n = max(1, math.ceil(dt / SUBSTEP))
    h = dt / n
    # (I - h A / 2) x+ = (I + h A / 2) x + h w,  A = [[0, 1], [-1, -B] / tau^2],
    # w = [-v_x rho, u / tau^2]
    a = 0.5 * h / tau2
    b = a * coefficient
    det = 1.0 + b + 0.5 * h * a
    drift = h * v_x * rho
    push = 2.0 * a * u
    for _ in range(n):
        e1 = eps + 0.5 * h * r - drift
        r1 = -a * eps + (1.0 - b) * r + push
        eps, r = ((1.0 + b) * e1 + 0.5 * h * r1) / det, (r1 - a * e1) / det
    return eps, r
