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
What a controller told on ``/diagnostics`` over a run, summed up for its report.

The node's status carries its reasons (``; `` between them) and its counters; a run's
statuses become each reason's first moment, number of reports and worst level, and the
counters of the last status that are not 0 (they count from the node's start). Pure
data: the bag is read by :mod:`lookahead_control.bags.recorded_diagnostics`.
"""

from __future__ import annotations

from dataclasses import dataclass
import re
from typing import Optional, Sequence

from lookahead_control.bags.recorded_diagnostics import StatusReport

#: the status levels of ``diagnostic_msgs/DiagnosticStatus``, by value
LEVELS = ('OK', 'WARN', 'ERROR', 'STALE')
#: where a reason's name ends: a colon, a parenthesis, or a number after "for" / "at"
#: (``steering oscillates for 1.20 s``, ``sim clock stopped at 9.990 s``)
_NAME_END = re.compile(r'[:(]|,? (?:for|at) [-+]?[0-9]')


@dataclass(frozen=True)
class Told:
    """
    One reason the controller gave over a run.

    :param name: the reason's name (its text up to a colon, a parenthesis or a number
        after "for" / "at": ``lateral_error out of scale with the motion ...``).
    :param level: the worst level of the statuses that gave it.
    :param reports: how many statuses gave it.
    :param first_s: the first of them [s after the run's first lateral error] (a status
        comes once per diagnostics period: what it tells began up to a period before).
    :param example: the reason as the first of them gave it, in full.
    """

    name: str
    level: int
    reports: int
    first_s: float
    example: str


@dataclass(frozen=True)
class DiagnosticsSummary:
    """
    A controller's ``/diagnostics`` over a run.

    :param reports: its statuses in the run (those received up to its end, if known).
    :param levels: how many of them at each level (:data:`LEVELS`).
    :param told: their reasons, in the order they first came.
    :param counters: the last status's counters that are not 0 (counts, and the seconds
        of the checks that found something), as ``(key, value)``.
    :param at_end: the reasons of the statuses received after the run's end (its
        simulator had finished: its clock stopped, its inputs stopped), not counted.
    :param top: the highest level of ``reports`` (-1: none; another value than
        :data:`LEVELS`' is not counted in ``levels``).
    """

    reports: int
    levels: tuple[int, int, int, int]
    told: tuple[Told, ...]
    counters: tuple[tuple[str, str], ...]
    at_end: tuple[Told, ...] = ()
    top: int = -1

    @property
    def worst(self) -> str:
        """Return the name of the highest level of any status (``-``: none recorded)."""
        return level_name(self.top) if self.top >= 0 else '-'


def level_name(level: int) -> str:
    """
    Return a status level's name.

    :param level: its value.
    :return: ``OK``, ``WARN``, ``ERROR``, ``STALE``, or ``level <n>`` for another value.
    """
    return LEVELS[level] if 0 <= level < len(LEVELS) else f'level {level}'


def split_reasons(message: str) -> list[str]:
    """
    Return a status message's reasons: split at ``; `` outside parentheses.

    :param message: the message (``ok``: no reason).
    :return: the reasons (empty for ``ok`` or an empty message).
    """
    if message.strip() in ('', 'ok'):
        return []
    out, depth, start = [], 0, 0
    for i, char in enumerate(message):
        if char == '(':
            depth += 1
        elif char == ')':
            depth = max(0, depth - 1)
        elif char == ';' and depth == 0 and message[i + 1:i + 2] in (' ', ''):
            out.append(message[start:i].strip())
            start = i + 1
    out.append(message[start:].strip())
    return [reason for reason in out if reason]


def reason_name(reason: str) -> str:
    """
    Return the name of a reason: its text up to a colon, a parenthesis or a "for" / "at" number.

    :param reason: one reason (``steering oscillates for 1.20 s (+-56 mrad ...``).
    :return: e.g. ``steering oscillates``.
    """
    match = _NAME_END.search(reason)
    head = reason[:match.start()] if match else reason
    return head.strip(' ,') or reason.strip()


def _counter(key: str, value: str) -> bool:
    """Return whether a status value is a counter from the node's start, not 0."""
    if key.startswith(('age max', 'answer latency')) or key.endswith(
            ('[rad]', '[Hz]', '[x model]')):
        return False            # measures of the last period, or the law's estimates
    try:
        return float(value) != 0.0
    except ValueError:
        return False


#: the controller's reasons that never raise its level (told at OK: the law's own clips,
#: messages sent again, an inactive node); a status carries one level for all its reasons,
#: so beside a WARN they read WARN (dev-probe114: 'duplicates' listed as WARN)
OK_REASONS = frozenset({'duplicates', 'demand capped', 'approach clipped', 'inactive'})


def _note_reason(told: dict[str, Told], report: StatusReport, reason: str,
                 start_ns: int) -> None:
    """Count a reason of a status into ``told`` (by its name)."""
    name = reason_name(reason)
    level = min(report.level, 0) if name in OK_REASONS else report.level
    before = told.get(name)
    if before is None:
        told[name] = Told(name, level, 1, (report.stamp_ns - start_ns) * 1e-9, reason)
    else:
        told[name] = Told(name, max(before.level, level), before.reports + 1,
                          before.first_s, before.example)


def summarize(reports: Sequence[StatusReport], start_ns: int,
              end_recv_ns: Optional[int] = None) -> DiagnosticsSummary:
    """
    Sum up a controller's statuses over a run.

    :param reports: its statuses, in the order received.
    :param start_ns: the run's first lateral-error stamp (the times' zero) [ns].
    :param end_recv_ns: the run's end: when a simulator's run that finished its scenario
        received its last input (the recorder's clock, as the statuses' ``recv_ns``);
        None: no such end (every status is the run's).
    :return: the summary.
    """
    levels = [0, 0, 0, 0]
    told: dict[str, Told] = {}
    at_end: dict[str, Told] = {}
    counted, top = 0, -1
    for report in reports:
        if end_recv_ns is not None and report.recv_ns > end_recv_ns:
            for reason in split_reasons(report.message):
                _note_reason(at_end, report, reason, start_ns)
            continue
        counted += 1
        top = max(top, report.level)
        if 0 <= report.level < len(levels):
            levels[report.level] += 1
        for reason in split_reasons(report.message):
            _note_reason(told, report, reason, start_ns)
    counters = tuple((k, v) for k, v in reports[-1].values if _counter(k, v)) if reports else ()
    return DiagnosticsSummary(counted, (levels[0], levels[1], levels[2], levels[3]),
                              tuple(told.values()), counters, tuple(at_end.values()), top)


def summary_note(summary: DiagnosticsSummary) -> str:
    """
    Return the metrics table's note of a run's ``/diagnostics``: the reasons at WARN and up.

    :param summary: the summary.
    :return: e.g. ``diagnostics: WARN 'steering oscillates' in 3 of 12 statuses, first
        told at t = 4.1 s`` (empty when every status was OK).
    """
    said = [f"{level_name(t.level)} '{t.name}' in {t.reports} of {summary.reports} statuses, "
            f'first told at t = {t.first_s:.3g} s' for t in summary.told if t.level >= 1]
    return ('diagnostics: ' + ', '.join(said)) if said else ''
