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

For fixed d_v = d_s, the eq. 26 schedule and the CG-compensated law side by side at each
speed: sim_plant, controller and the recorder as three processes in lockstep, one bag per
run; then ``analyze`` writes ``report.md`` with the table and plots, plus the largest
difference between each ROS run's steering and the offline core runner's (which has no
output limits: where the node's rate or angle limit cuts a command, the two part). One
more run goes through path_bridge (sim_plant publishing odometry and the road as a path,
as a vehicle stack would).
"""

from __future__ import annotations

from pathlib import Path
import shutil
import sys
from typing import Sequence

from lookahead_control.analysis.paper_tables import PAPER_SPEEDS
from lookahead_control.core.baselines import BaselineParams
from lookahead_control.core.cli import ArgumentParser, markdown_table, number, run_tool, ToolError
from lookahead_control.core.config import source_config_dir
from lookahead_control.core.controller import build_law, LAW_NAMES
from lookahead_control.core.params import ControllerParams, SCHEDULE_MODES, VehicleParams
from lookahead_control.ros.closed_loop import LoopConfig, run_loop
from lookahead_control.tools.analyze_tool import (analyze, COLUMNS, diagnostics_lines,
                                                  write_outputs)
import numpy as np
from sim_plant.closed_loop_sim import run
from sim_plant.scenario import load_scenario

MANIFEST = '.demo_written'     # what the last demo run wrote into its --out folder
MAX_SPEED = 90.0               # m/s, the scenarios' limit


def offline_difference(scenario: Path, speed: float, schedule: str,
                       stamps_s: np.ndarray, steering: np.ndarray,
                       law: str = 'paper') -> float:
    """
    Return max |ROS steering - offline runner steering| at the recorded steps [rad].

    :param scenario: the scenario file.
    :param speed: the run's speed [m/s].
    :param schedule: the d_v schedule (of the paper law).
    :param stamps_s: step times of the recording [s].
    :param steering: the recorded steering at those steps [rad] (NaN: unanswered).
    :param law: the steering law (the node's ``law`` parameter, default settings).
    :return: the largest difference over the answered steps.
    """
    vehicle, controller = VehicleParams(), ControllerParams(schedule=schedule)
    result = run(load_scenario(scenario, speed), vehicle,
                 controller if law == 'paper' else build_law(law, vehicle, controller,
                                                             BaselineParams()))
    index = np.clip(np.round(stamps_s / (result.time[1] - result.time[0])).astype(int), 0,
                    result.time.size - 1)
    answered = ~np.isnan(steering)
    return float(np.max(np.abs(result['steering_cmd'][index] - steering)[answered],
                        initial=0.0))


def prepare_out(out: Path) -> None:
    """
    Make ``out`` ready for a demo run without deleting anything demo did not write.

    A missing or empty folder is used as it is. A folder a previous demo run made (it
    holds :data:`MANIFEST`, listing what that run wrote) loses exactly those entries,
    and only if it holds nothing else. Any other non-empty folder is refused.

    :param out: the output folder.
    :raises ToolError: ``out`` is a file, or holds files demo did not write.
    """
    if out.exists() and not out.is_dir():
        raise ToolError(f'--out {out}: is a file, not a folder')
    entries = sorted(p.name for p in out.iterdir()) if out.is_dir() else []
    if entries:
        manifest = out / MANIFEST
        written = (set(manifest.read_text(encoding='utf-8').split('\n')) - {''}
                   if manifest.is_file() else set())
        foreign = [e for e in entries if e != MANIFEST and e not in written]
        if not manifest.is_file() or foreign:
            raise ToolError(f'--out {out}: not empty and not a demo folder (holds '
                            f'{", ".join(foreign[:3])}{" ..." if len(foreign) > 3 else ""}'
                            '); give a new or empty folder: demo deletes only what it wrote')
        for name in sorted(written & set(entries)):
            target = out / name
            if target.is_dir() and not target.is_symlink():
                shutil.rmtree(target)
            else:
                target.unlink()
        manifest.unlink()
    out.mkdir(parents=True, exist_ok=True)         # unwritable: one line, before any run


def record_written(out: Path) -> None:
    """
    List what this run wrote into ``out`` (the next run may replace exactly that).

    :param out: the output folder.
    """
    names = sorted(p.name for p in out.iterdir() if p.name != MANIFEST)
    (out / MANIFEST).write_text('\n'.join(names) + '\n', encoding='utf-8')


def bridge_run(scenario: Path, out: Path, report: Path) -> float:
    """
    Run the paper scenario at 37 m/s through path_bridge, as on a real vehicle.

    sim_plant publishes odometry and the road as a path; path_bridge turns them into the
    controller's inputs. The run's section is appended to ``report``.

    :param scenario: the scenario file.
    :param out: the demo's output folder (the bag goes to ``bridge_paper_37`` in it).
    :param report: the report to append to.
    :return: the largest |steering - offline runner| of the run [rad].
    :raises ToolError: the closed loop failed.
    """
    bridge = out / 'bridge_paper_37'
    print(f'demo: paper d_v at 37 m/s through path_bridge -> {bridge}', flush=True)
    try:
        if run_loop(LoopConfig(scenario, speed=37.0, bag=bridge, via_bridge=True)) != 0:
            raise ToolError('the closed loop through path_bridge failed')
    finally:
        record_written(out)
    (run, series, row), = analyze([bridge])
    gap = offline_difference(scenario, 37.0, 'paper', series.time,
                             series.channels['steering_cmd'])
    with report.open('a', encoding='utf-8') as f:
        f.write('\n## Through path_bridge\n\nsim_plant (odometry + the road as a path) -> '
                f'path_bridge -> controller, paper d_v at 37 m/s (`{bridge.name}`): largest '
                f'|steering - offline runner| {gap:.3g} rad, at the straight-to-curve step '
                "(derived bound 0.020 rad, docs/vehicle_bridge.md). The controller's "
                f"/diagnostics, at worst {row['diagnostics']} (a run through the bridge "
                "starts with the simulator's step 0 repeated until it is answered, and the "
                'controller counts the repeats as duplicates: docs/vehicle_bridge.md):\n\n'
                + '\n'.join(diagnostics_lines(run)))
    return gap


def main(argv: Sequence[str] | None = None) -> int:
    """
    Run, record and analyse the demo.

    :param argv: command-line arguments.
    :return: exit code.
    """
    p = ArgumentParser(prog='demo', description=__doc__.strip().splitlines()[0])
    p.add_argument('--out', type=Path, default=Path('bags') / 'demo',
                   help='output folder for the bags, report.md and plots (default '
                   'bags/demo); must be new, empty or made by demo: demo replaces what '
                   'its previous run wrote there and refuses any other non-empty folder')
    p.add_argument('--speeds', type=number(0.0, MAX_SPEED, low_open=True, unit='m/s'),
                   nargs='+', default=list(PAPER_SPEEDS), metavar='M/S',
                   help='constant speeds of the runs [m/s] (default: 10 20 30 37)')
    p.add_argument('--schedules', nargs='+', default=['fixed', 'paper'],
                   choices=SCHEDULE_MODES, metavar='SCHEDULE',
                   help=f'd_v schedules to run, of {", ".join(SCHEDULE_MODES)} '
                   '(default: fixed paper)')
    p.add_argument('--laws', nargs='*', default=['cg_compensated'],
                   choices=[name for name in LAW_NAMES if name != 'paper'], metavar='LAW',
                   help="other steering laws to run beside the paper law's schedules, of "
                   f'{", ".join(n for n in LAW_NAMES if n != "paper")} (default: '
                   'cg_compensated; none: give --laws alone)')
    p.add_argument('--no-bridge', action='store_true',
                   help='skip the run through path_bridge (paper d_v at 37 m/s, odometry '
                   'and the road as a path, as a vehicle stack would send them)')
    args = p.parse_args(argv)
    scenario = source_config_dir() / 'scenarios' / 'paper_r400.yaml'
    for speed in args.speeds:                   # a bad scenario: one line, no processes
        load_scenario(scenario, speed)
    prepare_out(args.out)
    # (bag label, law, d_v schedule): the paper law per schedule, then the other laws
    variants = ([(schedule, 'paper', schedule) for schedule in dict.fromkeys(args.schedules)]
                + [(law, law, 'paper') for law in dict.fromkeys(args.laws)])
    bags: list[tuple[Path, str, str, float]] = []
    try:
        for label, law, schedule in variants:
            for speed in dict.fromkeys(args.speeds):
                bag = args.out / f'{label}_{speed:g}'
                what = f'{schedule} d_v' if law == 'paper' else f'law {law}'
                print(f'demo: {what} at {speed:g} m/s -> {bag}', flush=True)
                if run_loop(LoopConfig(scenario, speed=speed, schedule=schedule,
                                       bag=bag, law=law)) != 0:
                    raise ToolError(f'the closed loop {what} at {speed:g} m/s failed')
                bags.append((bag, law, schedule, speed))
    finally:
        record_written(args.out)
    results = analyze([bag for bag, _, _, _ in bags])
    for (run_data, series, row), (bag, law, schedule, speed) in zip(results, bags):
        row['vs_offline_rad'] = offline_difference(
            scenario, speed, schedule, series.time, series.channels['steering_cmd'], law)
    report = write_outputs(results, args.out, title='Demo: the paper scenario through '
                           'sim_plant + controller + recorder (lockstep, DDS)')
    rows = [{k: row[k] for k in (*COLUMNS, 'vs_offline_rad')} for _, _, row in results]
    with report.open('a', encoding='utf-8') as f:
        f.write('\n## ROS runs vs the offline core runner\n\n'
                'Largest |steering difference| per run [rad]. The curvature crosses DDS as '
                "float32; the offline runner has no output limits, so where the node's rate "
                'or angle limit cuts a command (the CG-compensated law asks for a steering '
                'step at the curvature step of this scenario at 30-37 m/s) the two runs part '
                'from there on:\n\n' + markdown_table(
                    [{'bag': r['bag'], 'speed_mps': r['speed_mps'],
                      'vs_offline_rad': r['vs_offline_rad']} for r in rows], digits=3)
                + '\n')
    if not args.no_bridge:
        gap = bridge_run(scenario, args.out, report)
    record_written(args.out)
    print(markdown_table(rows, digits=3))
    if not args.no_bridge:
        print(f'through path_bridge: largest |steering - offline| {gap:.3g} rad')
    print(f'wrote {report}')
    return 0


def entry() -> int:
    """Entry point of ``demo``."""
    return run_tool(main)


if __name__ == '__main__':
    sys.exit(entry())
