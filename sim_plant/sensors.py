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
Sensor noise: white Gaussian noise per measured channel, seeded so runs repeat exactly.

Each control step draws four standard normals ``(n_lat, n_yaw, n_vy, n_r)`` in that
order from ``numpy.random.default_rng(seed)``; the offline runner draws them all at
once (``standard_normal((steps, 4))``), the simulator node one row per step: the same
numbers. The lateral error is measured at the sensor (``d_s`` ahead of the CG, the
look-down sensor): the controller sees ``y_s + sigma_lat n_lat`` there and relative yaw
``eps_r + sigma_yaw n_yaw``, so its CG error ``y_s - d_s eps_r`` carries both noises.
"""

from __future__ import annotations

from dataclasses import dataclass

from lookahead_control.core.params import check_range, ParameterError
import numpy as np
import numpy.typing as npt

CHANNELS = ('lateral_error', 'relative_yaw', 'lateral_velocity', 'yaw_rate')


@dataclass(frozen=True)
class NoiseParams:
    """
    Standard deviations of the measurement noise (0 turns a channel's noise off).

    Defaults are those of a production lane camera and an automotive IMU/velocity
    estimate: lateral error 3 cm, relative yaw 2 mrad, v_y 0.02 m/s, yaw rate 2 mrad/s.

    :param lateral_error: lateral error at the sensor [m].
    :param relative_yaw: relative yaw [rad].
    :param lateral_velocity: body lateral velocity [m/s].
    :param yaw_rate: yaw rate [rad/s].
    """

    lateral_error: float = 0.03
    relative_yaw: float = 0.002
    lateral_velocity: float = 0.02
    yaw_rate: float = 0.002

    def __post_init__(self) -> None:
        check_range('noise.lateral_error', self.lateral_error, 0.0, 5.0, unit='m')
        check_range('noise.relative_yaw', self.relative_yaw, 0.0, 0.5, unit='rad')
        check_range('noise.lateral_velocity', self.lateral_velocity, 0.0, 5.0, unit='m/s')
        check_range('noise.yaw_rate', self.yaw_rate, 0.0, 0.5, unit='rad/s')

    @property
    def sigmas(self) -> npt.NDArray[np.float64]:
        """Return the four standard deviations in draw order."""
        return np.array([self.lateral_error, self.relative_yaw, self.lateral_velocity,
                         self.yaw_rate])


def check_seed(seed: int) -> int:
    """
    Return ``seed`` as an int, or raise if it is not a non-negative integer.

    :param seed: the seed.
    :return: the seed.
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ParameterError(f'noise seed = {seed!r} is not allowed; a non-negative '
                             'integer is required')
    return int(seed)


def noise_table(noise: NoiseParams, seed: int, steps: int) -> npt.NDArray[np.float64]:
    """
    Return the scaled noise of ``steps`` control steps, shape ``(steps, 4)``.

    :param noise: standard deviations.
    :param seed: the run's seed.
    :param steps: number of control steps.
    :return: row k = noise of step k, in :data:`CHANNELS` order.
    """
    rng = np.random.default_rng(check_seed(seed))
    return rng.standard_normal((steps, 4)) * noise.sigmas


class NoiseStream:
    """The noise of one run, one step at a time (the simulator node)."""

    def __init__(self, noise: NoiseParams, seed: int) -> None:
        """
        Start the stream.

        :param noise: standard deviations.
        :param seed: the run's seed.
        """
        self._rng = np.random.default_rng(check_seed(seed))
        self._sigmas = noise.sigmas

    def draw(self) -> tuple[float, float, float, float]:
        """Return the next step's noise ``(lateral, yaw, v_y, r)``."""
        row = self._rng.standard_normal(4) * self._sigmas
        return float(row[0]), float(row[1]), float(row[2]), float(row[3])
