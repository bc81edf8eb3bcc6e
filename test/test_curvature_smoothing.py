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

"""The previewed curvature averaged along the road (core/curvature_smoothing.py)."""

from __future__ import annotations

from dataclasses import replace
import math

from lookahead_control.core import curvature_smoothing
from lookahead_control.core.config import load_controller, load_lane_keeping, load_vehicle
from lookahead_control.core.control_law import LateralState
from lookahead_control.core.curvature_smoothing import (CurvatureHistory, MAX_OUTPUT,
                                                        MAX_SAMPLES, smoothed_preview)
from lookahead_control.core.lane_keeping import CgCompensatedLaw, LaneKeepingParams
from lookahead_control.core.laws import Preview
from lookahead_control.core.output_stage import NodeOutputStage
from lookahead_control.core.params import ParameterError
from lookahead_control.core.safety import SafetyParams
import numpy as np
import pytest

W = 5.0
D = np.arange(0.0, 101.0, 5.0)
STEP = np.where(D >= 10.0, -0.0025, 0.0)        # S1's step, inside the segment 5-10 m


def triangle_average(x: float, road, half_width: float = W, breaks=None) -> float:
    """
    Average ``road`` around ``x`` by the triangular window, by integration.

    With ``breaks`` (the road's breakpoints: linear between them) Simpson's rule on each
    piece, exact for the window times a linear piece; without, a fine trapezoid rule.
    """
    if breaks is None:
        u = np.linspace(-half_width, half_width, 20001)
        weight = (half_width - np.abs(u)) / half_width ** 2
        return float(np.trapezoid(weight * road(x + u), u))
    inner = np.asarray(breaks, dtype=float) - x
    nodes = np.unique(np.concatenate([[-half_width, 0.0, half_width],
                                      inner[np.abs(inner) < half_width]]))
    a, b = nodes[:-1], nodes[1:]
    m = 0.5 * (a + b)

    def g(u):
        return (half_width - np.abs(u)) / half_width ** 2 * road(x + u)
    return float(np.sum((b - a) / 6.0 * (g(a) + 4.0 * g(m) + g(b))))


def test_a_clothoid_passes_unchanged_and_a_step_becomes_the_window_average():
    clothoid = -1e-4 * D
    out_d, out_k = smoothed_preview(D, clothoid, W)
    inside = (out_d >= W) & (out_d <= D[-1] - W)
    assert out_d[0] == 0.0 and out_d[-1] == pytest.approx(D[-1])
    assert np.max(np.abs(np.diff(out_d) - W / 8)) < 1e-9
    assert out_k[inside] == pytest.approx(-1e-4 * out_d[inside], abs=1e-12)
    # a step (the polygon's ramp over 5-10 m): the triangle average of the ramp, an
    # S-curve over 0-15 m centred on 7.5 m; against an independent integration
    out_d, out_k = smoothed_preview(D, STEP, W)
    for x, k in zip(out_d, out_k):
        assert k == pytest.approx(triangle_average(x, lambda s: np.interp(s, D, STEP),
                                                   breaks=D), abs=1e-12 * 0.0025)
    assert np.interp(7.5, out_d, out_k) == pytest.approx(-0.00125, abs=1e-9)
    assert np.all(np.diff(out_k) <= 1e-15)
    assert out_k[out_d <= 0.0] == pytest.approx(0.0, abs=1e-15)
    assert out_k[out_d >= 15.0] == pytest.approx(-0.0025, abs=1e-15)
    # the steepest slope the law reads: the ramp's (0.0025 / 5 m) times the share of
    # the window on the ramp at its centre, 1 - 2 (1/2) (2.5 / 5)^2 = 0.75 (a segment's
    # secant: within 1 % below it)
    steepest = np.max(np.abs(np.diff(out_k) / np.diff(out_d)))
    assert 0.99 * 0.75 * 0.0025 / 5.0 < steepest <= 0.75 * 0.0025 / 5.0


def test_the_window_reaches_behind_the_cg_into_the_road_driven():
    def road(s):
        return np.where(np.asarray(s) >= 100.0, -0.0025, 0.0)

    history = CurvatureHistory(W)
    s, v, dt = 90.0, 37.0, 0.005
    for _ in range(int(12.0 / (v * dt))):         # 12 m: the step now 2 m behind the CG
        s += v * dt
        history.record(v, dt, float(road(s)))
    ahead = np.asarray(road(s + D), dtype=float)
    out_d, out_k = smoothed_preview(D, ahead, W, history)
    # exact on the road as recorded (linear between the samples, 0.185 m apart: the
    # step driven over is a ramp within one), close to the step itself
    where, rho = history.behind()
    assert out_k[0] == pytest.approx(
        triangle_average(0.0, lambda u: np.where(u < 0.0, np.interp(u, where, rho),
                                                 np.interp(u, D, ahead)),
                         breaks=np.concatenate([where, D])), abs=1e-12 * 0.0025)
    assert out_k[0] == pytest.approx(triangle_average(s, road), abs=0.02 * 0.0025)
    assert -0.0025 < out_k[0] < -0.0015             # the step behind still counts
    # without the road behind, the curvature at the CG is held behind it: the full step
    assert smoothed_preview(D, ahead, W)[1][0] == pytest.approx(-0.0025)
    # the history keeps what the window reaches, not the whole drive
    assert history.size <= W / (v * dt) + 2
    assert history.behind()[0][0] <= -W


def test_a_level_road_keeps_its_curvature_exactly_run_by_run():
    # a straight or an arc (most steps of a run) is its own average, to the bit: before,
    # the integrals' rounding left -0.0025 as -0.0025000000000000005 on 8 of these 12
    # roads, and every step paid for the integrals (S1 runs: 7 % of their CPU)
    for c in (-0.0025, 1.0 / 333.0, 0.0017, -1.0 / 47.0):
        for start in (0.0, 1.3, 123.4):
            history = CurvatureHistory(W)
            for _ in range(30):
                history.record(37.0, 0.01, c)
            out_d, out_k = smoothed_preview(D + start, np.full(D.size, c), W, history, 2.6)
            assert np.all(out_k == c), (c, start)
            assert out_d[0] == start and np.all(np.diff(out_d) > 0.0)
    # a batch: the level run exactly, the other averaged as on its own; a run whose road
    # behind differs (the step driven over) or has no curvature is not level
    batch = CurvatureHistory(W)
    for _ in range(30):
        batch.record(np.array([37.0, 37.0, 37.0]), 0.01, np.array([-0.0025, 0.0, 0.0]))
    ahead = np.stack([np.full(D.size, -0.0025), STEP, np.full(D.size, -0.0025)], axis=1)
    _, both = smoothed_preview(D, ahead, W, batch, 2.6)
    assert np.all(both[:, 0] == -0.0025)
    assert -0.0025 < both[0, 2] < -0.001                    # the arc just entered
    single = CurvatureHistory(W)
    for _ in range(30):
        single.record(37.0, 0.01, 0.0)
    assert both[:, 1] == pytest.approx(smoothed_preview(D, STEP, W, single, 2.6)[1],
                                       rel=1e-12, abs=1e-15)
    batch.forget(np.array([True, False, False]))        # its samples lose their curvature
    _, after = smoothed_preview(D, ahead, W, batch, 2.6)
    assert after[:, 0] == pytest.approx(np.full(after.shape[0], -0.0025), rel=1e-12)


def test_on_a_level_road_a_run_of_a_batch_is_its_single_run_to_the_bit():
    # dev-probe88: a batch keeps the samples its slowest run reads; the level test looked
    # at them all, so the fast run, level over its own window, took the integrals in the
    # batch and not alone (1.3e-18 apart; S1 closed loops 2.8e-16 m, before the shortcut
    # 0). A restarted run's samples (NaN) are filled as its cleared single run holds back
    c = -0.0025
    batch, single, cleared = CurvatureHistory(W), CurvatureHistory(W), CurvatureHistory(W)
    for i in range(40):                 # 0.2 s straight, then 0.2 s on the arc
        rho = 0.0 if i < 20 else c
        batch.record(np.array([10.0, 37.0, 37.0]), 0.01, np.array([rho, rho, rho]))
        single.record(37.0, 0.01, rho)
    cleared.record(37.0, 0.01, c)
    batch.forget(np.array([False, False, True]))
    level = np.full((D.size, 3), c)
    _, both = smoothed_preview(D, level, W, batch, 37.0 * 0.3)
    for j, alone in ((1, single), (2, cleared)):
        _, one = smoothed_preview(D, level[:, j], W, alone, 37.0 * 0.3)
        assert np.array_equal(both[:, j], one) and np.all(one == c), j
    assert not np.all(both[:, 0] == c)  # the slow run has the straight in its window
    # another batch's history is not this road: the polygon alone, level (0.0017: the
    # integrals round it, -0.0025 they happen to keep)
    _, other = smoothed_preview(D, np.full((D.size, 2), 0.0017), W, batch, 37.0 * 0.3)
    assert np.all(other == 0.0017)


def test_a_history_recorded_for_every_run_at_once_forgets_one_run():
    # dev-probe88: recorded with one speed and curvature (shape ()), forget() of one run
    # of two raised ValueError (the samples' axis did not broadcast to the runs')
    history = CurvatureHistory(W)
    for _ in range(30):
        history.record(37.0, 0.01, -0.0025)
    history.forget(np.array([True, False]))
    where, rho = history.behind()
    assert where.shape == rho.shape == (history.size, 2)
    assert np.all(np.isnan(rho[:, 0])) and np.all(rho[:, 1] == -0.0025)
    assert np.all(where[:, 0] == where[:, 1])


def test_a_batch_is_its_single_runs_and_a_restarted_run_forgets_only_its_road():
    speeds = np.array([10.0, 37.0])
    batch = CurvatureHistory(W)
    singles = [CurvatureHistory(W) for _ in speeds]
    for i in range(200):
        rho = np.array([-1e-3 * np.sin(0.05 * i), 2e-3 * np.cos(0.03 * i)])
        batch.record(speeds, 0.01, rho)
        for j, one in enumerate(singles):
            one.record(float(speeds[j]), 0.01, float(rho[j]))
    ahead = np.stack([np.full(D.size, -1e-3), np.full(D.size, 2e-3)], axis=1)
    _, both = smoothed_preview(D, ahead, W, batch)
    for j, one in enumerate(singles):
        assert both[:, j] == pytest.approx(smoothed_preview(D, ahead[:, j], W, one)[1],
                                           rel=1e-12, abs=1e-15)
    batch.forget(np.array([True, False]))
    _, after = smoothed_preview(D, ahead, W, batch)
    assert after[:, 0] == pytest.approx(np.full(after.shape[0], -1e-3))  # no road behind
    assert after[:, 1] == pytest.approx(both[:, 1], rel=1e-12)


def test_a_polygon_the_law_would_not_read_passes_unchanged_and_a_nan_run_stays_nan():
    for d, k in ((np.array([0.0, 5.0, 5.0]), np.zeros(3)),
                 (np.array([0.0, np.nan]), np.zeros(2)),
                 (np.array([]), np.array([]))):
        out_d, out_k = smoothed_preview(d, k, W)
        assert out_d.tolist() == pytest.approx(d.tolist(), nan_ok=True)
        assert out_k.tolist() == k.tolist()
    both = np.stack([STEP, STEP], axis=1)
    both[3, 1] = np.nan
    _, out = smoothed_preview(D, both, W)
    assert np.all(np.isfinite(out[:, 0])) and np.all(np.isnan(out[:, 1]))
    # one point: the curvature at the CG, held
    out_d, out_k = smoothed_preview(np.array([0.0]), np.array([-0.002]), W)
    assert out_d.tolist() == [0.0] and out_k.tolist() == pytest.approx([-0.002])


def test_the_half_width_is_off_or_a_metre_to_fifty():
    assert LaneKeepingParams().curvature_smoothing == 5.0
    for good in (0.0, 1.0, 50.0):
        LaneKeepingParams(curvature_smoothing=good)
    with pytest.raises(ParameterError, match=r'lane_keeping.curvature_smoothing = 0.5 m '
                       r'would average over less than a metre.*allowed: 0 \(the polygon as '
                       r'received\) or 1-50 m'):
        LaneKeepingParams(curvature_smoothing=0.5)
    with pytest.raises(ParameterError, match='curvature_smoothing = 60'):
        LaneKeepingParams(curvature_smoothing=60.0)


def _state(s: float, v: float = 37.0) -> LateralState:
    return LateralState(y_cg=0.0, eps_r=0.0, v_y=0.0, r=0.0, v_x=v, a_x=0.0,
                        rho=-0.0025 if s >= 100.0 else 0.0, rho_rate=0.0)


def test_the_law_forgets_the_road_behind_at_a_time_jump_and_keeps_it_at_a_retune():
    vehicle, controller = load_vehicle(None), load_controller(None)
    law = CgCompensatedLaw(vehicle, controller, LaneKeepingParams())
    s = 95.0
    for _ in range(25):                 # to 104.25 m: the window reaches the straight
        s += 0.37
        law.step(_state(s), Preview(D, np.where(s + D >= 100.0, -0.0025, 0.0)), 0.01)
    kept = law._history.behind()[1][0]
    assert law._history.size > 10 and kept == 0.0
    retuned = CgCompensatedLaw(vehicle, controller, LaneKeepingParams(natural_frequency=6.5))
    retuned.reset()
    carried, _ = retuned.take_over(law)
    assert 'curvature behind the CG' in carried
    assert retuned._history.size == law._history.size
    law.step(_state(s), Preview(D, np.full(D.size, -0.0025)), 1.0)     # beyond max_gap
    assert law._history.size == 1 and law._history.behind()[1][0] == -0.0025


def test_s1_at_37_mps_through_the_node_output_stage():
    # the curvature step asked 0.083 rad for 30 ms where the node sends 0.0587 at
    # 37 m/s; the cut excited the CG's zero dynamics: 4.61 cm at t = 3.0 s, a second
    # after the step, and 7.8 % relative-yaw overshoot (the CG's offset over d_v).
    # Averaged over +-5 m: 2.67 cm, 5.3 % (nonlinear plant, 20 ms delay, no noise)
    from lookahead_control.tools import compare
    from sim_plant.closed_loop_sim import run
    from sim_plant.scenario import load_scenario
    from sim_plant.vehicle_model import PlantParams
    vehicle, controller = load_vehicle(None), load_controller(None)
    scenario = load_scenario(compare.SCENARIO_DIR / 's1_paper_step.yaml')
    peaks, overshoots = [], []
    for width in (0.0, 5.0):
        settings = replace(load_lane_keeping(None), curvature_smoothing=width)
        law = NodeOutputStage(CgCompensatedLaw(vehicle, controller, settings),
                              vehicle.wheelbase, SafetyParams())
        r = run(scenario, vehicle, law, PlantParams(model='nonlinear'), initial_speed=37.0,
                dt=compare.DT, delay=0.02, preview_distance=compare.PREVIEW_DISTANCE)
        eps, t = r['eps_r'], r.time
        final = float(np.mean(eps[t > t[-1] - 2.0]))
        peaks.append(float(np.max(np.abs(r['y_cg']))))
        overshoots.append(float(np.max(np.abs(eps)) / abs(final) - 1.0))
    assert peaks[0] > 0.044 and overshoots[0] > 0.075
    assert peaks[1] < 0.029 and overshoots[1] < 0.06


# -- dev-probe59 -------------------------------------------------------------------------

def test_a_fine_polygon_is_averaged_exactly():
    # the window was a sum over 15 points W / 8 apart: a polygon 0.1 m apart aliased (17-20
    # % of its range off); it is now integrated exactly over the linear pieces
    rng = np.random.default_rng(59)
    for width in (1.0, 5.0, 45.0):
        d = np.arange(0.0, 100.0, 0.1)
        k = rng.normal(0.0, 1e-3, d.size)
        out_d, out_k = smoothed_preview(d, k, width, reach=30.0)
        inside = out_d <= 30.0 + width / 8
        for x, value in zip(out_d[inside], out_k[inside]):
            assert value == pytest.approx(triangle_average(
                x, lambda s: np.interp(s, d, k), width, breaks=d), abs=1e-12 * 1e-3)


def test_a_far_point_neither_crashes_nor_slows_the_law():
    # a legal road_curvature of three points, the last at 3e38 m (the safety layer bounds
    # the count, not the distance): the grid was (d[-1] + 2 W) / (W / 8) points, and the
    # node died (ValueError: Maximum allowed size exceeded; 11.9 GiB at 1e9 m)
    d = np.array([0.0, 5.0, 3e38])
    k = np.full(3, -0.002)
    out_d, out_k = smoothed_preview(d, k, W, reach=2.6)
    assert out_d.size <= 10 and out_d[-1] == 3e38
    assert out_k == pytest.approx(np.full(out_d.size, -0.002))
    law = CgCompensatedLaw(load_vehicle(None), load_controller(None), LaneKeepingParams())
    for _ in range(20):
        out = law.step(_state(0.0), Preview(d, k), 0.01)
    assert np.isfinite(out.steering)
    # the averaged polygon reaches one step past the farthest read, then the received
    # points: a short polygon keeps two points (its slope)
    out_d, _ = smoothed_preview(np.array([0.0, 5.0]), np.array([0.0, 0.001]), 50.0, reach=1.0)
    assert out_d.tolist() == [0.0, 5.0]


def test_standing_still_the_history_stays_bounded():
    # at a standstill no sample is ever W behind: the history grew by one sample a step
    # (150 s at 100 Hz: 15,000 samples, 34-50 ms a step in the node)
    history = CurvatureHistory(W)
    for _ in range(3 * MAX_SAMPLES):
        history.record(0.0, 0.01, -0.001)
    assert history.size == MAX_SAMPLES
    batch = CurvatureHistory(W)                 # one run stopped, one at 37 m/s
    for _ in range(3 * MAX_SAMPLES):
        batch.record(np.array([0.0, 37.0]), 0.01, np.array([-0.001, 0.002]))
    assert batch.size == MAX_SAMPLES
    law = CgCompensatedLaw(load_vehicle(None), load_controller(None), LaneKeepingParams())
    for _ in range(2 * MAX_SAMPLES):
        law.step(_state(0.0, v=0.0), Preview(D, np.zeros(D.size)), 0.01)
    assert law._history.size == MAX_SAMPLES


def test_a_restarted_run_of_a_batch_is_its_single_run_restarted():
    # a non-finite output restarts one run of a batch: its old samples were NaN and the
    # window behind fell back to the polygon's first value, while the single run, cleared,
    # held the curvature where it restarted (5.7e-5 to 1.8e-4 rad apart for 5 steps)
    vehicle, controller = load_vehicle(None), load_controller(None)
    speeds = np.array([37.0, 30.0])
    batch = CgCompensatedLaw(vehicle, controller, LaneKeepingParams())
    singles = [CgCompensatedLaw(vehicle, controller, LaneKeepingParams()) for _ in speeds]
    s = np.array([80.0, 80.0])
    for i in range(300):
        s = s + speeds * 0.01
        y = np.array([np.nan if i == 150 else 0.01, 0.01])
        rho = np.where(s >= 100.0, -0.0025, 0.0)
        ahead = np.where(s[None, :] + D[:, None] >= 100.0, -0.0025, 0.0)
        # (dev-probe60: the curvature measured at the CG 0.001 off the polygon's: the
        # restarted run's old samples took the new measurement, its single run held the
        # polygon's first value back: 2e-2 rad apart on the step after)
        rho = rho + 0.001
        state = LateralState(y_cg=y, eps_r=0 * y, v_y=0 * y, r=0 * y, v_x=speeds,
                             a_x=0 * y, rho=rho, rho_rate=0 * y)
        out = batch.step(state, Preview(D, ahead), 0.01)
        for j, law in enumerate(singles):
            one = law.step(LateralState(y_cg=float(y[j]), eps_r=0.0, v_y=0.0, r=0.0,
                                        v_x=float(speeds[j]), a_x=0.0, rho=float(rho[j]),
                                        rho_rate=0.0), Preview(D, ahead[:, j]), 0.01)
            if np.isfinite(one.steering):
                assert out.steering[j] == pytest.approx(one.steering, rel=1e-9, abs=1e-12)
            else:
                assert not np.isfinite(out.steering[j])


# -- dev-probe60 -------------------------------------------------------------------------

def test_a_polygon_a_billion_metres_off_is_averaged_without_rounding_away():
    # the integrals ran from the road's first breakpoint: a polygon starting 1e9 m ahead
    # (the history about the CG) or 1e9 m behind lost the curvature to rounding (0.2 read
    # as 16 at W 1; the node sent -0.00143 rad for 0.00885 at 25 m/s): a constant road
    # is constant
    history = CurvatureHistory(5.0)
    for _ in range(100):
        history.record(10.0, 0.005, 0.2)
    for start in (1e8, 1e10, 1e12, 3e38):
        for width in (1.0, 5.0, 50.0):
            history.half_width = width
            _, out = smoothed_preview(np.array([start, start * (1 + 1e-7) + 10.0]),
                                      np.array([0.2, 0.2]), width, history, reach=50.0)
            assert out == pytest.approx(np.full(out.size, 0.2), abs=1e-12)
    _, out = smoothed_preview(np.array([-1e9, -1e6, 0.0, 5.0, 95.0]), np.full(5, 0.002),
                              1.0, reach=2.6)
    assert out == pytest.approx(np.full(out.size, 0.002), abs=1e-15)
    vehicle, controller = load_vehicle(None), load_controller(None)
    steering = []
    for width in (0.0, 5.0):
        law = CgCompensatedLaw(vehicle, controller,
                               LaneKeepingParams(curvature_smoothing=width))
        arc = LateralState(0.0, 0.0, 0.0, 0.0, 20.0, 0.0, 0.01, 0.0)
        for _ in range(50):
            out_law = law.step(arc, Preview(np.array([1e9, 1e9 + 10.0]), np.full(2, 0.01)),
                               0.01)
        steering.append(out_law.steering)
    assert steering[1] == pytest.approx(steering[0], rel=1e-9)


def test_a_polygon_behind_the_cg_is_averaged_at_the_cg():
    # it was averaged at its last point (0.00907 where the road at the CG averages to
    # 0.00953), and the law held that ahead. Since dev-probe90 the road behind the CG is
    # the road driven (0.01 here), the polygon's value at the CG held ahead: 0.01
    history = CurvatureHistory(W)
    for _ in range(100):
        history.record(10.0, 0.01, 0.01)
    d, k = np.array([-10.0, -1.0]), np.array([0.0, 0.01])
    out_d, out_k = smoothed_preview(d, k, W, history, reach=2.6)
    assert out_d[0] == 0.0 and out_d[-1] > 2.6
    assert out_k == pytest.approx(np.full(out_k.size, 0.01), abs=1e-15)


def test_a_polygon_s_points_behind_the_cg_are_not_the_road_driven():
    # dev-probe90: a bridge's polygon (-50 m, 0.19), (0, 1/400), (20 m, 1/400) on a 400 m
    # curve: the window behind the CG read the ramp to 0.19, the average's slope at the
    # CG swung the default law's command to -0.039 rad (0.0136 on the curve)
    rho = 1.0 / 400.0
    history = CurvatureHistory(W)
    for _ in range(100):
        history.record(30.0, 0.01, rho)
    d, k = np.array([-50.0, 0.0, 20.0]), np.array([0.19, rho, rho])
    out_d, out_k = smoothed_preview(d, k, W, history, reach=12.0)
    assert out_d[0] == 0.0 and np.all(out_k == rho)
    # a point behind between two ahead: the polygon's value at the CG, then its points
    d, k = np.array([-3.0, 2.0, 20.0]), np.array([0.19, 0.0, 0.0])
    trimmed = smoothed_preview(np.array([0.0, 2.0, 20.0]),
                               np.array([0.19 * 2.0 / 5.0, 0.0, 0.0]), W, history, 12.0)
    got = smoothed_preview(d, k, W, history, 12.0)
    np.testing.assert_array_equal(got[0], trimmed[0])
    np.testing.assert_allclose(got[1], trimmed[1], rtol=1e-12, atol=1e-17)
    # the law: the command of the polygon with the point behind is that without it
    commands = []
    for points in (np.array([-50.0, 0.0, 20.0, 40.0]), np.array([0.0, 20.0, 40.0])):
        curvatures = np.where(points < 0.0, 0.19, rho)
        law = CgCompensatedLaw(load_vehicle(None), load_controller(None),
                               LaneKeepingParams())
        eps = -0.0132                    # the steady relative yaw at 30 m/s on it
        state = LateralState(y_cg=0.0, eps_r=eps, v_y=0.0, r=30.0 * rho, v_x=30.0,
                             a_x=0.0, rho=rho, rho_rate=0.0)
        for _ in range(50):
            out = law.step(state, Preview(points, curvatures), 0.01)
        commands.append(out.steering)
    assert commands[0] == commands[1] and commands[0] > 0.0, commands


def test_reach_not_finite_is_the_polygon_s_end_within_a_bound():
    d, k = np.array([0.0, 5.0, 3e38]), np.full(3, -0.002)
    for reach in (math.nan, math.inf, -math.inf):
        out_d, out_k = smoothed_preview(d, k, W, reach=reach)
        assert out_d.size <= MAX_OUTPUT + 2 and out_d[-1] == 3e38
    law = CgCompensatedLaw(load_vehicle(None), load_controller(None), LaneKeepingParams())
    fast = LateralState(0.0, 0.0, 0.0, 0.0, 1e30, 0.0, -0.002, 0.0)
    law.step(fast, Preview(d, k), 0.01)     # a reach of 7e28 m: no grid to match


def test_a_stopped_run_keeps_the_batch_s_road_short():
    # a stopped run keeps every sample (none is W behind it): every run's road was 1024
    # samples long, 44 ms a step for 96 runs (384 ms with W 1 and a 3 s preview)
    history = CurvatureHistory(W)
    speeds = np.full(96, 30.0)
    speeds[7] = 0.0
    for _ in range(MAX_SAMPLES + 100):
        history.record(speeds, 0.01, np.full(96, 0.001))
    assert history.size == MAX_SAMPLES
    k = np.full((D.size, 96), 0.001)
    x, _ = curvature_smoothing._road(D, k, curvature_smoothing._behind(history, 96), -W)
    assert x.shape[0] <= W / 0.3 + 2 + D.size
    _, out = smoothed_preview(D, k, W, history, reach=2.6)
    assert out == pytest.approx(np.full(out.shape, 0.001), abs=1e-15)
