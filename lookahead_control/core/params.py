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
Typed, validated parameters of the vehicle and of the controller.

Every dataclass here is frozen and checks itself in ``__post_init__``: an impossible
value raises :class:`ParameterError` naming the field, the value and what is allowed.
Symbols follow ``docs/model.md`` (REP-103 signs, SI units).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from functools import cached_property
import math
from typing import Any, Iterable

from lookahead_control.core import numeric as xp
from lookahead_control.core.numeric import Real

SCHEDULE_MODES = ('paper', 'exact', 'fixed')
REFERENCE_MODES = ('lane_tangent', 'arc_approx', 'arc_exact', 'cg_compensated')


class ParameterError(ValueError):
    """A parameter value that is impossible or inconsistent."""


def check_finite(name: str, value: float) -> float:
    """
    Return ``value`` as float, or raise if it is not a finite number.

    :param name: the parameter's name, used in the message.
    :param value: the value to check.
    :return: the value as a float.
    """
    try:
        number = float(value)
    except (TypeError, ValueError) as err:
        raise ParameterError(f'{name} = {value!r} is not a number; a finite real is '
                             'required') from err
    except OverflowError as err:        # an integer of hundreds of digits (a YAML file)
        text = repr(value)
        shown = text if len(text) <= 20 else f'{text[:12]}...({len(text)} digits)'
        raise ParameterError(f'{name} = {shown} is too large for a real number; a finite '
                             'real is required') from err
    if not math.isfinite(number):
        raise ParameterError(f'{name} = {value!r} is not finite; a finite real is required')
    return number


def check_range(name: str, value: float, low: float, high: float,
                *, low_open: bool = False, unit: str = '') -> float:
    """
    Return ``value`` as float, or raise if it lies outside the allowed range.

    :param name: the parameter's name, used in the message.
    :param value: the value to check.
    :param low: the lower bound.
    :param high: the upper bound (inclusive).
    :param low_open: if true the lower bound itself is not allowed.
    :param unit: unit appended to the message.
    :return: the value as a float.
    """
    number = check_finite(name, value)
    below = number <= low if low_open else number < low
    if below or number > high:
        bracket = '(' if low_open else '['
        suffix = f' {unit}' if unit else ''
        raise ParameterError(
            f'{name} = {value!r}{suffix} is out of range; allowed: {bracket}{low:g}, '
            f'{high:g}]{suffix}')
    return number


def check_choice(name: str, value: str, choices: Iterable[str]) -> str:
    """
    Return ``value``, or raise if it is not one of ``choices``.

    :param name: the parameter's name, used in the message.
    :param value: the value to check.
    :param choices: the allowed values.
    :return: the value.
    """
    allowed = tuple(choices)
    if value not in allowed:
        raise ParameterError(f'{name} = {value!r} is not allowed; choose one of '
                             f'{", ".join(allowed)}')
    return value


def check_flag(name: str, value: Any) -> bool:
    """
    Return ``value``, or raise if it is not a boolean.

    :param name: the parameter's name, used in the message.
    :param value: the value to check.
    :return: the value.
    """
    if not isinstance(value, bool):
        raise ParameterError(f'{name} = {value!r} is not allowed; choose true or false')
    return bool(value)


@dataclass(frozen=True)
class VehicleParams:
    """
    Single-track vehicle parameters (paper Table 1 by default).

    :param mass: vehicle mass m [kg].
    :param yaw_inertia: yaw moment of inertia I_z [kg m^2].
    :param l1: distance from the CG to the front axle [m].
    :param l2: distance from the CG to the rear axle [m].
    :param c_f: front axle cornering stiffness, whole axle [N/rad].
    :param c_r: rear axle cornering stiffness, whole axle [N/rad].
    :param d_s: distance from the CG to the front bumper (look-down sensor) [m].
    :param cg_height: height of the CG above the ground [m]: under a longitudinal
        acceleration ``a_x`` the axle loads move by ``m a_x h / L`` and each axle's
        cornering stiffness with its load (:func:`axle_load_factors`); 0 (the default,
        the paper's model): none.
    """

    mass: float = 1485.0
    yaw_inertia: float = 2872.0
    l1: float = 1.1
    l2: float = 1.58
    c_f: float = 80000.0
    c_r: float = 80000.0
    d_s: float = 1.96
    cg_height: float = 0.0

    _RANGES = {
        'mass': (0.0, 1.0e5, 'kg'),
        'yaw_inertia': (0.0, 1.0e6, 'kg m^2'),
        'l1': (0.0, 20.0, 'm'),
        'l2': (0.0, 20.0, 'm'),
        'c_f': (0.0, 1.0e7, 'N/rad'),
        'c_r': (0.0, 1.0e7, 'N/rad'),
        'd_s': (0.0, 50.0, 'm'),
        'cg_height': (0.0, 3.0, 'm'),
    }

    def __post_init__(self) -> None:
        for item in fields(self):
            low, high, unit = self._RANGES[item.name]
            object.__setattr__(self, item.name, check_range(
                f'vehicle.{item.name}', getattr(self, item.name), low, high,
                low_open=item.name != 'cg_height', unit=unit))

    @cached_property
    def wheelbase(self) -> float:
        """Wheelbase l_1 + l_2 [m]."""
        return self.l1 + self.l2

    @cached_property
    def eta(self) -> float:
        """Zero-dynamics constant eta = m l_1 / (C_r (l_1 + l_2)) [s^2/m]."""
        return self.mass * self.l1 / (self.c_r * self.wheelbase)

    @cached_property
    def understeer_gradient(self) -> float:
        """Understeer gradient K = m l_2 / (C_f L) - m l_1 / (C_r L) [rad s^2/m]."""
        return (self.mass * self.l2 / (self.c_f * self.wheelbase)
                - self.mass * self.l1 / (self.c_r * self.wheelbase))


#: the smallest share of its static load an axle keeps in :func:`axle_load_factors` (a
#: larger transfer lifts the axle: no model of this package holds there)
MIN_LOAD_SHARE = 0.1
#: [m/s^2] the gravity of the axle-load transfer (as the plants' and the estimator's)
LOAD_GRAVITY = 9.80665


def axle_load_factors(vehicle: VehicleParams, a_x: Real) -> tuple[Real, Real]:
    """
    Return each axle's load over its static load under a longitudinal acceleration.

    ``F_zf = m (g l_2 - a_x h) / L``, ``F_zr = m (g l_1 + a_x h) / L`` (``h`` =
    ``cg_height``): the factors ``1 - a_x h / (g l_2)`` and ``1 + a_x h / (g l_1)``, the
    transfer bounded so that each is at least :data:`MIN_LOAD_SHARE` (the total kept).
    Braking loads the front axle. A tyre's cornering stiffness grows with its load (in
    proportion for CommonRoad's Pacejka tyres at small slip), so the axle stiffness is
    ``C`` times the factor.

    :param vehicle: vehicle parameters (``cg_height`` 0: both factors 1, exactly).
    :param a_x: dv_x/dt [m/s^2] (float or array).
    :return: ``(front, rear)`` factors.
    """
    h = vehicle.cg_height
    if h == 0.0:
        return 1.0, 1.0
    # the transfer itself is bounded, so that the load one axle keeps is not made up on
    # the other (dev-probe62: flooring each factor made 3 % more load at 3 m, 77 % at
    # -10 m/s^2)
    keep = 1.0 - MIN_LOAD_SHARE
    transfer = xp.clip(a_x * (h / LOAD_GRAVITY), -keep * vehicle.l1, keep * vehicle.l2)
    return 1.0 - transfer / vehicle.l2, 1.0 + transfer / vehicle.l1


def saturating_accelerations(vehicle: VehicleParams) -> tuple[float, float]:
    """
    Return the a_x beyond which :func:`axle_load_factors` moves no more load.

    :param vehicle: vehicle parameters with ``cg_height`` > 0.
    :return: ``(lowest, highest)`` a_x [m/s^2]: the transfer's bounds over ``h / g``.
    """
    keep = (1.0 - MIN_LOAD_SHARE) * LOAD_GRAVITY / vehicle.cg_height
    return -keep * vehicle.l1, keep * vehicle.l2


def loaded_vehicle(vehicle: VehicleParams, a_x: Real) -> VehicleParams:
    """
    Return the vehicle with each axle's cornering stiffness at its load under ``a_x``.

    For a batch (``a_x`` an array) the stiffnesses are arrays, which the checks of
    :class:`VehicleParams` do not take: the copy is made without them (its values come
    from a checked vehicle and :func:`axle_load_factors`' bounded transfer).

    :param vehicle: the vehicle (``cg_height`` 0: returned as it is).
    :param a_x: dv_x/dt [m/s^2] (float or array).
    :return: the vehicle at those loads.
    """
    if vehicle.cg_height == 0.0:
        return vehicle
    front, rear = axle_load_factors(vehicle, a_x)
    out = object.__new__(VehicleParams)
    for item in fields(vehicle):
        object.__setattr__(out, item.name, getattr(vehicle, item.name))
    object.__setattr__(out, 'c_f', vehicle.c_f * front)
    object.__setattr__(out, 'c_r', vehicle.c_r * rear)
    return out


@dataclass(frozen=True)
class ControllerParams:
    """
    Parameters of the input-output linearizing law (eq. 15) and its d_v schedule.

    The error dynamics are ``e'' + k_d e' + k_p e = 0`` with ``k_p = w_n^2`` and
    ``k_d = 2 zeta w_n``.

    :param natural_frequency: w_n of the loop of the regulated error e = y_v - y_ref
        [rad/s].
    :param damping_ratio: zeta of that loop [-].
    :param schedule: d_v schedule: ``paper`` (eq. 26), ``exact`` (eq. 24) or ``fixed``
        (d_v = the vehicle's ``d_s``, the look-down controller; ``VehicleParams.d_s`` is
        the one source of d_s).
    :param max_look_ahead: upper clamp of the scheduled d_v [m].
    :param reference: what ``y_v`` is regulated to: ``lane_tangent`` (0, the paper's
        simulations), ``arc_approx`` (y_o of eq. 4), ``arc_exact`` (y_o of eq. 3) or
        ``cg_compensated`` (``d_v eps_ss``: the CG on the lane, docs/lane_keeping.md).
    :param min_speed: the law divides by v_x; below this speed it uses this speed [m/s].
    """

    natural_frequency: float = 3.0
    damping_ratio: float = 1.0
    schedule: str = 'paper'
    max_look_ahead: float = 60.0
    reference: str = 'lane_tangent'
    min_speed: float = 1.0

    def __post_init__(self) -> None:
        check_range('controller.natural_frequency', self.natural_frequency, 0.0, 100.0,
                    low_open=True, unit='rad/s')
        check_range('controller.damping_ratio', self.damping_ratio, 0.0, 10.0,
                    low_open=True)
        check_choice('controller.schedule', self.schedule, SCHEDULE_MODES)
        check_range('controller.max_look_ahead', self.max_look_ahead, 0.0, 200.0,
                    low_open=True, unit='m')
        check_choice('controller.reference', self.reference, REFERENCE_MODES)
        check_range('controller.min_speed', self.min_speed, 0.0, 20.0, low_open=True,
                    unit='m/s')
        for name in ('natural_frequency', 'damping_ratio', 'max_look_ahead', 'min_speed'):
            object.__setattr__(self, name, float(getattr(self, name)))

    @cached_property
    def k_p(self) -> float:
        """Return the proportional gain k_p = w_n^2 [1/s^2]."""
        return self.natural_frequency ** 2

    @cached_property
    def k_d(self) -> float:
        """Return the derivative gain k_d = 2 zeta w_n [1/s]."""
        return 2.0 * self.damping_ratio * self.natural_frequency
