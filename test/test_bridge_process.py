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

"""path_bridge over real DDS: the closed loop through it, and a bridge facing a live stack."""

from pathlib import Path
import subprocess
import sys

from bridge_loop import bridge_loop
from conftest import spin_until
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PointStamped
from lookahead_control.bags.run_data import load_run
from lookahead_control.ros import conversions as conv
from lookahead_control.ros import vehicle_conversions as vconv
from lookahead_control.ros.closed_loop import LoopConfig, run_loop, stop
from nav_msgs.msg import Odometry, Path as PathMsg
import numpy as np
import pytest
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sim_plant.road import Road, Segment
from sim_plant.scenario import load_scenario
from test_bridge_loop import junction_tolerances, SPEED, STEP_K

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / 'config' / 'scenarios' / 'paper_r400.yaml'
pytestmark = pytest.mark.process


def test_closed_loop_through_the_bridge_reproduces_the_direct_loop(tmp_path):
    bag = tmp_path / 'bridge'
    assert run_loop(LoopConfig(SCENARIO, speed=SPEED, bag=bag, via_bridge=True)) == 0
    run = load_run(bag)
    truth, steering = run.truth.by_stamp(), run.steering.by_stamp()
    scenario = load_scenario(SCENARIO, SPEED)
    stamps, d_bridge, y_bridge, _ = bridge_loop(scenario)           # 1 m, h = 5 m
    direct = bridge_loop(scenario, direct=True)
    assert sorted(truth) == stamps.tolist() and set(stamps.tolist()) <= set(steering)
    d_ros = np.array([steering[int(s)]['angle'] for s in stamps])
    y_ros = np.array([truth[int(s)]['y_cg'] for s in stamps])
    # the ROS loop is the bridged loop computed without ROS (same cores, float32 curvature)
    np.testing.assert_allclose(d_ros, d_bridge, rtol=0, atol=1e-8)
    np.testing.assert_allclose(y_ros, y_bridge, rtol=0, atol=1e-8)
    # and differs from the direct loop by no more than the sampled curvature step makes
    # (test_bridge_loop: 0.0100 rad for one step at the junction, its response in y_cg)
    pulse, y_bound = junction_tolerances(direct)
    assert np.max(np.abs(d_ros - direct[1])) <= 2.0 * pulse
    assert abs(d_ros[STEP_K] - direct[1][STEP_K]) >= 0.9 * pulse
    assert np.max(np.abs(y_ros - direct[2])) <= y_bound
    assert np.max(np.abs(y_ros)) > 0.3          # it really went round the curve


def test_a_bridge_joining_a_running_stack(probe):
    node, executor = probe
    road = Road([Segment('straight', 500.0)])
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    path_pub = node.create_publisher(PathMsg, '/plan', latched)
    # published once, before the bridge exists (transient local keeps it for late joiners)
    path_pub.publish(vconv.to_path(0, 'map', road.sample(500.0, 0.5).tolist()))
    odom_pub = node.create_publisher(Odometry, '/odom', 10)
    answers, status = [], []
    node.create_subscription(PointStamped, '/lateral_error',
                             lambda m: answers.append(conv.from_lateral_error(m)), 100)
    node.create_subscription(
        DiagnosticArray, '/diagnostics',
        lambda m: status.extend(s for s in m.status if s.name.endswith('path_bridge')), 100)
    cmd = [sys.executable, '-m', 'lookahead_control.ros.path_bridge_node', '--ros-args',
           '--params-file', str(ROOT / 'config' / 'path_bridge.yaml'),
           '-r', 'odometry:=/odom', '-r', 'path:=/plan', '-p', 'odometry_timeout:=0.3']
    bridge = subprocess.Popen(cmd)
    try:
        # both inputs matched (the path's too: before, only /odom was awaited in the graph)
        assert spin_until(executor, lambda: odom_pub.get_subscription_count() > 0
                          and path_pub.get_subscription_count() > 0
                          and node.count_publishers('/lateral_error') > 0, 60)
        spin_until(executor, lambda: False, 0.5)

        def drive(first, count, frame='map'):
            # in lockstep: each message waits (up to 5 s) for the answer to the one
            # before, so that neither a loaded machine's dropped messages nor a late
            # answer changes what the test counts
            for k in range(first, first + count):
                before = len(answers)
                odom_pub.publish(vconv.to_odometry(k * 10_000_000, frame, 'base_link',
                                                   10.0 + 0.2 * k, 0.3, 0.0, 20.0, 0.0, 0.0))
                spin_until(executor, lambda: len(answers) > before,
                           5.0 if frame == 'map' else 0.01)

        drive(0, 30)
        # every message from the first the bridge had the path for is answered, in order
        # (the path reaches a late joiner by transient local, at discovery)
        assert len(answers) >= 25
        assert [a.stamp_ns for a in answers] == [k * 10_000_000
                                                 for k in range(30 - len(answers), 30)]
        assert all(a.value == pytest.approx(0.3, abs=1e-9) for a in answers)
        # odometry in another frame than the path: ERROR at once, and no output
        count = len(answers)
        drive(30, 10, frame='odom')
        assert spin_until(executor, lambda: any(
            s.level == DiagnosticStatus.ERROR and "path in 'map'" in s.message
            for s in status), 5)
        assert len(answers) == count
        # the odometry publisher dies: ERROR 'no odometry'
        status.clear()
        drive(40, 5)
        assert spin_until(executor, lambda: any('no odometry for 0.3 s' in s.message
                                                for s in status), 5)
    finally:
        assert stop(bridge, 'path_bridge') == 0
