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

"""The default law under biased sensors (dev-probe73): where the CG settles."""

from __future__ import annotations

from lookahead_control.core.config import load_vehicle
from lookahead_control.tools.compare import LawSettings, league_law
import numpy as np
import pytest
from sim_plant.closed_loop_sim import run
from sim_plant.road import Road, Segment
from sim_plant.scenario import Scenario
from sim_plant.speed_profile import SpeedProfile
from sim_plant.vehicle_model import PlantParams

VEHICLE = load_vehicle(None)
SPEED = 30.0


class _Biased:
    """A law fed biased sensors: the relative yaw, v_y (the lateral sensor at d_s)."""

    def __init__(self, law, yaw_bias=0.0, v_y_bias=0.0):
        self.law, self.yaw_bias, self.v_y_bias = law, yaw_bias, v_y_bias

    def __getattr__(self, name):
        if name == 'law':
            raise AttributeError(name)
        return getattr(self.law, name)

    def step(self, state, preview, dt):
        # the lateral error is measured at d_s: y_cg = y_s - d_s eps_r, with eps_r biased
        state = state._replace(y_cg=state.y_cg - VEHICLE.d_s * self.yaw_bias,
                               eps_r=state.eps_r + self.yaw_bias,
                               v_y=state.v_y + self.v_y_bias)
        return self.law.step(state, preview, dt)


def _steady(road, **bias):
    scenario = Scenario('bias', 40.0, road, SpeedProfile(SPEED))
    law = _Biased(league_law('cg_compensated', VEHICLE, LawSettings()), **bias)
    res = run(scenario, VEHICLE, law, PlantParams(model='nonlinear'), dt=0.005,
              control_period=0.01, delay=0.02)
    last = res.time >= 36.0
    return float(np.mean(res['y_cg'][last]))


ROADS = {'straight': Road([Segment('straight', 5000.0)]),
         'arc': Road([Segment('straight', 4 * SPEED),
                      Segment('clothoid', 1.5 * SPEED, 0.0, 3.0 / SPEED ** 2),
                      Segment('arc', 40 * SPEED, 3.0 / SPEED ** 2, 3.0 / SPEED ** 2)])}


@pytest.mark.parametrize('road', sorted(ROADS))
def test_probe73_a_relative_yaw_bias_leaves_the_cg_where_the_lateral_sensor_says(road):
    # dev-probe73: 5 mrad of relative-yaw bias (a camera's mounting) put the CG 4.1 cm
    # to the other side on the goal plant at 30 m/s: the integral summed the state
    # filter's y_cg, which fuses the biased yaw through the kinematics. It sums the
    # measured y_cg now, whose bias is d_s b (the lateral sensor at the bumper): the CG
    # settles there, as the lateral sensor says
    base = _steady(ROADS[road])
    biased = _steady(ROADS[road], yaw_bias=0.005)
    assert biased - base == pytest.approx(VEHICLE.d_s * 0.005, abs=1.5e-3), (base, biased)


@pytest.mark.parametrize('road', sorted(ROADS))
def test_probe73_a_v_y_bias_leaves_the_cg_on_the_lane(road):
    # dev-probe73: 0.05 m/s of v_y bias moved the CG 1.8 cm; the lateral sensor is not
    # biased, so the CG belongs on the lane
    base = _steady(ROADS[road])
    biased = _steady(ROADS[road], v_y_bias=0.05)
    assert abs(biased - base) < 1.5e-3, (base, biased)


@pytest.mark.parametrize('speed', [10.0, 30.0])
def test_probe75_one_lateral_error_far_off_moves_the_integral_by_its_band_only(speed):
    # dev-probe75: with the integral on the measured CG error, one message 2 m off went
    # into the reference's rate k_i y_cg and stepped the command by 50 mrad at 10 m/s
    # (19 before); the measurement is taken within MEASURED_BAND of the filter's estimate
    from lookahead_control.core.control_law import LateralState
    from lookahead_control.core.lane_keeping import (CgCompensatedLaw, integral_gain_at,
                                                     MEASURED_BAND)
    from lookahead_control.core.params import ControllerParams
    law = CgCompensatedLaw(VEHICLE, ControllerParams())
    state = LateralState(0.02, 0.0, 0.0, 0.0, speed, 0.0, 0.0, 0.0)
    for k in range(300):
        law.step(state, None, 0.01 if k else 0.0)
    before, steering = law.integral, law.last_steering
    law.step(state._replace(y_cg=2.02), None, 0.01)
    step = 0.01 * float(integral_gain_at(law.settings, speed))
    # the filter's estimate moves some centimetres toward the spike, the band adds 0.1 m;
    # without the band the step integrates all 2.02 m (0.006 m at 0.3 1/s)
    assert abs(law.integral - before) < step * 0.25, (law.integral - before) / step
    # and the command moves by what the filter makes of it, not by k_i times 2 m more
    law_b = CgCompensatedLaw(VEHICLE, ControllerParams())
    for k in range(300):
        law_b.step(state, None, 0.01 if k else 0.0)
    law_b.step(state._replace(y_cg=0.02 + MEASURED_BAND), None, 0.01)
    assert abs(law.last_steering - steering) < abs(law_b.last_steering - steering) + 0.03
