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

Starts both nodes with the package's params files, waits for the simulator to finish
the scenario, stops the controller with SIGINT, and exits non-zero if either failed.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
import datetime
import os
from pathlib import Path
import signal
import subprocess
import sys
import time
from typing import Optional, Sequence

from lookahead_control.core.cli import run_tool, ToolError
from lookahead_control.core.config import source_config_dir
from lookahead_control.core.params import SCHEDULE_MODES
from sim_plant.scenario import load_scenario


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


def node_commands(cfg: LoopConfig) -> tuple[list[str], list[str]]:
    """
    Return the command lines of the simulator and of the controller.

    :param cfg: what to run.
    :return: ``(sim command, controller command)``.
    """
    config = source_config_dir()
    common = ['--params-file', str(config / 'vehicle.yaml')]
    sim = [sys.executable, '-m', 'sim_plant.sim_plant_node', '--ros-args', *common,
           '-p', f'scenario_file:={cfg.scenario}', '-p', f'speed:={float(cfg.speed)}',
           '-p', f'mode:={cfg.mode}', '-p', f'rate_hz:={float(cfg.rate_hz)}',
           '-p', f'plant.model:={cfg.plant}', '-p', 'use_sim_time:=false',
           '-p', f'subscribers:={2 if cfg.bag else 1}', *cfg.extra_sim_args]
    controller = [sys.executable, '-m', 'lookahead_control.ros.controller_node', '--ros-args',
                  *common, '--params-file', str(config / 'controller.yaml'),
                  '-p', f'controller.schedule:={cfg.schedule}',
                  '-p', f'wait_for_matching_stamps:={str(cfg.mode == "lockstep").lower()}',
                  '-p', 'use_sim_time:=true', *cfg.extra_controller_args]
    return sim, controller


def recorder_command(bag: Path) -> list[str]:
    """
    Return the command line of the recorder for one run.

    :param bag: the bag directory to create.
    :return: the command.
    """
    return [sys.executable, '-m', 'lookahead_control.bags.recorder_node', '-o', str(bag)]


def stop(process: subprocess.Popen, name: str, grace: float = 10.0) -> int:
    """
    Stop a node with SIGINT (then SIGKILL after ``grace`` seconds).

    :param process: the process.
    :param name: its name, for messages.
    :param grace: seconds to wait for a clean exit.
    :return: its exit code (0 for a clean SIGINT exit).
    """
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
        try:
            process.wait(grace)
        except subprocess.TimeoutExpired:
            print(f'closed_loop: {name} ignored SIGINT for {grace:g} s: killed',
                  file=sys.stderr)
            process.kill()
            process.wait()
            return 1
    code = process.returncode
    return 0 if code in (0, -signal.SIGINT) else code


def run_loop(cfg: LoopConfig, env: Optional[dict[str, str]] = None) -> int:
    """
    Run the scenario through both processes.

    :param cfg: what to run.
    :param env: environment of the child processes (default: ours).
    :return: 0 if both nodes ended cleanly and the scenario finished.
    """
    if not cfg.scenario.is_file():
        raise ToolError(f'{cfg.scenario}: no such scenario file')
    load_scenario(cfg.scenario, cfg.speed or None)    # a bad file: one line, no processes
    sim_cmd, ctl_cmd = node_commands(cfg)
    # the recorder first: the simulator starts once it and the controller are matched
    recorder = (subprocess.Popen(recorder_command(cfg.bag), env=env) if cfg.bag
                else None)
    controller = subprocess.Popen(ctl_cmd, env=env)
    sim = subprocess.Popen(sim_cmd, env=env)
    start = time.monotonic()
    try:
        while sim.poll() is None:
            early = [(name, proc) for name, proc in (('controller', controller),
                                                     ('record', recorder))
                     if proc is not None and proc.poll() is not None]
            if early:
                print(f'closed_loop: {early[0][0]} exited early ({early[0][1].returncode})',
                      file=sys.stderr)
                break
            if time.monotonic() - start > cfg.timeout:
                print(f'closed_loop: simulator did not finish within {cfg.timeout:g} s',
                      file=sys.stderr)
                break
            time.sleep(0.05)
    finally:
        sim_code = stop(sim, 'sim_plant') if sim.poll() is None else sim.returncode
        finished_in_time = time.monotonic() - start <= cfg.timeout
        ctl_code = stop(controller, 'controller')
        rec_code = stop(recorder, 'record') if recorder is not None else 0
    if sim_code != 0 or ctl_code != 0 or rec_code != 0 or not finished_in_time:
        print(f'closed_loop: failed (sim_plant {sim_code}, controller {ctl_code}, '
              f'record {rec_code})', file=sys.stderr)
        return 1
    return 0


def default_bag(scenario: Path, schedule: str, speed: float) -> Path:
    """
    Return ``bags/<scenario>_<schedule>_<speed>_<time>``, with the speed the run has.

    :param scenario: the scenario file.
    :param schedule: the d_v schedule.
    :param speed: the ``--speed`` option (0: the scenario's own initial speed) [m/s].
    :return: the bag directory.
    """
    speed = speed or load_scenario(scenario).speed.initial
    return Path('bags') / (f'{scenario.stem}_{schedule}_{speed:g}_'
                           f'{datetime.datetime.now():%Y%m%d_%H%M%S}')


def main(argv: Sequence[str] | None = None) -> int:
    """
    Parse arguments and run one closed loop.

    :param argv: command-line arguments.
    :return: exit code.
    """
    p = argparse.ArgumentParser(description='run sim_plant and controller as two '
                                'processes over DDS for one scenario')
    p.add_argument('--scenario', type=Path,
                   default=source_config_dir() / 'scenarios' / 'paper_r400.yaml')
    p.add_argument('--speed', type=float, default=0.0,
                   help="initial speed [m/s] (0: the scenario's)")
    p.add_argument('--schedule', choices=SCHEDULE_MODES, default='paper')
    p.add_argument('--mode', choices=('lockstep', 'realtime'), default='lockstep')
    p.add_argument('--plant', choices=('linear', 'nonlinear'), default='linear')
    p.add_argument('--rate', type=float, default=100.0, help='control rate [Hz]')
    p.add_argument('--timeout', type=float, default=300.0)
    p.add_argument('--bag', type=Path, default=None,
                   help='bag directory (default: bags/<scenario>_<schedule>_<speed>_<time>)')
    p.add_argument('--no-record', action='store_true', help='do not record a bag')
    args = p.parse_args(argv)
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    bag = None if args.no_record else (args.bag or default_bag(args.scenario, args.schedule,
                                                               args.speed))
    if bag is not None:
        if bag.exists():
            raise ToolError(f'{bag}: exists already; choose another --bag')
        # an unwritable place: one line now, not a failed recorder after start-up
        bag.mkdir(parents=True)
        bag.rmdir()
    code = run_loop(LoopConfig(args.scenario, args.speed, args.schedule, args.mode,
                               args.plant, args.rate, args.timeout, bag=bag))
    if bag is not None and code == 0:
        print(f'closed_loop: recorded {bag}')
    return code


def entry() -> int:
    """Entry point of ``closed_loop``."""
    return run_tool(main)
