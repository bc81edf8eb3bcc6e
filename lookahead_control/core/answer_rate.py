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
The bound on the controller's answer rate in event mode on the wall clock.

At most ``max_answer_rate_hz`` answers per second on the steady clock, sustained, with
bursts of :data:`BURST`: a lateral error that finds the bound used up is not answered at
once; the answer is deferred until the bound allows one and then given to the newest
lateral error; any that came in between are coalesced (taken in, never answered). Each
measurement is still answered at most once and in order, and the added latency is at
most one period. Without it a flood of valid
lateral errors (dev-probe71: 470 msg/s) was answered message by message, 0.8 ms each:
the node took a whole core and read its other inputs 104 ms late. Under sim time there
is no bound: a lockstep simulator waits for the answer to every step.
"""

from __future__ import annotations

import math
from typing import Optional

#: answers at once before the rate holds them back
BURST = 3


class AnswerPacer:
    """
    Decide when a lateral error is answered under the answer-rate bound.

    A token bucket on the steady clock: ``burst`` answers at once, refilled at the rate.
    A sensor at the rate with delivery jitter (two messages a millisecond apart after a
    late one) is answered message by message; a sustained flood at the rate.
    """

    def __init__(self, max_rate_hz: float, burst: int = BURST) -> None:
        """
        Start with a full bucket.

        :param max_rate_hz: most answers per second on the steady clock, sustained [Hz].
        :param burst: answers at once before the rate holds them back.
        :raises ValueError: if the rate is not a finite number > 0.
        """
        self.set_rate(max_rate_hz)       # rate_hz and the period
        self.burst = burst
        self._tokens = float(burst)
        self._filled: Optional[int] = None
        #: a lateral error waits for a token
        self.deferred = False
        #: lateral errors taken in and never answered (a newer one was answered)
        self.coalesced = 0

    @property
    def period_ns(self) -> int:
        """Return the time in which one answer is refilled [ns]."""
        return self._period

    rate_hz: float
    _period: int

    def set_rate(self, max_rate_hz: float) -> None:
        """
        Change the bound (from the next lateral error on).

        :param max_rate_hz: most answers per second [Hz].
        :raises ValueError: if the rate is not a finite number > 0.
        """
        if not 0.0 < max_rate_hz < float('inf'):
            raise ValueError(f'max_answer_rate_hz {max_rate_hz!r}: must be a finite number '
                             '> 0 [Hz]')
        self.rate_hz = max_rate_hz
        # (at least 1 ns: a rate above 1e9 Hz is no bound, not a division by 0)
        self._period = max(1, int(round(1e9 / max_rate_hz)))

    def _refill(self, steady_ns: int) -> None:
        if self._filled is None or steady_ns < self._filled:
            # the first lateral error, or a steady clock read earlier (not expected of
            # it): a full bucket, never a period that does not end
            self._tokens = float(self.burst)
        else:
            self._tokens = min(float(self.burst),
                               self._tokens + (steady_ns - self._filled) / self._period)
        self._filled = steady_ns

    def arrived(self, steady_ns: int) -> Optional[int]:
        """
        Take in a lateral error; say whether to answer it now.

        :param steady_ns: the steady clock now [ns].
        :return: None: answer now (the answer is counted as given); else the wait [ns]
            until the deferred answer, for a timer to be armed; 0: the deferred answer is
            already waiting (the lateral error it would have answered is coalesced).
        """
        if self.deferred:
            self.coalesced += 1
            return 0
        self._refill(steady_ns)
        if self._tokens >= 1.0:
            self._tokens -= 1.0
            return None
        self.deferred = True
        return max(1, int(math.ceil((1.0 - self._tokens) * self._period)))

    def wait(self, steady_ns: int) -> int:
        """
        Return the time until the deferred answer is allowed at the present rate [ns].

        A rate changed while an answer is deferred counts at once (dev-probe74: a bound
        raised from 1 Hz to 1e5 Hz still held the answer for 965 ms).

        :param steady_ns: the steady clock now [ns].
        :return: the wait (0: now).
        """
        self._refill(steady_ns)
        return max(0, int(math.ceil((1.0 - self._tokens) * self._period)))

    def drop(self) -> None:
        """Leave the deferred answer's lateral error unanswered: a newer one will be."""
        if self.deferred:
            self.deferred = False
            self.coalesced += 1

    def due(self, steady_ns: int) -> None:
        """
        Note the deferred answer given (its timer fired).

        :param steady_ns: the steady clock now [ns].
        """
        self._refill(steady_ns)
        self._tokens = max(0.0, self._tokens - 1.0)
        self.deferred = False

    def cancel(self) -> None:
        """Drop a deferred answer (node cleaned up); the next lateral error is answered."""
        self.deferred = False
        self._filled = None
