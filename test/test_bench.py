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

"""`make bench` stays runnable: a quick pass of the in-process benchmarks."""

import json
import os
from pathlib import Path
import subprocess
import sys

ROOT = Path(__file__).resolve().parent.parent


def test_quick_bench_writes_results_and_a_table(tmp_path):
    env = dict(os.environ, BENCH_RESULTS=str(tmp_path))
    out = subprocess.run([sys.executable, '-m', 'bench.run', '--quick', '--only', 'core',
                          'batch'], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    core = json.loads((tmp_path / '1_core_step.json').read_text())
    batch = json.loads((tmp_path / '4_batch.json').read_text())
    assert core['value'] > core['baseline_value'] > 0.0
    # the vectorized batch computes what the scalar loop computes
    assert batch['details']['max_abs_diff_vs_scalar_m'] < 1e-9
    table = (tmp_path / 'table.md').read_text()
    assert '| 1 |' in table and '| 4 |' in table
