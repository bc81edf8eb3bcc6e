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
How fast the default law removes a steady side force: a crosswind stepped on.

``python -m bench.crosswind [low_speed_integral_gain ...]``: the goal plant (nonlinear,
20 ms transport delay, default sensor noise, noise seeds 1-8), a straight road (S0's)
for 30 s from the lane centre with no heading error, 5 ms plant steps, a lateral force
of 1 kN on the body from 2 s on; at 10, 20 and 37 m/s, the mean over the seeds of
``|mean y_cg|`` in the windows 2-3, 5-6, 10-11 and 27-28 s after the force came. One
row per ``lane_keeping.low_speed_integral_gain`` given (default: 0.3, the constant
``k_i``, and 0.05, the speed schedule).
"""

from __future__ import annotations

import dataclasses
import sys
from typing import Sequence

from lookahead_control.core.config import load_vehicle
from lookahead_control.core.lane_keeping import CgCompensatedLaw, LaneKeepingParams
from lookahead_control.core.params import ControllerParams
from lookahead_control.tools.compare import load_scenarios
import numpy as np
from sim_plant.closed_loop_sim import run
from sim_plant.sensors import NoiseParams
from sim_plant.vehicle_model import PlantParams

FORCE = 1000.0                  # [N]
ONSET = 2.0                     # [s]
WINDOWS = ((2.0, 3.0), (5.0, 6.0), (10.0, 11.0), (27.0, 28.0))   # [s] after the onset
SPEEDS = (10.0, 20.0, 37.0)
SEEDS = list(range(1, 9))


def crosswind_errors(low_speed_integral_gain: float, speed: float) -> list[float]:
    """
    Return the mean ``|mean y_cg|`` [m] over the seeds in each window after the force.

    :param low_speed_integral_gain: ``lane_keeping.low_speed_integral_gain`` [1/s].
    :param speed: the speed [m/s].
    :return: one value per window of :data:`WINDOWS`.
    """
    vehicle = load_vehicle(None)
    s0 = load_scenarios(['s0_straight'])['s0_straight']
    scenario = dataclasses.replace(s0, duration=ONSET + WINDOWS[-1][1],
                                   initial=dataclasses.replace(s0.initial, relative_yaw=0.0))
    law = CgCompensatedLaw(vehicle, ControllerParams(), LaneKeepingParams(
        low_speed_integral_gain=low_speed_integral_gain))
    result = run(scenario, vehicle, law, PlantParams(model='nonlinear'),
                 initial_speed=np.full(len(SEEDS), speed), dt=0.005, delay=0.02,
                 preview_distance=100.0, noise=NoiseParams(), seed=SEEDS,
                 disturbance=lambda t: (FORCE if t >= ONSET else 0.0, 0.0))
    y, time = np.asarray(result['y_cg']), np.asarray(result.time)
    out = []
    for start, end in WINDOWS:
        inside = (time >= ONSET + start) & (time < ONSET + end)
        out.append(float(np.mean(np.abs(y[inside].mean(axis=0)))))
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """
    Print the table.

    :param argv: ``low_speed_integral_gain`` values (default 0.3 and 0.05).
    :return: 0.
    """
    gains = [float(a) for a in (sys.argv[1:] if argv is None else argv)] or [0.3, 0.05]
    windows = ' / '.join(f'{a:g}-{b:g} s' for a, b in WINDOWS)
    print(f'| low_speed_integral_gain | speed | mean abs CG error [cm], {windows} |')
    print('|---|---|---|')
    for gain in gains:
        for speed in SPEEDS:
            values = ' / '.join(f'{100.0 * e:.1f}' for e in crosswind_errors(gain, speed))
            print(f'| {gain:g} | {speed:g} m/s | {values} |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
