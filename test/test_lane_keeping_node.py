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


"""The controller node with reference cg_compensated: parameters, law, resets (no DDS)."""

from conftest import feed
from lookahead_control.core.lane_keeping import CgCompensatedLaw, LaneKeepingParams
import pytest
from rclpy.parameter import Parameter

MS = 1_000_000


def _feed(node, stamp, y=0.1, v_x=30.0, rho=-0.0025):
    # straight and level apart from the lateral error (no yaw, no v_y, d = 0)
    feed(node, stamp, y=y, d=0.0, eps=0.0, r=0.0, v_x=v_x, v_y=0.0, rho=rho)


def test_node_selects_the_lane_keeping_law_by_parameter(context):
    from lookahead_control.ros.controller_node import ControllerNode
    node = ControllerNode(context=context, parameter_overrides=[
        Parameter('use_sim_time', value=True), Parameter('law', value='cg_compensated'),
        Parameter('lane_keeping.integral_gain', value=0.5),
        Parameter('lane_keeping.state_filter', value='none')])
    try:
        node.trigger_configure()
        node.trigger_activate()
        law = node.core.law
        assert isinstance(law, CgCompensatedLaw)
        assert law.settings == LaneKeepingParams(integral_gain=0.5, state_filter='none')
        assert law.state_filter is None
        for k in range(11):
            _feed(node, (1000 + 10 * k) * MS)
        assert law.integral == pytest.approx(0.5 * 0.1 * 0.1)
        refused = node.set_parameters([Parameter('lane_keeping.low_speed_frequency',
                                                 value=50.0)])[0]
        assert not refused.successful and 'low_speed_frequency' in refused.reason
        refused = node.set_parameters([Parameter('lane_keeping.max_gap', value=0.0)])[0]
        assert not refused.successful
        ok = node.set_parameters([Parameter('law', value='paper')])[0]
        assert ok.successful
        _feed(node, 1200 * MS)             # applied between two control steps
        assert node.core.law_name == 'paper' and node.core.last.law.y_ref == 0.0
    finally:
        node.destroy_node()


def test_the_applied_parameters_log_names_the_running_law_s_gains():
    # probe20: the log printed the paper law's w_n = 3 while cg_compensated ran (7)
    from lookahead_control.core.lane_keeping import LaneKeepingParams
    from lookahead_control.core.params import ControllerParams
    from lookahead_control.ros.controller_node import applied_summary
    controller, lane_keeping = ControllerParams(), LaneKeepingParams()
    assert controller.natural_frequency != lane_keeping.natural_frequency
    line = applied_summary('cg_compensated', controller, lane_keeping)
    assert f'w_n={lane_keeping.natural_frequency:g}, zeta={lane_keeping.damping_ratio:g}' \
        in line, line
    line = applied_summary('paper', controller, lane_keeping)
    assert f'w_n={controller.natural_frequency:g}, zeta={controller.damping_ratio:g}' in line
