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
import os
from pathlib import Path
import sys
from typing import Any, Callable, Mapping, NoReturn, Sequence

from lookahead_control.core import interrupts
from lookahead_control.core.config import ConfigError
from lookahead_control.core.interrupts import exit_code, install, raise_if_received, Terminated
from lookahead_control.core.params import ParameterError

EXIT_USAGE = 2
#: ``record`` refusing an output that exists: not 2, which is also a write failure
#: mid-run, so that ``closed_loop`` tells a bag another run took (nothing of this run in
#: it) from one that holds what its recorder wrote
EXIT_OUTPUT_EXISTS = 3
EXIT_BROKEN_PIPE = 128 + 13     # as a shell reports a process ended by SIGPIPE


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
    # as the interrupt hook names it: `python -m ...demo` is `demo` too, not `demo.py`
    prog = Path(sys.argv[0]).name.removesuffix('.py')
    install()           # SIGTERM stops the tool as Ctrl-C does (children, bags)
    try:
        # a Ctrl-C or SIGTERM while the tool started that an import swallowed (a C
        # extension's init can turn it into an ImportError a fallback catches): the tool
        # stops as the nodes do (node_main), instead of running on
        raise_if_received()
        return main(argv)
    except BrokenPipeError:
        # `tool | head`: the reader left; no message (nobody reads it), and no second
        # error when Python flushes stdout at exit
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    except (ConfigError, ParameterError, ToolError, ValueError) as err:
        print(f'{prog}: error: {one_line(str(err))}', file=sys.stderr)
        return err.exit_code if isinstance(err, ConfigError) else EXIT_USAGE
    except OSError as err:
        where = f'{err.filename}: ' if err.filename else ''
        print(f'{prog}: error: {where}{err.strerror or err}', file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt as err:          # SIGINT, or SIGTERM (Terminated)
        print(f'{prog}: {"terminated" if isinstance(err, Terminated) else "interrupted"}',
              file=sys.stderr)
        return exit_code(err)
    finally:
        # the tool has answered every signal it received: an in-process caller's next
        # tool does not stop on them (dev-probe112)
        interrupts.received.clear()


class ArgumentParser(argparse.ArgumentParser):
    """An ``argparse`` parser whose usage errors are one line (and exit 2)."""

    def error(self, message: str) -> NoReturn:
        """
        Print ``<prog>: error: <message> (see --help)`` and exit 2.

        :param message: argparse's message.
        """
        self.exit(EXIT_USAGE, f'{self.prog}: error: {one_line(message)} (see --help)\n')


def number(low: float = -math.inf, high: float = math.inf, *, low_open: bool = False,
           high_open: bool = False, unit: str = '',
           integer: bool = False) -> Callable[[str], Any]:
    """
    Return an argparse ``type`` that accepts a finite number in a range.

    :param low: the lower bound.
    :param high: the upper bound.
    :param low_open: the lower bound itself is not allowed.
    :param high_open: the upper bound itself is not allowed.
    :param unit: the unit, for the message.
    :param integer: accept integers only.
    :return: the converter (raises ``argparse.ArgumentTypeError`` naming the range).
    """
    suffix = f' {unit}' if unit else ''
    allowed = (f'{"(" if low_open else "["}{low:g}, {high:g}{")" if high_open else "]"}'
               f'{suffix}').replace('[-inf', '(-inf').replace('inf]', 'inf)')

    def convert(text: str) -> Any:
        try:
            value: Any = int(text) if integer else float(text)
        except ValueError:
            kind = 'an integer' if integer else 'a number'
            raise argparse.ArgumentTypeError(f'{text!r} is not {kind}') from None
        below = value <= low if low_open else value < low
        above = value >= high if high_open else value > high
        if not math.isfinite(value) or below or above:
            raise argparse.ArgumentTypeError(f'{text}{suffix} is out of range; allowed: '
                                             f'{allowed}')
        return value
    convert.__name__ = 'integer' if integer else 'number'
    return convert


#: the signature of a PNG file: only such a file is replaced by ``--plot``
PNG_SIGNATURE = b'\x89PNG\r\n\x1a\n'


def _written_by_a_tool(path: Path, suffix: str) -> bool:
    """
    Return whether an existing regular file is of the kind a tool writes there.

    :param path: the file (regular, not a link).
    :param suffix: ``.png`` (its signature) or ``.json`` (a JSON array or object).
    :return: whether it is.
    :raises OSError: it cannot be read.
    """
    with path.open('rb') as handle:
        if suffix == '.png':
            return handle.read(len(PNG_SIGNATURE)) == PNG_SIGNATURE
        try:
            data = json.load(handle)
        except ValueError:      # not JSON, not UTF-8: someone's file
            return False
    return isinstance(data, (list, dict))


def output_file(suffix: str) -> Callable[[str], Path]:
    """
    Return an argparse ``type`` for an output file that must end with ``suffix``.

    Refused when the option is read, before any work: another suffix (matplotlib would
    pick the format from it, or fail late; a ``--json README.md`` replaced the README),
    a folder, a path under a file or in a folder this user may not write in (before:
    ``File exists`` after a whole league, dev-probe96), a symbolic link (it was followed:
    a JSON file elsewhere rewritten, a dangling ``x.json -> NOTES.md`` wrote ``NOTES.md``),
    something that is not a regular file (a FIFO: reading it to check it hung the tool,
    dev-probe98), and an existing file that is not of the kind (a PNG's signature; a
    JSON array or object, the whole file parsed): a tool's earlier output is replaced,
    nothing else.

    :param suffix: ``.png`` or ``.json``.
    :return: the converter.
    """
    def convert(text: str) -> Path:
        path = Path(text)
        if path.suffix.lower() != suffix:
            raise argparse.ArgumentTypeError(f'{text}: expected a {suffix} file name')
        if path.is_symlink():
            raise argparse.ArgumentTypeError(f'{text}: is a symbolic link (to '
                                             f'{os.readlink(path)}); give the file itself')
        if path.is_dir():
            raise argparse.ArgumentTypeError(f'{text}: is a folder')
        folder = path.parent
        while not folder.exists() and folder != folder.parent:
            folder = folder.parent
        if not folder.is_dir() or not os.access(folder, os.W_OK):
            raise argparse.ArgumentTypeError(f'{text}: {folder} is not a folder this user '
                                             'may write in')
        if path.exists():
            if not path.is_file():
                raise argparse.ArgumentTypeError(f'{text}: exists and is not a regular file '
                                                 '(a device, a FIFO, a socket)')
            try:
                ours = _written_by_a_tool(path, suffix)
            except OSError as err:
                raise argparse.ArgumentTypeError(f'{text}: cannot read it to check what it '
                                                 f'holds ({err.strerror})') from err
            if not ours:
                raise argparse.ArgumentTypeError(
                    f'{text}: exists and is no {suffix[1:].upper()} file a tool wrote (only '
                    'such a file is replaced); choose another name or move it away')
        return path
    convert.__name__ = 'path'
    return convert


def parser(description: str, plot: bool = True) -> ArgumentParser:
    """
    Return an argument parser with the options every analysis tool shares.

    :param description: the tool's one-line purpose.
    :param plot: offer ``--plot`` (tools without a plot must not accept it).
    :return: the parser.
    """
    p = ArgumentParser(description=description)
    p.add_argument('--vehicle', type=Path, default=None,
                   help='vehicle params YAML (default: config/vehicle.yaml)')
    if plot:
        p.add_argument('--plot', type=output_file('.png'), default=None, metavar='PNG',
                       help='also write a PNG plot to this path')
    p.add_argument('--json', type=output_file('.json'), default=None, metavar='FILE',
                   help='also write the table as JSON (a .json file: an earlier one is '
                   'replaced, no other file)')
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


def write_csv(path: Path, rows: Sequence[Mapping[str, Any]],
              columns: Sequence[str] | None = None) -> None:
    """
    Write rows as CSV.

    :param path: the file.
    :param rows: the rows.
    :param columns: the header (default: the first row's keys; without rows and
        columns the file has an empty header).
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open('w', newline='', encoding='utf-8') as handle:
        fields = list(columns) if columns is not None else list(rows[0].keys()) if rows else []
        writer = csv.DictWriter(handle, fieldnames=fields)
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


# -- output folders a tool may rewrite -----------------------------------------------------

def output_manifest(out: Path, tool: str) -> Path:
    """
    Return the file in which ``tool`` lists what it wrote into ``out``.

    :param out: the output folder.
    :param tool: the tool's name.
    :return: ``out/.<tool>_written``.
    """
    return out / f'.{tool}_written'


def claim_output(out: Path, tool: str, overwrite: bool = False,
                 names: Sequence[str] = ()) -> frozenset[str]:
    """
    Check that ``tool`` may write into ``out`` before it runs; never delete anything.

    A missing or empty folder (created here), or one that ``tool`` wrote (its manifest is
    there), is fine. Any other non-empty folder is refused unless ``overwrite``: then
    files of the tool's names are replaced and nothing else is touched. In a folder
    ``tool`` wrote, a file of one of ``names`` that its manifest does not list (put
    there by someone else, e.g. a name an older version of the tool did not write) is
    refused the same way.

    :param out: the ``--out`` folder.
    :param tool: the tool's name (the manifest's and the message's).
    :param overwrite: the user allowed writing into a folder ``tool`` did not make.
    :param names: the files this run will write there.
    :return: the names the tool's previous runs wrote there (empty if none).
    :raises ToolError: ``out`` is a file, or a non-empty folder ``tool`` did not write,
        or a file of ``names`` there that ``tool`` did not write.
    """
    if out.exists() and not out.is_dir():
        raise ToolError(f'--out {out}: is a file, not a folder')
    manifest = output_manifest(out, tool)
    if manifest.is_file():
        previous = frozenset(manifest.read_text(encoding='utf-8').split('\n')) - {''}
        foreign = [n for n in names if n not in previous and (out / n).exists()]
        if foreign and not overwrite:
            raise ToolError(f'--out {out}: {foreign[0]} is there and {tool} did not write '
                            'it; move it away, or give --overwrite to replace it')
        return previous
    entries = sorted(p.name for p in out.iterdir()) if out.is_dir() else []
    if entries and not overwrite:
        raise ToolError(f'--out {out}: not empty and not written by {tool} (holds '
                        f'{", ".join(entries[:3])}{" ..." if len(entries) > 3 else ""}); '
                        'give a new or empty folder, or --overwrite to replace files of '
                        f"{tool}'s names there")
    try:
        out.mkdir(parents=True, exist_ok=True)      # unwritable: one line, before any run
    except OSError as err:
        raise ToolError(f'--out {out}: cannot create it ({err.strerror})') from err
    return frozenset()


def record_output(out: Path, tool: str, written: Sequence[Path],
                  previous: frozenset[str] = frozenset()) -> None:
    """
    List what ``tool`` wrote into ``out`` (its previous runs' files stay listed).

    Nothing is deleted: a file an earlier run wrote and this one did not stays, listed,
    and is named on stderr (dev-probe96: an earlier run's ``fig_fixed.png`` stayed beside
    a report of other bags, unsaid).

    :param out: the output folder.
    :param tool: the tool's name.
    :param written: the files this run wrote (those outside ``out`` are ignored).
    :param previous: :func:`claim_output`'s answer (the previous runs' files).
    """
    mine = {p.name for p in written if p.parent.resolve() == out.resolve()}
    stale = sorted(name for name in previous - mine if (out / name).exists())
    if stale:
        more = ' ...' if len(stale) > 5 else ''
        print(f'{tool}: note: {out} keeps {len(stale)} file(s) of an earlier {tool} run '
              f'that this one did not write: {", ".join(stale[:5])}{more} (a new --out has '
              "only this run's)", file=sys.stderr)
    manifest = output_manifest(out, tool)
    tmp = manifest.with_name(manifest.name + '.tmp')
    tmp.write_text('\n'.join(sorted(mine | previous)) + '\n', encoding='utf-8')
    os.replace(tmp, manifest)
