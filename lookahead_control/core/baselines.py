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
The lateral controllers a user would pick instead: pure pursuit, Stanley, LQR.

Each is written from its reference (``docs/baselines.md`` gives the equations, the
references and how the defaults were tuned) on the inputs every law of this package gets:
the CG lateral error ``y_cg`` (from the error measured at the sensor distance), relative
yaw ``eps_r``, yaw rate ``r``, ``v_x``, ``v_y``, ``a_x`` and the road curvature ahead
(``distances`` [m] from the CG's foot point along the lane, ``curvatures`` [1/m]).

- Pure pursuit as Autoware's ``autoware_pure_pursuit``: rear-axle reference point,
  look-ahead ``clamp(k_v v_x + k_e |e_ra| (past a threshold) - k_rho |rho|, L_min, L_max)``,
  target the lane point that distance from the rear axle,
  ``delta = atan(L 2 y_t / |t|^2)``.
- Stanley as in Hoffmann et al. (ACC 2007): front-axle reference point,
  ``delta = -(psi_fa - psi_ss) - atan(k e_fa / (k_soft + v_x)) - k_r (r - r_traj)``,
  with the steady-state yaw term ``psi_ss = k_ag m v_x r_traj / (C_f (1 + l_1 / l_2))``
  (the front tyres' steady slip: with ``k_ag = 1`` the law holds the front axle on an arc
  of the single-track model with zero error).
- LQR as Apollo's lateral controller: state ``[e_1, e_1', e_2, e_2']`` of the error model
  (Rajamani 2012, eq. 2.45), bilinear discretization, gain from the discrete algebraic
  Riccati equation (solved here by structure-preserving doubling) at each speed of a
  table, interpolated in speed; curvature feedforward ``L rho + K_v v^2 rho + k_3
  e_2,ss``. ``e_1'`` is measured as ``v_y cos e_2 + v_x sin e_2`` (Apollo's ``v sin e_2``
  ignores ``v_y``; ``lateral_rate = 'apollo'`` selects it for comparison).

Geometry is exact: the lane is laid out from the curvature preview in the frame of its
tangent at the CG's foot point, so pure pursuit's 20-90 m look-ahead stays right on a
25 m-radius S-bend. Every function takes floats (a node's step) or arrays (a batch, one
run per element; preview curvatures then have shape ``(points, runs)``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
import math
from typing import Any, NamedTuple

from lookahead_control.core.control_law import LateralState, LawOutput
from lookahead_control.core.laws import Law, output, Preview
from lookahead_control.core.numeric import Real
from lookahead_control.core.params import (check_choice, check_range, ParameterError,
                                           VehicleParams)
import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]
LATERAL_RATE_MODES = ('kinematic', 'apollo')
PATH_STEP = 0.5        # [m] spacing of the lane laid out from the preview


# -- lane geometry from the curvature preview ------------------------------------------

class LanePath(NamedTuple):
    """
    The lane centreline in the frame of its tangent at the CG's foot point.

    x along that tangent, y to its left; shape ``(M,)`` for one run, ``(M, N)`` for N.

    :param step: arc-length spacing of the points [m].
    :param x: longitudinal coordinates [m].
    :param y: lateral coordinates [m].
    :param heading: tangent direction [rad].
    :param curvature: curvature [1/m].
    """

    step: float
    x: Array
    y: Array
    heading: Array
    curvature: Array


def _interp_columns(s: Array, distances: Array, values: Array) -> Array:
    """Interpolate ``values`` (``(K,)`` or ``(K, N)``) at ``s`` (``(M,)``), ends held."""
    if distances.shape[0] == 1:
        return np.broadcast_to(values[:1], (s.shape[0],) + values.shape[1:]).copy()
    idx = np.clip(np.searchsorted(distances, s, side='right') - 1, 0, distances.shape[0] - 2)
    span = distances[idx + 1] - distances[idx]
    w = np.clip((s - distances[idx]) / span, 0.0, 1.0)
    if values.ndim == 2:
        w = w[:, None]
    return values[idx] * (1.0 - w) + values[idx + 1] * w


def lane_path(distances: Any, curvatures: Any, length: float,
              step: float = PATH_STEP) -> LanePath:
    """
    Lay out the lane centreline from its curvature along the arc length.

    The heading is the trapezoidal integral of the curvature; each chord points along the
    mean heading of its ends and is as long as the chord of an arc of that turn (exact on an
    arc, second order on a clothoid).

    :param distances: preview distances from the CG's foot point, increasing [m].
    :param curvatures: curvature at each distance, ``(K,)`` or ``(K, N)`` [1/m].
    :param length: lay the lane out to this arc length [m].
    :param step: point spacing [m].
    :return: the lane points.
    """
    d = np.asarray(distances, dtype=float).reshape(-1)
    c = np.asarray(curvatures, dtype=float)
    if c.shape[0] != d.shape[0] or d.shape[0] == 0:
        raise ParameterError(f'preview: {d.shape[0]} distances but curvatures of shape '
                             f'{c.shape}; one curvature per distance (and at least one) '
                             'is required')
    m = int(math.ceil(max(length, step) / step)) + 1
    s = np.arange(m, dtype=float) * step
    rho = _interp_columns(s, d, c)
    heading = np.zeros_like(rho)
    heading[1:] = np.cumsum(0.5 * step * (rho[1:] + rho[:-1]), axis=0)
    turn = heading[1:] - heading[:-1]
    mid = heading[:-1] + 0.5 * turn
    chord = step * np.sinc(0.5 * turn / np.pi)         # 2 sin(turn / 2) / (turn / step)
    x = np.zeros_like(rho)
    y = np.zeros_like(rho)
    x[1:] = np.cumsum(chord * np.cos(mid), axis=0)
    y[1:] = np.cumsum(chord * np.sin(mid), axis=0)
    return LanePath(step, x, y, heading, rho)


def _gather(column: Array, index: Any) -> Any:
    """Return ``column[index]`` per run (``index`` an int or an ``(N,)`` int array)."""
    if column.ndim == 1:
        return column[index]
    return np.take_along_axis(column, np.asarray(index)[None, :], axis=0)[0]


def _at_arc(path: LanePath, s: Any) -> tuple[Any, Any, Any, Any]:
    """Return ``(x, y, heading, curvature)`` of the lane at arc length ``s`` (per run)."""
    m = path.x.shape[0]
    pos = np.clip(np.asarray(s, dtype=float) / path.step, 0.0, m - 1.0)
    idx = np.minimum(np.floor(pos).astype(int), m - 2)
    w = pos - idx
    out = []
    for col in (path.x, path.y, path.heading, path.curvature):
        out.append(_gather(col, idx) * (1.0 - w) + _gather(col, idx + 1) * w)
    return out[0], out[1], out[2], out[3]


def _like(value: Any, template: Any) -> Any:
    """Return ``value`` as a float if ``template`` is a float, else as an array."""
    if isinstance(template, np.ndarray):
        return np.asarray(value, dtype=float)
    return float(value)


def _batch_of(*values: Any) -> Any:
    """Return the first array among ``values`` (the batch template), else a float."""
    for v in values:
        if isinstance(v, np.ndarray):
            return v
    return 0.0


# -- pure pursuit (Autoware) -------------------------------------------------------------

@dataclass(frozen=True)
class PurePursuitParams:
    """
    Autoware's adaptive pure pursuit (``autoware_pure_pursuit``).

    :param velocity_ratio: look-ahead per speed, Autoware's ``ld_velocity_ratio`` [s].
    :param lateral_error_ratio: look-ahead per |rear-axle error| once it exceeds
        ``lateral_error_threshold``, Autoware's ``ld_lateral_error_ratio`` [-].
    :param lateral_error_threshold: Autoware's ``long_ld_lateral_error_threshold`` [m].
    :param curvature_ratio: look-ahead taken off per |curvature|, Autoware's
        ``ld_curvature_ratio`` [m^2].
    :param min_look_ahead: Autoware's ``min_lookahead_distance`` [m].
    :param max_look_ahead: Autoware's ``max_lookahead_distance`` [m].
    """

    velocity_ratio: float = 0.3
    lateral_error_ratio: float = 3.6
    lateral_error_threshold: float = 0.5
    curvature_ratio: float = 120.0
    min_look_ahead: float = 4.35
    max_look_ahead: float = 60.0

    def __post_init__(self) -> None:
        check_range('pure_pursuit.velocity_ratio', self.velocity_ratio, 0.0, 10.0, unit='s')
        check_range('pure_pursuit.lateral_error_ratio', self.lateral_error_ratio, 0.0, 100.0)
        check_range('pure_pursuit.lateral_error_threshold', self.lateral_error_threshold,
                    0.0, 100.0, unit='m')
        check_range('pure_pursuit.curvature_ratio', self.curvature_ratio, 0.0, 1.0e4,
                    unit='m^2')
        check_range('pure_pursuit.min_look_ahead', self.min_look_ahead, 0.0, 200.0,
                    low_open=True, unit='m')
        check_range('pure_pursuit.max_look_ahead', self.max_look_ahead, 0.0, 200.0,
                    low_open=True, unit='m')
        if self.min_look_ahead > self.max_look_ahead:
            raise ParameterError(
                f'pure_pursuit.min_look_ahead = {self.min_look_ahead!r} m exceeds '
                f'pure_pursuit.max_look_ahead = {self.max_look_ahead!r} m; it must not')


class PurePursuitOutput(NamedTuple):
    """
    One pure-pursuit evaluation.

    :param steering: front-wheel angle [rad].
    :param look_ahead: look-ahead distance from the rear axle [m].
    :param target_lateral: the target's lateral coordinate in the vehicle frame [m].
    :param curvature: commanded path curvature 2 y_t / |t|^2 [1/m].
    """

    steering: Real
    look_ahead: Real
    target_lateral: Real
    curvature: Real


def pure_pursuit_look_ahead(v_x: Real, lateral_error: Real, rho: Real,
                            params: PurePursuitParams) -> Real:
    """
    Return Autoware's adaptive look-ahead distance.

    :param v_x: speed [m/s].
    :param lateral_error: rear-axle lateral error [m].
    :param rho: road curvature [1/m].
    :param params: pure-pursuit parameters.
    :return: ``clamp(k_v |v| + k_e |e| [|e| >= e_0] - k_rho |rho|, L_min, L_max)`` [m].
    """
    error = np.abs(lateral_error)
    total = (params.velocity_ratio * np.abs(v_x)
             + np.where(error >= params.lateral_error_threshold,
                        params.lateral_error_ratio * error, 0.0)
             - params.curvature_ratio * np.abs(rho))
    return _like(np.clip(total, params.min_look_ahead, params.max_look_ahead),
                 _batch_of(v_x, lateral_error, rho))


def pure_pursuit(y_cg: Real, eps_r: Real, v_x: Real, distances: Any, curvatures: Any,
                 vehicle: VehicleParams, params: PurePursuitParams) -> PurePursuitOutput:
    """
    Evaluate pure pursuit from the rear axle on the lane laid out from the preview.

    :param y_cg: CG lateral error [m].
    :param eps_r: relative yaw [rad].
    :param v_x: speed [m/s].
    :param distances: preview distances [m].
    :param curvatures: preview curvatures [1/m].
    :param vehicle: vehicle parameters (l_2, wheelbase).
    :param params: pure-pursuit parameters.
    :return: the steering angle and intermediate values.
    """
    template = _batch_of(y_cg, eps_r, v_x)
    y, e, v = (np.asarray(a, dtype=float) for a in (y_cg, eps_r, v_x))
    rear_x, rear_y = -vehicle.l2 * np.cos(e), y - vehicle.l2 * np.sin(e)
    rho0 = np.asarray(curvatures, dtype=float)[0]
    # the lane behind the CG taken as an arc of the curvature at the CG
    rear_error = rear_y - 0.5 * rho0 * vehicle.l2 * vehicle.l2
    ld = np.asarray(pure_pursuit_look_ahead(v, rear_error, rho0, params), dtype=float)
    path = lane_path(distances, curvatures, float(np.max(ld)) + vehicle.l2 + 2.0 * PATH_STEP
                     + float(np.max(np.abs(y))))
    dist = np.hypot(path.x - rear_x, path.y - rear_y)
    beyond = dist >= ld
    last = dist.shape[0] - 1
    j = np.where(beyond.any(axis=0), np.argmax(beyond, axis=0), last)
    j0 = np.maximum(j - 1, 0)
    d0, d1 = _gather(dist, j0), _gather(dist, j)
    frac = np.where(d1 > d0, np.clip((ld - d0) / np.where(d1 > d0, d1 - d0, 1.0), 0.0, 1.0),
                    1.0)
    tx = _gather(path.x, j0) * (1.0 - frac) + _gather(path.x, j) * frac - rear_x
    ty = _gather(path.y, j0) * (1.0 - frac) + _gather(path.y, j) * frac - rear_y
    local_y = -np.sin(e) * tx + np.cos(e) * ty
    squared = tx * tx + ty * ty
    curvature = np.where(squared > 0.0, 2.0 * local_y / np.where(squared > 0.0, squared, 1.0),
                         0.0)
    steering = np.arctan(vehicle.wheelbase * curvature)
    return PurePursuitOutput(_like(steering, template), _like(ld, template),
                             _like(local_y, template), _like(curvature, template))


# -- Stanley (Hoffmann et al. 2007) ------------------------------------------------------

@dataclass(frozen=True)
class StanleyParams:
    """
    Stanley's steering law with Hoffmann et al.'s (2007) additions.

    :param gain: k of ``atan(k e / (k_soft + v))`` [1/s].
    :param softening: k_soft, keeps the cross-track term finite at low speed [m/s].
    :param yaw_rate_gain: k_d,yaw on ``r - r_traj`` [s].
    :param steady_yaw_gain: k_ag on the steady-state yaw term (1: the single-track value).
    """

    gain: float = 4.0
    softening: float = 1.0
    yaw_rate_gain: float = 0.05
    steady_yaw_gain: float = 1.0

    def __post_init__(self) -> None:
        check_range('stanley.gain', self.gain, 0.0, 100.0, low_open=True, unit='1/s')
        check_range('stanley.softening', self.softening, 0.0, 100.0, low_open=True,
                    unit='m/s')
        check_range('stanley.yaw_rate_gain', self.yaw_rate_gain, 0.0, 10.0, unit='s')
        check_range('stanley.steady_yaw_gain', self.steady_yaw_gain, 0.0, 5.0)


class StanleyOutput(NamedTuple):
    """
    One Stanley evaluation.

    :param steering: front-wheel angle [rad].
    :param front_error: lateral error of the front axle from the lane [m].
    :param front_heading: relative yaw at the front axle's foot point [rad].
    :param steady_yaw: the steady-state yaw term psi_ss [rad].
    :param path_yaw_rate: r_traj = v_x rho at the front axle [rad/s].
    """

    steering: Real
    front_error: Real
    front_heading: Real
    steady_yaw: Real
    path_yaw_rate: Real


def stanley(y_cg: Real, eps_r: Real, r: Real, v_x: Real, distances: Any, curvatures: Any,
            vehicle: VehicleParams, params: StanleyParams) -> StanleyOutput:
    """
    Evaluate Stanley at the front axle on the lane laid out from the preview.

    :param y_cg: CG lateral error [m].
    :param eps_r: relative yaw [rad].
    :param r: yaw rate [rad/s].
    :param v_x: speed [m/s].
    :param distances: preview distances [m].
    :param curvatures: preview curvatures [1/m].
    :param vehicle: vehicle parameters.
    :param params: Stanley parameters.
    :return: the steering angle and intermediate values.
    """
    template = _batch_of(y_cg, eps_r, r, v_x)
    y, e, rate, v = (np.asarray(a, dtype=float) for a in (y_cg, eps_r, r, v_x))
    fx, fy = vehicle.l1 * np.cos(e), y + vehicle.l1 * np.sin(e)
    path = lane_path(distances, curvatures, vehicle.l1 + float(np.max(np.abs(y))) + 10.0)
    s = np.maximum(fx, 0.0)
    for _ in range(3):          # Newton steps to the foot point of the front axle
        px, py, heading, _rho = _at_arc(path, s)
        s = np.maximum(s + (fx - px) * np.cos(heading) + (fy - py) * np.sin(heading), 0.0)
    px, py, heading, rho = _at_arc(path, s)
    error = -(fx - px) * np.sin(heading) + (fy - py) * np.cos(heading)
    psi = e - heading
    r_traj = v * rho
    psi_ss = (params.steady_yaw_gain * vehicle.mass * v * r_traj
              / (vehicle.c_f * (1.0 + vehicle.l1 / vehicle.l2)))
    steering = (-(psi - psi_ss) - np.arctan(params.gain * error / (params.softening + v))
                - params.yaw_rate_gain * (rate - r_traj))
    return StanleyOutput(_like(steering, template), _like(error, template),
                         _like(psi, template), _like(psi_ss, template),
                         _like(r_traj, template))


# -- LQR on the lateral error model (Apollo) ---------------------------------------------

@dataclass(frozen=True)
class LqrParams:
    """
    Apollo's LQR lateral controller on the error model ``[e_1, e_1', e_2, e_2']``.

    :param q_lateral: Q weight of e_1 [1/m^2].
    :param q_lateral_rate: Q weight of e_1' [s^2/m^2].
    :param q_heading: Q weight of e_2 [1/rad^2].
    :param q_heading_rate: Q weight of e_2' [s^2/rad^2].
    :param r: R weight of the steering angle [1/rad^2].
    :param period: sampling period the gains are designed for [s].
    :param min_speed: lowest speed of the gain table (below: its first gain) [m/s].
    :param max_speed: highest speed of the gain table [m/s].
    :param speed_step: spacing of the gain table [m/s].
    :param lateral_rate: ``kinematic`` (e_1' = v_y cos e_2 + v_x sin e_2) or ``apollo``
        (e_1' = v_x sin e_2, which ignores v_y).
    :param feedforward: add Apollo's curvature feedforward.
    """

    q_lateral: float = 0.01
    q_lateral_rate: float = 0.0
    q_heading: float = 0.1
    q_heading_rate: float = 0.0
    r: float = 1.0
    period: float = 0.01
    min_speed: float = 1.0
    max_speed: float = 70.0
    speed_step: float = 0.5
    lateral_rate: str = 'kinematic'
    feedforward: bool = True

    def __post_init__(self) -> None:
        for name in ('q_lateral', 'q_lateral_rate', 'q_heading', 'q_heading_rate'):
            check_range(f'lqr.{name}', getattr(self, name), 0.0, 1.0e6)
        check_range('lqr.r', self.r, 0.0, 1.0e6, low_open=True)
        check_range('lqr.period', self.period, 0.0, 1.0, low_open=True, unit='s')
        check_range('lqr.min_speed', self.min_speed, 0.0, 50.0, low_open=True, unit='m/s')
        check_range('lqr.max_speed', self.max_speed, 0.0, 150.0, low_open=True, unit='m/s')
        check_range('lqr.speed_step', self.speed_step, 0.0, 10.0, low_open=True, unit='m/s')
        check_choice('lqr.lateral_rate', self.lateral_rate, LATERAL_RATE_MODES)
        if self.min_speed >= self.max_speed:
            raise ParameterError(f'lqr.min_speed = {self.min_speed!r} m/s must be below '
                                 f'lqr.max_speed = {self.max_speed!r} m/s')
        if self.q_lateral + self.q_heading <= 0.0:
            raise ParameterError('lqr.q_lateral = lqr.q_heading = 0: the error would not be '
                                 'regulated; one of them must be positive')


def error_model(vehicle: VehicleParams, v_x: float) -> tuple[Array, Array]:
    """
    Return ``(A, B)`` of the lateral error model (Rajamani 2012, eq. 2.45; Apollo).

    State ``[e_1, e_1', e_2, e_2']`` (lateral error at the CG, its rate, relative yaw, its
    rate), input the front-wheel angle; curvature enters as a disturbance.

    :param vehicle: vehicle parameters (axle cornering stiffnesses).
    :param v_x: speed [m/s] (> 0).
    :return: the 4x4 and 4x1 matrices.
    """
    m, iz, lf, lr = vehicle.mass, vehicle.yaw_inertia, vehicle.l1, vehicle.l2
    cf, cr = vehicle.c_f, vehicle.c_r
    a = np.array([
        [0.0, 1.0, 0.0, 0.0],
        [0.0, -(cf + cr) / (m * v_x), (cf + cr) / m, (lr * cr - lf * cf) / (m * v_x)],
        [0.0, 0.0, 0.0, 1.0],
        [0.0, (lr * cr - lf * cf) / (iz * v_x), (lf * cf - lr * cr) / iz,
         -(lf * lf * cf + lr * lr * cr) / (iz * v_x)]])
    b = np.array([[0.0], [cf / m], [0.0], [lf * cf / iz]])
    return a, b


def discretize(a: Array, b: Array, period: float) -> tuple[Array, Array]:
    """
    Discretize as Apollo does: bilinear (Tustin) for A, ``B T`` for B.

    :param a: continuous A.
    :param b: continuous B.
    :param period: sampling period T [s].
    :return: ``((I - A T/2)^-1 (I + A T/2), B T)``.
    """
    eye = np.eye(a.shape[0])
    ad = np.asarray(np.linalg.solve(eye - 0.5 * period * a, eye + 0.5 * period * a),
                    dtype=np.float64)
    return ad, b * period


def solve_dare(a: Array, b: Array, q: Array, r: Array, tolerance: float = 1e-12,
               max_iterations: int = 100) -> Array:
    """
    Solve ``P = A'PA - A'PB (R + B'PB)^-1 B'PA + Q`` by structure-preserving doubling.

    Each doubling step squares the horizon of the Riccati recursion (Chu et al., 2004):
    ``A_{k+1} = A_k W A_k``, ``G_{k+1} = G_k + A_k W G_k A_k'``, ``H_{k+1} = H_k + A_k' H_k
    W A_k`` with ``W = (I + G_k H_k)^-1``, ``G_0 = B R^-1 B'``, ``H_0 = Q``; ``H -> P``.

    :param a: A (n x n).
    :param b: B (n x m).
    :param q: Q (n x n, symmetric positive semi-definite).
    :param r: R (m x m, symmetric positive definite).
    :param tolerance: stop when the relative change of H is below this.
    :param max_iterations: give up after this many doublings.
    :return: the stabilizing solution P.
    :raises ValueError: no convergence (not stabilizable or detectable).
    """
    ak = np.array(a, dtype=float)
    gk = b @ np.linalg.solve(r, b.T)
    hk = np.array(q, dtype=float)
    eye = np.eye(ak.shape[0])
    for _ in range(max_iterations):
        with np.errstate(over='ignore', invalid='ignore'):   # divergence: caught below
            try:
                w = np.linalg.inv(eye + gk @ hk)
            except np.linalg.LinAlgError:
                # I + G H singular: weights beyond precision (dev-probe71: lqr.r 1e-6 with
                # q_lateral 1e6 at period 1 s crashed the node a run-time set reached)
                break
            a_next = ak @ w @ ak
            g_next = gk + ak @ w @ gk @ ak.T
            h_next = hk + ak.T @ hk @ w @ ak
            change = np.linalg.norm(h_next - hk, 1)
        ak, gk, hk = a_next, g_next, 0.5 * (h_next + h_next.T)
        if not np.all(np.isfinite(hk)):
            break
        if change <= tolerance * max(1.0, float(np.linalg.norm(hk, 1))):
            return hk
    raise ValueError('discrete Riccati equation: no convergence (is (A, B) stabilizable '
                     'and (A, Q) detectable?)')


def lqr_gain(vehicle: VehicleParams, params: LqrParams, v_x: float) -> Array:
    """
    Return the state-feedback gain K (1x4) at one speed: ``delta = -K x``.

    :param vehicle: vehicle parameters.
    :param params: LQR parameters (weights, period).
    :param v_x: speed [m/s].
    :return: ``K = (R + B'PB)^-1 B'PA`` of the discretized model.
    """
    ad, bd = discretize(*error_model(vehicle, v_x), params.period)
    q = np.diag([params.q_lateral, params.q_lateral_rate, params.q_heading,
                 params.q_heading_rate])
    r = np.array([[params.r]])
    try:
        p = solve_dare(ad, bd, q, r)
        gain = np.asarray(np.linalg.solve(r + bd.T @ p @ bd, bd.T @ p @ ad),
                          dtype=np.float64)
    except ValueError as err:       # LinAlgError is one
        raise ValueError(
            f'lqr.q_lateral = {params.q_lateral:g}, q_lateral_rate = '
            f'{params.q_lateral_rate:g}, q_heading = {params.q_heading:g}, q_heading_rate = '
            f'{params.q_heading_rate:g}, r = {params.r:g}, period = {params.period:g}: no '
            f'LQR gain at {v_x:g} m/s ({err}); weights within a few decades of each other '
            'have one') from err
    if not np.all(np.isfinite(gain)):
        raise ValueError(f'lqr: the gain at {v_x:g} m/s is not finite with r = '
                         f'{params.r:g} and period = {params.period:g}')
    return gain


@lru_cache(maxsize=16)
def gain_table(vehicle: VehicleParams, params: LqrParams) -> tuple[Array, Array]:
    """
    Return the speeds and gains of the schedule (computed once per parameter set).

    :param vehicle: vehicle parameters.
    :param params: LQR parameters.
    :return: ``(speeds (S,), gains (S, 4))``.
    """
    n = int(math.floor((params.max_speed - params.min_speed) / params.speed_step + 1e-9)) + 1
    speeds = params.min_speed + params.speed_step * np.arange(n, dtype=float)
    if speeds[-1] < params.max_speed:
        speeds = np.append(speeds, params.max_speed)
    gains = np.array([lqr_gain(vehicle, params, float(v))[0] for v in speeds])
    speeds.setflags(write=False)
    gains.setflags(write=False)
    return speeds, gains


class LqrOutput(NamedTuple):
    """
    One LQR evaluation.

    :param steering: front-wheel angle [rad].
    :param lateral_rate: e_1' as measured [m/s].
    :param heading_rate: e_2' = r - v_x rho [rad/s].
    :param feedback: -K x [rad].
    :param feedforward: curvature feedforward [rad].
    :param k_lateral: K_1, the gain on e_1 [rad/m].
    """

    steering: Real
    lateral_rate: Real
    heading_rate: Real
    feedback: Real
    feedforward: Real
    k_lateral: Real


def lqr_feedforward(vehicle: VehicleParams, v_x: Real, rho: Real, k_heading: Real) -> Real:
    """
    Return Apollo's curvature feedforward (Rajamani 2012, eq. 3.12).

    ``L rho + K_v v^2 rho + k_3 e_2,ss`` with the understeer gradient ``K_v = m l_2 /
    (C_f L) - m l_1 / (C_r L)`` and the steady relative yaw ``e_2,ss = (eta v^2 - l_2) rho``
    (axle stiffnesses; Apollo writes them per wheel, hence its ``/2``).

    :param vehicle: vehicle parameters.
    :param v_x: speed [m/s].
    :param rho: road curvature [1/m].
    :param k_heading: K_3, the gain on e_2 [-].
    :return: the feedforward angle [rad].
    """
    wheelbase, k_v = vehicle.wheelbase, vehicle.understeer_gradient
    e2_ss = (vehicle.eta * v_x * v_x - vehicle.l2) * rho
    return wheelbase * rho + k_v * v_x * v_x * rho + k_heading * e2_ss


def lqr(y_cg: Real, eps_r: Real, v_y: Real, r: Real, v_x: Real, rho: Real,
        vehicle: VehicleParams, params: LqrParams) -> LqrOutput:
    """
    Evaluate Apollo's LQR lateral law with the gain scheduled on speed.

    :param y_cg: CG lateral error e_1 [m].
    :param eps_r: relative yaw e_2 [rad].
    :param v_y: body lateral velocity [m/s].
    :param r: yaw rate [rad/s].
    :param v_x: speed [m/s].
    :param rho: road curvature at the CG [1/m].
    :param vehicle: vehicle parameters.
    :param params: LQR parameters.
    :return: the steering angle and intermediate values.
    """
    template = _batch_of(y_cg, eps_r, v_y, r, v_x, rho)
    y, e, vy, rate, v, k = (np.asarray(a, dtype=float) for a in (y_cg, eps_r, v_y, r, v_x, rho))
    speeds, gains = gain_table(vehicle, params)
    speed = np.clip(v, params.min_speed, params.max_speed)
    gain = [np.interp(speed, speeds, gains[:, i]) for i in range(4)]
    e1_rate = v * np.sin(e) + (vy * np.cos(e) if params.lateral_rate == 'kinematic' else 0.0)
    e2_rate = rate - v * k
    feedback = -(gain[0] * y + gain[1] * e1_rate + gain[2] * e + gain[3] * e2_rate)
    forward = (lqr_feedforward(vehicle, speed, k, gain[2]) if params.feedforward
               else 0.0 * speed)
    steering = feedback + forward
    return LqrOutput(_like(steering, template), _like(e1_rate, template),
                     _like(e2_rate, template), _like(feedback, template),
                     _like(forward, template), _like(gain[0], template))


# -- the laws (core.laws.Law) ------------------------------------------------------------

BASELINE_NAMES = ('pure_pursuit', 'stanley', 'lqr')


def _road(state: LateralState, preview: Preview) -> tuple[Array, Array]:
    """Return the preview's arrays, or the state's curvature held ahead if it is empty."""
    if preview.distances.size == 0:
        return np.zeros(1), np.asarray(state.rho, dtype=float)[None, ...]
    return preview.distances, preview.curvatures


def _flat(value: Real) -> Any:
    """Return a batch field as a 1-D array (floats stay floats)."""
    return value.reshape(-1) if isinstance(value, np.ndarray) else value


def _shaped(value: Any, shape: tuple[int, ...]) -> Any:
    """Return a 1-D batch result in the batch's shape (floats stay floats)."""
    return value.reshape(shape) if isinstance(value, np.ndarray) else value


class PurePursuitLaw:
    """
    Autoware's pure pursuit as a :class:`~lookahead_control.core.laws.Law` (stateless).

    :class:`LawOutput` fields: ``d_v`` = look-ahead from the rear axle minus ``l_2`` (the
    target's distance ahead of the CG), ``y_v`` = ``error`` = the vehicle's lateral offset
    from the target in the vehicle frame (``-y_t``), ``f_v`` = commanded curvature; the
    others 0.
    """

    def __init__(self, vehicle: VehicleParams, params: PurePursuitParams) -> None:
        """
        Create the law.

        :param vehicle: the controller's vehicle model (l_2, wheelbase).
        :param params: pure-pursuit parameters.
        """
        self.vehicle = vehicle
        self.params = params

    def reset(self) -> None:
        """Nothing to clear: the law has no internal state."""

    def step(self, state: LateralState, preview: Preview, dt: float) -> LawOutput:
        """
        Return the pure-pursuit command.

        :param state: the measured state.
        :param preview: the curvature ahead (empty: ``state.rho`` held).
        :param dt: unused.
        :return: the command.
        """
        shape = np.shape(state.y_cg)
        distances, curvatures = _road(state, preview)
        out = pure_pursuit(_flat(state.y_cg), _flat(state.eps_r), _flat(state.v_x), distances,
                           curvatures.reshape(curvatures.shape[0], -1) if shape else
                           curvatures, self.vehicle, self.params)
        offset = _shaped(-out.target_lateral, shape)
        return output(_shaped(out.steering, shape),
                      d_v=_shaped(out.look_ahead, shape) - self.vehicle.l2, y_v=offset,
                      error=offset, f_v=_shaped(out.curvature, shape))


class StanleyLaw:
    """
    Stanley (Hoffmann et al. 2007) as a :class:`~lookahead_control.core.laws.Law`.

    Stateless. :class:`LawOutput` fields: ``d_v`` = ``l_1`` (the front axle), ``y_v`` =
    ``error`` = the front axle's lateral error from the lane, ``y_ref`` = the steady-state
    yaw term psi_ss, ``f_v`` = r_traj; the others 0.
    """

    def __init__(self, vehicle: VehicleParams, params: StanleyParams) -> None:
        """
        Create the law.

        :param vehicle: the controller's vehicle model.
        :param params: Stanley parameters.
        """
        self.vehicle = vehicle
        self.params = params

    def reset(self) -> None:
        """Nothing to clear: the law has no internal state."""

    def step(self, state: LateralState, preview: Preview, dt: float) -> LawOutput:
        """
        Return the Stanley command.

        :param state: the measured state.
        :param preview: the curvature ahead (empty: ``state.rho`` held).
        :param dt: unused.
        :return: the command.
        """
        shape = np.shape(state.y_cg)
        distances, curvatures = _road(state, preview)
        out = stanley(_flat(state.y_cg), _flat(state.eps_r), _flat(state.r), _flat(state.v_x),
                      distances, curvatures.reshape(curvatures.shape[0], -1) if shape else
                      curvatures, self.vehicle, self.params)
        error = _shaped(out.front_error, shape)
        steering = _shaped(out.steering, shape)
        return output(steering, d_v=self.vehicle.l1 + 0.0 * steering, y_v=error, error=error,
                      y_ref=_shaped(out.steady_yaw, shape),
                      f_v=_shaped(out.path_yaw_rate, shape))


class LqrLaw:
    """
    Apollo's LQR lateral controller as a :class:`~lookahead_control.core.laws.Law`.

    Stateless (the gain table is computed once per parameter set). The curvature fed
    forward is ``state.rho`` (at the CG, as Apollo's matched point). :class:`LawOutput`
    fields: ``d_v`` = 0, ``y_v`` = ``error`` = e_1, ``y_v_rate`` = ``error_rate`` = e_1',
    ``y_ref`` = the feedforward angle, ``f_v`` = e_2', ``beta_1`` = K_1; the others 0.
    """

    def __init__(self, vehicle: VehicleParams, params: LqrParams) -> None:
        """
        Create the law and its gain table.

        :param vehicle: the controller's vehicle model.
        :param params: LQR parameters.
        """
        self.vehicle = vehicle
        self.params = params
        gain_table(vehicle, params)

    def reset(self) -> None:
        """Nothing to clear: the law has no internal state."""

    def step(self, state: LateralState, preview: Preview, dt: float) -> LawOutput:
        """
        Return the LQR command.

        :param state: the measured state.
        :param preview: unused (``state.rho`` is the curvature at the CG).
        :param dt: unused (the gains are designed for ``params.period``).
        :return: the command.
        """
        out = lqr(state.y_cg, state.eps_r, state.v_y, state.r, state.v_x, state.rho,
                  self.vehicle, self.params)
        return output(out.steering, y_v=state.y_cg + 0.0 * out.steering,
                      y_v_rate=out.lateral_rate, y_ref=out.feedforward,
                      error=state.y_cg + 0.0 * out.steering, error_rate=out.lateral_rate,
                      f_v=out.heading_rate, beta_1=out.k_lateral)


@dataclass(frozen=True)
class BaselineParams:
    """
    The parameters of every baseline law (the node holds all, uses the selected one).

    :param pure_pursuit: pure-pursuit parameters.
    :param stanley: Stanley parameters.
    :param lqr: LQR parameters.
    """

    pure_pursuit: PurePursuitParams = PurePursuitParams()
    stanley: StanleyParams = StanleyParams()
    lqr: LqrParams = LqrParams()


def baseline_law(name: str, vehicle: VehicleParams, params: BaselineParams) -> Law:
    """
    Return the baseline law called ``name``.

    :param name: one of :data:`BASELINE_NAMES`.
    :param vehicle: the controller's vehicle model.
    :param params: the baselines' parameters.
    :return: the law.
    """
    check_choice('law', name, BASELINE_NAMES)
    if name == 'pure_pursuit':
        return PurePursuitLaw(vehicle, params.pure_pursuit)
    if name == 'stanley':
        return StanleyLaw(vehicle, params.stanley)
    return LqrLaw(vehicle, params.lqr)
