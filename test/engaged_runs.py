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


"""The car engaged metres off the lane on a straight: does it come back (shared by tests)."""

from __future__ import annotations

from dataclasses import replace

from lookahead_control.core.config import load_vehicle
from lookahead_control.core.lane_keeping import CgCompensatedLaw, LaneKeepingParams
from lookahead_control.core.params import ControllerParams, VehicleParams
from lookahead_control.tools.compare import DELAY, DT, load_scenarios, PREVIEW_DISTANCE
import numpy as np
from sim_plant.closed_loop_sim import run
from sim_plant.scenario import Scenario
from sim_plant.vehicle_model import PlantParams

VEHICLE = load_vehicle(None)


def straight_lane(seconds: float, heading: float | None = None) -> Scenario:
    """
    Return S0 (a straight lane) cut to ``seconds``, with its initial relative yaw replaced.

    :param seconds: the run's length [s].
    :param heading: the initial relative yaw [rad]; None: the scenario's (0.01 rad).
    :return: the scenario.
    """
    scenario = replace(load_scenarios(['s0_straight'])['s0_straight'], duration=seconds)
    if heading is None:
        return scenario
    return replace(scenario, initial=replace(scenario.initial, relative_yaw=heading))


def engaged_off_the_lane(settings: LaneKeepingParams, plant: PlantParams,
                         speeds: list[float], offset: float | list[float],
                         vehicle: VehicleParams = VEHICLE,
                         law_vehicle: VehicleParams = VEHICLE, dt: float = DT,
                         seconds: float = 20.0, delay: float = DELAY,
                         heading: float | None = None) -> tuple[list[float], np.ndarray]:
    """
    Run the default law engaged ``offset`` metres off a straight lane (no noise).

    :param settings: the law's settings.
    :param plant: the plant.
    :param speeds: one run per speed [m/s].
    :param offset: the CG's initial lateral error [m] (a list: one per speed).
    :param vehicle: the plant's vehicle.
    :param law_vehicle: the law's model.
    :param dt: the plant's step [s].
    :param seconds: the run's length [s].
    :param delay: transport delay [s].
    :param heading: the initial relative yaw [rad] (toward positive y_cg: away from the
        lane for a positive offset); None: the scenario's (0.01 rad).
    :return: the speeds where the CG is not within 5 cm in the last 5 s (or the run
        diverged), and the overshoot past the centre per speed [m].
    """
    scenario = straight_lane(seconds, heading)
    law = CgCompensatedLaw(law_vehicle, ControllerParams(), settings)
    result = run(scenario, vehicle, law, plant, initial_speed=np.array(speeds),
                 initial_error=np.asarray(offset, dtype=float), dt=dt,
                 preview_distance=PREVIEW_DISTANCE, delay=delay)
    late = np.abs(result['y_cg'][result.time >= seconds - 5.0])
    lost = [float(v) for i, v in enumerate(speeds)
            if not np.all(np.isfinite(late[:, i])) or not np.max(late[:, i]) < 0.05]
    return lost, -np.min(result['y_cg'], axis=0)
