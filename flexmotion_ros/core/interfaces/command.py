"""Which quantity the actuator is commanded in: ``command_interface: effort | velocity | position``.

* ``effort``: the model's input is the force (or torque) itself, as the
  planners have always assumed (``u_max`` in N).
* ``velocity`` / ``position``: the joint has its own servo (a drive's velocity
  or position loop) that tracks a reference.  The model's input is then the
  joint *acceleration* the servo imposes (``u_max`` in m/s^2 or rad/s^2; build
  such a model with e.g. ``crane(..., input="acceleration")``), and the planner
  sends the velocity or position reference integrated exactly from the planned
  acceleration (:mod:`.reference`).

A velocity limit of such a joint is a bound on the model's rigid-body
velocity: it is the limited planner's ``limits.velocity_max`` (same unit,
m/s or rad/s), see :func:`velocity_limit_option`.
"""

from __future__ import annotations

import difflib
import math
from enum import Enum

from ..errors import ConfigError, ModelError
from ..model.modal_model import ModalModel


class CommandInterface(Enum):
    """The command interface of the actuated joint (values: the parameter's strings)."""

    EFFORT = "effort"
    VELOCITY = "velocity"
    POSITION = "position"

    @property
    def acceleration_input(self) -> bool:
        """The model's input is the joint acceleration (a servo tracks a reference)."""
        return self is not CommandInterface.EFFORT


def command_interface(value: object, parameter: str = "command_interface") -> CommandInterface:
    """Parse ``effort`` / ``velocity`` / ``position`` (or a :class:`CommandInterface`).

    Raises
    ------
    ConfigError
        Any other value: one line with the allowed names and the closest one to a typo.
    """
    if isinstance(value, CommandInterface):
        return value
    names = [c.value for c in CommandInterface]
    text = str(value).strip().lower() if isinstance(value, str) else None
    if text in names:
        return CommandInterface(text)
    close = difflib.get_close_matches(str(value), names, n=1, cutoff=0.5)
    hint = f" (did you mean {close[0]}?)" if close else ""
    raise ConfigError(parameter, f"must be one of {names}, got {value!r}{hint}")


def check_acceleration_model(model: ModalModel, interface: CommandInterface) -> None:
    """Refuse a model that cannot describe a servo-driven joint (velocity / position interfaces).

    The servo imposes the joint's acceleration: the rigid body is a double
    integrator of the input (``c = 0``; ``b0`` converts the input unit into
    the joint's acceleration and is normally 1).

    Raises
    ------
    ModelError
        ``model.c`` is not 0 for a velocity or position interface.
    """
    if interface.acceleration_input and model.c != 0.0:
        raise ModelError(
            "model.c",
            f"must be 0.0 for command_interface {interface.value} (the servo imposes the joint's "
            f"acceleration; a viscous term belongs to the force model), got {model.c}",
        )


def velocity_limit_option(velocity_limit: float, interface: CommandInterface) -> dict[str, float]:
    """The limited planner's option that enforces a joint's velocity limit (m/s or rad/s).

    A velocity- or position-commanded joint's velocity is the model's
    rigid-body velocity ``v`` (``b0 = 1``), so its limit is exactly
    ``limits.velocity_max`` of the ``limited`` method, which bounds ``|v|`` at
    every instant (it is monotone within a sample, so the samples hold the
    maximum).  For an effort joint the same option applies to the rigid-body
    velocity.  The node wiring passes this dict into the configuration's
    ``options`` (with ``method: limited``).

    Raises
    ------
    ConfigError
        The limit is not finite and > 0.
    """
    try:
        v = float(velocity_limit)
    except (TypeError, ValueError):
        v = math.nan
    if not (math.isfinite(v) and v > 0.0):
        raise ConfigError("velocity_limit", f"must be finite and > 0 (m/s or rad/s), got {velocity_limit!r}")
    command_interface(interface)
    return {"limits.velocity_max": v}


__all__ = ["CommandInterface", "check_acceleration_model", "command_interface", "velocity_limit_option"]
