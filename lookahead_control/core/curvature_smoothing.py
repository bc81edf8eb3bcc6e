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
side): a straight line (a clothoid) is unchanged, a step becomes an S-curve of length
``2 W`` centred on it, a kink is rounded over ``+-W``. The window reaches behind the CG:
:class:`CurvatureHistory` keeps the curvature the law saw at the CG over the last ``W``
of road. ``docs/lane_keeping.md`` ("The previewed curvature, averaged along the road")
has the measurements.
"""

from __future__ import annotations

from typing import Any, Optional

from lookahead_control.core.numeric import Real
import numpy as np

#: quadrature points per half window (the grid's spacing, W / TAPS, is also the
#: averaged polygon's: the law reads a segment's slope, so a coarser output (W / 4) led
#: the rate by half a segment: S1 / S4 at 37 m/s 3.29 / 4.27 cm against 2.89 / 3.96)
TAPS = 8


def triangle_weights(taps: int = TAPS) -> np.ndarray:
    """
    Return the weights of the triangular window on ``2 taps + 1`` evenly spaced points.

    :param taps: points per half window.
    :return: the weights, summing to 1 (0 at the window's ends left out: ``2 taps - 1``
        weights for the offsets ``-(taps - 1) .. taps - 1`` grid steps).
    """
    j = np.arange(-(taps - 1), taps, dtype=float)
    weights = taps - np.abs(j)
    return weights / weights.sum()


class CurvatureHistory:
    """
    The curvature the law saw at the CG over the last ``half_width`` metres of road.

    Works on floats (one vehicle) and on arrays (a batch of runs): the distance travelled
    and the curvature are recorded per run.
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
        self.travelled: Optional[Any] = None
        self.samples: list[tuple[Any, Any]] = []

    def record(self, v_x: Real, dt: float, rho: Real) -> None:
        """
        Record the curvature at the CG after travelling ``v_x dt``.

        :param v_x: speed [m/s] (negative or not finite: taken as 0).
        :param dt: the step [s].
        :param rho: the curvature at the CG [1/m] (not finite: unknown there).
        """
        speed = np.where(np.isfinite(v_x), np.maximum(v_x, 0.0), 0.0)
        step, rho = np.broadcast_arrays(np.asarray(speed * dt, dtype=float),
                                        np.asarray(rho, dtype=float))
        if self.travelled is not None and np.shape(self.travelled) != step.shape:
            self.clear()                # another batch: its road behind is not this one
        self.travelled = step.copy() if self.travelled is None else self.travelled + step
        self.samples.append((np.array(self.travelled), rho.copy()))
        # the oldest sample kept is the last one at or beyond half_width behind every run
        while (len(self.samples) > 1
               and np.all(self.samples[1][0] <= self.travelled - self.half_width)):
            self.samples.pop(0)

    def forget(self, runs: Any) -> None:
        """
        Forget the road behind some runs of a batch (they restarted).

        :param runs: boolean per run.
        """
        self.samples = [(s, np.where(runs, np.nan, rho)) for s, rho in self.samples]

    def behind(self, distances: np.ndarray) -> Optional[np.ndarray]:
        """
        Return the curvature at ``distances`` behind the CG (negative), per run.

        Linear between the samples; before the oldest sample its value; NaN where the
        run has no finite sample there.

        :param distances: relative distances ``<= 0``, shape ``(M,)`` [m].
        :return: shape ``(M,)`` (floats recorded) or ``(M, N)``; None: no history.
        """
        if not self.samples:
            return None
        where = np.stack([s for s, _ in self.samples]) - self.travelled   # (P,) or (P, N)
        rho = np.stack([k for _, k in self.samples])
        u = distances.reshape((-1,) + (1,) * (where.ndim - 1))
        # per target and run: the sample at or before it and the one after (clipped)
        after = np.clip(np.sum(where[None] <= u[:, None], axis=1), 1, len(self.samples) - 1
                        ) if len(self.samples) > 1 else np.zeros(u.shape, dtype=int)
        before = np.maximum(after - 1, 0)

        def pick(values: np.ndarray, index: np.ndarray) -> np.ndarray:
            if values.ndim == 1:
                return values[index]
            return np.take_along_axis(values, np.broadcast_to(
                index, (index.shape[0], values.shape[1])), axis=0)

        s0, s1 = pick(where, before), pick(where, after)
        k0, k1 = pick(rho, before), pick(rho, after)
        gap = s1 - s0
        with np.errstate(invalid='ignore', divide='ignore'):
            share = np.where(gap > 0.0, np.clip((u - s0) / gap, 0.0, 1.0), 1.0)
        return k0 + share * (k1 - k0)


def smoothed_preview(distances: Any, curvatures: Any, half_width: float,
                     history: Optional[CurvatureHistory] = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the polygon averaged along the road by a triangular window of ``half_width``.

    The polygon is read as the law reads it (linear, held beyond its ends); behind the
    CG the window reads ``history`` (without it, or where a run has none: the polygon's
    first value, the curvature at the CG). The result is sampled every
    ``half_width / TAPS`` from the polygon's first distance to its last: read by linear
    interpolation like any polygon. A polygon the law would not read (not 1-D,
    empty, not increasing, a non-finite distance) is returned unchanged, and a run whose
    curvatures are not all finite keeps NaN (the law's fallback for it stays).

    :param distances: the polygon's distances ahead of the CG [m], shape ``(K,)``.
    :param curvatures: its curvatures [1/m], ``(K,)`` or ``(K, N)``.
    :param half_width: ``W`` [m] (> 0).
    :param history: the curvature behind the CG.
    :return: ``(distances, curvatures)`` of the averaged polygon.
    """
    d = np.asarray(distances, dtype=float)
    k = np.asarray(curvatures, dtype=float)
    if (d.ndim != 1 or d.size == 0 or k.shape[:1] != d.shape or not np.all(np.isfinite(d))
            or np.any(np.diff(d) <= 0.0)):
        return d, k
    usable = np.all(np.isfinite(k), axis=0)
    k = np.where(usable, k, 0.0)
    step = half_width / TAPS
    grid = d[0] - half_width + step * np.arange(
        int(np.floor((d[-1] - d[0] + 2.0 * half_width) / step + 1e-9)) + 1)
    column = (-1,) + (1,) * (k.ndim - 1)
    raw = _polygon_at(d, k, grid.reshape(column))
    past = grid < 0.0
    if np.any(past):
        behind = None if history is None else history.behind(grid[past])
        first = raw[np.argmax(grid >= d[0])] if np.any(grid >= d[0]) else k[0]
        if behind is not None and behind.shape[1:] == k.shape[1:]:
            raw[past] = np.where(np.isfinite(behind), behind, first)
        else:
            raw[past] = first
    weights = triangle_weights()
    centre = np.arange(TAPS, grid.size - TAPS)              # points with a whole window
    smooth = sum(w * raw[centre + j] for j, w in zip(range(-(TAPS - 1), TAPS), weights))
    out_d, out_k = grid[centre], np.asarray(smooth)
    return out_d, np.where(usable, out_k, np.nan)


def _polygon_at(d: np.ndarray, k: np.ndarray, where: np.ndarray) -> np.ndarray:
    """Return the polygon's linear interpolation at ``where`` (``(M,)`` or ``(M, 1)``)."""
    flat = where.reshape(-1)
    if d.size == 1:
        return np.broadcast_to(k[0], flat.shape + k.shape[1:]).copy()
    i = np.clip(np.searchsorted(d, flat, side='right') - 1, 0, d.size - 2)
    share = np.clip((flat - d[i]) / (d[i + 1] - d[i]), 0.0, 1.0)
    share = share.reshape(share.shape + (1,) * (k.ndim - 1))
    return k[i] + share * (k[i + 1] - k[i])
