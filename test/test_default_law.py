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
The controller's default law: ``cg_compensated`` with its state filter.

What ``ros2 run lookahead_control controller`` runs with no parameter file, and what the
shipped ``config/controller.yaml`` selects; on the issue's highway curve the law the
node builds keeps the CG on the lane, where the paper's law (the old default) rides a
metre outside it.
"""

from pathlib import Path

from lookahead_control.core.lane_keeping import CgCompensatedLaw
from lookahead_control.core.params import VehicleParams
import numpy as np
from rclpy.parameter import Parameter
from sim_plant.closed_loop_sim import run
from sim_plant.vehicle_model import PlantParams
import yaml

ROOT = Path(__file__).resolve().parent.parent


def _law(context, *overrides):
    """Return the law a configured controller node built from its parameters."""
    from lookahead_control.ros.controller_node import ControllerNode
    node = ControllerNode(context=context, parameter_overrides=list(overrides))
    try:
        node.trigger_configure()
        return node.core.law_name, node.core.law
    finally:
        node.destroy_node()


def test_a_node_with_no_law_parameter_runs_cg_compensated_with_its_filter(context):
    name, law = _law(context)
    assert name == 'cg_compensated'
    assert isinstance(law, CgCompensatedLaw) and law.state_filter is not None


def test_the_shipped_params_file_selects_the_default_law():
    params = yaml.safe_load((ROOT / 'config' / 'controller.yaml').read_text())
    assert params['/**']['ros__parameters']['law'] == 'cg_compensated'


def test_the_default_law_keeps_the_cg_on_a_highway_curve_where_the_paper_law_does_not(
        context):
    # S2 (clothoid into R = 400 m) at 37 m/s on the nonlinear (Fiala) plant with 20 ms
    # transport delay, ideal sensors, the laws exactly as the node builds them
    from lookahead_control.tools.compare import load_scenarios
    scenario = load_scenarios(['s2_curve_entry'])['s2_curve_entry']

    def drive(law):
        result = run(scenario, VehicleParams(), law, PlantParams(model='nonlinear'),
                     initial_speed=37.0, dt=0.005, delay=0.02, preview_distance=100.0)
        return np.abs(result['y_cg'])

    default = drive(_law(context)[1])
    assert default.max() < 0.04 and default[-1] < 0.005
    old_name, old = _law(context, Parameter('law', value='paper'))
    assert old_name == 'paper'
    assert drive(old)[-1] > 0.5
