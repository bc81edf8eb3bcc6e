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

"""A hostile user's probe of lane_keeping.exact_inverse (dev-exactinv): what it found."""

from __future__ import annotations

import json

from lookahead_control.core.control_law import LateralState
from lookahead_control.core.lane_keeping import CgCompensatedLaw, LaneKeepingParams
from lookahead_control.core.laws import Preview
from lookahead_control.core.params import ControllerParams, VehicleParams
import numpy as np

VEHICLE = VehicleParams()
DISTANCES = np.arange(0.0, 101.0, 5.0)


def _clothoid_inverse(damping, jerk=1.0, v=37.0, steps=500):
    """Return the law's exact-inverse relative yaw along a clothoid of this lateral jerk."""
    law = CgCompensatedLaw(VEHICLE, ControllerParams(), LaneKeepingParams(
        exact_inverse=1.0, exact_inverse_damping=damping, state_filter='none',
        compliance_time_constant=0.0, integral_gain=0.0))
    rate = jerk / (v * v)                       # curvature per second
    eps = []
    for k in range(steps):
        rho = rate * k * 0.01
        state = LateralState(y_cg=0.0, eps_r=0.0, v_y=0.0, r=v * rho, v_x=v, rho=rho,
                             rho_rate=rate, a_x=0.0)
        law.step(state, Preview(DISTANCES, rho + rate * DISTANCES / v), 0.01)
        eps.append(float(law._inverse[0]))
    return np.array(eps)


def test_the_added_damping_leaves_the_first_order_inverse_alone_under_load():
    # exact_inverse_damping acts on eps' - eps_ss'; the model's forcing (c(a) v^2 - l_2)
    # rho moves with the tangent compliance of the brush tyre (design_friction 1, the
    # default), and eps_ss' was formed with the secant one: on a 1 m/s^3 clothoid at
    # 37 m/s the damped model drifted from the undamped one, 0.34 mrad 5 s in (5 m/s^2;
    # 1.4 cm of y_ref with d_v 40 m); with the tangent 0.015 mrad, the second-order term
    own, damped = _clothoid_inverse(0.0), _clothoid_inverse(0.7)
    assert abs(own[-1] - damped[-1]) < 5e-5, own[-1] - damped[-1]
    assert abs(own[-1]) > 0.03                          # the curve is there


def test_lane_keeping_stability_says_the_estimated_rows_leave_the_exact_inverse_out(
        tmp_path, capsys):
    # without road_curvature the exact inverse's model runs along the filter's curvature
    # estimate (a state of the loop), while the sampled check's "curvature estimated"
    # rows take the law's terms in the estimate as static gains: before, the tool said
    # "with the curvature estimated HOLDS" for a file with exact_inverse 0.5 (the same
    # numbers as for 0) without a word that the model's dynamics were not in that loop
    from lookahead_control.core.cli import run_tool
    from lookahead_control.tools import lane_keeping_tool
    params = tmp_path / 'controller.yaml'
    params.write_text('/**:\n  ros__parameters:\n    lane_keeping:\n'
                      '      exact_inverse: 0.5\n')
    report = tmp_path / 'stability.json'
    run_tool(lane_keeping_tool.stability_main, ['--samples', '3', '--controller',
                                                str(params), '--json', str(report)])
    out = capsys.readouterr().out
    assert ('lane_keeping.exact_inverse = 0.5: with road_curvature its model is an '
            'exogenous reference') in out
    assert "leave out its model's dynamics along the estimate: that loop is not checked" \
        in out
    assert 'with the curvature estimated HOLDS (without the exact inverse)' in out
    assert len(json.loads(report.read_text())['notes']) == 1
    assert lane_keeping_tool.exact_inverse_notes(LaneKeepingParams()) == []
