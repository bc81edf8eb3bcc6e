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
Stability of the CG-compensated law's closed loop (the Section 4 argument, extended).

The homogeneous closed loop (straight road, ``rho = 0``) of the linear single-track plant
and the law with its CG-error integral has the state ``x = [y_cg, eps_r, v_y, r, I]``
and ``x' = A(v_x) x``. The reference ``d_v eps_ss(v_x, rho)`` is an exogenous signal
(it multiplies ``rho``), and the compliance estimate only scales it and is clipped, so
neither enters ``A``: they are bounded inputs to a stable system. The same holds for the
load-dependent compliance (the brush shape of the reference curve's lateral
acceleration, clipped with the estimate) and the rate feedforward (it multiplies the
road's curvature rate, clipped to ``max_lateral_jerk``). The estimate's own dynamics
(the filtered regression) are not in ``A``: they act on the loop only through these
clipped, curvature-multiplied gains.

- :func:`certificate` is the paper's Section 4 test on ``A(v_x)`` in scaled
  coordinates ``z = S^-1 x``: ``P(v_x)`` solves ``A_z^T P + P A_z = -I``;
  ``V = z^T P z`` decreases while speed varies if ``a_max max_v ||dP/dv_x||_2 < 1``.
- :func:`discrete_radius` is the robustness check: the sampled loop (ZOH at the control
  period), a plant whose mass, inertia and cornering stiffnesses differ from the
  design's, a first-order steering actuator and a transport delay of whole periods;
  stable if the spectral radius is below 1.
"""

from __future__ import annotations

import itertools
from typing import NamedTuple, Optional

from lookahead_control.core.lane_keeping import LaneKeepingParams, loop_gains
from lookahead_control.core.params import ControllerParams, VehicleParams
from lookahead_control.core.schedule import look_ahead
from lookahead_control.core.stability import lyapunov
import numpy as np
import numpy.typing as npt

Matrix = npt.NDArray[np.float64]
STATE_NAMES = ('y_cg', 'eps_r', 'v_y', 'r', 'integral')
# the certificate's coordinates z = S^-1 x (S diagonal, units of each state): chosen once
# by minimizing the test's worst value for the default settings (a Nelder-Mead search
# over log S); any fixed S gives a valid test, this one a sharp one
CERTIFICATE_SCALE = (1.0, 0.0807, 2.31, 1.69, 1.06)


def feedback_gain(vehicle: VehicleParams, controller: ControllerParams,
                  settings: LaneKeepingParams, v_x: float) -> Matrix:
    """
    Return ``K`` with ``delta = K x`` on a straight road at constant speed.

    :param vehicle: the design vehicle.
    :param controller: d_v schedule (its gains are not used: the settings' are).
    :param settings: the law's gains and integral gain.
    :param v_x: speed [m/s].
    :return: a row of 5 gains over ``[y_cg, eps_r, v_y, r, I]``.
    """
    d_v = float(look_ahead(v_x, 0.0, vehicle, controller)[0])
    m, iz, l1, l2 = vehicle.mass, vehicle.yaw_inertia, vehicle.l1, vehicle.l2
    beta_1 = vehicle.c_f * (1.0 / m + l1 * d_v / iz)
    beta_2 = vehicle.c_r * (1.0 / m - l2 * d_v / iz)
    k_p, k_d = (float(k) for k in loop_gains(settings, v_x))
    k_i = settings.integral_gain
    y_v = np.array([1.0, d_v, 0.0, 0.0, 0.0])
    y_v_rate = np.array([0.0, v_x, 1.0, d_v, 0.0])
    f_v = -np.array([0.0, 0.0, beta_1 + beta_2, beta_1 * l1 - beta_2 * l2, 0.0]) / v_x
    error = y_v + np.array([0.0, 0.0, 0.0, 0.0, 1.0])           # y_ref = -I
    error_rate = y_v_rate + np.array([k_i, 0.0, 0.0, 0.0, 0.0])  # y_ref' = -k_i y_cg
    return np.asarray((-f_v - k_p * error - k_d * error_rate) / beta_1)


def plant_matrices(plant: VehicleParams, v_x: float) -> tuple[Matrix, Matrix]:
    """
    Return ``(A_p, B_p)`` of the linear single-track plant over ``[y_cg, eps_r, v_y, r]``.

    :param plant: the plant's vehicle parameters.
    :param v_x: speed [m/s].
    :return: the 4x4 state matrix and the 4x1 steering input matrix.
    """
    m, iz, l1, l2 = plant.mass, plant.yaw_inertia, plant.l1, plant.l2
    c_f, c_r = plant.c_f, plant.c_r
    a = np.array([
        [0.0, v_x, 1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
        [0.0, 0.0, -(c_f + c_r) / (m * v_x), (c_r * l2 - c_f * l1) / (m * v_x) - v_x],
        [0.0, 0.0, (c_r * l2 - c_f * l1) / (iz * v_x),
         -(c_f * l1 * l1 + c_r * l2 * l2) / (iz * v_x)]])
    b = np.array([[0.0], [0.0], [c_f / m], [c_f * l1 / iz]])
    return a, b


def closed_loop_matrix(vehicle: VehicleParams, controller: ControllerParams,
                       settings: LaneKeepingParams, v_x: float,
                       plant: Optional[VehicleParams] = None) -> Matrix:
    """
    Return the continuous closed-loop matrix over ``[y_cg, eps_r, v_y, r, I]``.

    Without actuator and delay, on the design plant, its eigenvalues are the roots of
    ``s^2 + k_d s + k_p`` (the y_v loop), the zero dynamics' two and the integral's.

    :param vehicle: the design vehicle (the law's model).
    :param controller: gains and schedule.
    :param settings: integral gain.
    :param v_x: speed [m/s].
    :param plant: the plant's parameters (None: the design vehicle).
    :return: the 5x5 matrix.
    """
    a_p, b_p = plant_matrices(plant or vehicle, v_x)
    k = feedback_gain(vehicle, controller, settings, v_x)
    a = np.zeros((5, 5))
    a[:4, :4] = a_p
    a[:4, :] += b_p @ k.reshape(1, 5)
    a[4, 0] = settings.integral_gain
    return a


class Certificate(NamedTuple):
    """
    The varying-speed test on the closed loop.

    :param v_min: lower speed [m/s].
    :param v_max: upper speed [m/s].
    :param a_max: acceleration bound [m/s^2].
    :param max_real_eig: max over speed of the largest real part of ``A``'s eigenvalues.
    :param max_norm: max over speed of ``a_max ||dP/dv_x||_2``.
    :param max_norm_speed: where it occurs [m/s].
    :param holds: every ``A`` is Hurwitz and ``max_norm < 1``.
    """

    v_min: float
    v_max: float
    a_max: float
    max_real_eig: float
    max_norm: float
    max_norm_speed: float
    holds: bool


def certificate(vehicle: VehicleParams, controller: ControllerParams,
                settings: LaneKeepingParams, v_min: float = 10.0, v_max: float = 37.0,
                a_max: float = 3.5, samples: int = 271,
                scale: tuple[float, ...] = CERTIFICATE_SCALE) -> Certificate:
    """
    Evaluate the Section 4 test on the CG-compensated closed loop.

    ``dP/dv_x`` solves ``A^T P_v + P_v A = -(A_v^T P + P A_v)`` with ``A_v`` from a
    central difference of ``A`` (step 1e-4 m/s; ``A`` is smooth in ``v_x`` where the
    schedule is not clamped, and a one-sided kink where it is).

    :param vehicle: the design vehicle.
    :param controller: gains and schedule.
    :param settings: the law's settings.
    :param v_min: lower speed [m/s].
    :param v_max: upper speed [m/s].
    :param a_max: acceleration bound [m/s^2].
    :param samples: number of speeds.
    :param scale: the diagonal of S, one positive unit per state.
    :return: the worst cases and whether the test holds.
    """
    if not 0.0 < v_min < v_max:
        raise ValueError(f'speed envelope [{v_min!r}, {v_max!r}] m/s must satisfy '
                         '0 < v_min < v_max')
    if not a_max >= 0.0:
        raise ValueError(f'a_max = {a_max!r} m/s^2 must be >= 0')
    worst_eig, worst_norm, worst_speed = -np.inf, -np.inf, v_min
    h = 1e-4
    units = np.asarray(scale, dtype=float)
    if units.shape != (5,) or not np.all(units > 0.0):
        raise ValueError(f'scale = {scale!r} must be 5 positive numbers')

    def matrix(v: float) -> Matrix:
        a = closed_loop_matrix(vehicle, controller, settings, v)
        return np.asarray(a * units[np.newaxis, :] / units[:, np.newaxis])

    for v in np.linspace(v_min, v_max, samples):
        a = matrix(float(v))
        worst_eig = max(worst_eig, float(np.max(np.linalg.eigvals(a).real)))
        if worst_eig >= 0.0:
            break
        a_v = (matrix(float(v) + h) - matrix(float(v) - h)) / (2 * h)
        p = lyapunov(a, np.eye(5))
        p_v = lyapunov(a, a_v.T @ p + p @ a_v)
        norm = a_max * float(np.max(np.abs(np.linalg.eigvalsh(0.5 * (p_v + p_v.T)))))
        if norm > worst_norm:
            worst_norm, worst_speed = norm, float(v)
    holds = worst_eig < 0.0 and worst_norm < 1.0
    return Certificate(v_min, v_max, a_max, worst_eig, worst_norm, worst_speed, holds)


def expm(a: Matrix) -> Matrix:
    """
    Return the matrix exponential (scaling and squaring, Taylor series to 20 terms).

    :param a: a square matrix.
    :return: ``exp(a)``.
    """
    norm = float(np.max(np.sum(np.abs(a), axis=1))) if a.size else 0.0
    squarings = max(0, int(np.ceil(np.log2(norm))) + 1) if norm > 0.5 else 0
    scaled = a / (2.0 ** squarings)
    result = np.eye(a.shape[0])
    term = np.eye(a.shape[0])
    for n in range(1, 21):
        term = term @ scaled / n
        result = result + term
    for _ in range(squarings):
        result = result @ result
    return result


def discrete_radius(vehicle: VehicleParams, controller: ControllerParams,
                    settings: LaneKeepingParams, v_x: float, *,
                    plant: Optional[VehicleParams] = None, period: float = 0.01,
                    lag: float = 0.05, delay_steps: int = 2) -> float:
    """
    Return the spectral radius of the sampled closed loop (stable if < 1).

    The plant (linear single-track with ``plant``'s parameters, a first-order actuator of
    time constant ``lag``) is discretized exactly with a zero-order hold over ``period``;
    the command reaches the actuator ``delay_steps`` periods late; the integral is a
    forward-Euler sum, as the law computes it.

    :param vehicle: the design vehicle.
    :param controller: gains and schedule.
    :param settings: the law's settings.
    :param v_x: speed [m/s].
    :param plant: the plant's parameters (None: the design vehicle).
    :param period: control period [s].
    :param lag: actuator time constant [s] (0: none).
    :param delay_steps: transport delay in control periods.
    :return: the spectral radius.
    """
    a_p, b_p = plant_matrices(plant or vehicle, v_x)
    if lag > 0.0:          # actuator state: delta' = (u - delta) / lag
        a_c = np.zeros((5, 5))
        a_c[:4, :4] = a_p
        a_c[:4, 4:5] = b_p
        a_c[4, 4] = -1.0 / lag
        b_c = np.zeros((5, 1))
        b_c[4, 0] = 1.0 / lag
    else:
        a_c, b_c = a_p, b_p
    n = a_c.shape[0]
    block = np.zeros((n + 1, n + 1))
    block[:n, :n] = a_c
    block[:n, n:] = b_c
    e = expm(block * period)
    phi, gamma = e[:n, :n], e[:n, n:]
    k = feedback_gain(vehicle, controller, settings, v_x)
    # state: plant (n), integral (1), commands in flight (delay_steps)
    size = n + 1 + delay_steps
    m = np.zeros((size, size))
    m[:n, :n] = phi
    gain = np.zeros((1, size))
    gain[0, :4] = k[:4]
    gain[0, n] = k[4]
    if delay_steps == 0:
        m[:n, :] += gamma @ gain
    else:
        m[:n, n + delay_steps] = gamma[:, 0]           # the oldest command acts now
        m[n + 1, :] = gain[0]                          # the newest one enters the line
        for j in range(1, delay_steps):
            m[n + 1 + j, n + j] = 1.0
    m[n, n] = 1.0
    m[n, 0] = period * settings.integral_gain
    return float(np.max(np.abs(np.linalg.eigvals(m))))


class RobustResult(NamedTuple):
    """
    The worst case of :func:`robust_check` over its grid.

    :param max_radius: the largest spectral radius found.
    :param worst: the case where it occurs (speed, mass, stiffness factors, delay).
    :param cases: how many cases were checked.
    :param holds: every case is stable.
    """

    max_radius: float
    worst: dict[str, float]
    cases: int
    holds: bool


def robust_check(vehicle: VehicleParams, controller: ControllerParams,
                 settings: LaneKeepingParams, *,
                 speeds: tuple[float, ...] = (10.0, 15.0, 20.0, 25.0, 30.0, 37.0),
                 stiffness: tuple[float, ...] = (0.7, 1.0, 1.3),
                 mass: tuple[float, ...] = (0.8, 1.0, 1.2),
                 delays: tuple[float, ...] = (0.0, 0.02, 0.05), period: float = 0.01,
                 lag: float = 0.05) -> RobustResult:
    """
    Check the sampled loop over a grid of plant mismatch, speed and delay.

    Front and rear stiffness factors vary independently; the mass factor scales the
    yaw inertia too (same radius of gyration). A friction coefficient below 1 lowers the
    tyres' secant stiffness at a given lateral acceleration: the stiffness factors stand
    for it in this linear check (0.7 of the stiffness covers mu = 0.7 up to about
    half the friction limit of a Fiala tyre).

    :param vehicle: the design vehicle.
    :param controller: gains and schedule.
    :param settings: the law's settings.
    :param speeds: speeds [m/s].
    :param stiffness: factors on C_f and on C_r.
    :param mass: factors on m and I_z.
    :param delays: transport delays [s] (rounded to whole periods).
    :param period: control period [s].
    :param lag: actuator time constant [s].
    :return: the worst case.
    """
    worst, where, cases = -np.inf, {}, 0
    for v, c_f, c_r, m, delay in itertools.product(speeds, stiffness, stiffness, mass,
                                                   delays):
        plant = VehicleParams(mass=vehicle.mass * m, yaw_inertia=vehicle.yaw_inertia * m,
                              l1=vehicle.l1, l2=vehicle.l2, c_f=vehicle.c_f * c_f,
                              c_r=vehicle.c_r * c_r, d_s=vehicle.d_s)
        steps = int(round(delay / period))
        radius = discrete_radius(vehicle, controller, settings, v, plant=plant,
                                 period=period, lag=lag, delay_steps=steps)
        cases += 1
        if radius > worst:
            worst = radius
            where = {'speed': v, 'c_f': c_f, 'c_r': c_r, 'mass': m, 'delay': delay}
    return RobustResult(worst, where, cases, worst < 1.0)
