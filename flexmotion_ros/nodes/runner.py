"""Running one node as an executable (``ros2 run``), the same way for every node.

Shutdown in order: rclpy's own signal handlers are off (they shut the
context down asynchronously, under the stream thread's feet: ``RCLError:
publisher's context is invalid`` in 5 of 16 Ctrl-C); SIGINT and SIGTERM
only wake the main thread, which then brings a lifecycle node through its
*shutdown* transition (the planner's stream ends with the hold), stops the
executor, destroys the node and only then shuts the context down.  Exit
status 0, no traceback.
"""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Callable

import rclpy
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.lifecycle import LifecycleNode
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from ..core.errors import FlexmotionError
from ..core.parameter_file import read_parameter_sections


def run(make_node: Callable[[], Node], make_executor: Callable[[], Executor], name: str, args: list[str] | None) -> int:
    """``rclpy.init``, build the node, spin until shutdown, clean up.

    A configuration refused at start-up (:class:`FlexmotionError`) is one
    line on stderr and exit status 2.  Jazzy's rclpy has no ``with
    rclpy.init()``: ``try/finally`` and ``rclpy.try_shutdown()``.
    """
    refused = check_parameter_files(sys.argv if args is None else args)
    if refused is None:
        try:
            rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
        except RuntimeError as exc:  # rcl refused its arguments (rclpy's RCLError): one line, not a traceback
            refused = " ".join(str(exc).split())
    if refused is not None:
        sys.stderr.write(f"{name}: error: {refused}\n")
        return 2
    done = threading.Event()  # a stop signal arrived, or the executor ended
    previous = {sig: signal.signal(sig, lambda signum, frame: done.set()) for sig in STOP_SIGNALS}
    node = None
    try:
        try:
            node = make_node()
        except FlexmotionError as exc:
            sys.stderr.write(f"{name}: error: {exc}\n")
            return 2
        executor = make_executor()
        executor.add_node(node)
        return _spin_until_stopped(node, executor, name, done)
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def parameter_files(args: list[str]) -> list[str]:
    """The ``--params-file FILE`` arguments inside ``--ros-args`` sections (rcl's syntax), in order."""
    files, in_ros, i = [], False, 0
    while i < len(args):
        a = args[i]
        if a == "--ros-args":
            in_ros = True
        elif a == "--":
            in_ros = False
        elif in_ros and a == "--params-file" and i + 1 < len(args):
            files.append(args[i + 1])
            i += 1
        i += 1
    return files


def check_parameter_files(args: list[str]) -> str | None:
    """Read every ``--params-file`` with the core's reader (rcl's rules) before ``rclpy.init``.

    Returns ``None`` if all are readable, else one line naming the file and,
    for a YAML syntax error, its line and column (rcl would end in an
    ``RCLError`` traceback).  Names and types are judged later, by the node.
    """
    for path in parameter_files(list(args)):
        try:
            read_parameter_sections(path, "--params-file")
        except FlexmotionError as exc:
            return " ".join(str(exc).split())
    return None


#: The signals that end a node in order.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def _spin_until_stopped(node: Node, executor: Executor, name: str, done: threading.Event) -> int:
    """Spin ``executor`` in a thread until ``done`` (a signal) or it ends; then shut ``node`` down in order.

    Returns the exit status: 0, or 1 if a callback raised and ended the
    executor (one line on stderr).
    """
    failure: list[BaseException] = []

    def spin() -> None:
        try:
            executor.spin()
        except ExternalShutdownException:
            pass
        except Exception as exc:  # noqa: BLE001 -- reported below in one line
            if not done.is_set():
                failure.append(exc)
        finally:
            done.set()

    thread = threading.Thread(target=spin, name=f"{name}-executor", daemon=True)
    thread.start()
    while not done.wait(1.0):
        pass
    # the node ends what it does while the context is valid: the planner's stream sends the hold now,
    # even if a callback (a long plan) is still running in the executor thread
    if isinstance(node, LifecycleNode):
        try:
            node.trigger_shutdown()
        except Exception as exc:  # noqa: BLE001 -- e.g. in a transition already; destroy_node still ends the stream
            node.get_logger().warning(f"shutdown transition: {type(exc).__name__}: {exc}")
    executor.shutdown(timeout_sec=1.0)
    thread.join(timeout=2.0)
    if failure:
        exc = failure[0]
        sys.stderr.write(f"{name}: error: a callback raised {type(exc).__name__}: {exc}\n")
        return 1
    return 0
