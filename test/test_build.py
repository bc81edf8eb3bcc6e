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

"""colcon builds the package; ament finds every executable where `ros2 run` looks."""

import os
from pathlib import Path
import shutil
import subprocess
import sys

from conftest import entry_points
import pytest

ROOT = Path(__file__).resolve().parent.parent
pytestmark = pytest.mark.build


@pytest.fixture(scope='module')
def colcon_install(tmp_path_factory):
    ws = tmp_path_factory.mktemp('ws')
    src = ws / 'src' / 'lookahead_control'
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(
        '.venv', '.git', 'build', 'install', 'log', 'bags', '__pycache__', '*.egg-info',
        '.pytest_cache', '.mypy_cache', '.hypothesis'))
    colcon = Path(sys.executable).parent / 'colcon'
    env = dict(os.environ, COLCON_HOME=str(ws / '.colcon'))
    result = subprocess.run(
        [str(colcon), 'build', '--base-paths', 'src', '--event-handlers',
         'console_direct-'], cwd=ws, env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    return ws / 'install'


def test_colcon_build_and_ament_lookup(colcon_install):
    prefix_path = str(colcon_install / 'lookahead_control')
    code = (
        'import os, sys\n'
        'from ament_index_python.packages import get_package_prefix, '
        'get_package_share_directory\n'
        'prefix = get_package_prefix("lookahead_control")\n'
        'share = get_package_share_directory("lookahead_control")\n'
        'lib = os.path.join(prefix, "lib", "lookahead_control")\n'
        'for exe in sys.argv[1:]:\n'
        '    path = os.path.join(lib, exe)\n'
        '    assert os.path.isfile(path) and os.access(path, os.X_OK), path\n'
        'assert os.path.isfile(os.path.join(share, "package.xml"))\n'
        'assert os.path.isfile(os.path.join(share, "config", "vehicle.yaml"))\n'
        'assert os.path.isfile(os.path.join(share, "config", "scenarios", '
        '"paper_r400.yaml"))\n'
        'print(prefix)\n')
    env = dict(os.environ, AMENT_PREFIX_PATH=prefix_path)
    result = subprocess.run([sys.executable, '-c', code, *entry_points()], env=env,
                            capture_output=True, text=True, cwd='/')
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == prefix_path


def test_installed_executable_runs(colcon_install):
    prefix = colcon_install / 'lookahead_control'
    site = next(prefix.glob('lib/python3*/site-packages'))
    env = dict(os.environ, AMENT_PREFIX_PATH=str(prefix),
               PYTHONPATH=f'{site}{os.pathsep}{os.environ.get("PYTHONPATH", "")}')
    exe = prefix / 'lib' / 'lookahead_control' / 'schedule'
    result = subprocess.run([sys.executable, str(exe), '--v-min', '20', '--v-max', '20'],
                            env=env, capture_output=True, text=True, cwd='/')
    assert result.returncode == 0, result.stderr
    assert '10.61' in result.stdout
