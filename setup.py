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

"""Package setup: ament_python layout, one console script per executable."""

from glob import glob

from setuptools import find_packages, setup

package_name = 'lookahead_control'

# executable name -> module:function; `ros2 run lookahead_control <name>`
EXECUTABLES = {
    'schedule': 'lookahead_control.tools.analysis_tools:schedule',
    'zero_dynamics': 'lookahead_control.tools.analysis_tools:zero_dynamics_tool',
    'certificate': 'lookahead_control.tools.analysis_tools:certificate_tool',
    'lane_keeping_stability': 'lookahead_control.tools.lane_keeping_tool:stability_tool',
    'paper_scenario': 'lookahead_control.tools.paper_scenario:entry',
    'controller': 'lookahead_control.ros.controller_node:entry',
    'sim_plant': 'sim_plant.sim_plant_node:entry',
    'closed_loop': 'lookahead_control.ros.closed_loop:entry',
    'path_bridge': 'lookahead_control.ros.path_bridge_node:entry',
    'record': 'lookahead_control.bags.recorder_node:entry',
    'recover': 'lookahead_control.bags.recorder_node:recover_entry',
    'replay': 'lookahead_control.bags.replay_node:entry',
    'analyze': 'lookahead_control.tools.analyze_tool:entry',
    'demo': 'lookahead_control.tools.demo:entry',
    'compare': 'lookahead_control.tools.compare:entry',
    'sweep': 'lookahead_control.tools.sweep:entry',
}

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/config/scenarios', glob('config/scenarios/*.yaml')),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='lookahead_control maintainers',
    maintainer_email='maintainers@lookahead-control.dev',
    description='Variable look-ahead lateral controller for ROS 2 Jazzy',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [f'{name} = {target}' for name, target in EXECUTABLES.items()],
    },
)
