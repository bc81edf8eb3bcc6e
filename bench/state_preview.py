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
The CG-compensated law with a share of its state terms' preview (``state_preview``).

``python -m bench.state_preview [--share G ...] [--seeds N] [--speeds V ...]
[--no-corners]``: the figures of docs/lane_keeping.md, "Preview of the drift term's
state terms". Each ``G`` is a value of ``lane_keeping.state_preview``; every other
setting is the package default. The tables are those of :mod:`bench.exact_inverse`: the
noise-free goal plant (nonlinear, 20 ms delay), with ``--seeds N`` the goal plant with N
noise seeds per speed, and the mismatch corners at 37 m/s.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from typing import Sequence

from bench.exact_inverse import measure, print_tables
from lookahead_control.core.lane_keeping import LaneKeepingParams


def main(argv: Sequence[str] | None = None) -> int:
    """
    Print the tables (markdown).

    :param argv: ``--share G ...`` (default 0 and the package default), ``--seeds N``
        (goal plant, default 0), ``--speeds V ...``, ``--no-corners``.
    :return: 0.
    """
    default = LaneKeepingParams()
    p = argparse.ArgumentParser(prog='python -m bench.state_preview',
                                description=__doc__.split('\n\n')[0].strip())
    p.add_argument('--share', type=float, nargs='+',
                   default=sorted({0.0, default.state_preview}))
    p.add_argument('--seeds', type=int, default=0)
    p.add_argument('--speeds', type=float, nargs='+', default=[30.0, 37.0])
    p.add_argument('--no-corners', action='store_true')
    args = p.parse_args(argv)
    results = {f'{g:g}': measure(dataclasses.replace(default, state_preview=g), args.speeds,
                                 args.seeds, not args.no_corners)
               for g in args.share}
    print_tables('state_preview', results, args.speeds, args.seeds, not args.no_corners)
    return 0


if __name__ == '__main__':
    sys.exit(main())
