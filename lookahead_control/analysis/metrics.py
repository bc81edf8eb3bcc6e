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
Performance metrics of lateral-control time series (pure numpy, no ROS).

Every quantity has one name, one symbol and one unit (:data:`QUANTITIES`, also listed in
``docs/model.md``); table columns carry the unit in their name (``_m``, ``_rad``,
``_rad_per_s``, ``_s``, ``_ms``, ``_mps``). A metric that does not apply to a run is NaN
(an empty cell, ``null`` in JSON) and the row's ``notes`` say why.

The relative-yaw step response at curve entry is described without dividing by the
final value (which is near zero for the paper's car at about 14.4 m/s, where
``eta v_x^2 = l_2``): the overshoot is over the step's own size ``|final - initial|``
(none for a pulse), the damping ratio comes from a damped cosine fitted to the response
from its largest extremum on (none when it does not oscillate or is not second-order),
and the settling band is 2% of the largest excursion from the final value.
"""

from __future__ import annotations

import math
from typing import Any, Mapping, NamedTuple, Optional, Sequence

from lookahead_control.core.control_law import arc_offset
import numpy as np
import numpy.typing as npt


Array = npt.NDArray[np.float64]
SETTLING_BAND = 0.02
MIN_DURATION = 1.0
STEP_HOLD = 2.0
MIN_STEP_FRACTION = 0.25
#: an overshoot is measured under noise only while 3 x the noise's effect is below this
#: fraction of the step (the overshoot's uncertainty stays below the 10 % goal)
MAX_NOISE_FRACTION = 0.1
FIT_TOLERANCE = 0.1
FIT_SAMPLES = 1000


class Quantity(NamedTuple):
    """
    A quantity's one name, symbol and unit, used in tables, plots and docs.

    :param symbol: its symbol (as in ``docs/model.md``).
    :param unit: its SI unit.
    :param label: a short name for legends and axes.
    :param meaning: what it is.
    """

    symbol: str
    unit: str
    label: str
    meaning: str


QUANTITIES: dict[str, Quantity] = {
    'cg_error': Quantity('y_cg', 'm', 'CG lateral error',
                         'lateral offset of the CG from the lane centre line, + left'),
    'look_down_error': Quantity('y_s', 'm', 'look-down error',
                                'y_cg + d_s eps_r: the offset a sensor at d_s ahead of '
                                'the CG reads (from the lane tangent at the CG)'),
    'look_ahead_lane_error': Quantity('y_a', 'm', 'look-ahead lane error',
                                      'y_v - y_o: offset of the point d_v ahead from the '
                                      'lane centre line (y_o exact, eq. 3)'),
    'regulated_error': Quantity('e', 'm', 'regulated error',
                                'y_v - y_ref: what the law drives to zero (= y_v with '
                                'the lane_tangent reference)'),
    'relative_yaw': Quantity('eps_r', 'rad', 'relative yaw',
                             'vehicle yaw minus lane tangent yaw, + CCW'),
    'steering_cmd': Quantity('delta_cmd', 'rad', 'steering command',
                             'front-wheel angle the controller commands, + left'),
    'steering': Quantity('delta', 'rad', 'wheel angle',
                         'front-wheel angle the plant reports (after its actuator), '
                         '+ left'),
    'd_v': Quantity('d_v', 'm', 'look-ahead distance', 'd_v in use'),
}
ERROR_NAMES = ('cg_error', 'look_down_error', 'look_ahead_lane_error', 'regulated_error')


def axis_label(name: str) -> str:
    """
    Return the plot label of a quantity: ``label symbol [unit]``.

    :param name: a key of :data:`QUANTITIES`.
    :return: the label.
    """
    q = QUANTITIES[name]
    return f'{q.label} {q.symbol} [{q.unit}]'


class StepMetrics(NamedTuple):
    """
    Response of a signal to a step of its input (here: relative yaw at curve entry).

    :param initial: value before the step (the first sample after it if none).
    :param final: final value, the mean of the last ``final_window`` of the window.
    :param excursion: largest |x - final| after the step [unit of the signal].
    :param overshoot: how far x goes beyond its final value, over the step's size
        ``|final - initial|`` [-]; NaN for a pulse (step under a quarter of the
        excursion).
    :param damping_ratio: of the damped cosine fitted by :func:`decay_damping` [-]; NaN
        when there is no second extremum beyond 2% of the first (zeta > 0.78) or the
        response is not second-order.
    :param settling_time: time after the step to stay within 2% of the excursion [s].
    :param note: why a value is NaN ('' when all apply).
    """

    initial: float
    final: float
    excursion: float
    overshoot: float
    damping_ratio: float
    settling_time: float
    note: str = ''


def peak(x: Array) -> float:
    """Return max |x|, NaN for an empty series."""
    return float(np.max(np.abs(x))) if x.size else math.nan


def rms(x: Array) -> float:
    """Return the root mean square of x, NaN for an empty series."""
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else math.nan


def damping_from_overshoot(overshoot: float) -> float:
    """
    Return the damping ratio of a second-order system with this step overshoot.

    :param overshoot: fractional overshoot (decay ratio per half period), in (0, 1).
    :return: zeta = -ln(OS) / sqrt(pi^2 + ln(OS)^2); NaN outside (0, 1).
    """
    if not 0.0 < overshoot < 1.0:
        return math.nan
    log = math.log(overshoot)
    return -log / math.sqrt(math.pi ** 2 + log * log)


def _nan_step(initial: float, final: float, note: str,
              excursion: float = math.nan) -> StepMetrics:
    return StepMetrics(initial, final, excursion, math.nan, math.nan, math.nan, note)


def lobe_peaks(deviation: Array, band: float) -> list[tuple[int, float]]:
    """
    Return the extrema of a deviation, one per lobe beyond ``+-band``.

    A lobe is a stretch on one side of zero; it ends only when the deviation crosses to
    beyond ``band`` on the other side (hysteresis: noise around zero makes no lobes).

    :param deviation: the signal minus its final value.
    :param band: the dead band [unit of the signal].
    :return: ``(index, value)`` of each lobe's largest magnitude, in time order.
    """
    peaks: list[tuple[int, float]] = []
    side = 0.0
    for i in np.nonzero(np.abs(deviation) > band)[0].tolist():
        value = float(deviation[i])
        if math.copysign(1.0, value) != side:
            side = math.copysign(1.0, value)
            peaks.append((i, value))
        elif abs(value) > abs(peaks[-1][1]):
            peaks[-1] = (i, value)
    return peaks


def fit_second_order(tau: Array, deviation: Array, omega: float, sigma: float
                     ) -> tuple[float, float, float]:
    """
    Fit ``c + exp(-sigma tau) (a cos(omega tau) + b sin(omega tau))`` by least squares.

    For each ``(sigma, omega)`` the fit is linear in ``(c, a, b)`` (solved by the normal
    equations for a whole grid at once); ``(sigma, omega)`` are searched on nested
    41 x 41 grids, each a tenth of the one before, around the first guess. At most
    :data:`FIT_SAMPLES` samples are used (evenly strided).

    :param tau: times from the first extremum [s].
    :param deviation: the response there.
    :param omega: first guess of the damped frequency [rad/s].
    :param sigma: first guess of the decay rate [1/s].
    :return: ``(sigma, omega, rms misfit / rms of the response)``.
    """
    stride = max(1, tau.size // FIT_SAMPLES)        # bounds the work on long responses
    tau, deviation = tau[::stride], deviation[::stride]
    scale = float(np.sqrt(np.mean(np.square(deviation))))
    best_s, best_w = sigma, omega
    w_span, s_span = 0.5 * omega, 0.5 * omega + 2.0 * sigma
    misfit = math.inf
    for _ in range(5):
        omegas = np.linspace(max(best_w - w_span, 1e-3), best_w + w_span, 41)
        sigmas = np.linspace(max(best_s - s_span, 0.0), best_s + s_span, 41)
        w_grid, s_grid = (g.ravel() for g in np.meshgrid(omegas, sigmas))
        env = np.exp(-np.outer(s_grid, tau))                            # (G, N)
        phase = np.outer(w_grid, tau)
        basis = np.stack([np.ones_like(env), env * np.cos(phase), env * np.sin(phase)],
                         axis=2)                                         # (G, N, 3)
        gram = np.einsum('gni,gnj->gij', basis, basis)
        rhs = np.einsum('gni,n->gi', basis, deviation)
        coef = np.linalg.solve(gram + 1e-18 * np.eye(3), rhs[..., None])[..., 0]
        residual = np.einsum('gni,gi->gn', basis, coef) - deviation
        cost = np.mean(np.square(residual), axis=1)
        k = int(np.argmin(cost))
        best_s, best_w, misfit = float(s_grid[k]), float(w_grid[k]), float(cost[k])
        w_span, s_span = w_span / 10.0, s_span / 10.0
    return best_s, best_w, math.sqrt(misfit) / scale if scale > 0.0 else math.inf


def decay_damping(deviation: Array, noise: float = 0.0,
                  time: Optional[Array] = None) -> tuple[float, str]:
    """
    Return the damping ratio of the dominant oscillation of a response.

    The largest interior extremum ``E_1`` of the deviation from the final value and the
    next one of opposite sign ``E_2`` give ``q = |E_2 / E_1|`` and ``zeta = -ln q /
    sqrt(pi^2 + ln^2 q)`` (the logarithmic decrement; exact for a second-order
    response). Extrema within ``max(2% of E_1, 3 noise)`` of zero are not counted; the
    first sample is the value before the step, not an extremum. With ``time``, a damped
    cosine is fitted to the response from ``E_1`` on (:func:`fit_second_order`, first
    guess from ``E_1``, ``E_2``) and its ``zeta = sigma / sqrt(sigma^2 + omega^2)`` is
    returned if it misses the response by at most :data:`FIT_TOLERANCE` (RMS, relative):
    otherwise the response is not second-order and has no damping ratio.

    :param deviation: the response minus its final value, from the step on.
    :param noise: standard deviation of the signal once settled.
    :param time: the sample times of ``deviation`` [s].
    :return: ``(zeta, '')``, or ``(NaN, why)``.
    """
    floor = 3.0 * noise
    peaks = [p for p in lobe_peaks(deviation, floor) if 0 < p[0] < deviation.size - 1]
    if not peaks:
        return math.nan, 'no extremum after the step (a monotonic response)'
    start, largest = max(peaks, key=lambda p: abs(p[1]))
    band = max(SETTLING_BAND * abs(largest), floor)
    after = lobe_peaks(deviation[start:], band)
    if len(after) < 2:
        return math.nan, ('no extremum beyond 2% of the largest after it (no oscillation '
                          'to measure; a second-order response has zeta > 0.78)')
    (i1, e1), (i2, e2) = after[0], after[1]
    zeta = damping_from_overshoot(abs(e2 / e1))
    if time is None:
        return zeta, ''
    # from E_1 to where the response stays within the band (bounds the fit's work)
    first = start + i1
    stop = min(int(np.nonzero(np.abs(deviation) > band)[0][-1]) + 1, deviation.size)
    stop = max(stop + (stop - first) // 2, start + i2 + 1)
    tau = time[first:stop] - time[first]
    omega = math.pi / float(tau[i2 - i1])
    sigma, omega, misfit = fit_second_order(
        tau, deviation[first:stop], omega, omega * zeta / math.sqrt(1.0 - zeta * zeta))
    if misfit > FIT_TOLERANCE:
        return math.nan, (f'the response is not second-order: the best fit misses it by '
                          f'{misfit:.0%} (RMS)')
    return sigma / math.hypot(sigma, omega), ''


def step_metrics(time: Array, x: Array, step_time: float,
                 final_window: float = 1.0, end_time: Optional[float] = None,
                 noise_free: Optional[Array] = None, damping: bool = True) -> StepMetrics:
    """
    Return overshoot, damping ratio and settling time of a step response.

    See the module docstring: overshoot is relative to the step's own size
    ``|final - initial|`` (NaN when the step is under a quarter of the excursion: a pulse,
    not a step); the damping ratio comes from the decay between successive extrema and
    the settling band from the excursion, so neither divides by the final value.

    With ``noise_free``, the same run without sensor noise (a simulation's twin), the
    noise's effect on the response is measured, not guessed: ``n = RMS(x - noise_free)``
    over the response. The settling band is then ``max(2% of the excursion, 3 n)`` (noise
    alone does not make a settled response unsettled; a response that has not settled
    beyond the noise still is not; the run is settled no earlier than its twin within
    2% of the excursion), and the overshoot is measured on the noisy signal
    itself, so the noise can only raise it. Where ``3 n`` exceeds
    :data:`MAX_NOISE_FRACTION` of the step's size the overshoot would be the noise's:
    NaN with a note.

    :param time: sample times [s].
    :param x: the signal.
    :param step_time: when the step happened [s].
    :param final_window: the final value is the mean over this last stretch [s].
    :param end_time: end of the response (the next step), default: the last sample [s].
    :param noise_free: ``x`` of the same run without sensor noise, at the same times.
    :param damping: measure the damping ratio (False: NaN without a note; it is the
        costly part, a least-squares fit, for a caller that needs only the overshoot and
        settling time).
    :return: the step metrics; NaN with a note where they do not apply.
    """
    end = float(time[-1]) if end_time is None else end_time
    window = (time >= step_time) & (time <= end)
    before = time < step_time
    if not window.any():
        return _nan_step(math.nan, math.nan, 'no samples after the step')
    t, y = time[window], x[window]
    noise_effect = (0.0 if noise_free is None
                    else float(np.sqrt(np.mean(np.square(y - noise_free[window])))))
    initial = float(x[before][-1]) if before.any() else float(y[0])
    if t[-1] - t[0] < 2.0 * final_window:
        return _nan_step(initial, math.nan, f'{t[-1] - t[0]:.3g} s after the step: too '
                         f'short (needs {2.0 * final_window:g} s)')
    final = float(np.mean(y[t >= t[-1] - final_window]))
    # the response starts from the value before the step
    deviation = np.concatenate([[initial - final], y - final])
    t = np.concatenate([[step_time], t])
    magnitude = np.abs(deviation)
    excursion = float(magnitude.max())
    if excursion == 0.0:
        return StepMetrics(initial, final, 0.0, 0.0, math.nan, 0.0,
                           'no response: damping undefined')
    band = max(SETTLING_BAND * excursion, 3.0 * noise_effect)
    if not math.isfinite(band):
        return _nan_step(initial, final, 'the response or its noise-free twin is not '
                         'finite', excursion)
    notes = []
    if band > SETTLING_BAND * excursion:
        notes.append(f'settling band 3 x the noise effect {noise_effect:.3g} (measured '
                     'against the noise-free run)')
    outside = np.nonzero(magnitude > band)[0]
    if outside.size == 0:
        return _nan_step(initial, final, f'the whole response is within 3 x the noise effect '
                         f'({3.0 * noise_effect:.3g}): it would measure the noise', excursion)
    last = int(outside[-1])
    if t[last] >= t[-1] - final_window and noise_free is None:
        # white noise from third differences (std sqrt(20) sigma), in which a smooth
        # response, settled or not, hardly shows
        settled = y[t[1:] >= t[-1] - final_window]
        noise = (float(np.std(np.diff(settled, 3))) / math.sqrt(20.0) if settled.size > 3
                 else 0.0)
        if 3.0 * noise > band:
            return _nan_step(initial, final, f'noise (std {noise:.3g}) beyond a third of '
                             f'the 2% settling band ({band:.3g}): settling, overshoot and '
                             'damping not measured', excursion)
        return _nan_step(initial, final, 'not settled within 2% of the excursion before '
                         f'the end of the response ({end - step_time:.3g} s)', excursion)
    if t[last] >= t[-1] - final_window:
        return _nan_step(initial, final, 'not settled within the band (2% of the excursion, '
                         f'or 3 x the noise effect {noise_effect:.3g}) before the end of the '
                         f'response ({end - step_time:.3g} s)', excursion)
    settling = float(t[min(last + 1, t.size - 1)] - step_time)
    if noise_free is not None:
        # the wider band lets the noisy run in earlier than the response itself settles:
        # it is settled no earlier than its noise-free twin within 2% of the excursion
        clean = np.asarray(noise_free, dtype=float)[window]
        twin = np.abs(np.concatenate([[initial], clean])
                      - float(np.mean(clean[t[1:] >= t[-1] - final_window])))
        outside = np.nonzero(twin > SETTLING_BAND * excursion)[0]
        if outside.size:
            settling = max(settling, float(t[min(int(outside[-1]) + 1, t.size - 1)]
                                           - step_time))
    size = abs(final - initial)
    if 3.0 * noise_effect > MAX_NOISE_FRACTION * size:
        overshoot = math.nan
        notes.append(f'overshoot: 3 x the noise effect ({3.0 * noise_effect:.3g}) is over '
                     f'{MAX_NOISE_FRACTION:g} of the step ({size:.3g}): it would measure '
                     'the noise, not the response')
    elif size < MIN_STEP_FRACTION * excursion:
        overshoot = math.nan
        notes.append(f'overshoot: the step ({size:.3g}) is under {MIN_STEP_FRACTION:g} of '
                     f'the excursion ({excursion:.3g}): a pulse, not a step')
    else:
        beyond = float(np.max(math.copysign(1.0, final - initial) * deviation))
        overshoot = max(beyond, 0.0) / size
    zeta, why = (decay_damping(deviation, float(np.std(y[t[1:] >= t[-1] - final_window])),
                               t) if damping else (math.nan, ''))
    if why:
        notes.append(f'damping: {why}')
    return StepMetrics(initial, final, excursion, overshoot, zeta, settling,
                       '; '.join(notes))


def rate(time: Array, x: Array) -> Array:
    """
    Return the backward difference dx/dt (one sample shorter).

    :param time: sample times [s].
    :param x: the signal.
    :return: its rate.
    """
    return np.diff(x) / np.diff(time)


def lateral_errors(y_cg: Array, eps_r: Array, rho: Array, d_v: Array, d_s: float,
                   y_ref: Array) -> dict[str, Array]:
    """
    Return the four lateral errors of :data:`ERROR_NAMES` (see :data:`QUANTITIES`).

    :param y_cg: CG lateral error [m].
    :param eps_r: relative yaw [rad].
    :param rho: curvature at the CG [1/m].
    :param d_v: look-ahead distance in use [m].
    :param d_s: look-down sensor distance [m].
    :param y_ref: the law's reference [m].
    :return: one array per name.
    """
    y_v = y_cg + d_v * eps_r
    return {
        'cg_error': y_cg,
        'look_down_error': y_cg + d_s * eps_r,
        'look_ahead_lane_error': y_v - arc_offset(rho, d_v, eps_r, exact=True),
        'regulated_error': y_v - y_ref,
    }


def curvature_step(time: Array, rho: Array, hold: float = STEP_HOLD
                   ) -> tuple[Optional[float], float, str]:
    """
    Return when the curvature steps and how long it then stays constant.

    :param time: sample times [s].
    :param rho: curvature [1/m].
    :param hold: the new curvature must hold this long to count as a step [s].
    :return: ``(step time or None, end of the constant stretch, why there is none)``.
    """
    if rho.size < 2:
        return None, math.nan, 'no curvature step: too few samples'
    changed = np.nonzero(np.abs(np.diff(rho)) > 0.0)[0]
    if not changed.size:
        return None, math.nan, ('no curvature step: the curvature is constant '
                                f'({rho[0]:g} 1/m)')
    first = int(changed[0]) + 1
    level = rho[first]
    off = np.nonzero(np.abs(rho[first:] - level) > 1e-6 * abs(level) + 1e-12)[0]
    end = float(time[first + int(off[0]) - 1]) if off.size else float(time[-1])
    if end - time[first] < hold or level == 0.0:
        return None, math.nan, ('no curvature step: the curvature changes gradually '
                                f'(clothoid) or holds less than {hold:g} s')
    return float(time[first]), end, ''


def run_metrics(time: Array, channels: Mapping[str, Array], d_s: float) -> dict[str, Any]:
    """
    Return the metrics table row of one run.

    Needs the channels ``y_cg, eps_r, rho, d_v, y_ref, steering_cmd``; ``steering`` (the
    wheel angle the plant reports) where the plant reports it (NaN otherwise).

    :param time: sample times [s].
    :param channels: the time series.
    :param d_s: look-down sensor distance [m].
    :return: peak/RMS of each lateral error, relative-yaw step response, steering
        command and wheel-angle peaks, and ``notes`` (why a metric is NaN).
    """
    notes: list[str] = []
    duration = float(time[-1] - time[0]) if time.size else 0.0
    enough = time.size >= 2 and duration >= MIN_DURATION
    if not enough:
        notes.append(f'errors, steering: {time.size} steps over {duration:.3g} s, too '
                     f'few (needs {MIN_DURATION:g} s)')
    errors = lateral_errors(channels['y_cg'], channels['eps_r'], channels['rho'],
                            channels['d_v'], d_s, channels['y_ref'])
    row: dict[str, Any] = {}
    for name, series in errors.items():
        row[f'peak_{name}_m'] = peak(series) if enough else math.nan
        row[f'rms_{name}_m'] = rms(series) if enough else math.nan
    step_time, end, why = curvature_step(time, channels['rho'])
    if step_time is None:
        yaw = _nan_step(math.nan, math.nan, why)
    else:
        yaw = step_metrics(time, channels['eps_r'], step_time, end_time=end)
    if yaw.note:
        notes.append(f'yaw: {yaw.note}')
    row.update(yaw_final_rad=yaw.final, yaw_excursion_rad=yaw.excursion,
               yaw_overshoot=yaw.overshoot, yaw_damping_ratio=yaw.damping_ratio,
               yaw_settling_s=yaw.settling_time)
    for name, missing in (('steering_cmd', 'the bag has no steering commands'),
                          ('steering', 'the plant does not report its wheel angle')):
        series = channels.get(name, np.zeros(0))
        valid = ~np.isnan(series) if series.size == time.size else np.zeros(0, dtype=bool)
        known = enough and int(valid.sum()) >= 2
        # rates between consecutive samples only: a missing sample is not a hold
        steps = valid[1:] & valid[:-1]
        row[f'peak_{name}_rad'] = peak(series[valid]) if known else math.nan
        row[f'peak_{name}_rate_rad_per_s'] = (peak(rate(time, series)[steps])
                                              if known else math.nan)
        if enough and not known:
            # dev-probe96: 'steering_cmd: the plant does not report its commanded'
            notes.append(f'{name}: {missing}')
    row['d_v_final_m'] = float(channels['d_v'][-1]) if time.size else math.nan
    row['notes'] = '; '.join(notes)
    return row


METRIC_COLUMNS = (
    *(f'{kind}_{name}_m' for name in ERROR_NAMES for kind in ('peak', 'rms')),
    'yaw_final_rad', 'yaw_excursion_rad', 'yaw_overshoot', 'yaw_damping_ratio',
    'yaw_settling_s', 'peak_steering_cmd_rad', 'peak_steering_cmd_rate_rad_per_s',
    'peak_steering_rad', 'peak_steering_rate_rad_per_s')


def metrics_legend() -> str:
    """
    Return the markdown text that defines every column of :data:`METRIC_COLUMNS`.

    :return: the text (one paragraph).
    """
    errors = '; '.join(f'`{name}`: {q.symbol} = {q.meaning}' for name, q in
                       ((n, QUANTITIES[n]) for n in ERROR_NAMES))
    return (
        f'Lateral errors [m], peak |x| and RMS: {errors}. Relative yaw eps_r after the '
        'curvature step (the curve entry): `yaw_final_rad` its final value, '
        '`yaw_excursion_rad` the largest |eps_r - final|, `yaw_overshoot` the excursion '
        'beyond the final value over the step |final - initial| (empty when the step is '
        'under a quarter of the excursion), `yaw_damping_ratio` the damping ratio of '
        'the second-order response fitted to it (empty when it is not oscillating or '
        'not second-order), `yaw_settling_s` the time to stay within 2% of the '
        'excursion. Steering: `steering_cmd` the command delta_cmd, `steering` the '
        'wheel angle delta the plant reports (after its actuator). An empty cell is a '
        'metric that does not apply; the notes say why.')


def notes_list(rows: Sequence[Mapping[str, Any]], keys: Sequence[str]) -> list[str]:
    """
    Return markdown list lines, one per row with notes, naming the row by ``keys``.

    :param rows: table rows with a ``notes`` entry.
    :param keys: the columns that name a row.
    :return: the lines (empty if no row has notes).
    """
    lines = [f'- {" ".join(str(row[k]) for k in keys)}: {row["notes"]}'
             for row in rows if row.get('notes')]
    return (['Notes:', '', *lines, ''] if lines else [])
