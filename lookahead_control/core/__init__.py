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
The core: the controller's math and state machine, free of ROS.

Parameters (``params``), look-ahead schedules (``schedule``), the input-output linearizing
law (``control_law``), the safety layer (``safety``), the stateful controller that the node
wraps (``controller``), the measurement sample types (``samples``), zero dynamics and the
stability certificate (``zero_dynamics``, ``stability``), params-file reading (``config``)
and the command-line plumbing shared by every executable (``cli``).

May import: the standard library, numpy, scipy, yaml. Never rclpy, ROS message packages,
rosbags, or any other layer of this package.
"""
