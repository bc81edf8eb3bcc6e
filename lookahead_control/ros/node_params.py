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
ROS parameter declarations built from the core's parameter schema.

The tables (``VEHICLE_SPECS``, ``CONTROLLER_SPECS``, ``SAFETY_SPECS``: names, defaults,
descriptions, ranges) are in :mod:`lookahead_control.core.param_schema`, which the
offline tools check params files with too; here each :class:`Spec` becomes a
``ParameterDescriptor``, so a ``--params-file`` works on either node and rclpy rejects
out-of-range values itself.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping, Sequence

from lookahead_control.core.baselines import (BaselineParams, LqrParams, PurePursuitParams,
                                              StanleyParams)
# the schema (names, types, defaults, ranges) is the core's, shared with the offline tools
from lookahead_control.core.lane_keeping import LaneKeepingParams
from lookahead_control.core.param_schema import (BASELINE_SPECS, CONTROLLER_SPECS,
                                                 LANE_KEEPING_SPECS, LAW_SPEC, SAFETY_SPECS,
                                                 Spec, VEHICLE_SPECS)
from lookahead_control.core.params import ControllerParams, VehicleParams
from lookahead_control.core.safety import SafetyParams
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter

__all__ = ['baseline_params', 'BASELINE_SPECS', 'build', 'check_choices',
           'CONTROLLER_SPECS', 'declare', 'descriptor', 'EXECUTOR_SPEC', 'EXECUTORS',
           'lane_keeping_params', 'LANE_KEEPING_SPECS', 'LAW_SPEC', 'MAX_PREVIEW_SPEC',
           'SAFETY_SPECS', 'safety_params', 'Spec', 'values', 'VEHICLE_SPECS',
           'vehicle_and_controller']

EXECUTORS = ('events', 'single_threaded')
EXECUTOR_SPEC = Spec('executor', 'events', 'rclpy executor: events '
                     '(rclpy.experimental.EventsExecutor: lower latency, no loss at 1 kHz) '
                     'or single_threaded', choices=EXECUTORS)
#: a curvature publisher's points a message at most (path_bridge, sim_plant)
MAX_PREVIEW_SPEC = Spec('max_preview_points', 256, 'most road_curvature points a message '
                        '(preview_distance / preview_step + 1): more is refused; the '
                        "controller's safety.max_curvature_points must be as high",
                        1, 100000)


def descriptor(spec: Spec) -> ParameterDescriptor:
    """
    Return the ROS descriptor of a spec (range for numbers, choices in the text).

    :param spec: the parameter spec.
    :return: the descriptor.
    """
    text = spec.description
    if spec.choices:
        text += f' (one of: {", ".join(spec.choices)})'
    desc = ParameterDescriptor(description=text)
    if spec.low is not None and spec.high is not None:
        if isinstance(spec.default, bool):
            pass
        elif isinstance(spec.default, int):
            desc.integer_range = [IntegerRange(from_value=int(spec.low),
                                               to_value=int(spec.high), step=0)]
        else:
            desc.floating_point_range = [FloatingPointRange(from_value=float(spec.low),
                                                            to_value=float(spec.high),
                                                            step=0.0)]
    return desc


def declare(node: Node, specs: Sequence[Spec]) -> None:
    """
    Declare every spec on the node (once per node).

    An integer set at run time for a real parameter (``ros2 param set /controller
    lane_keeping.integral_gain 1``) is taken as that real, as an integer in a params file
    is at start-up (``node_main.checked_arguments``); rclpy alone refuses it ("Wrong
    parameter type, expected 'Type.DOUBLE'"). Its range and the node's checks then apply
    to the real.

    :param node: the node.
    :param specs: the specs.
    """
    node.declare_parameters('', [(s.name, s.default, descriptor(s)) for s in specs])
    reals = frozenset(s.name for s in specs if isinstance(s.default, float))

    def as_reals(params: list[Parameter]) -> list[Parameter]:
        return [Parameter(p.name, Parameter.Type.DOUBLE, float(p.value))
                if p.name in reals and p.type_ == Parameter.Type.INTEGER else p
                for p in params]

    # rclpy concatenates what every pre-set callback returns: one per node
    node.add_pre_set_parameters_callback(as_reals)


def values(node: Node, specs: Sequence[Spec],
           pending: Sequence[Parameter] = ()) -> dict[str, Any]:
    """
    Return the node's current parameter values, with ``pending`` changes applied.

    :param node: the node.
    :param specs: which parameters.
    :param pending: parameters about to be set.
    :return: name -> value.
    """
    out = {s.name: node.get_parameter(s.name).value for s in specs}
    for p in pending:
        if p.name in out:
            out[p.name] = p.value
    return out


def check_choices(specs: Sequence[Spec], params: Mapping[str, Any]) -> None:
    """
    Raise ValueError if a string parameter is not one of its choices.

    :param specs: the specs.
    :param params: name -> value.
    """
    for s in specs:
        if s.choices and params[s.name] not in s.choices:
            raise ValueError(f'{s.name} = {params[s.name]!r} is not allowed; choose one of '
                             f'{", ".join(s.choices)}')


def build(cls: type, params: Mapping[str, Any], prefix: str) -> Any:
    """
    Build a parameter dataclass from ``prefix.field`` values.

    :param cls: VehicleParams or ControllerParams.
    :param params: name -> value.
    :param prefix: ``vehicle`` or ``controller``.
    :return: the validated dataclass (raises ParameterError).
    """
    names = {f.name for f in dataclasses.fields(cls)}
    return cls(**{k.split('.', 1)[1]: v for k, v in params.items()
                  if k.startswith(prefix + '.') and k.split('.', 1)[1] in names})


def vehicle_and_controller(params: Mapping[str, Any]) -> tuple[VehicleParams,
                                                               ControllerParams]:
    """
    Build both core parameter sets from flat ROS parameter values.

    :param params: name -> value.
    :return: the vehicle and controller parameters.
    """
    return build(VehicleParams, params, 'vehicle'), build(ControllerParams, params,
                                                          'controller')


def baseline_params(params: Mapping[str, Any]) -> BaselineParams:
    """
    Build the baseline laws' parameters from flat ROS parameter values.

    :param params: name -> value.
    :return: the parameters (raises ParameterError).
    """
    return BaselineParams(build(PurePursuitParams, params, 'pure_pursuit'),
                          build(StanleyParams, params, 'stanley'),
                          build(LqrParams, params, 'lqr'))


def safety_params(params: Mapping[str, Any]) -> SafetyParams:
    """
    Build the safety limits from flat ROS parameter values.

    :param params: name -> value.
    :return: the limits.
    """
    return build(SafetyParams, params, 'safety')


def lane_keeping_params(params: Mapping[str, Any]) -> LaneKeepingParams:
    """
    Build the CG-compensated law's settings from flat ROS parameter values.

    :param params: name -> value.
    :return: the settings.
    """
    return build(LaneKeepingParams, params, 'lane_keeping')
