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

"""The speed's scale check (``core/speed_check.py``) and the controller's answer to it."""

from __future__ import annotations

import math
from typing import Callable, Optional

from lookahead_control.core.params import ParameterError
from lookahead_control.core.samples import LateralErrorSample, VelocitySample, YawSample
from lookahead_control.core.speed_check import SpeedCheck, SpeedCheckParams
import numpy as np
import pytest
from sim_plant.closed_loop_sim import measure
from sim_plant.road import Road, Segment
# the core with the linear plant on the map check's S-bend, and the map of the road
from test_map_fallback import _core_on_s_bend, _map

PERIOD = 0.01
AHEAD = np.arange(0.0, 50.01, 5.0)      # path_bridge's default preview


def _s_bend(v: float, acceleration: float) -> Road:
    """Return the map check's S-bend at ``acceleration`` laid out for ``v``."""
    k = acceleration / v ** 2
    return Road([Segment('straight', 2 * v), Segment('clothoid', 1.5 * v, 0.0, k),
                 Segment('arc', 3 * v, k, k), Segment('clothoid', 2 * v, k, -k),
                 Segment('arc', 3 * v, -k, -k), Segment('clothoid', 1.5 * v, -k, 0.0),
                 Segment('straight', 6 * v)])


def _drive(road: Road, v: float, factor: float = 1.0, seconds: float = 14.0,
           map_noise: float = 0.0, speed_noise: float = 0.05, lag: float = 0.0,
           curvature_scale: float = 1.0,
           preview: Optional[Callable[[float, np.ndarray], np.ndarray]] = None,
           seed: int = 4) -> tuple[SpeedCheck, float, Optional[float]]:
    """
    Drive along ``road`` at ``v`` and step the check with the speed times ``factor``.

    :param map_noise: white noise on each preview point [1/m].
    :param speed_noise: white noise on the speed [m/s].
    :param lag: the preview's latency [s].
    :param curvature_scale: the map's factor on the curvature.
    :param preview: ``(time, preview) -> preview`` sent instead (None: as it is).
    :return: the check, the longest it was out of scale [s], and when it told (None:
        never); the check's ``ratio`` is set to the one it told at.
    """
    rng = np.random.default_rng(seed)
    check = SpeedCheck()
    longest, told, ratio = 0.0, None, math.nan
    for k in range(1, int(round(seconds / PERIOD))):
        t = k * PERIOD
        points = curvature_scale * np.asarray(road.curvature(v * (t - lag) + AHEAD)[0])
        points = points + rng.normal(0.0, map_noise, AHEAD.size) if map_noise else points
        if preview is not None:
            points = preview(t, points)
        measured = factor * v + rng.normal(0.0, speed_noise)
        out = check.step(PERIOD, measured, int(round(t * 1e9)),
                         list(zip(AHEAD.tolist(), points.tolist())))
        longest = max(longest, check.off_for)
        if out and told is None:
            told, ratio = t, check.ratio
    if told is not None:
        check.ratio = ratio
    return check, longest, told


@pytest.mark.parametrize('v', [6.0, 12.0, 19.0])
@pytest.mark.parametrize('factor', [3.6, 2.237, 1.0 / 3.6])
def test_a_speed_in_other_units_is_told_on_a_winding_road(v, factor):
    # dev-sc47: a speed in km/h stays under safety.max_speed up to 19.4 m/s and put the
    # default law 0.3-26 m off S-bends, told only as a map disagreeing
    check, _, told = _drive(_s_bend(v, 1.0), v, factor)
    assert told is not None and told < 6.0, (told, check.ratio)
    assert check.ratio == pytest.approx(factor, rel=0.15)
    assert check.scale == pytest.approx(factor, rel=0.15)


@pytest.mark.parametrize('v', [6.0, 12.0, 19.0, 30.0, 37.0])
@pytest.mark.parametrize('acceleration', [1.0, 3.0])
@pytest.mark.parametrize('factor', [1.0, 1.1, 0.9])
def test_a_right_speed_is_not_told(v, acceleration, factor):
    # within a factor of 1.5 the speed fits (a speed 10 % off is not found here)
    check, longest, told = _drive(_s_bend(v, acceleration), v, factor, map_noise=1e-4)
    assert told is None and longest <= 0.5, (longest, check.ratio)


@pytest.mark.parametrize('case', [{'map_noise': 1e-3}, {'lag': 0.5}, {'lag': -0.5},
                                  {'curvature_scale': 2.0}, {'curvature_scale': 0.5},
                                  {'curvature_scale': -1.0}, {'speed_noise': 1.0}])
def test_a_map_off_in_curvature_time_or_noise_is_no_speed_fault(case):
    # the map check's faults (scale, latency, noise) move both previews alike
    check, longest, told = _drive(_s_bend(15.0, 2.0), 15.0, **case)
    assert told is None and longest <= 0.5, (longest, check.ratio)


def test_a_periodic_road_fits_the_right_speed():
    # S-bends 40 m long: a shift and that shift plus 40 m fit alike
    k = 0.01
    road = Road([Segment('straight', 20.0)] + [
        Segment('clothoid', 10.0, a, b) for _ in range(30)
        for a, b in ((0.0, k), (k, 0.0), (0.0, -k), (-k, 0.0))])
    check, longest, told = _drive(road, 12.0, map_noise=1e-4)
    assert told is None and longest <= 0.5, (longest, check.ratio)
    assert not math.isnan(check.ratio)          # judged
    assert _drive(road, 12.0, 3.6, map_noise=1e-4)[2] is not None


@pytest.mark.parametrize('road', [
    Road([Segment('straight', 500.0)]),
    Road([Segment('arc', 500.0, 0.01, 0.01)])])
def test_a_road_that_does_not_change_is_no_evidence(road):
    check, longest, told = _drive(road, 10.0, 3.6, map_noise=1e-5)
    assert told is None and longest == 0.0 and math.isnan(check.ratio)


def test_a_preview_that_does_not_move_is_told():
    # a bridge repeating one preview with new stamps: the road saw no travel
    held: dict[str, np.ndarray] = {}

    def frozen(t: float, points: np.ndarray) -> np.ndarray:
        if t >= 3.0:
            return held.setdefault('points', points)
        return points

    check, _, told = _drive(_s_bend(15.0, 1.0), 15.0, preview=frozen)
    assert told is not None and told < 5.5 and math.isinf(check.ratio)


def test_a_preview_in_feet_is_told():
    # distances 3.28 times too large: the road moves 3.28 times as far under the speed
    road = _s_bend(12.0, 1.0)

    def feet(t: float, points: np.ndarray) -> np.ndarray:
        return np.asarray(road.curvature(12.0 * t + AHEAD / 3.28)[0])

    check, _, told = _drive(road, 12.0, preview=feet)
    assert told is not None and check.ratio == pytest.approx(1.0 / 3.28, rel=0.1)


def test_restarts_and_inputs_without_evidence():
    check = SpeedCheck()
    preview = [(float(d), 0.01 * math.sin(d / 8.0)) for d in AHEAD]
    for k in range(600):            # a km/h-like speed, the preview never moving
        check.step(PERIOD, 15.0, k * 10_000_000, preview)
    assert check.out_of_scale
    for bad in (math.nan, math.inf):
        again = SpeedCheck()
        again.off_for = 5.0
        assert not again.step(PERIOD, bad, 1, preview) and again.off_for == 0.0
    for dt in (-0.01, 1.5, math.nan):       # a gap, the clock back: a restart
        again = SpeedCheck()
        again.off_for = 5.0
        assert not again.step(dt, 15.0, 1, preview) and again.off_for == 0.0
    slow = SpeedCheck()
    slow.off_for = 5.0
    assert not slow.step(PERIOD, 0.5, 1, preview) and slow.off_for == 0.0
    # fewer than three points, a point not finite, an old stamp: nothing new
    kept = SpeedCheck()
    kept.off_for = 5.0
    assert kept.step(PERIOD, 15.0, 1, preview[:2])
    assert kept.step(PERIOD, 15.0, 2, preview[:2] + [(60.0, math.nan)])
    assert kept.step(PERIOD, 15.0, 3, preview) and kept.step(PERIOD, 15.0, 3, preview)
    assert len(kept._previews) == 1


@pytest.mark.parametrize('field, value', [
    ('travel', 0.0), ('max_age', 0.0), ('min_overlap', -1.0), ('excitation', 0.0),
    ('misfit', -0.1), ('contrast', 0.5), ('limit', 1.0), ('hold', -1.0),
    ('min_speed', -1.0), ('every', math.nan)])
def test_settings_out_of_range_are_refused_by_name(field, value):
    with pytest.raises(ParameterError, match=f'speed_check.{field}'):
        SpeedCheckParams(**{field: value})


def _core_loop(factor: float, v: float, acceleration: float) -> dict[str, float]:
    """
    Run the default law's core and the linear plant on the S-bend with the speed x ``factor``.

    :return: the seconds told, the ratio seen, and the peak CG error [m].
    """
    scenario, core, stepper, substeps, n_steps, rng = _core_on_s_bend('cg_compensated', v,
                                                                      acceleration)
    x = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    peak = 0.0
    for k in range(n_steps):
        t = k * PERIOD
        stamp = int(round(t * 1e9))
        inputs = measure(x, t, scenario, v, 0.0)
        core.accept('yaw', YawSample(stamp, x[2] + rng.normal(0.0, 0.002),
                                     x[4] + rng.normal(0.0, 0.002),
                                     float(inputs.a_x) - x[3] * x[4]), stamp)
        core.accept('velocity', VelocitySample(stamp, factor * float(inputs.v_x), x[3]),
                    stamp)
        core.accept('road_curvature', _map(stamp, scenario, x[0]), stamp)
        core.accept('lateral_error', LateralErrorSample(stamp, 0.0,
                                                        x[1] + rng.normal(0.0, 0.03)), stamp)
        command = core.compute(stamp)
        peak = max(peak, abs(x[1]))
        x = stepper(x, t, 0.002, substeps, command.steering)
    return {'told': core.turning['speed_out_of_scale'], 'seen': core.speed_seen, 'peak': peak}


@pytest.mark.parametrize('v', [10.0, 19.0])
def test_the_core_tells_a_speed_in_km_h(v):
    # before: 0.61 / 1.24 m off the S-bend at 10 / 19 m/s and no word of the speed
    run = _core_loop(3.6, v, 1.0)
    assert run['told'] > 3.0 and run['seen'] == pytest.approx(3.6, rel=0.15), run
    right = _core_loop(1.0, v, 1.0)
    assert right['told'] == 0.0 and right['seen'] == 1.0, right


def test_the_node_warns_of_a_speed_out_of_scale_once(active_controller):
    from diagnostic_msgs.msg import DiagnosticStatus
    node = active_controller
    assert 'v_x out of scale' not in node.diagnostics().message
    node.core.turning['speed_out_of_scale'] += 1.3
    node.core.speed_seen = 3.6
    status = node.diagnostics()
    assert status.level == DiagnosticStatus.WARN
    assert ('v_x out of scale with the curvature preview for 1.30 s (the speed moved the '
            'car 3.6 times as far as the road moved under it): a speed in other units (km/h'
            in status.message)
    assert 'v_x out of scale' not in node.diagnostics().message      # told once
    node.core.turning['speed_out_of_scale'] += 0.2
    node.core.speed_seen = math.inf
    assert '(the preview did not move)' in node.diagnostics().message
