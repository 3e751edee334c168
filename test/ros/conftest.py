"""ROS test harness: real rclpy nodes over real DDS, isolated per pytest run.

Isolation: a ``ROS_DOMAIN_ID`` already set is respected; otherwise each
pytest run takes a free one in 1..100 (a lock file per id under the temp
directory, held for the run, so two concurrent runs never share one).  With
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, set here at import, before any
``rclpy.init``, and every node in a namespace unique to the run, two runs on
one machine never talk.

rclpy is imported at module level on purpose: where it is missing, the ROS
tests fail at collection instead of being skipped.
"""

from __future__ import annotations

import atexit
import fcntl
import os
import random
import sys
import tempfile
import threading
import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

# small matrices: a multi-threaded BLAS is 100x slower on a loaded machine (see flexmotion_ros.nodes)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import pytest
import rclpy
from rcl_interfaces.srv import SetParameters, SetParametersAtomically
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter

_RNG = random.Random(os.getpid() ^ time.time_ns())
#: Lock files of the domain ids that test runs hold (one open, locked file per id; released at exit).
DOMAIN_LOCK_DIR = Path(tempfile.gettempdir()) / "flexmotion_ros_test_domains"
_DOMAIN_LOCKS: list = []


def _choose_domain_id() -> str:
    """The user's ``ROS_DOMAIN_ID`` if set; else a free id in 1..100, held for this process by a lock file.

    The lock (``flock`` on ``DOMAIN_LOCK_DIR/<id>.lock``) is released when the
    process exits, however it exits: two concurrent test runs never share an id.
    A set id is locked too where it is free (runs that pick one then avoid it).
    """
    DOMAIN_LOCK_DIR.mkdir(exist_ok=True)
    given = os.environ.get("ROS_DOMAIN_ID", "").strip()
    if given:
        _lock_domain(given)
        return given
    ids = [str(i) for i in range(1, 101)]
    _RNG.shuffle(ids)
    for i in ids:
        if _lock_domain(i):
            return i
    raise RuntimeError(f"no free ROS_DOMAIN_ID in 1..100: every lock in {DOMAIN_LOCK_DIR} is held")


def _lock_domain(domain_id: str) -> bool:
    """Take the lock of ``domain_id`` for this process; False where another process holds it."""
    f = open(DOMAIN_LOCK_DIR / f"{domain_id}.lock", "a")  # noqa: SIM115 -- held open: the lock lives with it
    try:
        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        f.close()
        return False
    _DOMAIN_LOCKS.append(f)
    return True


os.environ["ROS_DOMAIN_ID"] = _choose_domain_id()
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
NAMESPACE = f"/flexmotion_test_{os.getpid()}_{_RNG.randrange(1 << 20)}"

from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.srv import GetPlan
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from flexmotion_ros.execution.plan_process import PlanningProcesses
from flexmotion_ros.nodes import messages
from flexmotion_ros.nodes.planner_node import COMMAND_QOS, LATCHED_QOS, PlannerNode
from flexmotion_ros.nodes.plant_node import PLANT_QOS, PlantNode

# Planning child processes as ``ros2 run`` has them (forked while this process has one thread: at collection,
# before any node or executor starts), for tests whose timing depends on planning off the interpreter lock.
try:
    PLANNING: PlanningProcesses | None = PlanningProcesses.fork()
    atexit.register(PLANNING.close)
except (RuntimeError, OSError) as _exc:
    PLANNING, PLANNING_UNAVAILABLE = None, f"{type(_exc).__name__}: {_exc}"
else:
    PLANNING_UNAVAILABLE = ""

#: A stiff two-mode machine: a 1.0 move takes 1.11 s at 200 Hz (222 samples).
FAST: dict[str, Any] = {
    "model.b0": 1.0,
    "model.omega": [5.0, 13.0],
    "model.zeta": [0.01, 0.02],
    "model.b": [1.0, -0.7],
    "u_max": 10.0,
    "rate_hz": 200.0,
}


def overrides(params: dict[str, Any]) -> list[Parameter]:
    return [Parameter(k, value=v) for k, v in params.items()]


class Probe(Node):
    """The test's own node: records every topic and talks to the planner's services."""

    def __init__(self, context: Context) -> None:
        super().__init__("probe", namespace=NAMESPACE, context=context)
        self.lock = threading.Lock()
        self.joint_states: list[JointState] = []
        self.commands: list[tuple[float, float, int]] = []  # (receive time s, value, DDS send time ns)
        self.diagnostics: list[DiagnosticArray] = []
        self.trajectories: list[JointTrajectory] = []
        p = "flexmotion_planner/"
        self.create_subscription(JointState, "joint_states", self._rec(self.joint_states), PLANT_QOS)
        self.create_subscription(Float64MultiArray, "commands", self._on_command, COMMAND_QOS)
        self.create_subscription(DiagnosticArray, "/diagnostics", self._rec(self.diagnostics), 50)
        self.create_subscription(JointTrajectory, p + "planned_trajectory", self._rec(self.trajectories), LATCHED_QOS)
        self.goal_pub = self.create_publisher(Float64, p + "goal", 10)
        self.jt_pub = self.create_publisher(JointTrajectory, p + "joint_trajectory", 10)
        self.move = self.create_client(GetPlan, p + "move")
        self.plan = self.create_client(GetPlan, p + "plan")
        self.stop = self.create_client(Trigger, p + "stop")
        self.set_params = self.create_client(SetParameters, p + "set_parameters")
        self.set_params_atomically = self.create_client(SetParametersAtomically, p + "set_parameters_atomically")
        self.command_pub = self.create_publisher(Float64MultiArray, "commands", COMMAND_QOS)

    def _rec(self, store: list) -> Callable:
        def cb(msg) -> None:
            with self.lock:
                store.append(msg)

        return cb

    def _on_command(
        self, msg: Float64MultiArray, info: dict
    ) -> None:  # rclpy passes MessageInfo to two-argument callbacks
        with self.lock:
            self.commands.append((time.monotonic(), messages.command_value(msg), int(info["source_timestamp"])))

    def states(self) -> np.ndarray:
        """Plant states received so far, one row per joint_states message."""
        with self.lock:
            msgs = list(self.joint_states)
        return np.array([messages.state_from_joint_state(m) for m in msgs]) if msgs else np.empty((0, 0))

    def command_values(self) -> np.ndarray:
        with self.lock:
            return np.array([v for _, v, _ in self.commands])

    def command_send_times(self) -> np.ndarray:
        """DDS source timestamps (s, system clock) of the commands received so far."""
        with self.lock:
            return np.array([t for _, _, t in self.commands], dtype=float) * 1e-9

    def planner_status(self) -> tuple[int, str, dict[str, str]] | None:
        with self.lock:
            diags = list(self.diagnostics)
        for d in reversed(diags):
            st = messages.diagnostic_values(d, "flexmotion_planner: motion", f"{NAMESPACE}/flexmotion_planner")
            if st is not None:
                return st
        return None


def participant_ids() -> list[int]:
    """Fast DDS participant ids this process holds in the test's domain (from its bound UDP ports; Linux).

    RTPS ports (spec 9.6.1.1): a participant's metatraffic unicast port is
    ``7400 + 250 domain + 10 + 2 id``.  Under ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``
    rmw_fastrtps announces only to ids 0..31 (``maxInitialPeersRange = 32``):
    a participant with a higher id and its peers never discover each other.
    """
    inodes = set()
    for fd in os.listdir("/proc/self/fd"):
        try:
            target = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    base = 7400 + 250 * int(os.environ["ROS_DOMAIN_ID"]) + 10
    ids = []
    with open("/proc/net/udp") as f:
        for line in f.readlines()[1:]:
            fields = line.split()
            port = int(fields[1].split(":")[1], 16)
            if fields[9] in inodes and base <= port < base + 250 and (port - base) % 2 == 0:
                ids.append((port - base) // 2)
    return sorted(ids)


class Ros:
    """Nodes of one test, each on its own single-threaded executor in a background thread.

    One executor per node, as if each ran in its own process (a planner busy
    planning does not hold up the plant or the probe).  Not Jazzy's
    ``MultiThreadedExecutor``: it re-queues callbacks that have not started and
    spins holding the GIL (ros2/rclpy#1452); here it stalled a 100 Hz
    subscription for seconds.
    """

    def __init__(self) -> None:
        self._participants_before = participant_ids()
        self.context = Context()
        rclpy.init(context=self.context)
        self.nodes: list[Node] = []
        self.executors: list[SingleThreadedExecutor] = []
        self._threads: list[threading.Thread] = []
        self.errors: list[str] = []  # exceptions that ended a node's executor (a callback raised)
        self._closing = False
        self.probe = self.add(Probe(self.context))

    def _spin(self, executor: SingleThreadedExecutor) -> None:
        try:
            # not executor.spin(): seen twice in CI (5d05544, 67806ce), close()'s executor.shutdown did not wake
            # a spin blocked in its wait set, and the thread outlived the join; a bounded wait ends the loop
            # within 0.1 s of close() whatever the executor's guard condition does
            while not self._closing and self.context.ok():
                executor.spin_once(timeout_sec=0.1)
        except Exception:  # noqa: BLE001 -- the node went deaf: reported by wait_for and at teardown
            if not self._closing:  # not the shutdown race of close() (the executor's guard condition goes first)
                self.errors.append(traceback.format_exc())

    def add(self, node: Node) -> Node:
        executor = SingleThreadedExecutor(context=self.context)
        executor.add_node(node)
        thread = threading.Thread(target=self._spin, args=(executor,), daemon=True)
        thread.name = f"executor-{node.get_name()}"
        thread.start()
        self.nodes.append(node)
        self.executors.append(executor)
        self._threads.append(thread)
        return node

    def planner(self, **params: Any) -> PlannerNode:
        p = {**FAST, "publish_hold_when_idle": False, **params}
        return self.add(PlannerNode(context=self.context, namespace=NAMESPACE, parameter_overrides=overrides(p)))

    def plant(self, **params: Any) -> PlantNode:
        p = {**{k: v for k, v in FAST.items() if k != "u_max"}, "lockstep": True, **params}
        return self.add(PlantNode(context=self.context, namespace=NAMESPACE, parameter_overrides=overrides(p)))

    def connected(self, planner: PlannerNode, subscribers: int = 2, timeout: float = 10.0) -> None:
        """Wait until the command stream, the goal topics and the services are matched."""
        probe = self.probe
        wait_for(
            lambda: planner.commands_publisher.get_subscription_count() >= subscribers, timeout, "commands subscribers"
        )
        wait_for(
            lambda: probe.goal_pub.get_subscription_count() >= 1 and probe.jt_pub.get_subscription_count() >= 1,
            timeout,
            "goal topics",
        )
        for client in (probe.move, probe.plan, probe.stop, probe.set_params):
            assert client.wait_for_service(timeout_sec=timeout), client.srv_name

    def call(self, client, request, timeout: float = 10.0):
        future = client.call_async(request)
        wait_for(future.done, timeout, f"answer from {client.srv_name}")
        return future.result()

    def close(self) -> None:
        """Stop every executor, wait for its thread, tear down; fail on a callback error or a hung callback.

        Jazzy's ``Executor.shutdown`` does not wait for a running callback: the
        join does, and a thread still alive after it is a callback that hangs
        (it would run on into the next test).
        """
        self._closing = True
        for executor in self.executors:
            executor.shutdown(timeout_sec=2.0)
        hung, stacks = [], []
        for thread in self._threads:
            thread.join(timeout=10.0)
            if thread.is_alive():
                hung.append(thread.name)
                frame = sys._current_frames().get(thread.ident)  # noqa: SLF001 -- where it hangs, for the report
                stacks.append("".join(traceback.format_stack(frame)) if frame is not None else "(no frame)")
        for node in self.nodes:
            node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        # every node destroyed, so the context's DDS participant is gone: a leak here accumulates over the
        # suite until a new participant gets an id past Fast DDS's 32 localhost discovery ports (unseen)
        leaked = sorted(set(participant_ids()) - set(self._participants_before))
        if leaked:
            raise AssertionError(
                f"ROS teardown: DDS participant(s) {leaked} still alive after every node was destroyed"
            )
        if hung or self.errors:
            raise AssertionError(
                f"ROS teardown: callbacks still running in {hung}; executor errors: {self.errors}\n" + "\n".join(stacks)
            )


#: The harness of the running test (wait_for reports its executor errors at once).
_CURRENT: list[Ros] = []


def wait_for(predicate: Callable[[], bool], timeout: float, what: str = "condition") -> None:
    """Poll ``predicate`` until true; fail the test after ``timeout`` s (never hang).

    A callback that raised (and so ended its node's executor) fails the wait at
    once with its traceback, instead of a time-out later.
    """
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return
        for r in _CURRENT:
            if r.errors:
                raise AssertionError(f"a node's executor stopped while waiting for {what}:\n{r.errors[0]}")
        time.sleep(0.01)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


@pytest.fixture
def ros():
    r = Ros()
    _CURRENT.append(r)
    try:
        yield r
    finally:
        _CURRENT.remove(r)
        r.close()


def goal_request(x: float) -> GetPlan.Request:
    req = GetPlan.Request()
    req.goal.pose.position.x = float(x)
    return req
