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
path_bridge and controller on a vehicle stack (real ROS 2 Jazzy installs).

ros2 launch lookahead_control path_bridge.launch.py odometry:=/odometry/global \
    path:=/plan path_durability:=volatile steering:=/vehicle/steering_cmd

Simulated (sim_plant speaking like a vehicle): add sim:=true; here use
``closed_loop --via-bridge``.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    share = get_package_share_directory('lookahead_control')
    config = os.path.join(share, 'config')
    args = {
        'odometry': '/odometry', 'path': '/path', 'imu': '/imu', 'steering': '/steering',
        'path_durability': 'transient_local', 'use_imu': 'false', 'base_to_cg': '0.0',
        'qos_reliability': 'reliable', 'sim': 'false',
        'scenario': os.path.join(config, 'scenarios', 'paper_r400.yaml'),
    }
    arg = LaunchConfiguration
    bridge = Node(package='lookahead_control', executable='path_bridge', name='path_bridge',
                  parameters=[os.path.join(config, 'path_bridge.yaml'), {
                      'path_durability': arg('path_durability'),
                      'use_imu': arg('use_imu'), 'base_to_cg': arg('base_to_cg'),
                      'qos_reliability': arg('qos_reliability')}],
                  remappings=[('odometry', arg('odometry')), ('path', arg('path')),
                              ('imu', arg('imu'))])
    controller = Node(package='lookahead_control', executable='controller',
                      name='controller',
                      parameters=[os.path.join(config, 'vehicle.yaml'),
                                  os.path.join(config, 'controller.yaml'),
                                  {'use_sim_time': arg('sim'),
                                   'wait_for_matching_stamps': arg('sim')}],
                      remappings=[('steering', arg('steering'))])
    sim = Node(package='lookahead_control', executable='sim_plant', name='sim_plant',
               condition=IfCondition(arg('sim')),
               parameters=[os.path.join(config, 'vehicle.yaml'), {
                   'scenario_file': arg('scenario'), 'output': 'vehicle'}],
               remappings=[('odometry', arg('odometry')), ('path', arg('path')),
                           ('imu', arg('imu')), ('steering', arg('steering'))])
    return LaunchDescription(
        [DeclareLaunchArgument(k, default_value=v) for k, v in args.items()]
        + [bridge, controller, sim])
