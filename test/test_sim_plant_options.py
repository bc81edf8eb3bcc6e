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

"""The sim_plant node's delay, noise, mismatch and CommonRoad options against the runner."""

from dataclasses import replace
import math
from pathlib import Path

from lookahead_control.core.control_law import cg_error_from, LateralState, steering_law
from lookahead_control.core.params import ControllerParams, VehicleParams
from lookahead_control.ros import conversions as conv
import numpy as np
import pytest
from rclpy.parameter import Parameter
from sim_plant.closed_loop_sim import run
from sim_plant.scenario import load_scenario
from sim_plant.sensors import NoiseParams
from sim_plant.vehicle_model import PlantParams

SCENARIO = Path(__file__).resolve().parent.parent / 'config' / 'scenarios' / 'paper_r400.yaml'
VEHICLE = VehicleParams()
CONTROLLER = ControllerParams()


def _drive(context, steps, **params):
    """Run the node's step loop with the core law in place of the controller node."""
    from sim_plant.sim_plant_node import SimPlantNode
    node = SimPlantNode(context=context, parameter_overrides=[
        Parameter(name, value=value) for name, value in {'speed': 25.0, **params}.items()])
    sent = {}
    for attr in ('pub_lateral', 'pub_yaw', 'pub_velocity', 'pub_curvature'):
        getattr(node, attr).publish = (lambda a: (lambda msg: sent.__setitem__(a, msg)))(attr)
    y_cg, messages = [], []
    try:
        for _ in range(steps):
            node.publish_measurements()
            lateral = conv.from_lateral_error(sent['pub_lateral'])
            yaw = conv.from_yaw(sent['pub_yaw'])
            velocity = conv.from_velocity(sent['pub_velocity'])
            messages.append((lateral.value, yaw.relative_yaw, velocity.v_y, yaw.yaw_rate))
            rho = node.scenario.road.curvature(float(node.x[0]))[0]
            state = LateralState(cg_error_from(lateral.value, yaw.relative_yaw,
                                               lateral.distance),
                                 yaw.relative_yaw, velocity.v_y, yaw.yaw_rate,
                                 velocity.v_x, 0.0, rho, 0.0)
            y_cg.append(float(node.x[1]))
            node.command = float(steering_law(state, VEHICLE, CONTROLLER).steering)
            node.integrate()
    finally:
        node.destroy_node()
    return np.array(y_cg), np.array(messages)


@pytest.mark.parametrize('model', ['linear', 'nonlinear'])
def test_node_with_delay_noise_and_mismatch_runs_as_the_offline_runner(context, model):
    steps = 250
    y_node, _ = _drive(context, steps, **{'plant.model': model, 'plant.delay': 0.023,
                                          'plant.mass_scale': 1.15,
                                          'plant.cornering_scale': 0.8,
                                          'noise.enabled': True, 'noise.seed': 7})
    scenario = replace(load_scenario(SCENARIO, 25.0), duration=(steps - 1) * 0.01)
    body = replace(VEHICLE, mass=VEHICLE.mass * 1.15, c_f=VEHICLE.c_f * 0.8,
                   c_r=VEHICLE.c_r * 0.8)
    offline = run(scenario, VEHICLE, CONTROLLER, PlantParams(model=model),
                  plant_vehicle=body, delay=0.023, noise=NoiseParams(), seed=7)
    # the relative yaw crosses the Imu quaternion (atan2 of a half-angle rotation): a
    # last-bit difference there is all that may differ
    np.testing.assert_allclose(y_node, offline['y_cg'], rtol=0, atol=1e-9)
    assert np.max(np.abs(y_node)) > 0.05            # it went into the curve


def test_node_noise_repeats_with_its_seed(context):
    _, a = _drive(context, 30, **{'noise.enabled': True, 'noise.seed': 3})
    _, b = _drive(context, 30, **{'noise.enabled': True, 'noise.seed': 3})
    _, c = _drive(context, 30, **{'noise.enabled': True, 'noise.seed': 4})
    _, clean = _drive(context, 30)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    spread = np.std(a - clean, axis=0)
    assert 0.015 < spread[0] < 0.05 and 0.001 < spread[1] < 0.004


def test_node_drives_a_commonroad_plant(context):
    y, _ = _drive(context, 120, **{'plant.model': 'commonroad_st', 'plant.vehicle_id': 2})
    assert np.all(np.isfinite(y)) and np.max(np.abs(y)) < 1.5


def _with_forces(tmp_path, name, forces):
    """Write paper_r400 with ``forces`` as its external_forces; return its path."""
    from lookahead_control.core.config import read_yaml
    import yaml
    document = read_yaml(SCENARIO)
    document['scenario']['external_forces'] = forces
    path = tmp_path / f'{name}.yaml'
    path.write_text(yaml.safe_dump(document))
    return path


def _windy(tmp_path):
    """Write paper_r400 with a crosswind from 0.5 s and a gust from 1 s; return its path."""
    return _with_forces(tmp_path, 'windy', [
        {'start': 0.5, 'force': 1500.0, 'moment': -200.0},
        {'start': 1.0, 'duration': 1.0, 'force': 800.0, 'frequency': 1.5}])


@pytest.mark.parametrize('model', ['linear', 'nonlinear'])
def test_node_pushes_the_car_with_the_scenarios_forces_as_the_offline_runner(
        context, tmp_path, model):
    # dev-sc37: the simulator node had no side force (only the offline runner took one)
    path = _windy(tmp_path)
    steps = 250
    options = {'plant.model': model, 'plant.delay': 0.02, 'scenario_file': str(path)}
    y_node, _ = _drive(context, steps, **options)
    y_calm, _ = _drive(context, steps, **{**options, 'scenario_file': str(SCENARIO)})
    scenario = replace(load_scenario(path, 25.0), duration=(steps - 1) * 0.01)
    offline = run(scenario, VEHICLE, CONTROLLER, PlantParams(model=model), delay=0.02)
    np.testing.assert_allclose(y_node, offline['y_cg'], rtol=0, atol=1e-9)
    assert np.max(np.abs(y_node - y_calm)) > 0.02


def test_node_pushes_a_commonroad_car_and_its_ground_truth_says_with_what(context, tmp_path):
    from sim_plant.sim_plant_node import GROUND_TRUTH, SimPlantNode
    path = _windy(tmp_path)
    options = {'plant.model': 'commonroad_st', 'plant.vehicle_id': 2}
    y_wind, _ = _drive(context, 150, **options, scenario_file=str(path))
    y_calm, _ = _drive(context, 150, **options)
    assert np.all(np.isfinite(y_wind)) and np.max(np.abs(y_wind - y_calm)) > 0.01
    node = SimPlantNode(context=context, parameter_overrides=[
        Parameter('scenario_file', value=str(path))])
    truth = []
    try:
        node.pub_truth.get_subscription_count = lambda: 1      # as if a recorder listened
        node.pub_truth.publish = truth.append
        for k in (0, 120, 150):
            node.k = k
            node.publish_measurements()
    finally:
        node.destroy_node()
    rows = [dict(zip(msg.name, msg.position)) for msg in truth]
    assert list(truth[0].name) == list(GROUND_TRUTH)
    # the mean over the period's ten plant steps of 1 ms (each holds its start's value)
    expected = [(0.0, 0.0)] + [
        (1500.0 + 80.0 * sum(math.sin(2 * math.pi * 1.5 * (t + 0.001 * j)) for j in range(10)),
         -200.0) for t in (0.2, 0.5)]
    for row, (force, moment) in zip(rows, expected):
        assert row['external_force'] == pytest.approx(force, abs=1e-6)
        assert row['external_moment'] == moment


def test_node_ground_truth_gives_a_gust_shorter_than_a_period_as_its_impulse(
        context, tmp_path):
    # dev-probe80: a 20 kN gust of 3 ms between two 10 ms rows read -416 N in the bag
    # while it moved v_y by 0.04 m/s: the truth sampled the force once per period
    from sim_plant.sim_plant_node import SimPlantNode
    path = _with_forces(tmp_path, 'gust', [{'start': 1.005, 'duration': 0.003,
                                            'force': 20000.0}])
    node = SimPlantNode(context=context, parameter_overrides=[
        Parameter('scenario_file', value=str(path))])
    try:
        forces = [node.mean_external(k * 0.01)[0] for k in range(98, 103)]
    finally:
        node.destroy_node()
    assert forces == pytest.approx([0.0, 0.0, 6000.0, 0.0, 0.0])


def test_node_refuses_a_force_its_plant_step_cannot_give(tmp_path):
    from lookahead_control.core.params import ParameterError
    from sim_plant.sim_plant_node import ALL_SPECS, check_parameters
    path = _with_forces(tmp_path, 'buzz', [{'start': 1.0, 'force': 100.0,
                                            'frequency': 10.0}])
    params = {spec.name: spec.default for spec in ALL_SPECS}
    params.update({'scenario_file': str(path), 'dt': 0.01})
    with pytest.raises(ParameterError, match=r'buzz\.yaml with dt = 0\.01 s: external_forces'
                       r'\[0\]\.frequency = 10 Hz needs at least 20 plant steps'):
        check_parameters(params)
    params['dt'] = 0.001
    assert check_parameters(params).scenario.forces[0].frequency == 10.0


def test_a_preview_longer_than_the_controller_takes_is_refused():
    # dev-probe94: as path_bridge's, sim_plant's preview of 1000 m at 0.1 m went out as
    # 10001 points a message, every one refused by the controller (256 by default)
    from lookahead_control.core.params import ParameterError
    from sim_plant.sim_plant_node import ALL_SPECS, check_parameters
    params = {spec.name: spec.default for spec in ALL_SPECS}
    params.update({'preview_distance': 1000.0, 'preview_step': 0.1})
    with pytest.raises(ParameterError, match='gives 10001 curvature points a message, more '
                       'than max_preview_points = 256'):
        check_parameters(params)
    params['max_preview_points'] = 10001
    check_parameters(params)


def _until_diverged(context, tmp_path, speed, force, steps, **params):
    """
    Integrate a straight at ``speed`` pushed by ``force`` from 1 s until the plant fails.

    :return: the node's failure text (its done check raises it, checked here).
    """
    from lookahead_control.core.params import ParameterError
    from sim_plant.sim_plant_node import finished, SimPlantNode
    path = tmp_path / 'push.yaml'
    path.write_text(f'scenario:\n  name: push\n  duration: 4.0\n  speed: {{initial: {speed}}}\n'
                    '  road:\n    - {type: straight, length: 500.0}\n'
                    f'  external_forces:\n    - {{start: 1.0, force: {force}}}\n')
    node = SimPlantNode(context=context, parameter_overrides=[
        Parameter('scenario_file', value=str(path)),
        *(Parameter(name, value=value) for name, value in params.items())])
    try:
        for _ in range(steps):
            node.integrate()                # raised ParameterError here (a callback)
            if node.failure:
                break
        with pytest.raises(ParameterError, match='diverged'):
            finished(node)
        return node.failure
    finally:
        node.destroy_node()


def test_a_diverged_plant_stops_the_node_with_one_line_not_from_a_callback(context, tmp_path):
    # dev-probe80: 50 kN on the multi-body car made it diverge at 1.38 s; the node raised
    # inside the steering callback, and rclpy logged FATAL with its stack before the line
    failure = _until_diverged(context, tmp_path, 37.0, 50000.0, 400,
                              **{'plant.model': 'commonroad_mb', 'dt': 0.002})
    assert failure.startswith('the commonroad_mb plant diverged at t = ')
    assert "under the scenario's external_forces" in failure


def test_a_diverged_linear_plant_stops_the_node_too(context, tmp_path):
    # dev-probe81: at 0.05 m/s a 1.5 kN force blew the (stiff) linear plant up, |v_y|
    # 1e111; every input was refused and the run went on to rc 0 at its deadlines
    failure = _until_diverged(context, tmp_path, 0.05, 1500.0, 300, dt=0.005)
    assert failure.startswith('the linear plant diverged between t = 1.')
    assert "under the scenario's external_forces (a non-finite state)" in failure


def test_a_command_beyond_the_wheel_s_limit_is_counted_and_said(context):
    # dev-probe92: the linear plant integrated 9.9 rad (a yaw rate of 75 rad/s, the car
    # 49 m off) without a word. It has no actuator (the paper's model) and applies what
    # it is sent (dev-probe94: clipping it changed runs with a controller limit above
    # 0.6 rad); a command beyond plant.max_steering_angle is counted and said, and a
    # refusal is said at once even right after such a warning
    from sim_plant.sim_plant_node import SimPlantNode
    node = SimPlantNode(context=context, parameter_overrides=[
        Parameter('speed', value=25.0), Parameter('mode', value='realtime')])
    logged = []
    logger = node.get_logger()
    warn, error = logger.warn, logger.error
    logger.warn = lambda text, **kw: (logged.append(text), warn(text, **kw))[1]
    logger.error = lambda text, **kw: (logged.append(text), error(text, **kw))[1]
    try:
        assert node.plant.model == 'linear' and node.plant.max_steering_angle == 0.6
        for k, angle in enumerate((0.3, 9.9, float('nan'), -0.7, 12.0)):
            node.on_steering(conv.to_steering(k * 10_000_000, angle, 0.0))
        assert node.command == -0.7 and (node.beyond, node.rejected) == (2, 2)
        assert logged[0] == ('steering +9.9000 rad for t = 0.01 s beyond '
                             'plant.max_steering_angle 0.6 rad: applied as sent: the linear '
                             'plant has no actuator (1 beyond)')
        assert logged[1].startswith('steering nan rad for t = 0.02 s refused'), logged
        assert len(logged) == 2                               # each kind throttled
        assert '2 rejected commands, 2 beyond plant.max_steering_angle' in node.summary()
    finally:
        node.destroy_node()
