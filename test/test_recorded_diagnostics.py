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
What the controller told: its recorded /diagnostics in analyze, its checks in replay.

dev-sc49: a bag of a run the controller warned of (a lateral error in cm, a yaw rate
frozen, v_y exactly 0 while turning) gave a metrics row and a report without a word of
it, and its re-run printed none of what the checks found.
"""

from __future__ import annotations

import json
import math

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from lookahead_control.analysis.bag_analysis import bag_row, finished_at, run_series
from lookahead_control.analysis.diagnostics_summary import (reason_name, split_reasons,
                                                            summarize)
from lookahead_control.bags import replay_node
from lookahead_control.bags.recorded_diagnostics import controller_reports, StatusReport
from lookahead_control.bags.rosbag_io import BagWriter, qos_from_ints, serialize_cdr, typestore
from lookahead_control.bags.run_data import load_run, rerun
from lookahead_control.ros import conversions as conv
from lookahead_control.tools.analyze_tool import analyze, write_outputs
import pytest
from std_msgs.msg import String

START = 1_000_000_000_000
TYPES = {'/lateral_error': 'geometry_msgs/msg/PointStamped', '/yaw': 'sensor_msgs/msg/Imu',
         '/velocity': 'geometry_msgs/msg/TwistStamped', '/steering': 'sensor_msgs/msg/JointState'}


def _bag(path, statuses=(), steps=1000, yaw_rate=0.0, jump_at=None):
    """
    Write a bag of a car at 20 m/s on the lane, and ``(stamp_ns, [status])`` diagnostics.

    :param yaw_rate: the yaw rate sent [rad/s] (v_y is sent as exactly 0).
    :param jump_at: the step from which the stamps are 5 s earlier (a time jump).
    """
    store = typestore()

    def serialize_message(msg):
        return serialize_cdr(msg, store)

    writer = BagWriter(path)
    qos = [qos_from_ints({'reliability': 1, 'durability': 2, 'depth': 10})]
    for topic, msgtype in TYPES.items():
        writer.add_topic(topic, msgtype, qos)
    if statuses:
        writer.add_topic('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray', qos)
    for k in range(steps):
        stamp = k * 10_000_000 - (5_000_000_000 if jump_at is not None and k >= jump_at
                                  else 0)
        recv = START + k * 10_000_000
        writer.write('/yaw', recv, serialize_message(conv.to_yaw(stamp, 'b', 0.0, yaw_rate,
                                                                 0.0)))
        writer.write('/velocity', recv, serialize_message(
            conv.to_velocity(stamp, 'b', 20.0, 0.0, 0.0)))
        writer.write('/lateral_error', recv + 1, serialize_message(
            conv.to_lateral_error(stamp, 'b', 0.0, 0.0)))
        writer.write('/steering', recv + 2, serialize_message(conv.to_steering(stamp, 0.0, 0.0)))
    for stamp, status in statuses:
        array = DiagnosticArray(status=status)
        array.header.stamp = conv.ns_to_stamp(stamp)
        writer.write('/diagnostics', START + stamp, serialize_message(array))
    writer.close()


def _status(level, message, node='/controller', values=()):
    from diagnostic_msgs.msg import KeyValue
    return DiagnosticStatus(level=level, name=conv.controller_status_name(node),
                            message=message, hardware_id='lookahead_control',
                            values=[KeyValue(key=k, value=v) for k, v in values])


def test_the_node_s_status_is_named_after_it(active_controller):
    # two controllers (vehicles in namespaces) share the one /diagnostics
    assert active_controller.diagnostics().name == 'lookahead_control: /controller'


def test_a_bag_s_warnings_are_in_its_row_and_its_report(active_controller, tmp_path):
    # the statuses the node itself gives: a lateral error in cm found for 1.5 s
    node = active_controller
    first = node.diagnostics()
    node.core.turning['lateral_error_out_of_scale'] += 1.5
    node.core.lateral_scale_seen = 101.0
    warned = node.diagnostics()
    quiet = node.diagnostics()
    assert [ord(s.level) for s in (first, warned, quiet)] == [0, 1, 0]
    # another vehicle's controller in the same bag, at ERROR: not this one's
    other = _status(2, 'stale inputs: yaw', '/car_b/controller')
    _bag(tmp_path / 'bag', [(1_000_000_000, [first]), (2_000_000_000, [warned, other]),
                            (3_000_000_000, [quiet])])
    run = load_run(tmp_path / 'bag')
    assert [r.level for r in run.diagnostics.reports] == [0, 1, 0]
    row = bag_row(run, run_series(run))
    assert row['diagnostics'] == 'WARN'
    assert ("diagnostics: WARN 'lateral_error out of scale with the motion relative_yaw, v_x "
            "and v_y predict' in 1 of 3 statuses, first told at t = 2 s") in row['notes']
    report = write_outputs(analyze([tmp_path / 'bag']), tmp_path / 'out', plots=False)
    text = report.read_text()
    section = text[text.index('## What the controller told'):]
    assert '- `bag`: 3 statuses of /controller (OK 2, WARN 1)' in section
    # the reason in full, as the node told it, and the counter it left
    assert ('  - WARN first told at t = 2 s, in 1: lateral_error out of scale with the motion '
            'relative_yaw, v_x and v_y predict for 1.50 s (it moves 101 times as far): a '
            'lateral error in cm') in section
    assert 'as metres and radians (docs/safety.md)\n' in section      # in full
    assert 'lateral_error_out_of_scale [s] 1.500' in section
    assert 'stale inputs' not in section
    assert [r.level for r in controller_reports(tmp_path / 'bag',
                                                '/car_b/controller').reports] == [2]
    # the column is in the CSV and the JSON
    rows = json.loads((tmp_path / 'out' / 'metrics.json').read_text())
    assert rows[0]['diagnostics'] == 'WARN'


def test_a_bag_without_diagnostics_says_so(tmp_path):
    _bag(tmp_path / 'bag')
    run = load_run(tmp_path / 'bag')
    assert run.diagnostics is None
    row = bag_row(run, run_series(run))
    assert row['diagnostics'] == '-' and 'diagnostics:' not in row['notes']
    report = write_outputs(analyze([tmp_path / 'bag']), tmp_path / 'out', plots=False)
    assert '- `bag`: no /diagnostics in the bag' in report.read_text()


def test_a_bag_from_before_the_status_carried_the_node_s_name(tmp_path):
    legacy = DiagnosticStatus(level=2, name=conv.LEGACY_STATUS_NAME,
                              message='stale inputs: yaw (no message for 0.5 s)')
    _bag(tmp_path / 'bag', [(500_000_000, [legacy])])
    row = bag_row(*(lambda run: (run, run_series(run)))(load_run(tmp_path / 'bag')))
    assert row['diagnostics'] == 'ERROR'
    assert "ERROR 'stale inputs' in 1 of 1 statuses, first told at t = 0.5 s" in row['notes']
    # the old name is the node's when the bag records no other controller; else whose it
    # is is not known (dev-probe110: an old two-vehicle bag credited /car_b's ERROR to
    # /controller, and a namespaced controller's old bag read '0 statuses')
    assert len(controller_reports(tmp_path / 'bag', '/car_b/controller').reports) == 1
    both = controller_reports(tmp_path / 'bag', '/controller',
                              ['/controller', '/car_b/controller'])
    assert both.reports == [] and both.legacy_unattributed == 1
    assert 'left out: the bag records other controllers too' in both.notes()[0]


def test_reasons_split_outside_parentheses_and_are_named_by_their_words():
    message = ('law restarts: 2 (a non-finite law output: 1; lateral errors further apart '
               'than lane_keeping.max_gap 0.5 s: 1; integral and estimate start again); '
               'steering oscillates for 1.20 s (+-56 mrad at 1.50 Hz): an actuator delay; '
               'yaw_rate hardly varies while the steering and the relative yaw do, for 2.00 '
               's (it does not vary at all); inactive')
    reasons = split_reasons(message)
    assert len(reasons) == 4 and reasons[-1] == 'inactive'
    assert [reason_name(r) for r in reasons] == [
        'law restarts', 'steering oscillates',
        'yaw_rate hardly varies while the steering and the relative yaw do', 'inactive']
    assert split_reasons('ok') == [] and split_reasons('') == []
    assert reason_name('sim clock stopped at 3.000 s for 2.0 s (wall)') == 'sim clock stopped'
    assert reason_name('late: yaw 120 ms (> latency_warn 100 ms)') == 'late'


def test_the_summary_keeps_each_reason_s_first_moment_and_worst_level():
    reports = [StatusReport(2_000_000_000, 0, 1, 'rejected: 1 (last: yaw: not finite)',
                            (('rejected', '1'), ('age max yaw [s]', '0.010000'))),
               StatusReport(3_000_000_000, 0, 2, 'stale inputs: yaw; rejected: 4 (last: x)',
                            (('rejected', '5'), ('time_jumps', '0'),
                             ('steering oscillation max [rad]', '0.010000'),
                             ('yaw_rate_still [s]', '0.250'), ('compliance memory [x model]',
                                                               '1.100'))),
               StatusReport(4_000_000_000, 0, 0, 'ok', (('rejected', '5'),))]
    summary = summarize(reports, 1_000_000_000)
    assert summary.worst == 'ERROR' and summary.levels == (1, 1, 1, 0)
    rejected, stale = summary.told
    assert (rejected.name, rejected.level, rejected.reports, rejected.first_s) == (
        'rejected', 2, 2, 1.0)
    assert rejected.example == 'rejected: 1 (last: yaw: not finite)'
    assert (stale.name, stale.first_s) == ('stale inputs', 2.0)
    # the counters of the last status only, those not 0 and counted from the start
    assert summary.counters == (('rejected', '5'),)
    assert summarize(reports[:2], 0).counters == (('rejected', '5'),
                                                  ('yaw_rate_still [s]', '0.250'))
    assert summarize([], 0).worst == '-'
    # a reason the node tells at OK is OK beside a WARN (dev-probe114: 'duplicates' and
    # 'demand capped' read WARN in a status whose WARN was an echo's)
    both = StatusReport(5_000_000_000, 0, 1, 'duplicates: 80 messages (so far: yaw 80); echo: '
                        'messages taken that came again (yaw 40 of 40); demand capped: 2 (x)', ())
    told = {t.name: t.level for t in summarize([both], 0).told}
    assert told == {'duplicates': 0, 'echo': 1, 'demand capped': 0}


def test_replay_says_what_the_re_run_s_checks_found(tmp_path, capsys):
    # turning at 0.1 rad/s with v_y exactly 0 and no road_curvature for 10 s, and the
    # stamps 5 s back at 6 s: what the node's /diagnostics would have warned of
    _bag(tmp_path / 'bag', steps=1000, yaw_rate=0.1, jump_at=600)
    result = rerun(load_run(tmp_path / 'bag'))
    assert result.told['time_jumps'] == 1.0
    assert result.told['v_y_exactly_zero'] == pytest.approx(9.98, abs=0.05)
    assert result.told['turning_without_curvature'] == pytest.approx(9.98, abs=0.05)
    assert 'lateral_error_out_of_scale' not in result.told
    out = tmp_path / 'replay.json'
    assert replay_node.main([str(tmp_path / 'bag'), '--offline', '--json', str(out)]) == 0
    printed = capsys.readouterr().out
    assert ("replay: the re-run's checks found, as the node's /diagnostics names them: "
            'turning_without_curvature 9.9') in printed
    assert 'time_jumps 1 (docs/safety.md' in printed
    told = json.loads(out.read_text())['checks_told']
    assert told['time_jumps'] == 1 and math.isclose(told['v_y_exactly_zero'],
                                                    result.told['v_y_exactly_zero'])
    # a quiet run says nothing of it
    _bag(tmp_path / 'quiet', steps=300)
    assert rerun(load_run(tmp_path / 'quiet')).told == {}
    assert replay_node.main([str(tmp_path / 'quiet'), '--offline']) == 0
    assert 'checks found' not in capsys.readouterr().out


def test_after_a_finished_scenario_no_status_counts():
    # every demo run's /diagnostics ended on 'sim clock stopped' (the simulator had
    # finished, the controller ran on): its diagnostics column read WARN for nothing that
    # happened in the run; and 'road_curvature lost' went on being told after it
    lost = 'road_curvature lost: no curvature feed-forward'
    stopped = 'sim clock stopped at 9.990 s for 1.0 s (wall)'
    reports = [StatusReport(5_000_000_000, 5_000_000_000, 1, lost, ()),
               StatusReport(9_990_000_000, 10_400_000_000, 1, f'{lost}; {stopped}', ()),
               StatusReport(9_990_000_000, 11_400_000_000, 2,
                            f'{lost}; {stopped}; saturated: 1', (('saturated', '1'),))]
    summary = summarize(reports, 0, end_recv_ns=10_000_000_000)
    assert summary.reports == 1 and summary.worst == 'WARN'
    assert [(t.name, t.reports) for t in summary.told] == [('road_curvature lost', 1)]
    assert [(t.name, t.reports, t.level) for t in summary.at_end] == [
        ('road_curvature lost', 2, 2), ('sim clock stopped', 2, 2), ('saturated', 1, 2)]
    assert summary.counters == (('saturated', '1'),)
    # without an end (a real vehicle, a run stopped early): every status is the run's
    assert summarize(reports, 0).worst == 'ERROR' and summarize(reports, 0).reports == 3


def test_a_run_without_a_finished_scenario_has_no_end(tmp_path):
    # dev-probe111: a vehicle whose sensors died 6 s into its run read OK, its ten ERROR
    # 'stale inputs' after its last input called 'its end, not a fault in it'
    stale = 'stale inputs: lateral_error, yaw, velocity'
    _bag(tmp_path / 'bag', [(3_000_000_000, [_status(0, 'ok')]),
                            (10_600_000_000, [_status(2, stale)])])
    run = load_run(tmp_path / 'bag')
    assert finished_at(run) is None
    row = bag_row(run, run_series(run))
    assert row['diagnostics'] == 'ERROR'
    assert "ERROR 'stale inputs' in 1 of 2 statuses, first told at t = 10.6 s" in row['notes']
    report = write_outputs(analyze([tmp_path / 'bag']), tmp_path / 'out', plots=False)
    assert 'after the simulator finished' not in report.read_text()


def test_every_reason_of_the_node_is_one_reason_with_its_name(active_controller):
    # dev-probe110: five reasons held '; ' outside parentheses and were cut in two: the
    # notes listed 'the law paper takes the curvature as the truth' as a warning of its own
    node = active_controller
    node.diagnostics()
    core = node.core
    for name in core.turning:
        core.turning[name] += 2.0
    for name in node.counters:
        node.counters[name] += 3
    core.time_jumps += 1
    core.law_restarts += 1
    core.law_restart_causes['gap'] = core.law_restart_causes.get('gap', 0) + 1
    core.rejected['yaw'] = 2
    core.last_rejection = 'yaw: not finite; bad (x)'
    core.duplicates.update({'yaw': 1, 'velocity': 2})
    core.taken.update({'yaw': 4, 'velocity': 4})
    core.duplicated.update({'yaw': 2})
    core.speed_seen, core.lateral_scale_seen, core.yaw_scale_seen = 3.6, 100.0, 57.0
    core.still_seen = math.inf
    names = [reason_name(r) for r in split_reasons(node.diagnostics().message)]
    assert names == [
        'rejected', 'saturated', 'rate limited', 'low speed', 'd v clamped', 'time jumps',
        'law restarts', 'duplicates', 'echo', 'demand capped', 'approach clipped',
        'turning without road_curvature',
        'velocity v_y exactly 0 while turning', 'road_curvature disagrees with the yaw rate',
        'steering oscillates', 'lateral_error moves against relative_yaw',
        'yaw_rate hardly varies while the steering and the relative yaw do',
        'v_x out of scale with the curvature preview',
        'lateral_error out of scale with the motion relative_yaw, v_x and v_y predict',
        'relative_yaw out of scale with the motion yaw_rate - v_x * curvature']


def _raw_bag(path, messages, msgtype='diagnostic_msgs/msg/DiagnosticArray',
             topic='/diagnostics'):
    """Write 2 s of the lane bag with raw ``(recv_ns, bytes)`` messages on /diagnostics."""
    store = typestore()
    writer = BagWriter(path)
    qos = [qos_from_ints({'reliability': 1, 'durability': 2, 'depth': 10})]
    for name, kind in TYPES.items():
        writer.add_topic(name, kind, qos)
    writer.add_topic(topic, msgtype, qos)
    for k in range(200):
        stamp = k * 10_000_000
        writer.write('/yaw', START + stamp, serialize_cdr(conv.to_yaw(stamp, 'b', 0.0, 0.0, 0.0),
                                                          store))
        writer.write('/velocity', START + stamp, serialize_cdr(
            conv.to_velocity(stamp, 'b', 20.0, 0.0, 0.0), store))
        writer.write('/lateral_error', START + stamp + 1, serialize_cdr(
            conv.to_lateral_error(stamp, 'b', 0.0, 0.0), store))
        writer.write('/steering', START + stamp + 2, serialize_cdr(
            conv.to_steering(stamp, 0.0, 0.0), store))
    for recv, data in messages:
        writer.write(topic, START + recv, data)
    writer.close()


def _array_bytes(statuses, stamp_ns=500_000_000):
    array = DiagnosticArray(status=statuses)
    array.header.stamp = conv.ns_to_stamp(stamp_ns)
    return serialize_cdr(array, typestore())


def test_a_corrupt_or_odd_diagnostics_message_is_skipped_and_said(tmp_path, capsys):
    # dev-probe110: one corrupt /diagnostics message made analyze and replay --offline a
    # traceback (rosbags' SerdeError is no ValueError); replay does not need them at all
    good = _array_bytes([_status(1, 'saturated: 2')], 500_000_000)
    corrupt = good[:40] + b'lookahead_control: /controller' + b'\xff' * 7
    _raw_bag(tmp_path / 'bag', [(500_000_000, good), (900_000_000, corrupt)])
    run = load_run(tmp_path / 'bag')
    assert run.diagnostics.corrupt == 1 and len(run.diagnostics.reports) == 1
    row = bag_row(run, run_series(run))
    assert row['diagnostics'] == 'WARN'
    assert 'diagnostics: 1 corrupt /diagnostics message(s) skipped' in row['notes']
    assert replay_node.main([str(tmp_path / 'bag'), '--offline']) == 0
    assert load_run(tmp_path / 'bag', diagnostics=None).diagnostics is None
    # a level outside OK..STALE is its number, never '-' nor negative (the byte 255 read
    # as -1, and a lone level 5 as none recorded)
    _raw_bag(tmp_path / 'odd', [(100_000_000, _array_bytes([_status(5, 'x: 1')])),
                                (200_000_000, _array_bytes([_status(255, 'y: 1')]))])
    run = load_run(tmp_path / 'odd')
    assert [r.level for r in run.diagnostics.reports] == [5, 255]
    assert bag_row(run, run_series(run))['diagnostics'] == 'level 255'
    # /diagnostics of another type is said, not taken for none
    _raw_bag(tmp_path / 'string', [(100_000_000, serialize_cdr(String(data='x'),
                                                               typestore()))],
             'std_msgs/msg/String')
    report = write_outputs(analyze([tmp_path / 'string']), tmp_path / 'out', plots=False)
    assert ('- `string`: /diagnostics has type std_msgs/msg/String, not '
            'diagnostic_msgs/msg/DiagnosticArray: not read') in report.read_text()


def test_a_status_recorded_twice_counts_once_and_odd_text_stays_one_line(tmp_path):
    # dev-probe110: two recorders doubled every count; a newline in a status broke the
    # report's list, HTML went through
    once = _array_bytes([_status(1, 'rejected: 1 (last: <b>x</b>\nsecond line)')])
    later = _array_bytes([_status(1, 'rejected: 1 (last: <b>x</b>\nsecond line)')])
    _raw_bag(tmp_path / 'bag', [(500_000_000, once), (500_000_500, once),
                                (1_500_000_000, later)])
    run = load_run(tmp_path / 'bag')
    # the same status received 0.5 us apart is one; the same text a second later is the
    # node's next status (a stopped clock keeps the stamp)
    assert run.diagnostics.duplicates == 1 and len(run.diagnostics.reports) == 2
    report = write_outputs(analyze([tmp_path / 'bag']), tmp_path / 'out', plots=False)
    text = report.read_text()
    assert ('  - WARN first told at t = 0.5 s, in 2: rejected: 1 (last: &lt;b&gt;x&lt;/b&gt; '
            'second line)\n') in text
    assert 'recorded twice (two recorders?) counted once' in text


def test_a_remapped_status_topic_is_read_where_it_is_named(tmp_path):
    # dev-probe111: a vehicle run with -r /diagnostics:=/car_b/diagnostics read 'no
    # /diagnostics in the bag', and no option named another topic
    _raw_bag(tmp_path / 'bag', [(500_000_000, _array_bytes([_status(1, 'saturated: 2')]))],
             topic='/car_b/diagnostics')
    assert load_run(tmp_path / 'bag').diagnostics is None
    run = load_run(tmp_path / 'bag', diagnostics='/car_b/diagnostics')
    assert [r.level for r in run.diagnostics.reports] == [1]
    from lookahead_control.bags.run_data import ConfigError
    with pytest.raises(ConfigError, match='--diagnostics /car_a/diagnostics: no '
                       '/car_a/diagnostics in the bag'):
        load_run(tmp_path / 'bag', diagnostics='/car_a/diagnostics')
    out = tmp_path / 'out'
    from lookahead_control.tools import analyze_tool
    assert analyze_tool.main([str(tmp_path / 'bag'), '--out', str(out), '--no-plots',
                              '--diagnostics', '/car_b/diagnostics']) == 0
    assert '- `bag`: 1 statuses of /controller (WARN 1)' in (out / 'report.md').read_text()
