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
Executable ``compare``: every law x scenarios S0-S5 x plants x speeds, one league table.

Each law gets the same inputs (the contract's measurements through the same sensors and
noise, the same curvature preview), the same actuator and plant, and the controller
node's output stage (its angle and rate limits, ``safety.*``:
:class:`~lookahead_control.core.output_stage.NodeOutputStage`) in the offline loop
(``sim_plant.closed_loop_sim.run``, vectorized over speeds). Writes ``league.md``
(summary and goal rows), ``league.csv`` (one row per run) and ``league.png`` into
``--out``; ``--tune`` runs the baselines' tuning grids instead (``docs/baselines.md``).
Every law runs its package defaults (the league's one tuning), or with ``--controller``
the settings the controller node would run with that params file.
A law added later is one entry of :data:`LAWS`.
"""

from __future__ import annotations

from collections import Counter
from concurrent.futures import as_completed, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from functools import partial
from importlib.machinery import PathFinder
import math
from multiprocessing import get_context
import os
from pathlib import Path
import pickle
import sys
import threading
import time
from typing import Any, Callable, Iterable, Iterator, Mapping, Optional, Sequence

from lookahead_control.analysis.metrics import MIN_DURATION, step_metrics
from lookahead_control.core.baselines import (baseline_law, BaselineParams, LqrParams,
                                              PurePursuitParams, StanleyParams)
from lookahead_control.core.cli import (claim_output, markdown_table, number, one_line, parser,
                                        record_output, run_tool, ToolError, write_csv,
                                        write_json)
from lookahead_control.core.control_law import arc_offset
from lookahead_control.core.controller import SteeringController
from lookahead_control.core.interrupts import raise_if_received
from lookahead_control.core.lane_keeping import CgCompensatedLaw, LaneKeepingParams
from lookahead_control.core.laws import Law, PaperLaw
from lookahead_control.core.output_stage import NodeOutputStage, OUTPUT_STAGE
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
from lookahead_control.core.safety import low_speed_weight, per_element, SafetyParams
from lookahead_control.core.schedule import paper_look_ahead
import numpy as np
import numpy.typing as npt
from sim_plant.closed_loop_sim import run, SimResult
from sim_plant.scenario import load_scenario, Scenario
from sim_plant.sensor_timing import (check_timing, parse_stream, SensorTiming, STREAMS,
                                     StreamTiming, timed_run, TIMED_STREAMS)
from sim_plant.sensors import NoiseParams
from sim_plant.vehicle_model import PlantParams

Array = npt.NDArray[np.float64]
ROOT = Path(__file__).resolve().parents[2]
SCENARIO_DIR = ROOT / 'config' / 'scenarios'
SCENARIOS = ('s0_straight', 's1_paper_step', 's2_curve_entry', 's3_s_bend',
             's4_lane_change', 's5_envelope')
#: more scenarios ``--scenarios`` takes, not in the league by default (no goal of issue 14
#: is about them): a side force on the body the map cannot tell the law
EXTRA_SCENARIOS = ('crosswind',)
SPEEDS = (10.0, 20.0, 30.0, 37.0)
PREVIEW_DISTANCE = 100.0        # [m] every law sees the curvature this far ahead
DELAY = 0.02                    # [s] transport delay of the "nonlinear + delay + noise" plant
NOISE_SEED = 1                  # seeds: speed_seed(speed): a run repeats in any subset
SEED_STRIDE = 1_000_000         # --seeds: the k-th seed of a speed is speed_seed + k stride
MAX_SEEDS = 1000                # --seeds' largest value
FINAL_WINDOW = 1.0              # [s] the steady error is the mean of the last second
NOISE_SCENARIO = 's0_straight'  # steering noise: command with noise minus without, here
MAX_SPEED = 90.0                # [m/s] the scenarios' limit
MAX_DURATION = 600.0            # [s] of simulated time per run (--duration)
DT = 0.005                      # [s] plant step (CommonRoad's multi-body model: 0.002)


@dataclass(frozen=True)
class LawSettings:
    """
    The settings the laws run with (a controller node's parameters, by namespace).

    :param controller: ``controller.*``: the paper laws' (their schedule is the law's
        name's) and the d_v schedule, clamp and speed floor of ``cg_compensated``.
    :param lane_keeping: ``lane_keeping.*``: the ``cg_compensated`` law's settings.
    :param baselines: ``pure_pursuit.*``, ``stanley.*``, ``lqr.*``.
    :param curvature_rate: ``use_curvature_preview``: the paper laws' ``d rho / dt``
        feed-forward (off by default in the node, so off here: until dev-sections the
        league's paper rows had it, 109.5 cm on S2 at 37 m/s against the node's 118.4).
    :param acceleration_source: where the node takes a_x from (``imu``, ``differentiate``,
        ``zero``): the tools run the laws on the exact a_x, the stability check takes
        ``zero``'s error into account.
    :param law: the law the node runs (``law``).
    :param mode: how the node answers (``event``: each lateral error; ``timer``).
    :param rate_hz: its timer's rate (``timer`` mode) [Hz].
    :param safety: ``safety.*``: the node's limits (default: ``config/controller.yaml``'s);
        the offline tools run its output stage with them
        (:class:`~lookahead_control.core.output_stage.NodeOutputStage`).
    :param align_inputs: the node's ``align_inputs`` (yaw and velocity read at the
        lateral error's stamp): it matters only with inputs on their own stamps, which
        ``compare --camera`` / ``--stream`` runs (:mod:`sim_plant.sensor_timing`).
    :param wait_for_matching_stamps: the node's (event mode), run with a sensor timing.
    :param sync_timeout: the node's (the longest wait for matching stamps) [s].
    :param watchdog_rate_hz: the node's (its safe command while an input is stale) [Hz].
    :param curvature_at_yaw_stamp: the node's (a curvature polygon older than the yaw
        sample taken read where the car was at its stamp): it matters only with a
        curvature stamped apart from the yaw, which ``compare --stream`` runs.
    """

    controller: ControllerParams = ControllerParams()
    lane_keeping: LaneKeepingParams = LaneKeepingParams()
    baselines: BaselineParams = BaselineParams()
    curvature_rate: bool = False
    acceleration_source: str = 'imu'
    law: str = 'cg_compensated'
    mode: str = 'event'
    rate_hz: float = 100.0
    safety: SafetyParams = field(default_factory=lambda: package_safety())
    align_inputs: str = 'with_prediction'
    wait_for_matching_stamps: bool = False
    sync_timeout: float = 0.05
    watchdog_rate_hz: float = 20.0
    curvature_at_yaw_stamp: bool = True


#: the node's settings that change a run but that the offline loop does not run (it
#: answers each measurement, 10 ms apart, with the law and the node's output stage, on
#: exact inputs and a_x): the safety layer's input checks, the source of a_x, the
#: answer's timing
NOT_RUN_OFFLINE = ('safety.', 'acceleration_source', 'mode')
#: what the offline tools run in their place
OFFLINE_RUNS = ("it runs each law and the node's output stage, each 10 ms measurement "
                'answered on exact inputs and a_x')
#: ... but the safety layer's timing, which exact and timely inputs never meet (the safe
#: angle: where stale inputs ramp to)
SAFETY_TIMING = ('safety.max_future', 'safety.input_timeout', 'safety.hold_time',
                 'safety.max_curvature_points', 'safety.latency_warn', 'safety.safe_angle')
#: the node's settings a run with a sensor timing (``--camera``, ``--stream``) does not run:
#: its transport and process (the loop hands the samples to the core under sim time, where
#: every lateral error is answered)
NOT_RUN_TIMED = ('qos_reliability', 'frame_id', 'executor', 'autostart',
                 'diagnostics_rate_hz', 'max_answer_rate_hz')
#: what it runs in their place
TIMED_RUNS = ("it hands each input's samples to the controller node's core as the node "
              'does under sim time, with their rates and latencies')
#: the node's settings a run with a sensor timing runs besides the laws' and the limits
NODE_TIMED = ('acceleration_source', 'mode', 'rate_hz', 'align_inputs',
              'wait_for_matching_stamps', 'sync_timeout', 'watchdog_rate_hz',
              'curvature_at_yaw_stamp')


def package_safety() -> SafetyParams:
    """
    Return the node's limits of the package's ``config/controller.yaml``.

    :return: the limits.
    """
    from lookahead_control.core.config import load_safety
    return load_safety(None)


LawFactory = Callable[[VehicleParams, LawSettings], Law]
LAWS: dict[str, LawFactory] = {
    'paper_fixed': lambda v, s: PaperLaw(v, replace(s.controller, schedule='fixed'),
                                         s.curvature_rate),
    'paper_eq26': lambda v, s: PaperLaw(v, replace(s.controller, schedule='paper'),
                                        s.curvature_rate),
    'pure_pursuit': lambda v, s: baseline_law('pure_pursuit', v, s.baselines),
    'stanley': lambda v, s: baseline_law('stanley', v, s.baselines),
    'lqr': lambda v, s: baseline_law('lqr', v, s.baselines),
    # as the node builds it (core/controller.build_law)
    'cg_compensated': lambda v, s: CgCompensatedLaw(v, s.controller, s.lane_keeping),
}
#: the package's own laws: a worker process has them (a law added to :data:`LAWS` at run
#: time is sent with its tasks)
_PACKAGE_FACTORIES = dict(LAWS)


def league_law(name: str, vehicle: VehicleParams, settings: LawSettings,
               factory: LawFactory | str | None = None) -> Law:
    """
    Return a law of the league as the controller node runs it: through its output stage.

    :param name: the law (a key of ``LAWS``).
    :param vehicle: the law's vehicle model (also the angle limit's wheelbase).
    :param settings: the settings.
    :param factory: the law's factory, or the name of the package law whose factory it
        is (None: ``LAWS[name]``).
    :return: the law.
    """
    make = (LAWS[factory] if isinstance(factory, str) else factory) or LAWS[name]
    return NodeOutputStage(make(vehicle, settings), vehicle.wheelbase, settings.safety)


def sent_factory(name: str, workers: int) -> LawFactory | str | None:
    """
    Return the factory to send with a law's tasks to a worker process, or None.

    A worker is a fresh interpreter (:func:`stoppable_pool`): it has the package's laws,
    not one a caller added to :data:`LAWS` (dev-probe112: ``failed: KeyError``). Such a
    law's factory goes with its tasks, pickled by reference; a package law's factory
    under another name goes as that law's name (dev-probe113: refused as a lambda).

    :param name: the law.
    :param workers: the league's processes (1: none is sent).
    :return: the factory, the name of the package law whose factory it is, or None (in
        this process, or a package law).
    :raises ToolError: the factory cannot be sent (a lambda, a local function).
    """
    if workers <= 1 or _PACKAGE_FACTORIES.get(name) is LAWS[name]:
        return None
    factory = LAWS[name]
    for package_name, package_factory in _PACKAGE_FACTORIES.items():
        if factory is package_factory:
            return package_name
    try:
        pickle.dumps(factory)
    except (pickle.PicklingError, AttributeError, TypeError) as err:
        raise ToolError(
            f'law {name!r}: its factory {factory!r} cannot be sent to a worker process '
            f'({err}): define it at module level (a function a worker can import), or '
            'run in this process (workers 1)') from err
    module = str(getattr(getattr(factory, 'func', factory), '__module__', None) or '')
    top = module.partition('.')[0]
    if (top and top != '__main__' and top not in sys.builtin_module_names
            and PathFinder.find_spec(top) is None):
        # loaded from a file by hand: this process has it, a worker cannot import it
        # (dev-probe114: the whole league's rows 'failed: BrokenProcessPool')
        raise ToolError(f'law {name!r}: its factory is in module {module!r}, which a worker '
                        'process cannot import (not on sys.path): put it on sys.path '
                        '(PYTHONPATH), or run in this process (workers 1)')
    return factory


def load_law_settings(path: Path | str, vehicle: Optional[VehicleParams] = None,
                      not_run: Sequence[str] = NOT_RUN_OFFLINE,
                      tool: str = 'this tool', runs: str = OFFLINE_RUNS,
                      output_stage: bool = True) -> LawSettings:
    """
    Load the laws' settings from a controller node's params file.

    The file is read once (a ``<(...)`` can be read only once) and checked first as the
    node checks it (``check_params_file`` with the node's parameters): a name the node
    does not have (``lane_keping.*``), in a section for the node, is refused as the node
    refuses it, not left at its default.

    :param path: a ROS params file (``config/controller.yaml`` format); what it does not
        set stays at the package default.
    :param vehicle: the tool's vehicle model (``--vehicle``; also its plant): a
        ``vehicle.*`` the file gives the node that differs from it is refused (the node
        would run another model than the one measured).
    :param not_run: the node's settings (names or ``namespace.`` prefixes) the tool does
        not run: one the file sets otherwise than the package is refused (the tool would
        measure another controller than the node's; dev-probe55).
    :param tool: the tool's name, for that message.
    :param runs: what the tool runs instead, for that message.
    :param output_stage: the tool runs the node's output stage (``OUTPUT_STAGE``): the
        file's limits are taken, not refused, and its ``SAFETY_TIMING`` settings too (the
        tool reports them as not met, :func:`safety_changes`); False: both refused.
    :return: the settings.
    :raises ConfigError: a bad file or value, in one line naming it.
    """
    from dataclasses import fields

    from lookahead_control.core.config import (ConfigError, dataclass_from_params,
                                               law_params_from, merged_params,
                                               node_file_sections)
    from lookahead_control.ros.controller_node import ALL_SPECS
    params = merged_params(node_file_sections(path, 'controller', ALL_SPECS), 'controller')
    if vehicle is not None:
        given = {k.partition('.')[2] for k in params if k.startswith('vehicle.')}
        node = dataclass_from_params(VehicleParams, params, 'vehicle', str(path))
        differ = [f'vehicle.{f.name} = {getattr(node, f.name)!r}' for f in fields(node)
                  if f.name in given and getattr(node, f.name) != getattr(vehicle, f.name)]
        if differ:
            raise ConfigError(
                f'{path}: {", ".join(differ)}: the controller would run this vehicle '
                'model, the tool measures the one of --vehicle (also its plant): give that '
                "vehicle in --vehicle, or leave vehicle.* out of the controller's file")
    package = package_node_defaults()
    unrun = [f'{name} = {value!r}' for name, value in params.items()
             if name.startswith(tuple(not_run))
             and not (output_stage and name in (*OUTPUT_STAGE, *SAFETY_TIMING))
             and name in package and value != package[name]]
    if unrun:
        raise ConfigError(
            f'{path}: {", ".join(unrun)}: the controller node runs this, {tool} does not '
            f'({runs}); measure it with closed_loop, or leave it out of this file')
    controller, lane_keeping, baselines = law_params_from(params, str(path))
    return LawSettings(controller, lane_keeping, baselines,
                       bool(params.get('use_curvature_preview', package['use_curvature_preview'])),
                       str(params.get('acceleration_source', package['acceleration_source'])),
                       str(params.get('law', package['law'])),
                       str(params.get('mode', package['mode'])),
                       float(params.get('rate_hz', package['rate_hz'])),
                       dataclass_from_params(SafetyParams, params, 'safety', str(path)),
                       str(params.get('align_inputs', package['align_inputs'])),
                       bool(params.get('wait_for_matching_stamps',
                                       package['wait_for_matching_stamps'])),
                       float(params.get('sync_timeout', package['sync_timeout'])),
                       float(params.get('watchdog_rate_hz', package['watchdog_rate_hz'])),
                       bool(params.get('curvature_at_yaw_stamp',
                                       package['curvature_at_yaw_stamp'])))


def package_node_defaults() -> dict[str, Any]:
    """
    Return the controller node's parameters with the package's files and no other.

    :return: name -> value: ``config/vehicle.yaml`` and ``config/controller.yaml`` over
        the parameters' declared defaults.
    """
    from lookahead_control.core.config import package_controller_params
    from lookahead_control.ros.controller_node import ALL_SPECS
    return {**{spec.name: spec.default for spec in ALL_SPECS}, **package_controller_params()}


def settings_changes(settings: LawSettings, timed: bool = False) -> list[str]:
    """
    Return ``namespace.name = value`` for every setting that differs from the default.

    :param settings: the laws' settings.
    :param timed: the runs had a sensor timing: the node's settings it runs
        (:data:`NODE_TIMED`) are said too, and every limit is run.
    :return: the lines, in field order (empty: the package defaults).
    """
    from lookahead_control.core.config import changed_fields
    parts: list[tuple[str, Any]] = [('controller', settings.controller),
                                    ('lane_keeping', settings.lane_keeping),
                                    *((name, getattr(settings.baselines, name))
                                      for name in ('pure_pursuit', 'stanley', 'lqr'))]
    lines = [f'{space}.{name} = {value!r}' for space, params in parts
             for name, value in changed_fields(params).items()]
    if settings.curvature_rate:
        lines.append('use_curvature_preview = True')
    if timed:
        package = package_node_defaults()
        lines += [f'{name} = {getattr(settings, name)!r}' for name in NODE_TIMED
                  if getattr(settings, name) != package[name]]
    lines += safety_changes(settings.safety, timed)
    return with_settings_notes(lines, settings.lane_keeping)


def safety_changes(safety: SafetyParams, timed: bool = False) -> list[str]:
    """
    Return ``safety.name = value`` for each of the node's limits off the package's.

    The output stage's limits are run; the others (only ``SAFETY_TIMING``'s pass
    :func:`load_law_settings`) are said to be never met, unless the runs had a sensor
    timing (``timed``: the node's core runs every limit).

    :param safety: the node's limits.
    :param timed: the runs had a sensor timing.
    :return: the lines (empty: the package's limits).
    """
    from dataclasses import fields
    default = package_safety()
    return [f'safety.{f.name} = {getattr(safety, f.name)!r}'
            + ('' if timed or f'safety.{f.name}' in OUTPUT_STAGE else
               ' (not met: the inputs are exact and timely)')
            for f in fields(safety) if getattr(safety, f.name) != getattr(default, f.name)]


def load_transfer_note(vehicle: VehicleParams, plants: Sequence[str],
                       laws: Sequence[str]) -> Optional[str]:
    """
    Return a note when cg_compensated runs a vehicle with load transfer on the linear plant.

    The linear plant is the paper's model, without load transfer, while the
    CG-compensated law linearizes with each axle's stiffness at its load: on it the law's
    model is a mismatch, which a run does not show (dev-sc28 left it to the docs).

    :param vehicle: the vehicle given to the tool.
    :param plants: the names of the plants run.
    :param laws: the names of the laws run (only cg_compensated reads ``cg_height``).
    :return: the note, or None.
    """
    if vehicle.cg_height <= 0.0 or 'linear' not in plants or 'cg_compensated' not in laws:
        return None
    return (f'vehicle.cg_height = {vehicle.cg_height:g} m: the linear plant has no '
            "load transfer (the paper's model), while cg_compensated linearizes with each "
            "axle's stiffness at its load under a_x: on that plant its model is a mismatch "
            '(the nonlinear plant moves its tyres with the load)')


def with_settings_notes(lines: list[str], lane_keeping: LaneKeepingParams) -> list[str]:
    """
    Return the settings lines with what runs otherwise than set.

    :param lines: ``namespace.name = value`` lines.
    :param lane_keeping: the CG-compensated law's settings.
    :return: the lines, the low-speed value's (else the capping value's) with the note of
        :func:`~lookahead_control.core.lane_keeping.frequency_schedule_note` or
        :func:`~lookahead_control.core.lane_keeping.integral_schedule_note`, the
        ``state_filter`` line with the note of
        :func:`~lookahead_control.core.lane_keeping.filterless_note`, the first
        ``filter_*`` line with that of
        :func:`~lookahead_control.core.lane_keeping.curvature_filter_note`.
    """
    from lookahead_control.core.lane_keeping import (curvature_filter_note, FILTER_SETTINGS,
                                                     filterless_note,
                                                     frequency_schedule_note,
                                                     integral_schedule_note)
    for note, names in ((frequency_schedule_note(lane_keeping),
                         ('low_speed_frequency', 'natural_frequency')),
                        (integral_schedule_note(lane_keeping),
                         ('low_speed_integral_gain', 'integral_gain')),
                        (filterless_note(lane_keeping),
                         ('state_filter', 'side_force', 'force_feedforward')),
                        (curvature_filter_note(lane_keeping), FILTER_SETTINGS)):
        if not note:
            continue
        for name in names:
            prefix = f'lane_keeping.{name} = '
            if any(line.startswith(prefix) for line in lines):
                lines = [f'{line} ({note})' if line.startswith(prefix) else line
                         for line in lines]
                break
    return lines


@dataclass(frozen=True)
class PlantCase:
    """
    One plant of the league.

    :param name: its column name.
    :param plant: the plant options.
    :param delay: transport delay control -> wheel [s].
    :param noisy: the default sensor noise (``sim_plant.sensors.NoiseParams()``) is on.
    :param vehicle_id: a CommonRoad parameter set: the laws then use its single-track
        mapping (``sim_plant.commonroad_plant.controller_vehicle``) as their model.
    :param dt: its integration step [s] (None: the league's).
    """

    name: str
    plant: PlantParams
    delay: float = 0.0
    noisy: bool = False
    vehicle_id: Optional[int] = None
    dt: Optional[float] = None

    def law_vehicle(self, vehicle: VehicleParams) -> VehicleParams:
        """
        Return the vehicle model the laws are given on this plant.

        :param vehicle: the league's vehicle (the plant's, for the package's plants).
        :return: that vehicle, or the CommonRoad set's single-track mapping.
        """
        if self.vehicle_id is None:
            return vehicle
        from sim_plant.commonroad_plant import controller_vehicle
        return controller_vehicle(self.vehicle_id)


NONLINEAR = PlantParams(model='nonlinear')
PLANTS = (PlantCase('linear', PlantParams()), PlantCase('nonlinear', NONLINEAR),
          PlantCase('nonlinear_delay_noise', NONLINEAR, DELAY, True),
          PlantCase('commonroad_mb', PlantParams(model='commonroad_mb', vehicle_id=2),
                    vehicle_id=2, dt=0.002),
          # the independent plant as the goal plant's conditions: a result about a car is
          # reported on a plant the law was not written against, with delay and noise
          PlantCase('commonroad_mb_delay_noise',
                    PlantParams(model='commonroad_mb', vehicle_id=2), DELAY, True,
                    vehicle_id=2, dt=0.002))
GOAL_PLANT = 'nonlinear_delay_noise'
#: the independent plant under the goal plant's delay and noise, reported beside it
INDEPENDENT_PLANT = 'commonroad_mb_delay_noise'


# -- goals (issue 14: one tuning, nonlinear plant + 20 ms delay + default noise) -----------

@dataclass(frozen=True)
class Goal:
    """
    One goal row: a metric bound on some scenarios, speeds and plant.

    :param name: short name.
    :param metric: the row field it bounds.
    :param bound: the largest allowed value.
    :param scenarios: where it applies.
    :param speeds: at which speeds (empty: all).
    :param plant: on which plant.
    """

    name: str
    metric: str
    bound: float
    scenarios: tuple[str, ...]
    speeds: tuple[float, ...] = ()
    plant: str = GOAL_PLANT

    def applies(self, row: Mapping[str, Any]) -> bool:
        """
        Return whether the goal applies to a run.

        :param row: the run's row.
        :return: scenario, plant and speed match.
        """
        return (row['scenario'] in self.scenarios and row['plant'] == self.plant
                and (not self.speeds or row['speed_mps'] in self.speeds))


GOALS = (
    Goal('S2 peak <= 3 cm at 37', 'peak_cg_error_m', 0.03, ('s2_curve_entry',), (37.0,)),
    Goal('S1 peak <= 6 cm at 37', 'peak_cg_error_m', 0.06, ('s1_paper_step',), (37.0,)),
    Goal('S3 peak <= 6 cm at 37', 'peak_cg_error_m', 0.06, ('s3_s_bend',), (37.0,)),
    Goal('S4 peak <= 6 cm at 37', 'peak_cg_error_m', 0.06, ('s4_lane_change',), (37.0,)),
    Goal('steady on an arc <= 1 cm', 'steady_cg_error_m', 0.01,
         ('s1_paper_step', 's2_curve_entry')),
    Goal('yaw overshoot <= 10 %', 'yaw_overshoot', 0.10,
         ('s1_paper_step', 's2_curve_entry', 's3_s_bend'), (30.0, 37.0)),
    Goal('S0 yaw rebound <= 50 %', 'yaw_rebound', 0.50, ('s0_straight',)),
    Goal('S0 noise <= 5 mrad rms at 37', 'steering_noise_rms_rad', 0.005, ('s0_straight',),
         (37.0,)),
    Goal('CommonRoad S2 <= 5 cm at 30-37', 'peak_cg_error_m', 0.05, ('s2_curve_entry',),
         (30.0, 37.0), 'commonroad_mb'),
)
#: goals on a plant without sensor noise: --seeds does not repeat their runs
NOISE_FREE_GOALS = frozenset(g.name for g in GOALS
                             if not any(c.noisy for c in PLANTS if c.name == g.plant))


# -- metrics -------------------------------------------------------------------------------

def _peak_rate(x: Array, period: float) -> float:
    return float(np.max(np.abs(np.diff(x)))) / period if x.size > 1 else 0.0


def curve_window(time: Array, rho: Array, hold: float = 2.0 * FINAL_WINDOW
                 ) -> Optional[tuple[float, float]]:
    """
    Return ``(start, end)`` of the first curve entry, None if there is none.

    From where the curvature leaves 0 to the end of the first stretch of constant,
    non-zero curvature that holds ``hold``. A step (S1), a clothoid into an arc (S2) and
    an S-bend's first arc (S3) have one; a lane change (S4) or a straight road has none.

    :param time: sample times [s].
    :param rho: road curvature at the CG [1/m].
    :param hold: the constant stretch must last this long [s].
    :return: the window, or None.
    """
    curved = np.nonzero(np.abs(rho) > 1e-9)[0]
    if curved.size == 0:
        return None
    first = int(curved[0])
    flat = np.abs(np.diff(rho)) <= 1e-12 * np.abs(rho[1:]) + 1e-15
    i = first
    while i < flat.size:
        if flat[i] and abs(rho[i]) > 1e-9:
            j = i
            while j < flat.size and flat[j]:
                j += 1
            if time[j] - time[i] >= hold:
                return float(time[first]), float(time[j])
            i = j
        i += 1
    return None


def yaw_rebound(eps_r: Array) -> float:
    """
    Return the relative yaw's rebound after an initial disturbance (S0).

    The largest excursion to the opposite side of the initial relative yaw, over it:
    ``max(-sign(eps_0) eps_r) / |eps_0|`` (0 for a monotonic return).

    :param eps_r: relative yaw from the disturbance on [rad].
    :return: the rebound [-] (NaN without an initial disturbance).
    """
    initial = float(eps_r[0])
    if initial == 0.0:
        return math.nan
    return max(0.0, float(np.max(-math.copysign(1.0, initial) * eps_r))) / abs(initial)


METRICS = ('peak_cg_error_m', 'steady_cg_error_m', 'peak_look_ahead_lane_error_m',
           'yaw_overshoot', 'yaw_rate_overshoot', 'yaw_rebound', 'peak_wheel_angle_rad',
           'peak_wheel_rate_rad_per_s', 'peak_command_rad', 'peak_command_rate_rad_per_s',
           'steering_noise_rms_rad', 'law_share')
NEVER_DROVE = 'the law never drove'
FAILED = 'failed: '          # a row's notes start so when its run raised (not a result)


def empty_row(note: str) -> dict[str, Any]:
    """
    Return the row of a run that has no metrics: it diverged, or it failed.

    Every metric is NaN (so it misses every goal that applies to it), ``off_road`` is
    true.

    :param note: why, e.g. ``diverged at t = 3.2 s`` or ``failed: <one line>``.
    :return: the metrics part of the row.
    """
    row: dict[str, Any] = {name: math.nan for name in METRICS}
    row.update({'off_road': True, 'diverged_at_s': math.nan, 'notes': note})
    return row


def _diverged_at(result: SimResult, index: Optional[int]) -> float:
    lost = result.diverged_at
    return float(lost if index is None else np.asarray(lost)[index])


def run_row(result: SimResult, index: Optional[int], vehicle: VehicleParams,
            clean_command: Optional[Array],
            clean: Optional[Mapping[str, Array]] = None,
            safety: Optional[SafetyParams] = None) -> dict[str, Any]:
    """
    Return the metrics of one run of a batch.

    A run that diverged (``result.diverged_at``: its plant failed or its state became
    non-finite) has no metrics: :func:`empty_row` with ``diverged at t = ... s``.

    :param result: the batch.
    :param index: the run's column (None: a single run).
    :param vehicle: the controller's vehicle model (eq. 26's d_v for the look-ahead point).
    :param clean_command: the same run's command without sensor noise (noise metric).
    :param clean: the same run without sensor noise, ``eps_r`` and ``r`` (the overshoots'
        settling band under noise: :func:`step_metrics`).
    :param safety: the limits of the output stage the law ran through: ``law_share`` is
        the share of the run's steps at which the law's command went out whole (at or
        above ``safety.low_speed``; below it the node blends to and holds its last
        command), noted where below 1; a run the law never drove (0) misses every goal
        (:func:`goal_verdicts`). None: 1, no note.
    :return: the metrics.
    """
    def channel(name: str) -> Array:
        values = result[name]
        return values if index is None else values[:, index]

    lost = _diverged_at(result, index)
    if math.isfinite(lost):
        empty = empty_row(f'diverged at t = {lost:.3f} s')
        empty['diverged_at_s'] = lost
        return empty
    t = result.time
    period = float(t[1] - t[0])
    y, eps, rate, rho = channel('y_cg'), channel('eps_r'), channel('r'), channel('rho')
    v_x = channel('v_x')
    d_v, _ = paper_look_ahead(v_x, 0.0 * v_x, vehicle)
    lane_error = y + d_v * np.sin(eps) - arc_offset(rho, d_v, eps, True)
    wheel, command = channel('steering'), channel('steering_cmd')
    row: dict[str, Any] = {
        'peak_cg_error_m': float(np.max(np.abs(y))),
        'steady_cg_error_m': abs(float(np.mean(y[t >= t[-1] - FINAL_WINDOW]))),
        'peak_look_ahead_lane_error_m': float(np.max(np.abs(lane_error))),
        'yaw_overshoot': math.nan, 'yaw_rate_overshoot': math.nan,
        'yaw_rebound': math.nan,
        'peak_wheel_angle_rad': float(np.max(np.abs(wheel))),
        'peak_wheel_rate_rad_per_s': _peak_rate(wheel, period),
        'peak_command_rad': float(np.max(np.abs(command))),
        'peak_command_rate_rad_per_s': _peak_rate(command, period),
        'steering_noise_rms_rad': (math.nan if clean_command is None else float(
            np.sqrt(np.mean(np.square(command - clean_command))))),
        'off_road': bool(not np.all(np.isfinite(y)) or np.max(np.abs(y)) > 5.0),
        'diverged_at_s': math.nan,
        'law_share': 1.0,
    }
    window = curve_window(t, rho)
    notes = []
    if safety is not None:
        weight = np.asarray(per_element(lambda v: low_speed_weight(v, safety), v_x))
        row['law_share'] = float(np.mean(weight >= 1.0))
        if row['law_share'] == 0.0:
            notes.append(f'{NEVER_DROVE}: the speed stayed below safety.low_speed '
                         f'{safety.low_speed:g} m/s (the node holds its last command): '
                         'a goal that applies to it counts as missed')
        elif row['law_share'] < 1.0:
            notes.append(f"the law drove {100.0 * row['law_share']:.0f} % of the run: "
                         f'below safety.low_speed {safety.low_speed:g} m/s the node holds '
                         'its last command')
    if not np.any(np.abs(rho) > 1e-9):
        row['yaw_rebound'] = yaw_rebound(eps)
    elif window is None:
        notes.append('no curve entry to a constant curvature: no overshoot')
    else:
        for name, signal in (('yaw_overshoot', eps), ('yaw_rate_overshoot', rate)):
            twin = None if clean is None else clean[name]
            # no damping ratio: the league does not report it, and its fit was 90 % of a
            # curve run's time (0.25 s of 0.27 s at 37 m/s on S2)
            step = step_metrics(t, signal, window[0], FINAL_WINDOW, window[1], twin,
                                damping=False)
            row[name] = step.overshoot
            if step.note:
                notes.append(f'{name}: {step.note}')
    if clean_command is not None and not np.all(np.isfinite(clean_command)):
        notes.append('the noise-free twin diverged: no steering noise')
    row['notes'] = '; '.join(notes)
    return row


def _meets(goal: Goal, row: Mapping[str, Any]) -> bool:
    """
    Return whether a run meets a goal.

    A NaN metric, a run off the road and a run the law never drove (``law_share`` 0: its
    figures are the held command's) do not.

    :param goal: the goal.
    :param row: the run's row.
    :return: met.
    """
    return (bool(row[goal.metric] <= goal.bound) and not row['off_road']
            and row.get('law_share', 1.0) != 0.0)


def goal_verdicts(row: Mapping[str, Any]) -> tuple[list[str], list[str]]:
    """
    Return the goals that apply to a run and those of them it misses.

    A NaN metric (not measurable) counts as missed.

    :param row: the run's row.
    :return: ``(applicable, missed)`` goal names.
    """
    applicable, missed = [], []
    for goal in GOALS:
        if goal.applies(row):
            applicable.append(goal.name)
            if not _meets(goal, row):
                missed.append(goal.name)
    return applicable, missed


# -- the runs ------------------------------------------------------------------------------

def load_scenarios(names: Iterable[str]) -> dict[str, Scenario]:
    """
    Load scenarios by name from ``config/scenarios``.

    :param names: file names without ``.yaml``.
    :return: name -> scenario.
    """
    return {name: load_scenario(SCENARIO_DIR / f'{name}.yaml') for name in names}


def check_scenarios(names: Sequence[str], plants: Sequence[PlantCase], dt: float,
                    duration: Optional[float]) -> None:
    """
    Refuse, before any run, a scenario every run of it would refuse.

    A run cut by ``--duration`` before its external forces start, or a force off a
    plant's step (dev-probe81: the crosswind cut to 1.5 s gave a league of zeros); a
    ``--dt`` the control period or a plant's delay is no whole multiple of (dev-probe96:
    every run "failed: ParameterError", exit 1, after the whole league).

    :param names: the scenarios.
    :param plants: the plants (each has its own step, or ``dt``).
    :param dt: the league's plant step [s].
    :param duration: ``--duration`` (None: each scenario's own).
    :raises ToolError: naming the scenario.
    """
    from sim_plant.closed_loop_sim import check_steps, CONTROL_PERIOD, delay_steps
    from sim_plant.scenario import check_force_timing
    for case in plants:
        try:
            check_steps(case.dt or dt, CONTROL_PERIOD, 1.0)
            delay_steps(case.delay, case.dt or dt)
        except ParameterError as err:
            given = (f"the {case.name} plant's step {case.dt:g} s" if case.dt
                     else f'--dt {dt:g}')
            raise ToolError(f'{given}: {err}') from err
    for name in names:
        scenario = load_scenarios([name])[name]
        try:
            if duration is not None:
                scenario = replace(scenario, duration=duration)
            for case in plants:
                check_force_timing(scenario.forces, case.dt or dt)
        except ParameterError as err:
            cut = '' if duration is None else f' cut to --duration {duration:g} s'
            raise ToolError(f'--scenarios {name}{cut}: {err}') from err


def scenario_speeds(scenario: Scenario, speeds: Sequence[float]) -> list[float]:
    """
    Return the speeds a scenario runs at (its own profile only, when it is fixed).

    :param scenario: the scenario.
    :param speeds: the league's speeds.
    :return: the speeds.
    """
    return [scenario.speed.initial] if getattr(scenario.speed, 'fixed', False) else list(
        speeds)


def speed_seed(speed: float) -> int:
    """
    Return the noise seed of the runs at one speed (the same whichever speeds are run).

    :param speed: the run's initial speed [m/s].
    :return: ``NOISE_SEED`` + the speed's index in :data:`SPEEDS`, or for another speed
        ``NOISE_SEED + len(SPEEDS)`` + the speed in mm/s.
    """
    if speed in SPEEDS:
        return NOISE_SEED + SPEEDS.index(speed)
    return NOISE_SEED + len(SPEEDS) + int(round(speed * 1000.0))


def run_seed(speed: float, index: int) -> int:
    """
    Return the ``index``-th noise seed of the runs at one speed (``--seeds``).

    :param speed: the run's initial speed [m/s].
    :param index: 0 .. seeds - 1 (0: :func:`speed_seed`, the league's one seed).
    :return: ``speed_seed(speed) + index * SEED_STRIDE`` (distinct over every index
        below :data:`MAX_SEEDS` and every two speeds the league allows that differ in
        mm/s: speeds closer than 0.5 mm/s may share their seeds).
    """
    return speed_seed(speed) + index * SEED_STRIDE


def case_runs(case: PlantCase, speeds: Sequence[float],
              seeds: int = 1) -> list[tuple[float, Optional[int]]]:
    """
    Return the runs of one plant: ``(speed, noise seed)``, in the rows' order.

    :param case: the plant.
    :param speeds: the speeds [m/s].
    :param seeds: noise seeds per speed on a noisy plant (a noise-free plant runs each
        speed once, seed None).
    :return: per speed, its seeds in order.
    """
    if not case.noisy:
        return [(float(v), None) for v in speeds]
    return [(float(v), run_seed(float(v), k)) for v in speeds for k in range(seeds)]


def run_case(task: tuple[Any, ...]) -> list[dict[str, Any]]:
    """
    Run one law on one scenario: every plant, every speed (vectorized per plant).

    :param task: ``(law, scenario name, speeds, plants, vehicle, dt, duration[,
        settings[, seeds[, factory]]])`` (a task crosses to a worker process; duration
        None: the scenario's; settings: :class:`LawSettings`, the defaults without;
        seeds: noise seeds per speed on a noisy plant, 1 without; factory: the law's,
        :func:`sent_factory`, None: ``LAWS[law]``).
    :return: one row per run.
    """
    law_name, scenario_name, speeds, plants, league_vehicle, dt, duration = task[:7]
    settings = task[7] if len(task) > 7 else LawSettings()
    seeds = task[8] if len(task) > 8 else 1
    factory = task[9] if len(task) > 9 else None
    timing = task[10] if len(task) > 10 else None
    scenario = load_scenarios([scenario_name])[scenario_name]
    if duration is not None:
        scenario = replace(scenario, duration=duration)
    rows = []
    for case in plants:
        runs = case_runs(case, speeds, seeds)
        try:
            metrics = (_plant_runs(law_name, scenario_name, scenario, runs, case,
                                   league_vehicle, dt, settings, factory)
                       if timing is None else
                       _timed_runs(law_name, scenario_name, scenario, runs, case,
                                   league_vehicle, dt, settings, timing))
        except Exception as err:        # one plant's failure loses no other row
            metrics = [empty_row(FAILED + one_line(f'{type(err).__name__}: {err}'))] * len(
                runs)
        rows += [finish_row(law_name, scenario_name, case.name, speed, m, seed)
                 for (speed, seed), m in zip(runs, metrics)]
    return rows


def _plant_runs(law_name: str, scenario_name: str, scenario: Scenario,
                runs: Sequence[tuple[float, Optional[int]]], case: PlantCase,
                league_vehicle: VehicleParams, dt: float, settings: LawSettings,
                factory: LawFactory | str | None = None) -> list[dict[str, Any]]:
    vehicle = case.law_vehicle(league_vehicle)
    law = league_law(law_name, vehicle, settings, factory)
    common: dict[str, Any] = {'dt': case.dt or dt, 'preview_distance': PREVIEW_DISTANCE,
                              'delay': case.delay}
    speeds = list(dict.fromkeys(speed for speed, _ in runs))
    if not case.noisy:
        result = run(scenario, vehicle, law, case.plant,
                     initial_speed=np.asarray(speeds, dtype=float), **common)
        return [run_row(result, i, vehicle, None, safety=settings.safety)
                for i in range(len(speeds))]
    # the noise-free twin of each speed (one for all its seeds): the steering noise (S0)
    # and the noise's effect on the yaw responses
    twin = run(scenario, vehicle, law, case.plant,
               initial_speed=np.asarray(speeds, dtype=float), **common)
    result = run(scenario, vehicle, law, case.plant,
                 initial_speed=np.asarray([speed for speed, _ in runs], dtype=float),
                 noise=NoiseParams(), seed=[int(seed or 0) for _, seed in runs], **common)
    rows = []
    for i, (speed, _) in enumerate(runs):
        j = speeds.index(speed)
        rows.append(run_row(
            result, i, vehicle,
            twin['steering_cmd'][:, j] if scenario_name == NOISE_SCENARIO else None,
            {'yaw_overshoot': twin['eps_r'][:, j], 'yaw_rate_overshoot': twin['r'][:, j]},
            safety=settings.safety))
    return rows


#: the node's law and ``controller.schedule`` of each league law it runs by name
NODE_LAWS = {'paper_fixed': ('paper', 'fixed'), 'paper_eq26': ('paper', 'paper'),
             'pure_pursuit': ('pure_pursuit', None), 'stanley': ('stanley', None),
             'lqr': ('lqr', None), 'cg_compensated': ('cg_compensated', None)}


def node_core(law_name: str, vehicle: VehicleParams, settings: LawSettings
              ) -> SteeringController:
    """
    Return the controller node's core running a league law with these settings.

    :param law_name: a league law the node runs (a key of :data:`NODE_LAWS`).
    :param vehicle: the law's vehicle model.
    :param settings: the node's settings.
    :return: the core, as the node builds it from its parameters.
    :raises ToolError: a law the node does not run (one added to :data:`LAWS`).
    """
    if law_name not in NODE_LAWS:
        raise ToolError(f'law {law_name!r}: a sensor timing runs the core of the controller '
                        f'node, which runs only {", ".join(NODE_LAWS)}')
    law, schedule = NODE_LAWS[law_name]
    controller = (settings.controller if schedule is None
                  else replace(settings.controller, schedule=schedule))
    return SteeringController(vehicle, controller, settings.acceleration_source,
                              settings.curvature_rate, settings.safety, law,
                              settings.baselines, settings.lane_keeping,
                              settings.align_inputs, settings.curvature_at_yaw_stamp)


def _timed_runs(law_name: str, scenario_name: str, scenario: Scenario,
                runs: Sequence[tuple[float, Optional[int]]], case: PlantCase,
                league_vehicle: VehicleParams, dt: float, settings: LawSettings,
                timing: SensorTiming) -> list[dict[str, Any]]:
    """Return the rows of one plant's runs with a sensor timing (one run at a time)."""
    vehicle = case.law_vehicle(league_vehicle)
    cores: list[SteeringController] = []

    def one(speed: float, noise: Optional[NoiseParams], seed: int) -> SimResult:
        core = node_core(law_name, vehicle, settings)
        cores.append(core)
        return timed_run(scenario.at_speed(speed), core,
                         timing, case.plant, dt=case.dt or dt, delay=case.delay,
                         noise=noise, seed=seed, mode=settings.mode,
                         rate_hz=settings.rate_hz,
                         wait_for_stamps=settings.wait_for_matching_stamps,
                         sync_timeout=settings.sync_timeout,
                         watchdog_hz=settings.watchdog_rate_hz)

    rows = []
    twins: dict[float, SimResult] = {}
    for speed, seed in runs:
        if not case.noisy:
            rows.append(run_row(one(speed, None, 0), None, vehicle, None,
                                safety=settings.safety))
        else:
            if speed not in twins:              # the noise-free twin of each speed
                twins[speed] = one(speed, None, 0)
            twin = twins[speed]
            rows.append(run_row(
                one(speed, NoiseParams(), int(seed or 0)), None, vehicle,
                twin['steering_cmd'] if scenario_name == NOISE_SCENARIO else None,
                {'yaw_overshoot': twin['eps_r'], 'yaw_rate_overshoot': twin['r']},
                safety=settings.safety))
        told = checks_told(cores[-1])
        if told:
            rows[-1]['notes'] = '; '.join(n for n in (rows[-1]['notes'], told) if n)
    return rows


#: a run's notes name what the controller's checks told so (``--camera`` / ``--stream``)
CHECKS_TOLD = 'the controller told: '


def checks_told(core: SteeringController) -> str:
    """
    Return what the controller node's checks told over a run through its core.

    :param core: the core after the run.
    :return: ``the controller told: <check> <seconds> s, ...`` (the seconds each check
        found something, as ``/diagnostics`` counts them; the lead of the curvature read
        when the map timing check told one), or ``''`` when none did (dev-probe126: an
        IMU clock ahead ran without a word of what the node would have said).
    """
    told = [f'{name} {seconds:.2f} s' for name, seconds in core.turning.items()
            if seconds > 0.0]
    if not told:
        return ''
    lead = core.map_lead_seen
    if core.turning.get('curvature_early_or_late', 0.0) > 0.0 and lead is not None:
        told.append(f'road_curvature read {abs(lead[0]):.2f} m '
                    f'{"ahead of" if lead[0] > 0.0 else "behind"} the car')
    return CHECKS_TOLD + ', '.join(told)


def finish_row(law: str, scenario: str, plant: str, speed: float,
               metrics: Mapping[str, Any], seed: Optional[int] = None) -> dict[str, Any]:
    """
    Return a run's full row: its keys, metrics and goal verdicts.

    :param law: the law.
    :param scenario: the scenario.
    :param plant: the plant's name.
    :param speed: the initial speed [m/s].
    :param metrics: the run's metrics (:func:`run_row` or :func:`empty_row`).
    :param seed: its noise seed (None: a noise-free plant).
    :return: the row.
    """
    row: dict[str, Any] = {'law': law, 'scenario': scenario, 'plant': plant,
                           'speed_mps': speed, 'noise_seed': seed}
    row.update(metrics)
    applicable, missed = goal_verdicts(row)
    row['goals'] = ', '.join(applicable)
    row['goals_missed'] = ', '.join(missed)
    return row


def league(laws: Sequence[str], scenarios: Sequence[str], speeds: Sequence[float],
           plants: Sequence[PlantCase], vehicle: VehicleParams, dt: float = DT,
           workers: int = 1, duration: Optional[float] = None,
           progress: bool = False, settings: Optional[LawSettings] = None,
           seeds: int = 1, timing: Optional[SensorTiming] = None) -> list[dict[str, Any]]:
    """
    Run the league: every law on every scenario, plant and speed.

    :param laws: law names (keys of :data:`LAWS`).
    :param scenarios: scenario names (files in ``config/scenarios``).
    :param speeds: speeds [m/s].
    :param plants: the plants.
    :param vehicle: the vehicle (controller model and plant).
    :param dt: plant step [s].
    :param workers: processes (1: in this process).
    :param duration: cut every scenario to this duration [s] (None: their own; tests).
    :param progress: show a progress bar on stderr (one step per law and scenario).
    :param settings: the laws' settings (None: the package defaults, the limits of its
        ``config/controller.yaml``).
    :param seeds: noise seeds per speed on the noisy plant (:func:`run_seed`; 1: the
        league's one seed per speed).
    :param timing: each input on its own rate and latency through the controller node's
        core (:mod:`sim_plant.sensor_timing`, one run at a time); None: the offline
        runner, every input at each 10 ms step on one stamp.
    :return: one row per run, in a fixed order (law, scenario, plant, speed, seed).
    """
    settings = settings or LawSettings()
    loaded = load_scenarios(scenarios)
    # one task per law, scenario and plant (each plant's runs are independent: the same
    # rows as one task per law and scenario), so that the pool can balance the costly
    # multi-body runs
    factories = {law: sent_factory(law, workers) for law in laws}
    tasks = [(law, name, scenario_speeds(loaded[name], speeds), (case,), vehicle, dt,
              duration, settings, seeds, factories[law], timing)
             for law in laws for name in scenarios for case in plants]
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=len(tasks), desc='compare', unit='case', mininterval=0.5)
    try:
        if workers <= 1:
            results = []
            for task in tasks:
                raise_if_received()         # a Ctrl-C a lazy import swallowed
                results.append(_guarded(partial(run_case, task), task))
                if bar is not None:
                    bar.update(1)
        else:
            # the costliest tasks first (longest processing time first); rows in tasks'
            # order
            cost = [plant_cost(t[3][0], t[2], seeds, t[6] or loaded[t[1]].duration, dt)
                    for t in tasks]
            order = sorted(range(len(tasks)), key=lambda i: -cost[i])
            with stoppable_pool(workers) as pool:
                futures = {pool.submit(run_case, tasks[i]): i for i in order}
                done: dict[int, list[dict[str, Any]]] = {}
                for future in as_completed(futures):
                    raise_if_received()
                    i = futures[future]
                    done[i] = _guarded(future.result, tasks[i])
                    if bar is not None:
                        bar.update(1)
            results = [done[i] for i in range(len(tasks))]
    finally:
        if bar is not None:
            bar.close()
    return [row for rows in results for row in rows]


def _end_with(caller: int, period: float = 0.5) -> None:
    """
    End this worker process when its caller is gone.

    A caller killed with SIGKILL runs no cleanup: its workers waited for a task forever
    (dev-probe112, 90 s and on). A thread here looks every ``period`` whether the worker
    was handed to another parent.

    :param caller: the caller's process id.
    :param period: how often to look [s].
    """
    def watch() -> None:
        while os.getppid() == caller:
            time.sleep(period)
        os._exit(1)

    threading.Thread(target=watch, name='end_with_caller', daemon=True).start()


@contextmanager
def stoppable_pool(workers: int) -> Iterator[ProcessPoolExecutor]:
    """
    Give a process pool of fresh interpreters that an interrupt stops at once.

    Its workers are spawned, not forked: a fork copies the caller as it is, with the
    threads of whatever it runs beside the league (ROS 2 middleware, a progress bar's
    monitor) gone and their locks and objects left behind; a forked worker of a process
    that had run ROS nodes died of a segmentation fault while collecting that garbage
    (dev-sc49's full suite: a row "failed: BrokenProcessPool"). A spawned worker imports
    the package afresh (about 0.2 s) and owes nothing to its caller's state.

    On Ctrl-C or SIGTERM the pool's own exit would run every task not yet started (the
    whole league) and then throw the rows away. Here the tasks not started are dropped
    and the workers killed: they only compute, nothing on disk to finish. A worker
    whose caller was killed (SIGKILL: no cleanup ran) ends itself (:func:`_end_with`).
    A worker is a fresh interpreter: a law added to :data:`LAWS` at run time goes with
    its tasks (:func:`sent_factory`), and a script that starts the pool needs the
    ``if __name__ == '__main__':`` guard (Python's spawn start method; :data:`POOL_BROKEN`).
    A module's value the caller changed at run time (``compare.PREVIEW_DISTANCE``) is
    not the worker's: it runs the package as imported (dev-probe113); the league's own
    settings go with the tasks.

    :param workers: processes.
    :return: the pool (a context manager's).
    """
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=get_context('spawn'),
                               initializer=_end_with, initargs=(os.getpid(),))
    try:
        yield pool
    except BaseException:
        running = list((getattr(pool, '_processes', None) or {}).values())
        pool.shutdown(wait=False, cancel_futures=True)      # forgets its workers
        for process in running:
            process.kill()
        raise
    pool.shutdown()


RUN_STEP_COST = 0.35     # a CommonRoad multi-body run's step / a package plant's batch step
BATCH_RUNS = 300         # a package plant's batch step costs as much as this many runs' share


def task_cost(case: PlantCase, runs: int, duration: float, dt: float) -> float:
    """
    Return a task's rough relative cost, to start the costliest first.

    A package plant steps its whole batch vectorized, at about the cost of one run
    (0.56-0.87 ms of CPU per step with 4 runs, measured) plus about 2.3 us per run and
    step (a ``--seeds`` batch of thousands of runs: S0, 4000 runs, 22 s; 100 runs,
    4.7 s); the CommonRoad models step one run after the other in pure Python (the
    multi-body model: 0.27 ms per run step, at 2 ms steps instead of 5).

    :param case: the plant.
    :param runs: the number of runs (speeds, times the seeds on a noisy plant).
    :param duration: the simulated time [s].
    :param dt: the league's plant step [s].
    :return: the cost (arbitrary units).
    """
    steps = duration / (case.dt or dt)
    if case.plant.model.startswith('commonroad'):
        return steps * runs * RUN_STEP_COST
    return steps * (1.0 + runs / BATCH_RUNS)


def plant_cost(case: PlantCase, speeds: Sequence[float], seeds: int, duration: float,
               dt: float) -> float:
    """
    Return the rough relative cost of one plant's runs of a task (:func:`task_cost`).

    A noisy plant also runs the noise-free twin of each speed (:func:`_plant_runs`): at
    one seed it costs about twice its noise-free version (measured: S2 4 s at 10-37 m/s,
    CPU 2.55 against 1.37 s on the CommonRoad multi-body plant, 0.98 against 0.50 s on the
    nonlinear one).

    :param case: the plant.
    :param speeds: the task's speeds.
    :param seeds: noise seeds per speed on a noisy plant.
    :param duration: the simulated time [s].
    :param dt: the league's plant step [s].
    :return: the cost (arbitrary units).
    """
    cost = task_cost(case, len(case_runs(case, speeds, seeds)), duration, dt)
    if case.noisy:
        cost += task_cost(case, len(speeds), duration, dt)
    return cost


#: why a pool's worker may have died, where the pool only says it broke
POOL_BROKEN = ('a worker process died (its error, if any, is on stderr): killed (out of '
               'memory?), or it could not start or unpickle a task: a worker is a fresh '
               'interpreter that imports the main module and the modules of the laws sent '
               'to it, so a script calling league with workers > 1 needs an `if __name__ '
               "== '__main__':` guard, must be a file (not stdin), and its laws' modules "
               'must be importable; workers 1 runs in this process')


def _guarded(runner: Callable[[], list[dict[str, Any]]], task: Any) -> list[dict[str, Any]]:
    """
    Return a task's rows, or one ``failed: ...`` row per run when the task raised.

    (run_case already keeps one plant's failure to that plant's rows; this catches the
    rest: a scenario that does not load, a worker process that died.)

    :param runner: runs the task (or fetches its result from the pool).
    :param task: the task (see :func:`run_case`).
    :return: its rows.
    """
    law, scenario, speeds, plants = task[:4]
    seeds = task[8] if len(task) > 8 else 1
    try:
        return runner()
    except Exception as err:            # one task's failure loses no other row
        text = str(err)
        if isinstance(err, BrokenProcessPool):
            # dev-probe112: a script without the main guard (or read from stdin) gives
            # this and nothing else in the rows
            text = POOL_BROKEN
        note = FAILED + one_line(f'{type(err).__name__}: {text}')
        return [finish_row(law, scenario, case.name, v, empty_row(note), seed)
                for case in plants for v, seed in case_runs(case, speeds, seeds)]


# -- reports -------------------------------------------------------------------------------

def _worst(rows: Iterable[Mapping[str, Any]], metric: str) -> float:
    values = [float(r[metric]) for r in rows if not math.isnan(float(r[metric]))]
    return max(values) if values else math.nan


def summary(rows: Sequence[Mapping[str, Any]], laws: Sequence[str],
            plant: str = GOAL_PLANT) -> list[dict[str, Any]]:
    """
    Return one league row per law on a plant (worst cases) and its goal count.

    :param rows: the runs.
    :param laws: the laws, in order.
    :param plant: the plant of the metric columns. On the goal plant the run counts (off
        the road, diverged, failed) and the goal count are over every plant's runs (the
        goals name their own plants); on another plant the run counts are over its runs
        and there is no goal count (no goal is judged on it).
    :return: the league rows.
    """
    table = []
    for law in laws:
        mine = [r for r in rows if r['law'] == law]
        goal = [r for r in mine if r['plant'] == plant]
        counted = mine if plant == GOAL_PLANT else goal
        at37 = [r for r in goal if r['speed_mps'] == 37.0]
        applicable = sum(len(r['goals'].split(', ')) for r in mine if r['goals'])
        missed = sum(len(r['goals_missed'].split(', ')) for r in mine if r['goals_missed'])
        entry: dict[str, Any] = {'law': law}
        for name in ('s1_paper_step', 's2_curve_entry', 's3_s_bend', 's4_lane_change'):
            entry[f'{name[:2].upper()} peak cg 37 [cm]'] = 100.0 * _worst(
                [r for r in at37 if r['scenario'] == name], 'peak_cg_error_m')
        entry['S5 peak cg [cm]'] = 100.0 * _worst(
            [r for r in goal if r['scenario'] == 's5_envelope'], 'peak_cg_error_m')
        entry['steady arc [cm]'] = 100.0 * _worst(
            [r for r in goal if r['scenario'] in ('s1_paper_step', 's2_curve_entry')],
            'steady_cg_error_m')
        entry['yaw overshoot 30-37 [%]'] = 100.0 * _worst(
            [r for r in goal if r['speed_mps'] >= 30.0 and r['scenario'] in
             ('s1_paper_step', 's2_curve_entry', 's3_s_bend')], 'yaw_overshoot')
        entry['S0 rebound 37 [%]'] = 100.0 * _worst(
            [r for r in at37 if r['scenario'] == 's0_straight'], 'yaw_rebound')
        entry['S0 noise 37 [mrad]'] = 1000.0 * _worst(
            [r for r in at37 if r['scenario'] == 's0_straight'], 'steering_noise_rms_rad')
        entry['peak wheel rate [rad/s]'] = _worst(goal, 'peak_wheel_rate_rad_per_s')
        entry['runs off the road'] = sum(bool(r['off_road']) for r in counted)
        entry['diverged runs'] = sum(math.isfinite(float(r['diverged_at_s']))
                                     for r in counted)
        entry['failed runs'] = sum(str(r['notes']).startswith(FAILED) for r in counted)
        if plant == GOAL_PLANT:
            entry['goals met'] = f'{applicable - missed}/{applicable}'
        table.append(entry)
    return table


def extra_scenario(rows: Sequence[Mapping[str, Any]], laws: Sequence[str],
                   scenario: str) -> list[dict[str, Any]]:
    """
    Return the peak CG error [cm] of each law on a scenario for every plant and speed.

    :param rows: the runs.
    :param laws: the laws.
    :param scenario: the scenario (one of :data:`EXTRA_SCENARIOS`).
    :return: one row per law, a column per plant and speed (worst over seeds).
    """
    mine = [r for r in rows if r['scenario'] == scenario]
    columns = list(dict.fromkeys((r['plant'], r['speed_mps']) for r in mine))
    return [{'law': law, **{f'{plant} {speed:g}': 100.0 * _worst(
        [r for r in mine if r['law'] == law and r['plant'] == plant
         and r['speed_mps'] == speed], 'peak_cg_error_m') for plant, speed in columns}}
        for law in laws]


def scenario_label(name: str) -> str:
    """
    Return a scenario's column label: ``S0``-``S5`` for the league's, else its name.

    :param name: the scenario's name.
    :return: the label.
    """
    return name[:2].upper() if name in SCENARIOS else name


def per_scenario(rows: Sequence[Mapping[str, Any]], laws: Sequence[str], plant: str,
                 speed: float) -> list[dict[str, Any]]:
    """
    Return the peak CG error [cm] of each law on each scenario for one plant and speed.

    :param rows: the runs.
    :param laws: the laws.
    :param plant: the plant.
    :param speed: the speed [m/s] (S5 runs its own profile and is listed anyway).
    :return: one row per law.
    """
    table = []
    for law in laws:
        entry: dict[str, Any] = {'law': law}
        mine = [r for r in rows if r['law'] == law and r['plant'] == plant and (
            r['speed_mps'] == speed or r['scenario'] == 's5_envelope')]
        for scenario in dict.fromkeys(r['scenario'] for r in mine):    # worst over seeds
            entry[scenario_label(scenario)] = 100.0 * _worst(
                [r for r in mine if r['scenario'] == scenario], 'peak_cg_error_m')
        table.append(entry)
    return table


def goal_unit(metric: str) -> tuple[float, str]:
    """
    Return the factor and unit a goal's metric is reported in.

    :param metric: a row field (``*_m``, ``*_rad`` or a ratio).
    :return: ``(100, 'cm')``, ``(1000, 'mrad')`` or ``(100, '%')``.
    """
    if metric.endswith('_m'):
        return 100.0, 'cm'
    if metric.endswith('_rad'):
        return 1000.0, 'mrad'
    return 100.0, '%'


CELL_COLUMNS = ('law', 'goal', 'scenario', 'speed_mps', 'runs', 'met_fraction',
                'not_measurable', 'mean', 'median', 'p95', 'worst', 'unit', 'bound')


def goal_cells(rows: Sequence[Mapping[str, Any]],
               laws: Sequence[str]) -> list[dict[str, Any]]:
    """
    Return each goal's verdict over the seeds of each run it applies to.

    One row per law, goal, scenario and speed: how many runs (seeds) there are, the share
    that meet the goal (as :func:`goal_verdicts`: a NaN metric or a run off the road
    misses it), how many have no value (not measurable), and the metric's mean, median,
    95th percentile and worst over the runs with one, in the goal's unit
    (:func:`goal_unit`).

    :param rows: the runs.
    :param laws: the laws, in order.
    :return: the rows.
    """
    table = []
    for law in laws:
        mine = [r for r in rows if r['law'] == law]
        for goal in GOALS:
            applies = [r for r in mine if goal.applies(r)]
            scale, unit = goal_unit(goal.metric)
            for scenario, speed in dict.fromkeys((r['scenario'], r['speed_mps'])
                                                 for r in applies):
                runs = [r for r in applies
                        if r['scenario'] == scenario and r['speed_mps'] == speed]
                values = np.array([float(r[goal.metric]) for r in runs], dtype=float)
                values = scale * values[np.isfinite(values)]
                stats = ([float(np.mean(values)), float(np.median(values)),
                          float(np.percentile(values, 95.0)), float(np.max(values))]
                         if values.size else [math.nan] * 4)
                table.append({
                    'law': law, 'goal': goal.name, 'scenario': scenario, 'speed_mps': speed,
                    'runs': len(runs), 'met_fraction': sum(_meets(goal, r) for r in runs)
                    / len(runs), 'not_measurable': len(runs) - int(values.size),
                    'mean': stats[0], 'median': stats[1], 'p95': stats[2], 'worst': stats[3],
                    'unit': unit, 'bound': scale * goal.bound})
    return table


def goals_over_seeds(cells: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """
    Return one row per law and goal from :func:`goal_cells`: its share of runs met.

    :param cells: :func:`goal_cells`' rows.
    :return: law, goal, runs, met [%], the cell met least often and its share, and the
        worst cell's median / 95th percentile / worst (the cell with the highest 95th
        percentile), in the goal's unit.
    """
    table = []
    for key in dict.fromkeys((c['law'], c['goal']) for c in cells):
        mine = [c for c in cells if (c['law'], c['goal']) == key]
        runs = sum(int(c['runs']) for c in mine)
        met = sum(float(c['met_fraction']) * int(c['runs']) for c in mine)
        least = min(mine, key=lambda c: float(c['met_fraction']))
        measured = [c for c in mine if math.isfinite(float(c['p95']))]
        high = max(measured, key=lambda c: float(c['p95'])) if measured else mine[0]
        table.append({
            'law': key[0], 'goal': key[1], 'runs': runs,
            'met [%]': 100.0 * met / runs,
            'met least': f"{least['scenario'][:2].upper()} {least['speed_mps']:g} m/s: "
                         f"{100.0 * float(least['met_fraction']):.0f} %",
            'not measurable': sum(int(c['not_measurable']) for c in mine),
            'highest cell': f"{high['scenario'][:2].upper()} {high['speed_mps']:g} m/s",
            'median': high['median'], '95th pct': high['p95'], 'worst': high['worst'],
            'unit': high['unit']})
    return table


def missed_runs(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """
    Return the goals missed, one row per law, scenario, plant and speed.

    :param rows: the runs.
    :return: ``goals_missed`` with, where a cell has several seeds, in how many of its
        runs each goal was missed (``name (k/n)``).
    """
    table = []
    for key in dict.fromkeys((r['law'], r['scenario'], r['plant'], r['speed_mps'])
                             for r in rows):
        runs = [r for r in rows
                if (r['law'], r['scenario'], r['plant'], r['speed_mps']) == key]
        counts: dict[str, int] = {}
        for r in runs:
            for name in filter(None, str(r['goals_missed']).split(', ')):
                counts[name] = counts.get(name, 0) + 1
        if counts:
            table.append({'law': key[0], 'scenario': key[1], 'speed_mps': key[3],
                          'goals_missed': ', '.join(
                              name if len(runs) == 1 else f'{name} ({k}/{len(runs)})'
                              for name, k in counts.items())})
    return table


def plot_title(rows: Sequence[Mapping[str, Any]]) -> str:
    """
    Return the title of the plot's peak panel: what its bars are the worst of.

    :param rows: the runs.
    :return: the title (with the seeds per run when there are several).
    """
    cells = Counter((r['law'], r['scenario'], r['speed_mps']) for r in rows
                    if r['plant'] == GOAL_PLANT)
    seeds = max(cells.values(), default=1)
    return ('37 m/s (S5: 10-37-10 m/s), nonlinear + 20 ms + noise'
            + (f', worst of {seeds} noise seeds' if seeds > 1 else ''))


def write_plot(rows: Sequence[Mapping[str, Any]], laws: Sequence[str], path: Path) -> Path:
    """
    Plot peak CG error per scenario at 37 m/s, S0 noise and rebound, on the goal plant.

    :param rows: the runs.
    :param laws: the laws.
    :param path: the PNG to write.
    :return: the path.
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    scen = [s for s in SCENARIOS + EXTRA_SCENARIOS if any(r['scenario'] == s for r in rows)]
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5), gridspec_kw={'width_ratios': [3, 1, 1]})
    width = 0.8 / max(len(laws), 1)
    plotted = False
    for j, law in enumerate(laws):
        mine = [r for r in rows if r['law'] == law and r['plant'] == GOAL_PLANT]
        peaks = [100.0 * _worst([r for r in mine if r['scenario'] == s and (
            r['speed_mps'] == 37.0 or s == 's5_envelope')], 'peak_cg_error_m') for s in scen]
        axes[0].bar(np.arange(len(scen)) + j * width, peaks, width, label=law)
        plotted = plotted or any(p > 0.0 for p in peaks)       # NaN: no such run
        s0 = [r for r in mine if r['scenario'] == 's0_straight' and r['speed_mps'] == 37.0]
        axes[1].bar(j, 1000.0 * _worst(s0, 'steering_noise_rms_rad'))
        axes[2].bar(j, 100.0 * _worst(s0, 'yaw_rebound'))
    axes[0].set_xticks(np.arange(len(scen)) + 0.4 - width / 2)
    axes[0].set_xticklabels([scenario_label(s) for s in scen])
    if plotted:             # log of nothing: matplotlib refuses (a league without the plant)
        axes[0].set_yscale('log')
    axes[0].set_ylabel('peak CG lateral error y_cg [cm] (log)' if plotted else
                       f'no {GOAL_PLANT} run at 37 m/s in this league')
    axes[0].set_title(plot_title(rows))
    axes[0].legend(fontsize=8)
    for ax, label in ((axes[1], 'S0 steering noise rms [mrad]'),
                      (axes[2], 'S0 yaw rebound [%]')):
        ax.set_xticks(range(len(laws)))
        ax.set_xticklabels(laws, rotation=60, ha='right', fontsize=8)
        ax.set_title(label, fontsize=9)
    axes[1].axhline(5.0, color='k', lw=0.8, ls='--')
    axes[2].axhline(50.0, color='k', lw=0.8, ls='--')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_report(rows: Sequence[Mapping[str, Any]], laws: Sequence[str], out: Path,
                 plot: bool = True, duration: Optional[float] = None,
                 settings: Optional[tuple[str, LawSettings]] = None,
                 seeds: int = 1, timing: Optional[SensorTiming] = None,
                 timing_checked: Optional[str] = None) -> Path:
    """
    Write league.csv (every run), league.md (summary, goals, per scenario), league.png.

    Also goals_over_seeds.csv (:func:`goal_cells`: each goal's share of runs met per
    scenario and speed; with one seed each share is 0 or 1).

    :param rows: the runs.
    :param laws: the laws.
    :param out: the output folder.
    :param plot: also write the PNG.
    :param duration: the runs were cut to this duration [s] (said in the table's head).
    :param settings: the params file the laws' settings came from and the settings
        (said in the table's head; None: the package defaults).
    :param seeds: noise seeds per speed on the noisy plant (more than 1: league.md has
        a section with each goal's share of runs met).
    :param timing: the inputs' timing the runs had (said in the table's head; None: the
        offline runner's, every input at each 10 ms step on one stamp).
    :param timing_checked: the sampled checks' line at that timing (:func:`timing_check`;
        said below the timing).
    :return: the markdown file.
    """
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / 'league.csv', rows)
    cells = goal_cells(rows, laws)
    write_csv(out / 'goals_over_seeds.csv', cells, CELL_COLUMNS)
    plants = list(dict.fromkeys(r['plant'] for r in rows))
    text = [
        '# League table: every law x '
        + ('S0-S5' if {r['scenario'] for r in rows} <= set(SCENARIOS) else ', '.join(
            scenario_label(name) for name in dict.fromkeys(r['scenario'] for r in rows)))
        + ' x plants x speeds', '',
        'Same inputs (the contract through the same sensors; noise seeds per run), '
        f'curvature preview {PREVIEW_DISTANCE:g} m, the same plant and actuator for every '
        "law; every law's command passes the controller node's output stage (its angle "
        'and rate limits, `safety.*`). '
        f'Goal plant: `{GOAL_PLANT}` (Fiala tyres, 50 ms actuator lag, 0.8 rad/s, '
        f'{1000 * DELAY:g} ms transport delay, default sensor noise). Worst case over the '
        'runs of each column; goals as in issue 14 (a NaN metric counts as missed). In the '
        "first table the metric columns are the goal plant's runs; the runs off the road, "
        'diverged and failed, and the goals met, count every plant of the league. '
        'Definitions: docs/baselines.md.', '',
        *([] if timing is None else [
            f'**Sensor timing (`--camera` / `--stream`): {timing.describe()}; every run '
            "through the controller node's core (its input checks, event or timer "
            'answers, watchdog), the inputs stamped at their capture: not the timing of '
            'the goal rows (every input at 100 Hz on one stamp).**', '']),
        *([] if timing_checked is None else [
            f'**Checked: {timing_checked}.**', '']),
        *([] if duration is None else [
            f'**Every scenario cut to {duration:g} s of simulated time (`--duration`): a '
            "quick look, not the league; the goal rows assume the scenarios' own.**", '']),
        *([] if settings is None else [
            f"**The laws' settings are those of `{settings[0]}` (`--controller`), not the "
            'package defaults the goal rows were set for:** '
            + ('; '.join(f'`{line}`' for line in settings_changes(settings[1],
                                                                  timing is not None))
               or 'none differs from the defaults') + '.', '']),
        *([] if seeds == 1 else [
            f'**{seeds} noise seeds per speed on the noisy plants (`--seeds`): every worst '
            'case below is over them, and the goal count counts runs.**', '']),
        # a noisy run a goal applies to (the independent plant's runs: none)
        *([] if seeds != 1 or not any(r['noise_seed'] is not None and r['goals']
                                      for r in rows) else [
            '**One noise seed per speed on the noisy plants: a goal met here may be missed '
            "with another seed (`--seeds N`: each goal's share of N runs).**", '']),
        # dev-probe89: without the goal plant the summary's metric columns were all '-'
        # and nothing said why
        *([] if GOAL_PLANT in plants else [
            f'**This league has no `{GOAL_PLANT}` run (`--plants`), so the metric columns '
            "below, which are the goal plant's, are empty: the runs are in the per-plant "
            'tables further down and in `league.csv`.**', '']),
        markdown_table(summary(rows, laws), digits=3), '']
    if INDEPENDENT_PLANT in plants:
        text += [f'## The same columns on `{INDEPENDENT_PLANT}`', '',
                 'The CommonRoad multi-body model (BMW 320i; its own tyres, suspension and '
                 'wheel dynamics; the laws given its single-track mapping) with the goal '
                 f"plant's {1000 * DELAY:g} ms transport delay and sensor noise: a plant the "
                 'laws were not written against. No goal row is judged on it (no goal '
                 "count: that of the table above is over the goals' plants); it is reported "
                 'beside the goal plant. Its runs off the road, diverged and failed runs '
                 'are those on this plant (above: on every plant).',
                 '', markdown_table(summary(rows, laws, INDEPENDENT_PLANT), digits=3), '']
    if seeds > 1:
        text += [f'## Goals over {seeds} noise seeds', '',
                 f'Each run of a noisy plant repeated with {seeds} noise seeds per speed '
                 f'(seed k of a speed: `speed_seed` + k x {SEED_STRIDE:,}; k = 0 is the '
                 "league's one seed). Per law and goal: the share of its runs that meet it "
                 '(a NaN metric counts as missed), the scenario and speed where it is met '
                 'least often, and the median, 95th percentile and worst of the metric in '
                 'the cell where its 95th percentile is highest. Every cell: '
                 '`goals_over_seeds.csv`.'
                 + ''.join(f' `{name}` is on a noise-free plant: one run per speed, not '
                           f'{seeds}.' for name in dict.fromkeys(
                               c['goal'] for c in cells if c['goal'] in NOISE_FREE_GOALS)),
                 '',
                 markdown_table(goals_over_seeds(cells), digits=3) if cells else
                 'none: no goal applies to a run of this league', '']
    for plant in plants:
        text += [f'## Peak CG error [cm] at 37 m/s, plant `{plant}` (S5: its profile)', '',
                 markdown_table(per_scenario(rows, laws, plant, 37.0), digits=3), '']
    for name in EXTRA_SCENARIOS:
        if any(r['scenario'] == name for r in rows):
            # no goal and no summary column is about it: every plant and speed here
            text += [f'## `{name}`: peak CG error [cm] per plant and speed', '',
                     'Worst over the noise seeds; no goal of issue 14 is about this '
                     'scenario.', '',
                     markdown_table(extra_scenario(rows, laws, name), digits=3), '']
    broken = [r for r in rows if math.isfinite(float(r['diverged_at_s']))
              or str(r['notes']).startswith(FAILED)]
    text += ['## Runs that diverged or failed', '',
             'A run **diverged** when its plant model failed (e.g. the CommonRoad '
             "multi-body model's wheel-slip division by zero once a wheel stops while the car "
             'moves) or its state became non-finite: it has no metrics and misses every goal '
             'that applies to it. A **failed** run raised an error in the tool (a bug, not '
             'a result): `compare` exits 1 after writing this report.', '',
             markdown_table([{k: r[k] for k in ('law', 'scenario', 'plant', 'speed_mps',
                                                'notes')} for r in broken])
             if broken else 'none', '']
    if timing is not None:
        told = [r for r in rows if CHECKS_TOLD in str(r['notes'])]
        text += ["## What the controller's checks told", '',
                 "The controller node's checks (`/diagnostics`, docs/safety.md) ran in every "
                 'run through its core: the runs where one found something, with the '
                 'seconds it did.', '',
                 markdown_table([{**{k: r[k] for k in ('law', 'scenario', 'plant',
                                                       'speed_mps', 'noise_seed')},
                                  'told': str(r['notes']).split(CHECKS_TOLD)[1]}
                                 for r in told]) if told else 'none', '']
    held = [r for r in rows if float(r.get('law_share', 1.0)) < 1.0]
    if held:
        text += ['## Runs the law did not drive throughout', '',
                 'Below `safety.low_speed` the output stage blends to the command sent '
                 'last above it and holds that, as the node does: those steps are not the '
                 "law's. `law_share`: the share of a run's steps at which the law's command "
                 'went out whole. A run the law never drove misses every goal that applies '
                 'to it.', '',
                 markdown_table([{k: r[k] for k in ('law', 'scenario', 'plant', 'speed_mps',
                                                    'law_share', 'notes')} for r in held],
                                digits=3), '']
    missed = missed_runs(rows)
    text += ['## Goals missed', '',
             *([] if seeds == 1 else [
                 '(k/n: missed in k of the n runs of the noise seeds.)', '']),
             markdown_table(missed) if missed else 'none', '']
    if plot:
        png = write_plot(rows, laws, out / 'league.png')
        text.append(f'![league]({png.name})')
    path = out / 'league.md'
    path.write_text('\n'.join(text) + '\n', encoding='utf-8')
    return path


# -- tuning (the same procedure for every baseline) ----------------------------------------

# the refined grids (docs/baselines.md gives the coarse 25-point first pass of each)
TUNING_GRIDS: dict[str, list[Any]] = {
    'pure_pursuit': [PurePursuitParams(velocity_ratio=a, curvature_ratio=b)
                     for a in (0.3, 0.45, 0.6) for b in (0.0, 120.0)],
    'stanley': [StanleyParams(gain=a, yaw_rate_gain=b)
                for a in (2.5, 4.0, 6.0) for b in (0.05, 0.1, 0.2)],
    'lqr': [LqrParams(q_lateral=a, q_heading=b)
            for a in (0.003, 0.01, 0.03) for b in (0.03, 0.1, 0.3)],
}
TUNING_NOISE_LIMIT = 0.005      # [rad] rms on S0 at 37 m/s, the noise goal
TUNING_SPEEDS = (30.0, 37.0)    # where the laws differ (10-20 m/s: all within 3 cm)
TUNING_DT = 0.005               # [s] plant step of the tuning runs


def tune_point(task: tuple[str, Any, VehicleParams, float, Optional[float]]
               ) -> dict[str, Any]:
    """
    Score one parameter set: worst peak CG error on S1 and S2, S0 noise at 37 m/s.

    :param task: ``(law, params, vehicle, dt, duration)`` (duration None: the
        scenarios' own).
    :return: the scores and parameters.
    """
    name, params, vehicle, dt, duration = task
    scenarios = load_scenarios(('s0_straight', 's1_paper_step', 's2_curve_entry'))
    if duration is not None:
        scenarios = {k: replace(v, duration=duration) for k, v in scenarios.items()}
    law = NodeOutputStage(baseline_law(name, vehicle,
                                       replace(BaselineParams(), **{name: params})),
                          vehicle.wheelbase, package_safety())
    case = next(p for p in PLANTS if p.name == GOAL_PLANT)
    v0 = np.asarray(TUNING_SPEEDS)
    peak = 0.0
    for scenario in ('s1_paper_step', 's2_curve_entry'):
        result = run(scenarios[scenario], vehicle, law, case.plant, initial_speed=v0,
                     dt=dt, preview_distance=PREVIEW_DISTANCE, delay=case.delay,
                     noise=NoiseParams(), seed=[NOISE_SEED + i for i in range(v0.size)])
        y = result['y_cg']
        peak = max(peak, float(np.max(np.abs(y))) if np.all(np.isfinite(y)) else math.inf)
    s0 = scenarios['s0_straight']
    common: dict[str, Any] = {'initial_speed': 37.0, 'dt': dt,
                              'preview_distance': PREVIEW_DISTANCE,
                              'delay': case.delay}
    clean = run(s0, vehicle, law, case.plant, **common)['steering_cmd']
    noisy = run(s0, vehicle, law, case.plant, noise=NoiseParams(), seed=NOISE_SEED,
                **common)['steering_cmd']
    noise = float(np.sqrt(np.mean(np.square(noisy - clean))))
    fields = {k: getattr(params, k) if k in GRID_FIELDS[name] else math.nan
              for k in ALL_GRID_FIELDS}
    return {'law': name, **fields, 'worst_peak_cg_s1_s2_m': peak,
            'noise_s0_37_rad': noise, 'feasible': noise <= TUNING_NOISE_LIMIT}


GRID_FIELDS = {'pure_pursuit': ('velocity_ratio', 'curvature_ratio'),
               'stanley': ('gain', 'yaw_rate_gain'), 'lqr': ('q_lateral', 'q_heading')}
ALL_GRID_FIELDS = tuple(f for fields in GRID_FIELDS.values() for f in fields)


def tune(laws: Sequence[str], vehicle: VehicleParams, dt: float, workers: int,
         duration: Optional[float] = None) -> list[dict[str, Any]]:
    """
    Score each baseline's grid; the best is the feasible point with the least peak error.

    :param laws: baseline names.
    :param vehicle: the vehicle.
    :param dt: plant step [s].
    :param workers: processes.
    :param duration: cut every scenario to this duration [s] (None: their own).
    :return: one row per grid point, the chosen ones marked ``best``.
    """
    tasks = [(name, params, vehicle, dt, duration) for name in laws
             for params in TUNING_GRIDS[name]]
    with stoppable_pool(max(workers, 1)) as pool:
        rows = []
        for row in pool.map(tune_point, tasks):
            raise_if_received()
            rows.append(row)
    for name in laws:
        feasible = [r for r in rows if r['law'] == name and r['feasible']]
        mine = feasible or [r for r in rows if r['law'] == name]
        best = min(mine, key=lambda r: (r['worst_peak_cg_s1_s2_m'], r['noise_s0_37_rad']))
        for r in rows:
            if r['law'] == name:
                r['best'] = r is best
    return rows


# -- command line --------------------------------------------------------------------------

def main(argv: Sequence[str] | None = None) -> int:
    """
    Run the league (or the tuning grids) and write the tables.

    :param argv: command-line arguments.
    :return: exit code.
    """
    p = parser('league table: every law x scenarios S0-S5 x plants x speeds', plot=False)
    p.add_argument('--laws', nargs='+', default=list(LAWS), choices=list(LAWS))
    p.add_argument('--scenarios', nargs='+', default=list(SCENARIOS),
                   choices=SCENARIOS + EXTRA_SCENARIOS,
                   help='default: S0-S5; crosswind (a 1.5 kN side force on a straight '
                   'from 2 to 12 s) runs only when named')
    p.add_argument('--plants', nargs='+', default=[c.name for c in PLANTS],
                   choices=[c.name for c in PLANTS])
    p.add_argument('--speeds', type=number(0.0, MAX_SPEED, low_open=True, unit='m/s'),
                   nargs='+', default=list(SPEEDS), metavar='M/S')
    p.add_argument('--dt', type=number(1.0e-4, 0.05, unit='s'), default=DT,
                   help='plant step [s] (CommonRoad: 0.002)')
    p.add_argument('--workers', type=number(1, 256, integer=True), default=2,
                   help='processes')
    p.add_argument('--duration', type=number(MIN_DURATION, MAX_DURATION, unit='s'),
                   default=None, metavar='S',
                   help='cut every scenario to S seconds of simulated time (a quick look; '
                   f'at least {MIN_DURATION:g} s, what the metrics need; default: each '
                   "scenario's own, which the goal rows assume)")
    p.add_argument('--out', type=Path, default=Path('bags') / 'compare',
                   help='folder for league.md, league.csv, league.png (new, empty or '
                   'written by compare; see --overwrite)')
    p.add_argument('--overwrite', action='store_true',
                   help='write into a non-empty --out folder compare did not write, '
                   'replacing files of its names there (nothing else is touched)')
    p.add_argument('--no-plots', action='store_true')
    p.add_argument('--no-progress', action='store_true',
                   help='no progress bar (it goes to stderr, one step per law and scenario)')
    p.add_argument('--tune', action='store_true',
                   help="score the baselines' tuning grids instead (writes tuning.csv)")
    p.add_argument('--seeds', type=number(1, MAX_SEEDS, integer=True), default=1,
                   metavar='N',
                   help='noise seeds per speed on the noisy plants (nonlinear_delay_noise, '
                   f'{INDEPENDENT_PLANT}): '
                   "their runs are repeated with N seeds, and league.md gives each goal's "
                   'share of runs met (default 1: the league, one seed per speed)')
    p.add_argument('--controller', type=Path, default=None, metavar='YAML',
                   help='run every law with the settings the controller node would run '
                   "with this params file (controller.*, lane_keeping.*, the baselines' "
                   "sections, the limits of the node's output stage every law runs "
                   'through: safety.max_steering_angle, max_steering_rate, '
                   'max_lateral_acceleration, low_speed, low_speed_blend; default: the '
                   'package defaults, the one tuning the goal rows are for)')
    p.add_argument('--camera', default=None, metavar='HZ/S[/S]',
                   help="the lateral error's rate and latency (a lane camera: 20/0.12 is "
                   '20 Hz, stamped at the frame and 120 ms late; a third number its '
                   "clock's offset, as for --stream): every run goes through the "
                   "controller node's core with the inputs on their own stamps "
                   '(sim_plant/sensor_timing.py, one run at a time: slower); the yaw, '
                   'velocity and curvature go with each frame, of its instant, unless '
                   '--stream gives them their own')
    p.add_argument('--stream', action='append', default=[], metavar='NAME=HZ/S[/S]',
                   help=f'an input on its own rate and latency ({", ".join(TIMED_STREAMS)}; '
                   'e.g. yaw=100/0.005; repeat for each; the others at 100 Hz without '
                   "latency); a third number is the sensor clock's offset, its stamps "
                   "ahead of the controller's clock (yaw=100/0/0.05: an IMU clock 50 ms "
                   'ahead)')
    args = p.parse_args(argv)
    from lookahead_control.core.config import ConfigError, load_vehicle
    timing = sensor_timing(args.camera, args.stream)
    if timing is not None and args.tune:
        raise ToolError("--camera / --stream: --tune scores the baselines' grids on the "
                        'offline runner; use one or the other')
    if timing is not None:
        for case in PLANTS:
            if case.name not in args.plants:
                continue
            try:
                check_timing(timing, case.dt or args.dt)
            except ParameterError as err:
                raise ToolError(f'--camera / --stream on plant {case.name}: {err}') from err
        unrun = [name for name in args.laws if name not in NODE_LAWS]
        if unrun:
            raise ToolError(f'--camera / --stream: {unrun[0]!r} is no law the controller '
                            f'node runs ({", ".join(NODE_LAWS)}): leave it out of --laws')
    vehicle = load_vehicle(args.vehicle)
    settings = None
    if args.controller is not None:
        if args.tune:
            raise ToolError("--controller: --tune scores the baselines' grids, not a file's "
                            'settings; use one or the other')
        settings = (load_law_settings(args.controller, vehicle, tool='compare')
                    if timing is None else
                    load_law_settings(args.controller, vehicle, not_run=NOT_RUN_TIMED,
                                      tool='compare --camera / --stream', runs=TIMED_RUNS))
        for name in args.laws:       # a setting no law accepts: one line, before any run
            try:
                LAWS[name](vehicle, settings)
            except (ParameterError, ConfigError) as err:
                raise ToolError(f'--controller {args.controller}: {name}: {err}') from err
    if timing is not None:
        check_clocks(timing, (settings or LawSettings()).safety)
    if args.tune and args.seeds != 1:
        raise ToolError("--seeds: --tune scores the baselines' grids on its own fixed noise "
                        'seeds (docs/baselines.md); use one or the other')
    noisy = [c.name for c in PLANTS if c.noisy]
    if args.seeds != 1 and not args.tune and not set(noisy) & set(args.plants):
        raise ToolError(f'--seeds {args.seeds}: the seeds repeat the runs of the noisy plants '
                        f'({", ".join(noisy)}), which --plants leaves out; add one, or leave '
                        '--seeds out')
    twice = [v for i, v in enumerate(args.speeds) if v in args.speeds[:i]]
    if twice:
        raise ToolError(f'--speeds: {twice[0]:g} m/s given twice: each run would be counted '
                        'twice (the same speed runs the same noise seeds); give each speed '
                        'once')
    if not args.tune:
        check_scenarios(args.scenarios, [c for c in PLANTS if c.name in args.plants],
                        args.dt, args.duration)
    outputs = (['tuning.csv'] if args.tune else
               ['league.csv', 'league.md', 'goals_over_seeds.csv',
                *(() if args.no_plots else ('league.png',))])
    previous = claim_output(args.out, 'compare', args.overwrite, outputs)   # before any run
    start = time.monotonic()
    if args.tune:
        names = [n for n in args.laws if n in TUNING_GRIDS] or list(TUNING_GRIDS)
        rows = tune(names, vehicle, TUNING_DT, args.workers, args.duration)
        print(markdown_table(rows, digits=4))
        args.out.mkdir(parents=True, exist_ok=True)
        write_csv(args.out / 'tuning.csv', rows)
        record_output(args.out, 'compare', [args.out / 'tuning.csv'], previous)
        if args.json:
            write_json(args.json, rows)
        print(f'wrote {args.out / "tuning.csv"} in {time.monotonic() - start:.0f} s (every '
              "point through the node's output stage, with config/controller.yaml's limits)")
        return 0
    plants = [c for c in PLANTS if c.name in args.plants]
    note = load_transfer_note(vehicle, args.plants, args.laws)
    if note:
        print(f'compare: note: {note}', file=sys.stderr)
    checked = None
    if timing is not None and 'cg_compensated' in args.laws:
        # the nominal runs cannot tell whether a car within the mismatch ranges rings
        # at this timing: the sampled checks can (before the runs: it is said first)
        checked = timing_check(vehicle, settings or LawSettings(), timing, plants,
                               args.speeds, args.controller, args.vehicle)
        print(f'compare: {checked[1]}', file=sys.stdout if checked[0] else sys.stderr)
    rows = league(args.laws, args.scenarios, args.speeds, plants, vehicle, args.dt,
                  args.workers, args.duration, progress=not args.no_progress,
                  settings=settings, seeds=args.seeds, timing=timing)
    report = write_report(rows, args.laws, args.out, plot=not args.no_plots,
                          duration=args.duration,
                          settings=None if settings is None else (str(args.controller),
                                                                  settings),
                          seeds=args.seeds, timing=timing,
                          timing_checked=None if checked is None else checked[1])
    record_output(args.out, 'compare', [args.out / name for name in outputs], previous)
    table = summary(rows, args.laws)
    print(markdown_table(table, digits=3))
    if args.json:
        # the independent plant's table of league.md too (before: only the goal plant's)
        independent = ({'independent_summary': summary(rows, args.laws, INDEPENDENT_PLANT)}
                       if INDEPENDENT_PLANT in args.plants else {})
        write_json(args.json, {'summary': table, **independent, 'runs': rows,
                               'goals_over_seeds': goals_over_seeds(goal_cells(rows,
                                                                               args.laws))})
    print(f'wrote {report} ({len(rows)} runs in {time.monotonic() - start:.0f} s)')
    undriven = sum(float(r.get('law_share', 1.0)) == 0.0 for r in rows)
    if undriven:
        print(f'compare: warning: the law never drove {undriven} run(s): their speed stayed '
              f'below safety.low_speed (every goal missed; {report.name}: "Runs the law did '
              'not drive throughout")', file=sys.stderr)
    failed = [r for r in rows if str(r['notes']).startswith(FAILED)]
    if failed:
        first = failed[0]
        print(f'compare: error: {len(failed)} run(s) failed (rows in {report.name}); first: '
              f"{first['law']} / {first['scenario']} / {first['plant']} / "
              f"{first['speed_mps']:g} m/s: {first['notes'][len(FAILED):]}", file=sys.stderr)
        return 1
    return 0


def timing_check(vehicle: VehicleParams, settings: LawSettings, timing: SensorTiming,
                 plants: Sequence[PlantCase], speeds: Sequence[float],
                 controller_file: Optional[Path] = None,
                 vehicle_file: Optional[Path] = None) -> tuple[bool, str]:
    """
    Check the loop of cg_compensated at a sensor timing over the mismatch grid.

    The law answers each frame (mode ``event``) or each tick of a timer (``timer``: a
    frame waits up to a tick, delay; a camera slower than the timer sets the period);
    the lateral error's latency and each plant's transport delay are the loop's delays.
    The checks of ``lane_keeping_stability`` (the counted rows of its verdict, without
    the certificate) at its speeds and those run: the nominal runs measure the nominal
    car only. The other inputs' own timings are not in it (its loop has every state of
    the frame's instant).

    :param vehicle: the design vehicle.
    :param settings: the laws' settings.
    :param timing: the inputs' timing.
    :param plants: the plants run (their transport delays).
    :param speeds: the speeds run [m/s].
    :param controller_file: the params file of ``--controller`` (named in the command).
    :param vehicle_file: the vehicle file of ``--vehicle`` (named in the command).
    :return: whether every check holds, and a line that says it with the tool's command.
    """
    import shlex

    from lookahead_control.core.lane_keeping import period_frequency
    from lookahead_control.core.lane_keeping_stability import (checked_delays, checked_speeds,
                                                               counted_checks, sampled_checks)
    law = settings.lane_keeping
    lateral = timing.lateral_error
    period, tick = 1.0 / lateral.rate_hz, 0.0
    if settings.mode == 'timer':
        tick = 1.0 / settings.rate_hz
        period = max(period, tick)
    answered = f'answered every {period:.4g} s'
    if period > law.max_gap:
        # dev-probe132: a 3 Hz camera was checked (1.705) and the command refused
        return False, (f'the loop of cg_compensated at this timing: {answered}, beyond '
                       f'lane_keeping.max_gap = {law.max_gap:g} s: the law restarts at every '
                       'frame (a time jump), no loop to check')
    asked, delays = checked_delays([case.delay + lateral.latency for case in plants], tick)
    # the tool's speeds and those run (dev-probe132: it checked the speeds run only, and
    # the tool's command its own envelope)
    v_min, v_max = min(10.0, *speeds), max(37.0, *speeds)
    checks = counted_checks(law, sampled_checks(vehicle, settings.controller, law, delays,
                                                checked_speeds(v_min, v_max), period))
    worst = max(checks, key=lambda c: c.max_radius)
    holds = all(c.holds for c in checks)
    cap = period_frequency(law, period)
    # in mode timer the tool adds the tick itself (dev-probe132: given twice)
    command = ' '.join(['lane_keeping_stability', '--period', f'{period:.10g}', '--delays',
                        *(f'{d:g}' for d in asked),
                        *([] if (v_min, v_max) == (10.0, 37.0) else
                          ['--v-min', f'{v_min:g}', '--v-max', f'{v_max:g}']),
                        *([] if vehicle_file is None else
                          ['--vehicle', shlex.quote(str(vehicle_file))]),
                        *([] if controller_file is None else
                          ['--controller', shlex.quote(str(controller_file))])])
    # (dev-probe132: a yaw 10 Hz 0.2 s late was said to be checked as the frame's)
    streams = ('yaw', 'velocity', 'road_curvature')
    others = ('' if timing.with_frame
              or all(getattr(timing, name) == StreamTiming() for name in streams)
              else "; the yaw, velocity and curvature streams' own rates and latencies are "
              "not in it (its loop has every state of the frame's instant)")
    case = ', '.join(f'{k} {v:g}' for k, v in worst.worst.items())
    return holds, (
        f'the loop of cg_compensated at this timing ({answered}, delays '
        f'{", ".join(f"{d:g}" for d in delays)} s'
        + (f', w_n cut to {cap:.4g} rad/s' if cap < law.natural_frequency else '')
        + f') over the mismatch grid (tyres x0.7-1.3, mass x0.8-1.2) at '
        f'{", ".join(f"{v:g}" for v in checked_speeds(v_min, v_max))} m/s: largest spectral '
        f'radius {worst.max_radius:.6g} ({case}): '
        + ('holds' if holds else 'DOES NOT HOLD: a car within those ranges rings or '
           'diverges at this timing, whatever the nominal runs measure (docs/'
           'vehicle_bridge.md, "A lane camera", 5.)')
        + f'{others}; `{command}` checks it with the certificate')


def sensor_timing(camera: Optional[str], streams: Sequence[str]) -> Optional[SensorTiming]:
    """
    Return the inputs' timing of ``--camera`` and ``--stream`` (None: neither given).

    :param camera: ``HZ/S`` of the lateral error (None: 100 Hz, no latency).
    :param streams: ``NAME=HZ/S`` of the other inputs (none: they go with each frame).
    :return: the timing.
    :raises ToolError: a bad value, an unknown or repeated name.
    """
    if camera is None and not streams:
        return None
    own: dict[str, StreamTiming] = {}
    try:
        lateral = StreamTiming() if camera is None else parse_stream(camera)
        for text in streams:
            name, sep, value = text.partition('=')
            name = name.strip()
            if not sep or name not in TIMED_STREAMS:
                raise ToolError(f'--stream {text!r}: not NAME=HZ/S[/S] with NAME one of '
                                f'{", ".join(TIMED_STREAMS)} (the lateral error\'s is '
                                '--camera)')
            if name in own:
                raise ToolError(f'--stream {name}: given twice; give each input once')
            own[name] = parse_stream(value)
    except ParameterError as err:
        raise ToolError(f'--camera / --stream: {err}') from err
    return SensorTiming(lateral, **own, with_frame=not streams)


def check_clocks(timing: SensorTiming, safety: SafetyParams) -> None:
    """
    Refuse a sensor clock off by so much that the node would refuse its every sample.

    :param timing: the inputs' timing.
    :param safety: the node's safety settings (``max_future``, ``input_timeout``).
    :raises ToolError: a stream whose stamps arrive further ahead of the controller's
        clock than ``safety.max_future``, or older than ``safety.input_timeout``
        (dev-probe126: an IMU clock 0.5 s ahead ran the league with every yaw sample
        refused, the car off the road, and the report did not say why).
    """
    names = ('lateral_error',) if timing.with_frame else STREAMS
    for name in names:
        stream = getattr(timing, name)
        ahead = stream.clock_offset - stream.latency     # the stamp against the clock
        option = '--camera' if name == 'lateral_error' else f'--stream {name}'
        if ahead > safety.max_future:
            raise ToolError(f'{option}: a clock {stream.clock_offset:g} s ahead and a latency '
                            f'of {stream.latency:g} s stamp every sample {ahead:g} s ahead of '
                            f"the controller's clock, beyond safety.max_future "
                            f'{safety.max_future:g} s: the node refuses each (allowed: '
                            'clock - latency at most max_future)')
        if -ahead > safety.input_timeout:
            raise ToolError(f'{option}: a clock {stream.clock_offset:g} s off and a latency '
                            f'of {stream.latency:g} s make every sample {-ahead:g} s old on '
                            f'arrival, beyond safety.input_timeout {safety.input_timeout:g} '
                            's: the node refuses each (allowed: latency - clock at most '
                            'input_timeout)')


def entry() -> int:
    """Entry point of ``compare``."""
    return run_tool(main)


if __name__ == '__main__':
    sys.exit(entry())
