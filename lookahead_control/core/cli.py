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

"""Shared command-line plumbing: one-line errors, tables, output folders."""

from __future__ import annotations

import argparse
import csv
import json
import math
from pathlib import Path
import sys
from typing import Any, Callable, Mapping, Sequence

from lookahead_control.core.config import ConfigError
from lookahead_control.core.params import ParameterError

EXIT_USAGE = 2


class ToolError(RuntimeError):
    """A failure a tool reports as one line and a non-zero exit."""


def one_line(text: str) -> str:
    """
    Return ``text`` on one line (parsers' messages span several).

    :param text: the message.
    :return: its words joined by single spaces.
    """
    return ' '.join(text.split())


def assignments(items: Sequence[str], option: str) -> dict[str, str]:
    """
    Parse repeated ``NAME=VALUE`` options.

    :param items: the option's values.
    :param option: its name, for the error.
    :return: name -> value (text).
    :raises ToolError: an item without ``=`` or without a name.
    """
    out = {}
    for item in items:
        name, sep, value = item.partition('=')
        if not sep or not name.strip():
            raise ToolError(f'{option} {item!r}: expected NAME=VALUE')
        out[name.strip()] = value
    return out


def run_tool(main: Callable[[Sequence[str] | None], int],
             argv: Sequence[str] | None = None) -> int:
    """
    Run a tool's main, turning expected failures into one line on stderr.

    :param main: the tool's main function.
    :param argv: its arguments (default: sys.argv[1:]).
    :return: the exit code.
    """
    prog = Path(sys.argv[0]).name
    try:
        return main(argv)
    except (ConfigError, ParameterError, ToolError, ValueError) as err:
        print(f'{prog}: error: {one_line(str(err))}', file=sys.stderr)
        return EXIT_USAGE
    except OSError as err:
        where = f'{err.filename}: ' if err.filename else ''
        print(f'{prog}: error: {where}{err.strerror or err}', file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print(f'{prog}: interrupted', file=sys.stderr)
        return 130


def parser(description: str) -> argparse.ArgumentParser:
    """
    Return an argument parser with the options every analysis tool shares.

    :param description: the tool's one-line purpose.
    :return: the parser.
    """
    p = argparse.ArgumentParser(description=description)
    p.add_argument('--vehicle', type=Path, default=None,
                   help='vehicle params YAML (default: config/vehicle.yaml)')
    p.add_argument('--plot', type=Path, default=None, metavar='PNG',
                   help='also write a PNG plot to this path')
    p.add_argument('--json', type=Path, default=None, metavar='FILE',
                   help='also write the table as JSON')
    return p


def fmt(value: Any, digits: int = 4) -> str:
    """
    Format a table cell: floats to ``digits`` significant digits, NaN as a dash.

    :param value: the cell.
    :param digits: significant digits.
    :return: its text.
    """
    if isinstance(value, float):
        if math.isnan(value):
            return '-'
        return f'{value:.{digits}g}'
    if isinstance(value, complex):
        return f'{value.real:.{digits}g}{value.imag:+.{digits}g}j'
    return str(value)


def markdown_table(rows: Sequence[Mapping[str, Any]], columns: Sequence[str] | None = None,
                   digits: int = 4) -> str:
    """
    Return rows as a GitHub markdown table.

    :param rows: the rows, all with the same keys.
    :param columns: which keys, in order (default: the first row's).
    :param digits: significant digits for floats.
    :return: the table text.
    """
    cols = list(columns or (rows[0].keys() if rows else []))

    def cell(text: str) -> str:
        return text.replace('|', '\\|')        # a | inside a cell would split it

    lines = ['| ' + ' | '.join(cell(c) for c in cols) + ' |', '|' + '---|' * len(cols)]
    for row in rows:
        lines.append('| ' + ' | '.join(cell(fmt(row[c], digits)) for c in cols) + ' |')
    return '\n'.join(lines)


def write_csv(path: Path, rows: Sequence[Mapping[str, Any]]) -> None:
    """
    Write rows as CSV.

    :param path: the file.
    :param rows: the rows.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open('w', newline='', encoding='utf-8') as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0].keys()) if rows else [])
        writer.writeheader()
        writer.writerows(rows)


def _jsonable(value: Any) -> Any:
    if hasattr(value, 'tolist') and not isinstance(value, (str, bytes)):
        value = value.tolist()          # numpy scalars and arrays
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, complex):
        return [value.real, value.imag]
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, Mapping):
        return {k: _jsonable(v) for k, v in value.items()}
    return value


def write_json(path: Path, data: Any) -> None:
    """
    Write data as strict JSON (NaN and infinities as null, complex as [re, im]).

    :param path: the file.
    :param data: rows or a mapping.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(_jsonable(data), indent=2, allow_nan=False) + '\n',
                    encoding='utf-8')
