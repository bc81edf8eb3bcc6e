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

"""Executables ``schedule``, ``zero_dynamics`` and ``certificate``: tables and plots."""

from __future__ import annotations

import argparse
from typing import Sequence

from lookahead_control.analysis.paper_tables import schedule_table, speed_grid, zero_dynamics_table
from lookahead_control.core.cli import (ArgumentParser, markdown_table, number, parser,
                                        run_tool, ToolError, write_json)
from lookahead_control.core.config import load_vehicle
from lookahead_control.core.params import ControllerParams
from lookahead_control.core.stability import certificate, PAPER_GERSHGORIN, PAPER_NORM_BOUND

# the speeds the tools accept [m/s] (the scenarios' limit is 90 m/s; 150 covers any car)
MAX_SPEED = 150.0
MAX_ROWS = 10000


def add_speed_grid(p: ArgumentParser, v_min: float, v_max: float, step: float) -> None:
    """
    Add ``--v-min``, ``--v-max`` and ``--step`` to a table tool's parser.

    :param p: the parser.
    :param v_min: default first speed [m/s].
    :param v_max: default last speed [m/s].
    :param step: default spacing [m/s].
    """
    speed = number(0.0, MAX_SPEED, low_open=True, unit='m/s')
    p.add_argument('--v-min', type=speed, default=v_min, metavar='M/S',
                   help=f'first speed of the table [m/s] (default {v_min:g})')
    p.add_argument('--v-max', type=speed, default=v_max, metavar='M/S',
                   help=f'last speed of the table [m/s] (default {v_max:g})')
    p.add_argument('--step', type=number(0.0, MAX_SPEED, low_open=True, unit='m/s'),
                   default=step, metavar='M/S',
                   help=f'speed spacing of the table [m/s] (default {step:g})')


def grid(v_min: float, v_max: float, step: float) -> list[float]:
    """
    Return the table's speeds, or refuse an empty or huge grid in one line.

    :param v_min: first speed [m/s].
    :param v_max: last speed [m/s].
    :param step: spacing [m/s].
    :return: the speeds.
    """
    if v_max < v_min:
        raise ToolError(f'--v-max {v_max:g} m/s is below --v-min {v_min:g} m/s')
    if (v_max - v_min) / step + 1 > MAX_ROWS:
        raise ToolError(f'--step {step:g} m/s gives more than {MAX_ROWS} rows from '
                        f'{v_min:g} to {v_max:g} m/s; use a larger step')
    return speed_grid(v_min, v_max, step)


def schedule_main(argv: Sequence[str] | None = None) -> int:
    """
    Print d_v of the paper, exact and fixed schedules over speed.

    :param argv: command-line arguments.
    :return: exit code.
    """
    p = parser('d_v schedules over speed (eq. 24, 26) and the zero-dynamics damping '
               'each gives')
    add_speed_grid(p, 5.0, 40.0, 5.0)
    args = p.parse_args(argv)
    rows = schedule_table(load_vehicle(args.vehicle), grid(args.v_min, args.v_max, args.step))
    print(markdown_table(rows))
    limit = ControllerParams().max_look_ahead
    clamped = [row['speed_mps'] for row in rows if row['d_v_exact_m'] >= limit]
    if clamped:
        print(f'd_v clamped at max_look_ahead = {limit:g} m (the controller default) from '
              f'{min(clamped):g} m/s: there the d_v and zeta columns are not those of eq. '
              '24 / 26')
    if args.json:
        write_json(args.json, rows)
    if args.plot:
        from lookahead_control.analysis.plotting import plot_schedule
        print(f'wrote {plot_schedule(rows, args.plot)}')
    return 0


def zero_dynamics_main(argv: Sequence[str] | None = None) -> int:
    """
    Print the zero-dynamics roots over speed for fixed and scheduled d_v (Fig. 2/3).

    :param argv: command-line arguments.
    :return: exit code.
    """
    p = parser('zero-dynamics roots over speed, fixed d_v = d_s vs eq. 26 (Fig. 2/3)')
    add_speed_grid(p, 5.0, 40.0, 2.5)
    args = p.parse_args(argv)
    rows = zero_dynamics_table(load_vehicle(args.vehicle),
                               grid(args.v_min, args.v_max, args.step))
    print(markdown_table(rows))
    if args.json:
        write_json(args.json, rows)
    if args.plot:
        from lookahead_control.analysis.plotting import plot_roots
        print(f'wrote {plot_roots(rows, args.plot)}')
    return 0


def add_envelope(p: argparse.ArgumentParser, samples: int, samples_help: str) -> None:
    """
    Add the speed/acceleration envelope options of the stability tools.

    :param p: the parser.
    :param samples: the default of ``--samples``.
    :param samples_help: its help text.
    """
    speed = number(0.0, MAX_SPEED, low_open=True, unit='m/s')
    p.add_argument('--v-min', type=speed, default=10.0, metavar='M/S',
                   help='lowest speed of the envelope [m/s] (default 10)')
    p.add_argument('--v-max', type=speed, default=37.0, metavar='M/S',
                   help='highest speed of the envelope [m/s] (default 37)')
    p.add_argument('--a-max', type=number(0.0, 20.0, unit='m/s^2'), default=3.5,
                   metavar='M/S^2',
                   help='largest |longitudinal acceleration| [m/s^2] (default 3.5)')
    p.add_argument('--samples', type=number(2, 1_000_000, integer=True), default=samples,
                   metavar='N', help=samples_help)


def check_envelope(args: argparse.Namespace) -> None:
    """
    Refuse an envelope whose highest speed is not above its lowest.

    :param args: the parsed options of :func:`add_envelope`.
    """
    if not args.v_max > args.v_min:
        raise ToolError(f'--v-max {args.v_max:g} m/s must be above --v-min '
                        f'{args.v_min:g} m/s')


def certificate_main(argv: Sequence[str] | None = None) -> int:
    """
    Print the Section 4 stability certificate for a vehicle and envelope.

    :param argv: command-line arguments.
    :return: exit code (1 if the certificate does not hold).
    """
    p = parser('Section 4 stability certificate of the zero dynamics under varying '
               'speed (Bauer-Fike and Gershgorin)', plot=False)
    add_envelope(p, 2701, 'speeds checked, evenly spaced from --v-min to --v-max, both '
                 'included [-] (default 2701: every 0.01 m/s)')
    args = p.parse_args(argv)
    check_envelope(args)
    cert = certificate(load_vehicle(args.vehicle), args.v_min, args.v_max, args.a_max,
                       args.samples)
    rows = [
        {'quantity': 'max ||dP/dt||_2', 'computed': cert.max_norm,
         'paper': PAPER_NORM_BOUND, 'passes if': '< 1'},
        {'quantity': 'b11 = -1 + dP11/dt (max)', 'computed': cert.b11,
         'paper': PAPER_GERSHGORIN['b11'], 'passes if': 'b11 + r < 0'},
        {'quantity': 'b22 = -1 + dP22/dt (max)', 'computed': cert.b22,
         'paper': PAPER_GERSHGORIN['b22'], 'passes if': 'b22 + r < 0'},
        {'quantity': 'r1 = r2 = |dP12/dt| (max)', 'computed': cert.r,
         'paper': PAPER_GERSHGORIN['r1'], 'passes if': '-'},
        {'quantity': 'max eig(-I + dP/dt)', 'computed': cert.max_eig_b,
         'paper': float('nan'), 'passes if': '< 0'},
    ]
    print(f'envelope: v_x in [{cert.v_min:g}, {cert.v_max:g}] m/s, |a_x| <= '
          f'{cert.a_max:g} m/s^2, d_v (eq. 25) <= {cert.d_v_max:.2f} m; checked at '
          f'{args.samples} speeds (every {(cert.v_max - cert.v_min) / (args.samples - 1):.3g} '
          f'm/s); worst norm at {cert.max_norm_speed:.2f} m/s')
    print(markdown_table(rows))
    verdict = cert.holds_norm or cert.holds_gershgorin
    print(f'Bauer-Fike: {"holds" if cert.holds_norm else "fails"}; Gershgorin: '
          f'{"holds" if cert.holds_gershgorin else "fails"}; certificate '
          f'{"HOLDS" if verdict else "DOES NOT HOLD"}')
    if args.json:
        write_json(args.json, {'certificate': cert._asdict(), 'rows': rows})
    return 0 if verdict else 1


def schedule() -> int:
    """Entry point of ``schedule``."""
    return run_tool(schedule_main)


def zero_dynamics_tool() -> int:
    """Entry point of ``zero_dynamics``."""
    return run_tool(zero_dynamics_main)


def certificate_tool() -> int:
    """Entry point of ``certificate``."""
    return run_tool(certificate_main)
