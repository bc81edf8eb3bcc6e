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

"""The sweep tool's throughput: 1 and 2 local Dask workers against one process."""

from __future__ import annotations

from pathlib import Path
import tempfile
import time

from bench.common import Result
from lookahead_control.core.params import ControllerParams, VehicleParams
from lookahead_control.tools.sweep import sweep, SweepSpec


def _runs_per_second(spec: SweepSpec, workers: int) -> tuple[float, float, int]:
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        table, _ = sweep(spec, Path(folder) / 'sweep', vehicle=VehicleParams(),
                         controller=ControllerParams(), workers=workers, plots=False)
        wall = time.perf_counter() - start
    return table.num_rows / wall, wall, table.num_rows


def sweep_workers(quick: bool = False) -> list[Result]:
    """
    Time one Monte Carlo sweep three ways: in this process, on 1 and on 2 Dask workers.

    The sweep: 3 scenarios x 2 laws x ``runs`` conditions of 5 s (nonlinear plant,
    mismatch, delay, noise), tasks of 16 runs. The Dask timings include starting the
    local cluster (as a user's sweep does).

    :param quick: 4 conditions per scenario of 2 s.
    :return: the two results (1 and 2 workers, each against the single process).
    """
    runs, duration = (4, 2.0) if quick else (32, 5.0)
    spec = SweepSpec(runs=runs, duration=duration, batch=16 if not quick else 4,
                     scenarios=('s1_paper_step', 's2_curve_entry', 's3_s_bend'))
    single, single_wall, count = _runs_per_second(spec, 0)
    results = []
    for workers in (1, 2):
        rate, wall, _ = _runs_per_second(spec, workers)
        goal = ('>= 0.8x the single process (cluster start included)' if workers == 1
                else '>= 1.5x the single process on 2 cores')
        met = rate >= (0.8 if workers == 1 else 1.5) * single
        results.append(Result(
            f'9_sweep_{workers}_worker{"s" if workers > 1 else ""}',
            f'sweep runs per second, {workers} local Dask worker{"s" * (workers > 1)}', rate,
            'runs/s', 'the same sweep in one process (no Dask)', single, rate / single,
            goal, met, 1, (rate, rate),
            {'runs': count, 'wall_s': wall, 'single_wall_s': single_wall,
             'tasks_of': spec.batch, 'run_duration_s': duration}))
    return results
