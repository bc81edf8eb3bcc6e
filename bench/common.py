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

"""What every benchmark shares: results, statistics, process CPU and memory."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
import json
import os
from pathlib import Path
import statistics
import subprocess
import sys
from typing import Any, Optional, Sequence

ROOT = Path(__file__).resolve().parent.parent
RESULTS = Path(os.environ.get('BENCH_RESULTS', ROOT / 'bench' / 'results'))
TICKS = os.sysconf('SC_CLK_TCK')


@dataclass
class Result:
    """
    One benchmark's figure next to its baseline measured in the same run.

    :param name: the benchmark.
    :param figure: what is measured, in words.
    :param value: its median.
    :param unit: its unit.
    :param baseline: what it is compared with, in words.
    :param baseline_value: the baseline's median.
    :param ratio: value / baseline (or the ratio the goal is stated in).
    :param goal: the goal, in words.
    :param met: whether the goal is met.
    :param repetitions: how many times each was measured.
    :param spread: (min, max) of the figure over the repetitions.
    :param details: anything else measured (raw samples, counts, CPU).
    """

    name: str
    figure: str
    value: float
    unit: str
    baseline: str
    baseline_value: float
    ratio: float
    goal: str
    met: bool
    repetitions: int
    spread: tuple[float, float]
    details: dict[str, Any] = field(default_factory=dict)

    def save(self) -> Path:
        """Write ``bench/results/<name>.json``."""
        RESULTS.mkdir(parents=True, exist_ok=True)
        path = RESULTS / f'{self.name}.json'
        path.write_text(json.dumps(asdict(self), indent=2, default=float) + '\n')
        return path


def median(values: Sequence[float]) -> float:
    """Return the median."""
    return float(statistics.median(values))


def percentile(values: Sequence[float], q: float) -> float:
    """
    Return a percentile of the samples (nearest rank).

    :param values: the samples.
    :param q: 0..100.
    :return: the percentile (nan for no samples).
    """
    if not values:
        return float('nan')
    ordered = sorted(values)
    index = min(len(ordered) - 1, max(0, int(round(q / 100.0 * len(ordered) + 0.5)) - 1))
    return float(ordered[index])


def cpu_seconds(pid: int) -> float:
    """
    Return the user + system CPU time a process used so far.

    :param pid: the process.
    :return: seconds.
    """
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS


def rss_mib(pid: int) -> tuple[float, float]:
    """
    Return a process's resident memory now and its peak.

    :param pid: the process.
    :return: ``(VmRSS, VmHWM)`` [MiB].
    """
    values = {}
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        key, _, rest = line.partition(':')
        if key in ('VmRSS', 'VmHWM'):
            values[key] = int(rest.split()[0]) / 1024.0
    return values['VmRSS'], values['VmHWM']


def python_process(module: str, *args: str, stderr: Optional[int] = None,
                   stdout: Optional[int] = None) -> subprocess.Popen:
    """
    Start ``python -m module args`` from the project root.

    :param module: the module.
    :param args: its arguments.
    :param stderr: passed to Popen.
    :param stdout: passed to Popen.
    :return: the process.
    """
    env = dict(os.environ, PYTHONPATH=f'{ROOT}{os.pathsep}{os.environ.get("PYTHONPATH", "")}')
    return subprocess.Popen([sys.executable, '-m', module, *args], cwd=ROOT, env=env,
                            stderr=stderr, stdout=stdout, text=True)
