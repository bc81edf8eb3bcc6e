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
import re
from typing import Any, Sequence

from lookahead_control.analysis.bag_analysis import (bag_row, law_label, run_diagnostics,
                                                     run_label, run_series, RunSeries,
                                                     speed_points)
from lookahead_control.analysis.diagnostics_summary import level_name, LEVELS
from lookahead_control.analysis.metrics import METRIC_COLUMNS, metrics_legend, notes_list
from lookahead_control.analysis.paper_tables import schedule_table, speed_grid
from lookahead_control.bags.recorded_diagnostics import DIAGNOSTICS
from lookahead_control.bags.run_data import CONTROLLER_NODE, load_run, RunData, TOPICS
from lookahead_control.core.cli import (assignments, claim_output, markdown_table,
                                        record_output, run_tool, ToolError, write_csv,
                                        write_json)
from lookahead_control.core.config import dataclass_from_params
from lookahead_control.core.interrupts import raise_if_received
from lookahead_control.core.params import VehicleParams

# plot titles of the laws (the paper's law by its d_v schedule)
LAW_TITLES = {'fixed': 'fixed d_v', 'paper': 'd_v of eq. 26', 'exact': 'd_v of eq. 24',
              'cg_compensated': 'CG-compensated law'}
LABEL_COLUMNS = ('bag', 'scenario', 'plant', 'mode', 'rate_hz', 'law', 'schedule',
                 'speed_mps')
COLUMNS = (*LABEL_COLUMNS, 'd_v_final_m', *METRIC_COLUMNS, 'latency_p50_ms',
           'latency_p99_ms', 'steps', 'unanswered', 'dropped', 'max_gap_s',
           'compliance_memory_final_ratio', 'diagnostics')


def topic_overrides(items: Sequence[str]) -> dict[str, str]:
    """
    Parse ``--topic ROLE=TOPIC`` options, refusing unknown roles.

    The names are resolved and checked by :func:`~lookahead_control.bags.run_data.load_run`
    as the ``--node`` resolves them (a relative name in its namespace, ``~`` its name).

    :param items: the option's values.
    :return: role -> topic.
    :raises ToolError: an unknown role.
    """
    out = assignments(items, '--topic')
    for role, topic in out.items():
        if role not in TOPICS:
            raise ToolError(f'--topic {role}={topic}: unknown role {role!r}; roles: '
                            f'{", ".join(TOPICS)}')
    return out


def analyze(bags: Sequence[Path], topics: dict[str, str] | None = None,
            node: str = CONTROLLER_NODE, diagnostics: str = DIAGNOSTICS
            ) -> list[tuple[RunData, RunSeries, dict[str, Any]]]:
    """
    Read every bag and compute its metrics row.

    :param bags: bag directories.
    :param topics: contract topic name overrides (role -> topic).
    :param node: the controller node whose run to analyze (its parameters, debug and
        namespace's topics: :func:`~lookahead_control.bags.run_data.node_topics`).
    :param diagnostics: the topic of the controller's statuses.
    :return: ``(run, series, row)`` per bag.
    """
    out = []
    for bag in bags:
        raise_if_received()                 # a Ctrl-C a lazy import swallowed
        run = load_run(bag, topics, node, diagnostics)
        series = run_series(run)
        out.append((run, series, bag_row(run, series)))
    return out


def curve_vehicle(runs: Sequence[RunData]) -> tuple[VehicleParams, str]:
    """
    Return the vehicle of the d_v-vs-speed curves and a sentence saying which it is.

    :param runs: the analysed runs.
    :return: the bags' vehicle if they all record the same one, else the default.
    """
    recorded = {tuple(sorted((k, v) for k, v in run.controller_params.items()
                             if k.startswith('vehicle.'))) for run in runs}
    if len(recorded) == 1 and next(iter(recorded)):
        vehicle = dataclass_from_params(VehicleParams, dict(next(iter(recorded))), 'vehicle',
                                        'bag parameters')
        return vehicle, (f"d_v against speed: the curves are the bags' vehicle "
                         f'(d_s = {vehicle.d_s:g} m, eta = {vehicle.eta:.4g} s^2/m).')
    return VehicleParams(), ('d_v against speed: the bags record no vehicle or several; '
                             'the curves are the default vehicle (assumed).')


def figure_name(label: str) -> str:
    """
    Return the file name of a law's figure: ``fig_<label>.png``, a file name whatever it is.

    :param label: the law's label (:func:`law_label`: ``n/a`` when the bag names none).
    :return: the name, every character but letters, digits, ``_``, ``-`` and ``.`` as ``_``.
    """
    return 'fig_' + re.sub(r'[^A-Za-z0-9_.-]', '_', label) + '.png'


def output_names(results: Sequence[tuple[RunData, RunSeries, dict[str, Any]]],
                 plots: bool = True) -> list[str]:
    """
    Return the names of the files :func:`write_outputs` will write for these results.

    :param results: the output of :func:`analyze`.
    :param plots: the plots are written too.
    :return: the file names.
    """
    names = ['metrics.csv', 'metrics.json', 'report.md']
    if plots:
        labels = dict.fromkeys(law_label(row) for _, _, row in results)
        names += [figure_name(label) for label in labels]
        names += ['overlay.png', 'look_ahead_vs_speed.png']
    return names


def bags_line(results: Sequence[tuple[RunData, RunSeries, dict[str, Any]]]) -> str:
    """
    Return the report's line naming the bags, and the controller unless ``/controller``.

    :param results: the output of :func:`analyze`.
    :return: e.g. ``Bags (controller /car_b/controller): `two```.
    """
    nodes = sorted({run.controller_node for run, _, _ in results})
    which = f' (controller {", ".join(nodes)})' if nodes != [CONTROLLER_NODE] else ''
    return f'Bags{which}: ' + ', '.join(f'`{run.bag}`' for run, _, _ in results)


def write_outputs(results: Sequence[tuple[RunData, RunSeries, dict[str, Any]]],
                  out: Path, plots: bool = True, title: str = 'Recorded runs',
                  written: list[Path] | None = None) -> Path:
    """
    Write ``report.md``, ``metrics.csv``, ``metrics.json`` and the PNG plots.

    :param results: the output of :func:`analyze`.
    :param out: the folder.
    :param plots: also write the plots.
    :param title: the report's heading.
    :param written: if given, every file written is appended to it.
    :return: the report's path.
    """
    files = [out / 'metrics.csv', out / 'metrics.json']
    out.mkdir(parents=True, exist_ok=True)
    rows = [{k: row[k] for k in (*COLUMNS, 'notes')} for _, _, row in results]
    write_csv(out / 'metrics.csv', rows)
    write_json(out / 'metrics.json', rows)
    text = [f'# {title}', '',
            'One row per bag: its name, scenario, plant (`n/a`: the bag has no simulator '
            'parameters, e.g. a real vehicle), mode and rate of the simulator, steering '
            'law and d_v schedule (used by the `paper` law). ' + metrics_legend()
            + ' Latency [ms]: steering receive time minus lateral-error receive time, as '
            'the recorder saw them; `dropped`: messages the recorder counted as lost '
            '(-1: not counted); `max_gap_s`: the longest gap between stamps, or between '
            'receive times (not in lockstep), of any input or of the steering (0: none); '
            "`compliance_memory_final_ratio`: the default law's memory of the rear "
            "compliance over the model's at its end, or before a restart it learned "
            "nothing after (`notes`); start the car's next run from it: "
            '`lane_keeping.compliance_memory_seed` (`-` for other laws); `diagnostics`: the '
            "worst level of the controller's `/diagnostics` during the run (`-`: none "
            'recorded; what it told: the section below).',
            '',
            markdown_table(rows, COLUMNS, digits=3), '',
            *notes_list(rows, ('bag',)),
            bags_line(results), '', *diagnostics_section(results)]
    if plots:
        from lookahead_control.analysis.plotting import plot_measured_look_ahead, plot_runs
        groups: dict[str, list[dict[str, Any]]] = {}
        for run, series, row in results:
            groups.setdefault(law_label(row), []).append(
                {'label': run_label(row), 'time': series.time, **series.channels})
        for label, runs in groups.items():
            png = plot_runs(runs, out / figure_name(label),
                            f'{LAW_TITLES.get(label, "law " + label)}: one line per bag')
            files.append(png)
            text.append(f'![{label}]({png.name})')
        overlay = [{'label': run_label(row), 'time': s.time, **s.channels}
                   for _, s, row in results]
        png = plot_runs(overlay, out / 'overlay.png', 'all bags')
        files.append(png)
        text.append(f'![overlay]({png.name})')
        top = max(float(s.channels['v_x'].max()) for _, s, _ in results)
        vehicle, said = curve_vehicle([run for run, _, _ in results])
        text.append(said)
        curve = schedule_table(vehicle, speed_grid(1.0, max(top, 40.0), 0.5))
        png = plot_measured_look_ahead(curve, speed_points([s for _, s, _ in results]),
                                       out / 'look_ahead_vs_speed.png')
        files.append(png)
        text.append(f'![d_v vs speed]({png.name})')
    report = out / 'report.md'
    report.write_text('\n'.join(text) + '\n', encoding='utf-8')
    if written is not None:
        written.extend([*files, report])
    return report


def diagnostics_section(results: Sequence[tuple[RunData, RunSeries, dict[str, Any]]]
                        ) -> list[str]:
    """
    Return the report's section of what each run's controller told on ``/diagnostics``.

    :param results: the output of :func:`analyze`.
    :return: markdown lines: the legend, then :func:`diagnostics_lines` per bag.
    """
    lines = ['## What the controller told (/diagnostics)', '', DIAGNOSTICS_LEGEND, '']
    for run, _, _ in results:
        lines += diagnostics_lines(run)
    return lines


#: the legend of :func:`diagnostics_section`
DIAGNOSTICS_LEGEND = (
    "Each reason of the controller's statuses once, as it was first told, with the worst "
    'level of the statuses that gave it, when it was first told (t from the first '
    "lateral-error stamp, on the node's clock; the node reports once a second of wall "
    'time, which in a lockstep run faster than real time is several seconds of t, so what '
    'a status tells may have begun that much before) and how many statuses gave it; then '
    "the counters of the last status that are not 0 (counted from the node's start; a "
    "check's `[s]`: the seconds it found something). Where a simulator's run finished its "
    'scenario, what the node told after its last input (the clock and the inputs stopping) '
    'is listed apart and not counted in the `diagnostics` column. docs/safety.md says what '
    'the reasons mean.')


def diagnostics_lines(run: RunData) -> list[str]:
    """
    Return one bag's lines of :func:`diagnostics_section`.

    :param run: the run.
    :return: markdown lines: its statuses by level, each reason once (its worst level,
        when first told, number of statuses, and its text as first told), what was told
        after a finished scenario, and the counters of its last status that are not 0.
    """
    summary = run_diagnostics(run)
    said = run.diagnostics.notes() if run.diagnostics is not None else []
    if summary is None:
        return [f'- `{run.bag.name}`: ' + (said[0] if said else 'no /diagnostics in the bag'),
                '']
    by_level = ', '.join(f'{name} {count}' for name, count in zip(LEVELS, summary.levels)
                         if count)
    lines = [f'- `{run.bag.name}`: {summary.reports} statuses of {run.controller_node}'
             + (f' ({by_level})' if by_level else '') + ''.join(f'; {text}' for text in said)]
    lines += [f'  - {level_name(t.level)} first told at t = {t.first_s:.3g} s, in '
              f'{t.reports}: {report_text(t.example)}' for t in summary.told]
    lines += [f'  - after the simulator finished (not counted): {level_name(t.level)} in '
              f'{t.reports}: {report_text(t.example)}' for t in summary.at_end]
    if summary.counters:
        lines.append('  - counters at the last status: ' + ', '.join(
            f'{report_text(key)} {report_text(value)}' for key, value in summary.counters))
    return lines + ['']


def report_text(text: str) -> str:
    """
    Return recorded text fit for one line of the markdown report.

    :param text: a status's text (any node's: newlines, control characters, HTML).
    :return: one line, control characters as spaces, ``<``, ``>`` and ``&`` escaped.
    """
    flat = ''.join(c if c.isprintable() else ' ' for c in text)
    return flat.replace('&', '&amp;').replace('<', '&lt;').replace('>', '&gt;')


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
                   help='folder for report.md, metrics.csv/json and PNGs (new, empty or '
                   'written by analyze; see --overwrite)')
    p.add_argument('--overwrite', action='store_true',
                   help='write into a non-empty --out folder analyze did not write, '
                   'replacing files of its names there (nothing else is touched)')
    p.add_argument('--topic', action='append', default=[], metavar='ROLE=TOPIC',
                   help='contract topic name in the bags, e.g. lateral_error=/lane/offset (a '
                   "relative name is in the --node's namespace, ~/x under its name); ROLE is "
                   f'one of {", ".join(TOPICS)}')
    p.add_argument('--node', default=CONTROLLER_NODE, metavar='NAME',
                   help='the controller node whose run to analyze, in a bag of several '
                   'vehicles (default /controller): its recorded parameters, NAME/debug and '
                   'the contract topics in its namespace (/car_b/controller: '
                   '/car_b/lateral_error, ...; --topic overrides one)')
    p.add_argument('--diagnostics', default=DIAGNOSTICS, metavar='TOPIC',
                   help="the controller's status topic in the bags (default /diagnostics; a "
                   'vehicle that remapped it: /car_b/diagnostics)')
    p.add_argument('--no-plots', action='store_true', help='write no PNG plots')
    args = p.parse_args(argv)
    results = analyze(args.bags, topic_overrides(args.topic), args.node,   # said first
                      args.diagnostics)
    previous = claim_output(args.out, 'analyze', args.overwrite,
                            output_names(results, not args.no_plots))
    written: list[Path] = []
    report = write_outputs(results, args.out, plots=not args.no_plots, written=written)
    record_output(args.out, 'analyze', written, previous)
    rows = [{k: row[k] for k in (*COLUMNS, 'notes')} for _, _, row in results]
    print(markdown_table(rows, COLUMNS, digits=3))
    print('\n'.join(notes_list(rows, ('bag',))))
    print(f'wrote {report}')
    return 0


def entry() -> int:
    """Entry point of ``analyze``."""
    return run_tool(main)


if __name__ == '__main__':
    import sys
    sys.exit(entry())
