"""The joint's reference, integrated exactly from a planned zero-order-hold sequence.

For a servo-driven joint (velocity or position interface) the model's input
``u_k`` is held on ``[t_k, t_{k+1})`` and the joint accelerates at
``a_k = b0 u_k`` (``c = 0``).  Its velocity is then piecewise linear and its
position piecewise quadratic, and at the sample instants, exactly::

    v_{k+1} = v_k + a_k dt
    p_{k+1} = p_k + v_k dt + a_k dt^2 / 2

(the rigid-body block of the model's matrix exponential, with no rounding
beyond the arithmetic).  For an effort joint (``c`` may be < 0) the same
samples come from the exact rigid-body propagation with ``e^{c dt}``, and are
the position and velocity the plan predicts.

What goes out for sample ``k`` (held by the receiver over ``[t_k, t_{k+1})``)
is the value *due at the end of that interval* for a reference, the value of
the interval for an input (:func:`setpoints`)::

    effort:   u_k           velocity: v_{k+1}           position: p_{k+1}

so that a servo that reaches its setpoint at the end of each period, with a
constant acceleration, reproduces the plan exactly (the ideal servo of
:mod:`.servo`), and a ``joint_trajectory_controller`` with
``interpolation_method: none`` (which outputs point ``i+1`` over
``[t_i, t_{i+1})``) plays it from points that carry the state at their own
time (:mod:`flexmotion_ros.execution.trajectory`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import GoalError
from ..model.modal_model import ModalModel
from .command import CommandInterface, check_acceleration_model, command_interface


@dataclass(frozen=True, kw_only=True)
class JointReference:
    """A planned joint motion sampled at the command rate.

    Attributes
    ----------
    dt : float
        Sample period (s).
    commands : ndarray, shape ``(K,)``
        The model's input ``u_k`` on ``[k dt, (k+1) dt)`` (N, or m/s^2 for an acceleration-input model).
    accelerations : ndarray, shape ``(K,)``
        Joint acceleration ``b0 u_k + c v_k`` at the start of each interval
        (m/s^2); constant over the interval when ``c = 0``.
    velocities : ndarray, shape ``(K + 1,)``
        Joint velocity at each sample instant, ``v_0`` .. ``v_K`` (m/s).
    positions : ndarray, shape ``(K + 1,)``
        Joint position at each sample instant, ``p_0`` .. ``p_K`` (m).
    """

    dt: float
    commands: np.ndarray
    accelerations: np.ndarray
    velocities: np.ndarray
    positions: np.ndarray

    @property
    def samples(self) -> int:
        """Number of commands ``K``."""
        return int(self.commands.size)

    def position_at(self, t: float) -> float:
        """Position (m) at time ``t`` (s from the first sample): the exact piecewise quadratic (``c = 0``).

        Before 0 the initial position, after ``K dt`` the final one.
        """
        k, s = self._interval(t)
        if k >= self.samples:
            return float(self.positions[-1] + self.velocities[-1] * s)
        return float(self.positions[k] + self.velocities[k] * s + 0.5 * self.accelerations[k] * s * s)

    def velocity_at(self, t: float) -> float:
        """Velocity (m/s) at time ``t`` (s): the exact piecewise linear velocity (``c = 0``)."""
        k, s = self._interval(t)
        if k >= self.samples:
            return float(self.velocities[-1])
        return float(self.velocities[k] + self.accelerations[k] * s)

    def _interval(self, t: float) -> tuple[int, float]:
        if t <= 0.0:
            return 0, 0.0
        k = min(int(math.floor(t / self.dt)), self.samples)
        return k, t - k * self.dt


def joint_reference(model: ModalModel, commands, dt: float, position: float, velocity: float = 0.0) -> JointReference:
    """The joint's positions, velocities and accelerations at every sample of a ZOH sequence.

    Parameters
    ----------
    model : ModalModel
        The planner's model; its rigid body is the joint (``p'' = c p' + b0 u``).
    commands : array_like
        ``u_k`` (the model's input unit), held for ``dt`` each.
    dt : float
        Sample period (s), ``> 0``.
    position, velocity : float
        The joint's position (m) and velocity (m/s) before the first command.

    Returns
    -------
    JointReference
        Exact samples (``c = 0``: the closed forms of the module docstring;
        ``c < 0``: the exact exponential ones).
    """
    u = np.asarray(commands, dtype=float).ravel()
    if not (math.isfinite(dt) and dt > 0.0):
        raise GoalError("dt", f"must be finite and > 0 s, got {dt}")
    if not (math.isfinite(position) and math.isfinite(velocity)) or not np.all(np.isfinite(u)):
        raise GoalError("commands", "the initial position, velocity and every command must be finite")
    K = u.size
    p = np.empty(K + 1)
    v = np.empty(K + 1)
    acc = np.empty(K)
    p[0], v[0] = float(position), float(velocity)
    b0, c = model.b0, model.c
    if c == 0.0:
        a = b0 * u
        for k in range(K):  # the recursion, not cumulative sums: each sample is the exact propagation of the last
            p[k + 1] = p[k] + v[k] * dt + 0.5 * a[k] * dt * dt
            v[k + 1] = v[k] + a[k] * dt
        acc[:] = a
    else:
        e = math.exp(c * dt)
        g1 = math.expm1(c * dt) / c  # int_0^dt e^{c s} ds
        g2 = (math.expm1(c * dt) - c * dt) / (c * c)  # int_0^dt (e^{c s} - 1) / c ds
        for k in range(K):
            acc[k] = b0 * u[k] + c * v[k]
            p[k + 1] = p[k] + v[k] * g1 + b0 * u[k] * g2
            v[k + 1] = e * v[k] + b0 * u[k] * g1
    return JointReference(dt=float(dt), commands=u, accelerations=acc, velocities=v, positions=p)


def setpoints(reference: JointReference, interface: CommandInterface | str) -> np.ndarray:
    """The value sent for each sample ``k`` (held over ``[t_k, t_{k+1})``), shape ``(K,)``.

    ``effort``: ``u_k`` (N); ``velocity``: ``v_{k+1}`` (m/s); ``position``:
    ``p_{k+1}`` (m) -- the reference due at the end of the interval.
    """
    iface = command_interface(interface)
    if iface is CommandInterface.EFFORT:
        return reference.commands.copy()
    if iface is CommandInterface.VELOCITY:
        return reference.velocities[1:].copy()
    return reference.positions[1:].copy()


def hold_setpoint(reference: JointReference, interface: CommandInterface | str, hold_effort: float = 0.0) -> float:
    """The hold after the last command: what keeps the joint at rest where the move ended.

    ``effort``: ``hold_effort`` (0 N: every target is an equilibrium);
    ``velocity``: 0 m/s; ``position``: the final position ``p_K`` (m) -- not 0.
    """
    iface = command_interface(interface)
    if iface is CommandInterface.EFFORT:
        return float(hold_effort)
    if iface is CommandInterface.VELOCITY:
        return 0.0
    return float(reference.positions[-1])


def reference_for(
    model: ModalModel, commands, dt: float, x0, interface: CommandInterface | str = CommandInterface.EFFORT
) -> JointReference:
    """:func:`joint_reference` from a full model state ``x0`` (``[p, v, q_1, q_1', ...]``), checking the model.

    Raises
    ------
    ModelError
        ``c != 0`` with a velocity or position interface.
    """
    iface = command_interface(interface)
    check_acceleration_model(model, iface)
    x0 = np.asarray(x0, dtype=float).ravel()
    return joint_reference(model, commands, dt, float(x0[0]), float(x0[1]))


__all__ = ["JointReference", "hold_setpoint", "joint_reference", "reference_for", "setpoints"]
