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
Elementary functions that work on Python floats and on numpy arrays alike.

The control law and the plant are written once and evaluated either on floats (one
run, a node: pure Python is fastest there) or on arrays (a vectorized batch of runs).
"""

from __future__ import annotations

import math
from typing import Any, TypeVar, Union

import numpy as np
import numpy.typing as npt

Real = Union[float, npt.NDArray[np.float64]]
T = TypeVar('T', float, Any)


def _is_array(a: Any, b: Any, c: Any = None) -> bool:
    # no *args / any(): this runs several times per control step (pure-Python floats)
    return (isinstance(a, np.ndarray) or isinstance(b, np.ndarray)
            or isinstance(c, np.ndarray))


def sin(x: Real) -> Real:
    """Sine of a float or an array."""
    return np.sin(x) if isinstance(x, np.ndarray) else math.sin(x)


def cos(x: Real) -> Real:
    """Cosine of a float or an array."""
    return np.cos(x) if isinstance(x, np.ndarray) else math.cos(x)


# tan, atan2 and power of a float go through numpy's kernels too: on a CPU with AVX-512 numpy
# dispatches SIMD (SVML) kernels that differ from the C library's in the last bit
# (about 0.5 % of tan, 8 % of atan2, 5 % of cube-root arguments), and a float run then left its
# one-element batch (the plants and laws are checked bit for bit against their batch
# runs, and compare's seeded rows against single runs). sin, cos and sqrt agree.


def tan(x: Real) -> Real:
    """Tangent of a float or an array (numpy's kernel for both)."""
    return np.tan(x) if isinstance(x, np.ndarray) else float(np.tan(x))


def power(x: Real, exponent: float) -> Real:
    """
    Return ``x ** exponent`` of a float or an array (numpy's kernel for both).

    :param x: the base.
    :param exponent: the exponent.
    :return: the power.
    """
    return np.power(x, exponent) if isinstance(x, np.ndarray) else float(np.power(x, exponent))


def sqrt(x: Real) -> Real:
    """Square root of a float or an array (non-negative input)."""
    return np.sqrt(x) if isinstance(x, np.ndarray) else math.sqrt(x)


def atan2(y: Real, x: Real) -> Real:
    """Four-quadrant arc tangent of floats or arrays (numpy's kernel for both)."""
    return np.arctan2(y, x) if _is_array(y, x) else float(np.arctan2(y, x))


def absolute(x: Real) -> Real:
    """Absolute value of a float or an array."""
    return np.abs(x) if isinstance(x, np.ndarray) else abs(x)


def sign(x: Real) -> Real:
    """Sign (-1, 0 or 1) of a float or an array."""
    if isinstance(x, np.ndarray):
        return np.sign(x)
    return math.copysign(1.0, x) if x != 0.0 else 0.0


def maximum(a: Real, b: Real) -> Real:
    """Element-wise maximum."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.maximum(a, b)
    return max(a, b)


def minimum(a: Real, b: Real) -> Real:
    """Element-wise minimum."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.minimum(a, b)
    return min(a, b)


def clip(x: Real, low: Real, high: Real) -> Real:
    """Clip ``x`` into ``[low, high]`` element-wise."""
    if _is_array(x, low, high):
        return np.minimum(np.maximum(x, low), high)
    return min(max(x, low), high)


def where(condition: Any, a: Real, b: Real) -> Real:
    """Select ``a`` where ``condition`` holds, else ``b`` (element-wise)."""
    if _is_array(condition, a, b):
        return np.where(condition, a, b)
    return a if condition else b
