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
What a controller told on ``/diagnostics`` during a recorded run, read from its bag.

No ROS here: the bag's messages through the rosbags type store. The controller's status
is the one named :func:`~lookahead_control.ros.conversions.controller_status_name` of
its node (bags recorded before the name carried the node: ``lookahead_control:
controller``, taken for ``/controller``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
import struct
from typing import Any, Optional

from lookahead_control.bags.mcap_columns import read_columns
from lookahead_control.bags.rosbag_io import typestore
from lookahead_control.core.config import ConfigError
from lookahead_control.ros import conversions as conv

DIAGNOSTICS = '/diagnostics'
DIAGNOSTIC_ARRAY = 'diagnostic_msgs/msg/DiagnosticArray'


@dataclass(frozen=True)
class StatusReport:
    """
    One status of the controller on ``/diagnostics``.

    :param stamp_ns: the array's header stamp (the node's clock: sim time under
        ``use_sim_time``) [ns].
    :param recv_ns: when the recorder received it [ns].
    :param level: 0 OK, 1 WARN, 2 ERROR, 3 STALE.
    :param message: its reasons, ``; `` between them (``ok``: none).
    :param values: its key-value pairs (the counters), in order.
    """

    stamp_ns: int
    recv_ns: int
    level: int
    message: str
    values: tuple[tuple[str, str], ...]


def controller_reports(bag: Path, node: str, store: Any = None
                       ) -> Optional[list[StatusReport]]:
    """
    Return a controller's statuses recorded on ``/diagnostics``, in receive order.

    :param bag: the bag directory.
    :param node: the controller's fully qualified name.
    :param store: the type store (None: the Jazzy one).
    :return: the statuses; None: the bag has no ``/diagnostics`` of the standard type.
    :raises ConfigError: a message is corrupt.
    """
    names = {conv.controller_status_name(node)}
    if node == '/controller':
        names.add(conv.LEGACY_STATUS_NAME)
    store = store or typestore()
    found: list[tuple[int, int, StatusReport]] = []
    seen = False
    for _, msgtype, raw in read_columns(bag, [DIAGNOSTICS]):
        if msgtype != DIAGNOSTIC_ARRAY:
            continue
        seen = True
        for i in range(raw.start.size):
            try:
                msg = store.deserialize_cdr(raw.data(i), msgtype)
            except (ValueError, AssertionError, IndexError, KeyError, struct.error,
                    UnicodeDecodeError) as err:
                raise ConfigError(f'{bag}: corrupt {DIAGNOSTICS} message: {err}') from err
            stamp = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
            for status in msg.status:
                if status.name in names:
                    found.append((int(raw.recv_ns[i]), int(raw.order[i]), StatusReport(
                        stamp, int(raw.recv_ns[i]), int(status.level), str(status.message),
                        tuple((str(kv.key), str(kv.value)) for kv in status.values))))
    if not seen:
        return None
    return [report for _, _, report in sorted(found, key=lambda f: (f[0], f[1]))]
