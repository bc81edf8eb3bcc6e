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
A check of the measured yaw rate's sign against the steering and the relative yaw.

A yaw rate of the wrong sign (a bridge that flips it, an IMU mounted upside down) makes
every law that feeds it back unstable, and neither the map check (which blames the map)
nor the stamps see it (dev-probe97: the steering shook on a straight from 1.2 s, the
car left the lane at 5.5 s, and the only word was a map WARN). Two witnesses are asked,
each correlated with the measured yaw rate over ``memory``, centred (a yaw-rate bias, a
constant curve and a steady side force drop out):

- the steering: a car turns the way it is steered, its yaw rate following the wheel
  angle with a positive gain (``v_x delta / L`` through ``lag``: actuator and yaw mode;
  its scale does not matter, only the correlation's sign is used). But a car that
  oversteers, and is steered against it, turns against the steering (dev-sc44 measured
  -0.79 for the paper law on the CommonRoad car braking in S5's arc);
- the relative yaw: ``eps_r' = r - v_x rho`` holds whatever the tyres do, so the
  relative yaw's rate plus ``v_x rho`` (both through ``lag``; ``rho`` the curvature
  received, 0 without) is the yaw rate. A map of the wrong sign, or a curve without a
  map, is a term of its own there, which the steering witness does not have.

Only while all three signals vary by ``excitation`` or more, at or above ``min_speed``,
is a correlation judged; the relative yaw's at or below ``limit`` and the steering's at
or below ``steering_limit``, for ``hold`` seconds: the yaw rate runs against the car. A
correct yaw rate gives correlations near +1 wherever the car is steered, a flipped one
near -1 with both.

The correlations do not see a yaw rate's scale. A yaw rate in deg/s (57 times too large)
made every law shake the car off a straight (dev-sc45: the default law at 30 m/s, off
the lane 2.5 s after the switch), while the range check refused only its large samples,
so the input never went stale. Its scale is judged by the two witnesses' gains, the
regressions (over the same statistics) of the yaw rate on the steering's yaw rate and of
the relative yaw's kinematic yaw rate on the yaw rate: a yaw rate ``k`` times too large
makes the first ``k`` times and the second ``1 / k`` times what they are, about 1 each
(the first is the car's yaw gain, under 1 where it understeers). A map error or a curve
without a map moves the second, a gust, an oversteering car or a skid the first, none
both. Once the steering's yaw rate and the lagged yaw rate vary by ``excitation`` or
more, ``|gain|`` at or above ``scale_limit`` and ``|kinematic gain|`` at or below its
inverse for ``hold`` seconds: the yaw rate is out of scale (either sign).

The other way, a yaw rate frozen (a bridge repeating its last value with new stamps) or
too small (x 0.1, deg/s read as rad/s twice) leaves the laws without their yaw damping
(dev-sc46: the default law up to 2 m off S-bends at 30-37 m/s): while both witnesses
vary by ``excitation`` or more, the smaller one's standard deviation over the lagged yaw
rate's (the stillness) at or above ``scale_limit`` for ``hold`` seconds is
:attr:`YawCheck.too_still`. Told, not a fault: refusing the yaw input would take the
safe behaviour, a straight wheel on the curve the law still follows.

The check is given the yaw rates taken, while the law answers. dev-probe99 found it
starved there: a yaw rate in deg/s that the range check made stale was a held value
most of the time, the law coming back at full lock whenever a sample passed, and 0.5 s
of evidence never gathered (the default law at 10-20 m/s, 50 m off). Given the yaw rates
received, refused or not (clipped, the median of five) and stepped while stale too,
dev-sc45 caught those, but dev-probe101 found three samples of a range-refused glitch
then taken for a scale, for good (the car 8-14 m off a curve under the safe behaviour):
not done. The moments start once the lags have settled after a restart, each sample of
the first ``memory`` weighed alike (dev-probe99: a first yaw rate 0.1 rad/s off, the
rest quiet, was weighed 0.53 when the moments were first judged, and out of scale 1.1 s
later, for good).
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from lookahead_control.core.params import check_range

#: lags of settling after a restart before the moments start
SETTLE = 3.0


@dataclass(frozen=True)
class YawCheckParams:
    """
    Settings of the check.

    :param lag: first-order lag from the command to its yaw rate (actuator and yaw
        mode), and of the kinematic witness's signals [s].
    :param memory: time constant of the correlation's statistics [s].
    :param excitation: the standard deviation the yaw rate and both witnesses need
        before the correlations are judged [rad/s] (the steering's in yaw rate at the
        speed, by ``v_x / L``).
    :param limit: a correlation with the relative yaw's witness at or below it is
        opposed [-].
    :param steering_limit: the same for the steering's witness, whose model is cruder
        (a lag, no actuator rate limit: a command saturating from side to side made
        -0.6 to -0.98 of a flipped yaw rate in dev-probe97's car) [-].
    :param scale_limit: a yaw rate this many times larger than the steering's (the gain)
        while the relative yaw's is at most its inverse (the kinematic gain) is out of
        scale [-].
    :param hold: opposed (or out of scale) this long is the fault [s].
    :param min_speed: below it the check restarts [m/s].
    """

    lag: float = 0.2
    memory: float = 1.0
    excitation: float = 0.02
    limit: float = -0.8
    steering_limit: float = -0.5
    scale_limit: float = 5.0
    hold: float = 0.5
    min_speed: float = 5.0

    def __post_init__(self) -> None:
        """Check the ranges."""
        check_range('yaw_check.lag', self.lag, 0.0, 5.0, unit='s')
        check_range('yaw_check.memory', self.memory, 0.05, 60.0, unit='s')
        check_range('yaw_check.excitation', self.excitation, 1.0e-4, 10.0, unit='rad/s')
        check_range('yaw_check.limit', self.limit, -1.0, 0.0)
        check_range('yaw_check.steering_limit', self.steering_limit, -1.0, 0.0)
        check_range('yaw_check.scale_limit', self.scale_limit, 1.5, 1000.0)
        check_range('yaw_check.hold', self.hold, 0.0, 60.0, unit='s')
        check_range('yaw_check.min_speed', self.min_speed, 0.0, 100.0, unit='m/s')


class YawCheck:
    """The measured yaw rate against the steering's and the relative yaw's: sign and scale."""

    def __init__(self, settings: YawCheckParams | None = None) -> None:
        """
        Start without statistics.

        :param settings: the settings (defaults if None).
        """
        self.settings = settings or YawCheckParams()
        self.reset()

    def reset(self) -> None:
        """Restart (a gap, a slow car, a non-finite input): statistics from the next step."""
        self._steered = math.nan        # the steering's yaw rate through the lag
        self._eps = self._turn = self._rate = math.nan      # the kinematic witness's filters
        self._mean = [0.0, 0.0, 0.0, 0.0]           # steered, r, kinematic, r filtered
        self._var = [0.0, 0.0, 0.0, 0.0]
        self._cov = [0.0, 0.0]                      # steered x r, kinematic x r filtered
        self._weight = 0.0
        self._since = 0.0               # time since the restart (the lags settle)
        self._steps = 0                 # steps in the moments
        #: the mean command over ``memory`` (what the safe behaviour holds after a fault:
        #: the last command is one of the shaking)
        self.command_mean = math.nan
        #: the correlation with the steering's yaw rate (NaN until excited)
        self.correlation = math.nan
        #: the correlation with the relative yaw's kinematic yaw rate (NaN until excited)
        self.kinematic_correlation = math.nan
        #: the regression of the yaw rate on the steering's yaw rate (NaN until both vary)
        self.gain = math.nan
        #: the regression of the relative yaw's kinematic yaw rate on the lagged yaw rate
        #: (NaN until the yaw rate varies)
        self.kinematic_gain = math.nan
        #: the lagged yaw rate's standard deviation over the larger of the witnesses' (NaN
        #: until the yaw rate varies)
        self.spread = math.nan
        #: seconds both have been at or below the limit
        self.opposed_for = 0.0
        #: seconds the yaw rate has been out of scale
        self.scaled_for = 0.0
        #: what found it out of scale: ``gains`` or ``spread`` (empty: not found)
        self.scaled_by = ''
        #: the smaller witness's standard deviation over the lagged yaw rate's (NaN until
        #: both witnesses vary; inf for a yaw rate that does not vary at all)
        self.stillness = math.nan
        #: seconds the yaw rate has hardly varied while both witnesses did
        self.still_for = 0.0

    @property
    def opposed(self) -> bool:
        """Return True once the yaw rate has run against both witnesses for ``hold``."""
        return self.opposed_for > 0.0 and self.opposed_for >= self.settings.hold

    @property
    def out_of_scale(self) -> bool:
        """Return True once the yaw rate has been out of scale with both for ``hold``."""
        return self.scaled_for > 0.0 and self.scaled_for >= self.settings.hold

    @property
    def too_still(self) -> bool:
        """Return True once the yaw rate has hardly varied while both witnesses did, ``hold``."""
        return self.still_for > 0.0 and self.still_for >= self.settings.hold

    @property
    def faulty(self) -> bool:
        """Return True once the yaw rate runs against the car or is out of scale."""
        return self.opposed or self.out_of_scale

    def verdict(self) -> str:
        """Return what is wrong with the yaw rate, ``yaw_rate ...`` (empty: nothing)."""
        found = []
        if self.opposed:
            # (dev-probe99: a yaw rate 0.5 s late runs against the car too)
            found.append(f'runs against the steering and the relative yaw (correlations '
                         f'{self.correlation:.2f}, {self.kinematic_correlation:.2f} for '
                         f'{self.opposed_for:.2g} s; its sign wrong, or late?)')
        if self.out_of_scale:
            # the evidence that found it: the gains where the law shook the car, the spread
            # where it hardly steered while the car drove straight out of a curve
            # (dev-probe99: the spread named beside the gains that found it read as
            # reassuring, 'varies 1.02 times as much')
            how = (f'gains {self.gain:.3g} and {self.kinematic_gain:.2g}, right: about 1 '
                   'each' if self.scaled_by == 'gains' else
                   f'it varies {self.spread:.3g} times as much as they do')
            found.append(f'out of scale with the steering and the relative yaw for '
                         f'{self.scaled_for:.2g} s ({how}; in deg/s, or its scale wrong?)')
        return 'yaw_rate ' + ' and '.join(found) if found else ''

    def step(self, dt: float, r: float, steering: float, v_x: float, wheelbase: float,
             eps_r: float, rho: float) -> bool:
        """
        Take one measured yaw rate and relative yaw, and the steering sent before them.

        :param dt: time since the previous step [s] (0: nothing moves; above 1 s: a
            restart).
        :param r: measured yaw rate [rad/s].
        :param steering: the command sent last [rad].
        :param v_x: speed [m/s].
        :param wheelbase: ``L`` [m] (the steering's kinematic yaw rate ``v_x delta / L``).
        :param eps_r: measured relative yaw [rad].
        :param rho: the road's curvature received at the CG (0: none) [1/m].
        :return: :attr:`faulty`.
        """
        s = self.settings
        if (not all(math.isfinite(x) for x in (dt, r, steering, v_x, eps_r, rho))
                or v_x < s.min_speed or not 0.0 <= dt <= 1.0):
            self.reset()
            return False
        if dt == 0.0:
            return self.faulty
        steered, turn = v_x * steering / wheelbase, v_x * rho
        if math.isnan(self._steered):
            self._steered, self._eps, self._turn, self._rate = steered, eps_r, turn, r
            self._mean = [steered, r, turn, r]
            self.command_mean = steering
            return False
        b = min(1.0, dt / s.lag) if s.lag > 0.0 else 1.0
        self._steered += b * (steered - self._steered)
        # eps_r through the lag: its rate is the lagged eps_r', so the lagged r - v_x rho
        eps_before = self._eps
        self._eps += b * (eps_r - self._eps)
        self._turn += b * (turn - self._turn)
        self._rate += b * (r - self._rate)
        kinematic = (self._eps - eps_before) / dt + self._turn
        a = min(1.0, dt / s.memory)
        self.command_mean += a * (steering - self.command_mean)
        self._since += dt
        if self._since < SETTLE * s.lag:
            # the lags start from the first sample: an outlier there would be a swing of
            # its own in the moments
            return self.faulty
        # exponentially weighted, centred moments over ``memory``, each sample of the
        # first ``memory`` weighed alike (the first one's weight is no longer 1)
        self._steps += 1
        self._weight = min(1.0, self._weight + a)
        a = max(a, 1.0 / self._steps)
        values = (self._steered, r, kinematic, self._rate)
        deltas = [x - m for x, m in zip(values, self._mean)]
        self._mean = [m + a * d for m, d in zip(self._mean, deltas)]
        self._var = [(1.0 - a) * (v + a * d * d) for v, d in zip(self._var, deltas)]
        self._cov = [(1.0 - a) * (self._cov[0] + a * deltas[0] * deltas[1]),
                     (1.0 - a) * (self._cov[1] + a * deltas[2] * deltas[3])]
        ready, floor = self._weight >= 1.0 - math.exp(-1.0), s.excitation ** 2
        # no evidence either way: an opposition or a scale already seen stays
        self.correlation = self.kinematic_correlation = math.nan
        self.gain = self.kinematic_gain = self.spread = math.nan
        if ready and min(self._var[:3]) >= floor:
            self.correlation = self._cov[0] / math.sqrt(self._var[0] * self._var[1])
            self.kinematic_correlation = self._cov[1] / math.sqrt(
                max(self._var[2] * self._var[3], 1e-300))
            opposed = (self.correlation <= s.steering_limit
                       and self.kinematic_correlation <= s.limit)
            self.opposed_for = self.opposed_for + dt if opposed else 0.0
        # the witnesses need not vary: their standing still while the yaw rate varies is
        # the evidence
        if ready and self._var[3] >= floor:
            self.spread = math.sqrt(self._var[3] / max(self._var[0], self._var[2], 1e-300))
            self.kinematic_gain = self._cov[1] / self._var[3]
            by = 'spread' if self.spread >= s.scale_limit else ''
            if self._var[0] >= floor:
                self.gain = self._cov[0] / self._var[0]
                if (abs(self.gain) >= s.scale_limit
                        and abs(self.kinematic_gain) <= 1.0 / s.scale_limit):
                    by = 'gains'
            self.scaled_for = self.scaled_for + dt if by else 0.0
            self.scaled_by = by
        # the other way: a yaw rate frozen (a bridge repeating its last value with new
        # stamps) or too small while the car is steered and turns (told, not refused)
        self.stillness = math.nan
        witness = min(self._var[0], self._var[2])
        if ready and witness >= floor:
            self.stillness = (math.sqrt(witness / self._var[3]) if self._var[3] > 0.0
                              else math.inf)
            still = self.stillness >= s.scale_limit
            self.still_for = self.still_for + dt if still else 0.0
        return self.faulty
