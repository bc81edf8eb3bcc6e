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
The CommonRoad vehicle models as plants (PyPI ``commonroad-vehicle-models``).

Two of its models: ``commonroad_st`` (single-track, linear tyres with load transfer
from the longitudinal acceleration, the model's kinematic switch below 0.1 m/s) and
``commonroad_mb`` (multi-body: 29 states, roll, pitch, suspension, Pacejka tyres, wheel
spin). Each is integrated in global coordinates (RK4 at the runner's ``dt``) on the
scenario's road laid out by :class:`~sim_plant.road_geometry.Centreline`, and its pose
is projected on the lane to give the contract: arc length, lateral error, relative yaw,
body lateral velocity, yaw rate, wheel angle.

Inputs: the model takes a steering-angle *rate* and a longitudinal acceleration. The
steering rate is that of the first-order actuator of
:class:`~sim_plant.vehicle_model.PlantParams` (``steering_time_constant``, rate and angle
limits), then the model's own limits (for the passenger cars, 0.4 rad/s and about
1 rad). The acceleration follows the scenario's speed profile: its acceleration plus
``2 1/s`` times the speed error, within the model's acceleration limits (about 2.3
m/s^2 at 37 m/s for parameter set 2), so the plant's speed may lag the profile; the law
gets the plant's own speed.

Parameter sets (``vehicle_id``): 1 Ford Escort, 2 BMW 320i, 3 VW Vanagon. Set 4 (a
semi-trailer truck) has no mass, inertia or tyre data in the package (it serves its
kinematic trailer model only) and is refused with that reason.
"""

from __future__ import annotations

import dataclasses
from functools import lru_cache
import math
from typing import Any, Callable

from lookahead_control.core.params import ParameterError, VehicleParams
from sim_plant.road_geometry import Centreline
from sim_plant.scenario import Scenario
from sim_plant.speed_profile import profile_speed

COMMONROAD_MODELS = ('commonroad_st', 'commonroad_mb')
PARAMETER_SETS = {1: 'Ford Escort', 2: 'BMW 320i', 3: 'VW Vanagon',
                  4: 'semi-trailer truck'}
SPEED_GAIN = 2.0        # 1/s: the speed loop giving the longitudinal acceleration
GRAVITY = 9.81          # the package's value


@lru_cache(maxsize=None)
def commonroad_parameters(vehicle_id: int) -> Any:
    """
    Return the package's parameters of set ``vehicle_id`` (an OmegaConf config).

    :param vehicle_id: 1, 2 or 3.
    :return: the parameters.
    :raises ParameterError: an unknown set, or set 4 (no dynamics data).
    """
    if vehicle_id not in PARAMETER_SETS:
        raise ParameterError(f'plant.vehicle_id = {vehicle_id!r} is not a CommonRoad '
                             f'parameter set; choose one of 1, 2, 3')
    if vehicle_id == 4:
        raise ParameterError('plant.vehicle_id = 4 (semi-trailer truck) has no mass, '
                             'inertia or tyre data in commonroad-vehicle-models: only its '
                             'kinematic trailer model uses it; choose 1, 2 or 3')
    from vehiclemodels.vehicle_parameters import setup_vehicle_parameters
    return setup_vehicle_parameters(vehicle_id=vehicle_id)


def controller_vehicle(vehicle_id: int) -> VehicleParams:
    """
    Return this package's single-track parameters matching a CommonRoad set.

    Mass ``m``, yaw inertia ``I_z``, axle distances ``a`` and ``b`` are taken as they
    are. The single-track model's lateral axle force is ``mu C_S F_z alpha`` with static
    axle load ``F_z`` (front ``m g b / l``), ``mu = p_dy1`` and ``C_S = -p_ky1 / p_dy1``,
    so the axle cornering stiffness is ``c_f = -p_ky1 m g b / l`` and ``c_r = -p_ky1 m g
    a / l``. The multi-body model's Pacejka tyres have about this stiffness at small
    slip (not exactly: that is part of what it tests), in proportion to their load.
    ``d_s`` (the bumper) is half the vehicle length. ``cg_height`` is the whole car's CG
    height: the sprung mass at ``h_s``, the unsprung masses at the wheel radius ``R_w``
    (0.582 m for set 2): under ``a_x`` the multi-body model moves load between the axles.

    :param vehicle_id: 1, 2 or 3.
    :return: the controller's vehicle model.
    """
    p = commonroad_parameters(vehicle_id)
    wheelbase = p.a + p.b
    stiffness = -p.tire.p_ky1 * p.m * GRAVITY
    height = (p.m_s * p.h_s + (p.m_uf + p.m_ur) * p.R_w) / (p.m_s + p.m_uf + p.m_ur)
    return VehicleParams(mass=p.m, yaw_inertia=p.I_z, l1=p.a, l2=p.b,
                         c_f=stiffness * p.b / wheelbase, c_r=stiffness * p.a / wheelbase,
                         d_s=0.5 * p.l, cg_height=height)


def controller_vehicle_params(vehicle_id: int) -> dict[str, float]:
    """
    Return :func:`controller_vehicle` as the controller node's ``vehicle.*`` parameters.

    What ``closed_loop --plant commonroad_*`` and the launch file give the controller.

    :param vehicle_id: 1, 2 or 3.
    :return: ``{'vehicle.mass': ..., ...}``.
    """
    car = controller_vehicle(vehicle_id)
    return {f'vehicle.{f.name}': float(getattr(car, f.name)) for f in dataclasses.fields(car)}


def _rk4(f: Callable[[list[float]], list[float]], x: list[float], h: float) -> list[float]:
    k1 = f(x)
    k2 = f([a + 0.5 * h * b for a, b in zip(x, k1)])
    k3 = f([a + 0.5 * h * b for a, b in zip(x, k2)])
    k4 = f([a + h * b for a, b in zip(x, k3)])
    w = h / 6.0
    return [a + w * (b + 2.0 * c + 2.0 * d + e) for a, b, c, d, e in zip(x, k1, k2, k3, k4)]


class CommonRoadPlant:
    """One run of a CommonRoad model on a scenario's road."""

    def __init__(self, scenario: Scenario, plant: Any, initial_speed: float,
                 initial_error: float) -> None:
        """
        Place the vehicle on the road at ``s = 0`` with the scenario's initial state.

        :param scenario: road, speed profile and initial state.
        :param plant: :class:`~sim_plant.vehicle_model.PlantParams` (model, vehicle_id,
            actuator).
        :param initial_speed: initial speed [m/s].
        :param initial_error: initial CG lateral error [m].
        """
        self.scenario = scenario
        self.plant = plant
        self.multibody = plant.model == 'commonroad_mb'
        self.p = commonroad_parameters(plant.vehicle_id)
        self.line = Centreline(scenario.road)
        self.initial_speed = initial_speed
        init = scenario.initial
        x, y, yaw = self.line.pose(0.0, initial_error, init.relative_yaw)
        beta = math.atan2(init.lateral_velocity, initial_speed)
        speed = math.hypot(initial_speed, init.lateral_velocity)
        core = [x, y, 0.0, speed, yaw, init.yaw_rate, beta]
        if self.multibody:
            from vehiclemodels.init_mb import init_mb
            from vehiclemodels.vehicle_dynamics_mb import vehicle_dynamics_mb
            self.state = [float(v) for v in init_mb(core, self.p)]
            self._f = vehicle_dynamics_mb
        else:
            from vehiclemodels.vehicle_dynamics_st import vehicle_dynamics_st
            self.state = core
            self._f = vehicle_dynamics_st
        self.s = 0.0
        self.command = 0.0                        # the last command held (acceleration)
        self.diverged_at: float | None = None     # [s] the step the model failed in
        self.failure = ''                         # what failed, one line

    def body_velocity(self, x: list[float]) -> tuple[float, float]:
        """
        Return the body velocity ``(v_x, v_y)`` at the CG of a model state.

        :param x: model state.
        :return: ``(v_x, v_y)`` [m/s].
        """
        if self.multibody:
            return x[3], x[10]
        return x[3] * math.cos(x[6]), x[3] * math.sin(x[6])

    def contract(self) -> tuple[tuple[float, ...], float, float]:
        """
        Return the contract state, the plant's speed and the curvature at the CG.

        :return: ``((s, y_cg, eps_r, v_y, r, steering), v_x, rho)`` (once the run has
            diverged: of its last finite state).
        """
        x = self.state
        lane = self.line.frenet(x[0], x[1], x[4], self.s)
        self.s = lane.s
        v_x, v_y = self.body_velocity(x)
        return ((lane.s, lane.lateral, lane.relative_yaw, v_y, x[5], x[2]), v_x,
                lane.curvature)

    def acceleration(self, t: float) -> float:
        """
        Return the model's ``dv_x/dt`` now: what the car's IMU measures (plus ``v_y r``).

        Not the speed profile's: the model follows the profile through its drivetrain
        and a speed controller, and goes on accelerating after the profile's ramp ends
        (S5: about 2 m/s^2 for a second). Before, the law and the simulator's IMU were
        given the profile's ``a_x`` on this plant.

        :param t: time [s] (the speed controller's reference).
        :return: ``dv_x/dt`` [m/s^2] of the body-frame speed at the CG (0 once the run
            has diverged).
        """
        if self.diverged_at is not None:
            return 0.0
        x = self.state
        try:
            rates = self._f(x, self._inputs(t, x, self.command), self.p)
        except (ZeroDivisionError, OverflowError, ValueError, FloatingPointError):
            return 0.0
        if self.multibody:
            return float(rates[3])
        # single track: v_x = v cos(beta)
        return float(rates[3] * math.cos(x[6]) - x[3] * math.sin(x[6]) * rates[6])

    def _inputs(self, t: float, x: list[float], command: float) -> list[float]:
        plant = self.plant
        target = min(max(command, -plant.max_steering_angle), plant.max_steering_angle)
        rate = min(max((target - x[2]) / plant.steering_time_constant,
                       -plant.max_steering_rate), plant.max_steering_rate)
        v_ref, a_ref = profile_speed(self.scenario.speed, t, self.initial_speed,
                                     self.scenario.speed.acceleration)
        v_x, _ = self.body_velocity(x)
        return [rate, float(a_ref) + SPEED_GAIN * (float(v_ref) - v_x)]

    def _pushed(self, rates: Any, x: list[float], force: float,
                moment: float) -> list[float]:
        """
        Return the model's rates with an external force and yaw moment on the body.

        Multi-body: the force acts on the sprung mass at its CG (the body's lateral
        velocity ``x[10]``), the moment about its yaw axis with the model's own roll-yaw
        coupling (``I_xz_s``). Single track: the force in the body frame splits into the
        speed's and the slip angle's rates. Below 0.1 m/s both models are kinematic (the
        tyres hold the car): nothing is added there.

        :param rates: the model's rates at ``x``.
        :param x: model state.
        :param force: lateral force [N, + left].
        :param moment: yaw moment [N m, + left].
        :return: the rates with the push.
        """
        out = [float(v) for v in rates]
        p = self.p
        if abs(x[3]) < 0.1:             # both models are kinematic there: no slip to push
            return out
        if self.multibody:
            out[10] += force / p.m_s
            # the model's yaw and roll rows: (I_z - I_xz^2 / I_Phi) r' = N + I_xz / I_Phi L
            out[5] += moment / (p.I_z - p.I_xz_s ** 2 / p.I_Phi_s)
            out[7] += (p.I_xz_s / p.I_z * moment) / (p.I_Phi_s - p.I_xz_s ** 2 / p.I_z)
            return out
        speed, beta = x[3], x[6]
        out[3] += force * math.sin(beta) / p.m
        out[6] += force * math.cos(beta) / (p.m * speed)
        out[5] += moment / p.I_z
        return out

    def advance(self, t: float, dt: float, command: float) -> bool:
        """
        Integrate one RK4 step of ``dt`` from ``t`` with a held steering command.

        A failure inside the model (``ZeroDivisionError`` when a wheel's longitudinal
        speed is clamped to exactly 0 while the car moves, ``OverflowError``,
        ``ValueError``, ``FloatingPointError``) or a non-finite state means the run
        **diverged**: the state stays at its last finite value, :attr:`diverged_at`
        holds ``t`` and every later call does nothing.

        :param t: time [s].
        :param dt: step [s].
        :param command: the commanded wheel angle [rad].
        :return: the run is still going (False once it has diverged).
        """
        if self.diverged_at is not None:
            return False
        self.command = command
        f, p = self._f, self.p
        # the inputs and the scenario's external force are evaluated once per step (a
        # zero-order hold at dt), as the CommonRoad examples do with the inputs
        force, moment = self.scenario.external(t)
        try:
            u = self._inputs(t, self.state, command)
            if force == 0.0 and moment == 0.0:
                state = _rk4(lambda z: [float(v) for v in f(z, u, p)], self.state, dt)
            else:
                state = _rk4(lambda z: self._pushed(f(z, u, p), z, force, moment),
                             self.state, dt)
        except (ZeroDivisionError, OverflowError, ValueError, FloatingPointError) as err:
            self.diverged_at, self.failure = t, f'{type(err).__name__}: {err}'
            return False
        if not all(math.isfinite(v) for v in state):
            self.diverged_at, self.failure = t, 'a non-finite state'
            return False
        self.state = state
        return True
