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
An estimate of how far the curvature the law reads runs ahead of the car's yaw.

The laws read the road's curvature at the car from the polygon, moved to the yaw
sample's stamp (``curvature_at_yaw_stamp``): that needs the map's and the IMU's clocks to
agree. An IMU clock 50 / 90 ms ahead of the map's reads every curve 1.9 / 3.3 m early at
37 m/s (dev-probe125: S3 2.7 -> 17.0 / 31.1 cm), within every stamp check; a map
localized off along the road does the same. Nothing else tells it: the map check's
residual (``core/map_check.py``) is a pulse of ``v_x rho`` times the lead, 4.6 mrad for
50 ms at 37 m/s on R 400 m, under its threshold.

The relative yaw moves as ``eps_r' = r - a rho`` with ``a = (v_x cos eps_r - v_y sin
eps_r) / (1 - rho y_cg)`` (kinematics in the lane's frame). Predicted from the measured
yaw rate and the curvature read, pulled to the measured relative yaw over ``leak``, the
prediction's distance ``e`` from the measurement is, to first order, a sum of three
known responses: ``e = lead G + scale H - bias C``, where ``G`` is the same leaky
prediction of ``a rho' / v_x`` (a curvature read ``lead`` metres ahead), ``H`` that of
``a rho`` (a curvature off in scale) and ``C`` that of 1 (a yaw-rate bias). A
least-squares fit of the three over the last ``memory`` seconds separates them: only
curve entries and exits (``rho'`` not 0) tell the lead; a scale error or a gyro bias,
which the map check judges, does not move it. The fit's lead is told when it is
``threshold`` or more and :meth:`MapTimingCheck.confidence` times its standard error or
more. The standard error is the larger of two: the fit's residual taken as correlated
over ``correlation``, and the spread of the scores (the responses times the residual)
summed over blocks of ``block`` seconds, which holds a noise coloured over seconds or a
gyro bias that wanders (dev-probe127: a relative yaw wandering 3 mrad over 2-10 s was
told as a 2.5 m lead). A variance from a few curve entries is itself uncertain: the
multiple is Student's t with as many degrees of freedom as blocks tell the lead, less
the three parameters (6.6 for four, 3.6 for fifteen; none for a single curve entry).

A jump of the relative yaw (a relocalization, a lane-marking switch) or a spike of the
yaw rate is no lead: its miss decays over ``leak``, and met on a curve entry it was
fitted as one (dev-probe126: a 20 mrad step 3 s into a drive told a 15 m lead for 26
s). A step whose miss over the last ``jump_window`` is ``jump`` times that miss's
running rms or more (and ``jump_floor`` or more) starts the prediction again at the
measurement: not fitted (a yaw-rate spike of 0.3 rad/s for 50 ms on the first curve
entry told a 34 m lead before).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from functools import lru_cache
import math

from lookahead_control.core.map_check import lane_motion
from lookahead_control.core.params import check_range, ParameterError


@dataclass(frozen=True)
class MapTimingParams:
    """
    Settings of the estimate.

    :param leak: time over which the prediction is pulled to the measured relative yaw
        [s].
    :param memory: the fit forgets with this time constant [s].
    :param threshold: a lead or lag this large or larger is told [m].
    :param confidence: ... and this many times its standard error or more.
    :param correlation: the residual's correlation time, for the standard error's floor
        [s].
    :param block: the length of the blocks whose scores give the standard error [s].
    :param jump: a miss over ``jump_window`` this many times its running rms or more is a
        jump.
    :param jump_floor: ... and this large or larger [rad].
    :param jump_window: the time a jump is judged over [s].
    :param refit: the fit is solved again at most this often [s].
    :param min_speed: below this speed no step is taken [m/s].
    """

    leak: float = 2.0
    memory: float = 60.0
    threshold: float = 1.5
    confidence: float = 3.0
    correlation: float = 0.25
    block: float = 2.0
    jump: float = 4.0
    jump_floor: float = 0.003
    jump_window: float = 0.1
    refit: float = 0.1
    min_speed: float = 5.0

    def __post_init__(self) -> None:
        """Check the ranges."""
        check_range('map_timing.leak', self.leak, 0.1, 60.0, unit='s')
        check_range('map_timing.memory', self.memory, 1.0, 3600.0, unit='s')
        check_range('map_timing.threshold', self.threshold, 0.01, 100.0, unit='m')
        check_range('map_timing.confidence', self.confidence, 0.0, 100.0)
        check_range('map_timing.correlation', self.correlation, 0.0, 10.0, unit='s')
        check_range('map_timing.block', self.block, 0.1, 60.0, unit='s')
        check_range('map_timing.jump', self.jump, 1.0, 1000.0)
        check_range('map_timing.jump_floor', self.jump_floor, 0.0, 1.0, unit='rad')
        check_range('map_timing.jump_window', self.jump_window, 0.0, 1.0, unit='s')
        check_range('map_timing.refit', self.refit, 0.0, 10.0, unit='s')
        check_range('map_timing.min_speed', self.min_speed, 0.0, 100.0, unit='m/s')
        if self.memory > MAX_BLOCKS * self.block:
            # dev-probe128: memory 3600 s in blocks of 0.1 s kept 108001 blocks, a solve
            # of 102 ms every 0.1 s
            raise ParameterError(f'map_timing.memory = {self.memory:g} s is more than '
                                 f'{MAX_BLOCKS} blocks of map_timing.block = {self.block:g} '
                                 f's; allowed: memory at most {MAX_BLOCKS} x block')


#: the fit's memory spans at most this many blocks (``BLOCKS_KEPT`` times as many kept)
MAX_BLOCKS = 100
#: the upper triangle of a symmetric 3 x 3 matrix, as the sums keep it
PAIRS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
#: blocks are kept over this many times the fit's memory
BLOCKS_KEPT = 3.0
#: the fitted parameters: the lead, the scale, the bias
PARAMETERS = 3
#: the miss's rms follows the noise over this time [s]
MISS_MEMORY = 10.0
#: no jump is judged before the rms has this many steps
MISS_LEARNED = 20


class MapTimingCheck:
    """The lead of the curvature read over the yaw measurements, fitted."""

    def __init__(self, settings: MapTimingParams | None = None) -> None:
        """
        Start with nothing fitted.

        :param settings: the settings (defaults if None).
        """
        self.settings = settings or MapTimingParams()
        #: steps taken for jumps (the prediction started again) since the start
        self.jumps = 0
        self.forget()

    def reset(self) -> None:
        """Start the prediction again (a gap, no curvature, a slow car); keep the fit."""
        self._last: tuple[float, float, float] | None = None    # (eps_r, rate, rho)
        self._predicted = 0.0
        self._error = 0.0
        self._responses = [0.0, 0.0, 0.0]
        self._window: deque[tuple[float, float]] = deque()
        self._window_time = 0.0

    def forget(self) -> None:
        """Forget the fit too (a restart of the controller's core: a time jump)."""
        self.reset()
        # the fit's sums: the upper triangle of the information (00 01 02 11 12 22),
        # the moment, the squares and the weight
        self._info = [0.0] * 6
        self._moment = [0.0, 0.0, 0.0]
        self._squares = 0.0
        self._weight = 0.0
        self._miss_square = 0.0
        self._misses = 0
        self._fitted = (0.0, math.inf)
        self._since_fit = math.inf
        # the fit's sums per block of `block` seconds, for the scores' spread: each
        # block's (end [s of fitted time], moment, information), the newest still open
        self._time = 0.0
        self._blocks: deque[tuple[float, list[float], list[float]]] = deque()
        self._open: tuple[list[float], list[float]] = ([0.0] * 3, [0.0] * 6)
        self._open_time = 0.0
        self._blocks_told = 0.0

    def step(self, dt: float, eps_r: float, r: float, v_x: float, rho: float,
             y_cg: float = 0.0, v_y: float = 0.0) -> bool:
        """
        Take one yaw measurement and the curvature at the car read with it.

        :param dt: time since the previous step [s] (0: the same measurement again,
            nothing moves; above 1 s or not finite: a restart).
        :param eps_r: measured relative yaw [rad].
        :param r: measured yaw rate [rad/s].
        :param v_x: speed [m/s].
        :param rho: curvature read at the car [1/m].
        :param y_cg: measured CG error [m].
        :param v_y: measured lateral velocity [m/s].
        :return: whether the step was fitted (not a restart, a repeat, a jump, a slow
            car or a bad value: the fit kept is then not of this moment).
        """
        s = self.settings
        values = (dt, eps_r, r, v_x, rho, y_cg, v_y)
        if not all(math.isfinite(x) for x in values) or v_x < s.min_speed:
            self.reset()
            return False
        if dt == 0.0 and self._last is not None:
            return False
        along, rate = lane_motion(eps_r, r, v_x, rho, y_cg, v_y)     # (as the map check)
        if self._last is None or not 0.0 < dt <= 1.0 or not math.isfinite(rate):
            self.reset()
            if math.isfinite(rate):
                self._last = (eps_r, rate, rho)
                self._predicted = eps_r
            return False
        last_eps, last_rate, last_rho = self._last
        self._last = (eps_r, rate, rho)
        pull = min(1.0, dt / s.leak)
        # the prediction as the map check makes it (a trapezoid, then the pull), and the
        # three responses through the same steps: to a lead of the curvature [m] (G), to
        # its scale (H), to a yaw-rate bias (C)
        predicted = self._predicted + dt * 0.5 * (last_rate + rate)
        miss = eps_r - predicted
        # the miss over the last jump_window: a spike of the yaw rate over a few steps is
        # one jump, not a few steps of noise (dev-probe126: 0.6 rad/s for 50 ms)
        window = self._window
        window.append((dt, miss - self._error))
        self._window_time += dt
        while len(window) > 1 and self._window_time - window[0][0] >= s.jump_window - 1e-12:
            self._window_time -= window.popleft()[0]
        recent = sum(x for _, x in window)
        limit = max(s.jump * math.sqrt(self._miss_square), s.jump_floor)
        # the rms follows the noise, a jump counted at the limit; a plain mean of the
        # first steps (learned from the floor over MISS_MEMORY, the noise of the default
        # sensors made 15-29 jumps in the first seconds of a run: dev-sc54)
        self._misses += 1
        share = max(min(1.0, dt / MISS_MEMORY), 1.0 / self._misses)
        self._miss_square += share * (min(recent * recent, limit * limit)
                                      - self._miss_square)
        if abs(recent) >= limit and self._misses > MISS_LEARNED:
            # a jump of the relative yaw or a spike of the yaw rate: started again here
            self.jumps += 1
            self.reset()
            self._last = (eps_r, rate, rho)
            self._predicted = eps_r
            return False
        g, h, c = self._responses
        g = (g + along / v_x * (rho - last_rho)) * (1.0 - pull)
        h = (h + dt * along * 0.5 * (rho + last_rho)) * (1.0 - pull)
        c = (c + dt) * (1.0 - pull)
        self._responses = [g, h, c]
        self._predicted = predicted + miss * pull
        error = miss * (1.0 - pull)
        self._error = error
        # a lead adds to the measured motion what the prediction took off, as does a
        # scale; a yaw-rate bias adds to the prediction
        row = (g, h, -c)
        products = [row[i] * row[j] for i, j in PAIRS]
        if not all(math.isfinite(x) for x in (*products, error * error, *row)):
            self.reset()
            return False
        keep = math.exp(-dt / s.memory)
        self._time += dt
        moment, info = self._open
        self._open = ([a + dt * x * error for a, x in zip(moment, row)],
                      [a + dt * p for a, p in zip(info, products)])
        self._open_time += dt
        if self._open_time >= s.block:
            self._blocks.append((self._time, *self._open))
            self._open, self._open_time = ([0.0] * 3, [0.0] * 6), 0.0
            while len(self._blocks) > BLOCKS_KEPT * s.memory / s.block + 1:
                self._blocks.popleft()
        self._info = [keep * a + dt * p for a, p in zip(self._info, products)]
        self._moment = [keep * m + dt * x * error for m, x in zip(self._moment, row)]
        self._squares = keep * self._squares + dt * error * error
        self._weight = keep * self._weight + dt
        self._since_fit += dt
        if self._since_fit >= s.refit:
            self._fitted, self._since_fit = self._solve(), 0.0
        return True

    def fit(self) -> tuple[float, float]:
        """
        Return the lead and its standard error [m], as last solved.

        :return: ``(lead, standard error)``; ``(0, inf)`` while the curvature has not
            varied enough to tell a lead (a straight or a constant arc).
        """
        return self._fitted

    def _solve(self) -> tuple[float, float]:
        a00, a01, a02, a11, a12, a22 = self._info
        if self._weight <= 0.0 or a00 <= 0.0:
            return 0.0, math.inf
        # normalized to a unit diagonal (the responses' scales differ by 1e4), a hair of
        # ridge for a response that never moved (the scale on a straight)
        d = [math.sqrt(max(x, 1e-300)) for x in (a00, a11, a22)]
        b01, b02, b12 = a01 / (d[0] * d[1]), a02 / (d[0] * d[2]), a12 / (d[1] * d[2])
        one = 1.0 + 1e-9
        # the inverse of the symmetric [[1, b01, b02], [b01, 1, b12], [b02, b12, 1]]
        c00, c11, c22 = one * one - b12 * b12, one * one - b02 * b02, one * one - b01 * b01
        c01, c02, c12 = b02 * b12 - b01 * one, b01 * b12 - b02 * one, b01 * b02 - b12 * one
        det = one * c00 + b01 * c01 + b02 * c02
        if not det > 0.0:
            return 0.0, math.inf
        inverse = [[c00, c01, c02], [c01, c11, c12], [c02, c12, c22]]
        inverse = [[inverse[i][j] / (det * d[i] * d[j]) for j in range(3)] for i in range(3)]
        theta = [sum(inverse[i][j] * self._moment[j] for j in range(3)) for i in range(3)]
        explained = sum(t * m for t, m in zip(theta, self._moment))
        rest = (self._squares - explained) / self._weight
        # the lead's variance: the residual's as if correlated over `correlation`, or
        # that of the blocks' scores through the fit (a noise coloured over seconds, a
        # wandering gyro bias: dev-probe127), whichever is larger
        floor = max(0.0, rest) * max(self.settings.correlation, 1e-3) * inverse[0][0]
        spread = max(floor, self._block_spread(theta, inverse[0]))
        # the responses are of the curvature read, (1 + k) times the road's: the fit's
        # scale is k / (1 + k) and its lead the road's over (1 + k)
        share = 1.0 - theta[1]
        if not (math.isfinite(rest) and math.isfinite(spread) and math.isfinite(theta[0])
                and share > 0.1):
            return 0.0, math.inf
        return theta[0] / share, math.sqrt(spread) / share

    def _block_spread(self, theta: list[float], w: list[float]) -> float:
        """
        Return the lead's variance from the blocks' scores at the fit ``theta``.

        A block's score is its moment less its information times ``theta`` (the sum of
        the responses times the residual); the lead's variance is ``w' Omega w`` with
        ``w`` the inverse information's first row and ``Omega`` the scores' outer
        products, weighted by the square of the fit's fading, times ``G / (G - 3)`` for
        the three parameters fitted from the same ``G`` blocks (their effective number,
        by the lead's information in each under the same weights; dev-probe128: without
        it 1.4-1.6 times too small). Sets :attr:`_blocks_told` to ``G - 3``, the
        degrees of freedom.
        """
        total = 0.0
        memory = self.settings.memory
        blocks = [*self._blocks, (self._time, *self._open)]
        weights = [math.exp(-2.0 * (self._time - end) / memory) for end, _, _ in blocks]
        share = [weight * info[0] for weight, (_, _, info) in zip(weights, blocks)]
        squares = sum(a * a for a in share)
        count = sum(share) ** 2 / squares if squares > 0.0 else 0.0
        self._blocks_told = count - PARAMETERS if math.isfinite(count) else 0.0
        if self._blocks_told <= 0.0:
            return math.inf
        for weight, (_, moment, info) in zip(weights, blocks):
            full = [[info[0], info[1], info[2]], [info[1], info[3], info[4]],
                    [info[2], info[4], info[5]]]
            score = [moment[i] - sum(full[i][j] * theta[j] for j in range(3))
                     for i in range(3)]
            along = sum(a * b for a, b in zip(w, score))
            total += weight * along * along
        return total * count / self._blocks_told

    def told(self) -> float | None:
        """
        Return the lead told, or None while within the threshold or not significant.

        :return: the lead [m] (positive: the curvature read ahead of the car).
        """
        lead, error = self.fit()
        s = self.settings
        needed = self.confidence() * error
        # (an error of 0 times an infinite multiple is no significance: dev-probe128)
        if math.isfinite(needed) and abs(lead) >= max(s.threshold, needed):
            return lead
        return None

    def confidence(self) -> float:
        """
        Return the multiple of the standard error a lead told must reach.

        ``confidence`` as a normal quantile, widened to Student's t of as many degrees
        of freedom as the blocks' spread has (:meth:`_block_spread`): a variance from a
        few curve entries is itself uncertain (dev-probe127: a relative yaw wandering 3
        mrad over seconds told 11-29 s into a drive). 6.6 for four degrees of freedom,
        3.6 for fifteen; infinite below one.

        :return: the multiple.
        """
        dof = self._blocks_told
        if not dof >= 1.0:
            return math.inf
        return t_quantile(self.settings.confidence, round(dof, 1))


@lru_cache(maxsize=1024)
def t_quantile(z: float, dof: float) -> float:
    """
    Return the quantile of Student's t with ``dof`` degrees of freedom at the normal's ``z``.

    The ``t`` whose upper tail equals the normal's above ``z``, found by bisection on the
    tail ``I_x(dof / 2, 1 / 2) / 2`` with ``x = dof / (dof + t^2)``.

    :param z: the normal quantile (0-100).
    :param dof: the degrees of freedom (at least 1).
    :return: the quantile (``z`` or more).
    """
    tail = 0.5 * math.erfc(z / math.sqrt(2.0))
    if tail <= 0.0:
        return math.inf

    def beyond(t: float) -> bool:
        """Return whether the t distribution's upper tail above ``t`` is above ``tail``."""
        return 0.5 * _incomplete_beta(0.5 * dof, 0.5, dof / (dof + t * t)) > tail

    low, high = z, max(2.0 * z, 1.0)
    while beyond(high):
        low, high = high, 2.0 * high
        if high > 1e12:
            return math.inf
    for _ in range(100):
        middle = 0.5 * (low + high)
        if beyond(middle):
            low = middle
        else:
            high = middle
        if high - low <= 1e-9 * high:
            break
    return 0.5 * (low + high)


def _incomplete_beta(a: float, b: float, x: float) -> float:
    """Return the regularized incomplete beta function ``I_x(a, b)`` (0 <= x <= 1)."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    front = math.exp(math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b)
                     + a * math.log(x) + b * math.log1p(-x))
    if x < (a + 1.0) / (a + b + 2.0):
        return front * _beta_fraction(a, b, x) / a
    return 1.0 - front * _beta_fraction(b, a, 1.0 - x) / b


def _beta_fraction(a: float, b: float, x: float) -> float:
    """Return the continued fraction of the incomplete beta function (Lentz's method)."""
    tiny = 1e-300
    c, d = 1.0, 1.0 - (a + b) * x / (a + 1.0)
    d = 1.0 / (d if abs(d) > tiny else tiny)
    result = d
    for m in range(1, 300):
        for numerator in (m * (b - m) * x / ((a + 2 * m - 1) * (a + 2 * m)),
                          -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1))):
            d = 1.0 + numerator * d
            d = 1.0 / (d if abs(d) > tiny else tiny)
            c = 1.0 + numerator / c
            c = c if abs(c) > tiny else tiny
            result *= c * d
        if abs(c * d - 1.0) < 1e-15:
            break
    return result
