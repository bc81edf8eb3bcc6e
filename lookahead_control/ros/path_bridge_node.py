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
The ``path_bridge`` node: odometry and a reference path in, the controller's contract out.

Subscribes ``odometry`` (``nav_msgs/Odometry``), ``path`` (``nav_msgs/Path``, transient
local by default; each new path replaces the last) and, with ``use_imu``, ``imu``
(``sensor_msgs/Imu``). For each odometry message it publishes ``yaw``, ``velocity``,
``road_curvature`` and then ``lateral_error`` (the controller answers that one), all
stamped with the odometry's stamp, plus ``~/debug``. When it cannot place the vehicle on
the path (no path, frames differ, past the end, off the path, bad values) it publishes
nothing and reports ERROR on ``/diagnostics``: the controller then sees stale inputs and
goes to its safe behaviour. The geometry is :mod:`lookahead_control.core.path_geometry`.
"""

from __future__ import annotations

import math
import sys
import time
from typing import Any, Callable, Mapping, Optional

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PointStamped, PolygonStamped, TwistStamped
from lookahead_control.core.controller import differentiated_step
from lookahead_control.core.params import ParameterError
from lookahead_control.core.path_geometry import (cg_pose, PathError, PathFollower, PathParams,
                                                  preview_points, ReferencePath,
                                                  twist_in_parent_frame)
from lookahead_control.core.safety import check_preview_points, SafetyParams
from lookahead_control.ros import conversions as conv
from lookahead_control.ros import vehicle_conversions as vconv
from lookahead_control.ros.controller_node import qos, writer_qos
from lookahead_control.ros.node_main import (build_or_destroy, end_process, run_node,
                                             Throttle)
from lookahead_control.ros.node_params import (build, check_choices, declare, EXECUTOR_SPEC,
                                               MAX_PREVIEW_SPEC, Spec, values)
from nav_msgs.msg import Odometry, Path
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, JointState

PATH_SPECS = (
    Spec('path.fit_half_window', 5.0, 'half-width of the local cubic fit giving heading '
         'and curvature [m]: wider smooths point noise more, rounds sharp changes more',
         0.01, 1000.0),
    Spec('path.search_distance', 10.0, 'the projection searches the last match +- this '
         '(plus the distance driven) [m]', 0.1, 1000.0),
    Spec('path.jump_distance', 1.0, 'odometry further than this from its prediction is '
         'a relocalization: the whole path is searched [m]', 0.01, 1000.0),
    Spec('path.max_distance', 5.0, 'further from the path than this: off the path, no '
         'output [m]', 0.01, 1000.0),
    Spec('path.start_tolerance', 1.0, 'the vehicle may be this far before the first '
         'path point [m]', 0.0, 1000.0),
    Spec('path.duplicate_distance', 1e-4, 'path points closer than this to the one '
         'before are dropped [m]', 0.0, 1.0),
)
NODE_SPECS = (
    Spec('sensor_distance', 0.0, 'point.x of the published lateral error: distance ahead '
         'of the CG [m]; point.y = y_cg + sensor_distance * relative yaw, as the '
         "controller's sensor model reads it", 0.0, 200.0),
    Spec('base_to_cg', 0.0, 'the CG lies this far ahead of the odometry child frame on '
         'its x axis [m] (Autoware base_link: the rear axle, so l_2)', -20.0, 20.0),
    Spec('frame_id', 'base_link', 'frame_id of the published contract messages'),
    Spec('base_frame_id', '', "odometry in another child frame is refused ('': any)"),
    Spec('preview_distance', 50.0, 'curvature preview published ahead of the CG [m]',
         0.0, 1000.0),
    Spec('preview_step', 5.0, 'spacing of the curvature preview points [m]', 0.1, 100.0),
    MAX_PREVIEW_SPEC,
    Spec('use_imu', False, 'yaw rate and body acceleration from imu (else: yaw rate from '
         'the odometry twist, acceleration from its v_x differences)'),
    Spec('imu_timeout', 0.05, 'an imu message further than this from the odometry stamp '
         'is not used [s]', 0.0, 10.0),
    Spec('odometry_timeout', 0.5, 'no odometry for this long (wall clock): ERROR [s]',
         0.01, 60.0),
    Spec('qos_reliability', 'reliable', 'reliability of the odometry and imu '
         'subscriptions (best_effort also connects to sensor-data publishers)',
         choices=('reliable', 'best_effort')),
    Spec('path_durability', 'transient_local', 'durability of the path subscription: '
         'transient_local receives a path published once before the bridge started, '
         "but matches only transient-local publishers (volatile for Nav2's plan)",
         choices=('transient_local', 'volatile')),
    Spec('autostart', True, 'configure and activate at start-up'),
    Spec('diagnostics_rate_hz', 1.0, '/diagnostics rate [Hz]', 0.1, 100.0),
    EXECUTOR_SPEC,
)
ALL_SPECS = PATH_SPECS + NODE_SPECS
#: odometry further apart than this [ns] starts the differentiated dv_x/dt again (0 until
#: the next pair)
ACCEL_GAP_NS = 500_000_000
#: the believable |dv_x/dt| [m/s^2]: the controller's default, where it refuses an accel_x
MAX_ACCELERATION = SafetyParams().max_acceleration
DEBUG_FIELDS = ('s', 'y_cg', 'eps_r', 'rho', 'path_heading', 'remaining', 'yaw_rate',
                'accel_x')


def check_parameters(params: Mapping[str, Any]) -> None:
    """
    Refuse parameters the bridge would not run with (its on-set check, at start-up).

    :param params: every parameter of :data:`ALL_SPECS` by name (checked values).
    :raises ParameterError: a path setting :class:`PathParams` refuses.
    :raises ValueError: a string parameter that is not one of its choices.
    """
    check_choices(ALL_SPECS, params)
    build(PathParams, params, 'path')
    # dev-probe92: 1000 m at 0.1 m gave 10001 points a message: the controller refused
    # every polygon (its max_curvature_points) and the bridge fell behind, unsaid
    check_preview_points(params['preview_distance'], params['preview_step'], preview_points,
                         params['max_preview_points'])


class PathBridgeNode(LifecycleNode):
    """Lifecycle node turning odometry and a path into the controller's inputs."""

    def __init__(self, **kwargs: Any) -> None:
        """
        Declare parameters; communication is set up in ``on_configure``.

        :param kwargs: passed to ``LifecycleNode`` (context, parameter_overrides, ...).
        """
        super().__init__('path_bridge', **kwargs)
        build_or_destroy(self._build, super().destroy_node)

    def _build(self) -> None:
        """Declare parameters and read them."""
        declare(self, ALL_SPECS)
        self.params = values(self, ALL_SPECS)
        self.path_params: PathParams = build(PathParams, self.params, 'path')
        self.path: Optional[ReferencePath] = None
        self.follower: Optional[PathFollower] = None
        self.path_frame = ''
        self._path_points: Any = None
        self.path_problem = 'no path received yet'
        self.problem = ''              # why the last odometry gave no output ('' = it did)
        self.events: dict[str, int] = {}
        self.last_event = ''
        self.counters = {'published': 0, 'refused': 0, 'paths': 0, 'rematches': 0,
                         'imu_fallbacks': 0}
        self._reported: dict[str, int] = {}
        self._imu: Optional[tuple[int, float, float]] = None
        # the differentiated dv_x/dt and the (stamp, v_x) it was last taken at
        self._accel: tuple[float, Optional[tuple[int, float]]] = (0.0, None)
        self._prev_pose: Optional[vconv.OdometrySample] = None
        self._parent_twists = 0     # consecutive odometry messages whose twist looks wrong
        self._odometry_wall: Optional[float] = None
        self.silent = False
        self._level = DiagnosticStatus.OK
        self.active = False
        self._subs: list[Any] = []
        self._pubs: dict[str, Any] = {}
        self._timers: list[Any] = []
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self._log = Throttle(1.0)
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._parameters_set)

    # -- parameters -------------------------------------------------------------------

    def _validate_parameters(self, params: list[Parameter]) -> SetParametersResult:
        try:
            check_parameters(values(self, ALL_SPECS, params))
        except (ParameterError, ValueError) as err:
            return SetParametersResult(successful=False, reason=str(err))
        return SetParametersResult(successful=True)

    def _parameters_set(self, params: list[Parameter]) -> None:
        self.params = values(self, ALL_SPECS)
        path_params = build(PathParams, self.params, 'path')
        if path_params != self.path_params:
            self.path_params = path_params
            if self._path_points is not None:
                self._set_path(self._path_points, self.path_frame)

    # -- lifecycle --------------------------------------------------------------------

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Create publishers, subscriptions and timers."""
        for name, kind in (('yaw', Imu), ('velocity', TwistStamped),
                           ('road_curvature', PolygonStamped),
                           ('lateral_error', PointStamped), ('~/debug', JointState)):
            self._pubs[name] = self.create_lifecycle_publisher(kind, name, writer_qos())
        inputs = qos(self.params['qos_reliability'])
        durability = (DurabilityPolicy.TRANSIENT_LOCAL
                      if self.params['path_durability'] == 'transient_local'
                      else DurabilityPolicy.VOLATILE)
        path_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                              reliability=ReliabilityPolicy.RELIABLE, durability=durability)
        self._subs = [self.create_subscription(Odometry, 'odometry', self.on_odometry, inputs),
                      # raw: rclpy's deserialization of a long path stalls the node (see
                      # vehicle_conversions.path_points_cdr)
                      self.create_subscription(Path, 'path', self.on_path_data, path_qos,
                                               raw=True)]
        if self.params['use_imu']:
            self._subs.append(self.create_subscription(Imu, 'imu', self.on_imu, inputs))
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._timers = [
            self.create_timer(1.0 / self.params['diagnostics_rate_hz'], self.on_diagnostics,
                              clock=steady),
            self.create_timer(0.05, self.on_watchdog, clock=steady)]
        self.get_logger().info(
            f'configured: odometry {self.params["qos_reliability"]}, path '
            f'{self.params["path_durability"]}, imu '
            f'{"used" if self.params["use_imu"] else "not used"}')
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
        for sub in self._subs:
            self.destroy_subscription(sub)
        for timer in self._timers:
            self.destroy_timer(timer)
        for pub in self._pubs.values():
            self.destroy_publisher(pub)
        self._subs, self._timers, self._pubs = [], [], {}
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Shut down from any state."""
        self.active = False
        return TransitionCallbackReturn.SUCCESS

    # -- inputs -----------------------------------------------------------------------

    def _event(self, key: str, text: str) -> None:
        """Count a WARN-level event (reported once in the next diagnostics)."""
        self.events[key] = self.events.get(key, 0) + 1
        self.last_event = text
        if self._log.ready():
            self.get_logger().warn(text)

    def _set_path(self, points: Any, frame: str) -> None:
        self._path_points, self.path_frame = points, frame
        try:
            path = ReferencePath(points, self.path_params)
        except PathError as err:
            self.path, self.follower = None, None
            self.path_problem = f'path refused: {err}'
            self.get_logger().error(self.path_problem)
            return
        self.path, self.follower, self.path_problem = path, PathFollower(path), ''
        if path.duplicates:
            self._event('duplicates', f'path: {path.duplicates} duplicate point(s) dropped')
        if path.cusp_at is not None:
            self._event('cusp', f'path: reverses at s = {path.cusp_at:.2f} m; only the '
                        'forward part before it is used')

    def on_path(self, msg: Path) -> None:
        """Replace the path (an unusable one leaves none: no output until the next)."""
        self._new_path(lambda: (msg.header.frame_id, vconv.path_points(msg)))

    def on_path_data(self, data: bytes) -> None:
        """Replace the path from the serialized message (the subscription's callback)."""
        self._new_path(lambda: vconv.path_points_cdr(data))

    def _new_path(self, convert: Callable[[], tuple[str, Any]]) -> None:
        self.counters['paths'] += 1
        try:
            frame, points = convert()
        except ValueError as err:
            self.path, self.follower, self._path_points = None, None, None
            self.path_problem = f'path refused: {err}'
            self.get_logger().error(self.path_problem)
        else:
            self._set_path(points, frame)
            if self.path is not None and self._log.ready():
                self.get_logger().info(f'path: {self.path.size} points, '
                                       f'{self.path.length:.1f} m in {self.path_frame!r}')
        self._report_if_changed()

    def on_imu(self, msg: Imu) -> None:
        """Keep the latest yaw rate and body longitudinal acceleration."""
        rate, accel = float(msg.angular_velocity.z), float(msg.linear_acceleration.x)
        if not (abs(rate) < 1e6 and abs(accel) < 1e6):
            self.counters['refused'] += 1
            self._event('imu', f'imu refused: yaw rate {rate!r}, acceleration {accel!r}')
            return
        self._imu = (conv.stamp_to_ns(msg.header.stamp), rate, accel)

    def _refuse(self, problem: str) -> None:
        self.counters['refused'] += 1
        if problem != self.problem and self._log.ready():
            self.get_logger().error(f'no output: {problem}')
        self.problem = problem
        self._report_if_changed()

    def on_odometry(self, msg: Odometry) -> None:
        """Place the vehicle on the path and publish the contract (or say why not)."""
        self._odometry_wall = time.monotonic()
        if not self.active:
            return
        try:
            odom = vconv.from_odometry(msg)
        except ValueError as err:
            self._refuse(str(err))
            return
        if not (abs(odom.v_x) < 1e6 and abs(odom.v_y) < 1e6 and abs(odom.yaw_rate) < 1e6):
            # as for the imu: beyond, the acceleration from speed differences and v_y r
            # overflow to inf or NaN
            self._refuse(f'odometry twist out of range (v_x {odom.v_x:g}, v_y {odom.v_y:g}, '
                         f'yaw rate {odom.yaw_rate:g}): each must be within +-1e6')
            return
        p = self.params
        if p['base_frame_id'] and odom.child_frame_id != p['base_frame_id']:
            self._refuse(f'odometry child frame {odom.child_frame_id!r} is not '
                         f'base_frame_id {p["base_frame_id"]!r}')
            return
        prev = self._prev_pose
        if (prev is not None and odom.stamp_ns == prev.stamp_ns
                and (odom.x, odom.y, odom.yaw) != (prev.x, prev.y, prev.yaw)):
            # a frozen clock: the controller would answer every message with the same
            # stamp, its rate limit would see no time pass and hold the steering (OK on
            # every status); a repeated identical message (a lockstep step 0) is answered
            self._prev_pose = odom
            moved = math.hypot(odom.x - prev.x, odom.y - prev.y)
            self._refuse(f'odometry stamp {odom.stamp_ns * 1e-9:.3f} s did not advance '
                         f'while the pose moved {moved:.3f} m (a frozen clock?)')
            return
        if self._twist_frame_wrong(odom):
            self._refuse(f'odometry twist is in the parent frame {odom.frame_id!r}, not in '
                         f'the child frame {odom.child_frame_id!r} (REP-105): the speed '
                         'would be wrong')
            return
        if self.follower is None:
            self._refuse(self.path_problem)
            return
        if odom.frame_id != self.path_frame:
            self._refuse(f'odometry pose in frame {odom.frame_id!r}, path in '
                         f'{self.path_frame!r}: publish both in one frame (no tf here)')
            return
        x, y, v_y = cg_pose(odom.x, odom.y, odom.yaw, odom.v_y, odom.yaw_rate,
                            p['base_to_cg'])
        rematches = self.follower.rematches
        try:
            lane = self.follower.locate(odom.stamp_ns, x, y, odom.yaw, odom.v_x, v_y)
        except PathError as err:
            self._refuse(str(err))
            return
        if lane.note:
            self.counters['rematches'] += self.follower.rematches - rematches
            self._event('rematch', lane.note)
        path = self.follower.path
        preview = path.preview(lane.s, p['preview_distance'], p['preview_step'])
        bad = next((point for point in preview if not math.isfinite(point[1])), None)
        if bad is not None:
            # never a NaN to the controller, whatever the path's points (dev-probe92)
            self.follower.reset()
            self._refuse(f'the path gives no finite curvature {bad[0]:g} m ahead of '
                         f's = {lane.s:.2f} m: its points are degenerate there')
            return
        yaw_rate, accel = self._rates(odom, v_y)
        stamp, frame = odom.stamp_ns, p['frame_id']
        pubs = self._pubs
        pubs['yaw'].publish(conv.to_yaw(stamp, frame, lane.relative_yaw, yaw_rate, accel))
        # a linear.y of exactly 0 is not measured (wheel odometry, an EKF without it): sent
        # on as 0, not as base_to_cg * r, which the controller would take as measured
        sent_v_y = v_y if odom.v_y != 0.0 else 0.0
        pubs['velocity'].publish(conv.to_velocity(stamp, frame, odom.v_x, sent_v_y, yaw_rate))
        pubs['road_curvature'].publish(conv.to_curvature(stamp, frame, preview))
        distance = p['sensor_distance']
        # last: the controller answers the lateral error
        pubs['lateral_error'].publish(conv.to_lateral_error(
            stamp, frame, distance, lane.lateral_error + distance * lane.relative_yaw))
        self.counters['published'] += 1
        if pubs['~/debug'].get_subscription_count() > 0:
            debug = (lane.s, lane.lateral_error, lane.relative_yaw, lane.curvature,
                     lane.heading, lane.remaining, yaw_rate, accel)
            pubs['~/debug'].publish(conv.to_named_values(stamp, list(zip(DEBUG_FIELDS,
                                                                         debug))))
        if self.problem:
            self.get_logger().info(f'output resumes (was: {self.problem})')
        self.problem = ''
        self._report_if_changed()

    def _twist_frame_wrong(self, odom: vconv.OdometrySample) -> bool:
        """
        Return True once 5 consecutive messages' twists fit a parent-frame velocity.

        :param odom: the odometry.
        :return: whether to refuse it.
        """
        prev, self._prev_pose = self._prev_pose, odom
        if prev is None:
            return False
        yaw = prev.yaw + 0.5 * math.remainder(odom.yaw - prev.yaw, 2.0 * math.pi)
        if twist_in_parent_frame(odom.x - prev.x, odom.y - prev.y,
                                 (odom.stamp_ns - prev.stamp_ns) * 1e-9, yaw, odom.v_x,
                                 odom.v_y):
            self._parent_twists += 1
        elif odom.stamp_ns != prev.stamp_ns:
            self._parent_twists = 0
        return self._parent_twists >= 5

    def _rates(self, odom: vconv.OdometrySample, v_y: float) -> tuple[float, float]:
        """
        Return the yaw rate and the IMU's body longitudinal acceleration for ``odom``.

        From ``imu`` when used and within ``imu_timeout`` of the odometry stamp; else the
        odometry's yaw rate and ``dv_x/dt - v_y r``, with ``dv_x/dt`` differentiated
        from the odometry speeds as the controller does it (over at least 10 ms, clipped
        at 15 m/s^2: :func:`~lookahead_control.core.controller.differentiated_step`).

        :param odom: the odometry.
        :param v_y: lateral velocity at the CG [m/s].
        :return: yaw rate [rad/s], acceleration [m/s^2].
        """
        estimate, anchor = self._accel
        if anchor is not None and odom.stamp_ns - anchor[0] > ACCEL_GAP_NS:
            estimate, anchor = 0.0, None            # after a gap: from the next pair on
        # over at least 10 ms and clipped at the controller's believable |a_x|, as the
        # controller differentiates (dev-probe71: a 700 Hz odometry with 2 cm/s of speed
        # noise made 1000 m/s^2, the controller refused half the yaw messages)
        self._accel = differentiated_step(estimate, anchor, odom.stamp_ns, odom.v_x,
                                          MAX_ACCELERATION)
        if self.params['use_imu']:
            imu = self._imu
            if imu is not None and abs(imu[0] - odom.stamp_ns) <= \
                    self.params['imu_timeout'] * 1e9:
                return imu[1], imu[2]
            self.counters['imu_fallbacks'] += 1
            age = ('none received' if imu is None
                   else f'{(odom.stamp_ns - imu[0]) * 1e-9:+.3f} s from the odometry')
            self._event('imu', f'imu not usable ({age}): yaw rate from odometry')
        return odom.yaw_rate, self._accel[0] - v_y * odom.yaw_rate

    # -- diagnostics ------------------------------------------------------------------

    def on_watchdog(self) -> None:
        """Report silent odometry at once (the controller goes safe on its own)."""
        last = self._odometry_wall
        silent = (self.active and last is not None
                  and time.monotonic() - last > self.params['odometry_timeout'])
        if silent != self.silent:
            self.silent = silent
            if silent:
                self.get_logger().error(f'no odometry for {self.params["odometry_timeout"]:g}'
                                        ' s')
            self.on_diagnostics()

    def _report_if_changed(self) -> None:
        level = DiagnosticStatus.ERROR if self.problem else DiagnosticStatus.OK
        if level != self._level:
            self._level = level
            self.on_diagnostics()

    def diagnostics(self) -> DiagnosticStatus:
        """
        Return the bridge's status for ``/diagnostics``.

        ERROR while the last odometry gave no output (the reason), the odometry is
        silent or there is no usable path; WARN on events since the last report
        (relocalizations, dropped duplicates, a reversing path, imu fallbacks); else OK.

        :return: the status.
        """
        reasons = []
        level = DiagnosticStatus.OK
        if self.problem:
            level = DiagnosticStatus.ERROR
            reasons.append(self.problem)
        if self.silent:
            level = DiagnosticStatus.ERROR
            reasons.append(f'no odometry for {self.params["odometry_timeout"]:g} s')
        if self.path_problem and self.path_problem != self.problem:
            level = DiagnosticStatus.ERROR
            reasons.append(self.path_problem)
        if not self.active:
            reasons.append('inactive')
        if self.events:
            level = max(level, DiagnosticStatus.WARN)
            reasons.append(', '.join(f'{k}: {v}' for k, v in sorted(self.events.items()))
                           + f' (last: {self.last_event})')
        self.events = {}
        counts: dict[str, float] = dict(self.counters)
        if self.path is not None:
            counts.update(path_points=self.path.size, path_length=round(self.path.length, 3))
        values = [KeyValue(key=k, value=str(v)) for k, v in counts.items()]
        values.append(KeyValue(key='path_frame', value=self.path_frame))
        return DiagnosticStatus(level=level,
                                name='lookahead_control: path_bridge',
                                message='; '.join(reasons) or 'ok',
                                hardware_id='lookahead_control', values=values)

    def on_diagnostics(self) -> None:
        """Publish ``/diagnostics``."""
        array = DiagnosticArray(status=[self.diagnostics()])
        array.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(array)


def _make_bridge() -> PathBridgeNode:
    node = PathBridgeNode()
    if node.params['autostart']:
        node.trigger_configure()
        node.trigger_activate()
    return node


def main(args: Optional[list[str]] = None) -> int:
    """
    Run the path bridge until shut down.

    :param args: command-line arguments (ROS arguments included).
    :return: exit code.
    """
    # its parameters checked as the other nodes' (before, no --help list, no typo or
    # choice check, an integer for a real refused in rclpy's words; dev-probe54)
    return run_node('path_bridge', args, _make_bridge, specs=ALL_SPECS,
                    description='vehicle bridge: odometry and a road path to the '
                    "controller's contract topics", check=check_parameters)


def entry() -> int:
    """Entry point of ``path_bridge``."""
    return end_process(main(sys.argv))


if __name__ == '__main__':
    sys.exit(entry())
