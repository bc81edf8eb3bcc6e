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
A check of the speed's scale against the curvature preview's motion: told, not refused.

A speed in km/h (3.6 times too large) stays under ``safety.max_speed`` (70 m/s) up to
19.4 m/s, so no range check refuses it, and it mis-tunes every law: dev-sc47 measured the
default law 0.3-1.3 m off an S-bend of 1 m/s^2 at 6-19 m/s and 19-26 m off one of 3
m/s^2, the paper's law 1.8-2.8 m and 7-26 m, and the only word was the map check's WARN
(the relative yaw's kinematics ``eps_r' = r - v_x rho`` see the speed times the
curvature, so a speed out of scale looks like a map out of scale there).

The curvature preview is an odometer that does not need the speed: a point ``d`` ahead
in one preview is ``d - s`` ahead in a preview taken after the car has moved ``s`` along
the road, whatever the tyres, the yaw rate, or the map's curvature scale and latency (the
same in both). So the newest preview is compared with the one taken when the speed,
integrated over the previews' stamps, had moved the car ``travel`` less: shifted by the
speed's travel, the older preview should lie on the newer. The shift that fits best
(searched from 0 to as far as the older preview reaches past the newer's start less
``min_overlap``, within ``reach``; a preview shorter than ``travel`` and ``min_overlap``
shrinks both) is the travel the road saw. Judged only while the curvature varies by
``excitation`` or more over the compared stretch (a straight or a constant arc moves no
curvature), at or above ``min_speed``: the best shift within a factor of ``band`` of the
speed's travel is the speed's; where it misfits by ``misfit`` or more and by
``contrast`` times the best shift off the speed's travel by a factor of ``limit`` or
more, the comparison is out of scale. The check tells it once such comparisons add up
to ``hold`` seconds, ``hold_travel`` metres of the speed's travel and ``comparisons`` in
number, a comparison that fits taking its time and travel off. A speed right within a
factor of ``band`` fits (a speed 10 % high is not found here), and so it does on a
periodic road, where a shift and that shift plus the period fit alike.

The speed is taken along the road (:func:`road_speed`: ``v_x cos eps_r - v_y sin eps_r``
over ``1 - rho y_cg``), and where that is far from ``v_x`` (a car far off the lane or
across it) there is no evidence. Only ``reach`` of a preview is used, and none with
points farther apart than ``max_spacing`` (dev-probe105: one point 1e9 m ahead made an
array of 74.5 GiB; points 15-25 m apart miss the shape of bends laid out for 4-6 m/s).

A bridge without a preview (a curvature at the CG alone) gives no evidence; a preview that
does not move (repeated with new stamps), one whose distances are scaled (a preview in
other units), and a path re-planned from the car's position at each message (it moves
with the car) are found out of scale too: the WARN names them.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
import math
from typing import Sequence

from lookahead_control.core.params import check_range, ParameterError
import numpy as np


@dataclass(frozen=True)
class SpeedCheckParams:
    """
    Settings of the check.

    :param travel: the speed's travel between the two previews compared [m].
    :param max_age: the older preview is at most this much older (stamps) [s].
    :param min_overlap: the stretch of road both previews must share [m].
    :param excitation: the curvature's standard deviation over the stretch compared
        before a comparison is judged [1/m].
    :param misfit: the speed's misfit (the rms difference at the best shift near its
        travel) at this or more [1/m] ...
    :param contrast: ... and at this many times the best shift's rms difference [-].
    :param band: a shift within this factor of the speed's travel is the speed's (the
        best of them is its misfit) [-].
    :param limit: ... compared with the best shift off it by this factor or more [-].
    :param hold: out of scale this long (of stamps) is told [s] ...
    :param hold_travel: ... over this much of the speed's travel [m] (more than
        ``travel``: a relocalization jump of the preview misfits the comparisons that
        span it, ``travel`` of them) ...
    :param comparisons: ... in this many comparisons or more (previews at 1 Hz: one
        comparison spans a second) [-]. A comparison that fits takes its time and
        travel off, down to 0 (where they restart).
    :param max_spacing: a preview with points farther apart than this within ``reach``
        is no evidence (linear between its points, it misses the road's shorter
        features) [m].
    :param min_speed: below it the check restarts [m/s].
    :param every: the previews are compared at most this often (stamps) [s].
    :param max_gap: a longer gap between previews restarts the check [s].
    :param reach: of each preview only this far ahead of its first point is kept [m].
    :param lane_limit: the speed along the road (:func:`road_speed`) off ``v_x`` by more
        than this fraction is no witness: a restart [-].
    """

    travel: float = 8.0
    max_age: float = 5.0
    min_overlap: float = 15.0
    excitation: float = 2.0e-4
    misfit: float = 5.0e-5
    contrast: float = 1.5
    band: float = 1.35
    limit: float = 1.5
    hold: float = 1.0
    hold_travel: float = 16.0
    comparisons: int = 5
    max_spacing: float = 10.0
    min_speed: float = 3.0
    every: float = 0.1
    max_gap: float = 1.0
    reach: float = 100.0
    lane_limit: float = 0.1

    def __post_init__(self) -> None:
        """Check the ranges."""
        check_range('speed_check.travel', self.travel, 0.1, 1000.0, unit='m')
        check_range('speed_check.max_age', self.max_age, 0.1, 60.0, unit='s')
        check_range('speed_check.min_overlap', self.min_overlap, 0.0, 1000.0, unit='m')
        check_range('speed_check.excitation', self.excitation, 1.0e-6, 1.0, unit='1/m')
        check_range('speed_check.misfit', self.misfit, 0.0, 1.0, unit='1/m')
        check_range('speed_check.contrast', self.contrast, 1.0, 1000.0)
        check_range('speed_check.band', self.band, 1.0, 100.0)
        check_range('speed_check.limit', self.limit, 1.05, 100.0)
        if self.band > self.limit:
            raise ParameterError(f'speed_check.band = {self.band!r} must be at most '
                                 f'speed_check.limit = {self.limit!r}')
        check_range('speed_check.hold', self.hold, 0.0, 60.0, unit='s')
        check_range('speed_check.hold_travel', self.hold_travel, 0.0, 1000.0, unit='m')
        check_range('speed_check.comparisons', self.comparisons, 1, 1000)
        check_range('speed_check.max_spacing', self.max_spacing, 0.1, 1000.0, unit='m')
        check_range('speed_check.min_speed', self.min_speed, 0.0, 100.0, unit='m/s')
        check_range('speed_check.every', self.every, 0.0, 10.0, unit='s')
        check_range('speed_check.max_gap', self.max_gap, 0.0, 60.0, unit='s')
        check_range('speed_check.reach', self.reach, 1.0, 10000.0, unit='m')
        check_range('speed_check.lane_limit', self.lane_limit, 0.0, 1.0)


#: the shifts searched are this fine [m]
SHIFT_STEP = 0.1
#: the newer preview is compared at points this far apart [m]
GRID_STEP = 1.0
#: the comparisons out of scale whose ratios make :attr:`SpeedCheck.scale`
LOGS_KEPT = 64


def road_speed(v_x: float, v_y: float, eps_r: float, rho: float, y_cg: float,
               limit: float) -> float | None:
    """
    Return the speed along the road, ``(v_x cos eps_r - v_y sin eps_r) / (1 - rho y_cg)``.

    That is the rate at which the road moves under the car, whatever the tyres (the lane's
    kinematics). Off ``v_x`` by more than ``limit`` (a fraction) it is no witness of the
    speed's scale: a car far off the lane or across it (dev-sc47: a car 35-87 m off an
    S-bend on a lateral error in cm made the road's travel 1.5 times the speed's), or a
    relative yaw that is itself wrong.

    :param v_x: the speed [m/s].
    :param v_y: the lateral speed [m/s].
    :param eps_r: the relative yaw [rad].
    :param rho: the road's curvature at the CG [1/m].
    :param y_cg: the CG's offset from the lane [m].
    :param limit: the largest relative difference taken [-].
    :return: the speed along the road [m/s], or None.
    """
    values = (v_x, v_y, eps_r, rho, y_cg)
    if not all(math.isfinite(x) for x in values) or v_x <= 0.0:
        return None
    projection = 1.0 - rho * y_cg
    if projection <= 0.0:
        return None
    along = (v_x * math.cos(eps_r) - v_y * math.sin(eps_r)) / projection
    return along if abs(along / v_x - 1.0) <= limit else None


class SpeedCheck:
    """The speed's travel against the curvature preview's motion."""

    def __init__(self, settings: SpeedCheckParams | None = None) -> None:
        """
        Start without previews.

        :param settings: the settings (defaults if None).
        """
        self.settings = settings or SpeedCheckParams()
        self.reset()

    def reset(self) -> None:
        """Restart (a gap, a slow car, a non-finite input): previews from the next step."""
        self._odometer = 0.0
        self._stamp: int | None = None      # the last preview's
        # (stamp [ns], odometer [m], distances [m], curvatures [1/m]) of the previews kept
        self._previews: deque[tuple[int, float, np.ndarray, np.ndarray]] = deque()
        self._judged_at: int | None = None
        #: the speed's travel over the road's (the best shift off it by ``limit`` or
        #: more) at the last comparison judged (NaN: none)
        self.ratio = math.nan
        #: the speed's misfit (the best shift within ``band``) over that shift's there
        self.contrast = math.nan
        #: seconds (of stamps) the speed has been out of scale, less those it fitted since
        self.off_for = 0.0
        #: the speed's travel over them [m]
        self.off_travel = 0.0
        #: comparisons out of scale since ``off_for`` was last 0
        self.off_count = 0
        # the log ratios of the last of them
        self._logs: deque[float] = deque(maxlen=LOGS_KEPT)
        self._judged_odometer = 0.0

    @property
    def out_of_scale(self) -> bool:
        """Return True once the speed has been out of scale with the preview long enough."""
        s = self.settings
        return (self.off_count >= s.comparisons and self.off_for >= s.hold
                and self.off_travel >= s.hold_travel)

    def step(self, stamp_ns: int, v_x: float, ahead: Sequence[tuple[float, float]]) -> bool:
        """
        Take one curvature preview received and the speed at its time.

        The speed's odometer runs on the previews' stamps: a gap of more than ``max_gap``
        between them restarts the check.

        :param stamp_ns: the preview's stamp [ns] (not after the last one: nothing new).
        :param v_x: the speed at that time [m/s] (not finite, or below ``min_speed``: a
            restart).
        :param ahead: the preview's ``(distance ahead [m], curvature [1/m])`` points
            (fewer than 3, not finite, or distances not rising: no evidence).
        :return: :attr:`out_of_scale`.
        """
        s = self.settings
        if self._stamp is not None and stamp_ns <= self._stamp:
            return self.out_of_scale
        if not math.isfinite(v_x) or v_x < s.min_speed:
            self.reset()
            return False
        if self._stamp is not None and (stamp_ns - self._stamp) * 1e-9 > s.max_gap:
            self.reset()
        if self._stamp is not None:
            self._odometer += v_x * (stamp_ns - self._stamp) * 1e-9
        self._stamp = stamp_ns
        points = np.asarray(ahead, dtype=float).reshape(-1, 2)
        if len(points) < 3 or not np.all(np.isfinite(points)):
            return self.out_of_scale
        # only ``reach`` of it: the cost is bounded whatever the points' distances
        # (dev-probe105: one point 1e9 m ahead made an array of 74.5 GiB)
        points = points[points[:, 0] <= points[0, 0] + s.reach]
        steps = np.diff(points[:, 0])
        if len(points) < 3 or not np.all(steps > 0.0) or float(steps.max()) > s.max_spacing:
            return self.out_of_scale
        self._previews.append((stamp_ns, self._odometer, points[:, 0], points[:, 1]))
        while stamp_ns - self._previews[0][0] > s.max_age * 1e9:
            self._previews.popleft()
        if self._judged_at is not None and stamp_ns - self._judged_at < s.every * 1e9:
            return self.out_of_scale
        travel, _ = self._lengths(float(points[-1, 0] - points[0, 0]))
        older = None
        for preview in reversed(self._previews):
            if self._odometer - preview[1] >= travel:
                older = preview
                break
        if older is None:
            return self.out_of_scale
        since = (stamp_ns - self._judged_at) * 1e-9 if self._judged_at is not None else 0.0
        moved = self._odometer - self._judged_odometer if self._judged_at is not None else 0.0
        self._judged_at, self._judged_odometer = stamp_ns, self._odometer
        verdict = self._compare(older, self._previews[-1])
        if verdict:
            self.off_for += since
            self.off_travel += moved
            self.off_count += 1
            self._logs.append(math.log(self.ratio))
        elif verdict is not None:
            # a fit takes its time off: a verdict flickering on a road the preview
            # draws coarsely still adds up (dev-probe105: hairpins of R 8 m at 7 m/s, a
            # speed in km/h, 20 m off and never told where each fit restarted it)
            self.off_for = max(0.0, self.off_for - since)
            self.off_travel = max(0.0, self.off_travel - moved)
            if self.off_for == 0.0:
                self.off_count = 0
                self._logs.clear()
        return self.out_of_scale

    def _lengths(self, length: float) -> tuple[float, float]:
        """
        Return the travel between the previews compared and the overlap they need.

        :param length: the preview's length [m] (shorter than ``travel`` and
            ``min_overlap`` allow: both shrink with it, to 0.3 and 0.5 of it).
        :return: ``(travel, min_overlap)`` [m].
        """
        s = self.settings
        return min(s.travel, 0.3 * length), min(s.min_overlap, 0.5 * length)

    @property
    def last_stamp(self) -> int | None:
        """Return the stamp of the last preview taken since the restart [ns] (None: none)."""
        return self._stamp

    @property
    def scale(self) -> float:
        """
        Return the speed's travel over the road's while out of it; NaN while it fits.

        The median of the last :data:`LOGS_KEPT` comparisons out of scale that found the
        road moving, inf where most of them found it still (a preview repeated without
        moving). A feature sharper than the preview's spacing moves in steps of the
        spacing: dev-probe106 found ratios of 41, 82 and inf on S1 (a step into the arc,
        points every 5 m) in km/h, and their mean WARNed 'the preview did not move'.
        """
        moving = [x for x in self._logs if math.isfinite(x)]
        if 2 * len(moving) < len(self._logs):
            return math.inf
        return math.exp(float(np.median(moving))) if moving else math.nan

    def _compare(self, older: tuple[int, float, np.ndarray, np.ndarray],
                 newer: tuple[int, float, np.ndarray, np.ndarray]) -> bool | None:
        """
        Compare two previews: whether the speed's travel misfits (None: no evidence).

        :param older: the older preview.
        :param newer: the newer one.
        :return: True where the speed is out of scale, False where it fits, None where
            the curvature does not vary enough to tell.
        """
        s = self.settings
        d_old, k_old = older[2], older[3]
        # the newer preview on a grid: the cost bounded by ``reach`` whatever its spacing
        d_new = np.arange(float(newer[2][0]), float(newer[2][-1]) + 1e-9, GRID_STEP)
        k_new = np.interp(d_new, newer[2], newer[3])
        if float(np.std(k_new)) < s.excitation:
            return None                 # nothing moves (before any large array)
        travel = newer[1] - older[1]
        overlap = self._lengths(float(d_old[-1] - d_old[0]))[1]
        # shifts from 0 as far as the older preview reaches past the newer's start, within
        # ``reach`` (dev-probe106: previews starting 1e7 m ahead, a route's arc length
        # sent as the distance, made 38 GiB)
        longest = min(float(d_old[-1]) - float(d_new[0]) - overlap, s.reach)
        if longest < travel:
            return None
        shifts = np.append(np.arange(0.0, longest + 1e-9, SHIFT_STEP), travel)
        where = d_new[None, :] + shifts[:, None]
        inside = (where <= d_old[-1]) & (where >= d_old[0])
        values = np.interp(where, d_old, k_old)
        counts = inside.sum(axis=1)
        fits = counts >= 3
        if not fits[-1]:
            return None
        errors = np.where(inside, values - k_new[None, :], 0.0)
        mean_square = np.full(shifts.shape, np.inf)
        mean_square[fits] = (errors[fits] ** 2).sum(axis=1) / counts[fits]
        spread = float(np.std(k_new[inside[-1]]))
        if spread < s.excitation:
            return None
        # the best shift within a factor of ``band`` of the speed's travel against the
        # best one off it by ``limit`` or more: on a periodic road a speed 10 % off fits
        # its own shift where the best one overall was an alias (dev-probe106: a slalom
        # of 20-36 m, a speed x 1.1 told as 0.13 times the road's travel)
        near = (shifts >= travel / s.band) & (shifts <= travel * s.band)
        # (over at least half as many points: the least of many mean squares over few
        # noisy points is low by chance)
        far = (((shifts <= travel / s.limit) | (shifts >= travel * s.limit)) & fits
               & (counts >= 0.5 * counts[-1]))
        if not np.any(far):
            return False
        misfit = math.sqrt(float(np.min(mean_square[near])))
        best = int(np.argmin(np.where(far, mean_square, np.inf)))
        best_misfit = math.sqrt(float(mean_square[best]))
        self.ratio = travel / shifts[best] if shifts[best] > 0.0 else math.inf
        self.contrast = misfit / best_misfit if best_misfit > 0.0 else math.inf
        return bool(misfit >= s.misfit and self.contrast >= s.contrast)
