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

"""The node's output stage in the offline runner (core/output_stage.py) against the node's."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st
from lookahead_control.bags.run_data import controller_from_params
from lookahead_control.core.config import load_controller, load_lane_keeping, load_vehicle
from lookahead_control.core.lane_keeping import CgCompensatedLaw
from lookahead_control.core.laws import PaperLaw
from lookahead_control.core.output_stage import NodeOutputStage
from lookahead_control.core.safety import limit, limit_batch, SafetyParams
from lookahead_control.core.samples import (CurvatureSample, LateralErrorSample,
                                            VelocitySample, YawSample)
from lookahead_control.tools import compare
import numpy as np
import pytest
from sim_plant.closed_loop_sim import run
from sim_plant.scenario import load_scenario
from sim_plant.sensors import NoiseParams
from sim_plant.vehicle_model import PlantParams

VEHICLE = load_vehicle(None)
CONTROLLER = load_controller(None)
LANE_KEEPING = load_lane_keeping(None)
S1 = load_scenario(compare.SCENARIO_DIR / 's1_paper_step.yaml')

values = st.one_of(st.floats(-1.0, 1.0), st.sampled_from([math.nan, math.inf, -math.inf]))
speeds = st.one_of(st.floats(-40.0, 40.0), st.sampled_from([0.0, 1e-200, math.nan]))


@settings(max_examples=300, deadline=None)
@given(raw=values, previous=st.one_of(st.none(), values), dt=st.sampled_from(
    [0.0, 0.01, 0.02, -1.0, math.nan]), v_x=speeds)
def test_the_batch_limit_is_the_nodes_limit_element_wise(raw, previous, dt, v_x):
    safety = SafetyParams(max_steering_rate=0.5)
    one = limit(raw, previous, dt, v_x, VEHICLE.wheelbase, safety)
    angle, cut = limit_batch(raw, previous, dt, v_x, VEHICLE.wheelbase, safety)
    assert angle == pytest.approx(one.angle, rel=1e-15, abs=0.0)
    assert cut == (one.saturated or one.rate_limited)
    # in a batch, next to other runs
    angles, cuts = limit_batch(np.array([raw, 0.3]), None if previous is None else np.array(
        [previous, math.nan]), dt, np.array([v_x, 20.0]), VEHICLE.wheelbase, safety)
    assert angles[0] == angle and bool(cuts[0]) == cut


@pytest.mark.parametrize('law', ['paper', 'cg_compensated'])
def test_the_stage_sends_what_the_node_sends(law):
    # the node's controller core (checks, law, output stage) against the stage around a
    # second law of the same kind, given the states the core built: equal commands, in
    # and out of the angle limit, the rate limit and the low-speed hand-over
    # (the map check off: 20 mrad of white noise on the relative yaw, ten times the
    # goal's, and lateral-error jumps of 1.5 m are not a car on this map, and the twin
    # has no map check)
    core, _ = controller_from_params({'law': law, 'safety.max_steering_rate': 0.3,
                                      'safety.max_lateral_acceleration': 4.0,
                                      'lane_keeping.map_fallback': 0.0})
    twin = NodeOutputStage(PaperLaw(VEHICLE, CONTROLLER, curvature_rate=False)
                           if law == 'paper' else
                           CgCompensatedLaw(VEHICLE, CONTROLLER, LANE_KEEPING),
                           VEHICLE.wheelbase, core.safety)
    twin.start()
    ahead = ((0.0, 0.0025), (50.0, 0.0025))
    rng = np.random.default_rng(3)
    cut = 0
    first = True
    for k in range(400):
        stamp = 1_000_000_000 + k * 10_000_000
        speed = 37.0 if k < 250 else max(1.0, 37.0 - 0.5 * (k - 250))   # to 1 m/s
        error = 0.4 * math.sin(0.05 * k) + (1.5 if k % 97 < 5 else 0.0)  # with jumps
        for name, sample in (
                ('lateral_error', LateralErrorSample(stamp, VEHICLE.d_s, error)),
                ('yaw', YawSample(stamp, 0.02 * rng.standard_normal(), 0.0925, 0.0)),
                ('velocity', VelocitySample(stamp, speed, 0.1)),
                ('road_curvature', CurvatureSample(stamp, 0.0025, 0.0, ahead))):
            assert core.accept(name, sample, stamp) is None
        command = core.compute(stamp)
        assert command is not None
        out = twin.step(core.state(stamp), core.preview(stamp), 0.0 if first else 0.01)
        first = False
        assert out.steering == command.steering, (k, out.steering, command.steering)
        cut += command.saturated or command.rate_limited
    assert cut > 40         # the limits were met


def test_a_batch_through_the_stage_is_its_single_runs_and_obeys_the_limits():
    # nonlinear plant, 20 ms, noise, 37 m/s: S1's curvature step asks 0.083 rad, the
    # node's angle limit there is atan(30 L / v^2) = 0.0587 rad
    seeds = [compare.run_seed(37.0, k) for k in range(3)]
    common = {'dt': compare.DT, 'delay': 0.02, 'noise': NoiseParams(),
              'preview_distance': compare.PREVIEW_DISTANCE}
    safety = SafetyParams()

    def law():
        return NodeOutputStage(CgCompensatedLaw(VEHICLE, CONTROLLER, LANE_KEEPING),
                               VEHICLE.wheelbase, safety)
    batch = run(S1, VEHICLE, law(), PlantParams(model='nonlinear'),
                initial_speed=np.full(3, 37.0), seed=seeds, **common)
    cap = math.atan(safety.max_lateral_acceleration * VEHICLE.wheelbase / 37.0 ** 2)
    command = batch['steering_cmd']
    assert np.max(np.abs(command)) <= cap + 1e-12
    assert np.max(np.abs(np.diff(command, axis=0))) <= safety.max_steering_rate * 0.01 + 1e-12
    bare = run(S1, VEHICLE, CgCompensatedLaw(VEHICLE, CONTROLLER, LANE_KEEPING),
               PlantParams(model='nonlinear'), initial_speed=np.full(3, 37.0), seed=seeds,
               **common)
    assert np.max(np.abs(bare['steering_cmd'])) > cap + 0.01     # the stage cut this run
    for i in (0, 2):
        single = run(S1, VEHICLE, law(), PlantParams(model='nonlinear'), initial_speed=37.0,
                     seed=seeds[i], **common)
        assert np.array_equal(single['steering_cmd'], command[:, i])
        assert np.array_equal(single['y_cg'], batch['y_cg'][:, i])


def test_the_batch_angle_limit_is_the_nodes_to_the_last_bit():
    # dev-probe57: numpy's vectorized arctan differs from the node's math.atan in the last
    # bit at 141 of 20001 speeds from 3 to 60 m/s (22.25 m/s: 1.4e-17 rad)
    safety = SafetyParams()
    v_x = np.linspace(3.0, 60.0, 20001)
    angles, _ = limit_batch(np.ones_like(v_x), None, 0.0, v_x, VEHICLE.wheelbase, safety)
    node = [limit(1.0, None, 0.0, float(v), VEHICLE.wheelbase, safety).angle for v in v_x]
    assert np.array_equal(angles, node)


def test_the_low_speed_hold_is_the_command_sent_not_the_laws():
    # dev-probe58: above low_speed the node kept the law's command as its hold, before the
    # angle limit; slowing through the hand-over the limit widens, and the hold was sent at
    # a size the car never got (0.6 rad with low_speed 30 m/s); now the command sent
    core, _ = controller_from_params({'law': 'paper', 'safety.low_speed': 30.0,
                                      'safety.low_speed_blend': 1.0,
                                      'safety.max_lateral_acceleration': 4.0})
    twin = NodeOutputStage(PaperLaw(VEHICLE, CONTROLLER, curvature_rate=False),
                           VEHICLE.wheelbase, core.safety)
    twin.start()
    sent_fast, sent_slow = [], []
    for k in range(300):
        stamp = 1_000_000_000 + k * 10_000_000
        speed = 35.0 if k < 100 else 28.0           # then held: below the blend
        for name, sample in (('lateral_error', LateralErrorSample(stamp, VEHICLE.d_s, 1.5)),
                             ('yaw', YawSample(stamp, 0.0, 0.0, 0.0)),
                             ('velocity', VelocitySample(stamp, speed, 0.0))):
            assert core.accept(name, sample, stamp) is None
        command = core.compute(stamp)
        out = twin.step(core.state(stamp), core.preview(stamp), 0.0 if k == 0 else 0.01)
        assert out.steering == command.steering
        (sent_fast if k < 100 else sent_slow).append(command.steering)
        if k == 99:
            raw = command.law.steering
    cap = math.atan(4.0 * VEHICLE.wheelbase / 35.0 ** 2)
    assert abs(raw) > cap + 0.002               # the law asked more than was sent
    assert abs(sent_fast[-1]) == pytest.approx(cap, abs=1e-12)
    assert max(abs(a) for a in sent_slow) <= abs(sent_fast[-1]) + 1e-15
