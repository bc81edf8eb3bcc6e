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

"""Tables and JSON the tools write are valid markdown and strict JSON (issue 12 item 12)."""

import json
import math

from lookahead_control.core.cli import markdown_table, write_json
import numpy as np


def _cells(line):
    """Split a markdown table row at unescaped pipes."""
    out, cell, escaped = [], '', False
    for ch in line.strip()[1:-1]:
        if ch == '|' and not escaped:
            out.append(cell)
            cell = ''
        else:
            cell += ch
        escaped = ch == '\\'
    return out + [cell]


def test_a_pipe_inside_a_cell_does_not_split_it():
    table = markdown_table([{'quantity': 'max ||dP/dt||_2', 'value': 0.5}])
    for line in table.splitlines():
        assert len(_cells(line)) == 2, line


def test_certificate_prints_a_valid_markdown_table(capsys):
    from lookahead_control.tools.analysis_tools import certificate_main
    certificate_main(['--samples', '11'])
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith('|')]
    assert len(rows) == 7
    assert all(len(_cells(line)) == 4 for line in rows)


def test_json_is_strict_for_nan_infinity_and_numpy(tmp_path):
    path = tmp_path / 'x.json'
    write_json(path, {'a': math.nan, 'b': [math.inf, np.float32('nan'), np.float64(1.5)],
                      'c': np.array([1.0, np.nan]), 'd': np.int64(3), 'e': 1 + 2j})

    def refuse(name):
        raise ValueError(f'not JSON: {name}')

    data = json.loads(path.read_text(), parse_constant=refuse)
    assert data == {'a': None, 'b': [None, None, 1.5], 'c': [1.0, None], 'd': 3,
                    'e': [1.0, 2.0]}
