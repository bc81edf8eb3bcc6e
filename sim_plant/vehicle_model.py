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
Plant models: the paper's linear single-track model and a nonlinear one.

State (a tuple; each entry a float for one run or an array for a batch):
``(s, y_cg, eps_r, v_y, r, delta)`` = arc length along the lane [m], lateral error of
the CG [m], relative yaw [rad], body lateral velocity [m/s], yaw rate [rad/s], actual
front-wheel angle [rad]. The longitudinal speed is prescribed (``SpeedProfile``).

- ``linear``: eq. 1 with linear tyres and ideal steering (``delta`` = command).
- ``nonlinear``: Fiala brush tyres saturating at ``mu F_z`` with static axle loads, the
  front force rotated by ``delta``, and a steering actuator with first-order lag,
  angle and rate limits.

Kinematics relative to the road: ``exact`` Frenet equations (the default) or the
``small_angle`` form the controller is designed on.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, Callable, Sequence

from lookahead_control.core import numeric as xp
from lookahead_control.core.numeric import Real
from lookahead_control.core.params import (axle_load_factors, check_choice, check_range,
                                           ParameterError, VehicleParams)
import numpy as np

State = tuple[Real, ...]
GRAVITY = 9.80665
PLANT_MODELS = ('linear', 'nonlinear', 'commonroad_st', 'commonroad_mb')
KINEMATICS = ('exact', 'small_angle')
STATE_NAMES = ('s', 'y_cg', 'eps_r', 'v_y', 'r', 'steering')


@dataclass(frozen=True)
class PlantParams:
    """
    Plant options beyond the single-track parameters.

    :param model: ``linear`` (the paper's eq. 1), ``nonlinear`` (Fiala tyres, actuator),
        ``commonroad_st`` or ``commonroad_mb`` (:mod:`sim_plant.commonroad_plant`).
    :param kinematics: ``exact`` Frenet kinematics or the ``small_angle`` design model.
    :param friction: tyre-road friction coefficient mu (nonlinear model) [-].
    :param steering_time_constant: actuator lag (nonlinear model) [s].
    :param max_steering_angle: actuator angle limit (nonlinear model) [rad].
    :param max_steering_rate: actuator rate limit (nonlinear model) [rad/s].
    :param vehicle_id: CommonRoad parameter set (1 Ford Escort, 2 BMW 320i, 3 VW
        Vanagon) of the CommonRoad models.
    """

    model: str = 'linear'
    kinematics: str = 'exact'
    friction: float = 1.0
    steering_time_constant: float = 0.05
    max_steering_angle: float = 0.6
    max_steering_rate: float = 0.8
    vehicle_id: int = 2

    def __post_init__(self) -> None:
        check_choice('plant.model', self.model, PLANT_MODELS)
        check_choice('plant.kinematics', self.kinematics, KINEMATICS)
        check_range('plant.friction', self.friction, 0.0, 2.0, low_open=True)
        check_range('plant.steering_time_constant', self.steering_time_constant, 0.0, 2.0,
                    low_open=True, unit='s')
        check_range('plant.max_steering_angle', self.max_steering_angle, 0.0, 1.2,
                    low_open=True, unit='rad')
        check_range('plant.max_steering_rate', self.max_steering_rate, 0.0, 20.0,
                    low_open=True, unit='rad/s')
        if self.vehicle_id not in (1, 2, 3, 4) or isinstance(self.vehicle_id, bool):
            raise ParameterError(f'plant.vehicle_id = {self.vehicle_id!r} is not allowed; '
                                 'choose one of 1, 2, 3 (CommonRoad parameter sets)')


class Stacked:
    """
    Frozen parameter dataclasses of a batch, one per run, as one duck-typed object.

    Each numeric field is an array of shape ``(N,)`` (or the float itself when every run
    has the same value); text fields must agree. ``wheelbase`` (and ``eta``) are
    computed like :class:`~lookahead_control.core.params.VehicleParams` does.
    """

    def __init__(self, items: Sequence[Any]) -> None:
        """
        Stack the items.

        :param items: dataclass instances of one type, at least one.
        :raises ParameterError: the list is empty, or a text field differs.
        """
        if not items:
            raise ParameterError('a batch needs at least one parameter set')
        kind = type(items[0])
        for item in fields(kind):
            values = [getattr(i, item.name) for i in items]
            if isinstance(values[0], str):
                if len(set(values)) > 1:
                    raise ParameterError(f'{item.name} differs within a batch '
                                         f'({sorted(set(values))}); run one batch each')
                setattr(self, item.name, values[0])
            elif all(v == values[0] for v in values):
                setattr(self, item.name, float(values[0]))
            else:
                setattr(self, item.name, np.array(values, dtype=float))
        self.items = tuple(items)
        self.l1: Any
        self.l2: Any
        if hasattr(self, 'l1') and hasattr(self, 'l2'):
            self.wheelbase = self.l1 + self.l2
            self.eta = getattr(self, 'mass') * self.l1 / (getattr(self, 'c_r') * self.wheelbase)


def stack(items: Sequence[Any]) -> Any:
    """
    Return one parameter set when all runs share it, else a :class:`Stacked` of them.

    :param items: one frozen parameter dataclass per run.
    :return: the shared instance or the stacked batch.
    """
    if items and all(i == items[0] for i in items):
        return items[0]
    return Stacked(items)


def fiala_force(slip: Real, stiffness: Real, limit: Real) -> Real:
    """
    Return the lateral force of a Fiala brush tyre (axle) at slip angle ``slip``.

    Linear for small slip (``-C tan(alpha)``), saturating at ``limit = mu F_z``.

    :param slip: slip angle alpha [rad].
    :param stiffness: cornering stiffness C [N/rad].
    :param limit: friction limit mu F_z [N].
    :return: lateral force [N], opposing the slip.
    """
    z = xp.tan(slip)
    a = xp.absolute(z)
    inside = (stiffness * z * (-1.0 + stiffness * a / (3.0 * limit))
              - stiffness ** 3 * z * z * z / (27.0 * limit * limit))
    outside = -limit * xp.sign(z)
    return xp.where(a < 3.0 * limit / stiffness, inside, outside)


def axle_forces(vehicle: VehicleParams, plant: PlantParams, v_x: Real, v_y: Real, r: Real,
                steering: Real, a_x: Real = 0.0) -> tuple[Real, Real]:
    """
    Return the front and rear lateral axle forces in the wheel frames [N].

    The nonlinear plant moves load between the axles under ``a_x`` when
    ``vehicle.cg_height`` > 0 (``axle_load_factors``): each Fiala tyre's stiffness and
    friction limit with its axle's load. The linear plant is the paper's model: none.

    :param vehicle: vehicle parameters.
    :param plant: plant options (model, friction).
    :param v_x: longitudinal speed [m/s].
    :param v_y: body lateral velocity [m/s].
    :param r: yaw rate [rad/s].
    :param steering: actual front-wheel angle [rad].
    :param a_x: dv_x/dt [m/s^2] (the axle loads).
    :return: ``(F_yf, F_yr)``.
    """
    if plant.model == 'linear':
        f_front = vehicle.c_f * (steering - (v_y + vehicle.l1 * r) / v_x)
        f_rear = -vehicle.c_r * (v_y - vehicle.l2 * r) / v_x
        return f_front, f_rear
    load = vehicle.mass * GRAVITY / vehicle.wheelbase
    slip_f = xp.atan2(v_y + vehicle.l1 * r, v_x) - steering
    slip_r = xp.atan2(v_y - vehicle.l2 * r, v_x)
    c_f: Real = vehicle.c_f
    c_r: Real = vehicle.c_r
    limit_f: Real = plant.friction * load * vehicle.l2
    limit_r: Real = plant.friction * load * vehicle.l1
    if vehicle.cg_height > 0.0:
        front, rear = axle_load_factors(vehicle, a_x)
        c_f, c_r = c_f * front, c_r * rear
        limit_f, limit_r = limit_f * front, limit_r * rear
    f_front = fiala_force(slip_f, c_f, limit_f)
    f_rear = fiala_force(slip_r, c_r, limit_r)
    return f_front, f_rear


def actuator_rate(plant: PlantParams, steering: Real, command: Real) -> Real:
    """
    Return d delta / dt of the first-order, angle- and rate-limited actuator.

    :param plant: plant options (time constant, limits).
    :param steering: actual angle [rad].
    :param command: commanded angle [rad].
    :return: steering rate [rad/s].
    """
    target = xp.clip(command, -plant.max_steering_angle, plant.max_steering_angle)
    return xp.clip((target - steering) / plant.steering_time_constant,
                   -plant.max_steering_rate, plant.max_steering_rate)


def derivatives(x: State, command: Real, v_x: Real, a_x: Real, rho: Real,
                vehicle: VehicleParams, plant: PlantParams) -> State:
    """
    Return dx/dt of the plant state.

    :param x: state ``(s, y_cg, eps_r, v_y, r, steering)``.
    :param command: steering command [rad].
    :param v_x: longitudinal speed [m/s].
    :param a_x: longitudinal acceleration [m/s^2] (the nonlinear plant's axle loads, with
        ``vehicle.cg_height``).
    :param rho: road curvature at ``s`` [1/m].
    :param vehicle: vehicle parameters.
    :param plant: plant options.
    :return: the state derivative.
    """
    _, y_cg, eps_r, v_y, r, steering = x
    if plant.model == 'linear':
        steering = command
        steering_rate: Real = 0.0 * command
        f_front, f_rear = axle_forces(vehicle, plant, v_x, v_y, r, steering)
        lateral = f_front + f_rear
        moment = vehicle.l1 * f_front - vehicle.l2 * f_rear
    else:
        steering_rate = actuator_rate(plant, steering, command)
        f_front, f_rear = axle_forces(vehicle, plant, v_x, v_y, r, steering, a_x)
        f_front = f_front * xp.cos(steering)
        lateral = f_front + f_rear
        moment = vehicle.l1 * f_front - vehicle.l2 * f_rear
    if plant.kinematics == 'exact':
        sin_e, cos_e = xp.sin(eps_r), xp.cos(eps_r)
        s_rate = (v_x * cos_e - v_y * sin_e) / (1.0 - rho * y_cg)
        y_rate = v_x * sin_e + v_y * cos_e
    else:
        s_rate = v_x + 0.0 * y_cg
        y_rate = v_y + v_x * eps_r
    return (s_rate, y_rate, r - rho * s_rate, lateral / vehicle.mass - v_x * r,
            moment / vehicle.yaw_inertia, steering_rate)


def rk4_step(f: Callable[[float, State], State], t: float, x: State, h: float) -> State:
    """
    Advance ``x' = f(t, x)`` by one classical Runge-Kutta step.

    :param f: the right-hand side, returning a tuple like ``x``.
    :param t: time [s].
    :param x: state tuple (floats or equally shaped arrays).
    :param h: step [s].
    :return: the state at ``t + h``.
    """
    k1 = f(t, x)
    k2 = f(t + 0.5 * h, _axpy(x, 0.5 * h, k1))
    k3 = f(t + 0.5 * h, _axpy(x, 0.5 * h, k2))
    k4 = f(t + h, _axpy(x, h, k3))
    w = h / 6.0
    if len(x) == 6:             # the plant state: unrolled, the scalar sim's hot loop
        return (x[0] + w * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
                x[1] + w * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]),
                x[2] + w * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2]),
                x[3] + w * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3]),
                x[4] + w * (k1[4] + 2.0 * k2[4] + 2.0 * k3[4] + k4[4]),
                x[5] + w * (k1[5] + 2.0 * k2[5] + 2.0 * k3[5] + k4[5]))
    return tuple(xi + w * (a + 2.0 * b + 2.0 * c + d)
                 for xi, a, b, c, d in zip(x, k1, k2, k3, k4))


def _axpy(x: Sequence[Real], a: float, k: Sequence[Real]) -> State:
    if len(x) == 6:
        return (x[0] + a * k[0], x[1] + a * k[1], x[2] + a * k[2], x[3] + a * k[3],
                x[4] + a * k[4], x[5] + a * k[5])
    return tuple(xi + a * ki for xi, ki in zip(x, k))
