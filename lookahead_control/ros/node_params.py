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
ROS parameter declarations generated from the core's parameter dataclasses.

One table of names, defaults, descriptions and ranges serves both nodes, so a
``--params-file`` works on either and rclpy rejects out-of-range values itself.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping, NamedTuple, Sequence

from lookahead_control.core.baselines import (BaselineParams, LATERAL_RATE_MODES, LqrParams,
                                              PurePursuitParams, StanleyParams)
from lookahead_control.core.controller import LAW_NAMES
from lookahead_control.core.lane_keeping import LaneKeepingParams
from lookahead_control.core.params import (ControllerParams, REFERENCE_MODES, SCHEDULE_MODES,
                                           VehicleParams)
from lookahead_control.core.safety import SafetyParams
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter


class Spec(NamedTuple):
    """A parameter: name, default, description, numeric range or string choices."""

    name: str
    default: Any
    description: str
    low: float | None = None
    high: float | None = None
    choices: Sequence[str] = ()


VEHICLE_SPECS = (
    Spec('vehicle.mass', 1485.0, 'vehicle mass m [kg]', 1.0, 1.0e5),
    Spec('vehicle.yaw_inertia', 2872.0, 'yaw moment of inertia I_z [kg m^2]', 1.0, 1.0e6),
    Spec('vehicle.l1', 1.1, 'CG to front axle l_1 [m]', 0.01, 20.0),
    Spec('vehicle.l2', 1.58, 'CG to rear axle l_2 [m]', 0.01, 20.0),
    Spec('vehicle.c_f', 80000.0, 'front axle cornering stiffness C_f [N/rad]', 1.0, 1.0e7),
    Spec('vehicle.c_r', 80000.0, 'rear axle cornering stiffness C_r [N/rad]', 1.0, 1.0e7),
    Spec('vehicle.d_s', 1.96, 'CG to front bumper, look-down sensor d_s [m]', 0.01, 50.0),
)

CONTROLLER_SPECS = (
    Spec('controller.natural_frequency', 3.0,
         'natural frequency w_n of the look-ahead error loop, k_p = w_n^2 [rad/s]',
         0.01, 100.0),
    Spec('controller.damping_ratio', 1.0, 'damping ratio zeta, k_d = 2 zeta w_n [-]',
         0.01, 10.0),
    Spec('controller.schedule', 'paper',
         'd_v schedule: paper (eq. 26), exact (eq. 24) or fixed (d_v = vehicle.d_s)',
         choices=SCHEDULE_MODES),
    Spec('controller.max_look_ahead', 60.0, 'upper clamp of the scheduled d_v [m]',
         0.01, 200.0),
    Spec('controller.reference', 'lane_tangent',
         'regulate y_v to 0 (lane_tangent), to the lane offset y_o (arc_approx, '
         'arc_exact) or to d_v eps_ss (cg_compensated: the CG on the lane, without the '
         'preview, estimate and integral of law cg_compensated)', choices=REFERENCE_MODES),
    Spec('controller.min_speed', 1.0, 'the law divides by v_x; floor of v_x [m/s]',
         0.01, 20.0),
)

LAW_SPEC = Spec('law', 'paper', 'steering law: paper (the look-ahead law, eq. 15 with the '
                'controller.* schedule), cg_compensated (the look-ahead law keeping the CG '
                'on the lane, lane_keeping.* below) or a baseline with its own parameters '
                'below; switchable while active (the rate limit applies to the change)',
                choices=LAW_NAMES)

# the CG-compensated law (law: cg_compensated); defaults: LaneKeepingParams
LANE_KEEPING_SPECS = tuple(
    Spec(f'lane_keeping.{name}', getattr(LaneKeepingParams(), name), text, low, high)
    for name, text, low, high in (
        ('natural_frequency', 'w_n of the y_v loop at and above frequency_speed [rad/s]',
         0.01, 100.0),
        ('damping_ratio', 'zeta of the y_v loop [-]', 0.01, 10.0),
        ('frequency_speed', 'below this speed w_n falls with the speed [m/s]', 0.01, 100.0),
        ('low_speed_frequency', 'lowest w_n of the y_v loop [rad/s]', 0.01, 100.0),
        ('reference_preview', 'the reference uses the curvature this long ahead [s]',
         0.0, 3.0),
        ('feedforward_preview', 'the drift term uses the curvature this long ahead: '
         'actuator lag + delay [s]', 0.0, 1.0),
        ('integral_gain', 'gain of the CG-error integral, 0: off [1/s]', 0.0, 5.0),
        ('integral_limit', 'clamp of the integral shift of the reference [m]', 0.0, 5.0),
        ('integral_min_speed', 'integral and estimate frozen below this speed [m/s]',
         0.0, 50.0),
        ('steering_limit', 'integral and estimate frozen at this |command| [rad]',
         0.01, 1.5),
        ('max_gap', 'a longer step between lateral errors restarts the law [s]', 0.01, 10.0),
        ('compliance_time_constant', 'forgetting time of the rear-compliance estimate, '
         '0: off [s]', 0.0, 100.0),
        ('compliance_filter', 'filter of the signals of the estimate [s]', 0.01, 10.0),
        ('compliance_prior', 'below this lateral acceleration the compliance of the model '
         'holds [m/s^2]', 0.01, 20.0),
        ('compliance_range', 'the estimate stays within 1/k and k times the model value [-]',
         1.0, 100.0),
        ('rate_feedforward', 'add the curvature-rate term of the inverse zero dynamics '
         '(better on linear tyres, worse on the nonlinear plant)', 0.0, 1.0),
    ))

BASELINE_SPECS = (
    Spec('pure_pursuit.velocity_ratio', 1.4, 'look-ahead per speed (Autoware '
         'ld_velocity_ratio) [s]', 0.0, 10.0),
    Spec('pure_pursuit.lateral_error_ratio', 3.6, 'look-ahead per |rear-axle error| past '
         'the threshold (ld_lateral_error_ratio) [-]', 0.0, 100.0),
    Spec('pure_pursuit.lateral_error_threshold', 0.5, 'long_ld_lateral_error_threshold [m]',
         0.0, 100.0),
    Spec('pure_pursuit.curvature_ratio', 120.0, 'look-ahead taken off per |curvature| '
         '(ld_curvature_ratio) [m^2]', 0.0, 1.0e4),
    Spec('pure_pursuit.min_look_ahead', 4.35, 'min_lookahead_distance [m]', 0.01, 200.0),
    Spec('pure_pursuit.max_look_ahead', 60.0, 'max_lookahead_distance [m]', 0.01, 200.0),
    Spec('stanley.gain', 1.5, 'k of atan(k e / (k_soft + v)) [1/s]', 0.001, 100.0),
    Spec('stanley.softening', 1.0, 'k_soft [m/s]', 0.001, 100.0),
    Spec('stanley.yaw_rate_gain', 0.1, 'k_d,yaw on r - r_traj [s]', 0.0, 10.0),
    Spec('stanley.steady_yaw_gain', 1.0, 'k_ag on the steady-state yaw term [-]', 0.0, 5.0),
    Spec('lqr.q_lateral', 0.3, 'Q weight of the lateral error [1/m^2]', 0.0, 1.0e6),
    Spec('lqr.q_lateral_rate', 0.0, 'Q weight of its rate [s^2/m^2]', 0.0, 1.0e6),
    Spec('lqr.q_heading', 1.0, 'Q weight of the relative yaw [1/rad^2]', 0.0, 1.0e6),
    Spec('lqr.q_heading_rate', 0.0, 'Q weight of its rate [s^2/rad^2]', 0.0, 1.0e6),
    Spec('lqr.r', 1.0, 'R weight of the steering angle [1/rad^2]', 1.0e-6, 1.0e6),
    Spec('lqr.period', 0.01, 'sampling period the gains are designed for [s]', 0.001, 1.0),
    Spec('lqr.lateral_rate', 'kinematic', "e1' measured as v_y cos e2 + v_x sin e2 "
         "(kinematic) or Apollo's v_x sin e2, which ignores v_y (apollo)",
         choices=LATERAL_RATE_MODES),
    Spec('lqr.feedforward', True, "Apollo's curvature feedforward"),
)

SAFETY_SPECS = tuple(
    Spec(f'safety.{name}', default, text, low, high) for name, default, text, low, high in (
        ('max_lateral_error', 5.0, 'inputs: largest believable |lateral error| [m]', 0.01, 100.0),
        ('max_relative_yaw', 1.0, 'inputs: largest believable |relative yaw| [rad]', 0.01, 3.2),
        ('max_yaw_rate', 2.0, 'inputs: largest believable |yaw rate| [rad/s]', 0.01, 10.0),
        ('max_speed', 70.0, 'inputs: largest believable |v_x| [m/s]', 1.0, 150.0),
        ('max_lateral_speed', 10.0, 'inputs: largest believable |v_y| [m/s]', 0.01, 50.0),
        ('max_acceleration', 15.0, 'inputs: largest believable |a_x| [m/s^2]', 0.1, 100.0),
        ('max_curvature', 0.2, 'inputs: largest believable |curvature| [1/m]', 1e-4, 10.0),
        ('max_sensor_distance', 100.0, 'inputs: largest measurement distance ahead [m]',
         0.1, 1000.0),
        ('max_future', 0.1, 'inputs: stamps further ahead of the clock are refused [s]',
         0.0, 10.0),
        ('input_timeout', 0.2, 'an input older than this is stale [s]', 0.01, 10.0),
        ('hold_time', 0.5, 'stale inputs: hold the command this long, then ramp [s]',
         0.0, 10.0),
        ('safe_angle', 0.0, 'stale inputs: the ramp goes to this angle [rad]', -1.0, 1.0),
        ('max_steering_angle', 0.6, 'output: angle limit [rad]', 0.01, 1.2),
        ('max_steering_rate', 5.0, 'output: rate limit [rad/s]', 0.01, 50.0),
        ('max_lateral_acceleration', 30.0, 'output: speed-dependent angle limit '
         'atan(a L / v^2), kinematic lateral acceleration a [m/s^2]', 0.1, 100.0),
        ('low_speed', 3.0, 'below this speed the law hands over to hold [m/s]', 0.1, 30.0),
        ('low_speed_blend', 1.0, 'width of the low-speed hand-over [m/s]', 0.01, 30.0),
    ))

EXECUTORS = ('events', 'single_threaded')
EXECUTOR_SPEC = Spec('executor', 'events', 'rclpy executor: events '
                     '(rclpy.experimental.EventsExecutor: lower latency, no loss at 1 kHz) '
                     'or single_threaded', choices=EXECUTORS)


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
    Declare every spec on the node.

    :param node: the node.
    :param specs: the specs.
    """
    node.declare_parameters('', [(s.name, s.default, descriptor(s)) for s in specs])


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
