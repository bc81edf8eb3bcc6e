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

"""docs/model.md states numbers: each is recomputed from the code (issue 12 item 12)."""

from dataclasses import fields
import math
from pathlib import Path
import re

from lookahead_control.analysis.metrics import QUANTITIES
from lookahead_control.core.control_law import arc_offset
from lookahead_control.core.params import VehicleParams
from lookahead_control.core.schedule import exact_look_ahead, paper_look_ahead
from lookahead_control.core.zero_dynamics import steady_relative_yaw, zero_dynamics
import pytest

DOC = Path(__file__).resolve().parents[1] / 'docs' / 'model.md'
VEHICLE = VehicleParams()


def _tables(text):
    """Return every markdown table as (header cells, rows of cells)."""
    tables, current = [], []
    for line in text.splitlines() + ['']:
        if line.startswith('|'):
            current.append([c.strip() for c in line.strip().strip('|').split('|')])
        elif current:
            tables.append((current[0], current[2:]))
            current = []
    return tables


def _table(header_start, last=None):
    found = [t for t in _tables(DOC.read_text(encoding='utf-8'))
             if t[0][0].startswith(header_start) and last in (None, t[0][-1])]
    assert len(found) == 1, header_start
    return found[0]


def _same(stated, computed):
    """Return whether a stated number equals the computed one to its printed digits."""
    digits = len(re.sub(r'^-?0?\.?0*', '', stated.replace('.', '', 1).lstrip('-')))
    return float(f'{computed:.{max(digits, 1)}g}') == float(stated)


def test_table_1_values_are_the_vehicle_defaults():
    _, rows = _table('symbol', 'Table 1')
    by_code = {row[1].strip('`'): float(row[-1]) for row in rows}
    assert by_code == {f.name: getattr(VEHICLE, f.name) for f in fields(VEHICLE)}


def test_law_input_table_names_every_lateral_state_field():
    from lookahead_control.core.control_law import LateralState
    _, rows = _table('symbol', 'meaning')
    assert {row[1].strip('`') for row in rows} >= {f'LateralState.{name}'
                                                   for name in LateralState._fields}


@pytest.mark.parametrize('row', _table('v_x [m/s]')[1], ids=lambda r: r[0])
def test_schedule_table_matches_the_code(row):
    v = float(row[0])
    d_paper = float(paper_look_ahead(v, 0.0, VEHICLE)[0])
    d_exact = float(exact_look_ahead(v, 0.0, VEHICLE)[0])
    computed = (d_paper, d_exact, zero_dynamics(VEHICLE, v, d_paper).damping_ratio,
                zero_dynamics(VEHICLE, v, VEHICLE.d_s).damping_ratio,
                steady_relative_yaw(VEHICLE, v, -1.0 / 400.0))
    for stated, value in zip(row[1:], computed):
        assert _same(stated, value), (row, computed)


def test_other_numbers_match_the_code():
    _, rows = _table('quantity')
    d_37 = float(paper_look_ahead(37.0, 0.0, VEHICLE)[0])
    computed = [VEHICLE.eta, math.sqrt(VEHICLE.l2 / VEHICLE.eta),
                -d_37 * steady_relative_yaw(VEHICLE, 37.0, -1.0 / 400.0),
                arc_offset(-1.0 / 400.0, d_37, 0.0, exact=True)]
    assert len(rows) == len(computed)
    for row, value in zip(rows, computed):
        assert _same(row[1], value), (row, value)


def test_eq_26_zero_dynamics_are_complex_pairs_and_only_eq_24_gives_one():
    # the claim the docs used to make: eq. 26 puts the roots on the real axis
    for v in (15.0, 20.0, 30.0, 37.0):
        paper = zero_dynamics(VEHICLE, v, float(paper_look_ahead(v, 0.0, VEHICLE)[0]))
        exact = zero_dynamics(VEHICLE, v, float(exact_look_ahead(v, 0.0, VEHICLE)[0]))
        assert paper.roots[0].imag != 0.0 and 0.97 < paper.damping_ratio < 1.0
        assert exact.damping_ratio == pytest.approx(1.0, abs=1e-9)


def test_the_quantities_table_is_the_code_vocabulary():
    _, rows = _table('name in tables')
    stated = {row[0].strip('`'): (row[1], row[2]) for row in rows}
    assert stated == {name: (q.symbol, q.unit) for name, q in QUANTITIES.items()}


def test_the_doc_points_nowhere_outside_the_repository():
    text = DOC.read_text(encoding='utf-8')
    assert '../' not in text and 'shared' not in text


def test_paper_reproduction_tables_are_what_paper_scenario_computes():
    # the figures of docs/paper_reproduction.md, recomputed (linear and nonlinear plant)
    from lookahead_control.core.params import ControllerParams
    from lookahead_control.tools.paper_scenario import metrics_rows, reproduce
    from sim_plant.vehicle_model import PlantParams
    doc = DOC.parent / 'paper_reproduction.md'
    tables = [t for t in _tables(doc.read_text(encoding='utf-8')) if t[0][0] == 'd_v']
    assert len(tables) == 2
    columns = {'d_v [m]': 'd_v_final_m', 'peak y_cg [m]': 'peak_cg_error_m',
               'peak y_s [m]': 'peak_look_down_error_m',
               'peak y_a [m]': 'peak_look_ahead_lane_error_m',
               'peak e [m]': 'peak_regulated_error_m', 'yaw overshoot': 'yaw_overshoot',
               'yaw zeta': 'yaw_damping_ratio', 'peak delta_cmd [rad]': 'peak_steering_cmd_rad',
               'peak delta_cmd rate [rad/s]': 'peak_steering_cmd_rate_rad_per_s',
               'peak delta [rad]': 'peak_steering_rad',
               'peak delta rate [rad/s]': 'peak_steering_rate_rad_per_s'}
    for (header, rows), plant in zip(tables, ('linear', 'nonlinear')):
        computed = {(r['controller'], r['speed_mps']): r for r in metrics_rows(
            reproduce(VEHICLE, ControllerParams(), PlantParams(model=plant)))}
        assert len(rows) == len(computed) == 8
        for row in rows:
            key = ('fixed' if row[0] == 'fixed' else 'paper', float(row[1]))
            for name, stated in zip(header[2:], row[2:]):
                value = computed[key][columns[name]]
                if stated == '-':
                    assert math.isnan(value), (plant, row, name)
                else:
                    assert _same(stated, value), (plant, row, name, value)
