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

"""Test session setup (DDS isolated to this session and to loopback) and shared helpers."""

import ast
import os
from pathlib import Path
import sys
import time

import pytest

# A unique ROS_DOMAIN_ID per test session (0..101 are safe for Fast DDS ports), set
# before anything imports rclpy, and discovery on loopback only. Under pytest-xdist
# (`make test` runs three workers) each worker of a session gets its own domain: the
# session's slot from the parent's pid, the worker's number within it.
_WORKER = os.environ.get('PYTEST_XDIST_WORKER', '')
if _WORKER.startswith('gw') and _WORKER[2:].isdigit():
    _COUNT = max(1, min(100, int(os.environ.get('PYTEST_XDIST_WORKER_COUNT', '1'))))
    os.environ['ROS_DOMAIN_ID'] = str(
        1 + (os.getppid() % (100 // _COUNT)) * _COUNT + int(_WORKER[2:]) % _COUNT)
else:
    os.environ['ROS_DOMAIN_ID'] = str(1 + os.getpid() % 100)
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('MPLBACKEND', 'Agg')

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def entry_points() -> dict:
    """Return setup.py's EXECUTABLES (name -> module:function) without running it."""
    tree = ast.parse((ROOT / 'setup.py').read_text(encoding='utf-8'))
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and getattr(node.targets[0], 'id', '') == \
                'EXECUTABLES':
            return ast.literal_eval(node.value)
    raise AssertionError('setup.py has no EXECUTABLES mapping')


def spin_until(executor, condition, timeout):
    """Spin until ``condition()`` or ``timeout`` seconds; return ``condition()``."""
    end = time.monotonic() + timeout
    while time.monotonic() < end and not condition():
        executor.spin_once(timeout_sec=0.01)
    return condition()


class Swerve:
    """Open loop: 0.3 rad at 0.5 Hz above 25 m/s (spins the multi-body car), else 0.01."""

    def reset(self):
        self.t = None

    def step(self, state, preview, dt):
        import math

        from lookahead_control.core.laws import output
        import numpy as np
        self.t = 0.0 if self.t is None else self.t + dt
        amplitude = np.where(np.asarray(state.v_x) > 25.0, 0.3, 0.01)
        return output(amplitude * math.sin(math.pi * self.t) + 0.0 * state.y_cg)


@pytest.fixture
def context():
    """Yield a private rclpy Context for nodes made in a test (callbacks called directly)."""
    import rclpy
    from rclpy.context import Context
    ctx = Context()
    rclpy.init(context=ctx)
    yield ctx
    rclpy.try_shutdown(context=ctx)


@pytest.fixture
def active_controller(context):
    """Yield a controller node with its defaults, configured and active (destroyed after)."""
    from lookahead_control.ros.controller_node import ControllerNode
    node = ControllerNode(context=context)
    try:
        node.trigger_configure()
        node.trigger_activate()
        yield node
    finally:
        node.destroy_node()


@pytest.fixture
def probe():
    """Yield a node in a private context and its executor: ``(node, executor)``."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    ctx = Context()
    rclpy.init(context=ctx)
    node = Node('test_probe', context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    yield node, executor
    # the executor first: destroy_node with the executor still holding the node died
    # once of SIGSEGV in this fixture's teardown (session 25's suite under two CPU hogs)
    executor.shutdown(timeout_sec=1.0)
    node.destroy_node()
    rclpy.try_shutdown(context=ctx)


def feed(node, stamp, y=0.5, d=1.96, eps=0.01, r=0.02, v_x=25.0, v_y=0.1, rho=-0.0025):
    """
    Deliver one set of contract inputs stamped ``stamp`` [ns] to a controller node.

    A node on sim time gets its clock set to the stamp first (a fake clock that reads the
    measurements' time); the lateral error goes last, as it triggers the command.
    """
    from lookahead_control.ros import conversions as conv
    if node.get_clock().ros_time_is_active:
        from rclpy.time import Time
        node.get_clock().set_ros_time_override(Time(nanoseconds=stamp))
    node.on_yaw(conv.to_yaw(stamp, 'base_link', eps, r, 0.0 - v_y * r))
    node.on_velocity(conv.to_velocity(stamp, 'base_link', v_x, v_y, r))
    node.on_curvature(conv.to_curvature(stamp, 'base_link', [(0.0, rho), (5.0, rho)]))
    node.on_lateral_error(conv.to_lateral_error(stamp, 'base_link', d, y))
