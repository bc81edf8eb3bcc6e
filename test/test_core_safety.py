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

"""The output limits' reference: the last angle sent and the newest stamp sent."""

from lookahead_control.core.controller import SteeringController
from lookahead_control.core.params import ControllerParams, VehicleParams
from lookahead_control.core.safety import SafetyParams
from lookahead_control.ros.conversions import LateralErrorSample, VelocitySample, YawSample

SAFETY = SafetyParams(max_steering_rate=0.1)
MS = 1_000_000


def _core():
    return SteeringController(VehicleParams(), ControllerParams(), 'imu', True, SAFETY)


def _step(core, stamp, y):
    for name, sample in (('yaw', YawSample(stamp, 0.0, 0.0, 0.0)),
                         ('velocity', VelocitySample(stamp, 25.0, 0.0)),
                         ('lateral_error', LateralErrorSample(stamp, 1.96, y))):
        assert core.accept(name, sample, stamp) is None
    return core.compute()


def test_an_answer_older_than_a_watchdog_command_holds_instead_of_jumping():
    core = _core()
    first = _step(core, 1000 * MS, 0.5).steering
    assert first < -0.005
    # inputs stale: the watchdog holds at t = 1.3 s (stamped with its clock)
    assert core.safe_command(1300 * MS).steering == first
    # a late answer stamped 1.25 s with a very different error: no time has passed on
    # the rate limit's axis since 1.3 s, so it holds
    late = _step(core, 1250 * MS, -0.5)
    assert late.steering == first and late.stamp_ns == 1250 * MS and late.rate_limited
    # 0.1 s past the watchdog command: at most 0.1 rad/s * 0.1 s further
    later = _step(core, 1400 * MS, -0.5)
    assert 0.0 < later.steering - first <= 0.1 * 0.1 + 1e-12


def test_a_time_jump_resets_the_inputs_but_not_the_angle_reference():
    core = _core()
    _step(core, 10_000 * MS, 0.5)
    before = _step(core, 10_010 * MS, 0.5).steering
    # a replay restarts at t = 0: the state resets, the first answer holds the angle
    # the actuator still has, and the next ones move within the rate limit
    after = _step(core, 0, -0.5)
    assert core.time_jumps == 1
    assert after.steering == before
    moved = _step(core, 10 * MS, -0.5).steering
    assert 0.0 < moved - before <= 0.1 * 0.01 + 1e-12


def test_sensors_on_another_clock_do_not_freeze_the_command_after_a_stale_period():
    # the node's clock runs 100 s ahead of the sensors' (a replayed bag, no time sync)
    core, offset = _core(), 100_000 * MS

    def step(stamp, y):
        for name, sample in (('yaw', YawSample(stamp, 0.0, 0.0, 0.0)),
                             ('velocity', VelocitySample(stamp, 25.0, 0.0)),
                             ('lateral_error', LateralErrorSample(stamp, 1.96, y))):
            assert core.accept(name, sample, stamp + offset) is None
        return core.compute()

    first = step(1000 * MS, 0.5).steering
    # stale: the watchdog's commands are stamped on the sensors' clock, not the node's
    held = core.safe_command(1300 * MS + offset)
    assert held.stamp_ns == 1300 * MS and held.steering == first
    ramped = core.safe_command(2000 * MS + offset).steering
    assert first < ramped <= 0.0
    # inputs return: the law's answers move again, within the rate limit
    angles = [step((2000 + 100 * k) * MS, -0.5).steering for k in range(1, 6)]
    assert angles[0] > ramped
    for before, after in zip([ramped] + angles, angles):
        assert 0.0 <= after - before <= 0.1 * 0.1 + 1e-12
