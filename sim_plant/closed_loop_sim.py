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
Offline closed loop (no DDS): plant + controller core, one run or a vectorized batch.

The controller samples the plant every ``control_period`` and holds its command (zero-
order hold), as the ROS system does; ``control_period = 0`` evaluates the law inside
every integrator stage (the continuous-time loop the paper analyses). The plant is
integrated with fixed-step RK4 at ``dt``.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Callable, Iterator

from lookahead_control.core.control_law import LateralState, LawOutput, steering_law
from lookahead_control.core.numeric import Real
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
import numpy as np
import numpy.typing as npt
from sim_plant.scenario import Scenario
from sim_plant.speed_profile import speed_at
from sim_plant.vehicle_model import derivatives, PlantParams, rk4_step, State


Array = npt.NDArray[np.float64]
CHANNELS = ('s', 'y_cg', 'eps_r', 'v_y', 'r', 'steering', 'v_x', 'a_x', 'rho',
            'steering_cmd', 'd_v', 'y_v', 'y_ref', 'error', 'error_rate')


@dataclass(frozen=True)
class SimResult:
    """
    Time series of one run (arrays of shape (T,)) or a batch (shape (T, N)).

    :param time: sample times [s].
    :param channels: one array per name in ``CHANNELS`` (SI units, REP-103 signs).
    :param scenario: the scenario that was run.
    :param vehicle: the vehicle parameters.
    :param controller: the controller parameters.
    :param plant: the plant options.
    """

    time: Array
    channels: dict[str, Array]
    scenario: Scenario
    vehicle: VehicleParams
    controller: ControllerParams
    plant: PlantParams

    def __getitem__(self, name: str) -> Array:
        """
        Return one channel.

        :param name: a name from ``CHANNELS``.
        :return: its array.
        """
        return self.channels[name]


def check_steps(dt: float, control_period: float, duration: float) -> tuple[int, int]:
    """
    Return ``(plant steps per control step, number of control steps)``.

    :param dt: plant integration step [s].
    :param control_period: controller period [s], 0 for continuous control.
    :param duration: simulated time [s].
    :return: the two step counts.
    """
    if not (math.isfinite(dt) and 0.0 < dt <= 0.1):
        raise ParameterError(f'dt = {dt!r} s is out of range; allowed: (0, 0.1] s')
    if not math.isfinite(control_period) or control_period < 0.0:
        raise ParameterError(f'control_period = {control_period!r} s must be >= 0')
    period = control_period if control_period > 0.0 else dt
    ratio = round(period / dt)
    if ratio < 1 or abs(ratio * dt - period) > 1e-9 * max(period, 1.0):
        raise ParameterError(f'control_period = {control_period!r} s is not a whole '
                             f'multiple of dt = {dt!r} s')
    return ratio, int(round(duration / period))


def measure(x: State, t: float, scenario: Scenario, initial_speed: Real,
            acceleration: Real) -> LateralState:
    """
    Return what the controller sees of the plant state (ideal sensors).

    :param x: plant state.
    :param t: time [s].
    :param scenario: the scenario (road, speed profile).
    :param initial_speed: initial speed(s) [m/s].
    :param acceleration: ramp acceleration(s) [m/s^2].
    :return: the controller's inputs.
    """
    v_x, a_x = speed_at(t, initial_speed, acceleration, scenario.speed.start,
                        scenario.speed.duration)
    rho, rho_slope = scenario.road.curvature(x[0])
    return LateralState(x[1], x[2], x[3], x[4], v_x, a_x, rho, v_x * rho_slope)


def plant_derivatives(scenario: Scenario, vehicle: VehicleParams, plant: PlantParams,
                      command: Real, initial_speed: Real,
                      acceleration: Real) -> Callable[[float, State], State]:
    """
    Return the plant's right-hand side ``f(t, x)`` for a held steering command.

    :param scenario: road and speed profile.
    :param vehicle: vehicle parameters.
    :param plant: plant options.
    :param command: the steering command held over the step [rad].
    :param initial_speed: initial speed(s) [m/s].
    :param acceleration: ramp acceleration(s) [m/s^2].
    :return: the right-hand side.
    """
    def rhs(t: float, state: State) -> State:
        v_x, a_x = speed_at(t, initial_speed, acceleration, scenario.speed.start,
                            scenario.speed.duration)
        rho, _ = scenario.road.curvature(state[0])
        return derivatives(state, command, v_x, a_x, rho, vehicle, plant)
    return rhs


Stepper = Callable[[State, float, float, int, float], State]


def linear_plant_stepper(scenario: Scenario, vehicle: VehicleParams, plant: PlantParams,
                         initial_speed: float, acceleration: float) -> Stepper:
    """
    Return ``step(x, t, dt, substeps, command)`` for one run of the linear plant.

    It gives what :func:`advance` with :func:`plant_derivatives` gives, to the last bit
    (the same operations in the same order), in a third of the time: the equations of
    :func:`~sim_plant.vehicle_model.derivatives` for the linear plant and the float path
    of :func:`~sim_plant.speed_profile.speed_at`, on plain floats with the constants
    bound once. The simulator node integrates every step with it.

    :param scenario: road and speed profile.
    :param vehicle: vehicle parameters.
    :param plant: plant options (``model`` must be ``linear``).
    :param initial_speed: initial speed [m/s].
    :param acceleration: ramp acceleration [m/s^2].
    :return: the stepper.
    :raises ValueError: the plant is not the linear one.
    """
    if plant.model != 'linear':
        raise ValueError(f'plant.model = {plant.model!r}: the stepper is for the linear plant')
    c_f, neg_c_r, l1, l2 = vehicle.c_f, -vehicle.c_r, vehicle.l1, vehicle.l2
    mass, inertia = vehicle.mass, vehicle.yaw_inertia
    start, duration = scenario.speed.start, scenario.speed.duration
    constant = acceleration == 0.0          # initial + 0.0 * ramp == initial
    exact = plant.kinematics == 'exact'
    curvature = scenario.road.curvature_function()
    sin, cos = math.sin, math.cos

    def rates(t: float, s: float, y: float, e: float, v_y: float, r: float,
              u: float) -> tuple[float, float, float, float, float]:
        v_x = initial_speed if constant else (
            initial_speed + acceleration * min(max(t - start, 0.0), duration))
        rho = curvature(s)
        f_front = c_f * (u - (v_y + l1 * r) / v_x)
        f_rear = neg_c_r * (v_y - l2 * r) / v_x
        if exact:
            sin_e, cos_e = sin(e), cos(e)
            s_rate = (v_x * cos_e - v_y * sin_e) / (1.0 - rho * y)
            y_rate = v_x * sin_e + v_y * cos_e
        else:
            s_rate = v_x + 0.0 * y
            y_rate = v_y + v_x * e
        return (s_rate, y_rate, r - rho * s_rate, (f_front + f_rear) / mass - v_x * r,
                (l1 * f_front - l2 * f_rear) / inertia)

    def step(x: State, t: float, dt: float, substeps: int, command: float) -> State:
        s, y, e, v_y, r = float(x[0]), float(x[1]), float(x[2]), float(x[3]), float(x[4])
        u, half, w = command, 0.5 * dt, dt / 6.0
        for j in range(substeps):           # rk4_step, unrolled
            tj = t + j * dt
            a0, a1, a2, a3, a4 = rates(tj, s, y, e, v_y, r, u)
            b0, b1, b2, b3, b4 = rates(tj + half, s + half * a0, y + half * a1,
                                       e + half * a2, v_y + half * a3, r + half * a4, u)
            c0, c1, c2, c3, c4 = rates(tj + half, s + half * b0, y + half * b1,
                                       e + half * b2, v_y + half * b3, r + half * b4, u)
            d0, d1, d2, d3, d4 = rates(tj + dt, s + dt * c0, y + dt * c1, e + dt * c2,
                                       v_y + dt * c3, r + dt * c4, u)
            s = s + w * (a0 + 2.0 * b0 + 2.0 * c0 + d0)
            y = y + w * (a1 + 2.0 * b1 + 2.0 * c1 + d1)
            e = e + w * (a2 + 2.0 * b2 + 2.0 * c2 + d2)
            v_y = v_y + w * (a3 + 2.0 * b3 + 2.0 * c3 + d3)
            r = r + w * (a4 + 2.0 * b4 + 2.0 * c4 + d4)
        return (s, y, e, v_y, r, command)
    return step


def advance(rhs: Callable[[float, State], State], x: State, t: float, dt: float,
            substeps: int, plant: PlantParams, command: Real) -> State:
    """
    Integrate ``substeps`` RK4 steps of ``dt`` from time ``t``.

    :param rhs: the right-hand side.
    :param x: the state at ``t``.
    :param t: time [s].
    :param dt: step [s].
    :param substeps: number of steps.
    :param plant: plant options (the linear plant's wheel angle is the command).
    :param command: the held command [rad].
    :return: the state at ``t + substeps * dt``.
    """
    for j in range(substeps):
        x = rk4_step(rhs, t + j * dt, x, dt)
    if plant.model == 'linear':
        x = x[:5] + (command,)
    return x


def _progress(n: int, enabled: bool) -> Iterator[int]:
    if not enabled:
        return iter(range(n))
    from tqdm import tqdm
    return iter(tqdm(range(n), desc='simulating', unit='step', mininterval=0.5))


def run(scenario: Scenario, vehicle: VehicleParams, controller: ControllerParams,
        plant: PlantParams | None = None, *, dt: float = 0.001,
        control_period: float = 0.01, initial_speed: Real | None = None,
        initial_error: Real | None = None, progress: bool = False) -> SimResult:
    """
    Simulate the closed loop of plant and controller core.

    Passing arrays as ``initial_speed`` and/or ``initial_error`` runs a vectorized
    batch (one run per element) on the scenario's road.

    :param scenario: road, speed profile, initial state and duration.
    :param vehicle: vehicle parameters (used by plant and controller alike).
    :param controller: controller parameters.
    :param plant: plant options (default: linear, exact kinematics).
    :param dt: plant integration step [s].
    :param control_period: controller period [s]; 0 for continuous control.
    :param initial_speed: override of the scenario's initial speed [m/s] (array: batch).
    :param initial_error: override of the initial CG lateral error [m] (array: batch).
    :param progress: show a progress bar.
    :return: the time series.
    """
    plant = plant or PlantParams()
    ratio, n_steps = check_steps(dt, control_period, scenario.duration)
    v0: Real = scenario.speed.initial if initial_speed is None else initial_speed
    y0: Real = scenario.initial.lateral_error if initial_error is None else initial_error
    shape = np.broadcast(np.asarray(v0), np.asarray(y0)).shape
    batch = len(shape) > 0

    def fill(value: float | Real) -> Real:
        return np.full(shape, value, dtype=float) if batch else float(value)

    if batch and np.any(np.asarray(v0) <= 0.0):
        raise ParameterError('initial_speed must be positive in every run')
    v0, y0 = fill(v0), fill(y0)
    accel = fill(scenario.speed.acceleration)
    init = scenario.initial
    x: State = (fill(0.0), y0, fill(init.relative_yaw), fill(init.lateral_velocity),
                fill(init.yaw_rate), fill(0.0))

    def law(t: float, state: State) -> LawOutput:
        return steering_law(measure(state, t, scenario, v0, accel), vehicle, controller)

    def plant_rhs(command: Real) -> Callable[[float, State], State]:
        return plant_derivatives(scenario, vehicle, plant, command, v0, accel)

    def continuous_rhs(t: float, state: State) -> State:
        command = law(t, state).steering
        return plant_rhs(command)(t, state)

    rows: list[list[Any]] = []
    t = 0.0
    for k in _progress(n_steps + 1, progress):
        t = k * ratio * dt
        out = law(t, x)
        inputs = measure(x, t, scenario, v0, accel)
        steering = out.steering if plant.model == 'linear' else x[5]
        rows.append([x[0], x[1], x[2], x[3], x[4], steering, inputs.v_x, inputs.a_x,
                     inputs.rho, out.steering, out.d_v, out.y_v, out.y_ref, out.error,
                     out.error_rate])
        if k == n_steps:
            break
        rhs = continuous_rhs if control_period == 0.0 else plant_rhs(out.steering)
        x = advance(rhs, x, t, dt, ratio, plant, out.steering)
    time = np.arange(len(rows), dtype=float) * (ratio * dt)
    columns = list(zip(*rows))
    channels = {name: np.asarray(col, dtype=float) for name, col in zip(CHANNELS, columns)}
    return SimResult(time, channels, scenario, vehicle, controller, plant)
