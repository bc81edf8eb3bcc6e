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
  predicted, up to a constant, by ``q = int (v_x eps_r + v_y) dt + d eps_r`` (the heading
  check's prediction, ``core/heading_check.py``, linear in ``eps_r``: 1.5 % off at 0.3
  rad, and a relative yaw in degrees keeps its scale there where the sine of 57 times it
  made noise of it; dev-probe107);
- the relative yaw moves as ``eps_r' = r - v_x rho``: it is predicted, up to a constant,
  by ``int (r - v_x rho) dt`` with the curvature received, and without a map by ``int (r
  - r_slow) dt``, ``r_slow`` the yaw rate through a lag of ``turn_lag`` (the road turns
  the car slowly, the steering fast; dev-probe107: without a map the first, with ``rho``
  0, told a relative yaw in degrees 17-19 s late on S-bends, or never). The second is
  judged only without a map (with the map, a car far off the road after a lateral error
  in cm read 5 and more on it), against ``free_limit``: it misses the relative yaw's slow
  part, which the lag takes for the road's, and reads high.

Each measured signal and its prediction go through the same band pass (a lag of ``lag``
minus one of ``washout``: noise, biases and the integrals' drift drop out) and are
compared over ``memory`` by centred moments: where they move together (correlation at or
above ``correlation``) the ratio of their standard deviations is the measured signal's
scale, about 1. Noise cannot make a large scale there: ``correlation x ratio`` is the
regression gain, so a reading of 5 at 0.8 is a gain of 4. Judged only while the
prediction varies by its ``excitation`` or more, at or above ``min_speed``; a scale at or
above ``scale_limit`` or, for the lateral error, at or below ``small_limit``, for
``hold`` seconds of readings is out of scale, and told at each reading out of scale from
then on (none without evidence: dev-probe107 found a verdict told on and on after the
bridge was fixed, on a straight where nothing moved); a gap of evidence longer than
``hold`` starts the time afresh (dev-probe108: 14 curve entries added up). The moments
start ``SETTLE`` washouts after a restart (dev-probe108: the band pass's start on a
bias's ramp read as a scale). A lateral error is not judged too small while ``v_y`` is
exactly 0 (a bridge without it: the prediction misses the sideslip). Told, never
refused: a refusal takes the safe behaviour, which leaves a curve as surely.

The check is given every sample received with a stamp that advances, refused for its
range or not (a unit error is mostly refused for range: the samples taken alone are too
few for evidence, dev-sc48), and with the other inputs received within ``max_age`` of
it; the relative yaw continued across the wrap of the quaternion it came as
(:func:`unwrap`). A relative yaw that moves less than predicted is not judged (the road's turn in a
curve without a map, or with the map lagging, moves the prediction), nor a lateral error
between ``small_limit`` and 1 (the CommonRoad car's kinematics read down to 0.26 in the
league's runs). A lateral error moving much less than predicted is a relative yaw in
degrees (with the yaw rate in deg/s too, the relative yaw's own reading is 1:
dev-probe107), or a lateral speed too large or biased; one moving much more, a lateral
error in cm or mm, a relative yaw too small, a lane reference jumping between lanes, or
an offset measured to the curved lane far ahead (dev-probe108): the WARN names them. A
bridge with every input in the same other units (cm, degrees and deg/s) reads about 1
everywhere here and is not told (dev-probe108).
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
#: the scale told is the median of at most this many last readings out of scale (one
#: reading over ``memory`` swings with the noise and the motion: 0.73-1.28 (5-95 %) for a
#: weave of the CG by 3.8 cm in 3 s at 37 m/s, the sensors' default noise); the readings
#: restart where the scale crosses a limit (dev-probe107: the median of 500 readings told
#: a lateral error in cm as 1.02 for 4 s after a long drive with the right unit)
SCALES = 500
#: washouts of settling after a restart before the moments start
SETTLE = 2.0


def unwrap(raw: float, before: Optional[tuple[float, float]]) -> float:
    """
    Return a relative yaw continued across the wrap at +-pi of the angle it was sent as.

    The relative yaw travels as a quaternion: in degrees it wraps where the true one
    passes 3.14 degrees, in mrad at 3.14 mrad (dev-probe109: the wrapped values broke the
    correlation, and a relative yaw in degrees or mrad went untold once the car moved).

    :param raw: the relative yaw received [rad].
    :param before: the previous one received and its continued value (None: none).
    :return: the continued value (the received one after none, or where one is not
        finite or beyond :data:`HUGE`, which the check takes as a restart).
    """
    # (the fuzz test: 1e300 after -1.8e308 made math.remainder(inf) raise)
    if before is None or not all(math.isfinite(x) and abs(x) <= HUGE for x in (raw, *before)):
        return raw
    return before[1] + math.remainder(raw - before[0], 2.0 * math.pi)


@dataclass(frozen=True)
class LaneScaleParams:
    """
    Settings of the check.

    :param lag: the band pass's fast lag (noise) [s].
    :param washout: the band pass's slow lag, subtracted (biases, drift) [s].
    :param memory: time constant of the moments [s].
    :param turn_lag: the lag of the yaw rate taken for the road's turn without a map [s].
    :param lateral_excitation: the standard deviation the lateral error's band-passed
        prediction needs before it is judged [m].
    :param yaw_excitation: the same for the relative yaw's [rad].
    :param correlation: the correlation at or above which the two move together [-].
    :param scale_limit: a ratio of the standard deviations at or above it is out of scale
        [-].
    :param small_limit: a ratio of the lateral error's at or below it is out of scale [-].
    :param free_limit: the relative yaw's ratio without a map at or above it is out of
        scale [-].
    :param hold: out of scale this long is told [s].
    :param min_speed: below it the check restarts [m/s].
    :param max_age: the other inputs within this of the sample judged, else a restart [s].
    """

    lag: float = 0.2
    washout: float = 2.0
    memory: float = 1.0
    turn_lag: float = 1.0
    lateral_excitation: float = 0.01
    yaw_excitation: float = 0.0005
    correlation: float = 0.8
    scale_limit: float = 5.0
    small_limit: float = 0.1
    free_limit: float = 10.0
    hold: float = 1.0
    min_speed: float = 5.0
    max_age: float = 0.5

    def __post_init__(self) -> None:
        """Check the ranges."""
        check_range('lane_scale_check.lag', self.lag, 0.0, 5.0, unit='s')
        check_range('lane_scale_check.washout', self.washout, 0.1, 60.0, unit='s')
        check_range('lane_scale_check.memory', self.memory, 0.05, 60.0, unit='s')
        check_range('lane_scale_check.turn_lag', self.turn_lag, 0.05, 60.0, unit='s')
        check_range('lane_scale_check.lateral_excitation', self.lateral_excitation, 1.0e-4,
                    10.0, unit='m')
        check_range('lane_scale_check.yaw_excitation', self.yaw_excitation, 1.0e-5, 1.0,
                    unit='rad')
        check_range('lane_scale_check.correlation', self.correlation, 0.0, 1.0)
        check_range('lane_scale_check.scale_limit', self.scale_limit, 1.5, 1000.0)
        check_range('lane_scale_check.small_limit', self.small_limit, 0.0, 0.67)
        check_range('lane_scale_check.free_limit', self.free_limit, 1.5, 1000.0)
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
        self._since = 0.0               # time since the restart (the lags settle)
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
        self._since += dt
        if self._since < SETTLE * self.washout:
            # dev-probe108: the band pass's start on a ramp (a relative-yaw bias of 1-2
            # degrees at 20-37 m/s, a v_y bias) read as a lateral error moving 11-25 times
            # less than predicted, at 0.4 s of a restart in 10-13 of 48 phases
            return
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
        # each root apart: the product of a variance decayed to denormals (a measured
        # signal frozen for minutes) and a small one is 0.0
        spread = math.sqrt(self._var[0]) * math.sqrt(self._var[1])
        if spread <= 0.0 or self._cov / spread < correlation:
            return math.nan
        return math.sqrt(self._var[0]) / math.sqrt(self._var[1])


class ScaleVerdict:
    """One signal's state: its stamp and integrals, how long out of scale, its readings."""

    def __init__(self) -> None:
        """Start without readings."""
        self.reset()

    def reset(self) -> None:
        """Forget the readings."""
        self.stamp: Optional[int] = None
        self.integral = 0.0             # the prediction's integral
        self.free = 0.0                 # the relative yaw's without the map
        self.slow = math.nan            # the yaw rate through ``turn_lag``
        self.reading = math.nan
        self.out_for = 0.0
        self.unjudged = 0.0             # time since the last reading with evidence
        self.side = 0                   # of the readings kept: -1 small, 0 in, +1 large
        self.readings: deque[float] = deque(maxlen=SCALES)

    @property
    def scale(self) -> float:
        """Return the median of the stretch's readings (NaN: none)."""
        return statistics.median(self.readings) if self.readings else math.nan

    def take(self, dt: float, reading: float, large: float, small: float,
             hold: float) -> bool:
        """
        Take one step's reading.

        :param dt: the step's time [s].
        :param reading: the scale read (NaN: no evidence).
        :param large: at or above it out of scale.
        :param small: at or below it out of scale.
        :param hold: out of scale this long is told [s].
        :return: whether this reading is told out of scale.
        """
        self.reading = reading
        if math.isnan(reading):
            # no evidence either way: the time out stays over a gap shorter than ``hold``
            # (dev-probe108: the sideslip of 14 curve entries added up to a verdict)
            self.unjudged += dt
            if self.unjudged > hold:
                self.out_for, self.side = 0.0, 0
                self.readings.clear()
            return False
        self.unjudged = 0.0
        side = 1 if reading >= large else -1 if reading <= small else 0
        if side != self.side:
            self.readings.clear()
            self.side = side
        self.readings.append(reading)
        self.out_for = self.out_for + dt if side else 0.0
        return self.out_for > 0.0 and self.out_for >= hold


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
        self._free = ScaleRegression(s.lag, s.washout, s.memory)    # without the map
        self._lateral_verdict = ScaleVerdict()
        self._yaw_verdict = ScaleVerdict()
        self.reset()

    def reset(self) -> None:
        """Restart both (a time jump, the node activated): statistics from the next ones."""
        self.reset_lateral()
        self.reset_yaw()

    def reset_lateral(self) -> None:
        """Restart the lateral error's statistics."""
        self._lateral.reset()
        self._lateral_verdict.reset()

    def reset_yaw(self) -> None:
        """Restart the relative yaw's statistics."""
        self._yaw.reset()
        self._free.reset()
        self._yaw_verdict.reset()

    @property
    def lateral_stamp(self) -> Optional[int]:
        """Return the stamp of the last lateral error stepped [ns] (None: restarted)."""
        return self._lateral_verdict.stamp

    @property
    def yaw_stamp(self) -> Optional[int]:
        """Return the stamp of the last relative yaw stepped [ns] (None: restarted)."""
        return self._yaw_verdict.stamp

    @property
    def lateral_reading(self) -> float:
        """Return the lateral error's scale read at the last step (NaN: no evidence)."""
        return self._lateral_verdict.reading

    @property
    def yaw_reading(self) -> float:
        """Return the relative yaw's scale read at the last step (NaN: no evidence)."""
        return self._yaw_verdict.reading

    @property
    def lateral_scale(self) -> float:
        """Return the lateral error's scale: the median of its stretch (NaN: none)."""
        return self._lateral_verdict.scale

    @property
    def yaw_scale(self) -> float:
        """Return the relative yaw's scale: the median of its stretch (NaN: none)."""
        return self._yaw_verdict.scale

    @property
    def lateral_for(self) -> float:
        """Return the seconds of readings the lateral error has been out of scale."""
        return self._lateral_verdict.out_for

    @property
    def yaw_for(self) -> float:
        """Return the seconds of readings the relative yaw has been out of scale."""
        return self._yaw_verdict.out_for

    def _dt(self, last: Optional[int], stamp_ns: int, *values: float) -> float:
        """Return the step's time (0: the first, NaN: a restart)."""
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
        :return: whether it is told out of scale at this sample.
        """
        s, verdict = self.settings, self._lateral_verdict
        dt = self._dt(verdict.stamp, stamp_ns, v_x, lateral_error, distance, eps_r, v_y)
        if math.isnan(dt):
            self.reset_lateral()
            return False
        verdict.stamp = stamp_ns
        verdict.integral += (v_x * eps_r + v_y) * dt
        self._lateral.step(dt, lateral_error, verdict.integral + distance * eps_r)
        if dt == 0.0:
            return False
        # a v_y of exactly 0 (a bridge without it, docs/vehicle_bridge.md) leaves the
        # sideslip out of the prediction: on a curve entry it moves, the lateral error
        # does not (dev-probe108: told as moving 14-16 times less on the CommonRoad car)
        return verdict.take(dt, self._lateral.judge(s.lateral_excitation, s.correlation),
                            s.scale_limit, s.small_limit if v_y != 0.0 else 0.0, s.hold)

    def step_yaw(self, stamp_ns: int, eps_r: float, r: float, v_x: float,
                 rho: Optional[float]) -> bool:
        """
        Take one relative yaw with its yaw rate, the speed and the curvature received last.

        :param stamp_ns: its stamp [ns].
        :param eps_r: the relative yaw received [rad].
        :param r: the yaw rate received with it [rad/s].
        :param v_x: speed [m/s].
        :param rho: the road's curvature at the CG (None: none received) [1/m].
        :return: whether it is told out of scale at this sample.
        """
        s, verdict = self.settings, self._yaw_verdict
        mapped = rho is not None
        rho = rho if rho is not None else 0.0
        dt = self._dt(verdict.stamp, stamp_ns, v_x, eps_r, r, rho)
        if math.isnan(dt):
            self.reset_yaw()
            return False
        verdict.stamp = stamp_ns
        verdict.slow = r if math.isnan(verdict.slow) else (
            verdict.slow + min(1.0, dt / s.turn_lag) * (r - verdict.slow))
        verdict.integral += (r - v_x * rho) * dt
        verdict.free += (r - verdict.slow) * dt
        self._yaw.step(dt, eps_r, verdict.integral)
        self._free.step(dt, eps_r, verdict.free)
        if dt == 0.0:
            return False
        # with the map its prediction, else the one without (both run on: a map that
        # comes and goes); too small is not judged (the road's turn moves the predictions)
        reading = (self._yaw if mapped else self._free).judge(s.yaw_excitation,
                                                              s.correlation)
        # without a map the prediction misses the relative yaw's slow part, which the lag
        # takes for the road's: it reads high (bench.lane_scale_check: up to 3.6 as it is
        # on the CommonRoad car's curve entry at 10 m/s, degrees 47-78)
        return verdict.take(dt, reading, s.scale_limit if mapped else s.free_limit, 0.0,
                            s.hold)
