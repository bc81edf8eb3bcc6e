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
Imports only go down the layers.

Each layer's modules are imported in a fresh interpreter in which everything above it is
made unimportable (for the core and the plant models also rclpy, rosbags and every ROS
message package); an import that crosses is reported with the file and line that made it.
"""

from __future__ import annotations

from pathlib import Path
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / 'lookahead_control'

ROS = ['rclpy', 'rosbags', 'mcap', 'rosidl_*', 'rpyutils', 'rmw*', '*_msgs', '*_interfaces',
       'launch*', 'ament_*']
ABOVE = {
    'core': ['lookahead_control.ros', 'lookahead_control.bags', 'lookahead_control.analysis',
             'lookahead_control.tools', 'sim_plant'] + ROS,
    'sim_plant': ['sim_plant.sim_plant_node', 'lookahead_control.ros', 'lookahead_control.bags',
                  'lookahead_control.analysis', 'lookahead_control.tools'] + ROS,
    'ros': ['lookahead_control.bags', 'lookahead_control.analysis', 'lookahead_control.tools'],
    'bags': ['lookahead_control.analysis', 'lookahead_control.tools'],
    'analysis': ['lookahead_control.tools'],
}

CHECKER = r"""
import fnmatch, importlib, importlib.abc, sys, traceback

blocked = sys.argv[1].split(',')
modules = sys.argv[2].split(',')


class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if any(fnmatch.fnmatchcase(name, p) or name.startswith(p + '.') for p in blocked):
            where = '?'
            for frame in reversed(traceback.extract_stack()[:-1]):
                if '<frozen' not in frame.filename and 'importlib' not in frame.filename:
                    where = f'{frame.filename}:{frame.lineno}'
                    break
            raise ImportError(f'layer violation: {name} imported at {where}')
        return None


sys.meta_path.insert(0, Block())
for module in modules:
    try:
        importlib.import_module(module)
    except ImportError as err:
        print(f'{module}: {err}')
        sys.exit(1)
"""


def layer_modules(layer: str) -> list[str]:
    """
    Return the importable modules of one layer.

    :param layer: a key of ``ABOVE``.
    :return: dotted module names.
    """
    if layer == 'sim_plant':
        return [f'sim_plant.{p.stem}' for p in sorted((ROOT / 'sim_plant').glob('*.py'))
                if p.stem not in ('__init__', 'sim_plant_node')] + ['sim_plant']
    return [f'lookahead_control.{layer}.{p.stem}' if p.stem != '__init__'
            else f'lookahead_control.{layer}'
            for p in sorted((PKG / layer).glob('*.py'))]


def check(blocked: list[str], modules: list[str]) -> subprocess.CompletedProcess[str]:
    """
    Import ``modules`` in a fresh interpreter where ``blocked`` cannot be imported.

    :param blocked: module names or fnmatch patterns (a package blocks its submodules).
    :param modules: the modules to import.
    :return: the finished process (stdout names the first violation).
    """
    return subprocess.run([sys.executable, '-c', CHECKER, ','.join(blocked), ','.join(modules)],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize('layer', sorted(ABOVE))
def test_imports_only_go_down(layer: str) -> None:
    modules = layer_modules(layer)
    assert len(modules) >= 2, f'no modules found for layer {layer}'
    result = check(ABOVE[layer], modules)
    assert result.returncode == 0, result.stdout + result.stderr


def test_every_module_belongs_to_a_layer() -> None:
    layers = set(ABOVE) - {'sim_plant'} | {'tools'}
    for path in PKG.rglob('*.py'):
        rel = path.relative_to(PKG).parts
        assert len(rel) == 1 and rel[0] == '__init__.py' or rel[0] in layers, (
            f'{path.relative_to(ROOT)} is in no layer: move it into one of {sorted(layers)}')


def test_checker_names_a_crossing_import() -> None:
    # The ros layer's conversions import ROS messages; with ROS blocked that is a
    # violation the checker must report with the importing file.
    result = check(ROS, ['lookahead_control.ros.conversions'])
    assert result.returncode == 1
    assert 'layer violation' in result.stdout
    assert 'conversions.py' in result.stdout
