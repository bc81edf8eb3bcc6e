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

"""The answer-rate bound of event mode on the wall clock, without DDS."""

from __future__ import annotations

import math

from lookahead_control.core.answer_rate import AnswerPacer
import pytest

MS = 1_000_000


def test_a_burst_then_at_most_the_rate_the_rest_deferred_or_coalesced():
    pacer = AnswerPacer(250.0, burst=3)
    assert pacer.period_ns == 4 * MS
    assert [pacer.arrived(100 * MS) for _ in range(3)] == [None] * 3   # the burst
    assert pacer.arrived(101 * MS) == 3 * MS        # 1 ms refilled of the 4 one needs
    assert pacer.deferred and pacer.coalesced == 0
    assert pacer.arrived(102 * MS) == 0             # the deferred one is left for this one
    assert pacer.arrived(103 * MS) == 0
    assert pacer.coalesced == 2
    pacer.due(104 * MS)                             # the timer fired: the newest answered
    assert not pacer.deferred
    assert pacer.arrived(107 * MS) == 1 * MS        # 3 ms refilled since
    pacer.due(108 * MS)
    assert pacer.arrived(112 * MS) is None          # a whole period later: at once
    assert pacer.coalesced == 2
    # a sustained flood: the answers over a second are the rate plus the burst
    flood = AnswerPacer(250.0, burst=3)
    answered, due_at = 0, None
    for t in range(0, 1000 * MS, MS // 4):          # 4000 lateral errors a second
        if due_at is not None and t >= due_at:
            flood.due(t)
            answered, due_at = answered + 1, None
        wait = flood.arrived(t)
        if wait is None:
            answered += 1
        elif wait > 0:
            due_at = t + wait
    assert answered in (252, 253), answered
    assert flood.coalesced == 4000 - answered - flood.deferred


def test_a_sensor_at_the_rate_with_jitter_is_answered_message_by_message():
    # a 100 Hz sensor whose messages come bunched (one 8 ms late, the next on time):
    # with a bound of 250 Hz every one is answered at once
    pacer = AnswerPacer(250.0)
    times = []
    for k in range(200):
        times.append(k * 10 * MS + (8 * MS if k % 7 == 3 else 0))
    assert all(pacer.arrived(t) is None for t in sorted(times))
    assert pacer.coalesced == 0
    slow = AnswerPacer(100.0)
    assert all(slow.arrived(k * 37 * MS) is None for k in range(100))


def test_a_steady_clock_that_reads_earlier_does_not_hold_answers_back():
    # not expected of a steady clock, but no answer is held for a period that never ends
    pacer = AnswerPacer(10.0, burst=1)
    assert pacer.arrived(500 * MS) is None
    assert pacer.arrived(400 * MS) is None


def test_cancel_drops_the_deferred_answer_and_the_period():
    pacer = AnswerPacer(10.0, burst=1)
    assert pacer.arrived(0) is None
    assert pacer.arrived(MS) == 99 * MS
    pacer.cancel()
    assert not pacer.deferred
    assert pacer.arrived(2 * MS) is None


def test_a_new_rate_counts_from_the_next_lateral_error():
    pacer = AnswerPacer(10.0, burst=1)
    assert pacer.arrived(0) is None
    pacer.set_rate(1000.0)
    assert pacer.rate_hz == 1000.0 and pacer.period_ns == MS
    assert pacer.arrived(2 * MS) is None


@pytest.mark.parametrize('rate', [0.0, -5.0, math.nan, math.inf])
def test_a_rate_that_is_not_a_finite_positive_number_is_refused_by_name(rate):
    with pytest.raises(ValueError, match=r'max_answer_rate_hz .*: must be a finite number > 0'):
        AnswerPacer(rate)
    pacer = AnswerPacer(10.0)
    with pytest.raises(ValueError, match='max_answer_rate_hz'):
        pacer.set_rate(rate)
    assert pacer.rate_hz == 10.0


def test_a_rate_changed_while_an_answer_waits_counts_for_it():
    # dev-probe74: a bound raised from 1 Hz to 1e5 Hz still held the waiting answer
    pacer = AnswerPacer(1.0, burst=1)
    assert pacer.arrived(0) is None
    assert pacer.arrived(10 * MS) == 990 * MS
    pacer.set_rate(1.0e5)
    assert pacer.wait(20 * MS) == 0                 # refilled long since at 1e5 Hz
    slower = AnswerPacer(100.0, burst=1)
    assert slower.arrived(0) is None
    assert slower.arrived(MS) == 9 * MS
    slower.set_rate(10.0)
    assert slower.wait(2 * MS) == 89 * MS          # 0.1 + 0.01 of an answer refilled


def test_a_dropped_deferred_answer_is_counted_as_coalesced():
    pacer = AnswerPacer(10.0, burst=1)
    assert pacer.arrived(0) is None
    assert pacer.arrived(MS) == 99 * MS
    pacer.drop()
    assert not pacer.deferred and pacer.coalesced == 1
    pacer.drop()                                    # nothing waits: nothing counted
    assert pacer.coalesced == 1


def test_a_rate_beyond_the_clock_s_resolution_is_no_bound_not_a_crash():
    # dev-probe74: 3e9 Hz rounded the period to 0 ns and arrived() divided by it
    pacer = AnswerPacer(3.0e9)
    assert pacer.period_ns == 1
    assert all(pacer.arrived(k) is None for k in range(0, 100, 2))
