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

Imported first by the package (``lookahead_control/__init__.py``,
``sim_plant/__init__.py``), so it is in place before any heavy import (numpy, rclpy):
an executable interrupted while it starts prints one line, not a stack of import frames.
Only the standard library here.
"""

from __future__ import annotations

import contextlib
from pathlib import Path
import signal
import sys
from types import FrameType, TracebackType
from typing import Any, Callable, Iterator, Optional

PACKAGE_NAME = 'lookahead_control'
_installed = False


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


def running_as_executable(argv0: Optional[str] = None) -> bool:
    """
    Return True when this process is one of the package's executables.

    ``python -m <module>`` (``sys.argv[0]`` is ``-m`` while the package is imported) or
    a console script installed in ``lib/lookahead_control/`` (``ros2 run``'s place; the
    venv's ``bin/`` links there). A library import (a test, a notebook) is left alone.

    :param argv0: the program (default ``sys.argv[0]``).
    :return: whether to install the executables' interrupt handling.
    """
    program = sys.argv[0] if argv0 is None and sys.argv else (argv0 or '')
    if program == '-m':
        return True
    try:
        return Path(program).resolve().parent.name == PACKAGE_NAME
    except (OSError, RuntimeError):
        return False


def _quiet_excepthook(previous: Callable[..., Any]) -> Callable[..., Any]:
    def hook(kind: type[BaseException], value: BaseException,
             trace: Optional[TracebackType]) -> None:
        if issubclass(kind, KeyboardInterrupt):
            what = 'terminated' if issubclass(kind, Terminated) else 'interrupted'
            print(f'{Path(sys.argv[0]).stem}: {what}', file=sys.stderr)
            return
        previous(kind, value, trace)
    return hook


def _raise_terminated(signum: int, frame: Optional[FrameType]) -> None:
    raise Terminated(signum)


def install() -> None:
    """
    Make an interrupt of an executable one line, and SIGTERM act like SIGINT.

    An uncaught KeyboardInterrupt prints ``<program>: interrupted`` instead of a
    traceback (Python still exits with the signal's code); SIGTERM raises
    :class:`Terminated`, a KeyboardInterrupt, so ``finally`` blocks stop children and
    finalize bags as for Ctrl-C (nodes handle both in ``ros.node_main.run_node``).
    Idempotent.
    """
    global _installed
    if _installed:
        return
    _installed = True
    sys.excepthook = _quiet_excepthook(sys.excepthook)
    with contextlib.suppress(ValueError):       # not the main thread: leave SIGTERM
        if signal.getsignal(signal.SIGTERM) == signal.SIG_DFL:
            signal.signal(signal.SIGTERM, _raise_terminated)


def install_if_executable() -> None:
    """Call :func:`install` when this process is one of the executables."""
    if running_as_executable():
        install()


@contextlib.contextmanager
def deferred() -> Iterator[list[int]]:
    """
    Hold SIGINT and SIGTERM while a cleanup runs (a second Ctrl-C must not cut it).

    :return: a context whose value lists the signals that arrived meanwhile.
    """
    received: list[int] = []

    def note(signum: int, frame: Optional[FrameType]) -> None:
        received.append(signum)
    previous = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    for s in previous:
        signal.signal(s, note)
    try:
        yield received
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
