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
Offline closed loop (no DDS): plant + any steering law, one run or a vectorized batch.

The law (:class:`~lookahead_control.core.laws.Law`) samples the plant every
``control_period`` and its command is held (zero-order hold), as the ROS system does;
``control_period = 0`` evaluates the law inside every integrator stage (the
continuous-time loop the paper analyses). The plant is integrated with fixed-step RK4 at
``dt``. Between law and plant: a transport delay (control to wheel, whole plant steps);
between plant and law: sensor noise (:mod:`sim_plant.sensors`); on the plant: a lateral
force and yaw moment disturbance. A batch varies speed, initial error, plant parameters,
delay, noise seed and (through the law) gains, one run per element.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math
from typing import Any, Callable, Iterator, Sequence

from lookahead_control.core.control_law import LateralState
from lookahead_control.core.laws import Law, PaperLaw, Preview
from lookahead_control.core.numeric import Real
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
import numpy as np
import numpy.typing as npt
from sim_plant.commonroad_plant import COMMONROAD_MODELS, CommonRoadPlant
from sim_plant.road import RoadBatch
from sim_plant.scenario import check_force_timing, Scenario
from sim_plant.sensors import check_seed, noise_table, NoiseParams
from sim_plant.speed_profile import profile_speed, ramps_speed
from sim_plant.vehicle_model import derivatives, PlantParams, rk4_step, stack, State


Array = npt.NDArray[np.float64]
#: the controller's period when a caller gives none [s] (the node's 100 Hz)
CONTROL_PERIOD = 0.01
CHANNELS = ('s', 'y_cg', 'eps_r', 'v_y', 'r', 'steering', 'v_x', 'a_x', 'rho',
            'steering_cmd', 'd_v', 'y_v', 'y_ref', 'error', 'error_rate')
Disturbance = Callable[[float], tuple[Real, Real]]


@dataclass(frozen=True)
class SimResult:
    """
    Time series of one run (arrays of shape (T,)) or a batch (shape (T, N)).

    :param time: sample times [s].
    :param channels: one array per name in ``CHANNELS`` (SI units, REP-103 signs).
    :param scenario: the scenario that was run.
    :param vehicle: the vehicle parameters.
    :param controller: the paper law's parameters (the law's ``controller`` attribute
        when it has one; None for other laws).
    :param plant: the plant options (a :class:`~sim_plant.vehicle_model.Stacked` batch
        when the runs' options differ).
    :param law: the law that was run.
    :param diverged_at: per run, the start [s] of the plant step in which the run
        diverged (its plant failed or its state became non-finite), NaN for a run that
        did not; every channel of a diverged run is NaN after that time (float for one
        run, array of the batch's shape).
    """

    time: Array
    channels: dict[str, Array]
    scenario: Scenario
    vehicle: VehicleParams
    controller: Any
    plant: Any
    law: Any = None
    diverged_at: Any = math.nan

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
    v_x, a_x = profile_speed(scenario.speed, t, initial_speed, acceleration)
    rho, rho_slope = scenario.road.curvature(x[0])
    return LateralState(x[1], x[2], x[3], x[4], v_x, a_x, rho, v_x * rho_slope)


def plant_derivatives(scenario: Scenario, vehicle: Any, plant: Any,
                      command: Real, initial_speed: Real, acceleration: Real,
                      disturbance: Disturbance | None = None
                      ) -> Callable[[float, State], State]:
    """
    Return the plant's right-hand side ``f(t, x)`` for a held steering command.

    :param scenario: road and speed profile.
    :param vehicle: the plant's vehicle parameters (or a stacked batch of them).
    :param plant: plant options (or a stacked batch).
    :param command: the steering command held over the step [rad].
    :param initial_speed: initial speed(s) [m/s].
    :param acceleration: ramp acceleration(s) [m/s^2].
    :param disturbance: ``t -> (lateral force [N], yaw moment [N m])`` on the body.
    :return: the right-hand side.
    """
    def rhs(t: float, state: State) -> State:
        v_x, a_x = profile_speed(scenario.speed, t, initial_speed, acceleration)
        rho, _ = scenario.road.curvature(state[0])
        rates = derivatives(state, command, v_x, a_x, rho, vehicle, plant)
        if disturbance is None:
            return rates
        force, moment = disturbance(t)
        return (rates[0], rates[1], rates[2], rates[3] + force / vehicle.mass,
                rates[4] + moment / vehicle.yaw_inertia, rates[5])
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
    ramps = scenario.speed.ramps
    exact = plant.kinematics == 'exact'
    curvature = scenario.road.curvature_function()
    sin, cos = math.sin, math.cos

    def rates(t: float, s: float, y: float, e: float, v_y: float, r: float,
              u: float) -> tuple[float, float, float, float, float]:
        v_x = initial_speed if constant else (
            initial_speed + acceleration * min(max(t - start, 0.0), duration))
        if ramps:
            v_x = float(ramps_speed(t, v_x, 0.0, ramps)[0])
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


def road_preview(scenario: Scenario, s: Real, distances: Array) -> Preview:
    """
    Return the curvature preview at arc length(s) ``s`` (what the node publishes).

    :param scenario: the scenario (road).
    :param s: arc length of the CG [m] (float or batch array).
    :param distances: preview distances ahead of the CG [m].
    :return: the preview; curvatures of shape ``(K,) + shape(s)``.
    """
    if isinstance(s, np.ndarray):
        rho, _ = scenario.road.curvature(s[None, ...] + distances.reshape(
            (-1,) + (1,) * s.ndim))
        return Preview(distances, np.asarray(rho, dtype=float))
    if not hasattr(scenario.road, 'curvature_function'):
        raise ParameterError('one run needs one road')
    curvature = scenario.road.curvature_function()
    return Preview(distances, np.array([curvature(s + float(d)) for d in distances]))


def preview_distances(distance: float, step: float) -> Array:
    """
    Return the preview points' distances ``0, step, ...`` up to ``distance`` (the node's).

    :param distance: how far ahead [m] (0: only the CG).
    :param step: spacing [m].
    :return: the distances.
    """
    if not (np.isfinite(distance) and distance >= 0.0 and np.isfinite(step) and step > 0.0):
        raise ParameterError(f'preview distance = {distance!r} m (>= 0) and step = '
                             f'{step!r} m (> 0) are required')
    return np.arange(int(distance / step) + 1, dtype=float) * step


def delay_steps(delay: Real, dt: float) -> Any:
    """
    Return the transport delay in plant steps (int, or int array for a batch).

    :param delay: control-to-wheel delay(s) [s], each a whole multiple of ``dt``.
    :param dt: plant integration step [s].
    :return: the delay in steps.
    """
    value = np.asarray(delay, dtype=float)
    if not np.all(np.isfinite(value)) or np.any(value < 0.0) or np.any(value > 1.0):
        raise ParameterError(f'delay = {delay!r} s is out of range; allowed: [0, 1] s')
    steps = np.round(value / dt)
    if np.any(np.abs(steps * dt - value) > 1e-9):
        raise ParameterError(f'delay = {delay!r} s is not a whole multiple of dt = '
                             f'{dt!r} s')
    return int(steps) if steps.ndim == 0 else steps.astype(np.int64)


def _batch_shape(*values: Any) -> tuple[int, ...]:
    shapes = [np.shape(v) for v in values if v is not None]
    return np.broadcast_shapes(*shapes) if shapes else ()


def _as_law(controller: ControllerParams | Law, vehicle: VehicleParams) -> Law:
    if isinstance(controller, ControllerParams):
        return PaperLaw(vehicle, controller)
    if not isinstance(controller, Law):
        raise TypeError(f'controller must be ControllerParams or a Law (reset, step); '
                        f'got {type(controller).__name__}')
    return controller


def run(scenario: Scenario, vehicle: VehicleParams, controller: ControllerParams | Law,
        plant: PlantParams | Sequence[PlantParams] | None = None, *, dt: float = 0.001,
        control_period: float = CONTROL_PERIOD, initial_speed: Real | None = None,
        initial_error: Real | None = None, progress: bool = False,
        plant_vehicle: VehicleParams | Sequence[VehicleParams] | None = None,
        delay: Real = 0.0, noise: NoiseParams | None = None,
        seed: int | Sequence[int] = 0, disturbance: Disturbance | None = None,
        preview_distance: float = 50.0, preview_step: float = 5.0) -> SimResult:
    """
    Simulate the closed loop of plant and steering law.

    A batch (one run per element) is run when any of ``initial_speed``,
    ``initial_error``, ``delay``, ``seed`` is an array / sequence, ``plant`` or
    ``plant_vehicle`` a sequence, or the law a batch law (e.g.
    :meth:`~lookahead_control.core.laws.PaperLaw.batch`); sizes must agree. Every
    run of a batch equals the single run with its values.

    :param scenario: road, speed profile, initial state and duration.
    :param vehicle: vehicle parameters: the paper law's model (when ``controller`` is
        ControllerParams) and the plant's unless ``plant_vehicle`` is given.
    :param controller: the law: a :class:`~lookahead_control.core.laws.Law`, or
        ControllerParams for :class:`~lookahead_control.core.laws.PaperLaw`.
    :param plant: plant options (default: linear, exact kinematics); a sequence: per run.
    :param dt: plant integration step [s].
    :param control_period: controller period [s]; 0 for continuous control.
    :param initial_speed: override of the scenario's initial speed [m/s] (array: batch).
    :param initial_error: override of the initial CG lateral error [m] (array: batch).
    :param progress: show a progress bar.
    :param plant_vehicle: the plant's vehicle parameters when they differ from the
        controller's model (mismatch); a sequence: one per run.
    :param delay: transport delay from the law's output to the wheel [s], a whole
        multiple of ``dt`` (array: per run). The wheel holds 0 until the first command
        arrives.
    :param noise: sensor noise standard deviations (None: ideal sensors).
    :param seed: noise seed (sequence: one per run).
    :param disturbance: ``t -> (lateral force [N], yaw moment [N m])`` on the plant's
        body (floats or batch arrays); None: the scenario's ``external_forces``, if any
        (a scenario with them takes no second disturbance).
    :param preview_distance: the law's curvature preview reaches this far [m].
    :param preview_step: spacing of the preview points [m].
    :return: the time series.
    """
    plant = plant or PlantParams()
    law = _as_law(controller, vehicle)
    external = bool(scenario.forces)        # the scenario's, which every plant takes
    if external and disturbance is not None:
        raise ParameterError(f'scenario {scenario.name!r} has external_forces: give the '
                             'disturbance there or as the disturbance argument, not both')
    if external and control_period == 0.0:
        raise ParameterError(f'scenario {scenario.name!r} has external_forces: they need '
                             'a sampled controller (control_period > 0)')
    if initial_speed is not None and np.ndim(initial_speed) == 0:
        scenario = scenario.at_speed(float(initial_speed))     # its road for its speed
    ratio, n_steps = check_steps(dt, control_period, scenario.duration)
    check_force_timing(scenario.forces, dt)         # after the steps: dt itself first
    seeds = None if isinstance(seed, (int, np.integer)) else np.asarray(seed)
    plants = None if isinstance(plant, PlantParams) else list(plant)
    vehicles = (None if plant_vehicle is None or isinstance(plant_vehicle, VehicleParams)
                else list(plant_vehicle))
    law_size = getattr(getattr(law, 'controller', None), 'k_p', None)
    shape = _batch_shape(initial_speed, initial_error,
                         None if np.ndim(delay) == 0 else delay, seeds,
                         None if plants is None else (len(plants),),
                         None if vehicles is None else (len(vehicles),),
                         law_size if isinstance(law_size, np.ndarray) else None)
    batch = len(shape) > 0
    v0: Real = scenario.speed.initial if initial_speed is None else initial_speed
    y0: Real = scenario.initial.lateral_error if initial_error is None else initial_error

    def fill(value: float | Real) -> Real:
        return np.full(shape, value, dtype=float) if batch else float(value)

    if batch and np.any(np.asarray(v0) <= 0.0):
        raise ParameterError('initial_speed must be positive in every run')
    v0, y0 = fill(v0), fill(y0)
    accel = fill(scenario.speed.acceleration)
    base = scenario
    if batch and initial_speed is not None and scenario.layout is not None:
        speeds = np.broadcast_to(np.asarray(v0), shape).ravel()
        if len(shape) != 1:
            raise ParameterError('a batch over speeds must be one-dimensional')
        scenario = replace(scenario, road=RoadBatch(  # type: ignore[arg-type]
            [scenario.at_speed(float(v)).road for v in speeds]))
    plant_model: Any = plant if plants is None else stack(plants)
    body = stack(vehicles) if vehicles is not None else (plant_vehicle or vehicle)
    lag = delay_steps(delay, dt)
    if control_period == 0.0 and (np.any(np.asarray(lag) != 0) or noise is not None):
        raise ParameterError('a transport delay or sensor noise needs a sampled '
                             'controller (control_period > 0)')
    if batch and isinstance(lag, np.ndarray):
        lag = np.broadcast_to(lag, shape)
    noise_rows = None
    if noise is not None:
        if batch:
            run_seeds = np.broadcast_to(np.asarray(seed), shape).ravel()
            noise_rows = np.stack([noise_table(noise, int(check_seed(int(k))), n_steps + 1)
                                   for k in run_seeds], axis=-1).reshape(
                                       (n_steps + 1, 4) + shape)
        else:
            noise_rows = noise_table(noise, check_seed(seed), n_steps + 1)  # type: ignore
    distances = preview_distances(preview_distance, preview_step)
    sensor = vehicle.d_s
    init = scenario.initial
    x: State = (fill(0.0), y0, fill(init.relative_yaw), fill(init.lateral_velocity),
                fill(init.yaw_rate), fill(0.0))
    group = None
    if plant_model.model in COMMONROAD_MODELS:
        if control_period == 0.0 or plant_vehicle is not None or disturbance is not None:
            raise ParameterError(f'the {plant_model.model} plant needs control_period > 0 '
                                 'and takes no plant_vehicle (its parameters are the '
                                 'CommonRoad set, plant.vehicle_id) and no disturbance '
                                 "but the scenario's external_forces")
        group = CommonRoadGroup(base, plants or [plant_model], v0, y0, shape)
        x = group.contract()

    def measure_truth(state: State, t: float) -> LateralState:
        if group is None:
            return measure(state, t, scenario, v0, accel)
        return group.measure(state, t, scenario, accel)

    def observe(state: State, t: float, k: int) -> LateralState:
        truth = measure_truth(state, t)
        if noise_rows is None:
            return truth
        n = noise_rows[k]
        eps_r = truth.eps_r + n[1]
        y_cg = (truth.y_cg + sensor * truth.eps_r + n[0]) - sensor * eps_r
        return truth._replace(y_cg=y_cg, eps_r=eps_r, v_y=truth.v_y + n[2],
                              r=truth.r + n[3])

    def plant_rhs(command: Real, push: tuple[float, float] | None = None
                  ) -> Callable[[float, State], State]:
        # push: the scenario's forces, held over the plant step from its start
        return plant_derivatives(scenario, body, plant_model, command, v0, accel,
                                 disturbance if push is None else lambda _t: push)

    def continuous_rhs(t: float, state: State) -> State:
        command = law.step(measure(state, t, scenario, v0, accel),
                           road_preview(scenario, state[0], distances), 0.0).steering
        return plant_rhs(command)(t, state)

    # a new run from rest: start() where the law has one (reset() keeps a model of the
    # car's actuator for the node), reset() otherwise (the Law contract, core/laws.py)
    getattr(law, 'start', law.reset)()
    commands: list[Real] = []
    rows: list[list[Any]] = []
    linear = plant_model.model == 'linear'
    lost = fill(math.nan)       # per run: the step in which its state became non-finite
    t = 0.0
    for k in _progress(n_steps + 1, progress):
        t = k * ratio * dt
        inputs = observe(x, t, k)
        out = law.step(inputs, road_preview(scenario, x[0], distances),
                       0.0 if k == 0 else ratio * dt)
        commands.append(out.steering)
        wheel = _applied(commands, k * ratio, lag, ratio, fill) if linear else x[5]
        truth = inputs if noise_rows is None else measure_truth(x, t)
        rows.append([x[0], x[1], x[2], x[3], x[4], wheel, truth.v_x, truth.a_x,
                     truth.rho, out.steering, out.d_v, out.y_v, out.y_ref, out.error,
                     out.error_rate])
        if k == n_steps:
            break
        if group is not None:
            for j in range(ratio):
                group.advance(t + j * dt, dt, _applied(commands, k * ratio + j, lag, ratio,
                                                       fill))
            x = group.contract()
            continue
        before = x
        with np.errstate(over='ignore', invalid='ignore'):   # a diverging run: below
            if control_period == 0.0:
                x = advance(continuous_rhs, x, t, dt, ratio, plant_model, out.steering)
            elif isinstance(lag, int) and lag == 0 and not external:
                x = advance(plant_rhs(out.steering), x, t, dt, ratio, plant_model,
                            out.steering)
            else:       # a delay or the scenario's forces: one plant step at a time
                for j in range(ratio):
                    applied = _applied(commands, k * ratio + j, lag, ratio, fill)
                    push = scenario.external(t + j * dt) if external else None
                    x = advance(plant_rhs(applied, push), x, t + j * dt, dt, 1, plant_model,
                                applied)
        x, lost = _hold_diverged(before, x, lost, t)
    if group is not None:
        lost = group.diverged_at()
    time = np.arange(len(rows), dtype=float) * (ratio * dt)
    columns = list(zip(*rows))
    channels = {name: np.asarray(col, dtype=float) for name, col in zip(CHANNELS, columns)}
    if np.any(np.isfinite(lost)):
        after = time.reshape((-1,) + (1,) * np.ndim(lost)) > np.asarray(lost)
        channels = {name: np.where(after, math.nan, values)
                    for name, values in channels.items()}
    return SimResult(time, channels, scenario, vehicle, getattr(law, 'controller', None),
                     plant_model, law, lost)


def _hold_diverged(before: State, after: State, lost: Real, t: float) -> tuple[State, Real]:
    """
    Hold each run whose state became non-finite at its last finite state.

    Element-wise: the other runs of a batch go on bit-identical. The held run's law
    still sees finite inputs; its channels are NaN after ``lost`` (see :func:`run`).

    :param before: the state at ``t``.
    :param after: the state one control step later.
    :param lost: per run, when it diverged (NaN: it has not).
    :param t: the time of ``before`` [s].
    :return: the state to go on from and the updated ``lost``.
    """
    finite = np.logical_and.reduce([np.isfinite(c) for c in after])
    if np.all(finite):
        return after, lost
    held = tuple(np.where(finite, a, b) for a, b in zip(after, before))
    if np.ndim(lost) == 0:
        return tuple(float(c) for c in held), (t if math.isnan(float(lost)) else lost)
    return held, np.where(np.isnan(lost) & ~finite, t, lost)


def _applied(commands: list[Real], step: int, lag: Any, ratio: int,
             fill: Callable[[float], Real]) -> Real:
    """
    Return the command at the wheel during plant step ``step`` (0 before the first).

    :param commands: the law's commands so far, one per control step.
    :param step: the plant step index.
    :param lag: the delay in plant steps (int or per-run int array).
    :param ratio: plant steps per control step.
    :param fill: makes a float into the batch's shape.
    :return: the applied command.
    """
    if isinstance(lag, int):
        source = (step - lag) // ratio
        return commands[source] if source >= 0 else fill(0.0)
    sources = (step - lag) // ratio
    first = max(int(np.min(sources)), 0)          # only the commands still in flight
    table = np.stack([np.broadcast_to(c, sources.shape) for c in commands[first:]])
    picked = np.take_along_axis(table, np.clip(sources - first, 0, None)[None, ...], 0)[0]
    return np.where(sources >= 0, picked, 0.0)


class CommonRoadGroup:
    """The CommonRoad plants of a run or batch, seen as the runner's state arrays."""

    def __init__(self, scenario: Scenario, plants: Sequence[Any], speeds: Real,
                 errors: Real, shape: tuple[int, ...]) -> None:
        """
        Place one plant per run.

        :param scenario: the scenario (each run's road is laid out for its speed).
        :param plants: plant options, one, or one per run.
        :param speeds: initial speeds [m/s] (float or batch array).
        :param errors: initial lateral errors [m].
        :param shape: the batch shape (``()`` for one run).
        """
        self.shape = shape
        n = int(np.prod(shape)) if shape else 1
        v = np.broadcast_to(np.asarray(speeds, dtype=float), shape).ravel()
        y = np.broadcast_to(np.asarray(errors, dtype=float), shape).ravel()
        options = list(plants) if len(plants) == n else [plants[0]] * n
        self.plants = [CommonRoadPlant(scenario.at_speed(float(v[i])), options[i],
                                       float(v[i]), float(y[i])) for i in range(n)]
        self.v_x: Real = 0.0
        self.rho: Real = 0.0

    def _pack(self, values: list[float]) -> Real:
        return np.array(values).reshape(self.shape) if self.shape else values[0]

    def contract(self) -> State:
        """Return the contract state ``(s, y_cg, eps_r, v_y, r, steering)``."""
        rows = [p.contract() for p in self.plants]
        self.v_x = self._pack([r[1] for r in rows])
        self.rho = self._pack([r[2] for r in rows])
        return tuple(self._pack([r[0][i] for r in rows]) for i in range(6))

    def measure(self, x: State, t: float, scenario: Scenario, accel: Real) -> LateralState:
        """
        Return the law's inputs: the plant's own speed and acceleration.

        :param x: the contract state.
        :param t: time [s].
        :param scenario: the scenario (speed profile, road slope).
        :param accel: first-ramp acceleration(s) (unused: the plant's own is measured;
            the profile's, given before, ended its ramps before the car did).
        :return: the inputs.
        """
        a_x = self._pack([plant.acceleration(t) for plant in self.plants])
        _, slope = scenario.road.curvature(x[0])
        return LateralState(x[1], x[2], x[3], x[4], self.v_x, a_x, self.rho,
                            self.v_x * slope)

    def advance(self, t: float, dt: float, command: Real) -> None:
        """
        Integrate every plant one step with its command.

        :param t: time [s].
        :param dt: step [s].
        :param command: the applied command(s) [rad].
        """
        commands = np.broadcast_to(np.asarray(command, dtype=float), self.shape).ravel()
        for plant, u in zip(self.plants, commands):
            plant.advance(t, dt, float(u))      # a diverged plant stays where it failed

    def diverged_at(self) -> Real:
        """
        Return, per run, the start of the step in which its model failed (NaN: none).

        :return: the times [s] (float for one run, array of the batch's shape).
        """
        return self._pack([math.nan if p.diverged_at is None else p.diverged_at
                           for p in self.plants])
