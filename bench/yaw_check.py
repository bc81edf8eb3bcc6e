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
The yaw-rate check's margin on the league's runs (``core/yaw_check.py``).

``python -m bench.yaw_check [LAW,LAW... [PLANT,PLANT...]]``: every law of ``compare``
(default all), S0-S5 at 10 / 20 / 30 / 37 m/s, on the plants given (default the goal
plant, the noise-free nonlinear plant and the CommonRoad multi-body plant with delay and
noise; noise seed 11), run as ``compare`` runs them; then :class:`YawCheck` on each run's
yaw rate and relative yaw (with the default sensor noise on both, seed 5) and the
command sent before them, once as they are, once with the yaw rate's sign flipped and
once each with it in deg/s (x 57.3) and 10 times too large (the loop itself is right:
a check of the verdict, not of a shaking car). Prints per run where a witness fell
below -0.5, any run refused as it is (none may be), the smallest over all runs and steps
of the larger of the two correlations (both negative together is the fault), the
largest of the scale's evidence: the spread (the yaw rate's standard deviation over the
larger witness's) and the smaller of ``|gain|`` and ``1 / |kinematic gain|`` (either at
``scale_limit`` is the fault), the stillness (the smaller witness's standard deviation
over the yaw rate's; ``scale_limit`` is told) with the yaw rate as it is, frozen from 2 s
and 10 times too small, and the heading check (``core/heading_check.py``) on the
run's lateral error (default noise; at the CG and 20 m ahead) with the relative yaw and
the lateral speed, as they are and with either sign flipped. About 15 minutes on one
core.
"""

from __future__ import annotations

import math
import sys
from typing import Sequence

from bench.league_runs import league_runs
from lookahead_control.core.heading_check import HeadingCheck
from lookahead_control.core.yaw_check import YawCheck
from lookahead_control.tools import compare
import numpy as np

PLANTS = ('nonlinear_delay_noise', 'nonlinear', 'commonroad_mb_delay_noise')
NOISE = 0.002                   # [rad/s, rad] the default sensor noise of r and eps_r
LATERAL_NOISE = 0.03            # [m] the default sensor noise of the lateral error
V_Y_NOISE = 0.02                # [m/s] ... of v_y
DISTANCE = 20.0                 # [m] a camera's look-ahead, for the heading check


def check_run(time: np.ndarray, r: np.ndarray, eps_r: np.ndarray, command: np.ndarray,
              v_x: np.ndarray, rho: np.ndarray, wheelbase: float
              ) -> tuple[float, float, float, float | None, float, float, float, float | None]:
    """
    Run the check over one run.

    :param time: sample times [s].
    :param r: yaw rate as measured [rad/s].
    :param eps_r: relative yaw as measured [rad].
    :param command: the command sent at each sample [rad].
    :param v_x: speed [m/s].
    :param rho: the curvature received [1/m].
    :param wheelbase: ``L`` [m].
    :return: the smallest steering correlation, the smallest relative-yaw correlation,
        the smallest over the steps of the larger of the two, the first time the yaw
        rate was refused (None: never), the largest spread, the largest of the smaller
        of ``|gain|`` and ``1 / |kinematic gain|``, the largest finite stillness and the
        first time the yaw rate was told too still (None: never).
    """
    check = YawCheck()
    low_steering = low_kinematic = joint = 2.0
    spread = gains = still = 0.0
    refused = still_at = None
    for k in range(1, time.size):
        opposed = check.step(float(time[k] - time[k - 1]), float(r[k]), float(command[k - 1]),
                             float(v_x[k]), wheelbase, float(eps_r[k]), float(rho[k]))
        if not math.isnan(check.correlation):
            low_steering = min(low_steering, check.correlation)
            low_kinematic = min(low_kinematic, check.kinematic_correlation)
            joint = min(joint, max(check.correlation, check.kinematic_correlation))
        if not math.isnan(check.spread):
            spread = max(spread, check.spread)
        if not math.isnan(check.gain):
            gains = max(gains, min(abs(check.gain),
                                   1.0 / max(abs(check.kinematic_gain), 1e-300)))
        if math.isfinite(check.stillness):
            still = max(still, check.stillness)
        if opposed and refused is None:
            refused = float(time[k])
        if check.too_still and still_at is None:
            still_at = float(time[k])
    return low_steering, low_kinematic, joint, refused, spread, gains, still, still_at


def heading_run(time: np.ndarray, lateral_error: np.ndarray, distance: float,
                eps_r: np.ndarray, v_x: np.ndarray, v_y: np.ndarray
                ) -> tuple[float, float | None]:
    """
    Run the heading check over one run.

    :param time: sample times [s].
    :param lateral_error: the lateral error as measured [m].
    :param distance: where it is measured, ahead of the CG [m].
    :param eps_r: relative yaw as measured [rad].
    :param v_x: speed [m/s].
    :param v_y: lateral speed as measured [m/s].
    :return: the smallest correlation and the first time it told the two running against
        each other (None: never).
    """
    check = HeadingCheck()
    low, told = 2.0, None
    for k in range(1, time.size):
        opposed = check.step(float(time[k] - time[k - 1]), float(lateral_error[k]), distance,
                             float(eps_r[k]), float(v_x[k]), float(v_y[k]))
        if not math.isnan(check.correlation):
            low = min(low, check.correlation)
        if opposed and told is None:
            told = float(time[k])
    return low, told


def main(argv: Sequence[str] | None = None) -> int:
    """
    Print the margin.

    :param argv: ``[LAW,LAW... [PLANT,PLANT...]]``.
    :return: 0, or 1 if a yaw rate as it is was refused or told too still (or a heading
        as it is told).
    """
    args = list(sys.argv[1:] if argv is None else argv)
    laws = args[0].split(',') if args else list(compare.LAWS)
    plants = args[1].split(',') if len(args) > 1 else list(PLANTS)
    rng = np.random.default_rng(5)
    worst, false_refusals, runs, spread, gains, still = 2.0, 0, 0, 0.0, 0.0, 0.0
    refused = {'flipped': 0, 'deg/s': 0, 'x10': 0, 'relative yaw flipped': 0,
               'lateral error flipped': 0}
    told_still = {'frozen': 0, 'x0.1': 0}
    heading = 2.0
    for law_name, case, name, _, law_vehicle, result, speeds in league_runs(laws, plants):
        time = np.asarray(result.time)
        for i, speed in enumerate(speeds):
            def column(channel: str) -> np.ndarray:
                return np.asarray(result[channel])[:, i]
            r = column('r') + rng.normal(0.0, NOISE, time.size)
            eps_r = column('eps_r') + rng.normal(0.0, NOISE, time.size)
            given = (column('steering_cmd'), column('v_x'), column('rho'),
                     law_vehicle.wheelbase)
            steering, kinematic, joint, at, wide, large, calm, calm_at = check_run(
                time, r, eps_r, *given)
            worst, spread = min(worst, joint), max(spread, wide)
            gains, still = max(gains, large), max(still, calm)
            where = f'{law_name} {case.name} {name} {speed:g} m/s'
            if min(steering, kinematic) < -0.5:
                print(f'a witness below -0.5: {where}: steering {steering:.2f}, '
                      f'relative yaw {kinematic:.2f}')
            if at is not None:
                false_refusals += 1
                print(f'REFUSED AS IT IS: {where} at {at:.2f} s')
            if calm_at is not None:
                false_refusals += 1
                print(f'TOLD TOO STILL AS IT IS: {where} at {calm_at:.2f} s')
            runs += 1
            # frozen at its value at 2 s (a bridge repeating it), 10 times too small
            frozen, at_2 = r.copy(), int(np.searchsorted(time, 2.0))
            frozen[at_2:] = r[at_2]
            told_still['frozen'] += check_run(time, frozen, eps_r, *given)[7] is not None
            told_still['x0.1'] += check_run(time, 0.1 * r, eps_r, *given)[7] is not None
            for fault, factor in (('flipped', -1.0), ('deg/s', math.degrees(1.0)),
                                  ('x10', 10.0)):
                refused[fault] += check_run(time, factor * r, eps_r,
                                            *given)[3] is not None
            # the heading check: at the CG and at a camera's look-ahead
            v_y = column('v_y') + rng.normal(0.0, V_Y_NOISE, time.size)
            for distance in (0.0, DISTANCE):
                lateral = (column('y_cg') + distance * column('eps_r')
                           + rng.normal(0.0, LATERAL_NOISE, time.size))
                low, at = heading_run(time, lateral, distance, eps_r, column('v_x'), v_y)
                heading = min(heading, low)
                if low < -0.5:
                    print(f'heading below -0.5: {where}, d {distance:g} m: {low:.2f}')
                if at is not None:
                    false_refusals += 1
                    print(f'HEADING TOLD AS IT IS: {where}, d {distance:g} m, at '
                          f'{at:.2f} s (lowest {low:.2f})')
                refused['relative yaw flipped'] += heading_run(
                    time, lateral, distance, -eps_r, column('v_x'), v_y)[1] is not None
                refused['lateral error flipped'] += heading_run(
                    time, -lateral, distance, eps_r, column('v_x'), v_y)[1] is not None
    print(f'smallest over runs and steps of the larger correlation (as it is): {worst:.2f}')
    print(f'largest spread (as it is): {spread:.2f}; largest smaller of |gain| and '
          f'1 / |kinematic gain|: {gains:.2f} (the fault: 5)')
    print(f'largest stillness (as it is): {still:.2f} (told: 5); told too still: '
          + ', '.join(f'{fault} {count} of {runs}' for fault, count in told_still.items()))
    print(f'smallest heading correlation (as it is; 2 distances a run): {heading:.2f}')
    # the heading check's faults (told, not refused) are tried at two distances a run
    print(f'refused or told as it is: {false_refusals}; refused or told: ' + ', '.join(
        f'{fault} {count} of {runs * (2 if "error" in fault or "yaw" in fault else 1)}'
        for fault, count in refused.items()))
    return 1 if false_refusals else 0


if __name__ == '__main__':
    sys.exit(main())
