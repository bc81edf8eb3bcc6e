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

"""Performance metrics of lateral-control time series (pure numpy, no ROS)."""

from __future__ import annotations

import math
from typing import Mapping, NamedTuple

from lookahead_control.core.control_law import arc_offset
import numpy as np
import numpy.typing as npt


Array = npt.NDArray[np.float64]
SETTLING_BAND = 0.02


class StepMetrics(NamedTuple):
    """
    Response of a signal to a step of its input (here: relative yaw at curve entry).

    :param final: final value (mean of the last second) [unit of the signal].
    :param overshoot: peak excursion beyond the final value over |final| [-].
    :param damping_ratio: second-order equivalent from the overshoot; NaN when there
        is no overshoot (the response is at least critically damped).
    :param settling_time: time after the step to stay within 2% of |final| [s].
    """

    final: float
    overshoot: float
    damping_ratio: float
    settling_time: float


def peak(x: Array) -> float:
    """Return max |x|, NaN for an empty series."""
    return float(np.max(np.abs(x))) if x.size else math.nan


def rms(x: Array) -> float:
    """Return the root mean square of x, NaN for an empty series."""
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else math.nan


def damping_from_overshoot(overshoot: float) -> float:
    """
    Return the damping ratio of a second-order system with this step overshoot.

    :param overshoot: fractional overshoot, > 0.
    :return: zeta = -ln(OS) / sqrt(pi^2 + ln(OS)^2); NaN if there is no overshoot.
    """
    if not overshoot > 0.0:
        return math.nan
    log = math.log(overshoot)
    return -log / math.sqrt(math.pi ** 2 + log * log)


def step_metrics(time: Array, x: Array, step_time: float,
                 final_window: float = 1.0) -> StepMetrics:
    """
    Return overshoot, damping ratio and settling time of a step response.

    :param time: sample times [s].
    :param x: the signal.
    :param step_time: when the step happened [s].
    :param final_window: the final value is the mean over this last stretch [s].
    :return: the step metrics.
    """
    after = time >= step_time
    tail = time >= time[-1] - final_window
    final = float(np.mean(x[tail]))
    if not np.any(after) or final == 0.0:
        return StepMetrics(final, math.nan, math.nan, math.nan)
    direction = math.copysign(1.0, final)
    excursion = float(np.max(direction * (x[after] - final)))
    overshoot = max(excursion, 0.0) / abs(final)
    outside = np.abs(x[after] - final) > SETTLING_BAND * abs(final)
    t_after = time[after]
    if not np.any(outside):
        settling = 0.0
    else:
        last = int(np.nonzero(outside)[0][-1])
        settling = float(t_after[min(last + 1, t_after.size - 1)] - step_time)
    return StepMetrics(final, overshoot, damping_from_overshoot(overshoot), settling)


def rate(time: Array, x: Array) -> Array:
    """
    Return the backward difference dx/dt (one sample shorter).

    :param time: sample times [s].
    :param x: the signal.
    :return: its rate.
    """
    return np.diff(x) / np.diff(time)


def lateral_errors(y_cg: Array, eps_r: Array, rho: Array, d_v: Array, d_s: float,
                   y_ref: Array) -> dict[str, Array]:
    """
    Return every lateral error the paper could mean, named by where it is measured.

    - ``cg``: the CG from the lane centre.
    - ``bumper``: the look-down sensor at ``d_s`` (``y_cg + d_s eps_r``).
    - ``look_ahead``: the look-ahead point from the lane centre, ``y_a = y_v - y_o``
      with the exact arc offset (eq. 2-3).
    - ``regulated``: what the law drives to zero, ``y_v - y_ref``.

    :param y_cg: CG lateral error [m].
    :param eps_r: relative yaw [rad].
    :param rho: curvature at the CG [1/m].
    :param d_v: look-ahead distance in use [m].
    :param d_s: bumper distance [m].
    :param y_ref: the law's reference [m].
    :return: one array per name.
    """
    y_v = y_cg + d_v * eps_r
    return {
        'cg': y_cg,
        'bumper': y_cg + d_s * eps_r,
        'look_ahead': y_v - arc_offset(rho, d_v, eps_r, exact=True),
        'regulated': y_v - y_ref,
    }


def run_metrics(time: Array, channels: Mapping[str, Array], d_s: float) -> dict[str, float]:
    """
    Return the metrics table row of one run.

    Needs the channels ``y_cg, eps_r, rho, d_v, y_ref, steering_cmd``.

    :param time: sample times [s].
    :param channels: the time series.
    :param d_s: bumper distance [m].
    :return: peak/RMS lateral errors at every point, yaw step metrics, steering peaks.
    """
    errors = lateral_errors(channels['y_cg'], channels['eps_r'], channels['rho'],
                            channels['d_v'], d_s, channels['y_ref'])
    row: dict[str, float] = {}
    for name, series in errors.items():
        row[f'peak_{name}'] = peak(series)
        row[f'rms_{name}'] = rms(series)
    curved = np.nonzero(np.abs(channels['rho']) > 0.0)[0]
    step_time = float(time[curved[0]]) if curved.size else float(time[0])
    yaw = step_metrics(time, channels['eps_r'], step_time)
    row.update(yaw_final=yaw.final, yaw_overshoot=yaw.overshoot,
               yaw_damping=yaw.damping_ratio, yaw_settling=yaw.settling_time)
    steering = channels['steering_cmd']
    row['peak_steering'] = peak(steering)
    row['peak_steering_rate'] = peak(rate(time, steering)) if steering.size > 1 else 0.0
    row['d_v_final'] = float(channels['d_v'][-1])
    return row
