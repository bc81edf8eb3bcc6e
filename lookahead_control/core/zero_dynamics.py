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
Zero (internal yaw) dynamics of the look-ahead output (paper eq. 16-20).

Holding ``y_v = 0`` at constant ``v_x`` and ``d_v``::

    eps_r'' + alpha (d_v + l_2) / v_x eps_r' + alpha eps_r = alpha (eta v_x^2 - l_2) rho
    alpha = C_r (l_1 + l_2) / (I_z + m l_1 d_v)
"""

from __future__ import annotations

import cmath
from typing import NamedTuple

from lookahead_control.core.params import VehicleParams
import numpy as np
import numpy.typing as npt


class ZeroDynamics(NamedTuple):
    """
    Characteristic data of the zero dynamics at one operating point.

    :param alpha: stiffness alpha [1/s^2].
    :param damping_ratio: (d_v + l_2) sqrt(alpha) / (2 v_x) [-].
    :param natural_frequency: sqrt(alpha) [rad/s].
    :param roots: the two characteristic roots [1/s].
    """

    alpha: float
    damping_ratio: float
    natural_frequency: float
    roots: tuple[complex, complex]


def alpha(vehicle: VehicleParams, d_v: float) -> float:
    """
    Return alpha = C_r (l_1 + l_2) / (I_z + m l_1 d_v).

    :param vehicle: vehicle parameters.
    :param d_v: look-ahead distance [m].
    :return: alpha [1/s^2].
    """
    return vehicle.c_r * vehicle.wheelbase / (
        vehicle.yaw_inertia + vehicle.mass * vehicle.l1 * d_v)


def zero_dynamics(vehicle: VehicleParams, v_x: float, d_v: float) -> ZeroDynamics:
    """
    Return the zero-dynamics characteristics at speed ``v_x`` and look-ahead ``d_v``.

    :param vehicle: vehicle parameters.
    :param v_x: longitudinal speed [m/s].
    :param d_v: look-ahead distance [m].
    :return: alpha, damping ratio, natural frequency and the roots (real part ascending).
    """
    a = alpha(vehicle, d_v)
    b = a * (d_v + vehicle.l2) / v_x
    disc = cmath.sqrt(b * b - 4.0 * a)
    roots = sorted(((-b - disc) / 2.0, (-b + disc) / 2.0), key=lambda z: (z.real, z.imag))
    wn = a ** 0.5
    return ZeroDynamics(a, b / (2.0 * wn), wn, (roots[0], roots[1]))


def steady_relative_yaw(vehicle: VehicleParams, v_x: float, rho: float) -> float:
    """
    Return the steady relative yaw on an arc, (eta v_x^2 - l_2) rho.

    :param vehicle: vehicle parameters.
    :param v_x: longitudinal speed [m/s].
    :param rho: curvature [1/m].
    :return: eps_r in steady state [rad].
    """
    return (vehicle.eta * v_x * v_x - vehicle.l2) * rho


def system_matrix(vehicle: VehicleParams, v_x: float, d_v: float) -> npt.NDArray[np.float64]:
    """
    Return A of ``[eps_r, eps_r']' = A [eps_r, eps_r']`` (Section 4).

    :param vehicle: vehicle parameters.
    :param v_x: longitudinal speed [m/s].
    :param d_v: look-ahead distance [m].
    :return: the 2x2 matrix.
    """
    a = alpha(vehicle, d_v)
    return np.array([[0.0, 1.0], [-a, -a * (d_v + vehicle.l2) / v_x]])
