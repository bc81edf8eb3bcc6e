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
A closed loop with a real car's sensor timing, through the controller node's core.

``sim_plant`` and the offline runner (:func:`sim_plant.closed_loop_sim.run`) measure
every input at 100 Hz on one stamp and answer at once. A car's inputs differ most there:
a lane camera gives the lateral error at 20-30 Hz, 50-120 ms after the frame (stamped
at the capture), beside an IMU at 100 Hz, odometry at 50 Hz and a map at 10 Hz. Here each
input is its own stream (:class:`StreamTiming`: rate, latency, phase), measured at its
capture (with the sensor noise of :class:`~sim_plant.sensors.NoiseParams`), stamped
there and delivered ``latency`` later to the controller's core
(:class:`~lookahead_control.core.controller.SteeringController`), which is driven as the
node drives it under sim time: every sample through ``accept`` (the input checks),
event mode answering each lateral error (waiting for matching stamps when the node's
``wait_for_matching_stamps`` is on, up to ``sync_timeout``) or timer mode at
``rate_hz``, the watchdog's safe command while an input is stale. The command reaches
the plant after the plant's transport delay.

The values of a message are those of its stamp (the contract's, ``docs/contract.md``).
With :attr:`SensorTiming.with_frame` the yaw, velocity and curvature go with each
lateral error, stamped with it and of its instant (what ``docs/vehicle_bridge.md``
advises a camera's bridge to send); without it each goes at its own rate.

Everything is quantized to the plant step ``dt``: a capture at ``k / rate_hz +
phase`` is measured at the plant step nearest to it, and delivered the number of steps
nearest to ``latency / dt`` later (halves up); a rate above ``1 / dt`` is refused. The
run is sampled every ``SAMPLE_PERIOD`` into a :class:`~sim_plant.closed_loop_sim.SimResult`
(the league's metrics apply to it).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import heapq
import math
from typing import Any, Optional

from lookahead_control.core.controller import Command, SteeringController
from lookahead_control.core.params import check_range, ParameterError, VehicleParams
from lookahead_control.core.samples import (curvature_from_points, LateralErrorSample,
                                            VelocitySample, YawSample)
import numpy as np
from sim_plant.closed_loop_sim import (advance, CHANNELS, check_steps, CommonRoadGroup,
                                       delay_steps, measure, plant_derivatives,
                                       preview_distances, SimResult)
from sim_plant.commonroad_plant import COMMONROAD_MODELS
from sim_plant.scenario import Scenario
from sim_plant.sensors import check_seed, NoiseParams
from sim_plant.vehicle_model import PlantParams, State

#: the inputs, in the order their deliveries of one plant step are handed over (the
#: lateral error last, as the simulator publishes it)
STREAMS = ('yaw', 'velocity', 'road_curvature', 'lateral_error')
#: the inputs whose timing may be given apart from the lateral error's
TIMED_STREAMS = STREAMS[:3]
#: the result's sampling period [s] (the league's control period)
SAMPLE_PERIOD = 0.01
#: the curvature polygon: points every this far [m] up to ``PREVIEW_DISTANCE`` ahead (the
#: league's preview)
PREVIEW_STEP = 5.0
PREVIEW_DISTANCE = 100.0
#: a stream's longest latency [s] (the inputs' timeout's range)
MAX_LATENCY = 1.0


@dataclass(frozen=True)
class StreamTiming:
    """
    When one input is measured and when the controller gets it.

    :param rate_hz: how often it is measured [Hz].
    :param latency: from its capture (its stamp) to its arrival at the controller [s].
    :param phase: its first capture [s] (within one period).
    :param clock_offset: its clock ahead of the controller's [s]: its stamps are the
        capture's plus it (a sensor on a clock of its own, not synchronized).
    """

    rate_hz: float = 100.0
    latency: float = 0.0
    phase: float = 0.0
    clock_offset: float = 0.0

    def __post_init__(self) -> None:
        check_range('rate_hz', self.rate_hz, 1.0, 1000.0, unit='Hz')
        check_range('latency', self.latency, 0.0, MAX_LATENCY, unit='s')
        check_range('phase', self.phase, 0.0, 1.0 / self.rate_hz, unit='s')
        check_range('clock_offset', self.clock_offset, -MAX_LATENCY, MAX_LATENCY, unit='s')


@dataclass(frozen=True)
class SensorTiming:
    """
    The timing of the controller's four inputs.

    :param lateral_error: the lateral error's (a lane camera's frames).
    :param yaw: the relative yaw, yaw rate and acceleration's.
    :param velocity: the velocity's.
    :param road_curvature: the curvature polygon's.
    :param with_frame: the yaw, velocity and curvature go with each lateral error,
        stamped with it and measured at its capture (their own timings unused).
    """

    lateral_error: StreamTiming = field(default_factory=StreamTiming)
    yaw: StreamTiming = field(default_factory=StreamTiming)
    velocity: StreamTiming = field(default_factory=StreamTiming)
    road_curvature: StreamTiming = field(default_factory=StreamTiming)
    with_frame: bool = False

    def describe(self) -> str:
        """
        Return the timing in one line.

        :return: e.g. ``lateral_error 20 Hz 120 ms late, the others with each frame``.
        """
        def one(name: str) -> str:
            s = getattr(self, name)
            return (f'{name} {s.rate_hz:g} Hz {1e3 * s.latency:g} ms late'
                    + (f' (phase {1e3 * s.phase:g} ms)' if s.phase else '')
                    + (f' (clock {round(1e3 * s.clock_offset, 3):+g} ms)'
                       if round(1e3 * s.clock_offset, 3) else ''))
        if self.with_frame:
            return f"{one('lateral_error')}, yaw, velocity and curvature with each frame"
        return ', '.join(one(name) for name in ('lateral_error', 'yaw', 'velocity',
                                                'road_curvature'))


def parse_stream(text: str) -> StreamTiming:
    """
    Return the timing written ``RATE/LATENCY[/CLOCK]`` (Hz / seconds / seconds).

    :param text: the text, e.g. ``20/0.12``, or ``100/0/0.05`` for a sensor whose clock
        runs 50 ms ahead of the controller's.
    :return: the timing.
    :raises ParameterError: not of that form, or a value out of its range.
    """
    parts = text.split('/')
    try:
        if len(parts) not in (2, 3):
            raise ValueError('not RATE/LATENCY[/CLOCK]')
        rate, latency, *clock = (float(part) for part in parts)
    except ValueError as err:
        raise ParameterError(f'timing {text!r} is not RATE/LATENCY[/CLOCK] (Hz / s / s, e.g. '
                             f'20/0.12, or 100/0/0.05 for a clock 50 ms ahead): {err}'
                             ) from err
    return StreamTiming(rate, latency, 0.0, clock[0] if clock else 0.0)


def check_timing(timing: SensorTiming, dt: float) -> None:
    """
    Refuse a timing the plant step cannot give: more than one capture per step.

    :param timing: the inputs' timing.
    :param dt: the plant step [s].
    :raises ParameterError: a rate above ``1 / dt`` (dev-probe120: 1000 Hz at a 5 ms step
        was five captures per step on one stamp, four of them refused as repeats, and the
        report said 1000 Hz).
    """
    names = ('lateral_error',) if timing.with_frame else STREAMS
    for name in names:
        rate = getattr(timing, name).rate_hz
        if rate * dt > 1.0 + 1e-9:
            raise ParameterError(f'{name}: rate_hz = {rate:g} Hz is more than one capture per '
                                 f'plant step of {dt:g} s; allowed: at most {1.0 / dt:g} Hz '
                                 '(a smaller dt)')


def _steps(time: float, dt: float) -> int:
    """Return the plant step nearest to ``time`` (halves up: 5 ms at a 2 ms step is 3)."""
    return math.floor(time / dt + 0.5)


@dataclass(frozen=True)
class _Delivery:
    """A measurement on its way: its input, stamp [ns] and sample(s)."""

    name: str
    stamp_ns: int
    samples: tuple[tuple[str, Any], ...]


class _Node:
    """The controller node's answering around the core, under sim time (no ROS)."""

    def __init__(self, core: SteeringController, mode: str, rate_hz: float,
                 wait_for_stamps: bool, sync_timeout: float, watchdog_hz: float) -> None:
        self.core = core
        self.mode = mode
        self.timer_ns = int(round(1e9 / rate_hz))
        self.wait = wait_for_stamps
        self.sync_ns = int(round(sync_timeout * 1e9))
        self.watchdog_ns = int(round(1e9 / watchdog_hz))
        self.pending: Optional[int] = None
        self.deadline = 0
        self.last_publish: Optional[int] = None
        self.next_tick = 0
        self.next_watchdog = self.watchdog_ns
        self.sent: list[Command] = []

    def deliver(self, now: int, delivery: _Delivery) -> None:
        taken = False
        for name, sample in delivery.samples:
            taken = self.core.accept(name, sample, now) is None
        if self.mode != 'event':
            return
        if delivery.name == 'lateral_error':
            if not taken:
                return
            stamp = delivery.stamp_ns
            if self.wait and not self._caught_up(now, stamp):
                self.pending, self.deadline = stamp, now + self.sync_ns
                return
            self._step(now)
        elif taken and self.pending is not None and self._caught_up(now, self.pending):
            self.pending = None
            self._step(now)

    def _caught_up(self, now: int, stamp: int) -> bool:
        return self.core.inputs_at(stamp) and now >= stamp

    def tick(self, now: int) -> None:
        """Run what the node's timers run at ``now`` (sync timeout, timer, watchdog)."""
        if self.pending is not None and now >= self.deadline:
            self.pending = None
            self._step(now)
        if self.mode == 'timer' and now >= self.next_tick:
            self.next_tick = now + self.timer_ns
            self._step(now)
        if now >= self.next_watchdog:
            self.next_watchdog = now + self.watchdog_ns
            if self.core.lateral is not None and self.core.stale(now):
                if self.last_publish is None or now - self.last_publish >= self.watchdog_ns:
                    command = self.core.safe_command(now)
                    if command is not None:
                        self._publish(now, command)

    def _step(self, now: int) -> None:
        command = self.core.compute(now)
        if command is not None:
            self._publish(now, command)

    def _publish(self, now: int, command: Command) -> None:
        self.last_publish = now
        self.sent.append(command)


def _samples(name: str, stamp: int, truth: Any, x: State, noise: Any, sensor: float,
             preview: list[tuple[float, float]]) -> tuple[tuple[str, Any], ...]:
    """Return the samples one capture sends (``noise``: lateral, yaw, v_y, r)."""
    n_lat, n_yaw, n_vy, n_r = noise
    v_x, a_x = float(truth.v_x), float(truth.a_x)
    e, v_y, r = float(x[2]), float(x[3]), float(x[4])
    if name == 'lateral_error':
        return (('lateral_error', LateralErrorSample(
            stamp, sensor, float(x[1]) + sensor * e + n_lat)),)
    if name == 'yaw':
        # the IMU measures the body acceleration dv_x/dt - v_y r (true values)
        return (('yaw', YawSample(stamp, e + n_yaw, r + n_r, a_x - v_y * r)),)
    if name == 'velocity':
        return (('velocity', VelocitySample(stamp, v_x, v_y + n_vy)),)
    return (('road_curvature', curvature_from_points(stamp, preview)),)


def timed_run(scenario: Scenario, core: SteeringController, timing: SensorTiming,
              plant: Optional[PlantParams] = None, *, dt: float = 0.001,
              delay: float = 0.0, noise: Optional[NoiseParams] = None, seed: int = 0,
              plant_vehicle: Optional[VehicleParams] = None, mode: str = 'event',
              rate_hz: float = 100.0, wait_for_stamps: bool = False,
              sync_timeout: float = 0.05, watchdog_hz: float = 20.0,
              sensor_distance: float = 0.0) -> SimResult:
    """
    Simulate the closed loop with each input on its own timing (see the module).

    :param scenario: road, speed profile, initial state and duration (laid out for its
        initial speed: :meth:`~sim_plant.scenario.Scenario.at_speed` first).
    :param core: the controller's core, as the node builds it from its parameters.
    :param timing: the inputs' timing.
    :param plant: plant options (default: linear).
    :param dt: plant step [s].
    :param delay: transport delay from the command's answer to the wheel [s] (a whole
        multiple of ``dt``).
    :param noise: sensor noise (None: ideal sensors); one draw of four per capture.
    :param seed: the noise's seed.
    :param plant_vehicle: the plant's vehicle (None: the core's model).
    :param mode: the node's ``mode`` (``event`` or ``timer``).
    :param rate_hz: its timer's rate [Hz].
    :param wait_for_stamps: the node's ``wait_for_matching_stamps``.
    :param sync_timeout: its ``sync_timeout`` (sim time here) [s].
    :param watchdog_hz: its ``watchdog_rate_hz`` [Hz].
    :param sensor_distance: where ahead of the CG the lateral error is measured [m].
    :return: the run, sampled every ``SAMPLE_PERIOD``; ``steering_cmd`` the last command
        sent (the law's outputs NaN: the core's answers are in ``law``'s place, None).
    :raises ParameterError: a step, delay, rate, timeout or mode out of range.
    """
    plant = plant or PlantParams()
    if mode not in ('event', 'timer'):
        raise ParameterError(f"mode = {mode!r} is not allowed; allowed: 'event', 'timer'")
    # the node's ranges (its parameter descriptors)
    check_range('rate_hz', rate_hz, 1.0, 2000.0, unit='Hz')
    check_range('watchdog_hz', watchdog_hz, 1.0, 1000.0, unit='Hz')
    check_range('sync_timeout', sync_timeout, 0.0, 1.0, unit='s')
    check_timing(timing, dt)
    sample_ratio, _ = check_steps(dt, SAMPLE_PERIOD, scenario.duration)
    n_steps = int(round(scenario.duration / dt))
    lag = int(delay_steps(delay, dt))
    vehicle = core.vehicle
    body = plant_vehicle or vehicle
    v0, accel = scenario.speed.initial, scenario.speed.acceleration
    init = scenario.initial
    x: State = (0.0, init.lateral_error, init.relative_yaw, init.lateral_velocity,
                init.yaw_rate, 0.0)
    group = None
    if plant.model in COMMONROAD_MODELS:
        group = CommonRoadGroup(scenario, [plant], v0, init.lateral_error, ())
        x = group.contract()
    rng = np.random.default_rng(check_seed(seed))
    sigmas = (noise or NoiseParams(0.0, 0.0, 0.0, 0.0)).sigmas
    node = _Node(core, mode, rate_hz, wait_for_stamps, sync_timeout, watchdog_hz)
    own = ('lateral_error',) if timing.with_frame else STREAMS
    next_capture = dict.fromkeys(own, 0)
    in_flight: list[tuple[int, int, int, _Delivery]] = []
    count = 0
    commands: list[tuple[int, float]] = []      # (step it acts from, angle)
    wheel_command = 0.0
    rows: list[list[float]] = []
    distances = preview_distances(PREVIEW_DISTANCE, PREVIEW_STEP).tolist()
    curvature = scenario.road.curvature_function()
    for k in range(n_steps + 1):
        t = k * dt
        now = int(round(t * 1e9))
        truth = (group.measure(x, t, scenario, accel) if group is not None
                 else measure(x, t, scenario, v0, accel))
        for name in own:
            stream: StreamTiming = getattr(timing, name)
            while True:
                at = _steps(next_capture[name] / stream.rate_hz + stream.phase, dt)
                if at > k:
                    break
                next_capture[name] += 1
                if at < k:
                    continue
                noise_row = rng.standard_normal(4) * sigmas
                names = (STREAMS if name == 'lateral_error' and timing.with_frame
                         else (name,))
                # the polygon only for a curvature sample (21 road lookups a capture)
                preview = ([(d, float(curvature(float(x[0]) + d))) for d in distances]
                           if 'road_curvature' in names else [])
                stamp = now + int(round(stream.clock_offset * 1e9))
                samples = tuple(s for n in names for s in _samples(
                    n, stamp, truth, x, noise_row, sensor_distance, preview))
                arrival = k + _steps(stream.latency, dt)
                heapq.heappush(in_flight, (arrival, STREAMS.index(name), count,
                                           _Delivery(name, stamp, samples)))
                count += 1
        before = len(node.sent)
        while in_flight and in_flight[0][0] <= k:
            node.deliver(now, heapq.heappop(in_flight)[3])
        node.tick(now)
        for command in node.sent[before:]:
            commands.append((k + lag, command.steering))
        while commands and commands[0][0] <= k:
            wheel_command = commands.pop(0)[1]
        if k % sample_ratio == 0:
            sent = node.sent[-1].steering if node.sent else 0.0
            wheel = x[5] if plant.model != 'linear' else wheel_command
            values = (x[0], x[1], x[2], x[3], x[4], wheel, truth.v_x, truth.a_x, truth.rho,
                      sent)
            rows.append([float(c) for c in values] + [math.nan] * 5)
        if k == n_steps:
            break
        if group is not None:
            group.advance(t, dt, wheel_command)
            x = group.contract()
            continue
        push = scenario.external(t) if scenario.forces else None

        def held(_t: float, p: Any = push) -> Any:
            return p
        rhs = plant_derivatives(scenario, body, plant, wheel_command, v0, accel,
                                None if push is None else held)
        x = advance(rhs, x, t, dt, 1, plant, wheel_command)
        if not all(math.isfinite(float(c)) for c in x):
            break
    time = np.arange(len(rows), dtype=float) * SAMPLE_PERIOD
    columns = list(zip(*rows))
    channels = {name: np.asarray(col, dtype=float) for name, col in zip(CHANNELS, columns)}
    lost: Any = math.nan
    if group is not None:
        lost = group.diverged_at()
    elif len(rows) < n_steps // sample_ratio + 1:
        lost = float(time[-1])
    return SimResult(time, channels, scenario, vehicle, None, plant, None, lost)
