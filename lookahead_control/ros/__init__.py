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
The ROS 2 shell: nodes, message conversions, parameter declarations, bringup.

Nodes only declare parameters, convert messages (``conversions``), call the core and
publish. ``node_main`` is the Jazzy ``main()`` every node shares; ``closed_loop`` starts
the sim, the controller and the recorder as processes.

May import: :mod:`lookahead_control.core`, :mod:`sim_plant`, rclpy and ROS messages.
Not bags, analysis or tools.
"""
