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
Analysis: metrics of a run, series from bags, the paper's tables, and plots.

Functions here return data; ``plotting`` imports matplotlib only when a plot is drawn.

May import: :mod:`lookahead_control.core`, :mod:`lookahead_control.bags`,
:mod:`lookahead_control.ros` (through bags), :mod:`sim_plant`. Not tools.
"""
