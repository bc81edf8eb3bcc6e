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

"""The analysis executables: tables, plots, files, and one-line errors."""

import json
from pathlib import Path
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _tool(module_func: str, *args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    module, func = module_func.split(':')
    code = f'import sys\nfrom {module} import {func}\nsys.exit({func}())'
    return subprocess.run([sys.executable, '-c', code, *args], cwd=cwd,
                          capture_output=True, text=True, timeout=300,
                          env={'PYTHONPATH': str(ROOT), 'PATH': '/usr/bin:/bin',
                               'MPLBACKEND': 'Agg'})


SCHEDULE = 'lookahead_control.tools.analysis_tools:schedule'
ZERO = 'lookahead_control.tools.analysis_tools:zero_dynamics_tool'
CERT = 'lookahead_control.tools.analysis_tools:certificate_tool'
PAPER = 'lookahead_control.tools.paper_scenario:entry'


def test_schedule_tool_table_and_plot(tmp_path):
    result = _tool(SCHEDULE, '--v-min', '10', '--v-max', '30', '--step', '10',
                   '--plot', str(tmp_path / 's.png'), '--json', str(tmp_path / 's.json'))
    assert result.returncode == 0, result.stderr
    assert '| 20 | 1.96 | 10.61 |' in result.stdout
    assert (tmp_path / 's.png').read_bytes()[:4] == b'\x89PNG'
    rows = json.loads((tmp_path / 's.json').read_text())
    assert [r['speed_mps'] for r in rows] == [10.0, 20.0, 30.0]


def test_zero_dynamics_tool_plot(tmp_path):
    result = _tool(ZERO, '--plot', str(tmp_path / 'roots.png'))
    assert result.returncode == 0, result.stderr
    assert (tmp_path / 'roots.png').stat().st_size > 10000


def test_certificate_tool_passes_and_fails():
    ok = _tool(CERT)
    assert ok.returncode == 0, ok.stderr
    assert 'certificate HOLDS' in ok.stdout and '0.477' in ok.stdout
    bad = _tool(CERT, '--a-max', '12', '--samples', '101')
    assert bad.returncode == 1
    assert 'DOES NOT HOLD' in bad.stdout


def test_paper_scenario_writes_report(tmp_path):
    result = _tool(PAPER, '--speeds', '20', '37', '--duration', '6', '--out', str(tmp_path))
    assert result.returncode == 0, result.stderr
    rows = json.loads((tmp_path / 'metrics.json').read_text())
    assert [(r['controller'], r['speed_mps']) for r in rows] == [
        ('fixed', 20.0), ('fixed', 37.0), ('paper', 20.0), ('paper', 37.0)]
    report = (tmp_path / 'report.md').read_text()
    assert 'fig_fixed.png' in report and 'fig_paper.png' in report
    assert (tmp_path / 'fig_paper.png').exists()


@pytest.mark.parametrize('tool', [SCHEDULE, ZERO, CERT, PAPER])
def test_bad_vehicle_file_is_one_line_and_nonzero(tool, tmp_path):
    bad = tmp_path / 'vehicle.yaml'
    bad.write_text('/**:\n  ros__parameters:\n    vehicle: {mass: -5.0}\n')
    result = _tool(tool, '--vehicle', str(bad))
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert 'vehicle.yaml' in lines[0] and 'vehicle.mass = -5.0' in lines[0]
    missing = _tool(tool, '--vehicle', str(tmp_path / 'nope.yaml'))
    assert missing.returncode == 2 and 'nope.yaml: cannot read' in missing.stderr
    assert 'Traceback' not in missing.stderr
