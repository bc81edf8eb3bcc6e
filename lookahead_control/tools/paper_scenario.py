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
from lookahead_control.core.cli import markdown_table, parser, run_tool, write_csv, write_json
from lookahead_control.core.config import load_controller, load_vehicle
from lookahead_control.core.params import ControllerParams, VehicleParams
from sim_plant.closed_loop_sim import run, SimResult
from sim_plant.scenario import paper_scenario
from sim_plant.vehicle_model import PlantParams

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
                            f'{label} d_v: 2 s straight, then right curve R = 400 m')
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
    p.add_argument('--plant', choices=('linear', 'nonlinear'), default='linear')
    p.add_argument('--speeds', type=float, nargs='+', default=list(PAPER_SPEEDS))
    p.add_argument('--duration', type=float, default=10.0)
    p.add_argument('--out', type=Path, default=Path('bags') / 'paper_scenario',
                   help='folder for report.md, metrics.csv/json and PNGs')
    p.add_argument('--no-plots', action='store_true')
    args = p.parse_args(argv)
    runs = reproduce(load_vehicle(args.vehicle), load_controller(args.controller),
                     PlantParams(model=args.plant), args.speeds, args.duration)
    rows = metrics_rows(runs)
    print(markdown_table(rows, TABLE_COLUMNS, digits=3))
    print('\n'.join(notes_list(rows, ('controller', 'speed_mps'))))
    report = write_report(runs, rows, args.out, plots=not args.no_plots)
    print(f'wrote {report}')
    return 0


def entry() -> int:
    """Entry point of ``paper_scenario``."""
    return run_tool(main)
