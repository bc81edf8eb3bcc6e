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

"""The analysis executables: tables, plots, files, and one-line errors."""

import json
from pathlib import Path
import signal
import subprocess
import sys

from lookahead_control.core.cli import ToolError
import pytest

ROOT = Path(__file__).resolve().parent.parent


def _tool(module_func: str, *args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    module, func = module_func.split(':')
    code = f'import sys\nfrom {module} import {func}\nsys.exit({func}())'
    return subprocess.run([sys.executable, '-c', code, *args], cwd=cwd,
                          capture_output=True, text=True, timeout=300,
                          env={'PYTHONPATH': str(ROOT), 'PATH': '/usr/bin:/bin',
                               'MPLBACKEND': 'Agg'})


SCHEDULE = 'lookahead_control.tools.analysis_tools:schedule'
ZERO = 'lookahead_control.tools.analysis_tools:zero_dynamics_tool'
CERT = 'lookahead_control.tools.analysis_tools:certificate_tool'
PAPER = 'lookahead_control.tools.paper_scenario:entry'


def test_schedule_tool_table_and_plot(tmp_path):
    result = _tool(SCHEDULE, '--v-min', '10', '--v-max', '30', '--step', '10',
                   '--plot', str(tmp_path / 's.png'), '--json', str(tmp_path / 's.json'))
    assert result.returncode == 0, result.stderr
    assert '| 20 | 1.96 | 10.61 |' in result.stdout
    assert (tmp_path / 's.png').read_bytes()[:4] == b'\x89PNG'
    rows = json.loads((tmp_path / 's.json').read_text())
    assert [r['speed_mps'] for r in rows] == [10.0, 20.0, 30.0]


def test_an_output_file_replaces_only_an_earlier_output(tmp_path, capsys):
    # dev-probe96: `--json README.md` replaced the README (exit 0), and a --json under a
    # file failed only after a whole league ('File exists'); now refused when read
    from lookahead_control.tools.analysis_tools import schedule_main as schedule
    readme = tmp_path / 'README.md'
    readme.write_text('# mine\n')
    notes = tmp_path / 'notes.json'
    notes.write_text('my notes, not JSON\n')
    picture = tmp_path / 'photo.png'
    picture.write_bytes(b'GIF89a, named .png')
    (tmp_path / 'a_file').write_text('x')
    (tmp_path / 'a_folder.json').mkdir()
    base = ['--v-min', '10', '--v-max', '20', '--step', '10']
    for args, said in (
            (['--json', str(readme)], 'README.md: expected a .json file name'),
            (['--json', str(notes)], 'notes.json: exists and is no JSON file a tool wrote'),
            (['--plot', str(picture)], 'photo.png: exists and is no PNG file a tool wrote'),
            (['--json', str(tmp_path / 'a_file' / 'x.json')],
             f'{tmp_path / "a_file"} is not a folder this user may write in'),
            (['--json', str(tmp_path / 'a_folder.json')], 'a_folder.json: is a folder')):
        with pytest.raises(SystemExit) as exit_:
            schedule([*base, *args])
        assert exit_.value.code == 2, args
        assert said in capsys.readouterr().err, args
    from lookahead_control.bags import replay_node
    with pytest.raises(SystemExit) as exit_:      # the option is read before the bag
        replay_node.main([str(tmp_path / 'no_bag'), '--offline', '--json', str(readme)])
    assert exit_.value.code == 2 and 'expected a .json file name' in capsys.readouterr().err
    assert readme.read_text() == '# mine\n' and notes.read_text() == 'my notes, not JSON\n'
    assert picture.read_bytes() == b'GIF89a, named .png'
    # dev-probe98: a FIFO hung the check (it read it), links were followed (a JSON file
    # elsewhere rewritten; a dangling x.json -> NOTES.md wrote NOTES.md), a file that
    # only began with [ (a git config) passed
    import os
    os.mkfifo(tmp_path / 'pipe.json')
    elsewhere = tmp_path / 'cfg'
    elsewhere.mkdir()
    (elsewhere / 'settings.json').write_text('{"mine": 1}')
    (tmp_path / 'link.json').symlink_to(elsewhere / 'settings.json')
    (tmp_path / 'dangling.json').symlink_to(elsewhere / 'NOTES.md')
    (tmp_path / 'gitcfg.json').write_text('[core]\n\tbare = false\n')
    for args, said in ((['--json', str(tmp_path / 'pipe.json')], 'is not a regular file'),
                       (['--json', str(tmp_path / 'link.json')], 'is a symbolic link'),
                       (['--json', str(tmp_path / 'dangling.json')], 'is a symbolic link'),
                       (['--json', str(tmp_path / 'gitcfg.json')], 'is no JSON file')):
        with pytest.raises(SystemExit) as exit_:
            schedule([*base, *args])
        assert exit_.value.code == 2 and said in capsys.readouterr().err, args
    assert (elsewhere / 'settings.json').read_text() == '{"mine": 1}'
    assert not (elsewhere / 'NOTES.md').exists()
    # an earlier output is replaced: the same command twice
    out, png = tmp_path / 'new' / 'table.json', tmp_path / 'table.png'
    for _ in range(2):
        assert schedule([*base, '--json', str(out), '--plot', str(png)]) == 0
        assert [r['speed_mps'] for r in json.loads(out.read_text())] == [10.0, 20.0]
        assert png.read_bytes()[:4] == b'\x89PNG'


def test_files_an_earlier_run_left_in_the_output_folder_are_named(tmp_path, capsys):
    # dev-probe96: analyze of two bags, then of one into the same --out: the first run's
    # fig_fixed.png stayed beside the new report, listed, unsaid (nothing is deleted)
    from lookahead_control.core.cli import claim_output, record_output
    out = tmp_path / 'report'
    first = [out / 'report.md', out / 'fig_fixed.png', out / 'fig_paper.png']
    assert claim_output(out, 'analyze', names=[p.name for p in first]) == frozenset()
    for path in first:
        path.write_text('first')
    record_output(out, 'analyze', first)
    assert capsys.readouterr().err == ''
    second = [out / 'report.md', out / 'fig_paper.png']
    previous = claim_output(out, 'analyze', names=[p.name for p in second])
    record_output(out, 'analyze', second, previous)
    assert capsys.readouterr().err == (
        f'analyze: note: {out} keeps 1 file(s) of an earlier analyze run that this one did '
        "not write: fig_fixed.png (a new --out has only this run's)\n")
    assert (out / 'fig_fixed.png').read_text() == 'first'           # nothing deleted
    (out / 'fig_fixed.png').unlink()                                # moved away: quiet
    record_output(out, 'analyze', second, claim_output(out, 'analyze'))
    assert capsys.readouterr().err == ''


def test_zero_dynamics_tool_plot(tmp_path):
    result = _tool(ZERO, '--plot', str(tmp_path / 'roots.png'))
    assert result.returncode == 0, result.stderr
    assert (tmp_path / 'roots.png').stat().st_size > 10000


def test_certificate_tool_passes_and_fails():
    ok = _tool(CERT)
    assert ok.returncode == 0, ok.stderr
    assert 'certificate HOLDS' in ok.stdout and '0.477' in ok.stdout
    bad = _tool(CERT, '--a-max', '12', '--samples', '101')
    assert bad.returncode == 1
    assert 'DOES NOT HOLD' in bad.stdout


def test_paper_scenario_writes_report(tmp_path):
    result = _tool(PAPER, '--speeds', '20', '37', '--duration', '6', '--out', str(tmp_path))
    assert result.returncode == 0, result.stderr
    rows = json.loads((tmp_path / 'metrics.json').read_text())
    assert [(r['controller'], r['speed_mps']) for r in rows] == [
        ('fixed', 20.0), ('fixed', 37.0), ('paper', 20.0), ('paper', 37.0)]
    report = (tmp_path / 'report.md').read_text()
    assert 'fig_fixed.png' in report and 'fig_paper.png' in report
    assert (tmp_path / 'fig_paper.png').exists()


@pytest.mark.parametrize('tool', [SCHEDULE, ZERO, CERT, PAPER])
def test_bad_vehicle_file_is_one_line_and_nonzero(tool, tmp_path):
    bad = tmp_path / 'vehicle.yaml'
    bad.write_text('/**:\n  ros__parameters:\n    vehicle: {mass: -5.0}\n')
    result = _tool(tool, '--vehicle', str(bad))
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert 'vehicle.yaml' in lines[0] and 'vehicle.mass = -5.0' in lines[0]
    missing = _tool(tool, '--vehicle', str(tmp_path / 'nope.yaml'))
    assert missing.returncode == 2 and 'nope.yaml: cannot read' in missing.stderr
    assert 'Traceback' not in missing.stderr


# -- issue 12: data loss, options, errors, one parameter schema --------------------------

def _exe(name, *args, cwd=ROOT, timeout=120, **kwargs):
    """Run an installed executable (``<prefix>/lib/lookahead_control/<name>``)."""
    exe = Path(sys.prefix) / 'lib' / 'lookahead_control' / name
    return subprocess.run([str(exe), *map(str, args)], cwd=cwd, capture_output=True,
                          text=True, timeout=timeout, **kwargs)


def _home_like(path):
    """Return a folder with a user's files in it (and what they hold)."""
    path.mkdir()
    (path / 'notes.txt').write_text('my notes\n')
    (path / 'thesis').mkdir()
    (path / 'thesis' / 'chapter1.tex').write_text('\\chapter{One}\n')
    return {p.relative_to(path): p.read_bytes() for p in path.rglob('*') if p.is_file()}


def _same(path, files):
    return {p.relative_to(path): p.read_bytes() for p in path.rglob('*') if p.is_file()} == files


@pytest.mark.parametrize('args', [['--speeds', '200'], ['--schedules', 'bogus'],
                                  ['--speeds', '20', '--schedules', 'fixed']])
def test_demo_never_deletes_a_folder_it_did_not_make(tmp_path, args):
    home = tmp_path / 'runs'
    files = _home_like(home)
    out = _exe('demo', '--out', home, *args, cwd=tmp_path)
    assert out.returncode == 2, out.stderr
    assert len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert _same(home, files)
    assert sorted(p.name for p in tmp_path.iterdir()) == ['runs']    # no bag, no bags/


def test_demo_replaces_only_what_its_last_run_wrote(tmp_path):
    from lookahead_control.tools.demo import MANIFEST, prepare_out
    out = tmp_path / 'demo'
    (out / 'fixed_10').mkdir(parents=True)
    (out / 'fixed_10' / 'fixed_10.mcap').write_bytes(b'old run')
    (out / 'report.md').write_text('old report')
    (out / MANIFEST).write_text('fixed_10\nreport.md\n')
    prepare_out(out)
    assert list(out.iterdir()) == []
    # a file the user added to a demo folder: refused, nothing deleted
    (out / 'fixed_10').mkdir()
    (out / 'mine.txt').write_text('mine')
    (out / MANIFEST).write_text('fixed_10\n')
    with pytest.raises(ToolError, match='mine.txt'):
        prepare_out(out)
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST, 'fixed_10', 'mine.txt']
    bags = tmp_path / 'bags'                # `demo --out bags`: recorded bags inside
    (bags / 'run_1').mkdir(parents=True)
    (bags / 'run_1' / 'metadata.yaml').write_text('x')
    with pytest.raises(ToolError, match='not empty and not a demo folder'):
        prepare_out(bags)
    assert (bags / 'run_1' / 'metadata.yaml').read_text() == 'x'


def _small_bag(path, count=200):
    """Write a complete bag of ``count`` Float64 messages on /x."""
    from lookahead_control.bags.rosbag_io import BagWriter, qos_from_ints, serialize_cdr
    from std_msgs.msg import Float64
    writer = BagWriter(path, chunk_interval=0.0001)
    writer.add_topic('/x', 'std_msgs/msg/Float64',
                     [qos_from_ints({'reliability': 1, 'durability': 2, 'depth': 10})])
    for k in range(count):
        writer.write('/x', 1_000_000_000 + k * 10_000_000, serialize_cdr(Float64(data=k)))
    writer.close()


def test_recover_leaves_a_complete_bag_and_every_backup_alone(tmp_path):
    bag = tmp_path / 'bag'
    _small_bag(bag)
    before = {p.name: p.read_bytes() for p in bag.iterdir()}
    for _ in range(2):
        out = _exe('recover', bag)
        assert out.returncode == 0, out.stderr
        assert 'is complete' in out.stdout and 'nothing to recover' in out.stdout
        assert {p.name: p.read_bytes() for p in bag.iterdir()} == before
    # a truncated bag, recovered twice (the second time cut again): two backups, both kept
    data = before['bag.mcap']
    (bag / 'metadata.yaml').unlink()
    (bag / 'bag.mcap').write_bytes(data[:len(data) // 2])
    assert _exe('recover', bag).returncode == 0
    first = (bag / 'bag.mcap.truncated').read_bytes()
    assert first == data[:len(data) // 2]
    recovered = (bag / 'bag.mcap').read_bytes()
    (bag / 'metadata.yaml').unlink()
    (bag / 'bag.mcap').write_bytes(recovered[:len(recovered) - 100])
    out = _exe('recover', bag)
    assert out.returncode == 0, out.stderr
    assert (bag / 'bag.mcap.truncated').read_bytes() == first
    assert (bag / 'bag.mcap.truncated.2').read_bytes() == recovered[:len(recovered) - 100]
    assert 'bag.mcap.truncated.2' in out.stdout


@pytest.mark.parametrize('text,named', [
    ('scenario:\n  speed: {initial: 20}\n  road:\n'
     '    - {type: arc, length: 100, curvature: bad}\n', 'road[0].curvature'),
    ('', 'empty file'),
    ('scenario:\n  duration: soon\n  speed: {initial: 20}\n  road:\n'
     '    - {type: straight, length: 100}\n', 'scenario.duration'),
    ('scenario:\n  speed: {initial: 20, bogus: 1}\n  road:\n'
     '    - {type: straight, length: 100}\n', 'bogus'),
    ('scenario:\n  speed: {initial: 20}\n  initial: {yaw: 1}\n  road:\n'
     '    - {type: straight, length: 100}\n', "initial: unknown keys ['yaw']"),
])
def test_bad_scenario_is_one_line_naming_file_and_field_before_any_process(tmp_path, text,
                                                                           named):
    scenario = tmp_path / 'scn.yaml'
    scenario.write_text(text)
    out = _exe('closed_loop', '--scenario', scenario, '--speed', '20', cwd=tmp_path)
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and 'scn.yaml' in lines[0] and named in lines[0], out.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ['scn.yaml']   # no bag


@pytest.mark.parametrize('args,blamed', [
    (['closed_loop', '--speed', '-5'], '--speed'), (['closed_loop', '--rate', '0'], '--rate'),
    (['demo', '--speeds', '200'], '--speeds'), (['paper_scenario', '--speeds', '-5'], '--speeds'),
    (['record', '-e', '[unclosed', '-o', 'b'], "-e '[unclosed'"),
    (['certificate', '--v-max', 'inf'], '--v-max'), (['certificate', '--samples', '1'],
                                                     '--samples'),
])
def test_bad_option_blames_the_option_before_anything_starts(tmp_path, args, blamed):
    out = _exe(*args, cwd=tmp_path)
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and blamed in lines[0], out.stderr
    assert 'paper_r400' not in lines[0] and 'segment' not in lines[0]
    assert list(tmp_path.iterdir()) == []


def test_schema_is_the_nodes_descriptors_and_the_dataclass_defaults():
    from lookahead_control.core.param_schema import (CONTROLLER_SPECS, SAFETY_SPECS,
                                                     VEHICLE_SPECS)
    from lookahead_control.core.params import ControllerParams, VehicleParams
    from lookahead_control.core.safety import SafetyParams
    from lookahead_control.ros import node_params
    for cls, specs in ((VehicleParams, VEHICLE_SPECS), (ControllerParams, CONTROLLER_SPECS),
                       (SafetyParams, SAFETY_SPECS)):
        defaults = cls()
        for spec in specs:
            assert getattr(defaults, spec.name.split('.', 1)[1]) == spec.default, spec.name
    assert node_params.VEHICLE_SPECS is VEHICLE_SPECS
    assert node_params.SAFETY_SPECS is SAFETY_SPECS
    desc = node_params.descriptor(VEHICLE_SPECS[0])
    assert (desc.floating_point_range[0].from_value, desc.floating_point_range[0].to_value) \
        == (VEHICLE_SPECS[0].low, VEHICLE_SPECS[0].high)


VEHICLE_FILES = {
    'typo': ('vehicle: {masss: 1500.0}', "unknown parameter 'vehicle.masss'"),
    'low': ('vehicle: {mass: 0.5}', 'vehicle.mass = 0.5 kg is out of range; allowed: [1, '),
    'bool': ('vehicle: {mass: true}', 'vehicle.mass = True: expected a number'),
    'text': ("vehicle: {d_s: 'far'}", "vehicle.d_s = 'far': expected a number"),
    'integer': ('vehicle: {mass: 1485}', None),
}


@pytest.mark.parametrize('case', sorted(VEHICLE_FILES))
def test_a_params_file_means_the_same_to_nodes_and_tools(case, tmp_path):
    body, error = VEHICLE_FILES[case]
    params = tmp_path / 'vehicle.yaml'
    params.write_text('/**:\n  ros__parameters:\n    ' + body + '\n')
    offline = _tool(SCHEDULE, '--vehicle', str(params))
    scenario = tmp_path / 'short.yaml'
    scenario.write_text('scenario:\n  duration: 0.2\n  speed: {initial: 20}\n  road:\n'
                        '    - {type: straight, length: 100}\n')
    command = [str(Path(sys.prefix) / 'lib' / 'lookahead_control' / 'sim_plant'),
               '--ros-args', '--params-file', str(params), '-p', f'scenario_file:={scenario}']
    if error is None:
        assert offline.returncode == 0, offline.stderr
        # the node takes the file: it declares its parameters, logs its scenario, and
        # then waits for a controller; stopped there
        proc = subprocess.Popen(command, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
        try:
            line = proc.stderr.readline()
            assert "scenario 'paper" in line or 'scenario' in line, line
        finally:
            proc.send_signal(signal.SIGINT)
            rest = proc.communicate(timeout=60)[1]
        assert proc.returncode == 0, line + rest
        return
    node = subprocess.run(command, capture_output=True, text=True, cwd=tmp_path, timeout=120)
    for out in (offline, node):
        assert out.returncode == 2, out.stderr
        lines = out.stderr.strip().splitlines()
        assert len(lines) == 1, out.stderr
        assert f'{params}: ' in lines[0] and error in lines[0], lines[0]
    assert offline.stderr.split(': ', 2)[2] == node.stderr.split(': ', 2)[2]


def test_node_command_line_values_are_checked_with_the_same_schema():
    out = _exe('controller', '--ros-args', '-p', 'vehicle.masss:=1500', '-p',
               'vehicle.mass:=1485')
    assert out.returncode == 2
    assert out.stderr.strip() == ('controller: error: -p vehicle.masss:=1500: unknown '
                                  "parameter 'vehicle.masss'; did you mean vehicle.mass or "
                                  'vehicle.d_s?')


def test_tool_piped_into_head_exits_quietly():
    exe = Path(sys.prefix) / 'lib' / 'lookahead_control' / 'zero_dynamics'
    proc = subprocess.Popen([str(exe), '--step', '0.01'], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    proc.stdout.readline()
    proc.stdout.close()                     # the reader leaves, as `| head -1` does
    _, err = proc.communicate(timeout=120)
    assert err.decode() == ''
    assert proc.returncode in (0, 141)


def test_paper_scenario_never_overwrites_a_report_it_did_not_write(tmp_path):
    home = tmp_path / 'thesis'
    home.mkdir()
    (home / 'report.md').write_text('my report\n')
    out = _exe('paper_scenario', '--out', home, '--speeds', '20', '--duration', '1',
               '--no-plots', cwd=tmp_path)
    assert out.returncode == 2 and 'report.md' in out.stderr, out.stderr
    assert (home / 'report.md').read_text() == 'my report\n'
    # its own folder it rewrites, run after run
    mine = tmp_path / 'mine'
    for _ in range(2):
        assert _exe('paper_scenario', '--out', mine, '--speeds', '20', '--duration', '1',
                    '--no-plots', cwd=tmp_path).returncode == 0
    assert (mine / 'report.md').read_text().startswith('# Paper scenario')


@pytest.mark.parametrize('module', ['compare', 'paper_scenario', 'lane_keeping_tool',
                                    'sweep', 'analyze_tool', 'demo'])
def test_each_tool_module_runs_with_python_m(module):
    # before: `python -m lookahead_control.tools.compare ...` imported the module and
    # exited 0 without running anything (no __main__ guard)
    out = subprocess.run([sys.executable, '-m', f'lookahead_control.tools.{module}', '--help'],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.startswith('usage:'), out
