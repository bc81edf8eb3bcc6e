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

"""Prescribed longitudinal speed: constant, or constant acceleration over an interval."""

from __future__ import annotations

from dataclasses import dataclass

from lookahead_control.core import numeric as xp
from lookahead_control.core.numeric import Real
from lookahead_control.core.params import check_range, ParameterError

MAX_ACCELERATION = 3.5  # the paper's envelope, Section 4 [m/s^2]


def speed_at(t: Real, initial: Real, acceleration: Real, start: float,
             duration: float) -> tuple[Real, Real]:
    """
    Return ``(v_x, a_x)`` at time ``t`` for a ramp of ``acceleration`` over an interval.

    :param t: time [s].
    :param initial: speed before the ramp [m/s].
    :param acceleration: acceleration during the ramp [m/s^2].
    :param start: ramp start time [s].
    :param duration: ramp duration [s].
    :return: speed [m/s] and acceleration [m/s^2].
    """
    if type(t) is float and type(initial) is float and type(acceleration) is float:
        # one run (the simulator node: 40 calls per 100 Hz step): no array dispatch
        ramped = min(max(t - start, 0.0), duration)
        return (initial + acceleration * ramped,
                acceleration if start <= t < start + duration else 0.0)
    elapsed = xp.clip(t - start, 0.0, duration)
    active = (t >= start) & (t < start + duration)
    return initial + acceleration * elapsed, xp.where(active, acceleration, 0.0 * initial)


@dataclass(frozen=True)
class SpeedProfile:
    """
    Speed ``initial``, ramping at ``acceleration`` from ``start`` for ``duration``.

    :param initial: initial speed [m/s].
    :param acceleration: ramp acceleration, |a_x| <= 3.5 m/s^2 [m/s^2].
    :param start: ramp start time [s].
    :param duration: ramp duration [s].
    """

    initial: float
    acceleration: float = 0.0
    start: float = 0.0
    duration: float = 0.0

    def __post_init__(self) -> None:
        check_range('speed.initial', self.initial, 0.0, 90.0, low_open=True, unit='m/s')
        check_range('speed.acceleration', self.acceleration, -MAX_ACCELERATION,
                    MAX_ACCELERATION, unit='m/s^2')
        check_range('speed.start', self.start, 0.0, 1.0e6, unit='s')
        check_range('speed.duration', self.duration, 0.0, 1.0e6, unit='s')
        final = self.initial + self.acceleration * self.duration
        if final <= 0.0:
            raise ParameterError(
                f'speed profile ends at {final:g} m/s (initial {self.initial:g}, '
                f'acceleration {self.acceleration:g} for {self.duration:g} s); the plant '
                'model needs a positive speed')

    def at(self, t: Real) -> tuple[Real, Real]:
        """
        Return ``(v_x, a_x)`` at time ``t``.

        :param t: time [s].
        :return: speed [m/s] and acceleration [m/s^2].
        """
        return speed_at(t, self.initial, self.acceleration, self.start, self.duration)
