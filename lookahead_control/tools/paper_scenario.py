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
Executable ``paper_scenario``: the paper's Fig. 4/5 reproduced offline, side by side.

2 s of straight road, then a right curve of radius 400 m, at 10/20/30/37 m/s, with the
same law on a fixed d_v = d_s (Fig. 4) and on the eq. 26 schedule (Fig. 5).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any, Sequence

from lookahead_control.analysis.metrics import (METRIC_COLUMNS, metrics_legend, notes_list,
                                                run_metrics)
from lookahead_control.analysis.paper_tables import PAPER_FIG5_LEGEND, PAPER_SPEEDS
from lookahead_control.core.cli import (markdown_table, number, parser, run_tool, ToolError,
                                        write_csv, write_json)
from lookahead_control.core.config import load_controller, load_vehicle
from lookahead_control.core.interrupts import raise_if_received
from lookahead_control.core.params import ControllerParams, VehicleParams
from sim_plant.closed_loop_sim import run, SimResult
from sim_plant.scenario import paper_scenario
from sim_plant.vehicle_model import PlantParams

DEFAULT_OUT = Path('bags') / 'paper_scenario'
MARKER = '.paper_scenario'      # in an --out folder this tool wrote
REPORT_FILES = ('report.md', 'metrics.csv', 'metrics.json')
MAX_SPEED = 90.0        # m/s, the scenarios' limit
MAX_DURATION = 600.0    # s of simulated time per run
#: what it runs in place of the node's safety layer
PAPER_RUNS = ("the paper's law alone, as the paper simulates it: no actuator limits, exact "
              'inputs and a_x')
TABLE_COLUMNS = ('controller', 'speed_mps', 'd_v_final_m', *METRIC_COLUMNS)


def reproduce(vehicle: VehicleParams, controller: ControllerParams,
              plant: PlantParams | None = None, speeds: Sequence[float] = PAPER_SPEEDS,
              duration: float = 10.0, dt: float = 0.001,
              control_period: float = 0.01) -> list[tuple[str, SimResult]]:
    """
    Run the paper's scenario with the fixed and the scheduled d_v at each speed.

    :param vehicle: vehicle parameters.
    :param controller: gains etc.; the schedule is set to ``fixed`` (d_v = d_s) and to
        the controller's own schedule (``paper`` unless it says ``exact``).
    :param plant: plant options.
    :param speeds: speeds [m/s].
    :param duration: simulated time [s].
    :param dt: plant step [s].
    :param control_period: controller period [s].
    :return: ``(controller label, result)`` pairs.
    """
    scheduled = controller.schedule if controller.schedule != 'fixed' else 'paper'
    designs = (('fixed', replace(controller, schedule='fixed')),
               (scheduled, replace(controller, schedule=scheduled)))
    runs = []
    for label, ctl in designs:
        for v in speeds:
            raise_if_received()             # a Ctrl-C a lazy import swallowed
            runs.append((label, run(paper_scenario(v, duration), vehicle, ctl, plant, dt=dt,
                                    control_period=control_period)))
    return runs


def metrics_rows(runs: Sequence[tuple[str, SimResult]]) -> list[dict[str, Any]]:
    """
    Return one metrics row per run.

    :param runs: ``(label, result)`` pairs of :func:`reproduce`.
    :return: rows with the columns of ``TABLE_COLUMNS``.
    """
    rows = []
    for label, result in runs:
        row: dict[str, Any] = {'controller': label,
                               'speed_mps': result.scenario.speed.initial}
        row.update(run_metrics(result.time, result.channels, result.vehicle.d_s))
        rows.append({k: row[k] for k in (*TABLE_COLUMNS, 'notes')})
    return rows


def write_report(runs: Sequence[tuple[str, SimResult]], rows: Sequence[dict[str, Any]],
                 out: Path, plots: bool = True) -> Path:
    """
    Write the metrics table (md, csv, json) and the Fig. 4/5 plots into ``out``.

    :param runs: the runs.
    :param rows: their metrics rows.
    :param out: the output folder.
    :param plots: also write PNG plots.
    :return: the markdown report's path.
    """
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / 'metrics.csv', rows)
    write_json(out / 'metrics.json', rows)
    report = out / 'report.md'
    legend = ', '.join(f'{v:g} m/s: {d:g} m' for v, d in PAPER_FIG5_LEGEND.items())
    text = [
        '# Paper scenario (Fig. 4/5): fixed d_v = d_s vs scheduled d_v', '',
        '2 s straight, then a right curve R = 400 m; constant speed; plant: '
        f'{runs[0][1].plant.model} single-track, {runs[0][1].plant.kinematics} '
        'kinematics; controller '
        f'w_n = {runs[0][1].controller.natural_frequency:g} rad/s, '
        f'zeta = {runs[0][1].controller.damping_ratio:g}, reference '
        f'{runs[0][1].controller.reference}.', '',
        metrics_legend(), '',
        markdown_table(rows, TABLE_COLUMNS), '',
        *notes_list(rows, ('controller', 'speed_mps')),
        f"The paper's Fig. 5 legend gives d_v = {legend}; eq. 26 with Table 1 gives "
        'the d_v_final column. This package follows eq. 26.', '']
    if plots:
        from lookahead_control.analysis.plotting import plot_runs
        for label in dict.fromkeys(lbl for lbl, _ in runs):
            series = [{'label': f'{r.scenario.speed.initial:g} m/s', 'time': r.time,
                       **r.channels} for lbl, r in runs if lbl == label]
            png = plot_runs(series, out / f'fig_{label}.png',
                            f'{label} d_v, {runs[0][1].plant.model} plant: 2 s straight, '
                            'then right curve R = 400 m')
            text.append(f'![{label}]({png.name})')
    report.write_text('\n'.join(text) + '\n', encoding='utf-8')
    return report


def main(argv: Sequence[str] | None = None) -> int:
    """
    Reproduce the paper's Fig. 4/5 offline and print the metrics table.

    :param argv: command-line arguments.
    :return: exit code.
    """
    p = parser("reproduce the paper's Fig. 4/5 scenario: fixed d_v = d_s vs eq. 26")
    p.add_argument('--controller', type=Path, default=None,
                   help='controller params YAML (default: config/controller.yaml)')
    p.add_argument('--plant', choices=('linear', 'nonlinear'), default='linear',
                   help='plant model (default linear)')
    p.add_argument('--speeds', type=number(0.0, MAX_SPEED, low_open=True, unit='m/s'),
                   nargs='+', default=list(PAPER_SPEEDS), metavar='M/S',
                   help='constant speeds of the runs [m/s] (default: 10 20 30 37)')
    p.add_argument('--duration', type=number(0.0, MAX_DURATION, low_open=True, unit='s'),
                   default=10.0, metavar='S', help='simulated time per run [s] (default 10)')
    p.add_argument('--out', type=Path, default=None,
                   help='folder for report.md, metrics.csv/json and fig_*.png (default: '
                   f'{DEFAULT_OUT} when neither --plot nor --json is given)')
    p.add_argument('--no-plots', action='store_true',
                   help='write no PNG into the --out folder')
    p.add_argument('--overwrite', action='store_true',
                   help='replace report files in an --out folder paper_scenario did not '
                   'write (nothing else there is touched)')
    args = p.parse_args(argv)
    out = args.out
    if out is None and args.plot is None and args.json is None:
        out = DEFAULT_OUT
    if args.no_plots and out is None:
        raise ToolError('--no-plots: no report folder is written (give --out)')
    if out is not None:
        check_out(out, args.overwrite)  # before the runs: nothing of the user's is replaced
    vehicle = load_vehicle(args.vehicle)
    controller = load_controller(None)
    if args.controller is not None:
        # read once and checked as the node reads it: a file without the node's section,
        # a name the node does not have, a file read once (<(...)), another vehicle or a
        # node setting the offline runs do not run ran the defaults as if from the file
        # (dev-probe55)
        from lookahead_control.tools.compare import load_law_settings, NOT_RUN_OFFLINE
        # the paper's simulation has no actuator limits: neither has its reproduction;
        # it runs the paper's law, whatever the file says of the others (dev-probe59:
        # lane_keeping.* and the baselines' settings were taken silently)
        controller = load_law_settings(args.controller, vehicle,
                                       (*NOT_RUN_OFFLINE, 'use_curvature_preview',
                                        'lane_keeping.', 'pure_pursuit.', 'stanley.', 'lqr.'),
                                       'paper_scenario', PAPER_RUNS,
                                       output_stage=False).controller
    runs = reproduce(vehicle, controller,
                     PlantParams(model=args.plant), args.speeds, args.duration)
    rows = metrics_rows(runs)
    print(markdown_table(rows, TABLE_COLUMNS, digits=3))
    print('\n'.join(notes_list(rows, ('controller', 'speed_mps'))))
    if args.json is not None:
        write_json(args.json, rows)
        print(f'wrote {args.json}')
    if args.plot is not None:
        from lookahead_control.analysis.plotting import plot_runs
        series = [{'label': f'{label} {r.scenario.speed.initial:g} m/s', 'time': r.time,
                   **r.channels} for label, r in runs]
        png = plot_runs(series, args.plot, 'fixed d_s vs scheduled d_v: 2 s straight, then '
                        'right curve R = 400 m')
        print(f'wrote {png}')
    if out is not None:
        print(f'wrote {write_report(runs, rows, out, plots=not args.no_plots)}')
        (out / MARKER).write_text('report.md, metrics.csv, metrics.json, fig_*.png\n',
                                  encoding='utf-8')
    return 0


def check_out(out: Path, overwrite: bool = False) -> None:
    """
    Refuse an output folder holding files of the report's names that this tool did not write.

    :param out: the ``--out`` folder.
    :param overwrite: the user allowed replacing them.
    :raises ToolError: ``out`` is a file, or would lose a file it did not write.
    """
    if out.exists() and not out.is_dir():
        raise ToolError(f'--out {out}: is a file, not a folder')
    if not out.is_dir() or (out / MARKER).is_file() or overwrite:
        return
    taken = sorted(p.name for p in out.iterdir() if p.name in REPORT_FILES
                   or (p.name.startswith('fig_') and p.suffix == '.png'))
    if taken:
        raise ToolError(f'--out {out}: holds {", ".join(taken)}, not written by '
                        'paper_scenario; give a new or empty folder, or --overwrite to '
                        'replace them')


def entry() -> int:
    """Entry point of ``paper_scenario``."""
    return run_tool(main)


if __name__ == '__main__':
    import sys
    sys.exit(entry())
