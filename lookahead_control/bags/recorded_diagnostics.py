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
its node. Bags recorded before the name carried the node have ``lookahead_control:
controller``: taken for the node when the bag records no other controller. A corrupt
message is skipped and counted (the run's other data does not depend on it), a status
recorded twice (two recorders) counted once.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
import struct
from typing import Any, Collection

from lookahead_control.bags.mcap_columns import read_columns
from lookahead_control.bags.rosbag_io import typestore
from lookahead_control.ros import conversions as conv
from rosbags.serde import SerdeError

DIAGNOSTICS = '/diagnostics'
DIAGNOSTIC_ARRAY = 'diagnostic_msgs/msg/DiagnosticArray'
#: [ns] a status received twice within this, with the same stamp and text, is one status
#: recorded twice
TWIN_NS = 100_000_000
_CORRUPT = (SerdeError, ValueError, AssertionError, IndexError, KeyError, struct.error,
            UnicodeDecodeError, OverflowError)


@dataclass(frozen=True)
class StatusReport:
    """
    One status of the controller on ``/diagnostics``.

    :param stamp_ns: the array's header stamp (the node's clock: sim time under
        ``use_sim_time``) [ns].
    :param recv_ns: when the recorder received it [ns].
    :param level: 0 OK, 1 WARN, 2 ERROR, 3 STALE (the byte as sent, 0-255).
    :param message: its reasons, ``; `` between them (``ok``: none).
    :param values: its key-value pairs (the counters), in order.
    """

    stamp_ns: int
    recv_ns: int
    level: int
    message: str
    values: tuple[tuple[str, str], ...]


@dataclass
class RecordedDiagnostics:
    """
    A controller's statuses in a bag, and what kept others out.

    :param reports: its statuses, in the order received (a status recorded twice once).
    :param corrupt: ``/diagnostics`` messages that could not be read (skipped).
    :param wrong_type: the type of ``/diagnostics`` when it is not a DiagnosticArray.
    :param legacy_unattributed: statuses with the name from before it carried the node,
        left out because the bag records other controllers than this one (whose they
        are is not known).
    :param duplicates: statuses recorded more than once, counted once.
    :param topic: the topic they were read from.
    """

    reports: list[StatusReport] = field(default_factory=list)
    corrupt: int = 0
    wrong_type: str = ''
    legacy_unattributed: int = 0
    duplicates: int = 0
    topic: str = DIAGNOSTICS

    def notes(self) -> list[str]:
        """
        Return what a report says of the reading: skipped, left out, counted once.

        :return: one sentence per thing to say (empty: nothing).
        """
        out = []
        if self.wrong_type:
            out.append(f'{self.topic} has type {self.wrong_type}, not {DIAGNOSTIC_ARRAY}: '
                       'not read')
        if self.corrupt:
            out.append(f'{self.corrupt} corrupt {self.topic} message(s) skipped')
        if self.legacy_unattributed:
            out.append(f'{self.legacy_unattributed} status(es) named '
                       f"'{conv.LEGACY_STATUS_NAME}' (before the name carried the node) "
                       'left out: the bag records other controllers too, whose they are is '
                       'not known')
        if self.duplicates:
            out.append(f'{self.duplicates} status(es) recorded twice (two recorders?) '
                       'counted once')
        return out


def controller_reports(bag: Path, node: str, controllers: Collection[str] = (),
                       store: Any = None, topic: str = DIAGNOSTICS) -> RecordedDiagnostics:
    """
    Return a controller's statuses recorded on ``/diagnostics``.

    Only messages whose bytes hold the status's name are decoded (a vehicle's
    ``/diagnostics`` carries every node's).

    :param bag: the bag directory.
    :param node: the controller's fully qualified name.
    :param controllers: the controllers whose parameters the bag recorded (the old name
        is this node's only when there is no other).
    :param store: the type store (None: the Jazzy one).
    :param topic: the topic of the statuses (``/diagnostics`` unless remapped).
    :return: the statuses, and what was skipped.
    """
    name = conv.controller_status_name(node)
    legacy_ok = set(controllers) <= {node}
    wanted = (name.encode(), conv.LEGACY_STATUS_NAME.encode())
    store = store or typestore()
    out = RecordedDiagnostics(topic=topic)
    found: list[tuple[int, int, StatusReport]] = []
    seen: dict[tuple[Any, ...], list[int]] = {}
    for _, msgtype, raw in read_columns(bag, [topic]):
        if msgtype != DIAGNOSTIC_ARRAY:
            out.wrong_type = msgtype
            continue
        for i in range(raw.start.size):
            data = raw.data(i)
            if not any(w in data for w in wanted):
                continue
            try:
                msg = store.deserialize_cdr(data, msgtype)
                stamp = int(msg.header.stamp.sec) * 1_000_000_000 + int(
                    msg.header.stamp.nanosec)
            except _CORRUPT:
                out.corrupt += 1
                continue
            for status in msg.status:
                if status.name == conv.LEGACY_STATUS_NAME and not legacy_ok:
                    out.legacy_unattributed += 1
                    continue
                if status.name not in (name, conv.LEGACY_STATUS_NAME):
                    continue
                report = StatusReport(
                    stamp, int(raw.recv_ns[i]), int(status.level) & 0xFF, str(status.message),
                    tuple((str(kv.key), str(kv.value)) for kv in status.values))
                # the same status from two recorders: the same stamp and text, received
                # together (the node's next status, even with a stopped clock, comes a
                # diagnostics period later)
                key = (report.stamp_ns, report.level, report.message, report.values)
                if any(abs(report.recv_ns - recv) < TWIN_NS for recv in seen.get(key, ())):
                    out.duplicates += 1
                    continue
                seen.setdefault(key, []).append(report.recv_ns)
                found.append((int(raw.recv_ns[i]), int(raw.order[i]), report))
    out.reports = [report for _, _, report in sorted(found, key=lambda f: (f[0], f[1]))]
    return out
