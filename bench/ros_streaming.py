"""Goal-to-first-command latency and streaming period jitter of ``flexmotion_planner`` at 1 kHz.

The planner runs as its own process (``python -m flexmotion_ros.nodes.planner_node``,
the code ``ros2 run flexmotion_ros planner`` runs) on the Wie-Bernstein file at
``--rate`` Hz, silent while idle.  This script is a second process over real DDS
(an isolated domain unless ``ROS_DOMAIN_ID`` is set): it sends ``--moves`` goals
on ``~/goal`` (from rest, alternating ``+-goal``), and measures

* goal -> first command: from publishing the goal to receiving the first
  command (planning + start of the stream + DDS both ways); the planner's own
  planning time and goal-to-first-send (from ``/diagnostics``: from the goal
  callback to the first command's publish, on the planner's clock) beside it;
* the period between consecutive commands of a move: at the planner (send
  times inside the stream thread, from ``/diagnostics``) and here (receive
  times: adds DDS and this process's executor); median, p99, max;
* lateness: the planner's worst send time after a sample's absolute deadline;
* stop latency: ``--stops`` moves are stopped through ``~/stop`` a random
  0.1 .. 0.6 s in; from the planner's receipt of the request to its first
  stop-plan sample sent (s, the planner's own clock, from ``/diagnostics``)
  and in samples (the splice lead), median and p99, and how many were served
  by a ready stop (planned in advance) rather than planned on demand;
* shutdown to hold: SIGINT 0.5 s into a last move; from the signal to the
  hold (0.0) received here, the exit status, and whether the last command
  received was the hold.

Each configuration runs with the stream thread under normal scheduling and
under ``SCHED_FIFO`` (``stream_priority``), where the OS permits it.
``--receiver-priority N`` runs this process's threads (the subscriber, as a
real-time controller would be) under ``SCHED_FIFO`` N while the goals are
sent: on a loaded machine its own wake-ups otherwise dominate the figure.

    python bench/ros_streaming.py
    python bench/ros_streaming.py --rate 1000 --moves 5 --priorities 0 50
    python bench/ros_streaming.py --moves 2 --stops 5 --priorities 0      # brief
    python bench/ros_streaming.py --accuracy --moves 4 --burners 2       # trajectory vs stream (bench/ros_accuracy.py)

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
    p.add_argument("--stops", type=int, default=5, help="moves stopped through ~/stop per configuration")
    p.add_argument(
        "--priorities", type=int, nargs="+", default=[0, 50], help="stream_priority values to run (0: normal)"
    )
    p.add_argument(
        "--receiver-priority",
        type=int,
        default=0,
        help="SCHED_FIFO priority of this process's threads (the subscriber) during the moves (0: normal)",
    )
    p.add_argument("-p", dest="extra", action="append", default=[], help="extra planner parameter NAME:=VALUE")
    p.add_argument(
        "--accuracy",
        action="store_true",
        help="instead: trajectory output vs the stream, real-time plant, beside CPU burners (bench/ros_accuracy.py)",
    )
    p.add_argument("--burners", type=int, default=2, help="--accuracy: CPU-burning processes beside the nodes")
    p.add_argument("--start-delay", type=float, default=0.2, help="--accuracy: trajectory.start_delay_s (s)")
    return p.parse_args()


def run_config(args, priority: int) -> dict:
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import Float64, Float64MultiArray
    from std_srvs.srv import Trigger

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
        "-p",
        "state.source:=assumed",
        *[a for x in args.extra for a in ("-p", x)],
        "-p",
        f"stream_priority:={priority}",
    ]
    log = open(f"/tmp/bench_ros_streaming_planner_{priority}.log", "w")  # noqa: SIM115 -- the child's log, closed in finally
    proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT)
    node = rclpy.create_node("bench", namespace=ns)
    lock = threading.Lock()
    recv: list[float] = []
    values: list[float] = []
    diags: list[dict] = []

    def on_cmd(msg) -> None:
        t = time.monotonic()
        with lock:
            recv.append(t)
            values.append(float(msg.data[0]))

    def on_diag(msg) -> None:
        st = messages.diagnostic_values(msg, DIAGNOSTIC_NAME, f"{ns}/flexmotion_planner")
        if st is not None:
            with lock:
                diags.append({"message": st[1], **st[2]})

    node.create_subscription(Float64MultiArray, "commands", on_cmd, COMMAND_QOS)
    node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 100)
    goal_pub = node.create_publisher(Float64, "flexmotion_planner/goal", 10)
    stop_client = node.create_client(Trigger, "flexmotion_planner/stop")
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    spin = threading.Thread(target=ex.spin, daemon=True)
    spin.start()
    if args.receiver_priority > 0:  # after the planner's fork (it must not inherit it); DDS's threads exist now
        from flexmotion_ros.execution.realtime import raise_threads

        refused = raise_threads(args.receiver_priority)
        if refused:
            print(f"receiver: {refused}", file=sys.stderr)

    def wait(pred, timeout: float, what: str) -> None:
        end = time.monotonic() + timeout
        while not pred():
            if proc.poll() is not None or time.monotonic() > end:
                raise RuntimeError(f"{what}: planner status {proc.poll()}, see {log.name}")
            time.sleep(0.005)

    rows = []
    stops = []
    shutdown: dict = {}
    rng = random.Random(1)
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
                    "planner_first_ms": float(d.get("last_plan.goal_to_first_command_s", "nan")) * 1e3,
                    "samples": int(d["last_plan.samples"]),
                    "recv_periods_ms": np.diff(times) * 1e3,
                    "send_median_ms": float(d["last_plan.stream_period_median_ms"]),
                    "send_p99_ms": float(d["last_plan.stream_period_p99_ms"]),
                    "send_max_ms": float(d["last_plan.stream_period_max_ms"]),
                    "late_max_ms": float(d["last_plan.stream_lateness_max_ms"]),
                    "received": int(times.size),
                }
            )
        wait(lambda: stop_client.service_is_ready(), 30.0, "~/stop")
        for _ in range(args.stops):
            target = args.goal if abs(target) < args.goal / 2 else 0.0
            with lock:
                n0, d0 = len(recv), len(diags)
            goal_pub.publish(Float64(data=target))
            wait(lambda n0=n0: len(recv) > n0, 30.0, "first command")
            time.sleep(rng.uniform(0.1, 0.6))
            with lock:
                d1 = len(diags)
            answer = stop_client.call_async(Trigger.Request())
            wait(answer.done, 30.0, "~/stop answer")
            wait(
                lambda d1=d1: any(d["message"] == "idle" and "last_plan.stream_samples" in d for d in diags[d1:]),
                60.0,
                "end of the stop",
            )
            time.sleep(0.2)
            with lock:
                d = [x for x in diags[d1:] if x["message"] == "idle" and "last_plan.stream_samples" in x][-1]
            stops.append(
                {
                    "latency_ms": float(d["last_plan.goal_to_first_command_s"]) * 1e3,
                    "lead_samples": int(d.get("last_plan.stop_lead_samples", -1)),
                    "ready": "ready stop" in answer.result().message or "last_plan.stop_lead_samples" in d,
                }
            )
            target = float(d["position_at_rest"])
        # shutdown to hold: SIGINT mid-move
        for to in (args.goal if abs(target) < args.goal / 2 else 0.0, -args.goal):  # a refused goal moves nothing
            with lock:
                n0 = len(recv)
            goal_pub.publish(Float64(data=to))
            end = time.monotonic() + 5.0
            while len(recv) <= n0 and time.monotonic() < end:
                time.sleep(0.005)
            if len(recv) > n0:
                break
        wait(lambda n0=n0: len(recv) > n0, 1.0, "first command")
        time.sleep(0.5)
        with lock:
            n_sig = len(recv)
        t_sig = time.monotonic()
        proc.send_signal(signal.SIGINT)
        status = proc.wait(timeout=10.0)
        time.sleep(0.3)
        with lock:
            hold_at = [t for t, v in zip(recv[n_sig:], values[n_sig:], strict=True) if v == 0.0]
            last = values[-1]
        shutdown = {
            "to_hold_ms": (hold_at[0] - t_sig) * 1e3 if hold_at else float("nan"),
            "status": status,
            "last": last,
        }
    finally:
        if args.receiver_priority > 0:  # the next configuration's planner starts under normal scheduling
            from flexmotion_ros.execution.realtime import lower_threads

            lower_threads()
        ex.shutdown(timeout_sec=1.0)
        spin.join(timeout=5.0)  # the executor thread ends before the node goes (else: terminate called)
        node.destroy_node()
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                proc.kill()
        log.close()
    refused = "SCHED_FIFO" in Path(log.name).read_text() and "refused" in Path(log.name).read_text()
    text = Path(log.name).read_text()
    shutdown["traceback"] = "Traceback" in text
    return {"priority": priority, "refused": refused, "rows": rows, "stops": stops, "shutdown": shutdown}


def main() -> None:
    args = _args()
    if args.accuracy:  # trajectory vs stream: what reaches the machine (issue 14)
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from ros_accuracy import accuracy  # noqa: PLC0415 -- the sibling script, only for this mode

        accuracy(args)
        return
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
        + (f"; receiver SCHED_FIFO {args.receiver_priority}" if args.receiver_priority > 0 else "")
    )
    print()
    hdr = (
        f"{'stream thread':<22}{'goal->1st cmd ms':>18}{'planner ms':>12}{'planning ms':>13}{'samples':>9}"
        f"{'send period ms (med/p99/max)':>31}{'recv period ms (med/p99/max)':>31}{'late max ms':>13}{'lost':>6}"
    )
    print(hdr)
    print("-" * len(hdr))
    for res in results:
        rows = res["rows"]
        lat = np.array([r["latency_ms"] for r in rows])
        plan = np.array([r["plan_ms"] for r in rows])
        planner = np.array([r["planner_first_ms"] for r in rows])
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
            f"{name:<22}{np.median(lat):>8.1f} (max {lat.max():5.1f}){np.nanmedian(planner):>10.1f}{np.median(plan):>13.1f}  {int(np.median([r['samples'] for r in rows])):>8}"
            f"{send[0]:>13.3f} /{send[1]:>6.3f} /{send[2]:>7.3f}"
            f"{np.median(recv):>13.3f} /{np.percentile(recv, 99):>6.3f} /{recv.max():>7.3f}"
            f"{max(r['late_max_ms'] for r in rows):>13.3f}{lost:>6d}"
        )
    print()
    print("goal->1st cmd: goal published here -> first command received here (median, max over moves); planner: the")
    print("planner's goal callback -> first command published (its clock); planning: its plan_move time.")
    print("send: periods between the planner's publish calls (worst move's p99/max);")
    print("recv: periods between arrivals here (all moves pooled; includes DDS and this process). late max: the")
    print("worst delay of a send after its absolute deadline t0 + k/rate (deadlines never drift: late samples go")
    print("out at once, none is skipped). lost: commands planned + hold minus commands received.")
    print()
    hdr = f"{'stream thread':<22}{'stop latency ms (med/p99)':>27}{'samples (med/p99)':>20}{'ready':>8}{'SIGINT->hold ms':>17}{'exit':>6}{'last cmd':>10}{'traceback':>11}"
    print(hdr)
    print("-" * len(hdr))
    for res in results:
        st, sd = res["stops"], res["shutdown"]
        name = "normal" if res["priority"] == 0 else f"SCHED_FIFO {res['priority']}"
        lat = np.array([r["latency_ms"] for r in st]) if st else np.array([np.nan])
        lead = np.array([r["lead_samples"] for r in st], float) if st else np.array([np.nan])
        print(
            f"{name:<22}{np.median(lat):>15.1f} /{np.percentile(lat, 99):>8.1f}"
            f"{np.median(lead):>12.0f} /{np.percentile(lead, 99):>5.0f}{sum(r['ready'] for r in st):>5d}/{len(st):<2d}"
            f"{sd.get('to_hold_ms', float('nan')):>17.1f}{sd.get('status', -1):>6}{sd.get('last', float('nan')):>10.3g}"
            f"{'yes' if sd.get('traceback') else 'no':>11}"
        )
    print()
    print("stop latency: the planner's receipt of ~/stop -> its first stop-plan sample sent (the planner's clock);")
    print("samples: the splice lead (-1: planned on demand, not a ready stop). SIGINT->hold: the signal sent here ->")
    print("the hold (0.0) received here; exit: the planner's status; last cmd: the last command received.")


if __name__ == "__main__":
    main()
