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

"""Parameters, config files, and the promise that the core imports no ROS."""

from pathlib import Path
import subprocess
import sys

from lookahead_control.core.config import ConfigError, load_controller, load_vehicle
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
import pytest
from sim_plant.scenario import load_scenario
from sim_plant.vehicle_model import PlantParams

ROOT = Path(__file__).resolve().parent.parent
CORE_MODULES = ['lookahead_control.core.params', 'lookahead_control.core.config',
                'lookahead_control.core.schedule', 'lookahead_control.core.control_law',
                'lookahead_control.core.zero_dynamics', 'lookahead_control.core.stability',
                'lookahead_control.analysis.metrics', 'lookahead_control.analysis.paper_tables',
                'sim_plant.vehicle_model', 'sim_plant.road', 'sim_plant.scenario',
                'sim_plant.closed_loop_sim', 'lookahead_control.tools.paper_scenario']


def test_core_imports_no_ros_and_no_matplotlib():
    code = ('import sys\n' + ''.join(f'import {m}\n' for m in CORE_MODULES)
            + 'bad = [m for m in sys.modules if m.split(".")[0] in '
            '("rclpy", "matplotlib")]\nassert not bad, bad\n')
    result = subprocess.run([sys.executable, '-c', code], cwd=ROOT, capture_output=True,
                            text=True)
    assert result.returncode == 0, result.stderr


def test_default_config_is_table_1():
    vehicle = load_vehicle()
    assert vehicle == VehicleParams(mass=1485.0, yaw_inertia=2872.0, l1=1.1, l2=1.58,
                                    c_f=80000.0, c_r=80000.0, d_s=1.96)
    controller = load_controller()
    assert controller.schedule == 'paper'
    assert controller.k_p == pytest.approx(controller.natural_frequency ** 2)
    assert controller.k_d == pytest.approx(2 * controller.damping_ratio
                                           * controller.natural_frequency)


@pytest.mark.parametrize('field,value', [
    ('mass', 0.0), ('mass', -1485.0), ('yaw_inertia', -1.0), ('l1', 0.0), ('l2', -1.58),
    ('c_f', 0.0), ('c_r', -80000.0), ('d_s', float('nan')), ('mass', float('inf')),
    ('l1', 'long'),
])
def test_bad_vehicle_parameters_are_rejected_by_name(field, value):
    with pytest.raises(ParameterError) as info:
        VehicleParams(**{field: value})
    message = str(info.value)
    assert f'vehicle.{field}' in message
    assert repr(value) in message


@pytest.mark.parametrize('kwargs,name', [
    ({'natural_frequency': 0.0}, 'controller.natural_frequency'),
    ({'damping_ratio': -0.5}, 'controller.damping_ratio'),
    ({'schedule': 'magic'}, 'controller.schedule'),
    ({'reference': 'centre'}, 'controller.reference'),
    ({'min_speed': 0.0}, 'controller.min_speed'),
])
def test_bad_controller_parameters_are_rejected_by_name(kwargs, name):
    with pytest.raises(ParameterError, match=name.replace('.', r'\.')):
        ControllerParams(**kwargs)


def test_plant_parameters_are_checked():
    with pytest.raises(ParameterError, match='plant.friction'):
        PlantParams(friction=0.0)
    with pytest.raises(ParameterError, match='plant.model'):
        PlantParams(model='unicycle')


def test_config_errors_name_file_and_problem(tmp_path):
    bad_yaml = tmp_path / 'bad.yaml'
    bad_yaml.write_text('/**:\n  ros__parameters:\n    vehicle: [1, 2\n')
    with pytest.raises(ConfigError, match=r'bad\.yaml: malformed YAML'):
        load_vehicle(bad_yaml)
    with pytest.raises(ConfigError, match=r'missing\.yaml: cannot read'):
        load_vehicle(tmp_path / 'missing.yaml')
    typo = tmp_path / 'typo.yaml'
    typo.write_text('/**:\n  ros__parameters:\n    vehicle:\n      mas: 1500.0\n')
    with pytest.raises(ConfigError, match="unknown parameter 'vehicle.mas'"):
        load_vehicle(typo)
    negative = tmp_path / 'neg.yaml'
    negative.write_text('/**:\n  ros__parameters:\n    vehicle:\n      mass: -3.0\n')
    with pytest.raises(ConfigError, match=r'neg\.yaml: vehicle\.mass = -3\.0'):
        load_vehicle(negative)


def test_node_section_overrides_wildcard(tmp_path):
    path = tmp_path / 'c.yaml'
    path.write_text('/**:\n  ros__parameters:\n    controller:\n      schedule: exact\n'
                    'controller:\n  ros__parameters:\n    controller:\n'
                    '      schedule: fixed\n')
    assert load_controller(path).schedule == 'fixed'


@pytest.mark.parametrize('key, applies', [
    ('/**', True), ('**', True), ('/*', True), ('controller', True), ('/controller', True),
    ('/**/controller', True), ('/*/controller', False), ('/ns/controller', False),
    ('/**/sim_plant', False), ('controllers', False), ('contr_ller', False),
])
def test_a_section_applies_to_the_node_as_rclpy_matches_it(key, applies, tmp_path):
    # rclpy: '/' prepended, '/*' -> '(/\\w+)', '/**' -> '(/\\w+)*', the whole name matched;
    # the sections in the file's order, a later one's value replacing an earlier one's.
    # Before, only /**, controller and /controller were read, the node's own last. (A
    # name rcl refuses, 'contr.ller', makes rcl refuse the file: test_params_yaml)
    path = tmp_path / 'c.yaml'
    path.write_text('/**:\n  ros__parameters:\n    controller:\n      schedule: exact\n'
                    f'{key!r}:\n  ros__parameters:\n    controller:\n'
                    '      schedule: fixed\n')
    assert load_controller(path).schedule == ('fixed' if applies else 'exact')
    if key != '/**':
        path.write_text(f'{key!r}:\n  ros__parameters:\n    controller:\n'
                        '      schedule: fixed\n'
                        '/**:\n  ros__parameters:\n    controller:\n      schedule: exact\n')
        assert load_controller(path).schedule == 'exact'


def test_scenario_files_load():
    for path in sorted((ROOT / 'config' / 'scenarios').glob('*.yaml')):
        scenario = load_scenario(path)
        assert scenario.duration > 0
    paper = load_scenario(ROOT / 'config' / 'scenarios' / 'paper_r400.yaml', speed=20.0)
    assert paper.road.segments[0].length == pytest.approx(40.0)   # 2 s at 20 m/s
    assert paper.road.curvature(41.0)[0] == pytest.approx(-1.0 / 400.0)


def test_bad_scenario_names_the_problem(tmp_path):
    path = tmp_path / 's.yaml'
    path.write_text('scenario:\n  speed: {initial: 20.0}\n  road:\n'
                    '    - {type: arc, length: 10.0}\n')
    with pytest.raises(ConfigError, match='an arc needs curvature'):
        load_scenario(path)
    path.write_text('scenario:\n  speed: {initial: 20.0, acceleration: 9.0}\n  road:\n'
                    '    - {type: straight, length: 10.0}\n')
    with pytest.raises(ConfigError, match='speed.acceleration = 9.0'):
        load_scenario(path)


def test_a_key_written_twice_in_a_scenario_is_refused_with_both_lines(tmp_path):
    # before: PyYAML kept the later value without a word: a second 'speed:' ran the
    # scenario at it, a second 'external_forces:' list dropped the first one's forces
    # and a second 'force:' in one entry took the later force
    crosswind = (ROOT / 'config' / 'scenarios' / 'crosswind.yaml').read_text()
    path = tmp_path / 's.yaml'
    for text, key, lines in [
            (crosswind.replace('  speed: {initial: 37.0}\n',
                               '  speed: {initial: 37.0, initial: 20.0}\n'), 'initial', (8, 8)),
            (crosswind + '  external_forces: []\n', 'external_forces', None),
            ('scenario:\n  duration: 5.0\n  speed: {initial: 20.0}\n  road:\n'
             '    - {type: straight, length: 200.0}\n  external_forces:\n'
             '    - {start: 1.0, duration: 1.0, force: 100.0, force: 1500.0}\n',
             'force', (7, 7))]:
        path.write_text(text)
        with pytest.raises(ConfigError, match=f"'{key}' written twice in one map") as err:
            load_scenario(path)
        if lines is not None:
            assert f'(line {lines[1]}): ' in str(err.value)
            assert f'(first on line {lines[0]}, column ' in str(err.value)
    # a merge's keys are overridden by the map's own, as YAML means
    path.write_text('scenario:\n  duration: 5.0\n  speed: {initial: 20.0}\n  road:\n'
                    '    - {type: straight, length: 200.0}\n  external_forces:\n'
                    '    - &gust {start: 1.0, duration: 0.5, force: 100.0}\n'
                    '    - {<<: *gust, start: 3.0, force: 1500.0}\n')
    forces = load_scenario(path).forces
    assert [(f.start, f.force) for f in forces] == [(1.0, 100.0), (3.0, 1500.0)]
    # dev-probe82: a map merged into another and used again through its alias was read
    # with the keys the merge had written into it: refused as 'force written twice'
    head = ('scenario:\n  duration: 5.0\n  speed: {initial: 20.0}\n  road:\n'
            '    - {type: straight, length: 200.0}\n  external_forces:\n')
    path.write_text(head + '    - {<<: &strong {<<: {start: 1.0, duration: 0.5, force: '
                    '100.0}, force: 1500.0, start: 2.0}, start: 4.0}\n    - *strong\n')
    forces = load_scenario(path).forces
    assert [(f.start, f.duration, f.force) for f in forces] == [(4.0, 0.5, 1500.0),
                                                                (2.0, 0.5, 1500.0)]
    # and two merges in one map: PyYAML kept the later one without a word
    path.write_text(head + '    - &g {start: 1.0, duration: 0.5, force: 100.0}\n'
                    '    - &h {start: 2.0, duration: 0.5, moment: 200.0}\n'
                    '    - {<<: *g, <<: *h, start: 3.0}\n')
    with pytest.raises(ConfigError, match=r"line 9\): '<<' written twice in one map \(first "
                       r'on line 9, column 8\): merge several maps with <<: \[\*a, \*b\]'):
        load_scenario(path)
    path.write_text(head + '    - &g {start: 1.0, duration: 0.5, force: 100.0}\n'
                    '    - &h {start: 2.0, duration: 0.5, moment: 200.0}\n'
                    '    - {<<: [*g, *h], start: 3.0}\n')
    last = load_scenario(path).forces[-1]
    assert (last.start, last.force, last.moment) == (3.0, 100.0, 200.0)
    # dev-probe83: a key written again through an alias of the first is the same node:
    # the check by node identity took the later value
    path.write_text(head.replace('  duration: 5.0\n', '  &d duration: 5.0\n')
                    + '    - {start: 1.0, duration: 0.5, force: 100.0}\n  *d : 12.0\n')
    with pytest.raises(ConfigError, match="'duration' written twice in one map"):
        load_scenario(path)
    # ... and YAML's '=' key, and a quoted '<<' (a string, not a merge), are keys as any
    from lookahead_control.core.config import read_yaml
    path.write_text('a: {=: 1}\nb: &b {x: 1}\nc: {<<: *b, "<<": 2}\n')
    assert read_yaml(path) == {'a': {'=': 1}, 'b': {'x': 1}, 'c': {'x': 1, '<<': 2}}
