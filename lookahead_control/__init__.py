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
Variable look-ahead lateral controller (Hingwe & Tomizuka) for ROS 2 Jazzy.

The package is layered; each layer imports only the layers below it, and
``test/test_layers.py`` enforces it:

- :mod:`lookahead_control.core`: the math and the controller's state machine (parameters,
  schedules, the law, safety, zero dynamics, the certificate, sample types, config files).
  No ROS.
- :mod:`sim_plant` (outside this package, same level as the core): vehicle models, roads,
  scenarios and the offline closed loop; only ``sim_plant.sim_plant_node`` uses ROS.
- :mod:`lookahead_control.ros`: the controller node, message conversions, parameter
  declarations, the shared node ``main()`` and the closed-loop bringup.
- :mod:`lookahead_control.bags`: MCAP bag writing, reading, recovery, columnar decoding,
  run data, and the recorder and replay nodes.
- :mod:`lookahead_control.analysis`: metrics, series from bags, tables and plots.
- :mod:`lookahead_control.tools`: command-line executables only.
"""

# executables only: Ctrl-C while starting is one line, SIGTERM stops like Ctrl-C
from lookahead_control.core.interrupts import install_if_executable

install_if_executable()
