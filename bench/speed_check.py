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
The speed check's margin on the league's runs (``core/speed_check.py``).

``python -m bench.speed_check [LAW,LAW... [PLANT,PLANT...]]``: the laws of ``compare``
given (default the default law and the paper's eq. 26), S0-S5 at 10 / 20 / 30 / 37 m/s,
on the plants given (default the goal plant, the noise-free nonlinear plant and the
CommonRoad multi-body plant with delay and noise; noise seed 11), run as ``compare`` runs
them; then :class:`SpeedCheck` on each run's speed (with a noise of 0.05 m/s, seed 5) and
the road's curvature preview 0-50 m ahead every 5 m (with a noise of 1e-4 1/m), once as
they are and once each with the speed in km/h (x 3.6), in mph (x 2.237) and 3.6 times too
small, where the speed read is under ``safety.max_speed`` (the loop itself is right: a
check of the verdict, not of a car on a wrong speed). Prints each run with when each
fault was told, each run told as it is (none may be), the longest time out of scale as
it is, and how many runs each fault was told in. About 2 minutes on one core.
"""

from __future__ import annotations

import sys
from typing import Sequence

from bench.league_runs import league_runs
from lookahead_control.core.safety import SafetyParams
from lookahead_control.core.speed_check import SpeedCheck
import numpy as np

LAWS = ('cg_compensated', 'paper_eq26')
PLANTS = ('nonlinear_delay_noise', 'nonlinear', 'commonroad_mb_delay_noise')
SPEED_NOISE = 0.05              # [m/s]
MAP_NOISE = 1.0e-4              # [1/m]
AHEAD = np.arange(0.0, 50.01, 5.0)      # [m] the preview's distances (path_bridge's)
FAULTS = {'km/h': 3.6, 'mph': 2.237, '/3.6': 1.0 / 3.6}
MAX_SPEED = SafetyParams().max_speed     # [m/s] faster is refused


def check_run(time: np.ndarray, v_x: np.ndarray, previews: np.ndarray
              ) -> tuple[float, float | None]:
    """
    Run the check along one run.

    :param time: the run's time [s].
    :param v_x: the speed given [m/s].
    :param previews: the curvature preview at each step, shape ``(steps, points)`` [1/m].
    :return: the longest time the speed was out of scale (told at ``hold``) [s], and the
        first time it was told (None: never).
    """
    check = SpeedCheck()
    longest, told = 0.0, None
    for k in range(1, time.size):
        stamp = int(round(float(time[k]) * 1e9))
        out = check.step(stamp, float(v_x[k]), list(zip(AHEAD.tolist(), previews[k].tolist())))
        longest = max(longest, check.off_for)
        if out and told is None:
            told = float(time[k])
    return longest, told


def main(argv: Sequence[str] | None = None) -> int:
    """
    Print the margin.

    :param argv: ``[LAW,LAW... [PLANT,PLANT...]]``.
    :return: 0, or 1 if a speed as it is was told out of scale.
    """
    args = list(sys.argv[1:] if argv is None else argv)
    laws = args[0].split(',') if args else list(LAWS)
    plants = args[1].split(',') if len(args) > 1 else list(PLANTS)
    rng = np.random.default_rng(5)
    false_tells, runs, longest = 0, 0, 0.0
    told = dict.fromkeys(FAULTS, 0)
    judged = dict.fromkeys(FAULTS, 0)
    for law_name, case, name, scenario, _, result, speeds in league_runs(laws, plants):
        time = np.asarray(result.time)
        for i, speed in enumerate(speeds):
            s = np.asarray(result['s'])[:, i]
            v_x = np.asarray(result['v_x'])[:, i] + rng.normal(0.0, SPEED_NOISE, time.size)
            previews = np.asarray(scenario.road.curvature(s[:, None] + AHEAD[None, :])[0],
                                  dtype=float)
            previews = previews + rng.normal(0.0, MAP_NOISE, previews.shape)
            off, at = check_run(time, v_x, previews)
            runs += 1
            longest = max(longest, off)
            where = f'{law_name} {case.name} {name} {speed:g} m/s'
            if at is not None:
                false_tells += 1
                print(f'TOLD AS IT IS: {where} at {at:.2f} s')
            faults = []
            for fault, factor in FAULTS.items():
                if factor * speed > MAX_SPEED:
                    continue            # refused by the range check
                judged[fault] += 1
                at = check_run(time, factor * v_x, previews)[1]
                told[fault] += at is not None
                faults.append(f'{fault} ' + (f'{at:.1f} s' if at is not None else 'not told'))
            print(f'{where}: ' + ', '.join(faults), flush=True)
    hold = SpeedCheck().settings.hold
    print(f'runs: {runs}; the longest out of scale as it is: {longest:.2f} s (told: '
          f'{hold:g} s)')
    print(f'told as it is: {false_tells}; told (runs under safety.max_speed): ' + ', '.join(
        f'{fault} {told[fault]} of {judged[fault]}' for fault in FAULTS))
    return 1 if false_tells else 0


if __name__ == '__main__':
    sys.exit(main())
