"""What the plant's parameters ask of its actuator: a force disturbance (``plant.disturbance.*``) and the servo (``plant.servo_bandwidth``).

:func:`disturbance_settings` and :func:`servo_settings` validate the values
(each bad one refused in one line naming its parameter) and give the
:class:`Disturbance` and :class:`~flexmotion_ros.core.interfaces.servo.Servo`
that :class:`~.actuator.Actuator` simulates.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from enum import Enum
from typing import Any

from ..core.errors import ConfigError
from ..core.interfaces.command import CommandInterface, command_interface
from ..core.interfaces.servo import Servo


class DisturbanceKind(Enum):
    """``plant.disturbance.type`` (values: the parameter's strings)."""

    NONE = "none"
    IMPULSE = "impulse"  # value: N s, at time_s
    STEP = "step"  # value: N, from time_s on


@dataclass(frozen=True, kw_only=True)
class Disturbance:
    """A force on the rigid body's input channel (the model's ``B``: it excites the modes as the actuator does).

    Attributes
    ----------
    kind : DisturbanceKind
    time_s : float
        When (s, from the first non-zero command: the first move's start).
    value : float
        Impulse (N s) or step (N).
    """

    kind: DisturbanceKind = DisturbanceKind.NONE
    time_s: float = 0.0
    value: float = 0.0

    @property
    def active(self) -> bool:
        """Something happens."""
        return self.kind is not DisturbanceKind.NONE and self.value != 0.0


def disturbance_settings(values: Mapping[str, Any], interface: CommandInterface | str) -> Disturbance:
    """Validate ``plant.disturbance.*``.

    Raises
    ------
    ConfigError
        A bad type, a negative or non-finite time, a non-finite value, or a
        disturbance on a velocity / position joint (its model's input is the
        servo's acceleration, it has no force input).
    """
    interface = command_interface(interface)
    names = [k.value for k in DisturbanceKind]
    kind = values.get("plant.disturbance.type", "none")
    if kind not in names:
        raise ConfigError("plant.disturbance.type", f"must be one of {names}, got {kind!r}")
    kind = DisturbanceKind(kind)
    t = float(values.get("plant.disturbance.time_s", 0.0))
    if not (math.isfinite(t) and t >= 0.0):
        raise ConfigError("plant.disturbance.time_s", f"must be finite and >= 0 s, got {t}")
    v = float(values.get("plant.disturbance.value", 0.0))
    if not math.isfinite(v):
        raise ConfigError("plant.disturbance.value", f"must be finite (N s or N), got {v}")
    if kind is not DisturbanceKind.NONE and interface is not CommandInterface.EFFORT:
        raise ConfigError(
            "plant.disturbance.type",
            f"a force disturbance needs command_interface effort, got {interface.value} "
            "(a servo-driven joint's model has the servo's acceleration as its input, no force)",
        )
    return Disturbance(kind=kind, time_s=t, value=v)


def servo_settings(values: Mapping[str, Any]) -> Servo:
    """``plant.servo_bandwidth`` (rad/s; 0: ideal tracking)."""
    w = float(values.get("plant.servo_bandwidth", 0.0))
    if not (math.isfinite(w) and w >= 0.0):
        raise ConfigError("plant.servo_bandwidth", f"must be finite and >= 0 rad/s (0: ideal), got {w}")
    return Servo(bandwidth=w if w > 0.0 else None)
