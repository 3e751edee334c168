"""``flexmotion demo``: planner and plant as real ROS 2 nodes, one move, a summary and a plot.

Starts ``flexmotion_planner`` and ``flexmotion_plant`` as two processes
(``python -m flexmotion_ros.nodes.planner_node`` / ``plant_node``: the same
code as ``ros2 run flexmotion_ros planner`` / ``plant``) talking over real
DDS, asks ``~/move`` for the goal, records ``commands`` and ``joint_states``
until the plant has applied the whole stream, then prints what was planned
and what the plant did, and writes a PNG (command, position, modal
deflections).

Readiness: the goal is sent only when every publisher the demo depends on
has matched every subscription, judged on the writer side (DDS drops what a
volatile writer published before a match): the planner's ``commands``
publisher (its ``command_subscribers`` on ``/diagnostics``: the plant and this
demo) and the plant's ``joint_states`` publisher (its
``joint_states_subscribers``: every subscription this process knows on the
topic).  Lockstep samples lost anyway are reported at once, with the counts
(:class:`_LossCheck`), instead of waiting out ``--timeout``.

Several inputs (a parameter file with ``model.inputs``, e.g. ``config/gantry.yaml``):
``--goal 3,2`` gives one target per rigid body (sent as ``pose.position.x, y, z``
of ``~/move``), the commands are recorded as rows of ``m`` and the summary and
the figure show every axis, every drive and every sway mode (:mod:`.multi_demo`).

Isolation: unless ``ROS_DOMAIN_ID`` is set, the demo picks a random domain
(1..100) with ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` for itself and its
nodes, all in a namespace of its own.  rclpy is imported only when the demo
runs, so the rest of the command line works without ROS.
"""

from __future__ import annotations

import argparse
import math
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from ..core.errors import ConfigError, GoalError
from ..core.multi_input.config import MultiPlannerConfig
from ..core.multi_input.dispatch import load_any_config
from ..core.parameter_file import read_parameter_file
from . import demo_report, multi_demo
from .multi_plan import numbers
from .shipped import DEFAULT_CONFIG, find_shipped, share_directories


def default_config() -> str | None:
    """The shipped Wie-Bernstein parameter file (install share directory or source checkout), if found."""
    found = find_shipped(DEFAULT_CONFIG)
    return None if found is None else str(found)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="closed loop over ROS 2: planner + simulated plant, one move, summary and plot")
    p.add_argument("--config", default=None, help="ROS 2 parameter file (default: config/wie_bernstein.yaml)")
    p.add_argument(
        "--goal",
        default="1.0",
        help="target position (m or rad), from rest at 0 (default 1.0); several rigid bodies: one each, e.g. 3,2",
    )
    p.add_argument("--plot", default="demo.png", help="PNG to write (default demo.png; '' for none)")
    p.add_argument("--rate", type=float, default=None, help="command rate (Hz; default: the file's rate_hz)")
    p.add_argument(
        "--realtime", action="store_true", help="plant on its own clock (default: lockstep, one sample per command)"
    )
    p.add_argument(
        "--apply-at",
        choices=["send", "arrival"],
        default="send",
        dest="apply_at",
        help="real time: commands act from their send time (default: the planner's timing alone) or their "
        "DDS arrival at the plant (adds the transport and the plant process's scheduling)",
    )
    p.add_argument(
        "--omega-scale",
        type=float,
        nargs="+",
        dest="omega_scale",
        help="plant model error: true/nominal frequency per mode",
    )
    p.add_argument("--timeout", type=float, default=60.0, help="give up after this many seconds (default 60)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    config_path = args.config or default_config()
    if config_path is None:
        searched = ", ".join(str(d / DEFAULT_CONFIG) for d in share_directories())
        raise ConfigError("config", f"no default parameter file found (searched {searched}); give --config FILE")
    config = load_any_config(config_path)  # refuse a bad file before starting anything
    goal = numbers(args.goal, "goal")
    if isinstance(config, MultiPlannerConfig):
        args.goal = config.check_goal(goal)
        if config.model.k > len(multi_demo.POSE_AXES):
            raise GoalError(
                "goal", f"the demo sends goals as pose x, y, z: at most 3 rigid bodies, got {config.model.k}"
            )
    else:
        if len(goal) != 1:
            raise GoalError("goal", f"this single-input model takes one target, got {len(goal)}: {goal}")
        args.goal = goal[0]
        if not math.isfinite(args.goal):
            raise GoalError("goal", f"must be finite, got {args.goal}")
        config.check_goal(args.goal)
    rate = float(args.rate or config.rate_hz)
    if not (0.0 < rate <= 1e6):
        raise ConfigError("rate_hz", f"must be in (0, 1e6] Hz, got {rate}")
    plant_params = read_parameter_file(config_path, "flexmotion_plant")
    plant_params.update({"rate_hz": rate, "lockstep": not args.realtime})
    if args.omega_scale:
        plant_params["plant.omega_scale"] = [float(s) for s in args.omega_scale]
    from ..nodes.plant_parameters import (
        plant_config_from_parameters,  # validates the model error too
    )

    plant_cfg = plant_config_from_parameters(plant_params)
    return _Demo(args, config_path, config, plant_cfg, rate).run()


#: Subscriptions the plant's ``joint_states`` publisher must have matched before the goal, at least: this demo's.
JOINT_STATES_MATCHES = 1
#: Lockstep: once the plant has applied every command, this long (s) without a new sample means samples were lost.
LOSS_QUIET_S = 2.0


class _LossCheck:
    """Fail at once when lockstep samples are missing for good, instead of waiting out the timeout.

    The plant has published one ``joint_states`` sample per command; when its
    diagnostics say it applied all ``expected`` commands and no sample has
    arrived here for :data:`LOSS_QUIET_S`, the missing ones are lost (a reliable
    reader that was matched gets every sample: only samples published before the
    match can be missing).
    """

    def __init__(
        self, states: list, plant_status: dict, lock: threading.Lock, expected: int, published_before: int
    ) -> None:
        self.states, self.plant_status, self.lock = states, plant_status, lock
        self.expected, self.published_before = expected, published_before
        self.count, self.since = -1, time.monotonic()

    def __call__(self) -> None:
        """Raise ``RuntimeError`` (the reason, with the counts) once the missing samples cannot come any more."""
        with self.lock:
            n = len(self.states)
            applied = int(self.plant_status.get("commands_applied", 0))
            published = int(self.plant_status.get("joint_states_published", 0))
        now = time.monotonic()
        if n != self.count:
            self.count, self.since = n, now
            return
        if applied >= self.expected and n < self.expected and now - self.since > LOSS_QUIET_S:
            raise RuntimeError(
                f"lost {self.expected - n} of the plant's {self.expected} joint_states samples of the move: "
                f"{n} received here, the plant published {published} ({self.published_before} before its "
                f"publisher had matched this demo's subscription) and applied {applied} commands; "
                f"nothing arrived for {LOSS_QUIET_S:g} s"
            )


class _Demo:
    def __init__(self, args, config_path, config, plant_cfg, rate) -> None:
        self.args, self.config_path, self.config, self.plant_cfg, self.rate = args, config_path, config, plant_cfg, rate
        self.dt = 1.0 / rate
        self.namespace = f"/flexmotion_demo_{os.getpid()}"
        self.procs: list[subprocess.Popen] = []
        self.logdir = Path(tempfile.mkdtemp(prefix="flexmotion_demo_"))

    # ------------------------------------------------------------ processes
    def _environment(self) -> dict[str, str]:
        env = dict(os.environ)
        if "ROS_DOMAIN_ID" not in env:
            env["ROS_DOMAIN_ID"] = str(random.SystemRandom().randint(1, 100))
            env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        env.setdefault("OPENBLAS_NUM_THREADS", "1")
        env["PYTHONUNBUFFERED"] = "1"
        return env

    def _start(self, module: str, params: list[str], env: dict[str, str]) -> None:
        cmd = [
            sys.executable,
            "-m",
            f"flexmotion_ros.nodes.{module}",
            "--ros-args",
            "-r",
            f"__ns:={self.namespace}",
            "--params-file",
            self.config_path,
        ]
        for p in params:
            cmd += ["-p", p]
        log = open(self.logdir / f"{module}.log", "w")  # noqa: SIM115 -- the child keeps it
        self.procs.append(subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT))

    def _stop_all(self) -> None:
        for p in self.procs:
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        for p in self.procs:
            try:
                p.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(timeout=5.0)

    def _check_alive(self) -> None:
        for p in self.procs:
            if p.poll() is not None:
                name = Path(p.args[2]).name if len(p.args) > 2 else "node"
                log = "\n".join(
                    (self.logdir / f"{n}.log").read_text()
                    for n in ("planner_node", "plant_node")
                    if (self.logdir / f"{n}.log").exists()
                )
                raise RuntimeError(f"{name} exited with status {p.returncode}:\n{log}")

    # ------------------------------------------------------------------ run
    def run(self) -> int:
        env = self._environment()
        os.environ.update({k: env[k] for k in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE") if k in env})
        rate = f"rate_hz:={self.rate!r}"
        self._start("planner_node", [rate, "publish_hold_when_idle:=false", "stream_priority:=50"], env)
        plant = [rate, f"lockstep:={'false' if self.args.realtime else 'true'}"]
        if self.args.realtime:  # commands apply at their arrival whatever the publish rate; spare the CPU
            plant += ["publish_rate_hz:=250.0", f"plant.apply_at:={self.args.apply_at}"]
        if self.args.omega_scale:
            plant.append("plant.omega_scale:=[" + ",".join(repr(float(s)) for s in self.args.omega_scale) + "]")
        self._start("plant_node", plant, env)
        import rclpy

        rclpy.init(args=[])
        status = 1
        try:
            status = self._drive(rclpy)
            return status
        except RuntimeError as exc:
            sys.stderr.write(f"flexmotion: error: {exc}\n")
            return 1
        finally:
            self._stop_all()
            rclpy.try_shutdown()
            if status == 0:  # the node logs are kept only when something went wrong
                shutil.rmtree(self.logdir, ignore_errors=True)

    def _drive(self, rclpy) -> int:
        from diagnostic_msgs.msg import DiagnosticArray
        from nav_msgs.srv import GetPlan
        from rclpy.event_handler import SubscriptionEventCallbacks
        from rclpy.executors import SingleThreadedExecutor
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Float64MultiArray

        from ..nodes import messages
        from ..nodes.planner_node import COMMAND_QOS, DIAGNOSTIC_NAME
        from ..nodes.plant_node import DIAGNOSTIC_NAME as PLANT_DIAGNOSTIC_NAME
        from ..nodes.plant_node import PLANT_QOS

        node = rclpy.create_node("flexmotion_demo", namespace=self.namespace)
        lock = threading.Lock()
        commands: list[tuple[float, float]] = []
        states: list[tuple[float, np.ndarray, float]] = []
        status: dict = {}
        plant_status: dict = {}

        multi = isinstance(self.config, MultiPlannerConfig)

        def on_command(msg) -> None:
            with lock:  # several inputs: the whole row of m values
                commands.append((time.time(), list(msg.data) if multi else messages.command_value(msg)))

        def on_state(msg) -> None:
            effort = msg.effort[0] if len(msg.effort) else math.nan  # several inputs: no effort per joint
            with lock:
                states.append((messages.from_time(msg.header.stamp), messages.state_from_joint_state(msg), effort))

        def on_diag(msg) -> None:
            st = messages.diagnostic_values(msg, DIAGNOSTIC_NAME, f"{self.namespace}/flexmotion_planner")
            if st is not None:
                with lock:
                    status.update(level=st[0], message=st[1], values=st[2])
            st = messages.diagnostic_values(msg, PLANT_DIAGNOSTIC_NAME, f"{self.namespace}/flexmotion_plant")
            if st is not None:
                with lock:
                    plant_status.update(st[2])

        node.create_subscription(Float64MultiArray, "commands", on_command, COMMAND_QOS)
        # the plant's best-effort idle heartbeat cannot match this reliable reader (by design): no warning for it
        node.create_subscription(
            JointState,
            "joint_states",
            on_state,
            PLANT_QOS,
            event_callbacks=SubscriptionEventCallbacks(incompatible_qos=lambda _event: None),
        )
        node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 50)
        move = node.create_client(GetPlan, "flexmotion_planner/move")
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        spinner = threading.Thread(target=executor.spin, daemon=True)
        spinner.start()
        deadline = time.monotonic() + self.args.timeout

        def wait(pred, what: str, check=None) -> None:
            while not pred():
                self._check_alive()
                if check is not None:
                    check()
                if time.monotonic() > deadline:
                    raise RuntimeError(
                        f"timed out waiting for {what} (node logs in {self.logdir}); "
                        f"{len(commands)} commands, {len(states)} plant samples received"
                    )
                time.sleep(0.02)

        try:
            print(
                f"starting flexmotion_planner and flexmotion_plant ({'real time' if self.args.realtime else 'lockstep'}, "
                f"{self.rate:g} Hz, ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID')}) ...",
                flush=True,
            )
            wait(lambda: move.service_is_ready(), "the planner's ~/move service")
            # the planner must see both the plant and us on 'commands' before streaming
            wait(
                lambda: int(status.get("values", {}).get("command_subscribers", 0)) >= 2,
                "plant and demo subscribed to commands",
            )
            # ... and the plant's joint_states writer must have matched our reader: samples published
            # before that match are lost (volatile durability).  Only the writer side knows it, and it
            # counts every reader (the planner's measured-state one too): wait for all the subscriptions
            # on the topic this process knows of.  The planner creates its subscriptions before its
            # services and discovery announces them in order, so its ~/move being ready means its
            # joint_states subscription is known here.
            topic = f"{self.namespace}/joint_states"
            expected = lambda: max(JOINT_STATES_MATCHES, node.count_subscribers(topic))  # noqa: E731
            wait(
                lambda: int(plant_status.get("joint_states_subscribers", 0)) >= expected(),
                "the plant's joint_states publisher to match every subscription (this demo's and the planner's; "
                "plant diagnostics joint_states_subscribers)",
            )
            with lock:
                published_before = int(plant_status.get("joint_states_published", 0))
            req = GetPlan.Request()
            for axis, target in zip(multi_demo.POSE_AXES, np.atleast_1d(self.args.goal)):
                setattr(req.goal.pose.position, axis, float(target))
            t_req = time.time()
            future = move.call_async(req)
            wait(future.done, "the ~/move answer")
            plan = future.result().plan
            reason = messages.path_error(plan)
            if reason is not None:
                raise RuntimeError(f"~/move refused: {reason}")
            K = len(plan.poses) - 1
            planned_t = np.array([messages.from_time(p.header.stamp) for p in plan.poses])
            planned_p = np.array([p.pose.position.x for p in plan.poses])
            if multi:
                k = self.config.model.k
                planned_p = np.array(
                    [[getattr(p.pose.position, a) for a in multi_demo.POSE_AXES[:k]] for p in plan.poses]
                )
            wait(lambda: len(commands) >= K + 1, f"{K + 1} commands")
            if self.args.realtime:
                # every command integrated (from its arrival time), then watch it stand still
                wait(
                    lambda: int(plant_status.get("commands_applied", 0)) >= K + 1,
                    f"the plant to apply {K + 1} commands",
                )
                t_done = time.time() + 0.5
                # states published after that (this process may lag behind the plant)
                wait(lambda: bool(states) and states[-1][0] > t_done, "the plant's state after the move")
            else:
                wait(
                    lambda: len(states) >= K + 1,
                    f"{K + 1} plant samples",
                    _LossCheck(states, plant_status, lock, K + 1, published_before),
                )
            time.sleep(0.3)
            wait(lambda: status.get("message") == "idle", "the planner's idle status")
        finally:
            executor.shutdown(timeout_sec=1.0)
            node.destroy_node()
        with lock:
            cmds, sts, diag = list(commands), list(states), dict(status)
            diag["plant"] = dict(plant_status)
        if multi:
            return multi_demo.report(self, t_req, cmds, sts, diag, K)
        return demo_report.report(self, t_req, cmds, sts, diag, planned_t, planned_p, K)
