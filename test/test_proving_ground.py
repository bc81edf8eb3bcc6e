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

"""Proving-ground scenarios S0-S5, road geometry and the CommonRoad plants."""

from dataclasses import replace
import math
from pathlib import Path

from conftest import Swerve
from lookahead_control.core.config import ConfigError
from lookahead_control.core.laws import output
from lookahead_control.core.params import ControllerParams, ParameterError
import numpy as np
from numpy.testing import assert_array_equal
import pytest
from sim_plant.closed_loop_sim import run
from sim_plant.commonroad_plant import (commonroad_parameters, CommonRoadPlant,
                                        controller_vehicle)
from sim_plant.road import Road, RoadBatch, Segment
from sim_plant.road_geometry import Centreline, wrap
from sim_plant.scenario import InitialState, load_scenario, Scenario
from sim_plant.speed_profile import SpeedProfile
from sim_plant.vehicle_model import PlantParams

SCENARIOS = Path(__file__).resolve().parent.parent / 'config' / 'scenarios'


def _load(name, speed=None):
    return load_scenario(SCENARIOS / f'{name}.yaml', speed)


@pytest.mark.parametrize('speed', [10.0, 20.0, 30.0, 37.0])
def test_scenarios_are_laid_out_for_each_speed(speed):
    s0 = _load('s0_straight', speed)
    assert s0.initial.relative_yaw == 0.01 and s0.road.curvature(300.0) == (0.0, 0.0)
    s1 = _load('s1_paper_step', speed)
    assert s1.road.segments[0].length == pytest.approx(2.0 * speed)
    s2 = _load('s2_curve_entry', speed)
    clothoid = s2.road.segments[1]
    assert clothoid.length == pytest.approx(max(40.0, 1.5 * speed))
    assert (clothoid.curvature_start, clothoid.curvature_end) == (0.0, -0.0025)
    s3 = _load('s3_s_bend', speed)
    arcs = [seg.curvature_start for seg in s3.road.segments if seg.kind == 'arc']
    assert arcs == pytest.approx([4.0 / speed ** 2, -4.0 / speed ** 2], rel=1e-12)
    # S4: the lane moves 3.5 m left and back, ends parallel (exact geometry)
    s4 = _load('s4_lane_change', speed)
    line = Centreline(s4.road)
    ends = np.cumsum([seg.length for seg in s4.road.segments])
    x, y = line.point(float(ends[4]))
    assert y == pytest.approx(3.5, abs=1e-9) and line.heading(float(ends[4])) == (
        pytest.approx(0.0, abs=1e-12))
    assert line.point(float(ends[9]))[1] == pytest.approx(0.0, abs=1e-9)
    peak = max(abs(seg.curvature_end) for seg in s4.road.segments)
    assert 3.8 < peak * speed ** 2 < 4.2          # about 4 m/s^2 at every speed


def test_s5_envelope_speed_and_lateral_acceleration():
    s5 = _load('s5_envelope')
    t = np.linspace(0.0, s5.duration, 30001)
    v, a = s5.speed.at(t)
    assert v[0] == 10.0 and np.max(v) == pytest.approx(37.0) and v[-1] == pytest.approx(10.0)
    assert np.max(np.abs(a)) == 3.5
    s = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    rho, _ = s5.road.curvature(s)
    assert np.max(np.abs(rho * v * v)) <= 3.5
    assert np.max(np.abs(rho * v * v)) > 3.0
    with pytest.raises(ConfigError, match='own speed profile'):
        _load('s5_envelope', 37.0)
    with pytest.raises(ParameterError, match='own speed profile'):
        run(s5, controller_vehicle(2), ControllerParams(), initial_speed=np.array([20.0]))


def _bad(tmp_path, body):
    path = tmp_path / 'bad.yaml'
    path.write_text(body)
    with pytest.raises(ConfigError) as err:
        load_scenario(path)
    message = str(err.value)
    assert '\n' not in message and str(path) in message
    return message


HEAD = 'scenario:\n  name: bad\n  duration: 5.0\n  speed: {initial: 20.0}\n'


def test_bad_scenario_files_give_one_clear_line(tmp_path):
    assert 'unknown keys' in _bad(tmp_path, HEAD + '  road:\n    - {type: arc, length: 5, '
                                  'curvature: 0.01, radius: 3}\n')
    assert 'needs offset' in _bad(tmp_path, HEAD + '  road:\n    - {type: lane_change, '
                                  'time: 2.0}\n')
    assert 'too short' in _bad(tmp_path, HEAD + '  road:\n    - {type: lane_change, '
                               'length: 2.0, offset: 3.5}\n')
    assert 'not both' in _bad(tmp_path, HEAD + '  road:\n    - {type: arc, length: 5, '
                              'curvature: 0.01, lateral_acceleration: 2}\n')
    assert 'min_length goes with time' in _bad(
        tmp_path, HEAD + '  road:\n    - {type: straight, length: 5, min_length: 9}\n')
    assert 'overlaps' in _bad(tmp_path, 'scenario:\n  speed: {initial: 10, phases: ['
                              '{start: 1, duration: 2, acceleration: 1}, {start: 2, '
                              'duration: 1, acceleration: -1}]}\n  road:\n'
                              '    - {type: straight, length: 5}\n')
    assert 'speed.phases[1].acceleration' in _bad(
        tmp_path, 'scenario:\n  speed: {initial: 10, phases: [{start: 1, duration: 2, '
        'acceleration: 1}, {start: 4, duration: 1, acceleration: -9}]}\n  road:\n'
        '    - {type: straight, length: 5}\n')
    assert 'unknown keys' in _bad(tmp_path, HEAD + '  roads: []\n  road:\n'
                                  '    - {type: straight, length: 5}\n')
    assert 'a straight has no' in _bad(tmp_path, HEAD + '  road:\n    - {type: straight, '
                                       'length: 5, curvature: 0.1}\n')


def test_road_batch_gives_each_run_its_road_to_the_bit():
    roads = [_load('s3_s_bend', v).road for v in (12.0, 25.0, 37.0)]
    batch = RoadBatch(roads)
    rng = np.random.default_rng(2)
    s = rng.uniform(-5.0, 900.0, (40, 3))
    rho, slope = batch.curvature(s)
    for n, road in enumerate(roads):
        one = road.curvature(s[:, n])
        assert_array_equal(rho[:, n], one[0])
        assert_array_equal(slope[:, n], one[1])


def test_batch_over_speeds_lays_out_each_run_like_its_single_run():
    scenario = replace(_load('s3_s_bend'), duration=3.0)
    speeds = np.array([15.0, 30.0])
    batch = run(scenario, controller_vehicle(2), ControllerParams(), initial_speed=speeds)
    for i, v in enumerate(speeds):
        single = run(scenario, controller_vehicle(2), ControllerParams(),
                     initial_speed=float(v))
        np.testing.assert_allclose(batch['y_cg'][:, i], single['y_cg'], rtol=1e-12,
                                   atol=1e-15)
        assert_array_equal(batch['rho'][:, i], single['rho'])


def test_centreline_of_a_circle_and_the_projection():
    radius = 250.0
    line = Centreline(Road([Segment('straight', 10.0),
                            Segment('arc', 2000.0, 1.0 / radius, 1.0 / radius)]))
    for s in (10.0, 100.0, 700.0, 1500.0):
        u = s - 10.0
        x, y = line.point(s)
        assert x == pytest.approx(10.0 + radius * math.sin(u / radius), abs=1e-9)
        assert y == pytest.approx(radius * (1.0 - math.cos(u / radius)), abs=1e-9)
    # a point driving exactly on the circle, 1.5 m inside, yawed by a fixed -beta
    for s in np.linspace(20.0, 1500.0, 25):
        pose = line.pose(float(s), 1.5, 0.0)
        lane = line.frenet(pose[0], pose[1], pose[2] + 0.004, float(s) - 3.0)
        assert lane.s == pytest.approx(s, abs=1e-9)
        assert lane.lateral == pytest.approx(1.5, abs=1e-9)
        assert lane.relative_yaw == pytest.approx(0.004, abs=1e-12)
        assert lane.curvature == 1.0 / radius
    assert wrap(3.0 * math.pi) == math.pi and wrap(-0.5) == -0.5


def _steady_cornering(vehicle_id, speed, radius):
    """Linear single-track steady state: (wheel angle, sideslip) for r = v / R."""
    p = commonroad_parameters(vehicle_id)
    a, b, m, r = p.a, p.b, p.m, speed / radius
    stiffness = -p.tire.p_ky1 * m * 9.81 / (a + b)
    c_f, c_r = stiffness * b, stiffness * a
    matrix = np.array([[c_f, -(c_f + c_r)], [a * c_f, -(a * c_f - b * c_r)]])
    rhs = np.array([m * speed * r + (c_f * a - c_r * b) * r / speed,
                    (a * a * c_f + b * b * c_r) * r / speed])
    return np.linalg.solve(matrix, rhs)


def test_commonroad_st_on_a_circle_keeps_lateral_zero_and_steady_relative_yaw():
    speed, radius = 20.0, 200.0
    delta, beta = _steady_cornering(2, speed, radius)
    road = Road([Segment('arc', 3000.0, 1.0 / radius, 1.0 / radius)])
    scenario = Scenario('circle', 5.0, road, SpeedProfile(speed),
                        InitialState(relative_yaw=-beta,
                                     lateral_velocity=speed * math.tan(beta),
                                     yaw_rate=speed / radius))
    plant = CommonRoadPlant(scenario, PlantParams(model='commonroad_st', vehicle_id=2),
                            speed, 0.0)
    plant.state[2] = delta
    for k in range(3000):
        plant.advance(k * 0.001, 0.001, delta)
        if k % 500 == 499:
            (s, y, eps, v_y, r, steer), v_x, rho = plant.contract()
            assert abs(y) < 2e-4 and eps == pytest.approx(-beta, abs=2e-6)
            assert r == pytest.approx(speed / radius, rel=1e-4) and rho == 1.0 / radius
    assert s == pytest.approx(speed * 3.0, rel=1e-3)


class _Sine:
    """Open loop: 0.01 rad at 0.5 Hz, whatever the state."""

    def reset(self):
        self.t = None

    def step(self, state, preview, dt):
        self.t = 0.0 if self.t is None else self.t + dt
        return output(0.01 * math.sin(math.pi * self.t) + 0.0 * state.y_cg)


def test_commonroad_st_matches_the_linear_plant_at_small_slip():
    vehicle = controller_vehicle(2)
    scenario = Scenario('straight', 4.0, Road([Segment('straight', 500.0)]),
                        SpeedProfile(20.0))
    fast = PlantParams(model='commonroad_st', steering_time_constant=0.001,
                       max_steering_rate=20.0)
    cr = run(scenario, vehicle, _Sine(), fast)
    linear = run(scenario, vehicle, _Sine(), PlantParams())
    for name in ('y_cg', 'eps_r', 'v_y', 'r'):
        peak = np.max(np.abs(linear[name]))
        assert np.max(np.abs(cr[name] - linear[name])) < 5e-3 * peak, name


def test_commonroad_plants_close_the_loop_and_refuse_set_4():
    scenario = replace(_load('s2_curve_entry', 25.0), duration=2.0)
    vehicle = controller_vehicle(3)
    st = run(scenario, vehicle, ControllerParams(),
             PlantParams(model='commonroad_st', vehicle_id=3))
    mb = run(scenario, vehicle, ControllerParams(),
             PlantParams(model='commonroad_mb', vehicle_id=3))
    for result in (st, mb):
        assert np.all(np.isfinite(result['y_cg'])) and result['s'][-1] > 45.0
        assert np.max(np.abs(result['y_cg'])) < 0.2
    assert np.max(np.abs(st['eps_r'] - mb['eps_r'])) < 5e-3
    with pytest.raises(ParameterError, match='semi-trailer truck'):
        run(scenario, vehicle, ControllerParams(),
            PlantParams(model='commonroad_st', vehicle_id=4))
    with pytest.raises(ParameterError, match='vehicle_id'):
        PlantParams(vehicle_id=7)


def test_a_diverging_multibody_run_stops_alone_and_the_batch_goes_on():
    # at 37 m/s the swerve spins the car: a rear wheel's speed is clamped to 0 while the
    # car moves and the model divides by it (the crash of `make compare`, issue 13)
    straight = Scenario('straight', 2.5, Road([Segment('straight', 2000.0)]),
                        SpeedProfile(20.0))
    vehicle = controller_vehicle(2)
    mb = PlantParams(model='commonroad_mb', vehicle_id=2)
    batch = run(straight, vehicle, Swerve(), mb, dt=0.002,
                initial_speed=np.array([10.0, 37.0]))
    slow = run(straight, vehicle, Swerve(), mb, dt=0.002, initial_speed=10.0)
    fast = run(straight, vehicle, Swerve(), mb, dt=0.002, initial_speed=37.0)
    assert math.isnan(slow.diverged_at) and math.isnan(batch.diverged_at[0])
    assert 1.0 < fast.diverged_at < 2.5 and batch.diverged_at[1] == fast.diverged_at
    for name, values in batch.channels.items():
        assert_array_equal(values[:, 0], slow[name])       # bit-identical, all finite
        assert np.all(np.isfinite(slow[name])), name
        assert_array_equal(values[:, 1], fast[name])       # NaN == NaN here
        ok = fast.time <= fast.diverged_at
        assert np.all(np.isfinite(fast[name][ok])) and np.all(np.isnan(fast[name][~ok]))


def test_a_plant_that_fails_holds_its_last_state_and_says_why():
    straight = Scenario('straight', 2.5, Road([Segment('straight', 2000.0)]),
                        SpeedProfile(37.0))
    plant = CommonRoadPlant(straight, PlantParams(model='commonroad_mb', vehicle_id=2),
                            37.0, 0.0)
    steps = [plant.advance(0.002 * k, 0.002, 0.3 * math.sin(math.pi * 0.002 * k))
             for k in range(1250)]
    assert plant.diverged_at is not None and not steps[-1] and steps[0]
    assert steps.index(False) == round(plant.diverged_at / 0.002)
    assert plant.failure == 'ZeroDivisionError: float division by zero'
    frozen = list(plant.state)
    assert not plant.advance(3.0, 0.002, 0.0) and plant.state == frozen
    assert all(math.isfinite(v) for v in plant.contract()[0])
