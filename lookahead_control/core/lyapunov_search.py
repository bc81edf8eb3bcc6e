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
A speed schedule of the certificate's ``P`` itself, found by semidefinite programming.

The certificate of :mod:`~lookahead_control.core.lane_keeping_stability` takes
``V = u^T P(v) u`` with ``P(v)`` the Lyapunov solution of a ``Q`` (constant or a speed
schedule): a family searched by Nelder-Mead, which stopped at a bound of 1.34 for a CG
height with ``acceleration_source: zero`` (dev-sc31). Here ``P(v)`` is linear between
knots and its knots are the unknowns. The test's value is at most ``t`` where

``A^T P + P A + a (P_v + G^T P + P G) - (1 - t) (A_0^T P + P A_0) <= 0``

for every vertex ``(a, a_hat)`` (``A = A(v, a, a_hat)``; with the load transfer the
accelerations' grid), and ``Q = -(A_0^T P + P A_0) >= I`` fixes the scale. For a fixed
``t`` these are linear matrix inequalities in the knots: a convex problem, solved at
sample speeds between the knots, and ``t`` is bisected. The result is then checked by
:func:`~lookahead_control.core.lane_keeping_stability.certificate` (``p_knots``) on its
full grid, with its bound between grid points: the samples here only steer the search.

cvxpy (with its Clarabel solver) is imported when a search runs: the certificate's check
needs numpy only.
"""

from __future__ import annotations

from typing import Any, NamedTuple
import warnings

from lookahead_control.core.lane_keeping import LaneKeepingParams
from lookahead_control.core.lane_keeping_stability import (_load_grid, check_test_envelope,
                                                           coordinates_rate,
                                                           loop_in_coordinates, QRows,
                                                           schedule_kinks)
from lookahead_control.core.params import ControllerParams, loaded_vehicle, VehicleParams
import numpy as np
import numpy.typing as npt

# knots closer than this to a kink are the kink [m/s]
_MERGE = 0.05
# one-sided samples sit this far inside their piece [m/s]
_INSIDE = 1e-6


class LyapunovSearch(NamedTuple):
    """
    A schedule of ``P`` found by :func:`search_lyapunov`.

    :param knots: ``(speed, P)`` pairs, ``P`` as 5 rows of 5 (the certificate's
        coordinates ``u``), linear in ``v`` between them.
    :param target: the test's value of ``knots`` at the sample speeds, computed from
        them (the full grid's bound, with its margin between points, is
        :func:`certificate`'s).
    :param solves: how many semidefinite programs were solved.
    :param samples: the sample speeds (each with every vertex).
    """

    knots: tuple[tuple[float, QRows], ...]
    target: float
    solves: int
    samples: int


def knot_speeds(vehicle: VehicleParams, controller: ControllerParams,
                settings: LaneKeepingParams, v_min: float, v_max: float,
                count: int) -> list[float]:
    """
    Return the knots' speeds: ``count`` uniform ones and the loop's kinks.

    :param vehicle: the design vehicle.
    :param controller: d_v schedule.
    :param settings: the law's settings.
    :param v_min: lower speed [m/s].
    :param v_max: upper speed [m/s].
    :param count: uniform knots from ``v_min`` to ``v_max`` (>= 2).
    :return: the speeds, increasing; a uniform one within 0.05 m/s of a kink dropped.
    """
    kinks = schedule_kinks(vehicle, controller, settings, v_min, v_max)
    uniform = [float(v) for v in np.linspace(v_min, v_max, count)
               if v in (v_min, v_max) or all(abs(v - k) > _MERGE for k in kinks)]
    return sorted(set(uniform) | set(kinks))


def _vertices(a_max: float, a_error: float, load_points: int,
              zero: bool) -> list[tuple[float, float]]:
    """Return the ``(a, a_hat)`` pairs of the test (the certificate's)."""
    if load_points:
        accelerations, hats = _load_grid(a_max, a_error, load_points, zero)
        return [(float(a), float(h)) for a, row in zip(accelerations, hats) for h in row]
    if zero:
        return [(-a_max, 0.0), (a_max, 0.0)]
    # affine in (a, a_hat): the vertices of the box
    errors = (0.0,) if a_error == 0.0 else (-a_error, a_error)
    return [(a, a + e) for a in (-a_max, a_max) for e in errors]


#: the upper triangle of a symmetric 5 x 5 matrix, row by row
_UPPER = [(r, c) for r in range(5) for c in range(r, 5)]


def _unit(j: int) -> npt.NDArray[np.float64]:
    """Return the symmetric unit matrix of upper-triangle entry ``j``."""
    e = np.zeros((5, 5))
    r, c = _UPPER[j]
    e[r, c] = e[c, r] = 1.0
    return e


#: each unit matrix flattened column by column: the coefficients of P itself
_BASIS = np.column_stack([_unit(j).flatten(order='F') for j in range(len(_UPPER))])


def _coefficients(linear: Any) -> npt.NDArray[np.float64]:
    """
    Return the 25 x 15 matrix of a linear map of symmetric matrices.

    :param linear: ``P -> L(P)``, linear.
    :return: ``vec(L(P)) = G u`` for ``u`` the upper triangle of ``P`` (column-major vec).
    """
    return np.column_stack([np.asarray(linear(_unit(j))).flatten(order='F')
                            for j in range(len(_UPPER))])


def _symmetric(m: Any) -> Any:
    """Return ``(m + m^T) / 2`` (cvxpy takes a PSD constraint on a symmetric expression)."""
    return 0.5 * (m + m.T)


class _KnotView:
    """One knot's ``P`` of the stacked upper triangles (``.value`` as cvxpy's)."""

    def __init__(self, x: Any, start: int) -> None:
        self.x, self.start = x, start

    @property
    def value(self) -> npt.NDArray[np.float64]:
        """Return the knot's symmetric matrix from the solution."""
        u = np.asarray(self.x.value)[self.start:self.start + len(_UPPER)]
        return np.asarray(sum(w * _unit(j) for j, w in enumerate(u)))


def search_lyapunov(vehicle: VehicleParams, controller: ControllerParams,
                    settings: LaneKeepingParams, v_min: float = 10.0, v_max: float = 37.0,
                    a_max: float = 3.5, a_error: float = 0.0, load_points: int = 0,
                    knots: int = 12, per_piece: int = 4, bisections: int = 6,
                    a_hat_zero: bool = False) -> LyapunovSearch:
    """
    Search a piecewise-linear ``P(v)`` that makes the certificate's value small.

    The knots are ``knots`` uniform speeds and the loop's kinks (:func:`knot_speeds`).
    Each piece between two knots is sampled at ``per_piece`` speeds (its ends taken from
    inside, as the one-sided limits), and with the load transfer also on both sides of
    each acceleration's own kink. At every sample and vertex the inequality of the
    module's docstring is imposed; ``t = 1`` first, then ``bisections`` halvings of
    ``[0, 1]``; each solve takes the ``P`` with the least total trace (no loose scale).
    A solution the solver calls inaccurate counts as met for the bisection; every
    solution's value is computed here at the samples, and the smallest kept (none below
    1: ``ValueError``).

    :param vehicle: the design vehicle.
    :param controller: gains and schedule.
    :param settings: the law's settings.
    :param v_min: lower speed [m/s].
    :param v_max: upper speed [m/s].
    :param a_max: acceleration bound [m/s^2].
    :param a_error: bound on the error of the law's ``a_x`` [m/s^2].
    :param load_points: as :func:`certificate` (0: static stiffnesses).
    :param knots: uniform knots (>= 2).
    :param per_piece: samples per piece (>= 2).
    :param bisections: halvings of the value's interval after ``t = 1`` (>= 0).
    :param a_hat_zero: the law's ``a_x`` is 0, as :func:`certificate`'s.
    :return: the knots of ``P``, the value met and the work done.
    :raises ValueError: an argument outside its range (:func:`check_test_envelope`, the
        counts), a loop unstable at a frozen speed, or no ``P`` with these knots whose
        value at the samples is below 1 (more knots, or no quadratic certificate of
        this form).
    :raises ImportError: without cvxpy.
    """
    check_test_envelope(v_min, v_max, a_max, a_error, load_points, a_hat_zero)
    for name, value, least in (('knots', knots, 2), ('per_piece', per_piece, 2),
                               ('bisections', bisections, 0)):
        if isinstance(value, bool) or not isinstance(value, int) or value < least:
            raise ValueError(f'{name} = {value!r} must be an integer >= {least}')
    import cvxpy as cp
    speeds = knot_speeds(vehicle, controller, settings, v_min, v_max, knots)
    vertices = _vertices(a_max, a_error, load_points, a_hat_zero)
    extra: list[float] = []
    if load_points:
        for a_hat in sorted({hat for _, hat in vertices}):
            extra += schedule_kinks(loaded_vehicle(vehicle, a_hat), controller, settings,
                                    v_min, v_max)
    # the samples: (piece, share along it, speed at which the loop is taken, side)
    samples = []
    for i, (low, high) in enumerate(zip(speeds, speeds[1:])):
        inside = min(_INSIDE, (high - low) / 4.0)
        shares = list(np.linspace(0.0, 1.0, per_piece))
        for kink in extra:
            if low + inside < kink < high - inside:
                shares += [(kink - low) / (high - low) - inside / (high - low),
                           (kink - low) / (high - low) + inside / (high - low)]
        for share in sorted(shares):
            at = min(max(low + share * (high - low), low + inside), high - inside)
            samples.append((i, float(share), at, 1.0 if share < 0.5 else -1.0))
    # the loop's matrices, made once for every t
    rows = []
    for i, share, at, side in samples:
        a_0 = loop_in_coordinates(vehicle, controller, settings, at)
        largest = float(np.max(np.linalg.eigvals(a_0).real))
        if largest >= 0.0:
            raise ValueError(f'the loop is not stable at {at:.4g} m/s (largest real part '
                             f'{largest:.3g} 1/s): no P certifies it')
        move = coordinates_rate(settings, at, side)
        loops = []
        for a, a_hat in vertices:
            plant = loaded_vehicle(vehicle, a) if load_points else None
            law = loaded_vehicle(vehicle, a_hat) if load_points else vehicle
            loops.append((a, loop_in_coordinates(law, controller, settings, at, a_hat,
                                                 plant=plant)))
        rows.append((i, share, a_0, move, loops))
    # P(v) by its knots' upper triangles: every inequality is one matrix of coefficients
    # times them (each LMI one affine map for cvxpy to take in: built from matrix
    # expressions, its canonicalization took 23 of a search's 33 s)
    size = len(_UPPER)
    x = cp.Variable(size * len(speeds))
    target = cp.Parameter(nonneg=True)
    constraints = []
    for i, share, a_0, move, loops in rows:
        low, high = speeds[i], speeds[i + 1]
        made = _coefficients(lambda e: a_0.T @ e + e @ a_0)
        changed = _coefficients(lambda e: move.T @ e + e @ move)
        piece = x[size * i:size * (i + 2)]
        weights = ((1.0 - share, share), (-1.0 / (high - low), 1.0 / (high - low)))
        at_p = np.hstack([w * made for w in weights[0]])
        constraints.append(_symmetric(cp.reshape(-(at_p @ piece), (5, 5), order='F'))
                           >> np.eye(5))
        for a, loop in loops:
            turned = _coefficients(lambda e: loop.T @ e + e @ loop)
            fixed = np.hstack([w * (turned + a * changed) + a * r * _BASIS
                               for w, r in zip(*weights)])
            m = cp.reshape(fixed @ piece - (1.0 - target) * (at_p @ piece), (5, 5),
                           order='F')
            constraints.append(_symmetric(m) << 0)
    trace = np.zeros(size * len(speeds))
    for k in range(len(speeds)):
        trace[[size * k + j for j, (r, c) in enumerate(_UPPER) if r == c]] = 1.0
    problem = cp.Problem(cp.Minimize(trace @ x / len(speeds)), constraints)
    variables = [_KnotView(x, size * k) for k in range(len(speeds))]

    def solve(t: float) -> bool:
        target.value = t
        try:
            with warnings.catch_warnings():     # 'may be inaccurate': checked below
                warnings.simplefilter('ignore')
                problem.solve(solver=cp.CLARABEL)
        except cp.error.SolverError:
            return False
        return problem.status in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE)

    def sampled_value() -> tuple[float, list[npt.NDArray[np.float64]]]:
        # the test's value of the solver's P at the samples, computed here: an
        # inaccurate solution is kept only for what it really gives
        knots_now = [0.5 * (np.array(v.value) + np.array(v.value).T) for v in variables]
        top = -np.inf
        for i, share, a_0, move, loops in rows:
            p = knots_now[i] + share * (knots_now[i + 1] - knots_now[i])
            rate = (knots_now[i + 1] - knots_now[i]) / (speeds[i + 1] - speeds[i]) \
                + move.T @ p + p @ move
            made = -(a_0.T @ p + p @ a_0)
            try:
                inverse = np.linalg.inv(np.linalg.cholesky(0.5 * (made + made.T)))
            except np.linalg.LinAlgError:       # Q not positive definite: no test
                return float('inf'), knots_now
            for a, loop in loops:
                d = loop - a_0
                m = d.T @ p + p @ d + a * rate
                top = max(top, float(np.max(np.linalg.eigvalsh(inverse @ m @ inverse.T))))
        return top, knots_now

    best_value, best = float('inf'), None
    solves, low, high = 0, 0.0, 1.0
    for step in range(bisections + 1):
        middle = 1.0 if step == 0 else 0.5 * (low + high)
        solves += 1
        if not solve(middle):
            if step == 0:
                break
            low = middle
            continue
        high = middle
        met, knots_now = sampled_value()
        if met < best_value:
            best_value, best = met, knots_now
    if best is None or best_value >= 1.0:
        raise ValueError(f'no P(v) linear between {len(speeds)} knots meets the test at '
                         f'the {len(samples)} sample speeds (|a_x| <= {a_max:g} m/s^2, '
                         f'a_x error <= {a_error:g} m/s^2): try more knots, or a '
                         'smaller envelope (it may have no certificate of this form)')
    found = tuple((speed, tuple(tuple(float(w) for w in row) for row in m))
                  for speed, m in zip(speeds, best))
    return LyapunovSearch(found, best_value, solves, len(samples))
