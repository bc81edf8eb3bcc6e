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

"""Benchmark 6: analyze on a synthetic 1 h, 100 Hz bag, next to reading its records."""

from __future__ import annotations

import math
from pathlib import Path
import shutil
import struct
import subprocess
import sys
import tempfile
import time
from typing import Any, Callable

from bench.common import median, Result, RESULTS, ROOT
from lookahead_control.bags.rosbag_io import BagWriter, qos_from_ints, serialize_cdr, typestore
from lookahead_control.ros import conversions as conv

TOPICS = {'/lateral_error': 'geometry_msgs/msg/PointStamped',
          '/yaw': 'sensor_msgs/msg/Imu', '/velocity': 'geometry_msgs/msg/TwistStamped',
          '/steering': 'sensor_msgs/msg/JointState'}
SENTINEL = 1234.5678


def _template(store: Any, msg: Any) -> tuple[bytearray, int]:
    """Serialize one message as rosbag2 does; return its bytes and the sentinel's offset."""
    data = bytearray(serialize_cdr(msg, store))
    return data, bytes(data).find(struct.pack('<d', SENTINEL))    # -1: none (yaw)


def synthetic_bag(path: Path, hours: float = 1.0) -> int:
    """
    Write a bag of the contract topics at 100 Hz: y = 0.1 sin(2 pi t / 10), 2 ms latency.

    Messages are serialized once per topic by rosbags and then patched (stamp, value),
    so the bag is exactly what rosbags would write, in seconds rather than minutes.

    :param path: the bag directory (must not exist).
    :param hours: duration.
    :return: the number of messages.
    """
    store = typestore()
    templates: dict[str, tuple[bytearray, int]] = {
        '/lateral_error': _template(store, conv.to_lateral_error(0, 'b', 0.0, SENTINEL)),
        '/yaw': _template(store, conv.to_yaw(0, 'b', 0.0, 0.0, 0.0)),
        '/velocity': _template(store, conv.to_velocity(0, 'b', SENTINEL, 0.0, 0.0)),
        '/steering': _template(store, conv.to_steering(0, SENTINEL, 0.0)),
    }
    writer = BagWriter(path, chunk_interval=3600.0, chunk_bytes=4 * 1024 * 1024)
    qos = [qos_from_ints({'reliability': 1, 'durability': 2, 'depth': 10})]
    for topic, msgtype in TOPICS.items():
        writer.add_topic(topic, msgtype, qos)
    steps = int(hours * 3600 * 100)
    start = 1_000_000_000_000
    pack_stamp, pack_value = struct.Struct('<iI').pack_into, struct.Struct('<d').pack_into
    values: dict[str, Callable[[float], float]] = {
        '/lateral_error': lambda t: 0.1 * math.sin(2 * math.pi * t / 10),
        '/yaw': lambda t: 0.0,
        '/velocity': lambda t: 20.0,
        '/steering': lambda t: 0.01 * math.cos(2 * math.pi * t / 10)}
    for k in range(steps):
        stamp = k * 10_000_000
        t = stamp * 1e-9
        for offset, topic in ((0, '/yaw'), (0, '/velocity'), (1, '/lateral_error'),
                              (2_000_001, '/steering')):
            data, at = templates[topic]
            pack_stamp(data, 4, stamp // 1_000_000_000, stamp % 1_000_000_000)
            if topic != '/yaw':
                pack_value(data, at, values[topic](t))
            writer.write(topic, start + stamp + offset, bytes(data))
    writer.close()
    return steps * len(TOPICS)


def _read_records(bag: Path) -> int:
    """Baseline: iterate every message record of the MCAP file, decoding nothing."""
    from mcap.reader import make_reader
    count = 0
    with open(next(bag.glob('*.mcap')), 'rb') as f:
        for _ in make_reader(f).iter_messages():
            count += 1
    return count


def _analyze_once(bag: Path) -> tuple[float, str]:
    """Run ``analyze`` (plots included) in a fresh process; return its wall time and table."""
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        out = subprocess.run([sys.executable, '-m', 'lookahead_control.tools.analyze_tool',
                              str(bag), '--out', tmp], cwd=ROOT, capture_output=True,
                             text=True, timeout=3600)
        value = time.perf_counter() - start
        if out.returncode != 0:
            raise RuntimeError(f'analyze failed: {out.stderr[-500:]}')
        return value, (Path(tmp) / 'metrics.json').read_text()


def analyze(quick: bool = False, repetitions: int = 3) -> Result:
    """
    Time ``analyze`` (a fresh process, plots included) on a 1 h, 100 Hz bag.

    Each repetition times the baseline (the ``mcap`` library iterating the records) and
    then ``analyze``, on the same bag: the file is in the page cache for both.

    :param quick: a 6 min bag.
    :param repetitions: how many times each is timed.
    :return: the result.
    """
    hours = 0.1 if quick else 1.0
    bag = RESULTS / f'synthetic_{hours:g}h'
    if not (bag / 'metadata.yaml').is_file():
        shutil.rmtree(bag, ignore_errors=True)
        RESULTS.mkdir(parents=True, exist_ok=True)
        synthetic_bag(bag, hours)
    baselines, values, count, table = [], [], 0, ''
    for _ in range(repetitions):
        start = time.perf_counter()
        count = _read_records(bag)
        baselines.append(time.perf_counter() - start)
        value, table = _analyze_once(bag)
        values.append(value)
    value, baseline = median(values), median(baselines)
    goal = 5.0 * hours
    return Result('6_analyze', f'analyze, {hours:g} h at 100 Hz ({count} messages)', value,
                  's', 'iterating the MCAP records without decoding (mcap)', baseline,
                  value / baseline, f'<= {goal:g} s', value <= goal, repetitions,
                  (min(values), max(values)),
                  {'messages': count, 'metrics': table[:2000], 'analyze_s': values,
                   'read_records_s': baselines})
