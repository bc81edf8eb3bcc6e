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

import math
import re
import sys
import time
from typing import Callable, Optional, Sequence, TypeVar

from lookahead_control.core.cli import one_line
from lookahead_control.core.config import ConfigError, read_yaml
from lookahead_control.core.params import ParameterError
import rclpy
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node

N = TypeVar('N', bound=Node)
RCLError = _rclpy.RCLError
_RCL_LOCATION = re.compile(r', at /\S+:\d+')


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


def check_params_files(args: Sequence[str]) -> None:
    """
    Read each ``--params-file`` before rcl does, for a one-line error naming it.

    :param args: command-line arguments.
    :raises ConfigError: a file is missing, unreadable, malformed or not a mapping.
    """
    for flag, path in zip(args, args[1:]):
        if flag == '--params-file' and not isinstance(read_yaml(path), dict):
            raise ConfigError(f'{path}: not a ROS parameters file (expected '
                              '"<node>: {ros__parameters: {...}}")')


def run_node(name: str, args: Optional[list[str]], make: Callable[[], N],
             done: Callable[[N], bool] = lambda node: False) -> int:
    """
    Create a node, spin it until done or shut down, and clean up.

    :param name: the executable's name, for the one-line error.
    :param args: command-line arguments (ROS arguments included).
    :param make: creates (and, if needed, activates) the node after ``rclpy.init``.
    :param done: True when the node has finished (default: run until shut down).
    :return: 0, or 2 for bad parameters or config.
    """
    try:
        check_params_files(args or [])
        rclpy.init(args=args)
    except ConfigError as err:
        print(f'{name}: error: {one_line(str(err))}', file=sys.stderr)
        return 2
    except RCLError as err:
        # a missing or malformed --params-file, a bad remapping: rcl's message, minus
        # the C source locations it appends
        print(f'{name}: error: {one_line(_RCL_LOCATION.sub("", str(err)))}', file=sys.stderr)
        return 2
    node: Optional[N] = None
    try:
        node = make()
        kind = (node.get_parameter('executor').value if node.has_parameter('executor')
                else 'single_threaded')
        executor = make_executor(kind)
        executor.add_node(node)
        spin_until(executor, lambda: done(node))
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RCLError:
        # SIGINT / SIGTERM shut the context down while a callback was using it (a
        # graph query, a publish): a clean stop; anything else is a real error
        if rclpy.ok():
            raise
    except (ConfigError, ParameterError) as err:
        print(f'{name}: error: {one_line(str(err))}', file=sys.stderr)
        return 2
    except (InvalidParameterTypeException, InvalidParameterValueException) as err:
        # a parameter override out of its descriptor's range or of the wrong type
        reason = str(err).split('Reason: ', 1)[-1].rsplit(': ', 1)[0]
        print(f'{name}: error: {one_line(reason)}', file=sys.stderr)
        return 2
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
