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
The Jazzy ``main()`` both nodes share: init, spin, one-line errors, clean shutdown.

Jazzy's rclpy has no ``with rclpy.init()``: init, try spin, finally destroy the node
and ``try_shutdown``.
"""

from __future__ import annotations

import sys
from typing import Callable, Optional, TypeVar

from lookahead_control.config import ConfigError
from lookahead_control.params import ParameterError
import rclpy
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

N = TypeVar('N', bound=Node)


def run_node(name: str, args: Optional[list[str]], make: Callable[[], N],
             spin: Callable[[Executor, N], None]) -> int:
    """
    Create a node, spin it until done or shut down, and clean up.

    :param name: the executable's name, for the one-line error.
    :param args: command-line arguments (ROS arguments included).
    :param make: creates (and, if needed, activates) the node after ``rclpy.init``.
    :param spin: spins the executor that holds the node.
    :return: 0, or 2 for bad parameters or config.
    """
    rclpy.init(args=args)
    node: Optional[N] = None
    try:
        node = make()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        spin(executor, node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (ConfigError, ParameterError) as err:
        print(f'{name}: error: {err}', file=sys.stderr)
        return 2
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
