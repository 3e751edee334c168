"""``flexmotion_plant``: a simulated flexible machine that closes the loop.

``ros2 run flexmotion_ros plant --ros-args --params-file config/wie_bernstein.yaml -p lockstep:=true``

Subscribes to ``commands`` (std_msgs/Float64MultiArray, first element = u)
and publishes ``joint_states`` (sensor_msgs/JointState: ``rigid_body``,
``mode_1`` ... ``mode_N``; position and velocity of each; effort = the
applied command on every joint), what its sensors read on ``measurements``
(physical coordinates ``measurement.names``, with white noise
``plant.noise_std``; :mod:`.plant_measurements`) and its status on
``/diagnostics``.

Several inputs (``model.inputs`` set, issue 12): ``commands`` carries one
value per input (``model.inputs`` order; a message with another count, or a
non-finite value, applies zero force), the integration is the exact ZOH of
the ``m``-input model (:func:`core.multi_input.exact.step_matrices`), and
``joint_states`` names ``model.rigid_bodies`` then ``model.mode_names``
(effort left empty: there is one command per input, not per joint).

Integration is exact (zero-order hold, the core's matrix-exponential
propagation :func:`core.simulation.step_matrices` of the simulated model; no
ODE solver):

* ``lockstep: true`` -- each command received advances exactly one sample
  period ``1/rate_hz``, then the state is published: deterministic, for tests;
  while no command arrives it publishes the unchanged state every
  ``plant.idle_state_period_s`` as a best-effort heartbeat (a reliable
  subscriber never sees it; the planner's measured-state subscription does);
* ``lockstep: false`` -- real time on the system clock: each command applies
  from the instant DDS received it (``MessageInfo.received_timestamp``, on a
  1 us grid; ``plant.apply_at: send`` uses the publisher's send time instead:
  a transport with constant latency, immune to this process being starved of
  CPU) and is held; after ``command_timeout`` s without a command
  the force is zero.  Commands are queued as they are handed over and
  integrated in order by a timer at ``rate_hz`` (``publish_rate_hz`` to
  publish less often), which then propagates to now and publishes.  So a
  command that a busy executor hands over late still applies exactly from its
  arrival; a published state may miss commands not yet handed over.

Model error (``plant.omega_scale``, ``plant.extra_zeta``) makes the simulated
machine differ from the parameter file the planner uses, to show what a wrong
model costs; ``plant.coulomb_force`` adds Coulomb friction at the rigid body
(simulated by ``core.friction.simulate_coulomb``).
"""

from __future__ import annotations

import gc
import math
import sys
import threading
import time
from collections import deque
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from ..core.friction.contact import simulate_coulomb
from ..core.multi_input.dispatch import mode_names, positions_text, rest_state, rigid_body_names
from ..core.multi_input.exact import step_matrices as multi_step_matrices
from ..core.simulation.exact import PiecewiseConstant, step_matrices
from . import messages
from .parameters import declare, declared_values, validating_callback
from .plant_actuator import ActuatorGlue
from .plant_measurements import MeasurementPublisher, stamp_from_ns
from .plant_parameters import PlantConfig, plant_config_from_parameters, plant_specs
from .runner import run

NODE_NAME = "flexmotion_plant"
DIAGNOSTIC_NAME = "flexmotion_plant: simulation"
#: Deep (10 s at 1 kHz) and reliable both ways, so that lockstep tests and the demo see every sample.
PLANT_QOS = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
#: The lockstep plant's idle heartbeat on joint_states: best effort, so a reliable subscriber (a recorder
#: counting one state per command) never sees it, while a best-effort one (the planner's measured state) does.
IDLE_STATE_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT, history=HistoryPolicy.KEEP_LAST)
#: Real-time event times are kept on this grid (s), so step matrices can be cached.
TIME_QUANTUM = 1e-6
#: Step matrices kept for real-time event intervals (bounded: cleared when full; ~1 MB for two modes).
_CACHE_LIMIT = 2048
#: Silent this long (us) after a cut-off, the zero force is settled into the state
#: (a busy executor has been measured handing commands over > 1 s late).
SETTLE_US = 10_000_000


class PlantNode(ActuatorGlue, Node):
    """The simulated plant; ``Node`` keyword arguments pass through.

    Raises
    ------
    FlexmotionError
        Invalid start-up parameters (the node is destroyed).
    """

    def __init__(self, **node_kwargs: Any) -> None:
        super().__init__(NODE_NAME, **node_kwargs)
        try:
            self._setup()
        except BaseException:
            self.destroy_node()
            raise

    def _setup(self) -> None:
        specs = plant_specs()
        self._names = [s.name for s in specs]
        declare(self, specs)
        self._lock = threading.Lock()
        self._apply(plant_config_from_parameters(self._values()))
        cfg = self.cfg
        self.add_on_set_parameters_callback(validating_callback(self._values, plant_config_from_parameters))
        self.add_post_set_parameters_callback(lambda params: self._apply(plant_config_from_parameters(self._values())))

        # Real time keeps the state at the last *event* (a command's arrival):
        # x_event at t_event (integer microseconds on the system clock since
        # start-up, the clock DDS receive stamps use), command u held since.
        self.x_event = rest_state(cfg.model, cfg.initial_position)
        self.x = self.x_event.copy()  # the last published state
        self.u = self._zero
        self.received = 0  # commands handed over by the executor
        self.applied = 0  # commands integrated
        self.timeouts = 0
        self.published = 0  # joint_states messages published (a subscriber counts its losses against it)
        self.max_lag = 0.0  # s, arrival -> integration (real time)
        self._events: deque[tuple[int, float]] = deque()
        self._origin_ns = time.time_ns()
        self._t_event = 0
        self._last_command_at: int | None = None
        self._timeout_reported_for = -math.inf  # the cut-off (us) last counted as a timeout
        self.joint_names = list(rigid_body_names(cfg.model)) + list(mode_names(cfg.model))
        self._actuator_setup(self._values())  # command interface, servo, disturbance, input (plant_actuator)

        self._pub = self.create_publisher(JointState, "joint_states", PLANT_QOS)
        self._measure = MeasurementPublisher(self, cfg)  # 'measurements': the sensors (plant_measurements.py)
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        # commands one at a time, in order; the timers in their own groups (or trajectories: plant_actuator)
        if not self._actuator_interfaces(self._values()):
            self.create_subscription(
                Float64MultiArray,
                "commands",
                self._on_command,
                PLANT_QOS,
                callback_group=MutuallyExclusiveCallbackGroup(),
            )
        if not cfg.lockstep and not self._plays_trajectories:
            rate = float(self._values()["publish_rate_hz"]) or cfg.rate_hz
            self.create_timer(1.0 / rate, self._on_timer, callback_group=MutuallyExclusiveCallbackGroup())
        idle_period = float(self._values()["plant.idle_state_period_s"])
        if cfg.lockstep and idle_period > 0.0:
            # a best-effort heartbeat while idle, on the steady clock (a paused lockstep machine is still there)
            self._idle_pub = self.create_publisher(JointState, "joint_states", IDLE_STATE_QOS)
            self._idle_seen = -1
            self.create_timer(
                idle_period,
                self._on_idle_timer,
                callback_group=MutuallyExclusiveCallbackGroup(),
                clock=Clock(clock_type=ClockType.STEADY_TIME),
            )
        self.create_timer(0.5, self.publish_diagnostics, callback_group=MutuallyExclusiveCallbackGroup())
        gc.collect()  # as the planner: keep full collections off the real-time path
        gc.freeze()
        errors = []
        if cfg.model != cfg.nominal:
            errors.append(
                f"omega {list(cfg.model.omega)} rad/s, zeta {list(cfg.model.zeta)} (file: {list(cfg.nominal.omega)}, {list(cfg.nominal.zeta)})"
            )
        if cfg.coulomb_force > 0.0:
            errors.append(f"Coulomb friction {cfg.coulomb_force:g} N")
        self._model_error = "; ".join(errors) or "none"
        self.get_logger().info(
            f"ready: {'lockstep' if cfg.lockstep else 'real time'} at {cfg.rate_hz:g} Hz, {cfg.model.n_modes} mode(s), "
            f"at {positions_text(cfg.initial_position)}"
            + (f", {cfg.inputs} inputs" if cfg.inputs > 1 else "")
            + (f"; model error: {self._model_error}" if errors else "")
            + (f"; {self._actuator_summary}" if self._actuator is not None else "")
        )

    # ------------------------------------------------------------ parameters
    def _values(self) -> dict[str, Any]:
        return declared_values(self, self._names)

    def _apply(self, cfg: PlantConfig) -> None:
        """Use ``cfg`` from the next step on (model errors and friction may change live)."""
        A, B = cfg.model.A(), cfg.model.B()
        # several inputs: Gamma is n x m (the multi-input exact ZOH); one input: a vector
        steps = multi_step_matrices if cfg.inputs > 1 else step_matrices
        with self._lock:
            self.cfg = cfg
            self._A, self._B = A, B
            self._step_matrices = steps
            self._zero = np.zeros(cfg.inputs) if cfg.inputs > 1 else 0.0  # the hold: zero force on every input
            self._steps: dict[int, tuple[np.ndarray, np.ndarray]] = {}
            self._Phi, self._Gam = steps(A, B, cfg.dt)
            self._coulomb = simulate_coulomb if cfg.coulomb_force > 0.0 else None
            self._timeout_us = round(cfg.command_timeout / TIME_QUANTUM)
            self._stamp_key = "source_timestamp" if cfg.apply_at == "send" else "received_timestamp"
            if hasattr(self, "_measure"):
                self._measure.configure(cfg)

    # ----------------------------------------------------------- integration
    def _step(self, x: np.ndarray, h: float, u, h_key: int | None = None) -> np.ndarray:
        """Exact zero-order-hold step: ``h`` s (``h_key`` in TIME_QUANTUM units, for the cache) with ``u`` (N; m values)."""
        if h <= 0.0:
            return x
        if self._coulomb is not None:
            pc = PiecewiseConstant(np.array([0.0, h]), np.array([u]))
            return np.asarray(self._coulomb(self.cfg.model, x, pc, self.cfg.coulomb_force), float)[-1]
        if h_key is None:
            Phi, Gam = self._Phi, self._Gam
        else:
            m = self._steps.get(h_key)
            if m is None:
                if len(self._steps) > _CACHE_LIMIT:
                    self._steps.clear()
                m = self._steps[h_key] = self._step_matrices(self._A, self._B, h_key * TIME_QUANTUM)
            Phi, Gam = m
        return Phi @ x + np.dot(Gam, u)

    def _cutoff(self) -> float:
        """Time (us) from which the held command stops acting (its arrival + command_timeout)."""
        return -math.inf if self._last_command_at is None else self._last_command_at + self._timeout_us

    def _state_at(self, t: int) -> np.ndarray:
        """Real time: state at ``t`` (us) from the last event: ``u`` until the timeout, then 0.

        The timeout is applied here, never stored: a command that the executor
        hands over after the cut-off but that arrived before it still counts.
        """
        x, t0 = self.x_event, self._t_event
        cutoff = self._cutoff()
        if t <= cutoff:
            return self._step(x, (t - t0) * TIME_QUANTUM, self.u, t - t0)
        if cutoff > t0:
            x = self._step(x, (cutoff - t0) * TIME_QUANTUM, self.u, cutoff - t0)
            t0 = int(cutoff)
        return self._step(x, (t - t0) * TIME_QUANTUM, self._zero, t - t0)

    def _integrate_events(self, now: int) -> None:
        """Apply the queued commands in order, each from its arrival time."""
        while self._events:
            arrived, u = self._events.popleft()
            arrived = max(arrived, self._t_event)  # in order; never step back
            if arrived > self._cutoff() and _nonzero(self.u):
                self._note_timeout()  # once per cut-off: the timer may have reported it already
            self.x_event = self._state_at(arrived)
            self._t_event = arrived
            self.u = u
            self._last_command_at = arrived
            self.applied += 1
            self.max_lag = max(self.max_lag, (now - arrived) * TIME_QUANTUM)
        if _nonzero(self.u) and now > self._cutoff() + max(SETTLE_US, 100 * self._timeout_us):
            # long silent: no late command can still arrive before the cut-off; settle it
            self._note_timeout()
            self.x_event = self._state_at(now)
            self._t_event = now
            self.u = self._zero

    def _note_timeout(self) -> bool:
        """Count and log the cut-off of the held command once (when it happens, or when a late command shows it).

        Returns True if this call reported it.
        """
        cutoff = self._cutoff()
        if cutoff == self._timeout_reported_for:
            return False
        self._timeout_reported_for = cutoff
        self.timeouts += 1
        self.get_logger().warning(f"no command for {self.cfg.command_timeout:g} s: zero force from then on")
        return True

    def _now(self) -> int:
        """System clock since start-up, in TIME_QUANTUM units."""
        return (time.time_ns() - self._origin_ns) // 1000

    def _on_command(self, msg: Float64MultiArray, info: dict) -> None:  # two arguments: rclpy passes MessageInfo
        u = messages.command_value(msg) if self.cfg.inputs == 1 else messages.command_values(msg, self.cfg.inputs)
        if not np.all(np.isfinite(u)):
            self.get_logger().error(
                f"non-finite command {u} (or not {self.cfg.inputs} values: {len(msg.data)}): applying zero force"
            )
            u = self._zero
        with self._lock:
            self.received += 1
            if self._actuator is not None:  # a servo, a disturbance (plant_actuator)
                self._actuated_command(u, info)
                return
            if self.cfg.lockstep:
                # y_k read just after u_k is applied, stamped with the command's send time (sample k's time)
                sent = info.get("source_timestamp") if info else None
                stamp = stamp_from_ns(sent) if sent else self.get_clock().now().to_msg()
                self._measure.publish(self.x_event, u, stamp)
                self.x = self.x_event = self._step(self.x_event, self.cfg.dt, u)
                self.u = u
                self.applied += 1
                self._publish(u)
                return
            arrived = self._now()
            stamp = info.get(self._stamp_key) if info else None
            if stamp:
                arrived = min(arrived, (stamp - self._origin_ns) // 1000)
            self._events.append((arrived, u))

    def _on_timer(self) -> None:
        with self._lock:
            now = self._now()
            self._integrate_events(now)
            self.x = self._state_at(now)
            held = now <= self._cutoff()
            self._publish(self.u if held else self._zero)
            self._measure.publish(self.x, self.u if held else self._zero, self.get_clock().now().to_msg())
            # the force is cut now: say so now (issue 16: the counter and the warning came 10 s later)
            reported = not held and _nonzero(self.u) and self._note_timeout()
        if reported:
            self.publish_diagnostics()

    def _on_idle_timer(self) -> None:
        """Lockstep: no command for a whole period, publish the (unchanged) state as a best-effort heartbeat."""
        with self._lock:
            idle = self.received == self._idle_seen
            self._idle_seen = self.received
            if idle:
                msg = messages.joint_state(self.joint_names, self.x, self.u, self.get_clock().now().to_msg())
        if idle:
            self._idle_pub.publish(msg)

    def _publish(self, u: float) -> None:
        self.published += 1
        self._pub.publish(messages.joint_state(self.joint_names, self.x, u, self.get_clock().now().to_msg()))

    def state(self) -> np.ndarray:
        """Simulated state ``[p, v, q1, q1', ...]``: now (real time, commands handed over so far) or after the last command (lockstep)."""
        if self._actuator is not None:
            return self._actuated_state()
        with self._lock:
            if self.cfg.lockstep:
                return self.x_event.copy()
            now = self._now()
            self._integrate_events(now)
            return self._state_at(now)

    def last_event(self) -> tuple[float, np.ndarray]:
        """Real time: the last command applied so far, as (its application time in s since start-up, the state then)."""
        with self._lock:
            if not self.cfg.lockstep:
                self._integrate_events(self._now())
            return self._t_event * TIME_QUANTUM, self.x_event.copy()

    def publish_diagnostics(self) -> None:
        with self._lock:
            values = {
                "mode": "lockstep" if self.cfg.lockstep else "real time",
                "rate_hz": self.cfg.rate_hz,
                "commands_received": self.received,
                "commands_applied": self.applied,
                "max_lag_ms": self.max_lag * 1e3,
                "timeouts": self.timeouts,
                "model_error": self._model_error,
                "position": float(self.x[0]),
                # writer-side matches: a subscriber knows it will get every sample published from now on
                "joint_states_subscribers": self._pub.get_subscription_count(),
                "joint_states_published": self.published,
                "measurements_subscribers": self._measure.subscription_count(),
                "measurements_published": self._measure.published,
                "measurement_channels": ", ".join(self._measure.map.names),
                "diagnostics_subscribers": self._diag_pub.get_subscription_count(),
                **self._actuator_status(),
            }
        ok = DiagnosticStatus.OK
        level = ok[0] if isinstance(ok, (bytes, bytearray)) else int(ok)
        self._diag_pub.publish(
            messages.diagnostics(
                DIAGNOSTIC_NAME,
                self.get_fully_qualified_name(),
                level,
                values["mode"],
                values,
                self.get_clock().now().to_msg(),
            )
        )


def _nonzero(u) -> bool:
    """Some input's command is not zero (a float, or one value per input)."""
    return bool(np.any(np.asarray(u) != 0.0))


def main(args: list[str] | None = None) -> int:
    """``ros2 run flexmotion_ros plant [--ros-args --params-file FILE -p lockstep:=true]``."""
    # single-threaded: the lowest overhead per callback (1 kHz commands + timer)
    return run(PlantNode, SingleThreadedExecutor, NODE_NAME, args)


if __name__ == "__main__":
    sys.exit(main())
