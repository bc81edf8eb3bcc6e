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
How far the loop through path_bridge may differ from the direct loop, derived (no ROS).

The paper road steps from curvature 0 to -1/400 at s = 74 m, which the CG reaches exactly
at the sample t = 2.00 s. The direct simulator reads the curvature there one-sided (the
arc's, held for the whole period); the bridge's fit, centred, gives half of it (the fit
never overshoots, test_core_path_geometry). So at that sample the steering differs by
g d_rho / 2, g = d steering / d rho of the law (8.0 rad m at 37 m/s): 0.0100 rad, and the
lateral error by the closed loop's response to that one-period pulse. Away from the
step the inputs differ by the fit's bias only (3 h^4 / (280 R^3) = 3.5e-8 m at h = 5 m).
"""

from pathlib import Path

from bridge_loop import bridge_loop
from lookahead_control.core.control_law import LateralState, steering_law
from lookahead_control.core.params import ControllerParams, VehicleParams
import numpy as np
import pytest
from sim_plant.scenario import load_scenario

SCENARIO = Path(__file__).resolve().parent.parent / 'config' / 'scenarios' / 'paper_r400.yaml'
SPEED, STEP_K, D_RHO = 37.0, 200, -1.0 / 400.0


def junction_tolerances(direct):
    """Return (steering pulse at the step, peak y_cg response to it) for the paper road."""
    _, _, y0, _ = direct

    def law(rho):
        state = LateralState(float(y0[STEP_K]), 0.0, 0.0, 0.0, SPEED, 0.0, rho, 0.0)
        return steering_law(state, VehicleParams(), ControllerParams()).steering

    gain = (law(D_RHO) - law(0.0)) / D_RHO
    pulse = abs(gain * D_RHO) / 2.0
    scenario = load_scenario(SCENARIO, SPEED)
    _, _, y_pulsed, _ = bridge_loop(scenario, direct=True, pulse=(STEP_K, pulse))
    return pulse, float(np.max(np.abs(y_pulsed - y0)))


@pytest.fixture(scope='module')
def direct():
    return bridge_loop(load_scenario(SCENARIO, SPEED), direct=True)


def test_the_direct_core_loop_is_the_offline_runner(direct):
    from sim_plant.closed_loop_sim import run
    offline = run(load_scenario(SCENARIO, SPEED), VehicleParams(), ControllerParams())
    steering = direct[1]
    assert np.max(np.abs(steering - offline['steering_cmd'][:steering.size])) < 1e-9


@pytest.mark.parametrize('spacing, half_window', [(1.0, 5.0), (0.25, 1.0)])
def test_the_bridged_loop_differs_only_by_the_sampled_curvature_step(direct, spacing,
                                                                     half_window):
    stamps, d0, y0, _ = direct
    _, d1, y1, lateral = bridge_loop(load_scenario(SCENARIO, SPEED), spacing, half_window)
    pulse, y_bound = junction_tolerances(direct)
    assert pulse == pytest.approx(0.0100, abs=1e-4)
    # before the fit window reaches the step: the fit's bias only
    before = stamps * 1e-9 < 2.0 - (half_window + spacing) / SPEED
    assert np.max(np.abs(d1 - d0)[before]) < 1e-7
    assert np.max(np.abs(y1 - y0)[before]) < 1e-7
    assert np.max(np.abs(lateral - y1)[before]) < 1e-7
    # at the step: half of it (and the rounding over +- h around it)
    assert 0.9 * pulse <= abs(d1[STEP_K] - d0[STEP_K]) <= 2.0 * pulse
    assert np.max(np.abs(d1 - d0)) <= 2.0 * pulse
    # the lateral error: no more than the loop's response to that pulse
    assert np.max(np.abs(y1 - y0)) <= y_bound
    assert y_bound < 0.0075
