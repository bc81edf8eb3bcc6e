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

"""Benchmarks 2, 3, 5, 7: the ROS processes against bare rclpy baselines."""

from __future__ import annotations

import json
from pathlib import Path
import re
import signal
import subprocess
import tempfile
import time
from typing import Any

from bench.common import cpu_seconds, median, percentile, python_process, Result, ROOT, rss_mib
from lookahead_control.bags.rosbag_io import bag_topics
from lookahead_control.ros.closed_loop import LoopConfig, node_commands, recorder_command, stop

SCENARIO = ROOT / 'config' / 'scenarios' / 'paper_r400.yaml'
BLASTED = ('/lateral_error', '/yaw', '/velocity', '/road_curvature', '/steering',
           '/controller/debug', '/sim_plant/ground_truth', '/clock')
CONTROLLER = ['lookahead_control.ros.controller_node', '--ros-args', '--params-file',
              str(ROOT / 'config' / 'vehicle.yaml'), '--params-file',
              str(ROOT / 'config' / 'controller.yaml')]


def _json_out(process: subprocess.Popen, timeout: float) -> Any:
    out, _ = process.communicate(timeout=timeout)
    return json.loads(out.strip().splitlines()[-1])


def _latency_once(target: list[str], rate: float, seconds: float) -> dict[str, Any]:
    server = python_process(*target)
    try:
        driver = python_process('bench.nodes', 'driver', '--rate', str(rate), '--seconds',
                                str(seconds), stdout=subprocess.PIPE)
        data = _json_out(driver, 60 + seconds)
    finally:
        stop(server, 'target')
    return data


def latency(quick: bool = False) -> list[Result]:
    """
    Input -> steering latency of the controller next to a bare echo, at 100 Hz and 1 kHz.

    :param quick: one short repetition each.
    :return: one result per rate.
    """
    repeat, shortest = (1, 2.0) if quick else (5, 5.0)
    results = []
    for rate in (100.0, 1000.0):
        # at least 2000 samples a run: a p99 of 500 samples (5 s at 100 Hz) is the
        # 5th-slowest wake-up of a run, and moved by 1.2-1.9 ms from run to run
        seconds = shortest if quick else max(shortest, 2000.0 / rate)
        runs: dict[str, list[dict[str, Any]]] = {'controller': [], 'echo': []}
        for _ in range(repeat):              # interleaved: both see the same machine
            runs['echo'].append(_latency_once(['bench.nodes', 'echo'], rate, seconds))
            runs['controller'].append(_latency_once(CONTROLLER, rate, seconds))

        def summary(items: list[dict[str, Any]]) -> dict[str, Any]:
            # percentiles of all samples pooled (a p99 of one short run is mostly the
            # scheduler's noise), and per run for the spread
            pooled = [x for r in items for x in r['latency_us']]
            return {'p50_us_pooled': percentile(pooled, 50),
                    'p99_us_pooled': percentile(pooled, 99),
                    'p50_us': [percentile(r['latency_us'], 50) for r in items],
                    'p99_us': [percentile(r['latency_us'], 99) for r in items],
                    'samples': len(pooled), 'sent': sum(r['sent'] for r in items),
                    'lost': sum(r['lost'] for r in items)}

        ctl, base = summary(runs['controller']), summary(runs['echo'])
        p99, p99_base = ctl['p99_us_pooled'], base['p99_us_pooled']
        ratio = p99 / p99_base
        hz = f'{rate:g} Hz'
        results.append(Result(
            f'2_latency_{int(rate)}hz',
            f'controller p99 latency, input -> steering, {hz} (pooled runs)', p99, 'us',
            f'bare echo node p99, {hz}', p99_base, ratio,
            'p99 <= 1.2x echo' + ('; 0 lost' if rate >= 1000 else ''),
            ratio <= 1.2 and (rate < 1000 or ctl['lost'] == 0), repeat,
            (min(ctl['p99_us']), max(ctl['p99_us'])),
            {'controller': ctl, 'echo': base, 'p50_us': ctl['p50_us_pooled'],
             'p50_us_echo': base['p50_us_pooled'], 'seconds_per_run': seconds}))
    return results


def lockstep(quick: bool = False) -> Result:
    """
    Lockstep steps/s of sim_plant + controller next to a bare ping-pong of the same types.

    A run of either is a fraction of a second to a few seconds and the machine's
    speed drifts between runs: each repetition is a pair, ping-pong then loop, of the
    same number of steps, and the figure is the median over the pairs of each.

    :param quick: one pair of 1000 steps.
    :return: the result.
    """
    repeat, seconds = (1, 10.0) if quick else (5, 30.0)
    steps = int(seconds * 100)
    loop, bare = [], []
    with tempfile.TemporaryDirectory() as tmp:
        scenario = Path(tmp) / 'lockstep.yaml'
        text = SCENARIO.read_text()
        if 'duration: 10.0' not in text:
            raise RuntimeError(f'{SCENARIO}: expected a 10 s scenario')
        scenario.write_text(text.replace('duration: 10.0', f'duration: {seconds}'))
        for _ in range(repeat):
            server = python_process('bench.nodes', 'pong')
            try:
                ping = python_process('bench.nodes', 'ping', '--steps', str(steps),
                                      stdout=subprocess.PIPE)
                bare.append(_json_out(ping, 300)['steps_per_s'])
            finally:
                stop(server, 'pong')
            sim_cmd, ctl_cmd = node_commands(LoopConfig(scenario, speed=30.0))
            controller = subprocess.Popen(ctl_cmd, cwd=ROOT)
            sim = subprocess.Popen(sim_cmd, cwd=ROOT, stderr=subprocess.PIPE, text=True)
            try:
                _, err = sim.communicate(timeout=600)
            finally:
                stop(controller, 'controller')
            found = re.search(rf'{steps} steps, 0 missed deadlines.*\(([\d.]+) steps/s\)',
                              err)
            if not found:
                raise RuntimeError(f'lockstep run failed: {err[-500:]}')
            loop.append(float(found.group(1)))
    value, baseline = median(loop), median(bare)
    return Result('3_lockstep', 'sim_plant + controller lockstep, steps/s', value,
                  'steps/s', f'bare ping-pong of the same message types ({steps} steps)',
                  baseline, value / baseline, '>= 0.8x ping-pong', value / baseline >= 0.8,
                  repeat, (min(loop), max(loop)),
                  {'loop_steps_per_s': loop, 'ping_pong_steps_per_s': bare,
                   'pair_ratios': [a / b for a, b in zip(loop, bare)],
                   'real_time_factor_at_100hz': value / 100.0})


def recorder(quick: bool = False) -> Result:
    """
    Record every contract topic at 1 kHz; drops and CPU next to a bare counting node.

    :param quick: 10 s instead of 60 s.
    :return: the result.
    """
    seconds = 10.0 if quick else 60.0

    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / 'bench_bag'
        # the publisher prints its counts at the end; CPU is timed over its whole window
        counted = _blast_window(lambda: python_process('bench.nodes', 'counter',
                                                       stderr=subprocess.PIPE), seconds)
        recorded = _blast_window(lambda: subprocess.Popen(
            recorder_command(bag), cwd=ROOT, stderr=subprocess.PIPE, text=True), seconds)
        topics = bag_topics(bag)
    published = recorded['per_topic'] * recorded['topics']
    in_bag = sum(count for topic, (_, count) in topics.items() if topic in BLASTED)
    drops = published - in_bag
    ratio = recorded['cpu_share'] / max(counted['cpu_share'], 1e-9)
    return Result('5_recorder', f'recorder CPU share, 8 topics x 1 kHz for {seconds:g} s',
                  recorded['cpu_share'], 'CPU share of one core',
                  'bare node counting the same raw messages', counted['cpu_share'], ratio,
                  '0 drops', drops == 0, 1, (recorded['cpu_share'], recorded['cpu_share']),
                  {'published': published, 'in_bag': in_bag, 'drops': drops,
                   'counter_received': counted['received'],
                   'recorder_report': recorded['report']})


def _blast_window(start_target: Any, seconds: float) -> dict[str, Any]:
    target = start_target()
    try:
        blast = python_process('bench.nodes', 'blast', '--rate', '1000', '--seconds',
                               str(seconds), stdout=subprocess.PIPE)
        time.sleep(1.0)
        cpu0, t0 = cpu_seconds(target.pid), time.monotonic()
        sent = _json_out(blast, seconds + 120)
        cpu = (cpu_seconds(target.pid) - cpu0) / (time.monotonic() - t0)
    finally:
        target.send_signal(signal.SIGINT)
        _, err = target.communicate(timeout=60)
    lines = err.strip().splitlines()
    received = None
    for text in reversed(lines):
        if text.startswith('{'):
            received = sum(json.loads(text).values())
            break
    return {**sent, 'cpu_share': cpu, 'received': received,
            'report': [t for t in lines if t.startswith('record:')]}


def memory(quick: bool = False) -> Result:
    """
    Resident memory of both nodes after 10 min of realtime running vs after 10 s.

    :param quick: 60 s instead of 10 min.
    :return: the result.
    """
    total = 60.0 if quick else 600.0
    with tempfile.TemporaryDirectory() as tmp:
        scenario = Path(tmp) / 'long.yaml'
        scenario.write_text(SCENARIO.read_text().replace('duration: 10.0',
                                                         f'duration: {total + 20:g}'))
        sim_cmd, ctl_cmd = node_commands(LoopConfig(scenario, speed=30.0, mode='realtime'))
        controller = subprocess.Popen(ctl_cmd, cwd=ROOT)
        sim = subprocess.Popen(sim_cmd, cwd=ROOT, stderr=subprocess.PIPE, text=True)
        samples: dict[str, list[tuple[float, float, float]]] = {'controller': [],
                                                                'sim_plant': []}
        try:
            start = time.monotonic()
            for mark in (10.0, total / 4, total / 2, 3 * total / 4, total):
                time.sleep(max(0.0, start + mark - time.monotonic()))
                for name, proc in (('controller', controller), ('sim_plant', sim)):
                    samples[name].append((mark, *rss_mib(proc.pid)))
        finally:
            stop(sim, 'sim_plant')
            stop(controller, 'controller')
    growth = {name: s[-1][1] / s[0][1] for name, s in samples.items()}
    worst = max(growth, key=lambda n: growth[n])
    return Result('7_memory', f'RSS after {total:g} s of realtime, worst node ({worst})',
                  samples[worst][-1][1], 'MiB', 'its RSS after 10 s', samples[worst][0][1],
                  growth[worst], 'no growth (<= 1.05x)', growth[worst] <= 1.05, 1,
                  (samples[worst][0][1], samples[worst][-1][1]),
                  {'samples_s_rss_hwm_mib': samples, 'growth': growth})
