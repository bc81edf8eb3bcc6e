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

"""Static checks that keep this a real ROS 2 package (as ament_lint does them)."""

from pathlib import Path
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parent.parent
SOURCES = ['lookahead_control', 'sim_plant', 'test', 'bench', 'setup.py', 'launch']
HEADER = ('# Copyright 2026 The lookahead_control Authors', '#',
          '# Licensed under the Apache License, Version 2.0 (the "License");')

pytestmark = pytest.mark.lint


def _python_files() -> list:
    files = []
    for name in SOURCES:
        path = ROOT / name
        files += sorted(path.rglob('*.py')) if path.is_dir() else [path]
    return [f for f in files if f.exists()]


def test_flake8():
    # in a fresh process: flake8 forks workers, and a fork of this process (which has
    # run DDS threads in earlier tests) can deadlock on a lock a thread held
    code = ('import sys\nfrom ament_flake8.main import main_with_errors\n'
            'rc, errors = main_with_errors(argv=sys.argv[1:])\n'
            'print("\\n".join(errors), file=sys.stderr)\nsys.exit(rc)')
    result = subprocess.run([sys.executable, '-c', code,
                             *[str(ROOT / s) for s in SOURCES if (ROOT / s).exists()]],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, 'flake8 found errors:\n' + result.stderr[-5000:]


def test_pep257():
    from ament_pep257.main import main
    rc = main(argv=[str(ROOT / s) for s in SOURCES if (ROOT / s).exists()])
    assert rc == 0, 'pep257 found errors (see output above)'


def test_license_headers():
    missing = [str(f.relative_to(ROOT)) for f in _python_files()
               if tuple(f.read_text(encoding='utf-8').split('\n')[:3]) != HEADER]
    assert not missing, f'files without the Apache-2.0 header: {missing}'
    assert 'Apache License' in (ROOT / 'LICENSE').read_text(encoding='utf-8')


def test_mypy():
    result = subprocess.run(
        [sys.executable, '-m', 'mypy', '--config-file', str(ROOT / 'mypy.ini'),
         'lookahead_control', 'sim_plant'], cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr


def test_package_xml_parses():
    from catkin_pkg.package import parse_package
    package = parse_package(str(ROOT / 'package.xml'))
    package.validate()
    assert package.name == 'lookahead_control'
    assert package.package_format == 3
    assert package.get_build_type() == 'ament_python'
    assert package.maintainers and '@' in package.maintainers[0].email
    assert package.licenses == ['Apache-2.0']
    depends = {d.name for d in package.exec_depends}
    assert {'rclpy', 'std_msgs', 'geometry_msgs', 'nav_msgs'} <= depends
