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
The controller node's output stage around a law, for the offline runner (ROS-free).

The node does not send the law's command: :class:`~lookahead_control.core.controller.
SteeringController` blends it to a hold below ``safety.low_speed``, clamps it to the
speed-dependent angle limit ``atan(a_lat L / v_x^2)`` (0.0587 rad at 37 m/s with the
defaults), limits its rate, and tells the law what was sent (``note_limited``: the
anti-windup of the default law; ``note_sent``: its state filter's actuator model).
:class:`NodeOutputStage` does the same to a law of the offline runner, element-wise
over a batch, so an offline run answers what the node sends on the same inputs. It
leaves out what exact and timely inputs never meet: the input checks, stale inputs,
and the node clock's second reference of the rate limit.
"""

from __future__ import annotations

from typing import Any, Optional

from lookahead_control.core.control_law import LateralState, LawOutput
from lookahead_control.core.laws import Law, Preview
from lookahead_control.core.safety import (limit_batch, low_speed_weight, per_element,
                                           SafetyParams)
import numpy as np

#: the node's parameters the stage runs
OUTPUT_STAGE = ('safety.max_steering_angle', 'safety.max_steering_rate',
                'safety.max_lateral_acceleration', 'safety.low_speed',
                'safety.low_speed_blend')


class NodeOutputStage:
    """
    A :class:`~lookahead_control.core.laws.Law` sending what the node sends for ``law``.

    Other attributes are the wrapped law's (``controller``, diagnostics).
    """

    def __init__(self, law: Law, wheelbase: float, safety: SafetyParams) -> None:
        """
        Wrap a law.

        :param law: the law.
        :param wheelbase: l_1 + l_2 of the node's vehicle model [m] (the angle limit's).
        :param safety: the node's limits (``safety.*``).
        """
        self.law = law
        self.wheelbase = wheelbase
        self.safety = safety
        self.sent: Optional[Any] = None     # the last command sent (None: none yet)
        self.hold: Any = 0.0                # the last command sent above the low speed

    def __getattr__(self, name: str) -> Any:
        """Give the wrapped law's attribute (only called for names this class lacks)."""
        if name == 'law':           # not set yet (copy, unpickling): no recursion
            raise AttributeError(name)
        return getattr(self.law, name)

    def reset(self) -> None:
        """
        Clear the law and the stage: no command sent yet, no hold.

        The node's own reset (stale inputs, a time jump) keeps the last angle sent as its
        rate limit's reference and low-speed hold; the offline runner resets only before
        a run, from rest.
        """
        self.law.reset()
        self.sent, self.hold = None, 0.0

    def start(self) -> None:
        """Start a new run from rest: the law's ``start`` where it has one, else reset."""
        getattr(self.law, 'start', self.law.reset)()
        self.sent, self.hold = None, 0.0

    def step(self, state: LateralState, preview: Preview, dt: float) -> LawOutput:
        """
        Return the law's output with the command the node would send.

        :param state: the measured state.
        :param preview: the curvature ahead.
        :param dt: time since the previous step [s] (0 with a command sent before: that
            command is held, as the node holds it).
        :return: the law's output, ``steering`` replaced by the command sent.
        """
        out = self.law.step(state, preview, dt)
        s = self.safety
        weight = per_element(lambda v: low_speed_weight(v, s), state.v_x)
        raw = np.asarray(out.steering, dtype=float)
        with np.errstate(invalid='ignore'):
            blended = np.where(weight >= 1.0, raw, weight * raw + (1.0 - weight) * self.hold)
        wanted: Any = (float(blended) if np.ndim(out.steering) == 0 and np.ndim(state.v_x) == 0
                       else blended)
        angle, cut = limit_batch(wanted, self.sent, dt, state.v_x, self.wheelbase, s)
        # the hold is the command sent above the low speed, as the node's
        held = np.where(weight >= 1.0, angle, self.hold)
        self.hold = float(held) if np.ndim(held) == 0 else held
        note_limited = getattr(self.law, 'note_limited', None)
        if note_limited is not None:
            note_limited(cut)
        note_sent = getattr(self.law, 'note_sent', None)
        if note_sent is not None:
            note_sent(angle)
        self.sent = angle
        return out._replace(steering=angle)
