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
A slow camera's hold in the feedforward preview (dev-sc55): ``lane_keeping.hold_preview``.

A lateral error answered once a frame holds the command for the frame: a 20 Hz camera's
command acts on average 25 ms after it was computed, 20 ms later than the 100 Hz the
preview was tuned at. The law adds ``hold_preview`` times the answer period beyond 10 ms
(over its last step intervals) to ``feedforward_preview``.
"""

from dataclasses import replace
import math

from lookahead_control.bags.run_data import as_it_ran, controller_from_params
from lookahead_control.core.control_law import LateralState
from lookahead_control.core.lane_keeping import (CgCompensatedLaw, hold_extra, HOLD_INTERVALS,
                                                 HOLD_LONGEST, HOLD_TUNED, LaneKeepingParams)
from lookahead_control.core.laws import Preview
from lookahead_control.core.param_schema import LANE_KEEPING_SPECS
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
from lookahead_control.tools import compare
import numpy as np
import pytest
from sim_plant.sensor_timing import SensorTiming, StreamTiming, timed_run

VEHICLE = VehicleParams()
CONTROLLER = ControllerParams()
#: a curve entered along a clothoid, 1/400 m after 60 m
POLYGON = Preview(np.array([0.0, 20.0, 80.0, 300.0]), np.array([0.0, 0.0, 0.0025, 0.0025]))


def test_the_extra_is_the_share_of_the_period_beyond_10_ms():
    assert hold_extra([], 0.5) == 0.0                       # no interval yet
    assert hold_extra([0.05], 0.0) == 0.0                   # switched off
    assert hold_extra([0.01] * HOLD_INTERVALS, 0.5) == 0.0  # the tuned period: nothing
    assert hold_extra([0.005] * 3, 1.0) == 0.0              # faster: never negative
    assert hold_extra([0.05], 0.5) == pytest.approx(0.02)
    assert hold_extra([1 / 30] * 5, 1.0) == pytest.approx(1 / 30 - HOLD_TUNED)
    # a camera stalled for seconds counts at most HOLD_LONGEST
    assert hold_extra([2.0] * 3, 0.5) == pytest.approx(0.5 * (HOLD_LONGEST - HOLD_TUNED))
    # holds of different lengths: the mean delay weighted by the time each is held,
    # sum T^2 / (2 sum T), checked by integrating a command's age over the holds
    holds = np.array([0.045, 0.055, 0.05, 0.1, 0.048, 0.052, 0.05, 0.047, 0.053])
    ages = np.concatenate([np.arange(0.0, t, 1e-6) for t in holds])
    assert hold_extra(holds, 0.5) == pytest.approx(0.5 * (2.0 * ages.mean() - HOLD_TUNED),
                                                   abs=1e-6)


def _rolling(intervals):
    """Return the hold preview after each interval, as the law keeps its window."""
    window, extras = [], []
    for interval in intervals:
        window = (window + [interval])[-HOLD_INTERVALS:]
        extras.append(hold_extra(window, 0.5))
    return np.array(extras)


def test_a_pattern_of_intervals_gives_a_steady_preview():
    # dev-probe129: the median of 9 switched every frame between two values on a pattern
    # (every third frame of a 20 Hz camera lost: 20 and 45 ms by turns; frames in pairs
    # 1 ms apart: 0 and 44.5 ms)
    lost = _rolling([0.05, 0.05, 0.1] * 30)[HOLD_INTERVALS:]
    assert np.ptp(lost) < 0.003 and lost.mean() == pytest.approx(0.5 * (0.075 - 0.01),
                                                                 abs=0.002)
    pairs = _rolling([0.001, 0.099] * 30)[HOLD_INTERVALS:]
    # the frame 1 ms after another is held 1 ms and weighs nothing: the 99 ms holds count
    assert np.ptp(pairs) < 0.001 and pairs.min() > 0.5 * (0.098 - 0.01) - 0.001
    # one lost frame among regular ones moves the preview by about a twentieth of it
    one = _rolling([0.05] * 30 + [0.1] + [0.05] * 30)
    assert one.max() - 0.02 < 0.0035 and one[-1] == pytest.approx(0.02)
    # a 100 Hz camera whose stamps jitter by +-2 ms: a tenth of a millisecond or so
    stamps = np.arange(200) * 0.01 + np.random.default_rng(5).uniform(-0.002, 0.002, 200)
    assert 0.0 < _rolling(np.diff(stamps))[HOLD_INTERVALS:].max() < 3e-4


def test_the_parameter_is_declared_configured_and_checked():
    assert LaneKeepingParams().hold_preview == 0.5
    spec = {s.name: s for s in LANE_KEEPING_SPECS}['lane_keeping.hold_preview']
    assert (spec.default, spec.low, spec.high) == (0.5, 0.0, 1.0)
    settings = compare.load_law_settings(compare.ROOT / 'config' / 'controller.yaml')
    assert settings.lane_keeping.hold_preview == 0.5
    for bad in (-0.1, 1.5, math.nan):
        with pytest.raises(ParameterError, match='hold_preview'):
            LaneKeepingParams(hold_preview=bad)


def _state(k, dt):
    """Return an open-loop state along the clothoid at step ``k``, wobbling about the lane."""
    t = k * dt
    rho = min(max(37.0 * t - 20.0, 0.0) / 60.0, 1.0) * 0.0025
    return LateralState(0.05 * math.sin(3.0 * t), 0.002 * math.cos(2.0 * t), 0.1,
                        37.0 * rho, 37.0, 0.0, rho, 0.0)


def _outputs(settings, dt, steps=60):
    law = CgCompensatedLaw(VEHICLE, CONTROLLER, settings)
    out = []
    for k in range(steps):
        moved = Preview(POLYGON.distances - 37.0 * k * dt, POLYGON.curvatures)
        out.append(float(law.step(_state(k, dt), moved, dt).steering))
    return np.array(out), law


def test_at_20_hz_the_law_is_the_one_with_the_longer_preview_and_at_100_hz_unchanged():
    held, law = _outputs(LaneKeepingParams(), 0.05)
    longer, _ = _outputs(LaneKeepingParams(hold_preview=0.0, feedforward_preview=0.09), 0.05)
    shorter, _ = _outputs(LaneKeepingParams(hold_preview=0.0), 0.05)
    np.testing.assert_allclose(held, longer, rtol=1e-9, atol=1e-12)
    assert np.max(np.abs(held - shorter)) > 1e-4      # the preview does move the command
    assert law.hold_time == pytest.approx(0.02)
    assert dict(law.debug_values())['hold_preview'] == pytest.approx(0.02)
    # answered 100 times a second the default adds nothing: the league's figures stand
    tuned, law = _outputs(LaneKeepingParams(), 0.01, 300)
    off, _ = _outputs(LaneKeepingParams(hold_preview=0.0), 0.01, 300)
    assert np.array_equal(tuned, off) and law.hold_time == 0.0


def test_repeats_restarts_and_retunes_keep_the_answer_period():
    law = CgCompensatedLaw(VEHICLE, CONTROLLER, LaneKeepingParams())
    empty = Preview(np.zeros(0), np.zeros(0))
    for k in range(HOLD_INTERVALS):
        law.step(_state(k, 0.05), empty, 0.05)
        law.step(_state(k, 0.05), empty, 0.0)       # a timer faster than the camera
    assert law.hold_time == pytest.approx(0.02)
    law.step(_state(0, 0.05), empty, 5.0)           # a time jump restarts the law ...
    assert law.resets == 1 and law.hold_time == pytest.approx(0.02)   # ... not the rate
    new = CgCompensatedLaw(VEHICLE, CONTROLLER, LaneKeepingParams(hold_preview=1.0))
    new.reset()
    new.take_over(law)
    assert new.hold_time == pytest.approx(0.04)


def _peak(hz, share, scenario='s1_paper_step'):
    settings = compare.LawSettings()
    settings = replace(settings, lane_keeping=replace(settings.lane_keeping,
                                                      hold_preview=share))
    run = timed_run(compare.load_scenarios([scenario])[scenario].at_speed(37.0),
                    compare.node_core('cg_compensated', VEHICLE, settings),
                    SensorTiming(StreamTiming(hz, 0.0), with_frame=True), compare.NONLINEAR,
                    dt=0.005, delay=compare.DELAY)
    return float(np.max(np.abs(run['y_cg']))), np.asarray(run['steering_cmd'])


def test_a_20_hz_camera_answered_once_a_frame_keeps_the_car_closer_on_the_paper_step():
    # the step's command impulse is held for a 50 ms frame: at 37 m/s on the nonlinear
    # plant with the goal's 20 ms delay the CG went 7.2 cm off the lane, 6.1 with the hold
    # in the preview (100 Hz: 2.7)
    without, _ = _peak(20.0, 0.0)
    held, _ = _peak(20.0, 0.5)
    assert held < without - 0.005, (held, without)
    at_100, commands = _peak(100.0, 0.5)
    assert np.array_equal(commands, _peak(100.0, 0.0)[1]) and at_100 < held


def test_a_bag_from_before_the_hold_preview_re_runs_without_it():
    recorded = {'law': 'cg_compensated', 'use_curvature_preview': True,
                'align_inputs': 'never', 'curvature_at_yaw_stamp': False,
                'lane_keeping.frequency_lag': 0.2}
    assert as_it_ran(recorded) == {'lane_keeping.hold_preview': 0.0}
    core, _ = controller_from_params(recorded)
    assert core.law.settings.hold_preview == 0.0
    core, _ = controller_from_params(recorded, {'lane_keeping.hold_preview': 0.5})
    assert core.law.settings.hold_preview == 0.5
    core, _ = controller_from_params({**recorded, 'lane_keeping.hold_preview': 0.25})
    assert core.law.settings.hold_preview == 0.25


def test_the_sampled_check_at_a_camera_s_period_takes_the_hold_preview():
    # without road_curvature the law previews its own estimate along the estimated rate:
    # the preview time is inside the loop, so a check at another period than 10 ms runs
    # the law's preview at that period (at 10 ms it adds nothing)
    from lookahead_control.core.lane_keeping_stability import filtered_loop, rate_gain
    held = LaneKeepingParams()
    longer = LaneKeepingParams(hold_preview=0.0, feedforward_preview=0.09)
    assert rate_gain(VEHICLE, CONTROLLER, held, 30.0, hold=0.02) == pytest.approx(
        rate_gain(VEHICLE, CONTROLLER, longer, 30.0))
    assert rate_gain(VEHICLE, CONTROLLER, held, 30.0, hold=0.02) != pytest.approx(
        rate_gain(VEHICLE, CONTROLLER, held, 30.0))
    loops = [filtered_loop(VEHICLE, CONTROLLER, settings, 30.0, period=0.05, delay_steps=0,
                           curvature_estimated=True) for settings in (held, longer)]
    np.testing.assert_allclose(loops[0], loops[1], rtol=1e-12, atol=1e-12)
    off = LaneKeepingParams(hold_preview=0.0)
    np.testing.assert_array_equal(
        filtered_loop(VEHICLE, CONTROLLER, held, 30.0, curvature_estimated=True),
        filtered_loop(VEHICLE, CONTROLLER, off, 30.0, curvature_estimated=True))


def test_replay_says_a_20_hz_bag_predates_the_hold_preview(tmp_path, capsys, monkeypatch):
    from test_rerun_lost_curvature import check_a_20_hz_bag_predating
    # the default's preview is another law at 20 Hz
    check_a_20_hz_bag_predating('lane_keeping.hold_preview', 0.5, tmp_path, capsys,
                                monkeypatch, **{'lane_keeping.frequency_lag': 0.2})
