"""The planner's output settings: ``output``, ``command_interface`` and ``trajectory.*``, validated against the model.

:func:`output_settings` checks the values (each bad one refused in one line
naming its parameter: a velocity or position joint needs ``c = 0``, effort
trajectories no splines, a receiver rate of 0 or at least 1 Hz, a start delay
up to :data:`MAX_START_DELAY_S`) and gives the frozen :class:`OutputSettings`
that :class:`~.output.OutputStream` follows.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from enum import Enum
from typing import Any

from ..core.errors import ConfigError
from ..core.interfaces.command import CommandInterface, check_acceleration_model, command_interface
from ..core.model.modal_model import ModalModel
from .trajectory import Interpolation, ReceiverSettings


class OutputMode(Enum):
    """``output`` (values: the parameter's strings)."""

    STREAM = "stream"
    TRAJECTORY = "trajectory"


#: Longest start delay of a trajectory move (s).
MAX_START_DELAY_S = 10.0


@dataclass(frozen=True, kw_only=True)
class OutputSettings:
    """The planner's output.

    Attributes
    ----------
    mode : OutputMode
    interface : CommandInterface
    topic : str
        Trajectory topic (``trajectory.topic``).
    receiver : ReceiverSettings
        How the receiver samples a trajectory (interpolation, look-ahead).
    start_delay_s : float
        Trajectory mode: a move from idle starts this far (s) after the next
        sample, and no splice is made closer than this to the stream: the
        time a trajectory has to reach the receiver.
    """

    mode: OutputMode = OutputMode.STREAM
    interface: CommandInterface = CommandInterface.EFFORT
    topic: str = "joint_trajectory"
    receiver: ReceiverSettings = ReceiverSettings()
    start_delay_s: float = 0.1

    def delay_samples(self, rate_hz: float) -> int:
        """``start_delay_s`` in whole samples, at least 2 in trajectory mode (0 in stream mode)."""
        if self.mode is OutputMode.STREAM:
            return 0
        return max(2, math.ceil(self.start_delay_s * rate_hz - 1e-9))


def _choice(enum_type, name: str, value: Any):
    names = [e.value for e in enum_type]
    if value not in names:
        raise ConfigError(name, f"must be one of {names}, got {value!r}")
    return enum_type(value)


def output_settings(values: Mapping[str, Any], model: ModalModel) -> OutputSettings:
    """Validate the output parameters against the planner's model.

    Raises
    ------
    ConfigError
        A bad value (named), effort with splines, a velocity / position joint
        whose model has ``c != 0`` (``model.c``).
    """
    mode = _choice(OutputMode, "output", values.get("output", "stream"))
    iface = command_interface(values.get("command_interface", "effort"))
    try:
        check_acceleration_model(model, iface)
    except Exception as exc:  # ModelError: the same one line, as a configuration error of the pair
        raise ConfigError("model.c", getattr(exc, "reason", str(exc))) from None
    topic = str(values.get("trajectory.topic", "joint_trajectory")).strip()
    if not topic:
        raise ConfigError("trajectory.topic", "must be a topic name, got an empty string")
    interp = _choice(Interpolation, "trajectory.interpolation", values.get("trajectory.interpolation", "none"))
    if mode is OutputMode.TRAJECTORY and iface is CommandInterface.EFFORT and interp is Interpolation.SPLINES:
        raise ConfigError(
            "trajectory.interpolation",
            "must be none for command_interface effort: splines interpolate effort linearly, not a zero-order hold",
        )
    rate = float(values.get("trajectory.receiver_update_rate", 0.0))
    if not (math.isfinite(rate) and (rate == 0.0 or rate >= 1.0)):
        raise ConfigError("trajectory.receiver_update_rate", f"must be 0 (no look-ahead) or >= 1 Hz, got {rate}")
    receiver = ReceiverSettings.jazzy(rate, interp) if rate > 0.0 else ReceiverSettings(interpolation=interp)
    delay = float(values.get("trajectory.start_delay_s", 0.1))
    if not (math.isfinite(delay) and 0.0 <= delay <= MAX_START_DELAY_S):
        raise ConfigError("trajectory.start_delay_s", f"must be in [0, {MAX_START_DELAY_S:g}] s, got {delay}")
    return OutputSettings(mode=mode, interface=iface, topic=topic, receiver=receiver, start_delay_s=delay)
