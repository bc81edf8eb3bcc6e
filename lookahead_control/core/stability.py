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
The Section 4 stability certificate of the zero dynamics under varying speed.

With d_v on eq. 25 (``d_v = 4 eta v_x^2 - l_2``) the zero dynamics are
``x' = A(v_x) x``. ``P(v_x)`` solves ``A^T P + P A = -I``; with ``V = x^T P x``,
``V' = x^T (-I + P') x`` and ``P' = (dP/dv_x) a_x``. ``V' < 0`` for every state if
``max |eig(P')| < 1`` (Bauer-Fike), or if the Gershgorin discs of ``B = -I + P'`` lie
in the open left half plane. ``dP/dv_x`` solves the differentiated Lyapunov equation
``A^T P_v + P_v A = -(A_v^T P + P A_v)`` exactly (no finite differences).
"""

from __future__ import annotations

from typing import NamedTuple

from lookahead_control.core.params import VehicleParams
from lookahead_control.core.zero_dynamics import system_matrix
import numpy as np
import numpy.typing as npt


Matrix = npt.NDArray[np.float64]

PAPER_NORM_BOUND = 0.477
PAPER_GERSHGORIN = {'b11': -0.4502, 'b22': -0.8133, 'r1': 0.0395, 'r2': 0.0395}


class Certificate(NamedTuple):
    """
    Worst cases of the certificate over the speed envelope at ``|a_x| = a_max``.

    :param v_min: lower speed of the envelope [m/s].
    :param v_max: upper speed of the envelope [m/s].
    :param a_max: acceleration bound [m/s^2].
    :param d_v_max: eq. 25 d_v at ``v_max`` [m].
    :param max_norm: max over speed of ``||P'||_2 = max |eig(P')|`` (P' symmetric).
    :param max_norm_speed: the speed where it occurs [m/s].
    :param b11: max over speed and sign of a_x of ``-1 + P'_11``.
    :param b22: max of ``-1 + P'_22``.
    :param r: max of ``|P'_12|`` (both disc radii of a symmetric 2x2).
    :param max_eig_b: max over speed and sign of a_x of the largest eigenvalue of B.
    :param holds_norm: the Bauer-Fike test passes (``max_norm < 1``).
    :param holds_gershgorin: every disc lies left of 0.
    """

    v_min: float
    v_max: float
    a_max: float
    d_v_max: float
    max_norm: float
    max_norm_speed: float
    b11: float
    b22: float
    r: float
    max_eig_b: float
    holds_norm: bool
    holds_gershgorin: bool


def lyapunov(a: Matrix, q: Matrix) -> Matrix:
    """
    Solve ``A^T P + P A = -Q`` for symmetric P (Kronecker form).

    :param a: an n x n Hurwitz matrix.
    :param q: an n x n symmetric matrix.
    :return: P.
    """
    n = a.shape[0]
    eye = np.eye(n)
    lhs = np.kron(eye, a.T) + np.kron(a.T, eye)
    p = np.linalg.solve(lhs, -q.reshape(-1, order='F')).reshape(n, n, order='F')
    return 0.5 * (p + p.T)


def eq25_look_ahead(vehicle: VehicleParams, v_x: float) -> tuple[float, float]:
    """
    Return eq. 25 ``d_v = 4 eta v_x^2 - l_2`` and ``d d_v / d v_x = 8 eta v_x``.

    :param vehicle: vehicle parameters.
    :param v_x: speed [m/s].
    :return: d_v [m] and its speed derivative [s].
    """
    return 4.0 * vehicle.eta * v_x * v_x - vehicle.l2, 8.0 * vehicle.eta * v_x


def lyapunov_derivative(vehicle: VehicleParams, v_x: float) -> tuple[Matrix, Matrix]:
    """
    Return ``P(v_x)`` and ``dP/dv_x`` along the eq. 25 schedule.

    :param vehicle: vehicle parameters.
    :param v_x: speed [m/s].
    :return: ``(P, dP/dv_x)``.
    """
    d_v, d_dv = eq25_look_ahead(vehicle, v_x)
    a = system_matrix(vehicle, v_x, d_v)
    # A = [[0, 1], [-alpha, -c]] with alpha(d_v), c = 4 v m l1 / (I_z + m l1 d_v)
    ml1 = vehicle.mass * vehicle.l1
    den = vehicle.yaw_inertia + ml1 * d_v
    alpha = vehicle.c_r * vehicle.wheelbase / den
    d_alpha = -alpha * ml1 * d_dv / den
    d_c = 4.0 * ml1 / den - 4.0 * v_x * ml1 * ml1 * d_dv / (den * den)
    a_v = np.array([[0.0, 0.0], [-d_alpha, -d_c]])
    p = lyapunov(a, np.eye(2))
    p_v = lyapunov(a, a_v.T @ p + p @ a_v)
    return p, p_v


def certificate(vehicle: VehicleParams, v_min: float = 10.0, v_max: float = 37.0,
                a_max: float = 3.5, samples: int = 2701) -> Certificate:
    """
    Evaluate the Section 4 certificate on a dense speed grid.

    ``P'`` is linear in ``a_x``, so the worst case over ``|a_x| <= a_max`` is at
    ``a_x = +-a_max``; both signs are checked.

    :param vehicle: vehicle parameters.
    :param v_min: lower speed [m/s].
    :param v_max: upper speed [m/s].
    :param a_max: acceleration bound [m/s^2].
    :param samples: number of speeds in the grid.
    :return: the worst cases and whether each test holds.
    """
    if not 0.0 < v_min < v_max:
        raise ValueError(f'speed envelope [{v_min!r}, {v_max!r}] m/s must satisfy '
                         '0 < v_min < v_max')
    if not a_max >= 0.0:
        raise ValueError(f'a_max = {a_max!r} m/s^2 must be >= 0')
    if eq25_look_ahead(vehicle, v_min)[0] + vehicle.l2 <= 0.0:
        raise ValueError(f'eq. 25 gives d_v + l_2 <= 0 at v_min = {v_min!r} m/s')
    max_norm, max_norm_speed = -np.inf, v_min
    b11 = b22 = r = max_eig = -np.inf
    for v in np.linspace(v_min, v_max, samples):
        _, p_v = lyapunov_derivative(vehicle, float(v))
        norm = a_max * float(np.max(np.abs(np.linalg.eigvalsh(p_v))))
        if norm > max_norm:
            max_norm, max_norm_speed = norm, float(v)
        for sign in (-1.0, 1.0):
            b = -np.eye(2) + sign * a_max * p_v
            b11 = max(b11, float(b[0, 0]))
            b22 = max(b22, float(b[1, 1]))
            r = max(r, abs(float(b[0, 1])))
            max_eig = max(max_eig, float(np.max(np.linalg.eigvalsh(b))))
    holds_gershgorin = b11 + r < 0.0 and b22 + r < 0.0
    return Certificate(v_min, v_max, a_max, eq25_look_ahead(vehicle, v_max)[0], max_norm,
                       max_norm_speed, b11, b22, r, max_eig, max_norm < 1.0,
                       holds_gershgorin)
