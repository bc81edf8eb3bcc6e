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
Input checks, low-speed hand-over, stale-input behaviour and output limits.

No ROS here. Modelled on Autoware's vehicle_cmd_gate: every input is checked before
use (finite, within what a vehicle produces, stamps advancing and neither older than
``input_timeout`` nor further than ``max_future`` ahead of the node's clock); the
command is clamped, then rate limited, last; a stale input holds the command, then
ramps it to a safe angle within the rate limit.

Output limits: ``|delta| <= min(max_steering_angle, atan(a_lat_max L / v_x^2))`` (the
lateral-acceleration limit of a kinematic single track, speed-dependent like the
gate's), ``|d delta / dt| <= max_steering_rate`` (from one or two references: the
controller's node clock and stamps). The rate limit has the last word: a cap that
falls faster than the rate allows (the speed rose) is approached at the rate.

Low speed: the law divides by ``v_x``. Below ``low_speed`` the command is blended over
``low_speed_blend`` m/s from the law to the last command given above it (hold), so the
hand-over is continuous in speed and no division blows up.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Callable, Optional

from lookahead_control.core.params import check_finite, check_range, ParameterError
import numpy as np

INPUT_NAMES = ('lateral_error', 'yaw', 'velocity', 'road_curvature')
# limits that may be 0: no hold (ramp at once), no stamp ahead of the node's clock
ZERO_ALLOWED = ('hold_time', 'max_future')


@dataclass(frozen=True)
class SafetyParams:
    """
    Limits of the inputs and of the command.

    :param max_lateral_error: largest believable |lateral error| [m].
    :param max_relative_yaw: largest believable |relative yaw| [rad].
    :param max_yaw_rate: largest believable |yaw rate| [rad/s].
    :param max_speed: largest believable |v_x| [m/s].
    :param max_lateral_speed: largest believable |v_y| [m/s].
    :param max_acceleration: largest believable |a_x| [m/s^2].
    :param max_curvature: largest believable |road curvature| [1/m].
    :param max_sensor_distance: largest believable measurement distance ahead [m].
    :param max_future: a stamp further ahead of the node's clock is refused [s] (0:
        any stamp ahead of it).
    :param input_timeout: an input older than this is stale [s].
    :param hold_time: on stale inputs, hold the command this long, then ramp [s] (0:
        ramp at once).
    :param safe_angle: where the ramp goes [rad].
    :param max_steering_angle: actuator angle limit [rad].
    :param max_steering_rate: actuator rate limit [rad/s].
    :param max_lateral_acceleration: speed-dependent angle limit a_lat [m/s^2].
    :param low_speed: below this the law hands over to holding [m/s].
    :param low_speed_blend: width of the hand-over [m/s].
    :param max_curvature_points: a curvature polygon with more points is refused.
    :param latency_warn: input age or answer latency above this is a warning [s].
    """

    max_lateral_error: float = 5.0
    max_relative_yaw: float = 1.0
    max_yaw_rate: float = 2.0
    max_speed: float = 70.0
    max_lateral_speed: float = 10.0
    max_acceleration: float = 15.0
    max_curvature: float = 0.2
    max_sensor_distance: float = 100.0
    max_future: float = 0.1
    input_timeout: float = 0.2
    hold_time: float = 0.5
    safe_angle: float = 0.0
    max_steering_angle: float = 0.6
    max_steering_rate: float = 5.0
    max_lateral_acceleration: float = 30.0
    low_speed: float = 3.0
    low_speed_blend: float = 1.0
    max_curvature_points: int = 256
    latency_warn: float = 0.05

    def __post_init__(self) -> None:
        """Check every limit is finite and positive, and the safe angle within limits."""
        for name, value in vars(self).items():
            check_finite(f'safety.{name}', value)
            if name in ZERO_ALLOWED:
                check_range(f'safety.{name}', value, 0.0, 1e6)
            elif name != 'safe_angle':
                check_range(f'safety.{name}', value, 0.0, 1e6, low_open=True)
        if abs(self.safe_angle) > self.max_steering_angle:
            raise ParameterError(f'safety.safe_angle = {self.safe_angle:g} rad: must be '
                                 'within +-safety.max_steering_angle '
                                 f'({self.max_steering_angle:g})')
        if self.low_speed_blend > self.low_speed:
            raise ParameterError(f'safety.low_speed_blend = {self.low_speed_blend:g}: must '
                                 f'be <= safety.low_speed ({self.low_speed:g})')


def _finite(*values: float) -> bool:
    for v in values:            # a loop, not all(<genexpr>): this runs per message
        if not (isinstance(v, (int, float)) and math.isfinite(v)):
            return False
    return True


# the limits each input's fields are checked against: (field, SafetyParams attribute)
SAMPLE_LIMITS = {
    'lateral_error': (('value', 'max_lateral_error'), ('distance', 'max_sensor_distance')),
    'yaw': (('relative_yaw', 'max_relative_yaw'), ('yaw_rate', 'max_yaw_rate'),
            ('accel_x', 'max_acceleration')),
    'velocity': (('v_x', 'max_speed'), ('v_y', 'max_lateral_speed')),
    'road_curvature': (('rho', 'max_curvature'), ('slope', 'max_curvature')),
}


def check_sample(name: str, sample: Any, params: SafetyParams) -> Optional[str]:
    """
    Return why a sample cannot be used, or None if it can (values only, not stamps).

    :param name: one of :data:`INPUT_NAMES`.
    :param sample: the converted sample.
    :param params: the limits.
    :return: the reason, e.g. ``'yaw: yaw_rate = nan'``.
    """
    for field, limit_name in SAMPLE_LIMITS[name]:      # once per message: no dicts built
        value = getattr(sample, field)
        if not _finite(value):
            return f'{name}: {field} = {value}'
        limit = getattr(params, limit_name)
        if abs(value) > limit:
            return f'{name}: |{field}| = {abs(value):.4g} > {limit:g}'
    if name == 'lateral_error' and sample.distance < 0.0:
        return f'{name}: distance = {sample.distance:g} m behind the CG'
    if name == 'road_curvature':
        return _check_ahead(sample.ahead, params)
    return None


def _check_ahead(points: Any, params: SafetyParams) -> Optional[str]:
    """Return why the preview points of a curvature sample cannot be used, or None."""
    limit = params.max_curvature
    for i, (distance, rho) in enumerate(points):
        if not _finite(distance, rho):
            return f'road_curvature: point {i} = ({distance}, {rho}) is not finite'
        if abs(rho) > limit:
            return (f'road_curvature: |curvature| of point {i} = {abs(rho):.4g} > '
                    f'{limit:g}')
    return None


def check_stamp(name: str, stamp_ns: int, last_ns: Optional[int], now_ns: Optional[int],
                params: SafetyParams) -> Optional[str]:
    """
    Return why a stamp cannot be used, or None.

    A stamp must advance past the input's last accepted one (ordering: a repeated stamp
    is not fresh data) and lie within ``[now - input_timeout, now + max_future]`` on the
    node's clock (staleness, judged on both sides).

    :param name: the input.
    :param stamp_ns: its stamp.
    :param last_ns: the stamp of the last accepted sample of this input.
    :param now_ns: the node's clock (None: unknown, no check against it).
    :param params: the limits.
    :return: the reason.
    """
    if now_ns is not None:
        if stamp_ns > now_ns + params.max_future * 1e9:
            return (f'{name}: stamp {(stamp_ns - now_ns) * 1e-9:.3f} s ahead of the node '
                    f'clock (max_future {params.max_future:g} s; sensor clock ahead?)')
        if stamp_ns < now_ns - params.input_timeout * 1e9:
            return (f'{name}: stamp {(now_ns - stamp_ns) * 1e-9:.3f} s behind the node '
                    f'clock (input_timeout {params.input_timeout:g} s; sensor clock behind?)')
    if last_ns is not None and stamp_ns <= last_ns:
        if stamp_ns == last_ns:
            return f'{name}: stamp {stamp_ns * 1e-9:.3f} s does not advance (repeated)'
        return f'{name}: stamp {stamp_ns * 1e-9:.3f} s goes back from {last_ns * 1e-9:.3f} s'
    return None


#: what a message repeating an input's last taken one exactly is told as
DUPLICATE = 'repeats the last message taken'


def duplicate_reason(name: str, stamp_ns: int) -> str:
    """
    Return why a message that repeats its input's last taken one is not used.

    :param name: the input.
    :param stamp_ns: its stamp.
    :return: ``'<input>: repeats the last message taken (stamp ... s, same values as
        read)'`` (as the controller reads it: a field it does not read may differ).
    """
    return f'{name}: {DUPLICATE} (stamp {stamp_ns * 1e-9:.3f} s, same values as read)'


def is_duplicate(reason: str) -> bool:
    """
    Return whether a reason a sample was not used is :func:`duplicate_reason`'s.

    :param reason: ``'<input>: <detail>'``.
    :return: it tells a duplicate, not a refusal.
    """
    return reason.partition(': ')[2].startswith(DUPLICATE)


def check_points(count: int, params: SafetyParams) -> Optional[str]:
    """
    Return why a curvature polygon of ``count`` points is refused, or None.

    :param count: its number of points.
    :param params: the limits.
    :return: the reason.
    """
    if count == 0:
        # a map or planner without a path: taken as a fresh straight road, the law
        # steered straight on in a curve and /diagnostics said OK (dev-probe55); refused,
        # it leaves the curvature to go lost (estimated, with the warning)
        return 'road_curvature: no points: an empty polygon carries no curvature'
    if count > params.max_curvature_points:
        return (f'road_curvature: points = {count} > max_curvature_points '
                f'{params.max_curvature_points}')
    return None


def check_preview_points(distance: float, step: float, count: Callable[[float, float], int],
                         limit: int, max_step: float = 100.0) -> None:
    """
    Refuse a curvature preview of more points a message than ``limit``.

    A publisher's ``preview_distance`` at ``preview_step`` each in range could give
    10001 points a message, which the controller refuses past its
    ``safety.max_curvature_points`` (dev-probe92: every polygon refused, unsaid).

    :param distance: ``preview_distance`` [m].
    :param step: ``preview_step`` [m].
    :param count: the publisher's point count of a ``(distance, step)``.
    :param limit: ``max_preview_points``.
    :param max_step: the largest ``preview_step`` the publisher takes [m].
    :raises ParameterError: too many points; the message names the least step that fits
        (4 significant digits, rounded up, checked with ``count``; if within
        ``max_step``) and the longest distance at this step.
    """
    points = count(distance, step)
    if points <= limit:
        return
    # int(d / s) + 1 <= L for s > d / L: up from there, and (L - 1) s down, in the
    # 4 digits printed, each checked as printed
    least = _digits(distance / limit, math.ceil)
    while count(distance, least) > limit:
        least = _digits(least * (1.0 + 1e-4), math.ceil)
    longest = _digits((limit - 1) * step, math.floor)
    while count(longest, step) > limit:
        longest = _digits(longest * (1.0 - 1e-4), math.floor)
    advice = (f'a preview_step of at least {least:g} m or ' if least <= max_step else '')
    raise ParameterError(f'preview_distance = {distance:g} m at preview_step = {step:g} m '
                         f'gives {points} curvature points a message, more than '
                         f'max_preview_points = {limit} (the controller refuses a polygon '
                         'longer than its safety.max_curvature_points, 256 by default; '
                         f'raise both together): {advice}a preview_distance of at most '
                         f'{longest:g} m')


def _digits(value: float, rounding: Callable[[float], int]) -> float:
    """
    Return ``value`` rounded to 4 significant digits by ``rounding`` (ceil or floor).

    :param value: a positive number, or 0.
    :param rounding: ``math.ceil`` or ``math.floor``.
    :return: the rounded value (0 for 0).
    """
    if value <= 0.0:
        return 0.0
    scale = 10.0 ** (math.floor(math.log10(value)) - 3)
    return float(f'{rounding(value / scale) * scale:.4g}')


def angle_limit(v_x: float, wheelbase: float, params: SafetyParams) -> float:
    """
    Return the steering angle limit at a speed [rad].

    :param v_x: speed [m/s] (any value; non-finite gives the static limit).
    :param wheelbase: l_1 + l_2 [m].
    :param params: the limits.
    :return: ``min(max_steering_angle, atan(a_lat L / v_x^2))``.
    """
    squared = v_x * v_x if _finite(v_x) else 0.0
    if not squared > 0.0:            # also a speed so small its square underflows
        return params.max_steering_angle
    return min(params.max_steering_angle,
               math.atan(params.max_lateral_acceleration * wheelbase / squared))


def low_speed_weight(v_x: float, params: SafetyParams) -> float:
    """
    Return the law's share of the command: 1 above ``low_speed``, 0 below the blend.

    :param v_x: speed [m/s].
    :param params: the limits.
    :return: the weight in [0, 1].
    """
    if not _finite(v_x):
        return 0.0
    low = params.low_speed - params.low_speed_blend
    return min(1.0, max(0.0, (v_x - low) / params.low_speed_blend))


@dataclass(frozen=True)
class Limited:
    """
    A command after the limits.

    :param angle: the command [rad].
    :param saturated: the angle limit cut it.
    :param rate_limited: the rate limit cut it.
    """

    angle: float
    saturated: bool
    rate_limited: bool


def limit(raw: float, previous: Optional[float], dt: float, v_x: float, wheelbase: float,
          params: SafetyParams, reference: Optional[tuple[float, float]] = None) -> Limited:
    """
    Clamp to the angle limit, then rate-limit from the previous command (and a reference).

    A non-finite ``raw`` holds the previous command (0 if none). The rate limit has the
    last word: when the angle limit falls below the previous command faster than the
    rate allows, the command moves towards it at the rate limit. With a ``reference``
    the command must lie within the rate limit of both; windows that do not meet (the
    rate was lowered since the previous command) hold the previous command.

    :param raw: the wanted angle [rad].
    :param previous: the last command sent [rad] (None: no rate limit from it).
    :param dt: time since it [s] (non-finite or negative: 0).
    :param v_x: speed for the angle limit [m/s].
    :param wheelbase: l_1 + l_2 [m].
    :param params: the limits.
    :param reference: a second reference ``(angle [rad], time since it [s])``, e.g. the
        last command sent at an earlier clock reading (None: none).
    :return: the limited command, always finite and within the rate limit; within the
        angle limit, or moving towards it at the rate limit.
    """
    cap = angle_limit(v_x, wheelbase, params)
    if previous is not None and not _finite(previous):
        previous = None
    wanted = raw if _finite(raw) else (previous if previous is not None else 0.0)
    angle = min(cap, max(-cap, wanted))
    saturated = angle != wanted
    low, high = -math.inf, math.inf
    for ref, span in ((previous, dt), reference or (None, 0.0)):
        if ref is None or not _finite(ref):
            continue
        step = params.max_steering_rate * (span if _finite(span) and span > 0.0 else 0.0)
        low, high = max(low, ref - step), min(high, ref + step)
    rate_limited = False
    if low > high:                  # windows that do not meet (both references given): hold
        rate_limited = angle != previous
        angle = previous if previous is not None else angle
    elif angle < low or angle > high:
        angle = min(high, max(low, angle))
        rate_limited = True
    return Limited(float(angle), saturated, rate_limited)


def limit_batch(raw: Any, previous: Any, dt: float, v_x: Any, wheelbase: float,
                params: SafetyParams) -> tuple[Any, Any]:
    """
    Apply :func:`limit` element-wise to a batch of runs (the offline output stage).

    Every element equals :func:`limit` on it (without ``reference``: one clock, the
    runner's). Floats in give floats out.

    :param raw: the wanted angles [rad].
    :param previous: the last commands sent [rad] (None: no rate limit; a non-finite
        element: none for that run).
    :param dt: time since them [s] (non-finite or negative: 0).
    :param v_x: speeds for the angle limit [m/s].
    :param wheelbase: l_1 + l_2 [m].
    :param params: the limits.
    :return: ``(angle, cut)``: the limited commands, and where the angle or the rate
        limit changed them.
    """
    scalar = np.ndim(raw) == 0 and np.ndim(v_x) == 0 and np.ndim(previous) == 0
    wanted_in = np.asarray(raw, dtype=float)
    # the node's angle_limit per element (numpy's vectorized arctan differs from its
    # math.atan in the last bit for some speeds, 22.25 m/s: 1.4e-17 rad; dev-probe57)
    cap = per_element(lambda v: angle_limit(v, wheelbase, params), v_x)
    last = np.full(np.shape(wanted_in), math.nan) if previous is None else np.asarray(
        previous, dtype=float)
    known = np.isfinite(last)
    wanted = np.where(np.isfinite(wanted_in), wanted_in, np.where(known, last, 0.0))
    angle = np.minimum(cap, np.maximum(-cap, wanted))
    cut = angle != wanted
    step = params.max_steering_rate * (dt if _finite(dt) and dt > 0.0 else 0.0)
    low = np.where(known, last - step, -math.inf)
    high = np.where(known, last + step, math.inf)
    rated = (angle < low) | (angle > high)
    angle = np.minimum(high, np.maximum(low, angle))
    cut = cut | rated
    if scalar:
        return float(angle), bool(cut)
    return angle, cut


def per_element(function: Any, values: Any) -> Any:
    """
    Return a scalar function applied to each element, as the node applies it (a float: a float).

    :param function: ``float -> float``.
    :param values: a float or an array.
    :return: the results, in the shape of ``values``.
    """
    if np.ndim(values) == 0:
        return function(float(values))
    flat = np.ravel(np.asarray(values, dtype=float))
    return np.reshape(np.array([function(float(v)) for v in flat]), np.shape(values))


def stale_target(held: float, stale_for: float, params: SafetyParams) -> float:
    """
    Return the command wanted while inputs are stale: hold, then ramp to the safe angle.

    :param held: the command when the inputs went stale [rad].
    :param stale_for: time since then [s].
    :param params: the limits.
    :return: the wanted angle (the rate limiter then applies).
    """
    if stale_for <= params.hold_time:
        return held
    ramp = params.max_steering_rate * (stale_for - params.hold_time)
    if held > params.safe_angle:
        return max(params.safe_angle, held - ramp)
    return min(params.safe_angle, held + ramp)
