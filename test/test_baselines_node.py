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

"""The ``law`` parameter: the baselines in the controller core and node, one safety layer."""

import math

from conftest import feed
from lookahead_control.core.baselines import baseline_law, BASELINE_NAMES, BaselineParams
from lookahead_control.core.control_law import LateralState
from lookahead_control.core.controller import LAW_NAMES, SteeringController
from lookahead_control.core.laws import Preview
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
from lookahead_control.core.safety import SafetyParams
from lookahead_control.core.samples import (CurvatureSample, LateralErrorSample, VelocitySample,
                                            YawSample)
from lookahead_control.ros import conversions as conv
import numpy as np
import pytest
from rclpy.parameter import Parameter

VEHICLE = VehicleParams()
MS = 1_000_000


def _give(core, stamp, y=0.5, d=1.96, eps=0.01, r=0.02, v_x=25.0, v_y=0.1, rho=-0.0025):
    core.update_yaw(YawSample(stamp, eps, r, 0.0))
    core.update_velocity(VelocitySample(stamp, v_x, v_y))
    core.update_curvature(CurvatureSample(stamp, rho, 0.0))
    core.update_lateral_error(LateralErrorSample(stamp, d, y))
    return core.compute()


@pytest.mark.parametrize('name', BASELINE_NAMES)
def test_core_runs_the_selected_law_on_the_contract_inputs(name):
    core = SteeringController(VEHICLE, ControllerParams(), law=name)
    command = _give(core, 10 * MS)
    # the law straight on the same numbers: y_cg = 0.5 - 1.96 * 0.01, curvature held ahead
    state = LateralState(0.5 - 1.96 * 0.01, 0.01, 0.1, 0.02, 25.0, 0.0, -0.0025, 0.0)
    law = baseline_law(name, VEHICLE, BaselineParams())
    expected = law.step(state, Preview(np.zeros(1), np.array([-0.0025])), 0.0)
    assert core.law_name == name
    assert command.law == expected
    cap = math.atan(core.safety.max_lateral_acceleration * VEHICLE.wheelbase / 25.0 ** 2)
    assert command.steering == pytest.approx(max(-cap, min(cap, float(expected.steering))),
                                             rel=1e-12)


def test_unknown_law_is_refused_and_the_old_one_kept():
    core = SteeringController(VEHICLE, ControllerParams(), law='lqr')
    with pytest.raises(ParameterError, match="law = 'mpc'"):
        core.configure(VEHICLE, ControllerParams(), 'imu', False, law='mpc')
    assert core.law_name == 'lqr'
    with pytest.raises(ParameterError, match='choose one of paper, pure_pursuit'):
        SteeringController(VEHICLE, ControllerParams(), law='')


@pytest.mark.parametrize('first,second', [('paper', 'lqr'), ('lqr', 'pure_pursuit'),
                                          ('stanley', 'paper'), ('pure_pursuit', 'stanley')])
def test_switching_mid_curve_moves_within_the_rate_limit(first, second):
    rate = 0.2
    core = SteeringController(VEHICLE, ControllerParams(), law=first,
                              safety=SafetyParams(max_steering_rate=rate))
    state = {'y': 0.3, 'eps': -0.01, 'r': -0.06, 'v_x': 30.0, 'v_y': 0.3, 'rho': -0.002}
    angles = [_give(core, k * 10 * MS, **state).steering for k in range(300)]
    settled = angles[-1]
    # the new law's own command on these inputs
    target = SteeringController(VEHICLE, ControllerParams(), law=second)
    wanted = _give(target, 0, **state).steering
    assert abs(wanted - settled) > 5 * rate * 0.01        # a real jump is asked for
    core.configure(VEHICLE, ControllerParams(), 'imu', False, law=second)
    after = [_give(core, (300 + k) * 10 * MS, **state) for k in range(200)]
    steps = np.diff([settled] + [c.steering for c in after])
    assert np.all(np.abs(steps) <= rate * 0.01 + 1e-12)
    assert after[0].rate_limited
    assert after[-1].steering == pytest.approx(wanted, abs=1e-12)


@pytest.mark.parametrize('name', LAW_NAMES)
@pytest.mark.parametrize('inputs', [
    {'v_x': 0.0}, {'v_x': 0.5, 'y': 4.9},
    {'y': -4.9, 'eps': 0.99, 'r': 1.9, 'v_y': 9.0, 'v_x': 69.0},
    {'y': 4.9, 'eps': -0.99, 'r': -1.9, 'v_y': -9.0, 'v_x': 2.5}])
def test_edge_inputs_give_a_finite_limited_command(name, inputs):
    core = SteeringController(VEHICLE, ControllerParams(), law=name)
    for k in range(3):
        command = _give(core, k * 10 * MS, **inputs)
        assert math.isfinite(command.steering)
        assert abs(command.steering) <= core.safety.max_steering_angle


def test_node_switches_law_while_active_through_the_rate_limiter(context):
    from lookahead_control.ros.controller_node import ControllerNode
    node = ControllerNode(context=context, parameter_overrides=[
        Parameter('use_sim_time', value=True), Parameter('law', value='stanley'),
        Parameter('safety.max_steering_rate', value=0.5)])
    try:
        node.trigger_configure()
        node.trigger_activate()
        for k in range(1, 200):
            feed(node, k * 10 * MS)
        assert node.core.law_name == 'stanley'
        before = node.core.last.steering
        refused = node.set_parameters([Parameter('law', value='mpc')])[0]
        assert not refused.successful and "'mpc'" in refused.reason
        refused = node.set_parameters_atomically([
            Parameter('pure_pursuit.min_look_ahead', value=30.0),
            Parameter('pure_pursuit.max_look_ahead', value=20.0)])
        assert not refused.successful and 'min_look_ahead' in refused.reason
        refused = node.set_parameters([Parameter('stanley.gain', value=-1.0)])[0]
        assert not refused.successful
        assert node.set_parameters([Parameter('law', value='lqr')])[0].successful
        feed(node, 200 * 10 * MS)
        assert node.core.law_name == 'lqr'
        assert abs(node.core.last.steering - before) <= 0.5 * 0.01 + 1e-12
        # bad data under the new law: refused by the same safety layer, never used
        last = node.core.last
        node.on_yaw(conv.to_yaw(201 * 10 * MS, 'base_link', float('nan'), 0.0, 0.0))
        node.on_lateral_error(conv.to_lateral_error(201 * 10 * MS, 'base_link', 1.96,
                                                    float('nan')))
        assert node.core.last is last
        assert sum(node.core.rejected.values()) == 2
    finally:
        node.destroy_node()


def test_probe71_lqr_weights_without_a_gain_are_refused_not_a_crash(context):
    # dev-probe71: lqr.q_lateral 1e6, r 1e-6, period 1 s were each within range and
    # accepted; the node then built the LQR (law lqr running, or switched to later) and
    # died in the Riccati solver (LinAlgError: Singular matrix), the last command held
    from lookahead_control.core.baselines import gain_table, LqrParams
    with pytest.raises(ValueError, match='lqr.q_lateral = 1e.06.*r = 1e-06, period = 1: '
                       'no LQR gain at 11 m/s'):
        gain_table(VEHICLE, LqrParams(q_lateral=1e6, r=1e-6, period=1.0))
    from lookahead_control.ros.controller_node import ControllerNode
    for law in ('lqr', 'cg_compensated'):
        node = ControllerNode(context=context, parameter_overrides=[
            Parameter('use_sim_time', value=True), Parameter('law', value=law)])
        try:
            node.trigger_configure()
            node.trigger_activate()
            for k in range(1, 50):
                feed(node, k * 10 * MS)
            for params in ([Parameter('lqr.q_lateral', value=1e6),
                            Parameter('lqr.r', value=1e-6), Parameter('lqr.period', value=1.0)],
                           [Parameter('lqr.q_lateral', value=1e-6),
                            Parameter('lqr.q_heading', value=1e6), Parameter('lqr.r', value=1e-6),
                            Parameter('lqr.period', value=1.0)]):
                refused = node.set_parameters_atomically(params)
                assert not refused.successful and 'no LQR gain' in refused.reason, \
                    (params, refused.reason)
            # one at a time: the last one that would leave no gain is refused
            assert node.set_parameters([Parameter('lqr.q_lateral', value=1e6)])[0].successful
            assert node.set_parameters([Parameter('lqr.r', value=1e-6)])[0].successful
            refused = node.set_parameters([Parameter('lqr.period', value=1.0)])[0]
            assert not refused.successful and 'no LQR gain' in refused.reason
            if law == 'cg_compensated':     # the LQR's weights are checked while it waits
                refused = node.set_parameters([Parameter('law', value='lqr'),
                                               Parameter('lqr.period', value=1.0)])
                assert refused[0].successful and not refused[1].successful
                assert node.core.law_name == 'lqr'
            feed(node, 50 * 10 * MS)
            assert math.isfinite(node.core.last.steering)
            assert node.get_parameter('lqr.period').value == 0.01
        finally:
            node.destroy_node()


def test_params_file_has_every_declared_baseline_parameter():
    import yaml
    from lookahead_control.ros.node_params import BASELINE_SPECS, LAW_SPEC
    from pathlib import Path
    document = yaml.safe_load((Path(__file__).resolve().parents[1] / 'config'
                               / 'controller.yaml').read_text())['/**']['ros__parameters']
    assert document['law'] == LAW_SPEC.default
    for spec in BASELINE_SPECS:
        group, name = spec.name.split('.')
        assert document[group][name] == spec.default, spec.name
    # and the dataclass defaults are the declared ones
    defaults = BaselineParams()
    for spec in BASELINE_SPECS:
        group, name = spec.name.split('.')
        assert getattr(getattr(defaults, group), name) == spec.default, spec.name
