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
The Jazzy ``main()`` both nodes share: init, spin, one-line errors, clean shutdown.

Jazzy's rclpy has no ``with rclpy.init()``: init, try spin, finally destroy the node
and ``try_shutdown``.
"""

from __future__ import annotations

import contextlib
import faulthandler
import math
import os
from pathlib import Path
import re
import signal
import sys
import tempfile
import time
from types import FrameType
from typing import Any, Callable, Iterator, Optional, Sequence, TypeVar

from lookahead_control.core import interrupts
from lookahead_control.core.cli import one_line, ToolError
from lookahead_control.core.config import (applies_to, check_params_file, ConfigError,
                                           node_sections, rcl_param_value)
from lookahead_control.core.param_schema import check_params
from lookahead_control.core.params import ParameterError
from lookahead_control.core.rcl_yaml import merge_flat, RclYamlError
import rclpy
from rclpy.exceptions import (InvalidNamespaceException, InvalidNodeNameException,
                              InvalidParameterTypeException, InvalidParameterValueException)
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args
from rclpy.validate_namespace import validate_namespace
from rclpy.validate_node_name import validate_node_name
import yaml

N = TypeVar('N', bound=Node)
RCLError = _rclpy.RCLError
#: what rclpy raises for ROS arguments it refuses: rcl's errors, and a token after
#: --ros-args that is no ROS argument (not an RCLError: it was a traceback; dev-probe56)
ROS_ARGS_ERRORS = (RCLError, _rclpy.UnknownROSArgsError)
_RCL_LOCATION = re.compile(r', at /\S+:\d+')

# rclpy's logger sets the attribute its __del__ reads after its name in __init__: a
# Ctrl-C between the two made __del__ print 'Exception ignored ... Traceback ...
# AttributeError' after 'replay: interrupted' (session 24's suite, once in 8 x 10
# interrupts); a class default keeps __del__ quiet
if not hasattr(RcutilsLogger, 'logger_sublogger_namepair'):
    RcutilsLogger.logger_sublogger_namepair = None

#: [s] longest a node may take to stop once its spin loop has ended (executor, node,
#: context): past it the Python stacks of all threads are written to stderr and the
#: process exits with 1. Beyond the simulator's wait for acknowledgements (10 s) and
#: below the 60 s a supervisor's test waits: a child of a killed closed_loop once ran on
#: for more than 60 s after its SIGTERM, where nothing was left to kill it (CI, stop 54)
STOP_DEADLINE = 30.0
#: whether this process started ROS in :func:`run_node` (:func:`end_process`)
_ros_started = False


def end_process(code: int) -> int:
    """
    End a node's process with ``code`` once it has stopped, without Python's finalization.

    The node, its executor and the context are gone by then (:func:`run_node`); what the
    interpreter's finalization still collects are rclpy's C++ objects, and one of those
    (the events executor's) crashed the controller with SIGSEGV while "Garbage-collecting"
    after a clean stop on Ctrl-C (CI, stop 54; once before in a suite). stdout and stderr
    are flushed first. A process that never started ROS (``--help``, a refused
    parameter, an entry point run inside a test) returns ``code`` as before.

    :param code: the exit code.
    :return: ``code``, when ROS was not started here.
    """
    if not _ros_started:
        return code
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):     # a reader gone (`| head`), a closed stream
            pass
    os._exit(code)


def build_or_destroy(build: Callable[[], None], destroy: Callable[[], Any]) -> None:
    """
    Build the rest of a node after rclpy's part; destroy that part if building raises.

    A node that raised in its ``__init__`` (a refused parameter) after rclpy's part was
    built was left to the garbage collector, which destroyed its DDS participant long
    after its context was shut down: a test worker hung there in Fast DDS (dev-sc46's
    suite: ``destroy_participant`` waiting on a listener, a thread of it spinning).

    :param build: builds the rest (declares parameters, reads them, ...).
    :param destroy: the rclpy base class's ``destroy_node``, bound (``super().destroy_node``:
        the node's own may read what was not built).
    """
    try:
        build()
    except BaseException:
        destroy()
        raise


def rcl_reason(err: Exception) -> str:
    """
    Return rcl's message of an error without the C source locations it appends.

    A remap rule rcl cannot parse gets what rcl expected (its own words are lexeme
    numbers: ``-r __ns:=car_b`` is "Expected lexeme type 19, got 18 at index 6").

    :param err: the error (an ``RCLError``).
    :return: the message, stripped.
    """
    if isinstance(err, _rclpy.UnknownROSArgsError):
        return (f'unknown ROS argument(s) {str(err).strip("[]")} after --ros-args (ROS '
                "arguments: -r, -p, --params-file, --log-level, ...; the program's own "
                'go before --ros-args or after --)')
    reason = _RCL_LOCATION.sub('', str(err)).strip()
    if "Couldn't parse remap rule" in reason:
        reason += (' (a rule is FROM:=TO with ROS names: a namespace absolute, '
                   '__ns:=/car_b; a node name one token, __node:=truck)')
    return reason


def parameter_reason(err: Exception) -> str:
    """
    Return why rclpy refused a parameter override, without its repeated preamble.

    :param err: ``InvalidParameterTypeException`` or ``InvalidParameterValueException``.
    :return: the reason (``Trying to set parameter 'use_sim_time' to '7' ...``).
    """
    return str(err).split('Reason: ', 1)[-1].rsplit(': ', 1)[0]


@contextlib.contextmanager
def rcl_log_held() -> Iterator[None]:
    """
    Hold back what rcl writes to stderr in the block, and let it out unless rcl fails.

    rcl logs ``[ERROR] [rcl]: Failed to parse global arguments`` (and a warning or two)
    before it raises the error the caller reports in one line: those lines are
    dropped with the error, kept without one (at the file descriptor: rcl writes there).
    """
    sys.stderr.flush()
    saved = os.dup(2)
    held = tempfile.TemporaryFile()
    failed = False
    os.dup2(held.fileno(), 2)
    try:
        yield
    except ROS_ARGS_ERRORS:
        failed = True
        raise
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        if not failed:
            held.seek(0)
            text = held.read()
            if text:
                os.write(2, text)
        held.close()


def program_arguments(full: Sequence[str]) -> list[str]:
    """
    Return a tool's own arguments: the command line without its program name and ROS args.

    :param full: the command line, program name first.
    :return: the rest, without ``--ros-args`` blocks.
    :raises ToolError: rcl refuses the ROS arguments (one line; before, a traceback).
    """
    try:
        with rcl_log_held():
            return list(remove_ros_args(list(full))[1:])
    except ROS_ARGS_ERRORS as err:
        raise ToolError(f'--ros-args: {rcl_reason(err)}') from err


class Throttle:
    """
    Let a log line through at most once per period.

    rclpy's ``throttle_duration_sec`` inspects the caller's frame on every call (about
    40 us), which a flood of bad messages or missed deadlines would pay each time.
    """

    def __init__(self, period: float) -> None:
        """
        Start open.

        :param period: least time between two lines [s].
        """
        self.period = period
        self._last = -math.inf

    def ready(self) -> bool:
        """Return True (and restart the period) if a line may be logged now."""
        now = time.monotonic()
        if now - self._last < self.period:
            return False
        self._last = now
        return True


def make_executor(kind: str) -> Executor:
    """
    Create the executor named by a node's ``executor`` parameter.

    :param kind: ``events`` (``rclpy.experimental.EventsExecutor``) or
        ``single_threaded``.
    :return: the executor, in the default context.
    """
    if kind == 'events':
        from rclpy.experimental import EventsExecutor
        return EventsExecutor()
    return SingleThreadedExecutor()


def spin_until(executor: Executor, done: Callable[[], bool], period: float = 0.1) -> None:
    """
    Spin until ``done()`` or shutdown, returning to Python at least every ``period``.

    Jazzy's ``EventsExecutor.spin()`` busy-waits in C++ and never returns to the
    interpreter, so Python's SIGINT handler never runs; ``spin_once`` with a timeout
    does neither, for both executors.

    :param executor: the executor.
    :param done: polled between callbacks.
    :param period: longest time in one ``spin_once`` [s].
    """
    while rclpy.ok() and not done():
        executor.spin_once(timeout_sec=period)


def guard_clock(node: Node) -> int:
    """
    Drop ``/clock`` messages rclpy cannot take, instead of letting them stop the node.

    rclpy's time source (``use_sim_time``) builds a ``Time`` from every ``/clock``
    message, and a negative ``sec`` (a simulator's clock wrapped past int32, a bad
    bridge) raised ``ValueError`` out of the executor: the node died with a traceback,
    no command and no diagnostics (dev-probe90). Such a message is now dropped with an
    error in the log; the clock keeps its last good time, so the node's own checks see
    the inputs go stale and act as for a clock that stopped.

    :param node: the node, after it is created (its ``/clock`` subscription, if any).
    :return: how many ``/clock`` subscriptions were guarded (0 without sim time).
    """
    from rclpy.time_source import TimeSource
    guarded = 0
    for subscription in list(node.subscriptions):
        callback = subscription.callback
        if getattr(callback, '__func__', None) is not TimeSource.clock_callback:
            continue
        # this module's Throttle, not rclpy's throttle_duration_sec: a flood of bad
        # /clock messages would pay its frame inspection on each
        said = Throttle(5.0)

        def checked(msg: Any, take: Callable[[Any], None] = callback,
                    said: Throttle = said) -> None:
            if msg.clock.sec < 0:
                if said.ready():
                    node.get_logger().error(
                        f'/clock message with a negative time dropped (sec '
                        f'{msg.clock.sec}, nanosec {msg.clock.nanosec}): the clock keeps its '
                        'last time')
                return
            take(msg)
        subscription.callback = checked
        guarded += 1
    return guarded


def install_clock_guard(node: Node) -> None:
    """
    Guard the node's ``/clock`` subscription now and whenever ``use_sim_time`` is set.

    rclpy's time source subscribes to ``/clock`` when ``use_sim_time`` becomes true,
    also at run time (a set, a lifecycle node configured again): that subscription is
    guarded too (:func:`guard_clock`; guarding again leaves a guarded one as it is).

    :param node: the node.
    """
    guard_clock(node)

    def after_set(parameters: list[Any]) -> None:
        if any(parameter.name == 'use_sim_time' for parameter in parameters):
            guard_clock(node)
    node.add_post_set_parameters_callback(after_set)


def now_ns(node: Node) -> int:
    """
    Return a node's clock in nanoseconds, as ``node.get_clock().now().nanoseconds``.

    Without building an ``rclpy.time.Time`` (about 2 us, a sixth of a message callback
    of the controller; it reads the clock once per input message).

    :param node: the node (system, steady or ROS time, simulated or not).
    :return: the time [ns].
    """
    handle = node.get_clock().handle
    with handle:
        return int(handle.get_now().nanoseconds)


#: the characters of a remapped name that rcl's argument parser takes
_TOKENS = re.compile(r'\w*')

#: rcl's --ros-args flags that take a value (the value is not a flag)
_VALUED_FLAGS = frozenset(('-r', '--remap', '-p', '--param', '--params-file', '--log-level',
                           '--log-config-file', '-e', '--enclave', '--log-file-name'))


def ros_flags(args: Sequence[str]) -> list[tuple[int, str, str]]:
    """
    Return the flags rcl reads, with their values: those inside ``--ros-args`` blocks.

    A block ends at ``--`` or at the next ``--ros-args``; a ``--params-file`` outside
    one is the program's, not rcl's (before, it was checked and rcl never read it).

    :param args: command-line arguments.
    :return: (index of the value, flag, value), in order.
    """
    out: list[tuple[int, str, str]] = []
    ros, i = False, 0
    while i < len(args):
        flag = args[i]
        if flag == '--ros-args':
            ros = True
        elif flag == '--':
            ros = False
        elif ros and flag in _VALUED_FLAGS and i + 1 < len(args):
            out.append((i + 1, flag, args[i + 1]))
            i += 1
        i += 1
    return out


class _Quoted(str):
    """A string parameter value, written quoted."""


class _ParamsDumper(yaml.SafeDumper):
    """
    Write params files with every string value quoted.

    rcl's parser reads an unquoted ``y``, ``n``, ``1e5`` or ``inf`` as a bool or a
    number, which PyYAML (YAML 1.1) writes unquoted as strings: a ``frame_id: "y"``
    copied so reached the node as a bool and the node exited (dev-probe48).
    """


_ParamsDumper.add_representer(
    _Quoted, lambda dumper, value: dumper.represent_scalar('tag:yaml.org,2002:str',
                                                           str(value), style="'"))


def _quoted(value: Any) -> Any:
    if isinstance(value, str):
        return _Quoted(value)
    if isinstance(value, list):
        return [_quoted(item) for item in value]
    return value


def dump_params(sections: dict[str, dict[str, Any]], handle: Any) -> None:
    """
    Write params-file sections, their string values quoted (as rcl must read them).

    Each parameter under its dotted name (``vehicle.mass: 1500.0``), as rcl reads it
    back; nested maps failed for a name beside its prefix (``foo`` and ``foo.bar``, which
    rcl reads) and for names rcl takes but cannot nest (``foo..bar``; dev-probe53).

    :param sections: section name (``/**``, ``controller`` ...) -> flat parameters.
    :param handle: a text file open for writing.
    """
    # in the sections' order: rcl applies them in it (sorted, '/**' came before
    # 'controller' and won where the file had it after, dev-probe49)
    yaml.dump({key: {'ros__parameters': {name: _quoted(value) for name, value in flat.items()}}
               for key, flat in sections.items()}, handle, Dumper=_ParamsDumper,
              sort_keys=False)


def node_full_name(args: Sequence[str], node_name: str) -> str:
    """
    Return the node's fully qualified name after the command line's remappings.

    As rcl applies them: the first ``-r __node:=name`` (or ``__name``; ``controller:``
    rules only for the node's own name) renames it, then the first ``-r __ns:=/car_b``
    whose node part, if any, is the new name places it (``--remap`` alike). The params
    files' sections that apply are those matching this name (``/car_b/controller:``).

    :param args: command-line arguments (ROS arguments included).
    :param node_name: the node's name in the code.
    :return: ``/<namespace>/<name>`` (``/controller`` without remappings).
    :raises ConfigError: a name or namespace the node's creation would refuse.
    """
    rules = []
    for _, flag, rule in ros_flags(args):
        if flag in ('-r', '--remap') and ':=' in rule:
            lhs, _, value = rule.partition(':=')
            target, _, key = lhs.rpartition(':')
            rules.append((target.lstrip('/'), key, value))
    name = next((value for target, key, value in rules if key in ('__node', '__name')
                 and value and target in ('', node_name)), node_name)
    namespace = next((value for target, key, value in rules if key == '__ns' and value
                      and target in ('', name)), '/')
    namespace = namespace if namespace.startswith('/') else '/' + namespace
    try:
        # what rcl's argument parser takes and the node's creation refuses ('-r
        # __ns:=/car_b/', a name over 255 characters): a traceback after ROS started
        # (dev-probe61); a rule rcl's parser refuses ('__node:=a/b') is left to its
        # message, which says what a rule must be
        if _TOKENS.fullmatch(name):
            validate_node_name(name)
        if _TOKENS.fullmatch(namespace.replace('/', '')):
            validate_namespace(namespace)
    except (InvalidNodeNameException, InvalidNamespaceException) as err:
        what = '__ns' if isinstance(err, InvalidNamespaceException) else '__node'
        reason = one_line(str(err).split('\n', 1)[0].rstrip(':'))
        raise ConfigError(f'-r {what}:={namespace if what == "__ns" else name}: '
                          f'{reason}') from err
    return namespace.rstrip('/') + '/' + name


def checked_arguments(args: Sequence[str], node_name: str, specs: Sequence[Any],
                      scratch: list[Path],
                      check: Optional[Callable[[dict[str, Any]], Any]] = None) -> list[str]:
    """
    Check the parameters given on the command line against the node's schema.

    The same check as the offline tools make (``core.param_schema``): unknown names in
    the node's sections (``vehicle.masss``), wrong types and values out of range are one
    line naming the file (or ``-p``). An integer for a real (``mass: 1485``) is taken as
    that real: the file is passed to rcl as a converted copy, ``-p`` rewritten. Then
    ``check`` runs on every parameter the node will start with: a value its core refuses
    (a setting that is 0 or within a range, a combination) is one line naming the file
    or ``-p`` that set it, as a range error is.

    :param args: command-line arguments (ROS arguments included).
    :param node_name: the node's name (its sections in params files).
    :param specs: its parameters (empty: only the files' syntax is checked).
    :param scratch: converted copies written are appended here (the caller deletes them).
    :param check: builds the node's core from its parameters by name (defaults and what
        is given, checked) and raises ``ParameterError`` or ``ValueError`` for what the
        core refuses (None: no such check).
    :return: the arguments to give rcl.
    :raises ConfigError: a bad file or value.
    """
    out = list(args)
    shown: dict[str, str] = {}      # a read-once file's copy -> the name given
    for at, flag, value in ros_flags(args):
        path = Path(value)
        if flag == '--params-file' and path.exists() and not path.is_file():
            # a file read once (<(...), a pipe): read here, rcl would find it empty
            # (before: the node ran unchecked on its defaults; dev-probe53)
            try:
                data = path.read_bytes()
            except OSError as err:
                raise ConfigError(f'{value}: cannot read: {err.strerror or err}') from err
            copy = tempfile.NamedTemporaryFile(
                'wb', suffix='.yaml', prefix=f'{node_name}_params_', delete=False)
            scratch.append(Path(copy.name))
            with copy:
                copy.write(data)
            out[at] = copy.name
            shown[copy.name] = value
    try:
        return _checked_files(out, node_name, specs, scratch, check)
    except ConfigError as err:
        # a read-once file is named as given (/dev/fd/63), not as its deleted copy
        message = str(err)
        for made, name in shown.items():
            message = message.replace(made, name)
        raise ConfigError(message) from err


@contextlib.contextmanager
def tool_arguments(full: Sequence[str], name: str) -> Iterator[list[str]]:
    """
    Check the params files among a tool's ROS arguments before rcl parses them.

    What :func:`checked_arguments` does for a node without parameters (``record``,
    ``replay``): a malformed file or a directory is one line naming it, and a file read
    once is copied first (rcl's argument parser would read it, and the node then find it
    empty); the copies are deleted when the block ends.

    :param full: the command line, program name first.
    :param name: the tool's node name.
    :return: the command line to parse and give rcl.
    :raises ConfigError: a bad file or name.
    """
    scratch: list[Path] = []
    try:
        yield checked_arguments(full, name, (), scratch)
    finally:
        for path in scratch:
            path.unlink(missing_ok=True)


def _checked_files(args: list[str], node_name: str, specs: Sequence[Any],
                   scratch: list[Path],
                   check: Optional[Callable[[dict[str, Any]], Any]]) -> list[str]:
    out = list(args)
    # each file read once, before rcl does, for a one-line error naming it (any node)
    files = {i: node_sections(value) for i, flag, value in ros_flags(args)
             if flag == '--params-file'}
    # a node started in a namespace or renamed reads its own sections
    # ('/car_b/controller:'); before, they were neither checked nor converted
    full_name = node_full_name(args, node_name)
    if not specs:
        return out
    # what rcl reads otherwise when a later file or -p sets an earlier one's names
    # (two types, a map over a value): one params entry per section name, -p in '/**'
    given: dict[str, dict[str, Any]] = {}
    origin: dict[str, dict[str, str]] = {}     # section -> name -> the argument setting it
    for i, flag, value in ros_flags(args):
        if flag == '--params-file':
            raw = dict(files[i])
            for key, flat in raw.items():
                _merge_given(given, key, flat, f'{value}: ')
                origin.setdefault(key, {}).update(dict.fromkeys(flat, value))
            sections = check_params_file(value, full_name, specs, files[i])
            if any(type(v) is not type(raw[key][name])
                   for key, flat in sections.items() for name, v in flat.items()):
                handle = tempfile.NamedTemporaryFile(
                    'w', suffix='.yaml', prefix=f'{node_name}_params_', delete=False)
                scratch.append(Path(handle.name))   # deleted even if writing it fails
                with handle:
                    dump_params(sections, handle)
                out[i] = handle.name
        elif flag in ('-p', '--param') and ':=' in value:
            # ``-p node:name:=value`` is for the node whose full name is /node (rcl's
            # rule: not under a namespace); another node's is rcl's business
            lhs, _, text = value.partition(':=')
            target, _, name = lhs.rpartition(':')
            if target and '/' + target != full_name:
                continue
            try:
                typed = rcl_param_value(text)
                _merge_given(given, target or '/**', {name: typed}, '')
                origin.setdefault(target or '/**', {})[name] = f'{flag} {value}'
                parsed = check_params({name: typed}, specs)[name]
            except (ParameterError, ConfigError) as err:
                raise ConfigError(f'{flag} {value}: {one_line(str(err))}') from err
            if type(parsed) is not type(typed):
                # an integer for a real or a whole real for an integer, as in a file
                out[i] = f'{target + ":" if target else ""}{name}:={parsed!r}'
    if check is not None:
        _check_whole(given, origin, full_name, specs, check)
    return out


def _check_whole(given: dict[str, dict[str, Any]], origin: dict[str, dict[str, str]],
                 full_name: str, specs: Sequence[Any],
                 check: Callable[[dict[str, Any]], Any]) -> None:
    """
    Run the node's own check on the parameters it will start with, naming their source.

    The sections that apply to the node in rcl's order (:func:`_merge_given`: one entry
    per section name, ``-p`` in ``/**``), over the defaults. Before, a value the schema's
    range lets through and the core refuses (``curvature_smoothing: 0.5``, allowed 0 or
    1-50 m) stopped the node without the file's name (dev-probe60's "seen").

    :param given: section name -> its merged parameters.
    :param origin: section name -> parameter -> the argument that set it last.
    :param full_name: the node's full name.
    :param specs: its parameters.
    :param check: the node's check (:func:`checked_arguments`).
    :raises ConfigError: ``<file or -p>: <the core's message>``.
    """
    names = {spec.name for spec in specs}
    effective: dict[str, Any] = {}
    source: dict[str, str] = {}
    for key, flat in given.items():
        if applies_to(key, full_name):
            mine = {name: value for name, value in flat.items() if name in names}
            effective.update(mine)
            source.update({name: origin[key][name] for name in mine})
    params = {spec.name: spec.default for spec in specs}
    try:
        params.update(check_params(effective, specs))
        check(params)
    except (ParameterError, ValueError) as err:
        message = str(err)
        # the parameters the message names, of those given: the arguments that set them
        # (a name without a namespace only as 'name =': 'law' is also a word)
        named = sorted((found.start(), name) for name in source
                       for found in [re.search(rf'(?<![\w.]){re.escape(name)}'
                                               rf'{"" if "." in name else " ="}(?![\w])',
                                               message)] if found)
        where = list(dict.fromkeys(source[name] for _, name in named))
        raise ConfigError(f'{" and ".join(where) + ": " if where else ""}{message}') from err


def _merge_given(given: dict[str, dict[str, Any]], key: str, flat: dict[str, Any],
                 source: str) -> None:
    entry = given.setdefault(key, {})
    try:
        merge_flat(entry, flat)
    except RclYamlError as err:
        raise ConfigError(f'{source}read otherwise by rcl after the arguments before it: '
                          f'{err.problem}') from err
    entry.update(flat)


def wants_help(args: Sequence[str]) -> bool:
    """
    Return True if ``-h`` / ``--help`` is among the arguments before ``--ros-args``.

    :param args: command-line arguments, the program first.
    :return: whether to print the help.
    """
    # not rclpy's remove_ros_args: it parses the params files (a bad one is not --help's
    # business, and rcl's error is not one line)
    own = list(args)[1:]
    if '--ros-args' in own:
        own = own[:own.index('--ros-args')]
    return any(a in ('-h', '--help') for a in own)


def help_text(name: str, description: str, specs: Sequence[Any]) -> str:
    """
    Return a node executable's ``--help``: usage, purpose and every parameter.

    :param name: the executable's name.
    :param description: what the node does (one line).
    :param specs: its parameters (``node_params.Spec``: name, default, description,
        range, choices).
    :return: the text.
    """
    lines = [f'usage: {name} [-h] [--ros-args [--params-file FILE] [-p NAME:=VALUE] '
             '[-r FROM:=TO] ...]', '', description, '',
             'options:', '  -h, --help  show this help and exit (no node is started)', '',
             'ROS parameters (--params-file FILE, -p NAME:=VALUE):']
    for spec in specs:
        kind = type(spec.default).__name__.replace('float', 'double').replace(
            'str', 'string')
        allowed = (f'; one of {", ".join(spec.choices)}' if spec.choices else
                   f'; [{spec.low:g}, {spec.high:g}]' if spec.low is not None
                   and spec.high is not None else '')
        lines.append(f'  {spec.name} ({kind}, default {spec.default!r}{allowed})')
        lines.append(f'      {spec.description}')
    return '\n'.join(lines) + '\n'


class _StopRequest:
    """SIGINT / SIGTERM while a node runs: a flag the spin loop reads, not an exception."""

    def __init__(self) -> None:
        """Install the handlers (restored by :meth:`restore`)."""
        self.signals: list[int] = list(interrupts.received)    # one a library swallowed
        self._previous = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
        for s in self._previous:
            signal.signal(s, self._note)

    def _note(self, signum: int, frame: Optional[FrameType]) -> None:
        # no exception: one raised inside a callback is logged by the executor as
        # "[FATAL] Exception in 'timers' callback" with a stack
        self.signals.append(signum)

    def __bool__(self) -> bool:
        """Return True once a stop was asked for."""
        return bool(self.signals)

    def restore(self) -> None:
        """Put back the handlers found at start."""
        for s, handler in self._previous.items():
            signal.signal(s, handler)


def run_node(name: str, args: Optional[list[str]], make: Callable[[], N],
             done: Callable[[N], bool] = lambda node: False,
             specs: Sequence[Any] = (), description: str = '',
             check: Optional[Callable[[dict[str, Any]], Any]] = None) -> int:
    """
    Create a node, spin it until done or shut down, and clean up.

    ``-h`` / ``--help`` prints the parameters and returns 0 without starting ROS.
    SIGINT and SIGTERM stop the spin loop between callbacks (rclpy's own signal
    handling is off, so no callback is cut by an exception), then the node is destroyed
    (the recorder finalizes its bag there); a stop that takes longer than
    :data:`STOP_DEADLINE` ends the process with the stacks of its threads.

    :param name: the executable's name, for the one-line error.
    :param args: command-line arguments (ROS arguments included).
    :param make: creates (and, if needed, activates) the node after ``rclpy.init``.
    :param done: True when the node has finished (default: run until shut down).
    :param specs: the node's parameters, for ``--help``.
    :param description: what the node does, for ``--help``.
    :param check: the node's check of its whole parameter set before ROS starts
        (:func:`checked_arguments`).
    :return: 0, or 2 for bad parameters or config (3: a recorder's output that exists).
    """
    if wants_help([name, *(args or [])[1:]]):
        print(help_text(name, description or f'the {name} node', specs), end='')
        return 0
    stop = _StopRequest()
    scratch: list[Path] = []
    try:
        return _run(name, args, make, done, stop, specs, scratch, check)
    finally:
        faulthandler.cancel_dump_traceback_later()
        stop.restore()
        for path in scratch:
            path.unlink(missing_ok=True)


def _run(name: str, args: Optional[list[str]], make: Callable[[], N],
         done: Callable[[N], bool], stop: _StopRequest, specs: Sequence[Any],
         scratch: list[Path], check: Optional[Callable[[dict[str, Any]], Any]]) -> int:
    try:
        rcl_args = checked_arguments(args or [], name, specs, scratch, check)
        with rcl_log_held():
            rclpy.init(args=rcl_args, signal_handler_options=SignalHandlerOptions.NO)
        global _ros_started
        _ros_started = True
    except ConfigError as err:
        print(f'{name}: error: {one_line(str(err))}', file=sys.stderr)
        return 2
    except ROS_ARGS_ERRORS as err:
        # a missing or malformed --params-file, a bad remapping: rcl's message, minus
        # the C source locations it appends
        print(f'{name}: error: {one_line(rcl_reason(err))}', file=sys.stderr)
        return 2
    node: Optional[N] = None
    executor: Optional[Executor] = None
    try:
        node = make()
        install_clock_guard(node)
        kind = (node.get_parameter('executor').value if node.has_parameter('executor')
                else 'single_threaded')
        executor = make_executor(kind)
        executor.add_node(node)
        spin_until(executor, lambda: bool(stop) or done(node))
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RCLError:
        # the context was shut down while a callback was using it (a graph query, a
        # publish): a clean stop; anything else is a real error
        if rclpy.ok():
            raise
    except (ConfigError, ParameterError) as err:
        print(f'{name}: error: {one_line(str(err))}', file=sys.stderr)
        # 3 for a recorder's output that exists (BagExistsError), else 2
        return err.exit_code if isinstance(err, ConfigError) else 2
    except (InvalidParameterTypeException, InvalidParameterValueException) as err:
        # a parameter override out of its descriptor's range or of the wrong type
        reason = parameter_reason(err)
        print(f'{name}: error: {one_line(reason)}', file=sys.stderr)
        return 2
    finally:
        # a stop that hangs (in the middleware, a destructor) ends with the stacks of
        # all threads and exit code 1 instead of a process nobody stops (STOP_DEADLINE)
        faulthandler.dump_traceback_later(STOP_DEADLINE, exit=True)
        if executor is not None:
            # the executor first, while its node and the context live: left to the
            # garbage collector after them, the controller once died of SIGSEGV while
            # garbage-collecting after Ctrl-C (the events executor; this session's suite)
            executor.shutdown(timeout_sec=1.0)
            executor = None
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
