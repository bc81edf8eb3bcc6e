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
    ('not json', 'Expecting value'),
    # dev-probe68: entries as text or true were taken as numbers; 1e308 failed inside
    # numpy without naming the file
    ('{"knots": [[14, [["1", 0, 0, 0, 0], [0, 1, 0, 0, 0], [0, 0, 1, 0, 0], '
     '[0, 0, 0, 1, 0], [0, 0, 0, 0, 1]]]]}', "Q's entries must be numbers"),
    ('{"knots": [[14, [[1e308, 0, 0, 0, 0], [0, 1, 0, 0, 0], [0, 0, 1, 0, 0], '
     '[0, 0, 0, 1, 0], [0, 0, 0, 0, 1]]]]}', 'condition number of 1e+308: above 1e12'),
    ('{"knots": [[14, [[1, 0, 0, 0, 0], [0, 1, 0, 0, 0], [0, 0, 1, 0, 0], '
     '[0, 0, 0, 1, 0], [0, 0, 0, 0, 1]]], [24, [[1, 2, 0, 0, 0], [2, 1, 0, 0, 0], '
     '[0, 0, 1, 0, 0], [0, 0, 0, 1, 0], [0, 0, 0, 0, 1]]]]}', 'knot 1 (24 m/s)')])
def test_the_tool_refuses_a_bad_schedule_file_in_one_line(tmp_path, capsys, text, blamed):
    path = tmp_path / 'q.json'
    if text is not None:
        path.write_text(text)
    assert run_tool(stability_main, ['--samples', '2', '--q-knots', str(path)]) == 2
    err = capsys.readouterr().err
    assert f'--q-knots {path}' in err and blamed in err, err
    assert 'Traceback' not in err


def test_the_tool_refuses_before_the_search_what_would_fail_after_it(tmp_path, capsys):
    # dev-probe68: a folder or an unwritable path as --search-q failed only after the
    # search; --json naming the schedule file overwrote it (exit 0); a budget without a
    # search was ignored
    (tmp_path / 'a_folder').mkdir()
    (tmp_path / 'a_file').write_text('x')
    given = tmp_path / 'given.json'
    given.write_text('{}')
    for args, blamed in (
            (['--search-q', 'a.json', '--q-knots', 'b.json'], 'not allowed with'),
            (['--search-q', str(tmp_path / 'a.json'), '--search-evaluations', '0'],
             '--search-evaluations: 0 is out of range; allowed: [1, 1e+06]'),
            (['--search-evaluations', '5'], '--search-evaluations: only with --search-q'),
            (['--search-q', str(tmp_path / 'a_folder')], 'a_folder: is a folder'),
            (['--search-q', str(tmp_path / 'a_file' / 'q.json')],
             f'{tmp_path / "a_file"} is not a folder this user may write in'),
            (['--search-q', str(given), '--json', str(given)],
             f'--json {given}: the same file as --search-q'),
            (['--q-knots', str(given), '--json', str(tmp_path / '.' / 'given.json')],
             'the same file as --q-knots')):
        with pytest.raises(SystemExit) as exit_:
            stability_main(['--samples', '2', *args])
        assert exit_.value.code == 2
        assert blamed in capsys.readouterr().err, args
    assert not (tmp_path / 'a.json').exists() and given.read_text() == '{}'


def test_the_search_places_its_knots_inside_the_envelope_and_refuses_an_unstable_loop():
    # dev-probe68: with --v-min 25 the knots stayed at 14 and 24 m/s: Q constant over the
    # whole envelope; now the envelope's thirds
    vehicle, controller = _soft_rear(), load_controller(None)
    settings = load_lane_keeping(None)
    found = stability.search_schedule(vehicle, controller, settings, v_min=25.0,
                                      evaluations=1, samples=5)
    assert [speed for speed, _ in found.knots] == [29.0, 33.0]
    with pytest.raises(ValueError, match='not stable at every frozen speed'):
        stability.search_schedule(vehicle, controller, replace(settings, integral_gain=0.0),
                                  evaluations=5, samples=5)


def test_the_json_report_says_which_q_gave_the_verdict(tmp_path, capsys):
    # dev-probe68: with a given schedule the report said only 'given' and the knots'
    # speeds; now the Q, their source and the search's settings
    report = tmp_path / 'r.json'
    run_tool(stability_main, ['--samples', '2', '--delays', '0.02', '--json', str(report)])
    q = json.loads(report.read_text())['q']
    assert q['name'] == 'loaded' and q['source'] == 'shipped'
    assert q['knots'][0][0] == 14.0 and q['knots'][1][1] == [
        list(row) for row in stability.CERTIFICATE_Q_HIGH]
    out = tmp_path / 'q.json'
    run_tool(stability_main, ['--samples', '2', '--delays', '0.02', '--json', str(report),
                              '--search-q', str(out), '--search-evaluations', '3'])
    q = json.loads(report.read_text())['q']
    written = json.loads(out.read_text())
    assert q['source'] == str(out) and q['knots'] == written['knots']
    assert written['searched_for'] == {'vehicle': None, 'controller': None, 'v_min': 10.0,
                                       'v_max': 37.0, 'a_max': 3.5, 'a_error': 0.0,
                                       'samples': 41, 'load_points': 0}
    assert not out.with_name('q.json.partial').exists()
    capsys.readouterr()


def test_the_search_without_scipy_is_one_line(tmp_path, capsys, monkeypatch):
    # scipy is not a dependency of the nodes: a real install may lack it
    import sys
    monkeypatch.setitem(sys.modules, 'scipy.optimize', None)
    out = tmp_path / 'q.json'
    assert run_tool(stability_main, ['--samples', '2', '--search-q', str(out)]) == 2
    err = capsys.readouterr().err
    assert '--search-q needs scipy (pip install scipy, or apt python3-scipy)' in err
    assert not out.exists()


def test_a_knot_next_to_a_kink_is_moved_onto_it():
    # dev-probe68: a third knot on the line between the loaded schedule's two Q (the same
    # Q(v)) 2e-13 m/s from the w_n kink at 30 * 5 / 7 m/s made a one-sided step of 1e-13
    # and a bound of 1e10; now it is moved onto the kink (any Q(v) > 0 is a valid test)
    vehicle, controller = load_vehicle(None), load_controller(None)
    settings = load_lane_keeping(None)
    (low, q_low), (high, q_high) = stability.CERTIFICATE_SCHEDULES['loaded']
    two = stability.certificate(vehicle, controller, settings, samples=55,
                                q_knots=((low, q_low), (high, q_high)))
    kink = 30.0 * 5.0 / 7.0
    for speed in (kink + 2e-13, kink + 1e-9, kink - 5e-7):
        share = (speed - low) / (high - low)
        middle = tuple(tuple((1.0 - share) * a + share * b for a, b in zip(r_low, r_high))
                       for r_low, r_high in zip(q_low, q_high))
        three = stability.certificate(vehicle, controller, settings, samples=55,
                                      q_knots=((low, q_low), (speed, middle),
                                               (high, q_high)))
        assert three.between == pytest.approx(two.between, rel=1e-6), speed
        assert three.knots == (low, pytest.approx(kink, abs=1e-12), high)


def test_an_interrupted_search_keeps_its_best_schedule(tmp_path, capsys, monkeypatch):
    # before: a Ctrl-C (or SIGTERM) in --search-q's minutes of Nelder-Mead lost every bound
    # computed; now the best schedule so far is written, and the tool still stops (130)
    import scipy.optimize
    from lookahead_control.core.interrupts import Terminated
    real = scipy.optimize.minimize

    def stopped_after_12(fun, x0, **kwargs):
        calls = {'n': 0}

        def counted(x):
            calls['n'] += 1
            if calls['n'] > 12:
                raise KeyboardInterrupt
            return fun(x)
        return real(counted, x0, **kwargs)

    monkeypatch.setattr(scipy.optimize, 'minimize', stopped_after_12)
    vehicle, controller = _soft_rear(), load_controller(None)
    settings = load_lane_keeping(None)
    found = stability.search_schedule(vehicle, controller, settings, evaluations=60,
                                      samples=11)
    assert isinstance(found.interrupted, KeyboardInterrupt)
    assert found.evaluations == 13 and found.found < found.start
    again = stability.certificate(vehicle, controller, settings, samples=11,
                                  q_knots=found.knots)
    assert again.between == pytest.approx(found.found, rel=1e-9)
    soft = tmp_path / 'soft.yaml'
    soft.write_text(SOFT_REAR)
    out = tmp_path / 'q.json'
    argv = ['--vehicle', str(soft), '--samples', '11', '--delays', '0.02', '--search-q',
            str(out), '--search-evaluations', '60']
    assert run_tool(stability_main, argv) == 130
    said = capsys.readouterr()
    data = json.loads(out.read_text())
    assert data['interrupted'] is True and data['evaluations'] == 13
    assert ('search interrupted after 13 bounds on 41 speeds: the best schedule so far '
            f"(bound {data['start_bound']:.4g} -> {data['search_bound']:.4g}) written to "
            f'{out}') in said.out and 'interrupted' in said.err
    assert not out.with_name('q.json.partial').exists()

    def terminated(fun, x0, **kwargs):
        fun(x0)
        raise Terminated
    monkeypatch.setattr(scipy.optimize, 'minimize', terminated)
    assert run_tool(stability_main, argv) == 143
    assert json.loads(out.read_text())['evaluations'] == 2
