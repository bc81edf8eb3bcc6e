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
A check of the relative yaw's sign against the lateral error's motion: told, not refused.

A relative yaw or a lateral error of the wrong sign (a bridge that flips one of them)
makes every law steer the car out of the lane: dev-sc45 measured the departure 1.4-6.7 s
after a flipped relative yaw and 2.9-9.7 s after a flipped lateral error (core, linear
plant, 20-30 m/s, straights and S-bends), and the only word was the lateral error's range
check once the car was more than 5 m off. The yaw-rate check does not see it (the yaw
rate is right; its relative-yaw witness runs at -1 alone, as a curve without a map can
make it). The controller tells it (``/diagnostics`` WARN) and does not refuse the
input: dev-probe100 found a lane change along a path shifted from the lane the relative
yaw is measured from, a relative-yaw bias of 0.02 rad or a ``v_y`` bias of 0.3 m/s at
start-up, a lane reference flickering between two lanes, and a lateral error measured
from the curved lane 40 m ahead taken for a wrong sign, and a refusal there (the safe
behaviour) put the car 3.5-50 m off the road where the law alone kept it.

The lane's kinematics do not need the road: the CG's offset moves as ``y_cg' = v_x sin
eps_r + v_y cos eps_r`` whatever the curvature and the tyres, and a lateral error
measured ``d`` ahead on the tangent at the CG is ``y_cg + d eps_r``. So
the lateral error is predicted, up to a constant, by ``q = int (v_x sin eps_r + v_y cos
eps_r) dt + d eps_r`` from the relative yaw and the lateral speed alone, and follows the
prediction with a correlation near +1 wherever the car moves in the lane; with either
sign wrong, near -1.

Both go through the same band pass (a lag of ``lag`` minus a lag of ``washout``: the
lateral error's noise and the integral's drift drop out; a relative-yaw or
lateral-speed bias does once the band pass has settled, not in the first seconds) and
are correlated over ``memory``, centred. Only while both vary by ``excitation`` or
more, at or above ``min_speed``, is the correlation judged; at or below ``limit`` for
``hold`` seconds the two inputs run against each other. A lateral
speed of exactly 0 (a bridge that has none) is no witness and the check restarts: the
sideslip it leaves out of ``q`` is ``-v_x eps_r`` where the car tracks the lane, so that
``q`` moves against the lateral error in a lane change (dev-sc45: -0.91 at 37 m/s).
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from lookahead_control.core.params import check_range, ParameterError


@dataclass(frozen=True)
class HeadingCheckParams:
    """
    Settings of the check.

    :param lag: the band pass's fast lag (the lateral error's noise) [s].
    :param washout: the band pass's slow lag, subtracted (biases, drift) [s].
    :param memory: time constant of the correlation's statistics [s].
    :param excitation: the standard deviation both band-passed signals need before the
        correlation is judged [m].
    :param limit: a correlation at or below it runs against [-].
    :param hold: this long at or below the limit is the fault [s].
    :param min_speed: below it the check restarts [m/s].
    """

    lag: float = 0.2
    washout: float = 2.0
    memory: float = 1.0
    excitation: float = 0.05
    limit: float = -0.8
    hold: float = 0.25
    min_speed: float = 5.0

    def __post_init__(self) -> None:
        """Check the ranges."""
        check_range('heading_check.lag', self.lag, 0.0, 5.0, unit='s')
        check_range('heading_check.washout', self.washout, 0.1, 60.0, unit='s')
        if not self.washout > self.lag:
            raise ParameterError(f'heading_check.washout = {self.washout!r} s must be above '
                                 f'heading_check.lag = {self.lag!r} s (a band pass)')
        check_range('heading_check.memory', self.memory, 0.05, 60.0, unit='s')
        check_range('heading_check.excitation', self.excitation, 1.0e-4, 10.0, unit='m')
        check_range('heading_check.limit', self.limit, -1.0, 0.0)
        check_range('heading_check.hold', self.hold, 0.0, 60.0, unit='s')
        check_range('heading_check.min_speed', self.min_speed, 0.0, 100.0, unit='m/s')


class HeadingCheck:
    """The lateral error against its prediction from the relative yaw and the lateral speed."""

    def __init__(self, settings: HeadingCheckParams | None = None) -> None:
        """
        Start without statistics.

        :param settings: the settings (defaults if None).
        """
        self.settings = settings or HeadingCheckParams()
        self.reset()

    def reset(self) -> None:
        """Restart (a gap, a slow car, a non-finite input): statistics from the next step."""
        self._integral = math.nan       # int (v_x sin eps_r + v_y cos eps_r) dt
        self._fast = [0.0, 0.0]         # lateral error, prediction: through ``lag``
        self._slow = [0.0, 0.0]         # ... through ``washout``
        self._mean = [0.0, 0.0]
        self._var = [0.0, 0.0]
        self._cov = 0.0
        self._weight = 0.0
        #: the correlation of the lateral error with its prediction (NaN until excited)
        self.correlation = math.nan
        #: seconds it has been at or below the limit
        self.opposed_for = 0.0

    @property
    def opposed(self) -> bool:
        """Return True once the lateral error has run against its prediction for ``hold``."""
        return self.opposed_for > 0.0 and self.opposed_for >= self.settings.hold

    def step(self, dt: float, lateral_error: float, distance: float, eps_r: float,
             v_x: float, v_y: float) -> bool:
        """
        Take one lateral error with the relative yaw and the speeds measured with it.

        :param dt: time since the previous step [s] (0: nothing moves; above 1 s: a
            restart).
        :param lateral_error: the lateral error measured [m].
        :param distance: where it is measured, ahead of the CG [m].
        :param eps_r: measured relative yaw [rad].
        :param v_x: speed [m/s].
        :param v_y: lateral speed [m/s] (exactly 0: the bridge has none, a restart).
        :return: :attr:`opposed`.
        """
        s = self.settings
        if (not all(math.isfinite(x) for x in (dt, lateral_error, distance, eps_r, v_x, v_y))
                or v_x < s.min_speed or not 0.0 <= dt <= 1.0 or v_y == 0.0):
            self.reset()
            return False
        if dt == 0.0:
            return self.opposed
        if math.isnan(self._integral):
            self._integral = 0.0
            values = (lateral_error, distance * eps_r)
            self._fast, self._slow = list(values), list(values)
            return False
        self._integral += (v_x * math.sin(eps_r) + v_y * math.cos(eps_r)) * dt
        values = (lateral_error, self._integral + distance * eps_r)
        fast = min(1.0, dt / s.lag) if s.lag > 0.0 else 1.0
        slow = min(1.0, dt / s.washout)
        self._fast = [f + fast * (x - f) for f, x in zip(self._fast, values)]
        self._slow = [w + slow * (x - w) for w, x in zip(self._slow, values)]
        band = [f - w for f, w in zip(self._fast, self._slow)]
        # exponentially weighted, centred moments over ``memory``
        a = min(1.0, dt / s.memory)
        deltas = [x - m for x, m in zip(band, self._mean)]
        self._mean = [m + a * d for m, d in zip(self._mean, deltas)]
        self._var = [(1.0 - a) * (v + a * d * d) for v, d in zip(self._var, deltas)]
        self._cov = (1.0 - a) * (self._cov + a * deltas[0] * deltas[1])
        self._weight = min(1.0, self._weight + a)
        if self._weight < 1.0 - math.exp(-1.0) or min(self._var) < s.excitation ** 2:
            # no evidence either way: an opposition already seen stays
            self.correlation = math.nan
            return self.opposed
        self.correlation = self._cov / math.sqrt(self._var[0] * self._var[1])
        self.opposed_for = self.opposed_for + dt if self.correlation <= s.limit else 0.0
        return self.opposed
