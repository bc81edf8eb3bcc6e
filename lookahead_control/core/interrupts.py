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
Interrupts of the executables: Ctrl-C and SIGTERM as a clean stop, never a traceback.

Imported first by the packages (``lookahead_control/__init__.py``,
``sim_plant/__init__.py``), before any heavy import (numpy, rclpy): an executable
interrupted while it starts prints one line, not a stack of import frames. Only modules
the interpreter has loaded at start-up (and ``signal``), so the import itself is short.
"""

from __future__ import annotations

import os
import signal
import sys
from types import FrameType, TracebackType
from typing import Any

PACKAGE_NAME = 'lookahead_control'
_installed = False
# `python -m lookahead_control.x`: argv[0] is '-m' while the package is being imported
_STARTED_AS_MODULE = sys.argv[:1] == ['-m']
# SIGINT / SIGTERM received by an executable, in order (a library may swallow the
# KeyboardInterrupt; the node's spin loop and the excepthook still see the signal)
received: list[int] = []


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where SIGINT raises KeyboardInterrupt (so every cleanup runs)."""

    def __init__(self, signum: int = signal.SIGTERM) -> None:
        """
        Remember the signal.

        :param signum: the signal number (for the exit code 128 + signum).
        """
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def exit_code(interrupt: BaseException) -> int:
    """
    Return the shell's exit code for an interrupt: 128 + the signal number.

    :param interrupt: a KeyboardInterrupt (SIGINT) or :class:`Terminated`.
    :return: 130 for SIGINT, 143 for SIGTERM.
    """
    return 128 + int(getattr(interrupt, 'signum', signal.SIGINT))


def raise_if_received() -> None:
    """
    Raise the interrupt of a SIGINT / SIGTERM that a library swallowed, if one came.

    A Ctrl-C while a C extension initializes (a lazy import) can become an ImportError a
    fallback catches, and the tool ran on: ``run_tool`` checks before the tool's main,
    a loop (``replay``'s, ``closed_loop``'s, the offline tools') between its steps. The
    signals are forgotten as their interrupt is raised (and when ``run_tool`` returns):
    a library caller that catches it can run again (dev-probe112: one Ctrl-C a caller
    had caught stopped every later league, sweep and analyze at once).

    :raises KeyboardInterrupt: a SIGINT was received (:class:`Terminated`: a SIGTERM).
    """
    if received:
        signum = received[-1]
        received.clear()
        raise interrupt_of(signum)


def interrupt_of(signum: int) -> KeyboardInterrupt:
    """
    Return the exception a signal raises: :class:`Terminated` for SIGTERM.

    :param signum: SIGINT or SIGTERM.
    :return: the KeyboardInterrupt to raise.
    """
    return Terminated(signum) if signum == signal.SIGTERM else KeyboardInterrupt()


def running_as_executable(argv0: str | None = None) -> bool:
    """
    Return True when this process is one of the package's executables.

    ``python -m <module>`` (``sys.argv[0]`` is ``-m`` while the package is imported,
    then the module's file) or a console script installed in ``lib/lookahead_control/``
    (``ros2 run``'s place; the venv's ``bin/`` links there). A library import (a test, a
    notebook, a user's script) is left alone, also a script in a folder of the package's
    name that is not in a ``lib`` (a colcon workspace's ``src/lookahead_control/``:
    dev-probe112).

    :param argv0: the program (default ``sys.argv[0]``).
    :return: whether to install the executables' interrupt handling.
    """
    program = argv0 if argv0 is not None else (sys.argv[0] if sys.argv else '')
    if program == '-m' or (argv0 is None and _STARTED_AS_MODULE):
        return True
    try:
        folder = os.path.dirname(os.path.realpath(program))
        return (os.path.basename(folder) == PACKAGE_NAME
                and os.path.basename(os.path.dirname(folder)) == 'lib')
    except (OSError, ValueError):
        return False


def _interrupted(value: BaseException | None) -> BaseException | None:
    """Return the KeyboardInterrupt behind an exception (an import wraps it), or None."""
    for _ in range(20):
        if value is None or isinstance(value, KeyboardInterrupt):
            return value
        value = value.__cause__ or value.__context__
    return None


class _Hook:
    """The excepthook: one line for an executable's interrupt, else the previous hook."""

    def __init__(self, previous: object) -> None:
        self.previous = previous

    def __call__(self, kind: type[BaseException], value: BaseException,
                 trace: TracebackType | None) -> None:
        # a library may wrap the interrupt into its own error (numpy's, rclpy's import
        # failures), or lose it: the signal was received all the same
        interrupt = _interrupted(value)
        if (interrupt is not None or received) and running_as_executable():
            terminated = isinstance(interrupt, Terminated) or (
                interrupt is None and received[-1] == signal.SIGTERM)
            name = os.path.basename(sys.argv[0]).rsplit('.py', 1)[0]
            print(f'{name}: {"terminated" if terminated else "interrupted"}',
                  file=sys.stderr)
            if not isinstance(value, KeyboardInterrupt):
                # Python exits 1 for the other error it has here (replay, Ctrl-C at
                # 0.77 s: 'replay: interrupted' and exit 1; dev-probe56): the signal's code
                sys.stdout.flush()
                sys.stderr.flush()
                os._exit(exit_code(interrupt) if interrupt is not None
                         else 128 + received[-1])
            return
        self.previous(kind, value, trace)       # type: ignore[operator]


class _UnraisableHook:
    """
    The unraisablehook: an executable's interrupt that Python cannot raise is silent.

    A Ctrl-C to the process group can land in a child between ``fork`` and ``exec``,
    while Python runs its after-fork hooks (``subprocess`` with ``preexec_fn``); Python
    then prints ``Exception ignored in ... Traceback`` and the child goes on to start its
    node. The parent has the same Ctrl-C and prints the one line. Once a signal has
    been received, any exception Python cannot raise is silent too: it is what the
    interrupt left half done (the process is stopping on that interrupt).
    """

    def __init__(self, previous: object) -> None:
        self.previous = previous

    def __call__(self, unraisable: Any) -> None:
        # also what an interrupt left half done: a Ctrl-C inside rclpy's logger
        # constructor, at 'import rclpy' (its root logger), before any of this package's
        # code could give the class the attribute its __del__ reads, made that __del__
        # print 'Exception ignored ... AttributeError' after 'record: interrupted'
        if ((_interrupted(unraisable.exc_value) is not None or received)
                and running_as_executable()):
            return
        self.previous(unraisable)               # type: ignore[operator]


def _on_signal(signum: int, frame: FrameType | None) -> None:
    """Remember the signal, then raise as Python does for SIGINT (Terminated for SIGTERM)."""
    received.append(signum)
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise Terminated(signum)


def _handle(signum: int, default: object) -> None:
    """Route a signal to :func:`_on_signal` unless someone else handles it already."""
    try:
        if signal.getsignal(signum) == default:
            signal.signal(signum, _on_signal)
    except ValueError:          # not the main thread
        pass


def _install_hooks() -> None:
    """Install the excepthook and the unraisablehook (once)."""
    if not isinstance(sys.excepthook, _Hook):
        sys.excepthook = _Hook(sys.excepthook)
    if not isinstance(sys.unraisablehook, _UnraisableHook):
        sys.unraisablehook = _UnraisableHook(sys.unraisablehook)


def install() -> None:
    """
    Make an interrupt of a tool one line, and SIGTERM act like SIGINT.

    An uncaught KeyboardInterrupt (also one an import wrapped into another error)
    prints ``<program>: interrupted`` instead of a traceback (Python still exits with the
    signal's code); SIGTERM raises :class:`Terminated`, a KeyboardInterrupt, so
    ``finally`` blocks stop children and finalize bags as for Ctrl-C (nodes handle both
    in ``ros.node_main.run_node``). Idempotent.
    """
    global _installed
    if _installed:
        return
    _installed = True
    _install_hooks()
    _handle(signal.SIGTERM, signal.SIG_DFL)
    _handle(signal.SIGINT, signal.default_int_handler)


def install_if_executable() -> None:
    """
    Install the start-up part of :func:`install` when this process is an executable.

    The excepthook goes in first, whatever the process (it only acts for an
    executable): an interrupt while this very check runs is one line too. Then SIGINT
    is remembered as it raises (:data:`received`); SIGTERM keeps its default until
    :func:`install` (a tool) or ``run_node`` (a node): a node told to stop while its
    Python is still starting just ends, silently.
    """
    _install_hooks()
    if running_as_executable():
        _handle(signal.SIGINT, signal.default_int_handler)


class deferred:  # noqa: N801 - used as a context manager, like contextlib's
    """
    Hold SIGINT and SIGTERM while a cleanup runs (a second Ctrl-C must not cut it).

    When the cleanup ran without an exception in flight (a run that ended on its own), a
    signal held is raised on leaving: a Ctrl-C during the cleanup between two runs stops
    the tool, not the cleanup. It is not added to :data:`received`: a library caller that
    catches the interrupt can run again (dev-probe110: every later run stopped at once).
    """

    def __enter__(self) -> list[int]:
        """Hold the signals; return the list of those that arrive meanwhile."""
        self.held: list[int] = []
        self._previous = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
        for s in self._previous:
            signal.signal(s, self._note)
        return self.held

    def _note(self, signum: int, frame: FrameType | None) -> None:
        self.held.append(signum)

    def __exit__(self, kind: type[BaseException] | None, *exc: object) -> None:
        """
        Put the previous handlers back; raise a signal held unless an exception is in flight.

        :param kind: the exception in flight, if any (it carries the stop already).
        :raises KeyboardInterrupt: a signal came meanwhile (:class:`Terminated`: SIGTERM).
        """
        for s, handler in self._previous.items():
            signal.signal(s, handler)
        if self.held and kind is None:
            raise interrupt_of(self.held[-1])
