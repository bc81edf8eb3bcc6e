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
ROS params files and ``-p`` values read as rcl reads them (its YAML parameter parser).

PyYAML (YAML 1.1) types plain scalars otherwise than rcl: ``2e-3``, ``inf`` and
``1.5e3`` are strings to it and doubles to rcl; ``y`` and ``n`` strings to it and bools
to rcl; ``1_000``, ``0b101``, ``1:20``, ``null`` and ``2001-12-14`` numbers, None or a
date to it and strings to rcl; it obeys tags (``!!float 1``) that rcl ignores. The
nodes' start-up check, ``closed_loop`` and the offline tools read params files here, so
the values they check are the values the node gets. What rcl refuses is refused, and so
is what rcl reads in a way no user means (a parameter written twice with two types, of
which rcl keeps the first type in the order bool, int, double, string; a section holding
both ``ros__parameters`` and another node's section, which rcl reads or refuses by the
order of the two). Left to PyYAML's scanner, which refuses a few texts libyaml takes
(a tab before a comment, several documents in one file): refused, with the line.
"""

from __future__ import annotations

from fractions import Fraction
import math
import re
import sys
from typing import Any, Optional

import yaml

PARAMS_KEY = 'ros__parameters'
STR_TAG = 'tag:yaml.org,2002:str'
#: rmw's longest node name
MAX_NODE_NAME = 255

_TRUE = frozenset(('Y', 'y', 'yes', 'Yes', 'YES', 'true', 'True', 'TRUE', 'on', 'On', 'ON'))
_FALSE = frozenset(('N', 'n', 'no', 'No', 'NO', 'false', 'False', 'FALSE', 'off', 'Off',
                    'OFF'))
_SPECIAL = {**{s: math.nan for s in ('.nan', '.NaN', '.NAN')},
            **{f'{sign}{s}': (-math.inf if sign == '-' else math.inf)
               for sign in ('', '+', '-') for s in ('.inf', '.Inf', '.INF')}}
_C_SPACE = '[ \\t\\n\\v\\f\\r]*'
_INT = re.compile(_C_SPACE + r'([+-]?)(0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)')
_DECIMAL = re.compile(_C_SPACE + r'([+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?)')
_HEX = re.compile(_C_SPACE + r'([+-]?)0[xX]([0-9a-fA-F]*)\.?([0-9a-fA-F]*)(?:[pP]([+-]?[0-9]+))?')
# C's strtod words, ASCII only: re.IGNORECASE alone also took the Unicode 'ı' and 'ſ'
_WORD = re.compile(_C_SPACE + r'([+-]?)(inf|infinity|nan(\([0-9A-Za-z_]*\))?)',
                   re.IGNORECASE | re.ASCII)
INT64_RANGE = (-2 ** 63, 2 ** 63 - 1)
_ROS_NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_]*')


class RclYamlError(yaml.MarkedYAMLError):
    """YAML that PyYAML reads and rcl refuses or reads otherwise than meant."""


def _error(problem: str, node: Any) -> RclYamlError:
    return RclYamlError(None, None, problem, node.start_mark)


# glibc judges tininess after rounding: a value that rounds (with an unbounded exponent)
# to the smallest normal double is not tiny; below the midpoint under it, it is
_TINY = Fraction(sys.float_info.min) - Fraction(1, 2 ** 1076)


def _strtod_range_error(exact: Fraction, value: float) -> bool:
    # glibc's ERANGE, after which rcl keeps the text: an overflow, or a result that is
    # tiny and inexact (an exact subnormal is no error)
    if math.isinf(value):
        return True
    return 0 < abs(exact) < _TINY and Fraction(value) != exact


def _hex_float(sign: str, whole: str, fraction: str, exponent: Optional[str]) -> Any:
    if not whole and not fraction:
        return None
    exact = Fraction(int(whole + fraction or '0', 16), 16 ** len(fraction)) * Fraction(
        2) ** int(exponent or 0)
    exact = -exact if sign == '-' else exact
    try:
        value = float(exact)
    except OverflowError:
        return None
    return None if _strtod_range_error(exact, value) else value


def rcl_scalar(text: str) -> Any:
    """
    Return an unquoted YAML scalar as rcl reads it in a params file or ``-p``.

    rcl's ``get_value``: a bool from its words, else an int64 if C's strtol (base 0)
    takes the whole text, else a double if strtod does (or YAML's ``.inf`` / ``.nan``
    spellings), else the text.

    :param text: the scalar's text (a quoted scalar is always the string itself).
    :return: a bool, an int (int64), a float or the text.
    """
    if text in _TRUE or text in _FALSE:
        return text in _TRUE
    whole = _INT.fullmatch(text)
    if whole:
        digits = whole.group(2)
        number = int(digits, 16 if digits[1:2] in ('x', 'X') else 8
                     if digits.startswith('0') else 10)
        number = -number if whole.group(1) == '-' else number
        if INT64_RANGE[0] <= number <= INT64_RANGE[1]:
            return number           # else strtol's ERANGE: strtod's turn
    if text in _SPECIAL:
        return _SPECIAL[text]
    word = _WORD.fullmatch(text)
    if word:
        value = math.nan if word.group(2)[:1] in ('n', 'N') else math.inf
        return -value if word.group(1) == '-' else value
    hexa = _HEX.fullmatch(text)
    if hexa:
        number = _hex_float(*hexa.groups())
        return text if number is None else number
    decimal = _DECIMAL.fullmatch(text)
    if not decimal:
        return text
    value = float(decimal.group(1))
    return text if _strtod_range_error(Fraction(decimal.group(1)), value) else value


class _Loader(yaml.SafeLoader):
    """PyYAML's composer with rcl's refusal of aliases and its ``!!str``."""

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise RclYamlError(None, None, f'an alias (*{event.anchor}): rcl reads no YAML '
                               'aliases or merge keys, write the values out',
                               event.start_mark)
        # aliases refused: an anchor names nothing, and rcl takes one written twice
        self.anchors = {}
        return super().compose_node(parent, index)

    def compose_scalar_node(self, anchor: Any) -> Any:
        tag = self.peek_event().tag
        node = super().compose_scalar_node(anchor)
        setattr(node, 'rcl_string', tag == STR_TAG)    # rcl keeps an explicit !!str a string
        return node


def compose(data: str | bytes) -> Any:
    """
    Return the YAML node tree of a text (bytes: UTF-8 or UTF-16 by its mark).

    :param data: the text.
    :return: the root node, or None for an empty document.
    :raises yaml.YAMLError: malformed YAML, or an alias.
    """
    loader = _Loader(data)
    try:
        return loader.get_single_node()
    except RecursionError as err:
        # rcl reads hundreds of levels; Python's recursion stops first (a traceback)
        raise RclYamlError(None, None, 'nested too deep to read (hundreds of levels)',
                           None) from err
    finally:
        loader.dispose()


def _kind(value: Any) -> str:
    if isinstance(value, list):
        return 'list of ' + (type(value[0]).__name__ if value else 'nothing')
    return type(value).__name__


# rcl keeps the latest value of each type a parameter was given, and rclpy reads the
# first type present in this order: the later value is read unless an earlier one's
# type comes first (a real after an integer: the integer is read)
_PRIORITY = ('bool', 'int', 'float', 'str', 'list of nothing', 'list of bool', 'list of int',
             'list of float', 'list of str')


def _shadowed(old: Any, new: Any) -> bool:
    # True if rcl reads the earlier value, not the later one
    kinds = (_kind(old), _kind(new))
    return kinds[0] != kinds[1] and _PRIORITY.index(kinds[0]) < _PRIORITY.index(kinds[1])


def _shadow_problem(name: str, old: Any, new: Any) -> str:
    return (f'{name} is given as {_kind(old)} {old!r} and later as {_kind(new)} {new!r}: '
            f'rcl keeps both and reads the {_kind(old)} {old!r}, not the later; give both '
            'the same type')


#: deeper maps are refused (Python's recursion would fail first, with a traceback)
MAX_DEPTH = 64


def value_of(node: Any, depth: int = 1) -> Any:
    """
    Return a parameter's value (a node under ``ros__parameters``) as rcl reads it.

    :param node: the node.
    :param depth: its depth under ``ros__parameters`` (1: a parameter or namespace
        there).
    :return: a scalar, a list of one type, or a mapping of names to values.
    :raises RclYamlError: what rcl refuses or reads otherwise than meant.
    """
    if depth > MAX_DEPTH:
        raise _error(f'maps nested more than {MAX_DEPTH} deep', node)
    if isinstance(node, yaml.ScalarNode):
        if node.value == '' and node.style not in ("'", '"'):
            raise _error("no value (rcl refuses an empty one; an empty string is '')", node)
        if node.style in ("'", '"') or getattr(node, 'rcl_string', False):
            return node.value.split('\0', 1)[0]        # rcl's C string ends at a NUL
        return rcl_scalar(node.value)
    if isinstance(node, yaml.MappingNode):
        if not node.value:
            raise _error('an empty map ({}) where a value belongs: rcl refuses it', node)
        out: dict[str, Any] = {}
        for key, item in node.value:
            name = _key(key)
            if depth >= 2 and '.' in name and isinstance(item, yaml.MappingNode):
                raise _error(f'{name!r}: a dotted name opening a map inside a map (rcl '
                             'misnames the names after it); write it as nested maps', key)
            new = value_of(item, depth + 1)
            if name in out:
                new = _merged(out[name], new, name, key)
            out[name] = new
        return out
    items = []
    for item in node.value:
        if not isinstance(item, yaml.ScalarNode):
            raise _error('a list or a map inside a list: a parameter is a list of plain '
                         'values', item)
        items.append(value_of(item, depth + 1))
    kinds = {type(item).__name__ for item in items}
    if len(kinds) > 1:
        raise _error(f'a list of mixed types ({", ".join(sorted(kinds))}): rcl refuses it; '
                     'write every item the same way (1.0, 2.5)', node)
    return items


def _key(node: Any) -> str:
    if not isinstance(node, yaml.ScalarNode):
        raise _error('a key that is not a plain name', node)
    if node.value.split('\0', 1)[0] == '':
        raise _error('an empty key: rcl refuses it', node)
    return str(node.value).split('\0', 1)[0]


def _merged(old: Any, new: Any, name: str, mark: Any) -> Any:
    """Return a value written twice: maps are one, a scalar the later of one type."""
    if isinstance(old, dict) and isinstance(new, dict):
        out = dict(old)
        for key, value in new.items():
            out[key] = _merged(out[key], value, f'{name}.{key}', mark) if key in out else value
        return out
    if isinstance(old, dict) or isinstance(new, dict):
        raise _error(f'{name} written twice, as a value and as a map: write it once', mark)
    if _shadowed(old, new):
        raise _error(_shadow_problem(name, old, new), mark)
    return new


def merge_flat(old: dict[str, Any], new: dict[str, Any], mark: Any = None) -> None:
    """
    Refuse what rcl reads otherwise when a later source sets parameters of earlier ones.

    A section of the same name again, another file, or a ``-p``: a name given two types
    (rcl keeps both and reads one by its type), or a later map under an earlier value's
    name (``frame_id: odom``, later ``frame_id: {child: x}``: rcl renames the value to
    ``frame_id.child``).

    :param old: the parameters so far (flat).
    :param new: the later ones (flat).
    :param mark: where the later ones begin (the error's line), or None.
    :raises RclYamlError: naming the parameter.
    """
    for param, value in new.items():
        if param in old and _shadowed(old[param], value):
            raise RclYamlError(None, None, _shadow_problem(param, old[param], value),
                               getattr(mark, 'start_mark', None))
        head = param.rpartition('.')[0]
        while head:
            if head in old and head not in new:
                raise RclYamlError(None, None, f'{head} is a value, and later the map of '
                                   f'{param}: rcl then renames the value; give one or the '
                                   'other', getattr(mark, 'start_mark', None))
            head = head.rpartition('.')[0]


def flatten(tree: dict[str, Any], prefix: str = '') -> dict[str, Any]:
    """
    Return nested parameters as dotted names.

    :param tree: ``{'a': {'b': 1}}``.
    :param prefix: the names' prefix.
    :return: ``{'a.b': 1}``.
    """
    out: dict[str, Any] = {}
    for key, value in tree.items():
        name = f'{prefix}.{key}' if prefix else key
        for param, item in (flatten(value, name) if isinstance(value, dict)
                            else {name: value}).items():
            if param in out and _shadowed(out[param], item):
                # 'a: {b: 1}' and 'a.b: 0.2' in one section: rcl reads the int
                raise RclYamlError(None, None, _shadow_problem(param, out[param], item),
                                   None)
            out[param] = item
    return out


def _joined(names: list[str]) -> str:
    # rcl's namespace tracker: a slash between names, unless the former ends with one
    out = names[0]
    for name in names[1:]:
        out += name if out.endswith('/') else '/' + name
    return out


def section_name_error(name: str) -> str | None:
    """
    Return why rcl refuses a params file's section name, or None if it takes it.

    The name the keys above ``ros__parameters`` spell (``/**/controller``), a leading
    slash added: each part between slashes a ROS name (letters, digits, underscores,
    not first a digit) or a wildcard ``*`` or ``**``; the node's name at most 255
    characters.

    :param name: the section's name.
    :return: the reason, or None.
    """
    tokens = (name if name.startswith('/') else '/' + name)[1:].split('/')
    for token in tokens:
        if token not in ('*', '**') and not _ROS_NAME.fullmatch(token):
            return (f'{token!r} is not a ROS name (letters, digits and underscores, not '
                    'first a digit) nor a wildcard (* or **)' if token else
                    'an empty name between slashes')
    if len(tokens[-1]) > MAX_NODE_NAME:
        return f'a node name of {len(tokens[-1])} characters (at most {MAX_NODE_NAME})'
    return None


def params_sections(data: str | bytes) -> list[tuple[str, dict[str, Any]]]:
    """
    Return a params file's node sections as rcl reads them, in the file's order.

    Keys above ``ros__parameters`` (any key starting with it, as rcl matches it) are
    the node's name, joined by slashes as rcl joins them (``/**: {controller: ...}`` is
    ``/**/controller``, ``/: {controller: ...}`` ``/controller``); sections of one name
    are one, at the place of the first.

    :param data: the file's text (bytes: UTF-8 or UTF-16 by its mark).
    :return: (section name, flat parameters) pairs; none for an empty file.
    :raises yaml.YAMLError: malformed YAML, or :class:`RclYamlError` (what rcl refuses
        or reads otherwise than meant), with the line.
    """
    root = compose(data)
    if root is None:
        return []                   # rcl: no parameters
    if not isinstance(root, yaml.MappingNode):
        raise _error('not a ROS parameters file (expected "<node>: {ros__parameters: '
                     '{...}}")', root)
    out: dict[str, dict[str, Any]] = {}

    def walk(node: yaml.MappingNode, names: list[str]) -> None:
        sections = [key for key, _ in node.value if isinstance(key, yaml.ScalarNode)
                    and str(key.value).startswith(PARAMS_KEY)]
        if sections and len(sections) != len(node.value):
            raise _error(f'{_joined(names) if names else "the top level"} holds both '
                         f'{sections[0].value} and other keys: rcl reads this or refuses '
                         'it by their order; write each node its own section', node)
        if len(sections) > 1:
            raise _error(f'{len(sections)} keys {PARAMS_KEY}... in one section: rcl '
                         'refuses it', sections[1])
        for key_node, value_node in node.value:
            key = _key(key_node)
            if key.startswith(PARAMS_KEY):
                if not names:
                    raise _error(f'{key} with no node name above it: rcl refuses it '
                                 '(expected "<node>: {ros__parameters: {...}}")', key_node)
                name = _joined(names)
                error = section_name_error(name)
                if error is not None:
                    raise _error(f'section {name!r}: rcl refuses the file: {error}',
                                 key_node)
                if not isinstance(value_node, yaml.MappingNode):
                    raise _error(f'{key} of {name!r} is not a map of parameters', value_node)
                flat = flatten(value_of(value_node)) if value_node.value else {}
                old = out.get(name, {})
                merge_flat(old, flat, key_node)
                out[name] = {**old, **flat}
            elif isinstance(value_node, yaml.MappingNode):
                walk(value_node, [*names, key])
            else:
                where = _joined([*names, key])
                raise _error(f'{where}: a value outside {PARAMS_KEY} (rcl refuses it; '
                             f'parameters go under "<node>: {{{PARAMS_KEY}: {{...}}}}")',
                             value_node)

    try:
        walk(root, [])
    except RecursionError as err:
        raise RclYamlError(None, None, 'nested too deep to read (hundreds of levels)',
                           None) from err
    return list(out.items())


def param_value(text: str) -> Any:
    """
    Return the value of a ``-p name:=value`` override as rcl reads it.

    :param text: the text after ``:=``.
    :return: the value.
    :raises RclYamlError: an empty value or a map (rcl refuses them), or what rcl
        refuses or reads otherwise than meant; yaml.YAMLError: malformed YAML.
    """
    node = compose(text)
    if node is None or isinstance(node, yaml.MappingNode):
        raise RclYamlError(None, None, f'{text!r} is not a value rcl reads (a number, true '
                           "/ false, a string, a list; an empty string is '')", None)
    return value_of(node)
