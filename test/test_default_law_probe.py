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
import numpy as np
import pytest

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
