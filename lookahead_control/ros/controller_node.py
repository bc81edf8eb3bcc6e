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

import sys
from typing import Any, Callable, Optional

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PointStamped, PolygonStamped, TwistStamped
from lookahead_control.core.controller import (ACCELERATION_SOURCES, Command, LAW_NAMES,
                                               SteeringController)
from lookahead_control.core.params import ParameterError, SCHEDULE_MODES
from lookahead_control.ros import conversions as conv
from lookahead_control.ros.node_main import now_ns, run_node, Throttle
from lookahead_control.ros.node_params import (baseline_params, BASELINE_SPECS, check_choices,
                                               CONTROLLER_SPECS, declare, EXECUTOR_SPEC,
                                               lane_keeping_params, LANE_KEEPING_SPECS,
                                               LAW_SPEC, safety_params, SAFETY_SPECS, Spec,
                                               values, vehicle_and_controller, VEHICLE_SPECS)
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
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
    Spec('acceleration_source', 'imu', "a_x from the yaw topic's IMU acceleration, "
         'differentiated from v_x, or zero', choices=ACCELERATION_SOURCES),
    Spec('use_curvature_preview', False, 'feed d rho/dt forward from the curvature '
         'preview (false: curvature at the CG only, as in the paper)'),
    Spec('autostart', True, 'configure and activate at start-up'),
    Spec('frame_id', 'base_link', "inputs in another frame are refused ('': any)"),
    Spec('watchdog_rate_hz', 20.0, 'stale-input check and safe-command rate [Hz]',
         1.0, 1000.0),
    Spec('diagnostics_rate_hz', 1.0, '/diagnostics rate [Hz]', 0.1, 100.0),
    EXECUTOR_SPEC,
)
ALL_SPECS = (VEHICLE_SPECS + (LAW_SPEC,) + CONTROLLER_SPECS + BASELINE_SPECS + SAFETY_SPECS
             + NODE_SPECS + LANE_KEEPING_SPECS)
DEBUG_FIELDS = ('d_v', 'd_v_rate', 'y_v', 'y_v_rate', 'y_ref', 'error', 'error_rate', 'f_v',
                'beta_1')


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


class ControllerNode(LifecycleNode):
    """Lifecycle node publishing the variable look-ahead steering command."""

    def __init__(self, **kwargs: Any) -> None:
        """
        Declare parameters; communication is set up in ``on_configure``.

        :param kwargs: passed to ``LifecycleNode`` (context, parameter_overrides, ...).
        """
        super().__init__('controller', **kwargs)
        declare(self, ALL_SPECS)
        params = values(self, ALL_SPECS)
        vehicle, controller = vehicle_and_controller(params)
        self.core = SteeringController(vehicle, controller, params['acceleration_source'],
                                       params['use_curvature_preview'], safety_params(params),
                                       params['law'], baseline_params(params),
                                       lane_keeping_params(params))
        self.counters = {'saturated': 0, 'rate_limited': 0, 'low_speed': 0,
                         'd_v_clamped': 0, 'stale_commands': 0}
        self._reported: dict[str, int] = {}
        self.stale_inputs: list[str] = []
        self._watchdog: Any = None
        self._diag_timer: Any = None
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self._dirty = False
        self._input_subs: list[Any] = []
        self._timer: Any = None
        self._sync_timer: Any = None
        self._pending_stamp: Optional[int] = None
        self._steering_pub: Any = None
        self._debug_pub: Any = None
        self.active = False
        self.published = 0
        self._refusal_log = Throttle(1.0)
        self._cache_input_parameters()
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._parameters_set)

    # -- parameters -----------------------------------------------------------------

    def _validate_parameters(self, params: list[Parameter]) -> SetParametersResult:
        try:
            merged = values(self, ALL_SPECS, params)
            check_choices(ALL_SPECS, merged)
            vehicle_and_controller(merged)
            safety_params(merged)
            baseline_params(merged)
            lane_keeping_params(merged)
        except (ParameterError, ValueError) as err:
            return SetParametersResult(successful=False, reason=str(err))
        return SetParametersResult(successful=True)

    def _parameters_set(self, params: list[Parameter]) -> None:
        self._dirty = True   # applied before the next control step
        self._cache_input_parameters()

    def _cache_input_parameters(self) -> None:
        # read on every message: plain attributes, not a parameter lookup each time
        self._frame = self.param('frame_id')
        self._mode = self.param('mode')
        self._wait_for_stamps = self.param('wait_for_matching_stamps')

    def _apply_parameters(self) -> None:
        if not self._dirty:
            return
        params = values(self, ALL_SPECS)
        vehicle, controller = vehicle_and_controller(params)
        self.core.configure(vehicle, controller, params['acceleration_source'],
                            params['use_curvature_preview'], safety_params(params),
                            params['law'], baseline_params(params),
                            lane_keeping_params(params))
        self._dirty = False
        self.get_logger().info(f'parameters applied: law={params["law"]}, '
                               f'schedule={controller.schedule}, '
                               f'w_n={controller.natural_frequency:g}, '
                               f'zeta={controller.damping_ratio:g}')

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
                                                             qos('reliable'))
        self._debug_pub = self.create_lifecycle_publisher(JointState, '~/debug',
                                                          qos('reliable'))
        subs: list[tuple[type, str, Callable[[Any], None]]] = [
            (PointStamped, 'lateral_error', self.on_lateral_error),
            (Imu, 'yaw', self.on_yaw),
            (TwistStamped, 'velocity', self.on_velocity),
            (PolygonStamped, 'road_curvature', self.on_curvature),
        ]
        self._input_subs = [self.create_subscription(t, n, cb, profile)
                            for t, n, cb in subs]
        if self.param('mode') == 'timer':
            self._timer = self.create_timer(1.0 / self.param('rate_hz'), self.on_timer)
        self._watchdog = self.create_timer(1.0 / self.param('watchdog_rate_hz'),
                                           self.on_watchdog)
        self._diag_timer = self.create_timer(1.0 / self.param('diagnostics_rate_hz'),
                                             self.on_diagnostics,
                                             clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            f'configured: mode={self.param("mode")}, law={self.core.law_name}, schedule='
            f'{self.core.params.schedule}, inputs {self.param("qos_reliability")}')
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Start publishing."""
        self.active = True
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop publishing."""
        self.active = False
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Destroy what ``on_configure`` created."""
        for sub in self._input_subs:
            self.destroy_subscription(sub)
        self._input_subs = []
        for timer in (self._timer, self._sync_timer, self._watchdog, self._diag_timer):
            if timer is not None:
                self.destroy_timer(timer)
        self._timer = self._sync_timer = self._watchdog = self._diag_timer = None
        for pub in (self._steering_pub, self._debug_pub):
            if pub is not None:
                self.destroy_publisher(pub)
        self._steering_pub = self._debug_pub = None
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Shut down from any state."""
        self.active = False
        return TransitionCallbackReturn.SUCCESS

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
            except (ValueError, IndexError, TypeError, AttributeError,
                    OverflowError) as err:
                reason = f'{name}: malformed message ({err})'
                self.core.count_rejection(reason)
            else:
                # the core checks the values and stamps, and counts what it refuses
                # sim time before the first /clock reads 0: no future check until it runs
                now = now_ns(self)
                refused = self.core.accept(name, sample, now or None)
                if refused is None:
                    return True
                reason = refused
        if self._refusal_log.ready():
            self.get_logger().warn(f'refused {reason}')
        return False

    def on_lateral_error(self, msg: PointStamped) -> None:
        """Store the lateral error; in event mode, answer it."""
        if not self._input('lateral_error', msg, conv.from_lateral_error):
            return
        if self._mode != 'event':
            return
        stamp = self.core.lateral.stamp_ns if self.core.lateral else 0
        if self._wait_for_stamps and not self.core.inputs_at(stamp):
            self._pending_stamp = stamp
            self._arm_sync_timer()
            return
        self.step()

    def _arm_sync_timer(self) -> None:
        if self._sync_timer is not None:
            self.destroy_timer(self._sync_timer)
        self._sync_timer = self.create_timer(self.param('sync_timeout'), self._sync_expired,
                                             clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _sync_expired(self) -> None:
        if self._sync_timer is not None:
            self.destroy_timer(self._sync_timer)
            self._sync_timer = None
        if self._pending_stamp is not None:
            self._pending_stamp = None
            self.step()

    def _maybe_release(self) -> None:
        if self._pending_stamp is not None and self.core.inputs_at(self._pending_stamp):
            self._pending_stamp = None
            if self._sync_timer is not None:
                self.destroy_timer(self._sync_timer)
                self._sync_timer = None
            self.step()

    def on_yaw(self, msg: Imu) -> None:
        """Store the relative yaw, yaw rate and body acceleration."""
        if self._input('yaw', msg, conv.from_yaw):
            self._maybe_release()

    def on_velocity(self, msg: TwistStamped) -> None:
        """Store the velocity."""
        if self._input('velocity', msg, conv.from_velocity):
            self._maybe_release()

    def on_curvature(self, msg: PolygonStamped) -> None:
        """Store the road curvature."""
        if self._input('road_curvature', msg, conv.from_curvature):
            self._maybe_release()

    def on_timer(self) -> None:
        """Timer mode: one command from the latest inputs (unless they are stale)."""
        if not self.core.stale(now_ns(self)):
            self.step()

    def on_watchdog(self) -> None:
        """Publish the safe command while an input is stale."""
        now = now_ns(self)
        stale = self.core.stale(now)
        if stale and not self.stale_inputs:
            self.get_logger().error(f'stale inputs: {", ".join(stale)}: holding, then '
                                    'ramping to the safe angle')
        elif self.stale_inputs and not stale:
            self.get_logger().info('inputs are back: control resumes')
        changed = stale != self.stale_inputs
        self.stale_inputs = stale
        if changed:
            self.on_diagnostics()       # ERROR (and its end) at once, not at the next 1 Hz
        if not stale or not self.active:
            return
        command = self.core.safe_command(now)
        if command is not None:
            self.counters['stale_commands'] += 1
            self._publish(command)

    # -- output ---------------------------------------------------------------------

    def step(self) -> Optional[Command]:
        """
        Compute and publish one command (nothing while inactive or inputs are missing).

        :return: the command, or None.
        """
        self._apply_parameters()
        if not self.active:
            return None
        command = self.core.compute()
        if command is None:
            return None
        self._publish(command)
        return command

    def _publish(self, command: Command) -> None:
        self._steering_pub.publish(conv.to_steering(command.stamp_ns, command.steering,
                                                    command.steering_rate))
        self.published += 1
        for flag in ('saturated', 'rate_limited'):
            self.counters[flag] += int(getattr(command, flag))
        self.counters['low_speed'] += int(command.status == 'low_speed')
        law = command.law
        if law is None:
            return
        if self.core.law_name == 'paper':
            self.counters['d_v_clamped'] += int(float(law.d_v) >= self.core.params.max_look_ahead)
        if self._debug_pub.get_subscription_count() == 0:
            return                  # nobody listens: do not build the debug message
        mode = self.core.params.schedule
        debug = [(name, float(getattr(law, name))) for name in DEBUG_FIELDS]
        debug.append((f'schedule:{mode}', float(SCHEDULE_MODES.index(mode))))
        debug.append((f'law:{self.core.law_name}', float(LAW_NAMES.index(self.core.law_name))))
        self._debug_pub.publish(conv.to_named_values(command.stamp_ns, debug))

    def diagnostics(self) -> DiagnosticStatus:
        """
        Return the controller's status for ``/diagnostics``.

        ERROR on stale inputs; WARN on refused messages, saturation, low-speed hand-over
        or clamped d_v since the last report; else OK.

        :return: the status with its reasons and counters.
        """
        counts = {**self.counters, 'rejected': sum(self.core.rejected.values()),
                  'time_jumps': self.core.time_jumps}
        new = {k: v - self._reported.get(k, 0) for k, v in counts.items()}
        self._reported = counts
        reasons = []
        level = DiagnosticStatus.OK
        if self.stale_inputs:
            level = DiagnosticStatus.ERROR
            reasons.append('stale inputs: ' + ', '.join(self.stale_inputs))
        if not self.active:
            reasons.append('inactive')
        for key in ('rejected', 'saturated', 'rate_limited', 'low_speed', 'd_v_clamped',
                    'time_jumps'):
            if new[key] > 0:
                level = max(level, DiagnosticStatus.WARN)
                text = f'{key.replace("_", " ")}: {new[key]}'
                if key == 'rejected':
                    text += f' (last: {self.core.last_rejection})'
                reasons.append(text)
        values = [KeyValue(key=k, value=str(v)) for k, v in counts.items()]
        values += [KeyValue(key=f'rejected {k}', value=str(v))
                   for k, v in sorted(self.core.rejected.items())]
        return DiagnosticStatus(level=level, name='lookahead_control: controller',
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
    return run_node('controller', args, _make_controller)


def entry() -> int:
    """Entry point of ``controller``."""
    return main(sys.argv)


if __name__ == '__main__':
    sys.exit(entry())
