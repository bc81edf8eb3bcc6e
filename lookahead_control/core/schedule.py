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
The look-ahead distance d_v scheduled on speed (paper eq. 21-26).

Each schedule returns ``(d_v, dd_v/dt)`` for a speed ``v_x`` [m/s] and ``a_x = dv_x/dt``
[m/s^2]; both work on floats and on numpy arrays.

- ``paper``: ``d_v = max(d_s, 4 eta v_x^2 - l_2)`` (eq. 26).
- ``exact``: the positive root of ``(l_2 + d_v)^2 = 4 v_x^2 (I_z + m l_1 d_v) /
  (C_r (l_1 + l_2))`` (eq. 22-24), which puts both zero-dynamics roots on one real
  value; floored at ``d_s`` like eq. 26.
- ``fixed``: ``d_v = d_s``, the vehicle's sensor distance (the look-down controller).

Scheduled values are clamped to ``max_look_ahead``; where a bound binds, dd_v/dt is 0.
"""

from __future__ import annotations

from lookahead_control.core import numeric as xp
from lookahead_control.core.numeric import Real
from lookahead_control.core.params import ControllerParams, VehicleParams


def paper_look_ahead(v_x: Real, a_x: Real, vehicle: VehicleParams,
                     d_max: float = float('inf')) -> tuple[Real, Real]:
    """
    Return the eq. 26 look-ahead distance and its time derivative.

    :param v_x: longitudinal speed [m/s].
    :param a_x: dv_x/dt, the rate of change of v_x [m/s^2].
    :param vehicle: vehicle parameters (eta, l_2, d_s).
    :param d_max: upper clamp [m].
    :return: ``(d_v [m], dd_v/dt [m/s])``.
    """
    eta, d_s = vehicle.eta, vehicle.d_s
    raw = 4.0 * eta * v_x * v_x - vehicle.l2
    if isinstance(raw, xp.np.ndarray):
        free = (raw > d_s) & (raw < d_max)
        return xp.clip(raw, d_s, d_max), xp.where(free, 8.0 * eta * v_x * a_x, 0.0 * v_x)
    # one float (a node's control step): no array dispatch
    if d_s < raw < d_max:
        return raw, 8.0 * eta * v_x * a_x
    return (d_s if raw <= d_s else d_max), 0.0 * v_x * a_x


def exact_look_ahead(v_x: Real, a_x: Real, vehicle: VehicleParams,
                     d_max: float = float('inf')) -> tuple[Real, Real]:
    """
    Return the eq. 24 look-ahead distance (equal zero-dynamics roots) and its rate.

    With ``k = 4 v_x^2 / (C_r (l_1 + l_2))`` and ``q = m l_1`` eq. 22 reads
    ``d^2 + (2 l_2 - k q) d + l_2^2 - k I_z = 0``; its positive root is
    ``d = (k q - 2 l_2 + sqrt(k^2 q^2 + 4 k (I_z - q l_2))) / 2``.

    :param v_x: longitudinal speed [m/s].
    :param a_x: dv_x/dt, the rate of change of v_x [m/s^2].
    :param vehicle: vehicle parameters.
    :param d_max: upper clamp [m].
    :return: ``(d_v [m], dd_v/dt [m/s])``.
    """
    q = vehicle.mass * vehicle.l1
    c = 4.0 * (vehicle.yaw_inertia - q * vehicle.l2)
    k = 4.0 * v_x * v_x / (vehicle.c_r * vehicle.wheelbase)
    root = xp.sqrt(xp.maximum(k * k * q * q + c * k, 0.0 * k))
    raw = 0.5 * (k * q - 2.0 * vehicle.l2 + root)
    # dd/dt = (dd/dk) (dk/dv) a_x with dk/dv = 8 v_x / (C_r (l_1 + l_2))
    dd_dk = 0.5 * (q + (2.0 * k * q * q + c) / (2.0 * xp.maximum(root, 1e-12)))
    rate_free = dd_dk * 8.0 * v_x * a_x / (vehicle.c_r * vehicle.wheelbase)
    free = (raw > vehicle.d_s) & (raw < d_max) if isinstance(raw, xp.np.ndarray) else (
        vehicle.d_s < raw < d_max)
    return xp.clip(raw, vehicle.d_s, d_max), xp.where(free, rate_free, 0.0 * v_x)


def look_ahead(v_x: Real, a_x: Real, vehicle: VehicleParams,
               controller: ControllerParams) -> tuple[Real, Real]:
    """
    Return ``(d_v, dd_v/dt)`` of the schedule the controller parameters select.

    :param v_x: longitudinal speed [m/s].
    :param a_x: dv_x/dt, the rate of change of v_x [m/s^2].
    :param vehicle: vehicle parameters.
    :param controller: controller parameters (schedule mode, clamp).
    :return: ``(d_v [m], dd_v/dt [m/s])``.
    """
    if controller.schedule == 'paper':
        return paper_look_ahead(v_x, a_x, vehicle, controller.max_look_ahead)
    if controller.schedule == 'exact':
        return exact_look_ahead(v_x, a_x, vehicle, controller.max_look_ahead)
    return min(vehicle.d_s, controller.max_look_ahead) + 0.0 * v_x, 0.0 * v_x
