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

"""Benchmarks 1 and 4: the control law alone, and the offline batch simulation."""

from __future__ import annotations

import time
import timeit

from bench.common import median, Result
from lookahead_control.core.control_law import LateralState, steering_law
from lookahead_control.core.params import ControllerParams, VehicleParams
import numpy as np
from sim_plant.closed_loop_sim import run
from sim_plant.scenario import paper_scenario


def core_step(quick: bool = False) -> Result:
    """
    Time one full law evaluation (eq. 26 schedule, eq. 15 law) next to an empty call.

    :param quick: fewer calls.
    :return: the result.
    """
    vehicle, controller = VehicleParams(), ControllerParams()
    state = LateralState(y_cg=0.1, eps_r=0.01, v_y=0.1, r=0.02, v_x=25.0, a_x=0.3,
                         rho=-0.0025, rho_rate=0.0)

    def empty(state: LateralState, vehicle: VehicleParams,
              controller: ControllerParams) -> None:
        return None

    number, repeat = (20_000, 5) if quick else (100_000, 15)
    law, base = [], []
    for _ in range(repeat):            # interleaved: both see the same machine load
        law.append(timeit.timeit(lambda: steering_law(state, vehicle, controller),
                                 number=number) / number * 1e9)
        base.append(timeit.timeit(lambda: empty(state, vehicle, controller),
                                  number=number) / number * 1e9)
    value, baseline = median(law), median(base)
    return Result('1_core_step', 'control law + schedule, one call', value, 'ns',
                  'empty call with the same arguments', baseline, value / baseline,
                  '<= 2 us per call', value <= 2000.0, repeat, (min(law), max(law)),
                  {'calls_per_repetition': number, 'law_ns': law, 'empty_ns': base,
                   'law_minus_empty_ns': value - baseline})


def batch(quick: bool = False) -> Result:
    """
    Time 1000 runs x 10 s at 1 kHz (plant and control), vectorized vs the scalar loop.

    The scalar loop is timed on a few runs and scaled to 1000.

    :param quick: 100 runs and 1 scalar run.
    :return: the result.
    """
    runs, scalar_runs, repeat = (100, 1, 1) if quick else (1000, 3, 3)
    scenario = paper_scenario(30.0)
    vehicle, controller = VehicleParams(), ControllerParams()
    speeds = np.linspace(15.0, 37.0, runs)
    errors = np.linspace(-0.5, 0.5, runs)
    vector, scalar = [], []
    for _ in range(repeat):
        start = time.perf_counter()
        out = run(scenario, vehicle, controller, dt=0.001, control_period=0.001,
                  initial_speed=speeds, initial_error=errors)
        vector.append(time.perf_counter() - start)
        start = time.perf_counter()
        for k in range(scalar_runs):
            one = run(scenario, vehicle, controller, dt=0.001, control_period=0.001,
                      initial_speed=float(speeds[k]), initial_error=float(errors[k]))
        scalar.append((time.perf_counter() - start) / scalar_runs * runs)
    # the batch computes what the scalar loop does
    difference = float(np.max(np.abs(out['y_cg'][:, scalar_runs - 1] - one['y_cg'])))
    value, baseline = median(vector), median(scalar)
    return Result('4_batch', f'{runs} runs x 10 s at 1 kHz, vectorized', value, 's',
                  f'scalar loop, {scalar_runs} runs timed and scaled to {runs}', baseline,
                  value / baseline, '<= 10 s for 1000 runs',
                  value <= 10.0 * runs / 1000, repeat, (min(vector), max(vector)),
                  {'runs': runs, 'steps': int(out.time.size), 'vector_s': vector,
                   'scalar_scaled_s': scalar, 'max_abs_diff_vs_scalar_m': difference})
