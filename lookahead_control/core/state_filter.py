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
A Kalman filter for the lateral states on the single-track model (``docs/lane_keeping.md``).

States ``x = [y_cg, eps_r, v_y, r, F_f, F_r]``: the CG's lateral error, the relative
yaw, the lateral velocity, the yaw rate and two axle-force disturbances [N] (random
walks: what the linear tyres get wrong, a Fiala tyre's load softening, a bank). ::

    y_cg' = v_y + v_x eps_r                  eps_r' = r - v_x rho
    m v_y' = F_yf + F_yr + F_f - m v_x r     I_z r' = l_1 (F_yf + F_f) - l_2 (F_yr + F_r)
    F_yf = C_f (delta - (v_y + l_1 r) / v_x)        F_yr = -C_r (v_y - l_2 r) / v_x

Known inputs: the road curvature ``rho`` at the CG and the wheel angle ``delta``, the
law's own commands through the transport delay and the first-order actuator lag
(deterministic, not estimated). Measured: what the controller's inputs measure, the
lateral error at the sensor ``y_cg + d_s eps_r``, ``eps_r``, ``v_y`` and ``r``, with
white noise of the configured standard deviations (the simulator's defaults).

Gain: for each step, the steady-state gain of the filter sampled at that step's period,
from the discrete algebraic Riccati equation (structure-preserving doubling), on a grid
of speeds and interpolated at the measured speed. The gain is interpolated between the
two periods of a log grid (``PERIOD_STEPS`` a decade) around the step (within 0.09 %);
the gains are solved when a (period, speed) point is first needed and kept
(``CACHED_PERIODS`` periods). The noise covariances
are constant and the model is time-invariant at a speed, so the time-varying gain
converges to the steady one within a few tenths of a second; the steady gain needs no
covariance per run of a batch and costs one interpolation per step. The prediction
integrates the model over the actual step (RK4) at the measured speed.

A ``v_y`` of exactly 0 while ``r`` is not (a bridge that does not measure the lateral
velocity and sends 0, as many odometry sources do: no turning car has exactly 0) is taken
as not measured: that step's gain is the steady gain of the filter without ``v_y`` among
its measurements, and ``v_y`` is estimated from the lateral error, ``eps_r`` and ``r``
(``unmeasured_v_y_steps`` counts those steps); a restart on such a step starts ``v_y``
from the steady cornering value at the measured ``r``, ``(l_2 - eta v_x^2) r``. A car
standing straight (both exactly 0, a noise-free simulation) keeps the full gain.

Without a road curvature (``step(..., estimating=True)``: none received, or lost) a
small estimator on the kinematics alone (:func:`kinematic_model`, dev-kinrho) gives it:
states ``[eps_r, rho]``, ``eps_r' = r - v_x rho`` with the measured yaw rate a known
input, ``rho`` a random walk of the road's lateral acceleration ``v_x^2 rho``
(``curvature_drift``), the measured relative yaw the only measurement, its own steady
gain (2x1, same period grid and speed table). Its estimate is the filter's curvature
input, as a received one would be (``state.rho`` is ignored; returned as ``rho``,
``rho_rate`` 0). A constant bias of the measured relative yaw (a camera's heading
calibration) moves the estimator's ``eps_r`` alone: in a steady state the innovation
vanishes and the estimate is ``r / v_x`` (the full model's ``y_cg' = v_y + v_x eps_r``
would take the bias for a curve). With a curvature received everything is as without
the estimator, bit for bit (the estimator follows the curvature received, so an estimate
starts from the last one). A restart starts it from ``r / v_x`` (a steady turn); below
``min_speed`` the last estimate above it is returned, but no more than
``r / max(v_x, min_speed)`` in the same direction (0 in the other; none yet:
``r / max(v_x, min_speed)``); within ``+-MAX_CURVATURE``.

Safety: a non-finite measurement passes through (the law refuses it) and the filter
restarts from the next finite one (per run in a batch); a time jump (``dt < 0``, not
finite, ``> max_gap``, decided by the law) restarts it; ``dt = 0`` advances nothing and
returns the last estimate; a step longer than ``MAX_PERIOD`` restarts it from that
measurement (0.5 s; with the filter on, the law's ``max_gap`` may not exceed it); below
``min_speed`` the model's ``1 / v_x`` terms are not trusted: the measurements pass
through and the filter restarts from them.
Everything works on floats and on numpy arrays (a batch), element by element the same
operations, so a run of a batch equals the single run bit for bit.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, fields
import functools
import math
from typing import Any, Optional

from lookahead_control.core.control_law import LateralState
from lookahead_control.core.numeric import Real
from lookahead_control.core.params import check_range, VehicleParams
import numpy as np
import numpy.typing as npt

FILTER_MODES = ('none', 'kalman')
#: [rad] the model's actuator input is clamped here: no road wheel turns further
MAX_WHEEL_ANGLE = 0.5 * math.pi
STATES = ('y_cg', 'eps_r', 'v_y', 'r', 'front_force', 'rear_force')
#: the gain's grid periods: ``10^(k / PERIOD_STEPS)`` s (0.01 s is one), a step's gain
#: interpolated between the two around its period, linearly in ``log(period)``: within
#: 0.09 % of the steady gain at the exact period (of each column's largest entry, 3-80 m/s,
#: 1e-4 to 0.5 s; the nearest grid period alone: 4 %)
PERIOD_STEPS = 200
#: steps of at most this length get their gain [s]; longer ones restart the filter (the
#: Riccati equation is ill-conditioned beyond: at 3 m/s and 1 s, Phi's condition is 1e17)
MAX_PERIOD = 0.5
#: periods whose gains are kept (least recently used dropped)
CACHED_PERIODS = 128
#: longest RK4 substep of the prediction [s]
MAX_SUBSTEP = 0.01
#: :meth:`KalmanStateFilter.ahead` integrates between the instants its commands in flight
#: change, unless they change more often than this: then in substeps of it [s] (a flood
#: of 1 us steps must not make 1e5 substeps)
MIN_AHEAD_SUBSTEP = 0.002
#: a command issued within this of an instant is in effect at it [s] (the sum of the
#: steps' dt is not exact: at a delay of n + 1/2 periods the filter took one command or
#: the next at random, dev-probe44)
TIE = 1e-9
#: speed grid of the gain table [m/s] (above its end the last gain is used)
SPEED_STEP = 1.0
TOP_SPEED = 80.0
#: the estimated curvature is kept within this [1/m] (R = 5 m; the node's max_curvature)
MAX_CURVATURE = 0.2
Matrix = npt.NDArray[np.float64]


@dataclass(frozen=True)
class StateFilterParams:
    """
    Settings of the Kalman filter (``lane_keeping.filter_*`` in the node).

    :param min_speed: below this speed the measurements pass through [m/s].
    :param actuator_lag: time constant of the steering actuator the model assumes [s].
    :param delay: transport delay from command to actuator the model assumes [s].
    :param lateral_noise: standard deviation of the lateral error at the sensor [m].
    :param yaw_noise: of the relative yaw [rad].
    :param lateral_velocity_noise: of the lateral velocity [m/s].
    :param yaw_rate_noise: of the yaw rate [rad/s].
    :param force_noise: white noise on each axle force, spectral density [N sqrt(s)].
    :param force_drift: random walk of the axle-force disturbances [N / sqrt(s)].
    :param kinematic_noise: white noise on ``y_cg'`` [m / sqrt(s)] (and on ``eps_r'``,
        divided by 10 m): the small-angle kinematics' error.
    :param curvature_drift: in the curvature estimator (no ``road_curvature``
        received), the random walk of the road's lateral acceleration
        ``v_x^2 rho`` [m/s^2.5]: ``rho' = w curvature_drift / v_x^2``. Roads are laid out
        for a rate of change of the lateral acceleration of 0.3-0.6 m/s^3 along their
        clothoids (highway design: clothoid length ``L = v^3 / (C R)``), about 0.5 m/s^2
        over a 1-2 s clothoid.
    """

    min_speed: float = 3.0
    actuator_lag: float = 0.05
    delay: float = 0.02
    lateral_noise: float = 0.03
    yaw_noise: float = 0.002
    lateral_velocity_noise: float = 0.02
    yaw_rate_noise: float = 0.002
    force_noise: float = 100.0
    force_drift: float = 2000.0
    kinematic_noise: float = 0.01
    curvature_drift: float = 0.7

    def __post_init__(self) -> None:
        limits = {'min_speed': (0.5, 50.0, 'm/s'), 'actuator_lag': (0.0, 2.0, 's'),
                  'delay': (0.0, 1.0, 's'),
                  'lateral_noise': (1e-5, 5.0, 'm'), 'yaw_noise': (1e-6, 0.5, 'rad'),
                  'lateral_velocity_noise': (1e-5, 5.0, 'm/s'),
                  'yaw_rate_noise': (1e-6, 0.5, 'rad/s'),
                  'force_noise': (0.0, 1e6, 'N sqrt(s)'),
                  # 0 would never correct the force states: a closed-loop pole at 1
                  # (lane_keeping_stability's filtered check, radius 1.0)
                  'force_drift': (1.0, 1e7, 'N/sqrt(s)'),
                  'kinematic_noise': (0.0, 10.0, 'm/sqrt(s)'),
                  'curvature_drift': (1e-4, 100.0, 'm/s^2.5')}
        for item in fields(self):
            low, high, unit = limits[item.name]
            object.__setattr__(self, item.name, check_range(
                f'lane_keeping.filter_{item.name}', getattr(self, item.name), low, high,
                unit=unit))


def continuous_model(vehicle: VehicleParams, v_x: float) -> tuple[Matrix, Matrix, Matrix]:
    """
    Return ``(A, B, G)`` of ``x' = A x + B [delta, rho] + G w`` at a speed.

    ``w = [kinematic, front force, rear force, front drift, rear drift]`` (unit white
    noises before scaling).

    :param vehicle: the design vehicle.
    :param v_x: speed [m/s] (> 0).
    :return: ``A`` (6x6), ``B`` (6x2), ``G`` (6x5).
    """
    m, iz, l1, l2 = vehicle.mass, vehicle.yaw_inertia, vehicle.l1, vehicle.l2
    cf, cr = vehicle.c_f, vehicle.c_r
    a = np.zeros((6, 6))
    a[0, 1], a[0, 2] = v_x, 1.0
    a[1, 3] = 1.0
    a[2, 2] = -(cf + cr) / (m * v_x)
    a[2, 3] = -(cf * l1 - cr * l2) / (m * v_x) - v_x
    a[2, 4], a[2, 5] = 1.0 / m, 1.0 / m
    a[3, 2] = -(cf * l1 - cr * l2) / (iz * v_x)
    a[3, 3] = -(cf * l1 * l1 + cr * l2 * l2) / (iz * v_x)
    a[3, 4], a[3, 5] = l1 / iz, -l2 / iz
    b = np.zeros((6, 2))
    b[2, 0], b[3, 0] = cf / m, cf * l1 / iz
    b[1, 1] = -v_x
    g = np.zeros((6, 5))
    g[0, 0], g[1, 0] = 1.0, 0.1
    g[2, 1], g[3, 1] = 1.0 / m, l1 / iz
    g[2, 2], g[3, 2] = 1.0 / m, -l2 / iz
    g[4, 3], g[5, 4] = 1.0, 1.0
    return a, b, g


def measurement_matrix(vehicle: VehicleParams) -> Matrix:
    """
    Return ``H`` of ``z = H x + n``, ``z = [y_cg + d_s eps_r, eps_r, v_y, r]``.

    :param vehicle: the vehicle (``d_s``).
    :return: ``H`` (4 x 6).
    """
    h = np.zeros((4, 6))
    h[0, 0], h[0, 1] = 1.0, vehicle.d_s
    h[1, 1], h[2, 2], h[3, 3] = 1.0, 1.0, 1.0
    return h


def expm(a: Matrix) -> Matrix:
    """
    Return the matrix exponential (scaling and squaring, Taylor series of order 18).

    The matrix is scaled to a norm of at most 1/2, where the series' remainder is below
    ``2^-18 / 18! < 1e-21`` relative, and squared back.

    :param a: a square matrix.
    :return: ``exp(a)``.
    """
    norm = float(np.max(np.sum(np.abs(a), axis=1))) if a.size else 0.0
    squarings = max(0, int(math.ceil(math.log2(norm / 0.5)))) if norm > 0.5 else 0
    scaled = a / float(2 ** squarings)
    term = np.eye(a.shape[0])
    total = term.copy()
    for k in range(1, 19):
        term = term @ scaled / k
        total = total + term
    for _ in range(squarings):
        total = total @ total
    return total


def discrete_model(vehicle: VehicleParams, settings: StateFilterParams, v_x: float,
                   period: float) -> tuple[Matrix, Matrix, Matrix, Matrix]:
    """
    Return ``(Phi, Q, H, R)`` of the filter sampled at ``period``.

    ``Phi = expm(A h)``; ``Q`` by Van Loan's method from ``G diag(q^2) G^T``; ``R`` the
    measurement noise's covariance.

    :param vehicle: the design vehicle.
    :param settings: the filter's settings.
    :param v_x: speed [m/s].
    :param period: sampling period [s].
    :return: the four matrices.
    """
    s = settings
    noises = [s.kinematic_noise, s.force_noise, s.force_noise, s.force_drift,
              s.force_drift]
    a, _, g = continuous_model(vehicle, v_x)
    q = np.diag(np.array(noises) ** 2)
    qc = g @ q @ g.T
    n, h = a.shape[0], period
    block = np.zeros((2 * n, 2 * n))
    block[:n, :n], block[:n, n:], block[n:, n:] = -a, qc, a.T
    van_loan = expm(block * h)
    phi = van_loan[n:, n:].T
    qd = phi @ van_loan[:n, n:]
    qd = 0.5 * (qd + qd.T)
    r = np.diag(np.array([s.lateral_noise, s.yaw_noise, s.lateral_velocity_noise,
                          s.yaw_rate_noise]) ** 2)
    return phi, qd, measurement_matrix(vehicle), r


def riccati_doubling(phi: Matrix, h: Matrix, q: Matrix, r: Matrix,
                     iterations: int = 60) -> Matrix:
    """
    Return the prior covariance ``P`` of the steady-state filter (doubling algorithm).

    Solves ``P = Phi P Phi^T - Phi P H^T (H P H^T + R)^-1 H P Phi^T + Q`` by the
    structure-preserving doubling algorithm (quadratic convergence).

    :param phi: transition matrix.
    :param h: measurement matrix.
    :param q: process noise covariance.
    :param r: measurement noise covariance.
    :param iterations: most doubling steps.
    :return: ``P``.
    """
    a = phi.T
    g = h.T @ np.linalg.solve(r, h)
    x = q.copy()
    eye = np.eye(a.shape[0])
    for _ in range(iterations):
        w = eye + g @ x
        a_w = a @ np.linalg.inv(w)
        x_next = x + a.T @ x @ np.linalg.solve(w, a)
        g = g + a_w @ g @ a.T
        a = a_w @ a
        x_next = 0.5 * (x_next + x_next.T)
        done = np.max(np.abs(x_next - x)) <= 1e-14 * max(np.max(np.abs(x_next)), 1e-300)
        x = x_next
        if done:
            break
    return x


def steady_gain(vehicle: VehicleParams, settings: StateFilterParams, v_x: float,
                period: float, v_y_measured: bool = True) -> Matrix:
    """
    Return the steady-state Kalman gain ``K`` (6x4) at a speed and a sampling period.

    The update is ``x = x_prior + K (z - H x_prior)``, ``K = P H^T (H P H^T + R)^-1``.
    Without ``v_y`` among the measurements, its row of ``H`` is dropped and its column of
    ``K`` is 0.

    :param vehicle: the design vehicle.
    :param settings: the filter's settings.
    :param v_x: speed [m/s].
    :param period: sampling period [s].
    :param v_y_measured: whether ``v_y`` is measured.
    :return: ``K``.
    """
    phi, q, h, r = discrete_model(vehicle, settings, v_x, period)
    rows = [0, 1, 2, 3] if v_y_measured else [0, 1, 3]
    h, r = h[rows], r[np.ix_(rows, rows)]
    p = riccati_doubling(phi, h, q, r)
    gain: Matrix = np.zeros((phi.shape[0], 4))
    gain[:, rows] = np.linalg.solve(h @ p @ h.T + r, h @ p).T
    return gain


def kinematic_model(settings: StateFilterParams, v_x: float, period: float
                    ) -> tuple[Matrix, Matrix, Matrix, Matrix]:
    """
    Return ``(Phi, Q, H, R)`` of the curvature estimator sampled at ``period``.

    States ``[eps_r, rho]``: ``eps_r' = r - v_x rho`` with the measured yaw rate ``r`` a
    known input, ``rho' = w curvature_drift / v_x^2`` (a random walk of the road's
    lateral acceleration); ``eps_r`` the only measurement. The process noise of
    ``eps_r`` is the kinematic one (``kinematic_noise / 10 m``, as in the full model)
    plus the yaw rate's measurement noise integrated over a step (variance
    ``(period yaw_rate_noise)^2`` a step: a density of ``yaw_rate_noise^2 period``).

    :param settings: the filter's settings.
    :param v_x: speed [m/s] (> 0).
    :param period: sampling period [s].
    :return: ``Phi`` (2x2), ``Q`` (2x2), ``H`` (1x2), ``R`` (1x1).
    """
    s = settings
    a = np.array([[0.0, -v_x], [0.0, 0.0]])
    qc = np.diag([(0.1 * s.kinematic_noise) ** 2 + s.yaw_rate_noise ** 2 * period,
                  (s.curvature_drift / (v_x * v_x)) ** 2])
    block = np.zeros((4, 4))
    block[:2, :2], block[:2, 2:], block[2:, 2:] = -a, qc, a.T
    van_loan = expm(block * period)
    phi = van_loan[2:, 2:].T
    qd = phi @ van_loan[:2, 2:]
    return (phi, 0.5 * (qd + qd.T), np.array([[1.0, 0.0]]),
            np.array([[s.yaw_noise ** 2]]))


def kinematic_gain(settings: StateFilterParams, v_x: float, period: float) -> Matrix:
    """
    Return the steady-state gain (2x1) of the curvature estimator (:func:`kinematic_model`).

    :param settings: the filter's settings.
    :param v_x: speed [m/s] (> 0).
    :param period: sampling period [s].
    :return: ``K``: the update is ``x = x_prior + K (eps_r - eps_r_prior)``.
    """
    phi, q, h, r = kinematic_model(settings, v_x, period)
    p = riccati_doubling(phi, h, q, r)
    gain: Matrix = np.asarray(np.linalg.solve(h @ p @ h.T + r, h @ p).T, dtype=np.float64)
    return gain


def period_bucket(dt: float) -> tuple[int, float]:
    """
    Return the grid periods around ``dt``: ``(k, w)``, ``dt = 10^((k + w) / PERIOD_STEPS)``.

    A period within ``1e-9`` of a grid point is that point (``w = 0``): the design period
    0.01 s, however its nanoseconds round, takes the gain of 0.01 s alone.

    :param dt: a step [s] (> 0).
    :return: ``k`` and the weight ``0 <= w < 1`` of the grid period above.
    """
    u = math.log10(dt) * PERIOD_STEPS
    bucket = math.floor(u)
    weight = u - bucket
    if weight > 1.0 - 1e-9:
        return bucket + 1, 0.0
    return bucket, (weight if weight >= 1e-9 else 0.0)


def bucket_period(bucket: int) -> float:
    """
    Return the grid period of an index (``period_bucket``'s inverse).

    :param bucket: ``k``.
    :return: ``10^(k / PERIOD_STEPS)`` [s].
    """
    return float(10.0 ** (bucket / PERIOD_STEPS))


class GainTable:
    """
    The steady-state gains on the speed grid, per grid period, solved when first needed.

    A step's gain needs two speed points of two grid periods: a new period costs at most
    four Riccati solutions (about 0.6 ms each), not a table. At most
    ``CACHED_PERIODS`` periods are kept.
    """

    def __init__(self, vehicle: VehicleParams, settings: StateFilterParams,
                 v_y_measured: bool = True, curvature_estimated: bool = False) -> None:
        """
        Create the empty table.

        :param vehicle: the design vehicle.
        :param settings: the filter's settings.
        :param v_y_measured: whether ``v_y`` is among the measurements.
        :param curvature_estimated: the curvature estimator's gains (2x1,
            :func:`kinematic_gain`) instead of the filter's (6x4).
        """
        self.vehicle, self.settings, self.v_y_measured = vehicle, settings, v_y_measured
        self.curvature_estimated = curvature_estimated
        self.states, self.columns = (2, 1) if curvature_estimated else (6, 4)
        count = int(math.ceil((TOP_SPEED - settings.min_speed) / SPEED_STEP)) + 1
        self.speeds: Matrix = settings.min_speed + SPEED_STEP * np.arange(count, dtype=float)
        self.periods: OrderedDict[int, tuple[Matrix, npt.NDArray[np.bool_]]] = OrderedDict()
        #: Riccati equations solved so far
        self.solved = 0

    def gains(self, bucket: int, needed: Any) -> Matrix:
        """
        Return the gains of a grid period, with the needed speed points solved.

        :param bucket: the grid period's index ``k`` (``period_bucket``).
        :param needed: speed-grid indices (an int or an integer array).
        :return: gains (n, 6, 4) or (n, 2, 1) (NaN at the points not solved yet).
        """
        entry = self.periods.get(bucket)
        if entry is None:
            entry = (np.full((self.speeds.size, self.states, self.columns), math.nan),
                     np.zeros(self.speeds.size, dtype=bool))
            self.periods[bucket] = entry
            while len(self.periods) > CACHED_PERIODS:
                self.periods.popitem(last=False)
        else:
            self.periods.move_to_end(bucket)
        gains, done = entry
        missing = np.unique(np.asarray(needed))
        for i in missing[~done[missing]]:
            speed, period = float(self.speeds[i]), bucket_period(bucket)
            gains[i] = (kinematic_gain(self.settings, speed, period)
                        if self.curvature_estimated else
                        steady_gain(self.vehicle, self.settings, speed, period,
                                    self.v_y_measured))
            done[i] = True
            self.solved += 1
        return gains


@functools.lru_cache(maxsize=32)
def gain_table(vehicle: VehicleParams, settings: StateFilterParams,
               v_y_measured: bool = True, curvature_estimated: bool = False) -> GainTable:
    """
    Return the gain table of a vehicle and settings (one shared by all filters).

    :param vehicle: the design vehicle.
    :param settings: the filter's settings.
    :param v_y_measured: whether ``v_y`` is among the measurements.
    :param curvature_estimated: the curvature estimator's table.
    :return: the table.
    """
    return GainTable(vehicle, settings, v_y_measured, curvature_estimated)


def _bounded(rho: Real) -> Real:
    """Return the curvature within ``+-MAX_CURVATURE`` (NaN stays NaN)."""
    if isinstance(rho, np.ndarray):
        return np.where(np.isnan(rho), rho, np.clip(rho, -MAX_CURVATURE, MAX_CURVATURE))
    return rho if math.isnan(rho) else min(max(rho, -MAX_CURVATURE), MAX_CURVATURE)


def _select(mask: Any, a: Real, b: Real) -> Real:
    """Return ``a`` where ``mask`` holds, else ``b`` (floats stay floats)."""
    if isinstance(mask, np.ndarray) or isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.where(mask, a, b)
    return a if mask else b


def piece_overlaps(edges: list[float], start: float, end: float) -> list[tuple[int, float]]:
    """
    Return how long each piece between ``edges`` overlaps ``[start, end]``.

    :param edges: the pieces' bounds, increasing.
    :param start: the interval's start.
    :param end: its end.
    :return: ``(piece index, overlap)`` for the pieces that overlap it.
    """
    out = []
    for i, (a, b) in enumerate(zip(edges, edges[1:])):
        overlap = min(b, end) - max(a, start)
        if overlap > 0.0:
            out.append((i, overlap))
    return out


def _mean_input(edges: list[float], commands: list[Real], start: float,
                end: float) -> Real:
    """Return the mean over ``[start, end]`` of the piecewise constant input."""
    total: Real = 0.0
    for i, overlap in piece_overlaps(edges, start, end):
        total = total + overlap * commands[i]
    return total / (end - start)


class KalmanStateFilter:
    """
    The steady-state Kalman filter of the lateral states, one step per measurement.

    ``step(state, dt)`` returns the state with ``y_cg``, ``eps_r``, ``v_y``, ``r``
    replaced by their estimates; ``command(u)`` records the steering command the law
    sent (the model's input after ``delay`` and the actuator lag); ``reset()`` and
    ``forget(mask)`` restart it (all runs / some runs of a batch).
    """

    def __init__(self, vehicle: VehicleParams,
                 settings: Optional[StateFilterParams] = None) -> None:
        """
        Create the filter (its gains are solved when first needed, shared per settings).

        :param vehicle: the design vehicle (the law's).
        :param settings: the filter's settings (defaults if None).
        """
        self.vehicle = vehicle
        self.settings = settings or StateFilterParams()
        self.table = gain_table(vehicle, self.settings)
        #: the gains without ``v_y`` (made when first needed)
        self.blind_table: Optional[GainTable] = None
        #: the curvature estimator's gains (made when first needed)
        self.kinematic_table: Optional[GainTable] = None
        #: the curvature estimator's states ``[eps_r, rho]`` and the yaw rate measured at
        #: the last step (NaN where it restarts; None before the first step)
        self.kinematic: Optional[list[Real]] = None
        self.steps_cache: tuple[float, int, float, float, float] = (
            math.nan, 1, 0.0, 0.0, 0.0)
        veh, low = vehicle, self.settings.min_speed
        fastest = max((veh.c_f + veh.c_r) / (veh.mass * low),
                      (veh.c_f * veh.l1 ** 2 + veh.c_r * veh.l2 ** 2) / (veh.yaw_inertia * low))
        self.max_substep = min(MAX_SUBSTEP, 1.0 / fastest)
        self.innovation: tuple[Real, ...] = ()
        self.x: Optional[list[Real]] = None
        self.wheel: Real = 0.0          # the actuator's angle the model assumes [rad]
        self.held: Real = 0.0           # the command in effect before the history
        self.history: list[tuple[float, Real]] = []
        self.time = 0.0
        self.rho: Real = 0.0
        #: the last curvature of a step above ``min_speed`` (estimated or received): the
        #: bound of the estimate below it (a speed read as 0 for a moment must not make
        #: ``r / min_speed``)
        self.held_rho: Real = math.nan
        #: the runs of a batch restarted by :meth:`forget` since the last step: their
        #: next step starts them as :meth:`reset` starts a single run (the model's
        #: curvature from that step's)
        self.forgotten: Any = False
        self.restarts = 0
        #: steps longer than ``MAX_PERIOD`` (restarts from the measurement)
        self.long_steps = 0
        #: steps (of any run) that took ``v_y`` as not measured (exactly 0, ``r`` not)
        self.unmeasured_v_y_steps = 0
        #: steps (of any run) that estimated the road curvature (none received)
        self.curvature_estimated_steps = 0

    def reset(self) -> None:
        """
        Restart from the next measurement.

        The actuator model and the commands still on their way to it are kept: they are
        the car's, not the estimate's (a run of a batch restarts the same way).
        """
        self.x = None
        self.kinematic = None
        self.held_rho = math.nan
        self.forgotten = False
        self.restarts += 1

    def start(self) -> None:
        """
        Restart for a new run from rest: :meth:`reset`, and the actuator model at rest.

        A new simulation's wheel starts at 0 with no command on its way (the offline
        runner's); :meth:`reset` keeps them, for the node's car whose actuator is still
        there. A batch of another size then starts clean as well.
        """
        self.reset()
        self.wheel = 0.0
        self.held = 0.0
        self.history = []
        self.time = 0.0
        self.rho = 0.0
        self.innovation = ()

    def take_over(self, old: 'KalmanStateFilter', estimate: bool = True) -> None:
        """
        Continue from another filter's state (a retune: new settings, the same car).

        The actuator model and the commands on their way to it (the car's) are always
        carried, with the diagnostics counters; the gains are this filter's (its
        settings' covariances). With ``estimate`` the state estimate is carried too
        (the lateral states, the force disturbances, the curvature estimator's states);
        without it the estimate restarts from the next measurement.

        :param old: the filter it replaces.
        :param estimate: carry the state estimate (False: it restarts from the next
            measurement). With another design vehicle it is carried too: its force
            disturbances, the old model's error, are nearer the new one's than a restart
            from the raw measurement, which was a bump (``take_over`` of the law).
        """
        self.wheel, self.held = old.wheel, old.held
        self.history = list(old.history)
        self.time, self.rho, self.innovation = old.time, old.rho, old.innovation
        self.restarts, self.long_steps = old.restarts, old.long_steps
        self.unmeasured_v_y_steps = old.unmeasured_v_y_steps
        self.curvature_estimated_steps = old.curvature_estimated_steps
        if estimate:
            self.x = None if old.x is None else list(old.x)
            self.kinematic = None if old.kinematic is None else list(old.kinematic)
            self.held_rho, self.forgotten = old.held_rho, old.forgotten

    def forget(self, where: Any) -> None:
        """
        Restart the runs of a batch where ``where`` holds (a non-finite input).

        :param where: boolean array over the batch.
        """
        if self.x is not None:
            self.x = [np.where(where, math.nan, v) for v in self.x]
        if self.kinematic is not None:
            self.kinematic = [np.where(where, math.nan, v) for v in self.kinematic]
        # as reset() does for a single run
        self.held_rho = np.where(where, math.nan, self.held_rho)
        self.forgotten = where | self.forgotten

    def command(self, steering: Real) -> None:
        """
        Record the command sent at the present step (the model's input after the delay).

        A non-finite command (refused downstream) leaves the actuator where it was.

        :param steering: the steering command [rad]; beyond ``MAX_WHEEL_ANGLE`` no wheel
            follows it: the model's input is clamped there (a command of 1e300 rad once
            made the model's wheel overflow into NaN for good when the caller did not
            report the angle sent).
        """
        last = self.history[-1][1] if self.history else self.held
        if isinstance(steering, np.ndarray):
            # (judged before the clip: an infinite command is no command, as for a float;
            # clipped first it was a wheel at 90 degrees in a batch, dev-probe47)
            finite = np.isfinite(steering)
            steering = np.where(finite, np.clip(steering, -MAX_WHEEL_ANGLE, MAX_WHEEL_ANGLE),
                                last)
        elif math.isfinite(steering):
            steering = min(MAX_WHEEL_ANGLE, max(-MAX_WHEEL_ANGLE, steering))
        self.history.append((self.time, _select(np.isfinite(steering), steering, last)))

    def correct(self, steering: Real) -> None:
        """
        Replace the command recorded at the present step by the one actually sent.

        The node's safety layer cuts the law's command (angle and rate limits, the
        low-speed blend): the actuator gets the cut one, so the model must too.
        A non-finite value is ignored (the recorded command stays).

        :param steering: the command sent [rad] (a batch: per run).
        """
        if self.history:
            issued, recorded = self.history[-1]
            self.history[-1] = (issued, _select(np.isfinite(steering), steering, recorded))

    def _applied(self, when: float) -> Real:
        """Return the command in effect at the actuator's input at time ``when``."""
        value = self.held
        keep = 0
        for i, (issued, command) in enumerate(self.history):
            if issued <= when + TIE:
                value, keep = command, i
            else:
                break
        if keep > 0:                    # older commands are no longer needed
            self.held = self.history[keep - 1][1]
            del self.history[:keep]
        return value

    def _measured(self, state: LateralState) -> list[Real]:
        """
        Return the state as measured.

        ``y_cg, eps_r, v_y, r``, no disturbance and the curvature received.
        """
        zero = 0.0 * state.y_cg
        return [state.y_cg, state.eps_r, state.v_y, state.r, zero, zero, state.rho]

    def _gain(self, v_x: Real, dt: float, blind: Any = False) -> list[list[Real]]:
        """
        Return ``K`` at the speed and step, interpolated in speed (element by element).

        :param v_x: speed [m/s].
        :param dt: the step [s].
        :param blind: where true, the gain without ``v_y`` among the measurements.
        :return: ``K`` as rows of columns.
        """
        count = int(np.count_nonzero(blind))
        self.unmeasured_v_y_steps += count
        return self._blind_or_not(self.table, self._blind_table, v_x, dt, blind, count)

    def _blind_table(self) -> GainTable:
        """Return the table without ``v_y`` (made when first needed)."""
        if self.blind_table is None:
            self.blind_table = gain_table(self.vehicle, self.settings, False)
        return self.blind_table

    def _blind_or_not(self, table: GainTable, blind_table: Any, v_x: Real, dt: float,
                      blind: Any, count: int) -> list[list[Real]]:
        """Return ``table``'s gain, ``blind_table()``'s where ``blind`` holds."""
        if count == 0:
            return self._table_gain(table, v_x, dt)
        other = self._table_gain(blind_table(), v_x, dt)
        if count == np.size(blind):     # every run without v_y: the full gain is not needed
            return other
        gain = self._table_gain(table, v_x, dt)
        return [[_select(blind, b, g) for b, g in zip(row_b, row_g)]
                for row_b, row_g in zip(other, gain)]

    def _table_gain(self, table: GainTable, v_x: Real, dt: float) -> list[list[Real]]:
        """Return ``K`` of one table at the speed and step, interpolated in speed."""
        speeds = table.speeds
        bucket, between = period_bucket(dt)
        top = speeds.size - 1
        u = (v_x - speeds[0]) / SPEED_STEP
        if isinstance(u, np.ndarray):
            u = np.clip(u, 0.0, float(top))
            i = np.minimum(np.floor(u).astype(int), top - 1)
            w = u - i
            gains = self._period_gains(table, bucket, between,
                                       np.concatenate([i.ravel(), i.ravel() + 1]))
            # the whole matrix per run at once (the same operations per element)
            low = gains[i]
            mixed = low + w[..., None, None] * (gains[i + 1] - low)
            return [[mixed[..., row, col] for col in range(table.columns)]
                    for row in range(table.states)]
        u = min(max(float(u), 0.0), float(top))
        j = min(int(math.floor(u)), top - 1)
        f = u - j
        gains = self._period_gains(table, bucket, between, [j, j + 1])
        return [[float(gains[j, row, col] + f * (gains[j + 1, row, col] - gains[j, row, col]))
                 for col in range(table.columns)] for row in range(table.states)]

    @staticmethod
    def _period_gains(table: GainTable, bucket: int, between: float, needed: Any) -> Matrix:
        """Return the gains on the speed grid at the period ``(bucket, between)``."""
        lower = table.gains(bucket, needed)
        if between == 0.0:
            return lower
        upper = table.gains(bucket + 1, needed)
        gains: Matrix = lower + between * (upper - lower)
        return gains

    def _predict(self, x: list[Real], dt: float, v_x: Real, rho: Real,
                 rho_start: Real) -> list[Real]:
        """
        Integrate the model over ``dt`` (RK4 substeps), the wheel angle exact in between.

        The curvature goes linearly from ``rho_start`` to ``rho`` over the step (the
        estimated one is constant: ``x[6]`` both, the random walk's prediction).

        A substep is at most ``MAX_SUBSTEP`` and at most ``1 / lambda`` of the fastest
        tyre mode at ``min_speed`` (RK4 is unstable beyond ``2.8 / lambda``): a long step
        (lost messages, a slow sensor) at low speed is integrated, not amplified. The
        count depends only on ``dt`` and the settings: the same for every run of a batch.
        """
        veh, s = self.vehicle, self.settings
        m, iz, l1, l2, cf, cr = (veh.mass, veh.yaw_inertia, veh.l1, veh.l2, veh.c_f,
                                 veh.c_r)
        if self.steps_cache[0] != dt:
            count = max(1, math.ceil(dt / self.max_substep - 1e-9))
            h = dt / count
            lag = s.actuator_lag
            self.steps_cache = (dt, count, h, math.exp(-h / lag) if lag > 0.0 else 0.0,
                                math.exp(-0.5 * h / lag) if lag > 0.0 else 0.0)
        _, count, h, decay, half = self.steps_cache
        a_vv = -(cf + cr) / (m * v_x)
        a_vr = -(cf * l1 - cr * l2) / (m * v_x) - v_x
        a_rv = -(cf * l1 - cr * l2) / (iz * v_x)
        a_rr = -(cf * l1 * l1 + cr * l2 * l2) / (iz * v_x)
        y, e, v, r, f_f, f_r = x[:6]
        v_force = (f_f + f_r) / m
        r_force = (l1 * f_f - l2 * f_r) / iz
        for j in range(count):
            applied = self._applied(self.time + (j + 0.5) * h - s.delay)
            start = self.wheel if s.actuator_lag > 0.0 else applied
            wheel = (start, applied + (start - applied) * half,
                     applied + (start - applied) * decay)
            curvature = (rho_start + (rho - rho_start) * (j / count),
                         rho_start + (rho - rho_start) * ((j + 0.5) / count),
                         rho_start + (rho - rho_start) * ((j + 1.0) / count))

            def rates(e: Real, v: Real, r: Real, k: int) -> tuple[Real, Real, Real, Real]:
                return (v + v_x * e, r - v_x * curvature[k],
                        a_vv * v + a_vr * r + cf / m * wheel[k] + v_force,
                        a_rv * v + a_rr * r + cf * l1 / iz * wheel[k] + r_force)

            mid = 0.5 * h
            k1 = rates(e, v, r, 0)
            k2 = rates(e + mid * k1[1], v + mid * k1[2], r + mid * k1[3], 1)
            k3 = rates(e + mid * k2[1], v + mid * k2[2], r + mid * k2[3], 1)
            k4 = rates(e + h * k3[1], v + h * k3[2], r + h * k3[3], 2)
            w = h / 6.0
            y, e, v, r = (old + w * (p + 2.0 * q + 2.0 * u + z)
                          for old, p, q, u, z in zip((y, e, v, r), k1, k2, k3, k4))
            self.wheel = wheel[2]
        return [y, e, v, r, f_f, f_r, x[6]]

    def ahead(self, time: float, v_x: Real, rho: Real, rho_start: Real) -> Optional[list[Real]]:
        """
        Return the present estimate predicted ``time`` ahead, the filter left as it was.

        The model integrated under the commands already sent (the actuator's input
        ``delay`` behind: over ``time <= delay`` none of them is still to be decided), its
        force disturbances held, the curvature going linearly from ``rho_start`` to
        ``rho`` (the road at the CG now and ``v_x time`` ahead). It integrates piece by
        piece between the instants the actuator's input changes (each command in flight
        over its own interval, whatever the control period and the delay); where the
        commands change more often than every ``MIN_AHEAD_SUBSTEP``, in substeps of that
        length under the mean of the commands over each (the wheel's lag is exact for a
        constant input: the mean is its first-order equivalent). The delay-aware law
        (``delay_prediction``) acts on it: the command it sends now reaches the actuator
        when the car is there.

        :param time: how far ahead [s], at most the filter's ``delay``.
        :param v_x: speed [m/s] (at least ``min_speed``; per run for a batch).
        :param rho: the curvature at the end [1/m].
        :param rho_start: the curvature now [1/m].
        :return: ``[y_cg, eps_r, v_y, r]`` ahead (NaN where the filter restarts), or None
            before the first step.
        """
        if self.x is None:
            return None
        if not 0.0 < time <= self.settings.delay:
            raise ValueError(f'the prediction time {time!r} s must be above 0 and at most '
                             f"the filter's delay {self.settings.delay!r} s: further ahead "
                             'the commands not yet sent would act')
        saved = (self.wheel, self.steps_cache)
        try:
            return self._integrate(list(self.x), time, v_x, rho, rho_start)[:4]
        finally:
            self.wheel, self.steps_cache = saved

    def _integrate(self, x: list[Real], dt: float, v_x: Real, rho: Real,
                   rho_start: Real) -> list[Real]:
        """
        Integrate the model over ``dt`` from now, piece by piece under the commands.

        :meth:`_predict` over each piece of constant input (:meth:`_inputs`); where the
        input changes more often than every ``MIN_AHEAD_SUBSTEP``, over substeps of that
        length under the mean of the commands over each. The wheel moves on; the time,
        the commands and the one held are left as they were (the caller prunes).
        """
        now, history, held = self.time, self.history, self.held
        edges, commands = self._inputs(dt)
        if len(commands) > dt / MIN_AHEAD_SUBSTEP + 1.0:
            count = math.ceil(dt / MIN_AHEAD_SUBSTEP - 1e-9)
            cuts = [dt * j / count for j in range(count + 1)]
            edges, commands = cuts, [_mean_input(edges, commands, a, b)
                                     for a, b in zip(cuts, cuts[1:])]
        try:
            for start, end, command in zip(edges, edges[1:], commands):
                # one constant input over the piece: no lookup in the history
                self.time, self.held, self.history = now + start, command, []
                x = self._predict(x, end - start, v_x,
                                  rho_start + (rho - rho_start) * (end / dt),
                                  rho_start + (rho - rho_start) * (start / dt))
            return x
        finally:
            self.time, self.history, self.held = now, history, held

    def _inputs(self, time: float) -> tuple[list[float], list[Real]]:
        """
        Return the actuator's input over the next ``time``: piece edges and commands.

        The command in effect from ``edges[i]`` to ``edges[i + 1]`` (seconds from now)
        is ``commands[i]``: the last one issued at or before ``delay`` earlier (within
        ``TIE``), the one held before the history where none is.
        """
        now, delay = self.time, self.settings.delay
        first: Real = self.held
        changes: list[tuple[float, Real]] = []
        for issued, command in self.history:
            at = issued + delay - now
            if at <= TIE:
                first = command
            elif at < time - TIE:
                if changes and at - changes[-1][0] <= TIE:
                    changes[-1] = (changes[-1][0], command)
                else:
                    changes.append((at, command))
        return ([0.0] + [at for at, _ in changes] + [time],
                [first] + [command for _, command in changes])

    def advance_actuator(self, dt: float, command: Real) -> None:
        """
        Move the actuator model ``dt`` on without a measurement, then record ``command``.

        While the inputs are stale the law does not run, but the safety layer's hold and
        ramp to the safe angle reach the wheel: the controller reports each of them with
        the time since the command before, so that the commands in flight and the wheel
        are the car's when the law starts again (the estimate itself restarts then).

        :param dt: time since the last command recorded [s] (not finite or < 0: 0).
        :param command: the command sent now [rad].
        """
        if math.isfinite(dt) and dt > 0.0:
            edges, commands = self._inputs(dt)
            lag = self.settings.actuator_lag
            wheel = self.wheel
            for start, end, applied in zip(edges, edges[1:], commands):
                wheel = (applied + (wheel - applied) * math.exp(-(end - start) / lag)
                         if lag > 0.0 else applied)
            self.wheel = wheel
            self._applied(self.time + dt - self.settings.delay)   # drops what has acted
            self.time += dt
        self.command(command)

    def step(self, state: LateralState, dt: float, estimating: Any = False) -> LateralState:
        """
        Take one measurement and return the estimated state.

        :param state: the measured state (``y_cg`` from the sensor's error and ``eps_r``).
        :param dt: time since the previous measurement [s]; the caller restarts the
            filter on a time jump; 0 returns the last estimate.
        :param estimating: where true (a bool, or an array over a batch), no curvature
            is received (``state.rho`` is ignored): the curvature estimator's value is
            the filter's curvature input.
        :return: ``state`` with ``y_cg``, ``eps_r``, ``v_y``, ``r`` estimated, and where
            estimating ``rho`` too (``rho_rate`` 0).
        """
        if not isinstance(estimating, np.ndarray):
            estimating = bool(estimating)
        estimates = int(np.count_nonzero(estimating))
        rho = self._estimate_curvature(state, dt, estimating, estimates)
        if estimates:
            self.curvature_estimated_steps += estimates
            # no curvature received: its input is ignored (the node sends 0)
            state = state._replace(rho=_select(estimating, rho, state.rho),
                                   rho_rate=_select(estimating, 0.0 * state.rho_rate,
                                                    state.rho_rate))
        measured = self._measured(state)
        good = (np.isfinite(state.y_cg) & np.isfinite(state.eps_r) & np.isfinite(state.v_y)
                & np.isfinite(state.r) & np.isfinite(state.v_x) & np.isfinite(state.rho))
        fast = good & (state.v_x >= self.settings.min_speed)
        # a v_y of exactly 0 while r is not: a bridge that does not measure v_y
        blind = fast & (state.v_y == 0.0) & (state.r != 0.0)
        if self.x is None:              # (re)start: every run from its next measurement
            self.x = [math.nan + 0.0 * mv for mv in measured]
            self.rho = state.rho
        elif np.count_nonzero(self.forgotten):
            # runs restarted by forget(): the same start (a step of dt 0 next would
            # otherwise leave them the curvature from before the restart)
            self.rho = _select(self.forgotten, state.rho, self.rho)
        self.forgotten = False
        fresh = np.isnan(self.x[0])
        if dt > MAX_PERIOD:
            # beyond the longest period with a well-conditioned gain
            fresh = fresh | True
            self.long_steps += 1
        if MAX_PERIOD >= dt > 0.0:
            v_x = _select(fast, state.v_x, self.settings.min_speed)
            prior = self._integrate(self.x, dt, v_x, state.rho, self.rho)
            self._applied(self.time + dt - self.settings.delay)   # drops what has acted
            gain = self._gain(v_x, dt, blind)
            y, e, v, r = measured[:4]
            innovation = (y + self.vehicle.d_s * e - (prior[0] + self.vehicle.d_s * prior[1]),
                          e - prior[1], v - prior[2], r - prior[3])
            self.innovation = innovation
            posterior = [prior[i] + (gain[i][0] * innovation[0] + gain[i][1] * innovation[1]
                                     + gain[i][2] * innovation[2]
                                     + gain[i][3] * innovation[3])
                         for i in range(len(gain))]
            posterior.append(state.rho)
            self.time += dt
            # the curvature the model used to the end of the step (the next step's start)
            self.rho = _select(good, state.rho, self.rho)
        else:                           # the same instant again: nothing advances
            posterior = self.x
        # restarted runs (NaN marks) start from this measurement; without v_y, from the
        # steady cornering v_y at the measured r (not from the 0: 14 cm instead of 3 after
        # a restart in a R 400 m curve at 37 m/s)
        start = measured
        if np.count_nonzero(blind):
            eta = self.vehicle.eta
            cornering = (self.vehicle.l2 - eta * state.v_x * state.v_x) * state.r
            start = [*measured[:2], _select(blind, cornering, measured[2]), *measured[3:]]
        self.x = [_select(fast & ~fresh, p, _select(fast, mv, math.nan))
                  for p, mv in zip(posterior, start)]
        self.held_rho = _select(fast & np.isfinite(self.x[6]), self.x[6],
                                self.held_rho + 0.0 * state.rho)
        return self._out(state, measured, fast, estimating if estimates else None)

    def _estimate_curvature(self, state: LateralState, dt: float, estimating: Any,
                            estimates: int) -> Real:
        """
        Advance the curvature estimator and return its curvature (``docs/lane_keeping.md``).

        States ``[eps_r, rho]``, ``eps_r' = r - v_x rho``: the measured yaw rate the input
        (the trapezoid of the last and this step's), the measured relative yaw the only
        measurement, the steady gain of :func:`kinematic_gain`. A constant bias of the
        relative yaw moves ``eps_r`` alone: in a steady state the innovation vanishes and
        ``rho = r / v_x``. Where a curvature is received, the estimator follows it
        (``eps_r`` the measurement, ``rho`` the curvature received: an estimate starts
        from the last one; a non-finite one restarts it), without a gain.
        It restarts as the filter does (a non-finite input, below ``min_speed``, a step
        longer than ``MAX_PERIOD``, :meth:`reset`, :meth:`forget`) from ``eps_r`` and the
        path the car drives, ``r / v_x``.

        :return: the estimate (the restart value where it restarts; the curvature
            received elsewhere) [1/m].
        """
        eps, r, v_x = state.eps_r, state.r, state.v_x
        fast = (np.isfinite(eps) & np.isfinite(r) & np.isfinite(v_x)
                & (v_x >= self.settings.min_speed))
        # where a curvature is received: the measurement and that curvature (where it
        # is not usable, a restart)
        follow = fast & np.isfinite(state.rho)
        followed = [_select(follow, eps, math.nan),
                    _select(follow, _bounded(state.rho), math.nan),
                    _select(fast, r, math.nan)]
        if not estimates:               # nothing to estimate: no gain needed
            self.kinematic = followed
            return state.rho
        path = self._path_curvature(state)
        if self.kinematic is None:
            self.kinematic = [math.nan + 0.0 * eps] * 3
        e_old, rho_old, r_old = self.kinematic
        fresh = np.isnan(e_old) | np.isnan(rho_old) | np.isnan(r_old) | (dt > MAX_PERIOD)
        if MAX_PERIOD >= dt > 0.0:
            if self.kinematic_table is None:
                self.kinematic_table = gain_table(self.vehicle, self.settings, True, True)
            # (not min_speed + 0 v_x: a non-finite speed would make it NaN)
            speed = _select(fast, v_x, self.settings.min_speed)
            gain = self._table_gain(self.kinematic_table, speed, dt)
            prior = e_old + dt * (0.5 * (r_old + r) - speed * rho_old)
            innovation = eps - prior
            e_new = prior + gain[0][0] * innovation
            rho_new = _bounded(rho_old + gain[1][0] * innovation)
        else:                           # the same instant again: nothing advances
            e_new, rho_new = e_old, rho_old
        run = fast & ~fresh
        estimated = [_select(run, e_new, _select(fast, eps, math.nan)),
                     _select(run, rho_new, _select(fast, path, math.nan)),
                     followed[2]]
        self.kinematic = [_select(estimating, a, b) for a, b in zip(estimated, followed)]
        # the filter needs a finite curvature: the path where the estimator restarts
        rho_out = self.kinematic[1]
        return _select(np.isfinite(rho_out), rho_out, _select(np.isfinite(path), path, 0.0))

    def _path_curvature(self, state: LateralState) -> Real:
        """Return ``r / v_x`` (the speed at least ``min_speed``), within the bounds."""
        # (a restart above min_speed: eps_r' = 0 on a steady turn)
        v_x = state.v_x
        low = self.settings.min_speed
        v_x = _select(v_x >= low, v_x, low + 0.0 * v_x)
        return _bounded(state.r / v_x)

    def _out(self, state: LateralState, measured: list[Real], fast: Any,
             estimating: Any = None) -> LateralState:
        """Return the estimate where the filter runs, the measurement elsewhere."""
        assert self.x is not None
        x = [_select(fast, est, mv) for est, mv in zip(self.x, measured)]
        out = state._replace(y_cg=x[0], eps_r=x[1], v_y=x[2], r=x[3])
        if estimating is None:
            return out
        # below min_speed: the path the car drives (the speed taken as at least
        # min_speed), but no more than the last estimate above it in the same direction
        # (a speed read as 0 for a moment; a car crawling straight after a curve: 0)
        path = self._path_curvature(state)
        held = self.held_rho
        smaller = _select(np.abs(held) <= np.abs(path), held, path)
        low = _select(np.isfinite(held), _select(held * path > 0.0, smaller, 0.0 * path), path)
        rho = _select(fast, _bounded(self.x[6]), _bounded(low))
        return out._replace(rho=_select(estimating, rho, state.rho))

    def curvature(self) -> Real:
        """
        Return the curvature the model uses: the estimate or the one received [1/m].

        :return: the curvature (NaN where the filter restarts).
        """
        if self.x is None:
            return math.nan
        return self.x[6]

    def disturbance(self) -> tuple[Real, Real]:
        """
        Return the estimated axle-force disturbances ``(front, rear)`` [N].

        :return: the two forces (NaN where the filter restarts).
        """
        if self.x is None:
            return math.nan, math.nan
        return self.x[4], self.x[5]
