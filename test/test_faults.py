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

"""Fault injection: bad files, unwritable and full disks, killed processes, bad peers."""

import contextlib
import ctypes
import os
from pathlib import Path
import random
import re
import resource
import signal
import struct
import subprocess
import sys
import tempfile
import time
import warnings

from conftest import entry_points, spin_until
from lookahead_control.bags.rosbag_io import (bag_topics, read_messages, RECORDER_KEY, recover,
                                              run_description)
from lookahead_control.ros import conversions as conv
from mcap.exceptions import McapError
from mcap.records import Channel, Message
from mcap.stream_reader import StreamReader
import pytest
import yaml

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / 'config' / 'scenarios' / 'paper_r400.yaml'
# where setup.cfg installs the executables: <prefix>/lib/lookahead_control, as ros2 run
EXES = Path(sys.prefix) / 'lib' / 'lookahead_control'
pytestmark = pytest.mark.process


def _run(exe, *args, timeout=60, **kwargs):
    return subprocess.run([str(EXES / exe), *map(str, args)], cwd=kwargs.pop('cwd', ROOT),
                          capture_output=True, text=True, timeout=timeout, **kwargs)


@pytest.fixture(scope='module')
def bad(tmp_path_factory):
    """Bad files of every kind: malformed, missing, out of range, not a dir, not a bag."""
    tmp = tmp_path_factory.mktemp('bad')
    files = {'malformed': tmp / 'malformed.yaml', 'missing': tmp / 'missing.yaml',
             'range': tmp / 'range.yaml', 'plain': tmp / 'plain.txt',
             'junk_bag': tmp / 'junk_bag', 'garbage_bag': tmp / 'garbage_bag',
             'no_bag': tmp / 'no_bag'}
    files['malformed'].write_text('controller:\n  ros__parameters: [1,\n')
    files['range'].write_text('controller:\n  ros__parameters:\n    controller:\n'
                              '      natural_frequency: -3.0\n')
    files['plain'].write_text('a file, not a directory\n')
    files['junk_bag'].mkdir()
    (files['junk_bag'] / 'metadata.yaml').write_text('not: [a bag')
    files['garbage_bag'].mkdir()
    (files['garbage_bag'] / 'garbage_bag.mcap').write_bytes(bytes(range(256)) * 40)
    return files


# executable -> (arguments, the file the one line must name), built from the bad files
CASES = {
    'schedule': [(['--vehicle', '{malformed}'], 'malformed.yaml'),
                 (['--vehicle', '{missing}'], 'missing.yaml')],
    'zero_dynamics': [(['--vehicle', '{malformed}'], 'malformed.yaml')],
    'certificate': [(['--vehicle', '{missing}'], 'missing.yaml')],
    'lane_keeping_stability': [(['--vehicle', '{missing}'], 'missing.yaml')],
    'paper_scenario': [(['--controller', '{malformed}', '--no-plots'], 'malformed.yaml'),
                       (['--no-plots', '--out', '{plain}/out'], 'plain.txt')],
    'controller': [(['--ros-args', '--params-file', '{malformed}'], 'malformed.yaml'),
                   (['--ros-args', '--params-file', '{missing}'], 'missing.yaml'),
                   (['--ros-args', '--params-file', '{range}'], 'natural_frequency')],
    'path_bridge': [(['--ros-args', '--params-file', '{malformed}'], 'malformed.yaml'),
                    (['--ros-args', '-p', 'path.fit_half_window:=-1.0'], 'fit_half_window')],
    'sim_plant': [(['--ros-args', '-p', 'scenario_file:={malformed}'], 'malformed.yaml'),
                  (['--ros-args', '-p', 'scenario_file:={missing}'], 'missing.yaml')],
    'closed_loop': [(['--scenario', '{malformed}', '--no-record'], 'malformed.yaml'),
                    (['--scenario', '{missing}', '--no-record'], 'missing.yaml'),
                    (['--bag', '{plain}/run'], 'plain.txt')],
    'record': [(['/talk', '-o', '{plain}/run'], 'plain.txt')],
    'recover': [(['{no_bag}'], 'no_bag'), (['{garbage_bag}'], 'garbage_bag')],
    'replay': [(['{no_bag}'], 'no_bag'), (['{junk_bag}', '--offline'], 'junk_bag')],
    'analyze': [(['{junk_bag}', '--no-plots'], 'junk_bag'),
                (['{garbage_bag}', '--no-plots'], 'garbage_bag')],
    'demo': [(['--out', '{plain}/demo'], 'plain.txt')],
    'compare': [(['--vehicle', '{malformed}'], 'malformed.yaml'),
                (['--laws', 'paper_eq26', '--scenarios', 's1_paper_step', '--plants', 'linear',
                  '--speeds', '37', '--workers', '1', '--no-plots', '--out', '{plain}/out'],
                 'plain.txt')],
    'sweep': [(['--out', 'run', '--vehicle', '{malformed}'], 'malformed.yaml'),
              (['--out', 'run', '--controller', '{missing}'], 'missing.yaml'),
              (['--out', 'run', '--scenarios', '{malformed}'], 'malformed.yaml'),
              (['--out', '{plain}/run', '--workers', '0', '--no-progress'], 'plain.txt')],
}


def test_every_executable_has_bad_file_cases():
    assert set(CASES) == set(entry_points())


@pytest.mark.parametrize('exe', sorted(CASES))
def test_every_cli_given_a_bad_file_prints_one_line_and_fails(exe, bad, tmp_path):
    for args, named in CASES[exe]:
        argv = [a.format(**bad) for a in args]
        out = _run(exe, *argv, cwd=tmp_path)
        assert out.returncode != 0, (argv, out.stderr)
        lines = out.stderr.strip().splitlines()
        assert len(lines) == 1, (argv, out.stderr)
        assert lines[0].startswith(f'{exe}: ') and named in lines[0], (argv, lines)
        assert 'Traceback' not in out.stderr


def _drop_root_file_override():
    """Run as if not root: without CAP_DAC_OVERRIDE a directory's mode bits apply."""
    if os.geteuid() != 0:
        return
    libc = ctypes.CDLL(None, use_errno=True)
    pr_capbset_drop = 24            # root's capabilities after exec come from this set
    for cap in (1, 2):              # CAP_DAC_OVERRIDE, CAP_DAC_READ_SEARCH
        if libc.prctl(pr_capbset_drop, cap, 0, 0, 0) != 0:
            raise OSError(ctypes.get_errno(), 'prctl(PR_CAPBSET_DROP)')


def test_record_given_an_output_that_exists_exits_3_and_leaves_it(tmp_path):
    # 3, not 2 as a write failure mid-run: closed_loop tells a bag another run took
    theirs = tmp_path / 'theirs'
    theirs.mkdir()
    (theirs / 'data.mcap').write_bytes(b'theirs')
    for output in (theirs, theirs / 'data.mcap'):
        out = _run('record', '/talk', '-o', output)
        assert out.returncode == 3, out.stderr
        assert out.stderr.strip() == (f'record: error: {output}: exists: a bag is never '
                                      'written over (choose another output)'), out.stderr
    assert [p.name for p in theirs.iterdir()] == ['data.mcap']
    assert (theirs / 'data.mcap').read_bytes() == b'theirs'


def test_unwritable_bags_dir_is_one_line_and_records_nothing(tmp_path):
    bags = tmp_path / 'bags'
    bags.mkdir()
    bags.chmod(0o555)
    try:
        for exe, args in (('record', ['/talk', '-o', bags / 'run']),
                          ('closed_loop', ['--bag', bags / 'run']),
                          ('demo', ['--out', bags / 'demo'])):
            out = _run(exe, *args, preexec_fn=_drop_root_file_override)
            assert out.returncode != 0, out.stderr
            lines = out.stderr.strip().splitlines()
            assert len(lines) == 1 and 'Permission denied' in lines[0], out.stderr
            assert str(bags) in lines[0]
        assert list(bags.iterdir()) == []
    finally:
        bags.chmod(0o755)


TALKER = """
import sys, time, rclpy
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray
rclpy.init()
node = Node('talker')
pub = node.create_publisher(Float64MultiArray, '/talk', 1000)
start, k = time.monotonic(), 0
print('up', flush=True)
while time.monotonic() - start < float(sys.argv[1]):
    pub.publish(Float64MultiArray(data=[float(k)] * 50))    # about 450 bytes
    k += 1
    time.sleep(max(0.0, start + k * 0.005 - time.monotonic()))   # 200 Hz
"""


#: Fast DDS over UDP on the loopback interface only: no shared-memory transport
UDP_LOOPBACK = """<?xml version="1.0" encoding="UTF-8" ?>
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <transport_descriptors>
    <transport_descriptor>
      <transport_id>udp_loopback</transport_id>
      <type>UDPv4</type>
      <interfaceWhiteList><address>127.0.0.1</address></interfaceWhiteList>
    </transport_descriptor>
  </transport_descriptors>
  <participant profile_name="udp_loopback" is_default_profile="true">
    <rtps>
      <userTransports><transport_id>udp_loopback</transport_id></userTransports>
      <useBuiltinTransports>false</useBuiltinTransports>
    </rtps>
  </participant>
</profiles>
"""


def _udp_only_env(folder):
    """
    Return the environment of processes that talk over UDP on the loopback only.

    Fast DDS's shared-memory transport lost a recorder's messages after SIGKILLed
    participants (eProsima/Fast-DDS#5053, #5469; dev-sc30, dev-sc43). A default profile
    without it is taken only when ``ROS_AUTOMATIC_DISCOVERY_RANGE`` is not LOCALHOST
    (rmw_fastrtps then sets the transports itself, shared memory among them: measured,
    its segments appear in /dev/shm): the range is left unset, and the profile's
    interface white list keeps the traffic on 127.0.0.1.
    """
    profile = folder / 'udp_loopback.xml'
    profile.write_text(UDP_LOOPBACK)
    env = {**os.environ, 'FASTRTPS_DEFAULT_PROFILES_FILE': str(profile)}
    env.pop('ROS_AUTOMATIC_DISCOVERY_RANGE', None)
    return env


@contextlib.contextmanager
def _talking(env=None):
    """Publish a counter on /talk at 200 Hz while in the block."""
    proc = subprocess.Popen([sys.executable, '-c', TALKER, '600'], stdout=subprocess.PIPE,
                            text=True, env=env)
    try:
        assert proc.stdout.readline().strip() == 'up'
        yield proc
    finally:
        proc.kill()
        proc.wait()


@pytest.fixture
def talker():
    """Publish a counter on /talk at 200 Hz while the test runs."""
    with _talking() as proc:
        yield proc


def _counter(bag):
    return [int(m.msg.data[0]) for m in read_messages(bag)]


def _record(bag, stderr=subprocess.PIPE, **kwargs):
    return subprocess.Popen([str(EXES / 'record'), '/talk', '-o', str(bag),
                             '--chunk-interval', '0.2'], stderr=stderr, text=True, **kwargs)


class Unfed(AssertionError):
    """A recorder subscribed to its topic and then received nothing."""


def _wait_recording(bag, recorder=None, log=None, timeout=180, unfed_after=None):
    """
    Wait until the recorder has flushed its first chunk of /talk messages.

    A condition, not a time: the bound is far above what a loaded machine needs (four
    recorders, a talker and two test workers under two CPU hogs once took over 30 s);
    a recorder that exits is reported at once, with what it said.

    :param unfed_after: if given, raise ``Unfed`` once the recorder's log has said it
        subscribed (to /talk, the one topic it records) this many seconds ago and nothing
        was recorded since.
    """
    end = time.monotonic() + timeout
    mcap = bag / f'{bag.name}.mcap'
    subscribed_at = None
    unfed = False
    while time.monotonic() < end:
        if mcap.is_file() and mcap.stat().st_size > 4096:
            return
        if recorder is not None and recorder.poll() is not None:
            said = log.read_text() if log is not None and log.exists() else ''
            raise AssertionError(f'{bag}: the recorder exited ({recorder.returncode}) '
                                 f'before recording: {said[-2000:]}')
        if unfed_after is not None and subscribed_at is None and log is not None \
                and 'subscribed to /' in log.read_text():
            subscribed_at = time.monotonic()
        if subscribed_at is not None and time.monotonic() - subscribed_at > unfed_after:
            unfed = True
            break
        time.sleep(0.02)
    if recorder is not None:
        # stop it: its log then says whether it ever subscribed to /talk ('subscribed
        # to', else 'no publisher of /talk ever seen') and what it received
        recorder.send_signal(signal.SIGINT)
        try:
            recorder.wait(timeout=30)
        except subprocess.TimeoutExpired:
            recorder.kill()
    said = log.read_text() if log is not None and log.exists() else ''
    if unfed:
        raise Unfed(f'{bag}: subscribed and received nothing in {unfed_after} s: '
                    f'{said[-2000:]}')
    raise AssertionError(f'{bag}: nothing recorded within {timeout} s: {said[-2000:]}')


def test_full_disk_is_one_line_and_keeps_what_was_recorded(tmp_path, talker):
    limit = 300_000           # the recorder's files may not grow past 300 kB: EFBIG

    def small_disk():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    bag = tmp_path / 'run'
    recorder = _record(bag, preexec_fn=small_disk)
    _, err = recorder.communicate(timeout=60)
    assert recorder.returncode != 0
    lines = err.strip().splitlines()
    assert [line for line in lines if '[INFO]' not in line] == [lines[-1]], err
    assert f'{bag.name}.mcap: write failed: File too large' in lines[-1], err
    assert f'recover {bag}' in lines[-1] and 'Traceback' not in err
    result = recover(bag)
    values = _counter(bag)
    # everything in the chunks that reached the file: about 300 kB of 0.5 kB messages
    assert values == list(range(values[0], values[0] + len(values)))
    assert result.messages == len(values) >= 0.7 * limit / 500


def test_record_resolves_a_relative_name_and_names_a_topic_it_never_saw(tmp_path, talker):
    # before: `record talk` matched no topic (only /talk does) and recorded nothing,
    # silently; and a misspelt topic left no trace but an empty bag
    bag, log = tmp_path / 'run', tmp_path / 'run.log'
    recorder = subprocess.Popen([str(EXES / 'record'), 'talk', '/tlak', '-o', str(bag),
                                 '--chunk-interval', '0.2'], stderr=log.open('w'), text=True)
    _wait_recording(bag, recorder, log)
    recorder.send_signal(signal.SIGINT)
    recorder.wait(timeout=30)
    err = log.read_text()
    assert recorder.returncode == 0, err
    assert list(bag_topics(bag)) == ['/talk']
    assert ('subscribed to /talk (std_msgs/msg/Float64MultiArray, 1 publisher(s), '
            'reliable)') in err
    assert err.rstrip().endswith('; no publisher of /tlak ever seen: not recorded'), err


QUIET = """
import time, rclpy
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray
rclpy.init()
node = Node('quiet')
pub = node.create_publisher(Float64MultiArray, '/quiet', 10)
print('up', flush=True)
time.sleep(600)                                     # in the graph, never publishing
"""


def test_record_names_a_subscribed_topic_that_delivered_nothing(tmp_path, talker):
    # before: a topic subscribed and never fed (a publisher silent, or messages the
    # middleware never delivered: Fast DDS shared memory after a SIGKILL, dev-sc30)
    # showed only in the total, '0 messages on 1 topics'
    quiet = subprocess.Popen([sys.executable, '-c', QUIET], stdout=subprocess.PIPE,
                             text=True)
    started = [quiet]
    try:
        assert quiet.stdout.readline().strip() == 'up'
        bag, log = tmp_path / 'run', tmp_path / 'run.log'
        recorder = subprocess.Popen([str(EXES / 'record'), '/talk', '/quiet', '-o', str(bag),
                                     '--chunk-interval', '0.2'], stderr=log.open('w'),
                                    text=True)
        started.append(recorder)
        _wait_recording(bag, recorder, log)
        end = time.monotonic() + 120
        while 'subscribed to /quiet' not in log.read_text() and time.monotonic() < end:
            time.sleep(0.05)
        recorder.send_signal(signal.SIGINT)
        recorder.wait(timeout=30)
        # and the SIGKILL test's way out of Fast DDS's unfed recorder sees one: a
        # recorder of /quiet alone is subscribed and never fed
        lone, lone_log = tmp_path / 'lone', tmp_path / 'lone.log'
        unfed = subprocess.Popen([str(EXES / 'record'), '/quiet', '-o', str(lone)],
                                 stderr=lone_log.open('w'), text=True)
        started.append(unfed)
        with pytest.raises(Unfed, match='subscribed and received nothing in 1 s'):
            _wait_recording(lone, unfed, lone_log, timeout=120, unfed_after=1)
        assert unfed.poll() is not None
    finally:
        for proc in started:
            _kill_if_running(proc)
    err = log.read_text()
    assert recorder.returncode == 0, err
    assert err.rstrip().endswith(
        '; subscribed, nothing received on /quiet (up to 1 publisher(s) at once)'), err
    assert sorted(bag_topics(bag)) == ['/quiet', '/talk']


def test_record_all_does_not_name_the_event_topics_silent(tmp_path, talker):
    # dev-probe65: recording everything, every run ended 'subscribed, nothing received
    # on /parameter_events (1 publisher(s))', the recorder's own publisher (closed_loop:
    # also /controller/transition_event): a clause on every healthy run hides the one
    # that matters
    bag, log = tmp_path / 'run', tmp_path / 'run.log'
    recorder = subprocess.Popen([str(EXES / 'record'), '-o', str(bag), '--chunk-interval',
                                 '0.2'], stderr=log.open('w'), text=True)
    try:
        _wait_said(log, recorder, 'subscribed to /parameter_events', 'subscribed to /talk')
        # the bag's first chunk may hold only /rosout and /parameter_events (CI, once:
        # /talk subscribed 3 s after them, stopped before its first message): wait for
        # a message of /talk itself
        _wait_recorded(bag, recorder, '/talk')
        recorder.send_signal(signal.SIGINT)
        recorder.wait(timeout=30)
    finally:
        _kill_if_running(recorder)
    err = log.read_text()
    assert recorder.returncode == 0, err
    assert '/parameter_events' in bag_topics(bag)
    assert 'nothing received' not in err, err


def test_record_names_a_topic_remapped_to_a_name_nobody_publishes(tmp_path, talker):
    # dev-probe65: with -r /talk:=/nowhere and nothing on /nowhere, /talk was skipped
    # without a word (the publishers' lookup remaps the name and found none), although
    # the docs promise 'not recorded, remapped'
    _, err = _record_until(tmp_path, ['-e', '/talk'], ['-r', '/talk:=/nowhere'],
                           '/talk: not recorded')
    assert err.rstrip().endswith('; not recorded, remapped: /talk -> /nowhere'), err


def test_record_names_the_type_it_cannot_record_on_a_topic_of_two_types(tmp_path):
    # dev-probe65: a String publisher sending and a Float64MultiArray one silent on one
    # topic: one subscription takes one type, and the summary said only 'nothing
    # received' when it took the silent one's
    sending = 'while True:\n    pub.publish(String(data=str(1)))\n    time.sleep(0.05)'
    string = QUIET.replace('Float64MultiArray', 'String').replace('time.sleep(600)', sending)
    procs = [subprocess.Popen([sys.executable, '-c', code], stdout=subprocess.PIPE,
                              text=True) for code in (QUIET, string)]
    try:
        for proc in procs:
            assert proc.stdout.readline().strip() == 'up'
        bag, log = tmp_path / 'run', tmp_path / 'run.log'
        recorder = subprocess.Popen([str(EXES / 'record'), '/quiet', '-o', str(bag)],
                                    stderr=log.open('w'), text=True)
        procs.append(recorder)          # killed below if the wait fails
        _wait_said(log, recorder, 'published as 2 types')
        recorder.send_signal(signal.SIGINT)
        recorder.wait(timeout=30)
    finally:
        for proc in procs:
            _kill_if_running(proc)
    err = log.read_text()
    assert recorder.returncode == 0, err
    recorded = bag_topics(bag)['/quiet'][0]
    other = ({'std_msgs/msg/String', 'std_msgs/msg/Float64MultiArray'} - {recorded}).pop()
    assert f'; not recorded, another type on: /quiet ({other})' in err, err


@pytest.mark.parametrize('name,ros_args,reason', [
    ('bad name', [], 'must not contain characters other than'),
    ('/a//b', [], "must not contain repeated '/'"),
    ('talk/', [], 'must not end with a forward slash'),
    ('1talk', [], 'must not start with a number'),
    # valid in /, too long in its namespace: before, a traceback after the bag was made
    ('t' * 200, ['--ros-args', '-r', '__ns:=/' + '/'.join(['n' * 40] * 5)],
     "topic length should not exceed '255U - 8U'")])
def test_record_refuses_a_topic_name_ros_does_not_allow(tmp_path, name, ros_args, reason):
    bag = tmp_path / 'run'
    out = subprocess.run([str(EXES / 'record'), name, '-o', str(bag), *ros_args],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 2, out
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(
        f'record: error: topic {name!r}: not a ROS topic name (letters, digits and _ between '
        "single '/'; a relative name is resolved in the recorder's namespace): "), lines
    assert reason in lines[0], lines         # rcl's own reason
    assert not bag.exists()


@pytest.mark.parametrize('exe', ['record', 'replay', 'controller', 'sim_plant', 'path_bridge'])
@pytest.mark.parametrize('ros_args, said', [
    (['-r', '__ns:=car_b'], ["remap rule: '-r __ns:=car_b'", '__ns:=/car_b']),
    (['-r', '__node:=a/b'], ["remap rule: '-r __node:=a/b'", '__node:=truck']),
    (['-r', 'steering'], ["remap rule: '-r steering'", 'FROM:=TO']),
    # not an RCLError in rclpy: a traceback in every executable (dev-probe56)
    (['garbage', ':='], ["unknown ROS argument(s) 'garbage', ':=' after --ros-args"])])
def test_ros_arguments_rcl_refuses_are_one_line_that_says_what_it_expected(
        exe, ros_args, said, tmp_path):
    # before: record and replay ended in a traceback (rclpy's remove_ros_args raised);
    # every node printed rcl's '[ERROR] [rcl]: Failed to parse global arguments' and a
    # warning before its line, whose reason was 'Expected lexeme type 19, got 18'
    args = {'record': ['-o', str(tmp_path / 'run')], 'replay': [str(tmp_path / 'no_bag')]}
    out = subprocess.run([str(EXES / exe), *args.get(exe, []), '--ros-args', *ros_args],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 2, out
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith(f'{exe}: error: '), lines
    assert all(part in lines[0] for part in said), lines
    assert not (tmp_path / 'run').exists()


def test_what_rcl_says_while_it_parses_is_kept_unless_it_fails(capfd):
    # rcl_log_held drops rcl's lines only with its error: a warning of a start that
    # goes on is the user's to read
    from lookahead_control.ros.node_main import RCLError, rcl_log_held
    with rcl_log_held():
        os.write(2, b'[WARN] kept\n')
    with pytest.raises(RCLError):
        with rcl_log_held():
            os.write(2, b'[ERROR] dropped\n')
            raise RCLError('refused')
    with pytest.raises(ValueError):
        with rcl_log_held():
            os.write(2, b'[WARN] kept too\n')
            raise ValueError('not rcl')
    err = capfd.readouterr().err
    assert '[WARN] kept\n' in err and '[WARN] kept too' in err and 'dropped' not in err


def _recorded(bag, topic):
    """Return whether the recorder's MCAP file, still being written, has a ``topic`` message."""
    path = bag / f'{bag.name}.mcap'
    if not path.is_file():
        return False
    channels = set()
    try:
        with path.open('rb') as stream:
            for record in StreamReader(stream).records:
                if isinstance(record, Channel) and record.topic == topic:
                    channels.add(record.id)
                elif isinstance(record, Message) and record.channel_id in channels:
                    return True
    except (McapError, EOFError, struct.error, ValueError):
        pass                      # the record being written: read again later
    return False


def _wait_recorded(bag, recorder, topic, timeout=180):
    """Wait until the recorder has written a message of ``topic`` (a condition)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if _recorded(bag, topic):
            return
        if recorder.poll() is not None:
            raise AssertionError(f'the recorder exited ({recorder.returncode})')
        time.sleep(0.05)
    raise AssertionError(f'{bag}: no message of {topic} recorded within {timeout} s')


def _wait_said(log, recorder, *words, timeout=180):
    """Wait until the recorder's log has each of ``words`` (a condition, not a time)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        said = log.read_text()
        if all(any(w in said for w in alternatives.split('|')) for alternatives in words):
            return
        if recorder.poll() is not None:
            raise AssertionError(f'the recorder exited ({recorder.returncode}): {said}')
        time.sleep(0.05)
    raise AssertionError(f'not said within {timeout} s: {words}: {log.read_text()}')


def _kill_if_running(proc):
    """Kill ``proc`` if it has not exited (a test that failed half-way)."""
    if proc.poll() is None:
        proc.kill()
        proc.wait()


def _record_until(tmp_path, args, ros_args, *words):
    """
    Run ``record ARGS -o tmp_path/run --ros-args ROS_ARGS`` until its log says ``words``.

    :return: the bag's path and what the recorder said when stopped with SIGINT (it
        exited with 0).
    """
    bag, log = tmp_path / 'run', tmp_path / 'run.log'
    recorder = subprocess.Popen([str(EXES / 'record'), *args, '-o', str(bag), '--ros-args',
                                 *ros_args], stderr=log.open('w'), text=True)
    try:
        _wait_said(log, recorder, *words)
        recorder.send_signal(signal.SIGINT)
        recorder.wait(timeout=30)
    finally:
        _kill_if_running(recorder)     # a failed wait left it recording (dev-sc30)
    err = log.read_text()
    assert recorder.returncode == 0, err
    return bag, err


def test_record_resolves_a_substitution_in_its_own_namespace(tmp_path):
    # before: names were checked in / whatever the namespace: {ns}/talk (/car_b/talk
    # for this recorder, as rcl resolves it) was refused as not a ROS name
    _, err = _record_until(tmp_path, ['{ns}/talk'], ['-r', '__ns:=/car_b'], 'recording to')
    assert err.rstrip().endswith('; no publisher of /car_b/talk ever seen: not recorded'), err


def test_record_never_writes_a_remapped_subscription_under_the_topics_name(tmp_path, talker):
    # a remapping given to the recorder applies to its own subscriptions: before, its
    # subscription to /talk with -r /talk:=/car_b/talk received /car_b/talk, and the bag
    # had car b's messages under /talk (as a launch SetRemap of /clock would do)
    other = subprocess.Popen([sys.executable, '-c', TALKER, '600', '--ros-args', '-r',
                              '/talk:=/car_b/talk'], stdout=subprocess.PIPE, text=True)
    try:
        assert other.stdout.readline().strip() == 'up'
        bag, log = tmp_path / 'run', tmp_path / 'run.log'
        recorder = subprocess.Popen([str(EXES / 'record'), '-e', '/(car_b/)?talk', '-o',
                                     str(bag), '--chunk-interval', '0.2', '--ros-args', '-r',
                                     '/talk:=/car_b/talk'], stderr=log.open('w'), text=True)
        _wait_said(log, recorder, 'subscribed to /car_b/talk',
                   'subscribed to /talk|/talk: not recorded')
        recorder.send_signal(signal.SIGINT)
        recorder.wait(timeout=30)
    finally:
        other.kill()
        other.wait()
    err = log.read_text()
    assert recorder.returncode == 0, err
    assert list(bag_topics(bag)) == ['/car_b/talk'], err
    assert ('/talk: not recorded: a remapping sends a subscription to it to /car_b/talk '
            '(remap the nodes, not the recorder)') in err
    assert err.rstrip().endswith('; not recorded, remapped: /talk -> /car_b/talk'), err


def test_a_late_recorder_counts_what_it_missed_before_subscribing(tmp_path, talker):
    time.sleep(0.5)                 # the talker has published about 100 messages
    bag = tmp_path / 'run'
    recorder = _record(bag)
    _wait_recording(bag, recorder)
    recorder.send_signal(signal.SIGINT)
    _, err = recorder.communicate(timeout=30)
    assert recorder.returncode == 0, err
    values = _counter(bag)          # the talker's k is its message k + 1
    report = yaml.safe_load(run_description(bag)[RECORDER_KEY])['/talk']
    assert values[0] >= 50 and report['before_first'] == values[0]
    assert report['published'] == values[-1] + 1
    assert report['received'] == len(values)
    assert report['dropped'] == values[-1] + 1 - values[0] - len(values)
    assert f'subscribed late: missed the first {values[0]} on /talk' in err


def test_sigkill_at_20_random_moments_every_bag_recovers(tmp_path):
    rng = random.Random(20261121)
    unfed = []
    # without shared memory, the transport that lost messages after SIGKILLs (dev-sc44;
    # the set-aside below stays for a loss of another cause)
    env = _udp_only_env(tmp_path)
    for batch in range(5):              # four recorders at a time, each killed on its own
        bags = [tmp_path / f'run{batch}_{i}' for i in range(4)]
        logs = [tmp_path / f'run{batch}_{i}.log' for i in range(4)]
        # a talker of the batch's own: the recorders that got nothing (below) were all
        # started next to a talker that had outlived SIGKILLed ones; once the one set
        # aside was followed by another (dev-sc43's final suite: 180 s, nothing)
        with _talking(env):
            recorders = [_record(bag, stderr=log.open('w'), env=env)
                         for bag, log in zip(bags, logs)]
            try:
                for i, (bag, log) in enumerate(zip(bags, logs)):
                    try:
                        _wait_recording(bag, recorders[i], log,
                                        unfed_after=None if unfed else 60)
                    except Unfed as err:
                        # Fast DDS 2.14's shared-memory transport: about one full suite
                        # in eight, one recorder started next to the talker that outlived
                        # the batch before's SIGKILLed ones subscribed and was never
                        # delivered a message (eProsima/Fast-DDS#5053, #5469; dev-sc30).
                        # Not what this test is about (the bags after a kill): once per
                        # run, it is set aside and a new recorder takes its place; a
                        # second one fails.
                        unfed.append(str(err))
                        bag.rename(bag.with_name(bag.name + '_unfed'))
                        log.rename(log.with_name(log.stem + '_unfed.log'))
                        recorders[i] = _record(bag, stderr=log.open('w'), env=env)
                        _wait_recording(bag, recorders[i], log)
                start = time.monotonic()
                delays = [rng.uniform(0.0, 1.0) for _ in bags]
                for delay, bag, recorder in sorted(zip(delays, bags, recorders)):
                    time.sleep(max(0.0, start + delay - time.monotonic()))
                    recorder.send_signal(signal.SIGKILL)
                    recorder.wait()
            finally:
                # the batch's other recorders too: one that recorded nothing left three
                # recording until found hours later (dev-sc29)
                for recorder in recorders:
                    if recorder.poll() is None:
                        recorder.kill()
                        recorder.wait()
        for bag in bags:
            chunks = _complete_chunks(bag / f'{bag.name}.mcap')
            in_complete_chunks = sum(len(times) for times in chunks)
            result = recover(bag)
            messages = list(read_messages(bag))
            values = [int(m.msg.data[0]) for m in messages]
            # everything the killed recorder had written in whole chunks is back, and
            # nothing else: no gap, no duplicate, nothing out of order
            assert result.messages == len(values) == in_complete_chunks > 0, bag
            assert values == list(range(values[0], values[0] + len(values))), bag
            # and each chunk closed on time: the writer closes it with the first message
            # written more than 0.2 s after the last close, so every other message of a
            # chunk was received within 0.2 s of its first (whatever the load: before, a
            # bound on the time from the last message to the kill, 1.2 s, held only on
            # a machine that ran the recorder often enough)
            for times in chunks:
                assert times[-2:][0] - times[0] <= 0.2e9 + 1e6, (bag, times)
    if unfed:
        warnings.warn(f'one recorder was never delivered /talk and was replaced: {unfed[0]}')


def _complete_chunks(path):
    """Return the log times [ns] of each whole chunk of a cut MCAP file (spec, by hand)."""
    data = path.read_bytes()
    pos, chunks = 8, []                             # after the magic
    while pos + 9 <= len(data):
        opcode, length = data[pos], int.from_bytes(data[pos + 1:pos + 9], 'little')
        end = pos + 9 + length
        if end > len(data):
            break                                   # the record the kill cut
        if opcode == 0x06:                          # Chunk, uncompressed
            body = data[pos + 9:end]
            compression = int.from_bytes(body[28:32], 'little')
            assert body[32:32 + compression] == b''
            size = int.from_bytes(body[32 + compression:40 + compression], 'little')
            records, inner, times = body[40 + compression:40 + compression + size], 0, []
            while inner < len(records):
                if records[inner] == 0x05:          # Message: channel, sequence, log_time
                    times.append(int.from_bytes(records[inner + 15:inner + 23], 'little'))
                inner += 9 + int.from_bytes(records[inner + 1:inner + 9], 'little')
            chunks.append(times)
        pos = end
    return chunks


BRIDGE = """
import sys, time, rclpy
from rclpy.node import Node
from lookahead_control.ros import conversions as conv
rclpy.init()
node = Node('bridge_' + '_'.join(sys.argv[1:]))
make = {'lateral_error': lambda t: conv.to_lateral_error(t, 'base_link', 1.96, 0.5),
        'yaw': lambda t: conv.to_yaw(t, 'base_link', 0.0, 0.0, 0.0),
        'velocity': lambda t: conv.to_velocity(t, 'base_link', 20.0, 0.0, 0.0)}
pubs = {n: node.create_publisher(type(make[n](0)), '/' + n, 10) for n in sys.argv[1:]}
print('up', flush=True)
while True:                                        # 100 Hz, stamped with the wall clock
    now = node.get_clock().now().nanoseconds
    for name, pub in pubs.items():
        pub.publish(make[name](now))
    time.sleep(0.01)
"""


def _bridge(*inputs):
    proc = subprocess.Popen([sys.executable, '-c', BRIDGE, *inputs], stdout=subprocess.PIPE,
                            text=True)
    if proc.stdout.readline().strip() != 'up':
        proc.kill()
        raise AssertionError(f'the bridge for {inputs} did not start ({proc.wait()})')
    return proc


def test_killed_lateral_error_publisher_gives_safe_command_error_and_recovery(probe):
    # Judged on the stamps: the bridge stamps its lateral errors with the wall clock, the
    # controller stamps /diagnostics with its clock (the same, one machine) and its
    # watchdog commands with its time on the measurements' clock (the last lateral
    # error's stamp plus its own time since it arrived). How fast this process reads
    # them (the machine's load) changes nothing; the waits below only wait.
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from sensor_msgs.msg import JointState
    node, executor = probe
    steering, diagnostics, lateral_stamps = [], [], []
    node.create_subscription(JointState, '/steering', lambda m: steering.append(
        conv.from_steering(m)), 100)
    node.create_subscription(DiagnosticArray, '/diagnostics', lambda m: diagnostics.append(
        (conv.stamp_to_ns(m.header.stamp), m.status[0].level, m.status[0].message)), 100)
    node.create_subscription(type(conv.to_lateral_error(0, '', 0, 0)), '/lateral_error',
                             lambda m: lateral_stamps.append(conv.stamp_to_ns(m.header.stamp)),
                             100)
    rate, timeout, hold_time = 0.5, 0.2, 0.5    # safety.input_timeout, safety.hold_time
    # the paper law: stateless, so after the outage the same inputs give the held angle
    # again (the default law's integral would keep growing on a frozen 0.5 m offset)
    controller = subprocess.Popen([str(EXES / 'controller'), '--ros-args', '-p',
                                   f'safety.max_steering_rate:={rate}', '-p', 'law:=paper'])
    bridges = []
    try:
        bridges.append(_bridge('yaw', 'velocity'))
        lateral = _bridge('lateral_error')
        bridges.append(lateral)
        assert spin_until(executor, lambda: len(steering) > 100 and lateral_stamps, 30)
        held = steering[-1][1]
        assert held < -0.005                     # steering against a 0.5 m offset
        lateral.kill()
        lateral.wait()
        # wait (not judged) until the ramp has reached 0 after an ERROR
        assert spin_until(executor, lambda: steering[-1][1] == 0.0 and any(
            level == DiagnosticStatus.ERROR for _, level, _ in diagnostics), 30)
        last = max(lateral_stamps)               # the last lateral error published
        # on the stamps: the safe command and the ERROR within 2x the timeout of it
        after = [(stamp, angle) for stamp, angle in steering if stamp > last]
        first = after[0][0]
        assert first - last <= 2 * timeout * 1e9, (first - last) * 1e-9
        error_at, _, message = next(d for d in diagnostics
                                    if d[0] > last and d[1] == DiagnosticStatus.ERROR)
        assert error_at - last <= 2 * timeout * 1e9, (error_at - last) * 1e-9
        # the dead input is named: in the first ERROR, or (two CPU hogs, once: the yaw
        # and velocity bridge starved first, 'stale inputs: yaw, velocity') in a later one
        assert spin_until(executor, lambda: any(
            level == DiagnosticStatus.ERROR and 'lateral_error' in text
            for stamp, level, text in diagnostics if stamp > last), 30), diagnostics[-5:]
        named = next(text for stamp, level, text in diagnostics
                     if stamp > last and level == DiagnosticStatus.ERROR
                     and 'lateral_error' in text)
        assert named.startswith('stale inputs: lateral_error'), (message, named)
        # the watchdog holds the last command for hold_time, then ramps to 0
        assert all(angle == held for stamp, angle in after
                   if stamp - first <= hold_time * 1e9)
        assert after[-1][0] - first > hold_time * 1e9 and after[-1][1] == 0.0
        bridges.append(_bridge('lateral_error'))
        resumed = len(steering)
        assert spin_until(executor, lambda: len(steering) > resumed + 100, 30)
        assert spin_until(executor, lambda: diagnostics[-1][1] != DiagnosticStatus.ERROR,
                          5)
        # control resumes without a jump: back to the held angle at the rate limit
        assert steering[-1][1] == pytest.approx(held, abs=1e-6)
        for (s0, a0), (s1, a1) in zip(steering, steering[1:]):
            assert abs(a1 - a0) <= rate * max(s1 - s0, 0) * 1e-9 + 1e-9, (s0, a0, s1, a1)
    finally:
        for proc in bridges:
            proc.kill()
            proc.wait()
        controller.send_signal(signal.SIGINT)
        assert controller.wait(10) == 0


def test_sim_plant_ignores_bad_commands_and_holds_on_missing_answers(probe, tmp_path):
    from sensor_msgs.msg import JointState
    node, executor = probe
    scenario = tmp_path / 'one_second.yaml'
    scenario.write_text(SCENARIO.read_text().replace('duration: 10.0', 'duration: 1.0'))
    steering = node.create_publisher(JointState, '/steering', 10)
    nan, huge, skip = range(10, 15), (30,), range(20, 25)
    seen = []

    def answer(msg):
        stamp = conv.stamp_to_ns(msg.header.stamp)
        k = round(stamp / 10_000_000)
        seen.append(k)
        if k in skip:
            return
        angle = float('nan') if k in nan else 50.0 if k in huge else -0.001 * k
        steering.publish(conv.to_steering(stamp, angle, 0.0))

    node.create_subscription(type(conv.to_lateral_error(0, '', 0, 0)), '/lateral_error',
                             answer, 10)
    for topic, msg in (('/yaw', conv.to_yaw(0, '', 0, 0, 0)),
                       ('/velocity', conv.to_velocity(0, '', 0, 0, 0)),
                       ('/road_curvature', conv.to_curvature(0, '', [(0.0, 0.0)]))):
        node.create_subscription(type(msg), topic, lambda m: None, 10)
    # A good answer the probe sends after the deadline (the probe starved for 0.5 s; it
    # once made a 12th miss) is a miss the simulator reports as late, with the delay on
    # its own clock: only the refused, the silent and those late steps may miss.
    sim = subprocess.Popen([str(EXES / 'sim_plant'), '--ros-args', '-p',
                            f'scenario_file:={scenario}', '-p', 'deadline:=0.5'],
                           stderr=subprocess.PIPE, text=True)
    try:
        assert spin_until(executor, lambda: sim.poll() is not None, 60)
    finally:
        if sim.poll() is None:
            sim.kill()
        _, err = sim.communicate()
    assert sim.returncode == 0, err
    missed = [round(float(t) * 100) for t in
              re.findall(r'no steering for t = ([-\d.e]+) s within 0.5 s', err)]
    late = {round(float(t) * 100): float(delay) for t, delay in
            re.findall(r'late steering for t = ([-\d.e]+) s: ([\d.]+) s after', err)}
    refused = set(nan) | set(huge) | set(skip)
    assert not refused & set(late), err
    assert all(delay > 0.5 for delay in late.values()), err
    assert sorted(missed) == sorted(refused | set(late)), err
    # NaN and 50 rad are refused (6), and those steps and the silent ones time out (11)
    assert (f'finished at t = 1 s: 100 steps, {11 + len(late)} missed deadlines, '
            f'6 rejected commands, 0 beyond plant.max_steering_angle, {len(late)} late '
            'answers') in err, err
    # the refusals are said when they come, and in the misses they cause (dev-probe92:
    # the log said only "no steering" while NaN answers came every step)
    assert 'steering nan rad for t = 0.1 s refused (not finite, or 10 rad or more)' in err
    assert re.search(r'no steering for t = 0.1 s within 0.5 s: holding \S+ rad \(\d+ missed, '
                     r'1 commands refused meanwhile\)', err), err
    assert sorted(set(seen)) == list(range(100))


SHUTDOWN_MID_CALLBACK = """
import rclpy
from rclpy.node import Node
from lookahead_control.ros.node_main import run_node


class Querier(Node):
    def __init__(self):
        super().__init__('querier')
        self.create_timer(0.05, self.query)

    def query(self):
        rclpy.shutdown()                    # what SIGTERM's handler does, mid-callback
        self.count_publishers('/talk')      # RCLError: the context is invalid


raise SystemExit(run_node('querier', [], Querier))
"""


def test_shutdown_while_a_callback_uses_the_context_is_a_clean_stop():
    # a recorder stopped by SIGTERM during its topic discovery once exited 1 with a
    # traceback: rcl_count_publishers on the context the signal had just shut down
    out = subprocess.run([sys.executable, '-c', SHUTDOWN_MID_CALLBACK], capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert 'Traceback' not in out.stderr


HANGING_STOP = """
import threading
from rclpy.node import Node
from lookahead_control.ros import node_main


class Stuck(Node):
    def __init__(self):
        super().__init__('stuck')
        self.create_timer(0.05, lambda: None)

    def destroy_node(self):
        threading.Event().wait()            # a stop that never ends (a middleware hang)


node_main.STOP_DEADLINE = 2.0
raise SystemExit(node_main.run_node('stuck', [], Stuck, lambda node: True))
"""


def test_a_node_whose_stop_hangs_ends_with_its_stacks():
    # CI (stop 54): a child of a SIGKILLed closed_loop ran on for over 60 s after its
    # SIGTERM, nobody left to kill it, and nothing said where it was stuck
    proc = subprocess.Popen([sys.executable, '-c', HANGING_STOP], stderr=subprocess.PIPE,
                            text=True)
    try:
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 1, err
    assert 'Timeout' in err and 'in destroy_node' in err, err


# what a node's console script runs, with two markers: ROS started, interpreter finalized
NODE_ENTRY = """
import atexit, importlib, sys
import rclpy
start = rclpy.init


def init(*args, **kwargs):
    start(*args, **kwargs)
    print('ROS started', file=sys.stderr, flush=True)


rclpy.init = init
atexit.register(lambda: print('finalized', file=sys.stderr, flush=True))
module, *sys.argv = sys.argv[1:]
print('before the end', end='')        # not flushed: a pipe buffers it
sys.exit(importlib.import_module(module).entry())
"""


@pytest.mark.parametrize('module, args', [
    ('lookahead_control.ros.controller_node', []),
    ('sim_plant.sim_plant_node', []),
    ('lookahead_control.ros.path_bridge_node', []),
    ('lookahead_control.bags.recorder_node', ['-o', 'bag', '/steering'])])
def test_a_node_process_ends_without_python_s_finalization(module, args, tmp_path):
    # CI (stop 54): the controller died of SIGSEGV while "Garbage-collecting" after a
    # clean stop on SIGINT: rclpy's C++ objects freed by the interpreter's finalization.
    # A node's process now ends once it has stopped, its output flushed.
    proc = subprocess.Popen([sys.executable, '-c', NODE_ENTRY, module, module, *args],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        assert proc.stderr.readline().strip() == 'ROS started'
        time.sleep(1.0)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert out == 'before the end' and 'finalized' not in err, (out, err)
    assert 'Traceback' not in err, err


FLOODER = """
import sys, time, rclpy
from rclpy.node import Node
from rclpy.serialization import serialize_message
from lookahead_control.ros import conversions as conv
rclpy.init()
node = Node('flooder')
pubs = {n: node.create_publisher(type(m), '/' + n, 10) for n, m in (
    ('lateral_error', conv.to_lateral_error(0, '', 0, 0)), ('yaw', conv.to_yaw(0, '', 0, 0, 0)),
    ('velocity', conv.to_velocity(0, '', 0, 0, 0)),
    ('road_curvature', conv.to_curvature(0, '', [])))}
# a 10 000-point polygon, serialized once (its stamp does not matter: it is too long)
huge = serialize_message(conv.to_curvature(0, 'base_link', [(0.01 * k, 0.001)
                                                            for k in range(10_000)]))
while node.count_subscribers('/lateral_error') == 0:
    time.sleep(0.05)
time.sleep(0.5)
sent = []

def phase(seconds, hz):
    step, stop = 1.0 / hz, time.monotonic() + seconds
    next_at = time.monotonic()
    while time.monotonic() < stop:
        t = node.get_clock().now().nanoseconds
        pubs['yaw'].publish(conv.to_yaw(t, 'base_link', 0.0, 0.0, 0.0))
        pubs['velocity'].publish(conv.to_velocity(t, 'base_link', 20.0, 0.0, 0.0))
        if len(sent) % 10 == 0:
            pubs['road_curvature'].publish(huge)
        else:
            pubs['road_curvature'].publish(conv.to_curvature(t, 'base_link', [(0.0, 0.001)]))
        pubs['lateral_error'].publish(conv.to_lateral_error(t, 'base_link', 0.0, 0.5))
        sent.append(t)
        next_at += step
        wait = next_at - time.monotonic()
        if wait > 0:
            time.sleep(wait)

phase(1.0, 100.0)
start = len(sent)
phase(2.0, 1000.0)                                 # as fast as it goes, up to 1 kHz
print('flood', len(sent) - start, flush=True)
print('after', sent[-1], flush=True)
phase(1.0, 100.0)
print(' '.join(map(str, sent)), flush=True)
"""


@pytest.mark.parametrize('executor', ['events', 'single_threaded'])
def test_a_flood_builds_no_backlog_and_long_polygons_cost_nothing(probe, executor):
    # Invariants only (how much gets through depends on the machine): every answer is
    # to a measurement at most input_timeout old on the controller's clock (its own
    # latency report), each measurement is answered at most once and never after a
    # newer one, 10 000-point polygons are refused by count, and control resumes.
    from diagnostic_msgs.msg import DiagnosticArray
    from sensor_msgs.msg import JointState
    node, executor_ = probe
    steering, reports = [], []
    node.create_subscription(JointState, '/steering', lambda m: steering.append(
        conv.from_steering(m)), 1000)
    node.create_subscription(DiagnosticArray, '/diagnostics', lambda m: reports.append(
        {kv.key: kv.value for kv in m.status[0].values}), 100)
    controller = subprocess.Popen([str(EXES / 'controller'), '--ros-args', '-p',
                                   f'executor:={executor}', '-p', 'diagnostics_rate_hz:=5.0'])
    flooder = subprocess.Popen([sys.executable, '-c', FLOODER], stdout=subprocess.PIPE,
                               text=True)
    try:
        assert spin_until(executor_, lambda: flooder.poll() is not None, 60)
        out = flooder.stdout.read().splitlines()
        flood_end = int(out[1].split()[1])
        sent = [int(s) for s in out[2].split()]
        # control resumes after the flood (however long the machine takes)
        assert spin_until(executor_, lambda: any(s > flood_end for s, _ in steering), 10)
        spin_until(executor_, lambda: False, 0.5)
    finally:
        flooder.kill()
        controller.send_signal(signal.SIGINT)
        assert controller.wait(10) == 0
    latencies = [float(r['answer latency max [s]']) for r in reports
                 if 'answer latency max [s]' in r]
    assert latencies and max(latencies) <= 0.2          # safety.input_timeout
    measured = set(sent)
    answers = [stamp for stamp, _ in steering if stamp in measured]
    assert answers == sorted(set(answers))
    assert int(reports[-1]['rejected road_curvature: points']) > 0


# -- issue 12: SIGTERM, SIGKILL and Ctrl-C of the bringup tools ---------------------------

def _children(pid):
    """Return the pids whose parent is ``pid``."""
    found = []
    for stat in Path('/proc').glob('[0-9]*/stat'):
        try:
            fields = stat.read_text().rsplit(')', 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def _alive(pid):
    try:
        state = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()[0]
    except OSError:
        return False
    return state != 'Z'


def _start_default_sigint():
    signal.signal(signal.SIGINT, signal.SIG_DFL)    # as from a shell, not a background job


def _wait_for_bag_data(bag, proc, timeout=120):
    """Wait until the recorder of a running bringup has flushed messages into ``bag``."""
    end = time.monotonic() + timeout
    mcap = bag / f'{bag.name}.mcap'
    while time.monotonic() < end and proc.poll() is None:
        if mcap.is_file() and mcap.stat().st_size > 20000:
            return
        time.sleep(0.05)
    raise AssertionError(f'{bag}: nothing recorded ({proc.poll()})')


@pytest.mark.parametrize('sig', [signal.SIGTERM, signal.SIGKILL, signal.SIGINT])
def test_stopping_closed_loop_stops_its_nodes_and_finalizes_the_bag(tmp_path, sig,
                                                                    monkeypatch):
    bag, temp = tmp_path / 'run', tmp_path / 'temp'
    temp.mkdir()
    # --param: the controller's parameters go to the node as a file in the temp folder
    proc = subprocess.Popen([str(EXES / 'closed_loop'), '--mode', 'realtime', '--bag',
                             str(bag), '--param', 'lane_keeping.compliance_memory_seed:=1.3'],
                            cwd=tmp_path, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_start_default_sigint,
                            env={**os.environ, 'TMPDIR': str(temp)})
    _wait_for_bag_data(bag, proc)
    written = list(temp.glob('closed_loop_controller_*.yaml'))
    assert [p.name.split('_')[3] for p in written] == [str(proc.pid)], written
    children = _children(proc.pid)
    assert len(children) == 3, children         # recorder, controller, simulator
    proc.send_signal(sig)                       # to closed_loop only, as systemd would
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == {signal.SIGTERM: 143, signal.SIGINT: 130,
                               signal.SIGKILL: -signal.SIGKILL}[sig], err
    end = time.monotonic() + 30
    while time.monotonic() < end and any(_alive(c) for c in children):
        time.sleep(0.1)
    assert not any(_alive(c) for c in children), 'nodes left running'
    assert (bag / 'metadata.yaml').is_file(), err     # finalized, no `recover` needed
    assert sum(c for _, c in __import__('lookahead_control.bags.rosbag_io', fromlist=['x'])
               .bag_topics(bag).values()) > 0
    assert 'Traceback' not in err and '[FATAL]' not in err, err
    # a killed run cannot delete its params file: the next run removes it (before: left
    # in the temp folder for good, one per killed run); a running one's file is kept
    assert list(temp.iterdir()) == (written if sig == signal.SIGKILL else [])
    mine = temp / f'closed_loop_controller_{os.getpid()}_x.yaml'
    mine.write_text('{}\n')
    from lookahead_control.ros import closed_loop
    monkeypatch.setattr(tempfile, 'tempdir', str(temp))
    new = closed_loop.write_controller_params({'lane_keeping.integral_gain': 0.5})
    assert sorted(temp.iterdir()) == sorted([mine, new])
    closed_loop.release_controller_params(new)
    assert list(temp.iterdir()) == [mine]


def test_only_this_user_s_params_files_of_ended_runs_are_removed(tmp_path):
    from lookahead_control.ros.closed_loop import remove_stale_params
    dead = subprocess.Popen(['true'])                       # a pid no process has now
    dead.wait()
    outside = tmp_path / 'outside'
    outside.mkdir()
    target = outside / 'keep.yaml'
    target.write_text('mine\n')
    folder = tmp_path / 'temp'
    folder.mkdir()
    stale = folder / f'closed_loop_controller_{dead.pid}_ab12.yaml'
    kept = [folder / f'closed_loop_controller_{os.getpid()}_cd34.yaml',   # running
            folder / 'closed_loop_controller_ef56.yaml',     # a name without a pid
            folder / 'closed_loop_controller_x1_gh78.yaml',
            folder / f'closed_loop_controller_{dead.pid}_ij90.txt',
            folder / f'other_{dead.pid}_kl12.yaml']
    for path in [stale, *kept]:
        path.write_text('{}\n')
    link = folder / f'closed_loop_controller_{dead.pid}_mn34.yaml'
    link.symlink_to(target)
    # dev-probe87: a name int() refuses stopped every run ('²'.isdigit()); a digit
    # that is not ASCII or a leading 0 is not a pid this code writes
    odd = [folder / f'closed_loop_controller_{name}_op56.yaml'
           for name in ('\u00b2', '\u0661\u0662\u0663', f'0{dead.pid}')]
    # dev-probe87: a run in another pid namespace (a container sharing /tmp) has a pid
    # no process has here: its lock keeps its file
    held = folder / f'closed_loop_controller_{dead.pid}_qr78.yaml'
    for path in [*odd, held]:
        path.write_text('{}\n')
    import fcntl
    with held.open() as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        assert remove_stale_params(folder) == [stale]
    assert sorted(folder.iterdir()) == sorted([*kept, link, *odd, held]) and target.exists()
    assert remove_stale_params(folder) == [held]


def test_sigterm_to_demo_stops_its_nodes_and_keeps_what_it_recorded(tmp_path):
    out = tmp_path / 'demo'
    proc = subprocess.Popen([str(EXES / 'demo'), '--out', str(out), '--speeds', '37',
                             '--schedules', 'fixed'], cwd=tmp_path, stderr=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    _wait_for_bag_data(out / 'fixed_37', proc)
    children = _children(proc.pid)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    time.sleep(0.5)
    assert children and not any(_alive(c) for c in children)
    assert (out / 'fixed_37' / 'metadata.yaml').is_file()
    # what it wrote is listed: the next demo run may replace it, and nothing else
    from lookahead_control.tools.demo import MANIFEST
    assert (out / MANIFEST).read_text().split() == ['fixed_37']


# executables and arguments that start quickly into their real work
EARLY = {'closed_loop': ['--mode', 'realtime', '--no-record'],
         'controller': [], 'sim_plant': [], 'record': ['/x', '-o', '{tmp}/bag'],
         'schedule': [], 'paper_scenario': ['--out', '{tmp}/paper'],
         'demo': ['--out', '{tmp}/demo'], 'replay': ['{tmp}/none']}


INTERRUPTS = 'lookahead_control.core.interrupts'


@pytest.mark.parametrize('exe', sorted(EARLY))
def test_ctrl_c_in_the_first_second_is_one_line_not_a_traceback(exe, tmp_path):
    """
    Ctrl-C to the process group (a terminal) at 8 moments of the first second.

    From the moment the package has been imported (Python reports each import as it
    ends: ``PYTHONPROFILEIMPORTTIME``); before that, the interpreter and the console
    script run and nothing of this repository can act.
    """
    repo_frames = (f'File "{ROOT}/lookahead_control', f'File "{ROOT}/sim_plant')
    for k in range(8):
        folder = tmp_path / str(k)
        folder.mkdir()
        args = [a.format(tmp=folder) for a in EARLY[exe]]
        proc = subprocess.Popen([str(EXES / exe), *args], cwd=folder, text=True,
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                env={**os.environ, 'PYTHONPROFILEIMPORTTIME': '1'},
                                preexec_fn=lambda: (os.setpgrp(), _start_default_sigint()))
        seen = []
        try:
            # the next import after the interrupts module's is the executable's own: by
            # then the package's __init__ has installed the handling
            for line in proc.stderr:
                seen.append(line)
                if seen[-2:-1] and seen[-2].split('|')[-1].strip() == INTERRUPTS:
                    break
            time.sleep(k * 0.12 + random.uniform(0.0, 0.1))
            os.killpg(proc.pid, signal.SIGINT)
            err = ''.join(seen) + proc.communicate(timeout=60)[1]
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        err = ''.join(line for line in err.splitlines(keepends=True)
                      if not line.startswith('import time:'))
        assert not any(frame in err for frame in repo_frames), (k, err)
        assert 'Traceback' not in err and '[FATAL]' not in err, (k, err)


@pytest.mark.parametrize('signum, code, word', [(signal.SIGINT, 130, 'interrupted'),
                                                (signal.SIGTERM, 143, 'terminated')])
def test_a_start_up_interrupt_an_import_swallowed_stops_the_tool(
        signum, code, word, monkeypatch, capsys):
    # the demo, sent Ctrl-C in its first 0.1 s, once ran on past 60 s (1 full run in 7,
    # 1 in 10 of this test alone under two CPU hogs): a C extension's init can turn the
    # KeyboardInterrupt into an ImportError that a fallback catches. The nodes already
    # honoured such a signal (node_main); the tools now do too
    from lookahead_control.core import cli, interrupts
    monkeypatch.setattr(interrupts, 'received', [signum])
    called = []
    assert cli.run_tool(lambda argv: called.append(argv) or 0, []) == code
    assert not called
    assert capsys.readouterr().err.endswith(f': {word}\n')
    monkeypatch.setattr(interrupts, 'received', [])
    assert cli.run_tool(lambda argv: called.append(argv) or 0, []) == 0 and called == [[]]


class _Running:
    """A node process that runs until it is stopped; a poll may receive a signal."""

    def __init__(self, on_poll=None):
        self.returncode, self.on_poll, self.signals = None, on_poll, []

    def poll(self):
        if self.on_poll is not None and self.returncode is None:
            self.on_poll()
        return self.returncode

    def send_signal(self, signum):
        self.signals.append(signum)
        self.returncode = -signum

    def wait(self, timeout=None):
        return self.returncode


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM])
def test_a_swallowed_interrupt_stops_a_closed_loop_before_and_between_its_processes(
        signum, monkeypatch):
    # the demo, sent Ctrl-C 0.44 s after its start under a CPU hog, started its first run
    # and its next ones (1 of 80 starts; this session's test_ctrl_c_in_the_first_second
    # ...[demo] in .ci/run): an import inside main swallowed the interrupt after
    # run_tool's own look, and nothing looked again
    from lookahead_control.core import interrupts
    from lookahead_control.ros import closed_loop
    scenario = ROOT / 'config' / 'scenarios' / 'paper_r400.yaml'
    started = []
    monkeypatch.setattr(closed_loop, 'spawn', lambda command, env=None: started.append(
        _Running()) or started[-1])
    monkeypatch.setattr(interrupts, 'received', [int(signum)])
    with pytest.raises(KeyboardInterrupt) as stop:
        closed_loop.run_loop(closed_loop.LoopConfig(scenario, speed=37.0, timeout=3.0))
    assert started == [] and interrupts.exit_code(stop.value) == 128 + signum
    # received while the nodes run (an interrupt a callback or __del__ lost): they are
    # stopped, the tool stops
    monkeypatch.setattr(interrupts, 'received', [])
    monkeypatch.setattr(closed_loop, 'spawn', lambda command, env=None: started.append(
        _Running(lambda: interrupts.received.append(int(signum)))) or started[-1])
    with pytest.raises(KeyboardInterrupt) as stop:
        closed_loop.run_loop(closed_loop.LoopConfig(scenario, speed=37.0, timeout=3.0))
    assert interrupts.exit_code(stop.value) == 128 + signum
    assert len(started) == 2 and all(p.signals == [signal.SIGTERM] for p in started)


def _swallowing(calls, signum, result):
    """Return a stand-in that records its call and, as a lazy import would, loses a signal."""
    def stand_in(*args, **kwargs):
        from lookahead_control.core import interrupts
        calls.append(args)
        interrupts.received.append(int(signum))
        return result(*args) if callable(result) else result
    return stand_in


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM])
def test_a_swallowed_interrupt_stops_the_offline_tools_between_their_runs(
        signum, monkeypatch, tmp_path):
    # dev-sc49's Next: run_tool looked for a swallowed Ctrl-C only before main; the first
    # run of an offline tool's loop imports its heavy modules lazily (scipy for the LQR,
    # dask), and an interrupt an import turned into a caught ImportError let compare,
    # sweep, paper_scenario and analyze run all their other runs (minutes)
    from lookahead_control.core import interrupts
    from lookahead_control.core.config import load_vehicle
    from lookahead_control.core.params import ControllerParams
    from lookahead_control.tools import analyze_tool, compare, paper_scenario, sweep
    from sim_plant.vehicle_model import PlantParams
    vehicle = load_vehicle(None)
    monkeypatch.setattr(interrupts, 'received', [])
    calls = []
    monkeypatch.setattr(compare, 'run_case', _swallowing(calls, signum, []))
    with pytest.raises(KeyboardInterrupt) as stop:
        compare.league(['paper_eq26', 'lqr'], ['s0_straight'], [37.0], compare.PLANTS[:2],
                       vehicle, workers=1)
    assert len(calls) == 1 and interrupts.exit_code(stop.value) == 128 + signum
    monkeypatch.setattr(interrupts, 'received', [])
    calls.clear()
    tasks = [{'task': k} for k in range(3)]
    runner = _swallowing(calls, signum, {'law': ['x']})
    monkeypatch.setattr(sweep, 'write_parquet', lambda table, path: None)
    with pytest.raises(KeyboardInterrupt):
        sweep.execute(tmp_path, sweep.SweepSpec(), tasks, vehicle, ControllerParams(), 0, None,
                      False, runner=runner)
    assert len(calls) == 1
    monkeypatch.setattr(interrupts, 'received', [])
    calls.clear()
    monkeypatch.setattr(paper_scenario, 'run', _swallowing(calls, signum, None))
    with pytest.raises(KeyboardInterrupt):
        paper_scenario.reproduce(vehicle, ControllerParams(), PlantParams(), [10.0, 37.0],
                                 1.0, 0.005, 0.01)
    assert len(calls) == 1
    monkeypatch.setattr(interrupts, 'received', [])
    calls.clear()
    monkeypatch.setattr(analyze_tool, 'load_run', _swallowing(calls, signum, None))
    monkeypatch.setattr(analyze_tool, 'run_series', lambda run: None)
    monkeypatch.setattr(analyze_tool, 'bag_row', lambda run, series: {})
    with pytest.raises(KeyboardInterrupt):
        analyze_tool.analyze([tmp_path / 'a', tmp_path / 'b'], {}, 'controller', None)
    assert len(calls) == 1


def test_an_interrupt_a_caller_caught_does_not_stop_its_next_runs(monkeypatch, tmp_path):
    # dev-probe112: interrupts.received was never emptied; after one Ctrl-C that a caller
    # caught (run_tool in-process, or a script taken for an executable: one in a colcon
    # workspace's src/lookahead_control/), every later league, sweep and analyze stopped
    # at once
    from lookahead_control.core import cli, interrupts
    from lookahead_control.core.params import VehicleParams
    from lookahead_control.tools import compare
    monkeypatch.setattr(interrupts, 'received', [])
    calls = []
    monkeypatch.setattr(compare, 'run_case', _swallowing(calls, signal.SIGINT, []))
    league = ['paper_eq26', 'lqr'], ['s0_straight'], [37.0], compare.PLANTS[:1], VehicleParams()
    with pytest.raises(KeyboardInterrupt):
        compare.league(*league, workers=1)
    assert interrupts.received == []        # raised once: forgotten
    monkeypatch.setattr(compare, 'run_case', lambda task: calls.append(task) or [])
    assert compare.league(*league, workers=1) == [] and len(calls) == 3

    # run_tool answers a signal it received and forgets it, whether its main raised or
    # returned
    def swallowed(argv):
        interrupts.received.append(int(signal.SIGTERM))
        return 0
    assert cli.run_tool(swallowed, []) == 0 and interrupts.received == []
    assert cli.run_tool(lambda argv: len(compare.league(*league, workers=1)), []) == 0
    assert len(calls) == 5
    # a user's script in a folder of the package's name is not an executable
    assert not interrupts.running_as_executable('/ws/src/lookahead_control/my_analysis.py')
    assert interrupts.running_as_executable('/opt/ws/install/lib/lookahead_control/compare')


def test_a_signal_held_through_a_cleanup_is_obeyed_after_it(monkeypatch):
    # a Ctrl-C while closed_loop stopped the nodes of a run that had ended on its own
    # was dropped: the demo went on to its next run
    from lookahead_control.core import interrupts
    monkeypatch.setattr(interrupts, 'received', [])
    done = []
    with pytest.raises(KeyboardInterrupt):
        with interrupts.deferred() as held:
            signal.raise_signal(signal.SIGINT)
            done.append(held[:])
    assert done == [[signal.SIGINT]]
    # not kept as received (dev-probe110: a library caller that caught it had every
    # later run_loop stop at once, starting no process)
    assert interrupts.received == []
    with pytest.raises(interrupts.Terminated):
        with interrupts.deferred():
            signal.raise_signal(signal.SIGTERM)
    # an exception in flight carries the stop already: it is the one that propagates
    with pytest.raises(RuntimeError):
        with interrupts.deferred():
            signal.raise_signal(signal.SIGINT)
            raise RuntimeError('the run failed')
    # nothing held: nothing raised, the handlers are back
    before = signal.getsignal(signal.SIGINT)
    monkeypatch.setattr(interrupts, 'received', [])
    with interrupts.deferred():
        pass
    assert signal.getsignal(signal.SIGINT) is before and interrupts.received == []


@pytest.mark.parametrize('signum, code', [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_an_interrupt_wrapped_in_another_error_exits_with_the_signals_code(signum, code):
    # dev-probe56: replay, Ctrl-C at 0.77 s: 'replay: interrupted' and exit 1 (the
    # interrupt came to the excepthook inside another error, which Python exits 1 for)
    script = ('import sys\nsys.argv[0] = "-m"\nimport lookahead_control\n'
              'from lookahead_control.core import interrupts\n'
              'interrupts.received.append({})\n'
              'try:\n    raise {}\n'
              'except KeyboardInterrupt as stop:\n    raise RuntimeError("wrapped") from stop\n')
    stop = 'KeyboardInterrupt' if signum == signal.SIGINT else 'interrupts.Terminated()'
    out = subprocess.run([sys.executable, '-c', script.format(int(signum), stop)],
                         capture_output=True, text=True, timeout=60)
    word = 'interrupted' if signum == signal.SIGINT else 'terminated'
    assert (out.returncode, out.stderr) == (code, f'-m: {word}\n'), out


def test_an_interrupt_python_cannot_raise_is_silent_in_an_executable():
    # as in a child Ctrl-C reaches between fork and exec, in threading's after-fork hook
    code = ('import sys\nsys.argv[0] = {!r}\nimport lookahead_control\n'
            'class A:\n    def __del__(self):\n        raise {}\nA()\nprint("went on")\n')
    for argv0, error, silent in (('-m', 'KeyboardInterrupt', True),
                                 ('script.py', 'KeyboardInterrupt', False),
                                 ('-m', 'RuntimeError("x")', False)):
        out = subprocess.run([sys.executable, '-c', code.format(argv0, error)],
                             capture_output=True, text=True, timeout=60)
        assert out.stdout == 'went on\n', out.stderr
        assert (out.stderr == '') is silent, (argv0, error, out.stderr)
    # what an interrupt left half done: a Ctrl-C inside rclpy's logger constructor at
    # 'import rclpy' (its root logger, before node_main's class default exists) made its
    # __del__ print 'Exception ignored ... AttributeError' after 'record: interrupted'
    # (this session's test_ctrl_c_in_the_first_second...[record], moment 3 of 8)
    half = ('import sys\nsys.argv[0] = {!r}\nimport lookahead_control\n'
            'from lookahead_control.core import interrupts\n{}\n'
            'from rclpy.impl.rcutils_logger import RcutilsLogger\n'
            'if hasattr(RcutilsLogger, "logger_sublogger_namepair"):\n'
            '    del RcutilsLogger.logger_sublogger_namepair\n'
            'RcutilsLogger.__new__(RcutilsLogger)\nprint("went on")\n')
    for argv0, signalled, silent in (('-m', True, True), ('-m', False, False),
                                     ('script.py', True, False)):
        out = subprocess.run([sys.executable, '-c', half.format(
            argv0, 'interrupts.received.append(2)' if signalled else '')],
            capture_output=True, text=True, timeout=60)
        assert out.stdout == 'went on\n', out.stderr
        assert (out.stderr == '') is silent, (argv0, signalled, out.stderr)


def test_ctrl_c_of_a_realtime_closed_loop_has_no_fatal_callback_error(tmp_path):
    proc = subprocess.Popen([str(EXES / 'closed_loop'), '--mode', 'realtime', '--bag',
                             str(tmp_path / 'run')], cwd=tmp_path, text=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            preexec_fn=lambda: (os.setpgrp(), _start_default_sigint()))
    _wait_for_bag_data(tmp_path / 'run', proc)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130
    assert '[FATAL]' not in err and 'Traceback' not in err, err
    assert (tmp_path / 'run' / 'metadata.yaml').is_file()


def test_a_logger_interrupted_in_its_constructor_deletes_quietly():
    # session 24: Ctrl-C to replay at 0.36 s landed inside rclpy's RcutilsLogger.__init__
    # before it set the attribute its __del__ reads: 'Exception ignored ... Traceback'
    # after the one-line 'replay: interrupted'
    import lookahead_control.ros.node_main  # noqa: F401  (the default it sets)
    from rclpy.impl.rcutils_logger import RcutilsLogger
    half_built = RcutilsLogger.__new__(RcutilsLogger)
    half_built.__del__()


def test_a_negative_sim_clock_is_dropped_not_a_crash(probe):
    # dev-probe90: one /clock message with sec < 0 (a simulator's clock wrapped past int32,
    # a bad bridge) raised ValueError in rclpy's time source: the controller died with a
    # traceback, no command, no diagnostics. Now it is dropped, said, and the node runs on
    import threading
    from diagnostic_msgs.msg import DiagnosticArray
    from rosgraph_msgs.msg import Clock
    node, executor = probe
    diagnostics = []
    node.create_subscription(DiagnosticArray, '/diagnostics',
                             lambda m: diagnostics.append(m.status[0].message), 100)
    clock = node.create_publisher(Clock, '/clock', 10)
    now = [100.0]

    def tick(seconds):
        """Publish the sim clock for ``seconds`` of it, 10 ms a message."""
        for _ in range(int(round(seconds / 0.01))):
            now[0] += 0.01
            message = Clock()
            message.clock.sec, message.clock.nanosec = int(now[0]), int(now[0] % 1.0 * 1e9)
            clock.publish(message)
            executor.spin_once(timeout_sec=0.002)
    controller = subprocess.Popen([str(EXES / 'controller'), '--ros-args', '-p',
                                   'use_sim_time:=true'], stderr=subprocess.PIPE, text=True)
    lines = []
    reader = threading.Thread(target=lambda: lines.extend(controller.stderr), daemon=True)
    reader.start()
    said = '/clock message with a negative time dropped (sec -1, nanosec 0)'
    try:
        assert spin_until(executor, lambda: clock.get_subscription_count() > 0, 30)
        end = time.monotonic() + 30
        while time.monotonic() < end and not diagnostics:
            tick(0.5)
        assert diagnostics, 'the controller never published diagnostics on the sim clock'
        bad = Clock()
        bad.clock.sec = -1
        clock.publish(bad)
        # nothing after it until the node has taken it (the time source keeps one message)
        assert spin_until(executor, lambda: controller.poll() is not None or any(
            said in line for line in lines), 30), lines
        assert controller.poll() is None, ''.join(lines)
        seen = len(diagnostics)
        end = time.monotonic() + 30
        while time.monotonic() < end and len(diagnostics) <= seen + 2:
            tick(0.5)
        assert controller.poll() is None, ''.join(lines)
        assert len(diagnostics) > seen + 2, 'no diagnostics after the negative clock'
    finally:
        controller.send_signal(signal.SIGINT)
        controller.wait(timeout=30)
        reader.join(timeout=10)
    err = ''.join(lines)
    assert controller.returncode == 0, err
    assert 'Traceback' not in err and err.count(said) == 1, err


def test_a_clock_subscription_made_at_run_time_is_guarded_too():
    # dev-probe91: the guard wrapped the /clock subscriptions there were when the node was
    # made; use_sim_time set later (a set, a lifecycle node configured again) made an
    # unguarded one, and a negative /clock raised out of the executor again
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from rosgraph_msgs.msg import Clock
    from lookahead_control.ros.node_main import install_clock_guard
    ctx = Context()
    rclpy.init(context=ctx)
    node = Node('clock_guard_probe', context=ctx)
    try:
        install_clock_guard(node)
        assert not [s for s in node.subscriptions if s.topic_name == '/clock']
        node.set_parameters([Parameter('use_sim_time', value=True)])
        clocks = [s for s in node.subscriptions if s.topic_name == '/clock']
        assert len(clocks) == 1
        bad, good = Clock(), Clock()
        bad.clock.sec, good.clock.sec = -1, 5
        clocks[0].callback(bad)                 # before: ValueError
        clocks[0].callback(good)
        assert node.get_clock().now().nanoseconds == 5_000_000_000
        clocks[0].callback(bad)                 # the clock keeps its last time
        assert node.get_clock().now().nanoseconds == 5_000_000_000
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
