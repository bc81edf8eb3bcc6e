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
A check of the received road curvature against the car's own yaw measurements.

The relative yaw moves as ``eps_r' = r - rho (v_x cos eps_r - v_y sin eps_r) / (1 - rho
y_cg)`` whatever the tyres do (kinematics in the lane's frame).
Predicted from the measured yaw rate and the curvature received, and pulled to the
measured relative yaw over ``leak`` (a yaw-rate bias would otherwise integrate up), its
distance from the measurement is a residual: about 0 with the right curvature, ``-leak
v_x Delta rho`` under a curvature off by ``Delta rho`` on an arc (a map 20 % off on a
3 m/s^2 curve at 30 m/s: 40 mrad), and a pulse of about ``v_x rho`` times the time by
which a map is ahead or behind. The default law takes the curvature as the truth with the
look-ahead distance as its lever (dev-probe73: a map 20 % off, 0.74 m off an S-bend at
30 m/s): the controller tells when the map and the car disagree, and at ``fallback``
times the threshold (a map far off: in sign, in scale by a third, a curve it does not
have) a law with its own curvature estimate drops the map (``dropped``) until the
residual has stayed below the threshold for ``recover`` seconds.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from lookahead_control.core.params import check_range


def lane_motion(eps_r: float, r: float, v_x: float, rho: float, y_cg: float,
                v_y: float) -> tuple[float, float]:
    """
    Return the speed along the lane and the relative yaw's rate its kinematics predict.

    :param eps_r: relative yaw [rad].
    :param r: yaw rate [rad/s].
    :param v_x: speed [m/s].
    :param rho: the lane's curvature at the car [1/m].
    :param y_cg: CG error [m].
    :param v_y: lateral velocity [m/s].
    :return: ``(a, r - a rho)`` with ``a = (v_x cos eps_r - v_y sin eps_r) / (1 - rho
        y_cg)`` (the lane's frame; the projection at least 0.1).
    """
    along = (v_x * math.cos(eps_r) - v_y * math.sin(eps_r)) / max(1.0 - rho * y_cg, 0.1)
    return along, r - along * rho


@dataclass(frozen=True)
class MapCheckParams:
    """
    Settings of the check.

    :param leak: time over which the prediction is pulled to the measured relative
        yaw (forgets a yaw-rate bias) [s].
    :param smoothing: low pass of the residual (the relative yaw's noise) [s].
    :param threshold: a residual this large or larger is a disagreement, at and above
        ``speed`` [rad].
    :param speed: below it the threshold grows as ``(speed / v_x)^2`` [m/s].
    :param min_speed: below this speed the check restarts [m/s].
    """

    leak: float = 2.0
    smoothing: float = 0.2
    threshold: float = 0.01
    speed: float = 20.0
    min_speed: float = 5.0

    def __post_init__(self) -> None:
        """Check the ranges."""
        check_range('map_check.leak', self.leak, 0.1, 60.0, unit='s')
        check_range('map_check.smoothing', self.smoothing, 0.0, 10.0, unit='s')
        check_range('map_check.threshold', self.threshold, 1.0e-4, 1.0, unit='rad')
        check_range('map_check.speed', self.speed, 0.0, 100.0, unit='m/s')
        check_range('map_check.min_speed', self.min_speed, 0.0, 100.0, unit='m/s')


class MapCheck:
    """The residual of the curvature received against the yaw measurements."""

    def __init__(self, settings: MapCheckParams | None = None) -> None:
        """
        Start without a prediction.

        :param settings: the settings (defaults if None).
        """
        self.settings = settings or MapCheckParams()
        self._predicted = math.nan
        self._rate = math.nan
        self._speed = math.inf
        #: the smoothed residual: measured minus predicted relative yaw [rad]
        self.residual = 0.0
        #: whether the curvature received is dropped (``step``'s ``fallback``)
        self.dropped = False
        self._calm = 0.0
        self._fallback = 0.0

    def reset(self, keep_dropped: bool = False) -> None:
        """
        Restart (no curvature, a gap, a slow car): the next step starts again.

        :param keep_dropped: keep a dropped curvature dropped until the check, started
            again, has been below the threshold for ``recover`` (a curvature lost for a
            moment: dev-probe76, a wrong map back in use for 0.24 s after each loss).
        """
        self._predicted = math.nan
        self._rate = math.nan
        self.residual = 0.0
        self.dropped = self.dropped and keep_dropped
        self._calm = 0.0

    def step(self, dt: float, eps_r: float, r: float, v_x: float, rho: float,
             y_cg: float = 0.0, v_y: float = 0.0, fallback: float = 0.0,
             recover: float = 1.0) -> float:
        """
        Take one measurement and the curvature at the CG received with it.

        With ``fallback`` > 0 a residual of ``fallback`` times the threshold (at its
        speed) or more sets ``dropped``; it clears once the
        residual has stayed below the threshold for ``recover`` seconds, at a restart
        (a gap, a slow car, a non-finite input; not a curvature lost, :meth:`reset`) and
        when ``fallback`` changes.

        :param dt: time since the previous step [s] (0: the same measurement again, a
            timer faster than it: nothing moves; above 1 s: a restart).
        :param eps_r: measured relative yaw [rad].
        :param r: measured yaw rate [rad/s].
        :param v_x: speed [m/s].
        :param rho: curvature received at the CG [1/m].
        :param y_cg: measured CG error [m] (the lane's frame: ``1 / (1 - rho y_cg)``).
        :param v_y: measured lateral velocity [m/s].
        :param fallback: the multiple of the threshold that drops the curvature; 0: never.
        :param recover: seconds below the threshold that take it again [s].
        :return: the smoothed residual [rad].
        """
        s = self.settings
        values = (dt, eps_r, r, v_x, rho, y_cg, v_y)
        if not all(math.isfinite(x) for x in values) or v_x < s.min_speed:
            self.reset()
            return self.residual
        self._speed = v_x
        if dt == 0.0 and not math.isnan(self._predicted):
            # dev-probe75: a timer answering twice per lateral error restarted the check
            # at every second answer, and it never told anything in timer mode
            return self.residual
        # the lane's frame (Frenet): at 6 m/s on R 9 m the small-angle form was 10 mrad
        # off a perfect map (dev-probe75)
        along, rate = lane_motion(eps_r, r, v_x, rho, y_cg, v_y)
        if math.isnan(self._predicted) or not 0.0 < dt <= 1.0:
            self._predicted, self._rate, self.residual = eps_r, rate, 0.0
            self._calm = 0.0
            self.dropped = self.dropped and 0.0 <= dt <= 1.0   # a gap takes it again
            return self.residual
        # the trapezoid of the last and this step's rate, then the pull to the measurement
        predicted = self._predicted + dt * 0.5 * (self._rate + rate)
        predicted += (eps_r - predicted) * min(1.0, dt / s.leak)
        self._predicted, self._rate = predicted, rate
        share = min(1.0, dt / s.smoothing) if s.smoothing > 0.0 else 1.0
        self.residual += share * ((eps_r - predicted) - self.residual)
        self._judge(dt, abs(self.residual), self.threshold_at(v_x), fallback, recover)
        return self.residual

    def _judge(self, dt: float, size: float, threshold: float, fallback: float,
               recover: float) -> None:
        """Drop the curvature, or take it again, on the residual's ``size``."""
        if fallback != self._fallback:
            # dev-probe76: map_fallback set to 0 while dropped kept the map dropped for
            # good; a new setting judges afresh
            self._fallback, self.dropped, self._calm = fallback, False, 0.0
        if fallback <= 0.0:
            return
        if size >= fallback * threshold:
            self.dropped, self._calm = True, 0.0
        elif self.dropped:
            # below the threshold for recover seconds (recover 0: at once, below it)
            self._calm = self._calm + dt if size < threshold else 0.0
            self.dropped = size >= threshold or self._calm < recover

    def threshold_at(self, v_x: float) -> float:
        """
        Return the threshold at a speed [rad].

        The residual of a given error of the lateral acceleration grows as ``1 / v_x``
        (``leak v_x Delta rho``), the harm it does to the law with ``v_x``: the
        threshold is ``threshold (speed / v_x)^2`` below ``speed`` (20 m/s). At 6 m/s
        path_bridge's curvature fit on R 9 m gave 61 mrad with the right map
        (dev-probe75), a map x0.9 at 10 m/s 64 mrad (9 cm).

        :param v_x: speed [m/s].
        :return: the threshold.
        """
        s = self.settings
        return s.threshold * max(1.0, (s.speed / max(v_x, 1e-3)) ** 2)

    @property
    def disagrees(self) -> bool:
        """Return True while the residual is at the threshold (at its speed) or beyond."""
        return abs(self.residual) >= self.threshold_at(self._speed)
