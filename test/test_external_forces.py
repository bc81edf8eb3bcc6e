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
A scenario's ``external_forces`` (crosswind, bank): every plant, offline and in the node.

dev-sc36 measured the default law's side force with a disturbance only the offline runner
took (a Python callable; the CommonRoad car through a monkeypatch): the simulator node had
no way to push the car, so no run over DDS, no bag, no ``compare`` row had a side force.
"""

from __future__ import annotations

from dataclasses import replace
import math
from pathlib import Path

from lookahead_control.core.config import ConfigError
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
import numpy as np
import pytest
from sim_plant.closed_loop_sim import run
from sim_plant.commonroad_plant import commonroad_parameters, CommonRoadPlant, controller_vehicle
from sim_plant.road import Road, Segment
from sim_plant.scenario import ExternalForce, load_scenario, Scenario, scenario_from_dict
from sim_plant.speed_profile import SpeedProfile
from sim_plant.vehicle_model import PlantParams

ROOT = Path(__file__).resolve().parent.parent
CROSSWIND = ROOT / 'config' / 'scenarios' / 'crosswind.yaml'
STRAIGHT = Road([Segment('straight', 3000.0)])


def _document(forces):
    return {'scenario': {'name': 'x', 'duration': 5.0, 'speed': {'initial': 20.0},
                         'road': [{'type': 'straight', 'length': 500.0}],
                         'external_forces': forces}}


def test_a_force_acts_from_its_start_for_its_duration_and_entries_add():
    step = ExternalForce(start=1.0, duration=2.0, force=1500.0, moment=-300.0)
    assert step.at(0.999) == (0.0, 0.0) and step.at(1.0) == (1500.0, -300.0)
    assert step.at(2.999) == (1500.0, -300.0) and step.at(3.0) == (0.0, 0.0)
    forever = ExternalForce(start=1.0, force=100.0)
    assert forever.at(1e4) == (100.0, 0.0)
    gust = ExternalForce(start=2.0, force=1000.0, moment=10.0, frequency=0.25)
    assert gust.at(3.0) == pytest.approx((1000.0, 10.0))      # a quarter period in
    assert gust.at(4.0)[0] == pytest.approx(0.0, abs=1e-9)
    scenario = Scenario('s', 5.0, STRAIGHT, SpeedProfile(20.0), forces=(step, forever, gust))
    half = math.sqrt(0.5)                                   # the gust an eighth period in
    assert scenario.external(2.5) == pytest.approx((1500.0 + 100.0 + 1000.0 * half,
                                                    -300.0 + 10.0 * half))
    assert Scenario('s', 5.0, STRAIGHT, SpeedProfile(20.0)).external(3.0) == (0.0, 0.0)


def test_the_shipped_crosswind_is_1_5_kN_from_2_to_12_s_and_kept_at_another_speed():
    scenario = load_scenario(CROSSWIND)
    assert scenario.forces == (ExternalForce(start=2.0, duration=10.0, force=1500.0),)
    assert scenario.external(1.99) == (0.0, 0.0) and scenario.external(2.0) == (1500.0, 0.0)
    assert scenario.external(12.0) == (0.0, 0.0)
    assert load_scenario(CROSSWIND, 20.0).forces == scenario.forces


@pytest.mark.parametrize('forces, message', [
    ([{'start': 1.0, 'force': 1e9}], 'external_forces[0].force = 1000000000.0 N is out of '
     'range; allowed: [-50000, 50000] N'),
    ([{'force': 1.0}, {'start': -1.0}], 'external_forces[1].start = -1.0 s is out of range'),
    ([{'start': 1.0, 'frequency': 100.0}], 'external_forces[0].frequency = 100.0 Hz'),
    ([{'force': float('nan')}], 'external_forces[0].force'),
    ([{'sart': 1.0}], "external_forces[0]: unknown keys ['sart']"),
    ([3.0], 'external_forces[0] must be a mapping'),
    ('wind', 'external_forces must be a list of mappings'),
    (None, 'external_forces must be a list of mappings'),
])
def test_a_bad_external_force_is_refused_naming_the_entry(forces, message):
    with pytest.raises(ConfigError) as err:
        scenario_from_dict(_document(forces))
    assert message in str(err.value)


def test_the_runner_takes_the_scenarios_forces_as_it_takes_a_disturbance():
    # the same push through the scenario or the disturbance argument: the same run, to
    # the last bit; both at once is refused (which would the user mean?)
    forces = (ExternalForce(start=0.5, force=1500.0, moment=400.0),
              ExternalForce(start=1.0, force=-600.0, frequency=0.5))
    plain = Scenario('s', 3.0, STRAIGHT, SpeedProfile(30.0))
    pushed = replace(plain, forces=forces)
    vehicle = VehicleParams()
    law = ControllerParams()
    for model in ('linear', 'nonlinear'):
        a = run(pushed, vehicle, law, PlantParams(model=model), delay=0.02)
        b = run(plain, vehicle, law, PlantParams(model=model), delay=0.02,
                disturbance=pushed.external)
        assert np.array_equal(a['y_cg'], b['y_cg']) and np.array_equal(a['r'], b['r'])
        assert np.max(np.abs(a['y_cg'])) > 0.01
    with pytest.raises(ParameterError, match='external_forces: give the disturbance there '
                       'or as the disturbance argument, not both'):
        run(pushed, vehicle, law, disturbance=pushed.external)


def _plant(model, forces, speed=30.0):
    scenario = Scenario('s', 10.0, Road([Segment('straight', 3000.0)]), SpeedProfile(speed),
                        forces=forces)
    return CommonRoadPlant(scenario, PlantParams(model=model, vehicle_id=2), speed, 0.0)


def _contract_after(plant, steps, dt):
    for k in range(steps):
        plant.advance(k * dt, dt, 0.0)
    return plant.contract()[0]


def _momentum(plant):
    """Return the car's lateral momentum [N s] in its body frame."""
    x, p = plant.state, plant.p
    if not plant.multibody:
        return p.m * plant.body_velocity(x)[1]
    # the sprung mass and the front and rear unsprung masses each have a lateral velocity
    return p.m_s * x[10] + p.m_uf * x[15] + p.m_ur * x[20]


@pytest.mark.parametrize('model', ['commonroad_st', 'commonroad_mb'])
def test_a_commonroad_car_is_pushed_by_newtons_law_at_first(model):
    # 5 ms after a force of 1.5 kN (or a moment of 2 kN m) starts, before the tyres have
    # a slip to answer with: the lateral momentum grows by F t, r by M t / I_z (the
    # multi-body force is on the sprung mass; its suspension passes it on to the others)
    p = commonroad_parameters(2)
    t, steps = 0.005, 5
    plants = {name: _plant(model, forces) for name, forces in (
        ('free', ()), ('wind', (ExternalForce(force=1500.0),)),
        ('turn', (ExternalForce(moment=2000.0),)))}
    x = {name: _contract_after(plant, steps, 1e-3) for name, plant in plants.items()}
    assert _momentum(plants['wind']) - _momentum(plants['free']) == pytest.approx(
        1500.0 * t, rel=0.03)
    assert abs(x['wind'][4] - x['free'][4]) < 1e-4
    assert x['turn'][4] - x['free'][4] == pytest.approx(2000.0 * t / p.I_z, rel=0.03)


def test_the_single_track_car_drifts_as_the_linear_model_says_under_a_steady_force():
    # independent: the linear single-track steady state with the mapped stiffnesses
    # (the CommonRoad single track's tyres are linear): C_f l1 = C_r l2 for this
    # mapping, so the car slides without turning, v_y = F v / (C_f + C_r)
    speed, force = 30.0, 200.0
    vehicle = controller_vehicle(2)
    x = _contract_after(_plant('commonroad_st', (ExternalForce(force=force),), speed), 4000,
                        2e-3)
    assert x[3] == pytest.approx(force * speed / (vehicle.c_f + vehicle.c_r), rel=1e-3)
    assert abs(x[4]) < 1e-5


def test_the_commonroad_plant_takes_the_scenarios_forces_but_no_other_disturbance():
    scenario = Scenario('s', 1.0, STRAIGHT, SpeedProfile(30.0),
                        forces=(ExternalForce(start=0.2, force=1500.0),))
    vehicle = controller_vehicle(2)
    plant = PlantParams(model='commonroad_st', vehicle_id=2)
    pushed = run(scenario, vehicle, ControllerParams(), plant, dt=0.002)
    calm = run(replace(scenario, forces=()), vehicle, ControllerParams(), plant, dt=0.002)
    assert np.max(pushed['v_y'] - calm['v_y']) > 0.01
    with pytest.raises(ParameterError, match="no disturbance but the scenario's "
                       'external_forces'):
        run(replace(scenario, forces=()), vehicle, ControllerParams(), plant, dt=0.002,
            disturbance=lambda t: (100.0, 0.0))


def test_the_default_law_is_ahead_of_itself_without_the_side_force_on_the_crosswind():
    # the shipped scenario on the goal plant's dynamics (Fiala tyres, actuator, 20 ms),
    # through the league's own runner: side_force 0 -> 1, 37 m/s, 25 -> 11 cm
    from lookahead_control.core.lane_keeping import LaneKeepingParams
    from lookahead_control.tools.compare import (LawSettings, NONLINEAR, PlantCase,
                                                 run_case)
    from lookahead_control.core.config import load_vehicle
    case = PlantCase('nonlinear_delay', NONLINEAR, 0.02)
    peaks = {}
    for share in (0.0, 1.0):
        settings = LawSettings(lane_keeping=LaneKeepingParams(side_force=share))
        row, = run_case(('cg_compensated', 'crosswind', [37.0], [case], load_vehicle(None),
                         0.005, None, settings))
        peaks[share] = row['peak_cg_error_m']
    assert peaks[0.0] > 0.2 and peaks[1.0] < 0.5 * peaks[0.0]
    assert math.isfinite(peaks[1.0])


@pytest.mark.process
def test_over_dds_a_crosswind_is_recorded_and_the_default_laws_side_force_answers_it(
        tmp_path):
    # real processes (sim_plant nonlinear plant, lockstep, the recorder): the crosswind
    # is in the bag's ground truth, and the default law's side force halves the CG's
    # excursion against the same law without it (offline, the goal plant: 25 -> 11 cm)
    import yaml

    from lookahead_control.bags.run_data import load_run
    from lookahead_control.core.config import read_yaml
    from lookahead_control.ros.closed_loop import LoopConfig, run_loop
    document = read_yaml(CROSSWIND)
    document['scenario']['duration'] = 7.0
    document['scenario']['external_forces'] = [{'start': 1.0, 'force': 1500.0}]
    scenario = tmp_path / 'gust.yaml'
    scenario.write_text(yaml.safe_dump(document))
    peaks = {}
    for share in (0.0, 1.0):
        bag = tmp_path / f'run_{share:g}'
        cfg = LoopConfig(scenario, speed=37.0, law='cg_compensated', plant='nonlinear',
                         bag=bag, timeout=600.0, extra_controller_args=[
                             '-p', f'lane_keeping.side_force:={share}'])
        assert run_loop(cfg) == 0
        truth = sorted(load_run(bag).truth.by_stamp().items())
        stamps = np.array([stamp for stamp, _ in truth])
        force = np.array([row['external_force'] for _, row in truth])
        assert np.array_equal(force, np.where(stamps >= 1_000_000_000, 1500.0, 0.0))
        assert stamps[-1] == 6_990_000_000
        peaks[share] = np.max(np.abs([row['y_cg'] for _, row in truth]))
    assert peaks[0.0] > 0.15 and peaks[1.0] < 0.6 * peaks[0.0]


def test_compare_runs_the_crosswind_when_named_and_says_so(tmp_path):
    from lookahead_control.tools import compare
    out = tmp_path / 'league'
    assert compare.main(['--scenarios', 'crosswind', 's0_straight', '--laws', 'stanley',
                         '--plants', 'linear', '--speeds', '37', '--duration', '3',
                         '--out', str(out), '--no-plots', '--no-progress',
                         '--workers', '1']) == 0
    text = (out / 'league.md').read_text()
    assert text.startswith('# League table: every law x crosswind, S0 x plants x speeds')
    assert '| law | crosswind | S0 |' in text
    assert 'crosswind' not in compare.SCENARIOS       # not in the default league
