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
``make bench``: every benchmark, each next to a baseline measured in the same run.

Writes ``bench/results/<name>.json`` and ``bench/results/table.md`` (every result on
file) and prints the table. ``--only NAME ...`` runs some; ``--quick`` shortens every
one (for a smoke run, not for figures); ``BENCH_RESULTS`` sets another results folder.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from typing import Callable, Union

from bench import bench_analyze, bench_core, bench_dds, bench_sweep
from bench.common import Result, RESULTS

BENCHMARKS: dict[str, Callable[[bool], Union[Result, list[Result]]]] = {
    'core': bench_core.core_step, 'latency': bench_dds.latency,
    'lockstep': bench_dds.lockstep, 'batch': bench_core.batch,
    'recorder': bench_dds.recorder, 'analyze': bench_analyze.analyze,
    'memory': bench_dds.memory, 'sweep': bench_sweep.sweep_workers,
}


def table(results: list[Result]) -> str:
    """
    Return the results as a markdown table.

    :param results: the results.
    :return: the table.
    """
    rows = ['| # | figure | value | baseline | baseline value | ratio | goal | met |',
            '|---|---|---|---|---|---|---|---|']
    for r in results:
        rows.append(f'| {r.name.split("_")[0]} | {r.figure} | {r.value:.4g} {r.unit} | '
                    f'{r.baseline} | {r.baseline_value:.4g} | {r.ratio:.3g} | {r.goal} | '
                    f'{"yes" if r.met else "**no**"} |')
    return '\n'.join(rows)


def main() -> int:
    """Run the selected benchmarks; print and save the table."""
    p = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    p.add_argument('--only', nargs='+', choices=sorted(BENCHMARKS), default=None)
    p.add_argument('--quick', action='store_true', help='short runs (smoke test)')
    args = p.parse_args()
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    results: list[Result] = []
    for name in args.only or list(BENCHMARKS):
        start = time.monotonic()
        print(f'bench: {name} ...', file=sys.stderr, flush=True)
        out = BENCHMARKS[name](args.quick)
        for result in out if isinstance(out, list) else [out]:
            result.details['bench_wall_s'] = time.monotonic() - start
            result.save()
            results.append(result)
            print(f'bench: {result.name}: {result.value:.4g} {result.unit} vs '
                  f'{result.baseline_value:.4g} (ratio {result.ratio:.3g}); goal '
                  f'{result.goal}: {"met" if result.met else "MISSED"}', file=sys.stderr,
                  flush=True)
    # the table holds every result on file, so `--only` refreshes some of them
    on_file = [Result(**json.loads(path.read_text()))
               for path in sorted(RESULTS.glob('[0-9]_*.json'))]
    text = (f'Machine: {platform.node()}, {os.cpu_count()} cores, Python '
            f'{platform.python_version()}{", quick" if args.quick else ""}\n\n'
            + table(on_file) + '\n')
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / 'table.md').write_text(text)
    print(text)
    return 0


if __name__ == '__main__':
    sys.exit(main())
