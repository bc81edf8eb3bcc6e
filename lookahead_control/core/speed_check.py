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
integrated, had moved the car ``travel`` less: shifted by the speed's travel, the older
preview should lie on the newer. The shift that fits best (searched from 0 to the
preview's length less ``min_overlap``) is the travel the road saw. Judged only while the
curvature varies by ``excitation`` or more over the compared stretch (a straight or a
constant arc moves no curvature), at or above ``min_speed``: where the speed's travel
misfits by ``misfit`` of the curvature's variation or more, at least ``contrast`` times
the best shift's misfit, and the best shift is off it by a factor of ``limit`` or more,
the speed is out of scale; for ``hold`` seconds, the check tells it. A speed right within
a factor of ``limit`` fits (a speed 10 % high is not found here). A periodic road fits a
shift and that shift plus its period alike: the speed's travel still fits where the speed
is right.

A bridge without a preview (a curvature at the CG alone) gives no evidence; a preview that
does not move (repeated with new stamps) and one whose distances are scaled (a preview
in other units) are found out of scale too: the WARN names them.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
import math
from typing import Sequence

from lookahead_control.core.params import check_range
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
    :param misfit: the speed's travel misfits at this rms difference over the
        curvature's standard deviation, or more [-].
    :param contrast: ... and at this many times the best shift's rms difference [-].
    :param limit: the best shift is off the speed's travel by this factor or more [-].
    :param hold: out of scale this long (of stamps) is told [s].
    :param min_speed: below it the check restarts [m/s].
    :param every: the previews are compared at most this often (stamps) [s].
    """

    travel: float = 8.0
    max_age: float = 5.0
    min_overlap: float = 15.0
    excitation: float = 2.0e-4
    misfit: float = 0.15
    contrast: float = 3.0
    limit: float = 1.5
    hold: float = 1.0
    min_speed: float = 1.0
    every: float = 0.1

    def __post_init__(self) -> None:
        """Check the ranges."""
        check_range('speed_check.travel', self.travel, 0.1, 1000.0, unit='m')
        check_range('speed_check.max_age', self.max_age, 0.1, 60.0, unit='s')
        check_range('speed_check.min_overlap', self.min_overlap, 0.0, 1000.0, unit='m')
        check_range('speed_check.excitation', self.excitation, 1.0e-6, 1.0, unit='1/m')
        check_range('speed_check.misfit', self.misfit, 0.0, 10.0)
        check_range('speed_check.contrast', self.contrast, 1.0, 1000.0)
        check_range('speed_check.limit', self.limit, 1.05, 100.0)
        check_range('speed_check.hold', self.hold, 0.0, 60.0, unit='s')
        check_range('speed_check.min_speed', self.min_speed, 0.0, 100.0, unit='m/s')
        check_range('speed_check.every', self.every, 0.0, 10.0, unit='s')


#: the shifts searched are this fine [m]
SHIFT_STEP = 0.1


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
        # (stamp [ns], odometer [m], distances [m], curvatures [1/m]) of the previews kept
        self._previews: deque[tuple[int, float, np.ndarray, np.ndarray]] = deque()
        self._judged_at: int | None = None
        #: the speed's travel over the road's (the best shift) at the last comparison
        #: judged (NaN: none)
        self.ratio = math.nan
        #: the speed's travel's rms misfit over the best shift's at that comparison
        self.contrast = math.nan
        #: seconds (of stamps) the speed has been out of scale
        self.off_for = 0.0
        # the log ratios of the comparisons out of scale since it last fitted
        self._logs: list[float] = []

    @property
    def out_of_scale(self) -> bool:
        """Return True once the speed has been out of scale with the preview for ``hold``."""
        return self.off_for > 0.0 and self.off_for >= self.settings.hold

    def step(self, dt: float, v_x: float, stamp_ns: int,
             ahead: Sequence[tuple[float, float]]) -> bool:
        """
        Take one answer's speed and the curvature preview received.

        :param dt: time since the previous step [s] (0: nothing moves; above 1 s: a
            restart).
        :param v_x: the speed [m/s].
        :param stamp_ns: the preview's stamp [ns] (the same as before: nothing new).
        :param ahead: the preview's ``(distance ahead [m], curvature [1/m])`` points,
            sorted by distance (fewer than 3: no preview, no evidence).
        :return: :attr:`out_of_scale`.
        """
        s = self.settings
        if not (math.isfinite(dt) and math.isfinite(v_x)) or v_x < s.min_speed \
                or not 0.0 <= dt <= 1.0:
            self.reset()
            return False
        self._odometer += v_x * dt
        newest = self._previews[-1][0] if self._previews else None
        if len(ahead) < 3 or (newest is not None and stamp_ns <= newest):
            return self.out_of_scale
        points = np.asarray(ahead, dtype=float)
        if not np.all(np.isfinite(points)):
            return self.out_of_scale
        self._previews.append((stamp_ns, self._odometer, points[:, 0], points[:, 1]))
        while stamp_ns - self._previews[0][0] > s.max_age * 1e9:
            self._previews.popleft()
        if self._judged_at is not None and stamp_ns - self._judged_at < s.every * 1e9:
            return self.out_of_scale
        older = None
        for preview in reversed(self._previews):
            if self._odometer - preview[1] >= s.travel:
                older = preview
                break
        if older is None:
            return self.out_of_scale
        since = (stamp_ns - self._judged_at) * 1e-9 if self._judged_at is not None else 0.0
        self._judged_at = stamp_ns
        verdict = self._compare(older, self._previews[-1])
        if verdict:
            self.off_for += since
            self._logs.append(math.log(self.ratio))
        elif verdict is not None:
            self.off_for, self._logs = 0.0, []
        return self.out_of_scale

    @property
    def scale(self) -> float:
        """Return the speed's travel over the road's while out of it; NaN while it fits."""
        return math.exp(sum(self._logs) / len(self._logs)) if self._logs else math.nan

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
        d_new, k_new = newer[2], newer[3]
        travel = newer[1] - older[1]
        length = float(d_old[-1])
        if length - travel < s.min_overlap:
            return None
        shifts = np.arange(0.0, length - s.min_overlap + 1e-9, SHIFT_STEP)
        shifts = np.append(shifts, travel)
        where = d_new[None, :] + shifts[:, None]
        inside = (where <= length) & (where >= d_old[0])
        values = np.interp(where, d_old, k_old)
        counts = inside.sum(axis=1)
        fits = counts >= 3
        errors = np.where(inside, values - k_new[None, :], 0.0)
        mean_square = np.full(shifts.shape, np.inf)
        mean_square[fits] = (errors[fits] ** 2).sum(axis=1) / counts[fits]
        if not fits[-1]:
            return None
        compared = k_new[inside[-1]]
        spread = float(np.std(compared))
        if spread < s.excitation:
            return None
        best = int(np.argmin(mean_square[:-1]))
        misfit = math.sqrt(float(mean_square[-1]))
        best_misfit = math.sqrt(float(mean_square[best]))
        self.ratio = travel / shifts[best] if shifts[best] > 0.0 else math.inf
        self.contrast = misfit / best_misfit if best_misfit > 0.0 else math.inf
        return bool(misfit >= s.misfit * spread and self.contrast >= s.contrast
                    and not 1.0 / s.limit < self.ratio < s.limit)
