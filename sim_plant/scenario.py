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
Scenarios: a road, a speed profile, initial conditions and a duration.

Scenario files (``config/scenarios/*.yaml``) are plain YAML::

    scenario:
      name: paper_r400
      duration: 10.0                  # s
      speed: {initial: 37.0, acceleration: 0.0, start: 0.0, duration: 0.0}
      initial: {lateral_error: 0.0, relative_yaw: 0.0, lateral_velocity: 0.0,
                yaw_rate: 0.0}
      road:
        - {type: straight, time: 2.0}           # length = time x initial speed
        - {type: arc, length: 3000.0, curvature: -0.0025}
        - {type: clothoid, length: 50.0, curvature_start: 0.0, curvature_end: 0.01}

A segment's length is given either in metres (``length``) or as the ``time`` it takes
at the initial speed, so "2 s of straight road" means the same at every speed;
``min_length`` [m] puts a floor under a ``time`` length. A curvature can be given as the
``lateral_acceleration`` [m/s^2, + left] it takes at the initial speed (``rho = a_y /
v^2``; on clothoids ``lateral_acceleration_start`` / ``_end``). A ``lane_change`` entry
(``offset`` [m, + left], ``time`` or ``length``) is four clothoids, curvature 0 -> k ->
0 -> -k -> 0, with k solved so the lane moves sideways by exactly ``offset``.

The speed may have several phases (``speed: {initial: 10, phases: [{start, duration,
acceleration}, ...]}``, instead of one ``acceleration``/``start``/``duration``), and
``fixed: true`` marks a profile that is part of the scenario (no speed override).

``external_forces`` (optional) push the car's body from outside: a crosswind, a banked
or crowned road (``m g`` times the bank's slope), a gust. Each entry is ``{start,
duration, force, moment, frequency}``: from ``start`` [s] for ``duration`` [s] (0: to
the end) a lateral force [N, + left] and a yaw moment [N m, + left] act on the body at
its CG, constant (``frequency`` 0) or as ``sin(2 pi frequency (t - start))`` times
them; entries add. Every plant takes them, the simulator node too::

      external_forces:
        - {start: 2.0, force: 1500.0}                   # a 1.5 kN crosswind from 2 s
        - {start: 10.0, duration: 20.0, force: 800.0, frequency: 0.2}

Every speed-dependent entry is laid out for the run's own speed: the road is kept as a
recipe (:meth:`Scenario.at_speed`) and a batch over speeds gives each run its road.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, MISSING, replace
import math
from pathlib import Path
from typing import Any, Callable, Mapping, Optional

from lookahead_control.core.config import ConfigError, read_yaml
from lookahead_control.core.params import check_range, ParameterError
import numpy as np
from sim_plant.road import Road, Segment
from sim_plant.speed_profile import SpeedProfile


MAX_CURVATURE = 1.0     # 1/m: a 1 m radius
MAX_FORCE = 5.0e4       # N: external lateral forces together (3 g on the paper's car)
MAX_MOMENT = 1.0e5      # N m: external yaw moments together
MAX_FORCES = 100        # entries of external_forces
#: [s] a force's start and end are taken this close: ``start + duration`` in floating
#: point (0.04 + 0.07 = 0.11000000000000001) left a force on at its end
EDGE = 1e-9
#: plant steps per period of a sinusoidal force at least (fewer: it aliases)
STEPS_PER_PERIOD = 20


@dataclass(frozen=True)
class InitialState:
    """
    Initial lateral state of the vehicle.

    :param lateral_error: y_cg [m].
    :param relative_yaw: eps_r [rad].
    :param lateral_velocity: v_y [m/s].
    :param yaw_rate: r [rad/s].
    """

    lateral_error: float = 0.0
    relative_yaw: float = 0.0
    lateral_velocity: float = 0.0
    yaw_rate: float = 0.0

    def __post_init__(self) -> None:
        check_range('initial.lateral_error', self.lateral_error, -10.0, 10.0, unit='m')
        check_range('initial.relative_yaw', self.relative_yaw, -1.0, 1.0, unit='rad')
        check_range('initial.lateral_velocity', self.lateral_velocity, -10.0, 10.0,
                    unit='m/s')
        check_range('initial.yaw_rate', self.yaw_rate, -2.0, 2.0, unit='rad/s')


@dataclass(frozen=True)
class ExternalForce:
    """
    A lateral force and yaw moment on the car's body from outside (wind, a bank).

    :param start: when it starts [s].
    :param duration: how long it acts [s] (0: to the end of the run).
    :param force: lateral force at the CG [N, + left].
    :param moment: yaw moment [N m, + left].
    :param frequency: 0: constant; else the force and moment are ``sin(2 pi frequency
        (t - start))`` times their values [Hz].
    """

    start: float = 0.0
    duration: float = 0.0
    force: float = 0.0
    moment: float = 0.0
    frequency: float = 0.0

    def __post_init__(self) -> None:
        for name, low, high, unit in (('start', 0.0, 1.0e5, 's'),
                                      ('duration', 0.0, 1.0e5, 's'),
                                      ('force', -MAX_FORCE, MAX_FORCE, 'N'),
                                      ('moment', -MAX_MOMENT, MAX_MOMENT, 'N m'),
                                      ('frequency', 0.0, 50.0, 'Hz')):
            raw = getattr(self, name)
            if isinstance(raw, bool) or not isinstance(raw, (int, float)):
                # YAML's true is no force of 1 N, nor '1500' (or 1.0e9, a string to
                # PyYAML: write 1.0e+9) a number
                raise ParameterError(f'external_forces.{name} = {raw!r} is not a number '
                                     f'[{unit}]; write a real such as 1500.0 or 1.0e+3')
            value = check_range(f'external_forces.{name}', raw, low, high, unit=unit)
            object.__setattr__(self, name, value)
        if self.force == 0.0 and self.moment == 0.0:
            raise ParameterError('external_forces: an entry with neither force nor moment '
                                 'pushes nothing; give force [N] and/or moment [N m]')

    def at(self, t: float) -> tuple[float, float]:
        """
        Return the force and moment at time ``t``.

        :param t: time [s] (its start and end are taken within :data:`EDGE`).
        :return: ``(force [N], moment [N m])``; zeros outside its time.
        """
        if t < self.start - EDGE or (self.duration > 0.0
                                     and t >= self.start + self.duration - EDGE):
            return 0.0, 0.0
        if self.frequency == 0.0:
            return self.force, self.moment
        wave = math.sin(2.0 * math.pi * self.frequency * (t - self.start))
        return self.force * wave, self.moment * wave


@dataclass(frozen=True)
class Scenario:
    """
    A closed-loop scenario.

    :param name: a short name for files and tables.
    :param duration: simulated time [s].
    :param road: the lane centreline.
    :param speed: the prescribed speed profile.
    :param initial: the initial lateral state.
    :param layout: ``speed -> road`` laid out for that initial speed (None: the road
        does not depend on speed).
    :param forces: forces on the body from outside (they add; none may start at or after
        the end, also of a run cut short).
    """

    name: str
    duration: float
    road: Road
    speed: SpeedProfile
    initial: InitialState = field(default_factory=InitialState)
    layout: Optional[Callable[[float], Road]] = field(
        default=None, compare=False, repr=False)
    forces: tuple[ExternalForce, ...] = ()

    def __post_init__(self) -> None:
        check_range('scenario.duration', self.duration, 0.0, 1.0e5, low_open=True, unit='s')
        late = [i for i, f in enumerate(self.forces) if f.start >= self.duration - EDGE]
        if late:
            # also a run cut short (compare's and sweep's --duration): it pushed nothing
            # and said nothing (dev-probe81)
            raise ParameterError(
                f'external_forces[{late[0]}].start = {self.forces[late[0]].start!r} s is at '
                f"or after the scenario's end ({self.duration:g} s): it would push nothing")

    def external(self, t: float) -> tuple[float, float]:
        """
        Return the sum of the external forces at time ``t``.

        :param t: time [s].
        :return: ``(lateral force [N], yaw moment [N m])`` on the body.
        """
        force = moment = 0.0
        for entry in self.forces:
            f, m = entry.at(t)
            force += f
            moment += m
        return force, moment

    def at_speed(self, speed: float) -> 'Scenario':
        """
        Return the scenario at initial speed ``speed``, its road laid out for it.

        :param speed: initial speed [m/s].
        :return: the scenario.
        :raises ParameterError: the scenario's speed profile is fixed, or the speed is
            out of range.
        """
        if speed == self.speed.initial:
            return self
        if self.speed.fixed:
            raise ParameterError(f'scenario {self.name!r} has its own speed profile '
                                 f'(speed.fixed); a speed override ({speed!r} m/s) is '
                                 'not allowed')
        profile = replace(self.speed, initial=speed)
        road = self.layout(speed) if self.layout is not None else self.road
        return replace(self, road=road, speed=profile)


def paper_scenario(speed: float, duration: float = 10.0) -> Scenario:
    """
    Return the paper's Section 5 scenario: 2 s straight, then a right curve R = 400 m.

    :param speed: constant longitudinal speed [m/s].
    :param duration: simulated time [s].
    :return: the scenario.
    """
    def road(v: float) -> Road:
        straight = Segment('straight', 2.0 * v)
        curve = Segment('arc', v * duration + 100.0, -1.0 / 400.0, -1.0 / 400.0)
        return Road([straight, curve])
    return Scenario(f'paper_r400_v{speed:g}', duration, road(speed), SpeedProfile(speed),
                    layout=road)


SEGMENT_KEYS = ('type', 'length', 'time', 'min_length', 'curvature', 'curvature_start',
                'curvature_end', 'lateral_acceleration', 'lateral_acceleration_start',
                'lateral_acceleration_end', 'offset')


def _curvature(entry: Mapping[str, Any], index: int, key: str, speed: float) -> float:
    """Return the curvature ``key`` of a road entry, or the one of its lateral acceleration."""
    accel_key = key.replace('curvature', 'lateral_acceleration')
    if key in entry and accel_key in entry:
        raise ParameterError(f'road[{index}]: give {key} or {accel_key}, not both')
    if accel_key in entry:
        accel = check_range(f'road[{index}].{accel_key}', entry[accel_key], -15.0, 15.0,
                            unit='m/s^2')
        return accel / (speed * speed)
    return check_range(f'road[{index}].{key}', entry.get(key, 0.0), -1.0, 1.0, unit='1/m')


def lane_change_curvature(offset: float, length: float) -> float:
    """
    Return the peak curvature k of a four-clothoid lane change (0, k, 0, -k, 0).

    Solved (bisection on the exact heading integral) so the centreline ends ``offset``
    to the side and parallel to where it started; to first order ``k = 8 offset /
    length^2``.

    :param offset: lateral offset [m, + left].
    :param length: total length of the four clothoids [m].
    :return: k [1/m].
    """
    if offset == 0.0:
        return 0.0
    a = 0.25 * length
    # heading over the first half (two clothoids), sampled finely; the second half
    # mirrors it, so the offset is 2 * integral of sin(heading) over the first half
    u = (np.arange(4000) + 0.5) / 4000.0 * 2.0 * a

    def side(k: float) -> float:
        heading = np.where(u < a, 0.5 * k * u * u / a,
                           k * a - 0.5 * k * (2.0 * a - u) ** 2 / a)
        return 2.0 * float(np.sum(np.sin(heading))) * (2.0 * a / u.size)
    target = abs(offset)
    low, high = 0.0, min(1.0, 0.5 * math.pi / a)      # heading stays below pi/2
    if side(high) < target:
        raise ParameterError(f'lane change of {offset!r} m over {length!r} m is not '
                             'possible (too short)')
    for _ in range(80):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if side(mid) < target else (low, mid)
    return math.copysign(0.5 * (low + high), offset)


def _segments(entry: Any, index: int, speed: float) -> list[Segment]:
    if not isinstance(entry, Mapping):
        raise ParameterError(f'road[{index}] must be a mapping, got {entry!r}')
    unknown = set(entry) - set(SEGMENT_KEYS)
    if unknown:
        raise ParameterError(f'road[{index}]: unknown keys {sorted(unknown)}; known: '
                             f'{sorted(SEGMENT_KEYS)}')
    kind = entry.get('type')
    if ('length' in entry) == ('time' in entry):
        raise ParameterError(f'road[{index}]: give exactly one of length (m) or time (s)')
    if 'length' in entry:
        length = check_range(f'road[{index}].length', entry['length'], 0.0, 1.0e7,
                             low_open=True, unit='m')
        if 'min_length' in entry:
            raise ParameterError(f'road[{index}]: min_length goes with time, not length')
    else:
        length = speed * check_range(f'road[{index}].time', entry['time'], 0.0,
                                     1.0e5, low_open=True, unit='s')
        if 'min_length' in entry:
            length = max(length, check_range(f'road[{index}].min_length',
                                             entry['min_length'], 0.0, 1.0e7, unit='m'))
    if kind == 'lane_change':
        if 'offset' not in entry:
            raise ParameterError(f'road[{index}]: a lane_change needs offset (m, + left)')
        offset = check_range(f'road[{index}].offset', entry['offset'], -20.0, 20.0,
                             unit='m')
        k = lane_change_curvature(offset, length)
        q = 0.25 * length
        return [Segment('clothoid', q, 0.0, k), Segment('clothoid', q, k, 0.0),
                Segment('clothoid', q, 0.0, -k), Segment('clothoid', q, -k, 0.0)]
    if kind == 'arc':
        if 'curvature' not in entry and 'lateral_acceleration' not in entry:
            raise ParameterError(f'road[{index}]: an arc needs curvature (1/m, + left) or '
                                 'lateral_acceleration (m/s^2, + left)')
        rho = _curvature(entry, index, 'curvature', speed)
        return [Segment('arc', length, rho, rho)]
    if kind == 'clothoid':
        return [Segment('clothoid', length,
                        _curvature(entry, index, 'curvature_start', speed),
                        _curvature(entry, index, 'curvature_end', speed))]
    if kind == 'straight':
        extra = set(entry) - {'type', 'length', 'time', 'min_length'}
        if extra:
            raise ParameterError(f'road[{index}]: a straight has no {sorted(extra)}')
    return [Segment(str(kind), length)]


def road_at(entries: list[Any], speed: float) -> Road:
    """
    Return the road of a scenario file's ``road`` entries laid out for ``speed``.

    :param entries: the entries.
    :param speed: initial speed [m/s].
    :return: the road.
    """
    return Road([seg for i, e in enumerate(entries) for seg in _segments(e, i, speed)])


def _speed_profile(body: Mapping[str, Any]) -> SpeedProfile:
    spec = body.get('speed', {})
    if not isinstance(spec, Mapping):
        raise ParameterError(f'speed must be a mapping, got {spec!r}')
    spec = dict(spec)
    phases = spec.pop('phases', None)
    if phases is None:
        return SpeedProfile(**spec)
    if set(spec) & {'acceleration', 'start', 'duration'}:
        raise ParameterError('speed: give phases or acceleration/start/duration, not both')
    if not isinstance(phases, list) or not phases or not all(
            isinstance(p, Mapping) and set(p) == {'start', 'duration', 'acceleration'}
            for p in phases):
        raise ParameterError('speed.phases must be a non-empty list of mappings with '
                             f'start, duration, acceleration; got {phases!r}')
    ramps = [(float(p['start']), float(p['duration']), float(p['acceleration']))
             for p in phases]
    first = ramps[0]
    return SpeedProfile(spec.pop('initial'), first[2], first[0], first[1],
                        tuple(ramps[1:]), **spec)


def _build(cls: Any, key: str, entry: Any) -> Any:
    """Build a scenario part from its mapping, naming a missing or unknown key."""
    if not isinstance(entry, Mapping):
        raise ParameterError(f'{key} must be a mapping, got {entry!r}')
    known = [f.name for f in fields(cls)]
    unknown = sorted(set(entry) - set(known), key=str)     # a YAML key may be a number
    if unknown:
        raise ParameterError(f'{key}: unknown keys {unknown}; known: {known}')
    required = [f.name for f in fields(cls) if f.default is MISSING
                and f.default_factory is MISSING]
    absent = [name for name in required if name not in entry]
    if absent:
        raise ParameterError(f'{key}: missing {", ".join(f"{key}.{a}" for a in absent)}')
    return cls(**entry)


def _external_forces(entries: Any) -> tuple[ExternalForce, ...]:
    """
    Build the ``external_forces`` list, naming the entry at fault.

    :param entries: the file's list (None, every entry commented out: none).
    :return: the forces (:class:`Scenario` refuses one starting at or after its end).
    """
    if entries is None:
        return ()
    if not isinstance(entries, list):
        raise ParameterError(f'external_forces must be a list of mappings (start, '
                             f'duration, force, moment, frequency), got {entries!r}')
    if len(entries) > MAX_FORCES:
        raise ParameterError(f'external_forces has {len(entries)} entries; at most '
                             f'{MAX_FORCES}')
    forces = []
    for i, entry in enumerate(entries):
        key = f'external_forces[{i}]'
        try:
            force = _build(ExternalForce, key, entry)
        except ParameterError as err:
            # a value out of range names the field: say which entry's
            text = str(err)
            raise ParameterError(text if text.startswith(key) else
                                 text.replace('external_forces', key, 1)) from err
        forces.append(force)
    for name, limit, unit in (('force', MAX_FORCE, 'N'), ('moment', MAX_MOMENT, 'N m')):
        total = _largest_sum(forces, name)
        if total > limit:
            raise ParameterError(f"external_forces: the entries' {name}s add up to "
                                 f'{total:g} {unit} at once; allowed together: {limit:g} '
                                 f'{unit}')
    return tuple(forces)


def _largest_sum(forces: list[ExternalForce], name: str) -> float:
    """Return the largest sum of the amplitudes ``name`` of the entries acting at once."""
    def acting(f: ExternalForce, t: float) -> bool:
        return f.start <= t and (f.duration == 0.0 or t < f.start + f.duration)
    # the sum of amplitudes is piecewise constant: largest at some entry's start
    return max((sum(abs(getattr(f, name)) for f in forces if acting(f, g.start))
                for g in forces), default=0.0)


def check_force_timing(forces: tuple[ExternalForce, ...], dt: float) -> None:
    """
    Refuse forces a plant step of ``dt`` cannot give as written.

    Every plant holds the force over each step from the step's start (the CommonRoad
    models' inputs are held so too): a start or an end between two steps would move by
    up to a step, a gust shorter than a step be missed or stretched, and a sinusoid of
    fewer than :data:`STEPS_PER_PERIOD` steps per period alias (dev-probe80: a 50 Hz
    force at ``dt`` 0.01 s pushed the linear plant by its amplitude, the CommonRoad car
    not at all).

    :param forces: the scenario's forces.
    :param dt: the plant's integration step [s].
    :raises ParameterError: naming the entry and what ``dt`` allows.
    """
    def on_grid(value: float) -> bool:
        return abs(value / dt - round(value / dt)) * dt <= EDGE

    for i, force in enumerate(forces):
        key = f'external_forces[{i}]'
        for name in ('start', 'duration'):
            value = getattr(force, name)
            if not on_grid(value):
                raise ParameterError(f'{key}.{name} = {value!r} s is not a whole number of '
                                     f'plant steps (dt = {dt!r} s): the force would start '
                                     'or end up to a step off; choose a multiple of dt')
        if force.duration > 0.0 and round(force.duration / dt) == 0:     # on the grid: 0
            raise ParameterError(f'{key}.duration = {force.duration!r} s is shorter than a '
                                 f'plant step (dt = {dt!r} s): it would push nothing')
        if force.frequency * dt * STEPS_PER_PERIOD > 1.0 + 1e-12:
            largest = 1.0 / (STEPS_PER_PERIOD * force.frequency)
            raise ParameterError(f'{key}.frequency = {force.frequency:g} Hz needs at least '
                                 f'{STEPS_PER_PERIOD} plant steps per period: dt <= 1 / '
                                 f'({STEPS_PER_PERIOD} x {force.frequency:g} Hz) = '
                                 f'{math.floor(largest * 1e9) / 1e9:.9g} s (dt = {dt!r} s)')


def scenario_from_dict(document: Any, source: str = 'scenario') -> Scenario:
    """
    Build a scenario from its parsed YAML document.

    :param document: the mapping with a ``scenario`` key.
    :param source: where it came from, for messages.
    :return: the scenario.
    """
    if document is None:
        raise ConfigError(f"{source}: empty file; expected a mapping 'scenario:' with "
                          'name, duration, speed, initial, road')
    try:
        body = document['scenario']
        if not isinstance(body, Mapping):
            raise ParameterError('scenario must be a mapping')
        unknown = set(body) - {'name', 'duration', 'speed', 'initial', 'road',
                               'external_forces'}
        if unknown:
            raise ParameterError(f'unknown keys {sorted(unknown)}; known: duration, '
                                 'external_forces, initial, name, road, speed')
        speed = _speed_profile(body)
        initial = _build(InitialState, 'initial', body.get('initial', {}))
        road_entries = body.get('road')
        if not isinstance(road_entries, list) or not road_entries:
            raise ParameterError('road must be a non-empty list of segments')
        road = road_at(road_entries, speed.initial)
        entries = list(road_entries)

        def layout(v: float) -> Road:
            try:
                return road_at(entries, v)
            except ParameterError as err:
                raise ConfigError(f'{source} at {v:g} m/s: {err}') from err
        scenario = Scenario(str(body.get('name', Path(source).stem)),
                            check_range('scenario.duration', body.get('duration', 10.0),
                                        0.0, 1.0e5, low_open=True, unit='s'),
                            road, speed, initial, layout)
        return replace(scenario, forces=_external_forces(body.get('external_forces')))
    except (KeyError, TypeError) as err:
        raise ConfigError(f'{source}: not a scenario ({err}); expected a mapping '
                          "'scenario:' with name, duration, speed, initial, road") from err
    except ParameterError as err:
        raise ConfigError(f'{source}: {err}') from err


def load_scenario(path: Path | str, speed: float | None = None) -> Scenario:
    """
    Load a scenario file, optionally replacing its (constant) initial speed.

    :param path: the scenario YAML file.
    :param speed: if given, the initial speed [m/s] (segment times scale with it).
    :return: the scenario.
    """
    scenario = scenario_from_dict(read_yaml(path), str(path))
    if speed is None:
        return scenario
    try:
        return scenario.at_speed(speed)
    except ParameterError as err:
        raise ConfigError(f'{path}: {err}') from err


def with_initial(scenario: Scenario, initial: InitialState) -> Scenario:
    """
    Return the scenario with other initial conditions.

    :param scenario: the scenario.
    :param initial: the new initial state.
    :return: a copy with ``initial`` replaced.
    """
    return replace(scenario, initial=initial)
