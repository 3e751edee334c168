"""The ROS side of the stream process: its own rclpy context, one tiny node, the ``commands`` publisher.

:func:`open_output` is what :meth:`~flexmotion_ros.execution.stream_process.StreamProcess.fork`
runs in the child at each ``configure``: it initialises rclpy once (without
signal handlers: Ctrl-C is the planner's to handle, the child ignores it),
creates the node ``<planner>_stream`` in the planner's namespace and a
publisher on the planner's resolved ``commands`` topic with the planner's
QoS.  Nothing spins: a publisher needs no executor, and its matched count is
kept by DDS's own threads.

Under ``stream_priority`` the publisher is asynchronous (Fast DDS's
``RMW_FASTRTPS_PUBLICATION_MODE=ASYNCHRONOUS``, set in this process only,
before its ``rclpy.init``): ``publish`` stores the sample in the writer's
history and returns; DDS's own sending thread (SCHED_FIFO one below the
loop, as the process's other threads) delivers it.  Synchronous, the deadline
loop itself pushed every sample into each reader's shared-memory port under
locks shared with the readers' processes, and waited whenever one of them
held a lock while preempted: traced in the 1 kHz storm (``bench/storm.py``,
``bench/gap_trace.py``), publishes blocked 3-27 ms with no wait for the CPU.
A 1 kHz publisher beside two normal-priority readers (60 s each, back to
back, load 14-18): synchronous 93 publishes over 1 ms, max 11.4 ms;
asynchronous none, max 0.27 ms.  :data:`PUBLICATION_MODE_ENV` chooses
otherwise; a user's ``RMW_FASTRTPS_PUBLICATION_MODE`` is left alone.  At the
end (:func:`open_output`'s ``close``) the child waits up to
:data:`FLUSH_TIMEOUT_S` for the readers to acknowledge what was sent, the
hold included, before the publisher goes.

The transports are Fast DDS's own choice (shared memory and UDP):
:data:`TRANSPORTS_ENV` sets ``FASTDDS_BUILTIN_TRANSPORTS`` in this process
only, for the benchmarks (``bench/storm.py``).  UDP only did not remove the
rare blocked ``publish`` at 1 kHz (shared memory was suspected: its port's
mutex lives in the reader's process too); synchronous over UDP blocked more
(bench/README.md, the storm section).
"""

from __future__ import annotations

import os
from collections.abc import Callable

import rclpy
from rclpy.duration import Duration
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import Float64MultiArray

from ..execution.stream_server import ChildSettings
from . import messages

#: The stream process's publication mode (``SYNCHRONOUS`` / ``ASYNCHRONOUS``); unset: asynchronous under
#: ``stream_priority``, Fast DDS's default otherwise.
PUBLICATION_MODE_ENV = "FLEXMOTION_STREAM_PUBLICATION_MODE"
#: The stream process's Fast DDS transports (a ``FASTDDS_BUILTIN_TRANSPORTS`` value, e.g. ``UDPv4``), for the
#: benchmarks; unset: Fast DDS's own choice.
TRANSPORTS_ENV = "FLEXMOTION_STREAM_TRANSPORTS"
#: How long the end of a configuration waits for the readers to acknowledge the last samples (s).
FLUSH_TIMEOUT_S = 0.5


def publication_mode(priority: int, environ: dict[str, str]) -> str | None:
    """``RMW_FASTRTPS_PUBLICATION_MODE`` for the stream process (None: leave it as it is)."""
    chosen = environ.get(PUBLICATION_MODE_ENV, "")
    if chosen:
        return chosen
    if priority <= 0 or "RMW_FASTRTPS_PUBLICATION_MODE" in environ:
        return None
    return "ASYNCHRONOUS"


def builtin_transports(environ: dict[str, str]) -> str | None:
    """``FASTDDS_BUILTIN_TRANSPORTS`` for the stream process: :data:`TRANSPORTS_ENV` if set (None: leave it)."""
    return environ.get(TRANSPORTS_ENV, "") or None


def stream_environment(priority: int, environ: dict[str, str]) -> dict[str, str]:
    """The variables the stream process sets in its own environment before ``rclpy.init`` (module docstring)."""
    chosen = {
        "RMW_FASTRTPS_PUBLICATION_MODE": publication_mode(priority, environ),
        "FASTDDS_BUILTIN_TRANSPORTS": builtin_transports(environ),
    }
    return {name: value for name, value in chosen.items() if value}


def open_output(cfg: ChildSettings) -> tuple[Callable[[list], None], Callable[[], int], Callable[[], None]]:
    """``(publish(values), matched_count(), close())`` for the child's stream (module docstring)."""
    if not rclpy.ok():
        # this process only (forked before any participant existed); the first configuration decides
        os.environ.update(stream_environment(cfg.priority, dict(os.environ)))
        rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(cfg.node_name, namespace=cfg.namespace or "/")
    qos = QoSProfile(
        depth=cfg.qos_depth,
        reliability=ReliabilityPolicy.RELIABLE if cfg.qos_reliable else ReliabilityPolicy.BEST_EFFORT,
        history=HistoryPolicy.KEEP_LAST,
    )
    pub = node.create_publisher(Float64MultiArray, cfg.topic, qos)
    msg = messages.command(0.0, cfg.inputs)

    def publish(values: list) -> None:
        msg.data = values
        pub.publish(msg)

    def close() -> None:
        if cfg.qos_reliable:  # an asynchronous publisher may still hold the last samples (the hold)
            try:
                pub.wait_for_all_acked(Duration(seconds=FLUSH_TIMEOUT_S))
            except Exception:  # noqa: BLE001, S110 -- a reader gone meanwhile: nothing more to wait for
                pass
        node.destroy_publisher(pub)
        node.destroy_node()

    return publish, pub.get_subscription_count, close


__all__ = [
    "FLUSH_TIMEOUT_S",
    "PUBLICATION_MODE_ENV",
    "TRANSPORTS_ENV",
    "builtin_transports",
    "open_output",
    "publication_mode",
    "stream_environment",
]
