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

"""The law interface (core/laws.py) and the offline runner driving any law."""

from lookahead_control.core.control_law import LateralState, LawOutput, steering_law
from lookahead_control.core.laws import (GainBatch, Law, output, PaperLaw, Preview,
                                         preview_from_points)
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
import numpy as np
from numpy.testing import assert_array_equal
import pytest
from sim_plant.closed_loop_sim import road_preview, run
from sim_plant.road import Road, Segment
from sim_plant.scenario import paper_scenario, Scenario
from sim_plant.sensors import noise_table, NoiseParams, NoiseStream
from sim_plant.speed_profile import SpeedProfile
from sim_plant.vehicle_model import PlantParams

VEHICLE = VehicleParams()


def _state(n=None):
    rng = np.random.default_rng(3)
    size = () if n is None else (n,)

    def draw(low, high):
        value = rng.uniform(low, high, size)
        return float(value) if n is None else value
    return LateralState(y_cg=draw(-1, 1), eps_r=draw(-0.05, 0.05), v_y=draw(-0.5, 0.5),
                        r=draw(-0.1, 0.1), v_x=draw(5, 40), a_x=draw(-3, 3),
                        rho=draw(-0.01, 0.01), rho_rate=draw(-1e-3, 1e-3))


@pytest.mark.parametrize('n', [None, 7])
def test_paper_law_is_bit_identical_to_steering_law(n):
    state = _state(n)
    for ctl in (ControllerParams(), ControllerParams(schedule='fixed', reference='arc_exact'),
                ControllerParams(schedule='exact', reference='arc_approx')):
        law = PaperLaw(VEHICLE, ctl)
        assert isinstance(law, Law)
        law.reset()
        got = law.step(state, Preview(np.zeros(0), np.zeros(0)), 0.0)
        want = steering_law(state, VEHICLE, ctl)
        for a, b in zip(got, want):
            assert_array_equal(a, b)


def test_gain_batch_gives_each_run_its_gains():
    state = _state(3)
    ctls = [ControllerParams(natural_frequency=w, damping_ratio=z)
            for w, z in ((1.0, 0.7), (3.0, 1.0), (5.0, 1.3))]
    got = PaperLaw.batch(VEHICLE, ctls).step(state, Preview(np.zeros(0), np.zeros(0)), 0.0)
    for i, ctl in enumerate(ctls):
        one = LateralState(*(float(v[i]) for v in state))
        want = steering_law(one, VEHICLE, ctl)
        assert got.steering[i] == pytest.approx(want.steering, rel=1e-14, abs=1e-15)
    with pytest.raises(ParameterError, match='schedule differs'):
        GainBatch([ControllerParams(), ControllerParams(schedule='fixed')])


def test_output_fills_zeros_of_the_batch_shape():
    out = output(np.array([0.1, -0.2]), d_v=np.array([3.0, 4.0]))
    assert isinstance(out, LawOutput)
    assert_array_equal(out.d_v, [3.0, 4.0])
    assert_array_equal(out.beta_1, [0.0, 0.0])
    assert output(0.05).error == 0.0
    with pytest.raises(TypeError, match='not LawOutput fields'):
        output(0.0, gain=1.0)


def test_preview_interpolates_and_holds_the_ends():
    p = preview_from_points([(10.0, 0.01), (0.0, 0.0), (5.0, 0.0), (5.0, 9.0)])
    # sorted; of the points at 5.0 the sharpest is kept (as the node keeps it, so the
    # safety check bounds every point it uses: docs/safety.md)
    assert_array_equal(p.distances, [0.0, 5.0, 10.0])
    assert p.at(7.5) == pytest.approx(4.505)
    assert p.at(-3.0) == 0.0 and p.at(50.0) == 0.01
    batch = Preview(np.array([0.0, 10.0]), np.array([[0.0, 0.01], [0.01, 0.03]]))
    np.testing.assert_allclose(batch.at(np.array([5.0, 5.0])), [0.005, 0.02], rtol=1e-15)
    assert_array_equal(batch.at(20.0), [0.01, 0.03])
    assert Preview(np.zeros(0), np.zeros(0)).at(3.0) == 0.0
    with pytest.raises(ParameterError, match='not finite'):
        preview_from_points([(0.0, float('nan'))])


def test_road_preview_is_the_road_ahead():
    scenario = paper_scenario(20.0)       # straight 40 m, then rho = -1/400
    distances = np.array([0.0, 5.0, 10.0])
    assert_array_equal(road_preview(scenario, 33.0, distances).curvatures,
                       [0.0, 0.0, -0.0025])
    batch = road_preview(scenario, np.array([0.0, 38.0]), distances)
    assert batch.curvatures.shape == (3, 2)
    assert_array_equal(batch.curvatures[:, 1], [0.0, -0.0025, -0.0025])


class _Recorder:
    """A stateful law: steers on the preview's curvature 20 m ahead; logs its calls."""

    def __init__(self):
        self.calls, self.resets, self.total = [], 0, None

    def reset(self):
        self.resets += 1
        self.total = None

    def step(self, state, preview, dt):
        self.total = dt if self.total is None else self.total + dt
        self.calls.append((dt, float(preview.at(20.0))))
        return output(2.68 * preview.at(20.0) - 0.1 * state.y_cg, d_v=20.0)


def test_runner_drives_any_law_with_preview_and_dt():
    law = _Recorder()
    result = run(paper_scenario(20.0, 3.0), VEHICLE, law)
    assert law.resets == 1 and len(law.calls) == 301
    assert law.calls[0][0] == 0.0 and all(c[0] == pytest.approx(0.01) for c in law.calls[1:])
    # the curve starts 40 m ahead: seen 20 m ahead at t = 1 s, one step after 0.99 s
    seen = [i for i, c in enumerate(law.calls) if c[1] != 0.0]
    assert seen[0] in (100, 101)
    assert result.law is law and result.controller is None
    assert np.all(result['d_v'] == 20.0) and np.all(result['y_ref'] == 0.0)


def test_transport_delay_shifts_the_wheel_angle():
    scenario = paper_scenario(25.0, 4.0)
    plain = run(scenario, VEHICLE, ControllerParams())
    late = run(scenario, VEHICLE, ControllerParams(), delay=0.02)
    # the wheel holds 0, then the command of two control steps before
    assert_array_equal(late['steering'][:2], [0.0, 0.0])
    assert_array_equal(late['steering'][2:], late['steering_cmd'][:-2])
    assert np.max(np.abs(late['y_cg'] - plain['y_cg'])) > 1e-3
    # a delay between control steps applies the command mid-period
    odd = run(scenario, VEHICLE, ControllerParams(), delay=0.013)
    assert not np.array_equal(odd['y_cg'], late['y_cg'])
    with pytest.raises(ParameterError, match='whole multiple'):
        run(scenario, VEHICLE, ControllerParams(), delay=0.0105)
    with pytest.raises(ParameterError, match='out of range'):
        run(scenario, VEHICLE, ControllerParams(), delay=-0.01)


def test_noise_repeats_with_its_seed_and_differs_between_seeds():
    scenario = paper_scenario(25.0, 3.0)
    noise = NoiseParams()
    a = run(scenario, VEHICLE, ControllerParams(), noise=noise, seed=4)
    b = run(scenario, VEHICLE, ControllerParams(), noise=noise, seed=4)
    c = run(scenario, VEHICLE, ControllerParams(), noise=noise, seed=5)
    for name in a.channels:
        assert_array_equal(a[name], b[name])
    assert not np.array_equal(a['steering_cmd'], c['steering_cmd'])
    # the node's one-step-at-a-time stream draws the same numbers
    stream = NoiseStream(noise, 4)
    table = noise_table(noise, 4, 50)
    assert_array_equal(np.array([stream.draw() for _ in range(50)]), table)
    with pytest.raises(ParameterError, match='seed'):
        noise_table(noise, -1, 5)


def test_batch_of_everything_equals_single_runs():
    road = Road([Segment('straight', 30.0), Segment('clothoid', 40.0, 0.0, -0.004),
                 Segment('arc', 2000.0, -0.004, -0.004)])
    scenario = Scenario('mix', 3.0, road, SpeedProfile(20.0, 1.0, 0.5, 1.0))
    speeds = np.array([15.0, 20.0, 28.0])
    delays = np.array([0.0, 0.02, 0.013])
    seeds = [1, 2, 3]
    bodies = [VehicleParams(mass=m, c_f=c) for m, c in ((1300.0, 7e4), (1485.0, 8e4),
                                                        (1700.0, 9e4))]
    plants = [PlantParams(model='nonlinear', friction=mu) for mu in (0.5, 0.8, 1.0)]
    ctls = [ControllerParams(natural_frequency=w) for w in (2.0, 3.0, 4.0)]
    noise = NoiseParams()

    def disturbance(t):
        return (300.0 if 1.0 <= t < 1.5 else 0.0), 0.0
    batch = run(scenario, VEHICLE, PaperLaw.batch(VEHICLE, ctls), plants,
                initial_speed=speeds, plant_vehicle=bodies, delay=delays, noise=noise,
                seed=seeds, disturbance=disturbance)
    for i in range(3):
        one = run(scenario, VEHICLE, ctls[i], plants[i], initial_speed=float(speeds[i]),
                  plant_vehicle=bodies[i], delay=float(delays[i]), noise=noise,
                  seed=seeds[i], disturbance=disturbance)
        for name in ('y_cg', 'eps_r', 'steering', 'steering_cmd', 'd_v'):
            np.testing.assert_allclose(batch[name][:, i], one[name], rtol=1e-10,
                                       atol=1e-13)


def test_disturbance_force_and_moment_act_on_the_body():
    scenario = Scenario('straight', 1.0, Road([Segment('straight', 500.0)]),
                        SpeedProfile(20.0))
    law = _Recorder()        # steers only on the preview and on y_cg (0.1 rad/m)
    force = run(scenario, VEHICLE, law, disturbance=lambda t: (1000.0, 0.0))
    moment = run(scenario, VEHICLE, law, disturbance=lambda t: (0.0, 1000.0))
    # a left force first accelerates the body left: v_y' = F / m at t = 0
    assert force['v_y'][1] == pytest.approx(1000.0 / VEHICLE.mass * 0.01, rel=0.05)
    # a left (CCW) moment first yaws it left: r' = M / I_z
    assert moment['r'][1] == pytest.approx(1000.0 / VEHICLE.yaw_inertia * 0.01, rel=0.05)
    with pytest.raises(ParameterError, match='no disturbance'):
        run(scenario, VEHICLE, law, PlantParams(model='commonroad_st'),
            disturbance=lambda t: (1.0, 0.0))
