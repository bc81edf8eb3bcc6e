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

"""The float and array forms of the core's math agree bit for bit on any CPU."""

import math

from lookahead_control.core import numeric as xp
import numpy as np
import pytest


@pytest.mark.parametrize('name,args', [
    ('sin', 1), ('cos', 1), ('tan', 1), ('sqrt', 1), ('atan2', 2), ('power', 1)])
def test_a_float_equals_its_one_element_array(name, args):
    # numpy dispatches SIMD (SVML) kernels on AVX-512 CPUs whose tan, atan2 and powers
    # differ from the C library's in the last bit: a law or plant run on floats then
    # left the same run as a batch (on such a machine before: 106 of 20000 tan, 1565 of
    # 20000 atan2, about 1000 of 20000 cube roots differed)
    rng = np.random.default_rng(7)
    values = rng.uniform(-3.0, 3.0, (20000, 2))
    if name in ('sqrt', 'power'):
        values = np.abs(values)
    function = getattr(xp, name)
    for row in values:
        if name == 'power':
            single, batch = function(float(row[0]), 1.0 / 3.0), function(row[:1], 1.0 / 3.0)
        elif args == 2:
            single = function(float(row[0]), float(row[1]))
            batch = function(row[:1], row[1:])
        else:
            single, batch = function(float(row[0])), function(row[:1])
        assert isinstance(single, float)
        assert single == float(batch[0]) or (math.isnan(single) and math.isnan(batch[0]))
