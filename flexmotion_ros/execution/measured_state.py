"""The machine's measured state, ROS-free: settings, staleness, the state vector from joint names.

The planner plans a move from where the machine *is*, not from where it
believes it is (a restarted planner knows nothing of the last move).  The
machine publishes ``joint_states`` (the plant: ``rigid_body``, ``mode_1`` ...
``mode_N``; position and velocity of each); :class:`MeasuredState` keeps the
latest message with its receive time and hands out the state vector
``[p, v, q1, q1', ...]`` only while it is fresh:

* ``state.source: measured`` (default) -- a goal from idle is planned from the
  last measured state if it was received within ``state.timeout_s``; a
  missing or stale state refuses the goal with the reason;
* ``state.source: assumed`` -- the old open-loop behaviour: the planner
  assumes the machine at rest at ``initial_position`` at start-up, then at
  the end of its own last plan.

Freshness is judged on the receive time (a monotonic clock): it says whether
the machine's driver is alive, whatever the clock the messages are stamped with.
"""

from __future__ import annotations

import enum
import math
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.errors import ConfigError, GoalError
from ..core.model.modal_model import ModalModel
from ..core.parameter_checks import check_choice, closest_hint
from ..core.simulation.exact import modal_amplitudes


class StateSource(enum.Enum):
    """Where the start state of a move from idle comes from (parameter ``state.source``)."""

    MEASURED = "measured"
    ASSUMED = "assumed"


class EarlyArrival(enum.Enum):
    """What a trajectory whose ``time_from_start`` is before the fastest arrival gets (``trajectory.early_arrival``)."""

    REFUSE = "refuse"
    OPTIMUM = "optimum"


#: Default joint name of the rigid body (the plant's first joint).
RIGID_BODY = "rigid_body"
#: A measured state is at rest when its rigid-body speed (m/s or rad/s) and every
#: modal amplitude (the modal coordinate's unit) are at most this.
AT_REST_TOL = 1e-9
#: A measured state "is" the predicted end of the planner's own move when every component is within this.
EXPECT_TOL = 1e-6


def mode_names(n_modes: int) -> list[str]:
    """The plant's modal joint names ``mode_1`` ... ``mode_N``."""
    return [f"mode_{i + 1}" for i in range(n_modes)]


@dataclass(frozen=True, kw_only=True)
class StateSettings:
    """The measured-state parameters of the planner, validated.

    Attributes
    ----------
    source : StateSource
    topic : str
        The ``sensor_msgs/JointState`` topic (``state.topic``).
    timeout_s : float
        A measured state older than this (s) is stale (``state.timeout_s``).
    joint_name : str
        The rigid-body joint (``joint_name``): trajectories name it, the state's first joint.
    mode_joint_names : tuple of str
        The joints holding the modal coordinates in ``joint_states`` (``state.mode_joint_names``;
        empty: ``mode_1`` ... ``mode_N``).
    early_arrival : EarlyArrival
        A trajectory asking to arrive before the time-optimal move can (``trajectory.early_arrival``).
    """

    source: StateSource = StateSource.MEASURED
    topic: str = "joint_states"
    timeout_s: float = 0.5
    joint_name: str = RIGID_BODY
    mode_joint_names: tuple[str, ...] = ()
    early_arrival: EarlyArrival = EarlyArrival.REFUSE

    def state_joint_names(self, n_modes: int) -> list[str]:
        """The joints of the state vector, in order: the rigid body, then one per mode."""
        modes = list(self.mode_joint_names) or mode_names(n_modes)
        if len(modes) != n_modes:
            raise GoalError(
                "state.mode_joint_names",
                f"names {len(modes)} joint(s) but the model has {n_modes} mode(s); give one per mode or none",
            )
        return [self.joint_name, *modes]


def _enum(enum_type: type[enum.Enum], name: str, value: Any) -> Any:
    return enum_type(check_choice(name, value, [e.value for e in enum_type]))


def state_settings(values: Mapping[str, Any]) -> StateSettings:
    """Validate the planner's measured-state and trajectory parameters; raise :class:`ConfigError` naming the bad one."""
    timeout = values.get("state.timeout_s", 0.5)
    try:
        timeout = float(timeout)
    except (TypeError, ValueError):
        raise ConfigError("state.timeout_s", f"must be a number of seconds in (0, 3600], got {timeout!r}") from None
    if not (math.isfinite(timeout) and 0.0 < timeout <= 3600.0):
        raise ConfigError("state.timeout_s", f"must be in (0, 3600] s, got {timeout}")
    topic = str(values.get("state.topic", "joint_states")).strip()
    if not topic:
        raise ConfigError("state.topic", "must be a topic name, got an empty string")
    joint = str(values.get("joint_name", RIGID_BODY)).strip()
    if not joint:
        raise ConfigError("joint_name", "must be a joint name, got an empty string")
    modes = tuple(str(m) for m in (values.get("state.mode_joint_names") or ()))
    names = [joint, *modes]
    if len(set(names)) != len(names):
        raise ConfigError(
            "state.mode_joint_names", f"joint names must differ from each other and from joint_name, got {names}"
        )
    return StateSettings(
        source=_enum(StateSource, "state.source", values.get("state.source", StateSource.MEASURED.value)),
        topic=topic,
        timeout_s=timeout,
        joint_name=joint,
        mode_joint_names=modes,
        early_arrival=_enum(EarlyArrival, "trajectory.early_arrival", values.get("trajectory.early_arrival", "refuse")),
    )


def state_vector(
    required: Sequence[str], names: Sequence[str], positions: Sequence[float], velocities: Sequence[float]
) -> np.ndarray:
    """``[p, v, q1, q1', ...]`` of the ``required`` joints, from a JointState's fields.

    Raises
    ------
    GoalError
        A required joint is missing (with the closest name present), a field is
        too short, or a value is not finite.
    """
    index = {str(n): i for i, n in enumerate(names)}
    x = np.empty(2 * len(required))
    for j, name in enumerate(required):
        i = index.get(name)
        if i is None:
            raise GoalError(
                "joint_states",
                f"joint {name!r} missing from the measured joint_states (has {list(index)}){closest_hint(name, index)}",
            )
        if i >= len(positions) or i >= len(velocities):
            raise GoalError("joint_states", f"joint {name!r} has no position and velocity in the measured message")
        x[2 * j], x[2 * j + 1] = float(positions[i]), float(velocities[i])
    if not np.all(np.isfinite(x)):
        raise GoalError("joint_states", f"the measured state is not finite: {x.tolist()}")
    return x


def at_rest(model: ModalModel, x: np.ndarray, tol: float = AT_REST_TOL) -> bool:
    """The state ``[p, v, q1, q1', ...]`` is still: ``|v| <= tol`` and every modal amplitude ``<= tol``."""
    x = np.asarray(x, float)
    return bool(abs(x[1]) <= tol and np.all(modal_amplitudes(model, x) <= tol))


@dataclass(frozen=True, kw_only=True)
class Measurement:
    """One received ``joint_states`` message.

    Attributes
    ----------
    names : tuple of str
    positions, velocities : tuple of float
        Positions (m or rad, modal coordinates) and velocities (per s).
    received_at : float
        Receive time (s, the store's monotonic clock).
    """

    names: tuple[str, ...]
    positions: tuple[float, ...]
    velocities: tuple[float, ...]
    received_at: float


class MeasuredState:
    """The latest measured state, thread-safe: written by a subscription, read when a goal is planned.

    Parameters
    ----------
    clock : callable
        Monotonic clock (s) for receive times and staleness.
    """

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._cond = threading.Condition()
        self._last: Measurement | None = None
        self.received = 0

    def update(self, names: Sequence[str], positions: Sequence[float], velocities: Sequence[float]) -> None:
        """Store one message (called from the subscription's thread)."""
        m = Measurement(
            names=tuple(names), positions=tuple(positions), velocities=tuple(velocities), received_at=self._clock()
        )
        with self._cond:
            self._last = m
            self.received += 1
            self._cond.notify_all()

    @property
    def last(self) -> Measurement | None:
        """The latest message, or None."""
        with self._cond:
            return self._last

    def age(self) -> float:
        """Seconds since the latest message (inf if none)."""
        with self._cond:
            return math.inf if self._last is None else self._clock() - self._last.received_at

    def fresh(
        self,
        required: Sequence[str],
        timeout_s: float,
        topic: str,
        wait: bool = True,
        expect: np.ndarray | None = None,
        tol: float = EXPECT_TOL,
    ) -> np.ndarray:
        """The state vector of ``required`` joints, received within ``timeout_s``.

        With ``wait``, a missing or stale state waits up to ``timeout_s`` for
        the next message (a goal just after start-up, a machine publishing
        slowly) before refusing.  With ``expect`` (the state the planner's own
        last move ends in), it also waits up to ``timeout_s`` for a state
        within ``tol`` of it: just after a move the latest message may still be
        in flight from before the end; if none matches by then, the machine is
        elsewhere (model error, friction, moved by someone else) and the
        latest fresh state is the answer.

        Raises
        ------
        GoalError
            No message (``state.source``: missing), the latest too old (stale),
            or a required joint missing from it.
        """
        end = self._clock() + (timeout_s if wait else 0.0)
        with self._cond:
            while True:
                m = self._last
                now = self._clock()
                x = None
                if m is not None and now - m.received_at <= timeout_s:
                    x = state_vector(required, m.names, m.positions, m.velocities)
                    if expect is None or float(np.max(np.abs(x - expect))) <= tol:
                        return x
                if now >= end:
                    if x is not None:
                        return x
                    if m is None:
                        raise GoalError(
                            "state.source",
                            f"no measured state: nothing received on {topic!r} (waited {timeout_s:g} s); "
                            "refusing rather than guessing where the machine is ('state.source: assumed' plans "
                            "from initial_position instead)",
                        )
                    raise GoalError(
                        "state.timeout_s",
                        f"measured state on {topic!r} is stale: last received {now - m.received_at:.3g} s ago, "
                        f"allowed {timeout_s:g} s; refusing rather than guessing where the machine is",
                    )
                self._cond.wait(end - now)


__all__ = [
    "AT_REST_TOL",
    "EXPECT_TOL",
    "RIGID_BODY",
    "EarlyArrival",
    "MeasuredState",
    "Measurement",
    "StateSettings",
    "StateSource",
    "at_rest",
    "mode_names",
    "state_settings",
    "state_vector",
]
