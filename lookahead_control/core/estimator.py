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
Online estimate of the rear axle's compliance from measured v_y and r (no tyre model).

The rear slip angle ``alpha_r = (l_2 r - v_y) / v_x`` and the rear force
``F_yr = (m l_1 a_y - I_z r') / (l_1 + l_2)`` of the single-track model give
``alpha_r = c phi`` with ``phi = F_yr (l_1 + l_2) / (m l_1) = v_x r + v_y' - I_z r' /
(m l_1)`` (a lateral acceleration) and ``c`` the rear compliance: ``eta = m l_1 / (C_r
(l_1 + l_2))`` for the model's linear tyres, the secant compliance at the present load
for any other tyre. ``c`` is estimated by regularized least squares with exponential
forgetting ``T``:

- the regression's signals pass ``F = 1 / (T_f s + 1)``; the derivatives of ``v_y`` and
  ``r`` are taken through it (``s F``), so no raw derivative of a noisy signal is used;
- ``c = (N + p^2 eta) / (D + p^2)`` with ``N' = (F alpha_r F phi - N) / T`` and
  ``D' = ((F phi)^2 - D) / T``: the model's ``eta`` holds until the lateral
  acceleration exceeds ``p``; clipped to ``[eta / k, eta k]``.
- memory (``memory_time`` ``T_m`` > 0): the same statistics ``N_m``, ``D_m`` with the
  slower ``T_m``, counted only while the tyres are loaded (each sample weighted by
  ``phi^2 / (phi^2 + p^2)``) and where the caller says (``remember``), give ``c_m = (N_m
  + p^2 eta) / (D_m + p^2)`` clipped to ``[eta / k_m, eta k_m]``, and the estimate falls
  back to ``c_m`` instead of ``eta``: ``c = (N + p^2 c_m) / (D + p^2)``. A straight does
  not erase what the last curves taught (the tyres do not change between two curves),
  so a second curve is not driven on the model's compliance again. ``k_m`` is narrower
  than ``k``: the memory holds what a car's tyres and load can be, not a slide's
  compliance (a tyre past its grip on a wet road) or a gust's. ``memory_seed`` ``s``
  replaces ``eta`` in the memory's prior, ``c_m = (N_m + p^2 s eta) / (D_m + p^2)``: a
  car whose compliance an earlier run learned starts (and restarts) from it, and its
  first curve is not driven on the model's compliance.

Load-dependent compliance (``friction > 0``): a brush tyre's secant compliance grows
with its load, ``c(a) = c_hat s(|a| / (mu g))`` with the design friction ``mu`` and
:func:`brush_shape` ``s``. The estimator then learns only the scale ``c_hat`` (the
regressor is ``s(|phi| / (mu g)) phi``; ``c_hat = eta`` for the nominal tyre), and the
law evaluates ``c`` at the lateral acceleration of the curve ahead: the compliance of a
curve is known before the tyres are loaded. A two-parameter form ``c(a) = theta_1 +
theta_2 |a|`` was tried instead and measured worse under sensor noise: on a single curve
the two are not separable (``docs/lane_keeping.md``).

Axle-load transfer (the vehicle's ``cg_height`` > 0): under ``a_x`` the rear axle carries
``f_r`` (:func:`~lookahead_control.core.params.axle_load_factors`) of its static load, and
a tyre's stiffness and friction limit go with its load, so the rear compliance is ``c /
f_r`` and the shape's load ratio ``|a| / (mu g f_r)``. The estimator then learns the
scale over the loaded compliance (the regressor is divided by ``f_r`` of the sample's
``a_x``, clipped where the transfer saturates and passed through ``F`` as the other
signals) and :meth:`ComplianceEstimator.at` gives the compliance at the present ``a_x``:
a braking step moves it at once, where an estimate of the compliance itself would
follow about a second later (``docs/lane_keeping.md``, "Axle-load transfer").
Everything works on floats and on numpy arrays (a batch).
"""

from __future__ import annotations

import itertools
import math
from typing import Any, Optional

from lookahead_control.core import numeric as xp
from lookahead_control.core.control_law import LateralState
from lookahead_control.core.numeric import Real
from lookahead_control.core.params import (axle_load_factors, saturating_accelerations,
                                           VehicleParams)
import numpy as np

GRAVITY = 9.80665
#: numbers for the memory's starts, unique in a process: a law built anew (a switch of
#: ``law`` away and back) starts its memory under another number than the old law's
_GENERATIONS = itertools.count(1)
#: highest load ratio ``|a| / (mu g)`` the shape is evaluated at (beyond it the tyre
#: saturates; the shape is 1.79, its slope 4.6)
MAX_LOAD = 0.9


def brush_shape(load: Real) -> tuple[Real, Real]:
    """
    Return the secant and tangent compliance of a brush (Fiala) axle over the linear one.

    The Fiala axle force is ``F / F_max = 1 - (1 - u)^3`` with ``u = C tan(alpha) /
    (3 F_max)``; in steady cornering the axle's load ratio is ``n = F / F_max = |a| /
    (mu g)``, so ``tan(alpha) = 3 F_max (1 - (1 - n)^(1/3)) / C`` and the slip per
    lateral acceleration over the linear tyre's ``F_max / (C mu g n)`` is ::

        secant s(n) = 3 (1 - (1 - n)^(1/3)) / n,   tangent d(n s) / dn = (1 - n)^(-2/3)

    both 1 at ``n = 0``; ``n`` is clipped to ``[0, MAX_LOAD]``.

    :param load: load ratio ``|a_y| / (mu g)`` [-] (float or array).
    :return: ``(secant, tangent)`` factors [-].
    """
    n = xp.clip(xp.absolute(load), 0.0, MAX_LOAD)
    root = xp.power(1.0 - n, 1.0 / 3.0)
    small = n < 1e-6
    secant = xp.where(small, 1.0 + n / 3.0,
                      3.0 * (1.0 - root) / xp.where(small, 1.0, n))
    return secant, 1.0 / (root * root)


class ComplianceEstimator:
    """Rear-compliance estimate (rear slip per lateral acceleration) from v_y and r."""

    def __init__(self, vehicle: VehicleParams, time_constant: float, filter_time: float,
                 prior: float, ratio: float, friction: float = 0.0,
                 memory_time: float = 0.0, memory_ratio: float = math.inf,
                 memory_seed: float = 1.0) -> None:
        """
        Create the estimator.

        :param vehicle: the design vehicle (eta, l_2, m, l_1, I_z).
        :param time_constant: forgetting time ``T`` [s] (> 0).
        :param filter_time: ``T_f`` of the signal filter [s] (> 0).
        :param prior: ``p``: lateral acceleration below which ``eta`` holds [m/s^2].
        :param ratio: ``k``: the estimate stays in ``[eta / k, eta k]``.
        :param friction: design friction ``mu`` of the load-dependent shape; 0: constant
            compliance (the estimate is the secant compliance itself).
        :param memory_time: ``T_m`` of the memory the estimate falls back to [s]; 0: it
            falls back to ``eta``.
        :param memory_ratio: ``k_m``: the memory stays in ``[eta / k_m, eta k_m]``
            (at most ``k``; inf: ``k``).
        :param memory_seed: ``s``: the memory's prior is ``s eta`` instead of ``eta``
            (what it starts from and returns to after a reset) [-].
        """
        self.vehicle = vehicle
        self.time_constant = time_constant
        self.filter_time = filter_time
        self.prior = prior
        self.ratio = ratio
        self.friction = friction
        self.memory_time = memory_time
        self.memory_ratio = min(memory_ratio, ratio)
        self.memory_seed = memory_seed
        #: the filtered rear slip, ``v_x r``, ``w`` and ``a_x`` (``F``)
        self.filtered: Optional[tuple[Real, Real, Real, Real]] = None
        self.moment: Real = 0.0          # N [rad m/s^2]
        self.energy: Real = 0.0          # D [m^2/s^4]
        self.memory_moment: Real = 0.0   # N_m [rad m/s^2]
        self.memory_energy: Real = 0.0   # D_m [m^2/s^4]
        #: a number that changes whenever the memory starts from its seed again (a
        #: reset, a new law, a retune that did not carry it): a run's record then tells
        #: what it learned since (``analyze``)
        self.generation = next(_GENERATIONS)

    def reset(self) -> None:
        """Forget everything learned, the memory too (back to its seed, ``s eta``)."""
        self.generation = next(_GENERATIONS)
        self.filtered = None
        self.moment = 0.0
        self.energy = 0.0
        self.memory_moment = 0.0
        self.memory_energy = 0.0

    def update(self, state: LateralState, dt: float, active: Any,
               running: Any = True, remember: Any = None) -> None:
        """
        Take one measurement.

        :param state: the measured state (``v_y``, ``r``, ``v_x``).
        :param dt: time since the previous update [s] (0: the filters only start).
        :param active: where false (per run), nothing is learned from this sample.
        :param running: where false (per run; below the law's speed floor, where
            ``(l_2 r - v_y) / v_x`` is no rear slip, e.g. a speed read as 0 for a
            moment), the signal filters restart at the next sample where it holds,
            instead of carrying this sample into the first ones learned from after it;
            what was learned is kept.
        :param remember: where false (per run), the memory learns nothing from this
            sample (None: where ``active``).
        """
        veh = self.vehicle
        v_x = xp.maximum(state.v_x, 1.0)
        slip = (veh.l2 * state.r - state.v_y) / v_x
        turn = v_x * state.r
        w = state.v_y - veh.yaw_inertia / (veh.mass * veh.l1) * state.r
        # a_x through the same filter: the load factor of the filtered regressor, and
        # no bias from a noisy a_x (the mean of 1 / f_r over the noise is not 1 / f_r:
        # dev-probe63, a raw a_x with 3 m/s^2 of noise learnt the scale 7 % low)
        a_x = state.a_x
        if veh.cg_height > 0.0:
            # beyond the a_x at which the transfer saturates the factor does not move: a
            # huge a_x (1e4) would linger in the filter for seconds (dev-probe64)
            a_x = xp.clip(a_x, *saturating_accelerations(veh))
        signals = (slip, turn, w, 0.0 * slip + a_x)
        if self.filtered is None:
            self.filtered = signals
        elif isinstance(self.filtered[0], np.ndarray):
            # runs of a batch forgotten after a bad input (NaN) start again here, as
            # one run does after reset()
            self.filtered = tuple(   # type: ignore[assignment]
                np.where(np.isnan(old), new, old) for old, new in zip(self.filtered, signals))
        assert self.filtered is not None
        f = min(dt / self.filter_time, 1.0)
        f_slip, f_turn, f_w, f_ax = (old + f * (new - old) for old, new in
                                     zip(self.filtered, signals))
        self.filtered = (f_slip, f_turn, f_w, f_ax)
        # the backward difference of the filtered w: (w - F w) / (T_f - dt) exactly
        phi = f_turn + (w - f_w) / max(self.filter_time - dt, 1e-3)
        if veh.cg_height > 0.0:
            # the scale over the compliance at the rear axle's present load
            rear = axle_load_factors(veh, f_ax)[1]
            if self.friction > 0.0:
                phi = phi * brush_shape(phi / (self.friction * GRAVITY * rear))[0]
            phi = phi / rear
        elif self.friction > 0.0:
            phi = phi * brush_shape(phi / (self.friction * GRAVITY))[0]
        zero = 0.0 * slip
        g = xp.where(active, min(dt / self.time_constant, 1.0) + zero, zero)
        self.moment = self.moment + g * (f_slip * phi - self.moment)
        self.energy = self.energy + g * (phi * phi - self.energy)
        if self.memory_time > 0.0:
            # the memory moves only while the tyres are loaded: a straight keeps it
            square = phi * phi
            learn = active if remember is None else remember
            g_m = xp.where(learn, min(dt / self.memory_time, 1.0) + zero, zero) * (
                square / (square + self.prior * self.prior))
            self.memory_moment = self.memory_moment + g_m * (f_slip * phi
                                                             - self.memory_moment)
            self.memory_energy = self.memory_energy + g_m * (square - self.memory_energy)
        if isinstance(running, np.ndarray) and not running.all():
            self.filtered = tuple(np.where(running, x, math.nan)     # type: ignore[assignment]
                                  for x in self.filtered)
        elif not isinstance(running, np.ndarray) and not running:
            self.filtered = None

    def take_over(self, old: 'ComplianceEstimator') -> None:
        """
        Continue from another estimator's statistics (a retune).

        The caller restarts instead where the settings that define the statistics
        (forgetting time, signal filter, design friction, the vehicle's ``cg_height``)
        changed. The estimate is carried as its scale over the model's ``eta``: with
        another design vehicle the moment ``N`` is scaled by the ratio of the two ``eta``
        (``c = (N + p^2 eta) / (D + p^2)`` scales with it), and the signal filters restart
        at the next sample (their rear slip and regressor are the other model's).

        :param old: the estimator it replaces.
        """
        ratio = self.vehicle.eta / old.vehicle.eta
        self.moment = old.moment * ratio if ratio != 1.0 else old.moment
        self.energy = old.energy
        self.generation = old.generation
        if self.memory_time > 0.0:
            self.memory_moment = (old.memory_moment * ratio if ratio != 1.0
                                  else old.memory_moment)
            self.memory_energy = old.memory_energy
        else:
            self.generation = next(_GENERATIONS)    # dropped: the model's eta from here on
        self.filtered = old.filtered if self.vehicle == old.vehicle else None

    def forget(self, where: Any) -> None:
        """
        Reset the runs of a batch where ``where`` holds (after a non-finite input).

        :param where: boolean array over the batch.
        """
        if self.filtered is not None:
            # NaN: the filters restart at the run's next sample (update)
            self.filtered = tuple(      # type: ignore[assignment]
                xp.where(where, math.nan, x) for x in self.filtered)
        self.moment = xp.where(where, 0.0, self.moment)
        self.energy = xp.where(where, 0.0, self.energy)
        self.memory_moment = xp.where(where, 0.0, self.memory_moment)
        self.memory_energy = xp.where(where, 0.0, self.memory_energy)

    def compliance(self) -> Real:
        """
        Return the estimate [s^2/m] (``eta`` before anything is learned).

        With the load-dependent shape it is the scale ``c_hat`` (the compliance at zero
        lateral load), with the load transfer at ``a_x`` 0 (the static axle loads);
        :meth:`at` gives the compliance at a lateral and a longitudinal acceleration. It
        falls back to :meth:`memory` where the last second taught little.

        :return: the estimate, clipped to ``[eta / k, eta k]``.
        """
        eta = self.vehicle.eta
        prior = self.prior * self.prior
        estimate = (self.moment + prior * self.memory()) / (self.energy + prior)
        return xp.clip(estimate, eta / self.ratio, eta * self.ratio)

    def memory(self) -> Real:
        """
        Return the memory the estimate falls back to [s^2/m] (``eta`` without one).

        :return: ``(N_m + p^2 s eta) / (D_m + p^2)`` with the seed ``s``, clipped to
            ``[eta / k_m, eta k_m]``.
        """
        eta = self.vehicle.eta
        if self.memory_time <= 0.0:
            return eta
        prior = self.prior * self.prior
        estimate = (self.memory_moment + prior * self.memory_seed * eta) / (
            self.memory_energy + prior)
        return xp.clip(estimate, eta / self.memory_ratio, eta * self.memory_ratio)

    def memory_weight(self) -> Real:
        """
        Return how much of the memory is learned rather than its seed.

        :return: ``D_m / (D_m + p^2)`` in ``[0, 1)``: 0 before any loaded driving, 1/2
            once the curves it learned weigh as much as the seed (0 without a memory).
        """
        if self.memory_time <= 0.0:
            return 0.0 * self.memory_energy
        return self.memory_energy / (self.memory_energy + self.prior * self.prior)

    def at(self, accel: Real, a_x: Real = 0.0) -> tuple[Real, Real]:
        """
        Return the secant and tangent compliance at a lateral acceleration [s^2/m].

        Secant: rear slip per lateral acceleration; tangent: its derivative d alpha / d a.
        Both are the estimate itself without the load-dependent shape and the load
        transfer; with either, both stay within ``[eta / k, eta k]``.

        :param accel: lateral acceleration (of the curve ahead) [m/s^2].
        :param a_x: longitudinal acceleration [m/s^2]: the rear axle's load (the
            vehicle's ``cg_height`` > 0; else unused).
        :return: ``(secant, tangent)``.
        """
        scale = self.compliance()
        rear: Real = 1.0
        if self.vehicle.cg_height > 0.0:
            rear = axle_load_factors(self.vehicle, a_x)[1]
        elif self.friction <= 0.0:
            return scale, scale
        secant: Real = 1.0
        tangent: Real = 1.0
        if self.friction > 0.0:
            secant, tangent = brush_shape(accel / (self.friction * GRAVITY * rear))
        eta = self.vehicle.eta
        low, high = eta / self.ratio, eta * self.ratio
        return (xp.clip(scale * secant / rear, low, high),
                xp.clip(scale * tangent / rear, low, high))
