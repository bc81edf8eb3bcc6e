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

"""The delay-aware law (lane_keeping.delay_prediction): the estimate across the delay."""

from __future__ import annotations

import dataclasses
import math

from lookahead_control.core import lane_keeping_stability as stability
from lookahead_control.core.control_law import LateralState
from lookahead_control.core.lane_keeping import (CgCompensatedLaw, LaneKeepingParams,
                                                 period_frequency)
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
from lookahead_control.core.state_filter import KalmanStateFilter
from lookahead_control.tools.compare import load_scenarios, NONLINEAR, PREVIEW_DISTANCE
import numpy as np
import pytest
from scipy.linalg import expm
from sim_plant.closed_loop_sim import run

VEHICLE = VehicleParams()
CONTROLLER = ControllerParams()
PERIOD = 0.01


def _long_delay(delay, prediction=True, **more):
    """
    Return the law's settings for a transport delay the filter is told of.

    The polygon as received (``curvature_smoothing`` 0): the prediction was measured
    on the law before the averaging (docs/lane_keeping.md, "The delay-aware law").
    """
    return LaneKeepingParams(filter_delay=delay, feedforward_preview=0.05 + delay,
                             delay_prediction=prediction,
                             **{'curvature_smoothing': 0.0, **more})


def _filter_after_commands(delay, period=PERIOD, jitter=0.0):
    """
    Return a filter run 0.6 s at 30 m/s on a 200 m arc with a varying command.

    :return: the filter, the commands sent and the filter's time at each (their issue).
    """
    settings = dataclasses.replace(LaneKeepingParams().filter_settings(), delay=delay)
    kalman = KalmanStateFilter(VEHICLE, settings)
    commands, issued = [], []
    for k in range(int(round(0.6 / period))):
        t = k * period
        kalman.step(LateralState(0.1 * math.sin(3 * t), 0.01 * math.cos(2 * t),
                                 -0.2 + 0.1 * math.sin(t), 0.15 + 0.02 * math.cos(4 * t),
                                 30.0, 0.0, 1 / 200.0, 0.0), period)
        commands.append(0.02 + 0.01 * math.sin(5 * t) + jitter * (-1) ** k)
        issued.append(kalman.time)
        kalman.command(commands[-1])
    return kalman, commands, issued


def _by_hand(kalman, commands, issued, delay, v_x, rho, horizon=None):
    """
    Integrate the single-track model with the filter's wheel by matrix exponentials.

    States ``[y, eps_r, v_y, r, wheel, 1]``, the force disturbances and the curvature in
    the constant column. Over the prediction the wheel's input at ``now + s`` is the
    last command issued at or before ``now + s - delay``: the pieces between the
    instants ``issued + delay - now`` are worked out here from the issue times, not
    with the filter's lookup.
    """
    m, iz, l1, l2, c_f, c_r = (VEHICLE.mass, VEHICLE.yaw_inertia, VEHICLE.l1, VEHICLE.l2,
                               VEHICLE.c_f, VEHICLE.c_r)
    lag = kalman.settings.actuator_lag
    y, e, v, r, f_f, f_r = (float(x) for x in kalman.x[:6])
    state = np.array([y, e, v, r, float(kalman.wheel), 1.0])
    now = issued[-1]
    horizon = delay if horizon is None else horizon
    changes = [(t + delay - now, c) for t, c in zip(issued, commands)]
    before = [c for at, c in changes if at <= 1e-12]
    edges = [0.0] + [at for at, _ in changes if 1e-12 < at < horizon - 1e-12] + [horizon]
    inputs = [before[-1]] + [c for at, c in changes if 1e-12 < at < horizon - 1e-12]
    for (start, end), command in zip(zip(edges, edges[1:]), inputs):
        a = np.zeros((6, 6))
        a[0, 1], a[0, 2] = v_x, 1.0
        a[1, 3], a[1, 5] = 1.0, -v_x * rho
        a[2, 2] = -(c_f + c_r) / (m * v_x)
        a[2, 3] = -(c_f * l1 - c_r * l2) / (m * v_x) - v_x
        a[2, 4], a[2, 5] = c_f / m, (f_f + f_r) / m
        a[3, 2] = -(c_f * l1 - c_r * l2) / (iz * v_x)
        a[3, 3] = -(c_f * l1 * l1 + c_r * l2 * l2) / (iz * v_x)
        a[3, 4], a[3, 5] = c_f * l1 / iz, (l1 * f_f - l2 * f_r) / iz
        a[4, 4], a[4, 5] = -1.0 / lag, command / lag
        state = expm(a * (end - start)) @ state
    return state[:4]


def test_ahead_is_the_model_integrated_by_hand_and_leaves_the_filter_as_it_was():
    kalman, commands, issued = _filter_after_commands(0.1)
    twin, _, _ = _filter_after_commands(0.1)
    got = kalman.ahead(0.1, 30.0, 1 / 200.0, 1 / 200.0)
    assert got is not None
    want = _by_hand(kalman, commands, issued, 0.1, 30.0, 1 / 200.0)
    assert np.allclose(got, want, rtol=1e-6, atol=1e-9)     # RK4 against the exact solution
    # it moved: across 100 ms the states are not the present ones
    assert abs(got[0] - kalman.x[0]) > 1e-3
    # nothing of the filter changed: its next step is its twin's to the bit
    assert kalman.history == twin.history and kalman.wheel == twin.wheel
    measurement = LateralState(0.05, 0.0, -0.2, 0.15, 30.0, 0.0, 1 / 200.0, 0.0)
    assert kalman.step(measurement, PERIOD) == twin.step(measurement, PERIOD)


@pytest.mark.parametrize('delay, period', [(0.1, 0.005), (0.1, 0.0025), (0.025, 0.01),
                                           (0.1, 0.015), (0.1, 1 / 30), (0.105, 0.01)])
def test_ahead_takes_every_command_in_flight_over_its_own_interval(delay, period):
    # dev-probe43/44: 10 ms substeps read one command each at their middle; at a 5 ms
    # period half the commands were skipped, and at a delay or a period that is not a
    # whole number of 10 ms the substeps straddled command changes (3-10 % of the
    # predicted motion off with a 2 mrad command jitter); at n + 1/2 periods of delay
    # the filter took one command or the next at random
    kalman, commands, issued = _filter_after_commands(delay, period, jitter=0.002)
    got = kalman.ahead(delay, 30.0, 1 / 200.0, 1 / 200.0)
    want = _by_hand(kalman, commands, issued, delay, 30.0, 1 / 200.0)
    motion = np.abs(want - np.asarray(kalman.x[:4]))
    assert np.all(np.abs(np.asarray(got) - want) <= 1e-5 * motion + 1e-9)


@pytest.mark.parametrize('delay, period', [(0.025, 0.01), (0.015, 0.01), (0.02, 0.008),
                                           (0.02, 0.01)])
def test_the_filter_s_own_step_takes_every_command_over_its_own_interval(delay, period):
    # dev-probe45: the step's prior read one command per 10 ms substep at its middle, so
    # at a delay of n + 1/2 periods (or a period that is not a whole 10 ms) a command
    # change inside the step was missed (v_y 4-22 % off an exact integration). The
    # prior over the next step, from the filter's present estimate, against the exact one
    kalman, commands, issued = _filter_after_commands(delay, period, jitter=0.002)
    want = _by_hand(kalman, commands, issued, delay, 30.0, 1 / 200.0, horizon=period)
    # (_integrate moves the filter's wheel on: the exact one is worked out first)
    got = kalman._integrate(list(kalman.x), period, 30.0, 1 / 200.0, 1 / 200.0)
    motion = np.abs(want - np.asarray(kalman.x[:4]))
    assert np.all(np.abs(np.asarray(got[:4]) - want) <= 1e-5 * motion + 1e-9)


def test_ahead_after_a_flood_of_microsecond_steps_is_not_thousands_of_substeps():
    kalman, _, _ = _filter_after_commands(0.1)
    for _ in range(3000):
        kalman.step(LateralState(0.0, 0.0, -0.2, 0.15, 30.0, 0.0, 1 / 200.0, 0.0), 1e-6)
        kalman.command(0.02)
    counts = []
    predict = kalman._predict

    def counted(*args):
        out = predict(*args)
        counts.append(kalman.steps_cache[1])
        return out

    kalman._predict = counted
    got = kalman.ahead(0.1, 30.0, 1 / 200.0, 1 / 200.0)
    assert sum(counts) <= 51                    # MIN_AHEAD_SUBSTEP, 2 ms
    assert all(math.isfinite(v) for v in got)


def test_ahead_refuses_a_time_past_the_delay_and_is_none_before_a_step():
    kalman = KalmanStateFilter(VEHICLE)
    assert kalman.ahead(0.02, 30.0, 0.0, 0.0) is None
    kalman, _, _ = _filter_after_commands(0.02)
    for bad in (0.05, 0.0, -0.01, math.nan):
        with pytest.raises(ValueError, match='prediction time'):
            kalman.ahead(bad, 30.0, 0.0, 0.0)


def test_settings_refuse_it_without_the_filter_or_as_a_number():
    with pytest.raises(ParameterError, match="delay_prediction = true needs .*kalman.*'none'"):
        LaneKeepingParams(delay_prediction=True, state_filter='none')
    with pytest.raises(ParameterError, match='delay_prediction = 1 must be true or false'):
        LaneKeepingParams(delay_prediction=1)
    assert LaneKeepingParams().delay_prediction is False
    # dev-probe43: with filter_delay 0 it was taken and predicted nothing
    with pytest.raises(ParameterError, match='filter_delay, which is 0'):
        LaneKeepingParams(delay_prediction=True, filter_delay=0.0)


def _arc_state(v_x, rho):
    """Return the steady state of the linear model with the CG on an arc."""
    r = v_x * rho
    v_y = VEHICLE.l2 * r - v_x * VEHICLE.eta * v_x * r
    return LateralState(0.0, -v_y / v_x, v_y, r, v_x, 0.0, rho, 0.0)


def test_on_a_steady_arc_the_prediction_changes_nothing():
    # at the filter's equilibrium under a constant command the state a delay ahead is
    # the present one and the road there the same: the same command (linear tyres, no
    # estimate, no integral: the steady state is exact)
    common = {'design_friction': 0.0, 'compliance_time_constant': 0.0, 'integral_gain': 0.0,
              'low_speed_integral_gain': 0.0}
    state = _arc_state(30.0, -1 / 300.0)
    outs = []
    for prediction in (False, True):
        law = CgCompensatedLaw(VEHICLE, CONTROLLER, _long_delay(0.1, prediction, **common))
        for _ in range(400):
            out = law.step(state, None, PERIOD)
        outs.append(float(out.steering))
    assert outs[1] == pytest.approx(outs[0], abs=1e-9)


def _stiff_run(scenario, prediction, delay=0.1, stiffness=1.3, speed=30.0):
    """Return ``y_cg`` and time of a noise-free run on tyres stiffer than the model."""
    plant = dataclasses.replace(VEHICLE, c_f=VEHICLE.c_f * stiffness,
                                c_r=VEHICLE.c_r * stiffness)
    law = CgCompensatedLaw(VEHICLE, CONTROLLER, _long_delay(delay, prediction))
    result = run(load_scenarios([scenario])[scenario], VEHICLE, law, NONLINEAR, dt=PERIOD,
                 initial_speed=speed, plant_vehicle=plant, delay=delay,
                 preview_distance=PREVIEW_DISTANCE)
    return np.asarray(result.time), np.asarray(result['y_cg'])


def test_tyres_30_percent_stiffer_with_100_ms_of_delay_ring_without_it_and_settle_with_it():
    # the case dev-probe42 found: the loop rings at 30 m/s with 100 ms of delay
    t, without = _stiff_run('s2_curve_entry', False)
    _, with_it = _stiff_run('s2_curve_entry', True)
    last = t > t[-1] - 3.0
    assert np.max(np.abs(without[last])) > 0.05
    assert np.max(np.abs(with_it[last])) < 0.01
    assert np.max(np.abs(with_it)) < 0.06


def test_the_road_moves_with_the_predicted_state():
    # the prototype acted on the predicted state with the road of now: the S-bend's
    # reversal then left the CG 10 cm off at the end (nominal tyres, 100 ms); with the
    # road read where the car will be it ends as the law without prediction does
    t, with_it = _stiff_run('s3_s_bend', True, stiffness=1.0)
    _, without = _stiff_run('s3_s_bend', False, stiffness=1.0)
    last = t > t[-1] - 3.0
    assert np.max(np.abs(with_it[last])) < 0.03
    assert np.max(np.abs(with_it[last])) <= np.max(np.abs(without[last])) + 0.002
    assert np.max(np.abs(with_it)) <= np.max(np.abs(without)) + 0.002


@pytest.mark.parametrize('delay', [0.1, 0.15])
def test_the_robust_check_holds_with_it_where_it_fails_without(delay):
    plant = dataclasses.replace(VEHICLE, c_f=VEHICLE.c_f * 1.3, c_r=VEHICLE.c_r * 1.3)
    steps = int(round(delay / PERIOD))
    radius = {p: stability.filtered_radius(VEHICLE, CONTROLLER, _long_delay(delay, p), 37.0,
                                           plant=plant, delay_steps=steps)
              for p in (False, True)}
    assert radius[False] > 1.005
    assert radius[True] < 0.997


@pytest.mark.parametrize('prediction, delay, v_x, period', [
    (True, 0.08, 30.0, 0.01), (True, 0.02, 10.0, 0.01), (False, 0.02, 37.0, 0.01),
    (True, 0.025, 37.0, 0.01), (False, 0.025, 30.0, 0.01), (True, 0.05, 30.0, 0.02),
    (True, 0.02, 30.0, 0.001), (True, 0.1, 37.0, 0.001)])
def test_the_robust_check_s_matrix_is_the_real_law_in_time(prediction, delay, v_x, period):
    # the real CgCompensatedLaw (its limits and the estimate off, straight road) in the
    # linear loop, the plant by ZOH and its delay as a list, against filtered_loop's
    # matrix. dev-probe43: the matrix put the integral's rate term on the predicted
    # y_cg and used the integral of the step before: 5e-3 / 1e-3 off with / without.
    # dev-probe44: at a delay of n + 1/2 periods the filter took one command or the next
    # at random (4e-3 - 2e-2 off with the prediction, 5e-4 without). dev-probe45: at a
    # 1 ms period (commands more often than every 2 ms: ahead's mean input) 3.8e-4 off.
    # The side force (dev-sc36) fades with the car's rotation relative to the lane, a
    # nonlinearity the matrix takes at 0 rotation: the start is 1e-4 of the old one
    # (0.3 m, 0.03 rad/s before), 3e-6 rad/s, where the fade is 1 to 1e-8 (the loop is
    # linear otherwise, the tolerance relative)
    settings = _long_delay(delay, prediction, demand_limit=0.0, approach_heading=0.0,
                           compliance_time_constant=0.0, integral_band=0.0)
    plant = dataclasses.replace(VEHICLE, c_f=VEHICLE.c_f * 0.8, mass=VEHICLE.mass * 1.2,
                                yaw_inertia=VEHICLE.yaw_inertia * 1.2)
    steps = int(round(delay / period))
    law = CgCompensatedLaw(VEHICLE, CONTROLLER, settings)
    # its cap of w_n where a second of answers at the period has moved it (dev-sc56)
    law.frequency = period_frequency(settings, period)
    a_c, b_c = stability._actuated_plant(plant, v_x, 0.05)
    phi, gamma = stability._zoh(a_c, b_c, period)
    start = np.array([0.3, 0.02, -0.1, 0.03]) * 1e-4
    x = np.zeros(a_c.shape[0])
    x[:4] = start
    sent, sim = [0.0] * steps, []
    for _ in range(300):
        sim.append(x[:5].copy())
        out = law.step(LateralState(x[0], x[1], x[2], x[3], v_x, 0.0, 0.0, 0.0), None,
                       period)
        sent.append(float(out.steering))
        x = phi @ x + gamma[:, 0] * sent.pop(0)
    m = stability.filtered_loop(VEHICLE, CONTROLLER, settings, v_x, plant=plant,
                                delay_steps=steps, period=period)
    s = np.zeros(m.shape[0])
    s[:4] = start
    s[6:10] = start                     # the filter starts at the measurement
    mat = []
    for _ in range(300):
        mat.append(s[:5].copy())
        s = m @ s
    sim_a, mat_a = np.array(sim), np.array(mat)
    # under a 2 ms period ahead takes the mean of the commands over 2 ms substeps once its
    # history is full, and the first steps' short history piece by piece; the matrix
    # takes the means throughout (a few 1e-6)
    tolerance = 1e-6 if period >= 0.002 or not prediction else 2e-5
    assert np.max(np.abs(sim_a - mat_a)) < tolerance * np.max(np.abs(sim_a))
    other = stability.filtered_loop(VEHICLE, CONTROLLER,
                                    dataclasses.replace(settings,
                                                        delay_prediction=not prediction),
                                    v_x, plant=plant, delay_steps=steps, period=period)
    assert not np.allclose(other, m)


def test_a_batch_with_it_equals_its_single_runs():
    # curvature received in one run, estimated in another, a NaN and a speed below the
    # filter's floor in a third: each run of the batch is its single run to the bit
    settings = _long_delay(0.06)
    rho = -1 / 400.0
    arc = _arc_state(37.0, rho)
    rng = np.random.default_rng(5)
    batch = CgCompensatedLaw(VEHICLE, CONTROLLER, settings)
    singles = [CgCompensatedLaw(VEHICLE, CONTROLLER, settings) for _ in range(3)]
    preview = type('Preview', (), {'distances': np.array([0.0, 50.0]),
                                   'curvatures': np.array([[rho] * 3, [2 * rho] * 3])})
    for k in range(250):
        received = np.array([True, k % 80 < 40, True])
        noise = rng.normal(0.0, 0.002, (4, 3))
        y = noise[0] * 10
        speed = np.full(3, 37.0)
        if k == 120:
            y[2] = math.nan
        if 150 <= k < 155:
            speed[2] = 2.0
        states = LateralState(y, arc.eps_r + noise[1], arc.v_y + noise[2] * 10,
                              arc.r + noise[3], speed, np.zeros(3),
                              np.where(received, rho, 0.0), np.zeros(3))
        batch.note_curvature(received)
        both = batch.step(states, preview, PERIOD)
        for i, single in enumerate(singles):
            single.note_curvature(bool(received[i]))
            one_preview = type('Preview', (), {'distances': preview.distances,
                                               'curvatures': preview.curvatures[:, i]})
            one = single.step(LateralState(*(float(np.asarray(v)[i]) for v in states)),
                              one_preview, PERIOD)
            assert (both.steering[i] == one.steering
                    or (math.isnan(both.steering[i]) and math.isnan(one.steering)))
    assert np.all(np.isfinite(both.steering))


def test_bad_inputs_give_no_nan_after_them():
    # a NaN, a speed dropout below the filter's floor, a frozen stamp, a time jump
    law = CgCompensatedLaw(VEHICLE, CONTROLLER, _long_delay(0.1))
    state = _arc_state(37.0, -1 / 400.0)
    events = {100: state._replace(eps_r=math.nan), 150: state._replace(v_x=0.0),
              151: state._replace(v_x=1.0), 200: state._replace(r=math.inf)}
    out = []
    for k in range(400):
        dt = {250: 0.0, 251: 0.0, 300: 5.0, 320: -0.1}.get(k, PERIOD)
        out.append(float(law.step(events.get(k, state), None, dt).steering))
    assert math.isnan(out[100]) and math.isnan(out[200])
    good = [v for k, v in enumerate(out) if k not in (100, 200)]
    assert all(math.isfinite(v) for v in good)
    # (at 0 and 1 m/s with a 37 m/s arc's yaw rate the law asks 0.4 rad with or without
    # the prediction: below the filter's floor the measurement passes)
    assert all(abs(v) < 0.1 for k, v in enumerate(out) if k not in (100, 150, 151, 200))
    assert abs(out[-1] - out[99]) < 2e-3


def _true_wheel(sent, delay, lag, until):
    """Return the wheel of a delayed first-order actuator under ``sent`` [(t, u)]."""
    wheel, changes = 0.0, [(t + delay, u) for t, u in sent if t + delay < until]
    for (start, u), end in zip(changes, [t for t, _ in changes[1:]] + [until]):
        wheel = u + (wheel - u) * math.exp(-(end - start) / lag)
    return wheel


@pytest.mark.parametrize('stale_ms', [300, 760, 2000])
def test_after_stale_inputs_the_filter_s_actuator_is_the_one_the_safe_commands_moved(
        stale_ms):
    # dev-probe44: the safety layer's hold and ramp to the safe angle were not recorded:
    # after 2 s of stale inputs the filter still had the law's last commands in flight
    # (the wheel at 0 by then) and the prediction ran on them. dev-probe45: the first
    # fix put the filter's wheel at the safe angle at once, while the real one follows
    # the ramp through the delay and the lag (26 mrad off the next commands at 760 ms)
    from lookahead_control.core.controller import SteeringController
    from lookahead_control.core.safety import SafetyParams
    from lookahead_control.core.samples import (LateralErrorSample, VelocitySample,
                                                YawSample)
    settings = _long_delay(0.1)
    core = SteeringController(VEHICLE, CONTROLLER, 'imu', False, SafetyParams(),
                              'cg_compensated', None, settings)
    ms = 1_000_000
    sent = []

    def fresh(t_ms):
        stamp = t_ms * ms
        for name, sample in (('yaw', YawSample(stamp, 0.0, 25.0 / 150.0, 0.0)),
                             ('velocity', VelocitySample(stamp, 25.0, 0.0)),
                             ('lateral_error', LateralErrorSample(stamp, 0.0, 0.02))):
            core.accept(name, sample, stamp)
        out = core.compute(stamp)
        sent.append((t_ms / 1000.0, out.steering))
        return out

    for k in range(101):
        before = fresh(10 * k)
    assert before.status == 'ok' and abs(before.steering) > 1e-2
    kalman = core.law.state_filter
    for t in range(1010, 1000 + stale_ms + 1, 10):     # the watchdog, inputs stale
        out = core.safe_command(t * ms)
        assert out.status == 'stale'
        sent.append((t / 1000.0, out.steering))
    end = sent[-1][0]
    lag = settings.filter_actuator_lag
    truth = _true_wheel(sent, 0.1, lag, end)
    assert kalman.wheel == pytest.approx(truth, abs=1e-9)
    # the commands in flight are the safe ones of the last 100 ms
    edges, commands = kalman._inputs(0.1)
    assert commands[1:] == [u for t, u in sent if end - 0.1 + 1e-9 < t < end - 1e-9]
    if stale_ms > 600:                  # the ramp has reached the wheel
        assert abs(kalman.wheel) < abs(before.steering) / 2
    after = fresh(1000 + stale_ms + 10)
    assert after.status == 'ok' and math.isfinite(after.steering)


def test_the_node_takes_it_and_refuses_it_without_the_filter(context):
    from lookahead_control.ros.controller_node import ControllerNode
    from rclpy.parameter import Parameter
    node = ControllerNode(context=context)
    try:
        descriptor = node.describe_parameters(['lane_keeping.delay_prediction'])[0]
        assert 'filter_delay' in descriptor.description
        ok = node.set_parameters([Parameter('lane_keeping.delay_prediction', value=True)])[0]
        assert ok.successful, ok.reason
        assert node.core.lane_keeping.delay_prediction is True
        refused = node.set_parameters([Parameter('lane_keeping.state_filter',
                                                 value='none')])[0]
        assert not refused.successful
        assert 'delay_prediction' in refused.reason
        assert node.core.lane_keeping.state_filter == 'kalman'
        refused = node.set_parameters([Parameter('lane_keeping.filter_delay', value=0.0)])[0]
        assert not refused.successful and 'filter_delay, which is 0' in refused.reason
        assert node.core.lane_keeping.filter_delay == 0.02
    finally:
        node.destroy_node()


def _params(tmp_path, name, **lane_keeping):
    """Write a controller params file with these ``lane_keeping.*`` and return its path."""
    path = tmp_path / name
    lines = ['controller:', '  ros__parameters:', '    lane_keeping:']
    lines += [f'      {key}: {str(value).lower()}' for key, value in lane_keeping.items()]
    path.write_text('\n'.join(lines) + '\n')
    return str(path)


def test_the_stability_tool_checks_a_long_delay_with_and_without_it(tmp_path, capsys):
    from lookahead_control.tools.lane_keeping_tool import stability_main
    long = {'filter_delay': 0.1, 'feedforward_preview': 0.15}
    on = _params(tmp_path, 'on.yaml', delay_prediction=True, **long)
    off = _params(tmp_path, 'off.yaml', **long)
    assert stability_main(['--samples', '28', '--controller', on, '--delays', '0.1']) == 0
    text = capsys.readouterr().out
    assert 'plant delays 0.1 s' in text and 'robust check with the filter HOLDS' in text
    assert stability_main(['--samples', '28', '--controller', off, '--delays', '0.1']) == 1
    assert 'robust check with the filter DOES NOT HOLD' in capsys.readouterr().out
    # the default grid is the sweep's delays
    assert stability_main(['--samples', '28']) == 0
    assert 'plant delays 0, 0.02, 0.05 s' in capsys.readouterr().out
    for bad in ('-0.01', '1.5', 'nan'):
        with pytest.raises(SystemExit):
            stability_main(['--delays', bad])
        assert 'allowed: [0, 1] s' in capsys.readouterr().err or bad == 'nan'


def test_the_tool_checks_and_prints_the_delays_it_rounded_once_each(tmp_path, capsys):
    # dev-probe43: 0.095 and 0.105 were printed as checked, both checked at 0.1 (banker's
    # rounding), and 0.1 given three ways counted 486 cases of 162. Since dev-sc55 a
    # fraction of the period is checked as it is: the delays are rounded to 1 ms
    from lookahead_control.tools.lane_keeping_tool import stability_main
    on = _params(tmp_path, 'on.yaml', delay_prediction=True, filter_delay=0.1,
                 feedforward_preview=0.15)
    stability_main(['--samples', '28', '--controller', on, '--delays', '0.095', '0.105',
                    '0.1000001', '0.1'])
    text = capsys.readouterr().out
    assert '--delays 0.1000001 rounded to 1 ms: 0.095, 0.1, 0.105 s' in text
    assert 'every 0.01 s, plant delays 0.095, 0.1, 0.105 s' in text
    assert 'max spectral radius, 486 mismatch cases, Kalman estimate |' in text


def test_one_run_s_bad_preview_in_a_batch_falls_back_for_that_run_alone():
    # dev-probe43 (before this feature): a NaN in one run's preview column made every run
    # of the batch fall back to the curvature at the CG; each run is now its single run
    from lookahead_control.core.lane_keeping import preview_curvature
    distances = np.array([0.0, 20.0, 60.0])
    columns = np.array([[0.001, 0.002, 0.004], [0.001, math.nan, 0.0],
                        [-0.002, -0.002, math.inf]]).T
    rho, slope = np.array([0.001, 0.0015, -0.002]), np.array([1e-5, 2e-5, 0.0])
    for ahead in (0.0, 10.0, np.array([5.0, 30.0, 80.0])):
        value, rate = preview_curvature(distances, columns, ahead, rho, slope)
        for i in range(3):
            at = float(np.asarray(ahead)[i]) if np.ndim(ahead) else ahead
            one = preview_curvature(distances, columns[:, i], at, float(rho[i]),
                                    float(slope[i]))
            assert (value[i], rate[i]) == pytest.approx(one, abs=1e-15)
    # the good run is read from its polygon, the bad ones extrapolate
    value, _ = preview_curvature(distances, columns, 10.0, rho, slope)
    assert value[0] == pytest.approx(0.0015) and value[1] == pytest.approx(0.0017)
