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
Sample types: the controller core's view of one measurement, free of ROS.

Each sample carries the stamp of the message it came from (integer nanoseconds) and the
values in SI units, REP-103 signs. :mod:`lookahead_control.ros.conversions` builds them
from messages; :mod:`lookahead_control.bags.cdr_decode` builds them from raw bag bytes.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Optional, Sequence

STEERING_JOINT = 'front_wheel_steering'


class LateralErrorSample(NamedTuple):
    """Lateral error ``value`` [m] measured ``distance`` [m] ahead of the CG."""

    stamp_ns: int
    distance: float
    value: float


class YawSample(NamedTuple):
    """Relative yaw [rad], yaw rate [rad/s], body longitudinal acceleration [m/s^2]."""

    stamp_ns: int
    relative_yaw: float
    yaw_rate: float
    accel_x: float


class VelocitySample(NamedTuple):
    """Longitudinal and lateral body velocity [m/s]."""

    stamp_ns: int
    v_x: float
    v_y: float


class CurvatureSample(NamedTuple):
    """
    Curvature at the CG [1/m], its slope along the road [1/m^2], and the points ahead.

    ``ahead`` holds the polygon's ``(distance ahead [m], curvature [1/m])`` points sorted
    by distance, one per distance (of points at the same distance the one of largest
    |curvature|, the first of equal ones): the curvature preview the laws get (empty: none
    was sent). If a point is not finite, ``ahead`` holds every point as sent, in the
    message's order, so that the safety check refuses the message and names the point.
    """

    stamp_ns: int
    rho: float
    slope: float
    ahead: tuple[tuple[float, float], ...] = ()


def yaw_to_quaternion(yaw: float) -> tuple[float, float, float, float]:
    """
    Return the quaternion ``(x, y, z, w)`` of a rotation by ``yaw`` about z.

    :param yaw: angle [rad].
    :return: the quaternion.
    """
    return 0.0, 0.0, math.sin(0.5 * yaw), math.cos(0.5 * yaw)


#: how far an orientation's norm may be from 1: a float32 quaternion is within 1e-7; a
#: zero one, or one of norm 0.9, is a broken publisher (0.9 for a yaw of 0.1 rad read as
#: 0.081 rad; (0, 0, 0, 0) as 0; dev-probe55)
QUATERNION_NORM_TOLERANCE = 0.01


def quaternion_problem(x: float, y: float, z: float, w: float) -> Optional[str]:
    """
    Return why a quaternion is no orientation, or None.

    :param x: quaternion x.
    :param y: quaternion y.
    :param z: quaternion z.
    :param w: quaternion w.
    :return: the reason (not finite, or its norm off 1 by more than the tolerance).
    """
    if _unit(math.sqrt(x * x + y * y + z * z + w * w)):
        return None
    if not all(math.isfinite(c) for c in (x, y, z, w)):
        return f'orientation ({x}, {y}, {z}, {w}) is not finite'
    # without overflow: (1e200, 0, 0, 0) has norm 1e200, not inf (dev-probe61)
    norm = math.hypot(x, y, z, w)
    return (f'orientation ({x:.6g}, {y:.6g}, {z:.6g}, {w:.6g}) has norm {norm:.6g}, not 1 '
            f'(within {QUATERNION_NORM_TOLERANCE:g})')


def _unit(norm: float) -> bool:
    """Return True if a quaternion of this norm is an orientation (NaN: no)."""
    # a norm of 0.99 or 1.01 is within the tolerance, whose rounding (|0.99 - 1| is
    # 0.010000000000000009) refused it (dev-probe61)
    return abs(norm - 1.0) <= QUATERNION_NORM_TOLERANCE + 1e-12


def quaternion_to_yaw(x: float, y: float, z: float, w: float) -> float:
    """
    Return the rotation about z of a unit quaternion (REP-103, counter-clockwise +).

    :param x: quaternion x.
    :param y: quaternion y.
    :param z: quaternion z.
    :param w: quaternion w.
    :return: yaw [rad] in (-pi, pi]; NaN if it is no orientation
        (:func:`quaternion_problem`), which the safety layer refuses.
    """
    squared = x * x + y * y + z * z + w * w
    norm = math.sqrt(squared)
    if not _unit(norm):
        return math.nan
    if abs(squared - 1.0) > 1e-12:
        # the formula needs a unit norm: off it by 1 % read a yaw of 1 rad 15 mrad off
        # (dev-probe56); a unit quaternion in doubles is taken as it is (exact re-runs)
        x, y, z, w = x / norm, y / norm, z / norm, w / norm
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def one_per_distance(polygon: Sequence[tuple[float, float]]
                     ) -> list[tuple[float, float]]:
    """
    Return finite (distance, curvature) points sorted by distance, one per distance.

    Of points at the same distance the one of largest |curvature| is kept (the first of
    equal ones): the sharper curve, mirror-symmetric, and a check of the kept points'
    |curvature| bounds every point's.

    :param polygon: the points (finite).
    :return: the points.
    """
    points: list[tuple[float, float]] = []
    for p in sorted(polygon, key=lambda q: q[0]):      # stable: message order for ties
        if points and p[0] == points[-1][0]:
            if abs(p[1]) > abs(points[-1][1]):
                points[-1] = p
        else:
            points.append(p)
    return points


def curvature_from_points(stamp: int, polygon: Sequence[tuple[float, float]]
                          ) -> CurvatureSample:
    """
    Return the curvature sample of (distance ahead, curvature) points.

    As :func:`lookahead_control.ros.conversions.from_curvature` describes it.

    :param stamp: the stamp [ns].
    :param polygon: the points.
    :return: the sample.
    """
    raw = [(x, k) for x, k in polygon]
    for x, k in raw:
        if not (math.isfinite(x) and math.isfinite(k)):    # no point dropped unchecked
            finite = [(a, b) for a, b in raw if math.isfinite(a) and math.isfinite(b)]
            return curvature_from_points(stamp, finite)._replace(ahead=tuple(raw))
    points = one_per_distance(raw)
    ahead = tuple(points)
    if not points:
        # no curvature (not 0): the safety layer refuses it, in a re-run from a bag as
        # in the node (check_points)
        return CurvatureSample(stamp, math.nan, 0.0, ahead)
    if points[-1][0] <= 0.0:
        return CurvatureSample(stamp, points[-1][1], 0.0, ahead)
    i = 0
    while i + 2 < len(points) and points[i + 1][0] <= 0.0:
        i += 1
    if len(points) == 1:
        return CurvatureSample(stamp, points[0][1], 0.0, ahead)
    (x0, k0), (x1, k1) = points[i], points[i + 1]
    slope = (k1 - k0) / (x1 - x0)
    return CurvatureSample(stamp, k0 + slope * max(0.0 - x0, 0.0), slope, ahead)
