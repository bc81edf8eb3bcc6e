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
A curvature polygon read where the car was at the yaw's stamp (``curvature_at_yaw_stamp``).

dev-sc53. A map sends its polygon at 10 Hz beside an IMU at 100 Hz: the newest polygon is
up to 100 ms older than the yaw rate the law takes, and the points it gives ahead of the
CG at its stamp are 3.7 m behind where the car is at 37 m/s. Read as stamped, the default
law (which takes its state for the present) met every curve late.
"""

from dataclasses import replace
from pathlib import Path

from lookahead_control.bags.run_data import (as_it_ran, controller_from_params, rerun,
                                             rerun_law, RunData, Samples)
from lookahead_control.core.controller import SteeringController
from lookahead_control.core.lane_keeping import LaneKeepingParams
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
from lookahead_control.core.safety import SafetyParams
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


def _core(law='cg_compensated', yaw_ms=100, **options):
    """Return a core: the polygon stamped at 0, the lateral error at 50 ms, the yaw later."""
    core = SteeringController(VEHICLE, ControllerParams(), law=law, **options)
    assert core.accept('road_curvature', curvature_from_points(0, POLYGON)) is None
    for name, sample in (('velocity', VelocitySample(50 * MS, 20.0, 0.0)),
                         ('lateral_error', LateralErrorSample(50 * MS, 0.0, 0.0)),
                         ('yaw', YawSample(yaw_ms * MS, 0.0, 0.0, 0.0))):
        assert core.accept(name, sample) is None
    return core


def _distances(core):
    """Return the distances of the polygon the law reads."""
    return [x for x, _ in core.road().ahead]


def test_a_polygon_older_than_the_yaw_is_read_where_the_car_was_at_its_stamp():
    # 100 ms at 20 m/s: 2 m driven, the curve 8 m ahead
    assert _distances(_core())[:3] == pytest.approx([-2.0, 8.0, 8.5])
    assert _distances(_core(yaw_ms=150))[1] == pytest.approx(7.0)
    # the age bounded by input_timeout
    short = _core(safety=SafetyParams(input_timeout=0.04))
    assert _distances(short)[1] == pytest.approx(9.2)
    # a polygon on the yaw's stamp, or newer: as it is
    assert _distances(_core(yaw_ms=0)) == [x for x, _ in POLYGON]
    # the curvature at the CG where the car was: a curve 2 m ahead of the polygon's CG
    near = _core()
    near.accept('road_curvature', curvature_from_points(10 * MS, [(0.0, 0.0), (2.0, 0.0),
                                                                  (2.5, 0.01), (100.0, 0.01)]))
    assert near.road().rho == 0.0                   # 1.8 m driven
    near.accept('yaw', YawSample(150 * MS, 0.0, 0.0, 0.0))
    assert near.road().rho == pytest.approx(0.01)   # 2.8 m
    # a one-point sample is a curvature held ahead: as it is
    near.accept('road_curvature', curvature_from_points(140 * MS, [(0.0, 0.004)]))
    assert near.road() is near.curvature


def test_as_stamped_when_off_or_with_the_yaw_of_the_lateral_error_s_stamp():
    assert _distances(_core(curvature_at_yaw_stamp=False)) == [x for x, _ in POLYGON]
    paper = _core('paper')
    assert _distances(paper)[1] == pytest.approx(8.0)       # (any law)
    paper.configure(paper.vehicle, paper.params, 'imu', False, curvature_at_yaw_stamp=False)
    assert _distances(paper) == [x for x, _ in POLYGON]
    with pytest.raises(ParameterError, match="curvature_at_yaw_stamp = 'yes'.*true or false"):
        SteeringController(VEHICLE, ControllerParams(), curvature_at_yaw_stamp='yes')
    # align_inputs always without the prediction: the yaw is read at the lateral error's
    # stamp; at that stamp the polygon measured worse than as stamped (compare, 25 Hz /
    # 80 ms camera, a 10 Hz map, S1 / S2 nonlinear | CommonRoad: 7.6 / 9.1 | 6.3 / 4.1 cm
    # as stamped, 13.2 / 8.6 | 7.5 / 4.5 at the lateral error's stamp)
    assert _distances(_core(align_inputs='always')) == [x for x, _ in POLYGON]
    assert _distances(_core(align_inputs='never'))[1] == pytest.approx(8.0)


def test_the_prediction_reads_it_at_the_lateral_error_s_stamp_whatever_the_yaw():
    lane = replace(LaneKeepingParams(), delay_prediction=True, filter_delay=0.1)
    assert _distances(_core(lane_keeping=lane))[1] == pytest.approx(9.0)
    assert _distances(_core(lane_keeping=lane, yaw_ms=190))[1] == pytest.approx(9.0)


def _peak(settings, scenario, timing=MAP_10HZ):
    case = compare.load_scenarios([scenario])[scenario].at_speed(37.0)
    result = timed_run(case, compare.node_core('cg_compensated', VEHICLE, settings), timing,
                       compare.NONLINEAR, dt=0.005, delay=compare.DELAY)
    return float(np.max(np.abs(result['y_cg'])))


def test_a_10_hz_map_beside_an_imu_of_now_no_longer_puts_the_curve_late():
    # the default law, a lateral error of now at 100 Hz, a 10 Hz map of now, 37 m/s,
    # noise-free: read as stamped S1 14.1 cm, S3 17.9 cm; read where the car was at the
    # yaw's stamp 4.2 / 3.0 (every input at 100 Hz on one stamp, the simulator's: 2.7 /
    # 2.7)
    settings = compare.LawSettings()
    as_stamped = replace(settings, curvature_at_yaw_stamp=False)
    for scenario, now, before in (('s1_paper_step', 0.05, 0.12), ('s3_s_bend', 0.04, 0.15)):
        moved, old = _peak(settings, scenario), _peak(as_stamped, scenario)
        assert moved < now < before < old, (scenario, moved, old)


def test_a_polygon_sent_with_each_frame_of_a_late_camera_is_read_with_the_frame():
    # dev-probe124: moved to the node's clock, a polygon sent with each frame (the yaw and
    # speed of the frame's instant too) was read ahead of the rest of the state: 30 Hz /
    # 50 ms, S2 at 37 m/s 2.5 -> 6.0 cm noise-free; with the yaw's stamp nothing moves
    settings = compare.LawSettings()
    frame = SensorTiming(StreamTiming(30.0, 0.05), with_frame=True)
    as_stamped = replace(settings, curvature_at_yaw_stamp=False)
    for scenario in ('s2_curve_entry', 's3_s_bend'):
        assert _peak(settings, scenario, frame) == _peak(as_stamped, scenario, frame)


def test_a_bag_of_a_node_before_curvature_at_yaw_stamp_re_runs_as_stamped():
    # (the hold preview recorded: curvature_at_yaw_stamp alone is missing)
    recorded = {'law': 'cg_compensated', 'use_curvature_preview': False,
                'align_inputs': 'with_prediction', 'lane_keeping.hold_preview': 0.0,
                'lane_keeping.frequency_lag': 0.2}
    assert as_it_ran(recorded) == {'curvature_at_yaw_stamp': False}
    assert not controller_from_params(recorded)[0].curvature_at_yaw_stamp
    assert controller_from_params(recorded,
                                  {'curvature_at_yaw_stamp': True})[0].curvature_at_yaw_stamp
    assert controller_from_params({**recorded,
                                   'curvature_at_yaw_stamp': True})[0].curvature_at_yaw_stamp


def _node_run(law, answer_ms, switch_at=None):
    """
    Return the recording of a node answering ``answer_ms`` after its inputs' stamps.

    A lateral error and IMU at 100 Hz, a 10 Hz polygon with a curve 20 m ahead of its CG,
    at 20 m/s; the inputs received in stamp order. ``switch_at``: at that step
    ``curvature_at_yaw_stamp`` is set false at run time (a ``/parameter_events`` set, the
    debug's ``parameter_sets``).
    """
    node = SteeringController(VEHICLE, ControllerParams(), law=law)
    rows = {'lateral_error': [], 'yaw': [], 'velocity': [], 'road_curvature': []}
    commands, sets = {}, []
    for k in range(150):
        stamp = k * 10 * MS
        if k == switch_at:
            node.configure(node.vehicle, node.params, 'imu', False,
                           curvature_at_yaw_stamp=False)
        samples = [('yaw', YawSample(stamp, 0.002 * np.sin(k / 5.0), 0.0, 0.0)),
                   ('velocity', VelocitySample(stamp, 20.0, 0.0)),
                   ('lateral_error', LateralErrorSample(stamp, 0.0, 0.01 * np.sin(k / 7.0)))]
        if k % 10 == 0:
            driven = 20.0 * k * 0.01
            samples.insert(0, ('road_curvature', curvature_from_points(
                stamp, [(x - driven, 0.0 if x < 20.0 else 0.01) for x in range(0, 101, 5)])))
        for name, sample in samples:
            rows[name].append(sample)
            assert node.accept(name, sample, stamp + answer_ms * MS) is None
        commands[stamp] = node.compute(stamp + answer_ms * MS).steering
        sets.append(float(switch_at is not None and k >= switch_at))
    inputs = {}
    for name, samples in rows.items():
        stamps = np.array([s.stamp_ns for s in samples], dtype=np.int64)
        values = {field: np.array([getattr(s, field) for s in samples], dtype=float)
                  for field in type(samples[0])._fields[1:] if field != 'ahead'}
        if name == 'road_curvature':
            values['ahead'] = np.empty(len(samples), dtype=object)
            values['ahead'][:] = [s.ahead for s in samples]
        inputs[name] = Samples(stamps + answer_ms * MS, stamps, np.arange(stamps.size),
                               values)
    stamps = np.array(sorted(commands), dtype=np.int64)
    steering = Samples(stamps + answer_ms * MS + 10, stamps, np.arange(stamps.size),
                       {'angle': np.array([commands[s] for s in stamps])})
    columns = {} if switch_at is None else {'parameter_sets': np.array(sets)}
    params = {'law': law, 'use_curvature_preview': False, 'curvature_at_yaw_stamp': True}
    return RunData(Path('synthetic'), inputs=inputs, steering=steering,
                   debug=Samples(stamps + 11, stamps, np.arange(stamps.size), columns),
                   controller_params=params,
                   parameter_events=None if switch_at is None else [
                       {'curvature_at_yaw_stamp': False}])


@pytest.mark.parametrize('law', ['cg_compensated', 'paper'])
def test_the_re_run_reads_the_road_as_the_node_did_whenever_it_answered(law):
    # on the stamps alone: the node's clock at the answer does not enter (dev-probe124:
    # read at the clock, an answer 40 ms after the stamps needed the clock recorded)
    run = _node_run(law, 40)
    result = rerun(run, order='stamp')
    assert result.compared == 150 and result.max_diff == 0.0
    stamps, out = rerun_law(run, order='stamp')
    assert len(stamps) == 150
    for i, stamp in enumerate(stamps.tolist()):
        assert float(out.steering[i]) == pytest.approx(result.commands[stamp].law.steering,
                                                       rel=1e-12, abs=1e-15)
    # off: another command (the polygon read as stamped)
    assert rerun(run, {'curvature_at_yaw_stamp': False}, order='stamp').max_diff > 1e-4


def test_a_run_time_set_of_curvature_at_yaw_stamp_is_followed_by_the_re_run():
    # dev-probe123: the re-run of any bag with a parameter set at run time crashed (the
    # core's arguments grew by one, reconfigure unpacked the old count)
    run = _node_run('cg_compensated', 40, switch_at=75)
    result = rerun(run, order='stamp')
    assert result.compared == 150 and result.parameter_sets == 1
    assert result.max_diff == 0.0
    kept = rerun(replace(run, parameter_events=None), order='stamp')
    assert kept.max_diff > 1e-4


def test_a_bad_value_in_configure_changes_nothing():
    # dev-probe123: align_inputs was taken before curvature_at_yaw_stamp was refused
    core = _core()
    with pytest.raises(ParameterError, match='curvature_at_yaw_stamp'):
        core.configure(core.vehicle, core.params, 'imu', False, align_inputs='always',
                       curvature_at_yaw_stamp='yes')
    assert core.align_inputs == 'with_prediction' and core.curvature_at_yaw_stamp is True


def test_replay_says_a_bag_predates_curvature_at_yaw_stamp(tmp_path, capsys):
    import json

    from lookahead_control.bags import replay_node
    from lookahead_control.core.cli import run_tool
    from test_rerun_lost_curvature import controllers_bag
    bag = tmp_path / 'old'
    params = {'law': 'cg_compensated', 'use_curvature_preview': False,
              'align_inputs': 'with_prediction', 'curvature_at_yaw_stamp': False,
              'lane_keeping.hold_preview': 0.5, 'lane_keeping.frequency_lag': 0.2}
    controllers_bag(bag, {'/controller': params}, steps=60,
                    unrecorded=('curvature_at_yaw_stamp',))
    report = tmp_path / 'old.json'
    # (1e-8: the yaw goes through the Imu's quaternion)
    assert run_tool(replay_node.main, [str(bag), '--check', '1e-8', '--json',
                                       str(report)]) == 0
    out = capsys.readouterr().out
    assert 'predates curvature_at_yaw_stamp' in out, out
    assert 'curvature_at_yaw_stamp=false' in out, out
    assert json.loads(report.read_text())['parameters_as_it_ran'] == {
        'curvature_at_yaw_stamp': False}
    assert run_tool(replay_node.main, [str(bag), '--offline', '-p',
                                       'curvature_at_yaw_stamp=true']) == 0
    assert 'predates' not in capsys.readouterr().out
