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
in :mod:`~lookahead_control.ros.conversions` give from the decoded message.

Two forms: one message from its bytes, and the columns of many messages at once, read
with numpy from a shared buffer (:mod:`~lookahead_control.bags.mcap_columns`). The column
decoders return a mask of the messages they could read; the others (big endian, cut
short, an unusual layout) are for the caller to decode the general way.
"""

from __future__ import annotations

import math
import struct
from typing import Any, Callable, NamedTuple, Optional

from lookahead_control.core.samples import (curvature_from_points, CurvatureSample,
                                            LateralErrorSample, quaternion_to_yaw, STEERING_JOINT,
                                            VelocitySample, YawSample)
import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]
ByteArray = npt.NDArray[np.uint8]

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


def curvature(data: bytes) -> CurvatureSample:
    """Decode ``geometry_msgs/PolygonStamped`` as :func:`conversions.from_curvature`."""
    sec, nanosec, length = _STAMP.unpack_from(data, 4)
    at = 4 + ((12 + length + 3) & ~3)
    count = _U32.unpack_from(data, at)[0]
    xyz = struct.unpack_from(f'<{3 * count}f', data, at + 4)
    return curvature_from_points(sec * 1_000_000_000 + nanosec,
                                 list(zip(xyz[0::3], xyz[1::3])))


def _joint_names(data: bytes) -> tuple[int, list[str], int]:
    """
    Read the stamp and names of a ``sensor_msgs/JointState``.

    :param data: the CDR bytes.
    :return: stamp [ns], names, and the offset (from the CDR origin, byte 4) of the
        positions' count.
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
    return sec * 1_000_000_000 + nanosec, names, (pos + 3) & ~3


def joint_state(data: bytes) -> tuple[int, list[str], tuple[float, ...]]:
    """
    Decode ``sensor_msgs/JointState`` names and positions.

    :param data: the CDR bytes.
    :return: stamp [ns], names, positions.
    """
    stamp, names, pos = _joint_names(data)
    count = _U32.unpack_from(data, 4 + pos)[0]
    pos = (pos + 4 + 7) & ~7
    positions = struct.unpack_from(f'<{count}d', data, 4 + pos)
    return stamp, names, positions


def steering_index(names: list[str], count: int) -> Optional[int]:
    """
    Return which position of a ``JointState`` is the steering angle.

    :param names: its joint names.
    :param count: its number of positions.
    :return: the index, None without a steering joint (as
        :func:`conversions.from_steering`).
    """
    if STEERING_JOINT in names:
        i = names.index(STEERING_JOINT)
    elif not names and count == 1:
        i = 0
    else:
        return None
    return i if i < count else None


def steering(data: bytes) -> Optional[tuple[int, float]]:
    """Decode a steering ``JointState`` as :func:`conversions.from_steering`."""
    stamp, names, positions = joint_state(data)
    i = steering_index(names, len(positions))
    return None if i is None else (stamp, positions[i])


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


# -- many messages at once -----------------------------------------------------------

MAX_LAYOUTS = 8     # joint-name layouts read as columns; messages beyond: one by one


class Columns(NamedTuple):
    """
    Fields of many messages.

    :param ok: which messages could be read (the others: decode them the general way).
    :param stamp_ns: header stamps [ns].
    :param values: one array per field (NaN where a message lacks it).
    """

    ok: BoolArray
    stamp_ns: IntArray
    values: dict[str, Array]


class _Gather:
    """One scalar per message from a shared buffer, each read checked against its end."""

    def __init__(self, buffer: ByteArray, start: IntArray, length: IntArray) -> None:
        self.buffer, self.start, self.end = buffer, start, start + length
        self.ok = length >= 16
        safe = np.where(self.ok, start, 0)
        self.ok &= (buffer[safe] == 0) & (buffer[safe + 1] == 1)    # little-endian CDR

    def read(self, at: IntArray, dtype: str) -> Any:
        """Return the scalar of type ``dtype`` at ``at`` of each message (0 if not ok)."""
        self.ok &= (at >= self.start) & (at + np.dtype(dtype).itemsize <= self.end)
        return self.peek(at, dtype, self.ok)

    def peek(self, at: IntArray, dtype: str, where: BoolArray) -> Any:
        """Return the scalar at ``at`` of the messages ``where`` holds (checked), else 0."""
        width = np.dtype(dtype).itemsize
        safe = np.where(where, at, 0)
        return self.buffer[safe[:, None] + np.arange(width)].view(dtype)[:, 0]

    def header(self) -> tuple[IntArray, IntArray]:
        """Return the stamps and the offset after ``frame_id`` (from the CDR origin)."""
        sec = self.read(self.start + 4, '<i4').astype(np.int64)
        nanosec = self.read(self.start + 8, '<u4').astype(np.int64)
        after = 12 + self.read(self.start + 12, '<u4').astype(np.int64)
        self.ok &= self.start + 4 + after <= self.end
        return sec * 1_000_000_000 + nanosec, after

    def body(self, after: IntArray) -> IntArray:
        """Return where an 8-aligned body after the header starts, in the buffer."""
        return self.start + 4 + ((after + 7) & ~7)

    def doubles(self, at: IntArray, names: tuple[str, ...]) -> dict[str, Array]:
        """Return consecutive float64 fields from ``at`` on, by name."""
        return {name: self.read(at + 8 * i, '<f8') for i, name in enumerate(names)}


def lateral_error_columns(buffer: ByteArray, start: IntArray, length: IntArray) -> Columns:
    """Decode many ``PointStamped`` as :func:`lateral_error` (fields of the sample)."""
    g = _Gather(buffer, start, length)
    stamp, after = g.header()
    values = g.doubles(g.body(after), ('distance', 'value'))
    return Columns(g.ok, stamp, values)


def velocity_columns(buffer: ByteArray, start: IntArray, length: IntArray) -> Columns:
    """Decode many ``TwistStamped`` as :func:`velocity` (fields of the sample)."""
    g = _Gather(buffer, start, length)
    stamp, after = g.header()
    values = g.doubles(g.body(after), ('v_x', 'v_y'))
    return Columns(g.ok, stamp, values)


def yaw_columns(buffer: ByteArray, start: IntArray, length: IntArray) -> Columns:
    """Decode many ``Imu`` as :func:`yaw` (fields of the sample)."""
    g = _Gather(buffer, start, length)
    stamp, after = g.header()
    at = g.body(after)
    q = g.doubles(at, ('x', 'y', 'z', 'w'))
    rate = g.read(at + 8 * 15, '<f8')
    accel = g.read(at + 8 * 25, '<f8')
    # math.atan2 one by one: numpy's arctan2 differs in the last bit for about 2 % of
    # inputs, and a re-run must reproduce the node's commands exactly
    yaw_ = np.array([quaternion_to_yaw(*xyzw) for xyzw in zip(
        q['x'].tolist(), q['y'].tolist(), q['z'].tolist(), q['w'].tolist())], dtype=float)
    return Columns(g.ok, stamp, {'relative_yaw': yaw_, 'yaw_rate': rate,
                                 'accel_x': accel})


def _joint_layouts(g: _Gather, after: IntArray
                   ) -> list[tuple[BoolArray, list[str], IntArray, IntArray]]:
    """
    Group ``JointState`` messages by their joint names.

    :param g: the messages.
    :param after: the offset after ``frame_id`` of each.
    :return: per layout: its messages, their names, where their positions start in the
        buffer and how many there are. Messages in none of them are marked not ok.
    """
    names_at = (after + 3) & ~3                     # from the CDR origin
    todo = g.ok.copy()
    layouts: list[tuple[BoolArray, list[str], IntArray, IntArray]] = []
    while todo.any() and len(layouts) < MAX_LAYOUTS:
        first = int(np.argmax(todo))
        data = g.buffer[g.start[first]:g.end[first]].tobytes()
        try:
            _, names, count_at = _joint_names(data)
        except (struct.error, UnicodeDecodeError):
            todo[first] = g.ok[first] = False
            continue
        block = np.frombuffer(data[4 + names_at[first]:4 + count_at], dtype=np.uint8)
        same = todo & (names_at % 8 == names_at[first] % 8)
        same &= g.start + 4 + names_at + block.size + 4 <= g.end
        idx = np.nonzero(same)[0]
        at = g.start[idx] + 4 + names_at[idx]
        same[idx[~(g.buffer[at[:, None] + np.arange(block.size)] == block).all(axis=1)]] = False
        # (the count's 4 bytes are in every message of the layout: checked above)
        count = g.peek(g.start + 4 + names_at + block.size, '<u4', same).astype(np.int64)
        positions = g.start + 4 + ((names_at + block.size + 4 + 7) & ~7)
        same &= positions + 8 * count <= g.end
        if not same[first]:         # its positions are cut short
            todo[first] = g.ok[first] = False
            continue
        layouts.append((same, names, positions, count))
        todo &= ~same
    g.ok &= ~todo
    return layouts


def named_columns(buffer: ByteArray, start: IntArray, length: IntArray) -> Columns:
    """Decode many debug / ground-truth ``JointState`` as :func:`named_values`."""
    g = _Gather(buffer, start, length)
    stamp, after = g.header()
    values: dict[str, Array] = {}
    for same, names, positions, count in _joint_layouts(g, after):
        for j, name in enumerate(names):
            column = values.setdefault(name, np.full(start.size, math.nan))
            has = same & (count > j)
            column[has] = g.buffer[positions[has, None] + 8 * j + np.arange(8)].view('<f8')[:, 0]
    return Columns(g.ok, stamp, values)


def steering_columns(buffer: ByteArray, start: IntArray, length: IntArray
                     ) -> tuple[Columns, BoolArray]:
    """
    Decode many steering ``JointState`` as :func:`steering`.

    :param buffer: the shared buffer.
    :param start: where each message starts.
    :param length: its length.
    :return: the columns (``angle``) and which messages hold a steering angle.
    """
    g = _Gather(buffer, start, length)
    stamp, after = g.header()
    angle = np.full(start.size, math.nan)
    present = np.zeros(start.size, dtype=bool)
    for same, names, positions, count in _joint_layouts(g, after):
        if STEERING_JOINT in names:
            i = names.index(STEERING_JOINT)
            has = same & (count > i)
        elif not names:
            i, has = 0, same & (count == 1)
        else:
            continue
        angle[has] = g.buffer[positions[has, None] + 8 * i + np.arange(8)].view('<f8')[:, 0]
        present |= has
    return Columns(g.ok, stamp, {'angle': angle}), present & g.ok


COLUMN_DECODERS: dict[str, Callable[[ByteArray, IntArray, IntArray], Columns]] = {
    'geometry_msgs/msg/PointStamped': lateral_error_columns,
    'sensor_msgs/msg/Imu': yaw_columns,
    'geometry_msgs/msg/TwistStamped': velocity_columns,
}
