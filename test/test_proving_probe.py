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

"""Findings of the proving-ground probe: each test failed on the code it was written against."""

from __future__ import annotations

from pathlib import Path

from lookahead_control.core.cli import run_tool
from lookahead_control.core.params import VehicleParams
from lookahead_control.tools import compare, sweep
import pytest


def test_league_row_does_not_depend_on_the_other_speeds() -> None:
    """A noisy run at 37 m/s gives the same row whether 30 m/s runs beside it or not."""
    plants = [case for case in compare.PLANTS if case.name == compare.GOAL_PLANT]
    rows = {}
    for speeds in ((37.0,), (30.0, 37.0)):
        league = compare.league(['stanley'], ['s0_straight'], speeds, plants,
                                VehicleParams(), duration=1.0)
        rows[speeds] = [row for row in league if row['speed_mps'] == 37.0][0]
    alone, beside = rows[(37.0,)], rows[(30.0, 37.0)]
    for name in ('peak_cg_error_m', 'peak_command_rad', 'steering_noise_rms_rad'):
        assert alone[name] == beside[name], name


def test_default_speeds_keep_their_seeds() -> None:
    """The full league's seeds are unchanged (1, 2, 3, 4 at 10, 20, 30, 37 m/s)."""
    assert [compare.speed_seed(v) for v in compare.SPEEDS] == [1, 2, 3, 4]
    assert compare.speed_seed(25.0) not in (1, 2, 3, 4)


@pytest.mark.parametrize('args, expected', [
    (['--max-error', '-1'], '--max-error -1.0: a peak CG error in (0, 100] m'),
    (['--max-error', 'nan'], '--max-error nan: a peak CG error in (0, 100] m'),
    (['--dt', '0'], '--dt 0.0: a plant step in (0, 0.01] s'),
    (['--duration', '-5'], "--duration -5.0: 0 (each scenario's own) or a time"),
    # dev-probe96: 0.001 s ran (every metric NaN, no run failed); 1e9 runs were told 'a
    # whole number >= 1 is required'; a step the control period is no multiple of
    (['--duration', '0.001'], "--duration 0.001: 0 (each scenario's own) or a time in "
     '[1, 1e5] s (what the metrics need)'),
    (['--runs', '1000000000'], '--runs 1000000000 is out of range; allowed: a whole number '
     'in [1, 1000000]'),
    (['--dt', '0.003'], '--dt 0.003: control_period = 0.01 s is not a whole multiple of '
     'dt = 0.003 s'),
])
def test_sweep_refuses_bad_numbers(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                   args: list[str], expected: str) -> None:
    """A negative or NaN failure threshold, a zero step, a negative duration: one line."""
    out = tmp_path / 'sweep'
    code = run_tool(sweep.main, ['--out', str(out), '--runs', '1', '--speeds', '20',
                                 '--scenarios', 's0_straight', '--laws', 'paper_fixed',
                                 '--workers', '0', '--no-plots', '--no-progress', *args])
    err = capsys.readouterr().err
    assert code == 2 and expected in err and err.count('\n') == 1
    assert not out.exists()
