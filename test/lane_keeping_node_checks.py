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

"""A check shared by the tests of the law's options: the node takes one at run time."""

from __future__ import annotations

from typing import Any


def check_run_time_parameter(context: Any, name: str, top: float, words: str, good: float,
                             bad: float) -> None:
    """
    Check that the controller node declares, takes and refuses ``lane_keeping.<name>``.

    :param context: an initialized rclpy context.
    :param name: the field of ``LaneKeepingParams``.
    :param top: the descriptor's upper bound.
    :param words: text the descriptor's description must contain.
    :param good: a value the node must take (it reaches the law's settings).
    :param bad: a value the node must refuse (the value taken stays).
    """
    from lookahead_control.ros.controller_node import ControllerNode
    from rclpy.parameter import Parameter
    full = f'lane_keeping.{name}'
    node = ControllerNode(context=context)
    try:
        descriptor = node.describe_parameters([full])[0]
        assert descriptor.floating_point_range[0].to_value == top
        assert words in descriptor.description
        ok = node.set_parameters([Parameter(full, value=good)])[0]
        assert ok.successful, ok.reason
        assert getattr(node.core.lane_keeping, name) == good
        refused = node.set_parameters([Parameter(full, value=bad)])[0]
        assert not refused.successful
        assert getattr(node.core.lane_keeping, name) == good
    finally:
        node.destroy_node()
