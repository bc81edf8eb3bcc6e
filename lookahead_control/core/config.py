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
Load parameters from ROS 2 params YAML files without ROS.

The same ``config/*.yaml`` files are given to the nodes with ``--params-file`` and read
here by the offline tools, so a run on the bench and a run in ROS use one source of
truth. A params file maps node names (or the ``/**`` wildcard) to ``ros__parameters``;
nested keys flatten to dotted names (``vehicle.mass``).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
import re
import sys
from typing import Any, Callable, Mapping, Sequence, Type, TypeVar

from lookahead_control.core.baselines import (BaselineParams, LqrParams, PurePursuitParams,
                                              StanleyParams)
from lookahead_control.core.lane_keeping import LaneKeepingParams
from lookahead_control.core.param_schema import (BASELINE_SPECS, check_params, CONTROLLER_SPECS,
                                                 LANE_KEEPING_SPECS, namespaces_of,
                                                 SAFETY_SPECS, Spec, unknown_name,
                                                 VEHICLE_SPECS)
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
import yaml


PACKAGE_NAME = 'lookahead_control'
D = TypeVar('D')


SPECS_BY_NAMESPACE = {'vehicle': VEHICLE_SPECS, 'controller': CONTROLLER_SPECS,
                      'safety': SAFETY_SPECS, 'lane_keeping': LANE_KEEPING_SPECS,
                      **{name: tuple(s for s in BASELINE_SPECS
                                     if s.name.partition('.')[0] == name)
                         for name in ('pure_pursuit', 'stanley', 'lqr')}}


class ConfigError(ValueError):
    """A configuration file that is missing, malformed or holds bad values."""


def source_config_dir() -> Path:
    """Return the ``config/`` folder of the source tree (or of the installed share)."""
    here = Path(__file__).resolve().parents[2] / 'config'
    if here.is_dir():
        return here
    try:
        from ament_index_python.packages import get_package_share_directory
    except ImportError as err:  # pragma: no cover - the venv always has it
        raise ConfigError(f'no config folder at {here} and ament_index_python is '
                          'missing') from err
    return Path(get_package_share_directory(PACKAGE_NAME)) / 'config'


def read_yaml(path: Path | str) -> Any:
    """
    Read a YAML file, turning every failure into one :class:`ConfigError`.

    :param path: the file.
    :return: the parsed document.
    """
    return _read(path, yaml.safe_load)


def read_params_yaml(path: Path | str) -> Any:
    """
    Read a ROS params file as rcl reads it (:func:`load_params_yaml`).

    :param path: the file.
    :return: the parsed document.
    :raises ConfigError: a missing, unreadable or malformed file, or one rcl refuses.
    """
    return _read(path, load_params_yaml)


def _read(path: Path | str, load: Callable[[str], Any]) -> Any:
    file = Path(path)
    try:
        text = file.read_text(encoding='utf-8')
    except OSError as err:
        raise ConfigError(f'{file}: cannot read: {err.strerror or err}') from err
    try:
        return load(text)
    except yaml.YAMLError as err:
        mark = getattr(err, 'problem_mark', None)
        where = f' (line {mark.line + 1})' if mark is not None else ''
        what = 'not readable by rcl' if isinstance(err, RclYamlError) else 'malformed YAML'
        raise ConfigError(f'{file}: {what}{where}: '
                          f'{getattr(err, "problem", None) or err}') from err


# rcl_yaml_param_parser's reading of a scalar that is not quoted (its ``get_value``):
# a bool from these words, else an int64 if C's strtol (base 0) takes the whole text,
# else a double if strtod does (or one of YAML's .inf / .nan spellings), else a string.
# PyYAML (YAML 1.1) reads many values otherwise: '2e-3', 'inf' and '1.5e3' are strings
# to it and doubles to rcl; 'y' and 'n' strings to it and bools to rcl; '1_000',
# '0b101', '1:20', 'null' and '2001-12-14' numbers, None or a date to it and strings
# to rcl; explicit tags (!!float) are obeyed by it and ignored by rcl.
_RCL_TRUE = frozenset(('Y', 'y', 'yes', 'Yes', 'YES', 'true', 'True', 'TRUE', 'on', 'On',
                       'ON'))
_RCL_FALSE = frozenset(('N', 'n', 'no', 'No', 'NO', 'false', 'False', 'FALSE', 'off',
                        'Off', 'OFF'))
_RCL_SPECIAL = {**{s: math.nan for s in ('.nan', '.NaN', '.NAN')},
                **{f'{sign}{s}': (-math.inf if sign == '-' else math.inf)
                   for sign in ('', '+', '-') for s in ('.inf', '.Inf', '.INF')}}
_C_SPACE = '[ \t\n\v\f\r]*'
_RCL_INT = re.compile(_C_SPACE + r'[+-]?(0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)')
_RCL_DECIMAL = re.compile(_C_SPACE + r'[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?')
_RCL_HEX = re.compile(_C_SPACE + r'([+-]?)(0[xX]([0-9a-fA-F]+\.?[0-9a-fA-F]*|'
                      r'\.[0-9a-fA-F]+)([pP][+-]?[0-9]+)?)')
_RCL_WORD = re.compile(_C_SPACE + r'([+-]?)(inf|infinity|nan(\([0-9A-Za-z_]*\))?)',
                       re.IGNORECASE)
INT64_RANGE = (-2 ** 63, 2 ** 63 - 1)


class RclYamlError(yaml.MarkedYAMLError):
    """YAML that PyYAML reads and rcl refuses (an alias, a list of mixed types)."""


def rcl_scalar(text: str) -> Any:
    """
    Return an unquoted YAML scalar as rcl reads it in a params file or ``-p``.

    :param text: the scalar's text (a quoted scalar is always the string itself).
    :return: a bool, an int (int64), a float or the text.
    """
    if text in _RCL_TRUE or text in _RCL_FALSE:
        return text in _RCL_TRUE
    whole = _RCL_INT.fullmatch(text)
    if whole:
        number = int(whole.group(1), 16 if whole.group(1)[1:2] in ('x', 'X') else 8
                     if whole.group(1).startswith('0') else 10)
        number = -number if text.lstrip().startswith('-') else number
        if INT64_RANGE[0] <= number <= INT64_RANGE[1]:
            return number           # else strtol's ERANGE: strtod's turn
    if text in _RCL_SPECIAL:
        return _RCL_SPECIAL[text]
    word = _RCL_WORD.fullmatch(text)
    if word:
        value = math.nan if word.group(2)[:1] in ('n', 'N') else math.inf
        return -value if word.group(1) == '-' else value
    hexa = _RCL_HEX.fullmatch(text)
    if hexa:
        value, digits = float.fromhex(hexa.group(2)), hexa.group(3)
        value = -value if hexa.group(1) == '-' else value
    elif _RCL_DECIMAL.fullmatch(text):
        value, digits = float(text), _RCL_DECIMAL.fullmatch(text).group(1)  # type: ignore
    else:
        return text
    # strtod's ERANGE (rcl then keeps the text): overflow, or a nonzero value that
    # underflows to a subnormal or to zero
    nonzero = any(c not in '0.xX' for c in digits)
    if math.isinf(value) or (nonzero and abs(value) < sys.float_info.min):
        return text
    return value


class _RclLoader(yaml.SafeLoader):
    """PyYAML's composer with rcl's refusal of aliases (``*name``)."""

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise RclYamlError(None, None, f'an alias (*{event.anchor}): rcl reads no YAML '
                               'aliases or merge keys, write the values out',
                               event.start_mark)
        return super().compose_node(parent, index)


def _rcl_object(node: yaml.Node) -> Any:
    if isinstance(node, yaml.ScalarNode):
        if node.style in ("'", '"'):
            return node.value
        return None if node.value == '' else rcl_scalar(node.value)
    if isinstance(node, yaml.MappingNode):
        out: dict[str, Any] = {}
        for key, value in node.value:
            if not isinstance(key, yaml.ScalarNode):
                raise RclYamlError(None, None, 'a key that is not a plain name',
                                   key.start_mark)
            new = _rcl_object(value)
            old = out.get(key.value)
            # a map opened twice is one map to rcl, the later values replacing
            out[key.value] = (_merged(old, new) if isinstance(old, dict)
                              and isinstance(new, dict) else new)
        return out
    items = []
    for item in node.value:
        if not isinstance(item, yaml.ScalarNode):
            raise RclYamlError(None, None, 'a list inside a list: a parameter is a list '
                               'of plain values', item.start_mark)
        items.append(_rcl_object(item))
    kinds = {type(item).__name__ for item in items}
    if len(kinds) > 1:
        raise RclYamlError(None, None, f'a list of mixed types ({", ".join(sorted(kinds))}):'
                           ' rcl refuses it; write every item the same way (1.0, 2.5)',
                           node.start_mark)
    return items


def _merged(old: dict[str, Any], new: dict[str, Any]) -> dict[str, Any]:
    out = dict(old)
    for key, value in new.items():
        out[key] = (_merged(out[key], value) if isinstance(out.get(key), dict)
                    and isinstance(value, dict) else value)
    return out


_ROS_NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_]*')


def section_name_error(name: str) -> str | None:
    """
    Return why rcl refuses a params file's section name, or None if it takes it.

    The name the keys above ``ros__parameters`` spell (``/**/controller``), a leading
    slash added: each part between slashes a ROS name (letters, digits, underscores,
    not first a digit) or a wildcard ``*`` or ``**``.

    :param name: the section's name.
    :return: the reason, or None.
    """
    for token in (name if name.startswith('/') else '/' + name)[1:].split('/'):
        if token not in ('*', '**') and not _ROS_NAME.fullmatch(token):
            return (f'{token!r} is not a ROS name (letters, digits and underscores, not '
                    'first a digit) nor a wildcard (* or **)' if token else
                    'an empty name between slashes')
    return None


def _rcl_node(text: str) -> Any:
    loader = _RclLoader(text)
    try:
        return loader.get_single_node()
    finally:
        loader.dispose()


def load_params_yaml(text: str) -> Any:
    """
    Parse YAML text as rcl reads a ROS params file (or a ``-p`` value).

    Unquoted scalars are typed as rcl types them (:func:`rcl_scalar`), tags are
    ignored, keys are their text, and what rcl refuses is refused: aliases (so merge
    keys), lists of mixed types and lists inside lists.

    :param text: the YAML text.
    :return: the document (None if empty).
    :raises yaml.YAMLError: malformed YAML, or :class:`RclYamlError`.
    """
    node = _rcl_node(text)
    return None if node is None else _rcl_object(node)


def rcl_param_value(text: str) -> Any:
    """
    Return the value of a ``-p name:=value`` override as rcl reads it.

    :param text: the text after ``:=``.
    :return: the value.
    :raises ConfigError: an empty value, a mapping, or YAML rcl refuses.
    """
    try:
        value = load_params_yaml(text)
    except yaml.YAMLError as err:
        raise ConfigError(f'{one_line_yaml_error(err)}') from err
    if value is None or isinstance(value, dict):
        raise ConfigError(f'{text!r} is not a value rcl reads (a number, true / false, a '
                          "string, a list; an empty string is '')")
    return value


def one_line_yaml_error(err: yaml.YAMLError) -> str:
    """
    Return a YAML error's problem in one line.

    :param err: the error.
    :return: its problem (and line), or its text.
    """
    mark = getattr(err, 'problem_mark', None)
    where = f' (line {mark.line + 1})' if mark is not None else ''
    return f'{getattr(err, "problem", None) or err}{where}'


def _flatten(prefix: str, tree: Mapping[str, Any], out: dict[str, Any]) -> None:
    for key, value in tree.items():
        name = f'{prefix}.{key}' if prefix else str(key)
        if isinstance(value, Mapping):
            _flatten(name, value, out)
        else:
            out[name] = value


def flat_parameters(section: Any) -> dict[str, Any]:
    """
    Return a params file section's ``ros__parameters`` as dotted names.

    :param section: ``{ros__parameters: {...}}``.
    :return: dotted name -> value (empty if the section has none).
    """
    out: dict[str, Any] = {}
    if isinstance(section, Mapping) and isinstance(section.get('ros__parameters'), Mapping):
        _flatten('', section['ros__parameters'], out)
    return out


def _is_namespace(node: Any) -> bool:
    # a mapping of node names (rcl's nested form ``/**: {controller: {ros__parameters:
    # ...}}``), not a node's section (``ros__parameters`` missing: an error if it applies)
    if not isinstance(node, yaml.MappingNode) or not node.value:
        return False
    if any(getattr(k, 'value', None) == 'ros__parameters' for k, _ in node.value):
        return False
    return all(isinstance(v, yaml.MappingNode) and (
        any(getattr(k, 'value', None) == 'ros__parameters' for k, _ in v.value)
        or _is_namespace(v)) for _, v in node.value)


def node_sections(path: Path | str) -> list[tuple[str, dict[str, Any] | None]]:
    """
    Return a params file's node sections as rcl reads them, in the file's order.

    Values are typed as rcl types them (:func:`load_params_yaml`). A namespace nesting
    (``/**: {controller: {ros__parameters: ...}}``) is the node name it spells
    (``/**/controller``); sections of the same name (a key written twice) are one, at the
    place of the first, the later one's entries replacing the earlier one's. A section
    name rcl refuses (:func:`section_name_error`) is refused.

    :param path: the params file.
    :return: (node name or pattern, its flat parameters, or None if it has no
        ``ros__parameters`` mapping) pairs.
    :raises ConfigError: a missing, unreadable or malformed file, not a mapping, or one
        rcl refuses.
    """
    document = read_params_yaml(path)
    if not isinstance(document, Mapping):
        raise ConfigError(f'{path}: not a ROS parameters file (expected '
                          '"<node>: {ros__parameters: {...}}")')
    out: dict[str, dict[str, Any] | None] = {}

    def walk(node: Any, prefix: list[str]) -> None:
        for key_node, value_node in node.value:
            parts = [*prefix, str(key_node.value)]
            if _is_namespace(value_node):
                walk(value_node, parts)
                continue
            name = parts[0] if len(parts) == 1 else '/' + '/'.join(
                p.strip('/') for p in parts if p.strip('/'))
            section = _rcl_object(value_node)
            flat = (flat_parameters(section) if isinstance(section, Mapping) and isinstance(
                section.get('ros__parameters'), Mapping) else None)
            error = None if flat is None else section_name_error(name)
            if error is not None:
                raise ConfigError(f'{path}: section {name!r} (line '
                                  f'{key_node.start_mark.line + 1}): rcl refuses the file: '
                                  f'{error}')
            old = out.get(name, {})
            out[name] = None if old is None or flat is None else {**old, **flat}

    walk(_rcl_node(Path(path).read_text(encoding='utf-8')), [])
    return list(out.items())


def applies_to(key: Any, node_name: str) -> bool:
    """
    Return True if a params file's section ``key`` is for the node, as rcl matches it.

    As rclpy reads a params file: a leading slash is added, ``/**`` matches any number of
    namespace levels (``/**``, ``/**/controller``) and ``/*`` one (``/*``), and the
    pattern must match the node's whole name.

    :param key: the section's name in the file.
    :param node_name: the node's name (``controller``; the node runs in the root namespace).
    :return: whether the section's parameters apply to the node.
    """
    pattern = str(key) if str(key).startswith('/') else '/' + str(key)
    parts = re.split(r'(/\*\*|/\*)', pattern)
    regex = ''.join({'/**': r'(/\w+)*', '/*': r'(/\w+)'}.get(p, re.escape(p)) for p in parts)
    return re.fullmatch(regex, '/' + node_name.lstrip('/')) is not None


def load_ros_params(path: Path | str, node_name: str | None = None) -> dict[str, Any]:
    """
    Read the flattened parameters of a ROS 2 params YAML file.

    With ``node_name``, every section that applies to that node (``/**``, ``/*``,
    ``/**/controller``, ``controller``, ``/controller``: :func:`applies_to`) in the
    file's order, a later section's value replacing an earlier one's, as rclpy merges
    them; without, the ``/**`` sections only.

    :param path: the params file.
    :param node_name: the node whose sections to merge, or None for wildcards only.
    :return: a mapping of dotted parameter names to values.
    """
    merged: dict[str, Any] = {}
    for key, flat in node_sections(path):
        wanted = (applies_to(key, node_name) if node_name else
                  str(key) in ('/**', '**'))
        if not wanted:
            continue
        if flat is None:
            raise ConfigError(f'{path}: section {key!r} has no ros__parameters mapping')
        merged.update(flat)
    return merged


def dataclass_from_params(cls: Type[D], params: Mapping[str, Any], prefix: str,
                          source: str = 'parameters') -> D:
    """
    Build a parameter dataclass from flattened ``prefix.field`` entries.

    Each entry is checked against the parameter schema the nodes declare their
    parameters from (:mod:`~lookahead_control.core.param_schema`): an unknown name (a
    typo) is an error, an integer for a real is that real, a value outside the node's
    range is refused. Missing fields keep their defaults.

    :param cls: the dataclass type.
    :param params: flattened parameters.
    :param prefix: the namespace of the dataclass fields, e.g. ``vehicle``.
    :param source: where the parameters came from (the file), for messages.
    :return: the validated dataclass.
    :raises ConfigError: ``<source>: <name> = <value> ...``.
    """
    names = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    specs = [s for s in SPECS_BY_NAMESPACE.get(prefix, ())
             if s.name.partition('.')[2] in names]
    mine = {k: v for k, v in params.items() if k.partition('.')[0] == prefix}
    try:
        if specs:
            mine = check_params(mine, specs)
        values: dict[str, Any] = {}
        for key, value in mine.items():
            field = key.partition('.')[2]
            if field not in names:
                raise ParameterError(unknown_name(key, (f'{prefix}.{n}' for n in names)))
            values[field] = value
        return cls(**values)
    except ParameterError as err:
        raise ConfigError(f'{source}: {err}') from err


def check_params_file(path: Path | str, node_name: str,
                      specs: Sequence[Spec]) -> dict[str, dict[str, Any]]:
    """
    Check a ROS params file for one node against its schema, as the node would read it.

    Sections for the node (``controller``, ``/controller``, ``/**/controller``) must
    hold only its parameters; wildcard sections (``/**``) serve other nodes too, so
    there only names in the node's namespaces (``vehicle.*`` ...) are checked.

    :param path: the params file.
    :param node_name: the node's name.
    :param specs: the node's parameters.
    :return: section -> the section's flat parameters, integers for reals converted.
    :raises ConfigError: ``<file>: <name> = <value> ...``, or a malformed file.
    """
    out: dict[str, dict[str, Any]] = {}
    for pattern, flat in node_sections(path):
        if not applies_to(pattern, node_name):
            continue
        if flat is None:
            raise ConfigError(f'{path}: section {pattern!r} has no ros__parameters mapping')
        wildcard = '*' in pattern
        try:
            out[pattern] = check_params(flat, specs,
                                        namespaces_of(specs) if wildcard else None)
        except ParameterError as err:
            raise ConfigError(f'{path}: {err}') from err
    return out


def load_vehicle(path: Path | str | None = None) -> VehicleParams:
    """
    Load the vehicle parameters (default: ``config/vehicle.yaml``).

    :param path: a ROS params file with ``vehicle.*`` entries.
    :return: the vehicle parameters.
    """
    file = Path(path) if path else source_config_dir() / 'vehicle.yaml'
    return dataclass_from_params(VehicleParams, load_ros_params(file), 'vehicle', str(file))


def load_controller(path: Path | str | None = None, **overrides: Any) -> ControllerParams:
    """
    Load the controller parameters (default: ``config/controller.yaml``).

    :param path: a ROS params file with ``controller.*`` entries.
    :param overrides: field values that replace the file's.
    :return: the controller parameters.
    """
    file = Path(path) if path else source_config_dir() / 'controller.yaml'
    params = load_ros_params(file, 'controller')
    params.update({f'controller.{k}': v for k, v in overrides.items()})
    return dataclass_from_params(ControllerParams, params, 'controller', str(file))


def load_lane_keeping(path: Path | str | None = None) -> LaneKeepingParams:
    """
    Load the CG-compensated law's settings (default: ``config/controller.yaml``).

    The node's own params file: its ``lane_keeping.*`` entries (in the ``controller``
    node's section or ``/**``), the rest of the law's settings at their defaults, exactly
    what the node would run.

    :param path: a ROS params file.
    :return: the settings.
    :raises ConfigError: ``<file>: lane_keeping.<name> = <value> ...``.
    """
    file = Path(path) if path else source_config_dir() / 'controller.yaml'
    return dataclass_from_params(LaneKeepingParams, load_ros_params(file, 'controller'),
                                 'lane_keeping', str(file))


def load_baselines(path: Path | str | None = None) -> BaselineParams:
    """
    Load the baseline laws' parameters (default: ``config/controller.yaml``).

    :param path: a ROS params file with ``pure_pursuit.*``, ``stanley.*``, ``lqr.*``
        entries for the ``controller`` node (the rest at their defaults).
    :return: the parameters.
    :raises ConfigError: ``<file>: <name> = <value> ...``.
    """
    file = Path(path) if path else source_config_dir() / 'controller.yaml'
    params = load_ros_params(file, 'controller')
    return BaselineParams(
        dataclass_from_params(PurePursuitParams, params, 'pure_pursuit', str(file)),
        dataclass_from_params(StanleyParams, params, 'stanley', str(file)),
        dataclass_from_params(LqrParams, params, 'lqr', str(file)))


def changed_fields(params: Any) -> dict[str, Any]:
    """
    Return the fields of a parameter dataclass that differ from its defaults.

    :param params: a dataclass instance whose fields all have defaults.
    :return: field name -> value, in field order (empty: all defaults).
    """
    default = type(params)()
    return {f.name: getattr(params, f.name) for f in dataclasses.fields(params)
            if getattr(params, f.name) != getattr(default, f.name)}
