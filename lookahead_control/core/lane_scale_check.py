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
A check of the lateral error's and the relative yaw's scale against the car's motion: told.

A lateral error in centimetres (100 times the metres) or a relative yaw in degrees (57.3
times the radians) leaves the range checks to refuse only their larger samples: dev-sc48
measured the default law 2-135 m off S-bends at 10-37 m/s with the lateral error in cm
(the input stale most of the time, the ERROR naming a range refusal, not the unit), and
0.2-124 m off with the relative yaw in degrees, told only as a map disagreeing with the
yaw rate and a steering oscillation.

Both have kinematics that need neither the road nor the tyres:

- the CG's offset moves as ``y_cg' = v_x sin eps_r + v_y cos eps_r``, and a lateral
  error measured ``d`` ahead on the tangent is ``y_cg + d eps_r``: the lateral error is
  predicted, up to a constant, by ``q = int (v_x sin eps_r + v_y cos eps_r) dt + d
  eps_r`` (the heading check's prediction, ``core/heading_check.py``);
- the relative yaw moves as ``eps_r' = r - v_x rho``: it is predicted, up to a constant,
  by ``int (r - v_x rho) dt``.

Each measured signal and its prediction go through the same band pass (a lag of ``lag``
minus one of ``washout``: noise, biases and the integrals' drift drop out) and are
compared over ``memory`` by centred moments: where they move together (correlation at or
above ``correlation``) the ratio of their standard deviations is the measured signal's
scale, about 1. Judged only while the prediction varies by its ``excitation`` or more, at
or above ``min_speed``; a scale at or above ``scale_limit`` for ``hold`` seconds is out of
scale. Told, never refused: a refusal takes the safe behaviour, which leaves a curve as
surely.

The check is given every sample received with a stamp that advances, refused for its
range or not (a unit error is mostly refused for range: the samples taken alone are too
few for evidence, dev-sc48), and with the other inputs received within ``max_age`` of
it. Only too large is judged: a lateral error too small is no unit in use, and a
relative yaw that moves less than its prediction is also a curve without a map (the
prediction moves by ``v_x rho``). A relative yaw too small (radians read as degrees)
makes the lateral error's read too large: the WARN names it.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
import math
import statistics
from typing import Optional

from lookahead_control.core.params import check_range, ParameterError

#: values beyond it are no evidence (a restart): the moments stay finite
HUGE = 1.0e6
#: the scale told is the median of this many last judged (one reading over ``memory``
#: swings with the noise and the motion: 0.73-1.28 (5-95 %) for a weave of the CG by 3.8
#: cm in 3 s at 37 m/s, the sensors' default noise)
SCALES = 500


@dataclass(frozen=True)
class LaneScaleParams:
    """
    Settings of the check.

    :param lag: the band pass's fast lag (noise) [s].
    :param washout: the band pass's slow lag, subtracted (biases, drift) [s].
    :param memory: time constant of the moments [s].
    :param lateral_excitation: the standard deviation the lateral error's band-passed
        prediction needs before it is judged [m].
    :param yaw_excitation: the same for the relative yaw's [rad].
    :param correlation: the correlation at or above which the two move together [-].
    :param scale_limit: a ratio of the standard deviations at or above it (or at or below
        its inverse) is out of scale [-].
    :param hold: out of scale this long is told [s].
    :param min_speed: below it the check restarts [m/s].
    :param max_age: the other inputs within this of the sample judged, else a restart [s].
    """

    lag: float = 0.2
    washout: float = 2.0
    memory: float = 1.0
    lateral_excitation: float = 0.01
    yaw_excitation: float = 0.0005
    correlation: float = 0.8
    scale_limit: float = 5.0
    hold: float = 1.0
    min_speed: float = 5.0
    max_age: float = 0.5

    def __post_init__(self) -> None:
        """Check the ranges."""
        check_range('lane_scale_check.lag', self.lag, 0.0, 5.0, unit='s')
        check_range('lane_scale_check.washout', self.washout, 0.1, 60.0, unit='s')
        check_range('lane_scale_check.memory', self.memory, 0.05, 60.0, unit='s')
        check_range('lane_scale_check.lateral_excitation', self.lateral_excitation, 1.0e-4,
                    10.0, unit='m')
        check_range('lane_scale_check.yaw_excitation', self.yaw_excitation, 1.0e-5, 1.0,
                    unit='rad')
        check_range('lane_scale_check.correlation', self.correlation, 0.0, 1.0)
        check_range('lane_scale_check.scale_limit', self.scale_limit, 1.5, 1000.0)
        check_range('lane_scale_check.hold', self.hold, 0.0, 60.0, unit='s')
        check_range('lane_scale_check.min_speed', self.min_speed, 0.0, 100.0, unit='m/s')
        check_range('lane_scale_check.max_age', self.max_age, 0.0, 5.0, unit='s')
        if not self.washout > self.lag:
            raise ParameterError(f'lane_scale_check.washout = {self.washout!r} s must be '
                                 f'above lane_scale_check.lag = {self.lag!r} s (a band pass)')


class ScaleRegression:
    """A measured signal against its prediction through one band pass: their scale."""

    def __init__(self, lag: float, washout: float, memory: float) -> None:
        """
        Start without statistics.

        :param lag: the band pass's fast lag [s].
        :param washout: its slow lag [s].
        :param memory: time constant of the moments [s].
        """
        self.lag, self.washout, self.memory = lag, washout, memory
        self.reset()

    def reset(self) -> None:
        """Forget the statistics."""
        self._fast: Optional[list[float]] = None
        self._slow = [0.0, 0.0]
        self._mean = [0.0, 0.0]
        self._var = [0.0, 0.0]
        self._cov = 0.0
        self._weight = 0.0
        self._steps = 0

    def step(self, dt: float, measured: float, predicted: float) -> None:
        """
        Take one pair.

        :param dt: time since the previous pair [s] (> 0).
        :param measured: the measured signal.
        :param predicted: its prediction (up to a constant).
        """
        values = (measured, predicted)
        if self._fast is None:
            self._fast, self._slow = list(values), list(values)
            return
        fast = min(1.0, dt / self.lag) if self.lag > 0.0 else 1.0
        slow = min(1.0, dt / self.washout)
        self._fast = [f + fast * (x - f) for f, x in zip(self._fast, values)]
        self._slow = [w + slow * (x - w) for w, x in zip(self._slow, values)]
        band = [f - w for f, w in zip(self._fast, self._slow)]
        # exponentially weighted, centred moments over ``memory``, the first ones alike
        self._steps += 1
        a = min(1.0, dt / self.memory)
        self._weight = min(1.0, self._weight + a)
        a = max(a, 1.0 / self._steps)
        deltas = [x - m for x, m in zip(band, self._mean)]
        self._mean = [m + a * d for m, d in zip(self._mean, deltas)]
        self._var = [(1.0 - a) * (v + a * d * d) for v, d in zip(self._var, deltas)]
        self._cov = (1.0 - a) * (self._cov + a * deltas[0] * deltas[1])

    def judge(self, excitation: float, correlation: float) -> float:
        """
        Return the measured signal's scale (NaN: no evidence).

        :param excitation: the prediction's standard deviation needed [unit of it].
        :param correlation: the correlation needed.
        :return: the ratio of the standard deviations where the two move together.
        """
        if (self._weight < 1.0 - math.exp(-1.0) or self._var[1] < excitation ** 2
                or self._var[0] <= 0.0):
            return math.nan
        if self._cov / math.sqrt(self._var[0] * self._var[1]) < correlation:
            return math.nan
        return math.sqrt(self._var[0] / self._var[1])


class LaneScaleCheck:
    """The lateral error and the relative yaw against their kinematic predictions: scale."""

    def __init__(self, settings: LaneScaleParams | None = None) -> None:
        """
        Start without statistics.

        :param settings: the settings (defaults if None).
        """
        self.settings = settings or LaneScaleParams()
        s = self.settings
        self._lateral = ScaleRegression(s.lag, s.washout, s.memory)
        self._yaw = ScaleRegression(s.lag, s.washout, s.memory)
        self.reset()

    def reset(self) -> None:
        """Restart both (a time jump): statistics from the next samples."""
        self.reset_lateral()
        self.reset_yaw()

    def reset_lateral(self) -> None:
        """Restart the lateral error's statistics."""
        self._lateral.reset()
        #: the stamp of the last lateral error stepped [ns] (None: restarted)
        self.lateral_stamp: Optional[int] = None
        self._lateral_integral = 0.0
        self._lateral_scales: deque[float] = deque(maxlen=SCALES)
        #: the lateral error's scale read at the last step (NaN: no evidence there)
        self.lateral_reading = math.nan
        #: seconds it has been out of scale
        self.lateral_for = 0.0

    def reset_yaw(self) -> None:
        """Restart the relative yaw's statistics."""
        self._yaw.reset()
        #: the stamp of the last relative yaw stepped [ns] (None: restarted)
        self.yaw_stamp: Optional[int] = None
        self._yaw_integral = 0.0
        self._yaw_scales: deque[float] = deque(maxlen=SCALES)
        #: the relative yaw's scale read at the last step (NaN: no evidence there)
        self.yaw_reading = math.nan
        #: seconds it has been out of scale
        self.yaw_for = 0.0

    @property
    def lateral_scale(self) -> float:
        """Return the lateral error's scale, the median of the last judged (NaN: none)."""
        return statistics.median(self._lateral_scales) if self._lateral_scales else math.nan

    @property
    def yaw_scale(self) -> float:
        """Return the relative yaw's scale, the median of the last judged (NaN: none)."""
        return statistics.median(self._yaw_scales) if self._yaw_scales else math.nan

    @property
    def lateral_out_of_scale(self) -> bool:
        """Return True once the lateral error has been out of scale for ``hold``."""
        return self.lateral_for > 0.0 and self.lateral_for >= self.settings.hold

    @property
    def yaw_out_of_scale(self) -> bool:
        """Return True once the relative yaw has been out of scale for ``hold``."""
        return self.yaw_for > 0.0 and self.yaw_for >= self.settings.hold

    def _dt(self, last: Optional[int], stamp_ns: int, *values: float) -> float:
        """Return the step's time (0: none, NaN: a restart)."""
        s = self.settings
        if not all(math.isfinite(x) and abs(x) <= HUGE for x in values):
            return math.nan
        if values[0] < s.min_speed:         # the speed first
            return math.nan
        if last is None:
            return 0.0
        dt = (stamp_ns - last) * 1e-9
        return dt if 0.0 < dt <= 1.0 else math.nan

    def step_lateral(self, stamp_ns: int, lateral_error: float, distance: float,
                     eps_r: float, v_x: float, v_y: float) -> bool:
        """
        Take one lateral error with the relative yaw and the speeds received last.

        :param stamp_ns: its stamp [ns].
        :param lateral_error: the lateral error received [m].
        :param distance: where it is measured, ahead of the CG [m].
        :param eps_r: the relative yaw received [rad].
        :param v_x: speed [m/s].
        :param v_y: lateral speed [m/s].
        :return: :attr:`lateral_out_of_scale`.
        """
        s = self.settings
        dt = self._dt(self.lateral_stamp, stamp_ns, v_x, lateral_error, distance, eps_r,
                      v_y)
        if math.isnan(dt):
            self.reset_lateral()
            return False
        self.lateral_stamp = stamp_ns
        if dt > 0.0:
            self._lateral_integral += (v_x * math.sin(eps_r) + v_y * math.cos(eps_r)) * dt
        self._lateral.step(dt, lateral_error, self._lateral_integral + distance * eps_r)
        if dt == 0.0:
            return self.lateral_out_of_scale
        scale = self.lateral_reading = self._lateral.judge(s.lateral_excitation,
                                                           s.correlation)
        if math.isnan(scale):       # no evidence either way: a scale already seen stays
            return self.lateral_out_of_scale
        self._lateral_scales.append(scale)
        # too small is not judged: on the CommonRoad car the kinematics hold less well,
        # and a law regulating the point measured keeps its motion small (the league's
        # runs as they are: down to 0.26, bench.lane_scale_check)
        self.lateral_for = self.lateral_for + dt if scale >= s.scale_limit else 0.0
        return self.lateral_out_of_scale

    def step_yaw(self, stamp_ns: int, eps_r: float, r: float, v_x: float,
                 rho: float) -> bool:
        """
        Take one relative yaw with its yaw rate, the speed and the curvature received last.

        :param stamp_ns: its stamp [ns].
        :param eps_r: the relative yaw received [rad].
        :param r: the yaw rate received with it [rad/s].
        :param v_x: speed [m/s].
        :param rho: the road's curvature at the CG (0: none received) [1/m].
        :return: :attr:`yaw_out_of_scale`.
        """
        s = self.settings
        dt = self._dt(self.yaw_stamp, stamp_ns, v_x, eps_r, r, rho)
        if math.isnan(dt):
            self.reset_yaw()
            return False
        self.yaw_stamp = stamp_ns
        self._yaw_integral += (r - v_x * rho) * dt
        self._yaw.step(dt, eps_r, self._yaw_integral)
        if dt == 0.0:
            return self.yaw_out_of_scale
        # too small is not judged: a curve without a map moves the prediction by ``v_x
        # rho`` and the relative yaw hardly
        scale = self.yaw_reading = self._yaw.judge(s.yaw_excitation, s.correlation)
        if math.isnan(scale):
            return self.yaw_out_of_scale
        self._yaw_scales.append(scale)
        self.yaw_for = self.yaw_for + dt if scale >= s.scale_limit else 0.0
        return self.yaw_out_of_scale
