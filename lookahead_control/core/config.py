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
from typing import Any, Mapping, Type, TypeVar

from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
import yaml


PACKAGE_NAME = 'lookahead_control'
D = TypeVar('D')


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
    file = Path(path)
    try:
        text = file.read_text(encoding='utf-8')
    except OSError as err:
        raise ConfigError(f'{file}: cannot read: {err.strerror or err}') from err
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as err:
        mark = getattr(err, 'problem_mark', None)
        where = f' (line {mark.line + 1})' if mark is not None else ''
        raise ConfigError(f'{file}: malformed YAML{where}: '
                          f'{getattr(err, "problem", None) or err}') from err


def _flatten(prefix: str, tree: Mapping[str, Any], out: dict[str, Any]) -> None:
    for key, value in tree.items():
        name = f'{prefix}.{key}' if prefix else str(key)
        if isinstance(value, Mapping):
            _flatten(name, value, out)
        else:
            out[name] = value


def load_ros_params(path: Path | str, node_name: str | None = None) -> dict[str, Any]:
    """
    Read the flattened parameters of a ROS 2 params YAML file.

    Sections for ``/**`` apply to every node; a section named after ``node_name``
    (with or without a leading slash) overrides them, as in ROS.

    :param path: the params file.
    :param node_name: the node whose section to merge, or None for wildcards only.
    :return: a mapping of dotted parameter names to values.
    """
    document = read_yaml(path)
    if not isinstance(document, Mapping):
        raise ConfigError(f'{path}: expected a mapping of node names to '
                          f'ros__parameters, got {type(document).__name__}')
    merged: dict[str, Any] = {}
    wanted = ['/**', '**']
    if node_name:
        wanted += [node_name, '/' + node_name.lstrip('/')]
    for key in wanted:
        section = document.get(key)
        if section is None:
            continue
        if not isinstance(section, Mapping) or not isinstance(
                section.get('ros__parameters'), Mapping):
            raise ConfigError(f'{path}: section {key!r} has no ros__parameters mapping')
        _flatten('', section['ros__parameters'], merged)
    return merged


def dataclass_from_params(cls: Type[D], params: Mapping[str, Any], prefix: str,
                          source: str = 'parameters') -> D:
    """
    Build a parameter dataclass from flattened ``prefix.field`` entries.

    Missing fields keep their defaults; unknown ``prefix.*`` names are an error, so a
    typo in a config file is not silently ignored.

    :param cls: the dataclass type.
    :param params: flattened parameters.
    :param prefix: the namespace of the dataclass fields, e.g. ``vehicle``.
    :param source: where the parameters came from, for messages.
    :return: the validated dataclass.
    """
    names = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    values: dict[str, Any] = {}
    for key, value in params.items():
        head, _, field = key.partition('.')
        if head != prefix:
            continue
        if field not in names:
            raise ConfigError(f'{source}: unknown parameter {key!r}; known: '
                              f'{", ".join(sorted(prefix + "." + n for n in names))}')
        values[field] = value
    try:
        return cls(**values)
    except ParameterError as err:
        raise ConfigError(f'{source}: {err}') from err


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
