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
``sweep``: Monte Carlo and grid robustness sweeps of steering laws, spread with Dask.

A sweep draws (Monte Carlo) or enumerates (grid) run conditions: scenario, speed,
cornering-stiffness and mass scale of the plant against the controller's model,
friction, transport delay and noise seed. Every law runs every condition (common random
numbers: the laws are compared on the same cars and roads). Runs of one law, scenario
and plant are grouped into tasks of ``--batch`` runs; each task is one vectorized batch
of the offline runner. Tasks go to a ``dask.distributed`` cluster: a local one by
default (``--workers``), an existing one with ``--scheduler ADDRESS``, or none
(``--workers 0``: this process).

Output folder: ``sweep.json`` (the sweep's options and models), ``parts/<task>.parquet``
(each finished task's rows, written atomically by this process as the task finishes: a killed
worker loses only its unfinished task, which Dask reruns; a killed sweep is resumed by
running it again with the same options and output folder), ``results.parquet`` (one
row per run: every parameter and metric), ``summary.md`` / ``summary.csv`` (per law:
failure rate, worst case and percentiles) and ``plots/*.png``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
import itertools
import json
import math
import os
from pathlib import Path
import sys
import time
from typing import Any, Callable, Mapping, Optional, Sequence

from lookahead_control.analysis.metrics import MIN_DURATION, rms, run_metrics
from lookahead_control.core.cli import (ArgumentParser, markdown_table, number, run_tool,
                                        ToolError, write_csv)
from lookahead_control.core.config import (changed_fields, load_controller, load_lane_keeping,
                                           load_safety, load_vehicle, source_config_dir)
from lookahead_control.core.interrupts import raise_if_received
from lookahead_control.core.lane_keeping import CgCompensatedLaw, LaneKeepingParams
from lookahead_control.core.laws import Law, PaperLaw
from lookahead_control.core.output_stage import NodeOutputStage, OUTPUT_STAGE
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
from lookahead_control.core.safety import SafetyParams
import numpy as np
from sim_plant.closed_loop_sim import check_steps, CONTROL_PERIOD

PLANTS = ('nonlinear', 'linear')
#: ``sweep.json``'s ``load_transfer_estimate`` since dev-sc29
LOADED_SCALE = 'scale over the loaded compliance'
RANGES = ('cornering', 'mass', 'friction', 'delay')
PARAMETER_COLUMNS = ('run_id', 'task', 'law', 'scenario', 'plant', 'speed', 'cornering',
                     'mass', 'friction', 'delay', 'seed', 'noise')
PERCENTILES = (50.0, 95.0, 99.0)
SUMMARY_METRICS = ('peak_cg_error_m', 'peak_look_ahead_lane_error_m',
                   'peak_steering_rad', 'peak_steering_rate_rad_per_s',
                   'rms_steering_noise_rad')


def paper_law(vehicle: VehicleParams, controller: ControllerParams,
              lane_keeping: LaneKeepingParams) -> Law:
    """Return the paper's law with the eq. 26 schedule, as the node runs it by default."""
    return PaperLaw(vehicle, ControllerParams(**{**asdict(controller), 'schedule': 'paper'}),
                    curvature_rate=False)


def paper_fixed_law(vehicle: VehicleParams, controller: ControllerParams,
                    lane_keeping: LaneKeepingParams) -> Law:
    """Return the paper's law with the fixed look-down, as the node runs it by default."""
    return PaperLaw(vehicle, ControllerParams(**{**asdict(controller), 'schedule': 'fixed'}),
                    curvature_rate=False)


# name -> factory(controller's vehicle model, paper-law parameters, lane-keeping
# settings); a new law registers here (one law object serves a whole batch: see
# core/laws.py). The names are those of the compare tool's league.
def cg_compensated_law(vehicle: VehicleParams, controller: ControllerParams,
                       lane_keeping: LaneKeepingParams) -> Law:
    """Return the CG-compensated look-ahead law (docs/lane_keeping.md), as the node builds it."""
    return CgCompensatedLaw(vehicle, controller, lane_keeping)


LAWS: dict[str, Callable[[VehicleParams, ControllerParams, LaneKeepingParams], Law]] = {
    'paper_eq26': paper_law,
    'paper_fixed': paper_fixed_law,
    'cg_compensated': cg_compensated_law,
}


@dataclass(frozen=True)
class SweepSpec:
    """
    What a sweep runs (``sweep.json``); a resumed sweep must have the same.

    :param mode: ``monte_carlo`` or ``grid``.
    :param runs: Monte Carlo: conditions per scenario.
    :param levels: grid: values per range (ends included).
    :param seed: Monte Carlo sampling seed; noise seeds derive from it.
    :param scenarios: scenario names (``config/scenarios/<name>.yaml``) or paths.
    :param speeds: initial speeds [m/s] (a scenario with its own profile ignores them).
    :param laws: law names (keys of ``LAWS``).
    :param plant: ``nonlinear`` (Fiala tyres, actuator) or ``linear``.
    :param cornering: range of the plant's cornering-stiffness scale - 1 (both axles).
    :param mass: range of the plant's mass (and yaw inertia) scale - 1.
    :param friction: range of the tyre-road friction coefficient.
    :param delay: range of the transport delay [s] (rounded to ``dt``).
    :param noise: sensor noise on (the defaults of ``sim_plant.sensors``).
    :param batch: runs per task.
    :param dt: plant step [s].
    :param duration: simulated time [s] (0: each scenario's own).
    :param max_error: a run fails when its peak CG error exceeds this [m].
    """

    mode: str = 'monte_carlo'
    runs: int = 32
    levels: int = 3
    seed: int = 0
    scenarios: tuple[str, ...] = ('s1_paper_step', 's2_curve_entry', 's3_s_bend')
    speeds: tuple[float, ...] = (20.0, 37.0)
    laws: tuple[str, ...] = ('paper_eq26', 'paper_fixed')
    plant: str = 'nonlinear'
    cornering: tuple[float, float] = (-0.3, 0.3)
    mass: tuple[float, float] = (-0.2, 0.2)
    friction: tuple[float, float] = (0.5, 1.0)
    delay: tuple[float, float] = (0.0, 0.05)
    noise: bool = True
    batch: int = 32
    dt: float = 0.001
    duration: float = 0.0
    max_error: float = 0.85

    def __post_init__(self) -> None:
        if self.mode not in ('monte_carlo', 'grid'):
            raise ToolError(f'--mode {self.mode!r}: choose monte_carlo or grid')
        if self.plant not in PLANTS:
            raise ToolError(f'--plant {self.plant!r}: choose one of {", ".join(PLANTS)}')
        unknown = [law for law in self.laws if law not in LAWS]
        if unknown or not self.laws:
            raise ToolError(f'--laws {",".join(self.laws)!r}: known laws are '
                            f'{", ".join(LAWS)}')
        if not self.scenarios or not self.speeds:
            raise ToolError('a sweep needs at least one scenario and one speed')
        for name, count in (('runs', self.runs), ('levels', self.levels),
                            ('batch', self.batch)):
            if not 1 <= count <= 1_000_000:
                # dev-probe96: 1e9 was told 'a whole number >= 1 is required'
                raise ToolError(f'--{name} {count!r} is out of range; allowed: a whole '
                                'number in [1, 1000000]')
        for name in RANGES:
            low, high = getattr(self, name)
            if not (math.isfinite(low) and math.isfinite(high) and low <= high):
                raise ToolError(f'--{name} {low!r}:{high!r}: a range LOW:HIGH with '
                                'LOW <= HIGH is required')
        checks = {'cornering': (-0.9, 5.0), 'mass': (-0.9, 5.0), 'friction': (0.01, 2.0),
                  'delay': (0.0, 1.0)}
        for name, (low, high) in checks.items():
            lo, hi = getattr(self, name)
            if lo < low or hi > high:
                raise ToolError(f'--{name} {lo!r}:{hi!r} is out of range; allowed: within '
                                f'[{low:g}, {high:g}]')
        if any(not (0.0 < v <= 90.0) for v in self.speeds):
            raise ToolError(f'--speeds {self.speeds!r}: each in (0, 90] m/s')
        if not 0.0 < self.max_error <= 100.0:
            raise ToolError(f'--max-error {self.max_error!r}: a peak CG error in (0, 100] m '
                            'is required')
        if not 0.0 < self.dt <= CONTROL_PERIOD:
            raise ToolError(f'--dt {self.dt!r}: a plant step in (0, {CONTROL_PERIOD:g}] s (at '
                            'most the control period) is required')
        try:
            check_steps(self.dt, CONTROL_PERIOD, 1.0)
        except ParameterError as err:
            raise ToolError(f'--dt {self.dt!r}: {err}') from err
        if not (self.duration == 0.0 or MIN_DURATION <= self.duration <= 1.0e5):
            # dev-probe96: 0.001 s ran, every metric NaN and no run failed
            raise ToolError(f"--duration {self.duration!r}: 0 (each scenario's own) or a "
                            f'time in [{MIN_DURATION:g}, 1e5] s (what the metrics need) is '
                            'required')

    def to_json(self) -> dict[str, Any]:
        """Return the spec as JSON-able data."""
        return {f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v)
                for f in fields(self)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> 'SweepSpec':
        """
        Return the spec of ``to_json`` data.

        :param data: the data.
        :return: the spec.
        """
        values: dict[str, Any] = {k: (tuple(v) if isinstance(v, list) else v)
                                  for k, v in data.items()}
        return cls(**values)


def scenario_path(name: str) -> Path:
    """
    Return the file of a scenario name or path.

    :param name: a name in ``config/scenarios`` (without ``.yaml``) or a path.
    :return: the path.
    """
    path = Path(name)
    if path.suffix in ('.yaml', '.yml'):
        return path
    return source_config_dir() / 'scenarios' / f'{name}.yaml'


def _levels(low: float, high: float, count: int) -> list[float]:
    if count == 1 or low == high:
        return [0.5 * (low + high)]
    return [float(v) for v in np.linspace(low, high, count)]


def conditions(spec: SweepSpec) -> list[dict[str, Any]]:
    """
    Return the run conditions of a sweep (without the law), in a fixed order.

    Monte Carlo: ``runs`` conditions per scenario, uniform in each range, speed drawn
    from ``speeds``; grid: every combination of ``levels`` values of each range and
    every speed, per scenario. Delays are rounded to ``dt``; each condition has its own
    noise seed.

    :param spec: the sweep.
    :return: one mapping per condition.
    """
    from sim_plant.scenario import load_scenario
    out: list[dict[str, Any]] = []
    rng = np.random.default_rng(spec.seed)
    for scenario in spec.scenarios:
        fixed = load_scenario(scenario_path(scenario)).speed
        speeds = [fixed.initial] if fixed.fixed else list(spec.speeds)
        if spec.mode == 'monte_carlo':
            draws = [{'speed': float(speeds[int(rng.integers(len(speeds)))]),
                      **{name: float(rng.uniform(*getattr(spec, name))) for name in RANGES}}
                     for _ in range(spec.runs)]
        else:
            grid = [_levels(getattr(spec, name)[0], getattr(spec, name)[1], spec.levels)
                    for name in RANGES]
            draws = [{'speed': v, **dict(zip(RANGES, combo))}
                     for v in speeds for combo in itertools.product(*grid)]
        for draw in draws:
            draw['delay'] = round(draw['delay'] / spec.dt) * spec.dt
            index = len(out)
            out.append({'run_id': index, 'scenario': scenario,
                        'seed': spec.seed * 1_000_003 + index, **draw})
    return out


def tasks(spec: SweepSpec) -> list[dict[str, Any]]:
    """
    Return the tasks: per law and scenario, conditions in chunks of ``batch``.

    :param spec: the sweep.
    :return: ``{'task': id, 'law': name, 'conditions': [...]}`` mappings.
    """
    runs = conditions(spec)
    out = []
    for law in spec.laws:
        for scenario in spec.scenarios:
            mine = [c for c in runs if c['scenario'] == scenario]
            for k in range(0, len(mine), spec.batch):
                stem = Path(scenario).stem
                out.append({'task': f'{law}-{stem}-{k // spec.batch:05d}', 'law': law,
                            'conditions': mine[k:k + spec.batch]})
    return out


def run_task(task: Mapping[str, Any], spec_data: Mapping[str, Any],
             vehicle: VehicleParams, controller: ControllerParams,
             lane_keeping: LaneKeepingParams | None = None,
             safety: SafetyParams | None = None) -> dict[str, list[Any]]:
    """
    Run one task as one vectorized batch and return its rows as columns.

    Each law runs through the node's output stage (angle and rate limits).

    :param task: a task of :func:`tasks`.
    :param spec_data: the sweep's ``to_json``.
    :param vehicle: the controller's vehicle model (the plant's before scaling).
    :param controller: the paper law's parameters.
    :param lane_keeping: the CG-compensated law's settings (None: the defaults).
    :param safety: the node's limits, for its output stage (None: config/controller.yaml's).
    :return: column name -> values, one per run.
    """
    from dataclasses import replace

    from sim_plant.closed_loop_sim import run
    from sim_plant.scenario import load_scenario
    from sim_plant.sensors import NoiseParams
    from sim_plant.vehicle_model import PlantParams
    spec = SweepSpec.from_json(spec_data)
    conds = task['conditions']
    scenario = load_scenario(scenario_path(conds[0]['scenario']))
    if spec.duration > 0.0:
        scenario = replace(scenario, duration=spec.duration)
    bodies = [VehicleParams(mass=vehicle.mass * (1.0 + c['mass']),
                            yaw_inertia=vehicle.yaw_inertia * (1.0 + c['mass']),
                            l1=vehicle.l1, l2=vehicle.l2,
                            c_f=vehicle.c_f * (1.0 + c['cornering']),
                            c_r=vehicle.c_r * (1.0 + c['cornering']), d_s=vehicle.d_s,
                            cg_height=vehicle.cg_height)
              for c in conds]
    plants = [PlantParams(model=spec.plant, friction=c['friction']) for c in conds]
    speeds = None if scenario.speed.fixed else np.array([c['speed'] for c in conds])
    law = NodeOutputStage(LAWS[task['law']](vehicle, controller,
                                            lane_keeping or LaneKeepingParams()),
                          vehicle.wheelbase, safety or load_safety(None))
    with np.errstate(all='ignore'):
        result = run(scenario, vehicle, law, plants, dt=spec.dt, initial_speed=speeds,
                     plant_vehicle=bodies, delay=np.array([c['delay'] for c in conds]),
                     noise=NoiseParams() if spec.noise else None,
                     seed=[c['seed'] for c in conds])
    columns: dict[str, list[Any]] = {}
    for i, cond in enumerate(conds):
        row = {'run_id': cond['run_id'], 'task': task['task'], 'law': task['law'],
               'scenario': Path(cond['scenario']).stem, 'plant': spec.plant,
               'speed': cond['speed'], 'cornering': cond['cornering'], 'mass': cond['mass'],
               'friction': cond['friction'], 'delay': cond['delay'], 'seed': cond['seed'],
               'noise': spec.noise,
               **run_row(result.time, {k: v[:, i] for k, v in result.channels.items()},
                         vehicle.d_s, spec.max_error)}
        for key, value in row.items():
            columns.setdefault(key, []).append(value)
    return columns


def run_row(time_s: np.ndarray, channels: Mapping[str, np.ndarray], d_s: float,
            max_error: float) -> dict[str, Any]:
    """
    Return the metrics of one run (``analysis.metrics.run_metrics`` and more).

    Added: ``rms_steering_noise_rad`` (the command minus its 0.5 s moving average: what
    noise puts on the steering) and ``failed`` (a value is not finite, or the peak CG
    error exceeds ``max_error``).

    :param time_s: sample times [s].
    :param channels: the run's channels.
    :param d_s: bumper distance [m].
    :param max_error: the failure threshold [m].
    :return: metric name -> value.
    """
    finite = all(bool(np.all(np.isfinite(channels[name])))
                 for name in ('y_cg', 'eps_r', 'steering', 'steering_cmd'))
    row: dict[str, Any] = dict(run_metrics(time_s, channels, d_s)) if finite else {}
    command = channels['steering_cmd']
    width = max(1, int(round(0.5 / float(time_s[1] - time_s[0])))) if time_s.size > 1 else 1
    if finite and command.size > width:
        smooth = np.convolve(command, np.ones(width) / width, mode='same')
        row['rms_steering_noise_rad'] = rms((command - smooth)[width:-width])
    else:
        row['rms_steering_noise_rad'] = math.nan
    # the failure threshold on the CG error itself (run_metrics leaves short runs empty)
    row['failed'] = (not finite) or float(np.max(np.abs(channels['y_cg']))) > max_error
    return {k: (float(v) if isinstance(v, (float, np.floating)) else v)
            for k, v in row.items()}


# -- output ------------------------------------------------------------------------


def part_path(out: Path, task_id: str) -> Path:
    """
    Return the Parquet part of a task.

    :param out: the sweep folder.
    :param task_id: the task.
    :return: ``out/parts/<task>.parquet``.
    """
    return out / 'parts' / f'{task_id}.parquet'


def write_parquet(columns: Mapping[str, Sequence[Any]], path: Path) -> None:
    """
    Write columns to a Parquet file atomically (a temporary file renamed into place).

    :param columns: column name -> values.
    :param path: the file.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f'.{path.name}.{os.getpid()}.tmp')
    pq.write_table(pa.table(dict(columns)), tmp)
    with open(tmp, 'rb') as handle:
        os.fsync(handle.fileno())
    os.replace(tmp, path)


def manifest_data(spec: SweepSpec, vehicle: VehicleParams, controller: ControllerParams,
                  lane_keeping: LaneKeepingParams | None = None,
                  safety: SafetyParams | None = None) -> dict[str, Any]:
    """
    Return what ``sweep.json`` holds: the options and the models every run used.

    :param spec: the sweep.
    :param vehicle: the controller's vehicle model (the plants are it, scaled).
    :param controller: the paper law's parameters.
    :param lane_keeping: the CG-compensated law's settings (None: the defaults).
    :param safety: the node's limits (None: config/controller.yaml's); its output stage's
        are kept.
    :return: JSON data (as read back from the file).
    """
    limits = safety or load_safety(None)
    data = {**spec.to_json(), 'vehicle': asdict(vehicle), 'controller': asdict(controller),
            'lane_keeping': asdict(lane_keeping or LaneKeepingParams()),
            'output_stage': {name.partition('.')[2]: getattr(limits, name.partition('.')[2])
                             for name in OUTPUT_STAGE},
            # what cg_compensated's compliance estimate learns with a cg_height (dev-sc29:
            # the scale over the compliance at the rear axle's load, before: the compliance)
            'load_transfer_estimate': LOADED_SCALE}
    return dict(json.loads(json.dumps(data)))


def _differences(old: dict[str, Any], new: dict[str, Any]) -> list[str]:
    """
    Return what differs between two sweep manifests: a key, or ``key.field`` of a model.

    :param old: the folder's manifest.
    :param new: this sweep's.
    :return: the names, a field's with both values.
    """
    out: list[str] = []
    for key in set(old) | set(new):
        before, now = old.get(key), new.get(key)
        if before == now:
            continue
        if isinstance(before, dict) and isinstance(now, dict):
            out += [f'{key}.{name} = {before.get(name)!r} in the folder, '
                    f'{now.get(name)!r} now'
                    for name in sorted(set(before) | set(now))
                    if before.get(name) != now.get(name)]
        else:
            out.append(key)
    return out


def prepare(out: Path, spec: SweepSpec, vehicle: VehicleParams | None = None,
            controller: ControllerParams | None = None,
            lane_keeping: LaneKeepingParams | None = None,
            safety: SafetyParams | None = None) -> None:
    """
    Create the sweep folder, or check that it holds the same sweep (resume).

    The same sweep: the same options, vehicle and controller models and lane-keeping
    settings (a resumed sweep must not mix runs of two models or two tunings).

    :param out: the folder.
    :param spec: the sweep.
    :param vehicle: the controller's vehicle model (default: config/vehicle.yaml).
    :param controller: the paper law's parameters (default: config/controller.yaml).
    :param lane_keeping: the CG-compensated law's settings (default: those of
        config/controller.yaml).
    :param safety: the node's limits, for its output stage (None: config/controller.yaml's).
    :raises ToolError: it holds another sweep.
    """
    manifest = out / 'sweep.json'
    new = manifest_data(spec, vehicle or load_vehicle(None),
                        controller or load_controller(None),
                        lane_keeping or load_lane_keeping(None), safety)
    if manifest.exists():
        try:
            old = json.loads(manifest.read_text(encoding='utf-8'))
        except (OSError, ValueError) as err:
            raise ToolError(f'{manifest}: unreadable ({err}); remove it or use another '
                            '--out') from err
        if not isinstance(old, dict):
            raise ToolError(f'{manifest}: not a sweep manifest (a JSON object); remove it '
                            'or use another --out')
        if {'vehicle', 'controller'} <= set(old) and 'lane_keeping' not in old:
            # the version before lane_keeping was recorded ran cg_compensated at the
            # package defaults whatever the file said: resumable with those, and only;
            # k_i was constant then (before dev-kisched: the default schedule, 0.05 1/s
            # at and below 15 m/s, would mix runs of two laws)
            gain = LaneKeepingParams().integral_gain
            constant = LaneKeepingParams(low_speed_integral_gain=gain)
            old['lane_keeping'] = manifest_data(spec, vehicle or load_vehicle(None),
                                                controller or load_controller(None),
                                                constant)['lane_keeping']
        settled = old.get('lane_keeping')
        if (isinstance(settled, dict) and 'integral_gain' in settled
                and 'low_speed_integral_gain' not in settled):
            # a sweep from before the integral gain's speed schedule (dev-kisched): its
            # cg_compensated ran k_i = integral_gain at every speed, which a
            # low_speed_integral_gain of integral_gain runs (the speeds then do nothing)
            old['lane_keeping'] = {**settled,
                                   'low_speed_integral_gain': settled['integral_gain'],
                                   **{k: new['lane_keeping'][k] for k in (
                                       'integral_speed', 'low_integral_speed')
                                      if k not in settled}}
        body = old.get('vehicle')
        if isinstance(body, dict) and 'cg_height' not in body:
            # a sweep from before vehicle.cg_height (dev-sc28) ran without load transfer,
            # which cg_height 0 runs to the last bit (dev-probe62: it was refused)
            old['vehicle'] = {**body, 'cg_height': 0.0}
        if 'load_transfer_estimate' not in old and isinstance(old.get('vehicle'), dict):
            height = old['vehicle'].get('cg_height')
            if (isinstance(height, (int, float)) and not isinstance(height, bool)
                    and height > 0.0):
                raise ToolError(
                    f'{out} holds a sweep with vehicle.cg_height = {height!r} written by '
                    "an earlier version of cg_compensated's compliance estimate under load "
                    'transfer (before dev-sc29 made it learn a scale over the loaded '
                    'compliance from a filtered a_x): runs of both must not mix; use '
                    'another --out')
            # without a cg_height the estimate is the one before, to the last bit (a
            # height of another type is left to the comparison below, which names it)
            old['load_transfer_estimate'] = LOADED_SCALE
        if 'output_stage' not in old and {'vehicle', 'controller'} <= set(old):
            raise ToolError(f'{out} holds a sweep from before the output stage: its laws ran '
                            "without the node's angle and rate limits, and runs of both "
                            'must not mix; use another --out')
        differ = sorted(_differences(old, new))
        if differ and not {'vehicle', 'controller', 'lane_keeping'} <= set(old):
            raise ToolError(f'{out} holds a sweep that did not record its vehicle, '
                            'controller and lane-keeping settings (an older version): it '
                            'cannot be resumed safely; use another --out')
        if differ:
            raise ToolError(f'{out} holds another sweep (options differ: '
                            f'{", ".join(differ)}); use another --out or the same options')
    elif out.exists() and any(out.iterdir()):
        raise ToolError(f'{out} exists and is not a sweep folder; use another --out')
    (out / 'parts').mkdir(parents=True, exist_ok=True)
    for stale in (out / 'parts').glob('.*.tmp'):
        stale.unlink()
    if not manifest.exists():
        tmp = manifest.with_name('.sweep.json.tmp')
        tmp.write_text(json.dumps(new, indent=2) + '\n', encoding='utf-8')
        os.replace(tmp, manifest)


def pending(out: Path, all_tasks: Sequence[Mapping[str, Any]]) -> list[Mapping[str, Any]]:
    """
    Return the tasks whose part is not on disk yet.

    :param out: the sweep folder.
    :param all_tasks: every task.
    :return: the unfinished ones.
    """
    return [t for t in all_tasks if not part_path(out, t['task']).exists()]


def _local_progress(total: int, enabled: bool) -> Any:
    if not enabled:
        return None
    from tqdm import tqdm
    return tqdm(total=total, desc='sweep', unit='task', mininterval=0.5)


def execute(out: Path, spec: SweepSpec, todo: Sequence[Mapping[str, Any]],
            vehicle: VehicleParams, controller: ControllerParams, workers: int,
            scheduler: Optional[str], progress: bool,
            runner: Callable[..., dict[str, list[Any]]] = run_task,
            lane_keeping: LaneKeepingParams | None = None,
            safety: SafetyParams | None = None) -> int:
    """
    Run the tasks and write each one's part as it finishes.

    :param out: the sweep folder.
    :param spec: the sweep.
    :param todo: the tasks to run.
    :param vehicle: the controller's vehicle model.
    :param controller: the paper law's parameters.
    :param workers: local Dask workers (0: run here, without Dask).
    :param scheduler: address of an existing Dask scheduler (None: a local cluster).
    :param progress: show a progress bar.
    :param runner: the task function (:func:`run_task`; tests wrap it).
    :param lane_keeping: the CG-compensated law's settings (None: the defaults).
    :param safety: the node's limits, for its output stage (None: config/controller.yaml's).
    :return: the number of tasks run.
    """
    bar = _local_progress(len(todo), progress)
    data = spec.to_json()
    lane_keeping = lane_keeping or LaneKeepingParams()
    if workers == 0 and scheduler is None:
        for task in todo:
            raise_if_received()             # a Ctrl-C a lazy import swallowed
            write_parquet(runner(task, data, vehicle, controller, lane_keeping, safety),
                          part_path(out, task['task']))
            if bar is not None:
                bar.update(1)
        if bar is not None:
            bar.close()
        return len(todo)
    from dask.distributed import as_completed, Client, LocalCluster
    cluster = None
    if scheduler is None:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=40)
        client = Client(cluster)
    else:
        client = Client(scheduler, timeout=30)
    try:
        # no retries: an exception is deterministic (it stops the sweep, finished parts
        # stay); a worker that dies is rerun elsewhere by the scheduler (allowed-failures)
        futures = {client.submit(runner, task, data, vehicle, controller, lane_keeping, safety,
                                 key=f'sweep-{task["task"]}-{time.time_ns()}',
                                 pure=False): task for task in todo}
        for future in as_completed(futures):
            raise_if_received()
            task = futures[future]
            write_parquet(future.result(), part_path(out, task['task']))
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
        client.close()
        if cluster is not None:
            cluster.close()
    return len(todo)


def collect(out: Path, all_tasks: Sequence[Mapping[str, Any]]) -> Any:
    """
    Return every run's row (a pyarrow Table sorted by law and run) and write it.

    :param out: the sweep folder.
    :param all_tasks: every task (each must have its part).
    :return: the table.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq
    tables = [pq.read_table(part_path(out, t['task'])) for t in all_tasks]
    table = pa.concat_tables(tables, promote_options='permissive').sort_by(
        [('law', 'ascending'), ('run_id', 'ascending')])
    write_parquet({name: table.column(name).to_pylist() for name in table.column_names},
                  out / 'results.parquet')
    return table


def summarize(table: Any) -> list[dict[str, Any]]:
    """
    Return per law (all scenarios) and per law and scenario: failures and percentiles.

    :param table: the results (pyarrow Table).
    :return: one row per group.
    """
    data = {name: np.asarray(table.column(name).to_pylist(), dtype=object)
            for name in table.column_names}
    rows = []
    groups = [(law, None) for law in dict.fromkeys(data['law'])]
    groups += [(law, sc) for law in dict.fromkeys(data['law'])
               for sc in dict.fromkeys(data['scenario'])]
    for law, scenario in groups:
        mask = data['law'] == law
        if scenario is not None:
            mask &= data['scenario'] == scenario
        if not np.any(mask):
            continue
        row: dict[str, Any] = {'law': law, 'scenario': scenario or 'all',
                               'runs': int(np.sum(mask)),
                               'failure_rate': float(np.mean(data['failed'][mask]
                                                             .astype(bool)))}
        for metric in SUMMARY_METRICS:
            values = np.array([np.nan if v is None else v for v in data[metric][mask]],
                              dtype=float)
            finite = values[np.isfinite(values)]
            row[f'{metric}_worst'] = float(np.max(finite)) if finite.size else math.nan
            for q in PERCENTILES:
                row[f'{metric}_p{q:g}'] = (float(np.percentile(finite, q)) if finite.size
                                           else math.nan)
        peaks = np.array([np.inf if v is None else v
                          for v in data['peak_cg_error_m'][mask]], dtype=float)
        worst = int(np.nonzero(mask)[0][int(np.argmax(np.nan_to_num(peaks, nan=np.inf)))])
        row['worst_case'] = (f"{data['scenario'][worst]} {data['speed'][worst]:g} m/s, "
                             f"C x{1 + data['cornering'][worst]:.2f}, "
                             f"m x{1 + data['mass'][worst]:.2f}, "
                             f"mu {data['friction'][worst]:.2f}, "
                             f"delay {1000 * data['delay'][worst]:.0f} ms")
        rows.append(row)
    return rows


SUMMARY_COLUMNS = ('law', 'scenario', 'runs', 'failure_rate', 'peak_cg_error_m_p50',
                   'peak_cg_error_m_p95', 'peak_cg_error_m_p99', 'peak_cg_error_m_worst',
                   'peak_look_ahead_lane_error_m_p95', 'peak_steering_rad_worst',
                   'peak_steering_rate_rad_per_s_p95', 'rms_steering_noise_rad_p50',
                   'worst_case')


#: what ``sweep`` prints: per law over all scenarios, then per law and scenario (the
#: worst case of each scenario, e.g. the mismatch corner of issue 14 per S1, S2, S3)
STDOUT_COLUMNS = ('law', 'scenario', 'runs', 'failure_rate', 'peak_cg_error_m_p50',
                  'peak_cg_error_m_p95', 'peak_cg_error_m_worst', 'worst_case')


def plot(table: Any, out: Path) -> list[Path]:
    """
    Write the sweep's plots: peak CG error distribution and against delay and friction.

    :param table: the results.
    :param out: the sweep folder.
    :return: the PNG paths.
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    folder = out / 'plots'
    folder.mkdir(parents=True, exist_ok=True)
    laws = list(dict.fromkeys(table.column('law').to_pylist()))
    law_col = np.array(table.column('law').to_pylist())
    peaks = np.array([np.nan if v is None else v
                      for v in table.column('peak_cg_error_m').to_pylist()], dtype=float)
    paths = []
    fig, ax = plt.subplots(figsize=(7, 4))
    for law in laws:
        values = np.sort(peaks[(law_col == law) & np.isfinite(peaks)])
        if values.size:
            ax.plot(values, np.arange(1, values.size + 1) / values.size, label=law)
    ax.set_xlabel('peak CG lateral error [m]')
    ax.set_ylabel('fraction of runs')
    ax.grid(True, alpha=0.3)
    ax.legend()
    ax.set_title('distribution of the peak CG error (empirical CDF)')
    paths.append(folder / 'peak_cg_cdf.png')
    fig.tight_layout()
    fig.savefig(paths[-1], dpi=100)
    plt.close(fig)
    for name, unit, scale in (('delay', 'ms', 1000.0), ('friction', '-', 1.0),
                              ('cornering', '-', 1.0)):
        x = np.array(table.column(name).to_pylist(), dtype=float) * scale
        fig, ax = plt.subplots(figsize=(7, 4))
        for law in laws:
            mask = law_col == law
            ax.scatter(x[mask], peaks[mask], s=10, alpha=0.6, label=law)
        ax.set_xlabel(f'{name} [{unit}]')
        ax.set_ylabel('peak CG lateral error [m]')
        ax.grid(True, alpha=0.3)
        ax.legend()
        paths.append(folder / f'peak_cg_vs_{name}.png')
        fig.tight_layout()
        fig.savefig(paths[-1], dpi=100)
        plt.close(fig)
    return paths


def settings_note(spec: SweepSpec, controller: ControllerParams | None,
                  lane_keeping: LaneKeepingParams | None,
                  safety: SafetyParams | None = None) -> str:
    """
    Return what ``summary.md`` says of the laws' settings: those that differ from the defaults.

    Each law is named with the settings it reads: the paper laws ``controller.*`` but
    their schedule (their name's), ``cg_compensated`` the d_v schedule, clamp and speed
    floor of ``controller.*`` (its gains are ``lane_keeping.*``'s) and ``lane_keeping.*``.

    :param spec: the sweep.
    :param controller: the paper law's parameters (None: the defaults).
    :param lane_keeping: the CG-compensated law's settings (None: the defaults).
    :param safety: the node's limits its output stage ran (None: config/controller.yaml's).
    :return: the sentences, each with a leading space ('' with no law to name).
    """
    control = changed_fields(controller or ControllerParams())
    mine = changed_fields(lane_keeping or LaneKeepingParams())
    text = ''
    paper = [law for law in spec.laws if law != 'cg_compensated']
    shown = [f'controller.{k} = {v!r}' for k, v in control.items() if k != 'schedule']
    if paper and shown:
        text += f' {", ".join(paper)}: {", ".join(shown)} (the rest default).'
    if 'cg_compensated' in spec.laws:
        shown = [f'controller.{k} = {v!r}' for k, v in control.items()
                 if k not in ('natural_frequency', 'damping_ratio', 'reference')]
        from lookahead_control.tools.compare import with_settings_notes
        shown += with_settings_notes([f'lane_keeping.{k} = {v!r}' for k, v in mine.items()],
                                     lane_keeping or LaneKeepingParams())
        text += ' cg_compensated: ' + (', '.join(shown) + ' (the rest default).' if shown
                                       else 'the default settings.')
    from lookahead_control.tools.compare import safety_changes
    limits = safety_changes(safety or load_safety(None))
    if limits:
        text += f" The node's limits: {', '.join(limits)}."
    return text


def report(out: Path, spec: SweepSpec, table: Any, plots: bool,
           lane_keeping: LaneKeepingParams | None = None,
           controller: ControllerParams | None = None,
           safety: SafetyParams | None = None) -> Path:
    """
    Write ``summary.md`` and ``summary.csv`` (and the plots).

    :param out: the sweep folder.
    :param spec: the sweep.
    :param table: the results.
    :param plots: also write the plots.
    :param lane_keeping: the CG-compensated law's settings (None: the defaults).
    :param controller: the paper law's parameters (None: the defaults).
    :param safety: the node's limits its output stage ran (None: config/controller.yaml's).
    :return: the markdown summary's path.
    """
    rows = summarize(table)
    settings = settings_note(spec, controller, lane_keeping, safety)
    write_csv(out / 'summary.csv', rows)
    text = [f'# Sweep: {spec.mode}, {table.num_rows} runs', '',
            f'Scenarios {", ".join(spec.scenarios)}; speeds {spec.speeds} m/s; '
            f'{spec.plant} plant; cornering stiffness x(1 + {spec.cornering}), mass and '
            f'yaw inertia x(1 + {spec.mass}), friction {spec.friction}, delay '
            f'{spec.delay} s, noise {"on" if spec.noise else "off"}. A run fails when its '
            f'peak CG error exceeds {spec.max_error:g} m or a value is not finite. The '
            "laws' commands pass the node's output stage (angle and rate limits)."
            + settings, '',
            markdown_table(rows, SUMMARY_COLUMNS, digits=3), '']
    if plots:
        for png in plot(table, out):
            text.append(f'![{png.stem}](plots/{png.name})')
    path = out / 'summary.md'
    path.write_text('\n'.join(text) + '\n', encoding='utf-8')
    return path


def sweep(spec: SweepSpec, out: Path, *, vehicle: VehicleParams | None = None,
          controller: ControllerParams | None = None,
          lane_keeping: LaneKeepingParams | None = None,
          safety: SafetyParams | None = None, workers: int = 2,
          scheduler: Optional[str] = None, progress: bool = False, plots: bool = True,
          max_tasks: Optional[int] = None,
          runner: Callable[..., dict[str, list[Any]]] = run_task) -> tuple[Any, int]:
    """
    Run (or resume) a sweep and write its results, summary and plots.

    :param spec: the sweep.
    :param out: the output folder.
    :param vehicle: the controller's vehicle model (default: config/vehicle.yaml).
    :param controller: the paper law's parameters (default: config/controller.yaml).
    :param lane_keeping: the CG-compensated law's settings (default: those of
        config/controller.yaml).
    :param safety: the node's limits, for its output stage (default: those of
        config/controller.yaml).
    :param workers: local Dask workers (0: no Dask).
    :param scheduler: address of an existing Dask scheduler.
    :param progress: show a progress bar.
    :param plots: write plots.
    :param max_tasks: run at most this many pending tasks, then stop (no summary).
    :param runner: the task function (:func:`run_task`; tests wrap it).
    :return: the results table (None when stopped early) and the tasks run.
    """
    vehicle = vehicle or load_vehicle(None)
    controller = controller or load_controller(None)
    lane_keeping = lane_keeping or load_lane_keeping(None)
    safety = safety or load_safety(None)
    all_tasks = tasks(spec)
    prepare(out, spec, vehicle, controller, lane_keeping, safety)
    todo = pending(out, all_tasks)
    if max_tasks is not None:
        todo = todo[:max_tasks]
    count = execute(out, spec, todo, vehicle, controller, workers, scheduler, progress,
                    runner, lane_keeping, safety)
    if pending(out, all_tasks):
        return None, count
    table = collect(out, all_tasks)
    report(out, spec, table, plots, lane_keeping, controller, safety)
    return table, count


def _range(text: str) -> tuple[float, float]:
    low, sep, high = text.partition(':')
    try:
        return (float(low), float(high)) if sep else (float(low), float(low))
    except ValueError as err:
        raise ToolError(f'range {text!r}: expected LOW:HIGH (numbers)') from err


def _names(text: str) -> tuple[str, ...]:
    return tuple(part.strip() for part in text.split(',') if part.strip())


def _speeds(text: str) -> tuple[float, ...]:
    try:
        return tuple(float(v) for v in _names(text))
    except ValueError as err:
        raise ToolError(f'--speeds {text!r}: expected numbers separated by commas') from err


def main(argv: Sequence[str] | None = None) -> int:
    """
    Run a robustness sweep.

    :param argv: command-line arguments.
    :return: exit code.
    """
    p = ArgumentParser(
        description='Monte Carlo / grid robustness sweep of steering laws (Dask)')
    d = SweepSpec()
    p.add_argument('--vehicle', type=Path, default=None,
                   help="the controller's vehicle model YAML (default: config/vehicle.yaml)"
                   '; the plant is it, scaled')
    p.add_argument('--out', type=Path, required=True, help='sweep folder (resumed if it '
                   'holds the same sweep)')
    p.add_argument('--controller', type=Path, default=None,
                   help="the controller node's params YAML: the paper laws' controller.* "
                   "and cg_compensated's lane_keeping.*, and the limits of the node's "
                   'output stage every law runs through (safety.max_steering_angle, '
                   'max_steering_rate, max_lateral_acceleration, low_speed, '
                   'low_speed_blend; default: config/controller.yaml)')
    p.add_argument('--mode', choices=('monte_carlo', 'grid'), default=d.mode)
    p.add_argument('--runs', type=int, default=d.runs, help='Monte Carlo: conditions per '
                   'scenario')
    p.add_argument('--levels', type=int, default=d.levels, help='grid: values per range')
    p.add_argument('--seed', type=number(0, 2**32 - 1, integer=True), default=d.seed)
    p.add_argument('--scenarios', type=_names, default=d.scenarios,
                   help='comma-separated names in config/scenarios or YAML paths')
    p.add_argument('--speeds', type=_speeds, default=d.speeds, help='m/s, comma-separated')
    p.add_argument('--laws', type=_names, default=d.laws,
                   help=f'comma-separated, of: {", ".join(LAWS)}')
    p.add_argument('--plant', choices=PLANTS, default=d.plant)
    for name, help_text in (('cornering', 'cornering stiffness scale - 1'),
                            ('mass', 'mass and yaw inertia scale - 1'),
                            ('friction', 'tyre-road friction'), ('delay', 'delay [s]')):
        low, high = getattr(d, name)
        p.add_argument(f'--{name}', type=_range, default=(low, high),
                       help=f'{help_text}, LOW:HIGH (default {low:g}:{high:g}; write '
                       f'--{name}=LOW:HIGH when LOW is negative)')
    p.add_argument('--no-noise', action='store_true', help='ideal sensors')
    p.add_argument('--batch', type=int, default=d.batch, help='runs per task')
    p.add_argument('--dt', type=float, default=d.dt, help='plant step [s]')
    p.add_argument('--duration', type=float, default=d.duration,
                   help="simulated time [s] (0: each scenario's)")
    p.add_argument('--max-error', type=float, default=d.max_error,
                   help='peak CG error [m] above which a run fails')
    p.add_argument('--workers', type=number(0, 256, integer=True), default=2,
                   help='local Dask workers (0: none)')
    p.add_argument('--scheduler', default=None, metavar='ADDRESS',
                   help='an existing Dask scheduler (tcp://host:8786)')
    p.add_argument('--no-plots', action='store_true')
    p.add_argument('--no-progress', action='store_true')
    args = p.parse_args(argv)
    if args.workers < 0:
        raise ToolError(f'--workers {args.workers}: 0 or more')
    spec = SweepSpec(args.mode, args.runs, args.levels, args.seed, args.scenarios,
                     args.speeds, args.laws, args.plant, args.cornering, args.mass,
                     args.friction, args.delay, not args.no_noise, args.batch, args.dt,
                     args.duration, args.max_error)
    from dataclasses import replace

    from sim_plant.scenario import check_force_timing, load_scenario
    for name in spec.scenarios:
        if not scenario_path(name).exists():
            raise ToolError(f'--scenarios: no scenario {name!r} ({scenario_path(name)})')
        # what every run would refuse, before any runs (dev-probe81: the other scenarios'
        # tasks ran first, then a line that did not name the file)
        try:
            scenario = load_scenario(scenario_path(name))
            if spec.duration > 0.0:
                scenario = replace(scenario, duration=spec.duration)
            check_force_timing(scenario.forces, spec.dt)
        except ParameterError as err:
            cut = f' cut to --duration {spec.duration:g} s' if spec.duration > 0.0 else ''
            raise ToolError(f'--scenarios {name} ({scenario_path(name)}){cut} at --dt '
                            f'{spec.dt!r} s: {err}') from err
    vehicle = load_vehicle(args.vehicle)
    from lookahead_control.tools.compare import load_transfer_note
    note = load_transfer_note(vehicle, [spec.plant], spec.laws)
    if note:
        print(f'sweep: note: {note}', file=sys.stderr)
    if args.controller is None:
        controller, lane_keeping = load_controller(None), load_lane_keeping(None)
        safety = load_safety(None)
    else:
        # as the node reads the file (its own check first: a name it does not have is
        # refused, not left at its default)
        from lookahead_control.tools.compare import load_law_settings, NOT_RUN_OFFLINE
        # the paper laws run as the node runs them by default: without d rho / dt
        paper = any(law.startswith('paper') for law in spec.laws)
        loaded = load_law_settings(args.controller, vehicle, (
            *NOT_RUN_OFFLINE, *(('use_curvature_preview',) if paper else ())), 'sweep')
        controller, lane_keeping, safety = (loaded.controller, loaded.lane_keeping,
                                            loaded.safety)
    for law in spec.laws:       # the node's checks across parameters: before any run
        try:
            LAWS[law](vehicle, controller, lane_keeping)
        except ParameterError as err:
            raise ToolError(f'--controller {args.controller or "(default)"}: {law}: '
                            f'{err}') from err
    start = time.monotonic()
    table, count = sweep(spec, args.out, vehicle=vehicle, controller=controller,
                         lane_keeping=lane_keeping, safety=safety,
                         workers=args.workers, scheduler=args.scheduler,
                         progress=not args.no_progress, plots=not args.no_plots)
    print(markdown_table(summarize(table), STDOUT_COLUMNS, digits=3))
    print(f'{count} tasks run in {time.monotonic() - start:.1f} s; '
          f'wrote {args.out / "results.parquet"} and {args.out / "summary.md"}')
    return 0


def entry() -> int:
    """Entry point of ``sweep``."""
    return run_tool(main)


if __name__ == '__main__':
    sys.exit(entry())
