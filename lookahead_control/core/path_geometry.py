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
A vehicle's pose relative to a reference path: the geometry behind ``path_bridge``.

A path is a polyline of points ``(x, y)`` in one frame (a ``nav_msgs/Path``), in
driving order. What the controller needs from it, at the vehicle's CG:

- **Heading and curvature** from a local least-squares cubic ``x(u), y(u)`` in the
  chord length ``u`` over the points within ``fit_half_window`` of each vertex (a
  Savitzky-Golay filter on a non-uniform grid; at least two neighbours a side). On a
  symmetric window the curvature term is that of a quadratic fit (odd and even terms
  separate), so point noise ``sigma`` gives a curvature noise of about
  ``6.7 sigma / (h^2 sqrt(N))`` for ``N`` points in ``[-h, h]``, where the three-point
  (circumcircle) curvature gives ``~4 sigma / spacing^2``; a clothoid's linear
  curvature is reproduced without bias, an arc's to ``h^2 rho^3``. Between vertices the
  two neighbouring fits are blended linearly, so position, heading and curvature are
  continuous along the path.
- **Projection**: the nearest point of the polyline, searched among the segments within
  ``search_distance`` (plus the distance driven) of the last match, then refined by
  Newton steps on the smooth fit (no chord error). Only segments pointing within 90
  degrees of the vehicle's heading count, so a path that comes back close to itself
  (a hairpin, a loop, a track driven twice) is not confused with its other branch. The
  first match, a pose that jumped further than ``jump_distance`` from where the last one
  and its velocity predicted (relocalization), and a match at the edge of the window
  search the whole path; among the branches within ``jump_distance`` of the nearest,
  the one closest in arc length to the prediction wins.
- **Signed lateral error** of the CG (+ left of the path, REP-103), **relative yaw**
  (vehicle yaw minus path heading, + counter-clockwise) and the **distance along the
  path** (chord length from the first point).

Pure Python and numpy; no ROS.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass
import math
from typing import Optional, Sequence

from lookahead_control.core.params import check_range, ParameterError
import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]

# path and pose coordinates beyond this are refused: a planar frame in metres never needs
# more (UTM northings are < 1e7 m), and the projection's products of such coordinates
# overflow no float (beyond, inf - inf gave NaN output or an uncaught ValueError)
MAX_COORDINATE = 1e9
#: passes of the duplicate filter before it judges each point against the last kept
MAX_DUPLICATE_PASSES = 20


class PathError(ValueError):
    """A path that cannot be used, or a pose that has no place on the path."""


@dataclass(frozen=True)
class PathParams:
    """
    How a path is fitted and searched.

    :param fit_half_window: half-width of the local fit window [m].
    :param search_distance: the local search covers the last match +- this (plus the
        distance driven since) [m].
    :param jump_distance: a pose further than this from its prediction is a
        relocalization: the whole path is searched [m].
    :param max_distance: a vehicle further than this from the path is off it [m].
    :param start_tolerance: the vehicle may be this far before the path's first point
        (the path is extended along its first tangent) [m].
    :param duplicate_distance: points closer than this to the previous one are dropped [m].
    """

    fit_half_window: float = 5.0
    search_distance: float = 10.0
    jump_distance: float = 1.0
    max_distance: float = 5.0
    start_tolerance: float = 1.0
    duplicate_distance: float = 1e-4

    def __post_init__(self) -> None:
        check_range('fit_half_window', self.fit_half_window, 0.01, 1000.0, unit='m')
        check_range('search_distance', self.search_distance, 0.1, 1000.0, unit='m')
        check_range('jump_distance', self.jump_distance, 0.01, 1000.0, unit='m')
        check_range('max_distance', self.max_distance, 0.01, 1000.0, unit='m')
        check_range('start_tolerance', self.start_tolerance, 0.0, 1000.0, unit='m')
        check_range('duplicate_distance', self.duplicate_distance, 0.0, 1.0, unit='m')


@dataclass(frozen=True)
class PathPoint:
    """
    The smooth path at one arc length.

    :param s: distance along the path [m].
    :param x: position x [m].
    :param y: position y [m].
    :param heading: tangent direction [rad] (+ counter-clockwise from x).
    :param curvature: curvature [1/m] (+ left turn).
    """

    s: float
    x: float
    y: float
    heading: float
    curvature: float


@dataclass(frozen=True)
class LaneState:
    """
    The vehicle's CG relative to the path.

    :param s: distance along the path of its projection [m].
    :param lateral_error: signed distance from the path [m] (+ left).
    :param relative_yaw: vehicle yaw minus path heading, in (-pi, pi] [rad].
    :param curvature: path curvature at the projection [1/m] (+ left).
    :param heading: path heading at the projection [rad].
    :param remaining: path length left ahead of the projection [m].
    :param note: why the whole path was searched (first match, relocalization, ...)
        or ''.
    """

    s: float
    lateral_error: float
    relative_yaw: float
    curvature: float
    heading: float
    remaining: float
    note: str = ''


def wrap_angle(angle: float) -> float:
    """
    Return an angle wrapped to (-pi, pi].

    :param angle: the angle [rad].
    :return: the wrapped angle [rad].
    """
    wrapped = math.remainder(angle, 2.0 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


def three_point_curvature(points: Array) -> Array:
    """
    Return the circumcircle curvature at each interior point (the naive estimate).

    For comparison with the fit: it amplifies point noise by ``~4 / spacing^2``.

    :param points: shape (N, 2).
    :return: shape (N - 2,), + left.
    """
    a, b, c = points[:-2], points[1:-1], points[2:]
    ab, bc, ca = b - a, c - b, a - c
    cross = ab[:, 0] * bc[:, 1] - ab[:, 1] * bc[:, 0]
    norms = (np.hypot(ab[:, 0], ab[:, 1]) * np.hypot(bc[:, 0], bc[:, 1])
             * np.hypot(ca[:, 0], ca[:, 1]))
    return np.asarray(2.0 * cross / norms, dtype=float)


def preview_points(distance: float, step: float) -> int:
    """
    Return the points of a curvature preview of ``distance`` at ``step``.

    :param distance: how far ahead [m].
    :param step: spacing [m].
    :return: the count (:meth:`ReferencePath.preview`; the path's end may cut it shorter).
    """
    return int(distance / step + 1e-9) + 1 if step > 0.0 else 1


def drop_duplicates(points: Array, distance: float) -> Array:
    """
    Return the points less the duplicates: consecutive kept points more than ``distance`` apart.

    A point within ``distance`` of the one given before it is dropped, and again among
    the points kept, until none is: ``(0, 0), (9e-5, 0), (1.8e-4, 0), (0, 0)`` at 1e-4 m
    keeps one ``(0, 0)``. Before, one pass kept the second ``(0, 0)`` next to the first
    (each dropped point within 1e-4 of its predecessor): a segment of length 0, direction
    0 / 0, and the bridge published NaN, then raised (dev-probe92).

    :param points: ``(x, y)`` rows, finite.
    :param distance: the duplicate distance [m] (0: only equal points are duplicates).
    :return: the points kept.
    """
    for _ in range(MAX_DUPLICATE_PASSES):
        steps = np.hypot(*np.diff(points, axis=0).T)
        keep = np.concatenate(([True], steps > distance))
        if keep.all():
            return points
        points = points[keep]
    # a chain the passes do not settle: each point against the last one kept
    kept = [0]
    last_x, last_y = points[0]
    for i, (x, y) in enumerate(points[1:].tolist(), start=1):
        if math.hypot(x - last_x, y - last_y) > distance:
            kept.append(i)
            last_x, last_y = x, y
    return points[kept]


class ReferencePath:
    """A reference path: its points, arc lengths and a lazily computed smooth fit."""

    def __init__(self, points: Sequence[Sequence[float]] | Array,
                 params: Optional[PathParams] = None) -> None:
        """
        Check and prepare a path.

        Duplicate points are dropped (counted in ``duplicates``); the path ends at its
        first cusp (a reversal: consecutive segments more than 90 degrees apart), since
        the controller only drives forward (``cusp_at`` says where, else None).

        :param points: ``(x, y)`` per point, in driving order.
        :param params: fit and search parameters.
        :raises PathError: empty, non-finite, or fewer than two distinct points.
        """
        self.params = params or PathParams()
        raw = np.asarray(points, dtype=float)
        if raw.size == 0:
            raise PathError('the path is empty')
        if raw.ndim != 2 or raw.shape[1] != 2:
            raise PathError(f'path points must be (x, y) pairs; got shape {raw.shape}')
        bad = np.flatnonzero(~np.isfinite(raw).all(axis=1))
        if bad.size:
            i = int(bad[0])
            raise PathError(f'path point {i} is not finite ({raw[i, 0]!r}, {raw[i, 1]!r}); '
                            f'{bad.size} such point(s)')
        far = np.flatnonzero((np.abs(raw) > MAX_COORDINATE).any(axis=1))
        if far.size:
            i = int(far[0])
            raise PathError(f'path point {i} is out of range ({raw[i, 0]:g}, {raw[i, 1]:g}): '
                            f'coordinates must be within +-{MAX_COORDINATE:g} m')
        pts = drop_duplicates(raw, self.params.duplicate_distance)
        self.given = len(raw)
        self.duplicates = int(len(raw) - len(pts))
        if len(pts) < 2:
            raise PathError(f'the path has {len(pts)} distinct point(s) ({len(raw)} given): '
                            'need 2 for a direction')
        seg = np.diff(pts, axis=0)
        dots = np.einsum('ij,ij->i', seg[:-1], seg[1:])
        cusps = np.flatnonzero(dots < 0.0)
        self.cusp_at: Optional[float] = None
        if cusps.size:
            pts = pts[:int(cusps[0]) + 2]
            seg = np.diff(pts, axis=0)
        self.points = pts
        self.seg = seg
        self.seg_length = np.hypot(seg[:, 0], seg[:, 1])
        self.s = np.concatenate(([0.0], np.cumsum(self.seg_length)))
        if cusps.size:
            self.cusp_at = float(self.s[-1])
        self.length = float(self.s[-1])
        self.size = len(pts)
        # per message only a few vertices are evaluated: plain floats, fitted on first use
        self._s_list = self.s.tolist()
        self._fits: list[Optional[tuple[float, ...]]] = [None] * self.size

    # -- smooth fit -------------------------------------------------------------------

    def fit(self, i: int) -> tuple[float, ...]:
        """
        Return the local cubic at vertex ``i``: ``(x0, x1, x2, x3, y0, y1, y2, y3)``.

        ``x(u) = x0 + x1 u + x2 u^2 + x3 u^3`` and likewise y, ``u`` the chord length from
        vertex ``i``. Fitted on first use and kept.

        :param i: the vertex.
        :return: the eight coefficients.
        """
        cached = self._fits[i]
        if cached is not None:
            return cached
        s, h, n = self.s, self.params.fit_half_window, self.size
        lo = min(int(np.searchsorted(s, s[i] - h, 'left')), max(i - 2, 0))
        hi = max(int(np.searchsorted(s, s[i] + h, 'right')), min(i + 3, n))
        u = s[lo:hi] - s[i]
        scale = max(float(np.max(np.abs(u))), 1e-12)
        degree = min(3, hi - lo - 1)
        basis = (u / scale)[:, None] ** np.arange(degree + 1)[None, :]
        solution, *_ = np.linalg.lstsq(basis, self.points[lo:hi], rcond=None)
        coeffs = np.zeros((2, 4))
        coeffs[:, :degree + 1] = (solution / scale ** np.arange(degree + 1)[:, None]).T
        fitted = tuple(coeffs.ravel().tolist())
        self._fits[i] = fitted
        return fitted

    def _local(self, i: int, u: float) -> tuple[float, float, float, float]:
        x0, x1, x2, x3, y0, y1, y2, y3 = self._fits[i] or self.fit(i)
        x = x0 + u * (x1 + u * (x2 + u * x3))
        y = y0 + u * (y1 + u * (y2 + u * y3))
        dx, dy = x1 + u * (2.0 * x2 + 3.0 * u * x3), y1 + u * (2.0 * y2 + 3.0 * u * y3)
        ddx, ddy = 2.0 * x2 + 6.0 * u * x3, 2.0 * y2 + 6.0 * u * y3
        speed = math.hypot(dx, dy)
        curvature = (dx * ddy - dy * ddx) / speed ** 3 if speed > 0.0 else 0.0
        return x, y, math.atan2(dy, dx), curvature

    def at(self, s: float) -> PathPoint:
        """
        Return the smooth path at distance ``s``.

        Before the first point and past the last, the path continues along its end
        tangent (curvature of the end fit).

        :param s: distance along the path [m].
        :return: position, heading and curvature there.
        """
        if s <= 0.0 or s >= self.length:
            i = 0 if s <= 0.0 else self.size - 1
            x, y, heading, curvature = self._local(i, 0.0)
            u = s - self._s_list[i]
            return PathPoint(s, x + u * math.cos(heading), y + u * math.sin(heading),
                             heading, curvature)
        i = min(max(bisect.bisect_right(self._s_list, s) - 1, 0), self.size - 2)
        s0, s1 = self._s_list[i], self._s_list[i + 1]
        # a segment shorter than the arc length's rounding (far from the origin) adds 0
        w = (s - s0) / (s1 - s0) if s1 > s0 else 0.0
        xa, ya, ha, ka = self._local(i, s - s0)
        xb, yb, hb, kb = self._local(i + 1, s - s1)
        return PathPoint(s, xa + w * (xb - xa), ya + w * (yb - ya),
                         ha + w * wrap_angle(hb - ha), ka + w * (kb - ka))

    def curvature(self, s: float) -> float:
        """
        Return the smooth curvature at distance ``s`` [1/m] (+ left).

        :param s: distance along the path [m].
        :return: the curvature.
        """
        return self.at(s).curvature

    # -- search -----------------------------------------------------------------------

    def nearest_segment(self, x: float, y: float, heading: float, lo_s: float = -math.inf,
                        hi_s: float = math.inf, hint_s: Optional[float] = None,
                        ambiguity: float = 0.0) -> tuple[float, float, bool]:
        """
        Return the nearest polyline point among the segments overlapping ``[lo_s, hi_s]``.

        Segments pointing more than 90 degrees away from ``heading`` are skipped (unless
        all are). With ``hint_s``, any segment within ``ambiguity`` of the nearest
        distance may win if it is closer to ``hint_s`` in arc length.

        :param x: point x [m].
        :param y: point y [m].
        :param heading: the vehicle's heading [rad].
        :param lo_s: start of the searched stretch [m].
        :param hi_s: end of the searched stretch [m].
        :param hint_s: the arc length expected [m].
        :param ambiguity: distance tolerance for the hint [m].
        :return: the distance along the path of the point found, its distance from
            ``(x, y)`` and whether it lies on the edge of the stretch (the nearest point
            may be outside it).
        """
        n_seg = self.size - 1
        i0 = min(max(int(np.searchsorted(self.s, lo_s, 'right')) - 1, 0), n_seg - 1)
        i1 = min(int(np.searchsorted(self.s, hi_s, 'left')), n_seg)
        i1 = max(i1, i0 + 1)
        a, d = self.points[i0:i1], self.seg[i0:i1]
        length2 = self.seg_length[i0:i1] ** 2
        rx, ry = x - a[:, 0], y - a[:, 1]
        dot = rx * d[:, 0] + ry * d[:, 1]
        t = np.clip(np.divide(dot, length2, out=np.zeros_like(dot), where=length2 > 0.0),
                    0.0, 1.0)
        dist = np.hypot(rx - t * d[:, 0], ry - t * d[:, 1])
        ahead = d[:, 0] * math.cos(heading) + d[:, 1] * math.sin(heading) > 0.0
        if ahead.any():
            dist = np.where(ahead, dist, np.inf)
        best = int(np.argmin(dist))
        along = self.s[i0:i1] + t * self.seg_length[i0:i1]
        if hint_s is not None and ambiguity > 0.0:
            near = np.flatnonzero(dist <= dist[best] + ambiguity)
            best = int(near[np.argmin(np.abs(along[near] - hint_s))])
        # extend along the end tangents before the first and past the last point
        s_found = float(along[best])
        if i0 + best == 0 and t[best] == 0.0:
            s_found = float((rx[best] * d[best, 0] + ry[best] * d[best, 1])
                            / self.seg_length[0])
        elif i0 + best == n_seg - 1 and t[best] == 1.0:
            s_found = float(self.s[n_seg - 1] + (rx[best] * d[best, 0] + ry[best] * d[best, 1])
                            / self.seg_length[n_seg - 1])
        edge = bool((best == 0 and t[best] == 0.0 and i0 > 0)
                    or (best == len(t) - 1 and t[best] == 1.0 and i1 < n_seg))
        return s_found, float(dist[best]), edge

    def project(self, x: float, y: float, s0: float) -> tuple[PathPoint, float]:
        """
        Refine a polyline match onto the smooth path (Newton steps on the tangent).

        :param x: point x [m].
        :param y: point y [m].
        :param s0: the polyline match [m].
        :return: the smooth path point and the signed lateral offset of ``(x, y)`` from
            it (+ left) [m].
        """
        s = s0
        point = self.at(s)
        lateral = 0.0
        for _ in range(4):
            c, sn = math.cos(point.heading), math.sin(point.heading)
            dx, dy = x - point.x, y - point.y
            along = c * dx + sn * dy
            lateral = c * dy - sn * dx
            step = along / max(1.0 - point.curvature * lateral, 0.1)
            s += step
            point = self.at(s)
            if abs(step) < 1e-9:
                break
        c, sn = math.cos(point.heading), math.sin(point.heading)
        lateral = c * (y - point.y) - sn * (x - point.x)
        return point, lateral

    def preview(self, s: float, distance: float, step: float) -> list[tuple[float, float]]:
        """
        Return (distance ahead, curvature) from ``s`` up to ``distance`` or the path's end.

        :param s: the start [m].
        :param distance: how far ahead [m].
        :param step: spacing [m].
        :return: the pairs, the first at distance 0.
        """
        out = []
        for k in range(preview_points(distance, step)):
            ahead = k * step
            if k and s + ahead > self.length:
                break
            out.append((ahead, self.curvature(s + ahead)))
        return out


class PathFollower:
    """Tracks one vehicle along one path: each pose is searched for near the last match."""

    def __init__(self, path: ReferencePath) -> None:
        """
        Start without a match (the first pose searches the whole path).

        :param path: the path.
        """
        self.path = path
        self.last_s: Optional[float] = None
        self._hint: Optional[float] = None
        self._last: Optional[tuple[int, float, float, float, float, float]] = None
        self.matched = False
        self.rematches = 0

    def reset(self) -> None:
        """Forget the last match (the next pose searches the whole path)."""
        if self.last_s is not None:
            self._hint = self.last_s
        self.last_s = None

    def locate(self, stamp_ns: int, x: float, y: float, yaw: float, v_x: float = 0.0,
               v_y: float = 0.0) -> LaneState:
        """
        Return the CG's place on the path.

        :param stamp_ns: the pose's stamp [ns].
        :param x: CG x in the path's frame [m].
        :param y: CG y [m].
        :param yaw: vehicle yaw in the path's frame [rad].
        :param v_x: body longitudinal velocity [m/s] (for the prediction).
        :param v_y: body lateral velocity [m/s].
        :return: the lane state.
        :raises PathError: the pose is off, before, past or against the path; the
            message says which.
        """
        for name, value in (('x', x), ('y', y), ('yaw', yaw), ('v_x', v_x), ('v_y', v_y)):
            if not math.isfinite(value):
                raise PathError(f'odometry {name} is not finite ({value!r})')
        for name, value in (('x', x), ('y', y)):
            if abs(value) > MAX_COORDINATE:
                raise PathError(f'odometry {name} is out of range ({value:g}): coordinates '
                                f'must be within +-{MAX_COORDINATE:g} m')
        path, p = self.path, self.path.params
        last, last_s = self._last, self.last_s
        note = ''
        hint: Optional[float] = None
        if last is None or last_s is None:
            note = 're-match after a refused pose' if self.matched else 'first match'
            # a path that passes a place twice (a loop driven twice): the first match
            # takes the earliest pass, a re-match the one nearest the last match
            hint = self._hint if self._hint is not None else 0.0
        else:
            stamp0, x0, y0, yaw0, vx0, vy0 = last
            dt = (stamp_ns - stamp0) * 1e-9
            if dt < 0.0:
                note, hint = f'odometry time went back {-dt:.3f} s', last_s
            elif dt > 1.0:
                note, hint = f'odometry gap of {dt:.2f} s', last_s
            else:
                px = x0 + (vx0 * math.cos(yaw0) - vy0 * math.sin(yaw0)) * dt
                py = y0 + (vx0 * math.sin(yaw0) + vy0 * math.cos(yaw0)) * dt
                miss = math.hypot(x - px, y - py)
                if miss > p.jump_distance:
                    note = (f'odometry jumped {miss:.2f} m from its prediction '
                            '(relocalization?)')
                    hint = last_s + math.hypot(px - x0, py - y0)
        self._last = (stamp_ns, x, y, yaw, v_x, v_y)
        if not note:
            assert last is not None and last_s is not None
            moved = math.hypot(x - last[1], y - last[2])
            window = p.search_distance + moved
            s0, _, edge = path.nearest_segment(x, y, yaw, last_s - window, last_s + window)
            if edge:
                note, hint = 'left the search window', last_s
        if note:
            s0, _, _ = path.nearest_segment(x, y, yaw, hint_s=hint,
                                            ambiguity=p.jump_distance)
            s0, _, _ = path.nearest_segment(x, y, yaw, s0 - p.search_distance,
                                            s0 + p.search_distance)
            if note != 'first match':
                self.rematches += 1
        point, lateral = path.project(x, y, s0)
        self.last_s = point.s
        relative_yaw = wrap_angle(yaw - point.heading)
        if point.s < -p.start_tolerance:
            self.reset()
            raise PathError(f'the path starts {-point.s:.2f} m ahead of the vehicle '
                            f'(start_tolerance {p.start_tolerance:g} m)')
        if point.s > path.length:
            self.reset()
            raise PathError(f'the vehicle is {point.s - path.length:.2f} m past the end '
                            'of the path (the path ended or lies behind the vehicle)')
        if abs(lateral) > p.max_distance:
            self.reset()
            raise PathError(f'the vehicle is {lateral:+.2f} m from the path '
                            f'(max_distance {p.max_distance:g} m)')
        if abs(relative_yaw) > 0.5 * math.pi:
            self.reset()
            raise PathError(f'the vehicle faces against the path (relative yaw '
                            f'{relative_yaw:+.2f} rad)')
        values = (point.s, lateral, relative_yaw, point.curvature, point.heading)
        if not all(math.isfinite(v) for v in values):
            # never a NaN to the controller, whatever the path's points (dev-probe92)
            self.reset()
            raise PathError(f'the path gives no finite place for the vehicle (s, offset, '
                            f'relative yaw, curvature, heading = {values}): its points are '
                            'degenerate there')
        self.matched = True
        if note == 'first match':
            note = ''
        elif note:
            note += f': matched at s = {point.s:.2f} m'
            was = last_s if last_s is not None else self._hint
            if was is not None:
                note += f' (was {was:.2f} m)'
        return LaneState(point.s, lateral, relative_yaw, point.curvature, point.heading,
                         path.length - point.s, note)


def cg_pose(x: float, y: float, yaw: float, v_y: float, yaw_rate: float,
            offset: float) -> tuple[float, float, float]:
    """
    Move a body-frame pose and lateral velocity from the odometry frame to the CG.

    :param x: odometry frame x [m].
    :param y: odometry frame y [m].
    :param yaw: yaw [rad].
    :param v_y: body lateral velocity at the odometry frame [m/s].
    :param yaw_rate: yaw rate [rad/s].
    :param offset: the CG lies this far ahead of the odometry frame on its x axis [m].
    :return: CG x, CG y, lateral velocity at the CG (``v_y + offset r``).
    """
    if not math.isfinite(offset):
        raise ParameterError(f'base_to_cg = {offset!r} m is not finite')
    return (x + offset * math.cos(yaw), y + offset * math.sin(yaw), v_y + offset * yaw_rate)


def twist_in_parent_frame(dx: float, dy: float, dt: float, yaw: float, v_x: float,
                          v_y: float) -> bool:
    """
    Return True if a twist fits the pose's motion as a parent-frame velocity, not a body one.

    REP-105 puts an odometry twist in the child (body) frame; some publishers (a world
    frame simulator plugin, a misconfigured filter) put it in the parent frame. The two
    agree when the yaw is near 0 and differ otherwise; this says "parent frame" only when
    the motion over ``dt`` matches the twist as given to 10 % of the speed and the body
    reading of it is off by 30 % or more, at 2 m/s or faster.

    :param dx: motion along the parent frame's x since the last pose [m].
    :param dy: motion along its y [m].
    :param dt: time since the last pose [s].
    :param yaw: yaw, mean over the interval [rad].
    :param v_x: twist linear x [m/s].
    :param v_y: twist linear y [m/s].
    :return: whether the twist looks like a parent-frame velocity.
    """
    if not 0.0 < dt <= 0.5:
        return False
    wx, wy = dx / dt, dy / dt
    speed = math.hypot(wx, wy)
    if speed < 2.0:
        return False
    c, s = math.cos(yaw), math.sin(yaw)
    body_error = math.hypot(wx - (c * v_x - s * v_y), wy - (s * v_x + c * v_y))
    parent_error = math.hypot(wx - v_x, wy - v_y)
    return parent_error < 0.1 * speed and body_error > 0.3 * speed
