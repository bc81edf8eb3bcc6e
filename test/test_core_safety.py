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

"""The output limits' reference: the last angle sent and the newest stamp sent."""

import math
import random

from lookahead_control.core.controller import SteeringController
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
from lookahead_control.core.safety import check_stamp, SafetyParams, stale_target
from lookahead_control.core.samples import (CurvatureSample, LateralErrorSample, VelocitySample,
                                            YawSample)
import pytest

SAFETY = SafetyParams(max_steering_rate=0.1)
MS = 1_000_000


def _core():
    return SteeringController(VehicleParams(), ControllerParams(), 'imu', True, SAFETY)


def _step(core, stamp, y):
    for name, sample in (('yaw', YawSample(stamp, 0.0, 0.0, 0.0)),
                         ('velocity', VelocitySample(stamp, 25.0, 0.0)),
                         ('lateral_error', LateralErrorSample(stamp, 1.96, y))):
        assert core.accept(name, sample, stamp) is None
    return core.compute()


def test_an_answer_older_than_a_watchdog_command_holds_instead_of_jumping():
    core = _core()
    first = _step(core, 1000 * MS, 0.5).steering
    assert first < -0.005
    # inputs stale: the watchdog holds at t = 1.3 s (stamped with its clock)
    assert core.safe_command(1300 * MS).steering == first
    # a late answer stamped 1.25 s with a very different error: no time has passed on
    # the rate limit's axis since 1.3 s, so it holds
    late = _step(core, 1250 * MS, -0.5)
    assert late.steering == first and late.stamp_ns == 1250 * MS and late.rate_limited
    # 0.1 s past the watchdog command: at most 0.1 rad/s * 0.1 s further
    later = _step(core, 1400 * MS, -0.5)
    assert 0.0 < later.steering - first <= 0.1 * 0.1 + 1e-12


def test_a_time_jump_resets_the_inputs_but_not_the_angle_reference():
    core = _core()
    _step(core, 10_000 * MS, 0.5)
    before = _step(core, 10_010 * MS, 0.5).steering
    # a replay restarts at t = 0: the state resets, the first answer holds the angle
    # the actuator still has, and the next ones move within the rate limit
    after = _step(core, 0, -0.5)
    assert core.time_jumps == 1
    assert after.steering == before
    moved = _step(core, 10 * MS, -0.5).steering
    assert 0.0 < moved - before <= 0.1 * 0.01 + 1e-12


def _live(core, now, stamp=None, y=0.5, v_x=25.0, names=('yaw', 'velocity', 'lateral_error'),
          steady=None):
    """Give one step of inputs received at ``now`` (stamped ``stamp``), then compute."""
    stamp = now if stamp is None else stamp
    samples = {'yaw': YawSample(stamp, 0.0, 0.0, 0.0), 'velocity': VelocitySample(stamp, v_x, 0.0),
               'lateral_error': LateralErrorSample(stamp, 1.96, y)}
    refused = [core.accept(name, samples[name], now) for name in names]
    # as the node: an accepted lateral error is answered
    answered = 'lateral_error' in names and refused[names.index('lateral_error')] is None
    return (core.compute(now, steady) if answered else None), refused


def test_an_input_that_stops_after_a_refusal_is_not_blamed_on_the_refusal():
    # dev-probe37: yaw stamps refused (0.5 s late), then taken again for a second, then
    # yaw stopped: /diagnostics said "stale inputs: yaw (last refused: yaw: stamp 0.500 s
    # behind ...)", a cause a second old; now the input is just stale
    core = _core()
    for k in range(20):                 # 100 Hz from 1000 s, yaw stamped 0.5 s late
        now = (1000_000 + 10 * k) * MS
        _live(core, now, names=('velocity', 'lateral_error'))
        assert 'behind the node clock' in core.accept(
            'yaw', YawSample(now - 500 * MS, 0.0, 0.0, 0.0), now)
    assert 'last refused: yaw: stamp 0.500 s behind' in core.describe_stale(['yaw'])
    for k in range(20, 120):            # a second of good inputs
        _live(core, (1000_000 + 10 * k) * MS)
    for k in range(120, 160):           # yaw stops
        _live(core, (1000_000 + 10 * k) * MS, names=('velocity', 'lateral_error'))
    now = 1001_590 * MS
    assert core.stale(now) == ['yaw']
    assert core.describe_stale(['yaw']) == 'yaw'
    # refused again after the last one taken: the refusal is the cause, and is told
    core.accept('yaw', YawSample(now - 500 * MS, 0.0, 0.0, 0.0), now)
    assert 'last refused: yaw: stamp 0.500 s behind' in core.describe_stale(['yaw'])


def test_stamps_are_judged_on_both_sides_of_the_node_clock():
    params = SafetyParams()                 # input_timeout 0.2 s, max_future 0.1 s
    now = 50_000 * MS
    assert check_stamp('yaw', now - 200 * MS, None, now, params) is None
    assert check_stamp('yaw', now + 100 * MS, None, now, params) is None
    old = check_stamp('yaw', now - 200 * MS - 1, None, now, params)
    assert old.startswith('yaw: stamp 0.200 s behind the node clock')
    new = check_stamp('yaw', now + 100 * MS + 1, None, now, params)
    assert new.startswith('yaw: stamp 0.100 s ahead of the node clock')
    assert 'does not advance' in check_stamp('yaw', now, now, now, params)
    assert 'goes back' in check_stamp('yaw', now - 1, now, now, params)
    # no clock (sim time before the first /clock, offline): only the ordering
    assert check_stamp('yaw', 1, None, None, params) is None


@pytest.mark.parametrize('offset_ms, why', [(200, 'ahead of the node clock'),
                                            (-300, 'behind the node clock')])
def test_a_sensor_clock_off_from_the_start_is_stale_and_told(offset_ms, why):
    # dev-probe97: a sensor clock 0.2 s ahead of the node's from start-up had every input
    # refused; nothing was ever taken, so nothing went stale: the node sent nothing and
    # said only WARN 'rejected: N', never ERROR (before, one good step was needed)
    core = _core()
    for k in range(40):
        now = (1000_000 + 10 * k) * MS
        command, reasons = _live(core, now, stamp=now + offset_ms * MS)
        assert command is None and all(r and why in r for r in reasons)
        stale = core.stale(now)
        # stale from input_timeout (0.2 s) after the first input came in
        assert stale == ([] if 10 * k <= 200 else ['lateral_error', 'yaw', 'velocity']), k
    assert core.describe_stale(['yaw']).startswith(
        f'yaw none taken (last refused: yaw: stamp {abs(offset_ms) / 1000:.3f} s {why}')
    # never commanded: no safe command to send (the car was never steered by it)
    assert core.safe_command(1000_400 * MS) is None
    # the clocks agree again: fresh inputs, the law answers
    now = 1000_400 * MS
    command, reasons = _live(core, now)
    assert reasons == [None, None, None] and command is not None and command.law is not None
    assert core.stale(now) == []


def test_a_sensor_clock_off_by_more_than_the_tolerance_gives_the_safe_behaviour():
    # a node clock at 1000 s, sensors 1.5 s behind it after one good step
    core = _core()
    first, _ = _live(core, 1000_000 * MS)
    refused = []
    for k in range(1, 40):
        now = (1000_000 + 10 * k) * MS
        command, reasons = _live(core, now, stamp=now - 1500 * MS)
        refused += reasons
        assert command is None or command.law is None     # never the law on old data
    assert all(r and 'behind the node clock' in r for r in refused)
    now = 1000_390 * MS
    assert core.stale(now) == ['lateral_error', 'yaw', 'velocity']
    assert 'last refused: yaw: stamp 1.500 s behind' in core.describe_stale(['yaw'])
    # the watchdog holds the last command, then ramps to the safe angle
    assert core.safe_command(now).steering == first.steering
    assert core.safe_command(now + 700 * MS).steering > first.steering


def test_a_dead_yaw_is_never_used_and_answers_do_not_restart_the_hold():
    core = SteeringController(VehicleParams(), ControllerParams(), 'imu', True,
                              SafetyParams(max_steering_rate=0.05, hold_time=0.3))
    t0 = 1000_000 * MS
    for k in range(10):
        good, _ = _live(core, t0 + 10 * k * MS)
    assert good.law is not None and good.steering < -0.005
    # yaw and velocity stop; the lateral error goes on at 100 Hz and keeps changing
    angles = []
    for k in range(10, 200):
        now = t0 + 10 * k * MS
        command, _ = _live(core, now, y=-0.5, names=('lateral_error',))
        stale_for = now - (t0 + 90 * MS)
        if stale_for <= 200 * MS:               # within input_timeout: still the law
            assert command.law is not None
            continue
        assert command.law is None and command.status == 'stale', k
        assert command.stamp_ns == now           # it answers this lateral error
        angles.append((now, command.steering))
    # hold for hold_time from the first safe command, then ramp at the rate limit;
    # the lateral errors answered meanwhile do not restart the hold
    start = angles[0][0]
    held = [a for t, a in angles if t - start <= 300 * MS]
    assert held and all(a == angles[0][1] for a in held)
    assert angles[0][1] > 0.0 and angles[-1][1] == 0.0      # the safe angle
    for (t0_, a0), (t1_, a1) in zip(angles, angles[1:]):
        assert 0.0 <= a0 - a1 <= 0.05 * (t1_ - t0_) * 1e-9 + 1e-15


def test_the_rate_limit_counts_the_node_clock_not_the_stamps():
    core, now = _core(), 1000_000 * MS          # rate limit 0.1 rad/s
    start = _step_at(core, now, now, 0.5)
    # the stamps jump 90 ms ahead (within max_future) while the node's clock moves 10 ms
    jump = _step_at(core, now + 10 * MS, now + 100 * MS, -0.5)
    assert jump.steering - start.steering == pytest.approx(0.1 * 0.010, abs=1e-15)
    # the published rate is the change over the node's clock
    assert jump.steering_rate == pytest.approx(0.1, rel=1e-9)
    # the node's clock stands still: this answer shares the 10 ms step already spent
    # from the last command at an earlier reading, so it holds, whatever the stamps do;
    # its rate is the change since that command over the node-clock time since it
    held = _step_at(core, now + 10 * MS, now + 105 * MS, -0.5)
    assert held.steering == jump.steering and held.rate_limited
    assert held.steering_rate == pytest.approx(0.1, rel=1e-9)
    # and it cannot move faster than the stamps advance either
    slow = _step_at(core, now + 60 * MS, now + 106 * MS, -0.5)
    assert slow.steering - held.steering == pytest.approx(0.1 * 0.001, abs=1e-15)
    assert slow.steering_rate == pytest.approx(0.1 * 0.001 / 0.050, rel=1e-9)


def test_a_step_of_the_system_clock_does_not_open_the_rate_limit():
    core, now, steady = _core(), 1000_000 * MS, 5_000 * MS
    start, _ = _live(core, now, steady=steady)
    # the system clock (and the sensors on it) jumps 10 s ahead; 10 ms pass
    later = now + 10_000 * MS
    jumped, _ = _live(core, later, y=-0.5, steady=steady + 10 * MS)
    assert jumped.steering - start.steering == pytest.approx(0.1 * 0.010, abs=1e-15)


def test_the_node_clock_going_back_holds_once_and_does_not_freeze():
    core, now = _core(), 1000_000 * MS
    start = _step_at(core, now, now, 3.0).steering
    assert start < -0.03
    # stale; after the 0.5 s hold the ramp to 0 runs at 0.1 rad/s
    ramp = [core.safe_command(now + k * 100 * MS).steering for k in range(3, 11)]
    assert ramp[:6] == [start] * 6 and start < ramp[6] < ramp[7]
    # the node's clock goes back 0.5 s: that command holds, the ramp then goes on
    # (it neither restarts the hold nor waits until the clock is back where it was)
    back = core.safe_command(now + 500 * MS).steering
    assert back == ramp[-1]
    on = core.safe_command(now + 600 * MS).steering
    assert on - back == pytest.approx(0.1 * 0.1, abs=1e-15)


def test_a_lost_curvature_counts_as_zero_not_as_its_last_value():
    core, now = _core(), 1000_000 * MS
    assert core.accept('road_curvature', CurvatureSample(now, 0.01, 0.0), now) is None
    with_curve, _ = _live(core, now)
    # curvature silent for more than input_timeout: not stale (optional), but lost
    later = now + 300 * MS
    answer, _ = _live(core, later)
    assert core.stale(later) == [] and core.curvature_lost(later)
    assert answer.law is not None
    zero = SteeringController(VehicleParams(), ControllerParams(), 'imu', True, SAFETY)
    expected, _ = _live(zero, later)
    assert answer.law.steering == expected.law.steering != with_curve.law.steering


def _step_at(core, now, stamp, y):
    for name, sample in (('yaw', YawSample(stamp, 0.0, 0.0, 0.0)),
                         ('velocity', VelocitySample(stamp, 25.0, 0.0)),
                         ('lateral_error', LateralErrorSample(stamp, 1.96, y))):
        assert core.accept(name, sample, now) is None
    return core.compute(now)


def test_inputs_received_after_the_clock_reading_are_stale():
    # the node's clock goes back 0.5 s (under the 1 s jump threshold) with no new
    # input: the inputs were received "in the future", their age is negative
    core, now = _core(), 1000_000 * MS
    _live(core, now)
    assert core.stale(now) == []
    back = now - 500 * MS
    assert core.stale(back) == ['lateral_error', 'yaw', 'velocity']
    assert core.compute(back).status == 'stale'
    assert core.stale(back + 200 * MS) == ['lateral_error', 'yaw', 'velocity']
    # nothing received since: still stale once the clock is past the reception again
    assert core.stale(now + 10 * MS) == ['lateral_error', 'yaw', 'velocity']
    # received again: fresh
    _live(core, now + 20 * MS)
    assert core.stale(now + 20 * MS) == []


def test_inputs_refused_after_a_time_jump_go_stale_and_ramp():
    core, now = _core(), 1000_000 * MS
    start = _step_at(core, now, now, 3.0).steering
    assert start < -0.03
    # the clock goes back 5 s; the sensors stay on the old time line: all refused
    back = now - 5_000 * MS
    _, refused = _live(core, back, stamp=now + 10 * MS)
    assert core.time_jumps == 1 and all(refused)
    assert core.stale(back + 200 * MS) == []            # within input_timeout of the jump
    stale = core.stale(back + 210 * MS)
    assert stale == ['lateral_error', 'yaw', 'velocity']
    assert 'lateral_error none taken (last refused: lateral_error: stamp' in \
        core.describe_stale(stale)
    # hold for hold_time (0.5 s), then ramp to 0 at 0.1 rad/s
    ramp = [core.safe_command(back + k * 100 * MS).steering for k in range(3, 10)]
    assert ramp[:4] == [start] * 4
    assert ramp[-1] - ramp[-2] == pytest.approx(0.1 * 0.1, abs=1e-15)


def test_low_speed_after_a_time_jump_holds_the_last_angle_sent():
    core, now = _core(), 1000_000 * MS
    start = _step_at(core, now, now, 3.0).steering
    assert start < -0.03
    back = now - 5_000 * MS
    for k in range(5):          # 1 m/s: below low_speed - low_speed_blend (2 m/s)
        answer, _ = _live(core, back + k * 10 * MS, y=-3.0, v_x=1.0)
        assert answer.status == 'low_speed' and answer.steering == start
    assert core.time_jumps == 1


def test_hold_time_and_max_future_may_be_zero_and_errors_name_the_parameter():
    params = SafetyParams(hold_time=0.0, max_future=0.0, max_steering_rate=0.1)
    # hold_time 0: the ramp starts at once
    assert stale_target(0.3, 0.0, params) == 0.3
    assert stale_target(0.3, 0.5, params) == pytest.approx(0.25, abs=1e-15)
    # max_future 0: a stamp at the clock is used, one nanosecond ahead is refused
    assert check_stamp('yaw', 10 * MS, None, 10 * MS, params) is None
    assert 'ahead of the node clock' in check_stamp('yaw', 10 * MS + 1, None, 10 * MS,
                                                    params)
    for name in ('input_timeout', 'max_steering_rate', 'hold_time', 'max_future'):
        with pytest.raises(ParameterError, match=f'^safety.{name} = '):
            SafetyParams(**{name: -1.0})
    with pytest.raises(ParameterError, match=r'^safety.input_timeout = 0.0 .*\(0, '):
        SafetyParams(input_timeout=0.0)


def _sim_time_run(readings, law='cg_compensated', y_of=None, safety=None, period=10 * MS):
    """
    Answer steps stamped ``t_k`` (every ``period``) on a sim clock reading ``readings[k]``.

    As in a realtime run on ``use_sim_time``: the /clock of step k may be processed
    before or after its lateral error, so two answers can see one clock reading. A
    straight road's curvature (0) comes with every step, as from ``sim_plant``: without
    it the default law estimates the curvature and its want follows a jump in the
    lateral error more slowly (these tests are about the rate limit).
    """
    core = SteeringController(VehicleParams(), ControllerParams(), 'imu', True,
                              safety or SafetyParams(), law=law)
    y_of = y_of or (lambda t: 0.3 * math.sin(0.5 * t) + 0.05)
    out = []
    for k, now in enumerate(readings):
        stamp = 100_000 * MS + period * k
        t = stamp * 1e-9
        samples = {'yaw': YawSample(stamp, 0.01 * math.cos(0.5 * t), 0.0, 0.0),
                   'velocity': VelocitySample(stamp, 25.0, 0.0),
                   'road_curvature': CurvatureSample(stamp, 0.0, 0.0),
                   'lateral_error': LateralErrorSample(stamp, 1.96, y_of(t))}
        refused = [core.accept(name, samples[name], now)
                   for name in ('yaw', 'velocity', 'road_curvature', 'lateral_error')]
        assert refused == [None] * 4 or stamp > now + core.safety.max_future * 1e9
        command = None if refused[3] else core.compute(now)     # as the node
        out.append((command, getattr(core.law, 'cut', None)))
    return out


def _stamps(n):
    return [100_000 * MS + 10 * MS * k for k in range(n)]


def test_two_answers_at_one_sim_clock_reading_are_not_rate_limited():
    # healthy realtime sim time: the clock of step k is seen before its lateral error
    # every third step, so the next answer sees the same reading (dt = 0 on the clock);
    # the steering changes at most ~2 mrad per step, far within 5 rad/s x 10 ms
    stamps = _stamps(300)
    readings = [s if k % 3 == 0 else s - 10 * MS for k, s in enumerate(stamps)]
    assert sum(a == b for a, b in zip(readings, readings[1:])) == 100
    for law in ('cg_compensated', 'paper'):
        jittered = _sim_time_run(readings, law)
        ideal = _sim_time_run(stamps, law)          # each answer at its own reading
        assert not any(c.rate_limited for c, _ in jittered), law
        assert not any(cut for _, cut in jittered if cut is not None), law
        # the clock's jitter changes nothing while the limit does not bind
        assert [c.steering for c, _ in jittered] == [c.steering for c, _ in ideal], law
        assert max(abs(a.steering - b.steering)
                   for (a, _), (b, _) in zip(ideal, ideal[1:])) < 0.005


def _check_rate_bound(readings, stamps, commands, rate):
    """
    Check every command against the rate limit; return the largest share used.

    On the node's clock from the last command at an earlier clock reading, on the
    stamps from the previous command; the share: of its step, the largest one a second
    answer at one reading took from that reference.
    """
    ref, last, shared = None, None, 0.0         # ref: (reading, angle)
    for now, stamp, command in zip(readings, stamps, commands):
        if last is not None and now > last[0]:
            ref = (last[0], last[2])
        if ref is not None:
            assert abs(command.steering - ref[1]) <= rate * (now - ref[0]) * 1e-9 + 1e-12
            if now == last[0]:
                shared = max(shared, abs(command.steering - ref[1]) / (
                    rate * (now - ref[0]) * 1e-9))
        if last is not None:
            assert abs(command.steering - last[2]) <= rate * (stamp - last[1]) * 1e-9 + 1e-12
        last = (now, stamp, command.steering)
    return shared


def test_a_true_rate_limit_still_flags_and_one_reading_shares_one_step():
    # a 1 m step of the lateral error at 1.0 s: the law wants more than 0.1 rad/s
    safety = SafetyParams(max_steering_rate=0.1)
    stamps = _stamps(200)
    readings = [s if k % 3 == 0 else s - 10 * MS for k, s in enumerate(stamps)]
    run = _sim_time_run(readings, y_of=lambda t: 0.05 + (1.0 if t >= 101.0 else 0.0),
                        safety=safety)
    commands = [c for c, _ in run]
    flagged = [k for k, c in enumerate(commands) if c.rate_limited]
    assert flagged and flagged[0] == 100
    assert all(cut for (c, cut) in run if c.rate_limited)      # anti-windup told
    # the answers at one reading share one step from the last command at an earlier
    # reading (checked command by command), and the second ones use all of it
    shared = _check_rate_bound(readings, stamps, commands, 0.1)
    assert shared == pytest.approx(1.0, rel=1e-9)
    # the published rate: the change since the last command at an earlier reading
    assert max(abs(c.steering_rate) for c in commands) == pytest.approx(0.1, rel=1e-9)


def test_a_standing_clock_and_a_flood_move_the_command_one_step_at_most():
    # sim paused: /clock stands still while a 1 kHz flood with advancing stamps goes on
    safety = SafetyParams()                         # 5 rad/s, max_future 0.1 s
    stamps = [100_000 * MS + k * MS for k in range(300)]
    frozen = 100_000 * MS + 20 * MS
    readings = [min(s, frozen) for s in stamps]     # the clock stops at 20 ms
    run = _sim_time_run(readings, y_of=lambda t: 0.05 + (2.0 if t >= 100.02 else 0.0),
                        safety=safety, period=MS)
    answered = [(now, c) for now, (c, _) in zip(readings, run) if c is not None]
    held_at = [c.steering for now, c in answered if now == frozen]
    before = [c.steering for now, c in answered if now < frozen][-1]
    # every answer at the standing reading stays within one 1 ms step of the last
    # command before it, however many come and however far the stamps go
    assert len(held_at) == 101          # stamps up to max_future ahead, then refused
    assert max(abs(a - before) for a in held_at) <= 5.0 * 0.001 + 1e-12
    # and it still flags: the law wants more
    assert all(c.rate_limited for now, c in answered[21:])


def test_a_clock_going_back_within_answers_holds_then_goes_on():
    stamps = _stamps(40)
    # the clock goes back 30 ms at step 20 (not a time jump), then on
    readings = [s - (30 * MS if k >= 20 else 0) for k, s in enumerate(stamps)]
    readings[21] = readings[20]                 # and stands still once
    run = _sim_time_run(readings, y_of=lambda t: 0.05 + (1.0 if t >= 100.15 else 0.0),
                        safety=SafetyParams(max_steering_rate=0.5))
    commands = [c for c, _ in run]
    assert commands[20].steering == commands[19].steering
    assert commands[21].steering == commands[19].steering
    assert abs(commands[22].steering - commands[21].steering) == pytest.approx(0.005, abs=1e-12)


def test_a_rate_lowered_between_two_answers_at_one_reading_holds():
    core = SteeringController(VehicleParams(), ControllerParams(), 'imu', True,
                              SafetyParams(max_steering_rate=1.0))
    now = 100_000 * MS
    first, _ = _live(core, now)
    second, _ = _live(core, now + 10 * MS, stamp=now + 10 * MS, y=2.0)
    assert second.rate_limited and abs(second.steering - first.steering) == pytest.approx(
        0.01, abs=1e-12)
    core.configure(VehicleParams(), ControllerParams(), 'imu', True,
                   SafetyParams(max_steering_rate=0.1))
    third, _ = _live(core, now + 10 * MS, stamp=now + 20 * MS, y=-2.0)
    # 0.1 rad/s x 10 ms around the first and 0.1 rad/s x 10 ms around the second do not
    # meet: it holds (never moves beyond either window)
    assert third.steering == second.steering and third.rate_limited
    fourth, _ = _live(core, now + 20 * MS, stamp=now + 30 * MS, y=-2.0)
    assert abs(fourth.steering - third.steering) == pytest.approx(0.001, abs=1e-12)


def test_at_start_up_the_answers_at_the_first_reading_are_limited_on_their_stamps():
    # no command was ever sent: the first is free (the actuator's angle is unknown), the
    # others at its clock reading move within the rate limit on their stamps (sim time:
    # steps 0 and 1 are both answered at the reading of /clock 0), then on the clock
    safety = SafetyParams(max_steering_rate=0.1)
    stamps = _stamps(4)
    readings = [stamps[0], stamps[0], stamps[0], stamps[3]]
    run = _sim_time_run(readings, y_of=lambda t: 0.05 + (1.0 if t >= 100.01 else 0.0),
                        safety=safety)
    angles = [c.steering for c, _ in run]
    assert [c.rate_limited for c, _ in run] == [False, True, True, True]
    assert angles[1] - angles[0] == pytest.approx(-0.001, abs=1e-12)
    assert angles[2] - angles[1] == pytest.approx(-0.001, abs=1e-12)
    # the clock advances 30 ms from the last command at the first reading
    assert angles[3] - angles[2] == pytest.approx(-0.001, abs=1e-12)    # stamps: 10 ms


def test_at_start_up_the_stamps_open_the_limit_no_further_than_a_running_clock_would():
    # sim time before the first /clock (or use_sim_time without one): the clock reads 0
    # and does not judge the stamps; a flood of lateral errors stamped 1 s apart, the
    # wanted angle flipping, moved the command by rate x 1 s at every answer, unflagged,
    # in no time on the node's clock; now the answers at the first reading together
    # move at most rate x (input_timeout + max_future) from the first command
    safety = SafetyParams(max_steering_rate=0.1)
    span = safety.input_timeout + safety.max_future
    run = _sim_time_run([0] * 12, y_of=lambda t: 2.0 if int(t) % 2 else -2.0,
                        safety=safety, period=1000 * MS)
    angles = [c.steering for c, _ in run]
    path = sum(abs(b - a) for a, b in zip(angles, angles[1:]))
    assert path == pytest.approx(0.1 * span, rel=1e-9)
    assert all(c.rate_limited for c, _ in run[1:])
    # the clock running: the first reading's stamps are judged, the same bound holds
    now = 100_000 * MS
    run = _sim_time_run([now] * 4, y_of=lambda t: -2.0 if t < 100.15 else 2.0,
                        safety=safety, period=100 * MS)
    angles = [c.steering for c, _ in run if c is not None]
    assert abs(angles[-1] - angles[0]) <= 0.1 * span + 1e-12


def _random_run(seed, rate):
    """Feed a random hostile sequence; return ``(node clock, stamp, angle, jumps)``s."""
    rng = random.Random(seed)
    core = SteeringController(VehicleParams(), ControllerParams(), 'imu', True,
                              SafetyParams(max_steering_rate=rate),
                              law=rng.choice(['cg_compensated', 'paper']))
    now, stamp, sent = rng.choice([0, 100_000 * MS]), 100_000 * MS, []
    for _ in range(60):
        draw = rng.random()
        if draw < 0.3:
            pass                                            # the clock stands
        elif draw < 0.4:
            now = max(0, now - rng.randint(1, 900) * MS) if now else 0     # goes back
        else:
            now = now + rng.randint(1, 50) * MS if now else rng.choice([0, 0, 100_000 * MS])
        stamp += rng.choice([0, 1, 5, 10, 50, 300]) * MS    # frozen, flooding, jumping
        if rng.random() < 0.15:
            command = core.safe_command(now)
        else:
            command, _ = _live(core, now, stamp, y=rng.choice([-3.0, 3.0, 0.1, -0.1]),
                               v_x=8.0)
        if command is not None:
            sent.append((now, command.stamp_ns, command.steering, core.time_jumps))
    return sent


def test_no_input_sequence_moves_the_command_faster_than_the_rate_limit():
    # clock standing, going back, running; stamps frozen, flooding, jumping; answers and
    # watchdog commands: each command within the rate of the last command at an earlier
    # reading on the node's clock and of the previous one on the newest stamp; a clock
    # going back (or a time jump) holds; the answers at the first reading move at most
    # rate x (input_timeout + max_future) in all (was up to 0.63 rad at 0.5 rad/s)
    rate, span = 0.5, SafetyParams().input_timeout + SafetyParams().max_future
    for seed in range(200):
        sent = _random_run(seed, rate)
        ref, start_path = None, 0.0
        newest = sent[0][1] if sent else 0
        for (n0, s0, a0, j0), (n1, s1, a1, j1) in zip(sent, sent[1:]):
            if j1 != j0 or n1 < n0:
                assert a1 == a0, seed
                ref, newest = (n1, a1), s1
                continue
            if n1 > n0:
                ref = (n0, a0)
            if ref is None:
                start_path += abs(a1 - a0)
            else:
                assert abs(a1 - ref[1]) <= rate * (n1 - ref[0]) * 1e-9 + 1e-12, seed
            assert abs(a1 - a0) <= rate * max(0, s1 - newest) * 1e-9 + 1e-12, seed
            newest = max(newest, s1)
        assert start_path <= rate * span + 1e-12, seed


def test_a_differentiated_a_x_is_taken_over_10_ms_and_within_the_believable():
    # dev-probe63: velocity stamps 1 us apart made a_x 1e5 m/s^2 and the commands swing
    # 6.5-57 mrad; an IMU's accel_x beyond safety.max_acceleration is refused, the
    # derivative was not checked. Dropping such values (b79384e) biased a noisy 1 kHz
    # feed toward 0 (dev-probe64). Now a_x is taken over at least 10 ms, clipped
    from lookahead_control.bags.run_data import _differentiated, Samples
    from lookahead_control.core.controller import DIFFERENTIATE_SPAN
    import numpy as np
    assert DIFFERENTIATE_SPAN == 0.01
    most = SafetyParams().max_acceleration

    def feed_through(feed):
        core = SteeringController(VehicleParams(), ControllerParams(), 'differentiate', True,
                                  SafetyParams())
        seen = []
        for stamp, v_x in feed:
            core.update_velocity(VelocitySample(stamp, v_x, 0.0))
            seen.append(core.acceleration())
        # the re-run's arrays give the same a_x after each sample
        velocity = Samples(np.array([s for s, _ in feed]), np.array([s for s, _ in feed]),
                           np.arange(len(feed)), {'v_x': np.array([v for _, v in feed])})
        assert list(_differentiated(velocity, np.arange(len(feed)), most)) == seen
        return seen

    # (stamp [ns], v_x): 3 m/s^2 at 100 Hz, a sample 1 us after one, a 20 m/s jump
    seen = feed_through([(0, 20.0), (10 * MS, 20.03), (20 * MS, 20.06),
                         (20 * MS + 1000, 20.07), (30 * MS, 20.09), (40 * MS, 20.12),
                         (50 * MS, 40.0), (60 * MS, 40.03), (55 * MS, 40.0),
                         (65 * MS, 40.03)])
    assert seen[:3] == pytest.approx([0.0, 3.0, 3.0])
    assert seen[3] == pytest.approx(3.0)         # 1 us after the last: not a derivative
    assert seen[4:6] == pytest.approx([3.0, 3.0])   # over 10 ms from the 20 ms sample
    assert seen[6] == most                      # the jump: 1988 m/s^2, clipped
    assert seen[7] == pytest.approx(3.0)
    assert seen[8] == pytest.approx(3.0)        # back in time: the anchor restarts
    assert seen[9] == pytest.approx(3.0)
    # a noisy 1 kHz feed (0.02 m/s) braking at 3.5 m/s^2: its mean, not 0.36 (b79384e)
    rng = np.random.default_rng(3)
    t = np.arange(20000) * MS
    v = 30.0 - 3.5 * t * 1e-9 + 0.02 * rng.standard_normal(t.size)
    seen = feed_through(list(zip(t.tolist(), v.tolist())))
    assert np.mean(seen[100:]) == pytest.approx(-3.5, abs=0.25)
    # a stop harder than the bound reads as the bound, not as 0
    seen = feed_through([(k * 10 * MS, 30.0 - 0.16 * k) for k in range(50)])
    assert seen[-1] == -most


def test_a_sim_clock_starting_after_the_inputs_does_not_freeze_the_command():
    # dev-probe91: inputs stamped 100 s received while the sim clock read 0 (not
    # started), then the clock starts at 101 s: the watchdog's command was stamped 100 s
    # + 101 s (the time 'since arrival' on a clock that had not run), and every answer
    # after it was held by the rate limit until the stamps reached 201 s
    core = _core()
    sim = 100_000 * MS
    for k in range(10):
        _step_at(core, 0, sim + k * 10 * MS, 0.5)
    held = core.last.steering
    watchdog = core.safe_command(sim + 1000 * MS)     # the clock starts: inputs stale
    assert watchdog.steering == held and watchdog.stamp_ns == sim + 90 * MS
    answers = [_step_at(core, sim + 1000 * MS + k * 10 * MS,
                        sim + 1000 * MS + k * 10 * MS, -0.5) for k in range(1, 21)]
    # back on the inputs: the command moves toward the new error, within the rate limit
    # (0.1 rad/s over 0.2 s); before, all 20 were the held command
    moved = [a.steering - held for a in answers]
    assert moved[0] == pytest.approx(0.1 * 0.01, rel=1e-9) and answers[0].rate_limited
    assert all(b >= a for a, b in zip(moved, moved[1:]))
    assert not answers[-1].rate_limited and answers[-1].steering == answers[-1].law.steering


def test_the_last_message_taken_sent_again_is_a_duplicate_not_a_refusal():
    # dev-sc50: a lockstep simulator repeats its step 0 until answered; the controller
    # refused each repeat, and every realtime run and every run through path_bridge began
    # with a WARN 'rejected: 4'. An exact repeat is not used and counted apart; a repeated
    # stamp with other values is still refused
    from lookahead_control.core.safety import is_duplicate
    core, now = _core(), 50_000 * MS
    yaw = YawSample(now, 0.01, 0.02, 0.0)
    assert core.accept('yaw', yaw, now) is None
    again = core.accept('yaw', YawSample(now, 0.01, 0.02, 0.0), now + 10 * MS)
    assert again == 'yaw: repeats the last message taken (stamp 50.000 s, same values as read)'
    assert is_duplicate(again) and core.duplicates == {'yaw': 1} and core.rejected == {}
    assert core.yaw is yaw
    other = core.accept('yaw', YawSample(now, 0.01, 0.03, 0.0), now + 20 * MS)
    assert 'does not advance' in other and not is_duplicate(other)
    assert core.rejected == {'yaw: stamp': 1} and core.duplicates == {'yaw': 1}
    # a repeat does not keep the input fresh: past input_timeout it is too old, refused
    late = core.accept('yaw', yaw, now + 201 * MS)
    assert 'behind the node clock' in late and core.rejected == {'yaw: stamp': 2}
    assert 'yaw' in core.stale(now + 201 * MS)
    # without a clock (offline) only the ordering: a repeat is a duplicate
    offline = _core()
    lateral = LateralErrorSample(now, 0.0, 0.3)
    assert offline.accept('lateral_error', lateral) is None
    assert is_duplicate(offline.accept('lateral_error', LateralErrorSample(now, 0.0, 0.3)))
    # a curvature preview compared whole, points included
    rho = CurvatureSample(now, 0.001, 0.0, ((0.0, 0.001), (10.0, 0.002)))
    assert offline.accept('road_curvature', rho) is None
    assert is_duplicate(offline.accept('road_curvature', rho._replace()))
    moved = offline.accept('road_curvature', rho._replace(ahead=((0.0, 0.001), (10.0, 0.003))))
    assert not is_duplicate(moved) and 'does not advance' in moved
    # while the yaw input is refused for a fault of its sign, a repeat is refused too
    offline.accept('yaw', yaw)
    offline.yaw_fault = 'yaw: yaw_rate runs against the steering'
    assert not is_duplicate(offline.accept('yaw', yaw))
    assert 'yaw' not in offline.duplicates
