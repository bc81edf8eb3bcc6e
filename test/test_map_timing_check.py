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

"""The lead of the curvature read over the yaw measurements (core/map_timing_check.py)."""

from __future__ import annotations

import math
from typing import Optional

from lookahead_control.core.controller import SteeringController
from lookahead_control.core.map_timing_check import (MapTimingCheck, MapTimingParams,
                                                     t_quantile)
from lookahead_control.core.params import ParameterError, VehicleParams
from lookahead_control.tools import compare
import numpy as np
import pytest
from sim_plant.scenario import scenario_from_dict
from sim_plant.sensor_timing import SensorTiming, StreamTiming, timed_run
from sim_plant.sensors import NoiseParams


def _curvature(s: float, radius: float = 300.0) -> float:
    """Return a road's curvature at ``s``: clothoids in and out of an arc, then back."""
    top = 1.0 / radius
    # straight to 50 m, in over 100 m, arc to 300, out over 100 m, straight, and the
    # same to the other side from 500 m
    if s >= 500.0:
        return -_curvature(s - 500.0, radius)
    ramp = [(0.0, 0.0), (50.0, 0.0), (150.0, top), (300.0, top), (400.0, 0.0), (500.0, 0.0)]
    xs, ys = zip(*ramp)
    return float(np.interp(s, xs, ys))


def _feed(check: MapTimingCheck, lead: float, *, v: float = 30.0, bias: float = 0.0,
          scale: float = 1.0, noise: float = 0.0, duration: float = 40.0,
          dt: float = 0.01, radius: float = 300.0, seed: int = 0) -> None:
    """
    Drive the check along the road with exact lane kinematics.

    :param lead: the curvature read this far ahead of the car [m].
    :param bias: a yaw-rate bias [rad/s].
    :param scale: the curvature read times this.
    :param noise: the relative yaw's noise [rad].
    """
    rng = np.random.default_rng(seed)
    for k in range(int(duration / dt) + 1):
        t = k * dt
        s = v * t
        eps_r = 0.004 * math.sin(1.3 * t)
        eps_rate = 0.004 * 1.3 * math.cos(1.3 * t)
        v_y = 0.1 * math.sin(0.9 * t)
        along = v * math.cos(eps_r) - v_y * math.sin(eps_r)
        r = eps_rate + along * _curvature(s, radius)
        check.step(dt if k else math.inf, eps_r + noise * rng.standard_normal(), r + bias, v,
                   scale * _curvature(s + lead, radius), 0.0, v_y)


@pytest.mark.parametrize('lead', [-3.0, -1.0, 0.0, 1.0, 2.5])
def test_the_lead_is_fitted_from_exact_kinematics(lead):
    check = MapTimingCheck()
    _feed(check, lead)
    fitted, error = check.fit()
    assert fitted == pytest.approx(lead, abs=0.02)
    assert error < 0.05
    assert (check.told() is None) == (abs(lead) < check.settings.threshold)


@pytest.mark.parametrize('bias, scale', [(0.005, 1.0), (0.0, 1.2), (-0.003, 0.8)])
def test_a_gyro_bias_or_a_map_off_in_scale_does_not_move_the_lead(bias, scale):
    # the map check's faults: fitted apart, the lead stays the road's
    for lead in (0.0, 2.0):
        check = MapTimingCheck()
        _feed(check, lead, bias=bias, scale=scale)
        assert check.fit()[0] == pytest.approx(lead, abs=0.05), (lead, check.fit())


def test_a_straight_or_an_arc_tells_no_lead():
    for radius in (1e9, 300.0):
        check = MapTimingCheck()
        _feed(check, 3.0, duration=1.6, radius=radius)   # (straight to 50 m at 30 m/s)
        assert check.fit() == (0.0, math.inf) or radius > 1e6
        assert check.told() is None


@pytest.mark.parametrize('seed', range(4))
def test_noise_is_in_the_standard_error_and_not_told(seed):
    # 1 mrad of relative-yaw noise at 100 Hz: the error covers the miss, nothing told
    check = MapTimingCheck()
    _feed(check, 0.0, noise=0.001, seed=seed)
    fitted, error = check.fit()
    assert 0.0 < error < 0.5
    assert abs(fitted) < 3.0 * error
    assert check.told() is None
    shifted = MapTimingCheck()
    _feed(shifted, 2.0, noise=0.001, seed=seed)
    assert shifted.told() == pytest.approx(2.0, abs=3.0 * shifted.fit()[1])


def _drive(check: MapTimingCheck, lead: float = 0.0, glitch=None, duration: float = 120.0,
           v: float = 30.0, seed: int = 0) -> tuple[float, float]:
    """
    Drive the test road again and again with the default sensors' noise and a glitch.

    :return: the seconds told and the largest lead told [m].
    """
    rng = np.random.default_rng(seed)
    dt, told, worst = 0.01, 0.0, 0.0
    for k in range(int(duration / dt) + 1):
        t = k * dt
        s = (v * t) % 1000.0
        eps = 0.004 * math.sin(1.3 * t)
        r = 0.004 * 1.3 * math.cos(1.3 * t) + v * math.cos(eps) * _curvature(s)
        eps += 0.002 * rng.standard_normal()
        r += 0.002 * rng.standard_normal()
        if glitch is not None:
            eps, r = glitch(t, eps, r)
        check.step(dt if k else math.inf, eps, r, v, _curvature((s + lead) % 1000.0))
        lead_told = check.told()
        if lead_told is not None:
            told, worst = told + dt, max(worst, abs(lead_told))
    return told, worst


def FLICKER(t: float, e: float, r: float) -> tuple[float, float]:  # noqa: N802
    """Return the relative yaw flickering by 10 mrad every 5 s."""
    return e + (0.01 if int(t / 5.0) % 2 else 0.0), r


@pytest.mark.parametrize('glitch', [
    lambda t, e, r: (e + (0.02 if t > 3.0 else 0.0), r),       # a relocalization early
    lambda t, e, r: (e + (0.05 if t > 3.0 else 0.0), r),
    lambda t, e, r: (e + (0.05 if t > 36.0 else 0.0), r),      # ... on a curve entry
    FLICKER,                                                    # flickering
    lambda t, e, r: (e + (0.05 if int(t / 5.0) % 2 else 0.0), r),
    lambda t, e, r: (e, r + (0.3 if 3.0 <= t < 3.05 else 0.0)),    # a pothole's spike
    lambda t, e, r: (e, r + (0.6 if 4.0 <= t < 4.05 else 0.0)),
    lambda t, e, r: (e, r + (0.6 if 36.0 <= t < 36.05 else 0.0)),
    lambda t, e, r: (e, 1e6 if 50.0 <= t < 50.01 else r),
], ids=['eps-0.02-at-3', 'eps-0.05-at-3', 'eps-0.05-at-36', 'eps-square-0.01',
        'eps-square-0.05', 'r-0.3-at-3', 'r-0.6-at-4', 'r-0.6-at-36', 'r-1e6'])
def test_a_jump_or_a_spike_is_no_lead(glitch):
    # dev-probe126, before the jumps and the correlation time of 1 s: 26-55 s told with
    # leads of 2-1835 m; each restarts the prediction now
    check = MapTimingCheck()
    told, worst = _drive(check, glitch=glitch)
    assert told == 0.0, (told, worst, check.fit(), check.jumps)
    assert math.isfinite(check.fit()[1]) and abs(check.fit()[0]) < 0.5
    shifted = MapTimingCheck()          # and a lead is told through the same glitch
    told, worst = _drive(shifted, 2.5, glitch=glitch)
    fitted, error = shifted.fit()
    assert fitted == pytest.approx(2.5, abs=max(0.3, 2.0 * error)), shifted.fit()
    # (a flicker of 10 mrad is under the jump limit, about 11 mrad with this noise: no
    # jump, its misses in the blocks' scores, the lead's error 0.47 m: seen, not told)
    assert told > (0.0 if glitch is FLICKER else 60.0), (told, shifted.fit())


def _wandering(lead: float, size: float, time: float, seed: int) -> tuple[float, float]:
    """
    Drive the test road 600 s with a relative-yaw error wandering by ``size`` over ``time``.

    (dev-probe127's drive: one random stream for the white noise and the wander.)

    :return: the seconds told and the fitted lead [m].
    """
    rng = np.random.default_rng(seed)
    check, dt, v, wander, told, next_draw = MapTimingCheck(), 0.01, 30.0, 0.0, 0.0, 0.0
    travelled = 0.0
    for k in range(60001):
        t = k * dt
        travelled += v * dt
        s = travelled % 1000.0
        eps = 0.004 * math.sin(1.3 * t)
        r = 0.004 * 1.3 * math.cos(1.3 * t) + v * math.cos(eps) * _curvature(s)
        wander += (-wander * dt / time
                   + size * math.sqrt(2.0 * dt / time) * rng.standard_normal())
        measured = eps + 0.002 * rng.standard_normal() + wander
        r += 0.002 * rng.standard_normal()
        if t >= next_draw:      # (its drive drew a map noise, here 0, each 0.1 s)
            rng.standard_normal()
            next_draw = t + 0.1
        check.step(dt if k else math.inf, measured, r, v, _curvature((s + lead) % 1000.0))
        told += dt if check.told() is not None else 0.0
    return told, check.fit()[0]


@pytest.mark.parametrize('time', [2.0, 10.0])
def test_a_relative_yaw_wandering_over_seconds_is_no_lead(time):
    # dev-probe127: a relative-yaw error wandering by 3 mrad over 2 or 10 s (beside the
    # white 2 mrad) was told as a lead of 2.4-2.5 m for 11-14 s, 14 s into the drive
    # (seed 2): the standard error took the residual as correlated over 1 s; now also
    # the spread of the blocks' scores, and the confidence of as few blocks as tell it
    told, fitted = _wandering(0.0, 0.003, time, 2)
    assert told == 0.0, (told, fitted)
    told, fitted = _wandering(2.5, 0.003, time, 2)
    assert told > 400.0 and fitted == pytest.approx(2.5, abs=0.9)


@pytest.mark.parametrize('dof, expected', [(1.0, 235.801), (2.0, 19.207), (4.0, 6.620),
                                           (15.0, 3.586), (100.0, 3.077), (1e9, 3.0)])
def test_the_confidence_is_student_s_t_of_the_blocks(dof, expected):
    # (scipy.stats.t.ppf(norm.cdf(3), dof)); dev-probe128: Cornish-Fisher's expansion
    # gave 11.06 / 5.95 at 2 / 4 degrees of freedom, too low
    check = MapTimingCheck()
    assert check.confidence() == math.inf          # nothing fitted
    check._blocks_told = dof
    assert check.confidence() == pytest.approx(expected, abs=2e-3)
    assert t_quantile(2.0, 5.0) == pytest.approx(2.648649, abs=1e-5)
    check._blocks_told = 0.9
    assert check.confidence() == math.inf


def test_no_lead_is_told_without_a_finite_limit():
    # dev-probe128: an error of 0 times an infinite multiple was NaN, and max(threshold,
    # NaN) the threshold: told without a test
    check = MapTimingCheck()
    check._fitted = (5.0, 0.0)
    assert check.confidence() == math.inf and check.told() is None


def test_a_memory_of_too_many_blocks_is_refused():
    # dev-probe128: memory 3600 s in blocks of 0.1 s kept 108001 blocks (102 ms a solve)
    with pytest.raises(ParameterError, match='map_timing.memory = 3600 s is more than 100 '
                                             'blocks of map_timing.block = 0.1 s'):
        MapTimingParams(memory=3600.0, block=0.1)


@pytest.mark.parametrize('r', [1e300, 1e150])
def test_a_wild_yaw_rate_neither_blinds_nor_fools_the_fit(r):
    # dev-probe126: one yaw rate of 1e300 after a fit made the sums inf, the standard
    # error 0 and a lead of 165 m told for good; a huge other value blinded it until a
    # restart
    check = MapTimingCheck()
    _feed(check, 2.0)
    check.step(0.01, 0.0, r, 30.0, 0.001)
    assert check.fit()[0] == pytest.approx(2.0, abs=0.05)
    _drive(check, 0.0, duration=150.0)
    fitted, error = check.fit()
    assert abs(fitted) < 0.3 and 0.0 < error < 0.5 and check.told() is None


def test_bad_steps_restart_the_prediction_and_keep_the_fit():
    check = MapTimingCheck()
    _feed(check, 2.0)
    fitted = check.fit()
    for values in ((0.01, math.nan, 0.0, 30.0, 0.0), (0.01, 0.0, math.inf, 30.0, 0.0),
                   (0.01, 0.0, 0.0, 2.0, 0.0), (5.0, 0.0, 0.0, 30.0, 0.0),
                   (0.0, 0.0, 0.0, 30.0, 0.0)):
        check.step(*values)
    assert check.fit() == fitted
    check.forget()
    assert check.fit() == (0.0, math.inf) and check.told() is None


@pytest.mark.parametrize('field, value', [('leak', 0.0), ('memory', 0.5), ('threshold', 0.0),
                                          ('confidence', -1.0), ('correlation', 11.0),
                                          ('min_speed', math.nan)])
def test_settings_out_of_range_are_refused_by_name(field, value):
    with pytest.raises(ParameterError, match=f'map_timing.{field}'):
        MapTimingParams(**{field: value})


#: S-bends of R 250 m on clothoids of 60-100 m, then a straight, again and again
S_BENDS = [{'type': 'clothoid', 'length': 60.0, 'curvature_start': 0.0, 'curvature_end': 0.004},
           {'type': 'arc', 'length': 150.0, 'curvature': 0.004},
           {'type': 'clothoid', 'length': 100.0, 'curvature_start': 0.004,
            'curvature_end': -0.004},
           {'type': 'arc', 'length': 150.0, 'curvature': -0.004},
           {'type': 'clothoid', 'length': 60.0, 'curvature_start': -0.004, 'curvature_end': 0.0},
           {'type': 'straight', 'length': 400.0}]


def _timed(offset: float, v: float = 30.0, seed: int = 0, scenario: str = 's3_s_bend',
           duration: float = 40.0, phases: Optional[list] = None) -> SteeringController:
    """
    Return the default law's core after a drive with the IMU's (and camera's) clock ahead.

    :param scenario: a league scenario, or ``'s_bends'``: :data:`S_BENDS` for
        ``duration`` seconds (speed ``phases`` as a scenario file gives them).
    """
    timing = SensorTiming(lateral_error=StreamTiming(100.0, 0.0, 0.0, offset),
                          yaw=StreamTiming(100.0, 0.0, 0.0, offset),
                          velocity=StreamTiming(50.0, 0.0),
                          road_curvature=StreamTiming(10.0, 0.0))
    if scenario == 's_bends':
        road = scenario_from_dict({'scenario': {
            'name': 's_bends', 'duration': duration,
            'speed': {'initial': v, **({'phases': phases} if phases else {})},
            'road': [{'type': 'straight', 'length': 50.0}] + S_BENDS * 6}})
    else:
        road = compare.load_scenarios([scenario])[scenario].at_speed(v)
    core = compare.node_core('cg_compensated', VehicleParams(), compare.LawSettings())
    timed_run(road, core, timing, compare.NONLINEAR, dt=0.005, delay=0.02,
              noise=NoiseParams(), seed=seed)
    return core


@pytest.mark.parametrize('offset, v, expected', [(0.09, 30.0, 2.7), (0.05, 37.0, 1.85),
                                                 (-0.09, 37.0, -1.65)])
def test_the_core_tells_an_imu_clock_off_the_map_s(offset, v, expected):
    # dev-probe125: an IMU clock 50 / 90 ms ahead of the map's read every curve 1.9 / 3.3
    # m early at 37 m/s (S3 2.7 -> 17.0 / 31.1 cm) and nothing told it. Behind, a polygon
    # newer than the yaw sample is read as it is: the 10 Hz map's 0-90 ms of age (45 ms
    # on average), the tenth of the polygons older than the yaw moved to it (90 ms)
    core = _timed(offset, v, scenario='s_bends')
    told = core.map_lead_seen
    assert core.turning['curvature_early_or_late'] > 5.0 and told is not None
    assert told[0] == pytest.approx(expected, abs=0.3)
    assert told[1] == pytest.approx(v, abs=0.5)
    # what compare's notes say of the run (its section 'What the controller's checks
    # told')
    said = compare.checks_told(core)
    assert said.startswith('the controller told: ') and 'curvature_early_or_late' in said
    assert (f'road_curvature read {abs(told[0]):.2f} m '
            f'{"ahead of" if offset > 0 else "behind"} the car') in said


@pytest.mark.parametrize('scenario', ['s_bends', 's1_paper_step', 's2_curve_entry',
                                      's3_s_bend', 's4_lane_change'])
def test_the_core_does_not_tell_synchronized_clocks(scenario):
    core = _timed(0.0, 37.0, scenario=scenario)
    fitted, error = core.map_timing.fit()
    assert core.turning['curvature_early_or_late'] == 0.0 and core.map_lead_seen is None
    # (one curve entry, S1 / S2, is fewer blocks than the three parameters fitted: no
    # standard error)
    assert abs(fitted) < max(0.2, 2.0 * error)
    assert (error < 0.5) == (scenario not in ('s1_paper_step', 's2_curve_entry'))


def test_a_stopping_car_tells_no_lead_it_no_longer_fits():
    # dev-probe127: braking from 30 m/s to 0.55 m/s after a lead was told, the told
    # seconds grew from 8.0 to 17.5 with nothing fitted below 5 m/s, and the WARN would
    # have said 4910 ms at 0.55 m/s (at 0 m/s the node's division raised)
    core = _timed(0.09, 30.0, scenario='s_bends', duration=45.0,
                  phases=[{'start': 35.0, 'duration': 9.5, 'acceleration': -3.1}])
    lead, v_x = core.map_lead_seen
    assert lead == pytest.approx(2.7, abs=0.3) and v_x >= 5.0
    moving = _timed(0.09, 30.0, scenario='s_bends', duration=35.0)
    # (the seconds of the last 10 s: only those above 5 m/s, about 8 of them)
    assert (core.turning['curvature_early_or_late']
            - moving.turning['curvature_early_or_late']) < 8.5


def test_the_node_warns_of_a_curvature_read_early_once(active_controller):
    from diagnostic_msgs.msg import DiagnosticStatus
    node = active_controller
    status = node.diagnostics()
    assert 'road_curvature read' not in status.message
    values = {v.key: v.value for v in status.values}
    assert values['road_curvature lead [m]'] == 'unknown'
    assert values['curvature_early_or_late [s]'] == '0.000'
    node.core.turning['curvature_early_or_late'] += 0.4      # under TURNING_WARN
    node.core.map_lead_seen = (1.92, 37.0)
    assert 'road_curvature read' not in node.diagnostics().message
    node.core.turning['curvature_early_or_late'] += 1.3
    node.core.map_lead_seen = (1.92, 37.0)
    status = node.diagnostics()
    assert status.level == DiagnosticStatus.WARN
    assert ('road_curvature read 1.92 m ahead of the car, 52 ms at 37 m/s, for 1.30 s '
            '(fitted over the curve entries and exits' in status.message)
    assert "the IMU stamped on a clock ahead of the map's by about that" in status.message
    assert 'Every law turns in that much early' in status.message
    assert 'road_curvature read' not in node.diagnostics().message      # told once
    node.core.turning['curvature_early_or_late'] += 0.6
    # the speed of the fit, not the car's now (dev-probe126: 1600 ms at 1.2 m/s)
    node.core.map_lead_seen = (-1.5, 30.0)
    message = node.diagnostics().message
    assert 'read 1.50 m behind the car, 50 ms at 30 m/s' in message
    assert "behind the map's by that or more" in message
    node.core.turning['curvature_early_or_late'] += 0.6
    node.core.map_lead_seen = (2.0, 0.0)        # (dev-probe127: a division by 0 raised)
    assert 'read 2.00 m ahead of the car, for 0.60 s' in node.diagnostics().message
