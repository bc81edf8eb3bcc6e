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
Prescribed longitudinal speed: constant, or constant acceleration over intervals.

The first ramp is ``(start, duration, acceleration)``; further ramps (``ramps``) follow
it without overlapping, so a profile can accelerate, cruise and brake (scenario S5).
"""

from __future__ import annotations

from dataclasses import dataclass
import math

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


Ramp = tuple[float, float, float]       # (start [s], duration [s], acceleration [m/s^2])


def ramps_speed(t: Real, speed: Real, accel: Real, ramps: tuple[Ramp, ...]
                ) -> tuple[Real, Real]:
    """
    Add the further ramps' speed and acceleration at ``t`` to ``(speed, accel)``.

    :param t: time [s].
    :param speed: speed of the first ramp [m/s].
    :param accel: acceleration of the first ramp [m/s^2].
    :param ramps: further ``(start, duration, acceleration)`` ramps.
    :return: speed [m/s] and acceleration [m/s^2].
    """
    for start, duration, acceleration in ramps:
        speed = speed + acceleration * xp.clip(t - start, 0.0, duration)
        active = (t >= start) & (t < start + duration) if isinstance(
            t, xp.np.ndarray) else start <= t < start + duration
        accel = accel + xp.where(active, acceleration, 0.0 * accel)
    return speed, accel


@dataclass(frozen=True)
class SpeedProfile:
    """
    Speed ``initial``, ramping at ``acceleration`` from ``start`` for ``duration``.

    :param initial: initial speed [m/s].
    :param acceleration: ramp acceleration, |a_x| <= 3.5 m/s^2 [m/s^2].
    :param start: ramp start time [s].
    :param duration: ramp duration [s].
    :param ramps: further ``(start, duration, acceleration)`` ramps, in time order,
        starting after the previous one ends.
    :param fixed: the profile belongs to the scenario: a speed override is refused.
    """

    initial: float
    acceleration: float = 0.0
    start: float = 0.0
    duration: float = 0.0
    ramps: tuple[Ramp, ...] = ()
    fixed: bool = False

    def __post_init__(self) -> None:
        check_range('speed.initial', self.initial, 0.0, 90.0, low_open=True, unit='m/s')
        speed, end = self.initial, -math.inf
        for i, (start, duration, accel) in enumerate(
                ((self.start, self.duration, self.acceleration),) + tuple(self.ramps)):
            name = 'speed' if i == 0 else f'speed.phases[{i}]'
            check_range(f'{name}.acceleration', accel, -MAX_ACCELERATION,
                        MAX_ACCELERATION, unit='m/s^2')
            check_range(f'{name}.start', start, 0.0, 1.0e6, unit='s')
            check_range(f'{name}.duration', duration, 0.0, 1.0e6, unit='s')
            if start < end:
                raise ParameterError(f'{name}.start = {start!r} s overlaps the previous '
                                     f'phase (ends at {end:g} s); phases follow each other')
            end = start + duration
            speed += accel * duration
            if speed <= 0.0 or speed > 90.0:
                raise ParameterError(
                    f'speed profile reaches {speed:g} m/s at {end:g} s (initial '
                    f'{self.initial:g}); the plant model needs a speed in (0, 90] m/s')

    @property
    def end_time(self) -> float:
        """Return when the last ramp ends [s]."""
        last = self.ramps[-1] if self.ramps else (self.start, self.duration, 0.0)
        return last[0] + last[1]

    def at(self, t: Real) -> tuple[Real, Real]:
        """
        Return ``(v_x, a_x)`` at time ``t``.

        :param t: time [s].
        :return: speed [m/s] and acceleration [m/s^2].
        """
        return profile_speed(self, t, self.initial, self.acceleration)


def profile_speed(profile: SpeedProfile, t: Real, initial: Real, acceleration: Real
                  ) -> tuple[Real, Real]:
    """
    Return ``(v_x, a_x)`` of ``profile`` at ``t`` with its first ramp's values replaced.

    Without further ramps this is :func:`speed_at` (the same operations).

    :param profile: the profile (ramp times, further ramps).
    :param t: time [s].
    :param initial: initial speed(s) [m/s].
    :param acceleration: first-ramp acceleration(s) [m/s^2].
    :return: speed [m/s] and acceleration [m/s^2].
    """
    v_x, a_x = speed_at(t, initial, acceleration, profile.start, profile.duration)
    if profile.ramps:
        return ramps_speed(t, v_x, a_x, profile.ramps)
    return v_x, a_x
