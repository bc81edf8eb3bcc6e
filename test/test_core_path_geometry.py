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
The path geometry core against analytic geometry, and the road's global geometry.

Tolerances come from the fit (half-window h, cubic least squares): on a circle of radius
R the even term u^4 / (8 R^3) of the centreline leaks into the fit's constant and
quadratic terms, biasing the lateral error by at most 3 h^4 / (280 R^3) and the curvature
by 3 h^2 / (14 R^3); on a clothoid the same with R = 1 / max |curvature|.
"""

import math

from lookahead_control.core.path_geometry import (cg_pose, drop_duplicates, PathError,
                                                  PathFollower, PathParams, ReferencePath,
                                                  three_point_curvature, wrap_angle)
import numpy as np
import pytest
from scipy.special import fresnel
from sim_plant.road import Road, Segment

H = PathParams().fit_half_window


def lateral_bound(radius):
    return 3.0 * H ** 4 / (280.0 * abs(radius) ** 3) + 1e-9


def curvature_bound(radius):
    return 3.0 * H ** 2 / (14.0 * abs(radius) ** 3) + 1e-9


def circle(radius, spacing, angle=1.5 * math.pi):
    """Points of a circle from the origin heading +x, turning left for radius > 0."""
    theta = np.arange(0.0, angle * abs(radius), spacing) / abs(radius)
    return np.c_[abs(radius) * np.sin(theta), radius * (1.0 - np.cos(theta))]


def drive(follower, road, s_values, lateral, relative_yaw, period=0.01, speed=20.0):
    out = []
    for k, s in enumerate(s_values):
        x, y, yaw = road.global_pose(s, lateral, relative_yaw)
        out.append(follower.locate(k * int(period * 1e9), x, y, yaw, speed, 0.0))
    return out


# -- the road's global geometry ---------------------------------------------------------

def test_road_pose_of_arcs_and_clothoids_against_closed_forms():
    road = Road([Segment('straight', 10.0), Segment('arc', 100.0, 0.02, 0.02),
                 Segment('clothoid', 50.0, 0.0, -0.01)])
    assert road.pose(5.0) == pytest.approx((5.0, 0.0, 0.0), abs=1e-12)
    # the arc: centre (10, 50), radius 50
    for u in (0.0, 30.0, 100.0):
        x, y, heading = road.pose(10.0 + u)
        assert (x, y) == pytest.approx((10.0 + 50.0 * math.sin(u / 50.0),
                                        50.0 - 50.0 * math.cos(u / 50.0)), abs=1e-9)
        assert heading == pytest.approx(u / 50.0, abs=1e-12)
    # the clothoid from curvature 0 with sharpness c = -0.01 / 50: Fresnel integrals
    x0, y0, h0 = road.pose(110.0)
    c = 0.01 / 50.0
    for u in (10.0, 50.0):
        f_s, f_c = fresnel(u * math.sqrt(c / math.pi))
        along, left = math.sqrt(math.pi / c) * f_c, -math.sqrt(math.pi / c) * f_s
        x, y, heading = road.pose(110.0 + u)
        assert x == pytest.approx(x0 + along * math.cos(h0) - left * math.sin(h0), abs=1e-9)
        assert y == pytest.approx(y0 + along * math.sin(h0) + left * math.cos(h0), abs=1e-9)
        assert heading == pytest.approx(h0 - 0.5 * c * u * u, abs=1e-12)
    # past the end: the last curvature continues (-0.01 here); before the start: straight
    x1, y1, h1 = road.pose(road.length)
    x, y, heading = road.pose(road.length + 10.0)
    assert heading == pytest.approx(h1 - 0.1)
    assert math.hypot(x - x1, y - y1) == pytest.approx(200.0 * math.sin(0.05), abs=1e-9)
    assert road.pose(-3.0) == pytest.approx((-3.0, 0.0, 0.0))


def test_road_sample_and_global_pose():
    road = Road([Segment('arc', 100.0, -0.01, -0.01)])
    points = road.sample(10.0, 3.0)
    assert points[:, 0] == pytest.approx([100 * math.sin(s / 100) for s in (0, 3, 6, 9, 10)])
    x, y, yaw = road.global_pose(0.0, 1.5, 0.1)
    assert (x, y, yaw) == pytest.approx((0.0, 1.5, 0.1))
    with pytest.raises(ValueError, match='path_spacing'):
        road.sample(10.0, 0.0)


# -- analytic geometry --------------------------------------------------------------------

@pytest.mark.parametrize('heading', [0.0, 0.5, -2.8])
@pytest.mark.parametrize('lateral', [0.8, -0.8])
def test_straight(heading, lateral):
    road = Road([Segment('straight', 200.0)])
    points = road.sample(200.0, 0.5)
    c, s = math.cos(heading), math.sin(heading)
    rotated = np.c_[points[:, 0] * c - points[:, 1] * s, points[:, 0] * s + points[:, 1] * c]
    follower = PathFollower(ReferencePath(rotated))
    for k, along in enumerate((20.0, 20.37, 150.2)):
        x = along * c - lateral * s
        y = along * s + lateral * c
        lane = follower.locate(k, x, y, heading + 0.1)
        assert lane.s == pytest.approx(along, abs=1e-9)
        assert lane.lateral_error == pytest.approx(lateral, abs=1e-9)
        assert lane.relative_yaw == pytest.approx(0.1, abs=1e-12)
        assert lane.curvature == pytest.approx(0.0, abs=1e-9)
        assert lane.remaining == pytest.approx(200.0 - along, abs=1e-9)


@pytest.mark.parametrize('radius', [400.0, 50.0, -50.0, -400.0])
@pytest.mark.parametrize('spacing', [0.5, 2.0])
@pytest.mark.parametrize('lateral', [0.7, -0.7])
def test_circle(radius, spacing, lateral):
    follower = PathFollower(ReferencePath(circle(radius, spacing)))
    road = Road([Segment('arc', 1000.0, 1.0 / radius, 1.0 / radius)])
    lanes = drive(follower, road, np.linspace(20.0, 200.0, 60), lateral, -0.05)
    for s, lane in zip(np.linspace(20.0, 200.0, 60), lanes):
        # distance along the path is the polyline's: each chord is short of its arc by
        # spacing^3 / (24 R^2)
        assert lane.s == pytest.approx(s, abs=s * spacing ** 2 / (24 * radius ** 2) + 1e-6)
        assert lane.lateral_error == pytest.approx(lateral, abs=lateral_bound(radius))
        # between vertices the heading is a blend of two fits, each off by the curvature
        # bias over at most one spacing
        assert lane.relative_yaw == pytest.approx(-0.05, abs=curvature_bound(radius) * spacing)
        assert lane.curvature == pytest.approx(1.0 / radius, abs=curvature_bound(radius))


@pytest.mark.parametrize('sign', [1.0, -1.0])
def test_clothoid(sign):
    road = Road([Segment('clothoid', 200.0, 0.0, sign * 0.02)])
    follower = PathFollower(ReferencePath(road.sample(200.0, 0.5)[:, :2]))
    s_values = np.linspace(10.0, 190.0, 50)
    lanes = drive(follower, road, s_values, 0.4 * sign, 0.02)
    radius = 1.0 / 0.02
    for s, lane in zip(s_values, lanes):
        assert lane.curvature == pytest.approx(road.curvature(s)[0], abs=curvature_bound(radius))
        assert lane.lateral_error == pytest.approx(0.4 * sign, abs=lateral_bound(radius))
        assert lane.relative_yaw == pytest.approx(0.02, abs=1e-5)
        assert lane.heading == pytest.approx(wrap_angle(road.pose(s)[2]), abs=1e-5)


def test_s_curve_is_exact_away_from_the_joins_and_never_overshoots_at_them():
    road = Road([Segment('straight', 30.0), Segment('arc', 60.0, 0.02, 0.02),
                 Segment('clothoid', 20.0, 0.02, -0.02), Segment('arc', 60.0, -0.02, -0.02)])
    path = ReferencePath(road.sample(road.length, 1.0)[:, :2])
    joins = (30.0, 90.0, 110.0)
    s = np.arange(0.0, road.length, 0.25)
    fitted = np.array([path.curvature(v) for v in s])
    true = road.curvature(s)[0]
    far = np.array([min(abs(v - j) for j in joins) > H + 1.0 for v in s])
    assert np.max(np.abs(fitted - true)[far]) <= curvature_bound(50.0)
    # at a step the fit rounds the corner: it stays within the neighbouring curvatures
    assert np.max(np.abs(fitted)) <= 0.02 * 1.05
    follower = PathFollower(path)
    lanes = drive(follower, road, np.arange(5.0, 165.0, 0.4), -0.3, 0.0)
    errors = np.array([lane.lateral_error for lane in lanes])
    # near a curvature step d_rho the fit rounds the corner: a cubic least-squares fit of
    # d_rho max(u, 0)^2 / 2 on [-h, h] is off by up to 0.0104 d_rho h^2 (continuous
    # window; x1.5 for the 11-point window and the blend between vertices)
    assert np.max(np.abs(errors + 0.3)) < 1.5 * 0.0104 * 0.02 * H ** 2


def test_noisy_points_do_not_make_curvature_spikes():
    rng = np.random.default_rng(7)
    sigma, spacing, radius = 0.005, 0.5, 400.0
    points = circle(radius, spacing, angle=0.75)
    noisy = points + rng.normal(0.0, sigma, points.shape)
    path = ReferencePath(noisy)
    fitted = np.array([path.curvature(v) for v in np.linspace(10.0, 280.0, 500)]) - 1 / radius
    count = 2 * H / spacing + 1
    predicted = 6.7 * sigma / (H ** 2 * math.sqrt(count))     # module docstring
    assert np.std(fitted) < 1.3 * predicted
    assert np.max(np.abs(fitted)) < 4.0 * predicted
    # the naive three-point curvature of the same points: spikes 100 times larger
    assert np.max(np.abs(three_point_curvature(noisy) - 1 / radius)) > 50 * np.max(
        np.abs(fitted))


# -- search: loops, hairpins, long paths, jumps ---------------------------------------------

def test_a_loop_driven_twice_keeps_its_lap():
    # the same circle twice: every point of lap 1 lies on lap 2
    points = circle(30.0, 0.5, angle=4.0 * math.pi)
    follower = PathFollower(ReferencePath(points))
    road = Road([Segment('arc', 1000.0, 1 / 30.0, 1 / 30.0)])
    s_values = np.arange(0.0, 1.6 * 2 * math.pi * 30.0, 0.3)
    lanes = drive(follower, road, s_values, 0.2, 0.0)
    # the polyline's length: each 0.5 m chord is short of its arc by 0.5^3 / (24 R^2)
    # (the first h metres have one-sided fit windows: less exact, checked elsewhere)
    inner = s_values >= H
    assert [lane.s for lane, keep in zip(lanes, inner) if keep] == pytest.approx(
        list(s_values[inner] * (1 - 0.5 ** 2 / (24 * 30.0 ** 2))), abs=1e-6)


def test_a_hairpin_does_not_swap_branches():
    # out along y = 0, a U-turn of radius 2 m, back along y = 4
    road = Road([Segment('straight', 30.0), Segment('arc', 2.0 * math.pi, 0.5, 0.5),
                 Segment('straight', 30.0)])
    follower = PathFollower(ReferencePath(road.sample(road.length, 0.25)[:, :2]))
    # 2.6 m left of the way out: 1.4 m from the way back, which points the other way
    lanes = drive(follower, road, np.arange(0.0, 25.0, 0.3), 2.6, 0.0)
    assert all(lane.lateral_error == pytest.approx(2.6, abs=1e-9) for lane in lanes)


def test_a_long_path_is_searched_near_the_last_match_only():
    road = Road([Segment('straight', 74.0), Segment('arc', 5000.0, -0.0025, -0.0025)])
    path = ReferencePath(road.sample(5000.0, 0.5)[:, :2])
    assert path.size == 10_001
    windows = []
    search = path.nearest_segment

    def spy(x, y, heading, lo_s=-math.inf, hi_s=math.inf, **kw):
        windows.append(hi_s - lo_s)
        return search(x, y, heading, lo_s, hi_s, **kw)

    path.nearest_segment = spy
    follower = PathFollower(path)
    s_values = np.arange(0.0, 4000.0, 0.37)
    lanes = drive(follower, road, s_values, 0.1, 0.0, speed=37.0)
    assert lanes[-1].s == pytest.approx(s_values[-1], abs=1e-3)
    # two searches for the first match (whole path, then around it), then windows of
    # 2 (search_distance + distance driven) metres: at most 43 segments of 0.5 m
    assert math.isinf(windows[0])
    assert max(windows[1:]) <= 2 * (10.0 + 0.371)


def test_a_relocalization_jump_rematches_and_says_so():
    road = Road([Segment('straight', 500.0)])
    follower = PathFollower(ReferencePath(road.sample(500.0, 1.0)[:, :2]))
    drive(follower, road, [100.0, 100.2], 0.0, 0.0)
    lane = follower.locate(20_000_000, 105.4, 0.3, 0.0, 20.0, 0.0)   # 5 m ahead of 100.4
    assert lane.s == pytest.approx(105.4) and lane.lateral_error == pytest.approx(0.3)
    assert 'jumped 5.01 m' in lane.note and 'was 100.20 m' in lane.note
    assert follower.rematches == 1
    # a jump of 30 m (further than the search window): found all the same
    lane = follower.locate(30_000_000, 135.6, 0.0, 0.0, 20.0, 0.0)
    assert lane.s == pytest.approx(135.6) and 'jumped' in lane.note
    back = follower.locate(10_000_000, 135.8, 0.0, 0.0, 20.0, 0.0)
    assert 'time went back' in back.note and back.s == pytest.approx(135.8)


def test_a_relocalization_on_a_loop_prefers_the_lap_it_was_on():
    points = circle(30.0, 0.5, angle=4.0 * math.pi)
    follower = PathFollower(ReferencePath(points))
    road = Road([Segment('arc', 1000.0, 1 / 30.0, 1 / 30.0)])
    lap = 2 * math.pi * 30.0
    s_values = np.arange(0.0, lap + 12.0, 0.3)
    drive(follower, road, s_values, 0.0, 0.0)
    x, y, yaw = road.global_pose(lap + 20.0, 0.0, 0.0)          # 8 m further: a jump
    lane = follower.locate(len(s_values) * 10_000_000, x, y, yaw, 20.0, 0.0)
    assert 'jumped' in lane.note
    assert lane.s == pytest.approx(lap + 20.0, abs=0.02)        # lap 2, not lap 1


# -- bad paths and poses ----------------------------------------------------------------------

@pytest.mark.parametrize('points, message', [
    ([], 'the path is empty'),
    ([(1.0, 2.0)], 'has 1 distinct point'),
    ([(1.0, 2.0)] * 5, r'has 1 distinct point\(s\) \(5 given\)'),
    ([(0.0, 0.0), (float('nan'), 1.0), (2.0, 0.0)], 'path point 1 is not finite'),
    ([(0.0, 0.0), (1.0, float('inf'))], 'path point 1 is not finite'),
])
def test_unusable_paths_are_refused_with_the_reason(points, message):
    with pytest.raises(PathError, match=message):
        ReferencePath(points)


def test_duplicates_are_dropped_and_a_cusp_ends_the_path():
    path = ReferencePath([(0, 0), (0, 0), (1, 0), (2, 0), (2, 0), (3, 0)])
    assert path.duplicates == 2 and path.size == 4 and path.length == 3.0
    assert path.cusp_at is None
    # forward to x = 3, then back (a reversing manoeuvre): only the forward part is used
    path = ReferencePath([(0, 0), (1, 0), (2, 0), (3, 0), (2, 0.1), (1, 0.1)])
    assert path.cusp_at == pytest.approx(3.0) and path.length == pytest.approx(3.0)


def test_a_duplicate_is_judged_against_the_last_point_kept():
    # dev-probe92: (0, 0), (9e-5, 0), (1.8e-4, 0), (0, 0) at the default 1e-4 m kept the
    # second (0, 0) next to the first (each dropped point within 1e-4 m of the one given
    # before it): a segment of length 0, direction 0 / 0; a car facing against the path
    # raised ValueError (argmin of nothing) or got NaN offsets
    points = [(0.0, 0.0), (0.9e-4, 0.0), (1.8e-4, 0.0), (0.0, 0.0)]
    points += [(float(i), 0.0) for i in range(1, 60)]
    path = ReferencePath(points)
    assert path.duplicates == 3 and path.size == 60 and np.all(path.seg_length > 1e-4)
    follower = PathFollower(path)
    with pytest.raises(PathError, match='faces against the path'):
        follower.locate(0, 5.0, 0.2, math.pi)
    place = follower.locate(10_000_000, 5.0, 0.2, 0.0)
    assert place.s == pytest.approx(5.0) and place.lateral_error == pytest.approx(0.2)
    with pytest.raises(PathError, match='faces against the path'):
        follower.locate(20_000_000, 5.1, 0.2, math.pi)
    # duplicate_distance 0: only equal points are duplicates; a chain the passes do not
    # settle is judged point by point against the last kept
    assert ReferencePath([(0, 0), (1e-9, 0), (1e-9, 0), (1, 0)],
                         PathParams(duplicate_distance=0.0)).size == 3
    # each pass drops one point of 0, 0.9, -0.15, 0.9, -0.15 ... (1 m): 60 passes
    chain = np.array([(0.0, 0.0)] + [(0.9, 0.0), (-0.15, 0.0)] * 60 + [(5.0, 0.0)])
    assert drop_duplicates(chain, 1.0).tolist() == [[0.0, 0.0], [5.0, 0.0]]


def test_paths_that_revisit_their_points_give_a_place_or_a_path_error():
    # dev-probe92's fuzz: paths of tiny steps that revisit earlier points, far from the
    # origin, raised ZeroDivisionError (a segment shorter than the arc length's rounding)
    # or gave NaN; every pose now gives finite values or a PathError
    # (on the old code 16-21 of 300 paths raised or gave NaN, for each of five seeds)
    rng = np.random.default_rng(92)
    for _ in range(300):
        n = int(rng.choice([3, 6, 30]))
        step = float(rng.choice([1e-5, 1e-3, 0.1, 1.0]))
        duplicate = float(rng.choice([0.0, 1e-4, 1e-4, 0.01]))
        pts, heading = [(0.0, 0.0)], 0.0
        for _ in range(n - 1):
            heading += float(rng.choice([0.0, rng.uniform(-3, 3), math.pi / 2]))
            length = step * float(rng.choice([1.0, 0.5, 1e-3]))
            pts.append((pts[-1][0] + length * math.cos(heading),
                        pts[-1][1] + length * math.sin(heading)))
            if rng.random() < 0.2:
                pts.append(pts[int(rng.integers(len(pts)))])
            if rng.random() < 0.2:      # a jitter that creeps past the distance and returns
                start = pts[-1]
                for _ in range(int(rng.integers(1, 4))):
                    angle = float(rng.uniform(-math.pi, math.pi))
                    pts.append((pts[-1][0] + 0.9 * duplicate * math.cos(angle),
                                pts[-1][1] + 0.9 * duplicate * math.sin(angle)))
                pts.append(start)
        origin = float(rng.choice([0.0, 1e6, 5e8]))
        params = PathParams(fit_half_window=float(rng.choice([0.01, 5.0])),
                            duplicate_distance=duplicate,
                            search_distance=float(rng.choice([0.1, 10.0])),
                            jump_distance=float(rng.choice([0.01, 100.0])))
        try:
            path = ReferencePath(np.array(pts) + origin, params)
        except PathError:
            continue
        follower = PathFollower(path)
        x, y = pts[int(rng.integers(len(pts)))]
        x, y, yaw, stamp = x + origin, y + origin, float(rng.uniform(-3, 3)), 0
        for _ in range(20):
            stamp += int(rng.choice([10_000_000, 0, -10_000_000, 2_000_000_000]))
            x, y = x + float(rng.uniform(-1, 1)) * step, y + float(rng.uniform(-1, 1)) * step
            yaw += float(rng.choice([0.0, 0.1, math.pi]))
            try:
                place = follower.locate(stamp, x, y, yaw, float(rng.choice([0.0, 10.0])))
            except PathError:
                continue
            assert all(math.isfinite(v) for v in (place.s, place.lateral_error, place.relative_yaw,
                                                  place.curvature, place.heading)), place
            assert all(math.isfinite(k) for _, k in path.preview(place.s, 50.0, 5.0))


def test_poses_without_a_place_on_the_path_are_refused():
    road = Road([Segment('straight', 100.0)])
    follower = PathFollower(ReferencePath(road.sample(100.0, 1.0)[:, :2]))
    with pytest.raises(PathError, match='1.50 m past the end'):
        follower.locate(0, 101.5, 0.0, 0.0)
    with pytest.raises(PathError, match='past the end'):          # the path lies behind
        follower.locate(1, 300.0, 2.0, 0.0)
    with pytest.raises(PathError, match='starts 3.00 m ahead'):
        follower.locate(2, -3.0, 0.0, 0.0)
    assert follower.locate(3, -0.5, 0.2, 0.0).s == pytest.approx(-0.5)   # within tolerance
    with pytest.raises(PathError, match=r'\+6.00 m from the path'):
        follower.locate(4, 50.0, 6.0, 0.0)
    with pytest.raises(PathError, match='faces against the path'):
        follower.locate(5, 50.0, 0.0, 3.0)
    with pytest.raises(PathError, match='odometry x is not finite'):
        follower.locate(6, float('nan'), 0.0, 0.0)
    with pytest.raises(PathError, match='odometry yaw is not finite'):
        follower.locate(7, 1.0, 0.0, float('inf'))
    lane = follower.locate(8, 50.0, 0.1, 0.0)                      # and back on it
    assert lane.s == pytest.approx(50.0) and 're-match' in lane.note


def test_path_params_validate_themselves():
    with pytest.raises(ValueError, match='fit_half_window'):
        PathParams(fit_half_window=0.0)
    with pytest.raises(ValueError, match='jump_distance'):
        PathParams(jump_distance=float('nan'))


def test_cg_pose_moves_the_rear_axle_frame_forward():
    x, y, v_y = cg_pose(1.0, 2.0, math.pi / 2, 0.1, 0.2, 1.5)
    assert (x, y, v_y) == pytest.approx((1.0, 3.5, 0.1 + 1.5 * 0.2))


def test_map_coordinates_far_from_the_origin_lose_nothing():
    # UTM-sized map coordinates: the fit works on offsets from each vertex
    points = circle(-100.0, 1.0)
    road = Road([Segment('arc', 1000.0, -0.01, -0.01)])
    near, far = (PathFollower(ReferencePath(points + offset))
                 for offset in (np.zeros(2), np.array([512_345.0, 5_412_345.0])))
    for k, s in enumerate(np.arange(20.0, 60.0, 0.37)):
        x, y, yaw = road.global_pose(s, 0.25, 0.01)
        a = near.locate(k, x, y, yaw, 37.0)
        b = far.locate(k, x + 512_345.0, y + 5_412_345.0, yaw, 37.0)
        assert (b.lateral_error, b.relative_yaw, b.curvature) == pytest.approx(
            (a.lateral_error, a.relative_yaw, a.curvature), abs=1e-8)


def test_slow_odometry_at_speed_is_no_jump():
    # 10 Hz odometry at 37 m/s: 3.7 m between messages, predicted from the twist
    road = Road([Segment('straight', 100.0), Segment('arc', 900.0, 0.005, 0.005)])
    follower = PathFollower(ReferencePath(road.sample(1000.0, 0.5)[:, :2]))
    lanes = drive(follower, road, np.arange(0.0, 800.0, 3.7), 0.2, 0.0, period=0.1,
                  speed=37.0)
    assert all(lane.note == '' for lane in lanes) and follower.rematches == 0


def test_a_parent_frame_twist_is_told_from_a_body_one():
    from lookahead_control.core.path_geometry import twist_in_parent_frame
    yaw, dt = 1.2, 0.01
    dx, dy = 20.0 * math.cos(yaw) * dt, 20.0 * math.sin(yaw) * dt
    assert not twist_in_parent_frame(dx, dy, dt, yaw, 20.0, 0.0)          # body: fine
    assert twist_in_parent_frame(dx, dy, dt, yaw, dx / dt, dy / dt)        # parent frame
    # heading along x the two readings agree: nothing to tell; slow or stale: no verdict
    assert not twist_in_parent_frame(0.2, 0.0, dt, 0.0, 20.0, 0.0)
    assert not twist_in_parent_frame(0.001, 0.0, dt, yaw, 0.1, 0.0)
    assert not twist_in_parent_frame(dx, dy, 0.0, yaw, dx / dt, dy / dt)
    # a 5 m relocalization jump fits neither reading
    assert not twist_in_parent_frame(dx + 5.0, dy, dt, yaw, dx / dt, dy / dt)
