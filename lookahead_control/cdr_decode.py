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
Direct decoding of the contract messages from their CDR bytes, for reading long bags.

A general deserializer builds every field of every message (about 12 us each); the
analysis needs a few numbers. These read them at their offsets (XCDR1, little endian,
alignment counted after the 4-byte encapsulation header) and give what the converters
in :mod:`~lookahead_control.conversions` give from the decoded message. Anything else
(big endian, unknown type) returns None and the caller decodes the general way.
"""

from __future__ import annotations

import struct
from typing import Any, Callable, Optional

from lookahead_control.conversions import (LateralErrorSample, quaternion_to_yaw,
                                           STEERING_JOINT, VelocitySample, YawSample)

_STAMP = struct.Struct('<iII')      # sec, nanosec, frame_id length
_D2 = struct.Struct('<2d')
_D4 = struct.Struct('<4d')
_U32 = struct.Struct('<I')
_D = struct.Struct('<d')


def _header(data: bytes) -> tuple[int, int]:
    """Return the stamp [ns] and the body offset (8-aligned) after the header."""
    sec, nanosec, length = _STAMP.unpack_from(data, 4)
    body = 12 + length                          # relative to the CDR origin (byte 4)
    return sec * 1_000_000_000 + nanosec, 4 + ((body + 7) & ~7)


def lateral_error(data: bytes) -> LateralErrorSample:
    """Decode ``geometry_msgs/PointStamped`` as :func:`conversions.from_lateral_error`."""
    stamp, at = _header(data)
    x, y = _D2.unpack_from(data, at)
    return LateralErrorSample(stamp, x, y)


def yaw(data: bytes) -> YawSample:
    """Decode ``sensor_msgs/Imu`` as :func:`conversions.from_yaw`."""
    stamp, at = _header(data)
    qx, qy, qz, qw = _D4.unpack_from(data, at)
    # orientation (4), its covariance (9), angular_velocity (3), its covariance (9)
    rate = _D.unpack_from(data, at + 8 * 15)[0]
    accel = _D.unpack_from(data, at + 8 * 25)[0]
    return YawSample(stamp, quaternion_to_yaw(qx, qy, qz, qw), rate, accel)


def velocity(data: bytes) -> VelocitySample:
    """Decode ``geometry_msgs/TwistStamped`` as :func:`conversions.from_velocity`."""
    stamp, at = _header(data)
    v_x, v_y = _D2.unpack_from(data, at)
    return VelocitySample(stamp, v_x, v_y)


def joint_state(data: bytes) -> tuple[int, list[str], tuple[float, ...]]:
    """
    Decode ``sensor_msgs/JointState`` names and positions.

    :param data: the CDR bytes.
    :return: stamp [ns], names, positions.
    """
    sec, nanosec, length = _STAMP.unpack_from(data, 4)
    origin = 4
    pos = 12 + length
    pos = (pos + 3) & ~3
    count = _U32.unpack_from(data, origin + pos)[0]
    pos += 4
    names = []
    for _ in range(count):
        pos = (pos + 3) & ~3
        size = _U32.unpack_from(data, origin + pos)[0]
        names.append(data[origin + pos + 4:origin + pos + 4 + size - 1].decode())
        pos += 4 + size
    pos = (pos + 3) & ~3
    count = _U32.unpack_from(data, origin + pos)[0]
    pos = (pos + 4 + 7) & ~7
    positions = struct.unpack_from(f'<{count}d', data, origin + pos)
    return sec * 1_000_000_000 + nanosec, names, positions


def steering(data: bytes) -> Optional[tuple[int, float]]:
    """Decode a steering ``JointState`` as :func:`conversions.from_steering`."""
    stamp, names, positions = joint_state(data)
    if STEERING_JOINT in names:
        i = names.index(STEERING_JOINT)
    elif not names and len(positions) == 1:
        i = 0
    else:
        return None
    return (stamp, positions[i]) if i < len(positions) else None


def named_values(data: bytes) -> tuple[int, dict[str, float]]:
    """Decode a debug / ground-truth ``JointState`` into its stamp and named values."""
    stamp, names, positions = joint_state(data)
    return stamp, dict(zip(names, positions))


DECODERS: dict[str, Callable[[bytes], Any]] = {
    'geometry_msgs/msg/PointStamped': lateral_error,
    'sensor_msgs/msg/Imu': yaw,
    'geometry_msgs/msg/TwistStamped': velocity,
}


def little_endian(data: bytes) -> bool:
    """Return True for plain little-endian CDR (what these decoders read)."""
    return len(data) >= 16 and data[0] == 0 and data[1] == 1
