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
The CG-compensated look-ahead law: the paper's yaw damping, the CG on the lane.

The paper's law regulates ``y_v = y_cg + d_v eps_r`` to 0, which parks the CG at
``-d_v eps_ss`` on an arc. This law keeps eq. 26's long ``d_v`` and the linearizing
structure (eq. 15) but regulates ``y_v`` to ::

    y_ref = d_v eps_ss(v_x, rho_p) - I,   eps_ss(v_x, rho) = (eta v_x^2 - l_2) rho

- ``eps_ss`` is the steady relative yaw of the single-track model with the CG on the
  lane (``docs/model.md``): ``y_ref`` is an exogenous signal, so the zero dynamics (and
  eq. 26's damping) are unchanged and the CG's equilibrium on an arc moves to 0.
- ``rho_p`` is the curvature ``v_x T_ref`` ahead (curvature preview): the reference
  moves before the curve arrives, as the yaw needs about one zero-dynamics time
  constant to follow.
- The road terms of the drift ``f_v`` use the curvature ``v_x T_ff`` ahead, ``T_ff`` the
  actuator lag plus the transport delay: the steering reaches the tyres when the road
  has arrived there. A command held longer than :data:`HOLD_TUNED` (a camera slower
  than 100 Hz answered once a frame) reaches the road later by half the extra hold on
  average: ``hold_preview`` times it is added to ``T_ff`` (:func:`hold_extra`).
- ``eta`` in ``eps_ss`` is the rear compliance ``c(a) = c_hat s(|a| / (mu_d g))``:
  the brush tyre's load-dependent secant compliance (``estimator.brush_shape``) at the
  reference curve's lateral acceleration ``a = v_x^2 rho_p``, the scale ``c_hat``
  estimated online; the reference's rate uses the tangent compliance.
- With ``rate_feedforward`` the zero dynamics' first-order inverse adds
  ``-(v_x I_z c / (m l_1) + (c v_x^2 - l_2) l_2 / v_x) rho'`` to ``eps_ss``, its
  curvature rate clipped to the lateral jerk ``max_lateral_jerk``.
- ``I`` is the integral of the CG error, ``I' = k_i y_cg`` on the measured ``y_cg``
  (the lateral sensor's, not the state filter's estimate, which a relative-yaw or
  ``v_y`` bias moves): it removes what the model gets wrong (cornering stiffness, tyre
  saturation, road bank) without knowing the tyre model. It is clamped to
  ``integral_limit`` and frozen while the steering command is at ``steering_limit``,
  the speed is below ``integral_min_speed`` or the CG error is ``integral_band`` or
  more (anti-windup: a metre-sized error, a car engaged off the lane
  centre or a wrong curvature for a moment, is a transient for the feedback, not a
  model error; integrated, it overshot the lane by 15-45 cm for seconds) unless it has
  stood there ``integral_band_time`` (then it is the model's), and
  reset when time jumps (a step of ``dt < 0`` or ``> max_gap``) or an input is not
  finite; ``dt = 0`` (the same measurement evaluated again) advances nothing.

Every step works on floats (one vehicle) and on numpy arrays (a batch of runs).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, fields, replace
import math
from typing import Any, Callable, Optional

from lookahead_control.core import cg_reference
from lookahead_control.core import numeric as xp
from lookahead_control.core.control_law import (axle_gains, drift_term, LateralState,
                                                LawOutput)
from lookahead_control.core.curvature_smoothing import CurvatureHistory, smoothed_preview
from lookahead_control.core.estimator import ComplianceEstimator
from lookahead_control.core.numeric import Real
from lookahead_control.core.params import (axle_load_factors, check_range, ControllerParams,
                                           loaded_vehicle, ParameterError, VehicleParams)
from lookahead_control.core.schedule import look_ahead
from lookahead_control.core.state_filter import (_bounded, FILTER_MODES, KalmanStateFilter,
                                                 MAX_PERIOD, StateFilterParams)
import numpy as np

#: the answer period ``feedforward_preview`` was tuned at (the node's 100 Hz) [s]: the
#: hold preview adds a share of the period beyond it
HOLD_TUNED = 0.01
#: the answer period is taken over this many last step intervals (a second of a 20 Hz
#: camera): a dropped frame moves it by a twentieth of the frame
HOLD_INTERVALS = 20
#: the longest interval the hold preview counts [s]: a camera slower than 5 Hz is not a
#: lane keeper's (the extra stops at ``hold_preview`` x 0.19 s)
HOLD_LONGEST = 0.2
#: the fastest change of the law's cap of w_n at a changing answer period [rad/s per s]:
#: a gain scheduled slower than the loop it sets (one frame 0.2 s late among 10 ms ones
#: takes the period to 0.107 s for 20 steps: the cap dips from 7 toward that period's 5
#: rad/s to 6.2 and is back 0.4 s later, not 7 -> 5 -> 7 at once); a 20 Hz camera's 5.88
#: from 7 in 0.56 s, where its ring grows 0.8 / s
FREQUENCY_RATE = 2.0


def answer_period(intervals: Any) -> float:
    """
    Return the law's answer period over its last step intervals.

    A command held for ``T`` acts on average ``T / 2`` after it was computed; over holds
    of different lengths the mean, weighted by the time each is held, is ``sum T^2 /
    (2 sum T)``: the period here is ``sum T^2 / sum T`` (``T`` itself when regular). A
    pattern of intervals (every third frame lost, frames in pairs) gives a steady value
    (their median switched between two every frame, dev-probe129); a burst 1 ms after a
    frame is held for 1 ms and weighs nothing.

    :param intervals: the last steps' intervals, each > 0 [s] (empty: none yet).
    :return: the period, each interval counted at most :data:`HOLD_LONGEST`; 0 without
        intervals [s].
    """
    if not len(intervals):
        return 0.0
    held = np.minimum(np.asarray(intervals, dtype=float), HOLD_LONGEST)
    # equal intervals: the interval itself (its sums round: 100 Hz added 1e-18 s)
    if np.ptp(held) == 0.0:
        return float(held[0])
    return float(np.dot(held, held) / np.sum(held))


def hold_extra(intervals: Any, share: float) -> float:
    """
    Return the time a command's hold adds to the feedforward preview.

    :param intervals: the last steps' intervals, each > 0 [s] (empty: none yet).
    :param share: ``hold_preview``, the share of the period (:func:`answer_period`) beyond
        :data:`HOLD_TUNED`.
    :return: ``share`` times that period's excess over :data:`HOLD_TUNED`, 0 without
        intervals [s].
    """
    return hold_at(answer_period(intervals), share)


def hold_at(period: float, share: float) -> float:
    """
    Return the time a command's hold adds to the feedforward preview at an answer period.

    :param period: the answer period (:func:`answer_period`) [s].
    :param share: ``hold_preview``, the share of the period beyond :data:`HOLD_TUNED`.
    :return: ``share`` times the period's excess over :data:`HOLD_TUNED` [s].
    """
    if share <= 0.0:
        return 0.0
    return share * max(period - HOLD_TUNED, 0.0)


def _check_off_or_range(name: str, value: float, allowed: tuple[float, float], unit: str,
                        off: str, why: str) -> None:
    """
    Refuse a setting that is neither 0 (off) nor within ``allowed``.

    :param name: the parameter's name.
    :param value: its value.
    :param allowed: the range of values other than 0.
    :param unit: its unit.
    :param off: what 0 means, for the message.
    :param why: what a value between 0 and ``allowed[0]`` would do, for the message.
    :raises ParameterError: naming the value and what is allowed.
    """
    low, high = allowed
    check_range(name, value, 0.0, high, unit=unit)
    if 0.0 < value < low:
        raise ParameterError(f'{name} = {value!r} {unit} {why}; allowed: 0 ({off}) or '
                             f'{low:g}-{high:g} {unit}')


@dataclass(frozen=True)
class LaneKeepingParams:
    """
    Settings of the CG-compensated law (its gains replace the paper modes' gains).

    :param natural_frequency: w_n of the y_v loop at and above ``frequency_speed``
        [rad/s] (``k_p = w_n^2``).
    :param damping_ratio: zeta of the y_v loop (``k_d = 2 zeta w_n``).
    :param frequency_speed: below this speed w_n falls in proportion to the speed [m/s].
        20 takes the S-bend and the lane change at 20 m/s from 6.9 / 8.5 to 3.3 / 4.9 cm
        but loses the lane from 2.5-3 m off at 15-25 m/s on the CommonRoad car, where 30
        brings it back (docs/lane_keeping.md, "The loop's w_n below 30 m/s").
    :param low_speed_frequency: ... but not below this [rad/s]; capped at
        ``natural_frequency`` (equal or above: w_n constant). At low speed ``beta_1`` is
        small: a high w_n asks for large steering angles, which the wheel's rate limit
        cannot follow from a metre or two off the lane (w_n 7 then loses the lane at
        4-15 m/s; docs/lane_keeping.md, "The loop's w_n below 30 m/s").
    :param frequency_lag: the loop's lags besides a slow answer's hold [s]: at an answer
        period ``T`` (:func:`answer_period`) beyond :data:`HOLD_TUNED` w_n is at most
        ``natural_frequency (HOLD_TUNED + frequency_lag) / (T + frequency_lag)``, not
        below ``low_speed_frequency`` (:func:`period_frequency`). A camera slower than
        100 Hz answered once a frame holds each command for its frame; over the mismatch
        grid (stiff light car, 50 ms) w_n 7 rings at 30 Hz and slower (radius 1.005 at 30
        Hz, 1.031 at 20 Hz) where the default's 6.30 / 5.88 rad/s hold it (0.990, 0.984);
        docs/lane_keeping.md, "The loop's w_n at a slow camera". 0: w_n does not follow
        the period, else 0.1-10 s (a smaller lag cuts deeper).
    :param reference_preview: ``T_ref``: the reference uses the curvature
        ``v_x T_ref`` ahead [s].
    :param feedforward_preview: ``T_ff``: the drift term uses the curvature ``v_x T_ff``
        ahead; about the actuator lag plus the transport delay, at answers
        :data:`HOLD_TUNED` apart [s].
    :param hold_preview: share of the answer period beyond :data:`HOLD_TUNED` (10 ms,
        the period ``feedforward_preview`` was tuned at) added to ``feedforward_preview``:
        a command held for a period ``T`` acts on average ``T / 2`` after it was computed,
        so 0.5 previews the extra hold's mean delay. The period is taken over the last
        :data:`HOLD_INTERVALS` steps' ``dt`` (:func:`hold_extra`; repeats of a
        measurement, ``dt = 0``, are not intervals). A 20 Hz camera answered once a frame
        at 37 m/s on the noise-free nonlinear plant without delay, S1-S4 peak CG summed:
        14.45 cm at 0, 13.67 at 0.5 (100 Hz: 10.85, unchanged); docs/lane_keeping.md, "A
        slow camera's hold". 0: none [-].
    :param integral_gain: ``k_i`` of the CG-error integral at and above
        ``integral_speed`` [1/s]; 0 switches it off at every speed.
    :param integral_speed: at and above this speed ``k_i`` is ``integral_gain`` [m/s].
    :param low_speed_integral_gain: ``k_i`` at and below ``low_integral_speed``, linear
        in the speed up to ``integral_speed`` [1/s]; capped at ``integral_gain``
        (``integral_gain`` or more: ``k_i`` constant, the default). A lower gain at low
        speed lessens the S0 yaw rebound on the package's plant but removes a side
        force or a model error more slowly (docs/lane_keeping.md, Defaults).
    :param low_integral_speed: at and below this speed ``k_i`` is
        ``low_speed_integral_gain`` [m/s]; below ``integral_speed``.
    :param integral_limit: clamp of the integral's shift of the reference [m].
    :param integral_min_speed: below this speed the integral is frozen [m/s].
    :param integral_band: the integral is frozen while ``|y_cg|`` is this or more [m];
        0 integrates at any error.
    :param integral_band_time: ... but not once ``|y_cg|`` has been there this long:
        a steady error outside the band is the model's, integrated [s]; 0: held for as
        long as it is outside.
    :param steering_limit: the integral is frozen while ``|delta|`` reaches this [rad].
    :param demand_limit: the command stays within the steady steering of the lane's
        curvature (at the CG and ahead) plus or minus that of this lateral acceleration,
        widened to the front axle's course (:func:`demand_band`: the band never stops
        the wheels from pointing where the front axle goes, the counter-steer of a
        slide) and, against a fast rotation relative to the lane, :data:`COUNTER_STEER`
        past it (the counter-steer of a yaw disturbance) [m/s^2]; 0: unlimited. 14 m/s^2
        (the default since dev-course) keeps the CommonRoad cars engaged metres off a
        straight lane with a heading error at 25-37 m/s from spinning. The integral and
        the compliance estimate hold while the command is held at the band (as at
        ``steering_limit``).
    :param max_gap: a step longer than this (or negative) is a time jump: the
        integral restarts at 0 [s].
    :param compliance_time_constant: forgetting time of the rear-compliance estimate
        [s]; 0 keeps the model's compliance ``eta``.
    :param compliance_filter: time constant of the filter applied to the regression's
        signals (the derivatives it needs are taken through it) [s].
    :param compliance_prior: weight of the model's compliance in the estimate, as a
        lateral acceleration [m/s^2]: below it the estimate stays near ``eta``.
    :param compliance_range: the estimate stays within ``eta / r`` and ``eta r`` [-].
    :param compliance_memory: time constant of the estimate's memory, counted while the
        tyres are loaded (beyond ``compliance_prior``) and the CG is within
        :data:`MEMORY_BAND` of the lane [s]: along a straight the estimate falls back to
        what the last curves taught instead of to ``eta``, so every curve after the first
        is driven on the learned compliance. 0: back to ``eta`` (else at least 1 s).
    :param compliance_memory_range: the memory stays within ``eta / r`` and ``eta r``
        (at most ``compliance_range``): what tyres and load can make of a car's
        compliance (the sweep's C x0.7 and mass x1.2: 1.71), not a slide's [-].
    :param compliance_memory_seed: the memory's starting value over the model's ``eta``:
        what it starts from and returns to after a restart, until loaded driving teaches
        it (about a second of a 3.4 m/s^2 curve outweighs it). 1: the model. Set it to
        the ``compliance_memory`` an earlier run of the car ended with (``~/debug``;
        ``analyze``'s ``compliance_memory_final_ratio``) and the first curve is driven on it.
        Within ``1 / r`` and ``r`` of ``compliance_memory_range`` (and
        ``compliance_range``); other than 1 only with the memory and the estimate on [-].
    :param rate_feedforward: add the curvature-rate term that makes the CG stay on the
        lane on a clothoid (first-order inverse of the zero dynamics).
    :param exact_inverse: share of the exact inverse of the zero dynamics in the
        reference's relative yaw (``core/cg_reference.py``: the relative yaw that keeps
        the CG on the lane, integrated along the reference's curvature; its acceleration
        along the drift term's curvature is the reference's acceleration);
        0: the first-order inverse (``rate_feedforward``) alone, 1: the exact one [-].
    :param exact_inverse_damping: the exact inverse's own mode (the CG zero dynamics,
        damping ratio 0.18 at 37 m/s) damped to this ratio, the first-order inverse kept;
        0: its own damping [-].
    :param state_preview: share of the drift term's state terms previewed
        ``feedforward_preview`` along the lane: held on the lane the states move with the
        curvature, so the law adds ``T_ff F_rho rho_ff'`` to ``f_v`` (``F_rho`` the slope
        of the state terms in the curvature along the lane, with the tangent compliance;
        ``rho_ff'`` clipped to ``max_lateral_jerk``), a lead on the curvature rate for the
        actuator lag and delay; 0 with ``feedforward_preview`` 0; 1: the whole preview,
        0: none [-].
    :param design_friction: friction of the design tyre for the load-dependent rear
        compliance ``c(a) = c_hat s(|a| / (mu g))`` (brush shape, evaluated at the
        reference curvature's lateral acceleration; the estimate learns ``c_hat``);
        0: a constant compliance [-].
    :param curvature_smoothing: the law reads the ``road_curvature`` polygon averaged
        along the road by a triangular window of this half-width, centred on each point,
        reaching behind the CG into the curvature it saw there
        (``core/curvature_smoothing.py``): a clothoid is unchanged, a curvature step is
        an S-curve of twice this length and a clothoid's ends are rounded, so the
        reference and its rate stay within what the car and the node's angle limit can
        follow (docs/lane_keeping.md, "The previewed curvature, averaged along the
        road"); 0: the polygon as received [m].
    :param max_lateral_jerk: the rate feedforward uses the curvature rate clipped to
        this lateral jerk ``v_x^2 rho'`` (a curvature step in the map would be an
        impulse); 0: no clip [m/s^3].
    :param state_filter: ``kalman``: the law sees the Kalman filter's estimate of
        ``y_cg, eps_r, v_y, r`` (``core/state_filter.py``), and of the road curvature
        while none is received; ``none``: the measurements (while no curvature is
        received the same filter runs for the curvature estimate alone).
    :param curvature_blend: when the curvature starts or stops arriving, the law moves
        from the curvature it used to the new one (received or estimated) linearly over
        this time [s]; 0: at once.
    :param estimate_rate_time: while the curvature is estimated, its rate is the
        backward difference of the estimate through ``1 / (T s + 1)`` with this ``T``,
        clipped to ``max_lateral_jerk``, and the law previews ``rho_hat + rho_hat' t``
        (its rate feedforward and the drift term's ``T_ff`` ahead) [s]; 0: the
        estimate's rate is taken as 0 (no preview without a curvature).
    :param map_fallback: the controller's map check (``core/map_check.py``) at this
        many times its threshold drops the curvature received: the law runs on its own
        estimate, as without one, until the check has stayed below its threshold for
        ``map_recover`` (a map off in sign, in scale by a third or more, a curve it does
        not have); a yaw-rate bias of 0.72 deg/s or more drops it too (at 20 m/s and
        up; more below, as the threshold grows); 0: never [-].
    :param map_recover: the time below the threshold that takes the curvature again [s].
    :param side_force: share of the state filter's rear-axle force disturbance taken as
        a side force (a crosswind, a bank) into the reference: the relative yaw
        ``-F_r / C_r`` the car holds against it with the CG on the lane
        (:meth:`CgCompensatedLaw._side_force`). It fades on a curve as ``p^2 / (a^2 +
        p^2)`` with the lane's lateral acceleration ``a`` (``p``: ``compliance_prior``):
        there the force is the tyres' softening, which the compliance estimate carries.
        Without the state filter there is no force estimate and no share; 0: the
        integral alone removes a side force (a 1.5 kN crosswind step at 37 m/s on the
        goal plant: 25 cm, with it 11 cm; docs/lane_keeping.md, "Side forces") [-].
    :param side_force_filter: low pass of that relative yaw [s]; the force estimate is
        noisy (S0 at 37 m/s, 8 seeds, steering noise 1.08 mrad without the side force,
        1.20 at 0.2 s, 1.41 at 0.1 s with the yaw rebound at 50 %, 2.6 unfiltered).
    :param force_feedforward: share of the state filter's axle-force disturbances
        ``(F_f, F_r)`` added to the linearization's drift term: ``f_v`` gains ``(F_f +
        F_r) / m + d_v (l_1 F_f - l_2 F_r) / I_z``, the part of ``y_v''`` the model's
        linear tyres do not carry (a crosswind, softer or saturating tyres, a heavier
        car), cancelled as the drift term cancels the rest
        (:meth:`CgCompensatedLaw._force_feedforward`). Needs the state filter; 0: off
        (the default: docs/lane_keeping.md, "Force feedforward") [-].
    :param force_feedforward_filter: low pass of those forces [s]; with the full share
        0.5 s or more (0.2 s fails the sampled robust check with the filter: stiff tyres,
        a light car and 50 ms at 37 m/s).
    :param delay_prediction: the law acts on the state filter's estimate predicted
        across the transport delay ``filter_delay`` (the filter's model under the
        commands already sent, :meth:`KalmanStateFilter.ahead`), on the road there: the
        curvature at the CG and the reference's ``v_x filter_delay`` further ahead, the
        state terms previewed ``feedforward_preview - filter_delay`` (the drift term's
        road is ``feedforward_preview`` ahead of now either way). The integral and the
        compliance estimate stay on the present estimate. Needs ``state_filter:
        kalman``.
    :param filter_min_speed: ... (and the ``filter_*`` below): the filter's settings,
        :class:`~lookahead_control.core.state_filter.StateFilterParams` without the
        ``filter_`` prefix.
    """

    natural_frequency: float = 7.0
    damping_ratio: float = 1.0
    frequency_speed: float = 30.0
    low_speed_frequency: float = 5.0
    frequency_lag: float = 0.2
    approach_heading: float = 0.1
    demand_limit: float = 14.0
    reference_preview: float = 0.0
    feedforward_preview: float = 0.07
    hold_preview: float = 0.5
    integral_gain: float = 0.3
    integral_speed: float = 30.0
    low_speed_integral_gain: float = 0.3
    low_integral_speed: float = 15.0
    integral_limit: float = 0.5
    integral_min_speed: float = 5.0
    integral_band: float = 0.5
    integral_band_time: float = 2.0
    steering_limit: float = 0.5
    max_gap: float = 0.25
    compliance_time_constant: float = 0.5
    compliance_filter: float = 0.3
    compliance_prior: float = 0.5
    compliance_range: float = 3.0
    compliance_memory: float = 10.0
    compliance_memory_range: float = 1.75
    compliance_memory_seed: float = 1.0
    rate_feedforward: bool = True
    exact_inverse: float = 0.0
    exact_inverse_damping: float = 0.0
    state_preview: float = 1.0
    design_friction: float = 1.0
    curvature_smoothing: float = 5.0
    max_lateral_jerk: float = 10.0
    state_filter: str = 'kalman'
    curvature_blend: float = 0.5
    estimate_rate_time: float = 0.5
    map_fallback: float = 2.5
    map_recover: float = 1.0
    side_force: float = 1.0
    side_force_filter: float = 0.2
    force_feedforward: float = 0.0
    force_feedforward_filter: float = 1.0
    delay_prediction: bool = False
    filter_min_speed: float = 3.0
    filter_actuator_lag: float = 0.05
    filter_delay: float = 0.02
    filter_lateral_noise: float = 0.03
    filter_yaw_noise: float = 0.002
    filter_lateral_velocity_noise: float = 0.02
    filter_yaw_rate_noise: float = 0.002
    filter_force_noise: float = 100.0
    filter_force_drift: float = 2000.0
    filter_kinematic_noise: float = 0.01
    filter_curvature_drift: float = 0.7

    def __post_init__(self) -> None:
        check_range('lane_keeping.natural_frequency', self.natural_frequency, 0.0, 100.0,
                    low_open=True, unit='rad/s')
        check_range('lane_keeping.damping_ratio', self.damping_ratio, 0.0, 10.0,
                    low_open=True)
        check_range('lane_keeping.frequency_speed', self.frequency_speed, 0.0, 100.0,
                    low_open=True, unit='m/s')
        check_range('lane_keeping.low_speed_frequency', self.low_speed_frequency, 0.0, 100.0,
                    low_open=True, unit='rad/s')
        _check_off_or_range('lane_keeping.frequency_lag', self.frequency_lag, (0.1, 10.0),
                            's', 'w_n not cut',
                            'would cut w_n deeper than the mismatch grid asks (0.05: to '
                            'low_speed_frequency at 20 Hz; 0.2 keeps its decay of 100 Hz; '
                            'the smaller the lag, the deeper the cut)')
        _check_off_or_range('lane_keeping.approach_heading', self.approach_heading,
                            (0.02, 0.15), 'rad', 'no clip',
                            'would leave a car engaged off the lane crawling back (1 m at '
                            '0.01 rad and 10 m/s takes 10 s)')
        _check_off_or_range('lane_keeping.demand_limit', self.demand_limit, (5.0, 50.0),
                            'm/s^2', 'unlimited',
                            'would hold the car back from the lane in ordinary driving '
                            '(S1 at 37 m/s: 8.5 cm off at 6 m/s^2 instead of 2.9)')
        check_range('lane_keeping.reference_preview', self.reference_preview, 0.0, 3.0,
                    unit='s')
        check_range('lane_keeping.feedforward_preview', self.feedforward_preview, 0.0, 1.0,
                    unit='s')
        check_range('lane_keeping.hold_preview', self.hold_preview, 0.0, 1.0)
        check_range('lane_keeping.integral_gain', self.integral_gain, 0.0, 5.0, unit='1/s')
        check_range('lane_keeping.integral_speed', self.integral_speed, 0.0, 100.0,
                    low_open=True, unit='m/s')
        check_range('lane_keeping.low_speed_integral_gain', self.low_speed_integral_gain,
                    0.0, 5.0, unit='1/s')
        check_range('lane_keeping.low_integral_speed', self.low_integral_speed, 0.0, 100.0,
                    unit='m/s')
        if self.low_integral_speed >= self.integral_speed:
            raise ParameterError(
                f'lane_keeping.low_integral_speed = {self.low_integral_speed!r} m/s is not '
                f'below lane_keeping.integral_speed = {self.integral_speed!r} m/s; the '
                'integral gain moves from low_speed_integral_gain to integral_gain '
                'between them, so it must be lower')
        check_range('lane_keeping.integral_limit', self.integral_limit, 0.0, 5.0, unit='m')
        check_range('lane_keeping.integral_min_speed', self.integral_min_speed, 0.0, 50.0,
                    unit='m/s')
        check_range('lane_keeping.integral_band', self.integral_band, 0.0, 10.0, unit='m')
        check_range('lane_keeping.integral_band_time', self.integral_band_time, 0.0, 60.0,
                    unit='s')
        check_range('lane_keeping.steering_limit', self.steering_limit, 0.0, 1.5,
                    low_open=True, unit='rad')
        check_range('lane_keeping.max_gap', self.max_gap, 0.0, 10.0, low_open=True,
                    unit='s')
        check_range('lane_keeping.compliance_time_constant', self.compliance_time_constant,
                    0.0, 100.0, unit='s')
        check_range('lane_keeping.compliance_filter', self.compliance_filter, 0.0, 10.0,
                    low_open=True, unit='s')
        check_range('lane_keeping.compliance_prior', self.compliance_prior, 0.0, 20.0,
                    low_open=True, unit='m/s^2')
        check_range('lane_keeping.compliance_range', self.compliance_range, 1.0, 100.0)
        _check_off_or_range('lane_keeping.compliance_memory', self.compliance_memory,
                            (1.0, 1000.0), 's', "back to the model's eta",
                            'would forget as fast as the estimate it backs '
                            '(compliance_time_constant) and follow the noise')
        check_range('lane_keeping.compliance_memory_range', self.compliance_memory_range,
                    1.0, 100.0)
        reach = min(self.compliance_memory_range, self.compliance_range)
        seed = check_range('lane_keeping.compliance_memory_seed', self.compliance_memory_seed,
                           0.0, math.inf, low_open=True)
        if not (1.0 - SEED_TOLERANCE) / reach <= seed <= reach * (1.0 + SEED_TOLERANCE):
            ranges = ('compliance_memory_range' if reach == self.compliance_memory_range
                      else 'compliance_range')
            raise ParameterError(
                f'lane_keeping.compliance_memory_seed = {seed!r} is out of range; allowed: '
                f'[{1.0 / reach:.6g}, {reach:.6g}] (1 / lane_keeping.{ranges} to it: the '
                f'range the memory holds; up to {SEED_TOLERANCE:.1%} beyond an end, a '
                'rounded value, is taken as that end)')
        if self.compliance_memory_seed != 1.0 and (self.compliance_memory == 0.0
                                                   or self.compliance_time_constant == 0.0):
            off = ('compliance_memory' if self.compliance_memory == 0.0
                   else 'compliance_time_constant')
            raise ParameterError(
                f'lane_keeping.compliance_memory_seed = {self.compliance_memory_seed!r} '
                f'has nothing to seed with lane_keeping.{off} = 0 (the law uses the '
                "model's eta); set it to 1, or turn the memory and the estimate on")
        check_range('lane_keeping.exact_inverse', self.exact_inverse, 0.0, 1.0)
        check_range('lane_keeping.exact_inverse_damping', self.exact_inverse_damping, 0.0,
                    2.0)
        check_range('lane_keeping.state_preview', self.state_preview, 0.0, 3.0)
        check_range('lane_keeping.design_friction', self.design_friction, 0.0, 2.0)
        check_range('lane_keeping.max_lateral_jerk', self.max_lateral_jerk, 0.0, 1000.0,
                    unit='m/s^3')
        _check_off_or_range('lane_keeping.curvature_smoothing', self.curvature_smoothing,
                            (1.0, 50.0), 'm', 'the polygon as received',
                            'would average over less than a metre of road')
        check_range('lane_keeping.curvature_blend', self.curvature_blend, 0.0, 10.0,
                    unit='s')
        check_range('lane_keeping.estimate_rate_time', self.estimate_rate_time, 0.0, 10.0,
                    unit='s')
        _check_off_or_range('lane_keeping.map_fallback', self.map_fallback, (1.0, 100.0),
                            'x the threshold', 'the map is never dropped',
                            'would drop a map the check does not call off')
        check_range('lane_keeping.map_recover', self.map_recover, 0.0, 60.0, unit='s')
        check_range('lane_keeping.side_force', self.side_force, 0.0, 1.0)
        check_range('lane_keeping.side_force_filter', self.side_force_filter, 0.0, 5.0,
                    unit='s')
        check_range('lane_keeping.force_feedforward', self.force_feedforward, 0.0, 1.0)
        check_range('lane_keeping.force_feedforward_filter', self.force_feedforward_filter,
                    0.0, 5.0, unit='s')
        if not isinstance(self.rate_feedforward, bool):
            raise ParameterError(f'lane_keeping.rate_feedforward = {self.rate_feedforward!r} '
                                 'must be true or false')
        if not isinstance(self.delay_prediction, bool):
            raise ParameterError(f'lane_keeping.delay_prediction = {self.delay_prediction!r} '
                                 'must be true or false')
        if self.state_filter not in FILTER_MODES:
            raise ParameterError(f'lane_keeping.state_filter = {self.state_filter!r} is not '
                                 f'allowed; choose one of {", ".join(FILTER_MODES)}')
        if self.state_filter == 'kalman' and self.max_gap > MAX_PERIOD:
            # the filter's gains end at MAX_PERIOD: a longer step would restart it unseen
            raise ParameterError(f'lane_keeping.max_gap = {self.max_gap!r} s is above '
                                 f'{MAX_PERIOD:g} s, the longest step the state filter runs; '
                                 'lower it or set lane_keeping.state_filter: none')
        if self.delay_prediction and self.state_filter != 'kalman':
            raise ParameterError('lane_keeping.delay_prediction = true needs '
                                 'lane_keeping.state_filter: kalman (the prediction runs the '
                                 f"filter's model), not {self.state_filter!r}")
        if self.delay_prediction and self.filter_delay <= 0.0:
            # (accepted before dev-probe43, and then it predicted nothing)
            raise ParameterError('lane_keeping.delay_prediction = true predicts across '
                                 'lane_keeping.filter_delay, which is 0: set it to the '
                                 "car's delay from the lateral error's stamp to the wheel "
                                 "(the command-to-actuator delay plus a camera's latency, "
                                 '> 0 s)')
        for item in fields(self):
            if item.name in ('rate_feedforward', 'state_filter', 'delay_prediction'):
                continue
            object.__setattr__(self, item.name, float(getattr(self, item.name)))
        self.filter_settings()

    def filter_settings(self) -> StateFilterParams:
        """
        Return the state filter's settings (the ``filter_*`` fields), validated.

        :return: the settings.
        """
        return StateFilterParams(**{name[len('filter_'):]: getattr(self, name)
                                    for name in FILTER_SETTINGS})


#: the state filter's settings among :class:`LaneKeepingParams`' (``filter_*``)
FILTER_SETTINGS = tuple(item.name for item in fields(LaneKeepingParams)
                        if item.name.startswith('filter_'))


def period_frequency(settings: LaneKeepingParams, period: float) -> float:
    """
    Return the highest w_n of the y_v loop at an answer period.

    ``natural_frequency (HOLD_TUNED + frequency_lag) / (period + frequency_lag)`` beyond
    :data:`HOLD_TUNED`, never below ``min(low_speed_frequency, natural_frequency)`` nor
    above ``natural_frequency``: a command held for the period acts later, as a longer
    lag of the loop would (``frequency_lag`` 0: ``natural_frequency`` at every period).

    :param settings: the law's settings.
    :param period: the answer period (:func:`answer_period`; 0: none measured yet; at most
        :data:`HOLD_LONGEST` counts) [s].
    :return: w_n's cap [rad/s] (the law's moves to it at :data:`FREQUENCY_RATE`).
    """
    top = settings.natural_frequency
    lag = settings.frequency_lag
    if lag <= 0.0 or not period > HOLD_TUNED:
        return top
    # as answer_period counts each interval (dev-probe131: the tool cut w_n at 0.25 s
    # where the law's period stops at 0.2)
    period = min(period, HOLD_LONGEST)
    return max(top * (HOLD_TUNED + lag) / (period + lag), min(settings.low_speed_frequency, top))


def _cap_within(settings: LaneKeepingParams, cap: float) -> float:
    """
    Return w_n's cap within the range the settings allow it.

    :param settings: the law's settings.
    :param cap: the cap [rad/s].
    :return: ``natural_frequency`` with ``frequency_lag`` 0 (the uncut law exactly), else
        ``cap`` between ``min(low_speed_frequency, natural_frequency)`` and
        ``natural_frequency`` [rad/s].
    """
    top = settings.natural_frequency
    if settings.frequency_lag <= 0.0:
        return top
    return min(max(cap, min(settings.low_speed_frequency, top)), top)


def settings_at_period(settings: LaneKeepingParams, period: float) -> LaneKeepingParams:
    """
    Return settings whose w_n schedule on speed is the law's at an answer period.

    :func:`loop_gains` at ``period`` cuts the speed schedule at
    :func:`period_frequency`; the same schedule is ``natural_frequency`` at that cap and
    ``frequency_speed`` moved to keep the slope below it (``frequency_lag`` 0: the
    period is in them). For checks that take settings, not a period (the stability
    tool's).

    :param settings: the law's settings.
    :param period: the answer period [s].
    :return: the settings (the same object where the period does not cut w_n).
    """
    cap = period_frequency(settings, period)
    if cap >= settings.natural_frequency:
        return settings
    return replace(settings, natural_frequency=cap, frequency_lag=0.0,
                   frequency_speed=settings.frequency_speed * cap / settings.natural_frequency)


def loop_gains(settings: LaneKeepingParams, v_x: Real,
               cap: Optional[float] = None) -> tuple[Real, Real]:
    """
    Return ``(k_p, k_d)`` of the y_v loop at a speed (w_n scheduled on speed and period).

    ``w_n = clip(natural_frequency v_x / frequency_speed, min(low_speed_frequency,
    natural_frequency), natural_frequency)``, at most ``cap`` (the law's follows
    :func:`period_frequency` at its answer period), ``k_p = w_n^2``, ``k_d = 2 zeta w_n``.

    :param settings: the law's settings.
    :param v_x: speed [m/s].
    :param cap: w_n's cap (None, or ``natural_frequency`` and above: w_n on speed alone)
        [rad/s].
    :return: the two gains [1/s^2], [1/s].
    """
    top = settings.natural_frequency
    w_n = xp.clip(top * v_x / settings.frequency_speed,
                  min(settings.low_speed_frequency, top), top)
    if cap is not None and cap < top:
        w_n = xp.minimum(w_n, cap)
    return w_n * w_n, 2.0 * settings.damping_ratio * w_n


def integral_gain_at(settings: LaneKeepingParams, v_x: Real) -> Real:
    """
    Return ``k_i`` of the CG-error integral at a speed (scheduled on speed).

    ``k_i = k_lo + (integral_gain - k_lo) clip((v_x - low_integral_speed) /
    (integral_speed - low_integral_speed), 0, 1)`` with ``k_lo =
    min(low_speed_integral_gain, integral_gain)``: ``integral_gain`` 0 is 0 at every
    speed, a ``low_speed_integral_gain`` of ``integral_gain`` or more a constant ``k_i``.

    :param settings: the law's settings.
    :param v_x: speed [m/s].
    :return: ``k_i`` [1/s].
    """
    top = settings.integral_gain
    low = min(settings.low_speed_integral_gain, top)
    share = xp.clip((v_x - settings.low_integral_speed)
                    / (settings.integral_speed - settings.low_integral_speed), 0.0, 1.0)
    return low + (top - low) * share


def integral_schedule_note(settings: LaneKeepingParams) -> str:
    """
    Return what runs instead of a ``low_speed_integral_gain`` above ``integral_gain``.

    :func:`integral_gain_at` caps the low-speed gain at ``integral_gain``: a settings
    line ``low_speed_integral_gain = 0.5`` with ``integral_gain`` 0.3 would tell of a gain
    that never runs.

    :param settings: the law's settings.
    :return: e.g. ``k_i 0.3 1/s at every speed: low_speed_integral_gain is capped at
        integral_gain`` ('' where the low-speed gain runs as set).
    """
    if settings.low_speed_integral_gain <= settings.integral_gain:
        return ''
    return (f'k_i {settings.integral_gain:g} 1/s at every speed: low_speed_integral_gain is '
            'capped at integral_gain')


def frequency_schedule_note(settings: LaneKeepingParams) -> str:
    """
    Return what runs instead of a ``low_speed_frequency`` above ``natural_frequency``.

    :func:`loop_gains` caps the low-speed w_n at ``natural_frequency``: a settings line
    ``low_speed_frequency = 9.0`` with ``natural_frequency`` 5 would tell of a w_n that
    never runs. The default ``low_speed_frequency`` (5 rad/s) is not told: no settings
    line names it, and a file that only lowers ``natural_frequency`` below it asks for
    that w_n at every speed, and gets it.

    :param settings: the law's settings.
    :return: e.g. ``w_n 5 rad/s at every speed: low_speed_frequency is capped at
        natural_frequency`` ('' where the low-speed w_n runs as set, or is the default).
    """
    if (settings.low_speed_frequency <= settings.natural_frequency
            or settings.low_speed_frequency == LaneKeepingParams.low_speed_frequency):
        return ''
    return (f'w_n {settings.natural_frequency:g} rad/s at every speed: low_speed_frequency '
            'is capped at natural_frequency')


def filterless_note(settings: LaneKeepingParams) -> str:
    """
    Return what does not run of the force estimates with ``state_filter: none``.

    ``side_force`` and ``force_feedforward`` take the Kalman filter's force estimates:
    without the filter they run as 0, and a settings line with either above 0 would tell
    of a share that never acts (dev-probe91: the default ``side_force`` 1 with the filter
    off ran silently).

    :param settings: the law's settings.
    :return: e.g. ``side_force runs as 0: its force estimate is the state filter's
        (state_filter none)`` ('' with the filter on, or both shares 0).
    """
    if settings.state_filter == 'kalman':
        return ''
    unused = [name for name, share in (('side_force', settings.side_force),
                                       ('force_feedforward', settings.force_feedforward))
              if share > 0.0]
    if not unused:
        return ''
    return (f"{' and '.join(unused)} run{'' if len(unused) > 1 else 's'} as 0: "
            f"{'their force estimates are' if len(unused) > 1 else 'its force estimate is'}"
            f" the state filter's (state_filter {settings.state_filter})")


def curvature_filter_note(settings: LaneKeepingParams) -> str:
    """
    Return where the ``filter_*`` settings act with ``state_filter: none``.

    Without the state filter a Kalman filter of the same settings still estimates the
    road's curvature, but only while ``road_curvature`` is not received (dev-probe93: a
    ``filter_lateral_noise`` set with the filter off and a map received changed nothing,
    untold).

    :param settings: the law's settings.
    :return: e.g. ``filter_lateral_noise acts only on the curvature estimate, which runs
        while road_curvature is not received (state_filter none)`` ('' with the filter
        on, or no ``filter_*`` setting changed).
    """
    if settings.state_filter == 'kalman':
        return ''
    default = LaneKeepingParams()
    changed = [name for name in FILTER_SETTINGS
               if getattr(settings, name) != getattr(default, name)]
    if not changed:
        return ''
    return (f"{', '.join(changed)} act{'' if len(changed) > 1 else 's'} only on the curvature "
            'estimate, which runs while road_curvature is not received (state_filter '
            f'{settings.state_filter})')


def approach_limit(heading: float, d_v: Real, v_x: Real, k_p: Real, k_d: Real) -> Real:
    """
    Return the clip of the CG's offset that makes the car close at ``heading``.

    With the offset part of the y_v error held at ``+-b`` the loop settles (straight road,
    constant speed, ``r = v_y = 0``) where the steering is 0: ``k_p (b + d_v eps_r) + k_d
    v_x eps_r = 0``, so ``eps_r = -k_p b / (k_p d_v + k_d v_x)``; the relative heading
    ``heading`` needs ``b = heading (d_v + k_d v_x / k_p)``. With the default gains
    (``zeta`` 1, ``w_n`` 5 up to 21.4 m/s, 7 from 30) and 0.1 rad: 0.60 m at 10 m/s,
    1.86 m at 20, 5.07 m at 37 m/s (Table 1 ``d_v``).

    :param heading: the approach heading [rad]; 0: no clip.
    :param d_v: the look-ahead distance [m].
    :param v_x: speed [m/s].
    :param k_p: the loop's proportional gain [1/s^2].
    :param k_d: its derivative gain [1/s].
    :return: the clip [m] (inf with ``heading`` 0).
    """
    if heading <= 0.0:
        return math.inf
    return heading * (d_v + k_d * v_x / k_p)


#: how far beyond the memory's range a ``compliance_memory_seed`` is taken (as the
#: range's end): a memory at the end as ``analyze`` prints it, rounded to 3 significant
#: digits (0.571 for 1 / 1.75; up to 0.5 % off, dev-probe47)
SEED_TOLERANCE = 5e-3
#: the compliance estimate's memory learns only while ``|y_cg|`` is below this [m]: a
#: CG further off says something the model does not know acts. Against the memory
#: learned without it (dev-probe41: a first curve past the grip on mu 0.5 / 0.7, then a
#: gentler one) the second curve's peak 6.96 / 4.77 -> 4.21 / 3.94 cm (0.05 m: 3.1 / 3.5
#: cm, but the soft-tyre corner's second curve 13.4 -> 15.5 cm instead of 13.7)
MEMORY_BAND = 0.1

#: how far past the front axle's course the demand band lets the command go against the
#: car's rotation relative to the lane (the counter-steer of a yaw disturbance) [rad]:
#: 0.05 left half of what the band cost against a 6 kN m yaw gust on mu 0.4 at 30-37 m/s,
#: 0.1 none of it (dev-probe39); with the rotation there is no margin (a margin on both
#: sides spun 7 of 96 CommonRoad runs engaged off the lane with 0.05, with 0.1 all 19
#: that spin without the band; against the rotation alone none)
COUNTER_STEER = 0.1
#: ... once the rotation is that of a turn of this lateral acceleration, ``|r - v_x rho|
#: v_x`` [m/s^2]: from 0 the margin let an evasive double lane change's reversal through
#: and lost the car at 37 m/s (3.5 m in 1.6 s, mu 1: 43 m off); from 4 it keeps it (1.9 m)
#: and the gust's counter-steer (0.21-0.26 m against 0.18-0.24 without a limit); 8 left
#: 0.42 / 0.52 m at 30 / 37 m/s (dev-course)
COUNTER_STEER_ROTATION = 4.0


def front_axle_course(vehicle: VehicleParams, v_y: Real, r: Real, v_x: Real) -> Real:
    """
    Return ``(v_y + l_1 r) / v_x``, where the front axle goes relative to the body.

    Steering there leaves the front tyres without slip: in a slide, when the rear has let
    go (``v_y`` large), it is the counter-steer that catches the car.

    :param vehicle: the design vehicle (``l_1``).
    :param v_y: lateral velocity of the CG [m/s].
    :param r: yaw rate [rad/s].
    :param v_x: speed [m/s] (> 0).
    :return: the front axle's course [rad] (small-angle, as the model's slip angles).
    """
    return (v_y + vehicle.l1 * r) / v_x


def demand_band(vehicle: VehicleParams, v_x: Real, rho_a: Real, rho_b: Real,
                limit: float, course: Optional[Real] = None,
                rotation: Real = 0.0) -> tuple[Real, Real]:
    """
    Return the steering band of ``demand_limit``: the lane's steady steering +- a margin.

    The single-track model's steady steering is ``delta = (L / v_x^2 + K) a`` for a
    lateral acceleration ``a`` (``K = VehicleParams.understeer_gradient``, taken as 0
    if negative), and ``a = v_x^2 rho`` on the lane. The band is
    that of the curvatures between ``rho_a`` and ``rho_b`` (at the CG and ahead: the
    law steers into a curve before the CG reaches it), widened by ``limit``'s steady
    steering, and then to ``course`` (:func:`front_axle_course`) where that lies
    outside, and on the side against ``rotation`` (once it is that of a turn of
    :data:`COUNTER_STEER_ROTATION`) to :data:`COUNTER_STEER` past the course. With 14
    m/s^2 it is never reached in S1-S4 at 10-37 m/s (S1 at 37 m/s: 2.91 -> 2.92 cm) and
    caps the loop's demand engaged metres off the lane with a heading error. Centred on
    the lane alone it also capped the counter-steer a sliding car needs (dev-probe38)
    and the counter-steer against a yaw disturbance (dev-probe39); the course and the
    margin against the rotation let them through (dev-course; docs/lane_keeping.md,
    "The demand limit").

    :param vehicle: the design vehicle.
    :param v_x: speed [m/s] (> 0).
    :param rho_a: one curvature [1/m].
    :param rho_b: the other [1/m].
    :param limit: the margin's lateral acceleration [m/s^2].
    :param course: the front axle's course [rad]; None or not finite: the lane's band
        alone (no margin either).
    :param rotation: the car's yaw rate relative to the lane, ``r - v_x rho`` [rad/s]:
        above :data:`COUNTER_STEER_ROTATION` ``/ v_x`` (turning left of the lane) the band
        reaches :data:`COUNTER_STEER` right of the course, below minus that left of it;
        else, or not finite: the course alone.
    :return: ``(low, high)`` [rad].
    """
    per_accel = vehicle.wheelbase / (v_x * v_x) + max(vehicle.understeer_gradient, 0.0)
    per_curvature = per_accel * v_x * v_x
    margin = limit * per_accel
    low = xp.minimum(rho_a, rho_b) * per_curvature - margin
    high = xp.maximum(rho_a, rho_b) * per_curvature + margin
    if course is None:
        return low, high
    known = _finite(course)
    course = xp.where(known, course, low)
    fast = COUNTER_STEER_ROTATION / v_x
    turning = known & _finite(rotation)
    against_left = xp.where(turning & (rotation > fast), COUNTER_STEER, 0.0)
    against_right = xp.where(turning & (rotation < -fast), COUNTER_STEER, 0.0)
    return (xp.minimum(low, course - against_left),
            xp.maximum(high, course + against_right))


def approach_error(error: Real, offset: Real, limit: Real) -> Real:
    """
    Return the y_v error the proportional term sees, the CG's offset in it clipped.

    ``error = offset + d_v (eps_r - eps_ref)`` with ``offset = y_cg + I``, the CG's
    distance from where the integral ``I`` wants it; the proportional term sees ``offset``
    clipped to ``+-limit`` (:func:`approach_limit`). Far off the lane the car then closes
    on its target at the approach heading instead of being asked for the steering of the
    whole offset times ``w_n^2``, which a rate-limited wheel cannot follow
    (docs/lane_keeping.md, "Engaged off the lane"). Within the clip the law is unchanged.

    :param error: the y_v error [m].
    :param offset: ``y_cg + I`` [m].
    :param limit: the clip [m] (inf: unclipped).
    :return: the error with its offset part clipped [m].
    """
    if isinstance(limit, float) and math.isinf(limit):
        return error
    return error - offset + xp.clip(offset, -limit, limit)


def steady_relative_yaw(vehicle: VehicleParams, v_x: Real, rho: Real,
                        compliance: Optional[Real] = None) -> Real:
    """
    Return ``eps_ss = (eta v_x^2 - l_2) rho``, the relative yaw with the CG on an arc.

    ``eta v_x^2 rho`` is the rear slip angle at the lateral acceleration ``v_x^2 rho``;
    ``compliance`` replaces ``eta`` (rear slip per lateral acceleration) by an estimate.

    :param vehicle: vehicle parameters (eta, l_2).
    :param v_x: speed [m/s].
    :param rho: curvature [1/m].
    :param compliance: rear slip per lateral acceleration [s^2/m] (None: eta).
    :return: eps_ss [rad] (-22.1 mrad at 37 m/s on R = 400 m right, Table 1).
    """
    eta = vehicle.eta if compliance is None else compliance
    return (eta * v_x * v_x - vehicle.l2) * rho


def preview_curvature(distances: Any, curvatures: Any, ahead: Real, rho: Real,
                      rho_slope: Real) -> tuple[Real, Real]:
    """
    Return the curvature ``ahead`` metres ahead and its slope along the road.

    Linear interpolation in the polygon ``(distances, curvatures)`` (distances ahead of
    the CG, increasing; ``curvatures`` of shape ``(K,)`` or ``(K, N)`` for a batch),
    held constant beyond its ends. Without a usable polygon (empty, not increasing, or a
    non-finite value; in a batch a run's non-finite column for that run alone) the
    curvature at the CG is extrapolated along its slope.

    :param distances: preview distances [m].
    :param curvatures: curvatures there [1/m].
    :param ahead: the distance wanted [m] (float or array per run).
    :param rho: curvature at the CG, the fallback [1/m].
    :param rho_slope: its slope d rho / ds, the fallback [1/m^2].
    :return: ``(rho_ahead [1/m], d rho / ds there [1/m^2])``.
    """
    return read_polygon(checked_polygon(distances, curvatures), ahead, rho, rho_slope)


class Polygon:
    """A ``road_curvature`` polygon checked once, read at several distances in a step."""

    def __init__(self, d: np.ndarray, k: np.ndarray, usable: Optional[np.ndarray]) -> None:
        """
        Keep the polygon and its segments' slopes.

        :param d: distances, increasing and finite, ``(K,)``.
        :param k: curvatures, ``(K,)`` or ``(K, N)``; a run without finite ones: zeros.
        :param usable: per run whether its curvatures were finite (None: every run).
        """
        self.d, self.k, self.usable = d, k, usable
        self.slopes = (None if d.size == 1 else
                       np.diff(k, axis=0) / np.diff(d).reshape((-1,) + (1,) * (k.ndim - 1)))


def checked_polygon(distances: Any, curvatures: Any) -> Optional[Polygon]:
    """
    Return the polygon the law can read, or None (it falls back to the CG's curvature).

    :param distances: preview distances [m].
    :param curvatures: curvatures there [1/m].
    :return: the checked polygon (see :func:`preview_curvature` for what is refused).
    """
    if distances is None or curvatures is None:
        return None
    d = np.asarray(distances, dtype=float)
    k = np.asarray(curvatures, dtype=float)
    if (d.ndim != 1 or d.size == 0 or k.shape[:1] != d.shape or not np.all(np.isfinite(d))
            or np.any(np.diff(d) <= 0.0)):
        return None
    usable = np.all(np.isfinite(k), axis=0)
    if np.all(usable):
        return Polygon(d, k, None)
    if k.ndim == 1:
        return None
    # a batch: the runs whose column is not finite fall back, the others are read
    # (dev-probe43: one run's NaN made every run of the batch fall back)
    return Polygon(d, np.where(usable, k, 0.0), usable)


def read_polygon(polygon: Optional[Polygon], ahead: Real, rho: Real,
                 rho_slope: Real) -> tuple[Real, Real]:
    """
    Return the curvature ``ahead`` metres ahead and its slope: :func:`preview_curvature`.

    :param polygon: :func:`checked_polygon`'s.
    :param ahead: the distance wanted [m] (float or array per run).
    :param rho: curvature at the CG, the fallback [1/m].
    :param rho_slope: its slope d rho / ds, the fallback [1/m^2].
    :return: ``(rho_ahead [1/m], d rho / ds there [1/m^2])``.
    """
    # without the polygon (or a run's column): the curvature at the CG along its slope
    if polygon is None:
        return rho + rho_slope * ahead, rho_slope + 0.0 * ahead
    value, slope = _read_inside(polygon, ahead, rho)
    usable = polygon.usable
    if usable is None:
        return value, slope
    return (_like(np.where(usable, value, rho + rho_slope * ahead), ahead, rho),
            _like(np.where(usable, slope, rho_slope + 0.0 * ahead), ahead, rho))


def _read_inside(polygon: Polygon, ahead: Real, rho: Real) -> tuple[Real, Real]:
    d, k, slopes = polygon.d, polygon.k, polygon.slopes
    if slopes is None:
        value = k[0] + 0.0 * np.asarray(ahead)
        return _like(value, ahead, rho), _like(0.0 * value, ahead, rho)
    a = np.clip(np.asarray(ahead, dtype=float), d[0], d[-1])
    i = np.clip(np.searchsorted(d, a, side='right') - 1, 0, d.size - 2)
    inside = (np.asarray(ahead) >= d[0]) & (np.asarray(ahead) < d[-1])
    if k.ndim == 1:
        value = k[i] + slopes[i] * (a - d[i])
        slope = np.where(inside, slopes[i], 0.0)
    else:
        cols = np.arange(k.shape[1])
        value = k[i, cols] + slopes[i, cols] * (a - d[i])
        slope = np.where(inside, slopes[i, cols], 0.0)
    return _like(value, ahead, rho), _like(slope, ahead, rho)


def _like(value: Any, *others: Any) -> Real:
    """Return a float when every input was one, else an array."""
    if any(isinstance(o, np.ndarray) for o in others) or np.ndim(value) > 0:
        return np.asarray(value, dtype=float)
    return float(value)


def cg_compensated_law(state: LateralState, vehicle: VehicleParams,
                       controller: ControllerParams, rho_ref: Real, rho_ref_rate: Real,
                       rho_ff: Real, rho_ff_rate: Real, offset: Real = 0.0,
                       offset_rate: Real = 0.0,
                       compliance: Optional[Real] = None,
                       rate_feedforward: bool = False,
                       tangent_compliance: Optional[Real] = None,
                       lead_rate: Optional[Real] = None,
                       state_preview: float = 0.0,
                       lead_time: float = 0.0,
                       lead_ff_rate: Optional[Real] = None,
                       gains: Optional[tuple[Real, Real]] = None,
                       approach_heading: float = 0.0, yaw_offset: Real = 0.0,
                       axle_forces: Optional[tuple[Real, Real]] = None) -> LawOutput:
    """
    Evaluate eq. 15 with the CG-compensating reference (stateless part of the law).

    ``y_ref = d_v eps_ss(v_x, rho_ref) - offset``; the drift term's road terms use
    ``rho_ff``; ``y_v`` and its rate use the curvature at the CG (``state.rho``), the
    kinematics.

    :param state: vehicle and road state.
    :param vehicle: vehicle parameters.
    :param controller: gains and d_v schedule.
    :param rho_ref: curvature for the reference [1/m].
    :param rho_ref_rate: its time derivative [1/(m s)].
    :param rho_ff: curvature for the drift term [1/m].
    :param rho_ff_rate: its time derivative [1/(m s)].
    :param offset: shift of the reference (the integral) [m].
    :param offset_rate: its time derivative [m/s].
    :param compliance: rear slip per lateral acceleration in ``eps_ss`` [s^2/m]
        (None: the model's eta).
    :param rate_feedforward: add the curvature-rate term of the zero dynamics' inverse
        to the reference's relative yaw.
    :param tangent_compliance: ``d alpha_r / d a`` at the reference's lateral
        acceleration, for the reference's rate [s^2/m] (None: ``compliance``).
    :param lead_rate: the curvature rate the rate feedforward uses [1/(m s)] (None:
        ``rho_ref_rate``).
    :param state_preview: share ``g`` of the state terms' preview: ``f_v`` (returned
        with it) plus ``g T F_rho rho_ff'``, ``F_rho = beta_1 (e' - l_1) + beta_2 (e' +
        l_2)``, ``e' = c_t v_x^2 - l_2`` with the tangent compliance ``c_t``: the slope
        in the curvature of the drift term's state terms on the lane (``r = v_x rho``,
        ``v_y = l_2 r - v_x alpha_r(v_x^2 rho)``) [-].
    :param lead_time: ``T``, how far ahead the state terms are previewed [s].
    :param lead_ff_rate: the curvature rate the preview uses [1/(m s)] (None:
        ``rho_ff_rate``).
    :param gains: ``(k_p, k_d)`` (None: the controller's).
    :param approach_heading: far off the lane the car closes on its target at this
        relative heading: the proportional term sees the CG's offset ``y_cg + offset``
        clipped to :func:`approach_limit` (:func:`approach_error`) [rad]; 0: unclipped.
    :param yaw_offset: shift of the reference's relative yaw (the side force) [rad].
    :param axle_forces: lateral forces ``(F_f, F_r)`` at the axles beyond the model's
        linear tyres [N], added to ``f_v`` as ``y_v''`` takes them: ``(F_f + F_r) / m +
        d_v (l_1 F_f - l_2 F_r) / I_z`` (None: none).
    :return: the steering angle and the intermediate values.
    """
    eta = vehicle.eta if compliance is None else compliance
    tangent = eta if tangent_compliance is None else tangent_compliance
    v_x = xp.maximum(state.v_x, controller.min_speed)
    d_v, d_v_rate = look_ahead(v_x, state.a_x, vehicle, controller)
    eps_r, rho = state.eps_r, state.rho
    y_v = state.y_cg + d_v * eps_r
    y_v_rate = state.v_y + v_x * eps_r + d_v * (state.r - v_x * rho) + d_v_rate * eps_r
    gain = eta * v_x * v_x - vehicle.l2
    eps_ss = gain * rho_ref
    if rate_feedforward:
        # first-order inverse of the zero dynamics (docs/lane_keeping.md): with the CG
        # held on the lane, eps_r = eps_ss + (eta d_v v_x - v_x / alpha - g l_2 / v_x) rho'
        #   = -(v_x I_z eta / (m l_1) + g l_2 / v_x) rho'
        lead = -(v_x * vehicle.yaw_inertia * eta / (vehicle.mass * vehicle.l1)
                 + gain * vehicle.l2 / v_x)
        eps_ss = eps_ss + lead * (rho_ref_rate if lead_rate is None else lead_rate)
    # d/dt (alpha_r(v_x^2 rho) - l_2 rho), alpha_r' = tangent (v_x^2 rho)'
    eps_ss_rate = (tangent * (2.0 * v_x * state.a_x * rho_ref + v_x * v_x * rho_ref_rate)
                   - vehicle.l2 * rho_ref_rate)
    y_ref = d_v * (eps_ss + yaw_offset) - offset
    y_ref_rate = d_v_rate * eps_ss + d_v * eps_ss_rate - offset_rate
    f_v, beta_1 = drift_term(state._replace(rho=rho_ff, rho_rate=rho_ff_rate), vehicle,
                             d_v, d_v_rate, v_x)
    if state_preview > 0.0 and lead_time > 0.0:
        # the drift term's road terms are rho_ff, T ahead; its state terms are the states
        # of now, which on the lane move with the curvature: F(x(t + T)) = F(x) + T F_rho
        # rho', F_rho = dF/drho along the lane, so with the tangent compliance (d alpha_r
        # / d a; the secant left it 10 % short at 37 m/s on R 400 m, dev-probe32). Left
        # out (docs/lane_keeping.md, "Preview of the drift term's state terms"): the
        # speed's part T (dF_rho/dv) a_x rho and the a_x-dependent terms a_x eps_r,
        # 2 d_v' r (about 0.1-0.2 mrad at 2 m/s^2 on R 400 m)
        beta_2 = axle_gains(vehicle, d_v)[1]
        slope = tangent * v_x * v_x - vehicle.l2
        f_rho = beta_1 * (slope - vehicle.l1) + beta_2 * (slope + vehicle.l2)
        ff_rate = rho_ff_rate if lead_ff_rate is None else lead_ff_rate
        f_v = f_v + state_preview * lead_time * f_rho * ff_rate
    if axle_forces is not None:
        front, rear = axle_forces
        f_v = f_v + ((front + rear) / vehicle.mass
                     + d_v * (vehicle.l1 * front - vehicle.l2 * rear) / vehicle.yaw_inertia)
    error = y_v - y_ref
    error_rate = y_v_rate - y_ref_rate
    k_p, k_d = gains if gains is not None else (controller.k_p, controller.k_d)
    limit = approach_limit(approach_heading, d_v, v_x, k_p, k_d)
    used = approach_error(error, state.y_cg + offset, limit)
    steering = (-f_v - k_p * used - k_d * error_rate) / beta_1
    return LawOutput(steering, d_v, d_v_rate, y_v, y_v_rate, y_ref, error, error_rate,
                     f_v, beta_1)


#: after a retune, the side force's changes move out of the integral for this long [s]:
#: a filter restarted by it converges in about a second (dev-probe79)
SIDE_HANDOVER = 1.5
#: [rad/s] the side force's share halves at this rotation relative to the lane: a yaw
#: gust of 6 kN m for 0.5 s on mu 0.4 at 30 / 37 m/s put the CG 1.2 / 1.9 m off without
#: it (0.21 / 0.26 without the side force), 0.22 / 0.29 with it; the cost, a 1.5 kN
#: crosswind step at 37 m/s 10.3 -> 11.4 cm (noise-free; 0.1 rad/s: 0.38 / 0.51 m)
SIDE_ROTATION = 0.03
#: the measured CG error the integral sums stays this close to the state filter's
#: estimate [m]: a sensor bias (centimetres) passes, an outlier does not
MEASURED_BAND = 0.1


class CgCompensatedLaw:
    """
    The CG-compensated look-ahead law: preview, compliance estimate, CG-error integral.

    ``step`` follows the ``Law`` protocol of the offline runner and the node: ``reset()``
    and ``step(state, preview, dt) -> LawOutput``; ``preview`` has ``distances`` [m]
    and ``curvatures`` [1/m] (or is None). State fields may be arrays (a batch).

    The rear compliance (rear slip angle per lateral acceleration, the model's ``eta``)
    is estimated by regularized least squares with forgetting. The single-track model
    gives the rear slip ``alpha_r = (l_2 r - v_y) / v_x`` from the rear force
    ``F_yr = (m l_1 a_y - I_z r') / (l_1 + l_2)`` as ``alpha_r = c phi`` with the
    regressor ``phi = v_x r + v_y' - I_z r' / (m l_1)``; both sides pass the same
    first-order filter ``F = 1 / (T_f s + 1)`` (the derivatives as ``s F``), and ::

        c = (N + p^2 eta) / (D + p^2),  N' = (F alpha_r F phi - N) / T,
        D' = ((F phi)^2 - D) / T

    It is ``c = eta`` on a straight road (``D`` is small against ``p^2``) and the rear
    tyres' secant compliance in a curve, whatever the tyre model: ``eps_ss = c v_x^2 rho
    - l_2 rho`` is then the relative yaw that puts the CG on the lane.
    """

    name = 'cg_compensated'

    def __init__(self, vehicle: VehicleParams, controller: ControllerParams,
                 settings: Optional[LaneKeepingParams] = None) -> None:
        """
        Create the law.

        :param vehicle: vehicle parameters of the design model.
        :param controller: d_v schedule (keep ``paper``: eq. 26), clamp and min speed;
            its gains are replaced by the settings' ones.
        :param settings: gains, preview, compliance and integral settings (defaults if
            None).
        """
        if controller.reference not in ('lane_tangent', 'cg_compensated'):
            raise ParameterError(
                f'controller.reference = {controller.reference!r}: the CG-compensated law '
                'builds its own reference; use cg_compensated or lane_tangent')
        self.vehicle = vehicle
        self.settings = settings or LaneKeepingParams()
        self.controller = replace(controller,
                                  natural_frequency=self.settings.natural_frequency,
                                  damping_ratio=self.settings.damping_ratio)
        self.integral: Real = 0.0
        #: how long ``|y_cg|`` has been outside ``integral_band`` [s]
        self.outside_time: Real = 0.0
        self.last_steering: Real = 0.0
        #: the last step's CG offset was clipped (``approach_heading``)
        self.clipped: Any = False
        #: the last step's command was held at the demand band (``demand_limit``)
        self.capped: Any = False
        self.cut: Any = False       # the last command sent was cut outside the law
        st = self.settings
        self.estimator = ComplianceEstimator(
            vehicle, max(st.compliance_time_constant, 1e-3), st.compliance_filter,
            st.compliance_prior, st.compliance_range, st.design_friction,
            st.compliance_memory, st.compliance_memory_range, st.compliance_memory_seed)
        self.state_filter = (KalmanStateFilter(vehicle, st.filter_settings())
                             if st.state_filter == 'kalman' else None)
        #: no curvature received (set by :meth:`note_curvature`; an array over a batch)
        self.estimating: Any = False
        #: with ``state_filter: none``, the filter run for the curvature alone (made at the
        #: first step without one, then run on: a curvature going and coming again finds
        #: it converged; its estimate is used only while none is received)
        self.curvature_filter: Optional[KalmanStateFilter] = None
        #: the runs of a batch the curvature filter has estimated for since their (re)start
        #: (a single run's filter is made at its first step without a curvature)
        self._curvature_runs: Any = False
        self._was_estimating: Any = None
        self._blend_offset: Real = 0.0      # curvature left to blend out at the switch
        self._blend_left: Real = 0.0        # its time left [s]
        self._rho_used: Real = 0.0          # the curvature at the CG the last step used
        self._blending: Optional[Real] = None   # the offset the present step adds
        self._changed: Any = False              # the runs that switched at this step
        #: the runs of a batch restarted at the last step (a non-finite output): their
        #: next step has no curvature source before it, as a single run's after reset()
        self._restarted: Any = False
        self._steer_offset: Real = 0.0          # command jump to blend out at the switch
        self._rate_last: Optional[Real] = None  # the curvature of the last step (rate)
        self._rate: Real = 0.0                  # the estimate's filtered rate [1/(m s)]
        #: the exact inverse's model (``exact_inverse > 0``): ``(eps, r)`` along the
        #: reference's and along the drift term's curvature; None: at the next step's
        #: equilibrium
        self._inverse: Optional[tuple[Real, Real]] = None
        self._inverse_ff: Optional[tuple[Real, Real]] = None
        #: the curvature seen at the CG over the last ``curvature_smoothing`` metres
        self._history = (CurvatureHistory(st.curvature_smoothing)
                         if st.curvature_smoothing > 0.0 else None)
        #: the side force's relative yaw (low-passed); None or NaN: from the next target
        self._side: Optional[Real] = None
        #: its shift of the reference at the last step, ``d_v`` times it [m]
        self._side_shift: Real = 0.0
        #: the force feedforward's axle forces (low-passed); None or NaN: from the next
        self._forces: Optional[tuple[Real, Real]] = None
        #: after a retune, the time left in which the side force's changes move out of
        #: the integral (:meth:`_take_over_side`) [s]
        self._handover_left: Real = 0.0
        #: a step has run since the start or the last reset (a retune before it is a
        #: start; an array over a batch, False for the runs restarted)
        self._stepped: Any = False
        #: the last steps' intervals (the answer period's, ``hold_preview``), kept across
        #: restarts and retunes: they are the sensor's rate, not the law's state
        self._intervals: deque[float] = deque(maxlen=HOLD_INTERVALS)
        #: the hold preview the last step added to ``feedforward_preview`` [s]
        self.hold_time = 0.0
        #: the answer period of the last step's intervals (0: none yet) [s]
        self.period = 0.0
        #: w_n's cap, following :func:`period_frequency` at the period at
        #: :data:`FREQUENCY_RATE` (kept across restarts and retunes with the intervals)
        #: [rad/s]
        self.frequency = self.settings.natural_frequency
        self.resets = 0
        #: restarts inside :meth:`step` by cause: ``gap`` (``dt`` negative, not finite or
        #: beyond ``max_gap``), ``non_finite`` (the output was not finite; in a batch,
        #: the runs restarted)
        self.restart_causes = {'gap': 0, 'non_finite': 0}

    def reset(self) -> None:
        """Forget the integral, the estimate and the last command (time jump, stale)."""
        self.integral = 0.0
        self.outside_time = 0.0
        self.last_steering = 0.0
        self.clipped = False
        self.capped = False
        self.cut = False
        self.estimator.reset()
        if self.state_filter is not None:
            self.state_filter.reset()
        self.curvature_filter = None
        self._was_estimating = None
        self._restarted = False
        self._blend_offset = self._blend_left = self._steer_offset = 0.0
        self._rate_last, self._rate = None, 0.0
        self._inverse = self._inverse_ff = None
        self._side = None
        self._side_shift = 0.0
        self._forces = None
        self._handover_left = 0.0
        self._stepped = False
        if self._history is not None:
            self._history.clear()
        self.resets += 1

    def take_over(self, old: 'CgCompensatedLaw') -> tuple[list[str], list[str]]:
        """
        Continue from the law it replaces after a retune (bumpless transfer).

        Called on a fresh law (after :meth:`reset`) with the same name, other settings or
        design vehicle (``docs/lane_keeping.md``, "Retuning at run time"):

        - the CG-error integral, clamped to the new ``integral_limit``, with its band
          timer; restarted at 0 when the new ``integral_gain`` is 0 (switched off);
        - the compliance estimate, as its scale over the model's ``eta``
          (:meth:`ComplianceEstimator.take_over`); restarted when
          ``compliance_time_constant``, ``compliance_filter``, ``design_friction`` or the
          vehicle's ``cg_height`` changed (they define its statistics) or the new time
          constant is 0 (the model's ``eta``); its memory with it, dropped when the new
          ``compliance_memory`` is 0;
        - the state filter's estimate, with its gains from the new settings (with
          another design vehicle too: the filter corrects its force disturbances);
          restarted from the next measurement when the filter was off before;
        - the actuator model and the commands on their way to it, the last command,
          the anti-windup flag, the curvature judgment and its switch-over blend, and
          the estimated curvature's rate (``estimate_rate_time``; the car's and the
          road's, never restarted);
        - the curvature seen behind the CG (``curvature_smoothing``; restarted when it
          was 0 before);
        - the answer period (the sensor's, never restarted) and w_n's cut at it as a
          share of ``natural_frequency`` (a new ``natural_frequency`` at 100 Hz runs at
          once; ``frequency_lag`` 0: no cut).

        Works on floats and on a batch's arrays alike.

        :param old: the law before the retune.
        :return: ``(carried, restarted)``: the parts by name, for the node's log.
        """
        s, was = self.settings, old.settings
        same_vehicle = self.vehicle == old.vehicle
        carried: list[str] = []
        restarted: list[str] = []
        self.last_steering, self.cut = old.last_steering, old.cut
        self.estimating, self._was_estimating = old.estimating, old._was_estimating
        self._restarted = old._restarted
        self._rho_used, self._changed = old._rho_used, old._changed
        if s.curvature_blend > 0.0:
            self._blend_offset, self._steer_offset = old._blend_offset, old._steer_offset
            self._blend_left = xp.minimum(old._blend_left, s.curvature_blend)
        if s.estimate_rate_time > 0.0 and old.settings.estimate_rate_time > 0.0:
            # the estimated curvature's rate is the road's: a retune without
            # road_curvature does not lose the preview along it
            self._rate, self._rate_last = old._rate, old._rate_last
            if bool(np.any(old.estimating)):
                carried.append('curvature rate')
        self.resets, self.restart_causes = old.resets, dict(old.restart_causes)
        self._intervals.extend(old._intervals)
        # the period once a step: the hold preview and the cut of w_n both take it
        self.period = answer_period(self._intervals)
        self.hold_time = hold_at(self.period, s.hold_preview)
        # the cut moves on from where it was, as a share of natural_frequency (a new
        # natural_frequency uncut runs at once, as before the cut: dev-probe131 found 7 ->
        # 9 at 100 Hz spread over a second), not above the new cut at the period where
        # the old sat higher only at its floor (dev-probe132: 7 -> 9 at 0.15 s carried
        # 6.43 against 5.4), within the new law's range; off, none
        share = old.frequency / old.settings.natural_frequency * s.natural_frequency
        self.frequency = _cap_within(s, min(share, max(period_frequency(s, self.period),
                                                       old.frequency)))
        if self.frequency < s.natural_frequency:
            carried.append('w_n cut')
        self.clipped = old.clipped      # recomputed at the next step, as after any step
        self.capped = old.capped
        if s.integral_gain > 0.0:
            self.integral = xp.clip(old.integral, -s.integral_limit, s.integral_limit)
            self.outside_time = old.outside_time
            clamped = bool(np.any(xp.absolute(old.integral) > s.integral_limit))
            carried.append('integral' + (f' (clamped to {s.integral_limit:g} m)'
                                         if clamped else ''))
        else:
            restarted.append('integral (integral_gain 0)')
        statistics = ('compliance_time_constant', 'compliance_filter', 'design_friction')
        # the CG height defines the regressor too (the scale over the loaded compliance):
        # carried, a scale learnt braking without it was counted again with it, 27 % over
        # the slip (dev-probe63)
        if s.compliance_time_constant > 0.0 and all(
                getattr(s, name) == getattr(was, name) for name in statistics) and (
                self.vehicle.cg_height == old.vehicle.cg_height):
            self.estimator.take_over(old.estimator)
            carried.append('compliance estimate' + ('' if same_vehicle else
                                                    ' (as its scale over eta)'))
        else:
            restarted.append('compliance estimate')     # (its memory under a new number)
        source = old.state_filter or old.curvature_filter
        if self.state_filter is not None:
            if source is not None:
                # another design vehicle too: before, the estimate restarted from the
                # raw measurement (its force disturbances were the old model's error):
                # a mass +5 % set on an arc at 37 m/s made the command jump 16.9 mrad
                # (1.35 carried); the filter corrects the disturbances from the next
                # measurement on (docs/lane_keeping.md, "Retuning at run time")
                keep = old.state_filter is not None
                self.state_filter.take_over(source, keep)
                carried.append('actuator model')
                (carried if keep else restarted).append('state filter estimate')
            else:
                self.state_filter.held = self.state_filter.wheel = old.last_steering
                restarted.append('state filter estimate')
        elif old.curvature_filter is not None:
            # state_filter none: the curvature's own filter, from the old law's
            self.curvature_filter = KalmanStateFilter(self.vehicle, s.filter_settings())
            self.curvature_filter.take_over(old.curvature_filter, same_vehicle)
            self._curvature_runs = old._curvature_runs
            carried.append('curvature filter')
        self._take_over_side(old, carried)
        if self.settings.force_feedforward > 0.0 and old._forces is not None \
                and old.state_filter is not None and self.state_filter is not None:
            # the low pass goes on from the old forces (the filter's estimate carried):
            # switched on, it starts from the estimate; off, the term leaves at once
            self._forces = old._forces
            carried.append('force feedforward')
        if self._history is not None and old._history is not None:
            # the road behind: the new half-width keeps what it reaches of it
            self._history.copy_from(old._history)
            carried.append('curvature behind the CG')
        if s.exact_inverse > 0.0 and old._inverse is not None:
            # the road's trajectory: kept (its next step runs with the new settings)
            self._inverse, self._inverse_ff = old._inverse, old._inverse_ff
            carried.append('exact inverse')
        return carried, restarted

    def _take_over_side(self, old: 'CgCompensatedLaw', carried: list[str]) -> None:
        """
        Carry the side force's shift of the reference across a retune (:meth:`take_over`).

        The integral holds the same kind of reference shift (``y_ref = d_v (eps_ss +
        side) - I``), so the shift moves through it: for :data:`SIDE_HANDOVER` after the
        retune every change of the new law's shift from the old one's moves into the
        integral (its first value, the new share's, the estimate of a filter that
        restarted converging); switched off, the old shift moves into it at once. The
        reference stays where it was and the integral gives up what the side force takes
        over. A retune before the old law's first step (or after its restart) is a
        start: nothing moves. dev-probe78 and dev-probe79 found, in a
        1.5 kN crosswind at 37 m/s: 1 -> 0 stepped the command by 12.2 mrad, 0 -> 1
        took the stale value of the last switch-off, 1 -> 0.5 moved the CG 11.8 cm and
        ``state_filter`` none -> kalman 24.6 cm (the integral held the wind and the new
        filter's estimate counted it again). Within ``integral_limit``; with
        ``integral_gain`` 0 nothing moves (the shift is dropped or taken at once).

        :param old: the law before the retune.
        :param carried: the parts carried, for the node's log (appended to).
        """
        stepped = self._stepped = old._stepped
        if not np.any(stepped):
            return              # nothing ran: the new law starts as a fresh one
        was_on = old.state_filter is not None and old.settings.side_force > 0.0
        now_on = self.state_filter is not None and self.settings.side_force > 0.0
        if now_on and was_on and old._side is not None and self.state_filter is not None \
                and self.state_filter.x is not None:
            self._side = old._side          # the low pass goes on from the old value
            carried.append('side force')
        # the shift the reference holds now; switched on, the new law's moves out of the
        # integral from its first step; switched off, it moves in at once
        self._side_shift = old._side_shift if was_on else 0.0
        if self.settings.integral_gain <= 0.0:
            return
        if now_on:
            self._handover_left = xp.where(stepped, SIDE_HANDOVER, 0.0)
        elif was_on:
            limit = self.settings.integral_limit
            self.integral = xp.clip(self.integral - old._side_shift, -limit, limit)
            self._side_shift = 0.0

    def start(self) -> None:
        """
        Restart for a new run from rest (the offline runner, before each run).

        :meth:`reset` keeps the state filter's actuator model (the node's car still has
        its wheel where the last command put it); a new simulation starts with the wheel
        at 0, with no curvature judged missing and no answer period measured (the hold
        preview and w_n's cap of a new sensor), so that a run does not depend on the run
        before it (dev-probe131: two 20 Hz runs of one law 5.2 mrad apart, the second
        starting at the first's cut).
        """
        self.reset()
        self._intervals.clear()
        self.hold_time = self.period = 0.0
        self.frequency = self.settings.natural_frequency
        if self.state_filter is not None:
            self.state_filter.start()
        self.estimating = False
        self.cut = False
        self._rho_used = 0.0
        self._blending = None
        self._changed = False

    def note_curvature(self, received: Any) -> None:
        """
        Say whether a road curvature is received for the next steps.

        Without one (never received, lost, or dropped by the controller's map check,
        ``map_fallback``) the state filter estimates it and the law
        uses the estimate at the CG where it would use the received curvature (the
        feed-forward and the reference), previewed along its rate (``estimate_rate_time``;
        0: no preview). With ``state_filter: none`` a filter
        runs for that estimate alone while none is received (the law keeps the
        measurements of the rest).

        :param received: True, False, or a boolean array over a batch.
        """
        self.estimating = (~np.asarray(received, dtype=bool)
                           if isinstance(received, np.ndarray) else not received)

    def curvature_estimated(self) -> bool:
        """
        Return whether the law runs on an estimated curvature (filter on, none received).

        :return: whether it does (for any run of a batch).
        """
        return bool(np.count_nonzero(self.estimating))

    def curvature_rate(self) -> Real:
        """
        Return the curvature rate of the last step [1/(m s)].

        While the curvature is estimated: the estimate's rate the law previewed along
        (``estimate_rate_time``); while one is received: its rate. 0 before a step, after
        a restart and with ``estimate_rate_time`` 0 (not tracked).

        :return: the rate (an array over a batch).
        """
        return self._rate

    def debug_values(self) -> list[tuple[str, float]]:
        """
        Return the law's state after its last step, for the controller's debug topic.

        ``curvature_estimated`` (1: it ran on its own estimate: no curvature received, or
        the one received dropped, ``map_fallback``),
        ``rho_used`` (the curvature at the CG it used [1/m]), ``integral`` (the CG-error
        integral's shift of the reference [m]), ``compliance_scale`` (the rear-compliance
        estimate over the model's ``eta``; with ``cg_height`` > 0 over the loaded ``eta`` at
        the present ``a_x``), ``compliance_memory`` (the memory it falls back
        to, over ``eta``), ``demand_capped`` (1: the command was held at
        the demand band, ``demand_limit``), ``approach_clipped`` (1: the CG's offset was
        clipped, ``approach_heading``), ``memory_generation`` (a number that changes
        whenever the memory starts from its seed again: a restart, a new law, a retune
        that restarted the estimate), ``memory_weight`` (how much of the memory is
        learned rather than its seed, 0-1), ``side_force_yaw`` (the side force's shift
        of the reference's relative yaw [rad], ``side_force``; 0 while off),
        ``hold_preview`` (the time the answer period added to ``feedforward_preview``
        [s], ``hold_preview``), ``frequency_cap`` (w_n's cap at the answer period
        [rad/s], ``frequency_lag``; the w_n that runs is the smaller of it and the speed
        schedule's). One run (not a batch).

        :return: ``(name, value)`` pairs.
        """
        def one(value: Any) -> float:
            return float(np.asarray(value, dtype=float).reshape(-1)[0])
        return [('curvature_estimated', float(self.curvature_estimated())),
                ('rho_used', one(self._rho_used)), ('integral', one(self.integral)),
                ('compliance_scale', one(self.estimator.compliance()) / self.vehicle.eta),
                ('compliance_memory', one(self.estimator.memory()) / self.vehicle.eta),
                ('demand_capped', one(self.capped)), ('approach_clipped', one(self.clipped)),
                ('memory_generation', float(self.estimator.generation)),
                ('memory_weight', one(self.estimator.memory_weight())),
                ('side_force_yaw', 0.0 if self._side is None else one(self._side)),
                ('hold_preview', float(self.hold_time)),
                ('frequency_cap', float(self.frequency))]

    def note_limited(self, cut: Any) -> None:
        """
        Say whether the command sent was cut outside the law (anti-windup).

        The node's safety layer cuts the command at its speed-dependent angle limit
        (0.059 rad at 37 m/s) and its rate limit, far below ``steering_limit``: while it
        does, the integral and the estimate are frozen at the next step.

        :param cut: the angle or rate limit changed the last command (a batch: per run).
        """
        self.cut = np.asarray(cut, dtype=bool) if np.ndim(cut) else bool(cut)

    def note_sent(self, angle: Real) -> None:
        """
        Take the command the safety layer sent for the last step (the state filter's input).

        :param angle: the angle sent [rad] (cut by the angle and rate limits).
        """
        if self.state_filter is not None:
            self.state_filter.correct(angle)
        if self.curvature_filter is not None:
            self.curvature_filter.correct(angle)

    def note_safe_command(self, angle: float, since: float) -> None:
        """
        Take a command the safety layer sent while the law did not run (stale inputs).

        The hold and the ramp to the safe angle reach the wheel, not the law's last
        commands: the state filter's actuator model moves on by ``since`` under the
        commands in flight and records this one
        (:meth:`KalmanStateFilter.advance_actuator`). Before dev-probe44 the filter kept
        the law's last commands in flight through stale inputs (2 s stale: the
        prediction ran on the 4.9 mrad sent before them, the wheel at 0); a first fix
        put the wheel at the safe angle at once, 26 mrad off the first commands after a
        ramp (dev-probe45: the wheel follows the ramp through the delay and the lag).

        :param angle: the command sent [rad]; a non-finite one is ignored.
        :param since: time since the command sent before it [s].
        """
        if not math.isfinite(angle):
            return
        for kalman in (self.state_filter, self.curvature_filter):
            if kalman is not None:
                kalman.advance_actuator(since, angle)

    def compliance(self) -> Real:
        """
        Return the rear-compliance estimate [s^2/m] (eta before anything is learned).

        With ``design_friction > 0`` it is the scale (the compliance at zero lateral
        load), with the vehicle's ``cg_height`` > 0 at ``a_x`` 0 (the axles' static loads).

        :return: the estimate.
        """
        return self.estimator.compliance()

    def step(self, state: LateralState, preview: Any, dt: float) -> LawOutput:
        """
        Advance the integral and the estimate by ``dt`` and return the law's output.

        :param state: vehicle and road state (the curvature slope is ``rho_rate / v_x``).
        :param preview: curvature ahead (``distances``, ``curvatures``), or None.
        :param dt: time since the previous step [s]; ``< 0``, not finite or ``> max_gap``
            resets; 0 (the same measurement again) advances nothing.
        :return: the steering angle and the intermediate values (``y_ref`` includes the
            integral's shift).
        """
        s = self.settings
        # dt = 0: the same instant again (a timer faster than the measurements): nothing
        # advances, nothing restarts
        if not (math.isfinite(dt) and 0.0 <= dt <= s.max_gap):
            self.reset()
            self.restart_causes['gap'] += 1
            dt = 0.0
        elif dt > 0.0:
            self._intervals.append(dt)
        # a command held longer than the preview was tuned for acts later on average
        # the period once a step: the hold preview and the cut of w_n both take it
        self.period = answer_period(self._intervals)
        self.hold_time = hold_at(self.period, s.hold_preview)
        # a slow answer period cuts w_n; the cap moves at FREQUENCY_RATE (off: none)
        target = period_frequency(s, self.period)
        self.frequency = _cap_within(s, self.frequency + min(
            max(target - self.frequency, -FREQUENCY_RATE * dt), FREQUENCY_RATE * dt))
        ff_preview = s.feedforward_preview + self.hold_time
        estimating = self.estimating
        # the integral sums the measured CG error, not the filter's estimate: the
        # estimate fuses the relative yaw, v_y and the yaw rate through the kinematics,
        # and a bias of one of them moved it (5 mrad of relative yaw: the CG settled
        # 4.1 cm off on the goal plant at 30 m/s, now +1.0 cm = d_s x 5 mrad, where the
        # lateral sensor puts it; dev-probe73). Within MEASURED_BAND of the estimate: a
        # lateral error 2 m off for one message stepped the command by 50 mrad at 10 m/s
        # through the reference's rate k_i y_cg (dev-probe75); a bias is centimetres
        measured_y = state.y_cg
        if self.state_filter is not None:
            state = self.state_filter.step(state, dt, estimating)
            measured_y = state.y_cg + xp.clip(measured_y - state.y_cg, -MEASURED_BAND,
                                              MEASURED_BAND)
        elif self.curvature_filter is not None or np.count_nonzero(estimating):
            state = self._estimate_curvature(state, dt, estimating)
        if estimating is True:          # no preview without a curvature
            preview = None
        v_x = xp.maximum(state.v_x, self.controller.min_speed)
        rated = s.estimate_rate_time > 0.0
        if rated:
            state = self._estimate_rate(state, dt, estimating, v_x)
        state = self._blend(state, estimating, dt)
        slope = state.rho_rate / v_x
        distances = getattr(preview, 'distances', None)
        curvatures = getattr(preview, 'curvatures', None)
        ahead = s.filter_delay if s.delay_prediction else 0.0
        if self._history is not None:
            if dt > 0.0 or self._history.travelled is None:
                self._history.record(state.v_x, dt, state.rho)
            if distances is not None and curvatures is not None:
                # the farthest the law reads: road() below, at the fastest run's speed
                fastest = np.max(np.where(np.isfinite(v_x), v_x, 0.0))
                reach = float(fastest) * max(s.reference_preview + ahead, ff_preview,
                                             ahead)
                distances, curvatures = smoothed_preview(distances, curvatures,
                                                         s.curvature_smoothing, self._history,
                                                         reach)
        blending = self._blending
        polygon = checked_polygon(distances, curvatures)    # read at several distances

        def road(time: float) -> tuple[Real, Real]:
            """Return the curvature ``v_x time`` ahead and its slope."""
            rho_t, slope_t = read_polygon(polygon, v_x * time, state.rho, slope)
            if rated and estimating is True:
                # the estimate extrapolated along its rate (preview_curvature's fallback)
                rho_t = _bounded(rho_t)
            elif isinstance(estimating, np.ndarray) and np.count_nonzero(estimating):
                est = _bounded(state.rho + slope * (v_x * time)) if rated else state.rho
                rho_t = xp.where(estimating, est, rho_t)
                slope_t = xp.where(estimating, slope if rated else 0.0, slope_t)
            if blending is not None:    # the preview moves with the curvature at the CG
                rho_t = rho_t + blending
            return rho_t, slope_t

        rho_ref, slope_ref = road(s.reference_preview + ahead)
        rho_ff, slope_ff = road(ff_preview)
        # the state the law acts on: the estimate where the command it sends now reaches
        # the actuator (delay_prediction), on the road there; the integral and the
        # estimate stay on the present one
        law_state = self._predicted(state, ahead, v_x, road) if ahead > 0.0 else state
        lead_rate = lead_ff_rate = None
        if s.max_lateral_jerk > 0.0:
            # a curvature step in the map is an impulse of curvature rate no steering can
            # follow: the rate feedforward (and the state preview) see at most this lateral
            # jerk
            most = s.max_lateral_jerk / (v_x * v_x)
            lead_rate = xp.clip(v_x * slope_ref, -most, most)
            lead_ff_rate = xp.clip(v_x * slope_ff, -most, most)
        # learning and integrating only above the speed floor and off the steering limit
        # and the demand band (demand_limit), and while the CG closes on the lane at the
        # approach heading (approach_heading): that error is the clip's pace, not the
        # model's
        unclipped = _not(self.clipped)
        active = ((state.v_x >= s.integral_min_speed)
                  & (xp.absolute(self.last_steering) < s.steering_limit) & _not(self.cut)
                  & unclipped & _not(self.capped))
        zero = 0.0 * state.y_cg
        if s.compliance_time_constant > 0.0:
            # the memory learns only near the lane: a CG further off says something the
            # model does not know acts (a slide, a gust), not a curve to carry to the next
            self.estimator.update(state, dt, active, state.v_x >= s.integral_min_speed,
                                  active & (xp.absolute(state.y_cg) < MEMORY_BAND))
        outside = xp.absolute(state.y_cg) >= s.integral_band
        # the band's clock stands while the offset is clipped: an error closing at the
        # approach heading does not stand
        outside_time = xp.where(outside, self.outside_time + xp.where(unclipped, dt, 0.0),
                                0.0)
        # an error that has stood outside integral_band_time is the model's: integrated
        standing = (outside_time >= s.integral_band_time) if s.integral_band_time > 0.0 else False
        inside: Any = True
        if s.integral_band > 0.0:
            inside = ((~outside | standing) if isinstance(outside, np.ndarray)
                      else (not outside) or bool(standing))
        rate = xp.where(active & inside & ((xp.absolute(self.integral) < s.integral_limit)
                                           | (self.integral * state.y_cg < 0.0)),
                        integral_gain_at(s, v_x) * measured_y, zero)
        integral = xp.clip(self.integral + rate * dt, -s.integral_limit, s.integral_limit)
        # the compliance at the rear axle's load under the a_x the law linearizes at
        secant, tangent = self.estimator.at(v_x * v_x * rho_ref, law_state.a_x)
        # the side force is held where the integral is, and while the CG is outside the
        # integral's band: an error that large is a slide, a gust or a car engaged off
        # the lane, not a steady force (the sampled checks hold it there too)
        near = _not(outside) if s.integral_band > 0.0 else True
        yaw_offset = self._side_force(state, v_x, dt, active & near)
        handing = np.greater(self._handover_left, 0.0)
        if np.any(handing):
            # after a retune: the side force's change moves out of the integral (its d_v
            # as evaluate() takes it), the reference stays (_take_over_side)
            d_v = look_ahead(xp.maximum(law_state.v_x, self.controller.min_speed),
                             law_state.a_x, loaded_vehicle(self.vehicle, law_state.a_x),
                             self.controller)[0]
            moved = d_v * yaw_offset - self._side_shift
            integral = xp.clip(integral + xp.where(handing & _finite(moved), moved, 0.0),
                               -s.integral_limit, s.integral_limit)
            self._handover_left = xp.maximum(self._handover_left - dt, 0.0)
        out = self.evaluate(law_state, dt, rho_ref, v_x * slope_ref, rho_ff, v_x * slope_ff,
                            integral, rate, secant, tangent, lead_rate, lead_ff_rate,
                            max(ff_preview - ahead, 0.0), yaw_offset,
                            self._force_feedforward(dt, state))
        shift = out.d_v * yaw_offset
        self._side_shift = xp.where(_finite(shift), shift, 0.0)
        self._stepped = True
        if self._blending is not None:
            # what the curvature does not carry (its rate, the preview) blends on the
            # command: the jump at the switch-over taken out over the same time
            jump = self.last_steering - out.steering
            self._steer_offset = xp.where(self._changed, xp.where(_finite(jump), jump, 0.0),
                                          self._steer_offset)
            left = self._blend_left
            out = out._replace(steering=out.steering + xp.where(
                left > 0.0, self._steer_offset * (left / s.curvature_blend), 0.0))
        capped: Any = False
        if s.demand_limit > 0.0:
            low, high = demand_band(self.vehicle, v_x, law_state.rho, rho_ff, s.demand_limit,
                                    front_axle_course(self.vehicle, law_state.v_y,
                                                      law_state.r, v_x),
                                    law_state.r - v_x * law_state.rho)
            capped = (out.steering < low) | (out.steering > high)
            out = out._replace(steering=xp.clip(out.steering, low, high))
        finite = _finite(out.steering)
        clipped: Any = False
        if s.approach_heading > 0.0:
            k_p, k_d = loop_gains(s, v_x, self.frequency)
            clipped = xp.absolute(law_state.y_cg + integral) > approach_limit(
                s.approach_heading, out.d_v, v_x, k_p, k_d)
        if self.state_filter is not None:
            self.state_filter.command(out.steering)
        if self.curvature_filter is not None:
            self.curvature_filter.command(out.steering)
        self._rho_used = state.rho
        if isinstance(finite, np.ndarray):
            self.integral = np.where(finite, integral, 0.0)
            self.outside_time = np.where(finite, outside_time, 0.0)
            self.last_steering = np.where(finite, out.steering, 0.0)
            self.clipped = np.where(finite, clipped, False)
            self.capped = np.where(finite, capped, False)
            self._restarted = ~finite
            if self._side is not None:      # restarted: from the next target
                self._side = np.where(finite, self._side, math.nan)
            if self._forces is not None:
                self._forces = (np.where(finite, self._forces[0], math.nan),
                                np.where(finite, self._forces[1], math.nan))
            self._side_shift = np.where(finite, self._side_shift, 0.0)
            self._handover_left = np.where(finite, self._handover_left, 0.0)
            self._stepped = finite
            if self._blending is not None:
                self._blend_left = np.where(finite, self._blend_left, 0.0)
            self.estimator.forget(~finite)
            if self._inverse is not None and self._inverse_ff is not None:
                # restarted: at the next step's equilibrium (a NaN starts it there)
                self._inverse = _forget(self._inverse, ~finite)
                self._inverse_ff = _forget(self._inverse_ff, ~finite)
            if self._history is not None:       # restarted: no road behind
                self._history.forget(~finite)
            if self._rate_last is not None:     # restarted: the rate from 0
                self._rate = np.where(finite, self._rate, 0.0)
                self._rate_last = np.where(finite, self._rate_last, math.nan)
            if self.state_filter is not None:
                self.state_filter.forget(~finite)
            if self.curvature_filter is not None:
                self.curvature_filter.forget(~finite)
                self._curvature_runs = self._curvature_runs & finite
            self.restart_causes['non_finite'] += int(np.count_nonzero(~finite))
        elif not finite:
            self.reset()
            self.restart_causes['non_finite'] += 1
        else:
            self.integral, self.last_steering = integral, out.steering
            self.outside_time, self.clipped = outside_time, bool(clipped)
            self.capped = bool(capped)
        return out

    def evaluate(self, state: LateralState, dt: float, rho_ref: Real, rho_ref_rate: Real,
                 rho_ff: Real, rho_ff_rate: Real, offset: Real, offset_rate: Real,
                 secant: Real, tangent: Real, lead_rate: Optional[Real],
                 lead_ff_rate: Optional[Real], lead_time: Optional[float] = None,
                 yaw_offset: Real = 0.0,
                 axle_forces: Optional[tuple[Real, Real]] = None) -> LawOutput:
        """
        Return the law's output at this step from the values :meth:`step` worked out.

        The stateless part, :func:`cg_compensated_law`, with the settings' gains, and with
        ``exact_inverse > 0`` the reference moved toward the exact inverse of the zero
        dynamics (``core/cg_reference.py``; its model advanced here by ``dt``).

        :param state: the (filtered) vehicle and road state.
        :param dt: time since the previous step [s] (0 after a restart).
        :param rho_ref: the reference's curvature [1/m].
        :param rho_ref_rate: its time derivative [1/(m s)].
        :param rho_ff: the drift term's curvature [1/m].
        :param rho_ff_rate: its time derivative [1/(m s)].
        :param offset: the integral's shift of the reference [m].
        :param offset_rate: its rate [m/s].
        :param secant: rear compliance at the reference's lateral acceleration [s^2/m].
        :param tangent: its tangent compliance [s^2/m].
        :param lead_rate: the rate feedforward's (clipped) curvature rate, None: unclipped.
        :param lead_ff_rate: the state preview's (clipped) curvature rate, None: unclipped.
        :param lead_time: how far ahead the state terms are previewed [s] (None:
            ``feedforward_preview`` and the last step's hold preview).
        :param yaw_offset: the side force's shift of the reference's relative yaw [rad].
        :param axle_forces: the force feedforward's axle forces [N] (None: none).
        :return: the steering angle and the intermediate values.
        """
        s = self.settings
        v_x = xp.maximum(state.v_x, self.controller.min_speed)
        gains = loop_gains(s, v_x, self.frequency)
        # each axle's stiffness at its load under a_x (vehicle.cg_height; 0: the model)
        out = cg_compensated_law(state, loaded_vehicle(self.vehicle, state.a_x),
                                 self.controller, rho_ref, rho_ref_rate,
                                 rho_ff, rho_ff_rate, offset, offset_rate,
                                 compliance=secant, rate_feedforward=s.rate_feedforward,
                                 tangent_compliance=tangent, gains=gains,
                                 lead_rate=lead_rate, state_preview=s.state_preview,
                                 lead_time=(s.feedforward_preview + self.hold_time
                                            if lead_time is None else lead_time),
                                 lead_ff_rate=lead_ff_rate,
                                 approach_heading=s.approach_heading,
                                 yaw_offset=yaw_offset, axle_forces=axle_forces)
        if s.exact_inverse <= 0.0:
            return out
        # the exact inverse of the zero dynamics (core/cg_reference.py): its relative yaw
        # along the reference's curvature, its relative-yaw acceleration along the drift
        # term's (the actuator lag and delay ahead), both with the secant compliance
        vehicle, share, damping = self.vehicle, s.exact_inverse, s.exact_inverse_damping
        if np.count_nonzero(self._changed) and self._inverse is not None \
                and self._inverse_ff is not None:
            # road_curvature started or stopped arriving: the model's past was the other
            # source's road; it restarts at the new curvature's equilibrium
            self._inverse = _forget(self._inverse, self._changed)
            self._inverse_ff = _forget(self._inverse_ff, self._changed)
        # eps_ss' for the added damping: the model's forcing (c(a) v_x^2 - l_2) rho moves
        # with the tangent compliance (d alpha_r / d a); the secant's slope left the
        # damped model 0.34 mrad off the undamped one 5 s into a 1 m/s^3 clothoid
        gain = tangent * v_x * v_x - vehicle.l2
        ref_rate = gain * (rho_ref_rate if lead_rate is None else lead_rate)
        ff_rate = gain * (rho_ff_rate if lead_rate is None else lead_rate)
        self._inverse = _advanced(self._inverse, vehicle, v_x, rho_ref, secant, dt, damping,
                                  ref_rate)
        self._inverse_ff = _advanced(self._inverse_ff, vehicle, v_x, rho_ff, secant, dt,
                                     damping, ff_rate)
        eps, r = self._inverse
        # the reference's acceleration d_v eps*'' (70 ms ahead), eps*'' = r*' - v_x rho'
        # - a_x rho: f_v already carries the lane's d_v (v_x rho' + a_x rho) (before
        # dev-probe30 it was counted again: an extra curvature-rate lead, see the docs)
        acceleration = (cg_reference.rates(vehicle, v_x, rho_ff, secant, *self._inverse_ff,
                                           damping, ff_rate)[1]
                        - v_x * rho_ff_rate - state.a_x * rho_ff)
        y_ref_rate = out.y_v_rate - out.error_rate
        y_ref = out.y_ref + share * (out.d_v * (eps + yaw_offset) - offset - out.y_ref)
        y_ref_rate = y_ref_rate + share * (out.d_v_rate * eps + out.d_v * (r - v_x * rho_ref)
                                           - offset_rate - y_ref_rate)
        error, error_rate = out.y_v - y_ref, out.y_v_rate - y_ref_rate
        k_p, k_d = gains
        used = approach_error(error, state.y_cg + offset,
                              approach_limit(s.approach_heading, out.d_v, v_x, k_p, k_d))
        steering = (-out.f_v + share * out.d_v * acceleration - k_p * used
                    - k_d * error_rate) / out.beta_1
        return out._replace(steering=steering, y_ref=y_ref, error=error,
                            error_rate=error_rate)

    def _side_force(self, state: LateralState, v_x: Real, dt: float, active: Any) -> Real:
        """
        Return the relative yaw a side force asks of the car with the CG on the lane.

        The state filter's rear-axle force disturbance ``F_r`` is what the linear rear tyre
        does not carry; held by the rear slip, it turns the car by ``-F_r / C_r`` (a
        steady crosswind at the CG: ``-F l_1 / (L C_r)``; the front's share the steering
        takes). On a curve the same force is the tyres' softening, which the compliance
        estimate carries in ``eps_ss``: the share fades with the lane's lateral
        acceleration ``a`` as ``p^2 / (a^2 + p^2)`` (``p`` = ``compliance_prior``), less
        the part the estimate carries, and with the car's rotation relative to the lane
        ``r'`` as ``q^2 / (r'^2 + q^2)`` (``q`` = :data:`SIDE_ROTATION`: a yaw gust, a
        slide). Low-passed over ``side_force_filter``; 0 while the filter restarts.

        :param state: the filtered state (``rho``: the curvature at the CG).
        :param v_x: the floored speed [m/s].
        :param dt: time since the previous step [s] (0: nothing advances).
        :param active: where it is updated (the integral runs, the CG within its band);
            elsewhere the value is held.
        :return: the shift of the reference's relative yaw [rad].
        """
        s = self.settings
        if self.state_filter is None or s.side_force <= 0.0:
            return 0.0
        vehicle = self.vehicle
        accel = v_x * v_x * state.rho
        # what the compliance estimate carries already at the lane's acceleration: its
        # rear force beyond the linear tyre's (dev-probe78: with the memory at C_r x0.7
        # the share counted it again, gentle S-bends 2.6 -> 5.3 cm)
        carried = vehicle.c_r * (vehicle.eta - self.estimator.at(accel, state.a_x)[0]) * accel
        rear = self.state_filter.disturbance()[1] - carried
        prior = s.compliance_prior * s.compliance_prior
        # and with the car's rotation relative to the lane: a yaw gust or a slide turns
        # it at 0.1-0.3 rad/s (its rear force is the tyres' at their grip, and taken as a
        # side force it steered the slide further), a crosswind of 3 kN at 37 m/s 0.04
        turn = state.r - v_x * state.rho
        rotation = SIDE_ROTATION * SIDE_ROTATION / (turn * turn + SIDE_ROTATION * SIDE_ROTATION)
        target = (-s.side_force * prior / (accel * accel + prior) * rotation * rear
                  / vehicle.c_r)
        target = xp.where(_finite(target), target, 0.0)
        last: Real = math.nan if self._side is None else self._side
        step = min(dt / s.side_force_filter, 1.0) if s.side_force_filter > 0.0 else 1.0
        # held where the integral is (the approach's clip, the steering or demand limit,
        # a command cut outside the law, below integral_min_speed): a force estimate
        # taken while the command is not the law's own is the clip's pace, not a force
        # (dev-sc36: 4 m off on soft tyres at 30 m/s, 50 ms, 14 -> 21 cm of overshoot);
        # and outside the band
        self._side = xp.where(_finite(last),
                              xp.where(active, last + (target - last) * step, last),
                              xp.where(active, target, 0.0))
        return self._side

    def _force_feedforward(self, dt: float,
                           state: LateralState) -> Optional[tuple[Real, Real]]:
        """
        Return the axle forces the drift term takes (``force_feedforward``), or None.

        The state filter's axle-force disturbances (what the model's linear tyres do not
        carry, as the filter sees it in the measured ``v_y`` and ``r``), times the share,
        low-passed over ``force_feedforward_filter``; from the first estimate after a
        start or a restart of the filter (0 while it restarts).

        With ``cg_height`` > 0 the filter's forces are over the model at the axles'
        static loads, the law's drift term is at their loads under ``a_x``
        (:func:`loaded_vehicle`): the force the load moved, ``(C(a_x) - C) alpha`` at the
        filter's slip angles, is the law's already and is taken out (dev-sc40: counted
        twice it held the CommonRoad car 4-5 cm off in S5's accelerating curve); the low
        pass starts from the filter's own estimate after a restart.

        :param dt: time since the previous step [s] (0: nothing advances).
        :param state: the filter's present estimate (its ``v_y``, ``r``, ``v_x``, ``a_x``).
        :return: ``(F_f, F_r)`` [N], or None without the filter or with the share 0.
        """
        s = self.settings
        if self.state_filter is None or s.force_feedforward <= 0.0:
            return None
        step = (min(dt / s.force_feedforward_filter, 1.0) if s.force_feedforward_filter > 0.0
                else 1.0)
        last = self._forces
        estimate = self.state_filter.disturbance()
        forces = estimate
        veh = self.vehicle
        if veh.cg_height > 0.0:
            front, rear = axle_load_factors(veh, state.a_x)
            # the filter's own speed floor (below it its forces are NaN: nothing fed)
            v_x = xp.maximum(state.v_x, s.filter_min_speed)
            slip_f = self.state_filter.wheel - (state.v_y + veh.l1 * state.r) / v_x
            slip_r = (veh.l2 * state.r - state.v_y) / v_x
            forces = (estimate[0] - (front - 1.0) * veh.c_f * slip_f,
                      estimate[1] - (rear - 1.0) * veh.c_r * slip_r)
        now = []
        for i, force in enumerate(forces):
            target = s.force_feedforward * force
            before: Real = math.nan if last is None else last[i]
            # after a (re)start from the filter's estimate as it is: a restarted filter's
            # forces start at 0 and take the load's part up only over its first steps,
            # so the part taken out would push the full load force the wrong way at once
            # (dev-probe86: one bad sample on an accelerating arc, 1.47 cm off, 5.44 on)
            now.append(xp.where(_finite(before), before + (target - before) * step,
                                s.force_feedforward * estimate[i]))
        self._forces = (now[0], now[1])
        return (xp.where(_finite(now[0]), now[0], 0.0), xp.where(_finite(now[1]), now[1], 0.0))

    def _predicted(self, state: LateralState, ahead: float, v_x: Real,
                   road: Callable[[float], tuple[Real, Real]]) -> LateralState:
        """
        Return the filter's estimate ``ahead`` seconds on, on the road there.

        The state filter's model under the commands already sent
        (:meth:`KalmanStateFilter.ahead`), the curvature from the CG's now to ``road``'s
        ``ahead``; where the filter passes the measurement (below its ``min_speed``, a
        restart) the present state, on the road ``ahead`` as well.

        :param state: the filter's present estimate.
        :param ahead: the prediction time, ``filter_delay`` [s].
        :param v_x: speed (at least the law's ``min_speed``) [m/s].
        :param road: the curvature and its slope a time ahead (:meth:`step`'s).
        :return: the state the law acts on.
        """
        rho_at, slope_at = road(ahead)
        here = state._replace(rho=rho_at, rho_rate=v_x * slope_at)
        assert self.state_filter is not None
        low = self.state_filter.settings.min_speed
        speed = xp.where(state.v_x >= low, v_x, low)
        x = self.state_filter.ahead(ahead, speed, rho_at, state.rho)
        if x is None:
            return here
        use = _finite(x[0]) & _finite(x[1]) & _finite(x[2]) & _finite(x[3]) \
            & (state.v_x >= low)
        y, e, v, r = (xp.where(use, new, old) for new, old in
                      zip(x, (state.y_cg, state.eps_r, state.v_y, state.r)))
        return here._replace(y_cg=y, eps_r=e, v_y=v, r=r)

    def _estimate_curvature(self, state: LateralState, dt: float,
                            estimating: Any) -> LateralState:
        """
        Return the measured state with the curvature estimated (``state_filter: none``).

        The filter starts with its actuator at the last command (the commands before it
        were not recorded) and from the next measurement. In a batch it is made for
        every run at the first step any run estimates; a run that has not estimated
        since its (re)start starts its estimate at its own first such step (from the
        path ``r / v_x``), as its single run's filter, made there, does.
        """
        if self.curvature_filter is None:
            self.curvature_filter = KalmanStateFilter(self.vehicle,
                                                      self.settings.filter_settings())
            self.curvature_filter.held = self.last_steering
            self.curvature_filter.wheel = self.last_steering
            self._curvature_runs = (estimating.copy() if isinstance(estimating, np.ndarray)
                                    else estimating)
        elif isinstance(estimating, np.ndarray):
            first = estimating & ~self._curvature_runs
            if np.count_nonzero(first):
                self.curvature_filter.forget(first)
            self._curvature_runs = self._curvature_runs | estimating
        estimate = self.curvature_filter.step(state, dt, estimating)
        return state._replace(rho=estimate.rho, rho_rate=estimate.rho_rate)

    def _estimate_rate(self, state: LateralState, dt: float, estimating: Any,
                       v_x: Real) -> LateralState:
        """
        Return the state with, where the curvature is estimated, its rate estimated.

        The backward difference of the estimate, clipped to ``max_lateral_jerk`` (a jump
        of the estimate, its restart to ``r / v_x``, is no rate), through ``1 / (T s +
        1)``, ``T = estimate_rate_time``; where a curvature is received its rate is
        followed (an estimate's rate starts from the last one). At a switch-over the
        estimate is not differenced against the curvature received.
        """
        rho = state.rho
        before = self._was_estimating
        last = rho if self._rate_last is None else self._rate_last
        if before is not None:
            last = xp.where(estimating != before, rho, last)
        if np.count_nonzero(self._restarted):
            # restarted at the last step: differenced from here on, as after reset()
            last = xp.where(self._restarted, rho, last)
        limited = self.settings.max_lateral_jerk > 0.0
        most = self.settings.max_lateral_jerk / (v_x * v_x)
        if dt > 0.0:
            weight = dt / (self.settings.estimate_rate_time + dt)
            step = (rho - last) / dt
            if limited:
                step = xp.clip(step, -most, most)
            rate = self._rate + weight * (step - self._rate)
            self._rate_last = rho
        else:                           # the same instant again: nothing advances
            rate, self._rate_last = self._rate, last
        if limited:
            rate = xp.clip(rate, -most, most)
        received = xp.where(_finite(state.rho_rate), state.rho_rate, 0.0)
        rate = xp.where(estimating, rate, received)
        # a non-finite curvature (a restart) starts the rate from 0
        rate = xp.where(_finite(rate), rate, 0.0)
        self._rate = rate
        return state._replace(rho_rate=xp.where(estimating, rate, state.rho_rate))

    def _blend(self, state: LateralState, estimating: Any, dt: float) -> LateralState:
        """
        Return the state with the curvature moved from the one used at a switch-over.

        When the curvature starts or stops arriving, the difference between the
        curvature used at the last step and the new one (at the CG) is added and taken
        out linearly over ``curvature_blend``: no jump of the reference or the
        feed-forward. Sets ``_blending`` to the offset added (None: nothing to blend).
        """
        self._blending = None
        before = self._was_estimating
        self._was_estimating = estimating
        # the runs whose curvature source switched (the exact inverse restarts them too,
        # whatever curvature_blend says)
        changed = False if before is None else estimating != before
        if np.count_nonzero(self._restarted):
            # a run restarted at the last step starts without a source before it
            changed = changed & ~self._restarted
        self._changed, self._restarted = changed, False
        span = self.settings.curvature_blend
        if before is None or span <= 0.0:
            return state
        if not np.count_nonzero(changed) and not np.count_nonzero(self._blend_left):
            return state
        if np.count_nonzero(changed):
            jump = self._rho_used - state.rho
            self._blend_offset = xp.where(changed, xp.where(_finite(jump), jump, 0.0),
                                          self._blend_offset)
        self._blend_left = xp.where(changed, span, xp.maximum(self._blend_left - dt, 0.0))
        left = self._blend_left
        self._blending = xp.where(left > 0.0, self._blend_offset * (left / span), 0.0)
        return state._replace(rho=state.rho + self._blending)


def _not(flag: Any) -> Any:
    """Return the negation of a flag, per run of a batch (a bool stays a bool)."""
    return ~flag if isinstance(flag, np.ndarray) else not flag


def _forget(state: tuple[Real, Real], runs: Any) -> tuple[Real, Real]:
    """
    Return the exact inverse's model with ``runs`` marked to restart (NaN).

    :param state: ``(eps, r)``, arrays of a batch or floats.
    :param runs: the runs to restart (a boolean array, or a bool for floats).
    :return: the model, NaN where restarted (``_advanced`` starts it at equilibrium).
    """
    return xp.where(runs, math.nan, state[0]), xp.where(runs, math.nan, state[1])


def _advanced(state: Optional[tuple[Real, Real]], vehicle: VehicleParams, v_x: Real,
              rho: Real, compliance: Real, dt: float, damping: float,
              eps_ss_rate: Real) -> tuple[Real, Real]:
    """
    Return the exact inverse's model advanced by ``dt`` (at equilibrium where it had none).

    :param state: ``(eps, r)``, None or non-finite where restarted.
    :param vehicle: the law's model.
    :param v_x: speed [m/s].
    :param rho: curvature [1/m].
    :param compliance: rear compliance [s^2/m].
    :param dt: the step [s].
    :param damping: ``exact_inverse_damping``.
    :param eps_ss_rate: ``eps_ss'`` [rad/s].
    :return: the new ``(eps, r)``.
    """
    start = cg_reference.equilibrium(vehicle, v_x, rho, compliance)
    if state is None:
        return start
    eps, r = cg_reference.advance(vehicle, v_x, rho, compliance, state, dt, damping,
                                  eps_ss_rate)
    ok = _finite(eps) & _finite(r)
    return xp.where(ok, eps, start[0]), xp.where(ok, r, start[1])


def _finite(x: Real) -> Any:
    return np.isfinite(x) if isinstance(x, np.ndarray) else math.isfinite(x)
