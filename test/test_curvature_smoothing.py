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

from lookahead_control.core.config import load_controller, load_lane_keeping, load_vehicle
from lookahead_control.core.control_law import LateralState
from lookahead_control.core.curvature_smoothing import CurvatureHistory, smoothed_preview
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


def triangle_average(x: float, road, half_width: float = W) -> float:
    """Average ``road`` around ``x`` by the triangular window, by fine integration."""
    u = np.linspace(-half_width, half_width, 20001)
    weight = (half_width - np.abs(u)) / half_width ** 2
    return float(np.trapezoid(weight * road(x + u), u))


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
        if x >= W:
            assert k == pytest.approx(triangle_average(x, lambda s: np.interp(s, D, STEP)),
                                      abs=0.005 * 0.0025)
    assert np.interp(7.5, out_d, out_k) == pytest.approx(-0.00125, abs=1e-9)
    assert np.all(np.diff(out_k) <= 1e-15)
    assert out_k[out_d <= 0.0] == pytest.approx(0.0, abs=1e-15)
    assert out_k[out_d >= 15.0] == pytest.approx(-0.0025, abs=1e-15)
    # the steepest slope the law reads: the ramp's (0.0025 / 5 m) times the share of
    # the window on the ramp at its centre, 1 - 2 (1/2) (2.5 / 5)^2 = 0.75
    assert np.max(np.abs(np.diff(out_k) / np.diff(out_d))) == pytest.approx(
        0.75 * 0.0025 / 5.0, rel=1e-9)


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
    # within 5 % of the step: the window is summed on W / 8 steps, and a step in the
    # road driven is one within a sample (0.185 m): a discontinuity in the sum
    assert out_k[0] == pytest.approx(triangle_average(s, road), abs=0.05 * 0.0025)
    assert -0.0025 < out_k[0] < -0.0015             # the step behind still counts
    # without the road behind, the curvature at the CG is held behind it: the full step
    assert smoothed_preview(D, ahead, W)[1][0] == pytest.approx(-0.0025)
    # the history keeps what the window reaches, not the whole drive
    assert len(history.samples) <= W / (v * dt) + 2
    assert history.samples[0][0] <= history.travelled - W


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
    kept = law._history.samples[0][1]
    assert len(law._history.samples) > 10 and kept == 0.0
    retuned = CgCompensatedLaw(vehicle, controller, LaneKeepingParams(natural_frequency=6.5))
    retuned.reset()
    carried, _ = retuned.take_over(law)
    assert 'curvature behind the CG' in carried
    assert len(retuned._history.samples) == len(law._history.samples)
    law.step(_state(s), Preview(D, np.full(D.size, -0.0025)), 1.0)     # beyond max_gap
    assert len(law._history.samples) == 1 and law._history.samples[0][1] == -0.0025


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
