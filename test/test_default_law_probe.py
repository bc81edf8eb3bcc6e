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
Probe of the default law (dev-probe16): a hostile new user's findings, one test each.

Each test fails on the code before its fix (named in the test).
"""

from lookahead_control.core.control_law import LateralState
from lookahead_control.core.lane_keeping import CgCompensatedLaw, LaneKeepingParams
from lookahead_control.core.params import ControllerParams, VehicleParams
from lookahead_control.ros import conversions as conv
import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.time import Time

VEHICLE = VehicleParams()


def _cornering(v_x, rho):
    """Return the steady (v_y, r) of the linear single-track model on an arc, by hand."""
    r = v_x * rho
    alpha_r = VEHICLE.mass * VEHICLE.l1 / (VEHICLE.c_r * VEHICLE.wheelbase) * v_x * r
    return VEHICLE.l2 * r - v_x * alpha_r, r


@pytest.mark.parametrize('state_filter', ['kalman', 'none'])
def test_a_speed_read_as_zero_for_a_moment_does_not_poison_the_compliance(state_filter):
    # a wheel-speed dropout: v_x read as 0 for 0.5 s in a R = 400 m curve at 37 m/s, the
    # other signals right. Old code: the estimator's signal filters ran on during it with
    # the rear slip (l_2 r - v_y) / max(v_x, 1) 37 times too large, and learning resumed
    # with that in them: the compliance went to its clip (3.4 x), which put the CG of the
    # nonlinear plant 1.2 m off after the dropout (paper law: 0.05 m)
    v_x, rho = 37.0, -1.0 / 400.0
    v_y, r = _cornering(v_x, rho)
    law = CgCompensatedLaw(VEHICLE, ControllerParams(),
                           LaneKeepingParams(state_filter=state_filter))

    def drive(speed, steps):
        for _ in range(steps):
            law.step(LateralState(0.0, 0.0, v_y, r, speed, 0.0, rho, 0.0), None, 0.01)
        return float(law.compliance())

    learned = drive(v_x, 200)
    drive(0.0, 50)
    after = [drive(v_x, 1) for _ in range(200)]
    assert max(after) == pytest.approx(learned, rel=0.02)
    assert min(after) == pytest.approx(learned, rel=0.02)


def test_a_speed_dropout_in_one_run_of_a_batch_restarts_only_its_filters():
    v_x, rho = 37.0, -1.0 / 400.0
    v_y, r = _cornering(v_x, rho)
    single = CgCompensatedLaw(VEHICLE, ControllerParams(), LaneKeepingParams())
    batch = CgCompensatedLaw(VEHICLE, ControllerParams(), LaneKeepingParams())
    for k in range(300):
        dropout = 200 <= k < 250
        speed = 0.0 if dropout else v_x
        one = single.step(LateralState(0.0, 0.0, v_y, r, speed, 0.0, rho, 0.0), None, 0.01)
        speeds = np.array([speed, v_x])
        both = batch.step(LateralState(np.zeros(2), np.zeros(2), np.full(2, v_y),
                                       np.full(2, r), speeds, np.zeros(2), np.full(2, rho),
                                       np.zeros(2)), None, 0.01)
        assert both.steering[0] == one.steering
    assert batch.compliance()[0] == single.compliance()


def _launch_arguments():
    """Return the closed-loop launch file's argument defaults and the controller's keys."""
    import ast
    from pathlib import Path
    tree = ast.parse((Path(__file__).resolve().parent.parent / 'launch'
                      / 'closed_loop.launch.py').read_text(encoding='utf-8'))
    args: dict = {}
    keys: set = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and getattr(node.targets[0], 'id', '') == 'args':
            args = {k.value: v.value for k, v in zip(node.value.keys, node.value.values)
                    if isinstance(v, ast.Constant)}
        if isinstance(node, ast.Dict):
            names = {k.value for k in node.keys if isinstance(k, ast.Constant)}
            if 'controller.schedule' in names:      # the controller's overrides
                keys |= names
    return args, keys


def test_the_launch_file_runs_the_law_closed_loop_runs(monkeypatch):
    # old launch file: no law argument, so it ran config/controller.yaml's law
    # (cg_compensated) while closed_loop, which the contract says it does the same as,
    # runs law paper (--law, default paper); the user could not choose the law
    from lookahead_control.ros import closed_loop
    seen = []
    monkeypatch.setattr(closed_loop, 'run_loop', lambda cfg: seen.append(cfg) or 0)
    assert closed_loop.main(['--no-record']) == 0
    cfg, = seen
    args, keys = _launch_arguments()
    assert args.get('law') == cfg.law == 'paper'
    assert (args['schedule'], args['mode'], args['plant'], float(args['speed'])) == (
        cfg.schedule, cfg.mode, cfg.plant, cfg.speed)
    assert 'law' in keys            # handed to the controller


MS = 1_000_000
S = 1_000_000_000


def _default_node(context, *overrides):
    """Return an active controller with the default law on a fake sim clock."""
    from lookahead_control.ros.controller_node import ControllerNode
    node = ControllerNode(context=context, parameter_overrides=[
        Parameter('use_sim_time', value=True), *overrides])
    node.trigger_configure()
    node.trigger_activate()
    return node


def _send(node, stamp, y=0.3, rho=-0.0025, v_x=30.0, points=None):
    node.get_clock().set_ros_time_override(Time(nanoseconds=stamp))
    node.on_yaw(conv.to_yaw(stamp, 'base_link', 0.0, v_x * rho, 0.0))
    node.on_velocity(conv.to_velocity(stamp, 'base_link', v_x, 0.0, 0.0))
    if points is not False:
        node.on_curvature(conv.to_curvature(stamp, 'base_link',
                                            points or [(0.0, rho), (5.0, rho)]))
    node.on_lateral_error(conv.to_lateral_error(stamp, 'base_link', VEHICLE.d_s, y))
    return node.core.last


def test_the_paper_gains_neither_tune_nor_restart_the_default_law(context):
    # old code: controller.natural_frequency / damping_ratio described as "the
    # look-ahead error loop" with no word that law cg_compensated (the default) ignores
    # them, and setting one threw away its integral, estimate and filter for nothing
    node = _default_node(context)
    try:
        for name in ('controller.natural_frequency', 'controller.damping_ratio'):
            text = node.describe_parameter(name).description
            assert 'law paper' in text and 'lane_keeping.' in text
        stamp = 100 * S
        for _ in range(200):
            stamp += 10 * MS
            _send(node, stamp)
        law, integral = node.core.law, node.core.law.integral
        assert node.core.law_name == 'cg_compensated' and integral > 0.05
        assert node.set_parameters([Parameter('controller.natural_frequency',
                                              value=5.0)])[0].successful
        stamp += 10 * MS
        _send(node, stamp)
        assert node.core.law is law and law.integral > integral
        assert node.set_parameters([Parameter('lane_keeping.natural_frequency',
                                              value=6.0)])[0].successful
        assert node.core.law is not law
        # the paper law does take them
        assert node.set_parameters([Parameter('law', value='paper')])[0].successful
        paper = node.core.law
        assert node.set_parameters([Parameter('controller.natural_frequency',
                                              value=4.0)])[0].successful
        assert node.core.law is not paper and node.core.law.controller.k_p == 16.0
    finally:
        node.destroy_node()
