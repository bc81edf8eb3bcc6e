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
A check of the steering sent for a sustained oscillation (a delay beyond the law's margin).

The controller cannot see an actuator's transport delay in its inputs. With more than
about 90 ms and ``delay_prediction`` off, the default law's steering settles into a
limit cycle at 1.4-1.75 Hz at 37 m/s (+-56 mrad at 95 ms) while the CG error stays
about 1 cm: a metric on the CG hides it; at 10 m/s with 150-200 ms it is slower and
far larger (0.43-0.67 Hz, +-180-450 mrad, the CG 1.5-2 m off). The check high-passes
the command sent twice through ``1 - 1 / (low_pass s + 1)`` (a ramp, a curve entered,
leaves no offset) and counts swings: from ``amplitude`` or more on one side to as much
on the other. ``swings`` of them, each within ``half_period`` of the one before (0.33
Hz and faster), is an oscillation. The steering that follows a road's curvature swings
only as fast as the road does: a slalom is told too. Calibrated offline
(the default law, goal plant and noise) in ``docs/safety.md``.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
import math

from lookahead_control.core.params import check_range


@dataclass(frozen=True)
class OscillationCheckParams:
    """
    Settings of the check.

    :param amplitude: the high-passed command must reach this on each side [rad].
    :param low_pass: time constant of each of the two high passes [s].
    :param half_period: a swing must follow the one before within this time [s].
    :param swings: this many swings in a row are an oscillation.
    """

    amplitude: float = 0.015
    low_pass: float = 0.5
    half_period: float = 1.5
    swings: int = 8

    def __post_init__(self) -> None:
        """Check the ranges."""
        check_range('oscillation_check.amplitude', self.amplitude, 1.0e-4, 1.0, unit='rad')
        check_range('oscillation_check.low_pass', self.low_pass, 0.01, 10.0, unit='s')
        check_range('oscillation_check.half_period', self.half_period, 0.01, 10.0,
                    unit='s')
        check_range('oscillation_check.swings', self.swings, 2, 1000)


class OscillationCheck:
    """Swings of the steering sent, its high pass from one side to the other."""

    def __init__(self, settings: OscillationCheckParams | None = None) -> None:
        """
        Start without a command.

        :param settings: the settings (defaults if None).
        """
        self.settings = settings or OscillationCheckParams()
        self._low = math.nan            # the low pass of the command [rad]
        self._low_high = 0.0            # ... of the command's first high pass [rad]
        self._side = 0
        self._since = 0.0       # time since the last swing (or the start) [s]
        self._peak = 0.0        # the largest |high pass| since the last swing [rad]
        # the last swings in a row: their intervals [s] and high-passed peaks [rad]
        self._run: deque[float] = deque(maxlen=self.settings.swings)
        self._peaks: deque[float] = deque(maxlen=self.settings.swings)

    def reset(self) -> None:
        """Restart (a gap, a restart of the law, a safe command): the next step starts."""
        self._low, self._low_high = math.nan, 0.0
        self._side, self._since, self._peak = 0, 0.0, 0.0
        self._run.clear()
        self._peaks.clear()

    @property
    def oscillating(self) -> bool:
        """Return whether the command oscillates (``swings`` in a row)."""
        return len(self._run) >= self.settings.swings

    @property
    def frequency(self) -> float:
        """Return the oscillation's frequency [Hz] (0 when it does not oscillate)."""
        return len(self._run) / (2.0 * sum(self._run)) if self.oscillating else 0.0

    @property
    def amplitude(self) -> float:
        """
        Return the command's amplitude [rad] (0 when it does not oscillate).

        The mean high-passed peak over the two high passes' gain at the frequency.
        """
        if not self.oscillating:
            return 0.0
        wt = (2.0 * math.pi * self.frequency * self.settings.low_pass) ** 2
        return sum(self._peaks) / len(self._peaks) * (1.0 + wt) / wt

    def step(self, dt: float, steering: float) -> bool:
        """
        Take the command sent ``dt`` after the one before.

        :param dt: time since the previous command [s] (0: the same again, nothing
            moves; not finite, negative or above ``half_period``: a restart).
        :param steering: the command sent [rad] (not finite: a restart).
        :return: whether it oscillates.
        """
        s = self.settings
        if not (math.isfinite(dt) and math.isfinite(steering)) or dt < 0.0 \
                or dt > s.half_period:
            self.reset()
            if math.isfinite(steering):
                self._low = steering
            return False
        if math.isnan(self._low):
            self._low = steering
            return False
        if dt == 0.0:
            return self.oscillating
        # two first-order high passes: a ramp of the command leaves no offset (one left
        # low_pass x its rate: 25 mrad at 0.05 rad/s hid a +-30 mrad swing; dev-probe77)
        share = min(1.0, dt / s.low_pass)
        self._low += share * (steering - self._low)
        first = steering - self._low
        self._low_high += share * (first - self._low_high)
        high = first - self._low_high
        self._since += dt
        self._peak = max(self._peak, abs(high))
        side = 1 if high >= s.amplitude else -1 if high <= -s.amplitude else 0
        if side and side != self._side:
            if self._side and self._since <= s.half_period:     # a swing in time
                self._run.append(self._since)
                self._peaks.append(self._peak)
            self._side, self._since, self._peak = side, 0.0, abs(high)
        if self._since > s.half_period:  # no swing in time: the row ends
            self._run.clear()
            self._peaks.clear()
        return self.oscillating
