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

"""
The curvature polygon read where the car is at the answer (``curvature_to_clock``, dev-sc53).

A map sends its polygon at 10 Hz: at an answer it is up to 100 ms old, and the points it
gives ahead of the CG at its stamp are 3.7 m behind where the car is at 37 m/s. Read as
stamped, the default law (which takes its state for the present) met every curve late.
"""

from dataclasses import replace
from pathlib import Path

from lookahead_control.bags.run_data import (as_it_ran, controller_from_params, rerun,
                                             rerun_law, RunData, Samples)
from lookahead_control.core.controller import SteeringController
from lookahead_control.core.lane_keeping import LaneKeepingParams
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
from lookahead_control.core.samples import (curvature_from_points, LateralErrorSample,
                                            VelocitySample, YawSample)
from lookahead_control.tools import compare
import numpy as np
import pytest
from sim_plant.sensor_timing import SensorTiming, StreamTiming, timed_run

MS = 1_000_000
VEHICLE = VehicleParams()
#: a straight 10 m, then a curve of 0.01 1/m
POLYGON = [(0.0, 0.0), (10.0, 0.0), (10.5, 0.01), (100.0, 0.01)]
#: a lateral error and IMU of now at 100 Hz, odometry at 50 Hz, a map of now at 10 Hz
MAP_10HZ = SensorTiming(StreamTiming(100.0, 0.0), yaw=StreamTiming(100.0, 0.0),
                        velocity=StreamTiming(50.0, 0.0),
                        road_curvature=StreamTiming(10.0, 0.0))


def _core(law='cg_compensated', **options):
    """Return a core with every input in, the polygon stamped at 0 and the rest at 50 ms."""
    core = SteeringController(VEHICLE, ControllerParams(), law=law, **options)
    assert core.accept('road_curvature', curvature_from_points(0, POLYGON)) is None
    for name, sample in (('yaw', YawSample(50 * MS, 0.0, 0.0, 0.0)),
                         ('velocity', VelocitySample(50 * MS, 20.0, 0.0)),
                         ('lateral_error', LateralErrorSample(50 * MS, 0.0, 0.0))):
        assert core.accept(name, sample) is None
    return core


def test_a_polygon_older_than_the_clock_is_read_where_the_car_is():
    core = _core()
    # 100 ms at 20 m/s: 2 m driven, the curve 8 m ahead
    road = core.road(100 * MS)
    assert [x for x, _ in road.ahead][:3] == pytest.approx([-2.0, 8.0, 8.5])
    assert road.rho == 0.0
    # the age bounded by input_timeout (0.2 s: 4 m)
    timeout = core.safety.input_timeout
    assert core.road(5000 * MS).ahead[0][0] == pytest.approx(-20.0 * timeout)
    # the curvature at the CG where the car is: a curve 2 m ahead of the polygon's CG
    near = _core()
    near.accept('road_curvature', curvature_from_points(10 * MS, [(0.0, 0.0), (2.0, 0.0),
                                                                  (2.5, 0.01), (100.0, 0.01)]))
    assert near.road(100 * MS).rho == 0.0           # 1.8 m driven
    assert near.road(150 * MS).rho == pytest.approx(0.01)   # 2.8 m
    # without a clock: on the stamps, to the lateral error's (50 ms: 1 m)
    assert core.road().ahead[1][0] == pytest.approx(9.0)
    # a clock at or behind the polygon's stamp: as it is
    assert core.road(0).ahead == tuple(POLYGON)
    assert core.road(-5 * MS).ahead == tuple(POLYGON)


def test_curvature_to_clock_false_reads_it_as_stamped_and_any_law_moves_it():
    assert _core(curvature_to_clock=False).road(100 * MS).ahead == tuple(POLYGON)
    paper = _core('paper')
    assert paper.road(100 * MS).ahead[1][0] == pytest.approx(8.0)
    paper.configure(paper.vehicle, paper.params, 'imu', False, curvature_to_clock=False)
    assert paper.road(100 * MS).ahead == tuple(POLYGON)
    with pytest.raises(ParameterError, match="curvature_to_clock = 'yes'.*true or false"):
        SteeringController(VEHICLE, ControllerParams(), curvature_to_clock='yes')


def test_the_prediction_reads_it_at_the_lateral_error_s_stamp_whatever_the_clock():
    lane = replace(LaneKeepingParams(), delay_prediction=True, filter_delay=0.1)
    core = _core(lane_keeping=lane)
    assert core.road(100 * MS).ahead[1][0] == pytest.approx(9.0)
    assert core.road(400 * MS).ahead[1][0] == pytest.approx(9.0)


def test_compute_reads_the_road_at_the_node_s_clock_or_the_one_given():
    core = _core()
    core.compute(100 * MS)
    assert core.road_clock_ns == 100 * MS
    core.compute(100 * MS, answered_ns=70 * MS)
    assert core.road_clock_ns == 70 * MS
    core.compute()
    assert core.road_clock_ns is None
    # outside compute(): the lateral error's stamp
    assert core.road().ahead[1][0] == pytest.approx(9.0)


def _peak(settings, scenario='s1_paper_step'):
    case = compare.load_scenarios([scenario])[scenario].at_speed(37.0)
    result = timed_run(case, compare.node_core('cg_compensated', VEHICLE, settings), MAP_10HZ,
                       compare.NONLINEAR, dt=0.005, delay=compare.DELAY)
    return float(np.max(np.abs(result['y_cg'])))


def test_a_10_hz_map_of_now_no_longer_puts_the_curve_late():
    # the default law, a lateral error of now at 100 Hz, a 10 Hz map of now, 37 m/s,
    # noise-free: read as stamped S1 14.1 cm, S3 17.9 cm; read where the car is 4.2 / 3.0
    # (every input at 100 Hz on one stamp, the simulator's: 2.7 / 2.7)
    settings = compare.LawSettings()
    as_stamped = replace(settings, curvature_to_clock=False)
    for scenario, now, before in (('s1_paper_step', 0.05, 0.12), ('s3_s_bend', 0.04, 0.15)):
        moved, old = _peak(settings, scenario), _peak(as_stamped, scenario)
        assert moved < now < before < old, (scenario, moved, old)


def test_a_bag_of_a_node_before_curvature_to_clock_re_runs_as_stamped():
    recorded = {'law': 'cg_compensated', 'use_curvature_preview': False,
                'align_inputs': 'with_prediction'}
    assert as_it_ran(recorded) == {'curvature_to_clock': False}
    assert not controller_from_params(recorded)[0].curvature_to_clock
    assert controller_from_params(recorded, {'curvature_to_clock': True})[0].curvature_to_clock
    assert controller_from_params({**recorded, 'curvature_to_clock': True})[0].curvature_to_clock


def _node_run(law, age_ms, debug=True, switch_at=None, repeats=1):
    """
    Return the recording of a node answering 100 Hz inputs ``age_ms`` after their stamp.

    A 10 Hz polygon with a curve 20 m ahead of its CG, at 20 m/s; the node's debug topic
    holds ``road_clock_age`` when ``debug``. ``switch_at``: at that step
    ``curvature_to_clock`` is set false at run time (a ``/parameter_events`` set, the
    debug's ``parameter_sets``). ``repeats``: each lateral error answered that many
    times, ``age_ms`` apart (timer mode).
    """
    node = SteeringController(VEHICLE, ControllerParams(), law=law)
    rows = {'lateral_error': [], 'yaw': [], 'velocity': [], 'road_curvature': []}
    commands, ages, sets, debug_stamps = {}, [], [], []
    for k in range(150):
        stamp = k * 10 * MS
        if k == switch_at:
            node.configure(node.vehicle, node.params, 'imu', False, curvature_to_clock=False)
        if k % 10 == 0:
            driven = 20.0 * k * 0.01
            rows['road_curvature'].append(curvature_from_points(
                stamp, [(x - driven, 0.0 if x < 20.0 else 0.01) for x in range(0, 101, 5)]))
            node.accept('road_curvature', rows['road_curvature'][-1])
        samples = (('yaw', YawSample(stamp, 0.002 * np.sin(k / 5.0), 0.0, 0.0)),
                   ('velocity', VelocitySample(stamp, 20.0, 0.0)),
                   ('lateral_error', LateralErrorSample(stamp, 0.0, 0.01 * np.sin(k / 7.0))))
        for name, sample in samples:
            rows[name].append(sample)
            node.accept(name, sample)
        for copy in range(repeats):
            age = age_ms * (copy + 1)
            command = node.compute(answered_ns=stamp + age * MS)
            commands.setdefault(stamp, command.steering)
            assert command.steering == commands[stamp]      # (held on the stamps)
            ages.append(age * 1e-3)
            sets.append(float(switch_at is not None and k >= switch_at))
            debug_stamps.append(stamp)
    inputs = {}
    for name, samples in rows.items():
        stamps = np.array([s.stamp_ns for s in samples], dtype=np.int64)
        values = {field: np.array([getattr(s, field) for s in samples], dtype=float)
                  for field in type(samples[0])._fields[1:] if field != 'ahead'}
        if name == 'road_curvature':
            values['ahead'] = np.empty(len(samples), dtype=object)
            values['ahead'][:] = [s.ahead for s in samples]
        inputs[name] = Samples(stamps + 1, stamps, np.arange(stamps.size), values)
    stamps = np.array(sorted(commands), dtype=np.int64)
    steering = Samples(stamps + 10, stamps, np.arange(stamps.size),
                       {'angle': np.array([commands[s] for s in stamps])})
    columns = {'road_clock_age': np.array(ages)} if debug else {}
    if switch_at is not None:
        columns['parameter_sets'] = np.array(sets)
    at = np.array(debug_stamps, dtype=np.int64)
    params = {'law': law, 'use_curvature_preview': False, 'curvature_to_clock': True}
    return RunData(Path('synthetic'), inputs=inputs, steering=steering,
                   debug=Samples(at + 11, at, np.arange(at.size), columns),
                   controller_params=params,
                   parameter_events=None if switch_at is None else [
                       {'curvature_to_clock': False}])


@pytest.mark.parametrize('law', ['cg_compensated', 'paper'])
def test_the_re_run_reads_the_road_at_the_recorded_node_s_clock(law):
    run = _node_run(law, 40)
    result = rerun(run, order='stamp')
    assert result.compared == 150
    assert result.max_diff == 0.0
    stamps, out = rerun_law(run, order='stamp')
    assert len(stamps) == 150
    for i, stamp in enumerate(stamps.tolist()):
        assert float(out.steering[i]) == pytest.approx(result.commands[stamp].law.steering,
                                                       rel=1e-12, abs=1e-15)
    # the debug topic not recorded: read at the lateral error's stamp, another command
    blind = rerun(_node_run(law, 40, debug=False), order='stamp')
    assert blind.max_diff > 1e-4


def test_replay_says_a_bag_predates_curvature_to_clock(tmp_path, capsys):
    import json

    from lookahead_control.bags import replay_node
    from lookahead_control.core.cli import run_tool
    from test_rerun_lost_curvature import controllers_bag
    bag = tmp_path / 'old'
    params = {'law': 'cg_compensated', 'use_curvature_preview': False,
              'align_inputs': 'with_prediction', 'curvature_to_clock': False}
    controllers_bag(bag, {'/controller': params}, steps=60, unrecorded=('curvature_to_clock',))
    report = tmp_path / 'old.json'
    # (1e-8: the yaw goes through the Imu's quaternion)
    assert run_tool(replay_node.main, [str(bag), '--check', '1e-8', '--json',
                                       str(report)]) == 0
    out = capsys.readouterr().out
    assert 'predates curvature_to_clock' in out and 'curvature_to_clock=false' in out, out
    assert json.loads(report.read_text())['parameters_as_it_ran'] == {
        'curvature_to_clock': False}
    assert run_tool(replay_node.main, [str(bag), '--offline', '-p',
                                       'curvature_to_clock=true']) == 0
    assert 'predates' not in capsys.readouterr().out


def test_a_run_time_set_of_curvature_to_clock_is_followed_by_the_re_run():
    # dev-probe123: the re-run of any bag with a parameter set at run time crashed (the
    # core's arguments grew by one, reconfigure unpacked the old count)
    run = _node_run('cg_compensated', 40, switch_at=75)
    result = rerun(run, order='stamp')
    assert result.compared == 150 and result.parameter_sets == 1
    assert result.max_diff == 0.0
    kept = rerun(replace(run, parameter_events=None), order='stamp')
    assert kept.max_diff > 1e-4


def test_timer_mode_s_repeated_answers_re_run_at_the_first_one_s_clock():
    # dev-probe123: the last answer's age was taken, the command sent is the first's
    # (the later ones are held on the stamps): 1.8 mrad off
    run = _node_run('paper', 3, repeats=3)
    assert len(run.debug) == 450
    assert rerun(run, order='stamp').max_diff == 0.0


def test_a_huge_recorded_clock_age_is_bounded_not_an_overflow():
    # dev-probe123: 1e300 s passed the finite filter and overflowed
    from lookahead_control.bags.run_data import MAX_CLOCK_AGE, recorded_clock_ages
    run = _node_run('paper', 40)
    ages = run.debug.values['road_clock_age'].copy()
    ages[:3] = [1e300, -1e300, np.nan]
    run = replace(run, debug=replace(run.debug, values={'road_clock_age': ages}))
    taken = recorded_clock_ages(run)
    assert list(taken.values())[:2] == [MAX_CLOCK_AGE, -MAX_CLOCK_AGE]
    assert len(taken) == 149
    result = rerun(run, order='stamp')
    assert result.compared == 150 and np.isfinite(result.max_diff)
    stamps, _ = rerun_law(run, order='stamp')
    assert len(stamps) == 150


def test_a_bad_value_in_configure_changes_nothing():
    # dev-probe123: align_inputs was taken before curvature_to_clock was refused
    core = _core()
    with pytest.raises(ParameterError, match='curvature_to_clock'):
        core.configure(core.vehicle, core.params, 'imu', False, align_inputs='always',
                       curvature_to_clock='yes')
    assert core.align_inputs == 'with_prediction' and core.curvature_to_clock is True


def test_a_safe_command_reads_no_road():
    core = _core()
    core.compute(60 * MS)
    assert core.road_clock_ns == 60 * MS
    core.safe_command(900 * MS)
    assert core.road_clock_ns is None


def test_with_the_inputs_read_at_the_lateral_error_s_stamp_the_polygon_is_as_stamped():
    # align_inputs always without the prediction: the state is the lateral error's
    # instant; read at the clock the polygon measured worse (compare, 25 Hz / 80 ms
    # camera, a 10 Hz map: S1 / S2 7.6 / 9.1 | 6.3 / 4.1 cm as stamped, 9.4 / 11.3 | 14.1 /
    # 7.3 at the clock, 13.2 / 8.6 | 7.5 / 4.5 at the lateral error's stamp)
    assert _core(align_inputs='always').road(100 * MS).ahead == tuple(POLYGON)
    assert _core(align_inputs='never').road(100 * MS).ahead[1][0] == pytest.approx(8.0)
