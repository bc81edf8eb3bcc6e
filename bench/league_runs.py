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

"""The league's runs as ``compare`` runs them, for the input checks' benches."""

from __future__ import annotations

from typing import Iterator, Sequence

from lookahead_control.core.params import VehicleParams
from lookahead_control.tools import compare
import numpy as np
from sim_plant.closed_loop_sim import run, SimResult
from sim_plant.scenario import Scenario
from sim_plant.sensors import NoiseParams


def league_runs(laws: Sequence[str], plants: Sequence[str]
                ) -> Iterator[tuple[str, compare.PlantCase, str, Scenario, VehicleParams,
                                    SimResult, list[float]]]:
    """
    Run the league's scenarios (S0-S5 at 10 / 20 / 30 / 37 m/s) per law and plant.

    The plant's noise (if any) is seeded 11, as ``compare``.

    :param laws: the laws (names of ``compare.LAWS``).
    :param plants: the plants (names of ``compare.PLANTS``).
    :return: per law, plant and scenario: ``(law, plant case, scenario name, scenario,
        the law's vehicle, the result with one column per speed, the speeds)``.
    """
    vehicle = VehicleParams()
    scenarios = compare.load_scenarios(compare.SCENARIOS)
    cases = [c for c in compare.PLANTS if c.name in plants]
    for law_name in laws:
        for case in cases:
            law_vehicle = case.law_vehicle(vehicle)
            for name, scenario in scenarios.items():
                speeds = compare.scenario_speeds(scenario, compare.SPEEDS)
                law = compare.league_law(law_name, law_vehicle, compare.LawSettings())
                noise = {'noise': NoiseParams(), 'seed': [11] * len(speeds)} if case.noisy else {}
                result = run(scenario, law_vehicle, law, case.plant,
                             initial_speed=np.asarray(speeds, dtype=float),
                             dt=case.dt or compare.DT, delay=case.delay,
                             preview_distance=compare.PREVIEW_DISTANCE, **noise)
                yield law_name, case, name, scenario, law_vehicle, result, list(speeds)
