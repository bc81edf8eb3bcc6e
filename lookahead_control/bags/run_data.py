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
can be remapped) into columns (:class:`Samples`: numpy arrays, an hour of 100 Hz in
about a second); :func:`rerun` feeds the recorded inputs into
:class:`~lookahead_control.core.controller.SteeringController` in the order the node
saw them and compares its commands with the recorded steering; :func:`rerun_law` gives
the law's values of that re-run for all steps at once.
"""

from __future__ import annotations

import bisect
from collections import Counter, deque
from dataclasses import dataclass, field
import math
from pathlib import Path
import re
import struct
from typing import Any, Callable, Iterable, Iterator, Mapping, Optional, Sequence

from lookahead_control.bags import cdr_decode as cdr
from lookahead_control.bags.mcap_columns import RawColumns, read_columns
from lookahead_control.bags.recorded_diagnostics import (controller_reports, DIAGNOSTICS,
                                                         RecordedDiagnostics)
from lookahead_control.bags.rosbag_io import (bag_topics, FULL_NODE_NAME, NODE_NAME_RULE,
                                              recorded_parameters, run_description,
                                              SCENARIO_KEY, typestore)
from lookahead_control.core.baselines import (BaselineParams, LqrParams, PurePursuitParams,
                                              StanleyParams)
from lookahead_control.core.config import ConfigError, dataclass_from_params
from lookahead_control.core.control_law import cg_error_from, LateralState, LawOutput, steering_law
from lookahead_control.core.controller import (Command, JUMP_NS, LAW_NAMES,
                                               SteeringController)
from lookahead_control.core.lane_keeping import LaneKeepingParams
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
from lookahead_control.core.safety import is_duplicate, SafetyParams
from lookahead_control.ros import conversions as conv
import numpy as np
import numpy.typing as npt
from rosbags.serde import SerdeError

Array = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

TOPICS = {'lateral_error': '/lateral_error', 'yaw': '/yaw', 'velocity': '/velocity',
          'road_curvature': '/road_curvature', 'steering': '/steering',
          'debug': '/controller/debug', 'ground_truth': '/sim_plant/ground_truth'}
INPUTS = ('lateral_error', 'yaw', 'velocity', 'road_curvature')
CONTROLLER_NODE = '/controller'
#: where every node publishes its parameter changes (rcl's absolute name)
PARAMETER_EVENTS = '/parameter_events'
# rmw's longest topic name: 255 less the DDS prefix rcl keeps room for
MAX_TOPIC_LENGTH = 247
_TOKEN = re.compile(r'[A-Za-z_][A-Za-z0-9_]*')
MSGTYPES = {'lateral_error': 'geometry_msgs/msg/PointStamped',
            'yaw': 'sensor_msgs/msg/Imu', 'velocity': 'geometry_msgs/msg/TwistStamped',
            'road_curvature': 'geometry_msgs/msg/PolygonStamped',
            'steering': 'sensor_msgs/msg/JointState', 'debug': 'sensor_msgs/msg/JointState',
            'ground_truth': 'sensor_msgs/msg/JointState'}
SAMPLES: dict[str, Any] = {
    'lateral_error': conv.LateralErrorSample, 'yaw': conv.YawSample,
    'velocity': conv.VelocitySample, 'road_curvature': conv.CurvatureSample}
_PARSE: dict[str, Callable[[Any], Any]] = {
    'lateral_error': conv.from_lateral_error, 'yaw': conv.from_yaw,
    'velocity': conv.from_velocity, 'road_curvature': conv.from_curvature}
_CORRUPT = (SerdeError, ValueError, AssertionError, struct.error, UnicodeDecodeError,
            IndexError, KeyError)


def node_topics(node: str = CONTROLLER_NODE) -> dict[str, str]:
    """
    Return the contract topics of a controller node and its simulator, by its namespace.

    A controller started in a namespace (``/car_b/controller``) reads and publishes its
    relative topic names there (``/car_b/lateral_error``, ``/car_b/steering``), its debug
    is ``<node>/debug`` and its simulator's ground truth ``<namespace>/sim_plant/
    ground_truth``: one bag can hold several vehicles.

    :param node: the controller's fully qualified name.
    :return: role -> topic (:data:`TOPICS` for ``/controller``).
    :raises ConfigError: not a fully qualified node name.
    """
    if not FULL_NODE_NAME.fullmatch(node):
        raise ConfigError(f'--node {node!r}: {NODE_NAME_RULE}')
    namespace = node.rpartition('/')[0]
    topics = {role: namespace + topic for role, topic in TOPICS.items()}
    topics['debug'] = f'{node}/debug'
    return topics


def resolve_name(topic: str, node: str = CONTROLLER_NODE) -> str:
    """
    Resolve a topic name as the node ``node`` resolves it (ROS name rules).

    As rcl expands a name: ``~`` is the node's fully qualified name, ``{node}`` its name,
    ``{ns}`` and ``{namespace}`` its namespace; a name still relative is put in the
    namespace. The result must be a full ROS topic name: tokens of letters, digits and
    ``_`` (not starting with a digit) between single ``/``, at most
    :data:`MAX_TOPIC_LENGTH` characters.

    :param topic: absolute (``/car_b/x``), private (``~/x``: under the node's name) or
        relative (``x``: in the node's namespace).
    :param node: the node's fully qualified name.
    :return: the absolute name.
    :raises ConfigError: ``topic`` is no ROS topic name, or does not make one.
    """
    namespace, _, name = node.rpartition('/')
    expanded = node + topic[1:] if topic == '~' or topic.startswith('~/') else topic
    for key, value in (('{node}', name), ('{ns}', namespace or '/'),
                       ('{namespace}', namespace or '/')):
        expanded = expanded.replace(key, value)
    if not expanded.startswith('/'):
        expanded = namespace + '/' + expanded
    # before: no check; 'bad name', '' or a typo read a topic no bag can hold and the
    # re-run compared nothing, exit 0
    if len(expanded) > MAX_TOPIC_LENGTH or not all(
            _TOKEN.fullmatch(token) for token in expanded[1:].split('/')):
        shown = repr(topic) + (f' ({node} resolves it as {expanded!r})'
                               if expanded != topic else '')
        raise ConfigError(f'{shown}: not a ROS topic name (letters, digits and _ between '
                          "single '/', no token starting "
                          f'with a digit, at most {MAX_TOPIC_LENGTH} characters; ~ is the '
                          'node, a relative name is in its namespace)')
    return expanded


def plant_node(node: str = CONTROLLER_NODE) -> str:
    """
    Return the simulator node of a controller: ``sim_plant`` in its namespace.

    :param node: the controller's fully qualified name (``/car_b/controller``).
    :return: e.g. ``/car_b/sim_plant``.
    """
    return node.rpartition('/')[0] + '/sim_plant'


def is_controller(params: Mapping[str, Any]) -> bool:
    """
    Return whether recorded node parameters are a controller's.

    :param params: a node's recorded parameters (flat names).
    :return: whether any is a controller's (``law``, ``controller.*``, ``safety.*`` ...;
        a simulator has ``vehicle.*`` only of these).
    """
    return any(name in MODELED or name.partition('.')[0] in LAW_SETS[1:] for name in params)


def recorded_controllers(bag: Path) -> list[str]:
    """
    Return the controller nodes whose parameters a bag recorded.

    :param bag: the bag.
    :return: their fully qualified names, sorted.
    """
    return controllers_of(recorded_parameters(bag))


def controllers_of(recorded: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """
    Return the controller nodes among a bag's recorded parameters.

    :param recorded: node -> its parameters (:func:`recorded_parameters`).
    :return: their fully qualified names, sorted.
    """
    return sorted(node for node, params in recorded.items() if is_controller(params))


def scenario_text(run: RunData) -> Optional[str]:
    """
    Return the scenario file the run's simulator ran, as the bag stored it.

    The recorder stores each described simulator's scenario under
    ``lookahead_control/scenario/<node>`` and the last one it read under
    ``lookahead_control/scenario``; a bag from before the per-node key holds only the
    latter, which is another simulator's where the bag's simulators ran different files.

    :param run: the run.
    :return: the scenario YAML text, or None where the bag does not say which it is.
    """
    own = run.description.get(SCENARIO_KEY + plant_node(run.controller_node))
    if own is not None:
        return own
    if not run.plant_params:
        return None
    files = {str(params['scenario_file']) for params in recorded_parameters(run.bag).values()
             if 'scenario_file' in params}
    if len(files) > 1:
        return None         # simulators of different scenarios: the one stored is either's
    return run.description.get(SCENARIO_KEY)


@dataclass(frozen=True)
class Samples:
    """
    The messages of one topic as columns, in receive order.

    :param recv_ns: receive times [ns].
    :param stamp_ns: header stamps [ns].
    :param order: position in the file (breaks receive-time ties).
    :param values: one array per field; NaN where a message lacks the field.
    """

    recv_ns: IntArray
    stamp_ns: IntArray
    order: IntArray
    values: dict[str, Array]

    def __len__(self) -> int:
        """Return the number of messages."""
        return int(self.stamp_ns.size)

    @staticmethod
    def empty(names: Sequence[str] = ()) -> Samples:
        """Return no messages with the given fields."""
        none = np.zeros(0, dtype=np.int64)
        return Samples(none, none, none, {name: np.zeros(0) for name in names})

    def by_stamp(self) -> dict[int, dict[str, float]]:
        """Return stamp -> field values, the last received message of each stamp."""
        names = list(self.values)
        rows = zip(*(self.values[n].tolist() for n in names)) if names else (
            () for _ in range(len(self)))
        return {stamp: dict(zip(names, row))
                for stamp, row in zip(self.stamp_ns.tolist(), rows)}


def _column(values: list[Any]) -> Any:
    """Return a field's values as an array: floats, or objects (the preview's points)."""
    if any(isinstance(v, tuple) for v in values):
        column = np.empty(len(values), dtype=object)
        column[:] = [v if isinstance(v, tuple) else () for v in values]
        return column
    return np.array(values, dtype=float)


class _Pieces:
    """Columns of one role gathered batch by batch (and message by message)."""

    def __init__(self, names: Sequence[str] = ()) -> None:
        self.names = list(names)
        self.pieces: list[tuple[IntArray, IntArray, IntArray, dict[str, Array]]] = []
        self.single: list[tuple[int, int, int, dict[str, float]]] = []

    def add(self, raw: RawColumns, columns: cdr.Columns, mask: npt.NDArray[np.bool_]
            ) -> None:
        self.pieces.append((raw.recv_ns[mask], raw.order[mask], columns.stamp_ns[mask],
                            {name: v[mask] for name, v in columns.values.items()}))

    def samples(self) -> Samples:
        if self.single:
            rows = [row for *_, row in self.single]
            heads = np.array([head for *head, _ in self.single], dtype=np.int64)
            self.pieces.append((heads[:, 0], heads[:, 1], heads[:, 2],
                                {n: _column([r.get(n, math.nan) for r in rows])
                                 for n in {name for row in rows for name in row}}))
            self.single = []
        if not self.pieces:
            return Samples.empty(self.names)
        names = list(dict.fromkeys(self.names + [n for p in self.pieces for n in p[3]]))
        recv, order, stamp = (np.concatenate([p[i] for p in self.pieces]) for i in range(3))
        values = {n: np.concatenate([p[3].get(n, np.full(p[0].size, math.nan))
                                     for p in self.pieces]) for n in names}
        sort = np.lexsort((order, recv))
        return Samples(recv[sort], stamp[sort], order[sort],
                       {n: v[sort] for n, v in values.items()})


@dataclass
class RunData:
    """
    The contract messages of one bag, as columns.

    :param bag: where they came from.
    :param inputs: per input (:data:`INPUTS`): the controller's input samples, with the
        fields of :data:`SAMPLES` (none if the bag lacks the topic).
    :param steering: the recorded commands (``angle``).
    :param debug: the controller's debug values.
    :param truth: the simulator's ground truth (empty for real vehicles).
    :param counts: messages per topic in the bag.
    :param description: the bag's ``lookahead_control/*`` run description.
    :param controller_params: the recorded parameters of the controller node.
    :param plant_params: the recorded parameters of its ``sim_plant`` (empty: none).
    :param controller_node: the controller node's name (``/controller``).
    :param parameter_events: the controller node's parameter sets at run time, in the
        order received from ``/parameter_events`` (``{name: value}`` each; a deleted
        parameter None); None: the bag has no ``/parameter_events``.
    :param parameter_events_recv_ns: when each of them was received (the recorder's
        clock, as the debug topic's ``recv_ns``); None: not known (taken as received
        after the first recorded answer).
    :param diagnostics: the controller node's statuses on ``/diagnostics``
        (:func:`~lookahead_control.bags.recorded_diagnostics.controller_reports`); None:
        the bag has no ``/diagnostics`` (or it was not read).
    """

    bag: Path
    inputs: dict[str, Samples] = field(default_factory=dict)
    steering: Samples = field(default_factory=Samples.empty)
    debug: Samples = field(default_factory=Samples.empty)
    truth: Samples = field(default_factory=Samples.empty)
    counts: dict[str, int] = field(default_factory=dict)
    description: dict[str, str] = field(default_factory=dict)
    controller_params: dict[str, Any] = field(default_factory=dict)
    plant_params: dict[str, Any] = field(default_factory=dict)
    controller_node: str = CONTROLLER_NODE
    parameter_events: Optional[list[dict[str, Any]]] = None
    parameter_events_recv_ns: Optional[list[int]] = None
    diagnostics: Optional[RecordedDiagnostics] = None


def load_run(bag: Path, topics: Optional[Mapping[str, str]] = None,
             node: str = CONTROLLER_NODE, diagnostics: Optional[str] = DIAGNOSTICS
             ) -> RunData:
    """
    Read the contract topics of a bag.

    The contract types are read as columns straight from the bag's bytes (about a
    microsecond per message); anything else (big-endian CDR, unusual joint layouts)
    through the general deserializer.

    :param bag: the bag directory.
    :param topics: role -> topic name overrides of the node's topics.
    :param node: the controller node whose run it is: its parameters, its debug topic
        and, unless ``topics`` says otherwise, the contract topics in its namespace
        (:func:`node_topics`).
    :param diagnostics: the topic of its statuses (``/diagnostics``; a relative name is
        the node's, as ``topics``); None: not read (a re-run does not need them). A
        topic other than ``/diagnostics`` the bag lacks is refused.
    :return: the run.
    :raises ConfigError: an unknown role in ``topics``, the bag is unreadable, lacks the
        lateral-error topic, a contract topic has another type, ``node`` is not
        ``/controller`` and the bag has neither its parameters nor its debug topic, or
        its recorded parameters are not a controller's.
    """
    unknown = sorted(set(topics or {}) - set(TOPICS))
    if unknown:
        # before: a KeyError traceback where the topic was in the bag, else ignored
        raise ConfigError(f'--topic {unknown[0]}=...: unknown role {unknown[0]!r}; roles: '
                          f'{", ".join(TOPICS)}')
    # a relative override is the node's, as the node resolves its own names: before,
    # steering=steering on /car_b/controller read a /car_b-less name
    defaults = node_topics(node)                # the node's name checked first
    overrides: dict[str, str] = {}
    for given_role, given in (topics or {}).items():
        try:
            overrides[given_role] = resolve_name(given, node)
        except ConfigError as err:
            raise ConfigError(f'--topic {given_role}={given}: {err}') from err
    names = {**defaults, **overrides}
    role_of = {topic: role for role, topic in names.items()}
    available = bag_topics(bag)
    absent = [role for role in overrides if overrides[role] not in available]
    if absent:
        # before: a named topic the bag lacks (a typo, the wrong namespace) was read as
        # no message: steering=stearing compared 0 commands and exited 0
        first = absent[0]
        raise ConfigError(f'{bag}: --topic {first}={(topics or {})[first]}: no '
                          f'{overrides[first]} in the bag (has: '
                          f'{", ".join(sorted(available)) or "none"})')
    recorded = recorded_parameters(Path(bag))        # every node's, one read
    controller_params = recorded.get(node, {})
    if node != CONTROLLER_NODE and not controller_params and names['debug'] not in available:
        described = sorted(recorded)
        raise ConfigError(f'{bag}: --node {node}: neither its parameters nor its '
                          f'{names["debug"]} are in the bag (parameters recorded of: '
                          f'{", ".join(described) or "no node"})')
    if controller_params and not is_controller(controller_params):
        # another node of the bag (a simulator: vehicle.* only) is no controller: its
        # re-run was the default controller on its namespace's inputs, a result without
        # a word (1.6 mrad off on a two-car DDS run)
        raise ConfigError(f'{bag}: --node {node}: its recorded parameters are not a '
                          "controller's (no law, controller.*, safety.* ...; controllers "
                          'recorded: '
                          f'{", ".join(recorded_controllers(Path(bag))) or "none"})')
    if names['lateral_error'] not in available:
        # a bag of vehicles in namespaces only: the controller to name is one of them
        others = [name for name in recorded_controllers(Path(bag)) if name != node]
        hint = (f' or name the controller: --node {" or ".join(others)}' if others else '')
        raise ConfigError(f'{bag}: no {names["lateral_error"]} topic (has: '
                          f'{", ".join(sorted(available)) or "none"}); remap with '
                          f'--topic lateral_error=NAME{hint}')
    for topic, (msgtype, _) in available.items():
        role = role_of.get(topic)
        if role is not None and msgtype != MSGTYPES[role]:
            raise ConfigError(f'{bag}: {topic} ({role}) has type {msgtype}; the contract '
                              f'type is {MSGTYPES[role]} (remap with --topic {role}=NAME)')
    fields = {**{role: SAMPLES[role]._fields[1:] for role in SAMPLES}, 'steering': ('angle',)}
    pieces = {role: _Pieces(fields.get(role, ())) for role in TOPICS}
    store = typestore()
    for topic, msgtype, raw in read_columns(bag, [t for t in role_of if t in available]):
        role = role_of[topic]
        try:
            _decode(pieces[role], role, raw, lambda data: store.deserialize_cdr(data, msgtype))
        except _CORRUPT as err:
            raise ConfigError(f'{bag}: corrupt {topic} message: {err}') from err
    run = RunData(Path(bag), {role: pieces[role].samples() for role in INPUTS},
                  pieces['steering'].samples(), pieces['debug'].samples(),
                  pieces['ground_truth'].samples(),
                  counts={t: c for t, (_, c) in available.items()},
                  description=run_description(Path(bag)))
    run.controller_params = controller_params
    run.plant_params = recorded.get(plant_node(node), {})
    run.controller_node = node
    if PARAMETER_EVENTS in available:
        received = parameter_events(bag, node, store, with_recv_ns=True)
        run.parameter_events = [change for _, change in received]
        run.parameter_events_recv_ns = [recv for recv, _ in received]
    if diagnostics is not None:
        try:
            topic = resolve_name(diagnostics, node)
        except ConfigError as err:
            raise ConfigError(f'--diagnostics {diagnostics}: {err}') from err
        if topic in available:
            run.diagnostics = controller_reports(bag, node, controllers_of(recorded), store,
                                                 topic)
        elif topic != DIAGNOSTICS:
            # a named topic the bag lacks, as for --topic (a typo read as none)
            raise ConfigError(f'{bag}: --diagnostics {diagnostics}: no {topic} in the bag')
    return run


def parameter_value(value: Any) -> Any:
    """
    Return the Python value of an ``rcl_interfaces/ParameterValue`` (None: not set).

    :param value: the message (any object with its fields).
    :return: the value.
    """
    field_of = {1: 'bool_value', 2: 'integer_value', 3: 'double_value', 4: 'string_value',
                5: 'byte_array_value', 6: 'bool_array_value', 7: 'integer_array_value',
                8: 'double_array_value', 9: 'string_array_value'}
    name = field_of.get(int(value.type))
    if name is None:
        return None
    out = getattr(value, name)
    if int(value.type) >= 5:
        return [x.item() if hasattr(x, 'item') else x for x in out]
    return out.item() if hasattr(out, 'item') else out


def parameter_events(bag: Path, node: str, store: Any = None,
                     with_recv_ns: bool = False) -> list[Any]:
    """
    Return a node's parameter sets recorded on ``/parameter_events``, in receive order.

    One ``{name: value}`` per message that changed or deleted a parameter (the node
    applies each as one set, and counts it: ``~/debug`` ``parameter_sets``); messages
    that only declare parameters (a node starting) are left out.

    :param bag: the bag.
    :param node: the node's fully qualified name.
    :param store: the type store (None: the Jazzy one).
    :param with_recv_ns: return ``(receive time [ns], set)`` pairs.
    :return: the sets.
    :raises ConfigError: a message is corrupt.
    """
    store = store or typestore()
    events: list[tuple[int, int, dict[str, Any]]] = []
    for _, msgtype, raw in read_columns(bag, [PARAMETER_EVENTS]):
        for i in range(raw.start.size):
            try:
                msg = store.deserialize_cdr(raw.data(i), msgtype)
            except _CORRUPT as err:
                raise ConfigError(f'{bag}: corrupt {PARAMETER_EVENTS} message: {err}') from err
            if msg.node != node or not (msg.changed_parameters or msg.deleted_parameters):
                continue
            change = {p.name: parameter_value(p.value) for p in msg.changed_parameters}
            change.update((p.name, None) for p in msg.deleted_parameters)
            events.append((int(raw.recv_ns[i]), int(raw.order[i]), change))
    ordered = sorted(events, key=lambda e: (e[0], e[1]))
    if with_recv_ns:
        return [(recv, change) for recv, _, change in ordered]
    return [change for _, _, change in ordered]


def _fields(sample: Any) -> dict[str, float]:
    """Return the fields of an input sample but its stamp."""
    return {name: value for name, value in sample._asdict().items() if name != 'stamp_ns'}


def _decode(pieces: _Pieces, role: str, raw: RawColumns,
            deserialize: Callable[[bytes], Any]) -> None:
    """Decode one batch of a role's messages: as columns, the rest one by one."""
    args = (raw.buffer, raw.start, raw.length)
    if role == 'steering':
        columns, present = cdr.steering_columns(*args)
        pieces.add(raw, columns, present)
    elif role in ('debug', 'ground_truth'):
        columns = cdr.named_columns(*args)
        pieces.add(raw, columns, columns.ok)
    elif role == 'road_curvature':         # a list of points: one by one
        columns = cdr.Columns(np.zeros(raw.start.size, dtype=bool), raw.recv_ns, {})
    else:
        columns = cdr.COLUMN_DECODERS[MSGTYPES[role]](*args)
        pieces.add(raw, columns, columns.ok)
    for i in np.nonzero(~columns.ok)[0].tolist():
        data = raw.data(i)
        head = (int(raw.recv_ns[i]), int(raw.order[i]))
        if role == 'road_curvature':
            sample = (cdr.curvature(data) if cdr.little_endian(data)
                      else conv.from_curvature(deserialize(data)))
            pieces.single.append((*head, sample.stamp_ns, _fields(sample)))
        elif role in _PARSE:
            sample = _PARSE[role](deserialize(data))
            pieces.single.append((*head, sample.stamp_ns, _fields(sample)))
        elif role == 'steering':
            parsed = conv.from_steering(deserialize(data))
            if parsed is not None:
                pieces.single.append((*head, parsed[0], {'angle': parsed[1]}))
        else:
            msg = deserialize(data)
            pieces.single.append((*head, conv.stamp_to_ns(msg.header.stamp),
                                  conv.from_named_values(msg)))


# node parameters the offline re-run does not model: it has no node clock (the recorder's
# receive times are another node's clock), so no watchdog (stale inputs, hold, ramp), no
# future-stamp check and no timer mode; overriding them would report a difference of 0
NOT_MODELED = frozenset({
    'safety.input_timeout', 'safety.hold_time', 'safety.safe_angle', 'safety.max_future',
    'watchdog_rate_hz', 'mode', 'rate_hz', 'sync_timeout', 'qos_reliability', 'frame_id',
    'autostart', 'diagnostics_rate_hz', 'executor', 'use_sim_time'})
#: node parameters a controller's bag may predate, and the value the node ran with then
#: (:func:`as_it_ran`): the newest yaw and velocity samples (before dev-sc52), the
#: curvature polygon as stamped (before dev-sc53), no hold in the feedforward preview
#: (before dev-sc55), w_n not cut at a slow answer period (before dev-sc56)
NODE_PARAMS_BEFORE = {'align_inputs': 'never', 'curvature_at_yaw_stamp': False,
                      'lane_keeping.hold_preview': 0.0, 'lane_keeping.frequency_lag': 0.0}
# node parameters it models besides the parameter sets of LAW_SETS
MODELED = ('law', 'acceleration_source', 'use_curvature_preview', 'wait_for_matching_stamps',
           'align_inputs', 'curvature_at_yaw_stamp')
# the parameter sets (namespaces) the re-run builds the controller and every law from
LAW_SETS = ('vehicle', 'controller', 'safety', 'lane_keeping', 'pure_pursuit', 'stanley',
            'lqr')


def as_it_ran(params: Mapping[str, Any],
              overrides: Optional[Mapping[str, Any]] = None) -> dict[str, Any]:
    """
    Return values for parameters a bag lacks because it predates them, as the law ran.

    A bag that records ``lane_keeping.integral_gain`` but not
    ``lane_keeping.low_speed_integral_gain`` was recorded before the integral gain was
    scheduled on speed (dev-kisched): its law ran with the constant ``integral_gain`` at
    every speed. A bag's missing value is not taken from the current defaults (from
    dev-kisched to dev-gate they were a schedule, 0.05 1/s at and below 15 m/s: another
    law), but is ``integral_gain`` (the overridden one if ``-p`` sets it): ``k_i``
    constant. An override of the name itself wins.

    A bag of a controller node (its parameters recorded, among them
    ``use_curvature_preview``, which every node since the first has) without a parameter
    of :data:`NODE_PARAMS_BEFORE` ran as that value says: without ``align_inputs``
    (before dev-sc52) it read the newest yaw and velocity samples (``never``; a bag of
    inputs on one stamp re-runs the same either way), without ``curvature_at_yaw_stamp``
    (before dev-sc53) the curvature polygon as stamped (false), without
    ``lane_keeping.hold_preview`` (before dev-sc55) no share of the answer period in the
    feedforward preview (0), without ``lane_keeping.frequency_lag`` (before dev-sc56) w_n
    not cut at the answer period (0; a bag answered 100 times a second re-runs the same
    either way, for both).

    :param params: the recorded parameters (empty: nothing is filled in).
    :param overrides: ``name -> value`` replacing recorded values.
    :return: ``name -> value`` to use where the bag has none (empty: nothing missing).
    """
    overrides = overrides or {}
    filled: dict[str, Any] = {}
    if 'use_curvature_preview' in params:      # a controller node's parameters
        filled.update({name: value for name, value in NODE_PARAMS_BEFORE.items()
                       if name not in params and name not in overrides})
    low = 'lane_keeping.low_speed_integral_gain'
    if ('lane_keeping.integral_gain' not in params or low in params or low in overrides):
        return filled
    filled[low] = overrides.get('lane_keeping.integral_gain',
                                params['lane_keeping.integral_gain'])
    return filled


def ran_law(params: Mapping[str, Any]) -> str:
    """
    Return the law a controller's (merged) parameters ran: ``paper`` where they name none.

    :param params: the parameters with their overrides.
    :return: the law's name.
    """
    return str(params.get('law', 'paper'))


def controller_from_params(params: Mapping[str, Any],
                           overrides: Optional[Mapping[str, Any]] = None,
                           node: str = CONTROLLER_NODE) -> tuple[SteeringController, bool]:
    """
    Build the controller core (law, input checks, output limits) from recorded parameters.

    A parameter the bag predates is the value that reproduces the law it ran
    (:func:`as_it_ran`), not the current default.

    :param params: flat ``/controller`` parameters (empty: defaults).
    :param overrides: ``name -> value`` replacing recorded values.
    :param node: the node they were recorded of, named in the message of a bad value.
    :return: the controller and whether it waited for matching stamps.
    :raises ConfigError: an override names an unknown parameter, one the re-run does not
        model (:data:`NOT_MODELED`), or a bad value.
    """
    merged = {**params, **as_it_ran(params, overrides), **(overrides or {})}
    for name in overrides or {}:
        head = name.partition('.')[0]
        if name in NOT_MODELED:
            raise ConfigError(f'override {name!r}: the offline re-run does not model it (no '
                              'node clock: no watchdog, hold or timer); replay the bag '
                              'over DDS to a controller node instead')
        if name not in MODELED and head not in LAW_SETS:
            raise ConfigError(f'override {name!r}: not a controller parameter the offline '
                              're-run uses ('
                              f'{", ".join(s + ".*" for s in LAW_SETS)}, '
                              f'{", ".join(MODELED)})')
    # before: 'bag parameters', which in a bag of several vehicles did not say whose
    source = f'bag parameters of {node}'
    args = _core_arguments(merged, source)
    try:
        core = SteeringController(*args)
    except ParameterError as exc:
        raise ConfigError(f'{source}: {exc}') from exc
    return core, bool(merged.get('wait_for_matching_stamps', False))


def _align_choice(value: Any) -> str:
    """
    Return ``align_inputs`` as a choice (a boolean: as a node of dev-sc52's first commits).

    :param value: the recorded or given value.
    :return: ``always`` for true, ``never`` for false, else the value as a string.
    """
    if isinstance(value, bool):
        return 'always' if value else 'never'
    return str(value)


def _core_arguments(merged: Mapping[str, Any], source: str) -> tuple[Any, ...]:
    """Return the controller core's arguments from flat parameters, in its order."""
    vehicle = dataclass_from_params(VehicleParams, merged, 'vehicle', source)
    controller = dataclass_from_params(ControllerParams, merged, 'controller', source)
    safety = dataclass_from_params(SafetyParams, merged, 'safety', source)
    baselines = BaselineParams(
        dataclass_from_params(PurePursuitParams, merged, 'pure_pursuit', source),
        dataclass_from_params(StanleyParams, merged, 'stanley', source),
        dataclass_from_params(LqrParams, merged, 'lqr', source))
    lane_keeping = dataclass_from_params(LaneKeepingParams, merged, 'lane_keeping', source)
    return (vehicle, controller, str(merged.get('acceleration_source', 'imu')),
            bool(merged.get('use_curvature_preview', False)), safety,
            ran_law(merged), baselines, lane_keeping,
            _align_choice(merged.get('align_inputs', 'with_prediction')),
            merged.get('curvature_at_yaw_stamp', True))


def reconfigure(core: SteeringController, params: Mapping[str, Any],
                overrides: Optional[Mapping[str, Any]] = None,
                node: str = CONTROLLER_NODE) -> None:
    """
    Apply a controller's parameters as they stand after a set at run time (as the node).

    :param core: the controller core of the re-run.
    :param params: its flat parameters with the set applied.
    :param overrides: ``name -> value`` that win over them (the re-run's ``-p``).
    :param node: the node they are of, named in the message of a bad value.
    :raises ConfigError: a bad value (the node would have refused the set).
    """
    merged = {**params, **as_it_ran(params, overrides), **(overrides or {})}
    source = f'parameters of {node} set at run time'
    try:
        core.configure(*_core_arguments(merged, source))
    except ParameterError as exc:
        raise ConfigError(f'{source}: {exc}') from exc


@dataclass(frozen=True)
class Rerun:
    """
    The controller re-run on recorded inputs.

    :param commands: stamp -> the re-computed command.
    :param compared: number of stamps with both a recorded and a re-computed command.
    :param max_diff: largest |recorded - re-computed| steering [rad]; NaN if a compared
        angle is not finite (``not_finite``) or nothing was compared.
    :param rms_diff: RMS of the differences [rad].
    :param order: ``stamp`` (lockstep: inputs of a step first) or ``receive``.
    :param estimated: answers of a law that ran on its own curvature estimate (no
        ``road_curvature`` received, lost, or dropped by the map check).
    :param estimated_at: their stamps.
    :param dropped: of those, the answers with the curvature received but dropped by the
        map check (``lane_keeping.map_fallback``).
    :param followed: answers where the re-run took the recorded controller's own
        judgment of the curvature (its debug ``curvature_estimated``) instead of judging
        it on the stamps.
    :param judged_otherwise: of those, the answers the stamps alone judge otherwise (a
        loss a step apart at a switch-over: the node's clock; many: a curvature in the
        bag that the controller did not receive, remapped or a QoS mismatch).
    :param law_switches: switches of the law at run time (``law`` set while running)
        that the re-run followed, from the debug topic's ``law:<name>``.
    :param parameter_sets: parameter sets at run time (recorded ``/parameter_events``)
        the re-run applied at the answer the debug topic's ``parameter_sets`` says.
    :param parameter_sets_unmarked: None: the bag's debug marks where sets took effect
        (or it had none); else the number of recorded sets the re-run could not place
        (a bag from before the marker: it keeps the start-up values but the law).
    :param parameter_sets_before_bag: sets the recorded controller had applied before
        its recorded ``/parameter_events`` begin (a recorder started after them: their
        values are in the bag's parameters); the recorded sets are numbered after them.
    :param inactive_skipped: lateral errors the recorded controller received while
        deactivated (:func:`inactive_inputs`), not computed, as the node did not.
    :param inactive_lost: answers the recorder lost next to a deactivation: among the
        skipped inputs that many were answered (the re-run is not exact there).
    :param refused: inputs the re-run's checks refused, by input, and the last reason
        (a node older than a check used what the re-run refuses).
    :param coalesced_skipped: lateral errors the recorded controller took in and left
        for a newer one under its answer-rate bound (``inactive_inputs(run,
        'coalesced')``), not computed, as the node did not.
    :param coalesced_lost: answers the recorder lost among those stretches.
    :param unreceived_skipped: other lateral errors of the bag the node left unanswered
        between two answers it numbered one after the other (:func:`unanswered_inputs`:
        its reader fell behind and lost them, or it refused them), not computed, as the
        node did not.
    :param not_finite: compared commands whose recorded (or re-computed) angle is not
        finite; ``max_diff`` is NaN then.
    :param repeated: inputs refused as repeating the stamp of the input of their role
        before them (the same message recorded twice: two recorders, a re-sent message),
        counted apart from ``refused``: the node refuses them too.
    :param told: what the re-run's checks would have told on ``/diagnostics``, over the
        whole run: the seconds of each check of the inputs and the output that found
        something (``SteeringController.turning``: ``lateral_error_out_of_scale``,
        ``curvature_disagrees`` ...), and the counts of time jumps and law restarts;
        only those not 0.
    :param runs: the runs the bag holds (:func:`run_starts`): where it holds several, a
        stamp's command is compared with that of the last run that has the stamp.
    :param strays: per input, those stamped more than a second off their run, alone (sent
        late, or stamped ahead; :func:`run_starts`): not re-run, as the node refused them
        against its clock.
    :param strays_to_end: the inputs whose last message in the bag is a stray (a sensor
        clock that jumped for good: the node took none of it from there).
    """

    commands: dict[int, Command]
    compared: int
    max_diff: float
    rms_diff: float
    order: str
    estimated: int = 0
    estimated_at: frozenset[int] = frozenset()
    followed: int = 0
    judged_otherwise: int = 0
    law_switches: int = 0
    parameter_sets: int = 0
    parameter_sets_unmarked: Optional[int] = None
    parameter_sets_before_bag: int = 0
    inactive_skipped: int = 0
    inactive_lost: int = 0
    refused: dict[str, int] = field(default_factory=dict)
    last_refusal: str = ''
    coalesced_skipped: int = 0
    coalesced_lost: int = 0
    unreceived_skipped: int = 0
    dropped: int = 0
    not_finite: int = 0
    repeated: int = 0
    told: dict[str, float] = field(default_factory=dict)
    runs: int = 1
    strays: dict[str, int] = field(default_factory=dict)
    strays_to_end: tuple[str, ...] = ()


def input_stream(run: RunData) -> list[tuple[int, str, Any]]:
    """
    Return the recorded inputs as samples, in the order they were received.

    :param run: the run.
    :return: ``(receive ns, input name, sample)``.
    """
    events: list[tuple[int, int, str, Any]] = []
    for role, samples in run.inputs.items():
        fields = SAMPLES[role]._fields[1:]
        columns = [samples.values[name].tolist() if name in samples.values
                   else [()] * len(samples) for name in fields]
        if 'ahead' in fields:           # the preview's points: a tuple per sample
            at = fields.index('ahead')
            columns[at] = [v if isinstance(v, tuple) else () for v in columns[at]]
        events += [(recv, order, role, SAMPLES[role](stamp, *row)) for recv, order, stamp, *row
                   in zip(samples.recv_ns.tolist(), samples.order.tolist(),
                          samples.stamp_ns.tolist(), *columns)]
    events.sort(key=lambda e: (e[0], e[1]))
    return [(recv, role, sample) for recv, _, role, sample in events]


#: inputs from one whose stamp jumped that must all have jumped, with the run's frequent
#: inputs among them, for a new run (or a gap); and the inputs before it that tell which
#: are frequent: a flushed queue of one sensor, a step or two sent again seconds late, a
#: message stamped seconds ahead are strays, not runs (dev-probe113, 114)
RUN_CONFIRM = 16


@dataclass(frozen=True)
class Runs:
    """
    The runs of a bag's input stream, and its strays.

    :param starts: the index (receive order) of each run's first input (``[0]``: one
        run; empty: no input).
    :param strays: the indices of inputs stamped more than the core's time-jump threshold
        before or after their run's newest, alone (a message sent late or stamped ahead:
        the node refused it against its clock).
    """

    starts: list[int]
    strays: frozenset[int]


def run_starts(inputs: Sequence[tuple[int, str, Any]]) -> Runs:
    """
    Return where the stamps start again (the runs of a bag that holds several) and strays.

    A recorder left running while a simulator was started again records a second run
    whose stamps begin at 0 again. Taken in receive order, an input whose stamp lies more
    than the core's time-jump threshold
    (:data:`~lookahead_control.core.controller.JUMP_NS`) below the newest stamp since
    the last start begins a run when the :data:`RUN_CONFIRM` inputs from it all lie that
    far back too, with two of the inputs that came at least twice in the
    :data:`RUN_CONFIRM` inputs before it among them (one sensor's flushed queue is no
    run; an input that stopped, or comes slower, is not waited for: dev-probe115, a lost
    curvature); a stamp that far ahead is a gap in the same run when they all lie ahead
    too. Otherwise the input is a stray.

    :param inputs: ``(receive ns, input name, sample)`` in receive order.
    :return: the runs.
    """
    starts: list[int] = []
    strays: set[int] = set()
    newest: Optional[int] = None
    # the run's last inputs (not strays)
    recent: deque[str] = deque(maxlen=RUN_CONFIRM)
    for i, (_, role, sample) in enumerate(inputs):
        stamp = sample.stamp_ns
        if newest is None:
            starts.append(i)
            newest = stamp
            recent.append(role)
            continue
        top = newest
        if stamp < top - JUMP_NS:
            if _jumped_together(inputs[i:i + RUN_CONFIRM], recent,
                                lambda s: s < top - JUMP_NS):
                starts.append(i)
                newest = stamp
                recent.clear()
                recent.append(role)
            else:
                strays.add(i)
            continue
        if stamp > top + JUMP_NS:
            if not _jumped_together(inputs[i:i + RUN_CONFIRM], recent,
                                    lambda s: s > top + JUMP_NS):
                strays.add(i)
                continue
            top = stamp                     # a gap in the recording: the same run
        newest = max(top, stamp)
        recent.append(role)
    return Runs(starts, frozenset(strays))


def _jumped_together(window: Sequence[tuple[int, str, Any]], recent: Iterable[str],
                     jumped: Callable[[int], bool]) -> bool:
    """Return whether a whole window of inputs jumped, two of the run's frequent in it."""
    frequent = {role for role, count in Counter(recent).items() if count >= 2}
    present = frequent & {role for _, role, _ in window}
    return (len(window) == RUN_CONFIRM and len(present) >= min(2, len(frequent))
            and all(jumped(sample.stamp_ns) for _, _, sample in window))


def _stamp_order(inputs: Sequence[tuple[int, str, Any]],
                 runs: Runs) -> list[tuple[int, str, Any]]:
    # the node answers a step once all inputs of its stamp are in: lateral error last;
    # each run of the bag apart, in the order they were recorded (dev-probe111: two runs
    # of a simulator in one bag were interleaved step by step)
    starts = runs.starts + [len(inputs)]
    ordered: list[tuple[int, str, Any]] = []
    for begin, end in zip(starts, starts[1:]):
        ordered += sorted(inputs[begin:end], key=lambda item: (
            item[2].stamp_ns, item[1] == 'lateral_error', item[0]))
    return ordered


def _resolve_order(order: Optional[str], matched: bool, simulated: bool = False) -> str:
    # stamp order where the node waited for a step's inputs (lockstep), and for a
    # simulator's run: sim_plant publishes a step's inputs together, the lateral error
    # last, which the recorder's receive times do not always keep (two processes, two
    # middleware queues: a realtime run re-run in receive order was 50 mrad off, in stamp
    # order exact); receive order for a real vehicle's
    order = order or ('stamp' if matched or simulated else 'receive')
    if order not in ('stamp', 'receive'):
        raise ConfigError(f'order {order!r}: must be stamp or receive')
    return order


def rerun(run: RunData, overrides: Optional[Mapping[str, Any]] = None,
          order: Optional[str] = None) -> Rerun:
    """
    Feed the recorded inputs into a fresh controller and compare with the recording.

    The whole controller core runs as in the node: input checks, the law, the low-speed
    hold and the output limits (angle, rate, lateral acceleration), with the recorded
    ``safety.*`` values or the overrides. Not modeled (no node clock): the watchdog's
    stale-input hold and ramp, the future-stamp check, timer mode. Whether the curvature
    is in is what the recorded controller judged where its debug topic says
    (:func:`recorded_judgment`; with ``law`` overridden too: it says which curvature the
    node had), else judged on the stamps (``SteeringController.curvature_lost``).

    :param run: the recorded run.
    :param overrides: parameter overrides (``controller.natural_frequency`` ...).
    :param order: ``stamp`` or ``receive`` (default: ``stamp`` if the node waited for
        matching stamps or the bag is a simulator's run (it holds ``/sim_plant``'s
        parameters), else ``receive``).
    :return: commands and differences.
    """
    core, matched = controller_from_params(run.controller_params, overrides,
                                           run.controller_node)
    order = _resolve_order(order, matched, bool(run.plant_params))
    inputs = input_stream(run)
    runs = run_starts(inputs)
    strays = {id(inputs[i]) for i in runs.strays}
    feed = _stamp_order(inputs, runs) if order == 'stamp' else inputs
    lateral = run.inputs.get('lateral_error')
    if lateral is not None and len(lateral) and len(run.steering):
        # a recorder that subscribed late: the answer to an input it missed is the rate
        # limit's reference of the first command it can compare
        before = np.nonzero(run.steering.stamp_ns < lateral.stamp_ns.min())[0]
        if before.size:
            last = before[np.argmax(run.steering.stamp_ns[before])]
            core.seed_output(float(run.steering.values['angle'][last]),
                             int(run.steering.stamp_ns[last]))
    commands: dict[int, Command] = {}
    estimated_at: set[int] = set()
    dropped = 0
    judged = recorded_judgment(run)
    # a law set at run time: the node's debug names the law of each answer (an override
    # of ``law`` runs that law throughout)
    laws = {} if 'law' in (overrides or {}) else recorded_laws(run)
    # other parameters set at run time: the recorded /parameter_events, each applied
    # before the first answer whose debug parameter_sets counts it (bumpless as in the
    # node: the core's configure)
    sets = recorded_parameter_sets(run)
    events = run.parameter_events or []
    unmarked = len(events) if events and not sets else None
    # the node counts its sets from its start, the bag's from the recorder's: a set
    # before the recorder subscribed is in the bag's parameters, not on its events
    before_bag = sets_before_bag(run)
    params, applied = dict(run.controller_params), 0
    followed = otherwise = switches = 0
    inactive, lost = inactive_inputs(run)
    coalesced, coalesced_lost = inactive_inputs(run, 'coalesced')
    unreceived = unanswered_inputs(run) - inactive - coalesced
    refusals: dict[str, int] = {}
    last_refusal = ''
    repeated = 0
    last_stamp: dict[str, int] = {}
    # per lateral error taken, the copy the node answered it at (~/debug copies), and
    # its repeats so far and whether the re-run answered it
    targets = answer_copies(run, inputs, runs, feed)
    copy, answered, target = 0, False, None
    for item in feed:
        _, role, sample = item
        if id(item) in strays:
            # stamped seconds off its run, alone: the node refused it against its clock
            # (the re-run has none: its core took it for a time jump and reset the law,
            # dev-probe114), and never answered it
            continue
        # the node's path: input checks (a refused sample is never used), then the law,
        # the low-speed hand-over and the output limits in compute()
        refused = core.accept(role, sample)
        if refused is not None and last_stamp.get(role) == sample.stamp_ns:
            # a message recorded twice, refused as the node refuses it (dev-probe96: 4000
            # such were told as inputs 'a node older than a check used')
            repeated += 1
        elif refused is not None:
            refusals[role] = refusals.get(role, 0) + 1
            last_refusal = refused
        last_stamp[role] = sample.stamp_ns
        if role != 'lateral_error':
            continue
        if refused is None:
            copy, answered = 0, False
            target = targets.get(id(item), 0) if targets is not None else None
        elif is_duplicate(refused):
            copy += 1
        if (sample.stamp_ns in inactive or sample.stamp_ns in coalesced
                or sample.stamp_ns in unreceived):
            continue                # not answered: inactive, coalesced, never received
        if _answered_here(refused, copy, answered, target):
            due = min(sets.get(sample.stamp_ns, applied + before_bag) - before_bag,
                      len(events))
            if due > applied:
                for change in events[applied:due]:
                    for name, value in change.items():
                        if value is None:
                            params.pop(name, None)
                        else:
                            params[name] = value
                law_before = core.law_name
                reconfigure(core, params, overrides, run.controller_node)
                switches += core.law_name != law_before
                applied = due
            law = laws.get(sample.stamp_ns, core.law_name)
            if law != core.law_name:    # as the node: a new law from its reset state
                core.configure(core.vehicle, core.params, core.acceleration_source,
                               core.use_preview, law=law)
                # without recorded parameters the first answer's law is the debug's,
                # not a set at run time (it was called one; dev-probe55)
                switches += bool(commands or run.controller_params)
            received = judged.get(sample.stamp_ns)
            if received is not None:
                followed += 1
                otherwise += received != core.curvature_received(None)
            command = core.compute(curvature_received=received)
            if command is not None:
                answered = True
                commands[command.stamp_ns] = command
                estimates = getattr(core.law, 'curvature_estimated', None)
                if estimates is not None and estimates():
                    estimated_at.add(command.stamp_ns)
                    dropped += core.curvature_in and core.map_check.dropped
    recorded = {stamp: v['angle'] for stamp, v in run.steering.by_stamp().items()}
    diffs = [abs(recorded[s] - c.steering) for s, c in commands.items() if s in recorded]
    # a command recorded as NaN (or inf) differs from every finite re-run: before, max()
    # stepped over its NaN and --check passed a bag of NaN commands (dev-probe93)
    not_finite = sum(not math.isfinite(d) for d in diffs)
    largest = math.nan if not_finite else max(diffs, default=math.nan)
    return Rerun(commands, len(diffs), largest,
                 math.sqrt(sum(d * d for d in diffs) / len(diffs)) if diffs else math.nan,
                 order, len(estimated_at), frozenset(estimated_at), followed, otherwise,
                 switches, applied, unmarked, before_bag, len(inactive), lost, refusals,
                 last_refusal, len(coalesced), coalesced_lost, len(unreceived), dropped,
                 not_finite, repeated, checks_told(core), max(1, len(runs.starts)),
                 dict(Counter(inputs[i][1] for i in sorted(runs.strays))),
                 _strays_to_end(inputs, runs.strays))


def recorded_copies(run: RunData, starts_ns: Sequence[int] = (0,)
                    ) -> Optional[list[dict[int, int]]]:
    """
    Return, per run and answered lateral error, the exact repeats of it before the answer.

    The node answers a repeat of a lateral error no command answered (a lockstep step 0
    taken in while inactive, or before its yaw), at the copy its ``~/debug`` ``copies``
    counts; the re-run answers at that copy too, with the inputs in by then (dev-probe116:
    at the first copy it was 2 mrad off, the node had the next step's yaw and velocity).

    :param run: the bag.
    :param starts_ns: when each run of the bag began (the receive time of its first input):
        each run's stamps start again, and a debug message counts for the run it was
        received in (dev-probe118: keyed by stamp alone, a second run's step 0 answered at
        its 4th copy left the first run's unanswered).
    :return: per run, stamp -> copies; empty dicts for a bag without the node's debug (the
        re-run then answers a repeat of a lateral error it has not answered, as the node
        does); None for a node older than dev-sc51 (debug without ``copies``): it
        answered no repeat.
    """
    copies = run.debug.values.get('copies')
    if copies is None:
        return None if run.debug.values else [{} for _ in starts_ns]
    out: list[dict[int, int]] = [{} for _ in starts_ns]
    for recv, stamp, count in zip(run.debug.recv_ns.tolist(), run.debug.stamp_ns.tolist(),
                                  copies.tolist()):
        if math.isfinite(count):
            at = max(0, bisect.bisect_right(starts_ns, recv) - 1)
            out[at][int(stamp)] = int(count)
    return out


def answer_copies(run: RunData, inputs: Sequence[tuple[int, str, Any]], runs: Runs,
                  feed: Sequence[tuple[int, str, Any]]) -> Optional[dict[int, int]]:
    """
    Return the copy at which the re-run answers each lateral error it takes.

    The node's count (:func:`recorded_copies`), or the last copy the bag holds where it
    holds fewer (a recorder that started late or lost one: dev-probe118, the stamp was
    never answered and replay did not say so).

    :param run: the bag.
    :param inputs: its input stream (:func:`input_stream`).
    :param runs: its runs (:func:`run_starts`).
    :param feed: the inputs in the order the re-run feeds them.
    :return: ``id(item)`` of each lateral error whose stamp advances (taken) -> the copy
        to answer it at (0: at itself); None for a node that answered no repeat.
    """
    run_of: dict[int, int] = {}
    bounds = runs.starts + [len(inputs)]
    for number, (begin, end) in enumerate(zip(bounds, bounds[1:])):
        run_of.update((id(item), number) for item in inputs[begin:end])
    wanted = recorded_copies(run, [inputs[i][0] for i in runs.starts] or [0])
    if wanted is None:
        return None
    out: dict[int, int] = {}
    taken: Optional[tuple[int, str, Any]] = None
    held = 0
    for item in feed:
        _, role, sample = item
        if role != 'lateral_error' or id(item) in runs.strays:
            continue
        last = taken[2] if taken is not None else None
        if last is not None and sample == last:
            held += 1
            continue
        if last is not None and (sample.stamp_ns <= last.stamp_ns
                                 and sample.stamp_ns >= last.stamp_ns - JUMP_NS):
            continue        # refused: going back or the same stamp with other values
        if taken is not None:
            out[id(taken)] = min(out[id(taken)], held)
        taken, held = item, 0
        out[id(item)] = wanted[run_of.get(id(item), 0)].get(sample.stamp_ns, 0)
    if taken is not None:
        out[id(taken)] = min(out[id(taken)], held)
    return out


def _answered_here(refused: Optional[str], copy: int, answered: bool,
                   target: Optional[int]) -> bool:
    """
    Return whether the re-run answers this arrival of a lateral error, as the node did.

    :param refused: why the re-run's core refused it (None: taken).
    :param copy: 0 for the lateral error taken, n for its n-th exact repeat since.
    :param answered: whether the re-run answered the lateral error taken already.
    :param target: the copy to answer it at (:func:`answer_copies`); None: a node that
        answered no repeat.
    :return: whether to compute the command here.
    """
    if answered or (refused is not None and not is_duplicate(refused)):
        return False
    if target is None:
        return refused is None              # an older node: no repeat answered
    # at the copy the node answered (or the first after it, where the re-run could not
    # answer there)
    return copy >= target


def _strays_to_end(inputs: Sequence[tuple[int, str, Any]], strays: frozenset[int]
                   ) -> tuple[str, ...]:
    """Return the inputs whose last message in the stream is a stray."""
    last = {role: i for i, (_, role, _) in enumerate(inputs)}
    return tuple(sorted(role for role, i in last.items() if i in strays))


def checks_told(core: SteeringController) -> dict[str, float]:
    """
    Return what a controller's checks found over its run, as its ``/diagnostics`` names it.

    :param core: the controller after the run.
    :return: seconds per check (``turning``), then ``time_jumps`` and ``law_restarts``
        counts; only those not 0, in that order.
    """
    told = {name: seconds for name, seconds in core.turning.items() if seconds > 0.0}
    told.update((name, float(count)) for name, count in (('time_jumps', core.time_jumps),
                                                         ('law_restarts', core.law_restarts))
                if count)
    return told


def _unanswered(run: RunData, lateral: Samples, answered: list[int]
                ) -> Iterator[tuple[int, int]]:
    """
    Yield the lateral errors of the bag with neither a steering nor a debug answer.

    :param run: the bag.
    :param lateral: its lateral errors.
    :param answered: the stamps of the debug answers, sorted.
    :return: ``(stamp, index of the next answer in answered)``; none after the last.
    """
    given = set(run.steering.stamp_ns.tolist()) | set(answered)
    for stamp in lateral.stamp_ns.tolist():
        if stamp in given:
            continue
        at = bisect.bisect_left(answered, stamp)
        if at < len(answered):      # after the last answer: nothing to compare
            yield int(stamp), at


def inactive_inputs(run: RunData, counter: str = 'activations'
                    ) -> tuple[frozenset[int], int]:
    """
    Return the lateral-error stamps the recorded controller received while deactivated.

    A deactivated node takes its inputs in and answers none, so its law is not stepped
    until it is activated again (then a time jump restarts it, or a long step follows).
    Its debug topic counts its activations (``activations``): an unanswered lateral
    error between two answers of different counts came while it was inactive (before,
    the re-run stepped the law on them: 7.5 mrad apart after a deactivate / activate),
    and so did one before the first answer if that answer's count is above 1 (the node
    was deactivated before it answered; dev-probe52: 4 mrad). An answer whose steering
    the recorder lost but whose debug it has was given. The debug's ``answers`` (the
    law's answers so far) tells how many answers of such a stretch the recorder lost:
    those inputs were answered, but which of them the bag does not say (counted; not
    before the bag's first answer, whose count also holds the answers before the bag).

    With ``counter='coalesced'`` the same for the lateral errors the node took in and
    left for a newer one under its answer-rate bound (event mode on the wall clock:
    ``max_answer_rate_hz``): unanswered between two answers whose ``coalesced`` counts
    differ.

    :param run: the bag.
    :param counter: the debug topic's count of the stretches: ``activations`` or
        ``coalesced``.
    :return: the stamps (empty: none, or the bag does not say; an older bag), and the
        answers the recorder lost in those stretches.
    """
    counts = run.debug.values.get(counter)
    lateral = run.inputs.get('lateral_error')
    if counts is None or lateral is None:
        return frozenset(), 0
    numbers = run.debug.values.get('answers')
    numbers_list = (numbers.tolist() if numbers is not None
                    else [math.nan] * len(counts))
    columns = zip(run.debug.stamp_ns.tolist(), counts.tolist(), numbers_list)
    marked = {int(t): (c, n) for t, c, n in columns if math.isfinite(c)}
    if not marked:
        return frozenset(), 0
    answered = sorted(marked)
    out, gaps = set(), set()
    for stamp, at in _unanswered(run, lateral, answered):
        after = marked[answered[at]][0]
        before = marked[answered[at - 1]][0] if at else (1.0 if counter == 'activations'
                                                         else 0.0)
        if before != after:
            out.add(int(stamp))
            gaps.add(at)
    lost = 0
    for at in gaps:
        if not at:
            # before the bag's first answer its count tells answers given before the
            # bag began (a recorder started while the node was deactivated: dev-probe94,
            # "lost 284 answers"), not lost by it; replay's late_join tells those
            continue
        number = marked[answered[at]][1]
        earlier = marked[answered[at - 1]][1]
        if math.isfinite(number) and math.isfinite(earlier):
            lost += max(0, int(number - earlier) - 1)
    return frozenset(out), lost


def unanswered_inputs(run: RunData) -> frozenset[int]:
    """
    Return the lateral-error stamps the recorded controller did not answer, by its count.

    In event mode the node answers each lateral error it takes in (or leaves it for a
    newer one: coalesced; or takes it in while inactive). Between two answers whose
    ``~/debug`` ``answers`` counts follow one another (n, n + 1) it gave no answer, so a
    lateral error of the bag there went unanswered: one the node never received (its
    reader, keep-last 10, fell behind in a flood: dev-probe74, 490-658 of 1500, and the
    re-run stepped the law on them, 15 mrad apart), one it refused, or one coalesced or
    received while inactive. Before the first answer counted 1, every one. Where counts
    skip a number the recorder lost answers: those are left to :func:`inactive_inputs`.

    :param run: the bag.
    :return: the stamps (empty where the bag has no debug ``answers``).
    """
    numbers = run.debug.values.get('answers')
    lateral = run.inputs.get('lateral_error')
    if numbers is None or lateral is None:
        return frozenset()
    marked = {int(t): n for t, n in zip(run.debug.stamp_ns.tolist(), numbers.tolist())
              if math.isfinite(n)}
    if not marked:
        return frozenset()
    answered = sorted(marked)
    out = set()
    for stamp, at in _unanswered(run, lateral, answered):
        earlier = marked[answered[at - 1]] if at else 0.0
        if marked[answered[at]] - earlier == 1.0:
            out.add(int(stamp))
    return frozenset(out)


def recorded_parameter_sets(run: RunData) -> dict[int, int]:
    """
    Return, per answered stamp, the parameter sets the recorded controller had applied.

    From its debug topic's ``parameter_sets`` (a count of the sets at run time, one per
    ``/parameter_events`` message of the node).

    :param run: the bag.
    :return: stamp -> count (empty: the bag does not say; an older bag).
    """
    counts = run.debug.values.get('parameter_sets')
    if counts is None:
        return {}
    return {int(t): int(c) for t, c in zip(run.debug.stamp_ns.tolist(), counts.tolist())
            if math.isfinite(c)}


def sets_before_bag(run: RunData) -> int:
    """
    Return how many parameter sets the recorded controller applied before the bag's.

    The node's debug counts its sets from its start; the bag's ``/parameter_events``
    hold those received once the recorder subscribed. The count on the first recorded
    answer less the sets received before that answer were never recorded (before, the
    re-run numbered the recorded sets from 1 and applied them too early).

    :param run: the bag.
    :return: the number (0: the bag has every set, or does not mark them).
    """
    counts = run.debug.values.get('parameter_sets')
    if counts is None:
        return 0
    marked = np.nonzero(np.isfinite(counts))[0]
    if not marked.size:
        return 0
    first = marked[np.argmin(run.debug.recv_ns[marked])]
    received = run.parameter_events_recv_ns
    got = 0 if received is None else sum(1 for t in received
                                         if t < int(run.debug.recv_ns[first]))
    return max(0, int(counts[first]) - got)


def recorded_laws(run: RunData) -> dict[int, str]:
    """
    Return, per answered stamp, the law the recorded controller ran (its debug topic).

    :param run: the bag.
    :return: stamp -> law name (empty: the bag does not say; a name no law has is left
        out).
    """
    out: dict[int, str] = {}
    stamps = run.debug.stamp_ns.tolist()
    for key, flags in run.debug.values.items():
        if key.startswith('law:') and key[4:] in LAW_NAMES:
            out.update((int(t), key[4:]) for t, f in zip(stamps, flags.tolist())
                       if math.isfinite(f))
    return out


def recorded_judgment(run: RunData) -> dict[int, bool]:
    """
    Return, per answered stamp, whether the recorded controller took the curvature as in.

    From its debug topic's ``curvature_received`` (any law; 1: in), or in an older bag
    the default law's ``curvature_estimated`` (1: it ran on its estimate, not in). The
    node judges a loss on its clock, which no stamp holds (in lockstep it receives a
    step's curvature on the previous step's clock: lost a step before the stamps say),
    and only it knows whether it received a curvature the bag holds (a remapping, a QoS
    mismatch).

    :param run: the bag.
    :return: stamp -> received (empty: the bag does not say).
    """
    flags = run.debug.values.get('curvature_received')
    received = True
    if flags is None:
        flags, received = run.debug.values.get('curvature_estimated'), False
    if flags is None:
        return {}
    return {int(t): bool(f) == received
            for t, f in zip(run.debug.stamp_ns.tolist(), flags.tolist()) if math.isfinite(f)}


def rerun_law(run: RunData, overrides: Optional[Mapping[str, Any]] = None,
              order: Optional[str] = None) -> tuple[IntArray, LawOutput]:
    """
    Evaluate the law on the recorded inputs as :func:`rerun` does, for all steps at once.

    The law's output (``d_v``, ``y_ref``, the error ...) depends only on the latest
    inputs when a lateral error arrives, not on the controller's output limits; this
    gives for each such arrival what ``rerun(run).commands[stamp].law`` holds, as arrays
    (numpy's functions may differ from ``math``'s in the last bit).

    :param run: the recorded run.
    :param overrides: parameter overrides.
    :param order: as for :func:`rerun`.
    :return: the lateral-error stamp of each evaluation (in feed order: the last of a
        stamp is the one ``rerun`` keeps) and the law's outputs.
    """
    core, matched = controller_from_params(run.controller_params, overrides,
                                           run.controller_node)
    order = _resolve_order(order, matched, bool(run.plant_params))
    if core.law_name != 'paper':
        # a law with a state (integral, estimate) or its own structure: step by step
        return _stepped_law(rerun(run, overrides, order))
    roles = [role for role in INPUTS if len(run.inputs.get(role, Samples.empty()))]
    if not {'lateral_error', 'yaw', 'velocity'} <= set(roles):
        none = np.zeros(0)
        return np.zeros(0, dtype=np.int64), steering_law(
            LateralState(none, none, none, none, none, none, none, none), core.vehicle,
            core.params)
    inputs = [run.inputs[role] for role in roles]
    code = np.concatenate([np.full(len(samples), i) for i, samples in enumerate(inputs)])
    index = np.concatenate([np.arange(len(samples)) for samples in inputs])
    recv, file_order, stamp = (np.concatenate([getattr(samples, name) for samples in inputs])
                               for name in ('recv_ns', 'order', 'stamp_ns'))
    lateral_code = roles.index('lateral_error')
    lateral = run.inputs['lateral_error']
    feed = np.lexsort((file_order, recv) if order == 'receive' else
                      (file_order, recv, code == lateral_code, stamp))
    code, index, fed_stamp = code[feed], index[feed], stamp[feed]
    # as the controller's accept(): a sample whose stamp does not advance past its input's
    # newest one (repeated, or arriving late) is refused and never used
    no_lateral: IntArray = np.zeros(0, dtype=np.int64)
    at, group, copy = no_lateral, no_lateral, no_lateral
    for i in range(len(roles)):
        where = np.nonzero(code == i)[0]
        newest = np.maximum.accumulate(fed_stamp[where])
        refused = np.concatenate(([False], fed_stamp[where][1:] <= newest[:-1]))
        if i == lateral_code:
            arrival, taken = _copies(lateral, index[where], refused)
            # the lateral errors taken and their exact repeats: where, which one, copy
            at, group, copy = (where[arrival >= 0], where[taken[arrival >= 0]],
                               arrival[arrival >= 0])
        code[where[refused]] = -1
    # at each position of the feed: the position of each input's latest sample (-1)
    latest = {role: np.maximum.accumulate(np.where(code == i, np.arange(code.size), -1))
              for i, role in enumerate(roles)}
    # each lateral error taken is answered once: at the first of its arrivals (it, then
    # its exact repeats) with the yaw and velocity in, from the copy the node answered
    # (~/debug copies; rerun())
    # (the runs of a bag are not told apart here: the last run's count of a stamp counts)
    wanted = recorded_copies(run)
    if wanted is None:
        usable = copy == 0
    else:
        least = np.array([wanted[0].get(int(t), 0)
                          for t in lateral.stamp_ns[index[at]].tolist()], dtype=np.int64)
        # no further than the last copy the bag holds (a recorder late or losing one)
        held = np.zeros(code.size, dtype=np.int64)
        np.maximum.at(held, group, copy)
        usable = copy >= np.minimum(least, held[group])
    usable &= (latest['yaw'][at] >= 0) & (latest['velocity'][at] >= 0)
    _, first = np.unique(group[usable], return_index=True)
    at = at[usable][np.sort(first)]
    if core.aligns and any(bool(np.any(fed_stamp[latest[role][at]] > fed_stamp[at]))
                           for role in ('yaw', 'velocity')):
        # a yaw or velocity newer than the lateral error it answers: the node read them
        # between their samples at its stamp (align_inputs always): step by step
        return _stepped_law(rerun(run, overrides, order))
    if core.curvature_at_yaw_stamp and not core.aligns and 'road_curvature' in latest:
        where = latest['road_curvature'][at]
        yaw = fed_stamp[latest['yaw'][at]]
        if np.any((where >= 0) & (fed_stamp[np.maximum(where, 0)] < yaw)):
            # a polygon older than the yaw sample taken: the node read it where the car
            # was at that sample's stamp (curvature_at_yaw_stamp): step by step
            return _stepped_law(rerun(run, overrides, order))

    def column(role: str, name: str) -> Array:
        if role not in latest:
            return np.zeros(at.size)
        where = latest[role][at]
        values = run.inputs[role].values[name][index[np.maximum(where, 0)]]
        return np.where(where >= 0, values, 0.0)

    eps_r, v_x = column('yaw', 'relative_yaw'), column('velocity', 'v_x')
    v_y, rate = column('velocity', 'v_y'), column('yaw', 'yaw_rate')
    if core.acceleration_source == 'imu':
        a_x = column('yaw', 'accel_x') + v_y * rate
    elif core.acceleration_source == 'differentiate':
        fed = np.nonzero(code == roles.index('velocity'))[0]
        a_x = _differentiated(run.inputs['velocity'], index[fed],
                              core.safety.max_acceleration)[
            np.searchsorted(fed, latest['velocity'][at])]
    else:
        a_x = np.zeros(at.size)
    # a curvature stamped more than input_timeout before the lateral error is lost: 0
    # (as SteeringController.curvature_lost judges it without a clock)
    received = np.zeros(at.size, dtype=bool)
    if 'road_curvature' in latest:
        where = latest['road_curvature'][at]
        age = (lateral.stamp_ns[index[at]]
               - run.inputs['road_curvature'].stamp_ns[index[np.maximum(where, 0)]])
        received = (where >= 0) & ~(age > core.safety.input_timeout * 1e9)
    state = LateralState(
        y_cg=cg_error_from(column('lateral_error', 'value'), eps_r,
                           column('lateral_error', 'distance')),
        eps_r=eps_r, v_y=v_y, r=rate, v_x=v_x, a_x=a_x,
        rho=np.where(received, column('road_curvature', 'rho'), 0.0),
        rho_rate=(np.where(received, v_x * column('road_curvature', 'slope'), 0.0)
                  if core.use_preview else np.zeros(at.size)))
    return lateral.stamp_ns[index[at]], steering_law(state, core.vehicle, core.params)


def _copies(lateral: Samples, taken_order: IntArray, refused: BoolArray
            ) -> tuple[IntArray, IntArray]:
    """
    Return each lateral error's arrival number and the lateral error taken it repeats.

    :param lateral: the recorded lateral errors.
    :param taken_order: the index in ``lateral`` of each lateral error, in feed order.
    :param refused: whether each was refused (its stamp did not advance).
    :return: per lateral error in feed order, 0 for one taken, n for the n-th exact
        repeat (stamp and values) of the last one taken, -1 for any other refused; and
        the feed position (among the lateral errors) of the last one taken.
    """
    position = np.arange(refused.size)
    last = np.maximum.accumulate(np.where(refused, -1, position))
    taken = taken_order[np.maximum(last, 0)]
    same = refused & (last >= 0) & (lateral.stamp_ns[taken_order] == lateral.stamp_ns[taken])
    for name in ('value', 'distance'):
        column = lateral.values[name]
        same &= column[taken_order] == column[taken]
    count = np.cumsum(same)
    copy = np.where(same, count - count[np.maximum(last, 0)], np.where(refused, -1, 0))
    return copy.astype(np.int64), np.maximum(last, 0)


def _stepped_law(result: Rerun) -> tuple[IntArray, LawOutput]:
    """
    Return the law's outputs of a step-by-step re-run as :func:`rerun_law` does.

    :param result: the re-run.
    :return: the stamps of the commands the law answered (increasing) and its outputs.
    """
    answered = sorted((stamp, c.law) for stamp, c in result.commands.items()
                      if c.law is not None)
    stamps = np.array([stamp for stamp, _ in answered], dtype=np.int64)
    columns = [np.array([float(getattr(law, name)) for _, law in answered])
               for name in LawOutput._fields]
    return stamps, LawOutput(*columns)


def _differentiated(velocity: Samples, fed: IntArray, most: float) -> Array:
    """
    Return the controller's differentiated a_x after each velocity sample of a feed.

    :param velocity: the velocity samples.
    :param fed: their indexes in the order they are fed.
    :param most: the believable |a_x| (``safety.max_acceleration``) [m/s^2].
    :return: a_x after each, as ``SteeringController.update_velocity`` takes it
        (:func:`~lookahead_control.core.controller.differentiated_step`; 0 before the
        first).
    """
    from lookahead_control.core.controller import differentiated_step
    v, stamp = velocity.values['v_x'][fed], velocity.stamp_ns[fed]
    out = np.zeros(fed.size)
    estimate: float = 0.0
    anchor: Optional[tuple[int, float]] = None
    for k in range(fed.size):       # each step depends on the anchor before it
        estimate, anchor = differentiated_step(estimate, anchor, int(stamp[k]), float(v[k]),
                                               most)
        out[k] = estimate
    return out
