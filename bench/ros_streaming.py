"""Goal-to-first-command latency and streaming period jitter of ``flexmotion_planner`` at 1 kHz.

The planner runs as its own process (``python -m flexmotion_ros.nodes.planner_node``,
the code ``ros2 run flexmotion_ros planner`` runs) on the Wie-Bernstein file at
``--rate`` Hz, silent while idle.  This script is a second process over real DDS
(an isolated domain unless ``ROS_DOMAIN_ID`` is set): it sends ``--moves`` goals
on ``~/goal`` (from rest, alternating ``+-goal``), and measures

* goal -> first command: from publishing the goal to receiving the first
  command (planning + start of the stream + DDS both ways); the planner's own
  planning time and goal-to-first-send (from ``/diagnostics``) beside it;
* the period between consecutive commands of a move: at the planner (send
  times inside the stream thread, from ``/diagnostics``) and here (receive
  times: adds DDS and this process's executor); median, p99, max;
* lateness: the planner's worst send time after a sample's absolute deadline.

Each configuration runs with the stream thread under normal scheduling and
under ``SCHED_FIFO`` (``stream_priority``), where the OS permits it.

    python bench/ros_streaming.py
    python bench/ros_streaming.py --rate 1000 --moves 5 --priorities 0 50

OpenBLAS threads are set to 1 before numpy loads (tiny matrices: threading only costs).
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
if "ROS_DOMAIN_ID" not in os.environ:
    os.environ["ROS_DOMAIN_ID"] = str(random.SystemRandom().randint(1, 100))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _args() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--config", default=str(ROOT / "config" / "wie_bernstein.yaml"), help="parameter file")
    p.add_argument("--rate", type=float, default=1000.0, help="command rate (Hz)")
    p.add_argument("--goal", type=float, default=0.5, help="move distance (m); moves alternate +goal / back to 0")
    p.add_argument("--moves", type=int, default=5, help="moves per configuration")
    p.add_argument(
        "--priorities", type=int, nargs="+", default=[0, 50], help="stream_priority values to run (0: normal)"
    )
    p.add_argument("-p", dest="extra", action="append", default=[], help="extra planner parameter NAME:=VALUE")
    return p.parse_args()


def run_config(args, priority: int) -> dict:
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import Float64, Float64MultiArray

    from flexmotion_ros.nodes import messages
    from flexmotion_ros.nodes.planner_node import COMMAND_QOS, DIAGNOSTIC_NAME

    ns = f"/bench_{os.getpid()}_{priority}"
    cmd = [
        sys.executable,
        "-m",
        "flexmotion_ros.nodes.planner_node",
        "--ros-args",
        "-r",
        f"__ns:={ns}",
        "--params-file",
        args.config,
        "-p",
        f"rate_hz:={args.rate!r}",
        "-p",
        "publish_hold_when_idle:=false",
        *[a for x in args.extra for a in ("-p", x)],
        "-p",
        f"stream_priority:={priority}",
    ]
    log = open(f"/tmp/bench_ros_streaming_planner_{priority}.log", "w")  # noqa: SIM115 -- the child's log, closed in finally
    proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT)
    node = rclpy.create_node("bench", namespace=ns)
    lock = threading.Lock()
    recv: list[float] = []
    diags: list[dict] = []

    def on_cmd(msg) -> None:
        t = time.monotonic()
        with lock:
            recv.append(t)

    def on_diag(msg) -> None:
        st = messages.diagnostic_values(msg, DIAGNOSTIC_NAME, f"{ns}/flexmotion_planner")
        if st is not None:
            with lock:
                diags.append({"message": st[1], **st[2]})

    node.create_subscription(Float64MultiArray, "commands", on_cmd, COMMAND_QOS)
    node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 100)
    goal_pub = node.create_publisher(Float64, "flexmotion_planner/goal", 10)
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    spin = threading.Thread(target=ex.spin, daemon=True)
    spin.start()

    def wait(pred, timeout: float, what: str) -> None:
        end = time.monotonic() + timeout
        while not pred():
            if proc.poll() is not None or time.monotonic() > end:
                raise RuntimeError(f"{what}: planner status {proc.poll()}, see {log.name}")
            time.sleep(0.005)

    rows = []
    try:
        wait(
            lambda: (
                goal_pub.get_subscription_count() >= 1 and any(int(d.get("command_subscribers", 0)) >= 1 for d in diags)
            ),
            30.0,
            "discovery",
        )
        time.sleep(0.5)
        target = 0.0
        for i in range(args.moves):
            target = args.goal if i % 2 == 0 else 0.0
            with lock:
                n0, d0 = len(recv), len(diags)
            t_send = time.monotonic()
            goal_pub.publish(Float64(data=target))
            wait(lambda n0=n0: len(recv) > n0, 30.0, "first command")
            t_first = recv[n0]
            wait(
                lambda d0=d0, target=target: any(
                    d["message"] == "idle" and "last_plan.stream_samples" in d and d.get("target") == f"{target:.9g}"
                    for d in diags[d0:]
                ),
                60.0,
                "end of move",
            )
            time.sleep(0.2)
            with lock:
                times = np.array(recv[n0:])
                d = [x for x in diags[d0:] if x["message"] == "idle" and "last_plan.stream_samples" in x][-1]
            rows.append(
                {
                    "latency_ms": (t_first - t_send) * 1e3,
                    "plan_ms": float(d["last_plan.plan_time_s"]) * 1e3,
                    "planner_first_ms": float(d["last_plan.goal_to_first_command_s"]) * 1e3,
                    "samples": int(d["last_plan.samples"]),
                    "recv_periods_ms": np.diff(times) * 1e3,
                    "send_median_ms": float(d["last_plan.stream_period_median_ms"]),
                    "send_p99_ms": float(d["last_plan.stream_period_p99_ms"]),
                    "send_max_ms": float(d["last_plan.stream_period_max_ms"]),
                    "late_max_ms": float(d["last_plan.stream_lateness_max_ms"]),
                    "received": int(times.size),
                }
            )
    finally:
        ex.shutdown(timeout_sec=1.0)
        node.destroy_node()
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            proc.kill()
        log.close()
    refused = "refused" in Path(log.name).read_text()
    return {"priority": priority, "refused": refused, "rows": rows}


def main() -> None:
    args = _args()
    import rclpy

    rclpy.init(args=[])
    try:
        results = [run_config(args, p) for p in args.priorities]
    finally:
        rclpy.try_shutdown()
    load = os.getloadavg()
    print(
        f"flexmotion_planner streaming, {Path(args.config).name}, {args.rate:g} Hz (nominal period {1e3 / args.rate:.3f} ms), "
        f"{args.moves} moves of {args.goal:g} per row; load average {load[0]:.1f} on {os.cpu_count()} CPUs"
    )
    print()
    hdr = (
        f"{'stream thread':<22}{'goal->1st cmd ms':>18}{'planning ms':>13}{'samples':>9}"
        f"{'send period ms (med/p99/max)':>31}{'recv period ms (med/p99/max)':>31}{'late max ms':>13}{'lost':>6}"
    )
    print(hdr)
    print("-" * len(hdr))
    for res in results:
        rows = res["rows"]
        lat = np.array([r["latency_ms"] for r in rows])
        plan = np.array([r["plan_ms"] for r in rows])
        recv = np.concatenate([r["recv_periods_ms"] for r in rows])
        lost = sum(r["samples"] + 1 - r["received"] for r in rows)
        name = (
            "normal"
            if res["priority"] == 0
            else f"SCHED_FIFO {res['priority']}" + (" (refused)" if res["refused"] else "")
        )
        send = (
            np.median([r["send_median_ms"] for r in rows]),
            max(r["send_p99_ms"] for r in rows),
            max(r["send_max_ms"] for r in rows),
        )
        print(
            f"{name:<22}{np.median(lat):>8.1f} (max {lat.max():5.1f}){np.median(plan):>11.1f}  {int(np.median([r['samples'] for r in rows])):>8}"
            f"{send[0]:>13.3f} /{send[1]:>6.3f} /{send[2]:>7.3f}"
            f"{np.median(recv):>13.3f} /{np.percentile(recv, 99):>6.3f} /{recv.max():>7.3f}"
            f"{max(r['late_max_ms'] for r in rows):>13.3f}{lost:>6d}"
        )
    print()
    print("goal->1st cmd: goal published here -> first command received here (median, max over moves); planning: the")
    print("planner's plan_move time. send: periods between the planner's publish calls (worst move's p99/max);")
    print("recv: periods between arrivals here (all moves pooled; includes DDS and this process). late max: the")
    print("worst delay of a send after its absolute deadline t0 + k/rate (deadlines never drift: late samples go")
    print("out at once, none is skipped). lost: commands planned + hold minus commands received.")


if __name__ == "__main__":
    main()
