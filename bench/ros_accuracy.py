"""Trajectory output vs the command stream, real-time plant, CPU burners: what arrives at the machine (issue 14).

``bench/ros_streaming.py --accuracy`` runs this.  For each output mode the
planner and a real-time plant run as processes of their own (the code
``ros2 run`` runs), beside ``--burners`` processes that burn a CPU each
(``python -c "while True: pass"``), on the Wie-Bernstein file at ``--rate``:

* ``stream``: one command per sample on ``commands``; the plant applies each
  from its DDS arrival (what an actuator does with a topic stream);
* ``trajectory``: the whole plan as one ``trajectory_msgs/JointTrajectory``;
  the plant plays it by its own clock with the joint trajectory controller's
  rule (interpolation none), integrating each piece exactly.

``--moves`` moves of ``--goal`` each (alternating ``+goal`` / ``0``); after
each, the plant's state once the planner is idle again (0.5 s later):
the final position error and the residual (the largest of |position error|,
|velocity| x 1 s and the mode's amplitude) as fractions of the move, median
and max over the moves, and the goal -> arrival time.

    python bench/ros_streaming.py --accuracy
    python bench/ros_streaming.py --accuracy --rate 1000 --moves 5 --burners 2
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time

import numpy as np


def run_mode(args, mode: str) -> dict:
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64

    from flexmotion_ros.core.config import load_config
    from flexmotion_ros.core.simulation.exact import modal_amplitudes
    from flexmotion_ros.nodes import messages
    from flexmotion_ros.nodes.planner_node import DIAGNOSTIC_NAME
    from flexmotion_ros.nodes.plant_node import PLANT_QOS

    model = load_config(args.config).model
    ns = f"/bench_accuracy_{os.getpid()}_{mode}"
    common = ["--ros-args", "-r", f"__ns:={ns}", "--params-file", args.config, "-p", f"rate_hz:={args.rate!r}"]
    planner_p = ["-p", "publish_hold_when_idle:=false", "-p", f"output:={mode}"]
    plant_p = ["-p", "lockstep:=false", "-p", "publish_rate_hz:=100.0"]
    if mode == "trajectory":
        planner_p += ["-p", f"trajectory.start_delay_s:={args.start_delay!r}"]
        plant_p += ["-p", "plant.input:=trajectory"]
    logs = [open(f"/tmp/bench_ros_accuracy_{mode}_{i}.log", "w") for i in range(2)]  # noqa: SIM115 -- closed below
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "flexmotion_ros.nodes.planner_node", *common, *planner_p],
            stdout=logs[0],
            stderr=subprocess.STDOUT,
        ),
        subprocess.Popen(
            [sys.executable, "-m", "flexmotion_ros.nodes.plant_node", *common, *plant_p],
            stdout=logs[1],
            stderr=subprocess.STDOUT,
        ),
    ]
    node = Node("bench_accuracy", namespace=ns)
    lock = threading.Lock()
    last: dict = {}

    def on_state(msg) -> None:
        with lock:
            last["x"] = messages.state_from_joint_state(msg)

    def on_diag(msg) -> None:
        st = messages.diagnostic_values(msg, DIAGNOSTIC_NAME, f"{ns}/flexmotion_planner")
        if st is not None:
            with lock:
                last["status"] = st[1]
                last["values"] = st[2]

    node.create_subscription(JointState, "joint_states", on_state, PLANT_QOS)
    node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 100)
    goal_pub = node.create_publisher(Float64, "flexmotion_planner/goal", 10)
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    spin = threading.Thread(target=ex.spin, daemon=True)
    spin.start()

    def wait(pred, timeout: float, what: str) -> None:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            with lock:
                if pred():
                    return
            time.sleep(0.01)
        raise RuntimeError(f"{mode}: timed out waiting for {what} (see /tmp/bench_ros_accuracy_{mode}_*.log)")

    rows = []
    try:
        wait(lambda: last.get("values", {}).get("streaming_ready") == "true", 30.0, "the plant to match")
        wait(lambda: goal_pub.get_subscription_count() >= 1 and "x" in last, 30.0, "the goal topic")
        position = 0.0
        for i in range(args.moves):
            target = args.goal if i % 2 == 0 else 0.0
            with lock:
                last.pop("status", None)
            t0 = time.monotonic()
            goal_pub.publish(Float64(data=target))
            wait(lambda: last.get("status") == "moving", 30.0, "the move")
            wait(lambda: last.get("status") == "idle", 120.0, "the end of the move")
            took = time.monotonic() - t0
            time.sleep(0.5)
            with lock:
                x = last["x"].copy()
            move = abs(target - position)
            amp = float(np.max(modal_amplitudes(model, x), initial=0.0))
            rows.append(
                {
                    "error": abs(x[0] - target) / move,
                    "residual": max(abs(x[0] - target), abs(x[1]) * 1.0, amp) / move,
                    "seconds": took,
                }
            )
            position = x[0]
    finally:
        ex.shutdown(timeout_sec=1.0)
        spin.join(timeout=2.0)
        node.destroy_node()
        for p in procs:
            p.send_signal(2)
        for p in procs:
            try:
                p.wait(timeout=10.0)
            except subprocess.TimeoutExpired:
                p.kill()
        for f in logs:
            f.close()
    return {"mode": mode, "rows": rows}


def accuracy(args) -> None:
    import rclpy

    burners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.burners)]
    rclpy.init(args=[])
    try:
        results = [run_mode(args, mode) for mode in ("stream", "trajectory")]
    finally:
        rclpy.try_shutdown()
        for b in burners:
            b.kill()
            b.wait()
    load = os.getloadavg()
    print(
        f"what reaches the machine, real-time plant, {os.path.basename(args.config)}, {args.rate:g} Hz, {args.moves} "
        f"moves of {args.goal:g}, beside {args.burners} CPU burner(s); load average {load[0]:.1f} on {os.cpu_count()} CPUs"
    )
    print()
    hdr = f"{'output':<12}{'final error / move (med/max)':>32}{'residual / move (med/max)':>30}{'goal -> idle s (med)':>23}"
    print(hdr)
    print("-" * len(hdr))
    for res in results:
        e = np.array([r["error"] for r in res["rows"]])
        r = np.array([r["residual"] for r in res["rows"]])
        s = np.array([r["seconds"] for r in res["rows"]])
        print(
            f"{res['mode']:<12}{np.median(e):>19.1e} / {e.max():<9.1e}{np.median(r):>18.1e} / {r.max():<9.1e}"
            f"{np.median(s):>16.2f}"
        )
    print()
    print("residual: the largest of |position error|, |velocity| x 1 s and the mode's amplitude, over the move's size.")
    print("trajectory mode starts a move trajectory.start_delay_s after it is planned (the transport margin).")


__all__ = ["accuracy", "run_mode"]
