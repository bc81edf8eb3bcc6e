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
Conversions of what a vehicle stack publishes: ``nav_msgs/Odometry``, ``nav_msgs/Path``.

Pure functions over message objects (no node, no DDS). REP-105: the odometry pose is the
child frame (``base_link``) in ``header.frame_id`` (``map`` or ``odom``), its twist in the
child frame.
"""

from __future__ import annotations

import math
import struct
from typing import NamedTuple, Sequence

from geometry_msgs.msg import PoseStamped
from lookahead_control.core.samples import quaternion_problem, yaw_to_quaternion
from lookahead_control.ros.conversions import ns_to_stamp, stamp_to_ns
from nav_msgs.msg import Odometry, Path
import numpy as np
import numpy.typing as npt


class OdometrySample(NamedTuple):
    """A planar odometry reading: pose in its frame, body-frame twist."""

    stamp_ns: int
    frame_id: str
    child_frame_id: str
    x: float
    y: float
    yaw: float
    v_x: float
    v_y: float
    yaw_rate: float


def from_odometry(msg: Odometry) -> OdometrySample:
    """
    Convert an odometry message (the planar part).

    :param msg: the message.
    :return: the sample.
    :raises ValueError: a non-finite field or an orientation that is no unit quaternion
        (its norm off 1 by more than ``QUATERNION_NORM_TOLERANCE``); the message names it.
    """
    p, q, t = msg.pose.pose.position, msg.pose.pose.orientation, msg.twist.twist
    values = {'position.x': p.x, 'position.y': p.y, 'orientation.x': q.x,
              'orientation.y': q.y, 'orientation.z': q.z, 'orientation.w': q.w,
              'twist.linear.x': t.linear.x, 'twist.linear.y': t.linear.y,
              'twist.angular.z': t.angular.z}
    for name, value in values.items():
        if not math.isfinite(value):
            raise ValueError(f'odometry {name} is not finite ({value!r})')
    # as the controller reads an Imu's: a norm off 1 by more than the tolerance is a
    # malformed message, not a rotation to normalize (before: any non-zero norm was
    # normalized, so (0, 0, 0.3, 0) read as a yaw of pi)
    problem = quaternion_problem(q.x, q.y, q.z, q.w)
    if problem:
        raise ValueError(f'odometry {problem}')
    norm = math.sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w)
    x, y, z, w = q.x / norm, q.y / norm, q.z / norm, q.w / norm
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return OdometrySample(stamp_to_ns(msg.header.stamp), msg.header.frame_id,
                          msg.child_frame_id, float(p.x), float(p.y), yaw,
                          float(t.linear.x), float(t.linear.y), float(t.angular.z))


def to_odometry(stamp_ns: int, frame_id: str, child_frame_id: str, x: float, y: float,
                yaw: float, v_x: float, v_y: float, yaw_rate: float) -> Odometry:
    """
    Build a planar odometry message.

    :param stamp_ns: the stamp [ns].
    :param frame_id: the pose's frame (``map``, ``odom``).
    :param child_frame_id: the body frame.
    :param x: position x [m].
    :param y: position y [m].
    :param yaw: yaw [rad].
    :param v_x: body longitudinal velocity [m/s].
    :param v_y: body lateral velocity [m/s].
    :param yaw_rate: yaw rate [rad/s].
    :return: the message.
    """
    msg = Odometry()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.header.frame_id = frame_id
    msg.child_frame_id = child_frame_id
    msg.pose.pose.position.x, msg.pose.pose.position.y = float(x), float(y)
    o = msg.pose.pose.orientation
    o.x, o.y, o.z, o.w = yaw_to_quaternion(yaw)
    msg.twist.twist.linear.x, msg.twist.twist.linear.y = float(v_x), float(v_y)
    msg.twist.twist.angular.z = float(yaw_rate)
    return msg


def path_points(msg: Path) -> npt.NDArray[np.float64]:
    """
    Return the ``(x, y)`` of a path's poses, checking that all are in the path's frame.

    :param msg: the path.
    :return: shape (N, 2).
    :raises ValueError: a pose stamped in another frame (the message names it).
    """
    frame = msg.header.frame_id
    poses = msg.poses
    for i, pose in enumerate(poses):
        other = pose.header.frame_id
        if other and other != frame:
            raise ValueError(f'path pose {i} is in frame {other!r}, the path in {frame!r}')
    out = np.empty((len(poses), 2))
    for i, pose in enumerate(poses):
        position = pose.pose.position
        out[i, 0], out[i, 1] = position.x, position.y
    return out


def path_points_cdr(data: bytes) -> tuple[str, npt.NDArray[np.float64]]:
    """
    Return the frame and the ``(x, y)`` of a serialized ``nav_msgs/Path`` (CDR).

    The same result as :func:`path_points` on the deserialized message, without building
    a Python object per pose: rclpy takes about 0.1 ms a pose to deserialize a path (a
    2000-point plan 0.18 s, 100 000 points 12 s on a loaded 2-core machine), which
    stalls every other callback of the node; this reads the bytes directly.

    :param data: the serialized message (4-byte encapsulation header, then the CDR body).
    :return: the path's ``header.frame_id`` and the points, shape (N, 2).
    :raises ValueError: a truncated or malformed message, or a pose stamped in another
        frame (the message names it).
    """
    if len(data) < 4 or data[1] not in (0, 1):
        raise ValueError('path: not a CDR message')
    order = '<' if data[1] == 1 else '>'
    body = memoryview(data)[4:]
    u32, f64 = struct.Struct(order + 'I'), struct.Struct(order + 'dd')

    def string(at: int) -> tuple[str, int]:
        at = (at + 3) & ~3
        (size,) = u32.unpack_from(body, at)
        end = at + 4 + size
        if size == 0 or end > len(body):
            raise ValueError('path: malformed string in the message')
        return bytes(body[at + 4:end - 1]).decode('utf-8', 'replace'), end

    try:
        frame, at = string(8)
        at = (at + 3) & ~3
        (count,) = u32.unpack_from(body, at)
        at += 4
        if count * 64 > len(body) - at:
            raise ValueError(f'path: {count} poses do not fit in {len(data)} bytes')
        out = np.empty((count, 2))
        for i in range(count):
            other, at = string(((at + 3) & ~3) + 8)
            if other and other != frame:
                raise ValueError(f'path pose {i} is in frame {other!r}, the path in '
                                 f'{frame!r}')
            at = (at + 7) & ~7
            out[i] = f64.unpack_from(body, at)
            at += 56
    except struct.error as err:
        raise ValueError(f'path: truncated message ({len(data)} bytes)') from err
    return frame, out


def to_path(stamp_ns: int, frame_id: str, points: Sequence[tuple[float, float, float]]
            ) -> Path:
    """
    Build a path from ``(x, y, heading)`` points.

    :param stamp_ns: the stamp [ns].
    :param frame_id: the frame of the path and its poses.
    :param points: the points.
    :return: the message.
    """
    msg = Path()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.header.frame_id = frame_id
    poses = []
    for x, y, heading in points:
        pose = PoseStamped()
        pose.header.stamp = msg.header.stamp
        pose.header.frame_id = frame_id
        pose.pose.position.x, pose.pose.position.y = float(x), float(y)
        o = pose.pose.orientation
        o.x, o.y, o.z, o.w = yaw_to_quaternion(float(heading))
        poses.append(pose)
    msg.poses = poses
    return msg
