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
The controller's state between messages: latest inputs, the law, the command.

No ROS here: the node converts messages into samples, hands them over, and publishes
what :meth:`SteeringController.compute` returns. Keeping it here makes the node thin
and the whole input -> command path testable without DDS.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

from lookahead_control.control_law import cg_error_from, LateralState, LawOutput, steering_law
from lookahead_control.conversions import (CurvatureSample, LateralErrorSample,
                                           VelocitySample, YawSample)
from lookahead_control.params import check_choice, ControllerParams, VehicleParams

ACCELERATION_SOURCES = ('imu', 'differentiate', 'zero')


@dataclass(frozen=True)
class Command:
    """
    One steering command and what produced it.

    :param stamp_ns: stamp of the lateral-error measurement it answers [ns].
    :param steering: front-wheel angle (+ left) [rad].
    :param steering_rate: change since the previous command over the time between them
        [rad/s] (0 for the first).
    :param law: the law's intermediate values.
    """

    stamp_ns: int
    steering: float
    steering_rate: float
    law: LawOutput


class SteeringController:
    """Holds the latest inputs and evaluates the law on demand."""

    def __init__(self, vehicle: VehicleParams, controller: ControllerParams,
                 acceleration_source: str = 'imu', use_preview: bool = False) -> None:
        """
        Create the controller state.

        :param vehicle: vehicle parameters.
        :param controller: controller parameters.
        :param acceleration_source: where a_x comes from: ``imu`` (the yaw message's
            body acceleration, corrected by ``+ v_y r``), ``differentiate`` (from v_x) or
            ``zero``.
        :param use_preview: feed ``d rho / dt = v_x d rho / ds`` forward from the
            curvature preview; if false, only the curvature at the CG is used and its
            changes act as a disturbance (as in the paper).
        """
        self.use_preview = use_preview
        self.vehicle = vehicle
        self.params = controller
        self.acceleration_source = check_choice('acceleration_source', acceleration_source,
                                                ACCELERATION_SOURCES)
        self.lateral: Optional[LateralErrorSample] = None
        self.yaw: Optional[YawSample] = None
        self.velocity: Optional[VelocitySample] = None
        self.curvature: Optional[CurvatureSample] = None
        self._previous_velocity: Optional[VelocitySample] = None
        self._accel_estimate = 0.0
        self.last: Optional[Command] = None

    def configure(self, vehicle: VehicleParams, controller: ControllerParams,
                  acceleration_source: str, use_preview: bool) -> None:
        """
        Replace the parameters (between two control steps).

        :param vehicle: vehicle parameters.
        :param controller: controller parameters.
        :param acceleration_source: see the constructor.
        :param use_preview: see the constructor.
        """
        self.use_preview = use_preview
        self.vehicle = vehicle
        self.params = controller
        self.acceleration_source = check_choice('acceleration_source', acceleration_source,
                                                ACCELERATION_SOURCES)

    def update_lateral_error(self, sample: LateralErrorSample) -> None:
        """Store the latest lateral-error sample."""
        self.lateral = sample

    def update_yaw(self, sample: YawSample) -> None:
        """Store the latest yaw sample."""
        self.yaw = sample

    def update_velocity(self, sample: VelocitySample) -> None:
        """Store the latest velocity sample and update the differentiated a_x."""
        previous = self.velocity
        if previous is not None and sample.stamp_ns > previous.stamp_ns:
            dt = (sample.stamp_ns - previous.stamp_ns) * 1e-9
            self._accel_estimate = (sample.v_x - previous.v_x) / dt
        self.velocity = sample

    def update_curvature(self, sample: CurvatureSample) -> None:
        """Store the latest curvature sample."""
        self.curvature = sample

    def missing(self) -> list[str]:
        """Return the names of the inputs never received (curvature is optional)."""
        return [name for name, value in (('lateral_error', self.lateral), ('yaw', self.yaw),
                                         ('velocity', self.velocity)) if value is None]

    def inputs_at(self, stamp_ns: int) -> bool:
        """
        Return True when every received input is at least as new as ``stamp_ns``.

        :param stamp_ns: the lateral-error stamp to wait for [ns].
        :return: whether yaw, velocity (and curvature, once seen) have caught up.
        """
        samples = [self.yaw, self.velocity] + ([self.curvature] if self.curvature else [])
        return all(s is not None and s.stamp_ns >= stamp_ns for s in samples)

    def acceleration(self) -> float:
        """Return a_x from the configured source [m/s^2]."""
        if self.acceleration_source == 'imu' and self.yaw is not None:
            v_y = self.velocity.v_y if self.velocity else 0.0
            return self.yaw.accel_x + v_y * self.yaw.yaw_rate
        if self.acceleration_source == 'differentiate':
            return self._accel_estimate
        return 0.0

    def state(self) -> Optional[LateralState]:
        """Return the law's inputs from the latest samples, None if any is missing."""
        if self.lateral is None or self.yaw is None or self.velocity is None:
            return None
        eps_r = self.yaw.relative_yaw
        rho, slope = (self.curvature.rho, self.curvature.slope) if self.curvature else (
            0.0, 0.0)
        v_x = self.velocity.v_x
        return LateralState(
            y_cg=cg_error_from(self.lateral.value, eps_r, self.lateral.distance),
            eps_r=eps_r, v_y=self.velocity.v_y, r=self.yaw.yaw_rate, v_x=v_x,
            a_x=self.acceleration(), rho=rho,
            rho_rate=v_x * slope if self.use_preview else 0.0)

    def compute(self) -> Optional[Command]:
        """
        Evaluate the law on the latest inputs.

        :return: the command answering the latest lateral error, None if an input is
            missing.
        """
        state = self.state()
        if state is None or self.lateral is None:
            return None
        law = steering_law(state, self.vehicle, self.params)
        stamp = self.lateral.stamp_ns
        rate = 0.0
        if self.last is not None and stamp > self.last.stamp_ns:
            rate = float(law.steering - self.last.steering) / ((stamp - self.last.stamp_ns) * 1e-9)
        self.last = Command(stamp, float(law.steering), float(rate), law)
        return self.last
