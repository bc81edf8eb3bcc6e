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
The road curvature the CG-compensated law previews, averaged along the road.

The ``road_curvature`` polygon is read by linear interpolation, and the law takes the
curvature's value at the CG with the slope of the segment ahead of it. A curvature step
in the map (S1) is then a 5 m-wide impulse of curvature rate (at 37 m/s, 0.135 s of a
reference rate of 6.6 m/s) followed by a step of the reference's value, and a clothoid's
ends are steps of the rate: the law asked 0.088 rad for 30 ms on S1 at 37 m/s, beyond
the node's angle limit (0.0587 rad), and the cut excited the CG's zero dynamics.

:func:`smoothed_preview` averages the curvature with a triangular window of half-width
``W`` centred on each point (the weight falls linearly from the point to ``W`` either
side), integrated exactly over the polygon's linear pieces: a straight line (a
clothoid) is unchanged, a step becomes an S-curve of length ``2 W`` centred on it, a
kink is rounded over ``+-W``. The window reaches behind the CG: :class:`CurvatureHistory`
keeps the curvature the law saw at the CG over the last ``W`` of road.
``docs/lane_keeping.md`` ("The previewed curvature, averaged along the road") has the
measurements.
"""

from __future__ import annotations

import math
from typing import Any, Optional

from lookahead_control.core.numeric import Real
import numpy as np

#: the averaged polygon's spacing is W / STEPS (the law reads a segment's slope: a
#: coarser output, W / 4, led the rate by half a segment: S1 / S4 at 37 m/s 3.29 / 4.27
#: cm against 2.89 / 3.96)
STEPS = 8
#: the history keeps at most this many samples: W behind the CG at 100 Hz down to
#: W / 10.24 m/s (0.5 m/s for 5 m); slower, the window behind is the last 10.24 s
MAX_SAMPLES = 1024
#: the averaged stretch has at most this many steps (with ``reach`` 2.6 m at 37 m/s and
#: 5 m it has 6; the bound keeps a polygon billions of metres long from a grid to match)
MAX_OUTPUT = 4096


class CurvatureHistory:
    """
    The curvature the law saw at the CG over the last ``half_width`` metres of road.

    Works on floats (one vehicle) and on arrays (a batch of runs): the distance travelled
    and the curvature are recorded per run, at most :data:`MAX_SAMPLES` samples.
    """

    def __init__(self, half_width: float) -> None:
        """
        Start with no history.

        :param half_width: how far behind the CG it reaches [m] (the window's half-width).
        """
        self.half_width = half_width
        self.clear()

    def clear(self) -> None:
        """Forget the road behind (a time jump: the distance travelled is unknown)."""
        self.travelled: Optional[np.ndarray] = None
        self._where = np.zeros(0)
        self._rho = np.zeros(0)
        self.size = 0

    def record(self, v_x: Real, dt: float, rho: Real) -> None:
        """
        Record the curvature at the CG after travelling ``v_x dt``.

        :param v_x: speed [m/s] (negative or not finite: taken as 0).
        :param dt: the step [s].
        :param rho: the curvature at the CG [1/m] (not finite: unknown there).
        """
        with np.errstate(invalid='ignore'):
            speed = np.where(np.isfinite(v_x), np.maximum(v_x, 0.0), 0.0)
        step, value = np.broadcast_arrays(np.asarray(speed * dt, dtype=float),
                                          np.asarray(rho, dtype=float))
        if self.travelled is not None and self.travelled.shape != step.shape:
            try:                        # one speed and curvature for every run so far
                step, value = (np.broadcast_to(step, self.travelled.shape),
                               np.broadcast_to(value, self.travelled.shape))
            except ValueError:
                self.clear()            # another batch: its road behind is not this one
        if self.travelled is None:
            self.travelled = np.zeros(step.shape)
            self._where = np.zeros((MAX_SAMPLES,) + step.shape)
            self._rho = np.zeros((MAX_SAMPLES,) + step.shape)
        else:
            self.travelled = self.travelled + np.where(np.isfinite(step), step, 0.0)
        # the oldest sample kept is the last one at or beyond half_width behind every run
        # (the positions grow along the samples: the runs' test is true on a prefix)
        beyond = (self._where[:self.size] <= self.travelled - self.half_width).reshape(
            self.size, self.travelled.size)
        drop = max(int(np.count_nonzero(beyond.all(axis=1))) - 1,
                   1 if self.size == MAX_SAMPLES else 0)
        if drop:
            self._where[:self.size - drop] = self._where[drop:self.size].copy()
            self._rho[:self.size - drop] = self._rho[drop:self.size].copy()
            self.size -= drop
        self._where[self.size] = self.travelled
        self._rho[self.size] = value
        self.size += 1

    def forget(self, runs: Any) -> None:
        """
        Forget the road behind some runs of a batch (they restarted).

        :param runs: boolean per run.
        """
        runs = np.asarray(runs, dtype=bool)
        if self.travelled is None or not np.any(runs):
            return
        if runs.shape != self.travelled.shape:
            # recorded with one speed and curvature for the whole batch: per run from now
            try:
                shape = np.broadcast_shapes(self.travelled.shape, runs.shape)
            except ValueError:
                self.clear()
                return
            # the samples' run axes aligned to the right, as the runs' (dev-probe88: a
            # history recorded with one speed for every run, shape (), raised here)
            ones = (1,) * (len(shape) - self.travelled.ndim) + self.travelled.shape
            self.travelled = np.broadcast_to(self.travelled, shape).copy()
            self._where = np.broadcast_to(self._where.reshape((MAX_SAMPLES,) + ones),
                                          (MAX_SAMPLES,) + shape).copy()
            self._rho = np.broadcast_to(self._rho.reshape((MAX_SAMPLES,) + ones),
                                        (MAX_SAMPLES,) + shape).copy()
        self._rho[:self.size] = np.where(runs, math.nan, self._rho[:self.size])

    def copy_from(self, other: 'CurvatureHistory') -> None:
        """
        Take another history's samples (a retune: the road behind is the same).

        :param other: the history.
        """
        self.travelled = None if other.travelled is None else other.travelled.copy()
        self._where, self._rho = other._where.copy(), other._rho.copy()
        self.size = other.size

    def behind(self) -> tuple[np.ndarray, np.ndarray]:
        """
        Return the samples, oldest first: distance from the CG (<= 0) and curvature.

        :return: ``(where, rho)``, shape ``(P,)`` or ``(P, N)``; NaN where a run has no
            finite curvature.
        """
        if self.travelled is None:
            return np.zeros(0), np.zeros(0)
        return self._where[:self.size] - self.travelled, self._rho[:self.size]


def smoothed_preview(distances: Any, curvatures: Any, half_width: float,
                     history: Optional[CurvatureHistory] = None, reach: float = math.inf
                     ) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the polygon averaged along the road by a triangular window of ``half_width``.

    The road is, behind the polygon's first point and the CG, ``history`` (a run's
    samples before its oldest finite one kept take that one's value; with none, the
    polygon's first value is held back), then the polygon as the law reads it (its first
    value held from the CG to its first point, linear, its last value held beyond its
    end). Of a polygon that starts behind the CG only its value at the CG and its points
    ahead are read: behind the CG the road is the one driven. The average is exact over
    the road's linear pieces, integrated from ``W`` before the first point given. It is
    given every ``half_width / STEPS`` from the CG (or the polygon's first point ahead
    of it) to one step past ``reach`` (the farthest point the law reads; at most the
    polygon's end if that is ahead, and at most :data:`MAX_OUTPUT` steps: a ``reach``
    not finite is the polygon's end), and the polygon's own points beyond that follow
    unchanged. A polygon the law would not read (not 1-D, empty, not increasing, a
    non-finite distance) is returned unchanged, and a run whose curvatures are not all
    finite keeps NaN (the law's fallback for it stays).

    :param distances: the polygon's distances ahead of the CG [m], shape ``(K,)``.
    :param curvatures: its curvatures [1/m], ``(K,)`` or ``(K, N)``.
    :param half_width: ``W`` [m] (> 0).
    :param history: the curvature behind the CG.
    :param reach: how far ahead of the CG the law reads [m].
    :return: ``(distances, curvatures)`` of the averaged polygon.
    """
    d = np.asarray(distances, dtype=float)
    k = np.asarray(curvatures, dtype=float)
    if (d.ndim != 1 or d.size == 0 or k.shape[:1] != d.shape or k.ndim > 2
            or not np.all(np.isfinite(d)) or np.any(np.diff(d) <= 0.0)):
        return d, k
    usable = np.all(np.isfinite(k), axis=0)
    flat = np.where(usable, k, 0.0).reshape(d.size, -1)          # (K, N)
    end = d[-1]
    if d[0] < 0.0:
        # the road behind the CG is the road driven (the history), not the polygon's
        # points there: its value at the CG, then its points ahead (dev-probe90: a point
        # 50 m behind at 0.19 1/m made the average's slope swing the command to the
        # other side of a 400 m curve)
        at_cg = _road_at(np.broadcast_to(d.reshape(-1, 1), flat.shape), flat,
                         np.zeros(1))
        ahead = d > 0.0
        d, flat = np.concatenate([np.zeros(1), d[ahead]]), np.vstack([at_cg, flat[ahead]])
    step = half_width / STEPS
    low = max(0.0, d[0])
    far = reach if math.isfinite(reach) else end
    # one step past the farthest read: its segment (the slope read there) is averaged too
    high = max(far, low) + step
    if end >= low:
        high = min(high, end)
    high = min(high, low + MAX_OUTPUT * step)
    out = low + step * np.arange(int(math.floor((high - low) / step)) + 1)
    if out[-1] < high:
        out = np.append(out, high)
    # a run whose road is one curvature (a straight, an arc) keeps it exactly: the
    # average of a constant, without the integrals' rounding (and most steps of a run)
    behind = _behind(history, flat.shape[1])
    level = _level_runs(d, flat, behind, low - half_width)
    if np.all(level):
        smooth = np.broadcast_to(flat[:1], (out.size, flat.shape[1]))
    else:
        x_road, y_road = _road(d, flat, behind, low - half_width)
        # the road over [low - W, high + W] only, measured from low: its integrals stay of
        # the window's size wherever the polygon lies (from its first point they lost the
        # curvature to rounding a billion metres away)
        x_road, y_road = _cut(x_road, y_road, low - half_width, high + half_width)
        at = out - low
        values = _second_integral(x_road - low, y_road, np.concatenate(
            [at - half_width, at, at + half_width])).reshape(3, at.size, -1)
        smooth = (values[0] - 2.0 * values[1] + values[2]) / (half_width * half_width)
        smooth = np.where(level, flat[:1], smooth)
    beyond = d > high
    out_d = np.concatenate([out, d[beyond]])
    out_k = np.vstack([smooth, flat[beyond]])
    out_k = np.where(usable.reshape(-1), out_k, math.nan)
    return out_d, (out_k.reshape(-1) if k.ndim == 1 else out_k)


def _behind(history: Optional[CurvatureHistory],
            runs: int) -> Optional[tuple[np.ndarray, np.ndarray]]:
    """
    Return the history's samples as ``(where, rho)`` of shape ``(P, runs)``, or None.

    :param history: the curvature behind the CG.
    :param runs: the runs of the polygon.
    :return: None without samples, or for another batch's history (not this road).
    """
    if history is None:
        return None
    where, rho = history.behind()
    if where.size == 0:
        return None
    where = where.reshape(where.shape[0], -1)
    if where.shape[1] != runs:
        return None
    return where, rho.reshape(rho.shape[0], -1)


def _level_runs(d: np.ndarray, k: np.ndarray,
                behind: Optional[tuple[np.ndarray, np.ndarray]], start: float) -> np.ndarray:
    """
    Return per run whether its road in the window is one curvature, as :func:`_road` reads it.

    A run's road is level when its polygon is one value and so is every history sample
    its window reads: those behind the polygon's first point (and the CG) from the last
    one at or before ``start``. A sample without a curvature (a restarted run's) is
    filled from the others as :func:`_road` fills it, so it is not looked at: a run of a
    batch is level exactly when its single run is (a batch keeps the samples its slowest
    run reads, and a restarted run's single run has cleared them).

    :param d: the polygon's distances, ``(K,)``.
    :param k: its curvatures, ``(K, N)`` (finite where the run is usable).
    :param behind: the history's samples (:func:`_behind`).
    :param start: where the window starts [m] (from the CG).
    :return: boolean ``(N,)``.
    """
    level = np.all(k == k[:1], axis=0)
    if behind is None:
        return level
    where, rho = behind
    last = np.count_nonzero(where <= start, axis=0) - 1         # per run, -1: none
    read = ((np.arange(where.shape[0]).reshape(-1, 1) >= last) & (where < min(d[0], 0.0))
            & ~np.isnan(rho))
    return level & np.all(~read | (rho == k[:1]), axis=0)


def _road(d: np.ndarray, k: np.ndarray, behind: Optional[tuple[np.ndarray, np.ndarray]],
          start: float) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the road's breakpoints per run: the history behind the polygon, the polygon.

    :param d: the polygon's distances, ``(K,)``.
    :param k: its curvatures, ``(K, N)``.
    :param behind: the history's samples (:func:`_behind`).
    :param start: where the road is wanted from [m]: the samples before the last one
        before it are left out (a stopped run of a batch keeps every run's samples).
    :return: ``(x, y)``, shape ``(B, N)``, ``x`` non-decreasing per run (a piece of
        length 0 is a jump).
    """
    runs = k.shape[1]
    x_poly, y_poly = d, k
    if d[0] > 0.0:                      # the polygon's first value, held from the CG
        x_poly, y_poly = np.append(0.0, d), np.vstack([k[:1], k])
    x = np.broadcast_to(x_poly.reshape(-1, 1), (x_poly.size, runs))
    if behind is None:                  # none, or another batch's: none of this road's
        return x, y_poly
    where, rho = behind
    needed = np.flatnonzero(np.any((where >= start) & (where < x_poly[0]), axis=1))
    if needed.size:
        first = max(int(needed[0]) - 1, 0)
    else:                               # the last sample before the window, or the newest
        before = np.flatnonzero(np.any(where < start, axis=1))
        first = int(before[-1]) if before.size else where.shape[0] - 1
    where, rho = where[first:], rho[first:]
    # the samples behind the polygon's first point (and the CG); a sample without a
    # curvature, or not kept, takes the next kept finite one's toward now (a restarted
    # run's old samples: what its single run, cleared, holds back); none: the polygon's
    keep = where < x_poly[0]
    rho = np.where(keep, rho, math.nan)
    size = rho.shape[0]
    index = np.where(np.isfinite(rho), np.arange(size).reshape(-1, 1), size)
    nearest = np.minimum.accumulate(index[::-1], axis=0)[::-1]
    filled = np.take_along_axis(np.vstack([rho, y_poly[:1]]), nearest, axis=0)
    # a sample not kept moves up to the polygon's first point (a piece of length 0)
    where = np.where(keep, where, x_poly[0])
    return np.vstack([where, x]), np.vstack([filled, y_poly])


def _cut(x: np.ndarray, y: np.ndarray, start: float, end: float
         ) -> tuple[np.ndarray, np.ndarray]:
    """Return the road ``(x, y)`` on ``[start, end]``: its points there and both ends."""
    y_start, y_end = np.vsplit(_road_at(x, y, np.array([start, end])), 2)
    inside = (x > start) & (x < end)
    # the points outside move onto the ends, with the ends' values (pieces of length 0)
    y_in = np.where(inside, y, np.where(x <= start, y_start, y_end))
    x_in = np.clip(x, start, end)
    runs = x.shape[1]
    return (np.vstack([np.full((1, runs), start), x_in, np.full((1, runs), end)]),
            np.vstack([y_start, y_in, y_end]))


def _segment(x: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Return per point and run the index of the last breakpoint at or before it."""
    if x.shape[1] == 1:
        count = np.searchsorted(x[:, 0], at, side='right').reshape(-1, 1)
    elif at.size * x.size <= 1_000_000:   # per run (the history's positions differ)
        count = np.count_nonzero(x[None] <= at.reshape(-1, 1, 1), axis=1)
    else:
        count = np.stack([np.searchsorted(x[:, j], at, side='right')
                          for j in range(x.shape[1])], axis=1)
    return np.clip(count - 1, 0, x.shape[0] - 1)


def _road_at(x: np.ndarray, y: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Return the road at the points ``at`` (``(M,)``) per run: linear, held beyond its ends."""
    i = _segment(x, at)
    j = np.minimum(i + 1, x.shape[0] - 1)
    x0, x1 = np.take_along_axis(x, i, axis=0), np.take_along_axis(x, j, axis=0)
    y0, y1 = np.take_along_axis(y, i, axis=0), np.take_along_axis(y, j, axis=0)
    with np.errstate(invalid='ignore', divide='ignore'):
        share = np.where(x1 > x0, np.clip((at.reshape(-1, 1) - x0)
                                          / np.where(x1 > x0, x1 - x0, 1.0), 0.0, 1.0), 0.0)
    return y0 + share * (y1 - y0)


def _second_integral(x: np.ndarray, y: np.ndarray, at: np.ndarray) -> np.ndarray:
    """
    Return ``F(at)``, ``F'' = `` the road, ``F = F' = 0`` at its first breakpoint.

    The road is linear between the breakpoints ``(x, y)`` (``(B, N)``, ``x``
    non-decreasing per run; a piece of length 0 is a jump) and constant beyond them.

    :param at: the points, shape ``(M,)``.
    :return: shape ``(M, N)``.
    """
    dx = np.diff(x, axis=0)
    dy = np.diff(y, axis=0)
    with np.errstate(invalid='ignore', divide='ignore'):
        slope = np.where(dx > 0.0, dy / np.where(dx > 0.0, dx, 1.0), 0.0)
    first = np.vstack([np.zeros((1, x.shape[1])),
                       np.cumsum(y[:-1] * dx + 0.5 * slope * dx * dx, axis=0)])
    second = np.vstack([np.zeros((1, x.shape[1])),
                        np.cumsum(first[:-1] * dx + 0.5 * y[:-1] * dx * dx
                                  + slope * dx ** 3 / 6.0, axis=0)])
    i = _segment(x, at)                                             # (M, N)
    h = at.reshape(-1, 1) - np.take_along_axis(x, i, axis=0)
    m = np.take_along_axis(np.vstack([slope, np.zeros((1, x.shape[1]))]), i, axis=0)
    m = np.where(h >= 0.0, m, 0.0)      # before the first breakpoint: held
    return (np.take_along_axis(second, i, axis=0) + np.take_along_axis(first, i, axis=0) * h
            + 0.5 * np.take_along_axis(y, i, axis=0) * h * h + m * h ** 3 / 6.0)
