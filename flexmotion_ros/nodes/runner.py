"""Running one node as an executable (``ros2 run``), the same way for every node."""

from __future__ import annotations

import sys
from collections.abc import Callable

import rclpy
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.node import Node

from ..core.errors import FlexmotionError


def run(make_node: Callable[[], Node], make_executor: Callable[[], Executor], name: str, args: list[str] | None) -> int:
    """``rclpy.init``, build the node, spin until shutdown, clean up.

    A configuration refused at start-up (:class:`FlexmotionError`) is one
    line on stderr and exit status 2.  Jazzy's rclpy has no ``with
    rclpy.init()``: ``try/finally`` and ``rclpy.try_shutdown()``.
    """
    rclpy.init(args=args)
    node = None
    try:
        try:
            node = make_node()
        except FlexmotionError as exc:
            sys.stderr.write(f"{name}: error: {exc}\n")
            return 2
        executor = make_executor()
        executor.add_node(node)
        try:
            executor.spin()
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        finally:
            executor.shutdown(timeout_sec=1.0)
        return 0
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
