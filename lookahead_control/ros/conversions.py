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
Conversions between the topic contract's messages and core types.

Pure functions over message objects: no node, no DDS. The contract (README, "Topic
contract") in short, REP-103 signs and SI units, vehicle frame at the CG:

- ``lateral_error`` ``geometry_msgs/PointStamped``: ``point.x`` distance ahead of the
  CG at which the error is measured, ``point.y`` lateral offset of that point from the
  lane centre (+ left).
- ``yaw`` ``sensor_msgs/Imu``: ``orientation`` the yaw relative to the lane tangent
  (rotation about z), ``angular_velocity.z`` the yaw rate, ``linear_acceleration.x``
  the body-frame longitudinal acceleration.
- ``velocity`` ``geometry_msgs/TwistStamped``: ``linear.x`` v_x, ``linear.y`` v_y.
- ``road_curvature`` ``geometry_msgs/PolygonStamped``: points ``(x, y)`` = (distance
  ahead of the CG, curvature + left); one point means curvature at the CG only.
- output ``steering`` ``sensor_msgs/JointState``: ``position[0]`` the front-wheel
  angle (+ left), ``velocity[0]`` its rate; the stamp of the measurement it answers.
"""

from __future__ import annotations

import struct
from typing import Sequence

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point32, PointStamped, PolygonStamped, TwistStamped
from lookahead_control.core.samples import (curvature_from_points, CurvatureSample,
                                            LateralErrorSample, quaternion_problem,
                                            quaternion_to_yaw, STEERING_JOINT, VelocitySample,
                                            yaw_to_quaternion, YawSample)
from sensor_msgs.msg import Imu, JointState


#: the controller's status on ``/diagnostics`` before it carried the node's name
LEGACY_STATUS_NAME = 'lookahead_control: controller'


def controller_status_name(node: str) -> str:
    """
    Return the name of a controller's status on ``/diagnostics``: its node's full name.

    Several controllers (vehicles in namespaces) publish on the one ``/diagnostics``; the
    name tells whose status it is, in the ``<package>: <node>`` form of a status name.

    :param node: the node's fully qualified name (``/car_b/controller``).
    :return: e.g. ``lookahead_control: /car_b/controller``.
    """
    return f'lookahead_control: {node}'


def stamp_to_ns(stamp: Time) -> int:
    """
    Return a ``builtin_interfaces/Time`` as integer nanoseconds.

    :param stamp: the stamp.
    :return: nanoseconds since the epoch of its clock.
    """
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def ns_to_stamp(ns: int) -> Time:
    """
    Return integer nanoseconds as a ``builtin_interfaces/Time``.

    :param ns: nanoseconds (>= 0).
    :return: the stamp.
    """
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def from_lateral_error(msg: PointStamped) -> LateralErrorSample:
    """
    Convert a ``lateral_error`` message.

    :param msg: the message.
    :return: the sample.
    """
    return LateralErrorSample(stamp_to_ns(msg.header.stamp), float(msg.point.x),
                              float(msg.point.y))


def from_yaw(msg: Imu) -> YawSample:
    """
    Convert a ``yaw`` message.

    :param msg: the message.
    :return: the sample.
    :raises ValueError: the orientation is no unit quaternion (a malformed message).
    """
    q = msg.orientation
    problem = quaternion_problem(q.x, q.y, q.z, q.w)
    if problem is not None:
        raise ValueError(problem)
    return YawSample(stamp_to_ns(msg.header.stamp), quaternion_to_yaw(q.x, q.y, q.z, q.w),
                     float(msg.angular_velocity.z), float(msg.linear_acceleration.x))


def from_velocity(msg: TwistStamped) -> VelocitySample:
    """
    Convert a ``velocity`` message.

    :param msg: the message.
    :return: the sample.
    """
    return VelocitySample(stamp_to_ns(msg.header.stamp), float(msg.twist.linear.x),
                          float(msg.twist.linear.y))


def from_curvature(msg: PolygonStamped) -> CurvatureSample:
    """
    Convert a ``road_curvature`` message: curvature at the CG and its slope.

    The points are (distance ahead, curvature). The curvature at the CG is interpolated
    at distance 0 (the nearest point if all lie ahead or behind); the slope is that of
    the first segment that starts at or ahead of the CG.

    :param msg: the message.
    :return: the sample (curvature NaN if the polygon is empty: no curvature, refused).
    """
    return curvature_from_points(stamp_to_ns(msg.header.stamp),
                                 [(float(p.x), float(p.y)) for p in msg.polygon.points])


def to_lateral_error(stamp_ns: int, frame_id: str, distance: float,
                     value: float) -> PointStamped:
    """
    Build a ``lateral_error`` message.

    :param stamp_ns: measurement time [ns].
    :param frame_id: the vehicle frame.
    :param distance: distance ahead of the CG of the measurement [m].
    :param value: lateral error at that point (+ left) [m].
    :return: the message.
    """
    msg = PointStamped()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.header.frame_id = frame_id
    msg.point.x = float(distance)
    msg.point.y = float(value)
    return msg


def to_yaw(stamp_ns: int, frame_id: str, relative_yaw: float, yaw_rate: float,
           accel_x: float) -> Imu:
    """
    Build a ``yaw`` message.

    :param stamp_ns: measurement time [ns].
    :param frame_id: the vehicle frame.
    :param relative_yaw: yaw relative to the lane tangent [rad].
    :param yaw_rate: yaw rate [rad/s].
    :param accel_x: body longitudinal acceleration [m/s^2].
    :return: the message.
    """
    msg = Imu()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.header.frame_id = frame_id
    qx, qy, qz, qw = yaw_to_quaternion(relative_yaw)
    msg.orientation.x, msg.orientation.y = qx, qy
    msg.orientation.z, msg.orientation.w = qz, qw
    msg.angular_velocity.z = float(yaw_rate)
    msg.linear_acceleration.x = float(accel_x)
    return msg


def to_velocity(stamp_ns: int, frame_id: str, v_x: float, v_y: float,
                yaw_rate: float) -> TwistStamped:
    """
    Build a ``velocity`` message.

    :param stamp_ns: measurement time [ns].
    :param frame_id: the vehicle frame.
    :param v_x: longitudinal speed [m/s].
    :param v_y: lateral speed [m/s].
    :param yaw_rate: yaw rate [rad/s] (informative; the controller reads ``yaw``).
    :return: the message.
    """
    msg = TwistStamped()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.header.frame_id = frame_id
    msg.twist.linear.x = float(v_x)
    msg.twist.linear.y = float(v_y)
    msg.twist.angular.z = float(yaw_rate)
    return msg


def to_curvature(stamp_ns: int, frame_id: str,
                 profile: Sequence[tuple[float, float]]) -> PolygonStamped:
    """
    Build a ``road_curvature`` message from (distance ahead, curvature) pairs.

    :param stamp_ns: measurement time [ns].
    :param frame_id: the vehicle frame.
    :param profile: the preview, starting at the CG (distance 0).
    :return: the message.
    """
    msg = PolygonStamped()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.header.frame_id = frame_id
    msg.polygon.points = [Point32(x=float(x), y=float(k), z=0.0) for x, k in profile]
    return msg


def to_steering(stamp_ns: int, angle: float, rate: float) -> JointState:
    """
    Build a ``steering`` message.

    :param stamp_ns: stamp of the measurement this command answers [ns].
    :param angle: front-wheel angle (+ left) [rad].
    :param rate: steering rate [rad/s].
    :return: the message.
    """
    msg = JointState()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.name = [STEERING_JOINT]
    msg.position = [float(angle)]
    msg.velocity = [float(rate)]
    return msg


def from_steering(msg: JointState) -> tuple[int, float] | None:
    """
    Return ``(stamp_ns, angle)`` of a ``steering`` message, None without the joint.

    :param msg: the message.
    :return: stamp and angle, or None.
    """
    names = list(msg.name)
    if STEERING_JOINT in names:
        i = names.index(STEERING_JOINT)
    elif not names and len(msg.position) == 1:
        i = 0
    else:
        return None
    if i >= len(msg.position):
        return None
    return stamp_to_ns(msg.header.stamp), float(msg.position[i])


def to_named_values(stamp_ns: int, values: Sequence[tuple[str, float]]) -> JointState:
    """
    Build a stamped list of named values (debug and ground-truth topics).

    :param stamp_ns: the stamp [ns].
    :param values: (name, value) pairs.
    :return: a ``JointState`` with the names and the values as positions.
    """
    msg = JointState()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.name = [n for n, _ in values]
    msg.position = [float(v) for _, v in values]
    return msg


def from_named_values(msg: JointState) -> dict[str, float]:
    """
    Return the named values of a debug or ground-truth message.

    :param msg: the message.
    :return: name -> value.
    """
    return dict(zip(msg.name, (float(v) for v in msg.position)))


_CDR_HEAD = {'<': struct.Struct('<iII'), '>': struct.Struct('>iII')}
_CDR_U32 = {'<': struct.Struct('<I'), '>': struct.Struct('>I')}


def curvature_header(data: bytes) -> tuple[int, str, int, int, str]:
    """
    Read a serialized ``road_curvature`` message up to its points, not the points.

    A ``PolygonStamped`` of n points costs about 3 us a point to deserialize in
    Python (30 ms for 10 000); its header and n cost the same for any n, so a node can
    refuse a polygon that is too long before paying for it.

    :param data: the CDR bytes (XCDR1, either endianness).
    :return: stamp [ns], frame_id, number of points, offset of the first point, and the
        byte order (``<`` or ``>``) for :func:`curvature_points`.
    :raises struct.error: the data is cut short.
    :raises UnicodeDecodeError: the frame_id is not UTF-8.
    """
    order = '<' if data[1] & 1 else '>'        # encapsulation 0x0001: CDR little endian
    sec, nanosec, length = _CDR_HEAD[order].unpack_from(data, 4)
    if length == 0 or 16 + length > len(data):
        raise struct.error(f'frame_id of {length} bytes in a message of {len(data)}')
    frame = bytes(data[16:15 + length]).decode('utf-8')   # without the terminating NUL
    at = 4 + ((12 + length + 3) & ~3)          # 4-aligned after the CDR origin (byte 4)
    count = _CDR_U32[order].unpack_from(data, at)[0]
    return sec * 1_000_000_000 + nanosec, frame, count, at + 4, order


def curvature_points(data: bytes, count: int, at: int, order: str
                     ) -> list[tuple[float, float]]:
    """
    Read the (x, y) of ``count`` ``Point32`` from a serialized ``PolygonStamped``.

    :param data: the CDR bytes.
    :param count: number of points (from :func:`curvature_header`).
    :param at: offset of the first point.
    :param order: byte order.
    :return: the points, as ``from_curvature`` reads them.
    :raises struct.error: the data is cut short.
    """
    values = struct.unpack_from(f'{order}{3 * count}f', data, at)
    return list(zip(values[0::3], values[1::3]))
