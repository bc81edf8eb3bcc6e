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
``replay --offline --node`` and ``analyze --node`` on bags of several vehicles (probe25).

Found on a real two-car run over DDS (``/controller`` + ``/sim_plant`` and the same in
``/car_b``, recorded with ``--describe`` of all four): the re-run and the analysis of
each car held (0 rad apart), but a node of the bag that is no controller was re-run as
one, an empty ``--node`` was the default, and the scenario of car b's row was whichever
simulator the recorder read last.
"""

from pathlib import Path
import re
import signal
import time
from types import SimpleNamespace

from lookahead_control.bags.rosbag_io import SCENARIO_KEY
from lookahead_control.bags.run_data import load_run
from lookahead_control.core.cli import run_tool
import pytest
from test_faults import _start_default_sigint
from test_rerun_lost_curvature import controllers_bag

SCENARIO_A = 'scenario:\n  name: road_a\n'
SCENARIO_B = 'scenario:\n  name: road_b\n'


_bag = controllers_bag

TWO_CARS = {'/controller': {'law': 'paper'},
            '/sim_plant': {'vehicle.d_s': 1.5, 'scenario_file': '/x/road_a.yaml',
                           'plant.model': 'linear', 'mode': 'lockstep'},
            '/car_b/controller': {'law': 'stanley'},
            '/car_b/sim_plant': {'vehicle.d_s': 1.5, 'scenario_file': '/x/road_b.yaml',
                                 'plant.model': 'nonlinear', 'mode': 'lockstep'}}


@pytest.mark.parametrize('node', ['/car_b/sim_plant', '/sim_plant'])
def test_a_recorded_node_that_is_no_controller_is_refused(tmp_path, capsys, node):
    # before: its parameters were in the bag, so it passed: replay re-ran the default
    # controller (its vehicle.*, defaults for the rest) on its namespace's topics against
    # its namespace's steering and exited 0 (a real two-car DDS bag: 1.6 mrad off),
    # analyze made a row of it; nothing said it was the simulator
    from lookahead_control.bags import replay_node
    from lookahead_control.tools import analyze_tool
    bag = tmp_path / 'two'
    _bag(bag, TWO_CARS)
    assert run_tool(replay_node.main, [str(bag), '--offline', '--node', node]) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1, err
    assert "not a controller's" in err and '/car_b/controller, /controller' in err, err
    assert run_tool(analyze_tool.main, [str(bag), '--node', node, '--out',
                                        str(tmp_path / 'out'), '--no-plots']) == 2
    assert "not a controller's" in capsys.readouterr().err
    assert not (tmp_path / 'out').exists()
    # the controllers themselves still re-run exactly
    for name in ('/controller', '/car_b/controller'):
        assert run_tool(replay_node.main, [str(bag), '--offline', '--node', name,
                                           '--check', '1e-9']) == 0


def test_an_empty_node_name_is_refused_in_both_modes(tmp_path, capsys):
    # before: replay took --node '' for the default (args.node or /controller) and ran
    # /controller's re-run; without --offline the empty value was not "given" and the bag
    # was played over DDS. analyze refused it already
    from lookahead_control.bags import replay_node
    bag = tmp_path / 'two'
    _bag(bag, TWO_CARS)
    assert run_tool(replay_node.main, [str(bag), '--offline', '--node', '']) == 2
    assert 'not a fully qualified node name' in capsys.readouterr().err
    assert run_tool(replay_node.main, [str(bag), '--node', '']) == 2
    assert '--node: only with --offline' in capsys.readouterr().err


def test_each_car_is_named_by_its_own_simulators_scenario(tmp_path):
    # before: the row's scenario was the bag's one lookahead_control/scenario entry, the
    # scenario of whichever simulator the recorder read last: car b's row named road_a
    from lookahead_control.tools import analyze_tool
    bag = tmp_path / 'two'
    _bag(bag, TWO_CARS, {SCENARIO_KEY + '/sim_plant': SCENARIO_A,
                         SCENARIO_KEY + '/car_b/sim_plant': SCENARIO_B,
                         SCENARIO_KEY: SCENARIO_A})
    for node, scenario, plant in (('/controller', 'road_a', 'linear'),
                                  ('/car_b/controller', 'road_b', 'nonlinear')):
        (_, _, row), = analyze_tool.analyze([bag], None, node)
        assert (row['scenario'], row['plant']) == (scenario, plant), node


def test_a_bag_before_the_per_node_scenario_says_what_it_can(tmp_path):
    # a bag written before the per-node key: one entry, the last simulator's. Where the
    # simulators ran different files it cannot say whose: n/a, not the other car's name
    # (before: road_a for both cars); one simulator or one file: that scenario
    from lookahead_control.bags.run_data import scenario_text
    from lookahead_control.tools import analyze_tool
    bag = tmp_path / 'old_two'
    _bag(bag, TWO_CARS, {SCENARIO_KEY: SCENARIO_A})
    for node in ('/controller', '/car_b/controller'):
        (_, _, row), = analyze_tool.analyze([bag], None, node)
        assert row['scenario'] == 'n/a', node
    same = {**TWO_CARS, '/car_b/sim_plant': {**TWO_CARS['/car_b/sim_plant'],
                                             'scenario_file': '/x/road_a.yaml'}}
    bag = tmp_path / 'old_same'
    _bag(bag, same, {SCENARIO_KEY: SCENARIO_A})
    for node in ('/controller', '/car_b/controller'):
        assert scenario_text(load_run(bag, None, node)) == SCENARIO_A
    one = {k: v for k, v in TWO_CARS.items() if not k.startswith('/car_b')}
    bag = tmp_path / 'old_one'
    _bag(bag, one, {SCENARIO_KEY: SCENARIO_A})
    (_, _, row), = analyze_tool.analyze([bag])
    assert row['scenario'] == 'road_a'


def test_the_recorder_stores_each_simulators_scenario(probe, tmp_path):
    # before: one lookahead_control/scenario entry, overwritten by every simulator whose
    # parameters came in: a two-car bag kept the last one's only
    from lookahead_control.bags.recorder_node import RecorderNode
    from lookahead_control.bags.rosbag_io import BagWriter, run_description
    from rcl_interfaces.msg import ParameterType, ParameterValue
    node, _ = probe
    files = {}
    for name, text in (('a', SCENARIO_A), ('b', SCENARIO_B)):
        files[name] = tmp_path / f'road_{name}.yaml'
        files[name].write_text(text)
    bag = tmp_path / 'bag'
    recorder = RecorderNode(BagWriter(bag), ['/none'],
                            describe=('/sim_plant', '/car_b/sim_plant'), context=node.context)
    try:
        for target, name in (('/sim_plant', 'a'), ('/car_b/sim_plant', 'b')):
            value = ParameterValue(type=ParameterType.PARAMETER_STRING,
                                   string_value=str(files[name]))
            answer = SimpleNamespace(result=lambda v=value: SimpleNamespace(values=[v]))
            recorder._got_values(target, ['scenario_file'], answer)
        described = run_description(bag)
    finally:
        recorder.destroy_node()
        recorder.bag.close()
    assert described[SCENARIO_KEY + '/sim_plant'] == SCENARIO_A
    assert described[SCENARIO_KEY + '/car_b/sim_plant'] == SCENARIO_B
    assert described[SCENARIO_KEY] == SCENARIO_B        # as before: the last one read


def test_a_re_run_without_the_nodes_parameters_says_so(tmp_path, capsys):
    # a recorder that joined late (or was not asked of the node): the node's debug is in
    # the bag, its parameters are not. Before: replay re-ran the default controller and
    # printed only the difference (analyze said "assumed: ..."; replay nothing); car b's
    # stanley run was re-run as the paper law
    import json

    from lookahead_control.bags import replay_node
    bag = tmp_path / 'late'
    _bag(bag, TWO_CARS, recorded=('/controller', '/sim_plant', '/car_b/sim_plant'))
    report = tmp_path / 'r.json'
    assert run_tool(replay_node.main, [str(bag), '--offline', '--node', '/car_b/controller',
                                       '--json', str(report)]) == 0
    out = capsys.readouterr().out
    assert ('the bag has no /car_b/controller parameters (recorded of: /car_b/sim_plant, '
            '/controller, /sim_plant): the re-run uses the default') in out, out
    assert json.loads(report.read_text())['parameters_recorded'] is False
    assert run_tool(replay_node.main, [str(bag), '--offline', '--json', str(report)]) == 0
    assert 'parameters (recorded of' not in capsys.readouterr().out
    assert json.loads(report.read_text())['parameters_recorded'] is True


@pytest.mark.parametrize('topic', ['lateral=/car_b/lateral_error', 'foo=/none'])
def test_an_unknown_topic_role_is_one_line(tmp_path, capsys, topic):
    # before: a typo'd role (lateral=) whose topic was in the bag crashed replay with a
    # KeyError traceback (exit 1, as a failed --check); one not in the bag was ignored
    from lookahead_control.bags import replay_node
    bag = tmp_path / 'two'
    _bag(bag, TWO_CARS)
    assert run_tool(replay_node.main, [str(bag), '--offline', '--node', '/car_b/controller',
                                       '--topic', topic]) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and 'unknown role' in err and 'lateral_error, yaw' in err, err


def test_a_simulator_sharing_its_clock_warns_once(probe):
    # a real two-car lockstep run (both sim_plants on /clock, controllers with
    # use_sim_time): each controller followed both clocks, refused its inputs as 1-2 s
    # ahead of or behind its clock, 20-24 missed deadlines; nothing named the cause.
    # Before: no shared_clock (AttributeError)
    from conftest import spin_until
    from rosgraph_msgs.msg import Clock
    from sim_plant.sim_plant_node import SimPlantNode
    node, executor = probe
    sim = SimPlantNode(context=node.context, namespace='/car_b')
    alone = SimPlantNode(context=node.context, namespace='/car_c', cli_args=[
        '--ros-args', '-r', '/clock:=/car_c/clock'])
    try:
        assert sim.shared_clock() is None        # alone on /clock
        other = node.create_publisher(Clock, '/clock', 10)
        warnings = []
        assert spin_until(executor, lambda: warnings.append(sim.shared_clock()) or
                          any(warnings), 60)
        warning = next(w for w in warnings if w)
        assert warning == ('another node publishes /clock: a controller with use_sim_time '
                           "follows both clocks; start each vehicle's nodes with "
                           '-r /clock:=/car_b/clock')
        assert sim.shared_clock() is None        # once
        # a simulator whose clock is remapped shares it with no one
        assert alone.pub_clock.topic_name == '/car_c/clock'
        assert alone.shared_clock() is None
        node.destroy_publisher(other)
    finally:
        sim.destroy_node()
        alone.destroy_node()


def test_a_bag_of_namespaced_vehicles_only_names_its_controllers(tmp_path, capsys):
    # before: replay/analyze without --node on a bag of /car_b and /car_c only said "no
    # /lateral_error topic ...; remap with --topic lateral_error=NAME": remapping one
    # topic re-runs the default /controller's (absent) parameters on a mix of topics
    from lookahead_control.bags import replay_node
    from lookahead_control.tools import analyze_tool
    bag = tmp_path / 'b_c'
    _bag(bag, {'/car_b/controller': {'law': 'paper'}, '/car_c/controller': {'law': 'stanley'},
               '/car_b/sim_plant': TWO_CARS['/car_b/sim_plant']})
    for main, args in ((replay_node.main, ['--offline']),
                       (analyze_tool.main, ['--out', str(tmp_path / 'out'), '--no-plots'])):
        assert run_tool(main, [str(bag), *args]) == 2
        err = capsys.readouterr().err
        assert err.count('\n') == 1, err
        assert err.rstrip().endswith('remap with --topic lateral_error=NAME or name the '
                                     'controller: --node /car_b/controller or '
                                     '/car_c/controller'), err
    assert run_tool(replay_node.main, [str(bag), '--offline', '--node', '/car_c/controller',
                                       '--check', '1e-9']) == 0


def test_the_report_names_the_controller_it_analyzed(tmp_path):
    # before: car b's report.md was car a's but for its numbers: one row named by the
    # bag, nothing saying which controller of it (the two rows of one bag, two reports)
    from lookahead_control.tools import analyze_tool
    bag = tmp_path / 'two'
    _bag(bag, TWO_CARS)
    for node, line in (('/car_b/controller', f'Bags (controller /car_b/controller): `{bag}`'),
                       ('/controller', f'Bags: `{bag}`')):
        out = tmp_path / node.replace('/', '_')
        assert analyze_tool.main([str(bag), '--node', node, '--out', str(out),
                                  '--no-plots']) == 0
        assert line in (out / 'report.md').read_text().splitlines()


@pytest.mark.process
def test_a_two_car_dds_run_re_runs_and_analyzes_each_car(tmp_path):
    # the probe's real run, kept: /controller + /sim_plant and /car_b/... (remapped clock)
    # in lockstep on two scenarios, recorded with --describe of all four. Each car's
    # re-run is exact, and its row is its own (scenario, plant, schedule, steps)
    import json
    import subprocess
    import sys

    from lookahead_control.bags import replay_node
    from lookahead_control.ros.closed_loop import LoopConfig, node_commands, stop
    from lookahead_control.tools import analyze_tool
    root = Path(__file__).resolve().parent.parent / 'config' / 'scenarios'
    scenarios = {}
    for name, source in (('a', 'paper_r400.yaml'), ('b', 's2_curve_entry.yaml')):
        text = (root / source).read_text()
        scenarios[name] = tmp_path / f'{name}.yaml'
        scenarios[name].write_text(re.sub(r'duration: [0-9.]+', 'duration: 2.0', text))
    bag = tmp_path / 'two_cars'
    sim_a, ctl_a = node_commands(LoopConfig(scenarios['a'], speed=30.0, bag=bag))
    sim_b, ctl_b = node_commands(LoopConfig(scenarios['b'], speed=20.0, plant='nonlinear',
                                            schedule='exact', bag=bag))
    car_b = ['-r', '__ns:=/car_b', '-r', '/clock:=/car_b/clock']
    recorder = subprocess.Popen([sys.executable, '-m', 'lookahead_control.bags.recorder_node',
                                 '-o', str(bag), '--describe', '/controller', '/sim_plant',
                                 '/car_b/controller', '/car_b/sim_plant'])
    controllers = [subprocess.Popen(ctl_a), subprocess.Popen(ctl_b + car_b)]
    logs = [tmp_path / 'sim_a.log', tmp_path / 'sim_b.log']
    sims = []
    for command, log in ((sim_a, logs[0]), (sim_b + car_b, logs[1])):
        with open(log, 'w') as stream:
            sims.append(subprocess.Popen(command, stderr=stream))
    try:
        for sim in sims:
            sim.wait(timeout=600)       # start-up on a loaded machine: minutes
    finally:
        for sim in sims:
            stop(sim, 'sim')
        assert [stop(c, 'controller') for c in controllers] == [0, 0]
        assert stop(recorder, 'record') == 0
    for sim, log in zip(sims, logs):
        text = log.read_text()
        assert sim.returncode == 0, text
        assert 'finished at t = 2 s: 200 steps' in text and 'publishes /clock' not in text
    for node in ('/controller', '/car_b/controller'):
        report = tmp_path / 'replay.json'
        assert run_tool(replay_node.main, [str(bag), '--offline', '--node', node, '--check',
                                           '1e-9', '--json', str(report)]) == 0, node
        data = json.loads(report.read_text())
        assert (data['node'], data['compared'], data['parameters_recorded']) == \
            (node, 200, True), data
    rows = {node: analyze_tool.analyze([bag], None, node)[0][2]
            for node in ('/controller', '/car_b/controller')}
    assert [(r['scenario'], r['plant'], r['schedule'], r['steps'], r['mode'])
            for r in rows.values()] == [('paper_r400', 'linear', 'paper', 200, 'lockstep'),
                                        ('s2_curve_entry', 'nonlinear', 'exact', 200,
                                         'lockstep')]
    assert rows['/car_b/controller']['speed_mps'] == pytest.approx(20.0, abs=0.5)


@pytest.mark.parametrize('name', ['/car_b/controller/', '//controller', '/car b/controller',
                                  '/1car/controller', '/car_ü/controller'])
def test_record_refuses_a_describe_name_no_node_can_have(tmp_path, capsys, monkeypatch,
                                                         name):
    # before: only a leading / was checked: record --describe /car_b/controller/ (a typo)
    # recorded the run, the name matched no node, and the bag lacked car b's parameters
    # without a word (replay --node then re-ran car b without them)
    from lookahead_control.bags import recorder_node
    # a recording that started would run until a signal: here it ends at once, exit 0
    monkeypatch.setattr(recorder_node, 'run_node', lambda *args, **kwargs: 0)
    bag = tmp_path / 'bag'
    assert run_tool(recorder_node.main, ['record', '-o', str(bag), '--describe',
                                         '/controller', name]) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and 'not a fully qualified node name' in err, err
    assert repr(name) in err and not bag.exists()


def test_record_says_which_described_node_it_never_saw(probe, tmp_path, capsys):
    # before: a --describe node that never showed (misspelt: /car_b/controler, or in
    # another namespace) ended the recording with no word; the bag lacked its parameters
    # and only replay --node found out. A default one (/sim_plant on a real car) is not
    # named
    from lookahead_control.bags.recorder_node import RecorderNode
    from lookahead_control.bags.rosbag_io import BagWriter
    node, _ = probe
    recorder = RecorderNode(BagWriter(tmp_path / 'bag'), ['/none'],
                            describe=('/controller', '/sim_plant', '/car_b/controler'),
                            context=node.context)
    recorder.destroy_node()
    err = capsys.readouterr().err
    assert err.rstrip().endswith('; never saw /car_b/controler (--describe): no '
                                 'parameters; no publisher of /none ever seen: not '
                                 'recorded'), err
    assert '/sim_plant' not in err and ' /controller' not in err, err


@pytest.mark.parametrize('name,resolved', [('steering', '/car_b/steering'),
                                           ('~/debug', '/car_b/controller/debug'),
                                           ('/car_b/steering', '/car_b/steering')])
def test_a_relative_topic_override_is_the_nodes_own(name, resolved):
    # before: --node /car_b/controller --topic steering=steering read a topic
    # 'steering' (no such name in a bag: every recorded name is absolute)
    from lookahead_control.bags.run_data import resolve_name
    assert resolve_name(name, '/car_b/controller') == resolved
    assert resolve_name('steering') == '/steering'


def test_replay_resolves_a_relative_topic_in_the_nodes_namespace(tmp_path, capsys):
    import json

    from lookahead_control.bags import replay_node
    bag = tmp_path / 'two'
    _bag(bag, {'/controller': {'law': 'paper'},
               '/car_b/controller': {'law': 'stanley', 'stanley.gain': 2.5}},
         scale={'/car_b/controller': 0.5})
    report = tmp_path / 'r.json'
    assert run_tool(replay_node.main, [str(bag), '--offline', '--check', '1e-9', '--node',
                                       '/car_b/controller', '--topic', 'steering=steering',
                                       '--json', str(report)]) == 0, capsys.readouterr()
    assert json.loads(report.read_text())['compared'] == 60


def test_a_bad_recorded_parameter_names_its_node(tmp_path, capsys):
    # before: 'bag parameters: ...': in a bag of two controllers, whose?
    import yaml

    from lookahead_control.bags import replay_node
    from lookahead_control.bags.rosbag_io import PARAMETERS_KEY
    bag = tmp_path / 'two'
    cars = {'/controller': {'law': 'paper'}, '/car_b/controller': {'law': 'stanley'}}
    bad = {node: {'ros__parameters': dict(own)} for node, own in cars.items()}
    bad['/car_b/controller']['ros__parameters']['stanley.gain'] = -1.0
    _bag(bag, cars, description={PARAMETERS_KEY: yaml.safe_dump(bad)})
    assert run_tool(replay_node.main, [str(bag), '--offline', '--node',
                                       '/car_b/controller']) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and 'bag parameters of /car_b/controller' in err, err
    assert 'stanley.gain' in err, err


NAMES = ['~', '~/debug', '{node}/x', '{ns}/x', '{namespace}/x', 'steering', '/car_b/steering',
         '_hidden/x', 'a/_b', '', '/', '~/', 'talk/', '/a//b', '//a', 'bad name', 'tälk',
         'a.b', '1talk', 'a/1b', 'x/~', '~//x', '{bad}/x', 'x' * 248, 'x' * 246]


@pytest.mark.parametrize('node', ['/controller', '/car_b/controller'])
def test_resolve_name_resolves_and_refuses_as_rcl_does(node):
    # before: resolve_name took any text: '{node}/x' was /car_b/{node}/x, 'bad name',
    # '' and /a//b were names (no bag has them: the re-run compared nothing, exit 0)
    from lookahead_control.bags.run_data import resolve_name
    from lookahead_control.core.config import ConfigError
    from rclpy.expand_topic_name import expand_topic_name
    from rclpy.validate_full_topic_name import validate_full_topic_name
    namespace, _, name = node.rpartition('/')
    for topic in NAMES:
        try:
            expected = expand_topic_name(topic, name, namespace or '/')
            validate_full_topic_name(expected)
        except Exception:       # rcl refuses it (ValueError or its own exception types)
            with pytest.raises(ConfigError, match='not a ROS topic name'):
                resolve_name(topic, node)
        else:
            assert resolve_name(topic, node) == expected, topic


@pytest.mark.parametrize('option,words', [
    ('steering=stearing', '--topic steering=stearing: no /car_b/stearing in the bag (has: '),
    ('yaw=', "--topic yaw=: '' (/car_b/controller resolves it as '/car_b/'): not a ROS "
             'topic name'),
    ('steering=/car_b//steering', "'/car_b//steering': not a ROS topic name")])
def test_replay_and_analyze_refuse_a_topic_override_that_is_no_name_of_the_bag(
        tmp_path, capsys, option, words):
    # before: a misspelt or malformed --topic read as a topic without messages: replay
    # compared 0 commands ('max |diff| nan rad') and exited 0
    from lookahead_control.bags import replay_node
    from lookahead_control.tools import analyze_tool
    bag = tmp_path / 'two'
    _bag(bag, TWO_CARS)
    for main, args in ((replay_node.main, ['--offline']),
                       (analyze_tool.main, ['--out', str(tmp_path / 'out'), '--no-plots'])):
        assert run_tool(main, [str(bag), *args, '--node', '/car_b/controller',
                               '--topic', option]) == 2
        err = capsys.readouterr().err
        assert err.count('\n') == 1 and words in err, err
    assert not (tmp_path / 'out').exists()


def test_analyze_resolves_a_relative_topic_in_the_nodes_namespace(tmp_path, capsys):
    # before: analyze refused it ('a topic name must be absolute') where replay took it
    from lookahead_control.tools import analyze_tool
    bag = tmp_path / 'two'
    _bag(bag, TWO_CARS, scale={'/car_b/controller': 0.5})
    out = tmp_path / 'out'
    assert run_tool(analyze_tool.main, [str(bag), '--out', str(out), '--no-plots', '--node',
                                        '/car_b/controller', '--topic', 'steering=steering',
                                        '--topic', 'debug=~/debug']) == 0
    assert 'Bags (controller /car_b/controller)' in (out / 'report.md').read_text()


def test_the_recorder_counts_a_restarted_publisher_from_its_new_numbers():
    # before: min/max of all sequence numbers: a publisher restarted (numbers from 1
    # again) after 4..300 and publishing 1..600 was 'published: 600, dropped: 0' with
    # 887 received (a real DDS run), and the one message its new writer lost was hidden
    from lookahead_control.bags.recorder_node import TopicStats
    stats = TopicStats(publishers=1)
    for seq in [*range(4, 301), *range(1, 301), *range(302, 601)]:
        stats.count(seq)
    assert stats.received == 297 + 599
    assert (stats.published(), stats.dropped(), stats.before_first()) == (900, 1, 3)
    many = TopicStats(publishers=2)
    many.count(5)
    assert (many.published(), many.dropped(), many.before_first()) == (None, None, None)


def test_record_names_a_topic_whose_type_is_not_installed(probe, tmp_path, capsys,
                                                          monkeypatch):
    # before: a warning in the log, and a summary without a word of the named topic
    from conftest import spin_until
    from lookahead_control.bags import recorder_node
    from lookahead_control.bags.rosbag_io import BagWriter, bag_topics
    from std_msgs.msg import Float64MultiArray

    def missing(msgtype):
        raise ImportError(f"No module named '{msgtype.split('/')[0]}'")

    monkeypatch.setattr(recorder_node, 'message_class', missing)
    node, executor = probe
    publisher = node.create_publisher(Float64MultiArray, '/untyped', 10)
    recorder = recorder_node.RecorderNode(BagWriter(tmp_path / 'bag'), ['untyped'],
                                          describe=(), context=node.context)
    try:
        executor.add_node(recorder)
        assert spin_until(executor, lambda: '/untyped' in recorder._subs, 60)
    finally:
        executor.remove_node(recorder)
        recorder.destroy_node()
        node.destroy_publisher(publisher)
    err = capsys.readouterr().err
    assert err.rstrip().endswith('; not recorded, type not installed: /untyped '
                                 '(std_msgs/msg/Float64MultiArray)'), err
    assert bag_topics(tmp_path / 'bag') == {}


def test_replay_and_record_check_the_params_files_among_their_ros_arguments(tmp_path, capsys):
    # dev-probe5x's "seen": replay took a params file holding only a string (it played,
    # and re-ran offline, on it), and a directory or a malformed file gave rcl's raw
    # message in record and replay; now both read them as the nodes do, in one line
    import os
    from lookahead_control.bags import recorder_node, replay_node
    bag = tmp_path / 'two'
    _bag(bag, TWO_CARS)
    word = tmp_path / 'word.yaml'
    word.write_text('hello\n')
    malformed = tmp_path / 'malformed.yaml'
    malformed.write_text('a: [1,\n')
    folder = tmp_path / 'folder'
    folder.mkdir()
    for path, why in ((word, 'not a ROS parameters file'), (malformed, 'malformed YAML'),
                      (folder, 'cannot read')):
        assert run_tool(replay_node.main, [str(bag), '--offline', '--ros-args',
                                           '--params-file', str(path)]) == 2
        err = capsys.readouterr().err
        assert f': error: {path}: ' in err and why in err, err
        assert err.count('\n') == 1, err
        assert run_tool(recorder_node.main, ['record', '-o', str(tmp_path / 'rec'),
                                             '--ros-args', '--params-file', str(path)]) == 2
        err = capsys.readouterr().err
        assert f': error: {path}: ' in err and why in err, err
        assert err.count('\n') == 1, err
        assert not (tmp_path / 'rec').exists()
    # a good file read once (a pipe) is read by the check, and the re-run still runs
    read, write = os.pipe()
    os.write(write, b'/**:\n  ros__parameters:\n    use_sim_time: false\n')
    os.close(write)
    try:
        assert run_tool(replay_node.main, [str(bag), '--offline', '--node', '/controller',
                                           '--check', '1e-9', '--ros-args', '--params-file',
                                           f'/dev/fd/{read}']) == 0
    finally:
        os.close(read)


def test_replay_and_record_name_a_bad_piped_file_and_namespace_in_one_line(tmp_path, capsys):
    # dev-probe61: a malformed file read once was named as the deleted copy the check
    # made of it (/tmp/.../replay_params_*.yaml); '-r __ns:=/car_b/' passes rcl's argument
    # parser and ended in a traceback when the node was created
    import os
    from lookahead_control.bags import recorder_node, replay_node
    bag = tmp_path / 'two'
    _bag(bag, TWO_CARS)
    for tool, argv in ((replay_node.main, [str(bag), '--offline']),
                       (recorder_node.main, ['record', '-o', str(tmp_path / 'rec')])):
        read, write = os.pipe()
        os.write(write, b'a: [\n')
        os.close(write)
        try:
            assert run_tool(tool, [*argv, '--ros-args', '--params-file',
                                   f'/dev/fd/{read}']) == 2
        finally:
            os.close(read)
        err = capsys.readouterr().err
        assert f': error: /dev/fd/{read}: malformed YAML' in err, err
        assert run_tool(tool, [*argv, '--ros-args', '-r', '__ns:=/car_b/']) == 2
        err = capsys.readouterr().err
        assert err.count('\n') == 1 and (': error: -r __ns:=/car_b/: Invalid namespace: '
                                         "namespace must not end with a '/'") in err, err
    assert not (tmp_path / 'rec').exists()


def test_replay_refuses_a_builtin_parameter_of_the_wrong_type_in_one_line(tmp_path, capsys):
    # dev-probe61: 'replay BAG -- ros-args -p use_sim_time:=7' (playing over DDS) ended in
    # a traceback from the node's creation, exit 1
    from lookahead_control.bags import replay_node
    bag = tmp_path / 'two'
    _bag(bag, TWO_CARS)
    assert run_tool(replay_node.main, [str(bag), '--wait', '0', '--ros-args', '-p',
                                       'use_sim_time:=7']) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and "parameter 'use_sim_time' to '7'" in err, err


def test_ctrl_c_while_replay_plays_is_one_line_and_exit_130(tmp_path):
    # dev-probe61: rclpy's own SIGINT handler invalidated the context, and the next
    # publish ended in a traceback ("publisher's context is invalid"), exit 1, 5 of 5
    import signal
    import subprocess
    import sys
    import time
    bag = tmp_path / 'two'
    _bag(bag, TWO_CARS)
    for pause in (0.2, 3.0):                # in --wait, and while playing
        # SIGINT at its default, as from a shell: a suite started as a background job
        # ignores SIGINT, and the child inherited that (it played 60 s: this test hung)
        proc = subprocess.Popen([sys.executable, '-m', 'lookahead_control.bags.replay_node',
                                 str(bag), '--rate', '0.01', '--wait', '1'],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                preexec_fn=_start_default_sigint)
        try:
            time.sleep(pause)
        finally:
            proc.send_signal(signal.SIGINT)
            out, err = proc.communicate(timeout=60)
        # died of the signal (run_tool re-raises it for the shell) or exit 130
        assert proc.returncode in (-signal.SIGINT, 130), err
        assert re.fullmatch(r'\S+: interrupted( after \d+ messages)?',
                            err.strip().splitlines()[-1]), err
        assert 'Traceback' not in err and 'context is invalid' not in err, err


def test_a_ctrl_c_a_library_swallowed_stops_replay_playing(tmp_path, capsys, monkeypatch):
    # a SIGINT while a C extension initializes (a lazy import in play) can become an
    # error a fallback catches; only interrupts.received remembers it, and replay played
    # the whole bag (run_tool checked it only before main)
    from lookahead_control.bags import replay_node
    from lookahead_control.core import interrupts
    bag = tmp_path / 'two'
    _bag(bag, TWO_CARS)
    opened = replay_node.bag_reader

    def swallowing(path):
        interrupts.received.append(signal.SIGINT)       # the signal, its exception lost
        return opened(path)

    monkeypatch.setattr(interrupts, 'received', [])
    monkeypatch.setattr(replay_node, 'bag_reader', swallowing)
    start = time.monotonic()
    assert run_tool(replay_node.main, [str(bag), '--rate', '0.05', '--wait', '0']) == 130
    assert time.monotonic() - start < 10.0          # the bag takes 12 s at 0.05x
    assert capsys.readouterr().err.strip().endswith('interrupted after 0 messages')
