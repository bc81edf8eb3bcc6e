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

"""Roads made of straight, arc and clothoid segments; curvature against arc length."""

from __future__ import annotations

import bisect
from dataclasses import dataclass
import math
from typing import Callable, Sequence

from lookahead_control.core.numeric import Real
from lookahead_control.core.params import check_choice, check_range, ParameterError
import numpy as np


SEGMENT_KINDS = ('straight', 'arc', 'clothoid')


@dataclass(frozen=True)
class Segment:
    """
    One road segment with linearly varying curvature (+ left turn).

    :param kind: ``straight``, ``arc`` or ``clothoid``.
    :param length: arc length [m].
    :param curvature_start: curvature at the start [1/m].
    :param curvature_end: curvature at the end [1/m] (equal to the start but on clothoids).
    """

    kind: str
    length: float
    curvature_start: float = 0.0
    curvature_end: float = 0.0

    def __post_init__(self) -> None:
        check_choice('segment.type', self.kind, SEGMENT_KINDS)
        check_range('segment.length', self.length, 0.0, 1.0e7, low_open=True, unit='m')
        for name in ('curvature_start', 'curvature_end'):
            check_range(f'segment.{name}', getattr(self, name), -1.0, 1.0, unit='1/m')
        if self.kind == 'straight' and (self.curvature_start or self.curvature_end):
            raise ParameterError('a straight segment has curvature 0; got '
                                 f'{self.curvature_start!r}, {self.curvature_end!r}')
        if self.kind == 'arc' and self.curvature_start != self.curvature_end:
            raise ParameterError('an arc has one curvature; got start '
                                 f'{self.curvature_start!r} and end {self.curvature_end!r}')


class Road:
    """A lane centreline as a sequence of segments, extended by its last curvature."""

    def __init__(self, segments: Sequence[Segment]) -> None:
        """
        Build the road.

        :param segments: at least one segment, in driving order.
        """
        if not segments:
            raise ParameterError('a road needs at least one segment')
        self.segments = tuple(segments)
        starts = [0.0]
        for seg in self.segments[:-1]:
            starts.append(starts[-1] + seg.length)
        self._starts = starts
        self._starts_np = np.array(starts)
        self._rho0 = np.array([s.curvature_start for s in self.segments])
        self._slope = np.array([(s.curvature_end - s.curvature_start) / s.length
                                for s in self.segments])
        self._rho0_list = [float(v) for v in self._rho0]     # scalar path: no numpy
        self._slope_list = [float(v) for v in self._slope]
        self.length = starts[-1] + self.segments[-1].length
        self._end_rho = self.segments[-1].curvature_end

    def curvature_function(self) -> Callable[[float], float]:
        """
        Return ``s -> rho`` for a float, equal to ``curvature(s)[0]``, for one caller.

        It remembers the segment it found last and checks it before bisecting: the
        simulator asks 40 times a step at nearly the same arc length.

        :return: the function.
        """
        starts, rho0, slopes = self._starts, self._rho0_list, self._slope_list
        length, end_rho = self.length, self._end_rho
        # segment i serves [bounds[i], bounds[i + 1]); the first also what lies before
        bounds = [-math.inf, *starts[1:], length]
        last = [0]

        def rho(s: float) -> float:
            i = last[0]
            if not bounds[i] <= s < bounds[i + 1]:
                if s >= length:
                    return end_rho
                i = last[0] = max(bisect.bisect_right(starts, s) - 1, 0)
            return rho0[i] + slopes[i] * (s - starts[i])
        return rho

    def curvature(self, s: Real) -> tuple[Real, Real]:
        """
        Return ``(rho, d rho / ds)`` at arc length ``s`` (float or array).

        Before the start the first segment's start curvature holds; past the end, the
        last segment's end curvature.

        :param s: arc length along the centreline [m].
        :return: curvature [1/m] and its slope [1/m^2].
        """
        if isinstance(s, np.ndarray):
            idx = np.clip(np.searchsorted(self._starts_np, s, side='right') - 1, 0, None)
            rho = self._rho0[idx] + self._slope[idx] * (s - self._starts_np[idx])
            slope = np.where(s >= self.length, 0.0, self._slope[idx])
            rho = np.where(s >= self.length, self._end_rho, rho)
            return rho, slope
        if s >= self.length:
            return self._end_rho, 0.0
        i = max(bisect.bisect_right(self._starts, s) - 1, 0)
        seg_slope = self._slope_list[i]
        return self._rho0_list[i] + seg_slope * (s - self._starts[i]), seg_slope

    def _start_poses(self) -> list[tuple[float, float, float]]:
        poses = getattr(self, '_poses', None)
        if poses is None:
            poses = [(0.0, 0.0, 0.0)]
            for i, seg in enumerate(self.segments[:-1]):
                poses.append(_advance(poses[-1], self._rho0_list[i], self._slope_list[i],
                                      seg.length))
            self._poses = poses
        return poses

    def pose(self, s: float) -> tuple[float, float, float]:
        """
        Return the centreline's global ``(x, y, heading)`` at arc length ``s``.

        The road starts at the origin heading along +x (REP-103: x forward, y left,
        heading counter-clockwise); each segment continues from the end of the one
        before. Straights and arcs are closed forms; a clothoid's position is the
        Fresnel integral of its heading by Gauss-Legendre quadrature (exact to rounding
        for phase changes up to 0.5 rad a panel). Before the start the first segment's
        start curvature holds, past the end the last one's end curvature, as in
        :meth:`curvature`.

        :param s: arc length [m].
        :return: x [m], y [m], heading [rad] (not wrapped).
        """
        s = float(s)
        if s >= self.length:
            i = len(self.segments) - 1
            end = _advance(self._start_poses()[i], self._rho0_list[i], self._slope_list[i],
                           self.segments[i].length)
            return _advance(end, self._end_rho, 0.0, s - self.length)
        i = max(bisect.bisect_right(self._starts, s) - 1, 0)
        start = self._starts[i]
        return _advance(self._start_poses()[i], self._rho0_list[i], self._slope_list[i],
                        s - start)

    def poses(self, s: Sequence[float]) -> np.ndarray:
        """
        Return :meth:`pose` at each arc length, as rows ``(x, y, heading)``.

        :param s: arc lengths [m].
        :return: an array of shape (len(s), 3).
        """
        return np.array([self.pose(v) for v in s], dtype=float).reshape(-1, 3)

    def sample(self, length: float, spacing: float) -> np.ndarray:
        """
        Return the centreline every ``spacing`` metres from 0 to ``length`` (included).

        :param length: how far [m] (past the road's end it continues with its last
            curvature).
        :param spacing: distance between points [m].
        :return: rows ``(x, y, heading)``.
        """
        check_range('path_spacing', spacing, 0.0, 1.0e4, low_open=True, unit='m')
        s = np.arange(0.0, length, spacing)
        return self.poses(list(np.append(s, length) if length - s[-1] > 1e-9 else s))

    def global_pose(self, s: float, lateral: float,
                    relative_yaw: float) -> tuple[float, float, float]:
        """
        Return the global pose of a body at road coordinates (Frenet to global).

        :param s: arc length of its projection [m].
        :param lateral: its distance from the centreline [m] (+ left).
        :param relative_yaw: its yaw relative to the road's heading [rad].
        :return: x [m], y [m], yaw [rad].
        """
        x, y, heading = self.pose(s)
        return (x - lateral * math.sin(heading), y + lateral * math.cos(heading),
                heading + relative_yaw)


_GAUSS_NODES, _GAUSS_WEIGHTS = np.polynomial.legendre.leggauss(16)


def _advance(pose: tuple[float, float, float], rho: float, slope: float,
             u: float) -> tuple[float, float, float]:
    """
    Move ``u`` metres along a curve of curvature ``rho + slope * u`` (u may be < 0).

    :param pose: the start ``(x, y, heading)``.
    :param rho: curvature at the start [1/m].
    :param slope: curvature change per metre [1/m^2].
    :param u: distance [m].
    :return: the pose at the end.
    """
    x, y, theta = pose
    heading = theta + rho * u + 0.5 * slope * u * u
    if slope == 0.0:
        # chord of an arc (or a straight line): length u sinc(rho u / 2), at the mean
        # heading; stable for rho -> 0
        half = 0.5 * rho * u
        chord = u * (math.sin(half) / half if half != 0.0 else 1.0)
        mid = theta + half
        return x + chord * math.cos(mid), y + chord * math.sin(mid), heading
    panels = max(1, math.ceil(max(abs(u) / 50.0,
                                  max(abs(rho), abs(rho + slope * u)) * abs(u) / 0.5)))
    edges = np.linspace(0.0, u, panels + 1)
    mids, halves = 0.5 * (edges[1:] + edges[:-1]), 0.5 * np.diff(edges)
    nodes = (mids[:, None] + halves[:, None] * _GAUSS_NODES[None, :]).ravel()
    weights = (halves[:, None] * _GAUSS_WEIGHTS[None, :]).ravel()
    phase = theta + rho * nodes + 0.5 * slope * nodes * nodes
    return (x + float(np.dot(weights, np.cos(phase))),
            y + float(np.dot(weights, np.sin(phase))), heading)


class RoadBatch:
    """
    One road per run of a batch (each laid out for its run's speed).

    ``curvature(s)`` takes arc lengths whose last axis is the batch (shape ``(..., N)``)
    and evaluates run n's road on ``s[..., n]`` with the operations of
    :meth:`Road.curvature`, so each run gets the values its own road gives.
    """

    def __init__(self, roads: Sequence[Road]) -> None:
        """
        Stack the roads.

        :param roads: one road per run.
        """
        if not roads:
            raise ParameterError('a road batch needs at least one road')
        self.roads = tuple(roads)
        width = max(len(r.segments) for r in roads)
        n = len(roads)
        self._starts = np.full((n, width), np.inf)
        self._rho0 = np.zeros((n, width))
        self._slope = np.zeros((n, width))
        for i, road in enumerate(roads):
            m = len(road.segments)
            self._starts[i, :m] = road._starts_np
            self._rho0[i, :m] = road._rho0
            self._slope[i, :m] = road._slope
        self.length = np.array([r.length for r in roads])
        self._end_rho = np.array([r._end_rho for r in roads])
        self._rows = np.arange(n)

    def curvature(self, s: Real) -> tuple[Real, Real]:
        """
        Return ``(rho, d rho / ds)`` of each run's road at its arc length.

        :param s: arc lengths, last axis the batch [m].
        :return: curvature [1/m] and slope [1/m^2], shaped like ``s``.
        """
        s = np.asarray(s, dtype=float)
        idx = np.maximum(np.count_nonzero(s[..., None] >= self._starts, axis=-1) - 1, 0)
        rows = self._rows
        slope = self._slope[rows, idx]
        rho = self._rho0[rows, idx] + slope * (s - self._starts[rows, idx])
        past = s >= self.length
        return np.where(past, self._end_rho, rho), np.where(past, 0.0, slope)
