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
The ``controller`` node: a managed (lifecycle) shell around ``SteeringController``.

Subscribes ``lateral_error``, ``yaw``, ``velocity``, ``road_curvature`` (relative names:
remap them), publishes ``steering`` and ``~/debug``. Auto-activates unless
``autostart`` is false; inactive, it publishes nothing.
"""

from __future__ import annotations

import math
import struct
import sys
import time
from typing import Any, Callable, Mapping, Optional

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PointStamped, PolygonStamped, TwistStamped
from lookahead_control.core.answer_rate import AnswerPacer
from lookahead_control.core.controller import (ACCELERATION_SOURCES, ALIGN_CHOICES,
                                               build_law, Command, LAW_NAMES,
                                               SteeringController)
from lookahead_control.core.lane_keeping import (curvature_filter_note, filterless_note,
                                                 frequency_schedule_note, integral_schedule_note,
                                                 LaneKeepingParams)
from lookahead_control.core.params import ControllerParams, ParameterError, SCHEDULE_MODES
from lookahead_control.core.safety import check_points, is_duplicate
from lookahead_control.core.samples import curvature_from_points
from lookahead_control.ros import conversions as conv
from lookahead_control.ros.node_main import (build_or_destroy, end_process, now_ns, run_node,
                                             Throttle)
from lookahead_control.ros.node_params import (baseline_params, BASELINE_SPECS, check_choices,
                                               CONTROLLER_SPECS, declare, EXECUTOR_SPEC,
                                               lane_keeping_params, LANE_KEEPING_SPECS,
                                               LAW_SPEC, safety_params, SAFETY_SPECS, Spec,
                                               values, vehicle_and_controller, VEHICLE_SPECS)
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType, JumpThreshold, ROSClock
from rclpy.duration import Duration
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Imu, JointState

NODE_SPECS = (
    Spec('mode', 'event', 'event: one command per lateral-error message; timer: at '
         'rate_hz with the latest inputs', choices=('event', 'timer')),
    Spec('rate_hz', 100.0, 'command rate in timer mode [Hz]', 1.0, 2000.0),
    Spec('qos_reliability', 'reliable', 'reliability of the input subscriptions; '
         'best_effort also connects to sensor-data (best-effort) publishers',
         choices=('reliable', 'best_effort')),
    Spec('wait_for_matching_stamps', False, 'event mode: wait until yaw, velocity (and '
         "curvature, once seen) carry the lateral error's stamp (lockstep simulation)"),
    Spec('sync_timeout', 0.05, 'longest wall-clock wait for matching stamps [s]',
         0.0, 1.0),
    Spec('max_answer_rate_hz', 250.0, 'event mode on the wall clock: lateral errors '
         'answered at most this often (bursts of 3); one that comes sooner is answered '
         'when the bound allows, or coalesced into a newer one (under use_sim_time: every '
         'one is answered); at least 20 Hz, so that the answers stay closer than the '
         "law's max_gap [Hz]", 20.0, 100000.0),
    Spec('acceleration_source', 'imu', "a_x from the yaw topic's IMU acceleration, "
         'differentiated from v_x, or zero', choices=ACCELERATION_SOURCES),
    Spec('use_curvature_preview', False, 'feed d rho/dt forward from the curvature '
         'preview (false: curvature at the CG only, as in the paper)'),
    Spec('align_inputs', 'with_prediction', 'when to read the yaw and velocity at the '
         "lateral error's stamp, between the samples around it (a lane camera late beside "
         'an IMU of now): while the law predicts its state from that stamp '
         '(lane_keeping.delay_prediction), always, or never (their newest samples)',
         choices=ALIGN_CHOICES),
    Spec('curvature_at_yaw_stamp', True, 'read a road_curvature polygon stamped before the '
         'yaw sample the law takes where the car was at its stamp, moved by v_x times the '
         "stamps' difference (a 10 Hz map beside a 100 Hz IMU is up to 100 ms behind it); "
         'false: as stamped. With law cg_compensated and lane_keeping.delay_prediction it '
         "is read at the lateral error's stamp instead, with align_inputs always as "
         'stamped; the sensor clocks must agree (docs/vehicle_bridge.md)'),
    Spec('autostart', True, 'configure and activate at start-up'),
    Spec('frame_id', 'base_link', "inputs in another frame are refused ('': any)"),
    Spec('watchdog_rate_hz', 20.0, 'stale-input check and safe-command rate [Hz]',
         1.0, 1000.0),
    Spec('diagnostics_rate_hz', 1.0, '/diagnostics rate [Hz]', 0.1, 100.0),
    EXECUTOR_SPEC,
)
ALL_SPECS = (VEHICLE_SPECS + (LAW_SPEC,) + CONTROLLER_SPECS + BASELINE_SPECS + SAFETY_SPECS
             + NODE_SPECS + LANE_KEEPING_SPECS)
# parameters on_configure reads (subscriptions, timers, clock): refused while configured
# (deactivate, clean up, set, configure again); and those read only at start-up
READ_ONLY_CONFIGURED = ('mode', 'rate_hz', 'qos_reliability', 'watchdog_rate_hz',
                        'diagnostics_rate_hz', 'use_sim_time')
READ_ONLY_STARTED = ('autostart', 'executor')
# /diagnostics WARNs when, since its last report, the controller answered this long while
# turning with no curvature or with a v_y of exactly 0 [s]
TURNING_WARN = 0.5
# /diagnostics WARNs when the sim clock has not moved for this long on the steady clock [s]
SIM_CLOCK_STOPPED = 0.5
MALFORMED = (ValueError, IndexError, TypeError, AttributeError, OverflowError, struct.error,
             UnicodeDecodeError)
DEBUG_FIELDS = ('d_v', 'd_v_rate', 'y_v', 'y_v_rate', 'y_ref', 'error', 'error_rate', 'f_v',
                'beta_1')


#: history of every publisher of the contract topics [messages]: the readers' QoS (keep
#: last 10) decides what a controller or an actuator gets; the writer's history decides
#: what a reader that fell behind (a recorder on a loaded machine) can still get. At 10 a
#: starved recorder lost 56 % of every contract topic of a lockstep run and none of the
#: ground truth (1000). History depth is no part of QoS matching.
WRITER_DEPTH = 1000


def writer_qos() -> QoSProfile:
    """
    Return the QoS of a contract topic's publisher: reliable, volatile, a deep history.

    :return: the profile (keep last :data:`WRITER_DEPTH`).
    """
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=WRITER_DEPTH,
                      durability=DurabilityPolicy.VOLATILE,
                      reliability=ReliabilityPolicy.RELIABLE)


def qos(reliability: str) -> QoSProfile:
    """
    Return the contract's QoS: keep last 10, volatile, reliable or best effort.

    :param reliability: ``reliable`` or ``best_effort``.
    :return: the profile.
    """
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                      durability=DurabilityPolicy.VOLATILE,
                      reliability=ReliabilityPolicy.RELIABLE if reliability == 'reliable'
                      else ReliabilityPolicy.BEST_EFFORT)


def applied_summary(law: str, controller: ControllerParams,
                    lane_keeping: LaneKeepingParams) -> str:
    """
    Return the log line of applied parameters, with the gains of the law that runs.

    With ``cg_compensated`` and a ``lane_keeping.low_speed_frequency`` above
    ``natural_frequency`` or a ``low_speed_integral_gain`` above ``integral_gain``
    (capped: w_n or ``k_i`` constant) also the w_n or ``k_i`` that runs, and with
    ``state_filter: none`` a force share that runs as 0 (:func:`settings_notes`).

    :param law: the running law.
    :param controller: the paper law's parameters (schedule, gains).
    :param lane_keeping: the default law's (its own gains, ``lane_keeping.*``).
    :return: the line.
    """
    gains: ControllerParams | LaneKeepingParams = (
        lane_keeping if law == 'cg_compensated' else controller)
    note = settings_notes(law, lane_keeping)
    return (f'parameters applied: law={law}, schedule={controller.schedule}, '
            f'w_n={gains.natural_frequency:g}, zeta={gains.damping_ratio:g}'
            + (f'; {note}' if note else ''))


def settings_notes(law: str, lane_keeping: LaneKeepingParams) -> str:
    """
    Return what runs otherwise than set ('' if everything runs as set).

    A capped low-speed w_n or integral gain, a force share without the state filter, and
    ``filter_*`` settings that act only on the curvature estimate without it.

    :param law: the running law (only ``cg_compensated`` has these settings).
    :param lane_keeping: its settings.
    :return: the notes, joined by ``'; '``.
    """
    if law != 'cg_compensated':
        return ''
    return '; '.join(n for n in (frequency_schedule_note(lane_keeping),
                                 integral_schedule_note(lane_keeping),
                                 filterless_note(lane_keeping),
                                 curvature_filter_note(lane_keeping)) if n)


def core_from_params(params: Mapping[str, Any]) -> SteeringController:
    """
    Return the controller core the node runs with these parameters.

    :param params: every parameter of :data:`ALL_SPECS` by name (checked values).
    :return: the core (its law built: the law's own checks have run).
    :raises ParameterError: a value or combination the core or its law refuses.
    """
    vehicle, controller = vehicle_and_controller(params)
    return SteeringController(vehicle, controller, params['acceleration_source'],
                              params['use_curvature_preview'], safety_params(params),
                              params['law'], baseline_params(params),
                              lane_keeping_params(params), params['align_inputs'],
                              params['curvature_at_yaw_stamp'])


def check_parameters(params: Mapping[str, Any]) -> None:
    """
    Refuse parameters the node would not start with (its on-set check, at start-up).

    :param params: every parameter of :data:`ALL_SPECS` by name (checked values).
    :raises ParameterError: a value or combination the core or its law refuses.
    :raises ValueError: a string parameter that is not one of its choices.
    """
    check_choices(ALL_SPECS, params)
    core_from_params(params)


class ControllerNode(LifecycleNode):
    """Lifecycle node publishing the variable look-ahead steering command."""

    def __init__(self, **kwargs: Any) -> None:
        """
        Declare parameters; communication is set up in ``on_configure``.

        :param kwargs: passed to ``LifecycleNode`` (context, parameter_overrides, ...).
        """
        super().__init__('controller', **kwargs)
        build_or_destroy(self._build, super().destroy_node)

    def _build(self) -> None:
        """Declare parameters, build the core and the counters."""
        declare(self, ALL_SPECS)
        self.core = core_from_params(values(self, ALL_SPECS))
        self.counters = {'saturated': 0, 'rate_limited': 0, 'low_speed': 0,
                         'd_v_clamped': 0, 'stale_commands': 0, 'demand_capped': 0,
                         'approach_clipped': 0}
        self._reported: dict[str, int] = {}
        self._reported_taken: dict[str, tuple[int, int]] = {}
        self._reported_turning: dict[str, float] = {}
        # the sim clock as last seen by a report, and the steady clock when it last moved
        self._sim_seen: tuple[Optional[int], int] = (None, 0)
        self.stale_inputs: list[str] = []
        self.curvature_lost = False
        self._watchdog: Any = None
        self._diag_timer: Any = None
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self._input_subs: list[Any] = []
        self._timer: Any = None
        self._sync_timer: Any = None
        self._pending_stamp: Optional[int] = None
        #: whether a command answered the lateral error last taken, and how many exact
        #: repeats of it came since (a repeat of one never answered is answered: a
        #: lockstep step 0 taken while inactive; ~/debug ``copies``)
        self._answered = False
        self._copies = 0
        self._steering_pub: Any = None
        self._debug_pub: Any = None
        self._jump_handle: Any = None
        self.configured = False
        self.active = False
        self.published = 0
        #: parameter sets applied at run time (each a /parameter_events message)
        self.parameter_sets = 0
        #: activations since start, and the law's answers (~/debug: the offline re-run
        #: skips what the node received while inactive, as the node did, and tells an
        #: answer the recorder lost from one never given)
        self.activations = 0
        self.answers = 0
        self._last_publish: Optional[int] = None
        self._refusal_log = Throttle(1.0)
        self._pacer = AnswerPacer(self.param('max_answer_rate_hz'))
        self._answer_timer: Any = None
        self._cache_input_parameters()
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._parameters_set)

    # -- parameters -----------------------------------------------------------------

    def _validate_parameters(self, params: list[Parameter]) -> SetParametersResult:
        for param in params:
            if param.name in READ_ONLY_STARTED:
                return SetParametersResult(successful=False, reason=(
                    f'{param.name}: read only at start-up; pass it with -p or a params file'))
            if param.name in READ_ONLY_CONFIGURED and self.configured:
                return SetParametersResult(successful=False, reason=(
                    f'{param.name}: read-only while the node is configured; deactivate, '
                    'clean up, set it, configure again'))
        try:
            merged = values(self, ALL_SPECS, params)
            check_choices(ALL_SPECS, merged)
            vehicle, controller = vehicle_and_controller(merged)
            safety_params(merged)
            baselines = baseline_params(merged)
            lane_keeping = lane_keeping_params(merged)
            # the law the set selects is built here, so that what the node then builds
            # cannot fail (its own checks across parameters, controller.reference; the
            # LQR's Riccati equation: dev-probe71, lqr.r 1e-6 with q_lateral 1e6 at
            # period 1 s was accepted and crashed the node building it)
            build_law(merged['law'], vehicle, controller, baselines, lane_keeping)
            if merged['law'] != 'lqr' and any(p.name.startswith('lqr.') for p in params):
                # weights set for later: refused now, not when law lqr is selected
                build_law('lqr', vehicle, controller, baselines, lane_keeping)
        except (ParameterError, ValueError) as err:
            return SetParametersResult(successful=False, reason=str(err))
        return SetParametersResult(successful=True)

    def _parameters_set(self, params: list[Parameter]) -> None:
        # applied at once (callbacks of a node run one at a time): a new input_timeout
        # or rate limit counts for the watchdog too, not only from the next answer on
        self._cache_input_parameters()
        self._apply_parameters()
        # one set applied (one /parameter_events message): ~/debug parameter_sets tells
        # the offline re-run the first answer computed after it
        self.parameter_sets += 1
        if self.core.retune is not None:
            carried, restarted = self.core.retune
            self.get_logger().info(
                f'{self.core.law_name} retuned without a restart: carried '
                f'{", ".join(carried) or "nothing"}'
                + (f'; restarted {", ".join(restarted)}' if restarted else ''))

    def _cache_input_parameters(self) -> None:
        # read on every message: plain attributes, not a parameter lookup each time
        self._frame = self.param('frame_id')
        self._mode = self.param('mode')
        self._wait_for_stamps = self.param('wait_for_matching_stamps')
        self._sync_timeout = self.param('sync_timeout')
        self._pacer.set_rate(self.param('max_answer_rate_hz'))
        if self._pacer.deferred and self._answer_timer is not None:
            # a new bound counts for the answer already waiting, not after it
            self._arm_answer(self._pacer.wait(time.monotonic_ns()))

    def _apply_parameters(self) -> None:
        params = values(self, ALL_SPECS)
        vehicle, controller = vehicle_and_controller(params)
        lane_keeping = lane_keeping_params(params)
        self.core.configure(vehicle, controller, params['acceleration_source'],
                            params['use_curvature_preview'], safety_params(params),
                            params['law'], baseline_params(params), lane_keeping,
                            params['align_inputs'], params['curvature_at_yaw_stamp'])
        self.get_logger().info(applied_summary(params['law'], controller, lane_keeping))

    def param(self, name: str) -> Any:
        """
        Return a parameter's value.

        :param name: the parameter.
        :return: its value.
        """
        return self.get_parameter(name).value

    # -- lifecycle ------------------------------------------------------------------

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Create publishers, subscriptions and (timer mode) the timer."""
        profile = qos(self.param('qos_reliability'))
        self._steering_pub = self.create_lifecycle_publisher(JointState, 'steering',
                                                             writer_qos())
        self._debug_pub = self.create_lifecycle_publisher(JointState, '~/debug',
                                                          writer_qos())
        subs: list[tuple[type, str, Callable[[Any], None], bool]] = [
            (PointStamped, 'lateral_error', self.on_lateral_error, False),
            (Imu, 'yaw', self.on_yaw, False),
            (TwistStamped, 'velocity', self.on_velocity, False),
            # raw: a polygon's length is checked before its points are decoded
            (PolygonStamped, 'road_curvature', self.on_curvature, True),
        ]
        self._input_subs = [self.create_subscription(t, n, cb, profile, raw=raw)
                            for t, n, cb, raw in subs]
        if self.param('mode') == 'timer':
            self._timer = self.create_timer(1.0 / self.param('rate_hz'), self.on_timer)
        else:
            # the answer-rate bound's deferred answer (armed by _answer)
            self._answer_timer = self.create_timer(
                1.0, self._answer_due, clock=Clock(clock_type=ClockType.STEADY_TIME),
                autostart=False)
        self._watchdog = self.create_timer(1.0 / self.param('watchdog_rate_hz'),
                                           self.on_watchdog)
        self._diag_timer = self.create_timer(1.0 / self.param('diagnostics_rate_hz'),
                                             self.on_diagnostics,
                                             clock=Clock(clock_type=ClockType.STEADY_TIME))
        # a sim-time clock update may release an answer waiting for it (lockstep); run
        # in the /clock callback, after the clock is set (the EventsExecutor has no
        # guard conditions to defer it with)
        self._jump_handle = self.get_clock().create_jump_callback(
            JumpThreshold(min_forward=Duration(nanoseconds=1), min_backward=None,
                          on_clock_change=False),
            post_callback=lambda jump: self._maybe_release())
        self.configured = True
        # a capped low-speed w_n or k_i, a force share without the filter, are told at
        # startup too (dev-probe33: only a run-time change said so, and a file lowering
        # natural_frequency alone ran silently)
        notes = settings_notes(self.core.law_name, self.core.lane_keeping)
        self.get_logger().info(
            f'configured: mode={self.param("mode")}, law={self.core.law_name}, schedule='
            f'{self.core.params.schedule}, inputs {self.param("qos_reliability")}'
            + (f'; {notes}' if notes else ''))
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Start publishing; a yaw rate refused for its sign is judged afresh."""
        self.active = True
        self.core.clear_yaw_fault()     # deactivate, fix the bridge, activate
        self.activations += 1
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop publishing."""
        self.active = False
        # a deferred answer is not given after an activation (dev-probe74: 0.5-0.9 s
        # late at a 1 Hz bound)
        if self._answer_timer is not None:
            self._answer_timer.cancel()
        self._pacer.cancel()
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Destroy what ``on_configure`` created."""
        for sub in self._input_subs:
            self.destroy_subscription(sub)
        self._input_subs = []
        for timer in (self._timer, self._sync_timer, self._watchdog, self._diag_timer,
                      self._answer_timer):
            if timer is not None:
                self.destroy_timer(timer)
        self._timer = self._sync_timer = self._watchdog = self._diag_timer = None
        self._answer_timer = None
        self._pacer.cancel()
        for pub in (self._steering_pub, self._debug_pub):
            if pub is not None:
                self.destroy_publisher(pub)
        self._steering_pub = self._debug_pub = None
        if self._jump_handle is not None:
            self._jump_handle.unregister()
            self._jump_handle = None
        self._pending_stamp = None
        self.configured = False
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Shut down from any state."""
        self.active = False
        return TransitionCallbackReturn.SUCCESS

    # -- time -----------------------------------------------------------------------

    def clocks(self) -> tuple[int, Optional[int]]:
        """
        Return the node's clock and, on the wall clock, the steady clock [ns].

        The node's clock judges stamps and staleness and times the rate limit; on the
        wall clock the steady clock also bounds the rate limit's time, so a step of the
        system clock cannot open it. Under sim time the steady clock has no part.

        :return: ``(now, steady)``; ``steady`` is None under sim time.
        """
        now = now_ns(self)
        return now, None if self.sim_time() else time.monotonic_ns()

    def sim_time(self) -> bool:
        """Return True while the node's clock is sim time (``/clock``)."""
        clock = self.get_clock()
        return isinstance(clock, ROSClock) and clock.ros_time_is_active

    # -- inputs ---------------------------------------------------------------------

    def _input(self, name: str, msg: Any, parse: Callable[[Any], Any]) -> bool:
        """
        Check and store one input; a refused message is counted and never used.

        :param name: the input.
        :param msg: the message.
        :param parse: its converter.
        :return: whether it was accepted.
        """
        frame = self._frame
        if frame and msg.header.frame_id != frame:
            reason = f'{name}: frame {msg.header.frame_id!r} is not {frame!r}'
            self.core.count_rejection(reason)
        else:
            try:
                sample = parse(msg)
            except MALFORMED as err:
                reason = f'{name}: malformed message ({err})'
                self.core.count_rejection(reason)
            else:
                refused = self._accept(name, sample)
                if refused is None:
                    return True
                reason = refused
        self._log_refusal(reason)
        return False

    def _accept(self, name: str, sample: Any) -> Optional[str]:
        # the core checks the values and stamps (against the node's clock; sim time
        # before the first /clock reads 0: not against it), and counts what it refuses
        return self.core.accept(name, sample, now_ns(self))

    def _echoes(self) -> dict[str, tuple[int, int]]:
        """
        Return the inputs most of whose messages came again since the last report.

        :return: input -> (messages taken that came again, messages taken), where the
            first is at least 2 and at least half the second.
        """
        out = {}
        for name, taken in self.core.taken.items():
            again = self.core.duplicated.get(name, 0)
            seen_again, seen_taken = self._reported_taken.get(name, (0, 0))
            self._reported_taken[name] = (again, taken)
            k, n = again - seen_again, taken - seen_taken
            if k >= 2 and 2 * k >= n:
                out[name] = (k, n)
        return out

    def _log_refusal(self, reason: str) -> None:
        if is_duplicate(reason):
            # counted and told at OK (a lockstep step 0 again), not logged: it would also
            # take the throttle's one line from a refusal (dev-probe112: every run through
            # path_bridge logged 'refused road_curvature: repeats ...')
            return
        if self._refusal_log.ready():
            self.get_logger().warn(f'refused {reason}')

    def on_lateral_error(self, msg: PointStamped) -> None:
        """Store the lateral error; in event mode, answer it (or a repeat never answered)."""
        if self._input('lateral_error', msg, conv.from_lateral_error):
            self._answered, self._copies = False, 0
        elif is_duplicate(self.core.refusals.get('lateral_error', '')):
            self._copies += 1
            if not self._unanswered_repeat():
                return
        else:
            return
        if self._mode != 'event':
            return
        stamp = self.core.lateral.stamp_ns if self.core.lateral else 0
        if self._wait_for_stamps and not self._caught_up(stamp):
            self._pending_stamp = stamp
            self._arm_sync_timer()
            return
        self._answer()

    def _unanswered_repeat(self) -> bool:
        """
        Return whether to answer the repeat of the last lateral error just received.

        A lockstep simulator sends step 0 again until it is answered: a node activated
        after the simulator started took it in while inactive, or could not answer it
        (its yaw not in yet), and left the simulator to its deadline (dev-probe113: 5 s
        through a bridge, one missed deadline). An answer already given is not given
        again (a publisher stuck on its last message, an echo), nor one still waiting
        (the answer-rate bound, matching stamps), nor one to a lateral error that went
        stale (dev-probe116: a safe command stamped on the clock for every copy).
        """
        return (not self._answered and self._pending_stamp is None
                and not self._pacer.deferred
                and 'lateral_error' not in self.core.stale(self.clocks()[0]))

    def _answer(self) -> None:
        """
        Answer the newest lateral error now, or at the end of the answer-rate period.

        Event mode on the wall clock (:mod:`lookahead_control.core.answer_rate`); under
        sim time, and while inactive, at once as before.
        """
        if not self.active or self.sim_time():
            self.step()
            return
        wait = self._pacer.arrived(time.monotonic_ns())
        if wait is None:
            self.step()
        elif wait > 0:
            self._arm_answer(wait)

    def _arm_answer(self, wait: int) -> None:
        # one timer, armed again per deferral (a timer made and destroyed per deferral
        # is a wait set rebuilt each time, in a flood)
        if self._answer_timer is not None:
            self._answer_timer.timer_period_ns = max(1, wait)
            self._answer_timer.reset()

    def _answer_due(self) -> None:
        if self._answer_timer is not None:
            self._answer_timer.cancel()
        if not self._pacer.deferred:
            return
        if self._pending_stamp is not None:
            # a newer lateral error waits for its matching stamps and is answered when
            # they are in (dev-probe74: answered here with the previous step's yaw and
            # velocity, then again at its release)
            self._pacer.drop()
            return
        self._pacer.due(time.monotonic_ns())
        self.step()

    def _caught_up(self, stamp: int) -> bool:
        """
        Return True when the other inputs, and a sim-time clock, reached ``stamp``.

        Lockstep: the simulator publishes a step's measurements, then ``/clock``, and
        waits for the answer; answering once the clock reads the step's time makes the
        rate limit's time (the node's clock) the simulator's step.

        :param stamp: the lateral error's stamp [ns].
        :return: whether to answer now.
        """
        if not self.core.inputs_at(stamp):
            return False
        return not self.sim_time() or now_ns(self) >= stamp

    def _arm_sync_timer(self) -> None:
        if self._sync_timer is not None:
            self.destroy_timer(self._sync_timer)
        self._sync_timer = self.create_timer(self._sync_timeout, self._sync_expired,
                                             clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _sync_expired(self) -> None:
        if self._sync_timer is not None:
            self.destroy_timer(self._sync_timer)
            self._sync_timer = None
        if self._pending_stamp is not None:
            self._pending_stamp = None
            self._answer()

    def _maybe_release(self) -> None:
        if self._pending_stamp is not None and self._caught_up(self._pending_stamp):
            self._pending_stamp = None
            if self._sync_timer is not None:
                self.destroy_timer(self._sync_timer)
                self._sync_timer = None
            self._answer()

    def on_yaw(self, msg: Imu) -> None:
        """Store the relative yaw, yaw rate and body acceleration."""
        if self._input('yaw', msg, conv.from_yaw):
            self._maybe_release()

    def on_velocity(self, msg: TwistStamped) -> None:
        """Store the velocity."""
        if self._input('velocity', msg, conv.from_velocity):
            self._maybe_release()

    def on_curvature(self, msg: Any) -> None:
        """
        Store the road curvature.

        :param msg: the serialized ``PolygonStamped`` (a raw subscription), or the
            message itself (tests).
        """
        data = msg if isinstance(msg, bytes) else serialize_message(msg)
        name = 'road_curvature'
        try:
            stamp, frame, count, at, order = conv.curvature_header(data)
        except MALFORMED as err:
            reason: Optional[str] = f'{name}: malformed message ({err})'
            self.core.count_rejection(str(reason))
        else:
            reason = (f'{name}: frame {frame!r} is not {self._frame!r}'
                      if self._frame and frame != self._frame else
                      check_points(count, self.core.safety))
            if reason is not None:
                self.core.count_rejection(reason)
            else:
                try:
                    sample = curvature_from_points(
                        stamp, conv.curvature_points(data, count, at, order))
                except MALFORMED as err:
                    reason = f'{name}: malformed message ({err})'
                    self.core.count_rejection(reason)
                else:
                    reason = self._accept(name, sample)
        if reason is None:
            self._maybe_release()
        else:
            self._log_refusal(reason)

    def on_timer(self) -> None:
        """Timer mode: one command from the latest inputs (the safe one if stale)."""
        self.step()

    def on_watchdog(self) -> None:
        """
        Judge the inputs; publish the safe command while stale and nothing else does.

        In event mode a stale yaw or velocity is answered with the safe command at each
        lateral error (so a lockstep simulator sees the ramp); the watchdog publishes it
        when no command went out for one watchdog period (the lateral error is dead).
        """
        now, steady = self.clocks()
        self._judge_inputs(now)
        if not self.stale_inputs or not self.active:
            return
        period = int(1e9 / self.param('watchdog_rate_hz'))
        if self._last_publish is not None and 0 <= now - self._last_publish < period:
            return
        command = self.core.safe_command(now, steady)
        if command is not None:
            self._publish(command, now)

    def _judge_inputs(self, now: int) -> None:
        """Update the stale inputs and the lost curvature; log and report changes."""
        stale = self.core.stale(now)
        lost = self.core.curvature_lost(now)
        if stale and stale != self.stale_inputs:
            self.get_logger().error(f'stale inputs: {self.core.describe_stale(stale)}: '
                                    'holding, then ramping to the safe angle')
        elif self.stale_inputs and not stale:
            self.get_logger().info('inputs are back: control resumes')
        if lost and not self.curvature_lost:
            self.get_logger().warn('road_curvature lost: '
                                   f'{self.core.describe_stale(["road_curvature"])}: '
                                   + ('steering on the estimated curvature'
                                      if self._estimates_curvature()
                                      else 'steering without curvature feed-forward'))
        elif self.curvature_lost and not lost:
            self.get_logger().info('road_curvature is back')
        changed = stale != self.stale_inputs or lost != self.curvature_lost
        self.stale_inputs, self.curvature_lost = stale, lost
        if changed:
            self.on_diagnostics()       # ERROR (and its end) at once, not at the next 1 Hz

    # -- output ---------------------------------------------------------------------

    def step(self) -> Optional[Command]:
        """
        Compute and publish one command (nothing while inactive or inputs are missing).

        The law's answer if every required input is fresh, else the safe command.

        :return: the command, or None.
        """
        if not self.active:
            return None
        now, steady = self.clocks()
        command = self.core.compute(now, steady)
        if command is None:
            return None
        if command.status == 'stale' or self.stale_inputs:
            self._judge_inputs(now)
        self._publish(command, now)
        return command

    def _publish(self, command: Command, now: Optional[int] = None) -> None:
        self._steering_pub.publish(conv.to_steering(command.stamp_ns, command.steering,
                                                    command.steering_rate))
        self.published += 1
        self._last_publish = now
        if self.core.lateral is not None and command.stamp_ns == self.core.lateral.stamp_ns:
            self._answered = True
        for flag in ('saturated', 'rate_limited'):
            self.counters[flag] += int(getattr(command, flag))
        self.counters['low_speed'] += int(command.status == 'low_speed')
        self.counters['stale_commands'] += int(command.status == 'stale')
        law = command.law
        if law is None:
            return
        self.answers += 1
        if self.core.law_name == 'paper':
            self.counters['d_v_clamped'] += int(float(law.d_v) >= self.core.params.max_look_ahead)
        # the law's own clips (cg_compensated): counted, told, not warned (they are its
        # design: docs/lane_keeping.md)
        for flag, name in (('demand_capped', 'capped'), ('approach_clipped', 'clipped')):
            self.counters[flag] += int(bool(getattr(self.core.law, name, False)))
        if self._debug_pub.get_subscription_count() == 0:
            return                  # nobody listens: do not build the debug message
        mode = self.core.params.schedule
        debug = [(name, float(getattr(law, name))) for name in DEBUG_FIELDS]
        debug.append((f'schedule:{mode}', float(SCHEDULE_MODES.index(mode))))
        debug.append((f'law:{self.core.law_name}', float(LAW_NAMES.index(self.core.law_name))))
        # any law: whether it had the curvature (judged on this node's clock, which no
        # stamp holds: the offline re-run takes it)
        debug.append(('curvature_received', float(self.core.curvature_in)))
        # the parameter sets applied before this answer (the re-run applies the recorded
        # /parameter_events at the answer where this count reaches them)
        debug.append(('parameter_sets', float(self.parameter_sets)))
        # the activations before this answer: inputs left unanswered between two answers
        # of different counts came while the node was inactive (the re-run skips them)
        debug.append(('activations', float(self.activations)))
        debug.append(('answers', float(self.answers)))
        # lateral errors left unanswered for a newer one (the answer-rate bound): the
        # re-run skips those between two answers whose counts differ
        debug.append(('coalesced', float(self._pacer.coalesced)))
        # the exact repeats of the answered lateral error that came before its answer
        # (0: answered on its first arrival): the re-run answers at that copy too
        debug.append(('copies', float(self._copies)))
        state = getattr(self.core.law, 'debug_values', None)
        if state is not None:       # a law with a state: cg_compensated (its estimate ...)
            debug += state()
        self._debug_pub.publish(conv.to_named_values(command.stamp_ns, debug))

    def _estimates_curvature(self) -> bool:
        """Return whether the running law estimates a curvature that is not received."""
        return self.core.law_name == 'cg_compensated'

    def diagnostics(self) -> DiagnosticStatus:
        """
        Return the controller's status for ``/diagnostics``.

        ERROR on stale inputs (named, with why their last message was refused); WARN on
        a lost curvature, refused messages, saturation, low-speed hand-over, clamped
        d_v, time jumps or law restarts since the last report (the law's own clips since
        then, the demand band and the approach clip, are told at OK), a sim clock that has
        not moved for :data:`SIM_CLOCK_STOPPED` (``use_sim_time``), answers while turning
        without a curvature or with a ``v_y`` of exactly 0 (:data:`TURNING_WARN`), a
        lateral error moving against the relative yaw (``core/heading_check.py``), a yaw
        rate hardly varying (``core/yaw_check.py``), a speed out of scale with the
        curvature preview (``core/speed_check.py``), a curvature read ahead of or behind
        the car's yaw measurements (``core/map_timing_check.py``: sensor clocks that
        disagree), or an input age or answer latency above ``safety.latency_warn``; else
        OK.

        :return: the status with its reasons and counters.
        """
        causes = {f'law_restarts_{k}': v for k, v in self.core.law_restart_causes.items()}
        counts = {**self.counters, 'rejected': sum(self.core.rejected.values()),
                  'duplicates': sum(self.core.duplicates.values()),
                  'time_jumps': self.core.time_jumps, 'law_restarts': self.core.law_restarts,
                  'coalesced': self._pacer.coalesced, **causes}
        new = {k: v - self._reported.get(k, 0) for k, v in counts.items()}
        self._reported = counts
        echoes = self._echoes()
        ages, latency = self.core.timing.take()
        warn_at = self.core.safety.latency_warn
        reasons = []
        level = DiagnosticStatus.OK
        if self.stale_inputs:
            level = DiagnosticStatus.ERROR
            reasons.append('stale inputs: ' + self.core.describe_stale(self.stale_inputs))
        if not self.active:
            reasons.append('inactive')
        estimates = self._estimates_curvature()
        if self.curvature_lost:
            level = max(level, DiagnosticStatus.WARN)
            reasons.append('road_curvature lost: ' + (
                'the curvature is estimated by law cg_compensated'
                if estimates else 'no curvature feed-forward'))
        for key in ('rejected', 'saturated', 'rate_limited', 'low_speed', 'd_v_clamped',
                    'time_jumps', 'law_restarts'):
            if new[key] > 0:
                level = max(level, DiagnosticStatus.WARN)
                text = f'{key.replace("_", " ")}: {new[key]}'
                if key == 'rejected':
                    text += f' (last: {self.core.last_rejection})'
                elif key == 'low_speed' and self.core.low_speed_v_x is not None:
                    # a car reversing was only 'low speed' (dev-probe55); the speed of the
                    # last answer held, not of the newest velocity (dev-probe90)
                    v_x = self.core.low_speed_v_x
                    text += (f' (v_x {v_x:.3g} m/s, below safety.low_speed '
                             f'{self.core.safety.low_speed:g}: holding the command'
                             + ('; reversing: the laws steer forward driving only'
                                if v_x < 0.0 else '') + ')')
                elif key == 'law_restarts':
                    why = {'gap': 'lateral errors further apart than lane_keeping.max_gap '
                                  f'{self.core.lane_keeping.max_gap:g} s',
                           'non_finite': 'a non-finite law output'}
                    each = [f'{why.get(cause, cause)}: {new[f"law_restarts_{cause}"]}'
                            for cause in self.core.law_restart_causes
                            if new[f'law_restarts_{cause}'] > 0]
                    text += f' ({"; ".join(each)}; integral and estimate start again)'
                reasons.append(text)
        if new['coalesced'] > 0:
            level = max(level, DiagnosticStatus.WARN)
            reasons.append(f'coalesced: {new["coalesced"]} lateral errors came faster than '
                           f'max_answer_rate_hz {self.param("max_answer_rate_hz"):g}: the '
                           'newest of each period answered (a flood, or a faster sensor: '
                           'raise the bound)')
        if new['duplicates'] > 0:
            so_far = ', '.join(f'{k} {v}' for k, v in self.core.duplicates.items())
            reasons.append(f'duplicates: {new["duplicates"]} messages repeated the last one '
                           f'taken of their input, same stamp and values as read, not used '
                           f'(so far: {so_far})')
        if echoes:
            # most messages of an input came twice or more: two publishers of one topic,
            # a bridge that loops its output back (dev-probe112: a threefold echo read
            # OK); a lockstep start's step 0, sent until answered, is one message
            level = max(level, DiagnosticStatus.WARN)
            echoed = ', '.join(f'{name} {k} of {n}' for name, (k, n) in echoes.items())
            reasons.append(f'echo: messages taken that came again since the last report '
                           f'({echoed}): two publishers of one topic, a bridge that sends its '
                           'output back, or a driver that sends each sample more than once')
        for key, setting in (('demand_capped', 'lane_keeping.demand_limit'),
                             ('approach_clipped', 'lane_keeping.approach_heading')):
            if new[key] > 0:
                reasons.append(f'{key.replace("_", " ")}: {new[key]} ({setting})')
        # under sim time a dead simulator stops the clock: nothing goes stale on it
        sim_ns = now_ns(self) if self.sim_time() else None
        steady = time.monotonic_ns()
        if sim_ns != self._sim_seen[0]:
            self._sim_seen = (sim_ns, steady)
        stopped = (steady - self._sim_seen[1]) * 1e-9
        # a clock reading 0 is one not started, or a simulator's /clock at 0 (a lockstep
        # sim waiting at its start): only a /clock publisher tells them apart
        at_zero = sim_ns == 0 and self.core.lateral is not None
        no_clock = at_zero and self.count_publishers('/clock') == 0
        if self.active and stopped >= SIM_CLOCK_STOPPED and no_clock:
            # dev-probe71: use_sim_time without a /clock: inputs were answered, the rate
            # limit's time never ran (the command froze), dead inputs never went stale,
            # and /diagnostics said ok throughout
            level = max(level, DiagnosticStatus.ERROR)
            reasons.append(f'use_sim_time and no /clock: the sim clock reads 0 for '
                           f'{stopped:.1f} s (wall) while inputs arrive: no input is judged '
                           "stale and the rate limit's time does not run (publish /clock, or "
                           'use_sim_time false)')
        elif self.active and sim_ns is not None and (sim_ns > 0 or at_zero) and \
                stopped >= SIM_CLOCK_STOPPED:
            # (at 0 with inputs: dev-probe72, a /clock held at 0 was taken for none)
            level = max(level, DiagnosticStatus.WARN)
            reasons.append(f'sim clock stopped at {sim_ns * 1e-9:.3f} s for {stopped:.1f} s '
                           '(wall): nothing is judged stale on it (use_sim_time; the '
                           'simulator or /clock gone?)')
        turning = {k: v - self._reported_turning.get(k, 0.0)
                   for k, v in self.core.turning.items()}
        self._reported_turning = dict(self.core.turning)
        if turning['turning_without_curvature'] >= TURNING_WARN:
            level = max(level, DiagnosticStatus.WARN)
            what = ('the curvature is estimated from the yaw rate and the relative yaw by law '
                    'cg_compensated (R 400 m at 37 m/s: about 30 cm peak)'
                    if estimates else
                    f'law {self.core.law_name} takes the road as straight (R 400 m at 37 '
                    'm/s: the CG settles metres outside the curve; law cg_compensated '
                    'estimates the curvature)')
            reasons.append(f'turning without road_curvature for '
                           f'{turning["turning_without_curvature"]:.2f} s: {what} '
                           '(docs/vehicle_bridge.md)')
        if turning['v_y_exactly_zero'] >= TURNING_WARN:
            level = max(level, DiagnosticStatus.WARN)
            # what the running law does with it (a law without a state filter believes it)
            if getattr(self.core.law, 'state_filter', None) is not None:
                what = ("taken as not measured by law cg_compensated's state filter (it "
                        'estimates v_y: about 2 times the CG error)')
            else:
                what = (f'law {self.core.law_name} takes the 0 as measured (S2 at 37 m/s: '
                        '85 cm and more; law cg_compensated with lane_keeping.state_filter '
                        'kalman estimates v_y)')
            reasons.append(f'velocity v_y exactly 0 while turning for '
                           f'{turning["v_y_exactly_zero"]:.2f} s: {what} '
                           '(docs/vehicle_bridge.md)')
        residual, self.core.map_residual = self.core.map_residual, 0.0
        # any drop is told (dev-probe76: a drop after 0.3 s of disagreement was not)
        if turning['curvature_disagrees'] >= TURNING_WARN or turning['curvature_dropped'] > 0:
            # dev-probe73: a map 20 % off, or 0.5 s ahead or behind, put the default law's
            # CG 0.7-1 m off an S-bend at 30 m/s, worse than no map, and nothing said so
            level = max(level, DiagnosticStatus.WARN)
            fallback = getattr(getattr(self.core.law, 'settings', None), 'map_fallback', 0.0)
            if turning['curvature_dropped'] > 0.0:
                acted = (f'The law {self.core.law_name} dropped the curvature for '
                         f'{turning["curvature_dropped"]:.2f} s and ran on its own estimate '
                         f'(lane_keeping.map_fallback {fallback:g} x the threshold)')
            else:
                acted = (f'The law {self.core.law_name} takes the curvature as the truth' + (
                    f' below lane_keeping.map_fallback {fallback:g} x the threshold'
                    if fallback > 0.0 else ''))
            reasons.append(f'road_curvature disagrees with the yaw rate for '
                           f'{turning["curvature_disagrees"]:.2f} s (relative yaw '
                           f'{residual * 1e3:+.1f} mrad off what the curvature and the yaw rate '
                           'predict, over the threshold of '
                           f'{self.core.map_check.settings.threshold * 1e3:g} mrad at 20 m/s '
                           'and up): one of the three is off: the curvature (a map off in '
                           'scale or position; or v_x, which it is multiplied by: a speed '
                           'in km/h), the yaw rate (a gyro bias: 0.3 deg/s is 10 '
                           f'mrad), or the relative yaw (a jump, a relocalization). {acted} '
                           '(docs/safety.md)')
        seen, self.core.map_lead_seen = self.core.map_lead_seen, None
        if turning['curvature_early_or_late'] >= TURNING_WARN and seen is not None:
            # dev-probe125: an IMU clock 50 / 90 ms ahead of the map's read every curve
            # 1.9 / 3.3 m early at 37 m/s (S3 2.7 -> 17.0 / 31.1 cm), within every stamp
            # check and under the map check's threshold, and nothing said so
            level = max(level, DiagnosticStatus.WARN)
            lead, v_x = seen
            ahead = lead > 0.0
            # (behind: a polygon newer than the yaw sample is read as it is, so the lag
            # stops at about the map's age; the clock may be further behind: dev-probe126)
            clock = ('ahead of the map' + "'s by about that" if ahead else
                     'behind the map' + "'s by that or more (a polygon newer than the yaw is "
                     "read as it is: the lag stops at the map's age)")
            reasons.append(f'road_curvature read {abs(lead):.2f} m '
                           f'{"ahead of" if ahead else "behind"} the car'
                           + (f', {abs(lead) / v_x * 1e3:.0f} ms at {v_x:.3g} m/s'
                              if v_x >= 1.0 else '') + ', for '
                           f'{turning["curvature_early_or_late"]:.2f} s (fitted over the curve '
                           'entries and exits: the relative yaw against the yaw rate and the '
                           f'curvature read): the IMU stamped on a clock {clock} (stamp every '
                           'input on one synchronized clock, at its capture), the map placed '
                           'off along the road, or a polygon too coarse for the curvature'
                           + "'s changes" + ('' if self.core.curvature_at_yaw_stamp else
                                             ' (curvature_at_yaw_stamp false: a polygon is '
                                             'read as stamped, up to a map period late)')
                           + f'. Every law turns in that much {"early" if ahead else "late"} '
                           '(docs/vehicle_bridge.md)')
        swing, self.core.oscillation_seen = self.core.oscillation_seen, (0.0, 0.0)
        if turning['steering_oscillates'] >= TURNING_WARN:
            # dev-probe73: from about 90 ms of actuator delay the default law's steering
            # swings +-56 mrad at 1.5 Hz at 37 m/s, the CG within 1.1 cm: nothing told it
            level = max(level, DiagnosticStatus.WARN)
            reasons.append(f'steering oscillates for {turning["steering_oscillates"]:.2f} s '
                           f'(+-{swing[0] * 1e3:.0f} mrad at {swing[1]:.2f} Hz): an actuator '
                           "delay beyond the law's margin (about 90 ms for cg_compensated: "
                           'set lane_keeping.delay_prediction with filter_delay at the '
                           "car's delay), a road that swings that fast, or the law ringing "
                           'after a jump of its inputs (docs/safety.md)')
        lowest, self.core.heading_seen = self.core.heading_seen, 1.0
        if turning['heading_disagrees'] > 0.0:
            # dev-sc45: a relative yaw or a lateral error of the wrong sign steered every
            # law out of the lane, told only once the lateral error was past 5 m
            level = max(level, DiagnosticStatus.WARN)
            reasons.append(f'lateral_error moves against relative_yaw for '
                           f'{turning["heading_disagrees"]:.2f} s (correlation down to '
                           f'{lowest:.2f} with the motion the relative yaw and v_y '
                           'predict): the sign of relative_yaw or of '
                           'lateral_error wrong, or the two measured from different '
                           'references (a lane change along a shifted path), or a bias in '
                           'relative_yaw or v_y (docs/safety.md)')
        stillness, self.core.still_seen = self.core.still_seen, 0.0
        if turning['yaw_rate_still'] > 0.0:
            # dev-sc46: a yaw rate frozen (or 10 times too small) put the default law's CG
            # up to 2 m off S-bends at 30-37 m/s, and nothing said so
            level = max(level, DiagnosticStatus.WARN)
            how = ('it does not vary at all' if math.isinf(stillness) else
                   f'they vary {stillness:.3g} times as much as it does')
            reasons.append(f'yaw_rate hardly varies while the steering and the relative yaw '
                           f'do, for {turning["yaw_rate_still"]:.2f} s ({how}): frozen (a '
                           'bridge repeating its last value), or its scale too small. The '
                           "law's yaw feedback is missing (docs/safety.md)")
        ratio, self.core.speed_seen = self.core.speed_seen, 1.0
        if turning['speed_out_of_scale'] > 0.0:
            # dev-sc47: a speed in km/h (under safety.max_speed up to 19.4 m/s) put the
            # default law 0.3-26 m off S-bends, told only as a map disagreeing
            level = max(level, DiagnosticStatus.WARN)
            how = ('the preview did not move' if math.isinf(ratio) else
                   f'the speed moved the car {ratio:.3g} times as far as the road moved '
                   'under it')
            reasons.append(f'v_x out of scale with the curvature preview for '
                           f'{turning["speed_out_of_scale"]:.2f} s ({how}): a speed in other '
                           'units (km/h reads 3.6 times, mph 2.24 times the m/s), or the '
                           "preview's distances in other units, or a preview repeated "
                           'without moving or re-planned from the car at each message. '
                           'Every law is tuned on the speed (docs/safety.md)')
        lateral_scale, self.core.lateral_scale_seen = self.core.lateral_scale_seen, 0.0
        if turning['lateral_error_out_of_scale'] > 0.0:
            # dev-sc48: a lateral error in cm put the default law 2-135 m off S-bends, the
            # input stale for its range, and the ERROR named the range, not the unit
            level = max(level, DiagnosticStatus.WARN)
            if lateral_scale < 1.0:
                # dev-probe107: the whole yaw message in degrees reads 1 for the relative
                # yaw's own check, and the yaw-rate check (the car 65-195 m off)
                how = (f'it moves {1.0 / lateral_scale:.3g} times less): a relative yaw in '
                       'degrees (57.3 times the radians; with the yaw rate in deg/s too, '
                       'neither check of the yaw sees it), or v_y in other units or biased')
            else:
                how = (f'it moves {lateral_scale:.3g} times as far): a lateral error in cm '
                       '(100 times the metres) or mm (1000 times), a relative yaw too small '
                       '(radians read as degrees), a lane reference jumping between lanes, '
                       'or an offset measured to the curved lane far ahead')
            reasons.append(f'lateral_error out of scale with the motion relative_yaw, v_x '
                           f'and v_y predict for {turning["lateral_error_out_of_scale"]:.2f} '
                           f's ({how}). Every law steers on them as metres and radians '
                           '(docs/safety.md)')
        yaw_scale, self.core.yaw_scale_seen = self.core.yaw_scale_seen, 0.0
        if turning['relative_yaw_out_of_scale'] > 0.0:
            # dev-sc48: a relative yaw in degrees put it 0.2-124 m off, told only as the map
            # disagreeing with the yaw rate and a steering oscillation
            level = max(level, DiagnosticStatus.WARN)
            reasons.append(f'relative_yaw out of scale with the motion yaw_rate - v_x * '
                           f'curvature (without a map: the yaw rate less its slow part) '
                           f'predicts for '
                           f'{turning["relative_yaw_out_of_scale"]:.2f} s (it moves '
                           f'{yaw_scale:.3g} times as far): a relative yaw in degrees (57.3 '
                           'times the radians) or mrad (1000 times), or a yaw rate too '
                           'small. Every law steers on it as radians (docs/safety.md)')
        late = {k: v for k, v in {**ages, 'answer': latency}.items()
                if v is not None and v > warn_at}
        if late:
            level = max(level, DiagnosticStatus.WARN)
            listed = ', '.join(f'{k} {v * 1e3:.0f} ms' for k, v in sorted(late.items()))
            reasons.append(f'late: {listed} (> latency_warn {warn_at * 1e3:g} ms)')
        values = [KeyValue(key=k, value=str(v)) for k, v in counts.items()]
        values += [KeyValue(key=f'{k} [s]', value=f'{v:.3f}')
                   for k, v in self.core.turning.items()]
        values += [KeyValue(key=f'age max {k} [s]', value=f'{v:.6f}')
                   for k, v in sorted(ages.items())]
        if latency is not None:
            values.append(KeyValue(key='answer latency max [s]', value=f'{latency:.6f}'))
        values.append(KeyValue(key='road_curvature residual max [rad]', value=f'{residual:.6f}'))
        fitted, error = self.core.map_timing.fit()
        values.append(KeyValue(key='road_curvature lead [m]',
                               value=f'{fitted:.3f}' if math.isfinite(error) else 'unknown'))
        values.append(KeyValue(key='road_curvature lead standard error [m]',
                               value=f'{error:.3f}' if math.isfinite(error) else 'unknown'))
        values.append(KeyValue(key='steering oscillation max [rad]', value=f'{swing[0]:.6f}'))
        values.append(KeyValue(key='steering oscillation frequency [Hz]',
                               value=f'{swing[1]:.3f}'))
        values += [KeyValue(key=f'rejected {k}', value=str(v))
                   for k, v in sorted(self.core.rejected.items())]
        # what the car taught the law's compliance estimate, over the model's (a memory
        # far from 1 run after run says vehicle.yaml's tyres or mass are not the car's)
        learned = dict(getattr(self.core.law, 'debug_values', list)())
        values += [KeyValue(key=f'{key.replace("_", " ")} [x model]', value=f'{learned[key]:.3f}')
                   for key in ('compliance_scale', 'compliance_memory') if key in learned]
        return DiagnosticStatus(level=level,
                                name=conv.controller_status_name(
                                    self.get_fully_qualified_name()),
                                message='; '.join(reasons) or 'ok',
                                hardware_id='lookahead_control', values=values)

    def on_diagnostics(self) -> None:
        """Publish ``/diagnostics``."""
        array = DiagnosticArray(status=[self.diagnostics()])
        array.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(array)


def _make_controller() -> ControllerNode:
    node = ControllerNode()
    if node.param('autostart'):
        node.trigger_configure()
        node.trigger_activate()
    return node


def main(args: Optional[list[str]] = None) -> int:
    """
    Run the controller node until shut down.

    :param args: command-line arguments (ROS arguments included).
    :return: exit code.
    """
    return run_node('controller', args, _make_controller, specs=ALL_SPECS,
                    description='variable look-ahead lateral controller (lifecycle node)',
                    check=check_parameters)


def entry() -> int:
    """Entry point of ``controller``."""
    return end_process(main(sys.argv))


if __name__ == '__main__':
    sys.exit(entry())
