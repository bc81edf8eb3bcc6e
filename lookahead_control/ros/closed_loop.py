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
Executable ``closed_loop``: sim_plant and controller as two processes, one scenario.

Starts both nodes (and the recorder) with the package's params files, waits for the
simulator to finish the scenario, stops the others with SIGTERM, and exits non-zero if
any failed. SIGINT or SIGTERM to ``closed_loop`` stops them the same way (bag
finalized).
``--via-bridge``: the simulator speaks like a vehicle (odometry, imu, the road as a path)
and ``path_bridge`` turns that into the controller's contract, as on a real vehicle.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass, field
import datetime
import os
from pathlib import Path
import re
import signal
import subprocess
import sys
import time
from typing import Any, Optional, Sequence

from lookahead_control.core.cli import (ArgumentParser, EXIT_OUTPUT_EXISTS, EXIT_USAGE, number,
                                        run_tool, ToolError)
from lookahead_control.core.config import source_config_dir
from lookahead_control.core.controller import LAW_NAMES
from lookahead_control.core.interrupts import deferred, raise_if_received
from lookahead_control.core.params import ParameterError, SCHEDULE_MODES
from sim_plant.commonroad_plant import COMMONROAD_MODELS
from sim_plant.scenario import check_force_timing, load_scenario, Scenario

MAX_SPEED = 90.0        # m/s, the scenarios' limit
PR_SET_PDEATHSIG = 1    # prctl option (linux/prctl.h)


@dataclass
class LoopConfig:
    """
    What to run.

    :param scenario: scenario YAML.
    :param speed: initial speed override [m/s] (0: the scenario's).
    :param schedule: d_v schedule of the controller.
    :param mode: sim mode, lockstep or realtime.
    :param plant: plant model.
    :param rate_hz: control rate [Hz].
    :param timeout: wall-clock limit for the simulator [s].
    :param extra_controller_args: more ROS arguments for the controller.
    :param extra_sim_args: more ROS arguments for the simulator.
    :param bag: record the run into this bag directory (None: do not record).
    :param via_bridge: sim_plant publishes odometry and a path; path_bridge converts.
    :param extra_bridge_args: more ROS arguments for the bridge.
    :param law: the controller's steering law (``law`` parameter; ``schedule`` is the
        paper law's d_v schedule).
    :param controller_params: the controller's one params file (None: the package's
        ``vehicle.yaml`` and ``controller.yaml``, and on a CommonRoad plant the set's
        mapped model after them): :func:`write_controller_params`.
    :param vehicle_id: the CommonRoad parameter set of a ``commonroad_*`` plant.
    """

    scenario: Path
    speed: float = 0.0
    schedule: str = 'paper'
    mode: str = 'lockstep'
    plant: str = 'linear'
    rate_hz: float = 100.0
    timeout: float = 300.0
    extra_controller_args: list[str] = field(default_factory=list)
    extra_sim_args: list[str] = field(default_factory=list)
    bag: Optional[Path] = None
    via_bridge: bool = False
    extra_bridge_args: list[str] = field(default_factory=list)
    law: str = 'paper'
    controller_params: Optional[Path] = None
    vehicle_id: int = 2


#: the simulator's plants ``closed_loop`` runs: the package's and CommonRoad's
PLANTS = ('linear', 'nonlinear', *COMMONROAD_MODELS)


def mapped_vehicle(vehicle_id: int) -> dict[str, float]:
    """
    Return the controller's ``vehicle.*`` parameters for a CommonRoad car.

    The set's single-track mapping (``sim_plant.commonroad_plant.controller_vehicle``,
    docs/proving_ground.md): without it the controller steered a BMW 320i with the
    package's car as its model.

    :param vehicle_id: the CommonRoad parameter set (1, 2 or 3).
    :return: ``{'vehicle.mass': ..., ...}``.
    :raises ToolError: a set the package cannot map.
    """
    from sim_plant.commonroad_plant import controller_vehicle_params
    try:
        return controller_vehicle_params(vehicle_id)
    except ParameterError as err:
        raise ToolError(f'--vehicle-id {vehicle_id}: {err}') from err


#: the controller parameters ``closed_loop`` sets itself: its options say the first
#: four; the controller answers each measurement (event mode) and starts itself
OWN_CONTROLLER_PARAMS = ('law', 'controller.schedule', 'wait_for_matching_stamps',
                         'use_sim_time', 'mode', 'rate_hz', 'autostart')


def controller_settings(params_file: Optional[Path], settings: Sequence[str], law: str,
                        schedule: str, vehicle: Optional[dict[str, float]] = None
                        ) -> tuple[dict[str, Any], list[str]]:
    """
    Return the controller's own settings, checked as the node checks them, before any start.

    ``config/vehicle.yaml``, ``config/controller.yaml``, ``vehicle`` (a CommonRoad car's
    mapped model), then the file, then the settings, each replacing the one before; the
    run's own parameters (:data:`OWN_CONTROLLER_PARAMS`) are left out of the file's and
    refused as settings.
    The node is given the result as its one params file (:func:`write_controller_params`):
    it runs what was checked here, whatever rcl would make of several files and ``-p``.
    A name the node does not have, a value out of its range, and a combination the
    node's core or its law refuses (with this run's ``law``) are one line here.

    :param params_file: the controller's params file (None: none).
    :param settings: ``NAME:=VALUE`` items (``--param``).
    :param law: the run's law (``--law``).
    :param schedule: the run's d_v schedule (``--schedule``).
    :param vehicle: ``vehicle.*`` parameters over the package's (None: none).
    :return: ``(parameters by name, the file's parameters left out)``.
    :raises ToolError: naming the file or setting and what is allowed.
    """
    from lookahead_control.core.config import (applies_to, ConfigError, node_file_sections,
                                               package_controller_params, rcl_param_value)
    from lookahead_control.core.param_schema import (check_params, ROS_BUILTIN,
                                                     ROS_BUILTIN_PREFIXES)
    from lookahead_control.core.params import ParameterError
    from lookahead_control.ros.controller_node import ALL_SPECS, core_from_params
    merged = {**package_controller_params(), **(vehicle or {})}
    dropped: list[str] = []
    if params_file is not None:
        try:
            read = node_file_sections(params_file, 'controller', ALL_SPECS)
            # rcl applies a section in the order it first met its name over all the
            # files: the package's open '/**', so the file's '/**' sections come before
            # its others whatever its own order (dev-probe49)
            sections = [(key, flat) for key, flat in read if applies_to(key, 'controller')]
            mine: dict[str, Any] = {}
            for key, flat in sorted(sections, key=lambda item: item[0] != '/**'):
                mine.update(flat)
        except ConfigError as err:
            raise ToolError(f'--controller {err}') from err
        dropped = [name for name in mine if name in OWN_CONTROLLER_PARAMS]
        merged.update({k: v for k, v in mine.items() if k not in OWN_CONTROLLER_PARAMS})
    for item in settings:
        name, sep, text = item.partition(':=')
        if not sep or not name or not text:
            raise ToolError(f'--param {item}: expected NAME:=VALUE, e.g. '
                            'lane_keeping.compliance_memory_seed:=1.42')
        if name in OWN_CONTROLLER_PARAMS:
            raise ToolError(f'--param {item}: closed_loop sets {name} itself (--law, '
                            '--schedule, --mode; the controller answers each measurement)')
        try:
            merged[name] = check_params({name: rcl_param_value(text)}, ALL_SPECS)[name]
        except (ParameterError, ConfigError) as err:
            raise ToolError(f'--param {item}: {err}') from err
    given = ' and '.join([*([f'--controller {params_file}'] if params_file else []),
                          *(['--param'] if settings else [])])
    # the node's own names: a /** section holds other nodes' too (the node skips them)
    known = {spec.name for spec in ALL_SPECS}
    merged = {k: v for k, v in merged.items() if k not in OWN_CONTROLLER_PARAMS and (
        k in known or k in ROS_BUILTIN or k.startswith(ROS_BUILTIN_PREFIXES))}
    try:
        checked = check_params(merged, ALL_SPECS)
        every = {spec.name: spec.default for spec in ALL_SPECS}
        core_from_params({**every, **checked, 'law': law, 'controller.schedule': schedule})
    except ParameterError as err:
        raise ToolError(f'{given}: {err}') from err
    return checked, dropped


SIM_FRAME = 'base_link'
ANY_FRAME = ''


def peak_speed(scenario: Scenario) -> float:
    """
    Return the highest speed of a scenario's profile within its duration [m/s].

    :param scenario: the scenario (its speed is piecewise linear in time).
    :return: the largest ``v_x`` at its phases' ends and its own.
    """
    profile = scenario.speed
    times = {0.0, scenario.duration}
    for start, duration, _ in ((profile.start, profile.duration, profile.acceleration),
                               *profile.ramps):
        times |= {start, start + duration}
    return max(float(profile.at(t)[0]) for t in times if 0.0 <= t <= scenario.duration)


#: [m/s] the CommonRoad cars' speed loop runs above its profile (7 mm/s at 70 m/s on
#: the single track): a scenario there keeps this far below ``safety.max_speed``
COMMONROAD_SPEED_MARGIN = 0.5


def loop_compatibility(params: dict[str, Any], rate_hz: float, given: str,
                       scenario: Optional[Scenario] = None, plant: str = 'linear') -> None:
    """
    Refuse controller settings this loop's simulator can never be answered under.

    Until dev-loopcheck such a run started and then waited for each answer to its
    deadline (0.5 s a step) until ``--timeout``: every input refused. So did a scenario
    faster than the controller's ``safety.max_speed`` from the moment it passed it
    (dev-probe82: ``--speed 75``, every velocity refused, 5 minutes to ``--timeout``).

    :param params: the controller's settings (:func:`controller_settings`).
    :param rate_hz: the loop's rate [Hz].
    :param given: where the settings came from, for the message.
    :param scenario: the run's scenario (None: its speed is not checked).
    :param plant: the simulator's plant (a CommonRoad car: :data:`COMMONROAD_SPEED_MARGIN`
        below the limit, dev-probe83: at 70 m/s every velocity refused from 70.01 on).
    :raises ToolError: naming the setting, its value and what is allowed.
    """
    period = 1.0 / rate_hz
    future = params.get('safety.max_future')
    if future is not None and future < period:
        raise ToolError(f'{given}: safety.max_future = {future:g} s: the simulator '
                        f'stamps each step one period ({period:g} s at --rate {rate_hz:g}) '
                        'ahead of its /clock, in lockstep and realtime alike, so the '
                        f'controller would refuse every input; allowed here: >= {period:g} s')
    frame = params.get('frame_id')
    if frame not in (None, ANY_FRAME, SIM_FRAME):
        raise ToolError(f'{given}: frame_id = {frame!r}: the simulator (and path_bridge) '
                        f'publish in {SIM_FRAME!r}, so the controller would refuse every '
                        f'input; allowed here: {SIM_FRAME!r} or {ANY_FRAME!r} (any)')
    from lookahead_control.core.safety import SafetyParams
    fastest = params.get('safety.max_speed', SafetyParams().max_speed)
    margin = COMMONROAD_SPEED_MARGIN if plant in COMMONROAD_MODELS else 0.0
    peak = peak_speed(scenario) if scenario is not None else 0.0
    if scenario is not None and peak > fastest - margin:
        car = (f' (the CommonRoad car runs above its speed profile: {margin:g} m/s below '
               'it)' if margin else '')
        raise ToolError(f'{given}: safety.max_speed = {fastest:g} m/s: scenario '
                        f'{scenario.name!r} reaches {peak:g} m/s, and the '
                        'controller refuses every velocity above it (the simulator would '
                        'wait for each answer until --timeout); allowed here: a --speed '
                        f'or scenario within it{car}, or a larger safety.max_speed')


PARAMS_PREFIX = 'closed_loop_controller_'


def _running(pid: int) -> bool:
    """Return whether a process of this pid exists (another user's counts)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def _unlocked(path: Path) -> bool:
    """Return whether no process holds the file's lock (a run's, in any pid namespace)."""
    import fcntl
    fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    finally:
        os.close(fd)
    return True


def remove_stale_params(folder: Path) -> list[Path]:
    """
    Remove the params files of runs that were killed before they could delete them.

    A file is stale when it is this user's, named ``closed_loop_controller_<pid>_*.yaml``
    (``<pid>`` ASCII digits without a leading 0), no process of that pid runs and no
    process holds its lock (a run holds it while it runs: a run in another pid
    namespace sharing the folder, e.g. a container's, keeps its file).

    :param folder: the folder the files are written to.
    :return: the files removed.
    """
    removed = []
    for path in folder.glob(PARAMS_PREFIX + '*_*.yaml'):
        pid = path.name[len(PARAMS_PREFIX):].split('_', 1)[0]
        if re.fullmatch('[1-9][0-9]*', pid) is None:
            continue
        try:
            if (path.is_symlink() or path.stat().st_uid != os.getuid()
                    or _running(int(pid)) or not _unlocked(path)):
                continue
            path.unlink()
        except OSError:                 # gone meanwhile, or not ours to remove
            continue
        removed.append(path)
    return removed


# the open files of this process's params files: their locks last while it runs
_HELD: dict[Path, int] = {}


def write_controller_params(params: dict[str, Any]) -> Path:
    """
    Write the controller's parameters as one params file (the caller deletes it).

    The file's name carries this process's id and the process holds its lock until
    :func:`release_controller_params`; the files of runs no longer running (killed with
    SIGKILL) are removed first (:func:`remove_stale_params`).

    :param params: parameters by name (:func:`controller_settings`).
    :return: the file.
    """
    import fcntl
    import tempfile

    from lookahead_control.ros.node_main import dump_params
    remove_stale_params(Path(tempfile.gettempdir()))
    handle = tempfile.NamedTemporaryFile('w', suffix='.yaml',
                                         prefix=f'{PARAMS_PREFIX}{os.getpid()}_',
                                         delete=False)
    path = Path(handle.name)
    try:
        with handle:
            fcntl.flock(handle.fileno(), fcntl.LOCK_EX)
            _HELD[path] = os.dup(handle.fileno())     # the lock stays with the copy
            dump_params({'/**': params}, handle)
    except BaseException:
        release_controller_params(path)
        raise
    return path


def release_controller_params(path: Path) -> None:
    """
    Delete a params file of :func:`write_controller_params` and drop its lock.

    :param path: the file.
    """
    path.unlink(missing_ok=True)
    fd = _HELD.pop(path, None)
    if fd is not None:
        os.close(fd)


def simulator_step(extra_sim_args: Sequence[str]) -> float:
    """
    Return the simulator's plant step: its ``dt`` from ``-p dt:=X``, else its default.

    :param extra_sim_args: the simulator's extra ROS arguments.
    :return: ``dt`` [s] (the default where the value is not a number: the node says so).
    """
    from sim_plant.sim_plant_node import SIM_SPECS
    step = float(next(spec.default for spec in SIM_SPECS if spec.name == 'dt'))
    for flag, value in zip(extra_sim_args, extra_sim_args[1:]):
        if flag == '-p' and value.startswith('dt:='):
            try:
                step = float(value[len('dt:='):])
            except ValueError:
                pass
    return step


def node_commands(cfg: LoopConfig) -> tuple[list[str], list[str]]:
    """
    Return the command lines of the simulator and of the controller.

    :param cfg: what to run.
    :return: ``(sim command, controller command)``.
    """
    config = source_config_dir()
    common = ['--params-file', str(config / 'vehicle.yaml')]
    # a CommonRoad car: the simulator's vehicle (its sensor at the car's d_s, its
    # parameters in the bag) and the controller's model are the set's mapping
    commonroad = cfg.plant in COMMONROAD_MODELS
    car = ([arg for name, value in mapped_vehicle(cfg.vehicle_id).items()
            for arg in ('-p', f'{name}:={value!r}')] if commonroad else [])
    sim = [sys.executable, '-m', 'sim_plant.sim_plant_node', '--ros-args', *common, *car,
           *(['-p', f'plant.vehicle_id:={int(cfg.vehicle_id)}'] if commonroad else []),
           '-p', f'scenario_file:={cfg.scenario}', '-p', f'speed:={float(cfg.speed)}',
           '-p', f'mode:={cfg.mode}', '-p', f'rate_hz:={float(cfg.rate_hz)}',
           '-p', f'plant.model:={cfg.plant}', '-p', 'use_sim_time:=false',
           '-p', f'subscribers:={2 if cfg.bag else 1}',
           *(['-p', 'output:=vehicle'] if cfg.via_bridge else []), *cfg.extra_sim_args]
    files = (['--params-file', str(cfg.controller_params)] if cfg.controller_params else
             [*common, '--params-file', str(config / 'controller.yaml'), *car])
    controller = [sys.executable, '-m', 'lookahead_control.ros.controller_node', '--ros-args',
                  *files,
                  '-p', f'controller.schedule:={cfg.schedule}', '-p', f'law:={cfg.law}',
                  '-p', f'wait_for_matching_stamps:={str(cfg.mode == "lockstep").lower()}',
                  '-p', 'use_sim_time:=true', *cfg.extra_controller_args]
    return sim, controller


def bridge_command(cfg: LoopConfig) -> list[str]:
    """
    Return the command line of the path bridge (``--via-bridge``).

    The yaw rate comes from the odometry twist (the same r as the imu): in lockstep the
    imu of a step may arrive after its odometry, and a bridge waiting for it would wait
    on every step.

    :param cfg: what to run.
    :return: the command.
    """
    config = source_config_dir()
    return [sys.executable, '-m', 'lookahead_control.ros.path_bridge_node', '--ros-args',
            '--params-file', str(config / 'path_bridge.yaml'), '-p', 'use_imu:=false',
            *cfg.extra_bridge_args]


def recorder_command(bag: Path) -> list[str]:
    """
    Return the command line of the recorder for one run.

    :param bag: the bag directory to create.
    :return: the command.
    """
    return [sys.executable, '-m', 'lookahead_control.bags.recorder_node', '-o', str(bag)]


def _child_setup() -> None:
    """
    Run in each child before it starts Python (``preexec_fn``).

    Its own process group: a terminal's Ctrl-C reaches closed_loop only, which stops
    the children deliberately (a SIGINT while a child's Python is still starting would
    print an import traceback). ``PR_SET_PDEATHSIG``: if closed_loop dies (SIGKILL) the
    children get SIGTERM and finalize, instead of running on unsupervised.
    """
    os.setpgrp()
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
    except (OSError, AttributeError):    # pragma: no cover - not Linux
        pass


def spawn(command: list[str], env: Optional[dict[str, str]] = None) -> subprocess.Popen:
    """
    Start a node process, supervised by this one (see :func:`_child_setup`).

    :param command: its command line.
    :param env: its environment (default: ours).
    :return: the process.
    """
    return subprocess.Popen(command, env=env, preexec_fn=_child_setup)


#: [s] a node's time to end after SIGTERM before it is killed
NODE_STOP_GRACE = 10.0
#: [s] the simulator's: beyond its wait for its subscribers' acknowledgements (10 s,
#: sim_plant_node.ACK_TIMEOUT), which a recorder killed mid-run never sends (dev-probe95:
#: 'sim_plant ignored SIGTERM for 10 s: killed', exit code 1, while it was waiting)
SIM_STOP_GRACE = 15.0


def stop(process: subprocess.Popen, name: str, grace: float = NODE_STOP_GRACE) -> int:
    """
    Stop a node with SIGTERM (then SIGKILL after ``grace`` seconds).

    The nodes treat SIGTERM as SIGINT (the recorder finalizes its bag); a child whose
    Python is still starting ends silently on it, where SIGINT prints a traceback.

    :param process: the process.
    :param name: its name, for messages.
    :param grace: seconds to wait for a clean exit.
    :return: its exit code (0 for a clean exit on the signal).
    """
    if process.poll() is None:
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(grace)
        except subprocess.TimeoutExpired:
            print(f'closed_loop: {name} ignored SIGTERM for {grace:g} s: killed',
                  file=sys.stderr)
            process.kill()
            process.wait()
            return 1
    code = process.returncode
    return 0 if code in (0, -signal.SIGINT, -signal.SIGTERM) else code


def run_loop(cfg: LoopConfig, env: Optional[dict[str, str]] = None) -> int:
    """
    Run the scenario through both processes.

    SIGINT and SIGTERM (``Terminated``) stop the children (SIGTERM each, the recorder
    last, so the bag is finalized) and are re-raised; a second signal during that
    cleanup is held, not obeyed half-way.

    :param cfg: what to run.
    :param env: environment of the child processes (default: ours).
    :return: 0 if both nodes ended cleanly and the scenario finished.
    """
    if not cfg.scenario.is_file():
        raise ToolError(f'{cfg.scenario}: no such scenario file')
    if not cfg.timeout > 0.0:
        raise ToolError(f'timeout {cfg.timeout:g} s: must be > 0')
    # a bad file or force: one line, no processes
    scenario = load_scenario(cfg.scenario, cfg.speed or None)
    dt = simulator_step(cfg.extra_sim_args)
    try:
        check_force_timing(scenario.forces, dt)
    except ParameterError as err:
        # dev-probe81: the simulator refused it after every process had started, and
        # the bag was left behind empty
        raise ToolError(f"{cfg.scenario} at the simulator's dt = {dt!r} s: {err}") from err
    sim_cmd, ctl_cmd = node_commands(cfg)
    processes: dict[str, subprocess.Popen] = {}
    why = ''
    start = time.monotonic()
    try:
        # a Ctrl-C an import swallowed since the tool's start (a lazy `import rclpy` can
        # turn it into an ImportError a fallback catches): no process is started, and
        # while they run the wait below looks again (a demo sent Ctrl-C in its first
        # second once ran its next runs for 60 s)
        raise_if_received()
        # the recorder first: the simulator starts once it and the controller are matched
        if cfg.bag:
            # main checked the place; another run may take it since (the recorder then
            # refuses it, exit code 3: bag_note)
            processes['record'] = spawn(recorder_command(cfg.bag), env)
        processes['controller'] = spawn(ctl_cmd, env)
        if cfg.via_bridge:
            processes['path_bridge'] = spawn(bridge_command(cfg), env)
        processes['sim_plant'] = spawn(sim_cmd, env)
        sim = processes['sim_plant']
        while sim.poll() is None:
            raise_if_received()
            early = [name for name in ('controller', 'path_bridge', 'record')
                     if name in processes and processes[name].poll() is not None]
            if early:
                why = (f'{early[0]} exited early (exit code '
                       f'{processes[early[0]].returncode}) before the scenario ended')
                break
            if time.monotonic() - start > cfg.timeout:
                why = (f'the simulator did not finish the scenario within --timeout '
                       f'{cfg.timeout:g} s (wall clock, start-up included): stopped it')
                break
            time.sleep(0.05)
    finally:
        with deferred():
            # the simulator first (it drives the loop), the bridge right after it (it
            # reports silent odometry after 0.5 s), the recorder last
            codes = {name: stop(processes[name], name,
                                SIM_STOP_GRACE if name == 'sim_plant' else NODE_STOP_GRACE)
                     for name in ('sim_plant', 'path_bridge', 'controller', 'record')
                     if name in processes}
    failed = {name: code for name, code in codes.items() if code != 0}
    if why or failed:
        detail = ', '.join(f'{name} exit code {code}' for name, code in failed.items())
        print(f'closed_loop: failed: {why or "a node failed"}'
              + (f' ({detail})' if detail else '') + bag_note(cfg.bag, codes.get('record')),
              file=sys.stderr)
        return 1
    return 0


def bag_note(bag: Optional[Path], code: Optional[int]) -> str:
    """
    Return what a failed run's bag holds, for its failure line.

    :param bag: the run's bag (None: not recorded).
    :param code: the recorder's exit code (None: not started).
    :return: ``'; ...'`` or ''.
    """
    if bag is None:
        return ''
    if code == EXIT_OUTPUT_EXISTS:
        # another run took the place after main's check, before or while the recorder
        # started (dev-probe93, dev-probe95): its bag was called this run's
        return (f'; record refused {bag} (another run made it after the check): nothing '
                'of this run was recorded')
    if not bag.is_dir():
        return ''
    if code == EXIT_USAGE:
        # a write failure mid-run (a full disk): its bag holds data (dev-probe94)
        return (f"; {bag} holds what this run's recorder wrote before it failed (record "
                'exit code 2: its line above says why)' + _recover_hint(bag))
    return f'; the bag {bag} holds what was recorded until then' + _recover_hint(bag)


def _recover_hint(bag: Path) -> str:
    """Return the advice to recover a bag without ``metadata.yaml`` ('' with it)."""
    # a recorder killed with SIGKILL leaves no metadata.yaml (dev-probe95)
    return '' if (bag / 'metadata.yaml').exists() else f' (no metadata.yaml: run recover {bag})'


def default_bag(scenario: Path, schedule: str, speed: float, tag: str = '') -> Path:
    """
    Return ``bags/<scenario>_<schedule>_<speed>_<tag><time>``, with the run's speed.

    :param scenario: the scenario file.
    :param schedule: the d_v schedule.
    :param speed: the ``--speed`` option (0: the scenario's own initial speed) [m/s].
    :param tag: inserted before the time (``bridge_`` for a run through path_bridge).
    :return: the bag directory.
    """
    speed = speed or load_scenario(scenario).speed.initial
    return Path('bags') / (f'{scenario.stem}_{schedule}_{speed:g}_{tag}'
                           f'{datetime.datetime.now():%Y%m%d_%H%M%S}')


def main(argv: Sequence[str] | None = None) -> int:
    """
    Parse arguments and run one closed loop.

    :param argv: command-line arguments.
    :return: exit code.
    """
    p = ArgumentParser(prog='closed_loop', description='run sim_plant and controller as '
                       'two processes over DDS for one scenario, recorded into a bag')
    p.add_argument('--scenario', type=Path,
                   default=source_config_dir() / 'scenarios' / 'paper_r400.yaml',
                   help='scenario YAML (default: config/scenarios/paper_r400.yaml)')
    p.add_argument('--speed', type=number(0.0, MAX_SPEED, unit='m/s'), default=0.0,
                   metavar='M/S', help="initial speed [m/s] (default 0: the scenario's)")
    p.add_argument('--schedule', choices=SCHEDULE_MODES, default='paper',
                   help='d_v schedule of the paper law (default paper, eq. 26)')
    p.add_argument('--law', choices=LAW_NAMES, default='paper',
                   help="steering law of the controller (default paper: the paper's law "
                   'with --schedule; cg_compensated: docs/lane_keeping.md; the baselines: '
                   'docs/baselines.md)')
    p.add_argument('--mode', choices=('lockstep', 'realtime'), default='lockstep',
                   help='lockstep: the simulator waits for each answer; realtime: wall '
                   'clock (default lockstep)')
    p.add_argument('--plant', choices=PLANTS, default='linear',
                   help='plant model (default linear; commonroad_st / commonroad_mb: '
                   "CommonRoad's single-track / multi-body car, the controller's model "
                   'mapped from it)')
    p.add_argument('--vehicle-id', type=int, choices=(1, 2, 3), default=None,
                   help='the CommonRoad car of a commonroad_* plant: 1 Ford Escort, 2 BMW '
                   '320i, 3 VW Vanagon (default 2)')
    p.add_argument('--rate', type=number(1.0, 2000.0, unit='Hz'), default=100.0,
                   metavar='HZ', help='measurement and control rate [Hz] (default 100)')
    p.add_argument('--timeout', type=number(0.0, 1.0e6, low_open=True, unit='s'),
                   default=300.0, metavar='S', help='wall-clock limit for the whole run, '
                   'start-up included [s] (default 300)')
    p.add_argument('--bag', type=Path, default=None,
                   help='bag directory, must not exist (default: '
                   'bags/<scenario>_<schedule or law>_<speed>_<time>)')
    p.add_argument('--no-record', action='store_true', help='do not record a bag')
    p.add_argument('--via-bridge', action='store_true',
                   help='sim_plant publishes odometry and the road as a path; path_bridge '
                   'turns them into the contract (as on a real vehicle)')
    p.add_argument('--controller', type=Path, default=None, metavar='YAML',
                   help="the controller node's own params file, over the package's "
                   '(this run sets law, controller.schedule, mode, rate_hz, autostart, '
                   'use_sim_time and wait_for_matching_stamps itself)')
    p.add_argument('--param', action='append', default=[], metavar='NAME:=VALUE',
                   help='a controller parameter, after the files (repeatable), e.g. '
                   "--param lane_keeping.compliance_memory_seed:=1.42 (a run's "
                   'compliance_memory_final_ratio from analyze)')
    args = p.parse_args(argv)
    if args.no_record and args.bag is not None:
        raise ToolError('--bag and --no-record contradict each other: give one')
    commonroad = args.plant in COMMONROAD_MODELS
    if args.vehicle_id is not None and not commonroad:
        raise ToolError(f'--vehicle-id {args.vehicle_id} with --plant {args.plant}: a '
                        'CommonRoad car is chosen only for --plant commonroad_st or '
                        'commonroad_mb')
    vehicle_id = 2 if args.vehicle_id is None else args.vehicle_id
    mapped = mapped_vehicle(vehicle_id) if commonroad else None
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    if not args.scenario.is_file():
        raise ToolError(f'{args.scenario}: no such scenario file')
    scenario = load_scenario(args.scenario, args.speed or None)    # one line, no process
    own = None
    if args.controller is not None or args.param or mapped is not None:
        own, dropped = controller_settings(args.controller, args.param, args.law,
                                           args.schedule, mapped)
        if dropped:
            print(f'closed_loop: --controller {args.controller}: {", ".join(dropped)} not '
                  'used (this run sets them: --law, --schedule; event mode, started by '
                  'itself)')
    given = ' and '.join([*([f'--controller {args.controller}'] if args.controller else []),
                          *(['--param'] if args.param else [])]) or 'config/controller.yaml'
    loop_compatibility(own if own is not None else controller_settings(
        None, [], args.law, args.schedule)[0], args.rate, given, scenario, args.plant)
    if mapped is not None and own is not None:
        changed = [name for name, value in mapped.items() if own[name] != value]
        print(f'closed_loop: CommonRoad set {vehicle_id}: the controller models it as '
              + ', '.join(f'{name[len("vehicle."):]} {own[name]:g}' for name in mapped)
              + (f' ({", ".join(changed)} from {given}, over the mapping)' if changed
                 else ' (mapped)'))
    bag = None if args.no_record else (args.bag or default_bag(
        args.scenario, args.schedule if args.law == 'paper' else args.law,
        float(scenario.speed.initial),
        'bridge_' if args.via_bridge else ''))
    if bag is not None:
        if bag.exists():
            raise ToolError(f'{bag}: exists already; choose another --bag')
        # an unwritable place: one line now, not a failed recorder after start-up
        bag.mkdir(parents=True)
        bag.rmdir()
    written = write_controller_params(own) if own is not None else None
    try:
        code = run_loop(LoopConfig(args.scenario, args.speed, args.schedule, args.mode,
                                   args.plant, args.rate, args.timeout, bag=bag,
                                   via_bridge=args.via_bridge, law=args.law,
                                   controller_params=written, vehicle_id=vehicle_id))
    finally:
        if written is not None:
            release_controller_params(written)
    if bag is not None and code == 0:
        print(f'closed_loop: recorded {bag}')
    return code


def entry() -> int:
    """Entry point of ``closed_loop``."""
    return run_tool(main)


if __name__ == '__main__':
    sys.exit(entry())
