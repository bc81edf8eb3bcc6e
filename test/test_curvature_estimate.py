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
The road curvature estimated while no ``road_curvature`` is received (dev-rho).

Reference values: the augmented gain from scipy's DARE on an independently written
model; the estimate of a noise-free steady turn against ``r / v_x``; closed-loop
figures on the nonlinear plant with 20 ms and the default noise that fail on the code
before (which took the curvature as 0: S2 at 37 m/s 2.92 m); bit-identity with a
curvature received (sums of the old code's run).
"""

from dataclasses import replace
import math

from lookahead_control.core.control_law import LateralState
from lookahead_control.core.lane_keeping import CgCompensatedLaw, LaneKeepingParams
from lookahead_control.core.params import ControllerParams, VehicleParams
from lookahead_control.core.state_filter import (KalmanStateFilter, kinematic_gain,
                                                 StateFilterParams)
import numpy as np
import pytest
import scipy.linalg
from test_state_filter import van_loan

VEHICLE = VehicleParams()


def kinematic_reference_gain(settings, v_x, period):
    """Return the curvature estimator's gain: scipy expm, Van Loan and DARE."""
    a = np.array([[0.0, -v_x], [0.0, 0.0]])
    # eps_r: kinematic noise / 10 m and the yaw rate's noise integrated over the step
    # (variance (h sigma_r)^2 a step, as a density sigma_r^2 h); rho: drift / v_x^2
    qc = np.diag([(settings.kinematic_noise / 10.0) ** 2
                  + settings.yaw_rate_noise ** 2 * period,
                  (settings.curvature_drift / v_x ** 2) ** 2])
    phi, q = van_loan(a, qc, period)
    assert np.allclose(phi, [[1.0, -v_x * period], [0.0, 1.0]], rtol=0, atol=1e-15)
    h = np.array([[1.0, 0.0]])
    r = np.array([[settings.yaw_noise ** 2]])
    p = scipy.linalg.solve_discrete_are(phi.T, h.T, q, r)
    return p @ h.T / (h @ p @ h.T + r)[0, 0]


@pytest.mark.parametrize('period', [0.01, 0.02])
@pytest.mark.parametrize('v_x', [3.0, 20.0, 37.0, 80.0])
def test_the_curvature_estimator_gain_equals_scipy_dare(v_x, period):
    settings = StateFilterParams()
    expected = kinematic_reference_gain(settings, v_x, period)
    gain = kinematic_gain(settings, v_x, period)
    assert gain.shape == (2, 1)
    assert np.all(np.abs(gain - expected) <= 1e-8 * np.abs(expected))
    # the estimator corrects the curvature against the innovation of eps_r: a relative
    # yaw above the prediction (turning less than r / v_x says) lowers rho
    assert gain[1, 0] < 0.0 < gain[0, 0] < 1.0


def _turn(v_x, rho):
    """Return the steady (v_y, r, eps_r) of the linear model with the CG on an arc."""
    r = v_x * rho
    alpha_r = VEHICLE.mass * VEHICLE.l1 / (VEHICLE.c_r * VEHICLE.wheelbase) * v_x * r
    v_y = VEHICLE.l2 * r - v_x * alpha_r
    return v_y, r, -v_y / v_x


def _steady_steering(v_x, rho):
    """Return the wheel angle of the linear model's steady turn (by hand)."""
    v_y, r, _ = _turn(v_x, rho)
    alpha_f = VEHICLE.mass * VEHICLE.l2 / (VEHICLE.c_f * VEHICLE.wheelbase) * v_x * r
    return alpha_f + (v_y + VEHICLE.l1 * r) / v_x


@pytest.mark.parametrize('v_x, rho', [(37.0, -1 / 400.0), (15.0, 1 / 60.0)])
def test_the_estimate_of_a_noise_free_steady_turn_is_r_over_v(v_x, rho):
    # steady on an arc the relative yaw is constant: eps_r' = r - v_x rho = 0. The
    # filter is told nothing of rho (it gets 0) and starts from a wrong restart value
    v_y, r, eps_r = _turn(v_x, rho)
    delta = _steady_steering(v_x, rho)
    f = KalmanStateFilter(VEHICLE)
    state = LateralState(0.0, eps_r, v_y, r, v_x, 0.0, 0.0, 0.0)
    for k in range(600):
        f.command(delta)
        out = f.step(state._replace(r=r * (1.3 if k == 0 else 1.0)), 0.01, True)
    assert out.rho == pytest.approx(rho, rel=2e-3)
    assert f.curvature() == out.rho and out.rho_rate == 0.0
    # received again: the curvature received is used and modelled
    out = f.step(state._replace(rho=rho), 0.01, False)
    assert out.rho == rho and f.curvature() == rho


def _run(name, speed, settings=None, lost=None, seed=0, flap=None):
    """Run the default law on the nonlinear plant, 20 ms, default noise, no curvature."""
    from lookahead_control.tools.compare import load_scenarios
    from sim_plant.closed_loop_sim import run
    from sim_plant.sensors import NoiseParams
    from sim_plant.vehicle_model import PlantParams

    class NoCurvature:

        def __init__(self):
            self.law = CgCompensatedLaw(VEHICLE, ControllerParams(),
                                        settings or LaneKeepingParams())
            self.t = 0.0

        def reset(self):
            self.law.reset()
            self.t = 0.0

        def step(self, state, preview, dt):
            self.t += dt
            off = lost is None or lost[0] <= self.t < lost[1]
            if flap is not None:
                off = int(self.t / flap) % 2 == 1
            self.law.note_curvature(not off)
            if off:
                return self.law.step(state._replace(rho=0.0 * state.rho,
                                                    rho_rate=0.0 * state.rho_rate), None, dt)
            return self.law.step(state, preview, dt)

    scenario = load_scenarios([name])[name]
    return run(scenario, VEHICLE, NoCurvature(), PlantParams(model='nonlinear'),
               initial_speed=speed, dt=0.001, delay=0.02, preview_distance=100.0,
               noise=NoiseParams(), seed=seed)


def test_without_curvature_the_default_law_holds_a_highway_curve():
    # old code: curvature 0, S2 at 37 m/s 2.92 m outside (1.7 m with state_filter none);
    # now 38.4 cm peak, 6.7 cm over the last 2 s (the 7-state estimate before
    # dev-kinrho: 38.7 / 7.9; with the curvature: 2.7 / 1.3 cm)
    result = _run('s2_curve_entry', 37.0)
    y = np.abs(result['y_cg'])
    assert np.max(y) < 0.5
    assert np.max(y[result.time > result.time[-1] - 2.0]) < 0.12
    # S3 (an S-bend at 4 m/s^2) at 20 m/s: old 2.03 m peak, now 39 cm (7-state: 37)
    assert np.max(np.abs(_run('s3_s_bend', 20.0)['y_cg'])) < 0.6


def test_a_curvature_lost_mid_curve_starts_the_estimate_from_the_last_one():
    # S1 at 37 m/s, the curvature lost for 1 s in the curve (5-6 s): old code 1.56 m peak
    result = _run('s1_paper_step', 37.0, lost=(5.0, 6.0))
    received = _run('s1_paper_step', 37.0, lost=(100.0, 101.0))
    late = result.time > 4.0
    assert np.max(np.abs(result['y_cg'][late])) < 0.15
    assert np.max(np.abs(received['y_cg'][late])) < 0.06


def test_a_curvature_flapping_on_and_off_does_not_jump_the_command():
    # on and off every 0.3 s on S2 at 37 m/s: the switch-over blends (0.5 s), the
    # command moves no faster than with the curvature always off
    flapping = _run('s2_curve_entry', 37.0, flap=0.3)
    off = _run('s2_curve_entry', 37.0)
    steps = np.max(np.abs(np.diff(flapping['steering_cmd'])))
    assert steps < 1.5 * np.max(np.abs(np.diff(off['steering_cmd'])))
    assert np.max(np.abs(flapping['y_cg'])) < 0.5
    law = CgCompensatedLaw(VEHICLE, ControllerParams(),
                           LaneKeepingParams(curvature_blend=0.0))
    v_y, r, eps_r = _turn(37.0, -1 / 400.0)
    state = LateralState(0.0, eps_r, v_y, r, 37.0, 0.0, -1 / 400.0, 0.0)
    blended = CgCompensatedLaw(VEHICLE, ControllerParams(), LaneKeepingParams())
    jumps = []
    for which in (law, blended):
        out = []
        for k in range(200):
            which.note_curvature(k < 100)
            out.append(float(which.step(state if k < 100 else state._replace(rho=0.0),
                                        None, 0.01).steering))
        jumps.append(abs(out[100] - out[99]))
    assert jumps[1] < 0.2 * jumps[0]


def test_with_curvature_received_the_runs_are_those_of_the_old_code():
    # the sums of the old code's (main 3cdb363) commands, S2 and S0 at 37 m/s with the
    # curvature received, bit for bit; S2 without the state preview (0 is the law before
    # it), S0 with the defaults (a straight: the preview adds nothing); both without the
    # compliance memory (0 is the estimator before it, dev-memory)
    from lookahead_control.tools.compare import load_scenarios
    from sim_plant.closed_loop_sim import run
    from sim_plant.sensors import NoiseParams
    from sim_plant.vehicle_model import PlantParams

    class Told:

        def __init__(self, settings):
            self.law = CgCompensatedLaw(VEHICLE, ControllerParams(), settings)

        def reset(self):
            self.law.reset()

        def step(self, state, preview, dt):
            self.law.note_curvature(True)
            return self.law.step(state, preview, dt)

    for name, total, settings in (
            # (dev-sc34: the integral sums the measured y_cg; before, -18.67866522659203
            # and -0.1944498962871857)
            # (side_force 0: the law before dev-sc36)
            ('s2_curve_entry', -18.678799055886273,
             LaneKeepingParams(state_preview=0.0, compliance_memory=0.0,
                               curvature_smoothing=0.0, side_force=0.0)),
            ('s0_straight', -0.19385351996716746,
             LaneKeepingParams(compliance_memory=0.0, curvature_smoothing=0.0,
                               side_force=0.0))):
        scenario = load_scenarios([name])[name]
        result = run(scenario, VEHICLE, Told(settings), PlantParams(model='nonlinear'),
                     initial_speed=37.0, dt=0.001, delay=0.02, preview_distance=100.0,
                     noise=NoiseParams(), seed=0)
        # the same commands to the last bits a CPU's math kernels decide: numpy picks
        # SIMD (SVML) kernels on AVX-512 machines whose tan / atan2 / cube root differ
        # from the C library's in the last bit; any change of the law moves this sum by
        # far more (a 1 % gain change: about 1e-3 of it)
        assert float(np.sum(result['steering'])) == pytest.approx(total, rel=1e-12, abs=0.0)


def test_a_batch_with_and_without_curvature_equals_its_single_runs():
    rho = -1 / 400.0
    v_y, r, eps_r = _turn(37.0, rho)
    rng = np.random.default_rng(3)
    batch = CgCompensatedLaw(VEHICLE, ControllerParams(), LaneKeepingParams())
    singles = [CgCompensatedLaw(VEHICLE, ControllerParams(), LaneKeepingParams())
               for _ in range(3)]
    for k in range(300):
        received = np.array([True, k < 150, k % 60 < 30])
        noise = rng.normal(0.0, 0.002, (4, 3))
        y = noise[0] * 10
        if k == 200:
            y[1] = math.nan             # a NaN in one run, while estimating
        states = LateralState(y, eps_r + noise[1], v_y + noise[2] * 10, r + noise[3],
                              np.full(3, 37.0), np.zeros(3),
                              np.where(received, rho, 0.0), np.zeros(3))
        batch.note_curvature(received)
        both = batch.step(states, None, 0.01)
        for i, single in enumerate(singles):
            single.note_curvature(bool(received[i]))
            one = single.step(LateralState(*(float(np.asarray(v)[i]) for v in states)),
                              None, 0.01)
            assert (both.steering[i] == one.steering
                    or (math.isnan(both.steering[i]) and math.isnan(one.steering)))
    assert batch.state_filter.curvature_estimated_steps == sum(
        s.state_filter.curvature_estimated_steps for s in singles)


def test_bad_inputs_while_estimating_give_no_nan_after_them():
    # NaN, a speed dropout below the filter's floor, a time jump, a frozen stamp (dt 0)
    law = CgCompensatedLaw(VEHICLE, ControllerParams(), LaneKeepingParams())
    v_y, r, eps_r = _turn(37.0, -1 / 400.0)
    state = LateralState(0.0, eps_r, v_y, r, 37.0, 0.0, 0.0, 0.0)
    law.note_curvature(False)
    events = {100: state._replace(eps_r=math.nan), 150: state._replace(v_x=0.0),
              151: state._replace(v_x=1.0), 200: state._replace(r=math.inf)}
    out = []
    for k in range(400):
        dt = {250: 0.0, 251: 0.0, 300: 5.0, 320: -0.1}.get(k, 0.01)
        out.append(float(law.step(events.get(k, state), None, dt).steering))
    assert math.isnan(out[100]) and math.isnan(out[200])
    good = [v for k, v in enumerate(out) if k not in (100, 200)]
    assert all(math.isfinite(v) for v in good)
    assert law.state_filter.curvature() == pytest.approx(-1 / 400.0, rel=0.05)
    assert abs(out[-1] - out[99]) < 2e-3


@pytest.mark.parametrize('v_x', [10.0, 37.0])
def test_the_curvature_gain_steers_the_steady_turn_by_hand(v_x):
    # K x_ss + k_rho rho is the linear model's steady wheel angle (worked out by hand)
    from lookahead_control.core.lane_keeping_stability import curvature_gain, feedback_gain
    settings = LaneKeepingParams()
    rho = -1 / 400.0
    v_y, r, eps_r = _turn(v_x, rho)
    k = feedback_gain(VEHICLE, ControllerParams(), settings, v_x)
    k_rho = curvature_gain(VEHICLE, ControllerParams(), settings, v_x)
    steady = k @ np.array([0.0, eps_r, v_y, r, 0.0]) + k_rho * rho
    assert steady == pytest.approx(_steady_steering(v_x, rho), rel=1e-9)


@pytest.mark.parametrize('v_y_measured', [True, False])
def test_the_curvature_estimating_loop_passes_the_filtered_robust_check(v_y_measured):
    # the 486 cases (speed 10-37 m/s, C_f, C_r x0.7-1.3, mass x0.8-1.2, delay 0-50 ms):
    # the largest radius is the integral's, as with the curvature received (0.99683 at
    # 10 m/s with the default k_i 0.3; 0.99950 with the schedule's 0.05 there); with the
    # integral held, the rest of the loop (the estimator's own modes)
    from lookahead_control.core.lane_keeping_stability import filtered_loop, robust_check
    settings = LaneKeepingParams()
    result = robust_check(VEHICLE, ControllerParams(), settings, filtered=True,
                          v_y_measured=v_y_measured, curvature_estimated=True)
    assert result.cases == 486 and result.holds
    assert result.max_radius == pytest.approx(0.99683, abs=5e-6)
    held = robust_check(VEHICLE, ControllerParams(), settings, filtered=True,
                        v_y_measured=v_y_measured, curvature_estimated=True,
                        integral_frozen=True)
    assert held.cases == 486 and held.holds
    # the loop is the one with the curvature estimator: three states more (eps_r, rho
    # and the law's rate of the estimate; two with estimate_rate_time 0)
    plain = filtered_loop(VEHICLE, ControllerParams(), settings, 37.0)
    augmented = filtered_loop(VEHICLE, ControllerParams(), settings, 37.0,
                              curvature_estimated=True)
    assert augmented.shape[0] == plain.shape[0] + 3
    unrated = filtered_loop(VEHICLE, ControllerParams(),
                            replace(settings, estimate_rate_time=0.0), 37.0,
                            curvature_estimated=True)
    assert unrated.shape[0] == plain.shape[0] + 2


def test_the_node_estimates_a_curvature_never_received_or_lost_and_says_so(context):
    from diagnostic_msgs.msg import DiagnosticStatus
    from lookahead_control.ros import conversions as conv
    from rclpy.time import Time
    from test_safety_probe import _controller
    ms = 1_000_000
    rho, v_x = -1 / 400.0, 37.0
    v_y, r, eps_r = _turn(v_x, rho)
    node = _controller(context)

    def one_second(stamp, curvature):
        for _ in range(100):
            stamp += 10 * ms
            node.get_clock().set_ros_time_override(Time(nanoseconds=stamp))
            node.on_yaw(conv.to_yaw(stamp, 'base_link', eps_r, r, 0.0))
            node.on_velocity(conv.to_velocity(stamp, 'base_link', v_x, v_y, 0.0))
            if curvature:
                node.on_curvature(conv.to_curvature(stamp, 'base_link',
                                                    [(0.0, rho), (5.0, rho)]))
            node.on_lateral_error(conv.to_lateral_error(stamp, 'base_link', VEHICLE.d_s,
                                                        VEHICLE.d_s * eps_r))
        return stamp, node.diagnostics()

    try:
        stamp, status = one_second(100_000 * ms, False)
        law = node.core.law
        assert law.curvature_estimated()
        assert law.state_filter.curvature() == pytest.approx(rho, rel=0.02)
        assert node.core.last.steering == pytest.approx(_steady_steering(v_x, rho), rel=0.05)
        assert status.level == DiagnosticStatus.WARN
        assert 'turning without road_curvature' in status.message
        assert 'the curvature is estimated' in status.message
        stamp, status = one_second(stamp, True)
        assert not law.curvature_estimated()
        assert status.level == DiagnosticStatus.OK, status.message
        stamp, status = one_second(stamp, False)       # lost: stale after input_timeout
        node._judge_inputs(stamp)
        status = node.diagnostics()
        assert law.curvature_estimated()
        assert 'road_curvature lost: the curvature is estimated' in status.message
        assert law.state_filter.curvature() == pytest.approx(rho, rel=0.02)
    finally:
        node.destroy_node()


def test_a_speed_read_as_zero_holds_the_last_estimate():
    # below the filter's floor the estimate is the last one above it, not r / v_x at
    # the floor speed (a wheel-speed dropout at 37 m/s: r / 3 m/s is 12 times the curve)
    rho, v_x = -1 / 400.0, 37.0
    v_y, r, eps_r = _turn(v_x, rho)
    f = KalmanStateFilter(VEHICLE)
    state = LateralState(0.0, eps_r, v_y, r, v_x, 0.0, 0.0, 0.0)
    for _ in range(300):
        f.command(_steady_steering(v_x, rho))
        f.step(state, 0.01, True)
    out = f.step(state._replace(v_x=0.0), 0.01, True)
    assert out.rho == pytest.approx(rho, rel=0.02)
    # crawling straight after the curve (r = 0): the path's 0, not the old curve
    assert f.step(state._replace(v_x=2.0, r=0.0), 0.01, True).rho == 0.0
    # a tighter turn at crawling speed: no more than the last estimate
    assert f.step(state._replace(v_x=2.0, r=-0.2), 0.01, True).rho == pytest.approx(
        rho, rel=0.02)
    # never above the floor: the path the car drives at the floor speed, bounded
    fresh = KalmanStateFilter(VEHICLE)
    out = fresh.step(state._replace(v_x=0.0, r=5.0), 0.01, True)
    assert out.rho == 0.2


def test_without_the_state_filter_the_curvature_is_estimated_too():
    # state_filter none: old code 1.73 m on S2 at 37 m/s without curvature; a filter now
    # runs for the curvature alone (the law keeps the measurements of the rest): 31.6 cm
    settings = LaneKeepingParams(state_filter='none')
    result = _run('s2_curve_entry', 37.0, settings)
    assert np.max(np.abs(result['y_cg'])) < 0.5
    assert result.law.law.state_filter is None
    assert result.law.law.curvature_filter is not None


def test_a_batch_with_a_preview_estimates_only_where_no_curvature_is_received():
    from lookahead_control.core.laws import Preview
    rho = -1 / 400.0
    v_y, r, eps_r = _turn(30.0, rho)
    distances = np.array([0.0, 10.0, 50.0])
    ahead = np.array([rho, 1.5 * rho, 2.0 * rho])
    batch = CgCompensatedLaw(VEHICLE, ControllerParams(), LaneKeepingParams())
    singles = [CgCompensatedLaw(VEHICLE, ControllerParams(), LaneKeepingParams())
               for _ in range(2)]
    for k in range(200):
        received = np.array([True, k < 80 or k >= 140])
        states = LateralState(np.full(2, 0.01), np.full(2, eps_r), np.full(2, v_y),
                              np.full(2, r), np.full(2, 30.0), np.zeros(2),
                              np.where(received, rho, 0.0), np.zeros(2))
        batch.note_curvature(received)
        both = batch.step(states, Preview(distances, np.stack([ahead, ahead], axis=1)), 0.01)
        for i, single in enumerate(singles):
            single.note_curvature(bool(received[i]))
            one = single.step(LateralState(*(float(v[i]) for v in states)),
                              Preview(distances, ahead), 0.01)
            assert both.steering[i] == one.steering


@pytest.mark.process
def test_over_dds_a_controller_that_gets_no_curvature_estimates_it(tmp_path):
    # real processes (sim_plant nonlinear, lockstep, the controller's road_curvature
    # remapped to a topic nobody publishes): old code 2.92 m on S2 at 37 m/s, now 35 cm
    # (2.4 cm with the curvature)
    from pathlib import Path

    from lookahead_control.bags.run_data import load_run
    from lookahead_control.ros.closed_loop import LoopConfig, run_loop
    scenario = Path(__file__).resolve().parent.parent / 'config' / 'scenarios' / (
        's2_curve_entry.yaml')
    bag = tmp_path / 'run'
    cfg = LoopConfig(scenario, speed=37.0, law='cg_compensated', plant='nonlinear', bag=bag,
                     extra_controller_args=['-r', 'road_curvature:=/nobody_publishes_this'],
                     # the recorder is the curvature's only subscriber
                     extra_sim_args=['-p', 'subscribers:=1'], timeout=600.0)
    assert run_loop(cfg) == 0
    run = load_run(bag)
    truth = sorted(run.truth.by_stamp().items())
    # with subscribers:=1 sim_plant waits for no ground-truth subscriber: the recorder
    # may join the truth topic a few steps late (1187 of 1200 once, under load); what
    # counts is every step from before the curve (at 2 s) to the end, with no gap
    stamps = np.array([stamp for stamp, _ in truth])
    assert stamps[0] < 1_000_000_000 and stamps[-1] == 11_990_000_000
    assert np.all(np.diff(stamps) == 10_000_000)
    y_cg = np.array([t['y_cg'] for _, t in truth])
    assert np.max(np.abs(y_cg)) < 0.5


@pytest.mark.parametrize('v_x, rho', [(37.0, -1 / 400.0), (37.0, 0.0), (20.0, 1 / 150.0)])
def test_a_relative_yaw_bias_is_not_taken_for_a_curve(v_x, rho):
    # a camera whose heading is 0.01 rad off: eps_r' = r - v_x rho cannot see a constant
    # bias, the estimate is r / v_x. Old code (the curvature a state of the full filter,
    # coupled to the lateral error): 37 m/s straight -4.68e-4 1/m (R 2.1 km)
    v_y, r, eps_r = _turn(v_x, rho)
    delta = _steady_steering(v_x, rho)
    f = KalmanStateFilter(VEHICLE)
    state = LateralState(0.0, eps_r + 0.01, v_y, r, v_x, 0.0, 0.0, 0.0)
    for _ in range(1000):
        f.command(delta)
        out = f.step(state, 0.01, True)
    assert abs(out.rho - rho) < 1e-6


def test_with_a_biased_relative_yaw_the_cg_stays_near_the_lane_without_curvature():
    # S0 at 37 m/s, the relative yaw measured 0.01 rad off (the goal plant, noise): old
    # code -46 cm over the last 2 s (-90 cm before integral_band_time); now -13.1 cm,
    # as with the curvature received (-11 cm)
    from lookahead_control.tools.compare import load_scenarios
    from sim_plant.closed_loop_sim import run
    from sim_plant.sensors import NoiseParams
    from sim_plant.vehicle_model import PlantParams

    class Biased:

        def __init__(self):
            self.law = CgCompensatedLaw(VEHICLE, ControllerParams(), LaneKeepingParams())

        def reset(self):
            self.law.reset()

        def step(self, state, preview, dt):
            self.law.note_curvature(False)
            return self.law.step(state._replace(eps_r=state.eps_r + 0.01, rho=0.0 * state.rho,
                                                rho_rate=0.0 * state.rho_rate), None, dt)

    scenario = load_scenarios(['s0_straight'])['s0_straight']
    result = run(scenario, VEHICLE, Biased(), PlantParams(model='nonlinear'),
                 initial_speed=37.0, dt=0.001, delay=0.02, preview_distance=100.0,
                 noise=NoiseParams(), seed=0)
    last = result.time > result.time[-1] - 2.0
    assert abs(np.mean(result['y_cg'][last])) < 0.2
    assert np.max(np.abs(result['y_cg'])) < 0.4


def test_the_estimator_follows_the_received_curvature_and_restarts_on_bad_input():
    # received for 1 s, then lost: the first estimate is the last curvature received;
    # a NaN yaw rate restarts it (the filter passes the step through) and it starts
    # again from r / v_x; dt = 0 advances nothing
    rho, v_x = -1 / 400.0, 37.0
    v_y, r, eps_r = _turn(v_x, rho)
    f = KalmanStateFilter(VEHICLE)
    state = LateralState(0.0, eps_r, v_y, r, v_x, 0.0, rho, 0.0)
    for _ in range(100):
        f.command(_steady_steering(v_x, rho))
        f.step(state, 0.01, False)
    assert f.kinematic[1] == rho
    out = f.step(state._replace(rho=0.0), 0.01, True)
    assert out.rho == pytest.approx(rho, rel=1e-3)
    assert f.step(state._replace(rho=0.0), 0.0, True).rho == out.rho
    bad = f.step(state._replace(r=math.nan, rho=0.0), 0.01, True)
    assert math.isnan(bad.r) and math.isnan(f.kinematic[1])
    again = f.step(state._replace(r=2.0 * r, rho=0.0), 0.01, True)
    assert again.rho == pytest.approx(2.0 * r / v_x, rel=1e-12)
    for _ in range(300):
        again = f.step(state._replace(rho=0.0), 0.01, True)
    assert again.rho == pytest.approx(rho, rel=1e-3)


@pytest.mark.parametrize('speed', [math.nan, math.inf, -math.inf])
def test_a_non_finite_speed_while_estimating_does_not_crash_the_filter(speed):
    # probe21: the estimator's speed below the floor was min_speed + 0 v_x, NaN for a
    # non-finite v_x: the gain look-up raised (ValueError; IndexError in a batch)
    v_y, r, eps_r = _turn(37.0, 1 / 500.0)
    state = LateralState(0.0, eps_r, v_y, r, 37.0, 0.0, 0.0, 0.0)
    f = KalmanStateFilter(VEHICLE)
    f.step(state, 0.02, True)
    f.step(state._replace(v_x=speed), 0.02, True)
    out = f.step(state, 0.02, True)
    assert math.isfinite(out.rho) and abs(out.rho) <= 0.2
    batch = LateralState(*[np.array([x, x]) for x in state])
    g = KalmanStateFilter(VEHICLE)
    g.step(batch, 0.02, np.array([True, True]))
    g.step(batch._replace(v_x=np.array([37.0, speed])), 0.02, np.array([True, True]))
    out = g.step(batch, 0.02, np.array([True, True]))
    assert np.all(np.isfinite(out.rho)) and np.all(np.abs(out.rho) <= 0.2)
    law = CgCompensatedLaw(VEHICLE, ControllerParams(), LaneKeepingParams())
    law.note_curvature(False)
    law.step(state, None, 0.02)
    law.step(state._replace(v_x=speed), None, 0.02)
    assert all(math.isfinite(law.step(state, None, 0.02).steering) for _ in range(3))


def _clothoid_rates(settings, v_x=37.0, jerk=0.5, seconds=8.0, dt=0.01):
    """Drive the law along a noise-free clothoid without road_curvature: its rates."""
    law = CgCompensatedLaw(VEHICLE, ControllerParams(), settings)
    rate = -jerk / v_x ** 2                 # a right clothoid, lateral jerk `jerk`
    rates = []
    for k in range(int(round(seconds / dt))):
        rho = rate * k * dt
        v_y, r, eps_r = _turn(v_x, rho)     # quasi-steady on the lane
        law.note_curvature(False)
        law.step(LateralState(0.0, eps_r, v_y, r, v_x, 0.0, 0.0, 0.0), None, dt)
        rates.append(float(law.curvature_rate()))
    return np.array(rates), rate


def test_on_a_clothoid_without_curvature_the_rate_estimate_converges_to_the_true_rate():
    # a 0.5 m/s^3 clothoid at 37 m/s (rho' = -3.65e-4 1/(m s), R 400 m after 6.8 s):
    # the estimate's filtered difference (estimate_rate_time 0.5 s) is within 1 % of the
    # true rate after 3 s (0.07 % after 4 s); the code before took it as 0
    rates, true = _clothoid_rates(LaneKeepingParams())
    assert np.all(np.abs(rates[300:] - true) < 0.01 * abs(true))
    assert abs(rates[-1] - true) < 1e-3 * abs(true)
    # clipped to the lateral jerk max_lateral_jerk (10 m/s^3 at 37 m/s: 7.3e-3)
    clipped, _ = _clothoid_rates(LaneKeepingParams(max_lateral_jerk=0.25))
    most = 0.25 / 37.0 ** 2
    assert np.max(np.abs(clipped)) <= most * (1.0 + 1e-12)
    assert clipped[-1] == pytest.approx(-most, rel=1e-3)
    # estimate_rate_time 0: the rate is not estimated (the code before)
    off, _ = _clothoid_rates(LaneKeepingParams(estimate_rate_time=0.0))
    assert np.all(off == 0.0)


def test_the_estimate_rate_previews_the_curve_without_curvature():
    # goal plant, seed 0, without road_curvature (peak cm, measured by bench.rho_preview
    # over 16 seeds in docs/lane_keeping.md): S2 at 37 m/s 38.4 with the estimate's
    # rate taken as 0 (the code before), 30.2 with it; S3 at 37 m/s 98.2 -> 71.6
    old = LaneKeepingParams(estimate_rate_time=0.0)
    s2_old = np.max(np.abs(_run('s2_curve_entry', 37.0, settings=old)['y_cg']))
    s2_new = np.max(np.abs(_run('s2_curve_entry', 37.0)['y_cg']))
    assert s2_old > 0.36 and s2_new < 0.33
    s3_new = np.max(np.abs(_run('s3_s_bend', 37.0)['y_cg']))
    assert s3_new < 0.8


def test_the_estimate_rate_costs_less_than_a_third_more_steering_noise():
    # S0 at 37 m/s, seed 0: the command less that of the noise-free run, std after 1 s
    def noise(settings):
        from lookahead_control.tools.compare import load_scenarios
        from sim_plant.closed_loop_sim import run
        from sim_plant.vehicle_model import PlantParams

        noisy = _run('s0_straight', 37.0, settings=settings)

        class Off:

            def __init__(self):
                self.law = CgCompensatedLaw(VEHICLE, ControllerParams(), settings)

            def reset(self):
                self.law.reset()

            def step(self, state, preview, dt):
                self.law.note_curvature(False)
                return self.law.step(state._replace(rho=0.0, rho_rate=0.0), None, dt)

        clean = run(load_scenarios(['s0_straight'])['s0_straight'], VEHICLE, Off(),
                    PlantParams(model='nonlinear'), initial_speed=37.0, dt=0.001,
                    delay=0.02, preview_distance=100.0)
        late = noisy.time > 1.0
        return np.std((noisy['steering_cmd'] - clean['steering_cmd'])[late])

    before = noise(LaneKeepingParams(estimate_rate_time=0.0))
    now = noise(LaneKeepingParams())
    assert before < now < 1.3 * before


def test_a_negative_estimate_rate_time_is_refused():
    from lookahead_control.core.params import ParameterError
    with pytest.raises(ParameterError, match='estimate_rate_time = -0.1'):
        LaneKeepingParams(estimate_rate_time=-0.1)


@pytest.mark.parametrize('v_x', [10.0, 37.0])
def test_the_rate_gain_is_the_law_s_terms_in_the_estimated_rate_by_hand(v_x):
    # with the estimate's rate q: the drift term's curvature T_ff ahead (q T_ff) and its
    # rate (q), the rate feedforward d_v lead q in the reference, its rate d_v gain q
    from lookahead_control.core.lane_keeping import loop_gains
    from lookahead_control.core.lane_keeping_stability import rate_gain
    from lookahead_control.core.schedule import look_ahead
    settings = LaneKeepingParams()
    m, iz, l1, l2, eta = (VEHICLE.mass, VEHICLE.yaw_inertia, VEHICLE.l1, VEHICLE.l2,
                          VEHICLE.eta)
    d_v = float(look_ahead(v_x, 0.0, VEHICLE, ControllerParams())[0])
    k_p, k_d = (float(k) for k in loop_gains(settings, v_x))
    beta_1 = VEHICLE.c_f * (1.0 / m + l1 * d_v / iz)
    gain = eta * v_x ** 2 - l2
    lead = -(v_x * iz * eta / (m * l1) + gain * l2 / v_x)
    # the state preview: the drift term's state terms on the lane, F_rho = beta_1 (gain -
    # l_1) + beta_2 (gain + l_2) per unit curvature, T_ff q ahead
    beta_2 = VEHICLE.c_r * (1.0 / m - l2 * d_v / iz)
    f_rho = beta_1 * (gain - l1) + beta_2 * (gain + l2)
    expected = (v_x ** 2 * settings.feedforward_preview + d_v * v_x + k_p * d_v * lead
                + k_d * d_v * gain
                - settings.state_preview * settings.feedforward_preview * f_rho) / beta_1
    assert settings.state_preview > 0.0
    assert rate_gain(VEHICLE, ControllerParams(), settings, v_x) == pytest.approx(
        expected, rel=1e-9)
    assert rate_gain(VEHICLE, ControllerParams(),
                     LaneKeepingParams(estimate_rate_time=0.0), v_x) == 0.0


def test_the_estimate_rate_previews_the_curve_on_the_independent_plant_too():
    # bench.rho_preview --plant commonroad_mb (dev-probe29; before, the goal plant only):
    # the CommonRoad multi-body plant (vehicle 2, its single-track mapping as the law's
    # model, 20 ms delay, default noise), seed 0, S2 at 37 m/s without road_curvature:
    # peak 18.4 cm with the estimate's rate taken as 0, 14.9 cm with it
    from bench.rho_preview import main, measure
    old = measure('s2_curve_entry', [37.0], 1, LaneKeepingParams(estimate_rate_time=0.0),
                  plant='commonroad_mb')[0]
    new = measure('s2_curve_entry', [37.0], 1, LaneKeepingParams(), plant='commonroad_mb')[0]
    assert old['peak'][0] > 17.5 and new['peak'][0] < 16.0, (old, new)
    # --tyres scales the package plant only: refused with the CommonRoad one
    with pytest.raises(SystemExit):
        main(['--plant', 'commonroad_mb', '--tyres', '0.7'])
