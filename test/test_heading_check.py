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

"""The heading check (``core/heading_check.py``) and the controller core's answer to it."""

from __future__ import annotations

import math

from lookahead_control.core.controller import SteeringController
from lookahead_control.core.heading_check import HeadingCheck, HeadingCheckParams
from lookahead_control.core.lane_keeping import LaneKeepingParams
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
from lookahead_control.core.safety import SafetyParams
from lookahead_control.core.samples import (curvature_from_points, LateralErrorSample,
                                            VelocitySample, YawSample)
import numpy as np
import pytest
from sim_plant.closed_loop_sim import check_steps, linear_plant_stepper, measure
from sim_plant.vehicle_model import PlantParams
from test_map_fallback import _s_bend      # the S-bend of the map check's tests

PERIOD, SPEED = 0.01, 30.0


def _weave(lateral_sign: float = 1.0, yaw_sign: float = 1.0, distance: float = 0.0,
           v_y_sent: bool = True, seconds: float = 8.0, seed: int = 3) -> HeadingCheck:
    """
    Run the check on a car weaving in its lane on a curve (sideslip in it), default noise.

    :param lateral_sign: the factor on the lateral error sent.
    :param yaw_sign: the factor on the relative yaw sent.
    :param distance: where the lateral error is measured [m].
    :param v_y_sent: whether the lateral speed is sent (else exactly 0).
    """
    rng = np.random.default_rng(seed)
    check, y = HeadingCheck(), 0.0
    for k in range(int(seconds / PERIOD)):
        t = k * PERIOD
        eps = 0.008 * math.sin(2.0 * math.pi * 0.3 * t) - 0.003   # a steady sideslip ...
        v_y = 0.003 * SPEED + 0.05 * math.sin(2.0 * math.pi * 0.7 * t)  # ... and a swing
        y += (SPEED * math.sin(eps) + v_y * math.cos(eps)) * PERIOD
        sent_y = lateral_sign * (y + distance * eps + rng.normal(0.0, 0.03))
        check.step(PERIOD, sent_y, distance, yaw_sign * (eps + rng.normal(0.0, 0.002)),
                   SPEED, (v_y + rng.normal(0.0, 0.02)) if v_y_sent else 0.0)
    return check


@pytest.mark.parametrize('distance', [0.0, 20.0])
def test_a_lateral_error_that_follows_the_relative_yaw_is_never_opposed(distance):
    check = _weave(distance=distance)
    assert not check.opposed and check.correlation > 0.9, check.correlation
    assert check.verdict() == ''


@pytest.mark.parametrize('distance', [0.0, 20.0])
@pytest.mark.parametrize('flipped', ['lateral_error', 'relative_yaw'])
def test_either_sign_flipped_is_opposed(flipped, distance):
    check = _weave(lateral_sign=-1.0 if flipped == 'lateral_error' else 1.0,
                   yaw_sign=-1.0 if flipped == 'relative_yaw' else 1.0, distance=distance)
    assert check.opposed and check.correlation < -0.9, check.correlation
    assert 'the sign of relative_yaw or of lateral_error wrong' in check.verdict()


def test_a_lateral_speed_of_exactly_zero_is_no_witness():
    # a bridge without v_y: the sideslip left out of the prediction runs against the
    # lateral error where the car tracks the lane (dev-sc45: -0.91 in a lane change)
    check = _weave(lateral_sign=-1.0, v_y_sent=False)
    assert not check.opposed and math.isnan(check.correlation)


def test_too_little_motion_is_not_judged():
    # the lateral error's noise alone (3 cm) is under the excitation (5 cm band-passed)
    rng = np.random.default_rng(2)
    check = HeadingCheck()
    for _ in range(800):
        check.step(PERIOD, -rng.normal(0.0, 0.03), 0.0, rng.normal(0.0, 0.002), SPEED,
                   rng.normal(0.0, 0.02))
    assert math.isnan(check.correlation) and not check.opposed


def test_a_slow_car_a_gap_or_a_bad_value_restarts_it():
    check = _weave(yaw_sign=-1.0)
    assert check.opposed
    assert not check.step(PERIOD, 0.0, 0.0, 0.0, 2.0, 0.1) and not check.opposed
    check = _weave(yaw_sign=-1.0)
    assert not check.step(1.5, 0.0, 0.0, 0.0, SPEED, 0.1) and not check.opposed
    check = _weave(yaw_sign=-1.0)
    assert not check.step(PERIOD, math.inf, 0.0, 0.0, SPEED, 0.1) and not check.opposed


@pytest.mark.parametrize('field, value', [('lag', -1.0), ('washout', 0.15), ('limit', 0.5),
                                          ('excitation', 0.0), ('hold', math.nan)])
def test_its_settings_are_checked(field, value):
    with pytest.raises(ParameterError, match=f'heading_check.{field}'):
        HeadingCheckParams(**{field: value})


def _loop(law: str, flipped: str, acceleration: float, seed: int = 1) -> dict[str, object]:
    """
    Run the controller core and the linear plant at 30 m/s, ``flipped``'s sign wrong from 2 s.

    :return: the core, the first time a command was not the law's, the peak CG error
        before it, and the time the CG was first 1 m off (None: never).
    """
    scenario, vehicle = _s_bend(acceleration=acceleration), VehicleParams()
    core = SteeringController(vehicle, ControllerParams(), 'imu', False, SafetyParams(), law,
                              None, LaneKeepingParams())
    stepper = linear_plant_stepper(scenario, vehicle, PlantParams(), SPEED, 0.0)
    substeps, n_steps = check_steps(0.002, PERIOD, scenario.duration)
    rng = np.random.default_rng(seed)
    x = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    safe_at, peak, off_at = None, 0.0, None
    for k in range(n_steps):
        t = k * PERIOD
        stamp = int(round(t * 1e9))
        inputs = measure(x, t, scenario, SPEED, 0.0)
        preview = [(float(d), float(scenario.road.curvature(x[0] + d)[0]))
                   for d in np.arange(0.0, 50.01, 5.0)]
        eps_sign = -1.0 if t >= 2.0 and flipped == 'relative_yaw' else 1.0
        y_sign = -1.0 if t >= 2.0 and flipped == 'lateral_error' else 1.0
        core.accept('yaw', YawSample(stamp, eps_sign * (x[2] + rng.normal(0.0, 0.002)),
                                     x[4] + rng.normal(0.0, 0.002),
                                     float(inputs.a_x) - x[3] * x[4]), stamp)
        core.accept('velocity', VelocitySample(stamp, float(inputs.v_x),
                                               x[3] + rng.normal(0.0, 0.02)), stamp)
        core.accept('road_curvature', curvature_from_points(stamp, preview), stamp)
        core.accept('lateral_error', LateralErrorSample(
            stamp, 0.0, y_sign * (x[1] + rng.normal(0.0, 0.03))), stamp)
        command = core.compute(stamp)
        if command.law is None and safe_at is None:
            safe_at = t
        if safe_at is None:
            peak = max(peak, abs(x[1]))
        if off_at is None and abs(x[1]) > 1.0:
            off_at = t
        x = stepper(x, t, 0.002, substeps, command.steering)
    return {'core': core, 'safe_at': safe_at, 'peak': peak, 'off_at': off_at}


@pytest.mark.parametrize('law', ['cg_compensated', 'paper', 'stanley'])
@pytest.mark.parametrize('flipped', ['lateral_error', 'relative_yaw'])
def test_the_core_refuses_a_flipped_relative_yaw_or_lateral_error(law, flipped):
    # dev-sc45: with either sign flipped from 2 s every law steered the car out of the
    # lane (off by 1 m 1.4-6.7 s later on straights and S-bends at 20-30 m/s), told only
    # once the lateral error was past 5 m
    run = _loop(law, flipped, acceleration=1.0)
    core = run['core']
    assert core.yaw_fault is not None and 'relative_yaw runs against the lateral error' in \
        core.yaw_fault, core.yaw_fault
    assert 'relative_yaw or of lateral_error wrong' in core.describe_stale(['yaw'])
    assert 2.0 < run['safe_at'] < 8.0, run['safe_at']
    # refused before the car was 1 m off, or at most 0.4 s after (the default law
    # turns a flipped relative yaw into a spin: 2.2 m at the refusal at 30 m/s)
    if run['off_at'] is not None:
        assert run['safe_at'] < run['off_at'] + 0.4, (run['safe_at'], run['off_at'])


@pytest.mark.parametrize('law', ['cg_compensated', 'paper', 'stanley'])
def test_right_signs_are_never_refused(law):
    run = _loop(law, 'nothing', acceleration=3.0)
    assert run['core'].yaw_fault is None and run['safe_at'] is None
