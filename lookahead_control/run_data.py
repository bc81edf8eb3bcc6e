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
A recorded run as data: the contract topics of a bag, and the controller re-run on them.

No ROS here. :func:`load_run` reads any rosbag2 MCAP bag with the contract topics (names
can be remapped); :func:`rerun` feeds the recorded inputs into
:class:`~lookahead_control.controller_core.SteeringController` in the order the node
saw them and compares its commands with the recorded steering.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from pathlib import Path
import struct
from typing import Any, Callable, Mapping, Optional, Sequence

from lookahead_control import cdr_decode as cdr
from lookahead_control import conversions as conv
from lookahead_control.bags import (bag_topics, node_parameters, RawMessage, read_raw,
                                    run_description)
from lookahead_control.config import ConfigError, dataclass_from_params
from lookahead_control.controller_core import Command, SteeringController
from lookahead_control.params import ControllerParams, VehicleParams

TOPICS = {'lateral_error': '/lateral_error', 'yaw': '/yaw', 'velocity': '/velocity',
          'road_curvature': '/road_curvature', 'steering': '/steering',
          'debug': '/controller/debug', 'ground_truth': '/sim_plant/ground_truth'}
INPUTS = ('lateral_error', 'yaw', 'velocity', 'road_curvature')
_JOINTS = ('sensor_msgs/msg/JointState',)
_FAST_TYPES = {'lateral_error': ('geometry_msgs/msg/PointStamped',),
               'yaw': ('sensor_msgs/msg/Imu',),
               'velocity': ('geometry_msgs/msg/TwistStamped',),
               'road_curvature': (), 'steering': _JOINTS, 'debug': _JOINTS,
               'ground_truth': _JOINTS}
_PARSE: dict[str, Callable[[Any], Any]] = {
    'lateral_error': conv.from_lateral_error, 'yaw': conv.from_yaw,
    'velocity': conv.from_velocity, 'road_curvature': conv.from_curvature}


@dataclass
class RunData:
    """
    The contract messages of one bag.

    :param bag: where they came from.
    :param inputs: ``(receive ns, input name, sample)`` in receive order.
    :param steering: stamp -> (angle, receive ns) of the recorded commands.
    :param debug: stamp -> the controller's debug values.
    :param truth: stamp -> the simulator's ground truth (empty for real vehicles).
    :param lateral_received: stamp -> receive ns of the lateral error.
    :param counts: messages per topic in the bag.
    :param description: the bag's ``lookahead_control/*`` run description.
    :param controller_params: the recorded parameters of ``/controller``.
    """

    bag: Path
    inputs: list[tuple[int, str, Any]] = field(default_factory=list)
    steering: dict[int, tuple[float, int]] = field(default_factory=dict)
    debug: dict[int, dict[str, float]] = field(default_factory=dict)
    truth: dict[int, dict[str, float]] = field(default_factory=dict)
    lateral_received: dict[int, int] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    description: dict[str, str] = field(default_factory=dict)
    controller_params: dict[str, Any] = field(default_factory=dict)


def load_run(bag: Path, topics: Optional[Mapping[str, str]] = None) -> RunData:
    """
    Read the contract topics of a bag.

    :param bag: the bag directory.
    :param topics: role -> topic name overrides of :data:`TOPICS`.
    :return: the run.
    :raises ConfigError: the bag is unreadable or lacks the lateral-error topic.
    """
    names = {**TOPICS, **(topics or {})}
    role_of = {topic: role for role, topic in names.items()}
    available = bag_topics(bag)
    if names['lateral_error'] not in available:
        raise ConfigError(f'{bag}: no {names["lateral_error"]} topic (has: '
                          f'{", ".join(sorted(available)) or "none"}); remap with '
                          '--topic lateral_error=NAME')
    run = RunData(Path(bag), counts={t: c for t, (_, c) in available.items()},
                  description=run_description(Path(bag)))
    run.controller_params = node_parameters(Path(bag), '/controller')
    for raw in read_raw(bag, [t for t in role_of if t in available]):
        role = role_of[raw.topic]
        # the contract types are read straight from their bytes (long bags); others,
        # and anything not plain little-endian CDR, through the general deserializer
        fast = cdr.little_endian(raw.data) and raw.msgtype in _FAST_TYPES[role]
        try:
            _store(run, role, raw, fast)
        except (ValueError, AssertionError, struct.error, UnicodeDecodeError) as err:
            raise ConfigError(f'{bag}: corrupt {raw.topic} message: {err}') from err
    return run


def _store(run: RunData, role: str, raw: RawMessage, fast: bool) -> None:
    if role in _PARSE:
        sample = (cdr.DECODERS[raw.msgtype](raw.data) if fast
                  else _PARSE[role](raw.decode()))
        run.inputs.append((raw.recv_ns, role, sample))
        if role == 'lateral_error':
            run.lateral_received.setdefault(sample.stamp_ns, raw.recv_ns)
    elif role == 'steering':
        parsed = cdr.steering(raw.data) if fast else conv.from_steering(raw.decode())
        if parsed is not None:
            run.steering[parsed[0]] = (parsed[1], raw.recv_ns)
    else:
        if fast:
            stamp, values = cdr.named_values(raw.data)
        else:
            msg = raw.decode()
            stamp, values = conv.stamp_to_ns(msg.header.stamp), conv.from_named_values(msg)
        getattr(run, 'debug' if role == 'debug' else 'truth')[stamp] = values


def controller_from_params(params: Mapping[str, Any],
                           overrides: Optional[Mapping[str, Any]] = None
                           ) -> tuple[SteeringController, bool]:
    """
    Build the controller core from recorded node parameters plus overrides.

    :param params: flat ``/controller`` parameters (empty: defaults).
    :param overrides: ``name -> value`` replacing recorded values.
    :return: the controller and whether it waited for matching stamps.
    :raises ConfigError: an override names an unknown parameter or a bad value.
    """
    merged = {**params, **(overrides or {})}
    known = set(params) | {'acceleration_source', 'use_curvature_preview',
                           'wait_for_matching_stamps'}
    for name in overrides or {}:
        head = name.partition('.')[0]
        if name not in known and head not in ('vehicle', 'controller'):
            raise ConfigError(f'override {name!r}: not a controller parameter')
    vehicle = dataclass_from_params(VehicleParams, merged, 'vehicle', 'bag parameters')
    controller = dataclass_from_params(ControllerParams, merged, 'controller',
                                       'bag parameters')
    core = SteeringController(vehicle, controller,
                              str(merged.get('acceleration_source', 'imu')),
                              bool(merged.get('use_curvature_preview', False)))
    return core, bool(merged.get('wait_for_matching_stamps', False))


@dataclass(frozen=True)
class Rerun:
    """
    The controller re-run on recorded inputs.

    :param commands: stamp -> the re-computed command.
    :param compared: number of stamps with both a recorded and a re-computed command.
    :param max_diff: largest |recorded - re-computed| steering [rad].
    :param rms_diff: RMS of the differences [rad].
    :param order: ``stamp`` (lockstep: inputs of a step first) or ``receive``.
    """

    commands: dict[int, Command]
    compared: int
    max_diff: float
    rms_diff: float
    order: str


def _stamp_order(inputs: Sequence[tuple[int, str, Any]]) -> list[tuple[int, str, Any]]:
    # the node answers a step once all inputs of its stamp are in: lateral error last
    return sorted(inputs, key=lambda item: (item[2].stamp_ns, item[1] == 'lateral_error',
                                            item[0]))


def rerun(run: RunData, overrides: Optional[Mapping[str, Any]] = None,
          order: Optional[str] = None) -> Rerun:
    """
    Feed the recorded inputs into a fresh controller and compare with the recording.

    :param run: the recorded run.
    :param overrides: parameter overrides (``controller.natural_frequency`` ...).
    :param order: ``stamp`` or ``receive`` (default: ``stamp`` if the node waited for
        matching stamps, else ``receive``).
    :return: commands and differences.
    """
    core, matched = controller_from_params(run.controller_params, overrides)
    order = order or ('stamp' if matched else 'receive')
    if order not in ('stamp', 'receive'):
        raise ConfigError(f'order {order!r}: must be stamp or receive')
    feed = _stamp_order(run.inputs) if order == 'stamp' else run.inputs
    update: dict[str, Callable[[Any], None]] = {
        'lateral_error': core.update_lateral_error, 'yaw': core.update_yaw,
        'velocity': core.update_velocity, 'road_curvature': core.update_curvature}
    commands: dict[int, Command] = {}
    for _, role, sample in feed:
        update[role](sample)
        if role == 'lateral_error':
            command = core.compute()
            if command is not None:
                commands[command.stamp_ns] = command
    diffs = [abs(run.steering[s][0] - c.steering) for s, c in commands.items()
             if s in run.steering]
    return Rerun(commands, len(diffs), max(diffs, default=math.nan),
                 math.sqrt(sum(d * d for d in diffs) / len(diffs)) if diffs else math.nan,
                 order)
