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
Metrics of recorded runs: time series per control step, and one table row per bag.

No ROS here. A step is a lateral-error stamp. Errors come from the simulator's ground
truth where the bag has it, else from the measurements (``y_cg = y_s - d eps_r``); the
look-ahead distance and reference from the controller's debug topic, else from the
controller re-run on the bag's inputs; latency is the receive time of the steering
minus that of the lateral error it answers.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Mapping, Optional

from lookahead_control.control_law import cg_error_from
from lookahead_control.metrics import run_metrics
from lookahead_control.params import VehicleParams
from lookahead_control.run_data import rerun, RunData
import numpy as np
import numpy.typing as npt
import yaml

Array = npt.NDArray[np.float64]
SERIES = ('y_cg', 'eps_r', 'rho', 'v_x', 'd_v', 'y_ref', 'error', 'steering_cmd')


@dataclass(frozen=True)
class RunSeries:
    """
    One value per control step.

    :param time: step stamps from the first [s].
    :param channels: the arrays named in :data:`SERIES`.
    :param latency: steering receive minus lateral-error receive, per answered step [s].
    :param unanswered: steps without a recorded steering command.
    """

    time: Array
    channels: dict[str, Array]
    latency: Array
    unanswered: int


def _latest(samples: list[tuple[int, Any]], stamps: list[int]) -> list[Any]:
    """Return, for each stamp, the newest sample stamped at or before it."""
    out: list[Any] = []
    ordered = sorted(samples, key=lambda item: item[0])
    i, current = 0, None
    for stamp in stamps:
        while i < len(ordered) and ordered[i][0] <= stamp:
            current = ordered[i][1]
            i += 1
        out.append(current)
    return out


def _forward_fill(values: list[float]) -> Array:
    """Replace each NaN by the last value before it (0 before the first value)."""
    out = np.array(values, dtype=float)
    index = np.where(np.isnan(out), 0, np.arange(out.size))
    np.maximum.accumulate(index, out=index)
    return np.nan_to_num(out[index], nan=0.0)


def run_series(run: RunData) -> RunSeries:
    """
    Return the per-step series of a run.

    :param run: the run read from a bag.
    :return: the series.
    :raises ValueError: no lateral-error message with yaw and velocity to go with it.
    """
    by_role: dict[str, list[tuple[int, Any]]] = {}
    for _, role, sample in run.inputs:
        by_role.setdefault(role, []).append((sample.stamp_ns, sample))
    stamps = sorted({s for s, _ in by_role.get('lateral_error', [])})
    lateral = _latest(by_role.get('lateral_error', []), stamps)
    yaw = _latest(by_role.get('yaw', []), stamps)
    velocity = _latest(by_role.get('velocity', []), stamps)
    curvature = _latest(by_role.get('road_curvature', []), stamps)
    keep = [i for i in range(len(stamps)) if yaw[i] is not None and velocity[i] is not None]
    if not keep:
        raise ValueError(f'{run.bag}: no lateral error with yaw and velocity to go with it')
    law = {} if run.debug else {s: c.law for s, c in rerun(run).commands.items()
                                if c.law is not None}
    rows: dict[str, list[float]] = {name: [] for name in SERIES}
    for i in keep:
        s = stamps[i]
        truth = run.truth.get(s, {})
        eps_r = truth.get('eps_r', yaw[i].relative_yaw)
        rows['eps_r'].append(eps_r)
        measured = float(cg_error_from(lateral[i].value, eps_r, lateral[i].distance))
        rows['y_cg'].append(truth.get('y_cg', measured))
        rows['rho'].append(truth.get('rho', curvature[i].rho if curvature[i] else 0.0))
        rows['v_x'].append(velocity[i].v_x)
        debug = run.debug.get(s)
        if debug is None and s in law:
            debug = {'d_v': float(law[s].d_v), 'y_ref': float(law[s].y_ref),
                     'error': float(law[s].error)}
        for name in ('d_v', 'y_ref', 'error'):
            rows[name].append(debug[name] if debug else math.nan)
        rows['steering_cmd'].append(run.steering[s][0] if s in run.steering else math.nan)
    kept = [stamps[i] for i in keep]
    channels = {name: _forward_fill(values) for name, values in rows.items()}
    latency = np.array([(run.steering[s][1] - run.lateral_received[s]) * 1e-9
                        for s in kept if s in run.steering and s in run.lateral_received])
    return RunSeries(np.array([(s - kept[0]) * 1e-9 for s in kept]), channels, latency,
                     sum(1 for s in kept if s not in run.steering))


def recorder_drops(run: RunData) -> Optional[int]:
    """Return the messages the recorder lost, if it counted them."""
    text = run.description.get('lookahead_control/recorder')
    if not text:
        return None
    report = yaml.safe_load(text) or {}
    return int(sum((entry or {}).get('dropped') or 0 for entry in report.values()))


def bag_row(run: RunData, series: RunSeries,
            label: Optional[str] = None) -> dict[str, Any]:
    """
    Return the metrics table row of one recorded run.

    :param run: the run.
    :param series: its series.
    :param label: the row label (default: the schedule the controller ran).
    :return: errors at the CG, bumper and look-ahead point, yaw step response,
        steering peaks, latency p50/p99, counts.
    """
    params = run.controller_params
    d_s = float(params.get('vehicle.d_s', VehicleParams().d_s))
    row: dict[str, Any] = {
        'run': label or str(params.get('controller.schedule', run.bag.name)),
        'speed_mps': round(float(series.channels['v_x'][0]), 3),
    }
    row.update(run_metrics(series.time, series.channels, d_s))
    lat = series.latency
    row['latency_p50_ms'] = float(np.percentile(lat, 50) * 1e3) if lat.size else math.nan
    row['latency_p99_ms'] = float(np.percentile(lat, 99) * 1e3) if lat.size else math.nan
    row['steps'] = int(series.time.size)
    row['unanswered'] = series.unanswered
    drops = recorder_drops(run)
    row['dropped'] = -1 if drops is None else drops
    return row


def speed_points(series_list: list[RunSeries]) -> list[Mapping[str, float]]:
    """Return ``(v_x, d_v)`` points of all runs for the d_v-vs-speed plot."""
    return [{'speed': float(v), 'd_v': float(d)} for s in series_list
            for v, d in zip(s.channels['v_x'], s.channels['d_v'])]
