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

"""A map far off dropped by the controller core: the default law on its own estimate."""

from __future__ import annotations

from typing import Any

from lookahead_control.core.controller import SteeringController
from lookahead_control.core.lane_keeping import LaneKeepingParams
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
from lookahead_control.core.safety import SafetyParams
from lookahead_control.core.samples import (curvature_from_points, CurvatureSample,
                                            LateralErrorSample, VelocitySample, YawSample)
import numpy as np
import pytest
from sim_plant.closed_loop_sim import check_steps, linear_plant_stepper, measure
from sim_plant.road import Road, Segment
from sim_plant.scenario import Scenario
from sim_plant.speed_profile import SpeedProfile
from sim_plant.vehicle_model import PlantParams

SPEED = 30.0
PERIOD = 0.01


def _s_bend(v: float = SPEED, acceleration: float = 3.0) -> Scenario:
    """Return an S-bend at ``acceleration`` laid out for ``v`` (clothoids, arcs, a reversal)."""
    k = acceleration / v ** 2
    road = Road([Segment('straight', 2 * v), Segment('clothoid', 1.5 * v, 0.0, k),
                 Segment('arc', 3 * v, k, k), Segment('clothoid', 2 * v, k, -k),
                 Segment('arc', 3 * v, -k, -k), Segment('clothoid', 1.5 * v, -k, 0.0),
                 Segment('straight', 6 * v)])
    return Scenario('s_bend', 16.0, road, SpeedProfile(v))


def _map(stamp: int, scenario: Scenario, s: float, scale: float = 1.0) -> CurvatureSample:
    """
    Return the road's curvature 0-50 m ahead of arc length ``s``, every 5 m, as received.

    :param scale: the map's factor on the road's curvature.
    """
    return curvature_from_points(stamp, [(float(d), scale * float(scenario.road.curvature(
        s + d)[0])) for d in np.arange(0.0, 50.01, 5.0)])


def _core_on_s_bend(law: str, speed: float = SPEED, acceleration: float = 3.0,
                    seed: int = 1) -> tuple[Scenario, SteeringController, Any, int, int,
                                            np.random.Generator]:
    """
    Set up the controller core with the default settings and the linear plant on the S-bend.

    :return: the scenario, the core, the plant's stepper (2 ms substeps), the substeps
        and control steps (10 ms) of the run, and a noise generator seeded ``seed``.
    """
    scenario, vehicle = _s_bend(speed, acceleration), VehicleParams()
    core = SteeringController(vehicle, ControllerParams(), 'imu', False, SafetyParams(), law,
                              None, LaneKeepingParams())
    stepper = linear_plant_stepper(scenario, vehicle, PlantParams(), speed, 0.0)
    substeps, n_steps = check_steps(0.002, PERIOD, scenario.duration)
    return scenario, core, stepper, substeps, n_steps, np.random.default_rng(seed)


def _loop(scale: float, fallback: float, sent: Any = None) -> dict[str, float]:
    """
    Run the controller core and the linear plant with the map at ``scale`` times the road.

    :param sent: ``t -> bool``, whether the curvature is sent at ``t`` (None: always).
    :return: the peak CG error [m], the core's seconds dropped and disagreeing, the
        share of steps the law ran on its own estimate, and the steps it ran on the map
        after the first drop and before 12 s.
    """
    scenario, vehicle = _s_bend(), VehicleParams()
    core = SteeringController(vehicle, ControllerParams(), 'imu', False, SafetyParams(),
                              'cg_compensated', None, LaneKeepingParams(map_fallback=fallback))
    stepper = linear_plant_stepper(scenario, vehicle, PlantParams(), SPEED, 0.0)
    substeps, n_steps = check_steps(0.002, PERIOD, scenario.duration)
    x = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    peak, estimated, mapped = 0.0, 0, 0
    for k in range(n_steps):
        stamp = int(round(k * PERIOD * 1e9))
        inputs = measure(x, k * PERIOD, scenario, SPEED, 0.0)
        core.accept('yaw', YawSample(stamp, x[2], x[4], float(inputs.a_x) - x[3] * x[4]),
                    stamp)
        core.accept('velocity', VelocitySample(stamp, float(inputs.v_x), x[3]), stamp)
        if sent is None or sent(k * PERIOD):
            core.accept('road_curvature', _map(stamp, scenario, x[0], scale), stamp)
        core.accept('lateral_error', LateralErrorSample(stamp, 0.0, x[1]), stamp)
        command = core.compute(stamp)
        on_estimate = int(dict(core.law.debug_values())['curvature_estimated'])
        estimated += on_estimate
        # (the S-bend's curves end at 13 s: a map x-1 of the straight after them is right)
        mapped += bool(core.turning['curvature_dropped']) and not on_estimate and k < 1200
        peak = max(peak, abs(x[1]))
        x = stepper(x, k * PERIOD, 0.002, substeps, command.steering)
    return {'peak': peak, 'dropped': core.turning['curvature_dropped'],
            'disagrees': core.turning['curvature_disagrees'], 'estimated': estimated / n_steps,
            'mapped_after_drop': mapped}


@pytest.mark.parametrize('scale', [0.0, -1.0, 2.0])
def test_sc35_a_map_far_off_is_dropped_and_the_car_stays_near_the_lane(scale):
    # dev-probe73 / dev-sc35: the map check told a wrong map but the law took it as the
    # truth. Here (linear plant, 30 m/s) a map that says straight, the other way or twice
    # the curve put the CG 2.5-6.0 m off; dropped at the default 2.5 x the threshold
    # 0.64-0.82 m (3 x: 0.72-0.93 m; 1 x: 0.34-0.46 m, but a gyro bias of 0.3 deg/s would
    # drop the map too)
    kept = _loop(scale, 0.0)
    dropped = _loop(scale, LaneKeepingParams().map_fallback)
    assert kept['dropped'] == 0.0 and kept['estimated'] == 0.0 and kept['disagrees'] > 5.0
    assert kept['peak'] > 1.0, kept
    assert dropped['dropped'] > 5.0 and dropped['estimated'] > 0.3, dropped
    assert dropped['peak'] < 0.35 * kept['peak'] and dropped['peak'] < 0.9, (dropped, kept)


def test_sc35_the_right_map_is_never_dropped_and_the_run_is_the_same():
    right, off = _loop(1.0, LaneKeepingParams().map_fallback), _loop(1.0, 0.0)
    assert right == off and right['dropped'] == 0.0 and right['estimated'] == 0.0
    assert right['peak'] < 0.05, right


@pytest.mark.parametrize('value', [0.5, -1.0, 101.0])
def test_sc35_a_fallback_between_0_and_1_or_out_of_range_is_refused_by_name(value):
    with pytest.raises(ParameterError, match='lane_keeping.map_fallback'):
        LaneKeepingParams(map_fallback=value)


def test_probe76_a_wrong_map_lost_for_moments_stays_dropped_when_it_is_back():
    # dev-probe76: the curvature missing for 0.3-0.5 s every 1-3 s (over input_timeout,
    # 0.2 s): each return restarted the check and the wrong map steered again for 0.24 s
    def sent(t):
        return t < 4.0 or (t % 2.0) < 1.6         # 0.4 s missing every 2 s from 4 s
    run = _loop(-1.0, LaneKeepingParams().map_fallback, sent)
    assert run['dropped'] > 5.0 and run['mapped_after_drop'] == 0, run
