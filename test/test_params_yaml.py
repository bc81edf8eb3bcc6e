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
Params files and ``-p`` values read as rcl reads them, checked against rcl itself.

Until dev-rclyaml the checks read params files with PyYAML (YAML 1.1): a
``integral_gain: 3e-1`` rcl takes as 0.3 was refused ("expected a number"), a
``frame_id: y`` rcl takes as a bool passed the check and the node then failed in rcl,
and a file with aliases or merge keys passed the check and rcl refused the file.
"""

from __future__ import annotations

import math
from pathlib import Path
import random
import re
import signal
import subprocess
import sys

from lookahead_control.core.config import (ConfigError, node_sections, rcl_param_value,
                                           source_config_dir)
from lookahead_control.core.rcl_yaml import compose, rcl_scalar
import pytest
import yaml

# what rcl (Jazzy's rcl_yaml_param_parser) made of these unquoted scalars, read with
# rclpy from a params file; the test below asks rcl again
RCL_READS = {
    '3e-1': 0.3, '2e-3': 0.002, '1e5': 1e5, '-1e+5': -1e5, '1.5e3': 1500.0, '1.': 1.0,
    '.5': 0.5, 'inf': math.inf, 'infinity': math.inf, '.inf': math.inf, '+.inf': math.inf,
    '-.inf': -math.inf, '.Inf': math.inf, '0x1p3': 8.0, '08': 8.0,
    '99999999999999999999': 1e20,
    'y': True, 'Y': True, 'yes': True, 'on': True, 'True': True, 'n': False, 'N': False,
    'no': False, 'off': False, 'FALSE': False,
    '017': 15, '0x10': 16, '-0x10': -16, '+5': 5, '-0': 0, '00': 0, '1485': 1485,
    '1_000': '1_000', '0b101': '0b101', '0o10': '0o10', '-.nan': '-.nan', '1e400': '1e400',
    '1e-400': '1e-400', '1e-310': '1e-310', '1:20': '1:20', '2001-12-14': '2001-12-14',
    'null': 'null', '~': '~', '0x': '0x', '1e': '1e', 'yes!': 'yes!', 'base_link': 'base_link',
    # dev-probe51: strtod's tininess is of the exact value (the first rounds to the
    # smallest normal double, and glibc says ERANGE); an exact subnormal is no error;
    # a hex float past the largest double overflowed float.fromhex (a traceback);
    # re.IGNORECASE took the Unicode dotless i and long s
    '2.2250738585072012e-308': '2.2250738585072012e-308', '0x1p-1074': 5e-324,
    '0x1p1024': '0x1p1024', '0x1.fffffffffffff8p1023': '0x1.fffffffffffff8p1023',
    '0x1.8': 1.5, '0xFFFFFFFFFFFFFFFFFF': float(0xFFFFFFFFFFFFFFFFFF),
    '\u0131nf': '\u0131nf', 'na\u017f': 'na\u017f',
    # dev-probe53: glibc judges tininess after rounding (these round to the smallest
    # normal double and are no range error)
    '2.2250738585072013e-308': 2.2250738585072014e-308,
    '0x1.fffffffffffff8p-1023': 2.2250738585072014e-308,
}
NAN_TEXTS = ('nan', '.nan', '.NaN', 'NAN', 'nan(12)')


def _same(a, b):
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return type(a) is type(b) and a == b


def _rcl_read(args, name='n'):
    """Return what rclpy declares for node ``name`` from ROS arguments (name -> value)."""
    import rclpy
    from rclpy.context import Context
    ctx = Context()
    rclpy.init(args=['--ros-args', *args], context=ctx)
    try:
        # no parameter services and no rosout publisher: the overrides are all it reads
        # (dev-sc56: one suite run hung in destroy_node for 20 min at 100 % CPU, a node
        # with its services; fewer DDS entities to tear down)
        node = rclpy.create_node(name, context=ctx, start_parameter_services=False,
                                 enable_rosout=False,
                                 automatically_declare_parameters_from_overrides=True)
        try:
            return {key: param.value for key, param in node._parameters.items()}
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)


def _rcl_parameters(tmp_path, text):
    """Return what rclpy declares from a params file for node ``n`` (name -> value)."""
    path = tmp_path / f'rcl_{random.getrandbits(32)}.yaml'
    path.write_text(text)
    return _rcl_read(['--params-file', str(path)])


def _rcl_refuses(tmp_path, text):
    import rclpy
    from rclpy.context import Context
    path = tmp_path / f'rcl_{random.getrandbits(32)}.yaml'
    path.write_text(text)
    ctx = Context()
    try:
        rclpy.init(args=['--ros-args', '--params-file', str(path)], context=ctx)
    except Exception as err:     # rclpy's RCLError
        return 'params file' in str(err)
    rclpy.try_shutdown(context=ctx)
    return False


def test_scalars_are_typed_as_rcl_types_them():
    for text, value in RCL_READS.items():
        assert _same(rcl_scalar(text), value), (text, rcl_scalar(text), value)
    for text in NAN_TEXTS:
        assert math.isnan(rcl_scalar(text)), text


def _random_scalars(count, seed):
    rng = random.Random(seed)
    alphabet = '0123456789.eE+-xXpPinfatyYnN_o'
    out = set()
    while len(out) < count:
        text = ''.join(rng.choice(alphabet) for _ in range(rng.randint(1, 6)))
        try:
            node = yaml.compose(f'p: {text}')
        except yaml.YAMLError:
            continue
        value = node.value[0][1]
        if isinstance(value, yaml.ScalarNode) and value.style is None and value.value == text:
            out.add(text)
    return sorted(out)


def test_a_params_file_reads_as_rcl_reads_it(tmp_path):
    # every fixed case and 400 random ones in one file, asked of rcl itself; quoted
    # scalars stay strings, tags are ignored, lists keep one type
    texts = [*RCL_READS, *NAN_TEXTS, *_random_scalars(400, 7)]
    body = ''.join(f'    p{i}: {text}\n' for i, text in enumerate(texts))
    extra = ("    q0: '3e-1'\n    q1: \"y\"\n    q2: !!float 1\n    q3: [y, true]\n"
             '    q4: [1, 0x10]\n    q5: [08, 1.5]\n    q6: {a: 2e-3}\n    q7: |\n      12\n'
             '    q8: {a: 1, b: {c: 2}}\n    q8: {b: {d: 3}, e: 4}\n')
    text = 'n:\n  ros__parameters:\n' + body + extra
    rcl = _rcl_parameters(tmp_path, text)
    ours = dict(node_sections(tmp_path / _write(tmp_path, text)))['n']
    assert set(ours) == set(rcl) - {'use_sim_time', 'start_type_description_service'}
    wrong = {name: (ours[name], rcl[name]) for name in ours if not _same(ours[name], rcl[name])
             and not (isinstance(ours[name], list) and all(
                 _same(a, b) for a, b in zip(ours[name], rcl[name])))}
    assert wrong == {}
    assert ours['q0'] == '3e-1' and ours['q2'] == 1 and ours['q6.a'] == 0.002
    # a map opened twice: one map (before, PyYAML kept only the later one)
    assert {k: v for k, v in ours.items() if k.startswith('q8')} == {
        'q8.a': 1, 'q8.b.c': 2, 'q8.b.d': 3, 'q8.e': 4}


SECTION_NAMES = [
    'controller', '/controller', '/**', '/*', '/**/controller', '/*/controller', '**',
    '*', '*/c', '**/c', '/ns/**', '/ns/*', '/*/*/c', '/**/**/c', '/a/*/b/c', 'ns/controller',
    '/ns/**/controller', '_c', 'c__d', '/ns1/c', 'A', '/contr*', '/ns*/c', '/***/c', '***',
    '/**/c*', '1controller', '/1ns/c', 'a-b', 'c.d', 'contr oller', '//c', '/ns//c', '/ns/',
    '/ns/c/', '/', '~/c', '/ns/~c', '\u00f6']


def test_section_names_are_taken_and_refused_as_rcl_does(tmp_path):
    # before: a section rcl refuses ('/contr*', '//c') was skipped by the checks, so
    # the file passed them and the node then failed in rcl
    verdicts = {}
    for name in SECTION_NAMES:
        text = f"'{name}':\n  ros__parameters:\n    a: 1\n"
        path = tmp_path / _write(tmp_path, text)
        try:
            node_sections(path)
            ours = True
        except ConfigError as err:
            assert 'rcl refuses the file' in str(err) and repr(name) in str(err), err
            ours = False
        verdicts[name] = (ours, not _rcl_refuses(tmp_path, text))
    assert {name: v for name, v in verdicts.items() if v[0] != v[1]} == {}
    assert sum(ours for ours, _ in verdicts.values()) == 21


def _write(tmp_path, text):
    path = tmp_path / f'ours_{random.getrandbits(32)}.yaml'
    path.write_text(text)
    return path.name


@pytest.mark.parametrize('text, match', [
    ('n:\n  ros__parameters:\n    a: &x 1.0\n    b: *x\n', r'alias \(\*x\)'),
    ('base: &base\n  ros__parameters: {a: 1.0}\nn:\n  <<: *base\n', r'alias \(\*base\)'),
    ('n:\n  ros__parameters:\n    a: [1, 2.5]\n', r'mixed types \(float, int\)'),
    ("n:\n  ros__parameters:\n    a: [y, 'y']\n", r'mixed types \(bool, str\)'),
    ('n:\n  ros__parameters:\n    a: [[1], [2]]\n', 'a list or a map inside a list'),
])
def test_what_rcl_refuses_is_refused_with_the_line(tmp_path, text, match):
    # before: PyYAML read these files and the check passed them; rcl then refused them
    assert _rcl_refuses(tmp_path, text)
    path = tmp_path / _write(tmp_path, text)
    with pytest.raises(ConfigError, match=f'not readable by rcl \\(line \\d\\): .*{match}'):
        node_sections(path)


def test_a_list_inside_a_list_is_refused(tmp_path):
    # with one item rcl takes it and flattens it ([[1]] is [1]): a mistake, refused
    text = 'n:\n  ros__parameters:\n    a: [[1]]\n'
    assert _rcl_parameters(tmp_path, text)['a'] == [1]
    with pytest.raises(ConfigError, match=r'line 3\): a list or a map inside a list'):
        node_sections(tmp_path / _write(tmp_path, text))


def test_a_command_line_value_reads_as_rcl_reads_it():
    assert rcl_param_value('3e-1') == 0.3 and rcl_param_value('y') is True
    assert rcl_param_value("'y'") == 'y' and rcl_param_value('1_000') == '1_000'
    assert rcl_param_value('[1, 2]') == [1, 2]
    for bad in ('', 'a: 1', '[1, 2.5]'):
        with pytest.raises(ConfigError):
            rcl_param_value(bad)
    assert compose('') is None


def test_the_node_takes_a_value_rcl_takes_and_refuses_one_rcl_types_otherwise(tmp_path):
    # before: 'integral_gain: 3e-1' was refused ("expected a number") and 'frame_id: y'
    # passed the check, then rcl read a bool and the node failed on its declaration
    from lookahead_control.ros.controller_node import ALL_SPECS
    from lookahead_control.ros.node_main import checked_arguments
    good = tmp_path / 'good.yaml'
    good.write_text('controller:\n  ros__parameters:\n    lane_keeping:\n'
                    '      integral_gain: 3e-1\n    vehicle:\n      mass: 1.5e3\n')
    assert checked_arguments(['--ros-args', '--params-file', str(good)], 'controller',
                             ALL_SPECS, []) == [
        '--ros-args', '--params-file', str(good)]
    bad = tmp_path / 'bad.yaml'
    bad.write_text('controller:\n  ros__parameters:\n    frame_id: y\n')
    with pytest.raises(ConfigError, match='frame_id = True'):
        checked_arguments(['--ros-args', '--params-file', str(bad)], 'controller', ALL_SPECS, [])
    three = ['--ros-args', '-p', 'lane_keeping.integral_gain:=3e-1']
    assert checked_arguments(three, 'controller', ALL_SPECS, []) == three
    with pytest.raises(ConfigError, match='-p frame_id:=: .*empty string'):
        checked_arguments(['--ros-args', '-p', 'frame_id:='], 'controller', ALL_SPECS, [])


def test_a_converted_copy_keeps_what_rcl_read(tmp_path):
    # an integer for a real makes the node pass rcl a converted copy: the values rcl
    # reads from it are those it read from the file (a 3e-1 stays 0.3, not '3e-1')
    from test_compliance_seed import _copy_reads
    mine = tmp_path / 'car.yaml'
    mine.write_text('controller:\n  ros__parameters:\n    vehicle:\n      mass: 1500\n'
                    '    lane_keeping:\n      integral_gain: 3e-1\n'
                    "      compliance_memory_seed: 1.2e0\n    frame_id: '1e5'\n")
    read = _copy_reads(mine)
    assert read['vehicle.mass'] == 1500.0 and read['lane_keeping.integral_gain'] == 0.3
    assert read['lane_keeping.compliance_memory_seed'] == 1.2 and read['frame_id'] == '1e5'


def test_closed_loop_and_replay_take_values_as_rcl_does(tmp_path):
    from lookahead_control.ros import closed_loop
    car = tmp_path / 'car.yaml'
    car.write_text('controller:\n  ros__parameters:\n    lane_keeping:\n'
                   '      integral_gain: 2.5e-1\n')
    params, _ = closed_loop.controller_settings(
        car, ['lane_keeping.compliance_memory_seed:=1.2e0'], 'cg_compensated', 'paper')
    assert params['lane_keeping.integral_gain'] == 0.25
    assert params['lane_keeping.compliance_memory_seed'] == 1.2


REMAPS = (['-r', '__ns:=/car_b'], ['-r', '__ns:=/car_b', '-r', '__node:=truck'],
          ['--remap', 'controller:__ns:=/car_b'], ['-r', 'other:__ns:=/car_b'], [],
          # dev-probe53: the first rule wins; a node's rule names the renamed node
          ['-r', '__ns:=/car_b', '-r', '__ns:=/car_a'],
          ['-r', 'controller:__ns:=/car_b', '-r', '__ns:=/car_a'],
          ['-r', '__node:=truck', '-r', 'controller:__ns:=/car_b'],
          ['-r', '__node:=truck', '-r', 'truck:__ns:=/car_b'],
          ['-r', '__node:=truck', '-r', 'controller:__node:=bus', '-r', '__ns:=/car_b'])


@pytest.mark.parametrize('key', ['/car_b/controller', 'car_b/controller', '/**', '/*',
                                 '/**/controller', 'controller', '/car_b/*', '/*/controller',
                                 '/car_b/truck'])
def test_a_renamed_or_namespaced_node_reads_its_own_sections(tmp_path, key):
    # before: the checks matched sections against '/controller' whatever the remapping,
    # so under -r __ns:=/car_b the section '/car_b/controller' was neither checked (a
    # typo passed) nor converted ('mass: 1500' made the node exit: INTEGER, expecting
    # DOUBLE); the node's full name now decides, as in rcl (asked here, 5 remappings)
    import rclpy
    from rclpy.context import Context
    from lookahead_control.core.config import check_params_file
    from lookahead_control.ros.controller_node import ALL_SPECS, ControllerNode
    from lookahead_control.ros.node_main import node_full_name
    path = tmp_path / 'ns.yaml'
    path.write_text(f"'{key}':\n  ros__parameters:\n    vehicle:\n      mass: 1600.5\n")
    for remap in REMAPS:
        args = ['--ros-args', *remap, '--params-file', str(path)]
        full = node_full_name(args, 'controller')
        sections = check_params_file(path, full, ALL_SPECS)
        ours = next((flat['vehicle.mass'] for flat in sections.values()), None)
        ctx = Context()
        rclpy.init(args=args, context=ctx)
        try:
            node = ControllerNode(context=ctx)
            try:
                assert node.get_fully_qualified_name() == full
                theirs = node.get_parameter('vehicle.mass').value
            finally:
                node.destroy_node()
        finally:
            rclpy.try_shutdown(context=ctx)
        assert (ours or 1485.0) == theirs, (key, remap, ours, theirs)


def test_a_namespaced_node_s_section_is_checked_and_converted(tmp_path):
    from test_compliance_seed import _node_reads
    from lookahead_control.ros.controller_node import ALL_SPECS
    from lookahead_control.ros.node_main import checked_arguments
    typo = tmp_path / 'typo.yaml'
    typo.write_text('/car_b/controller:\n  ros__parameters:\n    vehicle:\n      masss: 3.0\n')
    with pytest.raises(ConfigError, match="unknown parameter 'vehicle.masss'"):
        checked_arguments(['--ros-args', '-r', '__ns:=/car_b', '--params-file', str(typo)],
                          'controller', ALL_SPECS, [])
    # the same file for a node in another namespace: not its section
    checked_arguments(['--ros-args', '-r', '__ns:=/car_a', '--params-file', str(typo)],
                      'controller', ALL_SPECS, [])
    whole = tmp_path / 'whole.yaml'
    whole.write_text('/car_b/controller:\n  ros__parameters:\n    vehicle:\n      mass: 1500\n')
    scratch = []
    args = checked_arguments(['--ros-args', '-r', '__ns:=/car_b', '--params-file', str(whole)],
                             'controller', ALL_SPECS, scratch)
    try:
        assert scratch and args[-1] == str(scratch[0])
        text = scratch[0].read_text()
        assert text.startswith('/car_b/controller:'), text
        assert _node_reads(scratch[0])['vehicle.mass'] == 1485.0   # not the root node's
    finally:
        for path in scratch:
            path.unlink()
    # the node itself starts (before: 'vehicle.mass' ... 'INTEGER', expecting 'DOUBLE')
    exe = Path(sys.prefix) / 'lib' / 'lookahead_control' / 'controller'
    proc = subprocess.Popen([str(exe), '--ros-args', '-r', '__ns:=/car_b', '--params-file',
                             str(whole)], stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    try:
        line = proc.stderr.readline()
    finally:
        proc.send_signal(signal.SIGINT)
        rest = proc.communicate(timeout=60)[1]
    assert '[car_b.controller]: configured' in line, line + rest
    assert proc.returncode == 0, rest


# dev-probe51's files: each read by rcl and here; both refuse it, or both read the same
AGREED = {
    'str tag': 'n:\n  ros__parameters:\n    a: !!str 0.25\n    b: !<tag:yaml.org,2002:str> 1\n'
               '    c: !!float 1\n    d: !!int 0.5\n',
    'same type twice': 'n:\n  ros__parameters:\n    c: 1.5\n    c: 2.5\n    g: {a: 1}\n'
                       '    g: {b: 2}\n',
    'a section twice': 'n:\n  ros__parameters:\n    a: 1\nn:\n  ros__parameters:\n    a: 2\n',
    'empty value': 'n:\n  ros__parameters:\n    a:\n    b: 1\n',
    'empty value, comment': 'n:\n  ros__parameters:\n    a: # c\n',
    'value outside ros__parameters': 'sim_plant: {rate: 100}\nn:\n  ros__parameters: {a: 1}\n',
    'value before ros__parameters': 'n:\n  rate: 100\n  ros__parameters:\n    a: 1\n',
    'top-level ros__parameters': 'ros__parameters:\n  a: 1\n',
    'two ros__parameters keys': 'n:\n  ros__parameters:\n    a: 1\n  ros__parameters_old:\n'
                                '    b: 1\n',
    'ros__parameters_v2': 'n:\n  ros__parameters_v2:\n    a: 1\n',
    'empty map value': 'n:\n  ros__parameters:\n    a: {}\n    b: 1\n',
    'empty ros__parameters': 'n:\n  ros__parameters: {}\nm:\n  ros__parameters: {a: 1}\n',
    'empty namespace': 'sim: {}\nn:\n  ros__parameters: {a: 1}\n',
    'empty key': "n:\n  ros__parameters:\n    '': 1\n",
    'empty file': '',
    'comment only': '# nothing\n',
    'slashes joined': "'/ns/':\n  '/n':\n    ros__parameters: {a: 1}\n",
    'a namespace ending in a slash': "'/':\n  n:\n    ros__parameters: {a: 1}\n",
    'long node name': f"'{'n' * 256}':\n  ros__parameters: {{a: 1}}\n",
    'longest node name': f"'{'n' * 255}':\n  ros__parameters: {{a: 1}}\n",
    'anchor twice': 'n:\n  ros__parameters:\n    a: &x 1\n    b: &x 2\n',
    'dotted then nested': 'n:\n  ros__parameters:\n    g.a: 0.5\n    g:\n      a: 0.7\n',
    # dev-probe53
    'a NUL in a string': 'n:\n  ros__parameters:\n    a: "base_link\\0x"\n',
    'an empty tagged value': 'n:\n  ros__parameters:\n    a: !!str\n    b: 1\n',
    'a name and its prefix': 'n:\n  ros__parameters:\n    foo: 1\n    foo.bar: 2\n',
}
# what rcl reads otherwise than anyone means: refused here, with the line
REFUSED_HERE = {
    # rcl keeps both values and reads the int (by type: bool, int, double, string)
    'two types twice': 'n:\n  ros__parameters:\n    a: 0\n    a: 0.2\n',
    'two types in two sections': 'n:\n  ros__parameters:\n    a: on\nn:\n  ros__parameters:\n'
                                 '    a: odom\n',
    # rcl reads the nested section in this order and refuses the file in the other
    'a section beside a node': '/**:\n  n:\n    ros__parameters: {b: 2}\n  ros__parameters:\n'
                               '    a: 1\n',
    'a node beside a section': '/**:\n  ros__parameters:\n    a: 1\n  n:\n    ros__parameters:\n'
                               '      b: 2\n',
    # rcl flattens it
    'a list inside a list': 'n:\n  ros__parameters:\n    a: [[1]]\n',
    # dev-probe53: rcl renames the earlier value (frame_id.child = odom)
    'a map over a value in a later section': 'n:\n  ros__parameters:\n    a: odom\n'
                                             'n:\n  ros__parameters:\n    a: {child: x}\n',
    # one name nested and dotted, two types: rcl reads the int
    'nested and dotted, two types': 'n:\n  ros__parameters:\n    g: {a: 1}\n    g.a: 0.2\n',
    # rcl misnames the names after it (x.b.d)
    'a dotted name opening a map': 'n:\n  ros__parameters:\n    x: {b.c: {e: 1}, d: 2}\n',
    'deep': 'n:\n  ros__parameters:\n    a: ' + '[' * 400 + '1' + ']' * 400 + '\n',
    'deeper maps': 'n:\n  ros__parameters:\n    a: ' + '{b: ' * 400 + '1' + '}' * 400 + '\n',
}


def _rcl_reads_file(tmp_path, text):
    """Return rcl's parameters of node ``/n``, or None if rcl refuses the file."""
    if _rcl_refuses(tmp_path, text):
        return None
    try:
        params = _rcl_parameters(tmp_path, text)
    except ValueError:          # rclpy: a value it cannot declare (an empty list)
        return None
    return {k: v for k, v in params.items()
            if k not in ('use_sim_time', 'start_type_description_service')}


def _ours(tmp_path, text):
    path = tmp_path / _write(tmp_path, text)
    try:
        return {k: v for name, flat in node_sections(path) if name in ('n', '/n', '/**')
                for k, v in flat.items()}
    except ConfigError as err:
        assert str(err).startswith(f'{path}: ') and '\n' not in str(err), err
        return None


def test_files_are_read_or_refused_as_rcl_does(tmp_path):
    wrong = {}
    for case, text in AGREED.items():
        rcl, ours = _rcl_reads_file(tmp_path, text), _ours(tmp_path, text)
        if rcl != ours:
            wrong[case] = (rcl, ours)
    assert wrong == {}
    assert _ours(tmp_path, AGREED['str tag']) == {'a': '0.25', 'b': '1', 'c': 1, 'd': 0.5}


def test_files_rcl_reads_against_their_meaning_are_refused(tmp_path):
    for case, text in REFUSED_HERE.items():
        assert _ours(tmp_path, text) is None, case
    rename = _rcl_reads_file(tmp_path, REFUSED_HERE['a map over a value in a later section'])
    assert set(rename) == {'a.child'}           # the value 'odom' of 'a' is gone
    assert _rcl_reads_file(tmp_path, REFUSED_HERE['nested and dotted, two types']) == {'g.a': 1}
    assert set(_rcl_reads_file(tmp_path, REFUSED_HERE['a dotted name opening a map'])) == {
        'x.b.c.e', 'x.b.d'}
    # rcl reads the first nested form and refuses the other: by the order alone
    assert _rcl_reads_file(tmp_path, REFUSED_HERE['a section beside a node']) is not None
    assert _rcl_reads_file(tmp_path, REFUSED_HERE['a node beside a section']) is None
    assert _rcl_reads_file(tmp_path, REFUSED_HERE['two types twice']) == {'a': 0}


def test_a_utf16_file_reads_and_a_latin1_one_is_one_line(tmp_path):
    # before: a traceback (UnicodeDecodeError) from the node, closed_loop and compare
    text = 'n:\n  ros__parameters:\n    a: 0.2\n'
    utf16 = tmp_path / 'utf16.yaml'
    utf16.write_bytes(text.encode('utf-16'))
    assert node_sections(utf16) == [('n', {'a': 0.2})]
    latin1 = tmp_path / 'latin1.yaml'
    latin1.write_bytes('# r\xe9glage\n'.encode('latin-1') + text.encode())
    with pytest.raises(ConfigError, match=f'{latin1}: malformed YAML'):
        node_sections(latin1)


def test_every_form_of_a_command_line_value_for_this_node_is_checked():
    # dev-probe51: --param (rcl's long form of -p) and -p controller:NAME:=V (for this
    # node) were not checked; a whole real for an integer now reaches rcl as the integer
    # (in a file it already did: -p and files disagreed); another node's rule is rcl's
    from lookahead_control.ros.controller_node import ALL_SPECS
    from lookahead_control.ros.node_main import checked_arguments
    for flag in ('-p', '--param'):
        with pytest.raises(ConfigError, match=f'{flag} lane_keeping.integral_gain:=9: '):
            checked_arguments(['--ros-args', flag, 'lane_keeping.integral_gain:=9'], 'controller',
                              ALL_SPECS, [])
    with pytest.raises(ConfigError, match='expected a number'):
        checked_arguments(['--ros-args', '-p',
                           'controller:lane_keeping.integral_gain:=!!str 0.25'],
                          'controller', ALL_SPECS, [])
    other = ['--ros-args', '-p', 'other:lane_keeping.integral_gain:=9']
    assert checked_arguments(other, 'controller', ALL_SPECS, []) == other
    # under a namespace 'controller:' is not this node's (rcl matches /controller)
    args = ['--ros-args', '-r', '__ns:=/car_b', '-p', 'controller:lane_keeping.integral_gain:=9']
    assert checked_arguments(args, 'controller', ALL_SPECS, []) == args
    assert checked_arguments(['--ros-args', '-p', 'controller:safety.max_curvature_points:=100.0'],
                             'controller', ALL_SPECS, []) == [
        '--ros-args', '-p', 'controller:safety.max_curvature_points:=100']


def test_a_params_file_read_once_is_checked_and_reaches_rcl(tmp_path):
    # dev-probe53: --params-file <(printf ...) (a pipe): the checks read it, rcl then found
    # it empty, and the node ran unchecked on its defaults (integral_gain: abc started)
    import os
    from lookahead_control.ros.controller_node import ALL_SPECS
    from lookahead_control.ros.node_main import checked_arguments
    for text, error in (('0.2', None), ('abc', 'expected a number')):
        read, write = os.pipe()
        os.write(write, ('controller:\n  ros__parameters:\n    lane_keeping:\n'
                         f'      integral_gain: {text}\n').encode())
        os.close(write)
        scratch = []
        try:
            if error:
                with pytest.raises(ConfigError, match=error):
                    checked_arguments(['--ros-args', '--params-file', f'/dev/fd/{read}'],
                                      'controller', ALL_SPECS, scratch)
                continue
            args = checked_arguments(['--ros-args', '--params-file', f'/dev/fd/{read}'],
                                     'controller', ALL_SPECS, scratch)
            assert args[-1] == str(scratch[0])
            from test_compliance_seed import _node_reads
            assert _node_reads(args[-1])['lane_keeping.integral_gain'] == 0.2
        finally:
            os.close(read)
            for path in scratch:
                path.unlink()


def test_later_arguments_rcl_would_read_otherwise_are_refused(tmp_path):
    # dev-probe53: a file's int and a later -p's real for one name (rcl reads the int 7,
    # the node ran 5.0), or two -p; and a later file's map over a -p's value (rcl drops it)
    from lookahead_control.ros.controller_node import ALL_SPECS
    from lookahead_control.ros.node_main import checked_arguments
    seven = tmp_path / 'seven.yaml'
    seven.write_text('/**:\n  ros__parameters:\n    safety:\n      max_curvature_points: 7\n')
    for args in (['--params-file', str(seven), '-p', 'safety.max_curvature_points:=5.0'],
                 ['-p', 'safety.max_curvature_points:=7',
                  '-p', 'safety.max_curvature_points:=5.0']):
        with pytest.raises(ConfigError, match='given as int 7 and later as float 5.0: rcl '
                           'keeps both and reads the int 7'):
            checked_arguments(['--ros-args', *args], 'controller', ALL_SPECS, [])
    assert _rcl_read(['--params-file', str(seven), '-p', 'safety.max_curvature_points:=5.0'],
                     'controller')['safety.max_curvature_points'] == 7
    child = tmp_path / 'child.yaml'
    child.write_text("/**:\n  ros__parameters:\n    frame_id: {child: 'x'}\n")
    with pytest.raises(ConfigError, match='frame_id is a value, and later the map'):
        checked_arguments(['--ros-args', '-p', 'frame_id:=odom', '--params-file', str(child)],
                          'controller', ALL_SPECS, [])
    # one type: the later wins, as in rcl
    checked_arguments(['--ros-args', '--params-file', str(seven), '-p',
                       'safety.max_curvature_points:=5'], 'controller', ALL_SPECS, [])


def test_arguments_rcl_does_not_read_are_not_checked(tmp_path):
    # dev-probe53: a --params-file before --ros-args, or a -p after its closing --, is the
    # program's: rcl never reads it, and it was refused
    from lookahead_control.ros.controller_node import ALL_SPECS
    from lookahead_control.ros.node_main import checked_arguments
    bad = tmp_path / 'bad.yaml'
    bad.write_text('controller:\n  ros__parameters:\n    law: bogus\n')
    for args in (['--params-file', str(bad)], ['--ros-args', '--', '-p', 'law:=bogus'],
                 ['--params-file', str(bad), '--ros-args', '-r', '__ns:=/a']):
        assert checked_arguments(args, 'controller', ALL_SPECS, []) == args
    with pytest.raises(ConfigError, match='law'):
        checked_arguments(['--ros-args', '--params-file', str(bad)], 'controller',
                          ALL_SPECS, [])


def test_a_later_integer_for_an_earlier_real_is_the_user_s_value(tmp_path):
    # dev-probe54: 'controller --params-file config/vehicle.yaml -p vehicle.mass:=1500'
    # was refused (two types), though rcl reads the later integer (it prefers an int to a
    # double) and the node takes it as 1500.0; only a real after an integer is read
    # otherwise (the integer), and refused
    from lookahead_control.core.config import source_config_dir
    from lookahead_control.ros.controller_node import ALL_SPECS
    from lookahead_control.ros.node_main import checked_arguments
    vehicle = str(source_config_dir() / 'vehicle.yaml')
    for args in (['--params-file', vehicle, '-p', 'vehicle.mass:=1500'],
                 ['-r', '__ns:=/car_b', '--params-file', vehicle, '-p', 'vehicle.mass:=2000'],
                 ['--params-file', vehicle, '-p', 'lane_keeping.integral_gain:=0']):
        checked_arguments(['--ros-args', *args], 'controller', ALL_SPECS, [])
    assert _rcl_read(['--params-file', vehicle, '-p', 'vehicle.mass:=1500'],
                     'controller')['vehicle.mass'] == 1500
    with pytest.raises(ConfigError, match='reads the int 1500, not the later'):
        checked_arguments(['--ros-args', '-p', 'vehicle.mass:=1500', '-p',
                           'vehicle.mass:=1600.0'], 'controller', ALL_SPECS, [])


def test_another_node_s_empty_list_leaves_the_file_readable(tmp_path):
    # dev-probe54: a launch-style file with 'recorder: {ros__parameters: {exclude: []}}'
    # was refused for the controller; rcl parses it (only that node could not declare it)
    text = ('recorder:\n  ros__parameters:\n    exclude: []\n'
            'controller:\n  ros__parameters:\n    lane_keeping:\n      integral_gain: 0.2\n')
    path = tmp_path / _write(tmp_path, text)
    assert dict(node_sections(path))['controller'] == {'lane_keeping.integral_gain': 0.2}
    assert not _rcl_refuses(tmp_path, text)


def test_a_tab_is_refused_saying_what_to_write(tmp_path):
    path = tmp_path / _write(tmp_path, 'n:\n  ros__parameters:\n    a:\t1.0\n')
    with pytest.raises(ConfigError, match='use spaces'):
        node_sections(path)


def test_path_bridge_checks_its_parameters_as_the_other_nodes_do(tmp_path):
    # dev-probe54: path_bridge ran with no checks: an integer for a real refused in
    # rclpy's words, a typo or an unknown choice run silently, --help without parameters
    from lookahead_control.ros.path_bridge_node import ALL_SPECS
    from lookahead_control.ros.node_main import checked_arguments
    checked_arguments(['--ros-args', '-p', 'sensor_distance:=2'], 'path_bridge', ALL_SPECS, [])
    with pytest.raises(ConfigError, match='did you mean'):
        checked_arguments(['--ros-args', '-p', 'sensor_distanse:=2.0'], 'path_bridge',
                          ALL_SPECS, [])
    with pytest.raises(ConfigError, match='qos_reliability'):
        checked_arguments(['--ros-args', '-p', 'qos_reliability:=best_effrt'], 'path_bridge',
                          ALL_SPECS, [])
    exe = Path(sys.prefix) / 'lib' / 'lookahead_control' / 'path_bridge'
    out = subprocess.run([str(exe), '--help'], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and 'sensor_distance' in out.stdout, out.stdout


@pytest.mark.parametrize('section', ['controller', '/**/controller', '/*', '/**/sim_plant'])
def test_a_vehicle_file_gives_the_car_to_every_node(tmp_path, section):
    # dev-probe54: --vehicle FILE read only /**: vehicle.* in a 'controller:' section was
    # left out and certificate, compare, sweep ran the default car without a word
    from lookahead_control.core.config import load_vehicle
    path = tmp_path / 'car.yaml'
    path.write_text(f"'{section}':\n  ros__parameters:\n    vehicle:\n      mass: 1600.0\n")
    with pytest.raises(ConfigError, match=f"vehicle.mass in section '{re.escape(section)}'"):
        load_vehicle(path)
    path.write_text("'/**':\n  ros__parameters:\n    vehicle:\n      mass: 1600.0\n")
    assert load_vehicle(path).mass == 1600.0


def _refused_when_piped(data: bytes, reason: str) -> None:
    """Check that a params file read once (a pipe) is refused under the name given."""
    import os
    from lookahead_control.ros.controller_node import ALL_SPECS, check_parameters
    from lookahead_control.ros.node_main import checked_arguments
    read, write = os.pipe()
    os.write(write, data)
    os.close(write)
    scratch: list = []
    try:
        with pytest.raises(ConfigError, match=f'^/dev/fd/{read}: {re.escape(reason)}'):
            checked_arguments(['--ros-args', '--params-file', f'/dev/fd/{read}'],
                              'controller', ALL_SPECS, scratch, check_parameters)
    finally:
        os.close(read)
        for path in scratch:
            path.unlink()


def test_a_value_the_core_refuses_names_the_argument_that_set_it(tmp_path):
    # dev-probe60's "seen": 'curvature_smoothing: 0.5' (allowed 0 or 1-50 m) passes the
    # schema's range 0-50 and stopped the node on the core's check, without the file's
    # name that every range error has; now the whole set is checked before ROS starts
    from lookahead_control.ros.controller_node import ALL_SPECS, check_parameters
    from lookahead_control.ros.node_main import checked_arguments

    def given(*args):
        return checked_arguments(['--ros-args', *args], 'controller', ALL_SPECS, [],
                                 check_parameters)

    half = tmp_path / 'half.yaml'
    half.write_text('/**:\n  ros__parameters:\n    lane_keeping:\n'
                    '      curvature_smoothing: 0.5\n')
    with pytest.raises(ConfigError, match=f'^{half}: lane_keeping.curvature_smoothing = 0.5 '
                       r'm would average .*allowed: 0 \(the polygon as received\) or 1-50 m'):
        given('--params-file', str(half))
    with pytest.raises(ConfigError, match='^-p lane_keeping.curvature_smoothing:=0.5: '
                       'lane_keeping.curvature_smoothing = 0.5 m'):
        given('-p', 'lane_keeping.curvature_smoothing:=0.5')
    # a later argument that sets it right: the node starts
    assert given('--params-file', str(half), '-p', 'lane_keeping.curvature_smoothing:=5.0')
    # another node's section is not this node's
    other = tmp_path / 'other.yaml'
    other.write_text('/car_b/controller:\n  ros__parameters:\n    lane_keeping:\n'
                     '      curvature_smoothing: 0.5\n')
    assert given('--params-file', str(other))
    # a combination: each argument that set a named parameter is named
    gap = tmp_path / 'gap.yaml'
    gap.write_text('/**:\n  ros__parameters:\n    lane_keeping:\n      max_gap: 1.0\n')
    with pytest.raises(ConfigError, match=f'^{gap}: lane_keeping.max_gap = 1.0 s is above'):
        given('--params-file', str(gap))
    with pytest.raises(ConfigError, match=f'^{gap} and -p lane_keeping.state_filter:=kalman: '):
        given('--params-file', str(gap), '-p', 'lane_keeping.state_filter:=kalman')
    assert given('--params-file', str(gap), '-p', 'lane_keeping.state_filter:=none')
    # a name without a namespace is named as 'name =', not as a word of the message
    with pytest.raises(ConfigError, match=r'^-p controller.reference:=arc_exact: controller.'
                       r"reference = 'arc_exact': the CG-compensated law builds"):
        given('-p', 'controller.reference:=arc_exact', '-p', 'law:=cg_compensated')
    with pytest.raises(ConfigError, match="^-p law:=bogus: law = 'bogus' is not allowed"):
        given('-p', 'law:=bogus')
    # a file read once is named as given, not as the copy the node reads
    _refused_when_piped(half.read_bytes(), 'lane_keeping.curvature_smoothing = 0.5 m')


def test_the_simulator_and_the_bridge_check_their_whole_set_at_start_up(tmp_path):
    from lookahead_control.ros import path_bridge_node
    from lookahead_control.ros.node_main import checked_arguments
    from sim_plant import sim_plant_node
    stop = tmp_path / 'stop.yaml'
    stop.write_text('sim_plant:\n  ros__parameters:\n    output: vehicle\n'
                    '    curvature_stop: 5.0\n')
    with pytest.raises(ConfigError, match=f'^{stop}: curvature_stop = 5: only with output'):
        checked_arguments(['--ros-args', '--params-file', str(stop)], 'sim_plant',
                          sim_plant_node.ALL_SPECS, [], sim_plant_node.check_parameters)
    assert checked_arguments(['--ros-args', '--params-file', str(stop), '-p', 'output:=contract'],
                             'sim_plant', sim_plant_node.ALL_SPECS, [],
                             sim_plant_node.check_parameters)
    assert checked_arguments(['--ros-args', '-p', 'path.fit_half_window:=2.0'], 'path_bridge',
                             path_bridge_node.ALL_SPECS, [], path_bridge_node.check_parameters)


def test_the_controller_executable_names_the_file_of_a_value_its_core_refuses(tmp_path):
    half = tmp_path / 'half.yaml'
    half.write_text('/**:\n  ros__parameters:\n    lane_keeping:\n'
                    '      curvature_smoothing: 0.5\n')
    exe = Path(sys.prefix) / 'lib' / 'lookahead_control' / 'controller'
    out = subprocess.run([str(exe), '--ros-args', '--params-file', str(half)],
                         capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert out.returncode == 2, out.stderr
    assert out.stderr == (f'controller: error: {half}: lane_keeping.curvature_smoothing = 0.5 '
                          'm would average over less than a metre of road; allowed: 0 (the '
                          'polygon as received) or 1-50 m\n')


def test_every_argument_behind_a_refusal_is_named(tmp_path):
    # dev-probe61: messages that wrote another parameter without its namespace
    # ('must be <= low_speed') named no argument or only one; the simulator's step and
    # delay checks and its speed override ran after ROS started, without the file's name;
    # a built-in parameter of the wrong type (use_sim_time: 1) too, in rclpy's words
    from lookahead_control.ros.controller_node import ALL_SPECS, check_parameters
    from lookahead_control.ros.node_main import checked_arguments
    from sim_plant import sim_plant_node

    def node(name, specs, check, *args):
        return checked_arguments(['--ros-args', *args], name, specs, [], check)

    def write(name, section, text):
        path = tmp_path / name
        path.write_text(f'{section}:\n  ros__parameters:\n{text}')
        return str(path)

    low = write('low.yaml', 'controller', '    safety.low_speed: 0.5\n')
    with pytest.raises(ConfigError, match=f'^{low}: safety.low_speed_blend = 1: must be <= '
                       r'safety.low_speed \(0.5\)'):
        node('controller', ALL_SPECS, check_parameters, '--params-file', low)
    limit = write('limit.yaml', 'controller', '    safety.max_steering_angle: 0.2\n')
    safe = write('safe.yaml', '/**', '    safety.safe_angle: 0.3\n')
    with pytest.raises(ConfigError, match=f'^{safe} and {limit}: safety.safe_angle = 0.3'):
        node('controller', ALL_SPECS, check_parameters, '--params-file', limit,
             '--params-file', safe)
    clock = write('clock.yaml', '/**', '    use_sim_time: 1\n')
    with pytest.raises(ConfigError, match=f'^{clock}: use_sim_time = 1: expected true or '
                       'false'):
        node('controller', ALL_SPECS, check_parameters, '--params-file', clock)
    sim = (sim_plant_node.ALL_SPECS, sim_plant_node.check_parameters)
    fine = write('fine.yaml', 'sim_plant', '    dt: 0.003\n')
    with pytest.raises(ConfigError, match=f'^{fine}: rate_hz = 100 Hz and dt = 0.003 s: the '
                       'period 1 / rate_hz must be a whole multiple of dt'):
        node('sim_plant', *sim, '--params-file', fine)
    with pytest.raises(ConfigError, match=f'^-p rate_hz:=7.0 and {fine}: rate_hz = 7 Hz'):
        node('sim_plant', *sim, '--params-file', fine, '-p', 'rate_hz:=7.0')
    with pytest.raises(ConfigError, match='^-p plant.delay:=0.0015: plant.delay = 0.0015 s '
                       'is not a whole multiple of dt = 0.001 s'):
        node('sim_plant', *sim, '-p', 'plant.delay:=0.0015')
    envelope = source_config_dir() / 'scenarios' / 's5_envelope.yaml'
    fast = write('fast.yaml', 'sim_plant', f'    scenario_file: {envelope}\n    speed: 20.0\n')
    with pytest.raises(ConfigError, match=f'^{fast}: speed = 20 m/s: {envelope}: scenario '
                       "'s5_envelope' has its own speed profile"):
        node('sim_plant', *sim, '--params-file', fast)
    vehicle = write('vehicle.yaml', 'sim_plant', '    output: vehicle\n')
    with pytest.raises(ConfigError, match=f'^-p curvature_stop:=3.0 and {vehicle}: '):
        node('sim_plant', *sim, '--params-file', vehicle, '-p', 'curvature_stop:=3.0')
    # a malformed file read once is named as given, not as the check's copy of it
    _refused_when_piped(b'controller:\n  ros__parameters:\n    lane_keeping.natural_'
                        b'frequency: 500.0\n', 'lane_keeping.natural_frequency = 500.0 rad/s '
                        'is out of range')
    # a name or namespace the node's creation refuses, before ROS starts
    for rule, why in (('__ns:=/car_b/', "namespace must not end with a '/'"),
                      ('__node:=1car', 'node name must not start with a number'),
                      (f'__node:={"a" * 256}', 'node name length should not exceed')):
        with pytest.raises(ConfigError, match=f'^-r {re.escape(rule)}: Invalid .*{why}'):
            node('controller', ALL_SPECS, check_parameters, '-r', rule)
