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

"""The search of a speed schedule of the certificate's Q (dev-sc31) and its tool options."""

from __future__ import annotations

from dataclasses import replace
import json

from lookahead_control.core import lane_keeping_stability as stability
from lookahead_control.core.cli import run_tool
from lookahead_control.core.config import load_controller, load_lane_keeping, load_vehicle
from lookahead_control.tools.lane_keeping_tool import stability_main
import pytest

#: the rear tyres 30 % softer than the law's model: the shipped Q certify 2.3 m/s^2
SOFT_REAR = '/**:\n  ros__parameters:\n    vehicle:\n      c_r: 56000.0\n'


def _soft_rear():
    vehicle = load_vehicle(None)
    return replace(vehicle, c_r=0.7 * vehicle.c_r)


def test_the_search_lowers_the_bound_and_reports_what_its_schedule_gives():
    vehicle, controller = _soft_rear(), load_controller(None)
    settings = load_lane_keeping(None)
    found = stability.search_schedule(vehicle, controller, settings, evaluations=60,
                                      samples=11)
    # it starts from the best shipped Q on its grid and keeps the best point it meets
    shipped = stability.certificate(vehicle, controller, settings, samples=11)
    assert found.start == pytest.approx(shipped.between, rel=1e-9)
    assert found.found < found.start and found.evaluations == 60
    # the schedule it returns gives the bound it reports (scaled: the test does not see
    # the scale), its first Q's first entry 1
    again = stability.certificate(vehicle, controller, settings, samples=11,
                                  q_knots=found.knots)
    assert again.between == pytest.approx(found.found, rel=1e-9)
    assert [speed for speed, _ in found.knots] == [14.0, 24.0]
    assert found.knots[0][1][0][0] == pytest.approx(1.0)
    # one evaluation: the start itself
    start = stability.search_schedule(vehicle, controller, settings, evaluations=1,
                                      samples=11)
    assert start.found == start.start == found.start and start.evaluations == 1
    for kwargs, blamed in (({'evaluations': 0}, 'evaluations = 0 must be >= 1'),
                           ({'speeds': (24.0, 14.0)}, r'knot speeds \(24.0, 14.0\)')):
        with pytest.raises(ValueError, match=blamed):
            stability.search_schedule(vehicle, controller, settings, samples=11, **kwargs)


def test_the_search_on_the_load_transfer_uses_at_most_five_accelerations():
    # with the load transfer the search grid has min(load_points, 5) accelerations
    vehicle = replace(load_vehicle(None), cg_height=0.58)
    controller, settings = load_controller(None), load_lane_keeping(None)
    found = stability.search_schedule(vehicle, controller, settings, load_points=9,
                                      evaluations=1, samples=11)
    assert found.start == pytest.approx(stability.certificate(
        vehicle, controller, settings, samples=11, load_points=5).between, rel=1e-9)


def test_the_tool_writes_the_schedule_it_found_and_certifies_with_a_given_one(
        tmp_path, capsys):
    soft = tmp_path / 'soft.yaml'
    soft.write_text(SOFT_REAR)
    out = tmp_path / 'q.json'
    common = ['--vehicle', str(soft), '--samples', '28', '--delays', '0.02']
    run_tool(stability_main, common + ['--search-q', str(out), '--search-evaluations', '40'])
    said = capsys.readouterr().out
    data = json.loads(out.read_text())
    assert data['evaluations'] == 40 and data['search_bound'] < data['start_bound']
    assert ('searched a schedule of Q (40 bounds on 41 speeds): bound '
            f"{data['start_bound']:.4g} -> {data['search_bound']:.4g}; written to {out}"
            in said)
    assert f'with Q given ({out}: knots at 14, 24 m/s)' in said
    row = next(line for line in said.splitlines() if line.startswith('| ... bounded'))
    # the file given back: the same certificate
    run_tool(stability_main, common + ['--q-knots', str(out)])
    again = capsys.readouterr().out
    assert row in again.splitlines() and f'with Q given ({out}: knots at 14, 24' in again
    # and it is the file's schedule that is checked, not the shipped ones
    vehicle = _soft_rear()
    knots = tuple((s, tuple(map(tuple, q))) for s, q in data['knots'])
    cert = stability.certificate(vehicle, load_controller(None), load_lane_keeping(None),
                                 samples=28, q_knots=knots)
    assert f'| ... bounded between grid points | {cert.between:.4g} |' in row


@pytest.mark.parametrize('text,blamed', [
    (None, 'No such file'),
    ('{"knots": [[14, [[1, 0], [0, 1]]]]}', 'positive definite 5x5'),
    ('[1, 2]', 'not a schedule of Q as --search-q writes it'),
    ('{"knots": [["14", [[1, 0, 0, 0, 0]]]]}', 'must be finite numbers'),
    ('not json', 'Expecting value')])
def test_the_tool_refuses_a_bad_schedule_file_in_one_line(tmp_path, capsys, text, blamed):
    path = tmp_path / 'q.json'
    if text is not None:
        path.write_text(text)
    assert run_tool(stability_main, ['--samples', '2', '--q-knots', str(path)]) == 2
    err = capsys.readouterr().err
    assert f'--q-knots {path}' in err and blamed in err, err
    assert 'Traceback' not in err


def test_the_tool_takes_one_source_of_q_and_a_positive_budget(tmp_path, capsys):
    for args, blamed in ((['--search-q', 'a.json', '--q-knots', 'b.json'], 'not allowed with'),
                         (['--search-q', str(tmp_path / 'a.json'), '--search-evaluations',
                           '0'], '--search-evaluations 0: must be >= 1')):
        with pytest.raises(SystemExit) as exit_:
            stability_main(['--samples', '2', *args])
        assert exit_.value.code == 2
        assert blamed in capsys.readouterr().err
    assert not (tmp_path / 'a.json').exists()


def test_the_search_without_scipy_is_one_line(tmp_path, capsys, monkeypatch):
    # scipy is not a dependency of the nodes: a real install may lack it
    import sys
    monkeypatch.setitem(sys.modules, 'scipy.optimize', None)
    out = tmp_path / 'q.json'
    assert run_tool(stability_main, ['--samples', '2', '--search-q', str(out)]) == 2
    err = capsys.readouterr().err
    assert '--search-q needs scipy (pip install scipy, or apt python3-scipy)' in err
    assert not out.exists()
