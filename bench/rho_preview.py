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
The default law without ``road_curvature`` (the curvature estimated), over noise seeds.

The goal plant of ``docs/lane_keeping.md`` ("Without ``road_curvature``"): nonlinear,
20 ms transport delay, default sensor noise, 1 ms steps, the offline law told at every
step that no curvature is received. Per scenario and speed, over the seeds: the peak
``|y_cg|`` and the largest ``|y_cg|`` of the last second (cm, per seed), S0's steering
noise (the command less that of the noise-free twin, std after 1 s, mrad, per seed).
``--set name=value`` changes a ``LaneKeepingParams`` field; ``--tyres`` scales the
plant's cornering stiffness. ``--plant commonroad_mb``: the independent CommonRoad
multi-body plant (vehicle 2, 2 ms steps, the same delay and noise; the law's model its
single-track mapping, as ``compare``'s ``commonroad_mb_delay_noise``).

    PYTHONPATH=$PWD python -m bench.rho_preview --seeds 16 --set estimate_rate_time=0.3
"""

from __future__ import annotations

import argparse
from dataclasses import replace
import json
from typing import Any, Optional, Sequence

from lookahead_control.core.lane_keeping import CgCompensatedLaw, LaneKeepingParams
from lookahead_control.core.params import ControllerParams, VehicleParams
from lookahead_control.tools.compare import load_scenarios
import numpy as np
from sim_plant.closed_loop_sim import run
from sim_plant.sensors import NoiseParams
from sim_plant.vehicle_model import PlantParams


class NoCurvature:
    """The default law, told at every step that no curvature is received."""

    def __init__(self, settings: LaneKeepingParams,
                 vehicle: Optional[VehicleParams] = None) -> None:
        """
        Create the law.

        :param settings: the law's settings.
        :param vehicle: the law's model (None: the package's vehicle).
        """
        self.law = CgCompensatedLaw(vehicle or VehicleParams(), ControllerParams(), settings)

    def reset(self) -> None:
        """Restart the law."""
        self.law.reset()

    def start(self) -> None:
        """Restart for a new run."""
        self.law.start()

    def step(self, state: Any, preview: Any, dt: float) -> Any:
        """
        Step the law without a curvature.

        :param state: the measured state.
        :param preview: ignored (no curvature received).
        :param dt: the step [s].
        :return: the law's output.
        """
        self.law.note_curvature(False)
        return self.law.step(state._replace(rho=0.0 * state.rho,
                                            rho_rate=0.0 * state.rho_rate), None, dt)


def measure(name: str, speeds: Sequence[float], seeds: int, settings: LaneKeepingParams,
            tyres: float = 1.0, plant: str = 'nonlinear') -> list[dict[str, Any]]:
    """
    Run one scenario at every speed and seed (one batch per speed).

    :param name: the scenario.
    :param speeds: speeds [m/s].
    :param seeds: seeds 0 .. seeds - 1.
    :param settings: the law's settings.
    :param tyres: the plant's cornering stiffness over the design's (package plant).
    :param plant: ``nonlinear`` (the goal plant) or ``commonroad_mb`` (vehicle 2).
    :return: one row per speed.
    """
    vehicle = VehicleParams()
    plant_vehicle = replace(vehicle, c_f=vehicle.c_f * tyres, c_r=vehicle.c_r * tyres)
    model, dt = PlantParams(model='nonlinear'), 0.001
    batch: dict[str, Any] = {'plant_vehicle': [plant_vehicle] * seeds}
    single: dict[str, Any] = {'plant_vehicle': plant_vehicle}
    if plant == 'commonroad_mb':
        # its parameters are the CommonRoad set's: the law gets its single-track mapping
        from sim_plant.commonroad_plant import controller_vehicle
        vehicle = controller_vehicle(2)
        model, dt, batch, single = PlantParams(model='commonroad_mb', vehicle_id=2), 0.002, {}, {}
    scenario = load_scenarios([name])[name]
    rows = []
    for speed in speeds:
        result = run(scenario, vehicle, NoCurvature(settings, vehicle), model,
                     initial_speed=np.full(seeds, speed), dt=dt, delay=0.02,
                     preview_distance=100.0, noise=NoiseParams(), seed=list(range(seeds)),
                     **batch)
        t = np.asarray(result.time)
        y = np.abs(np.asarray(result['y_cg'])).reshape(t.size, -1) * 100.0
        peak = y.max(axis=0)
        last = y[t > t[-1] - 1.0].max(axis=0)
        steer = np.asarray(result['steering_cmd']).reshape(t.size, -1)
        # the steering noise: the command less the noise-free twin's, std after 1 s
        twin = run(scenario, vehicle, NoCurvature(settings, vehicle), model,
                   initial_speed=speed, dt=dt, delay=0.02, preview_distance=100.0,
                   **single)
        clean = np.asarray(twin['steering_cmd']).reshape(t.size, 1)
        noise = (steer - clean)[t > 1.0].std(axis=0) * 1000.0
        rows.append({'scenario': name, 'speed': speed, 'peak': peak.tolist(),
                     'last': last.tolist(), 'noise': noise.tolist()})
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    """
    Measure and print the rows as JSON lines.

    :param argv: command line.
    :return: 0.
    """
    p = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    p.add_argument('--scenarios', nargs='+', default=['s0_straight', 's1_paper_step',
                                                      's2_curve_entry', 's3_s_bend',
                                                      's4_lane_change'])
    p.add_argument('--speeds', type=float, nargs='+', default=[10.0, 20.0, 30.0, 37.0])
    p.add_argument('--seeds', type=int, default=16)
    p.add_argument('--tyres', type=float, default=1.0)
    p.add_argument('--plant', choices=('nonlinear', 'commonroad_mb'), default='nonlinear')
    p.add_argument('--set', action='append', default=[], metavar='NAME=VALUE')
    args = p.parse_args(argv)
    if args.plant == 'commonroad_mb' and args.tyres != 1.0:
        p.error(f'--tyres {args.tyres:g}: scales the package plant only (--plant nonlinear)')
    changes: dict[str, Any] = {k: float(v) for k, v in (item.split('=', 1)
                                                        for item in args.set)}
    settings = LaneKeepingParams(**changes)
    for name in args.scenarios:
        for row in measure(name, args.speeds, args.seeds, settings, args.tyres, args.plant):
            row.update(settings=changes, tyres=args.tyres, plant=args.plant)
            print(json.dumps(row), flush=True)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
