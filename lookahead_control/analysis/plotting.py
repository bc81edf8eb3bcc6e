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


def line_styles(count: int) -> list[dict[str, Any]]:
    """
    Return distinguishable colour and dash pairs for ``count`` lines.

    Up to 10 lines get the 10 colours of matplotlib's ``tab10``; beyond that the colours
    repeat with another dash pattern, so no two lines look alike.

    :param count: how many lines.
    :return: matplotlib line keyword arguments per line.
    """
    dashes = ('-', '--', ':', '-.')
    colours = [f'C{i}' for i in range(10)]
    return [{'color': colours[i % 10], 'linestyle': dashes[(i // 10) % len(dashes)]}
            for i in range(count)]


def plot_runs(runs: Sequence[Mapping[str, Any]], path: Path, title: str) -> Path:
    """
    Plot errors, relative yaw and steering against time, one colour per run.

    The steering panel shows the command (solid) and, where the plant reports it, the
    wheel angle (dotted, same colour). Labels use the names of ``metrics.QUANTITIES``.

    :param runs: mappings with ``label``, ``time`` and the channels ``error``,
        ``y_cg``, ``eps_r``, ``steering_cmd`` and optionally ``steering``.
    :param path: the PNG file.
    :param title: the figure title.
    :return: the path written.
    """
    from lookahead_control.analysis.metrics import axis_label
    plt = _pyplot()
    fig, axes = plt.subplots(4, 1, figsize=(8, 11), sharex=True)
    panels = (('error', axis_label('regulated_error')),
              ('y_cg', axis_label('cg_error')),
              ('eps_r', axis_label('relative_yaw')),
              ('steering_cmd', 'steering delta_cmd (solid),\nwheel angle delta (dotted) '
               '[rad]'))
    for run, style in zip(runs, line_styles(len(runs))):
        time: npt.NDArray[np.float64] = run['time']
        for ax, (key, _) in zip(axes, panels):
            ax.plot(time, run[key], label=run['label'], lw=1.2, **style)
        wheel = run.get('steering')
        if wheel is not None and not np.isnan(wheel).all():
            axes[3].plot(time, wheel, color=style['color'], linestyle=':', lw=1.5)
    for ax, (_, label) in zip(axes, panels):
        ax.set_ylabel(label, fontsize=7)
        ax.grid(True, alpha=0.3)
    axes[0].set_title(title)
    # a fixed place: 'best' searches the lines' points, seconds on hour-long runs
    axes[0].legend(fontsize=6, loc='upper right')
    axes[-1].set_xlabel('time [s]')
    return _save(fig, path)
