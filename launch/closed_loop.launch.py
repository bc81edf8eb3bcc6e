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
Launch sim_plant and controller (real ROS 2 Jazzy installs; here use ``closed_loop``).

ros2 launch lookahead_control closed_loop.launch.py speed:=37.0 schedule:=paper

Its arguments and their defaults are ``closed_loop``'s: ``law`` is ``paper`` (the paper's
law with ``schedule``), as ``closed_loop`` runs it; ``law:=cg_compensated`` runs the
controller's own default law. ``plant:=commonroad_mb`` (or ``commonroad_st``) drives
CommonRoad's car ``vehicle_id`` (1 Ford Escort, 2 BMW 320i, 3 VW Vanagon) and gives the
controller (and the simulator's sensor) that car's mapped model, as ``closed_loop
--plant commonroad_mb`` does; ``vehicle_id`` is 2 if not given, and refused with another
plant.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import (DeclareLaunchArgument, EmitEvent, OpaqueFunction,
                            RegisterEventHandler)
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def _nodes(context, config):
    """Return the two nodes, the controller's model the plant's car (CommonRoad: mapped)."""
    from lookahead_control.ros.closed_loop import PLANTS
    from sim_plant.commonroad_plant import COMMONROAD_MODELS, controller_vehicle_params
    cars = {'1': 'Ford Escort', '2': 'BMW 320i', '3': 'VW Vanagon'}
    plant = LaunchConfiguration('plant').perform(context)
    mode = LaunchConfiguration('mode').perform(context)
    text = LaunchConfiguration('vehicle_id').perform(context)
    # checked here, so that both nodes get one reading of them (dev-probe83: ' lockstep'
    # was lockstep to the simulator, whose parameter YAML strips it, and not to the
    # controller's wait)
    if plant not in PLANTS:
        raise ValueError(f'plant:={plant}: one of {", ".join(PLANTS)}')
    if mode not in ('lockstep', 'realtime'):
        raise ValueError(f'mode:={mode}: lockstep or realtime')
    mapped, chosen = {}, {}
    if plant in COMMONROAD_MODELS:
        if text.strip() not in ('', *cars):
            raise ValueError(f'vehicle_id:={text}: a CommonRoad car is '
                             + ', '.join(f'{k} ({v})' for k, v in cars.items()))
        vehicle_id = int(text.strip() or '2')
        mapped = controller_vehicle_params(vehicle_id)
        chosen = {'plant.vehicle_id': vehicle_id}
    elif text.strip():
        raise ValueError(f'vehicle_id:={text} with plant:={plant}: a CommonRoad car is '
                         'chosen only for plant:=commonroad_st or commonroad_mb')
    # the simulator waits for each answer in lockstep only (closed_loop's choice)
    lockstep = mode == 'lockstep'
    sim = Node(package='lookahead_control', executable='sim_plant', name='sim_plant',
               parameters=[os.path.join(config, 'vehicle.yaml'), mapped, {
                   'scenario_file': LaunchConfiguration('scenario'),
                   'speed': LaunchConfiguration('speed'),
                   'mode': mode, 'plant.model': plant, **chosen}])
    controller = Node(package='lookahead_control', executable='controller',
                      name='controller',
                      parameters=[os.path.join(config, 'vehicle.yaml'),
                                  os.path.join(config, 'controller.yaml'), mapped, {
                                      'controller.schedule': LaunchConfiguration('schedule'),
                                      'law': LaunchConfiguration('law'),
                                      'wait_for_matching_stamps': lockstep,
                                      'use_sim_time': True}])
    return [controller, sim,
            RegisterEventHandler(OnProcessExit(target_action=sim,
                                               on_exit=[EmitEvent(event=Shutdown())]))]


def generate_launch_description():
    share = get_package_share_directory('lookahead_control')
    config = os.path.join(share, 'config')
    args = {
        'scenario': os.path.join(config, 'scenarios', 'paper_r400.yaml'),
        'speed': '0.0', 'schedule': 'paper', 'mode': 'lockstep', 'plant': 'linear',
        'law': 'paper', 'vehicle_id': '',
    }
    return LaunchDescription(
        [DeclareLaunchArgument(k, default_value=v) for k, v in args.items()]
        + [OpaqueFunction(function=_nodes, args=[config])])
