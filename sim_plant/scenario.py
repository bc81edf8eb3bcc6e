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
at the initial speed, so "2 s of straight road" means the same at every speed.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, MISSING, replace
from pathlib import Path
from typing import Any, Mapping

from lookahead_control.core.config import ConfigError, read_yaml
from lookahead_control.core.params import check_finite, check_range, ParameterError
from sim_plant.road import Road, Segment
from sim_plant.speed_profile import SpeedProfile


MAX_CURVATURE = 1.0     # 1/m: a 1 m radius


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
class Scenario:
    """
    A closed-loop scenario.

    :param name: a short name for files and tables.
    :param duration: simulated time [s].
    :param road: the lane centreline.
    :param speed: the prescribed speed profile.
    :param initial: the initial lateral state.
    """

    name: str
    duration: float
    road: Road
    speed: SpeedProfile
    initial: InitialState = field(default_factory=InitialState)

    def __post_init__(self) -> None:
        check_range('scenario.duration', self.duration, 0.0, 1.0e5, low_open=True, unit='s')


def paper_scenario(speed: float, duration: float = 10.0) -> Scenario:
    """
    Return the paper's Section 5 scenario: 2 s straight, then a right curve R = 400 m.

    :param speed: constant longitudinal speed [m/s].
    :param duration: simulated time [s].
    :return: the scenario.
    """
    straight = Segment('straight', 2.0 * speed)
    curve = Segment('arc', speed * duration + 100.0, -1.0 / 400.0, -1.0 / 400.0)
    return Scenario(f'paper_r400_v{speed:g}', duration, Road([straight, curve]),
                    SpeedProfile(speed))


def _segment(entry: Any, index: int, initial_speed: float) -> Segment:
    if not isinstance(entry, Mapping):
        raise ParameterError(f'road[{index}] must be a mapping, got {entry!r}')
    known = {'type', 'length', 'time', 'curvature', 'curvature_start', 'curvature_end'}
    unknown = set(entry) - known
    if unknown:
        raise ParameterError(f'road[{index}]: unknown keys {sorted(unknown)}; known: '
                             f'{sorted(known)}')
    kind = entry.get('type')
    if ('length' in entry) == ('time' in entry):
        raise ParameterError(f'road[{index}]: give exactly one of length (m) or time (s)')
    if 'length' in entry:
        length = check_range(f'road[{index}].length', entry['length'], 0.0, 1.0e7,
                             low_open=True, unit='m')
    else:
        length = initial_speed * check_range(f'road[{index}].time', entry['time'], 0.0,
                                             1.0e5, low_open=True, unit='s')

    def curvature(key: str, default: float | None = None) -> float:
        value = entry.get(key, default)
        if value is None:
            raise ParameterError(f'road[{index}]: an arc needs curvature (1/m, + left)')
        return check_range(f'road[{index}].{key}', value, -MAX_CURVATURE, MAX_CURVATURE,
                           unit='1/m')
    if kind == 'arc':
        rho = curvature('curvature')
        return Segment('arc', length, rho, rho)
    if kind == 'clothoid':
        return Segment('clothoid', length, curvature('curvature_start', 0.0),
                       curvature('curvature_end', 0.0))
    return Segment(str(kind), length)


def _build(cls: Any, key: str, entry: Any) -> Any:
    """Build a scenario part from its mapping, naming a missing or unknown key."""
    if not isinstance(entry, Mapping):
        raise ParameterError(f'{key} must be a mapping, got {entry!r}')
    known = [f.name for f in fields(cls)]
    unknown = sorted(set(entry) - set(known))
    if unknown:
        raise ParameterError(f'{key}: unknown keys {unknown}; known: {known}')
    required = [f.name for f in fields(cls) if f.default is MISSING
                and f.default_factory is MISSING]
    absent = [name for name in required if name not in entry]
    if absent:
        raise ParameterError(f'{key}: missing {", ".join(f"{key}.{a}" for a in absent)}')
    return cls(**entry)


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
        speed = _build(SpeedProfile, 'speed', body.get('speed', {}))
        initial = _build(InitialState, 'initial', body.get('initial', {}))
        road_entries = body.get('road')
        if not isinstance(road_entries, list) or not road_entries:
            raise ParameterError('road must be a non-empty list of segments')
        road = Road([_segment(e, i, speed.initial) for i, e in enumerate(road_entries)])
        return Scenario(str(body.get('name', Path(source).stem)),
                        check_finite('scenario.duration', body.get('duration', 10.0)), road,
                        speed, initial)
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
    document = read_yaml(path)
    if speed is not None and document is not None:
        if not isinstance(document, Mapping) or not isinstance(
                document.get('scenario'), Mapping):
            raise ConfigError(f'{path}: expected a mapping with a scenario key')
        body = dict(document['scenario'])
        body['speed'] = {**dict(body.get('speed', {})), 'initial': speed}
        document = {'scenario': body}
    return scenario_from_dict(document, str(path))


def with_initial(scenario: Scenario, initial: InitialState) -> Scenario:
    """
    Return the scenario with other initial conditions.

    :param scenario: the scenario.
    :param initial: the new initial state.
    :return: a copy with ``initial`` replaced.
    """
    return replace(scenario, initial=initial)
