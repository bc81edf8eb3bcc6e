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
from pathlib import Path
import re
from typing import Any, Mapping, Sequence, Type, TypeVar

from lookahead_control.core.baselines import (BaselineParams, LqrParams, PurePursuitParams,
                                              StanleyParams)
from lookahead_control.core.lane_keeping import LaneKeepingParams
from lookahead_control.core.param_schema import (BASELINE_SPECS, check_params, CONTROLLER_SPECS,
                                                 LANE_KEEPING_SPECS, namespaces_of,
                                                 SAFETY_SPECS, Spec, unknown_name,
                                                 VEHICLE_SPECS)
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
from lookahead_control.core.rcl_yaml import param_value, params_sections, RclYamlError
from lookahead_control.core.safety import SafetyParams
import yaml


PACKAGE_NAME = 'lookahead_control'
MERGE_TAG = 'tag:yaml.org,2002:merge'
VALUE_TAG = 'tag:yaml.org,2002:value'
#: a map's merge key (``<<``) in the duplicate check
_MERGE = object()
D = TypeVar('D')


SPECS_BY_NAMESPACE = {'vehicle': VEHICLE_SPECS, 'controller': CONTROLLER_SPECS,
                      'safety': SAFETY_SPECS, 'lane_keeping': LANE_KEEPING_SPECS,
                      **{name: tuple(s for s in BASELINE_SPECS
                                     if s.name.partition('.')[0] == name)
                         for name in ('pure_pursuit', 'stanley', 'lqr')}}


class ConfigError(ValueError):
    """A configuration file that is missing, malformed or holds bad values."""

    #: the exit code of a tool or node that stops on it (bad usage, as argparse's)
    exit_code = 2


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


class _UniqueKeyLoader(yaml.SafeLoader):
    """PyYAML's safe loader, refusing a key written twice in one map."""

    def __init__(self, stream: Any) -> None:
        super().__init__(stream)
        self._checked: dict[int, Any] = {}

    def flatten_mapping(self, node: Any) -> None:
        """
        Merge a map's ``<<`` keys into it, first refusing a key written twice in it.

        PyYAML keeps the later value without a word: a scenario with two ``speed:`` or
        two ``external_forces:`` lists ran with the second alone. The check reads each
        map once, as written, before PyYAML's merge rewrites its keys in place (so a map
        merged into another and used again through its alias is not taken for one with
        its merged keys written twice, dev-probe82). Keys a merge (``<<: *base``) brings
        in are overridden by the map's own, as YAML means; two ``<<`` in one map are
        refused (PyYAML kept the later one: ``<<: [*a, *b]`` merges both).

        :param node: a mapping node.
        :raises yaml.constructor.ConstructorError: a key written twice, with both lines.
        """
        if id(node) not in self._checked:
            self._checked[id(node)] = node          # kept: its id stays its own
            first: dict[Any, Any] = {}
            for key_node, _ in node.value:
                if key_node.tag == MERGE_TAG:
                    key: Any = _MERGE          # not the string '<<' (a quoted key)
                    why = 'merge several maps with <<: [*a, *b]'
                elif key_node.tag == VALUE_TAG:
                    key = key_node.value       # '=': PyYAML's merge makes it a string
                    why = 'write it once'
                else:
                    key = self.construct_object(key_node, deep=True)
                    why = 'write it once'
                try:
                    earlier = first.get(key)
                    first.setdefault(key, key_node)
                except TypeError:
                    continue                # unhashable: construct_mapping refuses it
                # by value: a key written again through an alias of the first is the
                # same node (dev-probe83: {&k a: 1, *k : 2} took 2)
                if earlier is not None:
                    mark = earlier.start_mark
                    where = f'line {mark.line + 1}' + (
                        f', column {mark.column + 1}'
                        if mark.line == key_node.start_mark.line else '')
                    name = repr('<<') if key is _MERGE else repr(key)
                    raise yaml.constructor.ConstructorError(
                        None, None, f'{name} written twice in one map (first on {where}): '
                        f'{why}', key_node.start_mark)
        super().flatten_mapping(node)


def read_yaml(path: Path | str) -> Any:
    """
    Read a YAML file, turning every failure into one :class:`ConfigError`.

    A key written twice in one map is refused (PyYAML keeps the later one silently).

    :param path: the file.
    :return: the parsed document.
    """
    file = Path(path)
    try:
        text = file.read_text(encoding='utf-8')
    except (OSError, UnicodeDecodeError) as err:
        raise ConfigError(f'{file}: cannot read: {getattr(err, "strerror", None) or err}'
                          ) from err
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 (a safe loader)
    except yaml.YAMLError as err:
        raise ConfigError(f'{file}: {yaml_problem(err)}') from err


def yaml_problem(err: yaml.YAMLError) -> str:
    """
    Return a YAML error in one line: what is wrong, where.

    :param err: the error (:class:`~lookahead_control.core.rcl_yaml.RclYamlError`: what
        rcl refuses or reads otherwise than meant).
    :return: ``malformed YAML (line 3): ...`` or ``not readable by rcl (line 3): ...``.
    """
    mark = getattr(err, 'problem_mark', None)
    where = f' (line {mark.line + 1})' if mark is not None else ''
    what = 'not readable by rcl' if isinstance(err, RclYamlError) else 'malformed YAML'
    problem = ' '.join(str(getattr(err, 'problem', None) or err).split())
    if "'\\t'" in problem:
        problem += ' (YAML here takes no tab around a value: use spaces)'
    return f'{what}{where}: {problem}'


def rcl_param_value(text: str) -> Any:
    """
    Return the value of a ``-p name:=value`` override as rcl reads it.

    :param text: the text after ``:=``.
    :return: the value (:func:`~lookahead_control.core.rcl_yaml.param_value`).
    :raises ConfigError: an empty value, a map, or YAML rcl refuses.
    """
    try:
        return param_value(text)
    except yaml.YAMLError as err:
        raise ConfigError(yaml_problem(err)) from err


def node_sections(path: Path | str) -> list[tuple[str, dict[str, Any]]]:
    """
    Return a params file's node sections as rcl reads them, in the file's order.

    Values typed as rcl types them, names as rcl spells them (``/**: {controller:
    {ros__parameters: ...}}`` is ``/**/controller``); sections of one name are one, at
    the place of the first (:func:`~lookahead_control.core.rcl_yaml.params_sections`).
    What rcl refuses is refused, and what it reads otherwise than meant.

    :param path: the params file.
    :return: (node name or pattern, its flat parameters) pairs.
    :raises ConfigError: a missing or unreadable file, malformed YAML, or one rcl
        refuses, naming the file and the line.
    """
    file = Path(path)
    try:
        data = file.read_bytes()
    except OSError as err:
        raise ConfigError(f'{file}: cannot read: {err.strerror or err}') from err
    try:
        return params_sections(data)
    except yaml.YAMLError as err:
        raise ConfigError(f'{file}: {yaml_problem(err)}') from err


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
    return merged_params(node_sections(path), node_name)


def merged_params(sections: Sequence[tuple[str, dict[str, Any]]],
                  node_name: str | None = None) -> dict[str, Any]:
    """
    Merge a params file's sections (:func:`node_sections`) as :func:`load_ros_params`.

    :param sections: the file's sections.
    :param node_name: the node whose sections to merge, or None for wildcards only.
    :return: a mapping of dotted parameter names to values.
    """
    merged: dict[str, Any] = {}
    for key, flat in sections:
        if applies_to(key, node_name) if node_name else str(key) in ('/**', '**'):
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


def check_params_file(path: Path | str, node_name: str, specs: Sequence[Spec],
                      sections: Sequence[tuple[str, dict[str, Any]]] | None = None
                      ) -> dict[str, dict[str, Any]]:
    """
    Check a ROS params file for one node against its schema, as the node would read it.

    Sections for the node (``controller``, ``/controller``, ``/**/controller``) must
    hold only its parameters; wildcard sections (``/**``) serve other nodes too, so
    there only names in the node's namespaces (``vehicle.*`` ...) are checked.

    :param path: the params file.
    :param node_name: the node's name.
    :param specs: the node's parameters.
    :param sections: the file's sections if already read (:func:`node_sections`).
    :return: section -> the section's flat parameters, integers for reals converted.
    :raises ConfigError: ``<file>: <name> = <value> ...``, or a malformed file.
    """
    out: dict[str, dict[str, Any]] = {}
    for pattern, flat in node_sections(path) if sections is None else sections:
        if not applies_to(pattern, node_name):
            continue
        wildcard = '*' in pattern
        try:
            out[pattern] = check_params(flat, specs,
                                        namespaces_of(specs) if wildcard else None)
        except ParameterError as err:
            raise ConfigError(f'{path}: {err}') from err
    return out


def node_file_sections(path: Path | str, node_name: str, specs: Sequence[Spec]
                       ) -> list[tuple[str, dict[str, Any]]]:
    """
    Read and check a params file given for one node, as that node would read it.

    A file none of whose sections applies to the node (``/car_b/controller:`` only, for
    the node ``/controller``) is refused: the node would run on its defaults, and the
    tool that asked for the file would say it ran the file (closed_loop and
    paper_scenario did).

    :param path: the params file.
    :param node_name: the node's name.
    :param specs: the node's parameters (:func:`check_params_file`).
    :return: the file's sections (:func:`node_sections`), all of them.
    :raises ConfigError: a malformed file, a bad value, or no section for the node.
    """
    sections = node_sections(path)
    if not any(applies_to(key, node_name) for key, _ in sections):
        names = ', '.join(str(key) for key, _ in sections) or 'none'
        raise ConfigError(f'{path}: no section applies to the {node_name} node (sections: '
                          f'{names}): its parameters are not in this file; expected '
                          f'{node_name}:, /{node_name}:, /**: or the like')
    check_params_file(path, node_name, specs, sections)
    return sections


def load_vehicle(path: Path | str | None = None) -> VehicleParams:
    """
    Load the vehicle parameters (default: ``config/vehicle.yaml``).

    The file's ``/**`` section, the one every node reads. ``vehicle.*`` in a section of
    one node (``controller:``, ``/**/sim_plant:``) is refused: the car is the plant's
    and the controller's alike (before, it was left out silently and the tools ran the
    default car; dev-probe54).

    :param path: a ROS params file with ``vehicle.*`` entries.
    :return: the vehicle parameters.
    :raises ConfigError: a bad file or value, or ``vehicle.*`` in one node's section.
    """
    file = Path(path) if path else source_config_dir() / 'vehicle.yaml'
    sections = node_sections(file)
    for key, flat in sections:
        names = sorted(name for name in flat if name.startswith('vehicle.'))
        if names and str(key) not in ('/**', '**'):
            raise ConfigError(f'{file}: {", ".join(names)} in section {key!r}, for one node: '
                              'a vehicle file gives the car in /**, which every node reads '
                              '(a controller model other than the car goes in its own '
                              'params file, --controller)')
    return dataclass_from_params(VehicleParams, merged_params(sections), 'vehicle', str(file))


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


def package_controller_params() -> dict[str, Any]:
    """
    Return what the package's own params files give the controller node.

    :return: ``config/vehicle.yaml`` then ``config/controller.yaml``, merged for the node.
    """
    config = source_config_dir()
    merged = load_ros_params(config / 'vehicle.yaml', 'controller')
    merged.update(load_ros_params(config / 'controller.yaml', 'controller'))
    return merged


def law_params_from(params: Mapping[str, Any], source: str
                    ) -> tuple[ControllerParams, LaneKeepingParams, BaselineParams]:
    """
    Build the laws' parameters from a controller node's merged parameters.

    What :func:`load_controller`, :func:`load_lane_keeping` and :func:`load_baselines`
    give for a file, from parameters read once (a ``--controller <(...)`` can be read
    only once: read again, it gave every default; dev-probe55).

    :param params: the node's merged parameters (:func:`merged_params`).
    :param source: where they came from, for messages.
    :return: the paper law's, the CG-compensated law's and the baselines' parameters.
    :raises ConfigError: ``<source>: <name> = <value> ...``.
    """
    return (dataclass_from_params(ControllerParams, params, 'controller', source),
            dataclass_from_params(LaneKeepingParams, params, 'lane_keeping', source),
            BaselineParams(
                dataclass_from_params(PurePursuitParams, params, 'pure_pursuit', source),
                dataclass_from_params(StanleyParams, params, 'stanley', source),
                dataclass_from_params(LqrParams, params, 'lqr', source)))


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


def load_safety(path: Path | str | None = None) -> SafetyParams:
    """
    Load the controller node's limits (default: ``config/controller.yaml``).

    :param path: a ROS params file with ``safety.*`` entries (the rest at their defaults).
    :return: the limits.
    :raises ConfigError: ``<file>: safety.<name> = <value> ...``.
    """
    file = Path(path) if path else source_config_dir() / 'controller.yaml'
    return dataclass_from_params(SafetyParams, load_ros_params(file, 'controller'), 'safety',
                                 str(file))


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
