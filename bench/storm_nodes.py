"""The storm's processes and its own node (``bench/storm.py``): the planner's parameters, node processes, memory.

:class:`Storm` is the storm's node (requests out; joint states and
diagnostics in); :func:`start_node` starts ``flexmotion_planner`` or
``flexmotion_plant`` as a process, as ``ros2 run`` does; :func:`rss_mb` /
:func:`family_pss_mb` read a process's memory (Linux).
"""

from __future__ import annotations

import math
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

RATE_HZ = 200.0
LIMIT = 3.0
PARAMS = """/**:
  ros__parameters:
    model:
      b0: 1.0
      c: 0.0
      omega: [5.0, 13.0]
      zeta: [0.01, 0.02]
      b: [1.0, -0.7]
    u_max: 10.0
    rate_hz: {rate!r}
    limits:
      position_min: {low!r}
      position_max: {high!r}
"""
#: An answer or a log line naming an internal failure (a Python exception type, a traceback, "unexpected").
INTERNAL = re.compile(r"Traceback|unexpected|\b[A-Z][A-Za-z]*(Error|Exception)\b")


def proc_mb(path: str, field: str) -> float:
    """A ``kB`` field (``VmRSS:``, ``Pss:``) of a /proc file in MB (Linux)."""
    with open(path) as f:
        for line in f:
            if line.startswith(field):
                return int(line.split()[1]) / 1024.0
    return math.nan


def rss_mb(pid: int) -> float:
    """Resident set size (MB) of process ``pid``."""
    return proc_mb(f"/proc/{pid}/status", "VmRSS:")


def pss_mb(pid: int) -> float:
    """Proportional set size (MB) of process ``pid``: shared pages split among their sharers."""
    return proc_mb(f"/proc/{pid}/smaps_rollup", "Pss:")


def family_pss_mb(pid: int) -> float:
    """PSS (MB) of process ``pid`` and its direct children (the planning and stream processes, forked:
    their copy-on-write pages are shared, so RSS would count them twice)."""
    total = pss_mb(pid)
    for task in Path(f"/proc/{pid}/task").glob("*/children"):
        for child in task.read_text().split():
            try:
                total += pss_mb(int(child))
            except OSError:
                pass  # the child ended meanwhile
    return total


def start_node(
    exe: str, ns: str, params: Path, extra: list[str], log: Path, env: dict | None = None
) -> subprocess.Popen:
    cmd = [sys.executable, "-m", f"flexmotion_ros.nodes.{exe}", "--ros-args", "-r", f"__ns:={ns}"]
    cmd += ["--params-file", str(params), *[a for x in extra for a in ("-p", x)]]
    out = open(log, "w")  # noqa: SIM115 -- the child's log, closed when the child ends
    env = {**os.environ, "PYTHONUNBUFFERED": "1", **(env or {})}
    return subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, env=env)


class Storm:
    """This process's node: requests out, commands / states / diagnostics in."""

    def __init__(self, ns: str) -> None:
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from nav_msgs.srv import GetPlan
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Float64
        from std_srvs.srv import Trigger
        from trajectory_msgs.msg import JointTrajectory

        from flexmotion_ros.nodes.plant_node import PLANT_QOS

        self.node = rclpy.create_node("storm", namespace=ns)
        self.ns = ns
        self.lock = threading.Lock()
        self.state: np.ndarray | None = None
        self.planner_status: dict = {}
        self.plant_status: dict = {}
        n = self.node
        n.create_subscription(JointState, "joint_states", self._on_state, PLANT_QOS)
        n.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 100)
        goal_qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
        self.goal_pub = n.create_publisher(Float64, "flexmotion_planner/goal", goal_qos)
        self.jt_pub = n.create_publisher(JointTrajectory, "flexmotion_planner/joint_trajectory", goal_qos)
        self.move = n.create_client(GetPlan, "flexmotion_planner/move")
        self.plan = n.create_client(GetPlan, "flexmotion_planner/plan")
        self.stop = n.create_client(Trigger, "flexmotion_planner/stop")
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(n)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()
        self.types = {"GetPlan": GetPlan, "Trigger": Trigger, "Float64": Float64, "JointTrajectory": JointTrajectory}

    def _on_state(self, msg) -> None:
        from flexmotion_ros.nodes import messages

        x = messages.state_from_joint_state(msg)
        with self.lock:
            self.state = x

    def _on_diag(self, msg) -> None:
        from flexmotion_ros.nodes import messages

        for name, hw, store in (
            ("flexmotion_planner: motion", f"{self.ns}/flexmotion_planner", "planner_status"),
            ("flexmotion_plant: simulation", f"{self.ns}/flexmotion_plant", "plant_status"),
        ):
            st = messages.diagnostic_values(msg, name, hw)
            if st is not None:
                with self.lock:
                    setattr(self, store, {"message": st[1], "stamp": time.monotonic(), **st[2]})

    def call(self, client, request, timeout: float = 30.0):
        """(answer or None, round-trip seconds)."""
        t0 = time.monotonic()
        fut = client.call_async(request)
        end = t0 + timeout
        while not fut.done() and time.monotonic() < end:
            time.sleep(0.0005)
        return (fut.result() if fut.done() else None), time.monotonic() - t0

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1.0)
        self.thread.join(timeout=5.0)
        self.node.destroy_node()


def goal_request(storm: Storm, x: float):
    req = storm.types["GetPlan"].Request()
    req.goal.pose.position.x = float(x)
    return req


def trajectory(storm: Storm, names: list[str], x: float, t: float):
    from trajectory_msgs.msg import JointTrajectoryPoint

    msg = storm.types["JointTrajectory"]()
    msg.joint_names = names
    pt = JointTrajectoryPoint()
    pt.positions = [float(x)]
    pt.velocities = [0.0]
    sec = math.floor(t)
    pt.time_from_start.sec = int(sec)
    pt.time_from_start.nanosec = int(round((t - sec) * 1e9)) if t >= 0 else 0
    if t < 0:
        pt.time_from_start.sec = -1
    msg.points = [pt]
    return msg


def stop_processes(nodes: dict[str, subprocess.Popen], storm: Storm, recorder: subprocess.Popen, probes: list) -> tuple:
    """End the nodes (SIGINT, as Ctrl-C), this process's node, the recorder and the pinned loops.

    Returns ``(crashed, status)``: the nodes that had ended before (their exit codes), and every node's exit code
    (or ``"killed"``).
    """
    planner, plant = nodes["planner"], nodes["plant"]
    crashed = {name: p.poll() for name, p in (("planner", planner), ("plant", plant)) if p.poll() is not None}
    for p in (planner, plant):
        if p.poll() is None:
            p.send_signal(signal.SIGINT)
    status = {}
    for name, p in (("planner", planner), ("plant", plant)):
        try:
            status[name] = p.wait(timeout=10.0)
        except subprocess.TimeoutExpired:
            p.kill()
            status[name] = "killed"
    storm.close()
    recorder.send_signal(signal.SIGINT)
    try:
        recorder.wait(timeout=20.0)
    except subprocess.TimeoutExpired:
        recorder.kill()
    for probe in probes:
        probe.send_signal(signal.SIGINT)
        probe.wait(timeout=10.0)
    return crashed, status
