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
Bags: rosbag2 directories with MCAP storage, written with rosbags, read with rosbags.

No ROS here. A bag is a directory with ``metadata.yaml`` (version 9) and one ``.mcap``
file of ``cdr`` messages with ``ros2msg`` schemas and each topic's
``offered_qos_profiles`` in its channel metadata, as ``ros2 bag record -s mcap`` writes.

The run description (parameters of the nodes, the scenario, the recorder's counts)
goes into ``custom_data`` of ``metadata.yaml`` under ``lookahead_control/*`` keys, and
into ``run_description.yaml`` beside the ``.mcap`` as soon as it is known, so a bag
cut short by ``kill -9`` still describes its run after :func:`recover`.

Chunks: rosbags (pinned) closes an MCAP chunk every MiB and keeps it in memory until
then; :class:`BagWriter` closes one every ``chunk_interval`` seconds or ``chunk_bytes``
bytes, whichever comes first, and flushes it to the file, so a killed recorder loses at
most that much.
"""

from __future__ import annotations

from dataclasses import dataclass
import os
from pathlib import Path
import re
import shutil
import struct
import tempfile
import time
from typing import Any, Callable, Iterator, Mapping, NamedTuple, Optional, Sequence

from lookahead_control.core.cli import EXIT_OUTPUT_EXISTS
from lookahead_control.core.config import ConfigError
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.interfaces import (Connection, Qos, QosDurability, QosHistory, QosLiveliness,
                                QosReliability, QosTime)
from rosbags.rosbag2 import StoragePlugin, Writer, WriterError
from rosbags.rosbag2.metadata import parse_qos
from rosbags.typesys import get_types_from_msg, get_typestore, Stores
from rosbags.typesys.store import Typestore
import yaml

DESCRIPTION_FILE = 'run_description.yaml'
KEY_PREFIX = 'lookahead_control/'
# a fully qualified node name (what --node and record --describe take)
FULL_NODE_NAME = re.compile(r'(/[A-Za-z_][A-Za-z0-9_]*)+')
NODE_NAME_RULE = ('not a fully qualified node name (e.g. /controller or /car_b/controller: '
                  '/-separated names of letters, digits and _, not starting with a digit)')
PARAMETERS_KEY = KEY_PREFIX + 'parameters'
SCENARIO_KEY = KEY_PREFIX + 'scenario'
RECORDER_KEY = KEY_PREFIX + 'recorder'


class BagError(ConfigError):
    """A bag that cannot be written or read; the message names the bag."""


class BagExistsError(BagError):
    """An output bag directory that exists: a bag is never written over."""

    exit_code = EXIT_OUTPUT_EXISTS


def typestore() -> Typestore:
    """Return the Jazzy type store: the common_interfaces types, among others."""
    return get_typestore(Stores.ROS2_JAZZY)


def to_rosbags(msg: Any, store: Typestore) -> Any:
    """
    Convert a ROS (rclpy) message to the rosbags class of the same type, recursively.

    :param msg: the message.
    :param store: the type store.
    :return: the rosbags message.
    """
    import array
    import numpy as np
    name = f'{type(msg).__module__.split(".")[0]}/msg/{type(msg).__name__}'
    fields = {}
    for field, kind in msg.get_fields_and_field_types().items():
        value = getattr(msg, field)
        if hasattr(value, 'get_fields_and_field_types'):
            value = to_rosbags(value, store)
        elif isinstance(value, (array.array, np.ndarray)):
            value = np.array(value, dtype=np.float64)
        elif isinstance(value, list) and value and hasattr(
                value[0], 'get_fields_and_field_types'):
            value = [to_rosbags(v, store) for v in value]
        elif kind == 'octet':
            # a byte (DiagnosticStatus.level; rclpy: bytes, or the int it was given):
            # rosbags holds it as an int8
            byte = value[0] if isinstance(value, bytes) else int(value) & 0xFF
            value = byte - 256 if byte > 127 else byte
        fields[field] = value
    return store.types[name](**fields)


def serialize_cdr(msg: Any, store: Optional[Typestore] = None) -> bytes:
    """
    Serialize a ROS message the way rosbag2 stores it (rclpy's own adds 4 bytes).

    :param msg: the message.
    :param store: the type store (default: Jazzy's).
    :return: the CDR bytes.
    """
    store = store or typestore()
    converted = to_rosbags(msg, store)
    return bytes(store.serialize_cdr(converted, converted.__msgtype__))


def qos_from_ints(profile: Mapping[str, int]) -> Qos:
    """
    Return a rosbags QoS from rmw enum values (rclpy's policies use the same numbers).

    :param profile: ``history``, ``depth``, ``reliability``, ``durability``,
        ``liveliness`` and ``deadline_ns``, ``lifespan_ns``, ``lease_ns``.
    :return: the profile as rosbags writes it into ``offered_qos_profiles``.
    """
    def span(ns: int) -> QosTime:
        return QosTime(int(ns) // 1_000_000_000, int(ns) % 1_000_000_000)
    return Qos(QosHistory(profile.get('history', 1)), int(profile.get('depth', 0)),
               QosReliability(profile.get('reliability', 1)),
               QosDurability(profile.get('durability', 2)),
               span(profile.get('deadline_ns', 0)), span(profile.get('lifespan_ns', 0)),
               QosLiveliness(profile.get('liveliness', 1)),
               span(profile.get('lease_ns', 0)), False)


def _atomic_write(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + '.tmp')
    tmp.write_text(text)
    os.replace(tmp, path)


class BagWriter:
    """A rosbag2 MCAP bag being written, flushed chunk by chunk."""

    def __init__(self, path: Path, chunk_interval: float = 0.5,
                 chunk_bytes: int = 64 * 1024) -> None:
        """
        Create the bag directory and open its MCAP file.

        :param path: the bag directory; must not exist, its parent must be writable.
        :param chunk_interval: longest time a message waits in memory [s].
        :param chunk_bytes: largest chunk kept in memory [bytes].
        :raises BagExistsError: the directory exists (or a file, or a link by that name).
        :raises BagError: it cannot be created.
        """
        self.path = Path(path)
        self.chunk_interval = chunk_interval
        self.chunk_bytes = chunk_bytes
        self.store = typestore()
        taken = f'{self.path}: exists: a bag is never written over (choose another output)'
        if os.path.lexists(self.path):
            raise BagExistsError(taken)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
            self.writer.open()
        except (WriterError, OSError) as err:
            if isinstance(err, WriterError) and 'exists already' in str(err):
                # made by another process since the check (the writer's own mkdir)
                raise BagExistsError(taken) from err
            raise BagError(f'{self.path}: cannot create bag: {err}') from err
        self.connections: dict[str, Connection] = {}
        self.custom: dict[str, str] = {}
        self._flushed_at = time.monotonic()
        self.closed = False
        self.error: Optional[BagError] = None

    def _abort(self, err: OSError) -> BagError:
        """
        Stop writing after an I/O error (disk full, file too large, device gone).

        What reached the file stays there: complete chunks are read back by ``recover``.

        :param err: the error.
        :return: the error to raise, naming the file and the problem.
        """
        if self.error is None:
            self.error = BagError(
                f'{self.path / (self.path.name + ".mcap")}: write failed: '
                f'{err.strerror or err}; the chunks written before it are kept: run '
                f'`recover {self.path}`')
            self.closed = True
            try:
                self.writer.abort()
            except OSError:
                pass        # the unwritten rest of the buffer is lost with the disk
        return self.error

    def add_topic(self, topic: str, msgtype: str, offered: Sequence[Qos] = ()) -> None:
        """
        Add a topic (a connection); messages of unknown types are refused here.

        :param topic: the topic name.
        :param msgtype: ``pkg/msg/Type``.
        :param offered: QoS profiles of its publishers.
        :raises BagError: the type is not in the Jazzy type store.
        """
        if self.error is not None:
            raise self.error
        if topic in self.connections:
            return
        if msgtype not in self.store.fielddefs:
            raise BagError(f'{self.path}: {topic}: type {msgtype} is not a Jazzy '
                           'common_interfaces type; it cannot be recorded')
        try:
            self.connections[topic] = self.writer.add_connection(
                topic, msgtype, typestore=self.store, offered_qos_profiles=list(offered))
        except OSError as err:
            raise self._abort(err) from err

    def write(self, topic: str, stamp_ns: int, data: bytes) -> None:
        """
        Write one serialized (CDR) message.

        :param topic: a topic added with :meth:`add_topic`.
        :param stamp_ns: its receive time [ns].
        :param data: the serialized message.
        :raises BagError: the file cannot be written (the bag is aborted).
        """
        if self.error is not None:
            raise self.error
        try:
            self.writer.write(self.connections[topic], stamp_ns, data)
            storage: Any = self.writer.storage
            if (storage.chunk.bio.tell() > self.chunk_bytes
                    or time.monotonic() - self._flushed_at > self.chunk_interval):
                self.flush()
        except OSError as err:
            raise self._abort(err) from err

    def flush(self) -> None:
        """Close the pending chunk (if it holds messages) and hand it to the OS."""
        storage: Any = self.writer.storage
        self._flushed_at = time.monotonic()
        if storage is None:
            return
        if storage.chunk.msgs:
            storage.close_chunk()
        storage.bio.flush()

    def describe(self, key: str, value: str) -> None:
        """
        Store a run description entry (``custom_data`` and the side file).

        :param key: the ``custom_data`` key.
        :param value: its text.
        :raises BagError: the side file cannot be written (the bag is aborted).
        """
        if self.error is not None:
            raise self.error
        self.custom[key] = value
        self.writer.set_custom_data(key, value)
        try:
            _atomic_write(self.path / DESCRIPTION_FILE, yaml.safe_dump(self.custom))
        except OSError as err:
            raise self._abort(err) from err

    def counts(self) -> dict[str, int]:
        """Return the messages written per topic."""
        return {topic: self.writer.counts[conn.id] for topic, conn in self.connections.items()}

    def close(self) -> None:
        """
        Write the summary and ``metadata.yaml``.

        :raises BagError: they cannot be written (the chunks stay for ``recover``).
        """
        if not self.closed:
            self.closed = True
            try:
                self.writer.close()
            except OSError as err:
                raise self._abort(err) from err


# -- reading ---------------------------------------------------------------------------


@dataclass(frozen=True)
class BagMessage:
    """One message of a bag: topic, type, receive time, decoded message."""

    topic: str
    msgtype: str
    recv_ns: int
    msg: Any


def bag_reader(path: Path) -> AnyReader:
    """
    Open a bag for reading (the caller closes it).

    :param path: the bag directory (or a lone ``.mcap`` file).
    :return: the open reader, with the Jazzy type store as default.
    :raises BagError: missing, unreadable or corrupt.
    """
    path = Path(path)
    if not path.exists():
        raise BagError(f'{path}: no such bag')
    try:
        reader = AnyReader([path], default_typestore=typestore())
        reader.open()
    except (AnyReaderError, OSError, ValueError, KeyError) as err:
        raise BagError(f'{path}: not a readable rosbag2 bag: {err} (truncated? try '
                       f'`recover {path}`)') from err
    return reader


class RawMessage(NamedTuple):
    """
    One message of a bag, still serialized.

    :param topic: its topic.
    :param msgtype: its type.
    :param recv_ns: its receive time [ns].
    :param data: its CDR bytes.
    :param deserialize: the bag's deserializer, ``deserialize(data, msgtype)``.
    """

    topic: str
    msgtype: str
    recv_ns: int
    data: bytes
    deserialize: Callable[[bytes, str], Any]

    def decode(self) -> Any:
        """Return the decoded message."""
        return self.deserialize(self.data, self.msgtype)


def read_raw(path: Path, topics: Optional[Sequence[str]] = None) -> Iterator[RawMessage]:
    """
    Yield a bag's messages in receive-time order, serialized.

    :param path: the bag.
    :param topics: only these topics (default: all).
    :return: the messages.
    :raises BagError: the bag cannot be read.
    """
    reader = bag_reader(path)
    try:
        conns = [c for c in reader.connections if topics is None or c.topic in topics]
        deserialize = reader.deserialize
        try:
            for conn, stamp, data in reader.messages(connections=conns):
                yield RawMessage(conn.topic, conn.msgtype, stamp, data, deserialize)
        except (AnyReaderError, OSError, ValueError, AssertionError) as err:
            raise BagError(f'{path}: corrupt message data: {err}') from err
    finally:
        reader.close()


def read_messages(path: Path, topics: Optional[Sequence[str]] = None) -> Iterator[BagMessage]:
    """
    Yield a bag's messages in receive-time order, decoded.

    :param path: the bag.
    :param topics: only these topics (default: all).
    :return: the messages.
    :raises BagError: the bag cannot be read.
    """
    for raw in read_raw(path, topics):
        try:
            msg = raw.decode()
        except (AnyReaderError, ValueError, AssertionError, struct.error) as err:
            raise BagError(f'{path}: corrupt message data: {err}') from err
        yield BagMessage(raw.topic, raw.msgtype, raw.recv_ns, msg)


def bag_topics(path: Path) -> dict[str, tuple[str, int]]:
    """
    Return the topics of a bag with type and message count.

    :param path: the bag.
    :return: ``{topic: (msgtype, count)}``.
    """
    reader = bag_reader(path)
    try:
        return {c.topic: (c.msgtype, c.msgcount) for c in reader.connections}
    finally:
        reader.close()


def run_description(path: Path) -> dict[str, str]:
    """
    Return the run description of a bag (``custom_data``, else the side file).

    :param path: the bag directory.
    :return: the ``lookahead_control/*`` entries (empty for foreign bags).
    """
    path = Path(path)
    data: dict[str, Any] = {}
    meta = path / 'metadata.yaml'
    try:
        if meta.is_file():
            info = yaml.safe_load(meta.read_text()) or {}
            data = (info.get('rosbag2_bagfile_information', {}) or {}).get('custom_data') or {}
        if not data and (path / DESCRIPTION_FILE).is_file():
            data = yaml.safe_load((path / DESCRIPTION_FILE).read_text()) or {}
    except (OSError, yaml.YAMLError) as err:
        raise BagError(f'{path}: unreadable run description: {err}') from err
    return {str(k): str(v) for k, v in data.items() if str(k).startswith(KEY_PREFIX)}


def recorded_parameters(path: Path) -> dict[str, dict[str, Any]]:
    """
    Return the recorded parameters of every node the run's bag describes (one read).

    :param path: the bag.
    :return: node's fully qualified name -> flat ``{name: value}``.
    """
    text = run_description(path).get(PARAMETERS_KEY, '')
    params = (yaml.safe_load(text) or {}) if text else {}
    if not isinstance(params, dict):
        return {}
    return {str(node): dict((entry or {}).get('ros__parameters') or {})
            for node, entry in params.items()}


def described_nodes(path: Path) -> list[str]:
    """
    Return the nodes whose parameters the run's bag recorded.

    :param path: the bag.
    :return: their fully qualified names, sorted.
    """
    return sorted(recorded_parameters(path))


def node_parameters(path: Path, node: str) -> dict[str, Any]:
    """
    Return the recorded parameters of one node of the run.

    :param path: the bag.
    :param node: the node's fully qualified name (``/controller``).
    :return: flat ``{name: value}`` (empty if not recorded).
    """
    return recorded_parameters(path).get(node, {})


# -- recovery ------------------------------------------------------------------------


@dataclass(frozen=True)
class Recovery:
    """What :func:`recover` saved."""

    bag: Path
    messages: int
    topics: int
    original: Optional[Path]
    complete: bool = False


def _backup_name(source: Path) -> Path:
    """
    Return a name for the original file that no existing file has.

    :param source: the ``.mcap`` file being replaced.
    :return: ``<name>.truncated``, or ``<name>.truncated.<n>`` when that exists (a
        second recovery never overwrites the first one's backup).
    """
    candidate = source.with_name(source.name + '.truncated')
    number = 1
    while candidate.exists():
        number += 1
        candidate = source.with_name(f'{source.name}.truncated.{number}')
    return candidate


def _mcap_file(path: Path) -> Path:
    files = sorted(path.glob('*.mcap'))
    if not files:
        raise BagError(f'{path}: no .mcap file to recover')
    return files[0]


def recover(path: Path) -> Recovery:
    """
    Rewrite a truncated bag (recorder killed) into a complete, readable one in place.

    Reads the MCAP records in order up to the first incomplete one (a partial last
    chunk is lost), rewrites them with rosbags and ``metadata.yaml``, and keeps the
    original file as ``<name>.mcap.truncated`` (``.truncated.2`` ... if that exists: a
    backup is never overwritten). A complete bag (the MCAP file ends with its footer and
    ``metadata.yaml`` is there) is left alone and reported with ``complete`` set.

    :param path: the bag directory.
    :return: what was saved.
    :raises BagError: nothing readable, or the directory cannot be written.
    """
    from mcap.exceptions import McapError
    from mcap.records import (Channel as McapChannel, Footer, Message as McapMessage,
                              Schema)
    from mcap.stream_reader import StreamReader

    path = Path(path)
    if not path.is_dir():
        raise BagError(f'{path}: a file, not a bag directory (a bag is the folder of '
                       'metadata.yaml and the .mcap)' if path.exists() else
                       f'{path}: no such bag directory')
    source = _mcap_file(path)
    schemas: dict[int, Schema] = {}
    channels: dict[int, McapChannel] = {}
    messages: list[McapMessage] = []
    footer = False
    try:
        with source.open('rb') as stream:
            for record in StreamReader(stream, skip_magic=False).records:
                if isinstance(record, Footer):
                    footer = True
                elif isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, McapChannel):
                    channels[record.id] = record
                elif isinstance(record, McapMessage):
                    messages.append(record)
    except (McapError, EOFError, ValueError, struct.error) as err:
        if not channels:
            raise BagError(f'{source}: nothing recoverable: cut inside its first chunk '
                           f'({type(err).__name__})') from err
    except OSError as err:
        raise BagError(f'{source}: cannot read: {err}') from err
    if footer and (path / 'metadata.yaml').is_file():
        return Recovery(path, len(messages), len(channels), None, complete=True)
    description = run_description(path)
    store = typestore()
    tmp = Path(tempfile.mkdtemp(prefix='recover-', dir=path.parent)) / path.name
    try:
        writer = Writer(tmp, version=9, storage_plugin=StoragePlugin.MCAP)
        writer.open()
        conns: dict[int, Connection] = {}
        for cid, channel in sorted(channels.items()):
            schema = schemas.get(channel.schema_id)
            if schema is None:
                continue
            if schema.name not in store.fielddefs:
                store.register(get_types_from_msg(schema.data.decode(), schema.name))
            qos = parse_qos(channel.metadata.get('offered_qos_profiles', '') or '[]')
            conns[cid] = writer.add_connection(channel.topic, schema.name, typestore=store,
                                               offered_qos_profiles=qos)
        saved = 0
        for message in sorted(messages, key=lambda m: m.log_time):
            if message.channel_id in conns:
                writer.write(conns[message.channel_id], message.log_time, message.data)
                saved += 1
        for key, value in description.items():
            writer.set_custom_data(key, value)
        writer.close()
        original = _backup_name(source)
        os.replace(source, original)
        for item in tmp.iterdir():
            os.replace(item, path / (item.name if item.suffix != '.mcap' else source.name))
    except (WriterError, OSError) as err:
        raise BagError(f'{path}: cannot write the recovered bag: {err}') from err
    finally:
        shutil.rmtree(tmp.parent, ignore_errors=True)
    _fix_file_name(path, source.name)
    return Recovery(path, saved, len(conns), original)


def _fix_file_name(path: Path, name: str) -> None:
    """Point ``metadata.yaml`` at the recovered file's name."""
    meta = path / 'metadata.yaml'
    info = yaml.safe_load(meta.read_text())
    bag = info['rosbag2_bagfile_information']
    bag['relative_file_paths'] = [name]
    for entry in bag.get('files', []):
        entry['path'] = name
    _atomic_write(meta, yaml.safe_dump(info, sort_keys=False))
