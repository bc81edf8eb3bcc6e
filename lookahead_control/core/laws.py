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
The steering-law interface every lateral controller implements (ROS-free).

A law turns one measurement of the vehicle (:class:`LateralState`) and the road ahead
(:class:`Preview`) into one steering command (:class:`LawOutput`). The offline runner
(``sim_plant.closed_loop_sim.run``), the sweep and compare tools call every law through
this interface, so every law gets the same inputs, actuator and plant.

The contract:

- ``reset() -> None`` clears all internal state (integrators, filters, delay buffers).
  A runner calls it once before the first step of a run or batch. A law whose
  ``reset`` keeps a model of the car (the default law's actuator model: after stale
  inputs the node's wheel is still where it was) also has ``start() -> None``, a new
  run from rest; the offline runner calls ``start`` when a law has it, so that a run
  never depends on the run before it.
- ``step(state, preview, dt) -> LawOutput`` gives one command. ``dt`` is the time since
  the previous step [s], 0 on the first step after ``reset``. The fields of ``state``
  are floats (one run) or numpy arrays of one shape (a batch of runs, one element per
  run); ``preview.curvatures`` then has that shape with one more leading axis. A law
  with internal state keeps it in arrays of the batch's shape, created on the first
  step after ``reset`` (e.g. ``0.0 * state.y_cg``). Write laws with
  :mod:`lookahead_control.core.numeric` so one code path serves floats and arrays, and
  never let a batch's runs mix (no reductions over the batch axis).
- :class:`LawOutput` (``core/control_law.py``): ``steering`` [rad, + left] is the
  command. A law fills the other fields that have a meaning for it and puts in the rest
  what its docstring says; never NaN (the runner records every field): :func:`output`
  fills unnamed fields with zeros of the command's shape. The conventions: ``d_v`` the
  distance ahead of the CG at which the law measures its error (0 if none),
  ``y_v``/``y_v_rate`` the lateral error it regulates and its rate, ``y_ref`` its
  reference, ``error``/``error_rate`` the regulated error and its rate, ``f_v``,
  ``beta_1`` the drift and input gain of an input-output linearization (0 and 0 for a
  law that has none).

The paper's law is :class:`PaperLaw`; it is stateless and gives, bit for bit, what
:func:`~lookahead_control.core.control_law.steering_law` gives.
"""

from __future__ import annotations

from typing import Any, NamedTuple, Protocol, runtime_checkable, Sequence

from lookahead_control.core.control_law import LateralState, LawOutput, steering_law
from lookahead_control.core.numeric import Real
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
from lookahead_control.core.samples import one_per_distance
import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]


class Preview(NamedTuple):
    """
    Road curvature ahead of the CG, as the node gets it from the ``road_curvature`` polygon.

    :param distances: distances ahead of the CG along the road [m], ascending, shape
        ``(K,)``; the first may be 0 (the curvature at the CG).
    :param curvatures: curvature at each distance [1/m, + left], shape ``(K,)`` for one
        run or ``(K,) + batch shape`` for a batch.
    """

    distances: Array
    curvatures: Array

    def at(self, distance: Real) -> Real:
        """
        Return the curvature ``distance`` ahead, interpolated linearly between points.

        Before the first and beyond the last point the end values hold. An empty preview
        gives 0 (a straight road).

        :param distance: distance ahead of the CG [m] (a float, or an array of the
            batch's shape: one distance per run).
        :return: curvature [1/m] (a float for one run, else an array of the batch shape).
        """
        d, k = self.distances, self.curvatures
        if d.size == 0:
            return 0.0 * np.asarray(distance, dtype=float) if isinstance(
                distance, np.ndarray) else 0.0
        if k.ndim == 1 and not isinstance(distance, np.ndarray):
            return float(np.interp(distance, d, k))
        batch = k.shape[1:]
        dist = np.broadcast_to(np.asarray(distance, dtype=float), batch)
        if d.size == 1:
            return np.broadcast_to(k[0], batch).astype(float)
        idx = np.clip(np.searchsorted(d, dist, side='right') - 1, 0, d.size - 2)
        x0, x1 = d[idx], d[idx + 1]
        k0 = np.take_along_axis(k.reshape(d.size, -1), idx.reshape(1, -1), 0).reshape(batch)
        k1 = np.take_along_axis(k.reshape(d.size, -1), (idx + 1).reshape(1, -1),
                                0).reshape(batch)
        w = np.clip((dist - x0) / (x1 - x0), 0.0, 1.0)
        return k0 + w * (k1 - k0)


def preview_from_points(points: Sequence[tuple[float, float]]) -> Preview:
    """
    Return the preview of ``(distance ahead, curvature)`` points (the polygon's x, y).

    Points are sorted by distance, one per distance (as
    :func:`lookahead_control.core.samples.one_per_distance`). Points behind the
    CG (negative distance) are kept: :meth:`Preview.at` interpolates across 0.

    :param points: the points.
    :return: the preview (one run).
    :raises ParameterError: a distance or curvature is not finite.
    """
    given = [(float(a), float(b)) for a, b in points]
    for dist, rho in given:
        if not (np.isfinite(dist) and np.isfinite(rho)):
            raise ParameterError(f'preview point ({dist!r}, {rho!r}) is not finite; '
                                 'finite distance [m] and curvature [1/m] required')
    kept = one_per_distance(given)
    return Preview(np.array([p[0] for p in kept], dtype=float),
                   np.array([p[1] for p in kept], dtype=float))


NO_PREVIEW = Preview(np.zeros(0), np.zeros(0))


@runtime_checkable
class Law(Protocol):
    """A lateral steering law: see the module docstring for the contract."""

    def reset(self) -> None:
        """Clear all internal state (integrators, filters, delay buffers)."""

    def step(self, state: LateralState, preview: Preview, dt: float) -> LawOutput:
        """
        Return one steering command.

        :param state: the measured vehicle and road state (floats or batch arrays).
        :param preview: the curvature ahead of the CG.
        :param dt: time since the previous step [s]; 0 on the first after ``reset``.
        :return: the command and its intermediate values.
        """


def output(steering: Real, **fields: Real) -> LawOutput:
    """
    Return a :class:`LawOutput` with ``steering`` and the named fields, zeros elsewhere.

    :param steering: the command [rad].
    :param fields: any other :class:`LawOutput` fields.
    :return: the output; unnamed fields are ``0.0 * steering`` (the batch's shape).
    :raises TypeError: a name is not a :class:`LawOutput` field.
    """
    unknown = set(fields) - set(LawOutput._fields)
    if unknown:
        raise TypeError(f'not LawOutput fields: {sorted(unknown)}')
    zero = 0.0 * steering
    return LawOutput(steering, *(fields.get(name, zero) for name in LawOutput._fields[1:]))


class PaperLaw:
    """
    The paper's input-output linearizing law with its d_v schedule, as a :class:`Law`.

    Stateless: ``step`` is :func:`~lookahead_control.core.control_law.steering_law` on the
    state (its ``rho`` and ``rho_rate`` carry the road; the preview is not used), so the
    results are bit-identical to calling it. Every :class:`LawOutput` field has its
    meaning in that function's docstring.
    """

    def __init__(self, vehicle: VehicleParams, controller: Any,
                 curvature_rate: bool = True) -> None:
        """
        Wrap the law.

        :param vehicle: the controller's vehicle model.
        :param controller: :class:`~lookahead_control.core.params.ControllerParams`, or
            :class:`GainBatch` (one set of gains per run of a batch).
        :param curvature_rate: feed the state's ``rho_rate`` forward; False: 0, as the
            controller node runs the law without ``use_curvature_preview`` (its default).
        """
        self.vehicle = vehicle
        self.controller = controller
        self.curvature_rate = curvature_rate

    @classmethod
    def batch(cls, vehicle: VehicleParams, controllers: Sequence[ControllerParams]
              ) -> 'PaperLaw':
        """
        Return the law of a batch of runs, one set of gains each.

        :param vehicle: the controller's vehicle model.
        :param controllers: one per run; schedule and reference must agree.
        :return: the law.
        """
        return cls(vehicle, GainBatch(controllers))

    def reset(self) -> None:
        """Nothing to clear: the law has no internal state."""

    def step(self, state: LateralState, preview: Preview, dt: float) -> LawOutput:
        """
        Evaluate eq. 15 with the scheduled look-ahead.

        :param state: the measured state.
        :param preview: unused (the state's ``rho``, ``rho_rate`` carry the road).
        :param dt: unused.
        :return: the command.
        """
        if not self.curvature_rate:
            state = state._replace(rho_rate=0.0 * state.rho_rate)
        return steering_law(state, self.vehicle, self.controller)


class GainBatch:
    """
    :class:`ControllerParams` of a batch: per-run arrays where the runs differ.

    Duck-typed for :func:`~lookahead_control.core.control_law.steering_law`: ``k_p``,
    ``k_d``, ``min_speed`` are arrays of shape ``(N,)``; the modes
    (``schedule``, ``reference``) and ``max_look_ahead`` must be the same in every run.
    """

    def __init__(self, controllers: Sequence[ControllerParams]) -> None:
        """
        Stack the controllers.

        :param controllers: one per run, at least one.
        :raises ParameterError: the list is empty or the modes differ.
        """
        if not controllers:
            raise ParameterError('a gain batch needs at least one controller')
        first = controllers[0]
        for name in ('schedule', 'reference', 'max_look_ahead'):
            values = {getattr(c, name) for c in controllers}
            if len(values) > 1:
                raise ParameterError(f'controller.{name} differs within a batch '
                                     f'({sorted(map(str, values))}); run one batch each')
        self.schedule = first.schedule
        self.reference = first.reference
        self.max_look_ahead = first.max_look_ahead
        self.controllers = tuple(controllers)
        self.k_p = np.array([c.k_p for c in controllers])
        self.k_d = np.array([c.k_d for c in controllers])
        self.min_speed = np.array([c.min_speed for c in controllers])
        self.natural_frequency = np.array([c.natural_frequency for c in controllers])
        self.damping_ratio = np.array([c.damping_ratio for c in controllers])
