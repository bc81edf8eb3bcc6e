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
The lane scale check's margin on the league's runs (``core/lane_scale_check.py``).

``python -m bench.lane_scale_check [LAW,LAW... [PLANT,PLANT...]]``: the laws of
``compare`` given (default the default law and the paper's eq. 26), S0-S5 at 10 / 20 / 30
/ 37 m/s, on the plants given (default the goal plant, the noise-free nonlinear plant and
the CommonRoad multi-body plant with delay and noise; noise seed 11), run as ``compare``
runs them; then :class:`LaneScaleCheck` on each run's lateral error (at the CG and 20 m
ahead), relative yaw, yaw rate, speeds (the default sensor noise, seed 5) and curvature
at the CG (a noise of 1e-4 1/m), as they are with the map and without, and once each
with the lateral error in cm (x 100), the relative yaw in degrees (x 57.3), both the
relative yaw and the yaw rate in degrees, and the relative yaw in degrees without a map
(the loop itself is right: a check of the verdict, not of a car on a wrong unit; such a
car moves more, and gives more evidence). Prints each run with when each fault was
told, each run with a scale of 2 or more read as it is, each run told as it is (none
may be), the largest scales read as they are (the relative yaw's with the map and
without, the lateral error's and the largest inverse of the lateral error's), and how
many runs each fault was told in (by either check). About 3 minutes on one core.
"""

from __future__ import annotations

import math
import sys
from typing import Sequence

from bench.league_runs import league_runs
from lookahead_control.core.lane_scale_check import LaneScaleCheck
import numpy as np

LAWS = ('cg_compensated', 'paper_eq26')
PLANTS = ('nonlinear_delay_noise', 'nonlinear', 'commonroad_mb_delay_noise')
NOISE = 0.002                   # [rad/s, rad] the default sensor noise of r and eps_r
LATERAL_NOISE = 0.03            # [m] ... of the lateral error
V_Y_NOISE = 0.02                # [m/s] ... of v_y
SPEED_NOISE = 0.05              # [m/s] ... of v_x
MAP_NOISE = 1.0e-4              # [1/m] the curvature's
DISTANCES = (0.0, 20.0)         # [m] the lateral error's: at the CG, a camera's look-ahead
DEGREES = math.degrees(1.0)
FAULTS = {'lateral cm': {'lateral': 100.0}, 'relative yaw deg': {'eps_r': DEGREES},
          'yaw message deg': {'eps_r': DEGREES, 'r': DEGREES},
          'relative yaw deg, no map': {'eps_r': DEGREES, 'rho': 0.0}}


def check_run(time: np.ndarray, inputs: dict[str, np.ndarray], distance: float
              ) -> tuple[float, float, float, float, float | None, float | None]:
    """
    Run the check along one run.

    :param time: the run's time [s].
    :param inputs: ``lateral``, ``eps_r``, ``r``, ``v_x``, ``v_y``, ``rho`` as given (no
        ``rho``: no map).
    :param distance: where the lateral error is measured, ahead of the CG [m].
    :return: the longest time either was out of scale, the relative yaw's largest scale
        read, the lateral error's largest and largest inverse, and the first time
        the lateral error and the relative yaw were told (None: never).
    """
    check = LaneScaleCheck()
    longest, yaw_high, lateral_high, lateral_low = 0.0, 0.0, 0.0, 0.0
    lateral_at: float | None = None
    yaw_at: float | None = None
    for k in range(time.size):
        stamp = int(round(float(time[k]) * 1e9))
        v_x = float(inputs['v_x'][k])
        rho = float(inputs['rho'][k]) if 'rho' in inputs else None
        if check.step_yaw(stamp, float(inputs['eps_r'][k]), float(inputs['r'][k]), v_x,
                          rho) and yaw_at is None:
            yaw_at = float(time[k])
        if check.step_lateral(stamp, float(inputs['lateral'][k]), distance,
                              float(inputs['eps_r'][k]), v_x,
                              float(inputs['v_y'][k])) and lateral_at is None:
            lateral_at = float(time[k])
        longest = max(longest, check.yaw_for, check.lateral_for)
        if not math.isnan(check.yaw_reading):
            yaw_high = max(yaw_high, check.yaw_reading)
        if not math.isnan(check.lateral_reading):
            lateral_high = max(lateral_high, check.lateral_reading)
            lateral_low = max(lateral_low, 1.0 / check.lateral_reading)
    return longest, yaw_high, lateral_high, lateral_low, lateral_at, yaw_at


def main(argv: Sequence[str] | None = None) -> int:
    """
    Print the margin.

    :param argv: ``[LAW,LAW... [PLANT,PLANT...]]``.
    :return: 0, or 1 if an input as it is was told out of scale.
    """
    args = list(sys.argv[1:] if argv is None else argv)
    laws = args[0].split(',') if args else list(LAWS)
    plants = args[1].split(',') if len(args) > 1 else list(PLANTS)
    rng = np.random.default_rng(5)
    false_tells, runs, longest = 0, 0, 0.0
    highs = [0.0, 0.0, 0.0, 0.0]       # relative yaw, lateral, inverse, relative yaw no map
    told = dict.fromkeys(FAULTS, 0)
    for law_name, case, name, _, _, result, speeds in league_runs(laws, plants):
        time = np.asarray(result.time)
        for i, speed in enumerate(speeds):
            def column(channel: str) -> np.ndarray:
                return np.asarray(result[channel])[:, i]
            noisy = {
                'eps_r': column('eps_r') + rng.normal(0.0, NOISE, time.size),
                'r': column('r') + rng.normal(0.0, NOISE, time.size),
                'v_x': column('v_x') + rng.normal(0.0, SPEED_NOISE, time.size),
                'v_y': column('v_y') + rng.normal(0.0, V_Y_NOISE, time.size),
                'rho': column('rho') + rng.normal(0.0, MAP_NOISE, time.size)}
            for distance in DISTANCES:
                inputs = dict(noisy, lateral=column('y_cg') + distance * column('eps_r')
                              + rng.normal(0.0, LATERAL_NOISE, time.size))
                runs += 1
                where = f'{law_name} {case.name} {name} {speed:g} m/s, d {distance:g} m'
                for mapped in (True, False):
                    given = inputs if mapped else {k: v for k, v in inputs.items()
                                                   if k != 'rho'}
                    off, *scales, lateral_at, yaw_at = check_run(time, given, distance)
                    longest = max(longest, off)
                    read = [*scales, 0.0] if mapped else [0.0, *scales[1:], scales[0]]
                    highs = [max(h, x) for h, x in zip(highs, read)]
                    how = '' if mapped else ' (no map)'
                    if max(scales) >= 2.0:
                        print(f'a scale from 2{how}: {where}: relative yaw {scales[0]:.2f}, '
                              f'lateral error {scales[1]:.2f}, its inverse {scales[2]:.2f}')
                    if lateral_at is not None or yaw_at is not None:
                        false_tells += 1
                        print(f'TOLD AS IT IS{how}: {where}: lateral error at {lateral_at}, '
                              f'relative yaw at {yaw_at}')
                faults = []
                for fault, factors in FAULTS.items():
                    wrong = dict(inputs, **{k: f * inputs[k] for k, f in factors.items()})
                    if factors.get('rho') == 0.0:
                        del wrong['rho']            # no map
                    ats = [x for x in check_run(time, wrong, distance)[4:] if x is not None]
                    at = min(ats) if ats else None      # either told
                    told[fault] += at is not None
                    faults.append(f'{fault} ' + (f'{at:.1f} s' if at is not None
                                                 else 'not told'))
                print(f'{where}: ' + ', '.join(faults), flush=True)
    hold = LaneScaleCheck().settings.hold
    print(f'runs: {runs}; the longest out of scale as it is: {longest:.2f} s (told: '
          f'{hold:g} s)')
    settings = LaneScaleCheck().settings
    print(f'largest scales as they are: relative yaw {highs[0]:.2f} (without a map '
          f'{highs[3]:.2f}), lateral error {highs[1]:.2f}, its inverse {highs[2]:.2f} '
          f'(told: {settings.scale_limit:g}, the relative yaw without a map '
          f'{settings.free_limit:g}, the inverse {1.0 / settings.small_limit:g})')
    print(f'told as it is: {false_tells}; told: ' + ', '.join(
        f'{fault} {count} of {runs}' for fault, count in told.items()))
    return 1 if false_tells else 0


if __name__ == '__main__':
    sys.exit(main())
