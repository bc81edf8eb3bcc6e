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
The controller's state between messages: latest inputs, the law, the command.

No ROS here: the node converts messages into samples, hands them over, and publishes
what :meth:`SteeringController.compute` returns. Keeping it here makes the node thin
and the whole input -> command path testable without DDS.
"""

from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass, replace
import math
from typing import Any, Optional

from lookahead_control.core.baselines import baseline_law, BASELINE_NAMES, BaselineParams
from lookahead_control.core.control_law import cg_error_from, LateralState, LawOutput
from lookahead_control.core.heading_check import HeadingCheck
from lookahead_control.core.lane_keeping import CgCompensatedLaw, LaneKeepingParams
from lookahead_control.core.lane_scale_check import LaneScaleCheck, unwrap
from lookahead_control.core.laws import Law, PaperLaw, Preview
from lookahead_control.core.map_check import MapCheck
from lookahead_control.core.map_timing_check import MapTimingCheck
from lookahead_control.core.oscillation_check import OscillationCheck
from lookahead_control.core.params import (check_choice, check_flag, ControllerParams,
                                           VehicleParams)
from lookahead_control.core.safety import (check_sample, check_stamp, duplicate_reason, limit,
                                           low_speed_weight, SafetyParams, stale_target)
from lookahead_control.core.samples import (curvature_from_points, CurvatureSample,
                                            LateralErrorSample, VelocitySample, YawSample)
from lookahead_control.core.speed_check import road_speed, SpeedCheck
from lookahead_control.core.yaw_check import YawCheck
import numpy as np

ACCELERATION_SOURCES = ('imu', 'differentiate', 'zero')
LAW_NAMES = ('paper',) + BASELINE_NAMES + ('cg_compensated',)
PREVIEW_HORIZON = 100.0     # [m] how far the curvature slope is extended for the baselines
#: the speed, relative yaw and lateral error taken last serve the speed check's odometer
#: within this of a preview [s]
SPEED_AGE = 0.5
#: when the yaw and velocity are read at the lateral error's stamp (``align_inputs``):
#: when the law predicts its state from that stamp (``cg_compensated`` with
#: ``lane_keeping.delay_prediction``), always, never (their newest samples)
ALIGN_CHOICES = ('with_prediction', 'always', 'never')
#: yaw and velocity samples kept to be read at a lateral error's stamp (``align_inputs``):
#: those of the last ``input_timeout + max_future`` (the oldest lateral error taken), but
#: at most this many (a 20 kHz IMU over the default 0.3 s is 6000)
KEPT_SAMPLES = 8192
#: ... and of the curvature polygons (up to ``max_curvature_points`` points each), at most
#: this many (a 1 kHz map over the default 0.3 s is 300; dev-probe122: at 64 a 1 kHz map
#: of now beside a camera 120 ms late found none from the frame's time)
KEPT_POLYGONS = 320


def build_law(name: str, vehicle: VehicleParams, controller: ControllerParams,
              baselines: BaselineParams,
              lane_keeping: Optional[LaneKeepingParams] = None) -> Law:
    """
    Return the steering law called ``name``.

    :param name: ``paper`` (the look-ahead law, eq. 15 with its schedule) or a baseline
        (``pure_pursuit``, ``stanley``, ``lqr``).
    :param vehicle: the controller's vehicle model.
    :param controller: the paper law's parameters.
    :param baselines: the baselines' parameters.
    :param lane_keeping: the ``cg_compensated`` law's settings (defaults if None;
        docs/lane_keeping.md).
    :return: the law.
    """
    check_choice('law', name, LAW_NAMES)
    if name == 'paper':
        return PaperLaw(vehicle, controller)
    if name == 'cg_compensated':
        return CgCompensatedLaw(vehicle, controller, lane_keeping)
    return baseline_law(name, vehicle, baselines)


def law_key(name: str, vehicle: VehicleParams, controller: ControllerParams,
            baselines: BaselineParams, lane_keeping: LaneKeepingParams) -> tuple[Any, ...]:
    """
    Return what the law called ``name`` is built from (equal keys: the same law).

    Only the parameters the law reads: ``cg_compensated`` takes its gains from
    ``lane_keeping`` (``controller.natural_frequency`` and ``damping_ratio`` are the
    paper law's), the baselines neither ``controller`` nor ``lane_keeping``, the paper
    law neither ``lane_keeping`` nor the baselines'.

    :param name: the law.
    :param vehicle: the controller's vehicle model.
    :param controller: the paper law's parameters.
    :param baselines: the baselines' parameters.
    :param lane_keeping: the ``cg_compensated`` law's settings.
    :return: the key.
    """
    if name == 'paper':
        return name, vehicle, controller
    if name == 'cg_compensated':
        return name, vehicle, replace(controller, natural_frequency=1.0,
                                      damping_ratio=1.0), lane_keeping
    return name, vehicle, baselines


# the law cannot run without these; road_curvature is optional (0 without it)
# turning: a yaw rate at least this at a speed at least TURN_SPEED (at 37 m/s a radius of
# 1850 m) is a curve, where a missing curvature or an unmeasured v_y costs the laws most
TURN_RATE = 0.02        # [rad/s]
TURN_SPEED = 10.0       # [m/s]
REQUIRED_INPUTS = ('lateral_error', 'yaw', 'velocity')
JUMP_NS = 1_000_000_000         # the node's clock going back further is a time jump
# per input: the attribute holding its latest sample, and the method storing a new one
_LATEST = {'lateral_error': 'lateral', 'yaw': 'yaw', 'velocity': 'velocity',
           'road_curvature': 'curvature'}
_UPDATE = {'lateral_error': 'update_lateral_error', 'yaw': 'update_yaw',
           'velocity': 'update_velocity', 'road_curvature': 'update_curvature'}


@dataclass(frozen=True)
class Command:
    """
    One steering command and what produced it.

    :param stamp_ns: stamp of the lateral-error measurement it answers [ns] (a watchdog
        command: the node's time on the measurements' clock).
    :param steering: front-wheel angle (+ left) [rad].
    :param steering_rate: change since the last command sent at an earlier reading of
        the node's clock over the time since it [rad/s] (0 for the first and when no
        time has passed; without a clock, since the previous command on the stamps).
    :param law: the law's intermediate values (None for a stale-input command).
    :param status: ``ok``, ``low_speed`` (handing over to hold) or ``stale`` (inputs
        timed out: hold, then ramp to the safe angle).
    :param saturated: the angle limit cut the command.
    :param rate_limited: the rate limit cut the command.
    """

    stamp_ns: int
    steering: float
    steering_rate: float
    law: Optional[LawOutput]
    status: str = 'ok'
    saturated: bool = False
    rate_limited: bool = False


class InputTiming:
    """
    The largest input age and answer latency since the last report, on the node's clock.

    Input age: the node's clock when a sample is accepted minus its stamp (transport and
    queueing delay, plus any sensor clock offset). Answer latency: the node's clock when
    an answer is computed minus the stamp of the lateral error it answers.
    """

    def __init__(self) -> None:
        """Start empty."""
        self.age: dict[str, float] = {}
        self.latency: Optional[float] = None

    def note_age(self, name: str, age: float) -> None:
        """
        Record one input's age [s].

        :param name: the input.
        :param age: its age [s].
        """
        self.age[name] = max(self.age.get(name, age), age)

    def note_latency(self, latency: float) -> None:
        """
        Record one answer's latency [s].

        :param latency: the latency [s].
        """
        self.latency = latency if self.latency is None else max(self.latency, latency)

    def take(self) -> tuple[dict[str, float], Optional[float]]:
        """Return the largest ages and latency since the last call, and start again."""
        out = self.age, self.latency
        self.age, self.latency = {}, None
        return out


#: the shortest time a differentiated a_x is taken over [s]: a derivative over two stamps
#: closer says nothing of the car (two 1 us apart made it 1e5 m/s^2, dev-probe63), and
#: dropping such single values instead biased a noisy 1 kHz feed's a_x toward 0
#: (-3.5 m/s^2 read as -0.36, dev-probe64)
DIFFERENTIATE_SPAN = 0.01


def differentiated_step(estimate: float, anchor: Optional[tuple[int, float]], stamp_ns: int,
                        v_x: float, most: float) -> tuple[float, Optional[tuple[int, float]]]:
    """
    Return the differentiated a_x and its anchor after one velocity sample.

    a_x is ``(v_x - v_anchor) / (t - t_anchor)`` once the sample is at least
    :data:`DIFFERENTIATE_SPAN` after the anchor (which it then becomes), clipped to the
    believable ``most`` (``safety.max_acceleration``, the bound an IMU's ``accel_x`` is
    refused at); a sample closer to the anchor leaves both; one not after it (a stream
    restarted, a time jump back) becomes the anchor; a non-finite derivative is not
    taken.

    :param estimate: a_x so far [m/s^2] (0 before the first).
    :param anchor: ``(stamp [ns], v_x)`` it was last taken at (None: none yet).
    :param stamp_ns: the sample's stamp [ns].
    :param v_x: its speed [m/s].
    :param most: the believable |a_x| [m/s^2].
    :return: the new ``(estimate, anchor)``.
    """
    if anchor is None or stamp_ns <= anchor[0]:
        return estimate, (stamp_ns, v_x)
    dt = (stamp_ns - anchor[0]) * 1e-9
    if dt < DIFFERENTIATE_SPAN:
        return estimate, anchor
    value = (v_x - anchor[1]) / dt
    if not math.isfinite(value):
        return estimate, (stamp_ns, v_x)
    return min(max(value, -most), most), (stamp_ns, v_x)


class SteeringController:
    """
    Holds the latest inputs and evaluates the law on demand.

    Time, in one place (``docs/safety.md``, "Stamps and clocks"):

    - **Stamps** order the samples of each input (a stamp must advance), judge their
      age against the node's clock (refused outside ``[now - input_timeout, now +
      max_future]``), measure latency, and name the measurement a command answers.
    - **The node's clock** (sim time under ``use_sim_time``) judges staleness and times
      the rate limit: a command moves at most ``max_steering_rate`` times the
      node-clock time since the last command sent at an earlier reading (the answers at
      one reading share one step; on the wall clock, also at most times the
      steady-clock time, so a system clock step cannot open the limit), and at most
      that rate times the advance of the newest command stamp since the previous
      command, so a recording of the commands obeys the limit on its own time axis too.
    - Without a clock (``now_ns`` None: offline re-runs, tests) the stamps are the only
      time axis, as in a lockstep simulation.
    """

    def __init__(self, vehicle: VehicleParams, controller: ControllerParams,
                 acceleration_source: str = 'imu', use_preview: bool = False,
                 safety: Optional[SafetyParams] = None, law: str = 'paper',
                 baselines: Optional[BaselineParams] = None,
                 lane_keeping: Optional[LaneKeepingParams] = None,
                 align_inputs: str = 'with_prediction',
                 curvature_at_yaw_stamp: bool = True) -> None:
        """
        Create the controller state.

        :param vehicle: vehicle parameters.
        :param controller: controller parameters.
        :param acceleration_source: where a_x comes from: ``imu`` (the yaw message's
            body acceleration, corrected by ``+ v_y r``), ``differentiate`` (from v_x) or
            ``zero``.
        :param use_preview: feed ``d rho / dt = v_x d rho / ds`` forward from the
            curvature preview; if false, only the curvature at the CG is used and its
            changes act as a disturbance (as in the paper). Law ``cg_compensated``
            always gets the preview (:meth:`preview`).
        :param safety: input and output limits (default limits if None).
        :param law: the steering law, one of :data:`LAW_NAMES`.
        :param baselines: the baseline laws' parameters (defaults if None).
        :param lane_keeping: the ``cg_compensated`` law's settings (defaults if None).
        :param align_inputs: when to read the yaw and the velocity at the lateral
            error's stamp (:meth:`aligned`), one of :data:`ALIGN_CHOICES`; ``never``:
            their newest samples, as before dev-sc52.
        :param curvature_at_yaw_stamp: read a curvature polygon stamped before the yaw
            sample the law takes where the car was at that sample's stamp (:meth:`road`);
            false: as stamped, as before dev-sc53.
        """
        self.law_name = ''
        self.align_inputs = check_choice('align_inputs', align_inputs, ALIGN_CHOICES)
        self.curvature_at_yaw_stamp = check_flag('curvature_at_yaw_stamp',
                                                 curvature_at_yaw_stamp)
        #: the yaw, velocity and curvature samples taken and their stamps, oldest first,
        #: back to ``input_timeout + max_future`` before the newest (:meth:`_keep`): what
        #: :meth:`aligned` and :meth:`road` read
        self._kept: dict[str, tuple[list[int], list[Any]]] = {
            'yaw': ([], []), 'velocity': ([], []), 'road_curvature': ([], [])}
        self.baselines = baselines or BaselineParams()
        self.lane_keeping = lane_keeping or LaneKeepingParams()
        self.law: Law = PaperLaw(vehicle, controller)
        #: what the last :meth:`configure` did to a law with state it kept by name but
        #: retuned: ``(carried, restarted)`` parts (None: no retune, the law was kept
        #: as it was or a new one started fresh)
        self.retune: Optional[tuple[list[str], list[str]]] = None
        self._law_stamp: Optional[int] = None
        self._law_key: Optional[tuple[Any, ...]] = None
        self._select_law(law, vehicle, controller, self.baselines)
        self.safety = safety or SafetyParams()
        self.rejected: dict[str, int] = {}
        self.last_rejection = ''
        #: input -> messages that repeated its last taken one exactly (same stamp, same
        #: values: a publisher sending again what may not have arrived, as a lockstep
        #: simulator's step 0): not used, not refused (no warning); counted apart
        self.duplicates: dict[str, int] = {}
        #: input -> messages taken (accepted)
        self.taken: dict[str, int] = {}
        #: input -> messages taken that came again at least once (an echo repeats most
        #: of them; a lockstep start's step 0, sent until answered, is one)
        self.duplicated: dict[str, int] = {}
        self._duplicated_now: set[str] = set()
        # input -> why its samples since the last one taken were refused
        self.refusals: dict[str, str] = {}
        self.time_jumps = 0
        #: restarts of a stateful law inside its own step (a gap between lateral errors
        #: beyond its ``max_gap``, a non-finite output): its integral and estimate start
        #: again; by cause in ``law_restart_causes``
        self.law_restarts = 0
        #: the curvature judged in or lost by the caller during compute() (None: here)
        self._judged: Optional[bool] = None
        #: whether the last law step had the curvature in (received, not lost): any law's
        #: judgment, on the node's ~/debug for the offline re-run (``curvature_received``)
        self.curvature_in = False
        self.law_restart_causes: dict[str, int] = {}
        #: seconds of answers, while turning (:data:`TURN_RATE`), with no curvature
        #: (``turning_without_curvature``: never received or lost) and with a ``v_y`` of
        #: exactly 0 (``v_y_exactly_zero``: a bridge that does not measure it)
        self.turning: dict[str, float] = {'turning_without_curvature': 0.0,
                                          'v_y_exactly_zero': 0.0,
                                          'curvature_disagrees': 0.0,
                                          'curvature_dropped': 0.0,
                                          'steering_oscillates': 0.0,
                                          'heading_disagrees': 0.0,
                                          'yaw_rate_still': 0.0,
                                          'speed_out_of_scale': 0.0,
                                          'lateral_error_out_of_scale': 0.0,
                                          'relative_yaw_out_of_scale': 0.0,
                                          'curvature_early_or_late': 0.0}
        #: the received curvature against the yaw measurements (``core/map_check.py``):
        #: seconds of answers with it over its threshold in ``curvature_disagrees``, and
        #: with it dropped (the law on its own estimate, ``lane_keeping.map_fallback``) in
        #: ``curvature_dropped``; the largest residual since the caller last took it in
        #: ``map_residual``
        self.map_check = MapCheck()
        #: the curvature read against the yaw measurements in time
        #: (``core/map_timing_check.py``): seconds of answers with its lead told in
        #: ``curvature_early_or_late``, the lead told last and the speed then since the
        #: caller last took them in ``map_lead_seen`` (None: none), the yaw stamp it last
        #: took in ``_timing_yaw``
        self.map_timing = MapTimingCheck()
        self.map_lead_seen: Optional[tuple[float, float]] = None
        self._timing_yaw: Optional[int] = None
        self._state_yaw: Optional[int] = None
        #: the v_x of the last answer held for low speed (``safety.low_speed``) [m/s]
        self.low_speed_v_x: Optional[float] = None
        self.map_residual = 0.0
        #: the steering sent checked for a sustained oscillation (an actuator delay
        #: beyond the law's margin, ``core/oscillation_check.py``): seconds of answers
        #: with it in ``steering_oscillates``, the largest ``(amplitude [rad], frequency
        #: [Hz])`` since the caller last took it in ``oscillation_seen``
        self.oscillation = OscillationCheck()
        self.oscillation_seen = (0.0, 0.0)
        #: the measured yaw rate against the steering sent (``core/yaw_check.py``): once
        #: it runs against it or is out of scale, ``yaw_fault`` holds why and the yaw
        #: input is refused (stale at once: the safe behaviour) until a restart (a time
        #: jump, the node activated again: :meth:`clear_yaw_fault`)
        self.yaw_check = YawCheck()
        #: the relative yaw against the lateral error's motion (``core/heading_check.py``):
        #: seconds of answers with one running against the other in
        #: ``heading_disagrees`` (told, not refused: dev-probe100 found lane changes along
        #: a shifted path, a relative-yaw bias and a flickering lane reference taken for a
        #: wrong sign, and a refusal puts the car off the road)
        self.heading_check = HeadingCheck()
        #: the lowest correlation it was opposed at since the caller last took it (1: none)
        self.heading_seen = 1.0
        #: a yaw rate that hardly varies while the steering and the relative yaw do (frozen,
        #: too small): seconds in ``yaw_rate_still`` (told, not refused: the safe behaviour
        #: puts the car off a curve, the laws on a still yaw rate 0.01-2 m off), and the
        #: largest stillness (:attr:`YawCheck.stillness`) since the caller last took it
        self.still_seen = 0.0
        #: the speed against the curvature preview's motion (``core/speed_check.py``):
        #: seconds in ``speed_out_of_scale`` (told, not refused: a speed in km/h under
        #: ``safety.max_speed`` mis-tunes the laws, refusing it takes the safe behaviour),
        #: and the speed's travel over the preview's (:attr:`SpeedCheck.scale`) when last
        #: told since the caller last took it (1: none)
        self.speed_check = SpeedCheck()
        self.speed_seen = 1.0
        #: the lateral error and the relative yaw against their kinematics
        #: (``core/lane_scale_check.py``), given every sample received with an advancing
        #: stamp (``_raw``), refused for its range or not: seconds in
        #: ``lateral_error_out_of_scale`` and ``relative_yaw_out_of_scale`` (told, not
        #: refused), and the scale of each when last told since the caller last took it
        #: (0: none)
        self.lane_scale = LaneScaleCheck()
        self.lateral_scale_seen = 0.0
        self.yaw_scale_seen = 0.0
        self._raw: dict[str, Any] = {}
        #: the last relative yaw received and its value continued across +-pi
        self._eps_unwrapped: Optional[tuple[float, float]] = None
        self.yaw_fault: Optional[str] = None
        self.timing = InputTiming()
        self._received: dict[str, int] = {}     # input -> node clock of its last sample
        self._first_received: Optional[int] = None
        # received after a later clock reading (the clock went back): stale until the
        # input is received again; the same for the start of the wait for the others
        self._voided: set[str] = set()
        self._first_voided = False
        self._last_now: Optional[int] = None
        self._held: Optional[float] = None
        self._stale_since: Optional[int] = None
        self._stale_ns = 0
        self._hold_value: Optional[float] = None
        self.use_preview = use_preview
        self.vehicle = vehicle
        self.params = controller
        self.acceleration_source = check_choice('acceleration_source', acceleration_source,
                                                ACCELERATION_SOURCES)
        self.lateral: Optional[LateralErrorSample] = None
        self.yaw: Optional[YawSample] = None
        self.velocity: Optional[VelocitySample] = None
        self.curvature: Optional[CurvatureSample] = None
        #: the (stamp [ns], v_x) the differentiated a_x was last taken at
        self._accel_anchor: Optional[tuple[int, float]] = None
        self._accel_estimate = 0.0
        self.last: Optional[Command] = None
        #: the polygon moved to the lateral error's time, for (polygon, distance moved)
        self._road_cache: tuple[Optional[CurvatureSample], float, Optional[CurvatureSample]] = (
            None, 0.0, None)
        # the rate limit's reference: the last angle sent (kept across resets: the
        # actuator is still there), the node's clock and the steady clock when it was
        # sent, and the newest command stamp so far
        self._rate_angle: Optional[float] = None
        #: the node's clock when the last command was sent (the law's or a safe one; the
        #: stamp where there is no clock): the safe commands' spacing for the law's filter
        self._sent_at: Optional[int] = None
        self._rate_now: Optional[int] = None
        self._rate_steady: Optional[int] = None
        self._rate_time: Optional[int] = None
        # the last command sent at a node-clock reading before the latest one: (angle,
        # node clock, steady clock); the rate limit's reference on the node's clock
        self._rate_ref: tuple[Optional[float], int, Optional[int]] = (None, 0, None)
        # the stamp of the first command ever sent (start-up: see _limited)
        self._start_stamp = 0

    def configure(self, vehicle: VehicleParams, controller: ControllerParams,
                  acceleration_source: str, use_preview: bool,
                  safety: Optional[SafetyParams] = None, law: Optional[str] = None,
                  baselines: Optional[BaselineParams] = None,
                  lane_keeping: Optional[LaneKeepingParams] = None,
                  align_inputs: Optional[str] = None,
                  curvature_at_yaw_stamp: Optional[bool] = None) -> None:
        """
        Replace the parameters (between two control steps).

        A new law starts from its reset state; its first command moves from the last one
        sent within the rate limit, like any other. A retune of the law running (its
        name unchanged) is bumpless: ``retune`` says what it carried over.

        :param vehicle: vehicle parameters.
        :param controller: controller parameters.
        :param acceleration_source: see the constructor.
        :param use_preview: see the constructor.
        :param safety: see the constructor (None: keep).
        :param law: see the constructor (None: keep).
        :param baselines: see the constructor (None: keep).
        :param lane_keeping: see the constructor (None: keep).
        :param align_inputs: see the constructor (None: keep).
        :param curvature_at_yaw_stamp: see the constructor (None: keep).
        """
        # every value checked before any is taken (dev-probe123: a bad curvature_at_yaw_stamp
        # left align_inputs changed)
        align = (self.align_inputs if align_inputs is None
                 else check_choice('align_inputs', align_inputs, ALIGN_CHOICES))
        at_yaw = (self.curvature_at_yaw_stamp if curvature_at_yaw_stamp is None
                  else check_flag('curvature_at_yaw_stamp', curvature_at_yaw_stamp))
        self.align_inputs, self.curvature_at_yaw_stamp = align, at_yaw
        self.lane_keeping = lane_keeping or self.lane_keeping
        self._select_law(law or self.law_name, vehicle, controller,
                         baselines or self.baselines)
        self.safety = safety or self.safety
        self.use_preview = use_preview
        self.vehicle = vehicle
        self.params = controller
        self.acceleration_source = check_choice('acceleration_source', acceleration_source,
                                                ACCELERATION_SOURCES)

    def _select_law(self, name: str, vehicle: VehicleParams, controller: ControllerParams,
                    baselines: BaselineParams) -> None:
        """
        Build the law (raises ParameterError first: the old law stays on error).

        The same law with the same parameters is kept with its state: a change of
        another parameter (a limit, a diagnostics threshold) does not restart an
        integral or an estimate. The same law with other parameters (a retune) takes
        over the old one's state where it has a ``take_over`` (``cg_compensated``); a
        law of another name starts from its reset state.
        """
        key = law_key(name, vehicle, controller, baselines, self.lane_keeping)
        self.retune = None
        if key == self._law_key:
            self.baselines = baselines
            return
        law = build_law(name, vehicle, controller, baselines, self.lane_keeping)
        law.reset()
        take_over = getattr(law, 'take_over', None)
        if name == self.law_name and take_over is not None and type(law) is type(self.law):
            # a retune of the same law: bumpless, it continues from the old one's state
            # (docs/lane_keeping.md, "Retuning at run time"); its time axis goes on
            self.retune = take_over(self.law)
        else:
            self._law_stamp = None
        self.law, self.law_name, self.baselines = law, name, baselines
        self._law_key = key

    def preview(self, now_ns: Optional[int] = None) -> Preview:
        """
        Return the curvature ahead as the laws get it (empty before any curvature).

        The ``road_curvature`` polygon's points when it has two or more (distances ahead
        of the CG at the polygon's stamp, as the offline runner gives them to the laws).
        A polygon of one point: that curvature held ahead; with ``use_preview`` (always
        for ``cg_compensated``) its slope extended over :data:`PREVIEW_HORIZON`, within
        the believable curvature. A lost curvature (:meth:`curvature_lost`) is 0 ahead
        too, as at the CG.

        :param now_ns: the node's clock [ns] (None: the latest curvature is used).
        :return: the preview.
        """
        road = self.road()
        if road is None:
            return Preview(np.zeros(0), np.zeros(0))
        if self.curvature_lost(now_ns):
            return Preview(np.zeros(1), np.zeros(1))
        ahead = road.ahead
        if len(ahead) >= 2:
            return Preview(np.array([p[0] for p in ahead], dtype=float),
                           np.array([p[1] for p in ahead], dtype=float))
        rho = road.rho
        if not (self.use_preview or self.law_name == 'cg_compensated'):
            return Preview(np.zeros(1), np.array([rho]))
        cap = self.safety.max_curvature
        ahead_rho = min(cap, max(-cap, rho + road.slope * PREVIEW_HORIZON))
        return Preview(np.array([0.0, PREVIEW_HORIZON]), np.array([rho, ahead_rho]))

    def road(self) -> Optional[CurvatureSample]:
        """
        Return the latest curvature polygon as the law reads it.

        With ``lane_keeping.delay_prediction`` the law predicts its state from the lateral
        error's stamp ``filter_delay`` ahead and reads the road there; a polygon stamped
        at another time (a lane camera's frame 50-120 ms old beside a map of now) gives
        the distances ahead of the CG at its own stamp, so it is moved by the distance
        driven between the two stamps, ``v_x (t_lateral - t_polygon)`` (an age within
        ``input_timeout``), and the curvature at the CG read there. With ``filter_delay``
        the camera's age plus the actuator's delay the road is then read where the
        command acts (dev-probe117: a camera 80 ms late beside a fresh map, 37 m/s,
        noise-free, S1 / S2 15.5 / 20.0 -> 2.9 / 9.5 cm). A polygon of one point, or one
        stamped with the lateral error, is read as it is. A polygon newer than the
        lateral error has no points behind its own CG: the newest one kept from at or
        before the lateral error's stamp is read instead, moved ahead (dev-sc52).

        Without the prediction the law takes its state for the present: the lateral error
        and the relative yaw as they came, the newest yaw rate and speed. With
        ``curvature_at_yaw_stamp`` (the default) a polygon stamped before the yaw sample
        it takes is read where the car was at that sample's stamp: moved by ``v_x`` times
        the stamps' difference (within ``input_timeout``). Read as stamped, a 10 Hz map of
        now beside an IMU of now was up to 100 ms old, the curve up to 3.7 m late at 37
        m/s (dev-sc53: the default law, a lateral error of now at 100 Hz, S1 at 37 m/s
        14.1 -> 4.2 cm, noise-free). Not to the node's clock: a polygon sent with each
        frame of a late camera, with the yaw of the frame's instant, was then read ahead
        of the rest of the state (dev-probe124: 30 Hz / 50 ms, S1-S4 on two plants summed
        72.6 -> 100.9 cm); not to the lateral error's stamp: behind a camera 80 ms late
        beside an IMU of now that put the feedforward late by the camera's age
        (dev-probe119: S1 6.3 -> 15.3 cm). With ``align_inputs`` ``always`` (the yaw read
        at the lateral error's stamp) as stamped: it measured better there than at that
        stamp.

        :return: the polygon the law reads (None: no curvature yet).
        """
        road = self.curvature
        if road is None or self.lateral is None or self.velocity is None or self.yaw is None:
            return road
        predicts = self.law_name == 'cg_compensated' and self.lane_keeping.delay_prediction
        limit = int(self.safety.input_timeout * 1e9)
        lateral = self.lateral.stamp_ns
        if not predicts:
            # with the yaw read at the lateral error's stamp (align_inputs always) as
            # stamped: moved to that stamp it measured worse (dev-sc53, vehicle_bridge.md)
            if not self.curvature_at_yaw_stamp or self.aligns or len(road.ahead) < 2:
                return road
            age = self.yaw.stamp_ns - road.stamp_ns
            if age <= 0:                # (sent with the yaw, or newer: as it is)
                return road
            return self._moved(road, min(limit, age))
        if road.stamp_ns > lateral:
            # newer than the lateral error (a map of now beside a late camera): its points
            # start at its own CG, ahead of the lateral error's, and the stretch between
            # has none (it was read as the first point's curvature: dev-probe121,
            # CommonRoad, 20 Hz / 120 ms camera, a 100 Hz map of now: S1 17.0 cm against
            # 2.6 with the polygon of the frame, noise-free); the newest polygon kept from
            # at or before the lateral error's stamp (within input_timeout), moved ahead,
            # covers it (a map sample on the frame's stamp: the frame's polygon)
            stamps, kept = self._kept['road_curvature']
            i = bisect_right(stamps, lateral) - 1
            # (the newest of two points or more: a one-point sample is no polygon)
            while i >= 0 and lateral - stamps[i] <= limit and len(kept[i].ahead) < 2:
                i -= 1
            if i >= 0 and lateral - stamps[i] <= limit:
                road = kept[i]
        if len(road.ahead) < 2:
            return road
        return self._moved(road, min(limit, max(-limit, lateral - road.stamp_ns)))

    def _moved(self, road: CurvatureSample, age: int) -> CurvatureSample:
        """Return the polygon moved ahead by the distance driven in ``age`` [ns]."""
        assert self.velocity is not None
        moved = self.velocity.v_x * age * 1e-9
        if moved == 0.0 or not math.isfinite(moved):
            return road
        seen, at, moved_road = self._road_cache
        if seen is road and at == moved and moved_road is not None:
            return moved_road
        moved_road = curvature_from_points(road.stamp_ns,
                                           [(x - moved, k) for x, k in road.ahead])
        self._road_cache = (road, moved, moved_road)
        return moved_road

    # -- checked input ------------------------------------------------------------

    def reset(self) -> None:
        """
        Forget the inputs and the last command (time jumped: replay restart, sim reset).

        The last angle sent stays the rate limit's reference and the angle held at low
        speed (the actuator is still there); the first command after the reset holds
        it, the next ones move from it.
        """
        self.lateral = self.yaw = self.velocity = self.curvature = None
        for stamps, kept in self._kept.values():
            stamps.clear()
            kept.clear()
        self._duplicated_now.clear()
        self._accel_anchor = None
        self._accel_estimate = 0.0
        self.last = None
        self._rate_now = self._rate_steady = self._rate_time = None
        self._received.clear()
        self._first_received = None
        self._voided.clear()
        self._first_voided = False
        self._last_now = None
        self._stale_since = None
        if self._rate_angle is not None:
            self._hold_value = self._rate_angle
        self.law.reset()
        self.map_check.reset()
        self.map_timing.forget()
        self._timing_yaw = None
        self.speed_check.reset()
        self._raw.clear()               # (the lane scale check restarts with the yaw fault)
        self._eps_unwrapped = None
        self.clear_yaw_fault()
        self._law_stamp = None          # (the oscillation check restarts with it)

    def seed_output(self, angle: float, stamp_ns: int) -> None:
        """
        Take a command sent before the first input this core sees (a re-run of a bag).

        A recorder that subscribed late misses the first inputs but may hold the answer
        to one of them: the next command then moves from that angle within the rate
        limit, as the node's did, instead of starting free.

        :param angle: the angle sent [rad].
        :param stamp_ns: its stamp [ns].
        """
        self._rate_angle = float(angle)
        self._rate_time = int(stamp_ns)

    def accept(self, name: str, sample: Any, now_ns: Optional[int] = None) -> Optional[str]:
        """
        Check a sample and store it; a refused one is counted and never used.

        The node's clock going back by more than 1 s (without a clock: a stamp more than
        1 s behind the last one of its input) is a time jump (replay restart, sim
        reset): the state is reset instead of producing a rate spike, and the sample is
        checked afresh. With a clock, a stamp going back is refused: it is the sensor's
        clock that jumped, not the node's.

        :param name: ``lateral_error``, ``yaw``, ``velocity`` or ``road_curvature``.
        :param sample: the converted sample.
        :param now_ns: the node's clock (receive time) [ns]: 0 while it is not running
            (sim time before the first ``/clock``), None without a clock (offline).
        :return: None if accepted, else the reason.
        """
        current = getattr(self, _LATEST[name])
        if now_ns is None:
            jumped = current is not None and sample.stamp_ns < current.stamp_ns - JUMP_NS
        else:
            jumped = self._last_now is not None and now_ns < self._last_now - JUMP_NS
        if jumped:
            self.time_jumps += 1
            self.reset()
            # the inputs' timeout runs from the jump: inputs refused from now on go stale
            self._first_received = now_ns
            current = None
        if now_ns is not None:
            self._last_now = now_ns     # the node's clock, whether the sample is used or not
        # a clock reading 0 is not running yet (sim time before the first /clock): the
        # stamps cannot be judged against it
        clock = now_ns if now_ns is not None and now_ns > 0 else None
        self._judge_scale(name, sample, clock)
        faulty = check_sample(name, sample, self.safety)
        reason = faulty or check_stamp(
            name, sample.stamp_ns, current.stamp_ns if current else None, clock, self.safety)
        if reason is None and name == 'yaw' and self.yaw_fault is not None:
            reason = self.yaw_fault
        received = 0 if now_ns is None else now_ns
        if (reason is not None and faulty is None and sample == current
                and not (name == 'yaw' and self.yaw_fault is not None)
                and check_stamp(name, sample.stamp_ns, None, clock, self.safety) is None):
            # the last taken message again, within the clock's bounds: nothing new to
            # use, nothing wrong to warn of; it does not keep the input fresh (a
            # publisher stuck repeating its last message still goes stale, and says so)
            reason = duplicate_reason(name, sample.stamp_ns)
            self.duplicates[name] = self.duplicates.get(name, 0) + 1
            if name not in self._duplicated_now:
                self._duplicated_now.add(name)
                self.duplicated[name] = self.duplicated.get(name, 0) + 1
            self.refusals[name] = reason
            return reason
        if reason is not None:
            self.refusals[name] = reason
            self.count_rejection(reason)
            if self._first_received is None:
                # an input came in: the inputs' timeout runs from it, taken or not
                # (dev-probe97: a sensor clock 0.2 s ahead from the start had every
                # input refused, and the node stayed silent with a WARN, no ERROR)
                self._first_received = received
            return reason
        if clock is not None:
            self.timing.note_age(name, (clock - sample.stamp_ns) * 1e-9)
        self._received[name] = received
        # why its samples were refused is told only while it is why the input is stale:
        # once one is taken, an older refusal is history (dev-probe37: a yaw input that
        # simply stopped was reported stale with a refusal a second older)
        self.refusals.pop(name, None)
        self._voided.discard(name)
        if self._first_received is None:
            self._first_received = received
        self.taken[name] = self.taken.get(name, 0) + 1
        self._duplicated_now.discard(name)
        getattr(self, _UPDATE[name])(sample)
        if name == 'road_curvature':
            self._judge_speed(sample)
        return None

    def count_rejection(self, reason: str) -> None:
        """
        Count a refused message under ``'<input>: <field or cause>'``.

        :param reason: why it was refused, ``'<input>: <detail>'``.
        """
        name, _, detail = reason.partition(':')
        key = f'{name}: {(detail.split() or ["?"])[0]}'
        self.rejected[key] = self.rejected.get(key, 0) + 1
        self.last_rejection = reason
        if name in _LATEST:
            self.refusals[name] = reason

    def _fresh(self, name: str, now_ns: int) -> bool:
        """
        Return whether an input's last sample is fresh at ``now_ns``.

        Fresh: received within ``input_timeout`` before ``now`` on the node's clock and
        stamped no more than ``input_timeout`` ago. A sample received after ``now``
        came before the clock went back: it stays stale until the input is received
        again (also once the clock is past its reception time again).
        """
        received = self._received.get(name)
        sample = getattr(self, _LATEST[name])
        if received is not None and received > now_ns:
            self._voided.add(name)
        timeout = self.safety.input_timeout * 1e9
        return (received is not None and sample is not None and name not in self._voided
                and now_ns - received <= timeout and now_ns - sample.stamp_ns <= timeout)

    def stale(self, now_ns: Optional[int]) -> list[str]:
        """
        Return the required inputs that are stale at ``now_ns``.

        Stale: received (on the node's clock) more than ``input_timeout`` ago or before
        the clock went back, stamped more than ``input_timeout`` ago, or never received
        although another input came in, taken or refused (or the time jumped), more than
        ``input_timeout`` ago or before the clock went back. An input refused over and
        over, or whose stamps stopped advancing (refused as repeated), therefore goes
        stale too, also after a time jump or when none was ever taken.
        ``road_curvature`` is optional: see :meth:`curvature_lost`.

        :param now_ns: the node's clock [ns] (None: not running, nothing is stale).
        :return: their names, in the order of ``REQUIRED_INPUTS``.
        """
        if now_ns is None or self._first_received is None:
            return []
        timeout = self.safety.input_timeout * 1e9
        if self._first_received > now_ns:
            self._first_voided = True
        waited = self._first_voided or now_ns - self._first_received > timeout
        return [name for name in REQUIRED_INPUTS
                if (name in self._received and not self._fresh(name, now_ns))
                or (name not in self._received and waited)]

    def curvature_received(self, now_ns: Optional[int]) -> bool:
        """
        Return whether a usable curvature is in: received once and not lost.

        :param now_ns: the node's clock [ns] (None: offline, judged on the stamps).
        :return: whether it is.
        """
        return self.curvature is not None and not self.curvature_lost(now_ns)

    def curvature_lost(self, now_ns: Optional[int]) -> bool:
        """
        Return True when ``road_curvature`` came in once and is now stale.

        The law then runs without curvature feed-forward (curvature 0, the feedback
        alone holds the lane) rather than on the old curvature or not at all: see
        ``docs/safety.md``.

        Without a clock (``now_ns`` None: an offline re-run) it is judged on the stamps,
        the lateral error's stamp as the clock: lost when the latest curvature is stamped
        more than ``input_timeout`` before the latest lateral error (the node, whose clock
        is about the lateral error's stamp when it answers, judges the same; before, a
        re-run held the last curvature where the node estimated it).

        :param now_ns: the node's clock [ns] (None: offline, judged on the stamps).
        :return: whether the curvature is lost (while :meth:`compute` is given the
            judgment: its opposite).
        """
        if self._judged is not None and self.curvature is not None:
            return not self._judged
        if now_ns is None:
            return (self.curvature is not None and self.lateral is not None
                    and self.lateral.stamp_ns - self.curvature.stamp_ns
                    > self.safety.input_timeout * 1e9)
        return ('road_curvature' in self._received
                and not self._fresh('road_curvature', now_ns))

    def describe_stale(self, names: list[str]) -> str:
        """
        Return ``'yaw (last refused: ...), velocity'``: the inputs and why, if known.

        :param names: stale inputs.
        :return: one line.
        """
        parts = []
        for name in names:
            why = self.refusals.get(name)
            # refused every time: received, but none taken (dev-probe97 read 'never
            # received (last refused: ...)')
            never = ('' if name in self._received else ' none taken' if why
                     else ' never received')
            parts.append(f'{name}{never}' + (f' (last refused: {why})' if why else ''))
        return ', '.join(parts)

    def safe_command(self, now_ns: int, steady_ns: Optional[int] = None,
                     stamp_ns: Optional[int] = None) -> Optional[Command]:
        """
        Return the stale-input command: hold, then ramp to the safe angle.

        The hold time runs from the first safe command; only an answer of the law from
        fresh inputs ends it.

        :param now_ns: the node's clock [ns].
        :param steady_ns: the steady clock [ns] (None under sim time).
        :param stamp_ns: the stamp to give it: the lateral error it answers, or None
            for the node's time on the measurements' clock (the watchdog).
        :return: the command, None before any command was sent.
        """
        sent = self._rate_angle
        if sent is None:
            return None
        if self._stale_since is None:
            self._stale_since, self._stale_ns = now_ns, 0
            # after a yaw rate found of the wrong sign the last command is one of the
            # shaking (dev-sc44: 0.089 rad held for 0.5 s at 30 m/s put the car off the
            # lane 0.7 s later): the mean command before the fault is held instead
            self._held = sent if self._fault_hold is None else self._fault_hold
            self.law.reset()            # a law with state restarts after stale inputs
            self._law_stamp = None
        # time stale, on the node's clock, counted forwards only (a clock going back
        # neither restarts the hold nor reverses the ramp)
        self._stale_ns += max(0, now_ns - self._stale_since)
        self._stale_since = now_ns
        held = self._held if self._held is not None else sent
        wanted = stale_target(held, self._stale_ns / 1e9, self.safety)
        v_x = self.velocity.v_x if self.velocity else 0.0
        stamp = self._measurement_time(now_ns) if stamp_ns is None else stamp_ns
        self.last = self._limited(wanted, stamp, now_ns, steady_ns, v_x, None, 'stale')
        since = (max(0, now_ns - self._sent_at) * 1e-9 if self._sent_at is not None
                 else 0.0)
        self._sent_at = now_ns
        note = getattr(self.law, 'note_safe_command', None)
        if note is not None:                # a state filter models the command sent
            note(self.last.steering, since)
        return self.last

    @property
    def _fault_hold(self) -> Optional[float]:
        """Return the angle the safe behaviour holds after a yaw fault (None: no fault)."""
        # the check is not stepped once it found the fault: its mean command is frozen
        # (NaN: the yaw-rate check restarted just before, e.g. slower than its min_speed)
        mean = self.yaw_check.command_mean
        return mean if self.yaw_fault is not None and math.isfinite(mean) else None

    def clear_yaw_fault(self) -> None:
        """Forget a yaw input refused by its checks, and the inputs' scales (the bridge fixed)."""
        if self.yaw_fault is not None and self.refusals.get('yaw') == self.yaw_fault:
            del self.refusals['yaw']
        self.yaw_check.reset()
        self.heading_check.reset()
        # dev-probe107: a lateral error in cm told on and on after the node's activation
        self.lane_scale.reset()
        self.yaw_fault = None

    def _judge_yaw_input(self, dt: float, state: LateralState, sent: float) -> None:
        """
        Step the yaw input's checks; refuse it once the yaw rate is found wrong.

        The yaw rate against the steering and the relative yaw (sign, scale): refused
        once wrong. The relative yaw against the lateral error's motion (sign): told in
        ``heading_disagrees``.

        :param dt: time since the law's previous answer [s].
        :param state: the measurements of this answer (its curvature: the one received,
            0 without or lost).
        :param sent: the command sent before this answer [rad].
        """
        if self.yaw_fault or self.lateral is None:
            return
        v_x, eps_r = float(state.v_x), float(state.eps_r)
        if self.heading_check.step(dt, self.lateral.value, self.lateral.distance, eps_r, v_x,
                                   float(state.v_y)):
            # dev-sc45: a relative yaw or a lateral error of the wrong sign steered every
            # law out of the lane, told only once the car was 5 m off
            self.turning['heading_disagrees'] += dt
            self.heading_seen = min(self.heading_seen, self.heading_check.correlation)
        check = self.yaw_check
        faulty = check.step(dt, float(state.r), sent, v_x, self.vehicle.wheelbase, eps_r,
                            float(state.rho))
        if check.too_still:
            self.turning['yaw_rate_still'] += dt
            self.still_seen = max(self.still_seen, check.stillness)
        if not faulty:
            return
        # dev-probe97: a yaw rate of the wrong sign shook the car off the road, told only
        # as a map WARN; dev-sc45: one in deg/s shook it off a straight, the range check
        # refusing its large samples only; now the yaw input is refused from here on:
        # stale at once
        self.yaw_fault = f'yaw: {check.verdict()}'
        self.refusals['yaw'] = self.yaw_fault
        self.count_rejection(self.yaw_fault)
        self._voided.add('yaw')

    def _judge_speed(self, sample: CurvatureSample) -> None:
        """
        Step the speed's scale check with a curvature preview taken (told, not refused).

        :param sample: the curvature sample, its stamp the time axis (the speed taken
            last, along the road by the relative yaw and the lateral error taken last,
            each within :data:`SPEED_AGE` of it; else the check restarts).
        """
        check, velocity, yaw, lateral = self.speed_check, self.velocity, self.yaw, self.lateral
        if velocity is None or yaw is None or lateral is None or any(
                abs(sample.stamp_ns - taken.stamp_ns) > SPEED_AGE * 1e9
                for taken in (velocity, yaw, lateral)):
            # (dev-sc47: a lateral error refused for its size left the last one taken, and
            # a car 53 m off the road looked 0.6 times as fast as the road moved)
            check.reset()
            return
        eps_r = yaw.relative_yaw
        along = road_speed(velocity.v_x, velocity.v_y, eps_r, sample.rho,
                           lateral.value - lateral.distance * eps_r, check.settings.lane_limit)
        if along is None:
            check.reset()
            return
        last = check.last_stamp
        if check.step(sample.stamp_ns, along, sample.ahead) and last is not None:
            # dev-sc47: a speed in km/h put the default law 0.3-26 m off S-bends at 6-19
            # m/s, under every range limit, told only as a map disagreeing
            self.turning['speed_out_of_scale'] += max(0, sample.stamp_ns - last) * 1e-9
            self.speed_seen = check.scale

    def _judge_scale(self, name: str, sample: Any, clock: Optional[int]) -> None:
        """
        Step the lane scale check with a sample received (told, not refused).

        Its range is not checked: a lateral error in cm or a relative yaw in degrees is
        mostly refused for it, and the samples taken alone are too few for evidence
        (dev-sc48). Its stamp is, against the last one received of its input.

        :param name: the input.
        :param sample: the converted sample.
        :param clock: the node's clock (None: none or not running).
        """
        last = self._raw.get(name)
        if check_stamp(name, sample.stamp_ns, last.stamp_ns if last is not None else None,
                       clock, self.safety) is not None:
            return
        self._raw[name] = sample
        check = self.lane_scale
        age = check.settings.max_age * 1e9
        if name == 'yaw':
            # dev-probe109: a relative yaw in degrees sent as a quaternion wraps at 3.14
            # true degrees, and the check went silent once the car moved
            raw = float(sample.relative_yaw)
            self._eps_unwrapped = (raw, unwrap(raw, self._eps_unwrapped))

        def near(other: str) -> Any:
            taken = self._raw.get(other)
            return (taken if taken is not None
                    and abs(taken.stamp_ns - sample.stamp_ns) <= age else None)

        velocity = near('velocity')
        if name == 'lateral_error':
            yaw, before = near('yaw'), check.lateral_stamp
            if velocity is None or yaw is None:
                check.reset_lateral()
            elif check.step_lateral(sample.stamp_ns, sample.value, sample.distance,
                                    self._relative_yaw(), velocity.v_x, velocity.v_y):
                # dev-sc48: a lateral error in cm put the default law 2-135 m off S-bends,
                # the input refused for its range, no word of the unit
                self._count_out_of_scale('lateral_error_out_of_scale', sample, before)
                self.lateral_scale_seen = check.lateral_scale
        elif name == 'yaw':
            curvature, before = near('road_curvature'), check.yaw_stamp
            rho = curvature.rho if curvature is not None else None
            if velocity is None:
                check.reset_yaw()
            elif check.step_yaw(sample.stamp_ns, self._relative_yaw(), sample.yaw_rate,
                                velocity.v_x, rho):
                # dev-sc48: a relative yaw in degrees put it 0.2-124 m off, told as a map
                # disagreeing and a steering oscillation
                self._count_out_of_scale('relative_yaw_out_of_scale', sample, before)
                self.yaw_scale_seen = check.yaw_scale

    def _relative_yaw(self) -> float:
        """Return the last yaw sample's relative yaw continued across +-pi (the check's)."""
        # set with the yaw sample it is of, and cleared with it (reset)
        held = self._eps_unwrapped
        return held[1] if held is not None else math.nan

    def _count_out_of_scale(self, key: str, sample: Any, before: Optional[int]) -> None:
        """Add the time since the check's previous sample to an out-of-scale count."""
        self.turning[key] += (max(0, sample.stamp_ns - before) * 1e-9
                              if before is not None else 0.0)

    def _measurement_time(self, now_ns: int) -> int:
        """
        Return the node's time on the measurements' clock.

        The last lateral-error stamp plus the time since it arrived, so that the stamps
        of watchdog commands continue those of the answers (sensors whose clock is
        within the stamp tolerance of the node's).

        :param now_ns: the node's clock [ns].
        :return: the same instant on the measurements' clock [ns].
        """
        received = self._received.get('lateral_error')
        if self.lateral is not None and received is not None:
            # received while a sim clock read 0 (not started): the time since is unknown,
            # not the whole sim time (dev-probe91: a clock starting at 101 s stamped the
            # watchdog's command 101 s ahead of the inputs, and the rate limit held every
            # answer at that command until their stamps caught up)
            return self.lateral.stamp_ns + (max(0, now_ns - received) if received else 0)
        return max(self._rate_time, now_ns) if self._rate_time is not None else now_ns

    def _limited(self, wanted: float, stamp_ns: int, now_ns: Optional[int],
                 steady_ns: Optional[int], v_x: float, law: Optional[LawOutput],
                 status: str) -> Command:
        """
        Apply the output limits to a wanted angle and make it the command sent.

        :param wanted: the angle wanted [rad].
        :param stamp_ns: its stamp [ns].
        :param now_ns: the node's clock [ns] (None: the stamps are the time axis).
        :param steady_ns: the steady clock [ns] (None: not used).
        :param v_x: the speed, for the angle limit [m/s].
        :param law: the law's output it comes from (None: a safe command).
        :param status: ``ok``, ``low_speed`` or ``stale``.
        :return: the command.
        """
        sent = self._rate_angle
        if now_ns is not None and self._rate_now is not None and now_ns < self._rate_now:
            self._rate_time = None      # the node's clock went back: both axes restart
        # time since the last command on the stamps' axis (newest stamp so far)
        on_stamps = (max(0, stamp_ns - self._rate_time) * 1e-9
                     if self._rate_time is not None else None)
        if (now_ns is not None and self._rate_time is not None and self._rate_ref[0] is None
                and now_ns == self._rate_now):
            # start-up, still at the first reading (no reference on the node's clock):
            # the stamps count only within the span a running clock lets them have after
            # the first command's, so a clock reading 0 (not judging them) or a flood of
            # answers cannot move the command further than the rate times that span
            span = int((self.safety.input_timeout + self.safety.max_future) * 1e9)
            on_stamps = max(0, min(stamp_ns, self._start_stamp + span)
                            - self._rate_time) * 1e-9
        if now_ns is None:
            elapsed = on_stamps if on_stamps is not None else 0.0
            out = limit(wanted, sent, elapsed, v_x, self.vehicle.wheelbase, self.safety)
            rate = (out.angle - sent) / elapsed if sent is not None and elapsed > 0.0 else 0.0
        else:
            # the node clock's reference: the last command sent at an earlier reading, so
            # the answers given at one reading (sim time: /clock did not advance between
            # two lateral errors) share one step of the rate limit instead of holding;
            # first after a reset or the clock going back: the last angle, no time yet
            if self._rate_now is None or now_ns < self._rate_now:
                self._rate_ref = (sent, now_ns, steady_ns)
            elif now_ns > self._rate_now:
                self._rate_ref = (sent, self._rate_now, self._rate_steady)
            ref_angle, ref_now, ref_steady = self._rate_ref
            elapsed = (now_ns - ref_now) * 1e-9
            if steady_ns is not None and ref_steady is not None:
                elapsed = min(elapsed, max(0, steady_ns - ref_steady) * 1e-9)
            self._rate_now, self._rate_steady = now_ns, steady_ns
            # and from the last command on the stamps, so a recording obeys the limit
            out = limit(wanted, sent if on_stamps is not None else None,
                        on_stamps if on_stamps is not None else 0.0, v_x,
                        self.vehicle.wheelbase, self.safety,
                        None if ref_angle is None else (ref_angle, elapsed))
            rate = ((out.angle - ref_angle) / elapsed
                    if ref_angle is not None and elapsed > 0.0 else 0.0)
        if sent is None:
            self._start_stamp = stamp_ns        # the first command ever: no reference
        self._rate_angle = out.angle
        self._rate_time = stamp_ns if self._rate_time is None else max(self._rate_time,
                                                                       stamp_ns)
        return Command(stamp_ns, out.angle, float(rate), law, status, out.saturated,
                       out.rate_limited)

    # -- unchecked input (trusted sources: offline re-runs, tests) ----------------

    def update_lateral_error(self, sample: LateralErrorSample) -> None:
        """Store the latest lateral-error sample."""
        self.lateral = sample

    def update_yaw(self, sample: YawSample) -> None:
        """Store the latest yaw sample."""
        self._keep('yaw', sample)
        self.yaw = sample

    def update_velocity(self, sample: VelocitySample) -> None:
        """
        Store the latest velocity sample and update the differentiated a_x.

        See :func:`differentiated_step`.

        :param sample: the velocity sample.
        """
        self._accel_estimate, self._accel_anchor = differentiated_step(
            self._accel_estimate, self._accel_anchor, sample.stamp_ns, sample.v_x,
            self.safety.max_acceleration)
        self._keep('velocity', sample)
        self.velocity = sample

    def update_curvature(self, sample: CurvatureSample) -> None:
        """Store the latest curvature sample."""
        self._keep('road_curvature', sample)
        self.curvature = sample

    def _keep(self, name: str, sample: Any) -> None:
        """
        Keep a yaw, velocity or curvature sample (a stamp not after the last: anew).

        Every sample of the last ``input_timeout + max_future`` and the one before: a
        lateral error is taken within ``input_timeout`` of the node's clock, a sample no
        further than ``max_future`` ahead of it, so the two around any lateral error
        taken are kept (dev-probe120: 512 samples at most, and a 5 kHz IMU beside a
        camera 150 ms late was read at the oldest kept, 0.047 m/s off). Older ones go
        when twice as many are kept, or beyond :data:`KEPT_SAMPLES` (polygons:
        :data:`KEPT_POLYGONS`).

        :param name: ``yaw``, ``velocity`` or ``road_curvature``.
        :param sample: the sample taken.
        """
        stamps, kept = self._kept[name]
        stamp = sample.stamp_ns
        if stamps and stamp <= stamps[-1]:
            stamps.clear()
            kept.clear()
        stamps.append(stamp)
        kept.append(sample)
        span = int((self.safety.input_timeout + self.safety.max_future) * 1e9)
        most = KEPT_POLYGONS if name == 'road_curvature' else KEPT_SAMPLES
        if stamps[0] < stamp - 2 * span or len(kept) > 2 * most:
            drop = max(len(kept) - most, bisect_right(stamps, stamp - span) - 1)
            del stamps[:drop]
            del kept[:drop]

    @property
    def aligns(self) -> bool:
        """
        Return whether the yaw and velocity are read at the lateral error's stamp now.

        ``align_inputs`` ``with_prediction`` (the default): while the law predicts its
        state from the lateral error's stamp (``cg_compensated`` with
        ``lane_keeping.delay_prediction``). A law that takes its state for the present
        has the newest yaw rate and speed: nearer the present than the frame's, and with
        a camera 120 ms late they damped the loop by accident (dev-probe121: aligned, the
        CommonRoad car spun out at 37 m/s where the newest gave 6 cm).
        """
        if self.align_inputs == 'with_prediction':
            return self.law_name == 'cg_compensated' and self.lane_keeping.delay_prediction
        return self.align_inputs == 'always'

    def aligned(self, name: str) -> Any:
        """
        Return the yaw or velocity sample at the lateral error's stamp (:attr:`aligns`).

        A law that predicts its state from the lateral error's stamp needs every input of
        that instant: a lane camera's lateral error and relative yaw come 50-120 ms after
        the frame, beside a yaw rate and a speed of now; mixed, the state never was
        (dev-probe117: S2 at 37 m/s 9.5-13.8 cm against 1.4-3.4 with every input of the
        frame's instant). So the samples are read at the lateral error's stamp: linearly
        between the two kept samples around it (one stamped exactly there: that sample),
        the newest where none is newer (as without alignment; every input on one stamp,
        as the simulator sends them: the same samples, bit for bit), the oldest kept
        where every one is newer.

        :param name: ``yaw`` or ``velocity``.
        :return: the sample (its stamp the lateral error's where interpolated; None
            before the first).
        """
        latest = getattr(self, name)
        lateral = self.lateral
        if (latest is None or lateral is None or not self.aligns
                or latest.stamp_ns <= lateral.stamp_ns):
            return latest
        stamps, kept = self._kept[name]
        stamp = lateral.stamp_ns
        i = bisect_right(stamps, stamp)
        if i == 0:
            return kept[0]
        before, after = kept[i - 1], kept[i]
        if before.stamp_ns == stamp:
            return before
        w = (stamp - before.stamp_ns) / (after.stamp_ns - before.stamp_ns)
        if name == 'yaw':
            # the relative yaw across +-pi the short way (a wrapped angle's mean is not)
            turn = math.remainder(after.relative_yaw - before.relative_yaw, 2.0 * math.pi)
            return YawSample(stamp, math.remainder(before.relative_yaw + w * turn,
                                                   2.0 * math.pi),
                             before.yaw_rate + w * (after.yaw_rate - before.yaw_rate),
                             before.accel_x + w * (after.accel_x - before.accel_x))
        return VelocitySample(stamp, before.v_x + w * (after.v_x - before.v_x),
                              before.v_y + w * (after.v_y - before.v_y))

    def missing(self) -> list[str]:
        """Return the names of the inputs never received (curvature is optional)."""
        return [name for name, value in (('lateral_error', self.lateral), ('yaw', self.yaw),
                                         ('velocity', self.velocity)) if value is None]

    def inputs_at(self, stamp_ns: int) -> bool:
        """
        Return True when every received input is at least as new as ``stamp_ns``.

        A curvature lost at ``stamp_ns`` (stamped more than ``input_timeout`` before it:
        a map lost, ``sim_plant`` ``curvature_stop``) is not waited for: before, each
        answer of a lockstep run waited ``sync_timeout`` of wall clock for it (S2 at 37 m/s,
        curvature stopped at 4 s: 38 s instead of 6 s), for the same answer.

        :param stamp_ns: the lateral-error stamp to wait for [ns].
        :return: whether yaw, velocity (and curvature, once seen and not lost) have caught
            up.
        """
        curvature = self.curvature
        waited = (curvature is not None
                  and stamp_ns - curvature.stamp_ns <= self.safety.input_timeout * 1e9)
        samples = [self.yaw, self.velocity] + ([curvature] if waited else [])
        return all(s is not None and s.stamp_ns >= stamp_ns for s in samples)

    def acceleration(self, yaw: Optional[YawSample] = None,
                     velocity: Optional[VelocitySample] = None) -> float:
        """
        Return a_x from the configured source [m/s^2].

        :param yaw: the yaw sample to use (None: the latest).
        :param velocity: the velocity sample to use (None: the latest).
        :return: a_x.
        """
        yaw = yaw or self.yaw
        velocity = velocity or self.velocity
        if self.acceleration_source == 'imu' and yaw is not None:
            v_y = velocity.v_y if velocity else 0.0
            return yaw.accel_x + v_y * yaw.yaw_rate
        if self.acceleration_source == 'differentiate':
            return self._accel_estimate
        return 0.0

    def state(self, now_ns: Optional[int] = None) -> Optional[LateralState]:
        """
        Return the law's inputs from the latest samples, None if any is missing.

        :param now_ns: the node's clock [ns]; a lost curvature counts as 0 (None: use
            the latest curvature, if any).
        :return: the state.
        """
        if self.lateral is None or self.yaw is None or self.velocity is None:
            return None
        yaw, velocity = self.aligned('yaw'), self.aligned('velocity')
        self._state_yaw = yaw.stamp_ns
        eps_r = yaw.relative_yaw
        road = self.road()
        rho, slope = (road.rho, road.slope) if (
            road is not None and not self.curvature_lost(now_ns)) else (0.0, 0.0)
        v_x = velocity.v_x
        return LateralState(
            y_cg=cg_error_from(self.lateral.value, eps_r, self.lateral.distance),
            eps_r=eps_r, v_y=velocity.v_y, r=yaw.yaw_rate, v_x=v_x,
            a_x=self.acceleration(yaw, velocity), rho=rho,
            rho_rate=v_x * slope if self.use_preview else 0.0)

    def compute(self, now_ns: Optional[int] = None,
                steady_ns: Optional[int] = None,
                curvature_received: Optional[bool] = None) -> Optional[Command]:
        """
        Evaluate the law on the latest inputs, or give the safe command if one is stale.

        :param now_ns: the node's clock [ns] (None: no clock, inputs are not judged
            stale and the stamps time the rate limit: offline re-runs).
        :param steady_ns: the steady clock [ns], on the wall clock (None: sim time).
        :param curvature_received: whether the curvature received counts as in at this
            step, not lost (None: judged here, :meth:`curvature_lost`; an offline re-run
            gives the recorded node's own judgment, which no stamp holds).
        :return: the command answering the latest lateral error (the safe command when
            a required input is stale), None if an input is missing.
        """
        self._judged = curvature_received
        try:
            return self._compute(now_ns, steady_ns)
        finally:
            self._judged = None

    def _step_map_timing(self, state: LateralState, dt: float) -> None:
        """Give the map timing check the yaw sample the law took, on its own stamps."""
        stamp, last = self._state_yaw, self._timing_yaw
        self._timing_yaw = stamp
        if stamp is None:
            return
        step = math.inf if last is None or stamp < last else (stamp - last) * 1e-9
        check = self.map_timing
        fitted = check.step(step, float(state.eps_r), float(state.r), float(state.v_x),
                            float(state.rho), float(state.y_cg), float(state.v_y))
        # only a step it fitted (dev-probe127: below its speed the fit kept was told on,
        # the seconds grew while braking to 0.55 m/s, and the WARN named that speed)
        lead = check.told() if fitted else None
        if lead is not None:
            self.turning['curvature_early_or_late'] += dt
            self.map_lead_seen = (lead, float(state.v_x))

    def _compute(self, now_ns: Optional[int], steady_ns: Optional[int]) -> Optional[Command]:
        if now_ns is not None and self.lateral is not None and self.stale(now_ns):
            fresh = self._fresh('lateral_error', now_ns)
            return self.safe_command(now_ns, steady_ns,
                                     self.lateral.stamp_ns if fresh else None)
        state = self.state(now_ns)
        if state is None or self.lateral is None:
            return None
        stamp = self.lateral.stamp_ns
        # the same lateral error answered again (timer mode between the frames of a slower
        # camera, while the yaw rate and speed come in): no time on the stamps, so the
        # command is held (the rate limit on the stamps), which is not the law's asking
        # faster than the actuator may go: not counted limited, and the law is not told
        # (dev-probe117: every tick counted limited froze the integral, a 25 Hz camera
        # under a 100 Hz timer left the CG 11 cm off on S2 at 37 m/s)
        again = self._law_stamp == stamp
        if self._law_stamp is None:     # a start, or after the safe command: swings apart
            self.oscillation.reset()    # (dev-probe77: counted as one run across a gap)
        dt = 0.0 if self._law_stamp is None else max(0, stamp - self._law_stamp) * 1e-9
        self._law_stamp = stamp
        v_x, r = float(state.v_x), float(state.r)
        if 0.0 < dt <= 1.0 and v_x >= TURN_SPEED and abs(r) >= TURN_RATE:
            if self.curvature is None or self.curvature_lost(now_ns):
                self.turning['turning_without_curvature'] += dt
            if float(state.v_y) == 0.0:
                self.turning['v_y_exactly_zero'] += dt
        self.curvature_in = self.curvature_received(now_ns)
        note_curvature = getattr(self.law, 'note_curvature', None)
        if self.curvature_in and self.curvature is not None:
            # a law that estimates a missing curvature drops a map far off (dev-sc35)
            settings = getattr(self.law, 'settings', None)
            fallback = getattr(settings, 'map_fallback', 0.0) if note_curvature else 0.0
            residual = self.map_check.step(dt, float(state.eps_r), r, v_x, float(state.rho),
                                           float(state.y_cg), float(state.v_y), fallback,
                                           getattr(settings, 'map_recover', 0.0))
            if abs(residual) > abs(self.map_residual):
                self.map_residual = residual
            if self.map_check.disagrees:    # (0 after its restart on a gap; dt 0 adds 0)
                self.turning['curvature_disagrees'] += dt
            if self.map_check.dropped:
                self.turning['curvature_dropped'] += dt
            self._step_map_timing(state, dt)
        else:       # a curvature lost and back: still dropped until the check is quiet
            self.map_check.reset(keep_dropped=True)
            self.map_timing.reset()
            self._timing_yaw = None
        if note_curvature is not None:      # a law that estimates a missing curvature
            note_curvature(self.curvature_in and not self.map_check.dropped)
        resets = getattr(self.law, 'resets', 0)
        causes = dict(getattr(self.law, 'restart_causes', {}))
        law = self.law.step(state, self.preview(now_ns), dt)
        if getattr(self.law, 'resets', 0) != resets:
            self.law_restarts += 1
            for cause, count in getattr(self.law, 'restart_causes', {}).items():
                if count > causes.get(cause, 0):
                    self.law_restart_causes[cause] = self.law_restart_causes.get(cause, 0) + 1
        self._stale_since = None
        if now_ns is not None and now_ns > 0:
            self.timing.note_latency((now_ns - self.lateral.stamp_ns) * 1e-9)
        # the output stage's speed is the car's now, the newest (the law's, read at the
        # lateral error's stamp with align_inputs, is older: dev-sc52's fuzz found a
        # command over the angle limit at the newest speed)
        v_x = float(self.velocity.v_x if self.velocity is not None else state.v_x)
        weight = low_speed_weight(v_x, self.safety)
        raw = float(law.steering)
        hold = self._hold_value if self._hold_value is not None else 0.0
        wanted = raw if weight >= 1.0 else weight * raw + (1.0 - weight) * hold
        if weight < 1.0:
            # the speed the diagnostics name with the hold (dev-probe90: they named the
            # speed of the newest velocity, 30 m/s, after a moment at -10)
            self.low_speed_v_x = v_x
        sent_before = self._rate_angle
        self.last = self._limited(wanted, self.lateral.stamp_ns, now_ns, steady_ns, v_x, law,
                                  'ok' if weight >= 1.0 else 'low_speed')
        if again and self.last.rate_limited:
            self.last = replace(self.last, rate_limited=False)
        if sent_before is not None:
            self._judge_yaw_input(dt, state, sent_before)
        if self.oscillation.step(dt, self.last.steering):
            self.turning['steering_oscillates'] += dt
            if self.oscillation.amplitude > self.oscillation_seen[0]:
                self.oscillation_seen = (self.oscillation.amplitude, self.oscillation.frequency)
        if weight >= 1.0:
            # the command sent, not the law's: a command the angle limit cut at speed was
            # held at its uncut size as the speed fell and the limit widened (dev-probe58:
            # 0.6 rad with low_speed 30 m/s, a size the car never got above it)
            self._hold_value = self.last.steering
        note_limited = getattr(self.law, 'note_limited', None)
        if note_limited is not None and not again:  # anti-windup of a law with an integral
            note_limited(self.last.saturated or self.last.rate_limited)
        note_sent = getattr(self.law, 'note_sent', None)
        if note_sent is not None:           # a state filter models the command sent
            note_sent(self.last.steering)
        self._sent_at = now_ns if now_ns is not None else self.lateral.stamp_ns
        return self.last
