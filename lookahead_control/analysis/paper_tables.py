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

"""The paper's analysis as data: schedule and zero-dynamics tables over speed."""

from __future__ import annotations

from typing import Any, Sequence

from lookahead_control.core.params import ControllerParams, VehicleParams
from lookahead_control.core.schedule import exact_look_ahead, paper_look_ahead
from lookahead_control.core.zero_dynamics import zero_dynamics
import numpy as np


PAPER_SPEEDS = (10.0, 20.0, 30.0, 37.0)
PAPER_FIG5_LEGEND = {10.0: 5.0, 20.0: 11.6, 30.0: 18.2, 37.0: 22.8}


def speed_grid(v_min: float, v_max: float, step: float) -> list[float]:
    """
    Return speeds from ``v_min`` to ``v_max`` inclusive in steps of ``step``.

    :param v_min: first speed [m/s].
    :param v_max: last speed [m/s].
    :param step: spacing [m/s].
    :return: the speeds.
    """
    if not (0.0 < v_min <= v_max and step > 0.0):
        raise ValueError(f'speed grid {v_min!r}..{v_max!r} step {step!r} m/s: need '
                         '0 < v_min <= v_max and step > 0')
    count = int(np.floor((v_max - v_min) / step + 1e-9)) + 1
    return [float(v_min + i * step) for i in range(count)]


def schedule_table(vehicle: VehicleParams, speeds: Sequence[float],
                   controller: ControllerParams | None = None) -> list[dict[str, Any]]:
    """
    Return d_v of each schedule and the zero-dynamics damping it gives, per speed.

    :param vehicle: vehicle parameters.
    :param speeds: speeds [m/s].
    :param controller: supplies the d_v clamp (default parameters if None).
    :return: one row per speed.
    """
    ctl = controller or ControllerParams()
    rows = []
    for v in speeds:
        d_paper, _ = paper_look_ahead(v, 0.0, vehicle, ctl.max_look_ahead)
        d_exact, _ = exact_look_ahead(v, 0.0, vehicle, ctl.max_look_ahead)
        rows.append({
            'speed_mps': v,
            'd_v_fixed_m': vehicle.d_s,
            'd_v_paper_m': float(d_paper),
            'd_v_exact_m': float(d_exact),
            'zeta_fixed': zero_dynamics(vehicle, v, vehicle.d_s).damping_ratio,
            'zeta_paper': zero_dynamics(vehicle, v, float(d_paper)).damping_ratio,
            'zeta_exact': zero_dynamics(vehicle, v, float(d_exact)).damping_ratio,
        })
    return rows


def zero_dynamics_table(vehicle: VehicleParams, speeds: Sequence[float],
                        controller: ControllerParams | None = None) -> list[dict[str, Any]]:
    """
    Return the zero-dynamics roots for the fixed (d_s) and the eq. 26 d_v, per speed.

    :param vehicle: vehicle parameters.
    :param speeds: speeds [m/s].
    :param controller: supplies the d_v clamp (default parameters if None).
    :return: one row per speed with both roots of both designs.
    """
    ctl = controller or ControllerParams()
    rows = []
    for v in speeds:
        d_paper, _ = paper_look_ahead(v, 0.0, vehicle, ctl.max_look_ahead)
        fixed = zero_dynamics(vehicle, v, vehicle.d_s)
        sched = zero_dynamics(vehicle, v, float(d_paper))
        rows.append({
            'speed_mps': v,
            'fixed_root_1': fixed.roots[0], 'fixed_root_2': fixed.roots[1],
            'fixed_zeta': fixed.damping_ratio,
            'd_v_paper_m': float(d_paper),
            'paper_root_1': sched.roots[0], 'paper_root_2': sched.roots[1],
            'paper_zeta': sched.damping_ratio,
        })
    return rows
