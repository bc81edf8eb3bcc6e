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
Recorded runs: MCAP bags in the rosbag2 layout, and the nodes that record and replay them.

``rosbag_io`` writes, reads and recovers bags through rosbags; ``mcap_columns`` and
``cdr_decode`` read contract topics as numpy columns; ``run_data`` turns a bag into the
arrays of one run and re-runs the controller core on it; ``recorder_node`` and
``replay_node`` are the ``record``/``recover`` and ``replay`` executables.

May import: :mod:`lookahead_control.core`, :mod:`lookahead_control.ros`, :mod:`sim_plant`.
Not analysis or tools.
"""
