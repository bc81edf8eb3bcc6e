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
The CG's move when ``lane_keeping.*`` is set mid-arc: bumpless retune against a rebuild.

``python -m bench.retune_jump``: S2 at 37 m/s (offline runner), ``integral_gain`` 0.3 ->
0.35 at 8 s (on the arc since 3.5 s), on the goal plant (nonlinear, 20 ms, sensor noise,
seeds 0-7) and on the nonlinear plant with the cornering stiffnesses x0.7 (the law's
model unchanged). Per plant: the largest ``|y_cg|`` difference from the run without the
set over the 3 s after it, for the retune (the new law takes over the old one's state,
as the node now does) and for a rebuild (a fresh law, as the node did before).
``--mass FACTOR``: the law's model mass times FACTOR is set instead (a ``vehicle.*``
set; its settings unchanged).
"""

from __future__ import annotations

from dataclasses import replace
import sys
from typing import Any, Optional, Sequence

from lookahead_control.core.control_law import LateralState, LawOutput
from lookahead_control.core.lane_keeping import CgCompensatedLaw, LaneKeepingParams
from lookahead_control.core.params import ControllerParams, VehicleParams
import numpy as np
from sim_plant.closed_loop_sim import run
from sim_plant.sensors import NoiseParams
from sim_plant.vehicle_model import PlantParams

AT = 8.0            # [s] when the parameter is set (S2's arc starts at 3.5 s)
AFTER = 3.0         # [s] the window measured after it
SEEDS = list(range(8))


class SetAt:
    """A ``cg_compensated`` law whose settings are set at ``AT``: retuned or rebuilt."""

    def __init__(self, vehicle: VehicleParams, settings: LaneKeepingParams,
                 new: Optional[LaneKeepingParams], carry: bool,
                 new_vehicle: Optional[VehicleParams] = None) -> None:
        """
        Create the law.

        :param vehicle: the law's model.
        :param settings: its settings at the start.
        :param new: the settings set at ``AT`` (None: never set).
        :param carry: take over the old law's state (else a fresh law, the dt of its
            first step 0, as the node's rebuild was).
        :param new_vehicle: the law's model set at ``AT`` with ``new`` (None: unchanged).
        """
        self.vehicle, self.new, self.carry = vehicle, new, carry
        self.new_vehicle = new_vehicle or vehicle
        self.controller = ControllerParams()
        self.law = CgCompensatedLaw(vehicle, self.controller, settings)
        self.time = 0.0
        self.done = False
        self.integral = 0.0     # [m] at the set

    def start(self) -> None:
        """Start a run from rest."""
        self.law.start()
        self.time, self.done = 0.0, False

    def reset(self) -> None:
        """Restart the law."""
        self.law.reset()

    def step(self, state: LateralState, preview: Any, dt: float) -> LawOutput:
        """
        Step the law, set at ``AT``.

        :param state: the measured state.
        :param preview: the curvature ahead.
        :param dt: the time since the last step [s].
        :return: the law's output.
        """
        self.time += dt
        if not self.done and self.time >= AT - 1e-9:
            self.integral = float(self.law.integral)
        if self.new is not None and not self.done and self.time >= AT - 1e-9:
            law = CgCompensatedLaw(self.new_vehicle, self.controller, self.new)
            law.reset()
            if self.carry:
                law.take_over(self.law)
            else:
                dt = 0.0
            self.law = law
        if self.time >= AT - 1e-9:
            self.done = True
        return self.law.step(state, preview, dt)


def jumps(plant: PlantParams, plant_vehicle: Optional[VehicleParams], delay: float,
          noise: Optional[NoiseParams], seeds: Sequence[int],
          mass: Optional[float] = None) -> dict[str, list[float]]:
    """
    Return the CG's largest move from the run without the set, per seed.

    :param plant: the plant.
    :param plant_vehicle: the plant's vehicle (None: the law's).
    :param delay: transport delay [s].
    :param noise: sensor noise (None: ideal).
    :param seeds: noise seeds.
    :param mass: set the law's model mass times this instead of ``integral_gain``.
    :return: ``retune`` and ``rebuild``: one value per seed [m]; ``integral``: the
        integral at the set [m].
    """
    from lookahead_control.tools.compare import load_scenarios
    scenario = load_scenarios(['s2_curve_entry'])['s2_curve_entry']
    vehicle = VehicleParams()
    base = LaneKeepingParams()
    tuned = replace(base, integral_gain=0.35) if mass is None else base
    new_vehicle = None if mass is None else replace(vehicle, mass=vehicle.mass * mass)
    out: dict[str, list[float]] = {'retune': [], 'rebuild': [], 'integral': []}
    for seed in seeds:
        series = {}
        for name, new, carry in (('none', None, True), ('retune', tuned, True),
                                 ('rebuild', tuned, False)):
            law = SetAt(vehicle, base, new, carry, new_vehicle)
            result = run(scenario, vehicle, law, plant, initial_speed=37.0, delay=delay,
                         noise=noise, seed=seed, plant_vehicle=plant_vehicle,
                         preview_distance=50.0)
            series[name] = (np.asarray(result.time), np.asarray(result['y_cg']))
            if name == 'none':
                out['integral'].append(law.integral)
        t, none = series['none']
        window = (t >= AT) & (t <= AT + AFTER)
        for name in ('retune', 'rebuild'):
            out[name].append(float(np.max(np.abs(series[name][1][window] - none[window]))))
    return out


def main(argv: Optional[Sequence[str]] = None) -> int:
    """
    Print the table.

    :param argv: command line (``--mass FACTOR``; None: the process's).
    :return: 0.
    """
    import argparse
    p = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    p.add_argument('--mass', type=float, default=None, metavar='FACTOR')
    args = p.parse_args(argv)
    nonlinear = PlantParams(model='nonlinear')
    soft = replace(VehicleParams(), c_f=VehicleParams().c_f * 0.7,
                   c_r=VehicleParams().c_r * 0.7)
    cases = (('goal plant (nonlinear, 20 ms, noise; seeds 0-7)', nonlinear, None, 0.02,
              NoiseParams(), SEEDS),
             ('nonlinear, C x0.7', nonlinear, soft, 0.0, None, [0]))
    print('| plant | integral at 8 s [cm] | CG move, rebuild (before) [cm] | '
          'CG move, retune (now) [cm] |')
    print('|---|---|---|---|')
    for name, plant, plant_vehicle, delay, noise, seeds in cases:
        got = jumps(plant, plant_vehicle, delay, noise, seeds, args.mass)

        def text(values: list[float]) -> str:
            if len(values) == 1:
                return f'{100 * values[0]:.2f}'
            return (f'{100 * float(np.mean(values)):.2f} (max '
                    f'{100 * float(np.max(values)):.2f})')
        print(f'| {name} | {text(got["integral"])} | {text(got["rebuild"])} | '
              f'{text(got["retune"])} |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
