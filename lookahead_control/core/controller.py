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
from typing import Any, Optional

from lookahead_control.core.baselines import baseline_law, BASELINE_NAMES, BaselineParams
from lookahead_control.core.control_law import cg_error_from, LateralState, LawOutput
from lookahead_control.core.lane_keeping import CgCompensatedLaw, LaneKeepingParams
from lookahead_control.core.laws import Law, PaperLaw, Preview
from lookahead_control.core.params import check_choice, ControllerParams, VehicleParams
from lookahead_control.core.safety import (check_sample, check_stamp, limit, low_speed_weight,
                                           SafetyParams, stale_target)
from lookahead_control.core.samples import (CurvatureSample, LateralErrorSample, VelocitySample,
                                            YawSample)
import numpy as np

ACCELERATION_SOURCES = ('imu', 'differentiate', 'zero')
LAW_NAMES = ('paper',) + BASELINE_NAMES + ('cg_compensated',)
PREVIEW_HORIZON = 100.0     # [m] how far the curvature slope is extended for the baselines


def build_law(name: str, vehicle: VehicleParams, controller: ControllerParams,
              baselines: BaselineParams,
              lane_keeping: Optional[LaneKeepingParams] = None) -> Law:
    """
    Return the steering law called ``name``.

    :param name: ``paper`` (the look-ahead law, eq. 15 with its schedule) or a baseline
        (``pure_pursuit``, ``stanley``, ``lqr``).
    :param vehicle: the controller's vehicle model.
    :param controller: the paper law's parameters.
    :param baselines: the baselines' parameters.
    :param lane_keeping: the ``cg_compensated`` law's settings (defaults if None;
        docs/lane_keeping.md).
    :return: the law.
    """
    check_choice('law', name, LAW_NAMES)
    if name == 'paper':
        return PaperLaw(vehicle, controller)
    if name == 'cg_compensated':
        return CgCompensatedLaw(vehicle, controller, lane_keeping)
    return baseline_law(name, vehicle, baselines)


# per input: the attribute holding its latest sample, and the method storing a new one
_LATEST = {'lateral_error': 'lateral', 'yaw': 'yaw', 'velocity': 'velocity',
           'road_curvature': 'curvature'}
_UPDATE = {'lateral_error': 'update_lateral_error', 'yaw': 'update_yaw',
           'velocity': 'update_velocity', 'road_curvature': 'update_curvature'}


@dataclass(frozen=True)
class Command:
    """
    One steering command and what produced it.

    :param stamp_ns: stamp of the lateral-error measurement it answers [ns].
    :param steering: front-wheel angle (+ left) [rad].
    :param steering_rate: change since the previous command over the time between them
        [rad/s] (0 for the first).
    :param law: the law's intermediate values (None for a stale-input command).
    :param status: ``ok``, ``low_speed`` (handing over to hold) or ``stale`` (inputs
        timed out: hold, then ramp to the safe angle).
    :param saturated: the angle limit cut the command.
    :param rate_limited: the rate limit cut the command.
    """

    stamp_ns: int
    steering: float
    steering_rate: float
    law: Optional[LawOutput]
    status: str = 'ok'
    saturated: bool = False
    rate_limited: bool = False


class SteeringController:
    """Holds the latest inputs and evaluates the law on demand."""

    def __init__(self, vehicle: VehicleParams, controller: ControllerParams,
                 acceleration_source: str = 'imu', use_preview: bool = False,
                 safety: Optional[SafetyParams] = None, law: str = 'paper',
                 baselines: Optional[BaselineParams] = None,
                 lane_keeping: Optional[LaneKeepingParams] = None) -> None:
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
        :param safety: input and output limits (default limits if None).
        :param law: the steering law, one of :data:`LAW_NAMES`.
        :param baselines: the baseline laws' parameters (defaults if None).
        :param lane_keeping: the ``cg_compensated`` law's settings (defaults if None).
        """
        self.law_name = ''
        self.baselines = baselines or BaselineParams()
        self.lane_keeping = lane_keeping or LaneKeepingParams()
        self.law: Law = PaperLaw(vehicle, controller)
        self._law_stamp: Optional[int] = None
        self._select_law(law, vehicle, controller, self.baselines)
        self.safety = safety or SafetyParams()
        self.rejected: dict[str, int] = {}
        self.last_rejection = ''
        self.time_jumps = 0
        self._received: dict[str, int] = {}
        self._last_now: Optional[int] = None
        self._held: Optional[float] = None
        self._stale_since: Optional[int] = None
        self._hold_value: Optional[float] = None
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
        # the rate limit's reference: the last angle sent (kept across resets: the
        # actuator is still there) and the newest stamp sent (so a command answering an
        # older step, or following a watchdog command, or after a time jump, holds)
        self._rate_angle: Optional[float] = None
        self._rate_time: Optional[int] = None

    def configure(self, vehicle: VehicleParams, controller: ControllerParams,
                  acceleration_source: str, use_preview: bool,
                  safety: Optional[SafetyParams] = None, law: Optional[str] = None,
                  baselines: Optional[BaselineParams] = None,
                  lane_keeping: Optional[LaneKeepingParams] = None) -> None:
        """
        Replace the parameters (between two control steps).

        A new law starts from its reset state; its first command moves from the last one
        sent within the rate limit, like any other.

        :param vehicle: vehicle parameters.
        :param controller: controller parameters.
        :param acceleration_source: see the constructor.
        :param use_preview: see the constructor.
        :param safety: see the constructor (None: keep).
        :param law: see the constructor (None: keep).
        :param baselines: see the constructor (None: keep).
        :param lane_keeping: see the constructor (None: keep).
        """
        self.lane_keeping = lane_keeping or self.lane_keeping
        self._select_law(law or self.law_name, vehicle, controller,
                         baselines or self.baselines)
        self.safety = safety or self.safety
        self.use_preview = use_preview
        self.vehicle = vehicle
        self.params = controller
        self.acceleration_source = check_choice('acceleration_source', acceleration_source,
                                                ACCELERATION_SOURCES)

    def _select_law(self, name: str, vehicle: VehicleParams, controller: ControllerParams,
                    baselines: BaselineParams) -> None:
        """Build the law (raises ParameterError first: the old law stays on error)."""
        law = build_law(name, vehicle, controller, baselines, self.lane_keeping)
        law.reset()
        self.law, self.law_name, self.baselines = law, name, baselines
        self._law_stamp = None

    def preview(self) -> Preview:
        """
        Return the curvature ahead as the laws get it (empty before any curvature).

        The curvature at the CG held ahead; with ``use_preview`` its slope extended over
        :data:`PREVIEW_HORIZON`, within the believable curvature.

        :return: the preview.
        """
        if self.curvature is None:
            return Preview(np.zeros(0), np.zeros(0))
        rho = self.curvature.rho
        if not self.use_preview:
            return Preview(np.zeros(1), np.array([rho]))
        cap = self.safety.max_curvature
        ahead = min(cap, max(-cap, rho + self.curvature.slope * PREVIEW_HORIZON))
        return Preview(np.array([0.0, PREVIEW_HORIZON]), np.array([rho, ahead]))

    # -- checked input ------------------------------------------------------------

    def reset(self) -> None:
        """
        Forget the inputs and the last command (time jumped: replay restart, sim reset).

        The last angle sent stays the rate limit's reference (the actuator is still
        there); the first command after the reset holds it, the next ones move from it.
        """
        self.lateral = self.yaw = self.velocity = self.curvature = None
        self._previous_velocity = None
        self._accel_estimate = 0.0
        self.last = None
        self._rate_time = None
        self._received.clear()
        self._stale_since = None
        self._hold_value = None
        self.law.reset()
        self._law_stamp = None

    def accept(self, name: str, sample: Any, now_ns: Optional[int] = None) -> Optional[str]:
        """
        Check a sample and store it; a refused one is counted and never used.

        A stamp more than 1 s behind the last one of its input, or a node clock gone
        back by more than 1 s, is a time jump: the state is reset instead of producing a
        rate spike, and the sample is accepted.

        :param name: ``lateral_error``, ``yaw``, ``velocity`` or ``road_curvature``.
        :param sample: the converted sample.
        :param now_ns: the node's clock (receive time) [ns].
        :return: None if accepted, else the reason.
        """
        current = getattr(self, _LATEST[name])
        jumped = ((current is not None and sample.stamp_ns < current.stamp_ns - 1_000_000_000)
                  or (now_ns is not None and self._last_now is not None
                      and now_ns < self._last_now - 1_000_000_000))
        if jumped:
            self.time_jumps += 1
            self.reset()
            current = None
        reason = check_sample(name, sample, self.safety) or check_stamp(
            name, sample.stamp_ns, current.stamp_ns if current else None, now_ns, self.safety)
        if reason is not None:
            self.count_rejection(reason)
            return reason
        if now_ns is not None:
            self._received[name] = now_ns
            self._last_now = now_ns
        getattr(self, _UPDATE[name])(sample)
        return None

    def count_rejection(self, reason: str) -> None:
        """
        Count a refused message under ``'<input>: <field or cause>'``.

        :param reason: why it was refused, ``'<input>: <detail>'``.
        """
        name, _, detail = reason.partition(':')
        key = f'{name}: {(detail.split() or ["?"])[0]}'
        self.rejected[key] = self.rejected.get(key, 0) + 1
        self.last_rejection = reason

    def stale(self, now_ns: int) -> list[str]:
        """
        Return the inputs older than the timeout (curvature only once it was seen).

        :param now_ns: the node's clock [ns].
        :return: their names.
        """
        timeout = self.safety.input_timeout * 1e9
        names = ['lateral_error', 'yaw', 'velocity'] + (
            ['road_curvature'] if 'road_curvature' in self._received else [])
        return [n for n in names if n in self._received
                and now_ns - self._received[n] > timeout]

    def safe_command(self, now_ns: int) -> Optional[Command]:
        """
        Return the stale-input command: hold, then ramp to the safe angle.

        :param now_ns: the node's clock [ns]; the command is stamped with this instant
            on the measurements' clock.
        :return: the command, None before any command was sent.
        """
        sent = self._rate_angle
        if sent is None:
            return None
        if self._stale_since is None:
            self._stale_since = now_ns
            self._held = sent
            self.law.reset()            # a law with state restarts after stale inputs
            self._law_stamp = None
        held = self._held if self._held is not None else sent
        wanted = stale_target(held, (now_ns - self._stale_since) * 1e-9, self.safety)
        v_x = self.velocity.v_x if self.velocity else 0.0
        self.last = self._limited(wanted, self._measurement_time(now_ns), v_x, None,
                                  'stale')
        return self.last

    def _measurement_time(self, now_ns: int) -> int:
        """
        Return the node's time on the measurements' clock.

        The last lateral-error stamp plus the time since it arrived. Commands are
        stamped, and rate limited, on the measurements' clock. That clock need not be
        the node's: a replayed bag, or a sensor clock that is not synchronized.

        :param now_ns: the node's clock [ns].
        :return: the same instant on the measurements' clock [ns].
        """
        received = self._received.get('lateral_error')
        if self.lateral is not None and received is not None:
            return self.lateral.stamp_ns + max(0, now_ns - received)
        return self._rate_time if self._rate_time is not None else now_ns

    def _limited(self, wanted: float, stamp_ns: int, v_x: float, law: Optional[LawOutput],
                 status: str) -> Command:
        """
        Apply the output limits to a wanted angle and make it the command sent.

        :param wanted: the angle wanted [rad].
        :param stamp_ns: its stamp [ns].
        :param v_x: the speed, for the angle limit [m/s].
        :param law: the law's output it comes from (None: the watchdog).
        :param status: ``ok``, ``low_speed`` or ``stale``.
        :return: the command.
        """
        sent = self._rate_angle
        dt, newest = self._rate_step(stamp_ns)
        out = limit(wanted, sent, dt, v_x, self.vehicle.wheelbase, self.safety)
        rate = (out.angle - sent) / dt if sent is not None and dt > 0.0 else 0.0
        self._rate_angle = out.angle
        # a watchdog command carries the newest stamp; an answer, its measurement's
        stamp = newest if law is None else stamp_ns
        return Command(stamp, out.angle, float(rate), law, status, out.saturated,
                       out.rate_limited)

    def _rate_step(self, stamp_ns: int) -> tuple[float, int]:
        """
        Advance the rate limit's time axis to a new command's stamp.

        :param stamp_ns: the stamp of the command about to be sent [ns].
        :return: the time the rate limit allows for [s] (0 when the stamp is not newer
            than the last command's: the command holds), and the newest stamp.
        """
        latest = self._rate_time if self._rate_time is not None else stamp_ns
        self._rate_time = max(latest, stamp_ns)
        return max(0, stamp_ns - latest) * 1e-9, self._rate_time

    # -- unchecked input (trusted sources: offline re-runs, tests) ----------------

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
        stamp = self.lateral.stamp_ns
        dt = 0.0 if self._law_stamp is None else max(0, stamp - self._law_stamp) * 1e-9
        self._law_stamp = stamp
        law = self.law.step(state, self.preview(), dt)
        self._stale_since = None
        v_x = float(state.v_x)
        weight = low_speed_weight(v_x, self.safety)
        raw = float(law.steering)
        if weight >= 1.0:
            self._hold_value = raw
        hold = self._hold_value if self._hold_value is not None else 0.0
        wanted = weight * raw + (1.0 - weight) * hold
        self.last = self._limited(wanted, self.lateral.stamp_ns, v_x, law,
                                  'ok' if weight >= 1.0 else 'low_speed')
        return self.last
