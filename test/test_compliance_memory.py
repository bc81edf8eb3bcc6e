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


"""The compliance estimate's memory (``compliance_memory``): by hand and in closed loop."""

from dataclasses import replace

from lookahead_control.core.config import load_vehicle
from lookahead_control.core.control_law import LateralState
from lookahead_control.core.estimator import ComplianceEstimator
from lookahead_control.core.lane_keeping import CgCompensatedLaw, LaneKeepingParams
from lookahead_control.core.params import ControllerParams, VehicleParams
import numpy as np
import pytest
from sim_plant.closed_loop_sim import run
from sim_plant.scenario import scenario_from_dict
from sim_plant.vehicle_model import PlantParams

VEHICLE = VehicleParams()
DT = 0.01
PRIOR = 0.5


def estimator(memory_time, ratio=3.0):
    return ComplianceEstimator(VEHICLE, 0.5, 0.3, PRIOR, ratio, 0.0, memory_time)


def cornering(factor, v_x, a_y):
    """Steady cornering of a plant with the rear stiffness times factor: (v_y, r)."""
    r = a_y / v_x
    alpha_r = VEHICLE.mass * VEHICLE.l1 / (factor * VEHICLE.c_r * VEHICLE.wheelbase) * a_y
    return VEHICLE.l2 * r - v_x * alpha_r, r


def state(v_y, r, v_x=30.0):
    return LateralState(0.0, 0.0, v_y, r, v_x, 0.0, 0.0, 0.0)


def law_after_a_curve(settings=None, y_cg=0.0):
    """Return a law after 3 s of steady 3 m/s^2 cornering at 30 m/s, rear axle 30 % softer."""
    v_y, r = cornering(0.7, 30.0, 3.0)
    law = CgCompensatedLaw(VEHICLE, ControllerParams(), settings)
    turn = LateralState(y_cg, -v_y / 30.0, v_y, r, 30.0, 0.0, r / 30.0, 0.0)
    for k in range(300):
        law.step(turn, None, 0.0 if k == 0 else DT)
    return law, turn


def test_the_memory_and_the_estimate_by_hand_in_a_steady_curve():
    # constant signals from the first sample: the filters hold them, phi = v_x r and
    # the rear slip (l_2 r - v_y) / v_x exactly; each sample moves the memory by g =
    # dt / T_m phi^2 / (phi^2 + p^2), the fast statistics by dt / T
    v_y, r = cornering(0.7, 30.0, 3.0)
    est = estimator(10.0)
    n = 300
    for _ in range(n):
        est.update(state(v_y, r), DT, True)
    phi = 30.0 * r
    slip = (VEHICLE.l2 * r - v_y) / 30.0
    p2, eta = PRIOR * PRIOR, VEHICLE.eta
    share_m = 1.0 - (1.0 - DT / 10.0 * phi * phi / (phi * phi + p2)) ** n
    memory = (share_m * slip * phi + p2 * eta) / (share_m * phi * phi + p2)
    share = 1.0 - (1.0 - DT / 0.5) ** n
    estimate = (share * slip * phi + p2 * memory) / (share * phi * phi + p2)
    assert est.memory() == pytest.approx(memory, rel=1e-12)
    assert est.compliance() == pytest.approx(estimate, rel=1e-12)
    # 3 s of curve already taught the memory most of the softer axle's compliance
    assert 1.3 < memory / eta < 1 / 0.7
    # without a memory the same samples give the estimator of before: eta as the prior
    plain = estimator(0.0)
    for _ in range(n):
        plain.update(state(v_y, r), DT, True)
    assert plain.memory() == eta
    assert plain.compliance() == pytest.approx(
        (share * slip * phi + p2 * eta) / (share * phi * phi + p2), rel=1e-12)


def test_a_straight_keeps_the_memory_and_the_estimate_falls_back_to_it():
    v_y, r = cornering(0.7, 30.0, 3.0)
    kept, plain = estimator(10.0), estimator(0.0)
    for est in (kept, plain):
        for _ in range(300):
            est.update(state(v_y, r), DT, True)
        # 3 s of straight: the signal filters' tail (the step from the curve's signals
        # to 0 is no car's) moves the memory a little; after it nothing does
        for _ in range(300):
            est.update(state(0.0, 0.0), DT, True)
    learned = kept.memory()
    assert learned / VEHICLE.eta > 1.2
    for est in (kept, plain):
        for _ in range(6000):       # a minute of straight road
            est.update(state(0.0, 0.0), DT, True)
    assert kept.memory() == pytest.approx(learned, rel=1e-7)
    assert kept.compliance() == pytest.approx(learned, rel=1e-7)
    # without the memory the straight took the estimate back to the model's eta
    assert plain.compliance() == pytest.approx(VEHICLE.eta, rel=1e-9)


def test_the_memory_s_own_range_and_what_it_is_told_not_to_remember():
    # a rear axle 5 times softer than the model (a tyre past its grip): the fast
    # estimate goes to its range (3), the memory only to its own (1.75)
    v_y, r = cornering(0.2, 30.0, 3.0)
    est = ComplianceEstimator(VEHICLE, 0.5, 0.3, PRIOR, 3.0, 0.0, 10.0, 1.75)
    for _ in range(3000):
        est.update(state(v_y, r), DT, True)
    assert est.memory() == pytest.approx(1.75 * VEHICLE.eta, rel=1e-12)
    assert est.compliance() == pytest.approx(3.0 * VEHICLE.eta, rel=1e-12)
    # never wider than the estimate's range
    assert ComplianceEstimator(VEHICLE, 0.5, 0.3, PRIOR, 1.5, 0.0, 10.0, 1.75).memory_ratio \
        == 1.5
    # remember=False: the estimate learns, the memory does not
    told = estimator(10.0)
    for _ in range(300):
        told.update(state(v_y, r), DT, True, True, False)
    assert told.memory() == VEHICLE.eta and told.memory_energy == 0.0
    assert told.compliance() > 2.0 * VEHICLE.eta


def test_the_law_remembers_only_near_the_lane():
    # the same steady curve of a softer axle, the CG 5 cm / 20 cm off the lane: only the
    # first is remembered (MEMORY_BAND 0.1 m); the estimate learns both
    near, far = (law_after_a_curve(LaneKeepingParams(state_filter='none'), y_cg)[0].estimator
                 for y_cg in (0.05, 0.2))
    # the same fast statistics; the memory only near the lane
    assert near.moment == far.moment and near.energy == far.energy > 0.0
    assert near.memory() / VEHICLE.eta > 1.2 and far.memory() == VEHICLE.eta
    assert far.memory_energy == 0.0


def test_inactive_samples_teach_the_memory_nothing_and_the_range_clips_it():
    v_y, r = cornering(0.2, 30.0, 3.0)     # a rear axle 5 times softer than the model
    est = estimator(10.0, ratio=2.0)
    for _ in range(300):
        est.update(state(v_y, r), DT, False)
    assert est.memory() == VEHICLE.eta and est.memory_energy == 0.0
    for _ in range(3000):
        est.update(state(v_y, r), DT, True)
    assert est.memory() == pytest.approx(2.0 * VEHICLE.eta, rel=1e-12)
    assert est.compliance() == pytest.approx(2.0 * VEHICLE.eta, rel=1e-12)


def test_forget_reset_and_take_over_carry_the_memory():
    v_y, r = cornering(0.7, 30.0, 3.0)
    batch = estimator(10.0)
    for _ in range(300):
        batch.update(state(np.array([v_y, v_y]), np.array([r, r])), DT, True)
    learned = batch.memory()[0]
    assert batch.memory()[1] == learned > VEHICLE.eta
    # a bad input in run 1 restarts its memory too (back to eta), run 0 keeps it
    batch.forget(np.array([False, True]))
    assert batch.memory()[0] == learned
    assert batch.memory()[1] == VEHICLE.eta
    # a retune carries the memory as its scale over the design vehicle's eta
    heavier = replace(VEHICLE, mass=1.1 * VEHICLE.mass)
    one = estimator(10.0)
    for _ in range(300):
        one.update(state(v_y, r), DT, True)
    scale = one.memory() / VEHICLE.eta
    new = ComplianceEstimator(heavier, 0.5, 0.3, PRIOR, 3.0, 0.0, 10.0)
    new.take_over(one)
    assert new.memory() / heavier.eta == pytest.approx(scale, rel=1e-12)
    # ... unless the new one keeps none
    off = ComplianceEstimator(VEHICLE, 0.5, 0.3, PRIOR, 3.0, 0.0, 0.0)
    off.take_over(one)
    assert off.memory() == VEHICLE.eta and off.memory_energy == 0.0
    # a reset (time jump, stale inputs) forgets it
    one.reset()
    assert one.memory() == VEHICLE.eta == one.compliance()


def test_the_law_reports_and_restarts_its_memory():
    law, turn = law_after_a_curve()
    values = dict(law.debug_values())
    assert values['compliance_memory'] == pytest.approx(law.estimator.memory() / VEHICLE.eta)
    assert values['compliance_memory'] > 1.1
    # a NaN input restarts the law, the memory with it
    law.step(turn._replace(v_y=float('nan')), None, DT)
    assert dict(law.debug_values())['compliance_memory'] == 1.0
    for bad in (-1.0, 0.5, float('nan'), 1001.0):
        with pytest.raises(ValueError, match='compliance_memory'):
            LaneKeepingParams(compliance_memory=bad)
    # dev-probe41: 0.001 s was allowed, a memory that follows the noise
    with pytest.raises(ValueError, match=r'compliance_memory = 0.001 s would forget'):
        LaneKeepingParams(compliance_memory=0.001)
    with pytest.raises(ValueError, match='compliance_memory_range'):
        LaneKeepingParams(compliance_memory_range=0.5)


def test_a_retune_carries_the_memory_and_setting_it_to_0_drops_it():
    old, _ = law_after_a_curve()
    learned = old.estimator.memory()
    assert learned / VEHICLE.eta > 1.2
    longer = CgCompensatedLaw(VEHICLE, ControllerParams(),
                              LaneKeepingParams(compliance_memory=30.0))
    longer.reset()
    carried, _ = longer.take_over(old)
    assert 'compliance estimate' in carried
    assert longer.estimator.memory() == learned
    # a narrower range clips it from the next step on
    narrow = CgCompensatedLaw(VEHICLE, ControllerParams(),
                              LaneKeepingParams(compliance_memory_range=1.1))
    narrow.reset()
    narrow.take_over(old)
    assert narrow.estimator.memory() == pytest.approx(1.1 * VEHICLE.eta, rel=1e-12)
    off = CgCompensatedLaw(VEHICLE, ControllerParams(), LaneKeepingParams(compliance_memory=0.0))
    off.reset()
    off.take_over(old)
    assert off.estimator.memory() == VEHICLE.eta and off.estimator.memory_energy == 0.0
    # the estimate itself is carried either way (its fallback is then eta)
    assert off.estimator.moment == old.estimator.moment


# -- closed loop: a second curve after a straight, on tyres softer than the model -------

def two_curves(gap):
    """Two right curves of 3.4 m/s^2 (R 400 m at 37 m/s), clothoids in and out."""
    road = [{'type': 'straight', 'time': 2.0},
            {'type': 'clothoid', 'time': 1.5, 'lateral_acceleration_start': 0.0,
             'lateral_acceleration_end': -3.4},
            {'type': 'arc', 'time': 4.0, 'lateral_acceleration': -3.4},
            {'type': 'clothoid', 'time': 1.5, 'lateral_acceleration_start': -3.4,
             'lateral_acceleration_end': 0.0},
            {'type': 'straight', 'time': gap},
            {'type': 'clothoid', 'time': 1.5, 'lateral_acceleration_start': 0.0,
             'lateral_acceleration_end': -3.4},
            {'type': 'arc', 'time': 30.0, 'lateral_acceleration': -3.4}]
    return scenario_from_dict({'scenario': {
        'name': 'two_curves', 'duration': 9.0 + gap + 5.0, 'speed': {'initial': 37.0},
        'initial': {'lateral_error': 0.0, 'relative_yaw': 0.0}, 'road': road}}, 'two_curves')


def test_a_second_curve_on_softer_tyres_is_driven_on_what_the_first_taught():
    # the goal plant's Fiala tyres 30 % softer than the model (C_f, C_r x0.7), 20 ms
    # of delay, 37 m/s, 20 s of straight between the curves: without the memory the
    # estimate is back at eta when the second curve comes and the CG leaves the lane by
    # as much as in the first (14.0 cm measured); with it, 5.5 cm (the first curve: 15.0
    # -> 14.7 cm)
    vehicle = load_vehicle(None)
    soft = replace(vehicle, c_f=0.7 * vehicle.c_f, c_r=0.7 * vehicle.c_r)
    gap = 20.0
    scenario = two_curves(gap)
    second = 9.0 + gap
    peaks = {}
    for memory in (0.0, 10.0):
        law = CgCompensatedLaw(vehicle, ControllerParams(),
                               LaneKeepingParams(compliance_memory=memory))
        result = run(scenario, vehicle, law, PlantParams(model='nonlinear'), dt=0.005,
                     initial_speed=37.0, plant_vehicle=soft, delay=0.02,
                     preview_distance=100.0)
        t, y = np.asarray(result.time), np.abs(np.asarray(result['y_cg']))
        peaks[memory] = (np.max(y[t < second]), np.max(y[t >= second]))
    assert peaks[0.0][1] > 0.1 and peaks[10.0][1] < 0.07
    assert peaks[10.0][1] < 0.5 * peaks[0.0][1]
    # the first curve is not made worse
    assert peaks[10.0][0] < peaks[0.0][0] + 0.005


def test_a_slide_on_a_wet_road_does_not_spoil_the_next_curve():
    # dev-probe41: a first curve past the grip (4.8 m/s^2 on mu 0.5 at 30 m/s: the CG
    # a metre off), 20 s of straight, a gentle curve (2 m/s^2). The memory learned the
    # slide's compliance (2.9 x eta) and the gentle curve peaked 16.8 cm (2.7 cm without
    # a memory). With the memory's own range (1.75) and its band (learning only with the
    # CG within 0.1 m of the lane): 4.2 cm
    vehicle = load_vehicle(None)

    def curve(accel, arc):
        return [{'type': 'clothoid', 'time': 1.5, 'lateral_acceleration_start': 0.0,
                 'lateral_acceleration_end': accel},
                {'type': 'arc', 'time': arc, 'lateral_acceleration': accel}]
    road = ([{'type': 'straight', 'time': 2.0}] + curve(-4.8, 4.0)
            + [{'type': 'clothoid', 'time': 1.5, 'lateral_acceleration_start': -4.8,
                'lateral_acceleration_end': 0.0}, {'type': 'straight', 'time': 20.0}]
            + curve(-2.0, 30.0))
    scenario = scenario_from_dict({'scenario': {
        'name': 'wet', 'duration': 29.0 + 10.0, 'speed': {'initial': 30.0},
        'initial': {'lateral_error': 0.0, 'relative_yaw': 0.0}, 'road': road}}, 'wet')
    memory = []

    class Watched(CgCompensatedLaw):

        def step(self, state, preview, dt):
            memory.append(float(self.estimator.memory()) / vehicle.eta)
            return super().step(state, preview, dt)
    law = Watched(vehicle, ControllerParams())
    result = run(scenario, vehicle, law, PlantParams(model='nonlinear', friction=0.5),
                 dt=0.005, initial_speed=30.0, delay=0.02, preview_distance=100.0)
    t, y = np.asarray(result.time), np.abs(np.asarray(result['y_cg']))
    assert np.max(y[t < 29.0]) > 0.5         # the first curve was past the grip
    assert max(memory) <= 1.75
    assert np.max(y[t >= 29.0]) < 0.05
