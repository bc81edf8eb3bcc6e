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
The ``sim_plant`` node: integrates the plant and publishes what a vehicle bridge would.

Publishes the controller's input contract (``lateral_error``, ``yaw``, ``velocity``,
``road_curvature``), ground truth on ``~/ground_truth`` and ``/clock``; subscribes
``steering``. With ``output: vehicle`` it speaks like a vehicle instead: ``odometry``
(``nav_msgs/Odometry`` of the CG in ``map_frame``, body twist), ``imu`` and the
scenario's road as a ``path`` (``nav_msgs/Path``, transient local, once), for
``path_bridge`` to turn into the contract. ``lockstep``: publish step k, wait for the
command stamped k, integrate, repeat (a missed ``deadline`` holds the last command and is
counted; a good answer arriving after it is logged as late, with its delay). ``realtime``:
one step per wall-clock period with the latest command.
"""

from __future__ import annotations

from dataclasses import replace
import math
from pathlib import Path
import sys
import time
from typing import Any, Mapping, NamedTuple, Optional

from geometry_msgs.msg import PointStamped, PolygonStamped, TwistStamped
from lookahead_control.core.config import ConfigError, source_config_dir
from lookahead_control.core.params import ParameterError, VehicleParams
from lookahead_control.core.safety import check_preview_points
from lookahead_control.ros import conversions as conv
from lookahead_control.ros.controller_node import qos, WRITER_DEPTH, writer_qos
from lookahead_control.ros.node_main import (build_or_destroy, end_process, run_node,
                                             Throttle)
from lookahead_control.ros.node_params import (build, declare, EXECUTOR_SPEC, MAX_PREVIEW_SPEC,
                                               Spec, values, VEHICLE_SPECS)
from lookahead_control.ros.vehicle_conversions import to_odometry, to_path
from nav_msgs.msg import Odometry, Path as PathMsg
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import Imu, JointState
from sim_plant.closed_loop_sim import (advance, check_steps, CommonRoadGroup, delay_steps,
                                       linear_plant_stepper, measure, plant_derivatives,
                                       preview_distances, Stepper)
from sim_plant.commonroad_plant import COMMONROAD_MODELS
from sim_plant.scenario import check_force_timing, load_scenario, Scenario
from sim_plant.sensors import NoiseParams, NoiseStream
from sim_plant.vehicle_model import KINEMATICS, PLANT_MODELS, PlantParams, State

OUTPUTS = ('contract', 'vehicle')
PLANT_SPECS = (
    Spec('plant.model', 'linear', 'linear (paper eq. 1), nonlinear (Fiala tyres, '
         'actuator), commonroad_st or commonroad_mb (CommonRoad single-track / multi-body)',
         choices=PLANT_MODELS),
    Spec('plant.kinematics', 'exact', 'Frenet kinematics: exact or small_angle',
         choices=KINEMATICS),
    Spec('plant.friction', 1.0, 'tyre-road friction mu (nonlinear) [-]', 0.01, 2.0),
    Spec('plant.steering_time_constant', 0.05, 'actuator lag (nonlinear) [s]', 0.001, 2.0),
    Spec('plant.max_steering_angle', 0.6, 'actuator angle limit of the nonlinear and '
         'CommonRoad plants [rad]; a command beyond it is counted and said (the linear '
         'plant, without an actuator, applies it as sent)',
         0.01, 1.2),
    Spec('plant.max_steering_rate', 0.8, 'actuator rate limit (nonlinear) [rad/s]',
         0.01, 20.0),
    Spec('plant.vehicle_id', 2, 'CommonRoad parameter set of commonroad_* plants: 1 Ford '
         'Escort, 2 BMW 320i, 3 VW Vanagon', 1, 3),
    Spec('plant.delay', 0.0, 'transport delay from the steering command to the wheel [s], '
         'a multiple of dt', 0.0, 1.0),
    Spec('plant.mass_scale', 1.0, "plant mass / vehicle.mass (the controller's model: "
         'mismatch)', 0.1, 10.0),
    Spec('plant.inertia_scale', 1.0, 'plant yaw inertia / vehicle.yaw_inertia', 0.1, 10.0),
    Spec('plant.cornering_scale', 1.0, 'plant cornering stiffness / vehicle.c_f, c_r',
         0.1, 10.0),
    Spec('noise.enabled', False, 'add seeded white noise to the published measurements'),
    Spec('noise.lateral_error', 0.03, 'noise std of the lateral error [m]', 0.0, 5.0),
    Spec('noise.relative_yaw', 0.002, 'noise std of the relative yaw [rad]', 0.0, 0.5),
    Spec('noise.lateral_velocity', 0.02, 'noise std of v_y [m/s]', 0.0, 5.0),
    Spec('noise.yaw_rate', 0.002, 'noise std of the yaw rate [rad/s]', 0.0, 0.5),
    Spec('noise.seed', 0, 'noise seed (the same seed repeats the run exactly)', 0,
         2 ** 31 - 1),
)
SIM_SPECS = (
    Spec('scenario_file', '', 'scenario YAML (empty: config/scenarios/paper_r400.yaml)'),
    Spec('speed', 0.0, "initial speed override [m/s] (0: the scenario's)", 0.0, 90.0),
    Spec('mode', 'lockstep', 'lockstep (wait for each answer) or realtime (wall clock)',
         choices=('lockstep', 'realtime')),
    Spec('rate_hz', 100.0, 'measurement / control rate [Hz]', 1.0, 2000.0),
    Spec('dt', 0.001, 'RK4 integration step [s]; 1/rate_hz must be a multiple',
         1e-5, 0.1),
    Spec('sensor_distance', -1.0, 'distance ahead of the CG of the published lateral '
         'error [m] (< 0: vehicle.d_s, the bumper)', -1.0, 200.0),
    Spec('deadline', 0.5, 'lockstep: wall-clock wait for an answer before holding [s]',
         0.001, 60.0),
    Spec('exit_at_end', True, 'stop at the end of the scenario'),
    Spec('frame_id', 'base_link', 'vehicle frame (at the CG) of the published messages'),
    Spec('preview_distance', 50.0, 'curvature preview published ahead of the CG [m]',
         0.0, 1000.0),
    Spec('curvature_stop', 0.0, 'output contract: road_curvature is published only before '
         'this scenario time (a map lost mid-run: the default controller then estimates the '
         'curvature) [s]; 0: to the end', 0.0, 1.0e6),
    Spec('preview_step', 5.0, 'spacing of the curvature preview points [m]', 0.1, 100.0),
    MAX_PREVIEW_SPEC,
    Spec('subscribers', 1, 'start once each contract topic has this many matched '
         'subscriptions (2: controller and recorder)', 1, 100),
    Spec('output', 'contract', 'contract: the lane-relative topics; vehicle: odometry, '
         'imu and the road as a path (through path_bridge, as a real vehicle)',
         choices=OUTPUTS),
    Spec('map_frame', 'map', 'output vehicle: frame of the odometry pose and the path'),
    Spec('path_spacing', 1.0, 'output vehicle: spacing of the published path points [m]',
         0.01, 100.0),
    Spec('settle', 0.3, 'wall-clock time the topics must stay matched before the first '
         "step [s]: a recorder subscribes to the controller's topics on its own poll "
         '(0.1 s for record and rosbag2)', 0.0, 10.0),
    EXECUTOR_SPEC,
)
# longest wait at exit for subscribers to acknowledge the last samples [s]
ACK_TIMEOUT = 10.0
#: history of the ground-truth publisher [messages]: 10 s at 100 Hz for a recorder behind
TRUTH_DEPTH = WRITER_DEPTH
ALL_SPECS = VEHICLE_SPECS + PLANT_SPECS + SIM_SPECS
GROUND_TRUTH = ('time', 's', 'y_cg', 'eps_r', 'v_y', 'r', 'steering', 'steering_cmd',
                'v_x', 'a_x', 'rho', 'command_time', 'external_force', 'external_moment')


class Checked(NamedTuple):
    """What the simulator's parameters give, checked (:func:`check_parameters`)."""

    vehicle: VehicleParams
    plant: PlantParams
    scenario: Scenario
    substeps: int
    n_steps: int
    lag: int


def check_parameters(params: Mapping[str, Any]) -> Checked:
    """
    Refuse parameters the simulator would not start with (before ROS starts, too).

    Each message names the parameters behind it as ``name = value``, so that the start-up
    check names the file or ``-p`` that set them.

    :param params: every parameter of :data:`ALL_SPECS` by name (checked values).
    :return: the vehicle (the controller's model), the plant, the scenario, the plant
        steps per control step, the control steps and the delay in plant steps.
    :raises ParameterError: a value or combination the simulator refuses.
    :raises ConfigError: a scenario file that does not load.
    """
    if params['output'] == 'vehicle' and params['curvature_stop'] > 0.0:
        # the road goes out once, as a path: path_bridge's curvature would not stop
        raise ParameterError(f"curvature_stop = {params['curvature_stop']:g}: only with output "
                             "= 'contract' (road_curvature); output = 'vehicle' sends the "
                             "road once as a path, the curvature is path_bridge's")
    build(NoiseParams, params, 'noise')
    # as path_bridge (dev-probe94: 1000 m at 0.1 m went out as 10001 points a message)
    check_preview_points(params['preview_distance'], params['preview_step'],
                         lambda distance, step: len(preview_distances(distance, step)),
                         params['max_preview_points'])
    path = Path(params['scenario_file']) if params['scenario_file'] else (
        source_config_dir() / 'scenarios' / 'paper_r400.yaml')
    speed = params['speed'] or None
    try:
        scenario = load_scenario(path, speed)
    except ConfigError as err:
        if speed is None:
            raise
        load_scenario(path)         # the file itself loads: the override is refused
        raise ParameterError(f'speed = {speed:g} m/s: {err}') from err
    dt, rate = params['dt'], params['rate_hz']
    try:
        substeps, n_steps = check_steps(dt, 1.0 / rate, scenario.duration)
    except ParameterError as err:
        raise ParameterError(f'rate_hz = {rate:g} Hz and dt = {dt!r} s: the period 1 / '
                             f'rate_hz must be a whole multiple of dt ({err})') from err
    try:
        check_force_timing(scenario.forces, dt)
    except ParameterError as err:
        raise ParameterError(f'{path} with dt = {dt!r} s: {err}') from err
    try:
        lag = delay_steps(params['plant.delay'], dt)
    except ParameterError as err:
        raise ParameterError(f"plant.delay = {params['plant.delay']!r} s is not a whole "
                             f'multiple of dt = {dt!r} s') from err
    return Checked(build(VehicleParams, params, 'vehicle'), build(PlantParams, params, 'plant'),
                   scenario, substeps, n_steps, lag)


class SimPlantNode(Node):
    """Plant simulator publishing the controller's input contract."""

    def __init__(self, **kwargs: Any) -> None:
        """
        Declare parameters, load the scenario, create publishers and timers.

        :param kwargs: passed to ``Node`` (context, parameter_overrides, ...).
        """
        super().__init__('sim_plant', **kwargs)
        build_or_destroy(self._build, super().destroy_node)

    def _build(self) -> None:
        """Declare parameters, load the scenario, create publishers and timers."""
        declare(self, ALL_SPECS)
        p = values(self, ALL_SPECS)
        self.params = p
        checked = check_parameters(p)
        self.vehicle: VehicleParams = checked.vehicle
        self.plant: PlantParams = checked.plant
        self.plant_vehicle = replace(
            self.vehicle, mass=self.vehicle.mass * p['plant.mass_scale'],
            yaw_inertia=self.vehicle.yaw_inertia * p['plant.inertia_scale'],
            c_f=self.vehicle.c_f * p['plant.cornering_scale'],
            c_r=self.vehicle.c_r * p['plant.cornering_scale'])
        self.noise = (NoiseStream(build(NoiseParams, p, 'noise'), p['noise.seed'])
                      if p['noise.enabled'] else None)
        self.scenario: Scenario = checked.scenario
        self.period = 1.0 / p['rate_hz']
        self.substeps, self.n_steps = checked.substeps, checked.n_steps
        self.sensor_distance = (p['sensor_distance'] if p['sensor_distance'] >= 0.0
                                else self.vehicle.d_s)
        self.lag = checked.lag
        self.commands: dict[int, float] = {}      # step -> command, for the delay
        speed = self.scenario.speed
        self._preview_rho = self.scenario.road.curvature_function()
        # the scenario's external forces (a crosswind, a bank) act on every plant: the
        # fast linear stepper has none, the generic right-hand side takes them
        self.stepper: Optional[Stepper] = (
            linear_plant_stepper(self.scenario, self.plant_vehicle, self.plant,
                                 float(speed.initial), float(speed.acceleration))
            if self.plant.model == 'linear' and not self.scenario.forces else None)
        init = self.scenario.initial
        self.x: State = (0.0, init.lateral_error, init.relative_yaw, init.lateral_velocity,
                         init.yaw_rate, 0.0)
        self.commonroad: Optional[CommonRoadGroup] = None
        if self.plant.model in COMMONROAD_MODELS:
            self.commonroad = CommonRoadGroup(self.scenario, [self.plant], speed.initial,
                                              init.lateral_error, ())
            self.x = self.commonroad.contract()
        self.k = 0
        self.command = 0.0
        self.failure = ''               # why the run stopped early (a diverged plant)
        self.missed = 0
        self.rejected = 0
        self.beyond = 0             # commands beyond plant.max_steering_angle
        self._rejected_seen = 0     # rejections told in the last missed-step line
        self.late = 0               # lockstep: good answers after their step's deadline
        self._missed_sent: dict[int, float] = {}    # lockstep: missed stamp -> sent at
        self.answered_stamp: Optional[int] = None
        self.waiting_stamp: Optional[int] = None
        self.sent_at = 0.0
        self._connected_since: Optional[float] = None
        self.started_at = 0.0       # wall clock of the first step of the loop
        self._miss_log = Throttle(1.0)
        self._refusal_log = Throttle(1.0)
        self._beyond_log = Throttle(1.0)
        # a graph query for another /clock publisher: once a second, not at every poll
        self._clock_check = Throttle(1.0)
        self.done = Future()
        frame = p['frame_id']
        self.frame = frame
        reliable = qos('reliable')
        out = writer_qos()
        self.vehicle_output = p['output'] == 'vehicle'
        self._resent_at = 0.0
        self._clock_shared = False
        if self.vehicle_output:
            self.pub_odometry = self.create_publisher(Odometry, 'odometry', out)
            self.pub_imu = self.create_publisher(Imu, 'imu', out)
            self.pub_path = self.create_publisher(PathMsg, 'path', QoSProfile(
                history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                durability=DurabilityPolicy.TRANSIENT_LOCAL))
            self.path_msg = self.road_path()
            self.pub_path.publish(self.path_msg)
        else:
            self.pub_lateral = self.create_publisher(PointStamped, 'lateral_error', out)
            self.pub_yaw = self.create_publisher(Imu, 'yaw', out)
            self.pub_velocity = self.create_publisher(TwistStamped, 'velocity', out)
            self.pub_curvature = self.create_publisher(PolygonStamped, 'road_curvature', out)
        # for recorders, not the contract: a deep history, so a recorder that falls behind
        # a lockstep run for a moment (319 steps/s: keep-last 10 is 30 ms) catches up
        # instead of losing steps (a run under load lost 0.93 s of ground truth)
        self.pub_truth = self.create_publisher(JointState, '~/ground_truth', out)
        self.pub_clock = self.create_publisher(ClockMsg, '/clock', out)
        self.sub_steering = self.create_subscription(JointState, 'steering',
                                                     self.on_steering, reliable)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        if p['mode'] == 'lockstep':
            self._poll = self.create_timer(0.002, self.on_poll, clock=steady)
        else:
            self._poll = self.create_timer(self.period, self.on_realtime_tick, clock=steady)
        self.get_logger().info(
            f'scenario {self.scenario.name!r}: {self.scenario.duration:g} s at '
            f'{self.scenario.speed.initial:g} m/s, {p["mode"]} at {p["rate_hz"]:g} Hz, '
            f'{self.plant.model} plant, {p["output"]} output')
        # every parameter is read once, above: a change at run time would be taken and
        # do nothing (``ros2 param set /sim_plant curvature_stop 5`` said it was set)
        self.add_on_set_parameters_callback(self._refuse_changes)

    def _refuse_changes(self, params: list[Parameter]) -> SetParametersResult:
        """
        Refuse a parameter change at run time: the simulator reads its parameters at start.

        :param params: the parameters to set.
        :return: the refusal, naming them.
        """
        names = ', '.join(p.name for p in params)
        return SetParametersResult(successful=False, reason=(
            f'{names}: sim_plant reads its parameters once, at start-up (scenario, plant, '
            'outputs); start it again with -p NAME:=VALUE'))

    def road_path(self) -> PathMsg:
        """
        Return the scenario's road as a path in ``map_frame``, every ``path_spacing``.

        It covers the road and, past its end, as far as the scenario can drive plus the
        curvature preview (the road continues with its last curvature).

        :return: the message (stamp 0).
        """
        speed = self.scenario.speed
        fastest = max(speed.initial, speed.initial + speed.acceleration * speed.duration)
        length = (max(self.scenario.road.length, fastest * self.scenario.duration)
                  + self.params['preview_distance'] + 50.0)
        points = self.scenario.road.sample(length, self.params['path_spacing'])
        return to_path(0, self.params['map_frame'], points.tolist())

    # -- time and measurements ------------------------------------------------------

    def stamp_ns(self, k: Optional[int] = None) -> int:
        """
        Return the stamp of step ``k`` (default: the current step) [ns].

        :param k: step index.
        :return: sim time in nanoseconds.
        """
        return int(round((self.k if k is None else k) * self.period * 1e9))

    def publish_measurements(self) -> int:
        """
        Publish /clock, the contract topics and ground truth for the current step.

        :return: the stamp published [ns].
        """
        stamp = self.stamp_ns()
        t = stamp * 1e-9
        scenario = self.scenario
        x = tuple(float(v) for v in self.x)
        inputs = (self.commonroad.measure(x, t, scenario, scenario.speed.acceleration)
                  if self.commonroad is not None else
                  measure(x, t, scenario, scenario.speed.initial, scenario.speed.acceleration))
        v_x, a_x, rho = float(inputs.v_x), float(inputs.a_x), float(inputs.rho)
        # sensor noise of this step (the same row however often a step is published)
        noise = (self.noise.row(self.k) if self.noise is not None
                 else (0.0, 0.0, 0.0, 0.0))
        if self.vehicle_output:
            self.publish_vehicle(stamp, x, v_x, a_x, noise)
        else:
            self.publish_contract(stamp, x, v_x, a_x, noise)
        if self.pub_truth.get_subscription_count() > 0:     # a recorder, a probe
            steering = self.applied(0) if self.plant.model == 'linear' else x[5]
            # command_time: the stamp of the step whose answer is applied (-1: none yet)
            answered = self.answered_stamp
            command_time = (answered * 1e-9 if answered is not None and answered >= 0
                            else -1.0)
            # the scenario's external force and moment: their mean over the period from
            # t (its impulse: a gust shorter than a period is not missed by the sample)
            force, moment = self.mean_external(t)
            truth = (t, x[0], x[1], x[2], x[3], x[4], steering, self.command, v_x, a_x,
                     rho, command_time, force, moment)
            self.pub_truth.publish(conv.to_named_values(stamp,
                                                        list(zip(GROUND_TRUTH, truth))))
        if self.vehicle_output:
            self.pub_odometry.publish(self._odometry)
        else:
            self.pub_lateral.publish(conv.to_lateral_error(
                stamp, self.frame, self.sensor_distance,
                x[1] + self.sensor_distance * x[2] + noise[0]))
        # /clock last: a controller on a sim-time timer wakes to this step's measurements
        self.pub_clock.publish(ClockMsg(clock=conv.ns_to_stamp(stamp)))
        return stamp

    def publish_vehicle(self, stamp: int, x: tuple[float, ...], v_x: float,
                        a_x: float, noise: tuple[float, float, float, float]) -> None:
        """
        Publish the imu and prepare the odometry of the CG (sent after ground truth).

        The CG's pose: the road's point at ``s`` moved ``y_cg`` along its normal, yaw the
        road's heading plus ``eps_r``; twist in the body frame (REP-105). The step's
        sensor noise perturbs the pose's lateral offset and yaw and the twist's v_y and r.

        :param stamp: the stamp [ns].
        :param x: the plant state.
        :param v_x: longitudinal speed [m/s].
        :param a_x: dv_x/dt [m/s^2].
        :param noise: the step's noise on (lateral error, relative yaw, v_y, yaw rate).
        """
        n_lat, n_yaw, n_vy, n_r = noise
        pos_x, pos_y, yaw = self.scenario.road.global_pose(x[0], x[1] + n_lat, x[2] + n_yaw)
        self._imu = conv.to_yaw(stamp, self.frame, yaw, x[4] + n_r, a_x - x[3] * x[4])
        self.pub_imu.publish(self._imu)
        self._odometry = to_odometry(stamp, self.params['map_frame'], self.frame, pos_x,
                                     pos_y, yaw, v_x, x[3] + n_vy, x[4] + n_r)

    def publish_contract(self, stamp: int, x: tuple[float, ...], v_x: float,
                         a_x: float, noise: tuple[float, float, float, float]) -> None:
        """
        Publish yaw, velocity and curvature (the lateral error goes after ground truth).

        :param stamp: the stamp [ns].
        :param x: the plant state.
        :param v_x: longitudinal speed [m/s].
        :param a_x: dv_x/dt [m/s^2].
        :param noise: the step's noise on (lateral error, relative yaw, v_y, yaw rate).
        """
        _, n_yaw, n_vy, n_r = noise
        # the IMU measures body acceleration: dv_x/dt - v_y r (true values)
        self.pub_yaw.publish(conv.to_yaw(stamp, self.frame, x[2] + n_yaw, x[4] + n_r,
                                         a_x - x[3] * x[4]))
        self.pub_velocity.publish(conv.to_velocity(stamp, self.frame, v_x, x[3] + n_vy,
                                                   x[4] + n_r))
        stop = self.params['curvature_stop']
        if stop <= 0.0 or stamp < int(round(stop * 1e9)):
            self.pub_curvature.publish(conv.to_curvature(stamp, self.frame,
                                                         self.preview(x[0])))

    def mean_external(self, t: float) -> tuple[float, float]:
        """
        Return the mean external force and moment over the control period from ``t``.

        :param t: the period's start [s].
        :return: ``(force [N], moment [N m])``: the mean of the values held over its plant
            steps.
        """
        if not self.scenario.forces:
            return 0.0, 0.0
        dt = self.params['dt']
        pushes = [self.scenario.external(t + j * dt) for j in range(self.substeps)]
        return (sum(f for f, _ in pushes) / self.substeps,
                sum(m for _, m in pushes) / self.substeps)

    def preview(self, s: float) -> list[tuple[float, float]]:
        """
        Return (distance ahead, curvature) pairs from the CG to the preview distance.

        :param s: arc length of the CG [m].
        :return: the preview.
        """
        step, total = self.params['preview_step'], self.params['preview_distance']
        count = int(total / step) + 1
        rho = self._preview_rho
        return [(i * step, float(rho(s + i * step))) for i in range(count)]

    def applied(self, substep: int) -> float:
        """
        Return the command at the wheel in plant step ``substep`` of this period.

        :param substep: 0 .. substeps - 1.
        :return: the command sent ``plant.delay`` earlier (0 before the first).
        """
        if self.lag == 0:
            return self.command
        source = (self.k * self.substeps + substep - self.lag) // self.substeps
        return self.commands.get(source, 0.0)

    def integrate(self) -> None:
        """Advance the plant by one period with the held (and delayed) command."""
        t = self.k * self.period
        dt = self.params['dt']
        self.commands[self.k] = self.command
        self.commands.pop(self.k - self.lag // self.substeps - 2, None)
        scenario = self.scenario
        if self.commonroad is not None:
            for j in range(self.substeps):
                self.commonroad.advance(t + j * dt, dt, self.applied(j))
            model = self.commonroad.plants[0]
            if model.diverged_at is not None:
                self.stop_diverged(f'at t = {model.diverged_at:g} s', model.failure)
                return
            self.x = self.commonroad.contract()
        elif self.lag == 0 and self.stepper is not None:
            self.x = self.stepper(self.x, t, dt, self.substeps, self.command)
        elif self.lag == 0 and not scenario.forces:
            rhs = plant_derivatives(scenario, self.plant_vehicle, self.plant, self.command,
                                    scenario.speed.initial, scenario.speed.acceleration)
            self.x = advance(rhs, self.x, t, dt, self.substeps, self.plant, self.command)
        else:
            for j in range(self.substeps):
                u = self.applied(j)
                if self.stepper is not None:
                    self.x = self.stepper(self.x, t + j * dt, dt, 1, u)
                    continue
                # the scenario's forces are held over each plant step, from its start
                push = scenario.external(t + j * dt) if scenario.forces else None
                rhs = plant_derivatives(scenario, self.plant_vehicle, self.plant, u,
                                        scenario.speed.initial, scenario.speed.acceleration,
                                        None if push is None else lambda _t: push)
                self.x = advance(rhs, self.x, t + j * dt, dt, 1, self.plant, u)
        if self.commonroad is None and not all(math.isfinite(float(v)) for v in self.x):
            # dev-probe81: the linear plant at 0.05 m/s under a force blew up (|v_y| 1e111)
            # and the run went on with every input refused, to rc 0
            self.stop_diverged(f'between t = {t:g} and {t + self.period:g} s',
                               'a non-finite state')
            return
        self.k += 1

    def stop_diverged(self, when: str, why: str) -> None:
        """
        End the run: the plant diverged (:func:`finished` raises it in one line).

        Raised by main's done check, outside the executor's callback: raised in the
        steering callback, rclpy logged it FATAL with its stack before the line
        (dev-probe80).

        :param when: when, e.g. ``at t = 1.384 s``.
        :param why: what failed.
        """
        pushed = " under the scenario's external_forces" if self.scenario.forces else ''
        self.failure = f'the {self.plant.model} plant diverged {when}{pushed} ({why})'
        self.done.set_result(False)

    def _refused_since(self) -> str:
        """Return ``', N commands refused'`` since the last missed-step line ('' if none)."""
        refused, self._rejected_seen = self.rejected - self._rejected_seen, self.rejected
        return f', {refused} commands refused meanwhile' if refused else ''

    def summary(self) -> str:
        """Return the run's counts: steps, missed deadlines, refused, beyond the limit, late."""
        wall = time.monotonic() - self.started_at if self.started_at else 0.0
        return (f'{self.k} steps, {self.missed} missed deadlines, {self.rejected} rejected '
                f'commands, {self.beyond} beyond plant.max_steering_angle, {self.late} '
                f'late answers; {wall:.3f} s wall ({self.k / max(wall, 1e-9):.0f} steps/s)')

    def finished(self) -> bool:
        """Return True (and stop) when the scenario's end is reached."""
        if self.k < self.n_steps or not self.params['exit_at_end']:
            return False
        if not self.done.done():
            self.get_logger().info(
                f'scenario {self.scenario.name!r} finished at t = '
                f'{self.k * self.period:g} s: {self.summary()}')
            self.done.set_result(True)
        return True

    def destroy_node(self) -> None:
        """
        Wait until every subscriber acknowledged what was published, then destroy.

        A reliable writer destroyed right after its last publish drops the samples its
        readers have not yet acknowledged: a recorder slowed down by a loaded machine
        then misses the end of the run (its ground truth). The wait ends as soon as all
        are acknowledged; ``ACK_TIMEOUT`` (for all publishers together) only bounds it
        for a subscriber that died without the middleware noticing yet.
        """
        if self.k and not self.done.done():
            # stopped before the scenario's end (a signal): the counts are said all the
            # same (dev-probe92: 1010 refused commands of a stopped run were never told)
            where = (f' of {self.scenario.duration:g} s' if self.k < self.n_steps else
                     f' (the scenario ended at {self.scenario.duration:g} s)')
            self.get_logger().info(f'stopped at t = {self.k * self.period:g} s{where}: '
                                   f'{self.summary()}')
        end = time.monotonic() + ACK_TIMEOUT
        for pub in list(self.publishers):
            left = end - time.monotonic()
            if left > 0 and pub.get_subscription_count() > 0:
                pub.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9)))
        super().destroy_node()

    # -- steering -------------------------------------------------------------------

    def on_steering(self, msg: JointState) -> None:
        """Take a steering command; in lockstep, the answer to the step waited for."""
        parsed = conv.from_steering(msg)
        if parsed is None:
            self.rejected += 1
            return
        stamp, angle = parsed
        if not (abs(angle) < 10.0 and angle == angle):
            self.rejected += 1
            if self._refusal_log.ready():
                self.get_logger().error(f'steering {angle!r} rad for t = {stamp * 1e-9:g} s '
                                        'refused (not finite, or 10 rad or more): holding '
                                        f'{self.command:+.4f} rad ({self.rejected} refused)')
            return
        limit = self.plant.max_steering_angle
        if abs(angle) > limit:
            # said and counted (dev-probe92: the linear plant integrated 9.9 rad, a yaw
            # rate of 75 rad/s, without a word); applied as the plant does: the linear
            # (the paper's model) has no actuator, the others' actuators clip there
            self.beyond += 1
            if self._beyond_log.ready():
                applied = ('as sent: the linear plant has no actuator' if self.plant.model
                           == 'linear' else f'at the limit by the {self.plant.model} '
                           "plant's actuator")
                self.get_logger().warn(f'steering {angle:+.4f} rad for t = '
                                       f'{stamp * 1e-9:g} s beyond plant.max_steering_angle '
                                       f'{limit:g} rad: applied {applied} ({self.beyond} '
                                       'beyond)')
        if self.params['mode'] == 'realtime':
            self.command = angle
            self.answered_stamp = stamp
            return
        if self.waiting_stamp is not None and stamp == self.waiting_stamp:
            self.command = angle
            self.answered_stamp = stamp
            self.waiting_stamp = None
            self.lockstep_advance()
        elif stamp in self._missed_sent:
            # the miss was the answer's lateness, not its absence: say so (a loaded
            # controller or probe), with the delay measured on this node's clock
            self.late += 1
            delay = time.monotonic() - self._missed_sent.pop(stamp)
            self.get_logger().warn(f'late steering for t = {stamp * 1e-9:g} s: '
                                   f'{delay:.3f} s after the step (deadline '
                                   f'{self.params["deadline"]:g} s), not applied')

    # -- lockstep -------------------------------------------------------------------

    def connected(self) -> bool:
        """
        Return True once every contract topic and the steering topic are matched.

        Matched (the middleware's count), not discovered (the graph's count): a
        subscriber is in the graph before its readers are matched to our writers, and a
        step published into that gap is lost to it.
        """
        wanted = self.params['subscribers']
        # vehicle output: the bridge (and a recorder) on odometry, the bridge on the path
        pubs = ((self.pub_odometry,) if self.vehicle_output else
                (self.pub_lateral, self.pub_yaw, self.pub_velocity, self.pub_curvature))
        if self.vehicle_output and self.pub_path.get_subscription_count() < 1:
            return False
        # steering: the controller publishes it; a recorder subscribes to it like this
        # node does (the graph's count: their match is not visible from here)
        return (all(pub.get_subscription_count() >= wanted for pub in pubs)
                and self.pub_truth.get_subscription_count() >= wanted - 1
                and self.sub_steering.get_publisher_count() > 0
                and self.count_subscribers(self.sub_steering.topic_name) >= wanted)

    def settled(self) -> bool:
        """
        Return True once :meth:`connected` has held for ``settle`` seconds.

        The simulator sees its own matches and who subscribes to ``steering``, but not
        whether a recorder is matched to the controller's other topics (its debug
        output): a recorder polling the graph subscribes to them up to one poll later.
        """
        if not self.connected():
            self._connected_since = None
            return False
        now = time.monotonic()
        if self._connected_since is None:
            self._connected_since = now
        return now - self._connected_since >= self.params['settle']

    def shared_clock(self) -> Optional[str]:
        """
        Return a warning, once, if another node publishes this simulator's ``/clock``.

        Two simulators on one ``/clock`` (vehicles in namespaces, a replay with
        ``--clock``) drive every ``use_sim_time`` node by both clocks: inputs refused as
        ahead of or behind its clock, missed deadlines (a real two-car lockstep run).

        :return: the warning the first time the clock is shared, else None.
        """
        topic = self.pub_clock.topic_name
        if self._clock_shared or self.count_publishers(topic) < 2:
            return None
        self._clock_shared = True
        namespace = self.get_namespace().rstrip('/') or '/<vehicle>'
        return (f'another node publishes {topic}: a controller with use_sim_time follows '
                f"both clocks; start each vehicle's nodes with -r /clock:={namespace}/clock")

    def on_poll(self) -> None:
        """Start once the controller is connected; enforce the deadline."""
        if self.done.done():
            return
        warning = self.shared_clock() if self._clock_check.ready() else None
        if warning:
            self.get_logger().warn(warning)
        if self.waiting_stamp is None and self.k == 0 and self.answered_stamp is None:
            if not self.settled():
                return
            self.answered_stamp = -1
            self.waiting_stamp = self.publish_measurements()
            self.sent_at = self.started_at = time.monotonic()
            return
        if (self.vehicle_output and self.k == 0 and self.waiting_stamp == 0
                and time.monotonic() - self._resent_at > 0.05):
            # through a bridge, step 0 can reach it before the controller's subscriptions
            # to the bridge are matched (invisible from here): repeat it until answered
            self._resent_at = time.monotonic()
            self.pub_imu.publish(self._imu)
            self.pub_odometry.publish(self._odometry)
        # step 0 through a bridge: up to 10 deadlines for the chain to connect
        deadline = self.params['deadline'] * (10 if self.vehicle_output and self.k == 0 else 1)
        if (self.waiting_stamp is not None
                and time.monotonic() - self.sent_at > deadline):
            self.missed += 1
            self._missed_sent[self.waiting_stamp] = self.sent_at
            # one line a miss (a miss costs the deadline's wall time): which steps missed
            self.get_logger().warn(f'no steering for t = {self.waiting_stamp * 1e-9:g} s '
                                   f'within {self.params["deadline"]:g} s: holding '
                                   f'{self.command:+.4f} rad ({self.missed} missed'
                                   f'{self._refused_since()})')
            self.waiting_stamp = None
            self.lockstep_advance()

    def lockstep_advance(self) -> None:
        """Integrate one period and publish the next step (or finish)."""
        self.integrate()
        if self.failure or self.finished():
            return
        self.waiting_stamp = self.publish_measurements()
        self.sent_at = time.monotonic()

    # -- realtime -------------------------------------------------------------------

    def on_realtime_tick(self) -> None:
        """Publish the current step, then integrate one period with the latest command."""
        if self.done.done():
            return
        if self.k == 0:
            if not self.loop_closed():
                return
            self.started_at = time.monotonic()
        if self.k > 0 and self.answered_stamp != self.stamp_ns(self.k - 1):
            self.missed += 1
            if self._miss_log.ready():
                self.get_logger().warn(
                    f'no steering for t = {(self.k - 1) * self.period:g} s within one '
                    f'period: applying {self.command:+.4f} rad ({self.missed} missed'
                    f'{self._refused_since()})')
        self.publish_measurements()
        self.integrate()
        self.finished()

    def loop_closed(self) -> bool:
        """
        Return True once the controller answered, or did not within ``deadline``.

        Until then step 0 is repeated: discovery says a controller exists before its
        topics are all matched, and steps published into that gap would count as missed.
        A controller that cannot answer step 0 (a sim-time timer does not fire at t = 0)
        starts the clock after ``deadline``.
        """
        if self.answered_stamp is not None:
            return True
        if not self.settled():
            return False
        now = time.monotonic()
        if not self.sent_at:
            self.sent_at = now
        if now - self.sent_at > self.params['deadline']:
            return True
        self.publish_measurements()
        return False


def finished(node: SimPlantNode) -> bool:
    """
    Return True once the run is over; raise if it ended in a failure.

    :param node: the simulator.
    :return: the run is over.
    :raises ParameterError: the plant diverged (``run_node`` prints it in one line).
    """
    if node.failure:
        raise ParameterError(node.failure)
    return node.done.done()


def main(args: Optional[list[str]] = None) -> int:
    """
    Run the simulator until the scenario ends or it is stopped.

    :param args: command-line arguments (ROS arguments included).
    :return: exit code.
    """
    return run_node('sim_plant', args, SimPlantNode, finished,
                    specs=ALL_SPECS, description='plant simulator: publishes the '
                    "controller's inputs for a scenario, integrates its steering",
                    check=check_parameters)


def entry() -> int:
    """Entry point of ``sim_plant``."""
    return end_process(main(sys.argv))


if __name__ == '__main__':
    sys.exit(entry())
