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
Plant side of lookahead_control: vehicle models, roads, scenarios, the sim node.

The modules here import no ROS except ``sim_plant_node``.
"""

# executables only: Ctrl-C while starting is one line, SIGTERM stops like Ctrl-C
from lookahead_control.core.interrupts import install_if_executable

install_if_executable()
