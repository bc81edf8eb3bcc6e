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
Property-based fuzzing of the checked controller core: no exception, no bad command.

``FUZZ_EXAMPLES`` sets the number of sequences (default 10^4, ``make fuzz``: 10^5).
"""

import math
import os

from hypothesis import given, HealthCheck, settings, strategies as st
from lookahead_control.controller_core import SteeringController
from lookahead_control.conversions import (CurvatureSample, LateralErrorSample,
                                           VelocitySample, YawSample)
from lookahead_control.params import ControllerParams, VehicleParams
from lookahead_control.safety import angle_limit, SafetyParams

EXAMPLES = int(os.environ.get('FUZZ_EXAMPLES', '10000'))
CASES = {'sequences': 0, 'messages': 0}
SAFETY = SafetyParams()
VEHICLE = VehicleParams()

adversarial = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1e-300, -1e-300, 1e300, float('nan'), float('inf'),
                     -float('inf'), 0.99, 1.01]),
    st.floats(-100.0, 100.0))
stamps = st.one_of(st.integers(0, 10**12), st.sampled_from([0, 1, 2**62]))
message = st.one_of(
    st.tuples(st.just('lateral_error'), stamps, adversarial, adversarial),
    st.tuples(st.just('yaw'), stamps, adversarial, adversarial, adversarial),
    st.tuples(st.just('velocity'), stamps, adversarial, adversarial),
    st.tuples(st.just('road_curvature'), stamps, adversarial, adversarial),
    st.tuples(st.just('tick'), stamps))
SAMPLES = {'lateral_error': LateralErrorSample, 'yaw': YawSample,
           'velocity': VelocitySample, 'road_curvature': CurvatureSample}


@settings(max_examples=EXAMPLES, deadline=None, database=None,
          suppress_health_check=list(HealthCheck))
@given(st.lists(message, max_size=30),
       st.sampled_from(['paper', 'exact', 'fixed']),
       st.sampled_from(['imu', 'differentiate', 'zero']))
def test_no_input_sequence_gives_a_bad_command(sequence, schedule, acceleration):
    core = SteeringController(VEHICLE, ControllerParams(schedule=schedule), acceleration,
                              True, SAFETY)
    CASES['sequences'] += 1
    previous = None
    for item in sequence:
        CASES['messages'] += 1
        name, stamp = item[0], item[1]
        if name == 'tick':
            command = core.safe_command(stamp) if core.stale(stamp) else core.compute()
        else:
            core.accept(name, SAMPLES[name](stamp, *item[2:]), stamp)
            command = core.compute() if name == 'lateral_error' else None
        if command is None:
            continue
        assert math.isfinite(command.steering) and math.isfinite(command.steering_rate)
        v_x = core.velocity.v_x if core.velocity else 0.0
        assert abs(command.steering) <= angle_limit(v_x, VEHICLE.wheelbase, SAFETY) + 1e-12
        if previous is not None and command.stamp_ns > previous.stamp_ns:
            dt = (command.stamp_ns - previous.stamp_ns) * 1e-9
            assert abs(command.steering - previous.steering) <= \
                SAFETY.max_steering_rate * dt + 1e-9
        previous = command


def test_zz_report_the_fuzz_count():
    print(f"\nfuzz: {CASES['sequences']} sequences, {CASES['messages']} messages, "
          '0 commands out of limits')
    assert CASES['sequences'] >= EXAMPLES or CASES['sequences'] == 0
