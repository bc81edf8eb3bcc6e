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
The parameter schema: every parameter's name, type, default, unit and range, once.

The nodes declare their ROS parameters from it (``ros.node_params`` builds the
``ParameterDescriptor`` of each :class:`Spec`), and the offline tools check params files
with it (``core.config``), so a file means the same to both: the same names (a typo is an
error, not ignored), the same types (an integer where a real is expected is taken as
that real, as ``1485`` for ``1485.0``), the same ranges and one error format,
``<file>: <name> = <value> ...``. No ROS here.
"""

from __future__ import annotations

import difflib
import math
from typing import Any, Iterable, Mapping, NamedTuple, Sequence

from lookahead_control.core.baselines import LATERAL_RATE_MODES
from lookahead_control.core.controller import LAW_NAMES
from lookahead_control.core.lane_keeping import LaneKeepingParams
from lookahead_control.core.params import ParameterError, REFERENCE_MODES, SCHEDULE_MODES
from lookahead_control.core.state_filter import FILTER_MODES


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
    Spec('vehicle.cg_height', 0.0, 'CG height above the ground h: under a_x the axle loads '
         'and cornering stiffnesses move by m a_x h / L, read by law cg_compensated and the '
         'nonlinear plant (0: none, the paper model) [m]',
         0.0, 3.0),
)

CONTROLLER_SPECS = (
    Spec('controller.natural_frequency', 3.0,
         'natural frequency w_n of the look-ahead error loop, k_p = w_n^2, of law paper '
         '(law cg_compensated, the default, uses lane_keeping.natural_frequency) [rad/s]',
         0.01, 100.0),
    Spec('controller.damping_ratio', 1.0, 'damping ratio zeta, k_d = 2 zeta w_n, of law '
         'paper (law cg_compensated: lane_keeping.damping_ratio) [-]', 0.01, 10.0),
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

LAW_SPEC = Spec('law', 'cg_compensated', 'steering law: cg_compensated (the default: the '
                'look-ahead law keeping the CG on the lane, lane_keeping.* below), paper '
                '(the look-ahead law, eq. 15 with the controller.* schedule) or a baseline '
                'with its own parameters below; switchable while active (the rate limit '
                'applies to the change)',
                choices=LAW_NAMES)

# the CG-compensated law (law: cg_compensated); defaults: LaneKeepingParams
LANE_KEEPING_SPECS = tuple(
    Spec(f'lane_keeping.{name}', getattr(LaneKeepingParams(), name), text, low, high)
    for name, text, low, high in (
        ('natural_frequency', 'w_n of the y_v loop at and above frequency_speed [rad/s]',
         0.01, 100.0),
        ('damping_ratio', 'zeta of the y_v loop [-]', 0.01, 10.0),
        ('frequency_speed', 'below this speed w_n falls with the speed [m/s]', 0.01, 100.0),
        ('low_speed_frequency', 'lowest w_n of the y_v loop, capped at natural_frequency '
         '(equal or above: w_n constant) [rad/s]', 0.01, 100.0),
        ('frequency_lag', "the loop's lags besides a slow answer's hold: at an answer period "
         'T beyond 10 ms (a camera slower than 100 Hz answered once a frame) w_n is at most '
         'natural_frequency (0.01 + frequency_lag) / (T + frequency_lag), not below '
         'low_speed_frequency; 0: w_n does not follow the period, else 0.1-10 (the '
         'smaller, the deeper the cut) [s]', 0.0, 10.0),
        ('approach_heading', 'far off the lane the car closes on it at this relative '
         'heading (the CG offset in the proportional term clipped); the integral and its '
         'band clock hold while clipped; 0: unclipped, else 0.02-0.15 [rad]', 0.0, 0.15),
        ('demand_limit', 'the command stays within the steady steering of the lane +- that of '
         "this lateral acceleration, or between it and the front axle's course (the "
         'counter-steer of a slide); 0: unlimited, else 5-50 [m/s^2]', 0.0, 50.0),
        ('reference_preview', 'the reference uses the curvature this long ahead [s]',
         0.0, 3.0),
        ('feedforward_preview', 'the drift term uses the curvature this long ahead: '
         'actuator lag + delay, at answers 10 ms apart [s]', 0.0, 1.0),
        ('hold_preview', 'share of the answer period beyond 10 ms (a camera slower than '
         '100 Hz answered once a frame: its hold) added to feedforward_preview; 0.5: the '
         "hold's mean delay, 0: none [-]", 0.0, 1.0),
        ('integral_gain', 'gain k_i of the CG-error integral at and above integral_speed, '
         '0: off at every speed [1/s]', 0.0, 5.0),
        ('integral_speed', 'at and above this speed k_i is integral_gain [m/s]',
         0.01, 100.0),
        ('low_speed_integral_gain', 'k_i at and below low_integral_speed, linear in the '
         'speed up to integral_speed; capped at integral_gain (integral_gain or more: k_i '
         'constant) [1/s]', 0.0, 5.0),
        ('low_integral_speed', 'at and below this speed k_i is low_speed_integral_gain; '
         'below integral_speed [m/s]', 0.0, 100.0),
        ('integral_limit', 'clamp of the integral shift of the reference [m]', 0.0, 5.0),
        ('integral_min_speed', 'integral and estimate frozen below this speed [m/s]',
         0.0, 50.0),
        ('integral_band', 'integral frozen while |CG error| is this or more; 0: no band, '
         'it integrates at any error [m]', 0.0, 10.0),
        ('integral_band_time', '... but integrates once |CG error| has stood outside the band '
         'this long; 0: held while outside [s]', 0.0, 60.0),
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
        ('compliance_memory', 'time constant of the memory the estimate falls back to on '
         'straights, counted while the tyres are loaded and the CG is within 0.1 m of the '
         'lane; 0: back to the model value, else at least 1 [s]', 0.0, 1000.0),
        ('compliance_memory_range', 'the memory stays within 1/k and k times the model '
         'value (at most compliance_range) [-]', 1.0, 100.0),
        ('compliance_memory_seed', "the memory's starting value over the model value, "
         'e.g. the compliance_memory an earlier run ended with; within 1/k and k of '
         'compliance_memory_range; 1: the model [-]', 0.01, 100.0),
        ('rate_feedforward', 'add the curvature-rate term of the inverse zero dynamics '
         'to the reference', 0.0, 1.0),
        ('exact_inverse', 'share of the exact inverse of the zero dynamics in the '
         'reference (the relative yaw that keeps the CG on the lane); 0: the first-order '
         'inverse alone [-]', 0.0, 1.0),
        ('exact_inverse_damping', "the exact inverse's own mode damped to this ratio, "
         'the first-order inverse kept; 0: its own damping [-]', 0.0, 2.0),
        ('state_preview', "share of the drift term's state terms previewed "
         'feedforward_preview along the lane (a lead on the curvature rate for the actuator '
         'lag and delay; 0 with feedforward_preview 0); 1: the whole preview, 0: none [-]',
         0.0, 3.0),
        ('design_friction', 'friction of the design tyre for the load-dependent rear '
         'compliance (brush shape); 0: constant compliance [-]', 0.0, 2.0),
        ('curvature_smoothing', 'the law reads road_curvature averaged along the road by '
         'a triangular window of this half-width reaching behind the CG (a curvature step '
         'becomes an S-curve); 0: as received [m]', 0.0, 50.0),
        ('max_lateral_jerk', 'the rate feedforward sees at most this lateral jerk '
         '(a curvature step in the map is not followed as an impulse); 0: no limit '
         '[m/s^3]', 0.0, 1000.0),
        ('curvature_blend', 'when road_curvature starts or stops arriving, the curvature '
         'used moves to the new one (received or estimated) over this time; 0: at once '
         '[s]', 0.0, 10.0),
        ('estimate_rate_time', 'while the curvature is estimated (no road_curvature), its '
         'rate is the derivative of the estimate through a low pass of this time constant, and '
         'the law previews the estimate along it; 0: rate 0, no preview [s]', 0.0, 10.0),
        ('map_fallback', "the controller's map check at this many times its threshold "
         'drops road_curvature: the law runs on its own curvature estimate until the check '
         'has stayed below its threshold for map_recover; 0: never [-]', 0.0, 100.0),
        ('map_recover', 'the time the map check stays below its threshold before '
         'road_curvature is taken again [s]', 0.0, 60.0),
        ('side_force', "share of the state filter's rear-axle force disturbance taken "
         'as a side force (crosswind, bank) into the reference: the relative yaw the car '
         'holds against it with the CG on the lane; on a curve it fades out with the '
         'lateral acceleration past compliance_prior (the compliance estimate carries the '
         'tyres there); needs state_filter kalman; 0: the integral alone removes a side '
         'force [-]', 0.0, 1.0),
        ('side_force_filter', 'low pass of that relative yaw (the force estimate is noisy) '
         '[s]', 0.0, 5.0),
        ('force_feedforward', "share of the state filter's axle-force disturbances added "
         "to the linearization's drift term (what the model's linear tyres do not carry: "
         'a crosswind, softer or saturating tyres); needs state_filter kalman; 0: off '
         '[-]', 0.0, 1.0),
        ('force_feedforward_filter', 'low pass of those forces; with the full share 0.5 s '
         'or more (0.2 s fails the robust check with the filter) [s]', 0.0, 5.0),
        ('delay_prediction', "act on the state filter's estimate predicted across "
         'filter_delay under the commands already sent, on the road there (for a long '
         'transport delay); needs state_filter kalman', 0.0, 1.0),
    )) + (
    Spec('lane_keeping.state_filter', LaneKeepingParams().state_filter,
         'kalman: the law uses the estimate of y_cg, eps_r, v_y, r of the Kalman filter, '
         'and of the road curvature while none is received (docs/lane_keeping.md, State '
         'filter); none: the measurements, and a filter of the curvature alone while '
         'none is received; side_force and force_feedforward run as 0 (no force '
         'estimate)',
         choices=FILTER_MODES),
) + tuple(
    Spec(f'lane_keeping.filter_{name}', getattr(LaneKeepingParams(), f'filter_{name}'),
         'state filter: ' + text, low, high)
    for name, text, low, high in (
        ('min_speed', 'below this speed the measurements pass through [m/s]', 0.5, 50.0),
        ('actuator_lag', 'time constant of the steering actuator it models [s]', 0.0, 2.0),
        ('delay', "delay from the lateral error's stamp to the wheel it models: the "
         "command-to-actuator delay, plus a lane camera's latency [s]", 0.0, 1.0),
        ('lateral_noise', 'standard deviation of the lateral error at the sensor [m]',
         1e-5, 5.0),
        ('yaw_noise', 'standard deviation of the relative yaw [rad]', 1e-6, 0.5),
        ('lateral_velocity_noise', 'standard deviation of v_y [m/s]', 1e-5, 5.0),
        ('yaw_rate_noise', 'standard deviation of the yaw rate [rad/s]', 1e-6, 0.5),
        ('force_noise', 'white noise on each axle force [N sqrt(s)]', 0.0, 1e6),
        ('force_drift', 'random walk of the axle-force disturbances; at least 1: 0 would '
         'never correct them, a closed-loop pole at 1 [N/sqrt(s)]', 1.0, 1e7),
        ('kinematic_noise', 'white noise on the rate of y_cg [m/sqrt(s)]', 0.0, 10.0),
        ('curvature_drift', 'random walk of the road lateral acceleration v_x^2 rho, for '
         'the curvature estimate while no road_curvature is received [m/s^2.5]', 1e-4,
         100.0),
    ))

BASELINE_SPECS = (
    Spec('pure_pursuit.velocity_ratio', 0.3, 'look-ahead per speed (Autoware '
         'ld_velocity_ratio) [s]', 0.0, 10.0),
    Spec('pure_pursuit.lateral_error_ratio', 3.6, 'look-ahead per |rear-axle error| past '
         'the threshold (ld_lateral_error_ratio) [-]', 0.0, 100.0),
    Spec('pure_pursuit.lateral_error_threshold', 0.5, 'long_ld_lateral_error_threshold [m]',
         0.0, 100.0),
    Spec('pure_pursuit.curvature_ratio', 120.0, 'look-ahead taken off per |curvature| '
         '(ld_curvature_ratio) [m^2]', 0.0, 1.0e4),
    Spec('pure_pursuit.min_look_ahead', 4.35, 'min_lookahead_distance [m]', 0.01, 200.0),
    Spec('pure_pursuit.max_look_ahead', 60.0, 'max_lookahead_distance [m]', 0.01, 200.0),
    Spec('stanley.gain', 4.0, 'k of atan(k e / (k_soft + v)) [1/s]', 0.001, 100.0),
    Spec('stanley.softening', 1.0, 'k_soft [m/s]', 0.001, 100.0),
    Spec('stanley.yaw_rate_gain', 0.05, 'k_d,yaw on r - r_traj [s]', 0.0, 10.0),
    Spec('stanley.steady_yaw_gain', 1.0, 'k_ag on the steady-state yaw term [-]', 0.0, 5.0),
    Spec('lqr.q_lateral', 0.01, 'Q weight of the lateral error [1/m^2]', 0.0, 1.0e6),
    Spec('lqr.q_lateral_rate', 0.0, 'Q weight of its rate [s^2/m^2]', 0.0, 1.0e6),
    Spec('lqr.q_heading', 0.1, 'Q weight of the relative yaw [1/rad^2]', 0.0, 1.0e6),
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
        ('max_curvature_points', 256, 'inputs: a road_curvature polygon with more points '
         'is refused, before its points are decoded', 1, 100000),
        ('latency_warn', 0.05, 'diagnostics: WARN when an input arrives, or an answer goes '
         'out, this long after the stamp [s]', 0.001, 10.0),
    ))

ROS_BUILTIN = ('use_sim_time', 'start_type_description_service')
#: rclpy's own parameters of every node, with their types (a ``use_sim_time: 1`` stopped
#: a node after ROS started, in rclpy's words and without the file's name; dev-probe61)
BUILTIN_SPECS = {spec.name: spec for spec in (
    Spec('use_sim_time', False, "rclpy: the node's clock follows /clock"),
    Spec('start_type_description_service', True, 'rclpy: the type description service'))}
ROS_BUILTIN_PREFIXES = ('qos_overrides.',)


def type_name(spec: Spec) -> str:
    """
    Return the ROS type name of a spec: bool, integer, double or string.

    :param spec: the parameter.
    :return: its type's name.
    """
    if isinstance(spec.default, bool):
        return 'bool'
    if isinstance(spec.default, int):
        return 'integer'
    if isinstance(spec.default, float):
        return 'double'
    return 'string'


def check_value(spec: Spec, value: Any) -> Any:
    """
    Return a parameter's value in its type, or raise naming it, the value and what is allowed.

    An integer is accepted for a real (``1485`` is ``1485.0``); a boolean is never a
    number, a number never a string.

    :param spec: the parameter.
    :param value: the value from a file or command line.
    :return: the value (an integer for a real converted to float).
    :raises ParameterError: wrong type, out of range, not a choice.
    """
    kind = type_name(spec)
    unit = spec.description.rsplit('[', 1)[-1].rstrip(']') if spec.description.endswith(
        ']') else ''
    suffix = f' {unit}' if unit and unit != '-' else ''
    number = isinstance(value, (int, float)) and not isinstance(value, bool)
    if kind == 'bool' and not isinstance(value, bool):
        raise ParameterError(f'{spec.name} = {value!r}: expected true or false')
    if kind == 'integer' and not (number and float(value).is_integer()):
        raise ParameterError(f'{spec.name} = {value!r}: expected an integer')
    if kind == 'double' and not number:
        raise ParameterError(f'{spec.name} = {value!r}: expected a number'
                             + (f' [{unit}]' if suffix else ''))
    if kind == 'string' and not isinstance(value, str):
        raise ParameterError(f'{spec.name} = {value!r}: expected a string'
                             + (f'; choose one of {", ".join(spec.choices)}' if spec.choices
                                else ''))
    if kind == 'integer':
        value = int(value)
    elif kind == 'double':
        value = float(value)
        if not math.isfinite(value):
            raise ParameterError(f'{spec.name} = {value!r}: not finite')
    if spec.choices and value not in spec.choices:
        raise ParameterError(f'{spec.name} = {value!r} is not allowed; choose one of '
                             f'{", ".join(spec.choices)}')
    if (kind in ('integer', 'double') and spec.low is not None and spec.high is not None
            and not spec.low <= value <= spec.high):
        raise ParameterError(f'{spec.name} = {value!r}{suffix} is out of range; allowed: '
                             f'[{spec.low:g}, {spec.high:g}]{suffix}')
    return value


def unknown_name(name: str, known: Iterable[str]) -> str:
    """
    Return the message for a name no parameter has, with the closest known names.

    :param name: the unknown name.
    :param known: the known names.
    :return: the message.
    """
    close = difflib.get_close_matches(name, list(known), n=3, cutoff=0.75)
    hint = f'; did you mean {" or ".join(close)}?' if close else ''
    return f'unknown parameter {name!r}{hint}'


def check_params(params: Mapping[str, Any], specs: Sequence[Spec],
                 namespaces: Iterable[str] | None = None) -> dict[str, Any]:
    """
    Check flat parameters against specs; return them converted.

    :param params: dotted name -> value.
    :param specs: the known parameters.
    :param namespaces: check only names in these namespaces (the part before the first
        dot; a ``/**`` section of a params file holds other nodes' parameters too); None:
        every name must be known (a section for this node).
    :return: name -> value, integers for reals converted; names outside ``namespaces``
        unchanged.
    :raises ParameterError: the first unknown name, wrong type or value out of range.
    """
    by_name = {s.name: s for s in specs}
    scope = None if namespaces is None else set(namespaces)
    out = {}
    for name, value in params.items():
        spec = by_name.get(name, BUILTIN_SPECS.get(name))
        if spec is None:
            builtin = name in ROS_BUILTIN or name.startswith(ROS_BUILTIN_PREFIXES)
            outside = scope is not None and name.partition('.')[0] not in scope
            if not (builtin or outside):
                raise ParameterError(unknown_name(name, by_name))
            out[name] = value
            continue
        out[name] = check_value(spec, value)
    return out


def namespaces_of(specs: Iterable[Spec]) -> set[str]:
    """
    Return the namespaces of dotted parameter names (``vehicle``, ``safety`` ...).

    :param specs: the parameters.
    :return: the parts before the first dot, of the names that have one.
    """
    return {s.name.partition('.')[0] for s in specs if '.' in s.name}
