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
An offline re-run of a run whose ``road_curvature`` stopped mid-run (probe19).

The node judges the curvature lost on its clock (stamped more than ``input_timeout``
ago) and the default law then estimates it; the offline re-run has no clock and held the
last curvature received to the end of the run, so it re-ran another law: a 400 m curve
at 30 m/s, the curvature stopped at 1.5 s and the curve ended at 2 s, 83 mrad apart (RMS
37 mrad; S2 at 37 m/s recorded over DDS with the curvature cut at 3 s: 37.6 mrad), with
nothing saying why. The reference is the node's own core fed with its lockstep clock (the
lateral error's stamp), as the node runs it.
"""

from dataclasses import replace
import math
from pathlib import Path
import sys

from lookahead_control.bags.run_data import (as_it_ran, controller_from_params, load_run,
                                             rerun, rerun_law, RunData, Samples)
from lookahead_control.core.samples import (CurvatureSample, LateralErrorSample, VelocitySample,
                                            YawSample)
import numpy as np
import pytest

PERIOD_NS = 10_000_000
SPEED, RHO = 30.0, 1.0 / 400.0
#: the order the inputs of one step arrive in
RANK = {'yaw': 0, 'velocity': 1, 'road_curvature': 2, 'lateral_error': 3}


def _inputs(steps, curvature_until_ns):
    """Return the samples of a 400 m curve to 2 s, the curvature sent until a stamp."""
    rows = {'lateral_error': [], 'yaw': [], 'velocity': [], 'road_curvature': []}
    for k in range(1, steps + 1):
        stamp = k * PERIOD_NS
        t = stamp * 1e-9
        # the curve ends at 2 s, after the curvature stopped coming
        rows['yaw'].append(YawSample(stamp, 0.002, SPEED * RHO if t < 2.0 else 0.0, 0.0))
        rows['velocity'].append(VelocitySample(stamp, SPEED, 0.0))
        if stamp < curvature_until_ns:
            # the road's (a curvature of the curve after it ended: a map the map check
            # drops, dev-sc35)
            rows['road_curvature'].append(CurvatureSample(stamp, RHO if t < 2.0 else 0.0,
                                                          0.0))
        rows['lateral_error'].append(
            LateralErrorSample(stamp, 0.0, 0.1 + 0.05 * math.sin(2.0 * math.pi * t)))
    return rows


def _feed(rows):
    """Return ``(role, sample)`` as the node gets them: each step's lateral error last."""
    return sorted(((role, sample) for role, samples in rows.items() for sample in samples),
                  key=lambda item: (item[1].stamp_ns, RANK[item[0]]))


def _samples(rows, names):
    stamps = np.array([row.stamp_ns for row in rows], dtype=np.int64)
    values = {name: np.array([getattr(row, name) for row in rows], dtype=float)
              for name in names}
    if 'rho' in names:                  # the preview's points: a tuple per sample
        values['ahead'] = np.empty(len(rows), dtype=object)
        values['ahead'][:] = [()] * len(rows)
    return stamps, values


def _bag(rows, commands, debug, params):
    """
    Return the recording of a run: the inputs as received, the commands, the debug topic.

    :param rows: the inputs (:func:`_inputs`), received in the order the node got them.
    :param commands: stamp -> the steering sent.
    :param debug: debug column name -> stamp -> value.
    :param params: the controller's recorded parameters.
    """
    fields = {'lateral_error': ('distance', 'value'),
              'yaw': ('relative_yaw', 'yaw_rate', 'accel_x'),
              'velocity': ('v_x', 'v_y'), 'road_curvature': ('rho', 'slope')}
    inputs = {}
    for role, names in fields.items():
        stamps, values = _samples(rows[role], names)
        # received (on the recorder's clock) in the order the node gets them
        inputs[role] = Samples(stamps + RANK[role], stamps, np.arange(stamps.size), values)
    stamps = np.array(sorted(commands), dtype=np.int64)
    steering = Samples(stamps + 10, stamps, np.arange(stamps.size),
                       {'angle': np.array([commands[s] for s in stamps])})
    columns = Samples(stamps + 11, stamps, np.arange(stamps.size),
                      {name: np.array([column[s] for s in stamps])
                       for name, column in debug.items()})
    return RunData(Path('synthetic'), inputs=inputs, steering=steering, debug=columns,
                   controller_params=params)


def _recorded(params, curvature_until_ns=1_500_000_000, seen_until_ns=None):
    """
    Return a run of the node whose curvature stopped, and its estimating answers.

    :param curvature_until_ns: the bag's curvature stops here.
    :param seen_until_ns: the node's stops here (None: the bag's; 0: it never gets one, as
        with a remapping).
    """
    rows = _inputs(300, curvature_until_ns)
    seen = [c for c in rows['road_curvature'] if seen_until_ns is None
            or c.stamp_ns < seen_until_ns]
    # the node: its clock at the lateral error's stamp (lockstep sim time)
    node, _ = controller_from_params(params)
    commands, estimated, flags = {}, 0, {}
    for role, sample in _feed({**rows, 'road_curvature': seen}):
        assert node.accept(role, sample, sample.stamp_ns) is None
        if role == 'lateral_error':
            command = node.compute(sample.stamp_ns)
            commands[sample.stamp_ns] = command.steering
            estimates = getattr(node.law, 'curvature_estimated', None)
            estimated += bool(estimates is not None and estimates())
            # what the node publishes on ~/debug with the command
            state = getattr(node.law, 'debug_values', None)
            flags[sample.stamp_ns] = (math.nan if state is None
                                      else dict(state())['curvature_estimated'])
    return _bag(rows, commands, {'curvature_estimated': flags}, params), estimated


def test_a_re_run_of_a_curvature_lost_mid_run_estimates_it_where_the_node_did():
    params = {'law': 'cg_compensated'}
    run, estimated = _recorded(params)
    assert estimated == 300 - 150 - 19      # lost once stamped over 0.2 s ago
    result = rerun(run, order='receive')
    # before: max 0.083 rad, RMS 0.037 (the re-run held the curvature of 1.49 s)
    assert result.compared == 300
    assert result.max_diff == 0.0, result.max_diff
    assert result.estimated == estimated        # and the re-run says where
    # offline, a curvature that keeps coming is never lost, however late in the run
    again, _ = controller_from_params(params)
    for role, sample in _feed(_inputs(300, math.inf)):
        if again.accept(role, sample) is None and role == 'lateral_error':
            assert again.compute() is not None and not again.law.curvature_estimated()


def test_replay_offline_says_where_the_law_ran_on_its_estimate(monkeypatch, capsys, tmp_path):
    import argparse
    import json

    from lookahead_control.bags import replay_node
    run, estimated = _recorded({'law': 'cg_compensated'})
    monkeypatch.setattr(replay_node, 'load_run', lambda bag, topics, node, **_: run)
    args = argparse.Namespace(bag=Path('synthetic'), param=[], topic=[], order='receive',
                              json=tmp_path / 'report.json', check=0.0, node=None)
    assert replay_node.offline(args) == 0
    out = capsys.readouterr().out
    assert (f'the law ran on its curvature estimate in {estimated} of 300 answers'
            in out), out
    report = json.loads((tmp_path / 'report.json').read_text())
    assert report['curvature_estimated'] == 131
    assert report['curvature_judged_otherwise_on_stamps'] == 0
    assert report['curvature_judgment_followed'] == 300 and 'otherwise' not in out


@pytest.mark.parametrize('seen_until_ns', [0, 1_000_000_000])
def test_a_curvature_the_controller_did_not_receive_is_re_run_as_the_controller_ran(
        monkeypatch, capsys, tmp_path, seen_until_ns):
    # the bag holds a curvature the controller never got (remapped, or a QoS mismatch from
    # 1 s on): before, the re-run used it, 20 mrad off with nothing saying why; the node's
    # ~/debug now says per answer whether it ran on its estimate, and the re-run takes that
    import argparse
    import json

    from lookahead_control.bags import replay_node
    run, estimated = _recorded({'law': 'cg_compensated'}, math.inf, seen_until_ns)
    assert estimated == (300 if seen_until_ns == 0 else 300 - 100 - 19)
    result = rerun(run, order='receive')
    assert result.max_diff == 0.0 and result.compared == 300
    assert result.estimated == estimated and result.followed == 300
    assert result.judged_otherwise == estimated         # the stamps alone: all received
    # judged on the stamps (the bag does not say: an older one), it is off
    bare = replace(run, debug=Samples.empty())
    blind = rerun(bare, order='receive')
    assert blind.max_diff > 0.005 and blind.estimated == blind.followed == 0
    monkeypatch.setattr(replay_node, 'load_run', lambda bag, topics, node, **_: run)
    args = argparse.Namespace(bag=Path('synthetic'), param=[], topic=[], order='receive',
                              json=tmp_path / 'report.json', check=0.0, node=None)
    assert replay_node.offline(args) == 0
    out = capsys.readouterr().out
    assert ("the re-run took the recorded controller's own judgment of the curvature "
            f'(its /controller/debug) in 300 answers; on the stamps alone '
            f'{estimated} would have gone otherwise') in out, out
    report = json.loads((tmp_path / 'report.json').read_text())
    assert report['curvature_judgment_followed'] == 300
    assert report['curvature_judged_otherwise_on_stamps'] == estimated
    assert report['curvature_estimated'] == estimated


@pytest.mark.parametrize('preview', [True, False])
def test_the_paper_law_as_arrays_takes_a_lost_curvature_as_0_as_the_node(preview):
    # the vectorized re-run of the paper law (analyze without the debug topic) took the
    # last curvature to the end of the run, the node 0 once it was lost: 0.016 rad apart
    params = {'law': 'paper', 'use_curvature_preview': preview}
    run, _ = _recorded(params)
    result = rerun(run, order='receive')
    assert result.compared == 300 and result.max_diff == 0.0, result.max_diff
    stamps, law = rerun_law(run, order='receive')
    assert stamps.size == 300
    for i, stamp in enumerate(stamps):
        for name in ('y_ref', 'error', 'steering'):
            assert float(getattr(law, name)[i]) == pytest.approx(
                getattr(result.commands[int(stamp)].law, name), rel=1e-12, abs=1e-15), (
                    stamp, name)


def test_a_lockstep_answer_does_not_wait_for_a_lost_curvature():
    # wait_for_matching_stamps (lockstep) waited for a curvature once seen, lost or not:
    # each answer after a map was lost waited sync_timeout of wall clock (S2 at 37 m/s
    # with sim_plant curvature_stop 4 s: 38 s instead of 6 s), for the same answer
    core, _ = controller_from_params({'law': 'cg_compensated'})
    timeout_ns = int(core.safety.input_timeout * 1e9)
    stamp = 2_000_000_000
    for role, sample in (('road_curvature', CurvatureSample(stamp - timeout_ns, RHO, 0.0)),
                         ('yaw', YawSample(stamp, 0.002, SPEED * RHO, 0.0)),
                         ('velocity', VelocitySample(stamp, SPEED, 0.0)),
                         ('lateral_error', LateralErrorSample(stamp, 0.0, 0.1))):
        assert core.accept(role, sample, stamp) is None
    assert not core.inputs_at(stamp)        # not lost yet (input_timeout ago): waited for
    later = stamp + PERIOD_NS
    for role, sample in (('yaw', YawSample(later, 0.002, SPEED * RHO, 0.0)),
                         ('velocity', VelocitySample(later, SPEED, 0.0))):
        assert core.accept(role, sample, later) is None
    assert core.inputs_at(later)            # lost: not waited for
    assert not core.inputs_at(later + PERIOD_NS)      # yaw and velocity still are


@pytest.mark.parametrize('law', ['paper', 'cg_compensated', 'stanley'])
def test_any_law_is_re_run_with_the_curvature_the_node_judged_in(law):
    # in lockstep the node receives a step's curvature on the previous step's clock (the
    # simulator sends /clock after the measurements): it lost a stopped curvature a step
    # before the stamps say. The paper law had no debug flag: judged on the stamps, the
    # answer at the switch-over was 20 mrad off (S2 37 m/s over DDS, curvature_stop 4 s);
    # ~/debug curvature_received (any law) now says what the node had
    rows = _inputs(300, 1_500_000_000)
    node, _ = controller_from_params({'law': law})
    commands, flags = {}, {}
    for role, sample in _feed(rows):
        now = sample.stamp_ns - (PERIOD_NS if role == 'road_curvature' else 0)
        assert node.accept(role, sample, now) is None
        if role == 'lateral_error':
            commands[sample.stamp_ns] = node.compute(sample.stamp_ns).steering
            flags[sample.stamp_ns] = float(node.curvature_in)
    assert sum(1 for f in flags.values() if not f) == 300 - 150 - 19 + 1   # a step early
    run = _bag(rows, commands, {'curvature_received': flags}, {'law': law})
    result = rerun(run, order='stamp')
    assert result.compared == 300 and result.max_diff == 0.0, result.max_diff
    assert result.followed == 300 and result.judged_otherwise == 1
    blind = rerun(replace(run, debug=Samples.empty()), order='stamp')
    assert blind.max_diff > 1e-6, blind.max_diff       # from the switch-over step


def test_a_law_set_at_run_time_is_re_run_where_the_node_switched_it():
    # `ros2 param set /controller law paper` mid-run: the bag's parameters are those of
    # the start, and the re-run ran that law throughout (over DDS, S2 37 m/s switched at
    # 5 s: 40.6 mrad apart from there on, unexplained); the node's debug names the law of
    # each answer, and the re-run now switches where it did
    rows = _inputs(300, math.inf)
    node, _ = controller_from_params({'law': 'cg_compensated'})
    commands, laws = {}, {}
    for role, sample in _feed(rows):
        assert node.accept(role, sample, sample.stamp_ns) is None
        if role == 'lateral_error':
            k = sample.stamp_ns // PERIOD_NS
            law = 'paper' if 100 < k <= 200 else 'cg_compensated'
            if law != node.law_name:
                node.configure(node.vehicle, node.params, node.acceleration_source,
                               node.use_preview, law=law)
            commands[sample.stamp_ns] = node.compute(sample.stamp_ns).steering
            laws[sample.stamp_ns] = law
    columns = {f'law:{name}': {s: 0.0 if law == name else math.nan
                               for s, law in laws.items()}
               for name in ('paper', 'cg_compensated')}
    columns['law:mpc'] = dict.fromkeys(laws, 0.0)     # no such law: left out
    run = _bag(rows, commands, columns, {'law': 'cg_compensated'})
    result = rerun(run, order='stamp')
    assert result.max_diff == 0.0 and result.compared == 300, result.max_diff
    assert result.law_switches == 2
    blind = rerun(replace(run, debug=Samples.empty()), order='stamp')
    assert blind.max_diff > 0.01 and blind.law_switches == 0
    # an override of the law runs it throughout
    forced = rerun(run, {'law': 'paper'}, order='stamp')
    assert forced.law_switches == 0 and forced.max_diff > 0.01
    # and analyze names the laws the run had, not only the start-up one
    from lookahead_control.analysis.bag_analysis import run_labels
    assert run_labels(run)['law'] == 'cg_compensated -> paper -> cg_compensated'
    assert run_labels(replace(run, debug=Samples.empty()))['law'] == 'cg_compensated'


def test_a_simulator_run_is_re_run_in_stamp_order_by_default():
    # a realtime simulator run (the node not waiting for matching stamps): the recorder
    # received a step's lateral error before that step's curvature, which the node did
    # not; the default, receive order, re-ran it 50 mrad off over DDS (probe23), stamp
    # order exactly. Receive order stays the default for a real vehicle's bag.
    run, _ = _recorded({'law': 'cg_compensated'}, math.inf)
    late = run.inputs['road_curvature']
    run.inputs['road_curvature'] = Samples(late.stamp_ns + 5, late.stamp_ns, late.order,
                                           late.values)
    run = replace(run, debug=Samples.empty())
    vehicle = rerun(run)
    assert vehicle.order == 'receive' and vehicle.max_diff > 1e-4
    simulated = rerun(replace(run, plant_params={'mode': 'realtime'}))
    assert simulated.order == 'stamp' and simulated.max_diff == 0.0
    assert rerun(replace(run, plant_params={'mode': 'realtime'}),
                 order='receive').max_diff == vehicle.max_diff


def _conv_sample(role, msg):
    """Return the controller's sample of a message, as the node converts it."""
    from lookahead_control.ros import conversions as conv
    return {'lateral_error': conv.from_lateral_error, 'yaw': conv.from_yaw,
            'velocity': conv.from_velocity, 'road_curvature': conv.from_curvature}[role](msg)


def controllers_bag(path, params, description=None, recorded=None, steps=60, debug=True,
                    scale=None, unrecorded=()):
    """
    Write a bag of the controllers of ``params``, each its topics and its core's commands.

    :param path: the bag directory.
    :param params: node -> its parameters (nodes without ``law`` get no topics).
    :param description: more run description entries.
    :param recorded: the nodes whose parameters the bag records (default: all).
    :param steps: steps of each controller's run (:func:`_inputs`).
    :param debug: add each controller's debug topic (no message on it).
    :param scale: node -> a factor on its inputs (another curve, another error).
    :param unrecorded: parameter names the controllers ran with but the bag does not
        record (a bag from before they existed).
    """
    import yaml

    from lookahead_control.bags.rosbag_io import (BagWriter, PARAMETERS_KEY, qos_from_ints,
                                                  serialize_cdr, typestore)
    from lookahead_control.bags.run_data import node_topics
    from lookahead_control.ros import conversions as conv
    store = typestore()
    qos = [qos_from_ints({'reliability': 1, 'durability': 2, 'depth': 10})]
    encode = {'lateral_error': lambda s: conv.to_lateral_error(s.stamp_ns, 'b', s.distance,
                                                               s.value),
              'yaw': lambda s: conv.to_yaw(s.stamp_ns, 'b', s.relative_yaw, s.yaw_rate,
                                           s.accel_x),
              'velocity': lambda s: conv.to_velocity(s.stamp_ns, 'b', s.v_x, s.v_y, 0.0),
              'road_curvature': lambda s: conv.to_curvature(s.stamp_ns, 'b', [(0.0, s.rho)])}
    msgtypes = {'lateral_error': 'geometry_msgs/msg/PointStamped', 'yaw': 'sensor_msgs/msg/Imu',
                'velocity': 'geometry_msgs/msg/TwistStamped',
                'road_curvature': 'geometry_msgs/msg/PolygonStamped',
                'steering': 'sensor_msgs/msg/JointState'}
    writer = BagWriter(path)
    messages = []
    for node, own in params.items():
        if 'law' not in own:
            continue
        topics = node_topics(node)
        core, _ = controller_from_params(own)
        rows = _inputs(steps, 10**12)
        factor = (scale or {}).get(node)
        if factor is not None:
            rows = {role: [s._replace(**{f: factor * v for f, v in s._asdict().items()
                                         if f != 'stamp_ns' and isinstance(v, float)})
                           for s in samples] for role, samples in rows.items()}
        for role, sample in _feed(rows):
            msg = encode[role](sample)
            messages.append((topics[role], sample.stamp_ns, RANK[role], msg))
            assert core.accept(role, _conv_sample(role, msg), sample.stamp_ns) is None
            if role == 'lateral_error':
                command = core.compute(sample.stamp_ns)
                messages.append((topics['steering'], sample.stamp_ns, 4,
                                 conv.to_steering(sample.stamp_ns, command.steering, 0.0)))
        for role, msgtype in msgtypes.items():
            writer.add_topic(topics[role], msgtype, qos)
        if debug:
            writer.add_topic(topics['debug'], 'sensor_msgs/msg/JointState', qos)
    for topic, stamp, rank, msg in sorted(messages, key=lambda m: (m[1], m[2])):
        writer.write(topic, 10**12 + stamp + rank, serialize_cdr(msg, store))
    writer.describe(PARAMETERS_KEY, yaml.safe_dump(
        {node: {'ros__parameters': {k: v for k, v in own.items() if k not in unrecorded}}
         for node, own in params.items() if recorded is None or node in recorded}))
    for key, text in (description or {}).items():
        writer.describe(key, text)
    writer.close()


def check_a_20_hz_bag_predating(name, now, tmp_path, capsys, monkeypatch, **params):
    """
    Check replay's words and re-run of a 20 Hz bag recorded before parameter ``name``.

    The bag's controller ran the law with ``name`` 0 (as before it existed) and does not
    record it: replay says so, fills in 0 and re-runs the bag's commands; ``-p`` with
    the value of ``now`` is another law at 20 Hz; a bag of another law is not told.

    :param name: the parameter's name.
    :param now: its default since (a value that moves the commands at 20 Hz).
    :param tmp_path: pytest's.
    :param capsys: pytest's.
    :param monkeypatch: pytest's.
    :param params: the bag's other recorded controller parameters.
    """
    import json

    from lookahead_control.bags import replay_node
    from lookahead_control.core.cli import run_tool
    monkeypatch.setattr(sys.modules[__name__], 'PERIOD_NS', 50_000_000)   # 20 Hz frames
    params = {'law': 'cg_compensated', 'use_curvature_preview': True,
              'align_inputs': 'with_prediction', 'curvature_at_yaw_stamp': False,
              **params, name: 0.0}
    bag, report = tmp_path / 'old', tmp_path / 'old.json'
    controllers_bag(bag, {'/controller': params}, steps=80, unrecorded=(name,))
    # (1e-8: the yaw goes through the Imu's quaternion)
    assert run_tool(replay_node.main, [str(bag), '--offline', '--check', '1e-8', '--json',
                                       str(report)]) == 0
    out = capsys.readouterr().out
    assert f'predates {name}' in out and f'{name}=0;' in out, out
    assert json.loads(report.read_text())['parameters_as_it_ran'] == {name: 0.0}
    assert run_tool(replay_node.main, [str(bag), '--offline', '--check', '1e-8', '-p',
                                       f'{name}={now}']) == 1
    assert 'predates' not in capsys.readouterr().out
    # a bag of another law: it has no such parameter, nothing to say
    other = tmp_path / 'lqr'
    controllers_bag(other, {'/controller': {**params, 'law': 'lqr'}}, steps=20,
                    unrecorded=(name,))
    assert run_tool(replay_node.main, [str(other), '--offline', '--check', '1e-8']) == 0
    assert 'predates' not in capsys.readouterr().out


def _two_controller_bag(path):
    """Write a bag of two vehicles: ``/controller`` and ``/car_b/controller``, 120 steps."""
    controllers_bag(path, {'/controller': {'law': 'paper'},
                           '/car_b/controller': {'law': 'stanley', 'stanley.gain': 2.5}},
                    steps=120, debug=False, scale={'/car_b/controller': 0.5})


def test_replay_offline_node_re_runs_the_named_controller_of_a_two_vehicle_bag(
        tmp_path, capsys):
    # before: no --node; --topic steering=/car_b/steering compared car b's commands with
    # /controller's law (paper) on /controller's inputs, and no option named car b's
    # parameters or debug
    import json

    from lookahead_control.bags import replay_node
    from lookahead_control.core.cli import run_tool
    bag = tmp_path / 'two'
    _two_controller_bag(bag)
    for i, node in enumerate(([], ['--node', '/controller'], ['--node', '/car_b/controller'])):
        report = tmp_path / f'{i}.json'
        assert run_tool(replay_node.main, [str(bag), '--offline', '--check', '1e-9',
                                           '--json', str(report), *node]) == 0, node
        data = json.loads(report.read_text())
        assert data['compared'] == 120 and data['max_diff_rad'] <= 1e-9, data
        assert data['node'] == (node[-1] if node else '/controller')
    capsys.readouterr()
    # the old way: car b's steering against the other controller's law and inputs
    assert run_tool(replay_node.main, [str(bag), '--offline', '--check', '1e-6', '--topic',
                                       'steering=/car_b/steering']) == 1
    # a --topic still overrides one of the node's topics
    assert run_tool(replay_node.main, [str(bag), '--offline', '--check', '1e-6', '--node',
                                       '/car_b/controller', '--topic',
                                       'steering=/steering']) == 1
    capsys.readouterr()
    # a node the bag does not know, a name that is not one: one line each
    for node, words in (('/car_c/controller', ['/car_b/controller, /controller']),
                        ('car_b/controller', ['not a fully qualified node name']),
                        ('/car_b/', ['not a fully qualified']),
                        ('/1car/controller', ['not a fully qualified'])):
        assert run_tool(replay_node.main, [str(bag), '--offline', '--node', node]) == 2
        err = capsys.readouterr().err
        assert err.count('\n') == 1 and all(w in err for w in words), err
    # --node is for the offline re-run only
    assert run_tool(replay_node.main, [str(bag), '--node', '/car_b/controller']) == 2
    assert '--node: only with --offline' in capsys.readouterr().err


def test_analyze_node_names_the_controller_of_a_two_vehicle_bag(tmp_path):
    # before: analyze read /controller's parameters and topics whatever the bag held
    from lookahead_control.tools import analyze_tool
    bag = tmp_path / 'two'
    _two_controller_bag(bag)
    rows = {}
    for node in ('/controller', '/car_b/controller'):
        (run, _, row), = analyze_tool.analyze([bag], None, node)
        rows[node] = row
        assert run.controller_node == node and len(run.steering) == 120
    assert rows['/controller']['law'] == 'paper' and rows['/car_b/controller']['law'] == \
        'stanley'
    assert analyze_tool.main([str(bag), '--node', '/car_b/controller', '--out',
                              str(tmp_path / 'out'), '--no-plots']) == 0
    assert '| stanley |' in (tmp_path / 'out' / 'report.md').read_text()


def test_analyze_refuses_to_replace_a_file_of_its_names_it_did_not_write(tmp_path, capsys):
    # before: in a folder analyze wrote (--no-plots), a user's overlay.png was replaced by
    # the next run with plots without a word (compare has the same check since probe24)
    from lookahead_control.core.cli import run_tool
    from lookahead_control.tools import analyze_tool
    bag = tmp_path / 'two'
    _two_controller_bag(bag)
    out = tmp_path / 'out'
    assert analyze_tool.main([str(bag), '--out', str(out), '--no-plots']) == 0
    (out / 'overlay.png').write_bytes(b'my own figure')
    assert run_tool(analyze_tool.main, [str(bag), '--out', str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and 'overlay.png' in err and '--overwrite' in err, err
    assert (out / 'overlay.png').read_bytes() == b'my own figure'
    assert analyze_tool.main([str(bag), '--out', str(out), '--overwrite']) == 0
    assert (out / 'overlay.png').read_bytes()[:4] == b'\x89PNG'
    assert analyze_tool.main([str(bag), '--out', str(out)]) == 0        # its own now
    # a law labelled n/a (the bag names no schedule): before, its figure went to a folder
    # fig_n/ as a.png and the report linked a.png, which was not there
    assert not (out / 'fig_n').exists() and (out / 'fig_n_a.png').is_file()
    assert '](fig_n_a.png)' in (out / 'report.md').read_text()
    assert analyze_tool.output_names([]) == ['metrics.csv', 'metrics.json', 'report.md',
                                             'overlay.png', 'look_ahead_vs_speed.png']


def test_rerun_of_a_bag_from_before_the_integral_gain_schedule_keeps_its_constant_k_i(
        tmp_path, capsys):
    # before: a bag recorded before lane_keeping.low_speed_integral_gain existed (its law
    # ran with k_i = integral_gain at every speed) was re-run with the schedule's
    # defaults (0.05 1/s at and below 15 m/s): at 10 m/s the re-run differed from the
    # recorded commands and replay --check failed on a bag it should reproduce
    import json

    from lookahead_control.bags import replay_node
    from lookahead_control.core.cli import run_tool
    low = 'lane_keeping.low_speed_integral_gain'
    old = {'law': 'cg_compensated', 'lane_keeping.integral_gain': 0.3, low: 0.3}
    bag = tmp_path / 'old'
    # inputs scaled to 10 m/s; the old law's k_i (constant), the name not recorded
    controllers_bag(bag, {'/controller': old}, steps=300, scale={'/controller': 1.0 / 3.0},
                    unrecorded=(low,))
    run = load_run(bag)
    assert low not in run.controller_params
    assert run.controller_params['lane_keeping.integral_gain'] == 0.3
    result = rerun(run)
    # 1e-9: the yaw goes through the Imu's quaternion (as in the two-vehicle bag's test)
    assert result.compared == 300 and result.max_diff <= 1e-9, result.max_diff
    # the schedule (low_speed_integral_gain 0.05, the default from dev-kisched to dev-gate)
    # is another law here
    scheduled = rerun(run, {low: 0.05})
    assert scheduled.max_diff > 1e-4, scheduled.max_diff
    # an override of integral_gain is the old law with that constant k_i
    pinned = rerun(run, {'lane_keeping.integral_gain': 0.5, low: 0.5})
    assert rerun(run, {'lane_keeping.integral_gain': 0.5}).commands == pinned.commands
    assert pinned.max_diff > 1e-4
    # a bag that records the name keeps its value
    assert as_it_ran({**old, low: 0.05}) == {}
    report = tmp_path / 'old.json'
    assert run_tool(replay_node.main, [str(bag), '--check', '1e-9', '--json',
                                       str(report)]) == 0
    out = capsys.readouterr().out
    assert f'predates {low}' in out and f'{low}=0.3' in out, out
    assert json.loads(report.read_text())['parameters_as_it_ran'] == {low: 0.3}
    assert run_tool(replay_node.main, [str(bag), '--check', '1e-9', '-p', f'{low}=0.05']) == 1
    assert 'predates' not in capsys.readouterr().out


def test_rerun_of_a_bag_recorded_with_the_schedule_keeps_it(tmp_path):
    # a bag recorded while the schedule was the default (low_speed_integral_gain 0.05,
    # dev-kisched to dev-gate) re-runs its 0.05 as recorded, not today's default (0.3)
    from lookahead_control.core.lane_keeping import LaneKeepingParams
    low = 'lane_keeping.low_speed_integral_gain'
    assert LaneKeepingParams().low_speed_integral_gain == 0.3
    recorded = {'law': 'cg_compensated', 'lane_keeping.integral_gain': 0.3, low: 0.05}
    bag = tmp_path / 'scheduled'
    controllers_bag(bag, {'/controller': recorded}, steps=300,
                    scale={'/controller': 1.0 / 3.0})      # 10 m/s: the schedule's 0.05
    run = load_run(bag)
    assert run.controller_params[low] == 0.05 and as_it_ran(run.controller_params) == {}
    result = rerun(run)
    assert result.compared == 300 and result.max_diff <= 1e-9, result.max_diff
    assert rerun(run, {low: 0.3}).max_diff > 1e-4      # today's default is another law here


def _deactivated(law, off):
    """
    Return a run of the node, deactivated over the steps ``off``, and its bag.

    :return: ``(rows, commands, debug columns, bag)``.
    """
    rows = _inputs(300, math.inf)
    node, _ = controller_from_params({'law': law})
    commands, counts, numbers, activations = {}, {}, {}, 1
    for role, sample in _feed(rows):
        assert node.accept(role, sample, sample.stamp_ns) is None
        if role != 'lateral_error':
            continue
        k = sample.stamp_ns // PERIOD_NS
        if k in off:
            continue                            # inactive: nothing computed, nothing sent
        activations += k == off.stop            # on_activate
        commands[sample.stamp_ns] = node.compute(sample.stamp_ns).steering
        counts[sample.stamp_ns] = float(activations)
        numbers[sample.stamp_ns] = float(len(commands))
    columns = {'activations': counts, 'answers': numbers}
    return rows, commands, columns, _bag(rows, commands, columns, {'law': law})


@pytest.mark.parametrize('law, inactive_steps', [('cg_compensated', 50), ('cg_compensated', 10),
                                                 ('paper', 50)])
def test_inputs_received_while_deactivated_are_not_re_run(law, inactive_steps):
    # a deactivated node takes its inputs in and answers none: its law is not stepped,
    # and once activated again a time jump (0.5 s > max_gap) restarts it, or a step of
    # 0.1 s follows. The re-run stepped the law on them (dev-probe48 over DDS: 7.5 mrad
    # apart after a deactivate / activate); ~/debug activations now says where
    rows, commands, columns, run = _deactivated(law, range(100, 100 + inactive_steps))
    result = rerun(run, order='stamp')
    assert result.compared == 300 - inactive_steps and result.max_diff == 0.0, result.max_diff
    assert result.inactive_skipped == inactive_steps and result.inactive_lost == 0
    blind = rerun(replace(run, debug=Samples.empty()), order='stamp')
    assert blind.inactive_skipped == 0
    if law == 'cg_compensated':         # a law with a state (the paper law has none)
        assert blind.max_diff > 1e-4, blind.max_diff
    # an answer the recorder lost while the node stayed active is still re-run
    lost = next(iter(sorted(commands)[10:]))
    dropped = _bag(rows, {s: c for s, c in commands.items() if s != lost},
                   {name: {s: c for s, c in column.items() if s != lost}
                    for name, column in columns.items()}, {'law': law})
    again = rerun(dropped, order='stamp')
    assert again.inactive_skipped == inactive_steps and again.max_diff == 0.0
    assert lost in again.commands


def test_a_node_deactivated_before_its_first_answer_is_re_run_as_it_ran():
    # dev-probe52: deactivated before it answered anything and activated later, the node
    # left every lateral error before its first answer unanswered; the re-run stepped
    # the law on them (4.03 mrad over DDS, silently): the first answer's count is 2
    rows, commands, columns, run = _deactivated('cg_compensated', range(1, 50))
    assert columns['activations'][min(commands)] == 2.0
    result = rerun(run, order='stamp')
    assert result.inactive_skipped == 49 and result.max_diff == 0.0, result.max_diff
    # autostarted (count 1 at the first answer): nothing before it is skipped
    _, _, _, started = _deactivated('cg_compensated', range(0))
    assert rerun(started, order='stamp').inactive_skipped == 0


def test_answers_lost_next_to_a_deactivation():
    # dev-probe52: the first answer after activating lost its steering but not its
    # debug: it was taken as unanswered and skipped (21 of 20 inputs, 1.6e-6 rad)
    rows, commands, columns, run = _deactivated('cg_compensated', range(100, 120))
    first_after = sorted(commands)[99]
    kept = Samples(*(np.delete(getattr(run.steering, f), 99)
                     for f in ('recv_ns', 'stamp_ns', 'order')),
                   {k: np.delete(v, 99) for k, v in run.steering.values.items()})
    assert first_after not in set(kept.stamp_ns.tolist())
    result = rerun(replace(run, steering=kept), order='stamp')
    assert result.inactive_skipped == 20 and result.inactive_lost == 0
    assert result.max_diff == 0.0 and first_after in result.commands
    # the last answer before it lost with its debug: the bag cannot tell it from an
    # input never answered; the count of answers says one is missing there
    last_before = sorted(commands)[98]
    dropped = _bag(rows, {s: c for s, c in commands.items() if s != last_before},
                   {name: {s: c for s, c in column.items() if s != last_before}
                    for name, column in columns.items()}, {'law': 'cg_compensated'})
    again = rerun(dropped, order='stamp')
    assert again.inactive_skipped == 21 and again.inactive_lost == 1


def test_a_bag_begun_while_the_node_was_deactivated_lost_no_answers():
    # dev-probe94 (lj4): a recorder started while the node was deactivated, after its
    # first answers: the bag's first answer counts them, and the lateral errors before
    # it came while inactive; replay said "the bag lost 284 answers next to a
    # deactivation" of answers given before the bag began
    from lookahead_control.bags.replay_node import late_join
    rows, commands, columns, _ = _deactivated('cg_compensated', range(100, 150))
    begun = 120 * PERIOD_NS                     # the recorder's start, while inactive
    late_rows = {role: [row for row in samples if row.stamp_ns >= begun]
                 for role, samples in rows.items()}
    kept = {s: c for s, c in commands.items() if s >= begun}
    bag = _bag(late_rows, kept, {name: {s: v for s, v in column.items() if s >= begun}
                                 for name, column in columns.items()},
               {'law': 'cg_compensated'})
    assert columns['answers'][min(kept)] == 100.0       # 99 answers before the bag
    result = rerun(bag, order='stamp')
    assert result.inactive_skipped == 30 and result.inactive_lost == 0
    assert result.compared == len(kept)
    # the re-run starts the law fresh where the node restarted its own (a time jump):
    # what differs is told as a late start, with the answers before the bag
    joined, first_diff = late_join(bag, result)
    assert joined == 99 and first_diff == result.max_diff > 0.0, (joined, first_diff)


def test_inputs_recorded_twice_are_counted_apart_from_refusals():
    # dev-probe96: a bag with every message twice re-ran equal, but replay put the 4000
    # refused copies down to 'a node older than a check'
    rows, commands = _paper_run(100, 'cg_compensated')
    twice = {role: [row for row in samples for _ in range(2)] for role, samples in rows.items()}
    result = rerun(_bag(twice, commands, {}, {'law': 'cg_compensated'}), order='stamp')
    assert result.compared == 100 and result.max_diff == 0.0, result.max_diff
    assert result.repeated == sum(len(samples) for samples in rows.values())
    assert result.refused == {}
    once = rerun(_bag(rows, commands, {}, {'law': 'cg_compensated'}), order='stamp')
    assert once.repeated == 0 and once.max_diff == 0.0


def _paper_run(steps, law='paper'):
    """Return the inputs of a curve and a law's answers (the paper's) as the node gave them."""
    rows = _inputs(steps, math.inf)
    node, _ = controller_from_params({'law': law})
    commands = {}
    for role, sample in _feed(rows):
        assert node.accept(role, sample, sample.stamp_ns) is None
        if role == 'lateral_error':
            commands[sample.stamp_ns] = node.compute(sample.stamp_ns).steering
    return rows, commands


def test_without_recorded_parameters_the_first_answers_law_is_no_run_time_set():
    # dev-probe55: a car recorded without --describe re-ran its debug's law, and replay
    # said 'the law was set at run time ... (1 switches)': the default law of the
    # re-run, not the node, had it otherwise
    rows, commands = _paper_run(100)
    columns = {'law:paper': dict.fromkeys(commands, 0.0),
               'law:cg_compensated': dict.fromkeys(commands, math.nan)}
    result = rerun(_bag(rows, commands, columns, {}), order='stamp')
    assert result.max_diff == 0.0 and result.compared == 100, result.max_diff
    assert result.law_switches == 0
    # with the start's parameters recorded, another law at the first answer was set
    # before the recorder joined: a set at run time
    started = rerun(_bag(rows, commands, columns, {'law': 'cg_compensated'}), order='stamp')
    assert started.max_diff == 0.0 and started.law_switches == 1


def test_the_re_run_counts_the_inputs_its_checks_refuse():
    # dev-probe56: a bag of a node older than a check (a zero quaternion, decoded as a
    # NaN yaw, which the node then used) re-ran 18.7 mrad apart and replay said nothing
    rows, commands = _paper_run(100)
    rows['yaw'][50] = rows['yaw'][50]._replace(relative_yaw=math.nan)
    result = rerun(_bag(rows, commands, {}, {'law': 'paper'}), order='stamp')
    assert result.refused == {'yaw': 1} and 'yaw' in result.last_refusal
    clean = rerun(_bag(_inputs(100, math.inf), commands, {}, {'law': 'paper'}), order='stamp')
    assert clean.refused == {} and clean.max_diff == 0.0


def _coalesced(law, skipped):
    """
    Return a run of the node whose answer-rate bound left the steps ``skipped`` unanswered.

    :return: ``(rows, commands, debug columns, bag)``.
    """
    rows = _inputs(300, math.inf)
    node, _ = controller_from_params({'law': law})
    commands, counts, numbers, coalesced = {}, {}, {}, 0
    for role, sample in _feed(rows):
        assert node.accept(role, sample, sample.stamp_ns) is None
        if role != 'lateral_error':
            continue
        if sample.stamp_ns // PERIOD_NS in skipped:
            coalesced += 1                      # taken in, left for a newer one
            continue
        commands[sample.stamp_ns] = node.compute(sample.stamp_ns).steering
        counts[sample.stamp_ns] = float(coalesced)
        numbers[sample.stamp_ns] = float(len(commands))
    columns = {'activations': dict.fromkeys(counts, 1.0), 'coalesced': counts,
               'answers': numbers}
    return rows, commands, columns, _bag(rows, commands, columns, {'law': law})


@pytest.mark.parametrize('skipped', [range(1, 4), range(100, 103), range(200, 260, 2)])
def test_lateral_errors_the_answer_rate_bound_coalesced_are_not_re_run(skipped):
    # dev-sc34: under max_answer_rate_hz the node leaves lateral errors that come too fast
    # for a newer one; ~/debug coalesced counts them, and the re-run skips them as the
    # node did (stepping the law on them moves its integral and estimate)
    rows, commands, columns, run = _coalesced('cg_compensated', set(skipped))
    result = rerun(run, order='stamp')
    assert result.coalesced_skipped == len(skipped) and result.coalesced_lost == 0
    assert result.inactive_skipped == 0
    assert result.compared == 300 - len(skipped) and result.max_diff == 0.0, result.max_diff
    blind = rerun(replace(run, debug=Samples.empty()), order='stamp')
    assert blind.coalesced_skipped == 0 and blind.max_diff > 1e-6, blind.max_diff
    # an answer the recorder lost (steering and debug) in such a stretch: counted
    last_before = sorted(commands)[skipped.start - 2] if skipped.start > 1 else None
    if last_before is not None:
        dropped = _bag(rows, {s: c for s, c in commands.items() if s != last_before},
                       {name: {s: c for s, c in column.items() if s != last_before}
                        for name, column in columns.items()}, {'law': 'cg_compensated'})
        again = rerun(dropped, order='stamp')
        assert again.coalesced_lost == 1, again.coalesced_lost


@pytest.mark.parametrize('lost', [range(100, 103), range(150, 250, 3)])
def test_lateral_errors_the_node_never_received_are_not_re_run(lost):
    # dev-probe74: in a flood the node's keep-last-10 reader lost 490-658 of 1500 lateral
    # errors that the recorder got; the re-run stepped the law on them (15.2 mrad apart,
    # without a word). Between two answers numbered one after the other nothing was
    # answered: those are skipped as the node never saw them
    rows = _inputs(300, math.inf)
    node, _ = controller_from_params({'law': 'cg_compensated'})
    commands, numbers = {}, {}
    for role, sample in _feed(rows):
        k = sample.stamp_ns // PERIOD_NS
        if role == 'lateral_error' and k in lost:
            continue                            # lost by the node's reader
        assert node.accept(role, sample, sample.stamp_ns) is None
        if role == 'lateral_error':
            commands[sample.stamp_ns] = node.compute(sample.stamp_ns).steering
            numbers[sample.stamp_ns] = float(len(commands))
    columns = {'activations': dict.fromkeys(numbers, 1.0), 'answers': numbers}
    run = _bag(rows, commands, columns, {'law': 'cg_compensated'})
    result = rerun(run, order='stamp')
    assert result.unreceived_skipped == len(lost)
    assert result.inactive_skipped == result.coalesced_skipped == 0
    assert result.compared == 300 - len(lost) and result.max_diff == 0.0, result.max_diff
    blind = rerun(replace(run, debug=Samples.empty()), order='stamp')
    assert blind.unreceived_skipped == 0 and blind.max_diff > 1e-6, blind.max_diff


def test_probe76_a_map_dropped_by_the_map_check_is_re_run_and_said_so(
        monkeypatch, capsys, tmp_path):
    # dev-probe76: the re-run of a bag whose map the node dropped matched, but replay said
    # the curvature was not in the bag or lost. A map the other way round on the curve
    import argparse
    import json

    from lookahead_control.bags import replay_node
    rows = _inputs(300, math.inf)
    rows['road_curvature'] = [CurvatureSample(c.stamp_ns, -RHO if c.stamp_ns * 1e-9 < 2.0
                                              else 0.0, 0.0) for c in rows['road_curvature']]
    params = {'law': 'cg_compensated'}
    node, _ = controller_from_params(params)
    commands, received, estimated, dropped = {}, {}, {}, 0
    for role, sample in _feed(rows):
        assert node.accept(role, sample, sample.stamp_ns) is None
        if role == 'lateral_error':
            commands[sample.stamp_ns] = node.compute(sample.stamp_ns).steering
            received[sample.stamp_ns] = float(node.curvature_in)
            estimated[sample.stamp_ns] = dict(node.law.debug_values())['curvature_estimated']
            dropped += node.map_check.dropped
    assert dropped > 100 and node.turning['curvature_dropped'] > 1.0
    run = _bag(rows, commands, {'curvature_received': received,
                                'curvature_estimated': estimated}, params)
    result = rerun(run, order='receive')
    assert result.max_diff == 0.0 and result.compared == 300
    assert result.dropped == dropped and result.estimated == sum(estimated.values())
    monkeypatch.setattr(replay_node, 'load_run', lambda bag, topics, node, **_: run)
    args = argparse.Namespace(bag=Path('synthetic'), param=[], topic=[], order='receive',
                              json=tmp_path / 'report.json', check=0.0, node=None)
    assert replay_node.offline(args) == 0
    out = capsys.readouterr().out
    assert f'in {dropped} of them it was received and dropped' in out, out
    assert json.loads((tmp_path / 'report.json').read_text())['curvature_dropped'] == dropped
