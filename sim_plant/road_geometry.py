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
A road's centreline in global coordinates, and the projection of a pose onto it.

The centreline starts at the origin heading along +x. Its heading is the integral of
the curvature (exact: quadratic in s on each segment); its position is the integral of
the heading's cosine and sine, by 8-point Gauss-Legendre quadrature over knots at most
``knot`` metres apart (error far below a micrometre on any road here). Past the road's
end the last curvature continues, before its start the first one (as
:meth:`~sim_plant.road.Road.curvature` does).

:meth:`Centreline.frenet` turns a global pose into what the controller's contract
measures: arc length of the closest centreline point, lateral error (+ left of the
lane), relative yaw (vehicle yaw minus the lane's tangent), and the curvature there.
"""

from __future__ import annotations

import bisect
import math
from typing import NamedTuple

from lookahead_control.core.params import ParameterError
import numpy as np
from sim_plant.road import Road

_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)
_NODES = [float(v) for v in 0.5 * (_GL_X + 1.0)]
_WEIGHTS = [float(v) for v in 0.5 * _GL_W]


class Frenet(NamedTuple):
    """
    A pose in lane coordinates.

    :param s: arc length of the closest centreline point [m].
    :param lateral: lateral error, + left of the centreline [m].
    :param relative_yaw: vehicle yaw minus the tangent's heading, in (-pi, pi] [rad].
    :param curvature: centreline curvature at ``s`` [1/m].
    """

    s: float
    lateral: float
    relative_yaw: float
    curvature: float


def wrap(angle: float) -> float:
    """
    Return ``angle`` wrapped into (-pi, pi].

    :param angle: an angle [rad].
    :return: the same direction in (-pi, pi].
    """
    wrapped = math.remainder(angle, 2.0 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


class Centreline:
    """The road's centreline in global coordinates."""

    def __init__(self, road: Road, knot: float = 5.0, extension: float = 2000.0) -> None:
        """
        Lay the road out.

        :param road: the road (curvature against arc length).
        :param knot: largest knot spacing [m].
        :param extension: how far past the end the last curvature is laid out [m].
        """
        starts = list(road._starts) + [road.length]
        rho0 = list(road._rho0_list) + [road._end_rho]
        slope = list(road._slope_list) + [0.0]
        self._seg_start, self._rho0, self._slope = starts, rho0, slope
        self._first_rho = rho0[0]
        self.length = road.length
        heading = [0.0]
        for i in range(len(starts) - 1):
            ds = starts[i + 1] - starts[i]
            heading.append(heading[-1] + rho0[i] * ds + 0.5 * slope[i] * ds * ds)
        self._seg_heading = heading
        knots: list[float] = []
        for i, s0 in enumerate(starts):
            end = starts[i + 1] if i + 1 < len(starts) else road.length + extension
            n = max(1, int(math.ceil((end - s0) / knot)))
            knots.extend(s0 + (end - s0) * j / n for j in range(n))
        knots.append(road.length + extension)
        self._knots = knots
        xs, ys = [0.0], [0.0]
        for a, b in zip(knots[:-1], knots[1:]):
            dx, dy = self._integral(a, b)
            xs.append(xs[-1] + dx)
            ys.append(ys[-1] + dy)
        self._x, self._y = xs, ys

    def _segment(self, s: float) -> int:
        return min(max(bisect.bisect_right(self._seg_start, s) - 1, 0),
                   len(self._seg_start) - 1)

    def curvature(self, s: float) -> float:
        """
        Return the curvature at arc length ``s``.

        :param s: arc length [m].
        :return: curvature [1/m].
        """
        if s < 0.0:
            return self._first_rho
        i = self._segment(s)
        return self._rho0[i] + self._slope[i] * (s - self._seg_start[i])

    def heading(self, s: float) -> float:
        """
        Return the tangent's heading at arc length ``s`` (0 at the start) [rad].

        :param s: arc length [m].
        :return: heading [rad], not wrapped.
        """
        if s < 0.0:
            return self._first_rho * s
        i = self._segment(s)
        u = s - self._seg_start[i]
        return self._seg_heading[i] + self._rho0[i] * u + 0.5 * self._slope[i] * u * u

    def _integral(self, a: float, b: float) -> tuple[float, float]:
        h = b - a
        dx = dy = 0.0
        for node, weight in zip(_NODES, _WEIGHTS):
            theta = self.heading(a + node * h)
            dx += weight * math.cos(theta)
            dy += weight * math.sin(theta)
        return dx * h, dy * h

    def point(self, s: float) -> tuple[float, float]:
        """
        Return the centreline point at arc length ``s``.

        :param s: arc length [m] (up to the laid-out extension).
        :return: ``(x, y)`` [m].
        """
        if s > self._knots[-1]:
            raise ParameterError(f'arc length {s:g} m is past the laid-out road '
                                 f'({self._knots[-1]:g} m); lengthen the scenario road')
        if s < 0.0:
            # the first curvature continued backwards (a circle or a line through 0)
            k = self._first_rho
            if abs(k * s) < 1e-9:
                return s, 0.5 * k * s * s
            return math.sin(k * s) / k, (1.0 - math.cos(k * s)) / k
        j = max(bisect.bisect_right(self._knots, s) - 1, 0)
        dx, dy = self._integral(self._knots[j], s)
        return self._x[j] + dx, self._y[j] + dy

    def pose(self, s: float, lateral: float, relative_yaw: float) -> tuple[float, float, float]:
        """
        Return the global pose ``lateral`` to the left of the centreline at ``s``.

        :param s: arc length [m].
        :param lateral: offset, + left [m].
        :param relative_yaw: yaw relative to the tangent [rad].
        :return: ``(x, y, yaw)``.
        """
        x, y = self.point(s)
        theta = self.heading(s)
        return (x - lateral * math.sin(theta), y + lateral * math.cos(theta),
                theta + relative_yaw)

    def frenet(self, x: float, y: float, yaw: float, s_guess: float) -> Frenet:
        """
        Return the lane coordinates of a global pose (Newton from ``s_guess``).

        The closest point solves ``g(s) = (P - C(s)) . T(s) = 0``; ``g'(s) = -1 +
        rho(s) (P - C(s)) . N(s)``. Started within a few metres (the previous step's
        ``s``), it converges to machine precision in 2-4 iterations.

        :param x: global x of the CG [m].
        :param y: global y of the CG [m].
        :param yaw: vehicle yaw [rad].
        :param s_guess: arc length to start from [m].
        :return: the lane coordinates.
        :raises ParameterError: the projection does not converge (the vehicle is off
            the road by more than a curve radius).
        """
        s = s_guess
        for _ in range(30):
            cx, cy = self.point(s)
            theta = self.heading(s)
            tx, ty = math.cos(theta), math.sin(theta)
            px, py = x - cx, y - cy
            along = px * tx + py * ty
            lateral = -px * ty + py * tx
            slope = 1.0 - self.curvature(s) * lateral
            if slope <= 0.05:
                raise ParameterError(f'lane projection at s = {s:g} m: the vehicle is '
                                     f'{lateral:g} m off a curve of radius '
                                     f'{1.0 / self.curvature(s):g} m')
            step = along / slope
            s += step
            if abs(step) < 1e-10:
                break
        else:
            raise ParameterError(f'lane projection did not converge near s = {s:g} m')
        cx, cy = self.point(s)
        theta = self.heading(s)
        lateral = -(x - cx) * math.sin(theta) + (y - cy) * math.cos(theta)
        return Frenet(s, lateral, wrap(yaw - theta), self.curvature(s))
