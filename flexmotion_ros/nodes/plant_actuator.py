"""The plant's actuated joint: command interfaces, servo, disturbances, trajectories (a part of :class:`~.plant_node.PlantNode`).

``command_interface``: the value each command (or trajectory point) carries
-- ``effort`` (N), or the ``velocity`` / ``position`` reference a servo
tracks (``plant.servo_bandwidth`` rad/s, first order; 0: ideal).
``plant.disturbance.*``: a force impulse or step on the rigid body's input,
at a time from the first non-zero force (the first move).  ``plant.input: trajectory``: the plant
plays ``trajectory_msgs/JointTrajectory`` from ``trajectory.topic`` with the
joint trajectory controller's rule (interpolation ``none``, no look-ahead) by
its own clock, integrating each constant piece exactly -- in real time, a
trajectory replaces the current one from its DDS receipt time, and the state
is integrated and published at every timer tick (``publish_rate_hz``, else
``rate_hz``); in lockstep, a trajectory is played to its end as soon as it
arrives, one ``joint_states`` message per sample, and one that starts before
the plant's time (a replacement) rewinds the plant to its first point.

All of it runs through :class:`~flexmotion_ros.execution.actuator.Actuator`
(exact, ROS-free); the plain effort plant without a disturbance keeps the
node's own integration.  Coulomb friction is simulated on that plain path
only.  Real time with ``plant.input: commands`` stays effort-only and
undisturbed (use lockstep, or trajectories, for the rest).  Several inputs
(``model.inputs``) take the plain path only: another interface, input or a
disturbance is refused at start-up, naming the parameter.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from trajectory_msgs.msg import JointTrajectory as JointTrajectoryMsg

from ..core.errors import ConfigError, FlexmotionError
from ..core.interfaces.command import CommandInterface, check_acceleration_model, command_interface
from ..execution.actuator import Actuator, TrajectoryPlayback, disturbance_settings, servo_settings
from ..execution.jtc import started
from ..execution.trajectory import NS
from .plant_measurements import stamp_from_ns
from .trajectory_messages import trajectory_from_msg

#: Trajectories in: reliable, keep last 10 (a replacement is never dropped for an older one).
TRAJECTORY_IN_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
INPUTS = ("commands", "trajectory")


class ActuatorGlue:
    """The plant node's actuated joint (a mixin of :class:`~.plant_node.PlantNode`)."""

    def _actuator_setup(self, values: dict[str, Any]) -> None:
        """Validate the interface, servo, disturbance and input; create the actuator if the plain path will not do."""
        cfg = self.cfg
        source = values.get("plant.input", "commands")
        if source not in INPUTS:
            raise ConfigError("plant.input", f"must be one of {list(INPUTS)}, got {source!r}")
        iface = command_interface(values.get("command_interface", "effort"))
        servo = servo_settings(values)
        dist = disturbance_settings(values, iface)
        if cfg.inputs > 1:  # several inputs (issue 12): forces on 'commands' only, for now
            for name, given, default in (
                ("command_interface", iface.value, "effort"),
                ("plant.input", source, "commands"),
                ("plant.disturbance.type", "none" if not dist.active else dist.kind.value, "none"),
            ):
                if given != default:
                    raise ConfigError(
                        name,
                        f"is one-input only for now, got {given!r} with {cfg.inputs} inputs (model.inputs): "
                        f"use {default!r}",
                    )
        self._plays_trajectories = source == "trajectory"
        self._actuator: Actuator | None = None
        self._playback: TrajectoryPlayback | None = None
        self._pending: list[tuple[Any, int]] = []
        self.trajectory_errors = 0
        # real time: trajectories whose first point was already past when DDS delivered them (the start is
        # played late, as a joint trajectory controller would: the transport ate the planner's start delay)
        self.trajectories_late = 0
        self.trajectory_late_max_ms = 0.0
        if iface is CommandInterface.EFFORT and not dist.active and not self._plays_trajectories:
            return  # the plain plant (its own exact integration, Coulomb friction)
        if cfg.coulomb_force > 0.0:
            raise ConfigError(
                "plant.coulomb_force",
                "is simulated for an undisturbed effort joint driven by commands only; set it to 0.0 with "
                f"command_interface {iface.value}, plant.input {source} or a disturbance",
            )
        if not cfg.lockstep and not self._plays_trajectories:
            raise ConfigError(
                "plant.input",
                "a real-time plant driven by commands supports an undisturbed effort joint only; use lockstep: true, "
                "or plant.input: trajectory",
            )
        if iface is not CommandInterface.EFFORT:
            try:
                check_acceleration_model(cfg.model, iface)
            except FlexmotionError as exc:
                raise ConfigError("model.c", getattr(exc, "reason", str(exc))) from None
        t0 = 0 if cfg.lockstep and not self._plays_trajectories else time.time_ns()
        self._actuator = Actuator(cfg.model, self.x_event, iface, servo, dist, t_ns=t0)
        self._period_ns = round(NS / cfg.rate_hz)
        if self._plays_trajectories:
            self._playback = TrajectoryPlayback(
                self._actuator, str(values.get("joint_name", "rigid_body")), period_ns=self._period_ns
            )
        parts = [f"command_interface {iface.value}"]
        if not servo.ideal and iface is not CommandInterface.EFFORT:
            parts.append(f"first-order servo {servo.bandwidth:g} rad/s")
        if dist.active:
            parts.append(f"disturbance {dist.kind.value} {dist.value:g} at {dist.time_s:g} s")
        if self._plays_trajectories:
            parts.append(f"trajectories on {values.get('trajectory.topic', 'joint_trajectory')}")
        self._actuator_summary = ", ".join(parts)

    def _actuator_interfaces(self, values: dict[str, Any]) -> bool:
        """Subscribe to trajectories (plant.input: trajectory) and start the real-time timer; False: the plain commands."""
        if not self._plays_trajectories:
            return False
        topic = str(values.get("trajectory.topic", "joint_trajectory"))
        self.create_subscription(
            JointTrajectoryMsg,
            topic,
            self._on_trajectory,
            TRAJECTORY_IN_QOS,
            callback_group=MutuallyExclusiveCallbackGroup(),
        )
        if not self.cfg.lockstep:
            rate = float(values.get("publish_rate_hz", 0.0)) or self.cfg.rate_hz
            self.create_timer(1.0 / rate, self._on_trajectory_tick, callback_group=MutuallyExclusiveCallbackGroup())
        return True

    # ------------------------------------------------------------- commands
    def _actuated_command(self, value: float, info: dict | None = None) -> None:
        """Lockstep: one setpoint, one sample period, exactly (under the node's lock).

        The sensors read the state when the command is applied, stamped with its send time (plant_measurements).
        """
        act = self._actuator
        t = act.t_ns + self._period_ns
        act.set(value, t)
        sent = info.get("source_timestamp") if info else None
        self._measure.publish(act.x, act.applied, stamp_from_ns(sent) if sent else self.get_clock().now().to_msg())
        act.advance_to(t)
        self.x = self.x_event = act.x
        self.u = act.applied
        self.applied += 1
        self._publish(self.u)

    # ----------------------------------------------------------- trajectories
    def _on_trajectory(self, msg: JointTrajectoryMsg, info: dict) -> None:  # two arguments: MessageInfo too
        received = int(info.get("received_timestamp") or 0) if info else 0
        received = received or time.time_ns()
        try:
            traj = trajectory_from_msg(msg)
            self._playback.check(traj)
        except FlexmotionError as exc:
            self.trajectory_errors += 1
            self.get_logger().error(f"trajectory refused: {exc}")
            return
        with self._lock:
            self.received += 1
            if not self.cfg.lockstep:
                self._pending.append((traj, received))
                return
            try:
                self._playback.receive_eager(traj, self.get_clock().now().nanoseconds, on_sample=self._sample_played)
            except FlexmotionError as exc:
                self.trajectory_errors += 1
                self.get_logger().error(f"trajectory refused: {exc}")

    def _sample_played(self, t_ns: int) -> None:
        """Lockstep trajectory: the state at a sample instant, published."""
        act = self._actuator
        self.x = self.x_event = act.x
        self.u = act.applied
        self.applied += 1
        self._publish(self.u)
        self._measure.publish(act.x, self.u, stamp_from_ns(t_ns))  # the reading at the sample instant

    def _on_trajectory_tick(self) -> None:
        """Real time: install what arrived (from its receipt), integrate to now, publish."""
        with self._lock:
            now = time.time_ns()
            self._trajectory_advance(now)
            self._publish(self.u)
            self._measure.publish(self.x, self.u, stamp_from_ns(now))

    def _trajectory_advance(self, now_ns: int) -> None:
        pb, act = self._playback, self._actuator
        pending, self._pending = self._pending, []
        for traj, received in pending:
            self._note_late_start(traj, received)
            pb.install(traj, max(received, act.t_ns))
            self.applied += 1
            self.max_lag = max(self.max_lag, (now_ns - received) / NS)
        pb.play_to(now_ns)
        self.x = self.x_event = act.x
        self.u = act.applied

    def _note_late_start(self, traj, received_ns: int) -> None:
        """Count (and warn of) a trajectory delivered after its first point: its start cannot be played on time."""
        if not traj.points:
            return
        late_ns = received_ns - int(started(traj, received_ns).point_times_ns()[0])
        if late_ns <= 0:
            return
        self.trajectories_late += 1
        self.trajectory_late_max_ms = max(self.trajectory_late_max_ms, late_ns / 1e6)
        self.get_logger().warning(
            f"trajectory arrived {late_ns / 1e6:.1f} ms after its first point: its start plays late "
            "(raise the planner's trajectory.start_delay_s above the transport's delay)"
        )

    def _actuated_state(self) -> np.ndarray:
        """The state now (real-time trajectories: integrated to now), else after the last sample."""
        with self._lock:
            if self._plays_trajectories and not self.cfg.lockstep:
                self._trajectory_advance(time.time_ns())
            return np.array(self._actuator.x, float)

    def playback_rewinds(self) -> int:
        """Lockstep trajectories: how often a replacement rewound the plant (0 without trajectories)."""
        return self._playback.rewinds if self._playback is not None else 0

    def _actuator_status(self) -> dict[str, Any]:
        if self._actuator is None:
            return {}
        out = {"actuator": self._actuator_summary}
        if self._playback is not None:
            out["trajectories_received"] = self._playback.received
            out["trajectory_rewinds"] = self._playback.rewinds
            out["trajectories_refused"] = self.trajectory_errors
            out["trajectories_late"] = self.trajectories_late
            out["trajectory_late_max_ms"] = self.trajectory_late_max_ms
        return out


__all__ = ["INPUTS", "TRAJECTORY_IN_QOS", "ActuatorGlue"]
