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
The loops sim_plant -> [path_bridge ->] controller -> sim_plant without ROS.

The same cores in the same order as the nodes (path geometry on the sampled road, the
controller core, the linear plant stepper), so a ROS run can be compared with it step by
step, and the bridged loop with the direct one. ``direct`` feeds the controller core what
sim_plant publishes in contract mode (the offline runner ``closed_loop_sim.run`` differs:
it feeds the curvature's rate forward, the node only with ``use_curvature_preview``).
"""

from lookahead_control.core.controller import SteeringController
from lookahead_control.core.params import ControllerParams, VehicleParams
from lookahead_control.core.path_geometry import PathFollower, PathParams, ReferencePath
from lookahead_control.core.samples import (curvature_from_points, LateralErrorSample,
                                            VelocitySample, YawSample)
import numpy as np
from sim_plant.closed_loop_sim import check_steps, linear_plant_stepper, measure
from sim_plant.vehicle_model import PlantParams


def path_length(scenario, preview=50.0):
    """Return how much road sim_plant publishes as its path (SimPlantNode.road_path)."""
    speed = scenario.speed
    fastest = max(speed.initial, speed.initial + speed.acceleration * speed.duration)
    return max(scenario.road.length, fastest * scenario.duration) + preview + 50.0


def bridge_loop(scenario, spacing=1.0, half_window=5.0, period=0.01, dt=0.001,
                direct=False, pulse=(0, 0.0)):
    """
    Return (stamps [ns], steering, y_cg, lateral error seen) of the loop.

    ``pulse = (k, angle)`` adds ``angle`` to the command applied over step k.
    """
    vehicle, plant = VehicleParams(), PlantParams()
    road, speed = scenario.road, scenario.speed
    path = ReferencePath(road.sample(path_length(scenario), spacing)[:, :2],
                         PathParams(fit_half_window=half_window))
    follower = PathFollower(path)
    core = SteeringController(vehicle, ControllerParams())
    stepper = linear_plant_stepper(scenario, vehicle, plant, speed.initial, speed.acceleration)
    substeps, n_steps = check_steps(dt, period, scenario.duration)
    init = scenario.initial
    x = (0.0, init.lateral_error, init.relative_yaw, init.lateral_velocity, init.yaw_rate, 0.0)
    rows = []
    previous = None
    for k in range(n_steps):
        stamp = int(round(k * period * 1e9))
        inputs = measure(x, k * period, scenario, speed.initial, speed.acceleration)
        v_x, v_y, r = float(inputs.v_x), x[3], x[4]
        px, py, yaw = road.global_pose(x[0], x[1], x[2])
        if direct:      # sim_plant's contract output
            lateral, relative_yaw, accel = x[1], x[2], float(inputs.a_x) - v_y * r
            preview = [(d, road.curvature(x[0] + d)[0]) for d in np.arange(0.0, 50.01, 5.0)]
        else:           # path_bridge's, from the odometry and the path
            lane = follower.locate(stamp, px, py, yaw, v_x, v_y)
            lateral, relative_yaw = lane.lateral_error, lane.relative_yaw
            accel = (0.0 if previous is None else (v_x - previous) / period) - v_y * r
            preview = path.preview(lane.s, 50.0, 5.0)
        previous = v_x
        preview = [(float(np.float32(d)), float(np.float32(rho)))      # Point32
                   for d, rho in preview]
        core.accept('yaw', YawSample(stamp, relative_yaw, r, accel))
        core.accept('velocity', VelocitySample(stamp, v_x, v_y))
        core.accept('road_curvature', curvature_from_points(stamp, preview))
        core.accept('lateral_error', LateralErrorSample(stamp, 0.0, lateral))
        command = core.compute()
        rows.append((stamp, command.steering, x[1], lateral))
        applied = command.steering + (pulse[1] if k == pulse[0] else 0.0)
        x = stepper(x, k * period, dt, substeps, applied)
    stamps, steering, y_cg, lateral = (np.array(c) for c in zip(*rows))
    return stamps.astype(np.int64), steering, y_cg, lateral
