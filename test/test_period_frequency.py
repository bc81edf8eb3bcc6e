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
The loop's w_n at a slow camera (dev-sc56): ``lane_keeping.frequency_lag``.

A lateral error answered once a frame holds each command for the frame, a lag of the
loop that grows with the period. Over the mismatch grid (the stiff, light car with 50 ms
of delay at 37 m/s) w_n 7 rings at 30 Hz and slower; the law cuts w_n to
``natural_frequency (0.01 + frequency_lag) / (T + frequency_lag)`` at its answer period
``T``, the cap moving at ``FREQUENCY_RATE``.
"""

from dataclasses import replace
import math

from lookahead_control.bags.run_data import as_it_ran
from lookahead_control.core.control_law import LateralState
from lookahead_control.core.lane_keeping import (CgCompensatedLaw, FREQUENCY_RATE,
                                                 LaneKeepingParams, loop_gains,
                                                 period_frequency, settings_at_period)
from lookahead_control.core.laws import Preview
from lookahead_control.core.param_schema import LANE_KEEPING_SPECS
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
from lookahead_control.tools import compare
import numpy as np
import pytest
from test_filtered_stability import _light_stiff_car_on_a_straight

VEHICLE = VehicleParams()
CONTROLLER = ControllerParams()
EMPTY = Preview(np.zeros(0), np.zeros(0))


def test_the_cap_follows_the_period_down_to_the_low_speed_w_n():
    settings = LaneKeepingParams()
    for fast in (0.0, 0.005, 0.01):                 # none measured yet, or 100 Hz and up
        assert period_frequency(settings, fast) == 7.0
    assert period_frequency(settings, 0.05) == pytest.approx(7.0 * 0.21 / 0.25)   # 5.88
    assert period_frequency(settings, 1 / 30) == pytest.approx(7.0 * 0.21 / (0.2 + 1 / 30))
    assert period_frequency(settings, 0.1) == 5.0   # 4.9: not below low_speed_frequency
    assert period_frequency(replace(settings, frequency_lag=0.0), 0.05) == 7.0     # off
    # w_n constant on speed (low_speed_frequency at or above natural_frequency): its
    # lowest w_n is natural_frequency, which the cap does not go below
    assert period_frequency(replace(settings, low_speed_frequency=9.0), 0.05) == 7.0
    assert period_frequency(replace(settings, natural_frequency=4.0), 0.05) == 4.0
    # each interval counts at most 0.2 s in the law's period: the cap stops there too
    # (dev-probe131: the tool cut w_n at 0.25 s deeper than the law ran)
    low = replace(settings, low_speed_frequency=3.0)
    assert period_frequency(low, 0.25) == period_frequency(low, 0.2) == pytest.approx(
        7.0 * 0.21 / 0.4)
    law = CgCompensatedLaw(VEHICLE, CONTROLLER, low)
    _caps(law, [0.25] * 40)
    assert law.frequency == pytest.approx(period_frequency(low, 0.25))


@pytest.mark.parametrize('changes', [{}, {'frequency_speed': 20.0},
                                     {'low_speed_frequency': 3.0, 'frequency_lag': 0.1},
                                     {'natural_frequency': 5.0, 'low_speed_frequency': 9.0},
                                     {'frequency_lag': 0.0}])
def test_the_settings_at_a_period_are_the_law_s_gains_there(changes):
    # the stability tool checks settings_at_period; the law runs loop_gains with its cap
    settings = replace(LaneKeepingParams(), **changes)
    speeds = np.linspace(1.0, 45.0, 177)
    for period in (0.0, 0.01, 0.02, 1 / 30, 0.05, 0.0667, 0.1, 0.2):
        at = settings_at_period(settings, period)
        law = loop_gains(settings, speeds, period_frequency(settings, period))
        np.testing.assert_allclose(loop_gains(at, speeds), law, rtol=1e-12)
        if period_frequency(settings, period) >= settings.natural_frequency:
            assert at is settings


def test_the_parameter_is_declared_configured_and_checked():
    assert LaneKeepingParams().frequency_lag == 0.2
    spec = {s.name: s for s in LANE_KEEPING_SPECS}['lane_keeping.frequency_lag']
    assert (spec.default, spec.low, spec.high) == (0.2, 0.0, 10.0)
    settings = compare.load_law_settings(compare.ROOT / 'config' / 'controller.yaml')
    assert settings.lane_keeping.frequency_lag == 0.2
    for bad in (-0.1, 11.0, math.nan, 1e-9, 0.05):
        with pytest.raises(ParameterError, match='frequency_lag'):
            LaneKeepingParams(frequency_lag=bad)
    # dev-probe131: a tiny lag was accepted and cut the deepest; 0 is off, else 0.1-10 s
    with pytest.raises(ParameterError, match=r'allowed: 0 \(w_n not cut\) or 0.1-10 s'):
        LaneKeepingParams(frequency_lag=0.01)
    assert LaneKeepingParams(frequency_lag=0.1).frequency_lag == 0.1


def _state(k, dt):
    """Return an open-loop state wobbling about a straight lane at 37 m/s."""
    t = k * dt
    return LateralState(0.05 * math.sin(3.0 * t), 0.002 * math.cos(2.0 * t), 0.1, 0.0,
                        37.0, 0.0, 0.0, 0.0)


def _caps(law, intervals):
    """Step the law over the intervals; return its cap after each step."""
    caps, t = [], 0.0
    for dt in intervals:
        t += dt
        law.step(_state(round(t / 0.01), 0.01), EMPTY, dt)
        caps.append(law.frequency)
    return np.array(caps)


def test_the_cap_moves_at_its_rate_and_a_late_frame_does_not_step_the_gain():
    law = CgCompensatedLaw(VEHICLE, CONTROLLER, LaneKeepingParams())
    assert law.frequency == 7.0
    caps = _caps(law, [0.05] * 30)          # a 20 Hz camera from the start
    assert np.diff(caps[:5]) == pytest.approx([-FREQUENCY_RATE * 0.05] * 4)
    assert caps[-1] == pytest.approx(5.88)
    assert dict(law.debug_values())['frequency_cap'] == pytest.approx(5.88)
    # one frame 0.2 s late among 10 ms ones: the period is 0.107 s for 20 steps (the cap's
    # target 5 rad/s), the cap dips to 6.2 at 2 rad/s per second and comes back
    law = CgCompensatedLaw(VEHICLE, CONTROLLER, LaneKeepingParams())
    caps = _caps(law, [0.01] * 30 + [0.2] + [0.01] * 60)
    assert caps[:30] == pytest.approx([7.0] * 30)
    assert caps.min() == pytest.approx(7.0 - FREQUENCY_RATE * 0.39) and caps[-1] == 7.0
    assert caps[30] == pytest.approx(7.0 - FREQUENCY_RATE * 0.2)   # over the late frame
    assert np.max(np.abs(np.diff(caps[31:]))) == pytest.approx(FREQUENCY_RATE * 0.01)


def _retuned(old, **changes):
    """Return a law with other settings that took over from ``old``, and its log."""
    new = CgCompensatedLaw(VEHICLE, CONTROLLER, replace(old.settings, **changes))
    new.reset()
    carried, _ = new.take_over(old)
    return new, carried


def test_restarts_and_retunes_keep_the_cut():
    law = CgCompensatedLaw(VEHICLE, CONTROLLER, LaneKeepingParams())
    _caps(law, [0.05] * 30)
    law.step(_state(0, 0.05), EMPTY, 5.0)           # a time jump restarts the law ...
    assert law.resets == 1 and law.frequency == pytest.approx(5.88)   # ... not the cap
    # a retune carries the cut as a share of natural_frequency: 9 at 20 Hz is 7.56 at once
    new, carried = _retuned(law, natural_frequency=9.0)
    assert new.frequency == pytest.approx(9.0 * 5.88 / 7.0) and 'w_n cut' in carried
    assert _caps(new, [0.05] * 5)[-1] == pytest.approx(period_frequency(new.settings, 0.05))
    # switched off: the uncut law at once (as a bag of the law before the cut re-runs)
    off, carried = _retuned(law, frequency_lag=0.0)
    assert off.frequency == 7.0 and 'w_n cut' not in carried
    assert np.all(_caps(off, [0.05] * 30) == 7.0)
    lower, _ = _retuned(law, natural_frequency=5.5)
    assert lower.frequency == pytest.approx(5.0)    # 5.5 x 0.84 = 4.62: its floor
    # dev-probe131: at 100 Hz (uncut) a raised natural_frequency took a second to arrive
    # (the cap carried as 7 rose at 2 rad/s per second; an older bag with that set
    # re-ran 6 mrad off): it runs at once
    for lag in (0.2, 0.0):
        fast = CgCompensatedLaw(VEHICLE, CONTROLLER, LaneKeepingParams(frequency_lag=lag))
        _caps(fast, [0.01] * 30)
        raised, carried = _retuned(fast, natural_frequency=9.0)
        assert raised.frequency == 9.0 and 'w_n cut' not in carried


def test_a_new_run_forgets_the_answer_period():
    # dev-probe131: start() (the offline runner's, before each run) kept the period and
    # the cut: two 20 Hz runs of one law object were 5.2 mrad apart
    law = CgCompensatedLaw(VEHICLE, CONTROLLER, LaneKeepingParams())

    def run():
        law.start()
        return [float(law.step(_state(k, 0.05), EMPTY, 0.05 if k else 0.0).steering)
                for k in range(40)]
    first = run()
    assert law.frequency == pytest.approx(5.88) and law.hold_time > 0.0
    assert run() == first


def test_at_100_hz_the_law_is_unchanged():
    # answered 100 times a second the cap is natural_frequency: the league's figures stand
    on = CgCompensatedLaw(VEHICLE, CONTROLLER, LaneKeepingParams())
    off = CgCompensatedLaw(VEHICLE, CONTROLLER, LaneKeepingParams(frequency_lag=0.0))
    for k in range(400):
        a = on.step(_state(k, 0.01), EMPTY, 0.01 if k else 0.0)
        b = off.step(_state(k, 0.01), EMPTY, 0.01 if k else 0.0)
        assert float(a.steering) == float(b.steering)
    assert on.frequency == 7.0 and on.period == 0.01


def test_a_slow_camera_s_ring_settles_with_the_cut():
    # the stiff, light car at 37 m/s with 50 ms through the node's core on the nonlinear
    # plant, each frame answered: w_n 7 rings (measured 44.9 / 40.6 / 25.1 mrad rms at
    # 20 / 25 / 30 Hz); with the cut (5.88 / 6.125 / 6.30 rad/s) it settles
    for hz in (20.0, 30.0):
        assert _light_stiff_car_on_a_straight(0.05, hz=hz, frequency_lag=0.0) > 0.02
        assert _light_stiff_car_on_a_straight(0.05, hz=hz) < 1e-3


def test_the_stability_check_runs_the_cut_loop(capsys, tmp_path):
    import json

    from lookahead_control.tools.lane_keeping_tool import stability_main
    report = tmp_path / 'cut.json'
    assert stability_main(['--samples', '21', '--period', '0.05', '--json', str(report)]) == 0
    out = capsys.readouterr().out
    assert ('at an answer period of 0.05 s the law cuts w_n at 5.88 rad/s '
            '(natural_frequency 7, frequency_lag 0.2 s)') in out
    # dev-probe131: the JSON report did not say the cut, nor the line its floor
    data = json.loads(report.read_text())
    assert (data['natural_frequency'], data['frequency_lag_s']) == (7.0, 0.2)
    assert data['frequency_cap_at_period'] == pytest.approx(5.88)
    assert stability_main(['--samples', '21', '--period', '0.1']) == 0
    assert 'cuts w_n at 5 rad/s (its floor, low_speed_frequency)' in capsys.readouterr().out
    off = tmp_path / 'off.yaml'
    off.write_text('/**:\n  ros__parameters:\n    lane_keeping:\n      frequency_lag: 0.0\n')
    assert stability_main(['--samples', '21', '--period', '0.05', '--controller',
                           str(off)]) == 1
    out = capsys.readouterr().out
    assert 'cuts w_n' not in out and 'robust check with the filter DOES NOT HOLD' in out
    # at 100 Hz nothing is cut
    assert stability_main(['--samples', '21']) == 0
    assert 'cuts w_n' not in capsys.readouterr().out


def test_a_bag_of_an_older_controller_re_runs_without_the_cut():
    filled = as_it_ran({'use_curvature_preview': True, 'law': 'cg_compensated'})
    assert filled['lane_keeping.frequency_lag'] == 0.0
    assert 'lane_keeping.frequency_lag' not in as_it_ran(
        {'use_curvature_preview': True, 'lane_keeping.frequency_lag': 0.2})


def test_replay_says_a_20_hz_bag_predates_the_cut(tmp_path, capsys, monkeypatch):
    from test_rerun_lost_curvature import check_a_20_hz_bag_predating
    # the default's cut is another law at 20 Hz
    check_a_20_hz_bag_predating('lane_keeping.frequency_lag', 0.2, tmp_path, capsys,
                                monkeypatch, **{'lane_keeping.hold_preview': 0.5})


def test_compare_at_a_camera_s_timing_says_what_the_checks_find(tmp_path, capsys):
    # the nominal runs of `compare --camera` cannot tell whether a car within the
    # mismatch ranges rings at that timing: it says what the sampled checks find, with the
    # tool's command (the 20 Hz camera 50 ms late, the goal's 20 ms: fails, cut or not)
    from sim_plant.sensor_timing import SensorTiming, StreamTiming
    names = ('nonlinear', 'nonlinear_delay_noise')
    plants = [case for case in compare.PLANTS if case.name in names]
    late = SensorTiming(StreamTiming(20.0, 0.05))
    holds, line = compare.timing_check(VEHICLE, compare.LawSettings(), late, plants, [37.0])
    assert not holds and 'DOES NOT HOLD' in line
    assert ('answered every 0.05 s, delays 0.05, 0.07 s, w_n cut to 5.88 rad/s' in line
            and '`lane_keeping_stability --period 0.05 --delays 0.05 0.07`' in line)
    # 30 ms late (50 ms with the goal's 20): the cut holds it; uncut, it rings (the test
    # above: 45 mrad rms at 50 ms)
    frame = SensorTiming(StreamTiming(20.0, 0.03))
    assert compare.timing_check(VEHICLE, compare.LawSettings(), frame, plants, [37.0])[0]
    uncut = compare.LawSettings(lane_keeping=LaneKeepingParams(frequency_lag=0.0))
    holds, line = compare.timing_check(VEHICLE, uncut, frame, plants, [37.0])
    assert not holds and 'w_n cut' not in line
    # a 50 Hz timer answering a 50 Hz camera: a frame waits up to a tick, delay
    timer = replace(compare.LawSettings(), mode='timer', rate_hz=50.0)
    line = compare.timing_check(VEHICLE, timer, SensorTiming(StreamTiming(50.0, 0.0)),
                                plants, [37.0])[1]
    assert 'answered every 0.02 s, delays 0, 0.02, 0.04 s' in line
    # the league's head says it, and stderr when it fails
    out = tmp_path / 'cmp'
    assert compare.main(['--laws', 'cg_compensated', '--scenarios', 's1_paper_step',
                         '--speeds', '37', '--plants', 'nonlinear_delay_noise', '--camera',
                         '20/0.05', '--duration', '1', '--out', str(out), '--no-plots',
                         '--no-progress', '--workers', '1']) == 0
    assert 'DOES NOT HOLD' in capsys.readouterr().err
    assert '**Checked: the loop of cg_compensated at this timing' in (
        out / 'league.md').read_text()


def _agrees(line, holds, tmp_path):
    """Run the tool's command the line prints; return whether its verdict is compare's."""
    import shlex

    from lookahead_control.tools.lane_keeping_tool import stability_main
    command = shlex.split(line.split('; `')[-1].split('`')[0])
    assert command[0] == 'lane_keeping_stability'
    # (the shipped Q: no search of a P for the heavy car, whose loop fails anyway)
    verdict = stability_main(command[1:] + ['--samples', '21', '--shipped-q-only']) == 0
    return verdict == holds


def test_the_tool_s_command_compare_prints_checks_what_compare_checked(tmp_path, capsys):
    # dev-probe132: the printed command gave the other verdict with a timer (the tick
    # added twice), another --vehicle (left out) and other speeds (compare checked the
    # speeds run, the tool its envelope)
    from sim_plant.sensor_timing import SensorTiming, StreamTiming
    names = ('nonlinear', 'nonlinear_delay_noise')
    plants = [case for case in compare.PLANTS if case.name in names]
    timer_file = tmp_path / 'timer.yaml'
    timer_file.write_text('/**:\n  ros__parameters:\n    mode: timer\n    rate_hz: 50.0\n')
    timer = replace(compare.LawSettings(), mode='timer', rate_hz=50.0)    # the file's
    holds, line = compare.timing_check(VEHICLE, timer, SensorTiming(StreamTiming(50.0, 0.0)),
                                       plants, [37.0], timer_file)
    assert 'delays 0, 0.02, 0.04 s' in line and '--delays 0 0.02 --controller' in line
    assert _agrees(line, holds, tmp_path)
    heavy_file = tmp_path / 'heavy car.yaml'
    heavy_file.write_text('/**:\n  ros__parameters:\n    vehicle:\n      mass: 2500.0\n'
                          '      yaw_inertia: 5000.0\n')
    heavy = replace(VEHICLE, mass=2500.0, yaw_inertia=5000.0)
    holds, line = compare.timing_check(heavy, compare.LawSettings(),
                                       SensorTiming(StreamTiming(25.0, 0.03)), plants, [37.0],
                                       vehicle_file=heavy_file)
    assert not holds and "--vehicle '" in line and _agrees(line, holds, tmp_path)
    for speeds in ([10.0, 20.0], [45.0]):
        holds, line = compare.timing_check(VEHICLE, compare.LawSettings(),
                                           SensorTiming(StreamTiming(25.0, 0.035)), plants,
                                           speeds)
        assert _agrees(line, holds, tmp_path), line
    assert '--v-max 45' in line and 'at 10, 15, 20, 25, 30, 37, 45 m/s' in line
    # delays to 1 ms half up, as the tool (compare rounded 12.5 ms to 12)
    line = compare.timing_check(VEHICLE, compare.LawSettings(),
                                SensorTiming(StreamTiming(20.0, 0.0125)), plants[:1],
                                [37.0])[1]
    assert '--delays 0.013`' in line


def test_compare_says_what_its_timing_check_leaves_out(tmp_path):
    from sim_plant.sensor_timing import SensorTiming, StreamTiming
    plants = [case for case in compare.PLANTS if case.name == 'nonlinear']
    # dev-probe132: a yaw 10 Hz 0.2 s late was said to be checked as the frame's
    yaw = SensorTiming(yaw=StreamTiming(10.0, 0.2))
    line = compare.timing_check(VEHICLE, compare.LawSettings(), yaw, plants, [37.0])[1]
    assert "the yaw, velocity and curvature streams' own rates and latencies are not" in line
    frame = SensorTiming(StreamTiming(20.0, 0.0), with_frame=True)
    assert 'streams' not in compare.timing_check(VEHICLE, compare.LawSettings(), frame,
                                                 plants, [37.0])[1]
    # a camera slower than max_gap: the law restarts at every frame (it printed a radius
    # of 1.705 and a command the tool refused)
    holds, line = compare.timing_check(VEHICLE, compare.LawSettings(),
                                       SensorTiming(StreamTiming(3.0, 0.0)), plants, [37.0])
    assert not holds and 'no loop to check' in line and 'radius' not in line


def test_a_retune_at_the_cut_s_floor_takes_the_new_cut():
    # dev-probe132: at 0.15 s frames (the cap at its 5 rad/s floor) natural_frequency 7 ->
    # 9 carried the share, 6.43, above the new cut at that period, 5.4
    law = CgCompensatedLaw(VEHICLE, CONTROLLER, LaneKeepingParams())
    _caps(law, [0.15] * 20)
    assert law.frequency == 5.0
    new, _ = _retuned(law, natural_frequency=9.0)
    assert new.frequency == pytest.approx(9.0 * 0.21 / 0.35)
