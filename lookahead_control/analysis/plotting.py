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

"""PNG plots of analysis data; matplotlib is imported only when a plot is made."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
import numpy.typing as npt


def _pyplot() -> Any:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def _save(fig: Any, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    _pyplot().close(fig)
    return path


def plot_schedule(rows: Sequence[Mapping[str, Any]], path: Path) -> Path:
    """
    Plot d_v of each schedule against speed.

    :param rows: rows of ``analysis.schedule_table``.
    :param path: the PNG file.
    :return: the path written.
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 4))
    v = [r['speed_mps'] for r in rows]
    for key, label in (('d_v_paper_m', 'paper, eq. 26'), ('d_v_exact_m', 'exact, eq. 24'),
                       ('d_v_fixed_m', 'fixed (look-down d_s)')):
        ax.plot(v, [r[key] for r in rows], label=label)
    ax.set_xlabel('speed v_x [m/s]')
    ax.set_ylabel('look-ahead d_v [m]')
    ax.grid(True, alpha=0.3)
    ax.legend()
    return _save(fig, path)


def plot_measured_look_ahead(rows: Sequence[Mapping[str, Any]],
                             points: tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]],
                             path: Path) -> Path:
    """
    Plot the schedules against speed with the d_v recorded runs used.

    :param rows: rows of ``analysis.schedule_table`` (the curves).
    :param points: speed and d_v of every recorded step.
    :param path: the PNG file.
    :return: the path written.
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 4))
    v = [r['speed_mps'] for r in rows]
    for key, label in (('d_v_paper_m', 'paper, eq. 26'), ('d_v_fixed_m', 'fixed d_s')):
        ax.plot(v, [r[key] for r in rows], label=label)
    ax.plot(points[0], points[1], '.', ms=3, label='recorded runs')
    ax.set_xlabel('speed v_x [m/s]')
    ax.set_ylabel('look-ahead d_v [m]')
    ax.grid(True, alpha=0.3)
    ax.legend()
    return _save(fig, path)


def plot_roots(rows: Sequence[Mapping[str, Any]], path: Path) -> Path:
    """
    Plot the zero-dynamics roots in the complex plane (the paper's Fig. 2/3).

    :param rows: rows of ``analysis.zero_dynamics_table``.
    :param path: the PNG file.
    :return: the path written.
    """
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, zoom in zip(axes, (False, True)):
        for prefix, marker, label in (('fixed', 'x', 'fixed d_v = d_s'),
                                      ('paper', 'o', 'scheduled d_v (eq. 26)')):
            roots = np.array([r[f'{prefix}_root_{i}'] for r in rows for i in (1, 2)])
            ax.scatter(roots.real, roots.imag, marker=marker, label=label, s=18)
        ax.axvline(0.0, color='k', lw=0.5)
        ax.set_xlabel('Re [1/s]')
        ax.set_ylabel('Im [rad/s]')
        ax.grid(True, alpha=0.3)
        if zoom:
            ax.set_xlim(-6.0, 0.5)
            ax.set_title('zoom (Fig. 3)')
        else:
            ax.set_title('zero-dynamics roots over speed (Fig. 2)')
            ax.legend()
    return _save(fig, path)


def plot_runs(runs: Sequence[Mapping[str, Any]], path: Path, title: str) -> Path:
    """
    Plot tracking error, relative yaw and steering against time, one line per run.

    :param runs: mappings with ``label``, ``time`` and the channels ``error``,
        ``y_cg``, ``eps_r``, ``steering_cmd``.
    :param path: the PNG file.
    :param title: the figure title.
    :return: the path written.
    """
    plt = _pyplot()
    fig, axes = plt.subplots(4, 1, figsize=(7, 10), sharex=True)
    panels = (('error', 'look-ahead error y_v - y_ref [m]'),
              ('y_cg', 'CG lateral error y_cg [m]'),
              ('eps_r', 'relative yaw eps_r [rad]'),
              ('steering_cmd', 'steering angle delta [rad]'))
    for run in runs:
        time: npt.NDArray[np.float64] = run['time']
        for ax, (key, _) in zip(axes, panels):
            ax.plot(time, run[key], label=run['label'])
    for ax, (_, label) in zip(axes, panels):
        ax.set_ylabel(label, fontsize=8)
        ax.grid(True, alpha=0.3)
    axes[0].set_title(title)
    # a fixed place: 'best' searches the lines' points, seconds on hour-long runs
    axes[0].legend(fontsize=7, loc='upper right')
    axes[-1].set_xlabel('time [s]')
    return _save(fig, path)
