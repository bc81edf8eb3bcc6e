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


"""Hostile-user probes of path_bridge: independent geometry and extreme inputs."""

import math

from diagnostic_msgs.msg import DiagnosticStatus
from lookahead_control.core.path_geometry import PathError, PathFollower, ReferencePath
from lookahead_control.ros import vehicle_conversions as vconv
import numpy as np
import pytest
import rclpy
from rclpy.context import Context
from rclpy.serialization import serialize_message

PERIOD = 10_000_000


@pytest.fixture
def bridge():
    from lookahead_control.ros.path_bridge_node import PathBridgeNode
    ctx = Context()
    rclpy.init(context=ctx)
    node = PathBridgeNode(context=ctx)
    node.trigger_configure()
    node.trigger_activate()
    node.out = []
    for name, pub in node._pubs.items():
        pub.publish = (lambda n: (lambda msg: node.out.append((n, msg))))(name)
    node.diag = []
    node._diag_pub.publish = lambda msg: node.diag.append(msg.status[0])
    yield node
    node.destroy_node()
    rclpy.try_shutdown(context=ctx)


def wrap(angle):
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


# -- geometry against closed forms -----------------------------------------------------


@pytest.mark.parametrize('heading', np.linspace(-math.pi, math.pi, 9))
@pytest.mark.parametrize('offset', [1.7, -2.3])
def test_straight_line_at_any_heading(heading, offset):
    # a line from (3, -2) at `heading`; the point `offset` to its left (+ left, REP-103)
    c, s = math.cos(heading), math.sin(heading)
    path = ReferencePath([(3.0 + k * c, -2.0 + k * s) for k in range(101)])
    along = 40.3
    x, y = 3.0 + along * c - offset * s, -2.0 + along * s + offset * c
    lane = PathFollower(path).locate(0, x, y, heading + 0.2, 10.0)
    assert lane.lateral_error == pytest.approx(offset, abs=1e-9)
    assert lane.s == pytest.approx(along, abs=1e-9)
    assert wrap(lane.relative_yaw - 0.2) == pytest.approx(0.0, abs=1e-12)
    assert lane.curvature == pytest.approx(0.0, abs=1e-9)
    assert lane.remaining == pytest.approx(100.0 - along, abs=1e-9)


@pytest.mark.parametrize('turn', [1, -1])
@pytest.mark.parametrize('offset', [1.3, -0.7])
def test_circle_both_directions(turn, offset):
    # R = 50 m at 1 m spacing, centre (5, 7); counter-clockwise (turn = 1) curves left
    radius, h = 50.0, 5.0
    angles = -turn * math.pi / 2 + turn * np.arange(250) / radius
    path = ReferencePath(np.c_[5.0 + radius * np.cos(angles), 7.0 + radius * np.sin(angles)])
    arc = 120.0
    angle = -turn * math.pi / 2 + turn * arc / radius
    r = radius - turn * offset     # left of a left turn is towards the centre
    lane = PathFollower(path).locate(0, 5.0 + r * math.cos(angle), 7.0 + r * math.sin(angle),
                                     angle + turn * math.pi / 2 + 0.1, 10.0)
    # the fit's bias on an arc (vehicle_bridge.md): lateral 3 h^4 / (280 R^3), curvature
    # 3 h^2 / (14 R^3); the polyline's length is the chord sum, 2 R sin(1 / 2R) per metre
    assert lane.lateral_error == pytest.approx(offset, abs=3 * h ** 4 / (280 * radius ** 3))
    assert lane.curvature == pytest.approx(turn / radius, abs=3 * h ** 2 / (14 * radius ** 3))
    assert wrap(lane.relative_yaw - 0.1) == pytest.approx(0.0, abs=1e-6)
    chord = 2.0 * radius * math.sin(0.5 / radius)
    assert lane.s == pytest.approx(arc * chord, abs=1e-4)
    for ahead, rho in path.preview(lane.s, 50.0, 5.0):
        assert rho == pytest.approx(turn / radius, abs=3 * h ** 2 / (14 * radius ** 3))


def test_uneven_spacing_on_a_straight_line():
    # 0.01 m and 20 m gaps mixed, heading 0.7 rad; a weaving vehicle
    rng = np.random.default_rng(1)
    gaps = np.where(rng.random(60) < 0.6, 0.01, 20.0)
    s = np.concatenate(([0.0], np.cumsum(gaps)))
    c, sn = math.cos(0.7), math.sin(0.7)
    follower = PathFollower(ReferencePath(np.c_[s * c, s * sn]))
    for k in range(1500):
        along, offset = 0.5 + 0.14 * k, 0.8 * math.sin(0.014 * k)
        if along > s[-1] - 1.0:
            break
        lane = follower.locate(k * PERIOD, along * c - offset * sn, along * sn + offset * c,
                               0.7, 14.0)
        assert lane.lateral_error == pytest.approx(offset, abs=1e-9)
        assert lane.s == pytest.approx(along, abs=1e-9)


def test_path_in_reverse_order_is_refused():
    path = ReferencePath([(float(k), 0.0) for k in range(100)][::-1])
    with pytest.raises(PathError, match='faces against the path'):
        PathFollower(path).locate(0, 50.0, 0.5, 0.0, 10.0)


# -- extreme finite values -------------------------------------------------------------


def test_huge_path_coordinates_are_refused_not_a_crash(bridge):
    # found: a path 1e306 m between points was accepted; the first odometry then raised
    # a plain ValueError ('attempt to get argmin of an empty sequence') out of the
    # callback, which kills the node
    bridge.on_path(vconv.to_path(0, 'map', [(k * 1e306, 0.0, 0.0) for k in range(100)]))
    bridge.on_odometry(vconv.to_odometry(0, 'map', 'base_link', 5e306, 0.0, 0.0, 10.0,
                                         0.0, 0.0))
    assert bridge.out == []
    assert 'out of range' in bridge.problem
    assert bridge.diag[-1].level == DiagnosticStatus.ERROR


def test_far_odometry_never_publishes_nan(bridge):
    # found: odometry at x = 1e308 (finite) on a path not parallel to x gave s, lateral
    # error and relative yaw NaN (inf - inf in the projection), all published
    path = [(float(k), 0.3 * math.sin(k / 7.0), 0.0) for k in range(200)]
    bridge.on_path(vconv.to_path(0, 'map', path))
    bridge.on_odometry(vconv.to_odometry(0, 'map', 'base_link', 10.0, 0.2, 0.0, 10.0,
                                         0.0, 0.0))
    assert len(bridge.out) == 4
    bridge.out.clear()
    for k, (x, y) in enumerate([(1e308, 0.0), (1e308, 1e-300), (-1e308, 1e308)]):
        bridge.on_odometry(vconv.to_odometry((k + 1) * PERIOD, 'map', 'base_link', x, y,
                                             0.0, -1.0, 0.0, 0.0))
        assert bridge.out == []
        assert 'out of range' in bridge.problem
        assert bridge.diag[-1].level == DiagnosticStatus.ERROR
    # and back on the path: output resumes
    bridge.on_odometry(vconv.to_odometry(9 * PERIOD, 'map', 'base_link', 10.5, 0.2, 0.0,
                                         10.0, 0.0, 0.0))
    assert [name for name, _ in bridge.out][-1] == 'lateral_error'
    assert math.isfinite(bridge.out[-1][1].point.y)
    assert bridge.problem == ''


def test_huge_twist_never_publishes_nan(bridge):
    # found: a finite but huge twist (v_x -1e308 after 10 m/s, v_y 1e10, yaw rate -1e308)
    # gave the published yaw message a NaN acceleration (dv_x/dt - v_y r: -inf + inf)
    path = [(float(k), 0.3 * math.sin(k / 7.0), 0.0) for k in range(200)]
    bridge.on_path(vconv.to_path(0, 'map', path))
    bridge.on_odometry(vconv.to_odometry(0, 'map', 'base_link', 22.0, 0.0, 0.0, 10.0,
                                         0.0, 0.0))
    assert len(bridge.out) == 4
    bridge.out.clear()
    bridge.on_odometry(vconv.to_odometry(PERIOD, 'map', 'base_link', 22.1, 0.0, 0.0, -1e308,
                                         1e10, -1e308))
    assert bridge.out == []
    assert 'odometry twist out of range' in bridge.problem
    assert bridge.diag[-1].level == DiagnosticStatus.ERROR


# -- long paths -------------------------------------------------------------------------


@pytest.mark.parametrize('count, frame, blank_pose_frame', [
    (0, 'map', None), (1, 'm', None), (3, 'ab', 1), (257, 'odom_frame', 100)])
def test_path_from_cdr_equals_the_deserialized_path(count, frame, blank_pose_frame):
    # frame names of every length mod 4 and 8 move the alignment of the doubles
    msg = vconv.to_path(7, frame, [(0.5 * j + 0.1, -0.25 * j, 0.3 * j) for j in range(count)])
    if blank_pose_frame is not None:
        msg.poses[blank_pose_frame].header.frame_id = ''     # '': the path's frame
    got_frame, points = vconv.path_points_cdr(serialize_message(msg))
    assert got_frame == frame
    assert points.shape == (count, 2)
    assert np.array_equal(points, vconv.path_points(msg))


def test_path_from_cdr_refuses_other_frames_and_bad_bytes():
    msg = vconv.to_path(0, 'map', [(1.0, 2.0, 0.0), (2.0, 2.0, 0.0), (3.0, 2.0, 0.0)])
    msg.poses[1].header.frame_id = 'odom'
    with pytest.raises(ValueError, match="path pose 1 is in frame 'odom', the path in 'map'"):
        vconv.path_points_cdr(serialize_message(msg))
    data = serialize_message(vconv.to_path(0, 'map', [(1.0, 2.0, 0.0)] * 3))
    for cut in (2, 10, 30):
        with pytest.raises(ValueError, match='path: '):
            vconv.path_points_cdr(data[:cut])


def test_the_bridge_takes_the_path_as_bytes_over_dds(bridge):
    # found: rclpy builds a Python object per pose when it deserializes a Path, about
    # 0.1 ms a pose on a loaded 2-core machine (a 2000-point Nav2 plan 0.18 s, 100 000
    # points 12 s), during which the single-threaded bridge handles no odometry: a
    # planner republishing its plan at 10-20 Hz starved the bridge and the controller
    # went to its safe angle again and again. The bridge now reads the serialized path.
    from nav_msgs.msg import Path
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import DurabilityPolicy, QoSProfile
    assert [sub.raw for sub in bridge._subs if sub.topic_name == '/path'] == [True]
    ctx = bridge.context
    sender = Node('planner', context=ctx)
    pub = sender.create_publisher(Path, 'path', QoSProfile(
        depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(bridge)
    try:
        pub.publish(vconv.to_path(0, 'map', [(0.5 * j, 0.0, 0.0) for j in range(2000)]))
        end = 0
        while bridge.path is None and end < 500:
            executor.spin_once(timeout_sec=0.02)
            end += 1
        assert bridge.path is not None and bridge.path.size == 2000
        assert bridge.path_frame == 'map'
        bridge.on_odometry(vconv.to_odometry(0, 'map', 'base_link', 10.0, 0.2, 0.0, 10.0,
                                             0.0, 0.0))
        assert bridge.out[-1][1].point.y == pytest.approx(0.2)
    finally:
        executor.remove_node(bridge)
        sender.destroy_node()


# -- stamps -----------------------------------------------------------------------------


@pytest.mark.parametrize('stamp', [0, 1_795_000_000_123_000_000])
def test_frozen_odometry_stamps_are_refused(bridge, stamp):
    # found: odometry whose stamp never advances (a frozen clock, or stamp 0) while the
    # vehicle moves was published with that one stamp, diagnostics OK; the controller
    # answered each with the same stamp, its rate limit saw no time pass and held the
    # steering, also reporting OK (measured over DDS: 200 messages in 2.5 s)
    bridge.on_path(vconv.to_path(0, 'map', [(float(k), 0.0, 0.0) for k in range(200)]))

    def odometry(x, at=stamp):
        return vconv.to_odometry(at, 'map', 'base_link', x, 0.2, 0.0, 10.0, 0.0, 0.0)

    bridge.on_odometry(odometry(10.0))
    assert [name for name, _ in bridge.out][-1] == 'lateral_error'
    bridge.on_odometry(odometry(10.0))          # the same message again: answered again
    assert len(bridge.out) == 8 and bridge.problem == ''
    bridge.on_odometry(odometry(10.1))
    assert len(bridge.out) == 8
    assert 'did not advance while the pose moved 0.100 m' in bridge.problem
    assert bridge.diag[-1].level == DiagnosticStatus.ERROR
    bridge.on_odometry(odometry(10.2, stamp + PERIOD))
    assert len(bridge.out) == 12 and bridge.problem == ''
