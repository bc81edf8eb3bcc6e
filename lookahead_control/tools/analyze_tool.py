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

"""``analyze``: metrics table (md, csv, json) and plots from one or more bags."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any, Sequence

from lookahead_control.analysis.bag_analysis import bag_row, run_series, RunSeries, speed_points
from lookahead_control.analysis.paper_tables import schedule_table, speed_grid
from lookahead_control.bags.run_data import load_run, RunData
from lookahead_control.core.cli import assignments, markdown_table, run_tool, write_csv, write_json
from lookahead_control.core.params import VehicleParams

COLUMNS = ('run', 'speed_mps', 'd_v_final', 'peak_cg', 'rms_cg', 'peak_bumper',
           'rms_bumper', 'peak_look_ahead', 'rms_look_ahead', 'yaw_overshoot',
           'yaw_damping', 'yaw_settling', 'peak_steering', 'peak_steering_rate',
           'latency_p50_ms', 'latency_p99_ms', 'steps', 'unanswered', 'dropped')


def analyze(bags: Sequence[Path], topics: dict[str, str] | None = None
            ) -> list[tuple[RunData, RunSeries, dict[str, Any]]]:
    """
    Read every bag and compute its metrics row.

    :param bags: bag directories.
    :param topics: contract topic name overrides (role -> topic).
    :return: ``(run, series, row)`` per bag.
    """
    out = []
    for bag in bags:
        run = load_run(bag, topics)
        series = run_series(run)
        out.append((run, series, bag_row(run, series)))
    return out


def write_outputs(results: Sequence[tuple[RunData, RunSeries, dict[str, Any]]],
                  out: Path, plots: bool = True, title: str = 'Recorded runs') -> Path:
    """
    Write ``report.md``, ``metrics.csv``, ``metrics.json`` and the PNG plots.

    :param results: the output of :func:`analyze`.
    :param out: the folder.
    :param plots: also write the plots.
    :param title: the report's heading.
    :return: the report's path.
    """
    out.mkdir(parents=True, exist_ok=True)
    rows = [{k: row[k] for k in COLUMNS} for _, _, row in results]
    write_csv(out / 'metrics.csv', rows)
    write_json(out / 'metrics.json', rows)
    text = [f'# {title}', '',
            'One row per bag. Errors [m]: `cg` at the centre of gravity, `bumper` at d_s, '
            '`look_ahead` at the look-ahead point (from the lane centre). Relative yaw '
            'step response after the curve starts; steering [rad, rad/s]; latency: '
            'steering receive time minus lateral-error receive time; `dropped`: messages '
            'the recorder counted as lost (-1: not counted).', '',
            markdown_table(rows, digits=3), '',
            'Bags: ' + ', '.join(f'`{run.bag}`' for run, _, _ in results), '']
    if plots:
        from lookahead_control.analysis.plotting import plot_measured_look_ahead, plot_runs
        groups: dict[str, list[dict[str, Any]]] = {}
        for run, series, row in results:
            groups.setdefault(row['run'], []).append(
                {'label': f'{row["speed_mps"]:g} m/s', 'time': series.time,
                 **series.channels})
        for label, runs in groups.items():
            png = plot_runs(runs, out / f'fig_{label}.png',
                            f'{label} d_v: recorded runs, one line per speed')
            text.append(f'![{label}]({png.name})')
        overlay = [{'label': f'{row["run"]} {row["speed_mps"]:g} m/s', 'time': s.time,
                    **s.channels} for _, s, row in results]
        png = plot_runs(overlay, out / 'overlay.png', 'all runs')
        text.append(f'![overlay]({png.name})')
        top = max(float(s.channels['v_x'].max()) for _, s, _ in results)
        curve = schedule_table(VehicleParams(), speed_grid(1.0, max(top, 40.0), 0.5))
        png = plot_measured_look_ahead(curve, speed_points([s for _, s, _ in results]),
                                       out / 'look_ahead_vs_speed.png')
        text.append(f'![d_v vs speed]({png.name})')
    report = out / 'report.md'
    report.write_text('\n'.join(text) + '\n', encoding='utf-8')
    return report


def main(argv: Sequence[str] | None = None) -> int:
    """
    Analyze bags and print the metrics table.

    :param argv: command-line arguments.
    :return: exit code.
    """
    p = argparse.ArgumentParser(prog='analyze', description='metrics table and plots '
                                'from rosbag2 MCAP bags with the contract topics')
    p.add_argument('bags', type=Path, nargs='+')
    p.add_argument('--out', type=Path, default=Path('bags') / 'analysis',
                   help='folder for report.md, metrics.csv/json and PNGs')
    p.add_argument('--topic', action='append', default=[], metavar='ROLE=TOPIC',
                   help='contract topic name in the bags, e.g. lateral_error=/lane/offset')
    p.add_argument('--no-plots', action='store_true')
    args = p.parse_args(argv)
    results = analyze(args.bags, assignments(args.topic, '--topic'))
    report = write_outputs(results, args.out, plots=not args.no_plots)
    print(markdown_table([{k: row[k] for k in COLUMNS} for _, _, row in results], digits=3))
    print(f'wrote {report}')
    return 0


def entry() -> int:
    """Entry point of ``analyze``."""
    return run_tool(main)


if __name__ == '__main__':
    import sys
    sys.exit(entry())
