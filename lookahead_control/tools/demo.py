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
``demo``: the paper scenario through the ROS system, recorded, then analysed.

For fixed d_v = d_s and the eq. 26 schedule at each speed: sim_plant, controller and
the recorder as three processes in lockstep, one bag per run; then ``analyze`` writes
``report.md`` with the table and plots, plus the largest difference between each ROS
run's steering and the offline core runner's.
"""

from __future__ import annotations

import argparse
from pathlib import Path
import shutil
import sys
from typing import Sequence

from lookahead_control.analysis.paper_tables import PAPER_SPEEDS
from lookahead_control.core.cli import markdown_table, run_tool, ToolError
from lookahead_control.core.config import source_config_dir
from lookahead_control.core.params import ControllerParams, VehicleParams
from lookahead_control.ros.closed_loop import LoopConfig, run_loop
from lookahead_control.tools.analyze_tool import analyze, COLUMNS, write_outputs
import numpy as np
from sim_plant.closed_loop_sim import run
from sim_plant.scenario import load_scenario


def offline_difference(scenario: Path, speed: float, schedule: str,
                       stamps_s: np.ndarray, steering: np.ndarray) -> float:
    """
    Return max |ROS steering - offline runner steering| at the recorded steps [rad].

    :param scenario: the scenario file.
    :param speed: the run's speed [m/s].
    :param schedule: the d_v schedule.
    :param stamps_s: step times of the recording [s].
    :param steering: the recorded steering at those steps [rad].
    :return: the largest difference.
    """
    result = run(load_scenario(scenario, speed), VehicleParams(),
                 ControllerParams(schedule=schedule))
    index = np.clip(np.round(stamps_s / (result.time[1] - result.time[0])).astype(int), 0,
                    result.time.size - 1)
    return float(np.max(np.abs(result['steering_cmd'][index] - steering)))


def main(argv: Sequence[str] | None = None) -> int:
    """
    Run, record and analyse the demo.

    :param argv: command-line arguments.
    :return: exit code.
    """
    p = argparse.ArgumentParser(prog='demo', description=__doc__.strip().splitlines()[0])
    p.add_argument('--out', type=Path, default=Path('bags') / 'demo')
    p.add_argument('--speeds', type=float, nargs='+', default=list(PAPER_SPEEDS))
    p.add_argument('--schedules', nargs='+', default=['fixed', 'paper'])
    args = p.parse_args(argv)
    scenario = source_config_dir() / 'scenarios' / 'paper_r400.yaml'
    if args.out.exists():
        shutil.rmtree(args.out)
    args.out.mkdir(parents=True)            # unwritable: one line, before any run
    bags = []
    for schedule in args.schedules:
        for speed in args.speeds:
            bag = args.out / f'{schedule}_{speed:g}'
            print(f'demo: {schedule} d_v at {speed:g} m/s -> {bag}', flush=True)
            if run_loop(LoopConfig(scenario, speed=speed, schedule=schedule, bag=bag)) != 0:
                raise ToolError(f'the closed loop {schedule} at {speed:g} m/s failed')
            bags.append(bag)
    results = analyze(bags)
    for (run_data, series, row), bag in zip(results, bags):
        schedule, speed = bag.name.split('_')
        row['vs_offline_rad'] = offline_difference(
            scenario, float(speed), schedule, series.time, series.channels['steering_cmd'])
    report = write_outputs(results, args.out, title='Demo: the paper scenario through '
                           'sim_plant + controller + recorder (lockstep, DDS)')
    rows = [{k: row[k] for k in (*COLUMNS, 'vs_offline_rad')} for _, _, row in results]
    with report.open('a', encoding='utf-8') as f:
        f.write('\n## ROS runs vs the offline core runner\n\n'
                'Largest |steering difference| per run [rad] (curvature crosses DDS as '
                'float32):\n\n' + markdown_table(
                    [{'bag': r['bag'], 'speed_mps': r['speed_mps'],
                      'vs_offline_rad': r['vs_offline_rad']} for r in rows], digits=3)
                + '\n')
    print(markdown_table(rows, digits=3))
    print(f'wrote {report}')
    return 0


def entry() -> int:
    """Entry point of ``demo``."""
    return run_tool(main)


if __name__ == '__main__':
    sys.exit(entry())
