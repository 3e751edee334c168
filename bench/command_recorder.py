"""Record the planner's ``commands`` in a process of their own: send time (DDS source timestamp, ns) and value.

The storm's own process is busy with requests, joint states and diagnostics;
at 1 kHz on a loaded machine its reader fell behind the 10,000-sample history
and lost samples, which then looked like stream gaps (61,414 received of
~190,000 sent in one run).  Here one subscription in one executor, under
``SCHED_FIFO`` when ``--priority`` is given, keeps up; ``--out`` gets
``send_ns`` and ``values`` (``.npz``) on SIGINT/SIGTERM.

    python bench/command_recorder.py --topic /ns/commands --out /tmp/commands.npz --priority 40
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--topic", required=True, help="the commands topic (absolute)")
    p.add_argument("--out", required=True, help="where send_ns and values go (.npz)")
    p.add_argument("--capacity", type=int, default=2_000_000, help="samples kept at most")
    p.add_argument("--priority", type=int, default=0, help="SCHED_FIFO priority (0: normal scheduling)")
    a = p.parse_args()
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from std_msgs.msg import Float64MultiArray

    from flexmotion_ros.nodes.planner_node import COMMAND_QOS

    if a.priority > 0:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(a.priority))  # threads made later inherit it
        except (OSError, AttributeError):
            pass
    send_ns = np.zeros(a.capacity, dtype=np.int64)
    values = np.zeros(a.capacity)
    count = [0]

    def on_command(msg, info) -> None:
        n = count[0]
        if n < a.capacity:
            send_ns[n] = info["source_timestamp"]
            values[n] = msg.data[0] if len(msg.data) else np.nan
            count[0] = n + 1

    rclpy.init(args=[], signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    executor = SingleThreadedExecutor()
    stop = {"now": False}

    def _stop(*_: object) -> None:
        stop["now"] = True

    signal.signal(signal.SIGINT, _stop)
    signal.signal(signal.SIGTERM, _stop)
    try:
        node = rclpy.create_node(f"command_recorder_{os.getpid()}")
        node.create_subscription(Float64MultiArray, a.topic, on_command, COMMAND_QOS)
        executor.add_node(node)
        while not stop["now"]:
            executor.spin_once(timeout_sec=0.05)
    except ExternalShutdownException:
        pass
    finally:
        n = count[0]
        np.savez(a.out, send_ns=send_ns[:n], values=values[:n])
        executor.shutdown(timeout_sec=1.0)
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
