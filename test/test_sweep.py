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

"""The sweep tool: results, resume, a killed Dask worker, bad options (small batches)."""

from dataclasses import asdict, replace
import json
import os
from pathlib import Path
import re

from lookahead_control.core.cli import run_tool, ToolError
from lookahead_control.core.lane_keeping import LaneKeepingParams
from lookahead_control.core.params import ControllerParams, VehicleParams
from lookahead_control.tools import sweep as sw
import numpy as np
import pyarrow.parquet as pq
import pytest
from sim_plant.closed_loop_sim import run
from sim_plant.scenario import load_scenario
from sim_plant.sensors import NoiseParams
from sim_plant.vehicle_model import PlantParams

SPEC = sw.SweepSpec(runs=3, scenarios=('s1_paper_step',), speeds=(25.0, 37.0), batch=2,
                    duration=1.2, dt=0.002)
VEHICLE = VehicleParams()
CONTROLLER = ControllerParams()


def _same(a, b):
    """Return whether two result tables hold the same values (NaN equal to NaN)."""
    da, db = a.to_pydict(), b.to_pydict()
    return list(da) == list(db) and all(
        np.array_equal(np.asarray(da[k]), np.asarray(db[k]),
                       equal_nan=np.asarray(da[k]).dtype.kind == 'f') for k in da)


def _sweep(out, spec=SPEC, **kwargs):
    return sw.sweep(spec, out, vehicle=VEHICLE, controller=CONTROLLER, plots=False,
                    **{'workers': 0, **kwargs})


@pytest.fixture(scope='module')
def reference(tmp_path_factory):
    """Return the folder and the table of one undisturbed sweep in this process."""
    folder = tmp_path_factory.mktemp('sweep') / 'a'
    table, count = _sweep(folder)
    assert count == 4
    return folder, table


def test_rows_hold_every_parameter_and_metric_and_equal_single_runs(reference):
    folder, table = reference
    assert table.num_rows == 6          # 2 laws x 3 conditions
    for name in sw.PARAMETER_COLUMNS + ('peak_cg_error_m', 'yaw_overshoot',
                                        'peak_steering_rad', 'rms_steering_noise_rad',
                                        'failed'):
        assert name in table.column_names, name
    row = {k: v[0] for k, v in table.to_pydict().items()}
    assert row['law'] == 'paper_eq26' and row['run_id'] == 0
    scenario = replace(load_scenario(sw.scenario_path('s1_paper_step')), duration=1.2)
    body = VehicleParams(mass=VEHICLE.mass * (1 + row['mass']),
                         yaw_inertia=VEHICLE.yaw_inertia * (1 + row['mass']),
                         c_f=VEHICLE.c_f * (1 + row['cornering']),
                         c_r=VEHICLE.c_r * (1 + row['cornering']))
    single = run(scenario, VEHICLE, CONTROLLER, PlantParams(model='nonlinear',
                                                            friction=row['friction']),
                 dt=0.002, initial_speed=row['speed'], plant_vehicle=body,
                 delay=row['delay'], noise=NoiseParams(), seed=row['seed'])
    peak = np.max(np.abs(single['y_cg']))
    assert row['peak_cg_error_m'] == pytest.approx(peak, rel=1e-9)
    assert 0.0 <= row['delay'] <= 0.05 and round(row['delay'] / 0.002, 9) % 1 == 0
    # the same conditions for every law (common random numbers)
    data = table.to_pydict()
    for name in ('speed', 'cornering', 'mass', 'friction', 'delay', 'seed'):
        assert data[name][:3] == data[name][3:]
    text = (folder / 'summary.md').read_text()
    assert '| paper_eq26 | all | 3 |' in text and 'paper_fixed' in text


def test_grid_enumerates_every_combination():
    spec = replace(SPEC, mode='grid', levels=2, speeds=(20.0,))
    conds = sw.conditions(spec)
    assert len(conds) == 2 ** 4
    assert {c['friction'] for c in conds} == {0.5, 1.0}
    assert {c['delay'] for c in conds} == {0.0, 0.05}


def test_resume_runs_only_what_is_missing_and_gives_the_same_table(tmp_path, reference):
    partial, count = _sweep(tmp_path / 'r', max_tasks=1)
    assert partial is None and count == 1
    parts = sorted((tmp_path / 'r' / 'parts').glob('*.parquet'))
    assert len(parts) == 1
    stamp = parts[0].stat().st_mtime_ns
    (tmp_path / 'r' / 'parts' / '.half-written.parquet.1.tmp').write_bytes(b'PAR1 junk')
    table, count = _sweep(tmp_path / 'r')
    assert count == 3 and parts[0].stat().st_mtime_ns == stamp     # not redone
    assert not list((tmp_path / 'r' / 'parts').glob('.*.tmp'))
    assert _same(table, reference[1])
    with pytest.raises(ToolError, match='options differ: runs'):
        _sweep(tmp_path / 'r', replace(SPEC, runs=4))


def crash_once(task, data, vehicle, controller, lane_keeping=None, safety=None):
    """Kill the worker process the first time the first task runs."""
    marker = Path(os.environ['SWEEP_TEST_MARKER'])
    if task['task'].endswith('-00000') and task['law'] == 'paper_eq26' and not marker.exists():
        marker.write_text('crashed')
        os._exit(1)
    return sw.run_task(task, data, vehicle, controller, lane_keeping, safety)


def test_a_killed_dask_worker_loses_no_result(tmp_path, monkeypatch, reference):
    marker = tmp_path / 'marker'
    monkeypatch.setenv('SWEEP_TEST_MARKER', str(marker))
    table, count = _sweep(tmp_path / 'd', workers=2, runner=crash_once)
    assert marker.exists()                      # a worker did die mid-task
    assert _same(table, reference[1])
    assert _same(pq.read_table(tmp_path / 'd' / 'results.parquet'), reference[1])


@pytest.mark.parametrize('args, expected', [
    (['--laws', 'paper,nope'], 'known laws are'),
    (['--delay', '0.05:0.0'], 'LOW <= HIGH'),
    (['--friction', 'a:b'], 'expected LOW:HIGH'),
    (['--scenarios', 's9_none'], "no scenario 's9_none'"),
    (['--speeds', '20,x'], 'expected numbers'),
    (['--cornering=-0.95:0.3'], 'out of range'),
])
def test_bad_options_give_one_line(tmp_path, capsys, args, expected):
    code = run_tool(sw.main, ['--out', str(tmp_path / 'x'), '--workers', '0'] + args)
    err = capsys.readouterr().err
    assert code == 2 and expected in err and err.count('\n') == 1


def test_output_folder_that_is_not_a_sweep_is_refused(tmp_path):
    (tmp_path / 'o').mkdir()
    (tmp_path / 'o' / 'notes.txt').write_text('mine')
    with pytest.raises(ToolError, match='not a sweep folder'):
        _sweep(tmp_path / 'o')


def fail_third(task, data, vehicle, controller, lane_keeping=None, safety=None):
    """Fail on the third task (a bug in a law, say)."""
    if task['task'] == 'paper_fixed-s1_paper_step-00000':
        raise ValueError('law exploded')
    return sw.run_task(task, data, vehicle, controller, lane_keeping, safety)


def test_a_failing_task_stops_the_sweep_and_keeps_finished_parts(tmp_path):
    with pytest.raises(ValueError, match='law exploded'):
        _sweep(tmp_path / 'e', runner=fail_third)
    assert len(list((tmp_path / 'e' / 'parts').glob('*.parquet'))) == 2
    table, count = _sweep(tmp_path / 'e')
    assert count == 2 and table.num_rows == 6


def test_a_resume_with_another_vehicle_or_controller_is_refused(reference, tmp_path):
    # the models are not options of the spec: before, the old parts were kept and the
    # results silently mixed two vehicles (or were those of the old one)
    folder, table = reference
    before = sorted(p.name for p in (folder / 'parts').iterdir())
    with pytest.raises(ToolError, match='options differ: controller'):
        sw.sweep(SPEC, folder, vehicle=VEHICLE,
                 controller=ControllerParams(natural_frequency=2.0), workers=0, plots=False)
    with pytest.raises(ToolError, match='options differ: vehicle'):
        sw.sweep(SPEC, folder, vehicle=replace(VEHICLE, mass=1600.0),
                 controller=CONTROLLER, workers=0, plots=False)
    with pytest.raises(ToolError, match='options differ: lane_keeping'):
        _sweep(folder, lane_keeping=LaneKeepingParams(integral_gain=1.0))
    assert sorted(p.name for p in (folder / 'parts').iterdir()) == before
    again, count = _sweep(folder)                 # the same models: resumed, nothing to do
    assert count == 0 and _same(again, table)
    # a folder of the versions that did not record them: refused, not guessed
    manifest = json.loads((folder / 'sweep.json').read_text())
    old = tmp_path / 'old'
    (old / 'parts').mkdir(parents=True)
    models = ('vehicle', 'controller', 'lane_keeping')
    (old / 'sweep.json').write_text(json.dumps(
        {k: v for k, v in manifest.items() if k not in models}))
    with pytest.raises(ToolError, match='did not record its vehicle, controller and '
                       'lane-keeping settings'):
        _sweep(old)
    # the version before this one recorded the models but not lane_keeping, and ran
    # cg_compensated at its defaults whatever the file said: resumed with those (before:
    # refused), refused with another tuning. Its k_i was constant (before dev-kisched), as
    # the defaults' is again: the speed schedule is another law at 25 m/s (before
    # dev-probe27: resumed with it, mixing the two laws' runs)
    (old / 'sweep.json').write_text(json.dumps(
        {k: v for k, v in manifest.items() if k != 'lane_keeping'}))
    before = (old / 'sweep.json').read_text()
    with pytest.raises(ToolError, match='options differ: lane_keeping'):
        _sweep(old, lane_keeping=LaneKeepingParams(integral_gain=1.0))
    with pytest.raises(ToolError, match=r'options differ: lane_keeping\.low_speed_integral_'
                       r'gain = 0\.3 in the folder, 0\.05 now'):
        _sweep(old, lane_keeping=LaneKeepingParams(low_speed_integral_gain=0.05))
    constant = LaneKeepingParams()
    resumed, count = _sweep(old)
    assert count == 4 and _same(resumed, _sweep(tmp_path / 'constant', lane_keeping=constant)[0])
    assert (old / 'sweep.json').read_text() == before
    (old / 'sweep.json').write_text('[]')
    with pytest.raises(ToolError, match='not a sweep manifest'):
        _sweep(old)


def test_a_sweep_from_before_the_integral_gain_schedule_resumes_with_its_constant_k_i(
        reference, tmp_path):
    # before: its manifest's lane_keeping lacks the schedule's three names, so every
    # resume was refused ("options differ: lane_keeping", naming nothing), even with the
    # settings that run its law (low_speed_integral_gain = integral_gain: k_i constant)
    folder, _ = reference
    manifest = json.loads((folder / 'sweep.json').read_text())
    schedule = ('integral_speed', 'low_speed_integral_gain', 'low_integral_speed')
    manifest['lane_keeping'] = {k: v for k, v in manifest['lane_keeping'].items()
                                if k not in schedule}
    old = tmp_path / 'old'
    (old / 'parts').mkdir(parents=True)
    (old / 'sweep.json').write_text(json.dumps(manifest))
    with pytest.raises(ToolError, match=r'options differ: lane_keeping\.low_speed_integral_'
                       r'gain = 0\.3 in the folder, 0\.05 now'):
        _sweep(old, lane_keeping=LaneKeepingParams(low_speed_integral_gain=0.05))
    resumed, count = _sweep(old, lane_keeping=LaneKeepingParams(integral_speed=40.0))
    assert count == 4 and resumed.num_rows == 6


def test_a_sweep_from_before_the_cg_height_resumes_as_one_without_load_transfer(
        reference, tmp_path):
    # dev-probe62: its manifest's vehicle lacks cg_height, and every resume was refused
    # ("vehicle.cg_height = None in the folder, 0.0 now"), though cg_height 0 runs it
    from dataclasses import replace
    from lookahead_control.core.config import load_vehicle
    folder, _ = reference
    manifest = json.loads((folder / 'sweep.json').read_text())
    del manifest['vehicle']['cg_height']
    old = tmp_path / 'old'
    (old / 'parts').mkdir(parents=True)
    (old / 'sweep.json').write_text(json.dumps(manifest))
    with pytest.raises(ToolError, match=r'options differ: vehicle\.cg_height = 0\.0 in the '
                       r'folder, 0\.5 now'):
        sw.sweep(SPEC, old, vehicle=replace(load_vehicle(None), cg_height=0.5),
                 controller=CONTROLLER, plots=False, workers=0)
    resumed, count = _sweep(old)
    assert count == 4 and resumed.num_rows == 6


def test_a_sweep_with_a_cg_height_from_before_the_loaded_scale_is_refused(
        reference, tmp_path):
    # dev-probe63: since dev-sc29 the estimate learns its scale over the loaded rear
    # compliance; a folder of runs with a cg_height from before it resumed silently,
    # mixing runs of two estimators. Without a cg_height the estimate is the same
    from dataclasses import replace
    from lookahead_control.core.config import load_vehicle
    folder, _ = reference
    manifest = json.loads((folder / 'sweep.json').read_text())
    assert manifest.pop('load_transfer_estimate') == sw.LOADED_SCALE
    flat = tmp_path / 'flat'
    (flat / 'parts').mkdir(parents=True)
    (flat / 'sweep.json').write_text(json.dumps(manifest))
    resumed, count = _sweep(flat)
    assert count == 4 and resumed.num_rows == 6
    tall = tmp_path / 'tall'
    (tall / 'parts').mkdir(parents=True)
    manifest['vehicle']['cg_height'] = 0.5
    (tall / 'sweep.json').write_text(json.dumps(manifest))
    with pytest.raises(ToolError, match=r'vehicle\.cg_height = 0\.5 written by an earlier '
                       r"version of cg_compensated's compliance estimate"):
        sw.sweep(SPEC, tall, vehicle=replace(load_vehicle(None), cg_height=0.5),
                 controller=CONTROLLER, plots=False, workers=0)
    # a height of another type is named by the comparison, as before (dev-probe64: a
    # list was a TypeError traceback, a string an error naming neither)
    for bad in ([0.5], 'abc', None):
        manifest['vehicle']['cg_height'] = bad
        (tall / 'sweep.json').write_text(json.dumps(manifest))
        with pytest.raises(ToolError, match=r'options differ: vehicle\.cg_height = '
                           + re.escape(repr(bad)) + ' in the folder'):
            sw.sweep(SPEC, tall, vehicle=replace(load_vehicle(None), cg_height=0.5),
                     controller=CONTROLLER, plots=False, workers=0)


def test_a_sweep_written_with_the_schedule_default_resumes_only_with_the_schedule(
        reference, tmp_path):
    # a folder written from dev-kisched to dev-gate records low_speed_integral_gain 0.05
    # (then the default): resumed with today's default (k_i constant) it would mix two
    # laws' runs, so it is refused naming the setting, and resumes with it given
    folder, _ = reference
    manifest = json.loads((folder / 'sweep.json').read_text())
    manifest['lane_keeping']['low_speed_integral_gain'] = 0.05
    old = tmp_path / 'old'
    (old / 'parts').mkdir(parents=True)
    (old / 'sweep.json').write_text(json.dumps(manifest))
    with pytest.raises(ToolError, match=r'options differ: lane_keeping\.low_speed_integral_'
                       r'gain = 0\.05 in the folder, 0\.3 now'):
        _sweep(old)
    resumed, count = _sweep(old, lane_keeping=LaneKeepingParams(low_speed_integral_gain=0.05))
    assert count == 4 and resumed.num_rows == 6


def test_the_controller_file_tunes_the_lane_keeping_law(tmp_path, capsys):
    # before, --controller gave the paper laws their parameters and cg_compensated ran its
    # defaults whatever the file said: a tuning of the node's lane_keeping.* was never
    # what the sweep measured
    text = (Path(sw.source_config_dir()) / 'controller.yaml').read_text()
    assert '      integral_gain: 0.3 ' in text and '      natural_frequency: 7.0 ' in text
    tuned = tmp_path / 'tuned.yaml'
    tuned.write_text(text.replace('      integral_gain: 0.3 ', '      integral_gain: 2 ')
                     .replace('      natural_frequency: 7.0 ', '      natural_frequency: 4.0 '))
    args = ['--workers', '0', '--mode', 'grid', '--levels', '2', '--cornering=-0.3:0.3',
            '--mass', '0:0', '--friction', '1:1', '--delay', '0:0', '--speeds', '37',
            '--scenarios', 's2_curve_entry', '--duration', '5', '--laws', 'cg_compensated',
            '--no-plots', '--no-progress', '--no-noise', '--dt', '0.005']
    assert run_tool(sw.main, args + ['--out', str(tmp_path / 'd')]) == 0
    assert run_tool(sw.main, args + ['--out', str(tmp_path / 't'), '--controller',
                                     str(tuned)]) == 0
    capsys.readouterr()
    default = pq.read_table(tmp_path / 'd' / 'results.parquet').to_pydict()
    mine = pq.read_table(tmp_path / 't' / 'results.parquet').to_pydict()
    settings = LaneKeepingParams(integral_gain=2.0, natural_frequency=4.0)
    assert json.loads((tmp_path / 't' / 'sweep.json').read_text())['lane_keeping'] == (
        json.loads(json.dumps(asdict(settings))))
    # each run is the law with those settings on that plant, and not the default's
    scenario = replace(load_scenario(sw.scenario_path('s2_curve_entry')), duration=5.0)
    for i, cornering in enumerate(mine['cornering']):
        body = replace(VEHICLE, c_f=VEHICLE.c_f * (1 + cornering),
                       c_r=VEHICLE.c_r * (1 + cornering))
        peaks = []
        for lk in (settings, LaneKeepingParams()):
            law = sw.cg_compensated_law(VEHICLE, CONTROLLER, lk)
            result = run(scenario, VEHICLE, law, PlantParams(model='nonlinear'), dt=0.005,
                         initial_speed=np.array([37.0]), plant_vehicle=[body],
                         delay=np.array([0.0]))
            peaks.append(float(np.max(np.abs(result['y_cg']))))
        assert mine['peak_cg_error_m'][i] == pytest.approx(peaks[0], rel=1e-9)
        assert default['peak_cg_error_m'][i] == pytest.approx(peaks[1], rel=1e-9)
        assert abs(peaks[0] - peaks[1]) > 0.05 * peaks[1]
    summary = (tmp_path / 't' / 'summary.md').read_text()
    assert ('cg_compensated: lane_keeping.natural_frequency = 4.0, '
            'lane_keeping.integral_gain = 2.0 (the rest default).') in summary
    assert 'cg_compensated: the default settings.' in (tmp_path / 'd' / 'summary.md').read_text()
    # a bad value in the file is one line naming it, before any run
    tuned.write_text(text.replace('      integral_gain: 0.3 ', '      integral_gain: -1.0 '))
    code = run_tool(sw.main, args + ['--out', str(tmp_path / 'b'), '--controller',
                                     str(tuned)])
    err = capsys.readouterr().err
    assert code == 2 and 'lane_keeping.integral_gain = -1.0' in err and err.count('\n') == 1
    assert not (tmp_path / 'b').exists()
    # so is a file the node refuses: controller.reference arc_exact with cg_compensated
    # (before: run with lane_tangent put in its place), a namespace typo in the node's
    # section (before: run at the defaults)
    for bad, blamed in ((text.replace('reference: lane_tangent', 'reference: arc_exact'),
                         "cg_compensated: controller.reference = 'arc_exact'"),
                        ('controller:\n  ros__parameters:\n    lane_keping:\n'
                         '      integral_gain: 2.0\n', "'lane_keping.integral_gain'")):
        tuned.write_text(bad)
        code = run_tool(sw.main, args + ['--out', str(tmp_path / 'b'), '--controller',
                                         str(tuned)])
        err = capsys.readouterr().err
        assert code == 2 and blamed in err and err.count('\n') == 1, err
        assert not (tmp_path / 'b').exists()


def test_the_printed_summary_gives_the_worst_case_of_each_scenario(tmp_path, capsys):
    # before, only the row over all scenarios was printed: the worst case per scenario
    # (issue 14's S1 / S2 / S3 figures) was only in summary.md
    code = run_tool(sw.main, ['--out', str(tmp_path / 'p'), '--workers', '0', '--mode',
                              'grid', '--levels', '2', '--cornering=-0.3:0.3', '--mass', '0:0',
                              '--friction', '1:1', '--delay', '0:0', '--speeds', '37',
                              '--scenarios', 's1_paper_step,s2_curve_entry', '--duration',
                              '2.6', '--dt', '0.002', '--laws', 'cg_compensated',
                              '--no-plots', '--no-progress'])
    out = capsys.readouterr().out
    assert code == 0
    data = pq.read_table(tmp_path / 'p' / 'results.parquet').to_pydict()
    lines = {line.split('|')[2].strip(): line.split('|') for line in out.splitlines()
             if line.startswith('| cg_compensated')}
    assert set(lines) == {'all', 's1_paper_step', 's2_curve_entry'}
    for scenario in ('s1_paper_step', 's2_curve_entry'):
        peaks = [p for p, s in zip(data['peak_cg_error_m'], data['scenario']) if s == scenario]
        worst = int(np.argmax(peaks))
        cornering = [c for c, s in zip(data['cornering'], data['scenario']) if s == scenario]
        assert len(peaks) == 2
        assert float(lines[scenario][7]) == pytest.approx(max(peaks), rel=5e-3)
        assert f'C x{1 + cornering[worst]:.2f}' in lines[scenario][8]
    assert float(lines['all'][7]) == pytest.approx(max(data['peak_cg_error_m']), rel=5e-3)


def test_the_summary_names_every_setting_each_law_ran_with(tmp_path):
    # before, summary.md named only lane_keeping.*: cg_compensated run with the file's
    # controller.max_look_ahead was said to run "the rest default", and the paper laws'
    # controller.* went unnamed
    spec = replace(SPEC, laws=('paper_eq26', 'cg_compensated'), runs=1, speeds=(37.0,))
    sw.sweep(spec, tmp_path / 's', vehicle=VEHICLE, workers=0, plots=False,
             controller=ControllerParams(natural_frequency=2.0, max_look_ahead=40.0),
             lane_keeping=LaneKeepingParams(integral_gain=0.6))
    summary = (tmp_path / 's' / 'summary.md').read_text()
    assert (' paper_eq26: controller.natural_frequency = 2.0, controller.max_look_ahead = '
            '40.0 (the rest default). cg_compensated: controller.max_look_ahead = 40.0, '
            'lane_keeping.integral_gain = 0.6 (the rest default).') in summary
