"""The joint's servo, simulated exactly: ideal tracking, or a first-order servo of given bandwidth.

A velocity- or position-commanded joint receives one setpoint per sample,
the reference due at the end of the interval (:func:`.reference.setpoints`).
The servo rebuilds the continuous reference from them -- constant
acceleration over each interval, the only interpolation that is causal and
exact for a zero-order-hold plan::

    velocity: a_k = (s_k - r_v) / dt                    r_v <- s_k
    position: a_k = 2 (s_k - r_p - r_v dt) / dt^2       r_p <- s_k,  r_v <- r_v + a_k dt

where ``(r_p, r_v)`` is the reference's state (m, m/s), starting at the
joint's state.  Then the joint follows it:

* **ideal**: the joint's acceleration is ``a_k`` (it is the reference);
* **first order**, bandwidth ``w_s`` (rad/s): ``a(t) = w_s (r_v(t) - v(t))``,
  the velocity loop ``V / V_ref = w_s / (s + w_s)``.  For a position servo
  ``P / P_ref = w_s / (s + w_s)``, i.e. ``v = w_s (r_p - p)``; differentiated
  that is the same equation, so both interfaces share it, the position servo
  starting from the tied velocity ``v(0) = w_s (r_p(0) - p(0))`` (0 from
  rest; a different measured velocity is replaced by it, an impulse on the
  modes, applied exactly).

Exact discretisation (no integrator): the augmented state
``z = [x, r_p, r_v]`` with the piecewise-constant input ``a_k``::

    x'   = A x + (B / b0) w_s (r_v - v)        (ideal: x' = A x + (B / b0) a_k)
    r_p' = r_v
    r_v' = a_k

is linear time-invariant, so ``z_{k+1} = Phi z_k + Gamma a_k`` with
``expm([[F, G], [0, 0]] dt) = [[Phi, Gamma], [0, 1]]``, exactly as for the
plant alone (:func:`~flexmotion_ros.core.simulation.exact.step_matrices`).
An effort joint has no servo: the setpoint is the model's input.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..model.modal_model import ModalModel
from ..simulation.exact import step_matrices
from .command import CommandInterface, check_acceleration_model, command_interface


@dataclass(frozen=True, kw_only=True)
class Servo:
    """How the joint tracks its reference.

    Attributes
    ----------
    bandwidth : float or None
        First-order bandwidth ``w_s`` (rad/s, > 0); None: ideal tracking.
    """

    bandwidth: float | None = None

    def __post_init__(self) -> None:
        if self.bandwidth is not None:
            w = self.bandwidth
            try:
                w = float(w)
            except (TypeError, ValueError):
                w = math.nan
            if not (math.isfinite(w) and w > 0.0):
                raise ConfigError(
                    "plant.servo_bandwidth", f"must be finite and > 0 rad/s (or none: ideal), got {self.bandwidth!r}"
                )
            object.__setattr__(self, "bandwidth", w)

    @property
    def ideal(self) -> bool:
        """Ideal tracking (no bandwidth)."""
        return self.bandwidth is None


@dataclass(frozen=True, kw_only=True)
class ServoRun:
    """An exact simulation of the plant driven through its servo.

    Attributes
    ----------
    states : ndarray, shape ``(K + 1, n)``
        Model states at every sample instant (before each setpoint and after the last).
    reference_positions, reference_velocities : ndarray, shape ``(K + 1,)``
        The reference ``r_p`` (m) and ``r_v`` (m/s) the servo rebuilt, at the same instants.
    accelerations : ndarray, shape ``(K,)``
        The reference acceleration ``a_k`` of each interval (m/s^2); the model's
        input for an effort joint (N).
    """

    states: np.ndarray
    reference_positions: np.ndarray
    reference_velocities: np.ndarray
    accelerations: np.ndarray


def servo_matrices(model: ModalModel, dt: float, servo: Servo) -> tuple[np.ndarray, np.ndarray]:
    """``Phi``, ``Gamma`` of the augmented state ``[x, r_p, r_v]`` over one sample ``dt`` (s).

    See the module docstring for the continuous system; the input is the
    reference acceleration ``a_k`` (m/s^2).
    """
    n = model.n_states
    A = model.A()
    Bj = model.B() / model.b0  # the model's response to one unit of joint acceleration
    F = np.zeros((n + 2, n + 2))
    G = np.zeros(n + 2)
    F[:n, :n] = A
    if servo.ideal:
        G[:n] = Bj
    else:
        w = float(servo.bandwidth)  # type: ignore[arg-type]
        F[:n, :n] -= w * np.outer(Bj, np.eye(n)[1])
        F[:n, n + 1] = w * Bj
    F[n, n + 1] = 1.0
    G[n + 1] = 1.0
    return step_matrices(F, G, dt)


@dataclass(frozen=True, kw_only=True)
class ServoState:
    """The plant and its servo's reference at one instant (for a plant that steps by its own clock).

    Attributes
    ----------
    x : ndarray
        Plant state ``[p, v, q_1, q_1', ...]``.
    reference_position, reference_velocity : float
        The servo's rebuilt reference ``r_p`` (m), ``r_v`` (m/s).
    acceleration : float
        The input held now: the reference acceleration of the current interval
        (m/s^2), or the force for an effort joint (N).
    setpoint : float or None
        The setpoint being tracked (None before the first).
    """

    x: np.ndarray
    reference_position: float
    reference_velocity: float
    acceleration: float = 0.0
    setpoint: float | None = None


def servo_start(model: ModalModel, x0, interface: CommandInterface | str, servo: Servo | None = None) -> ServoState:
    """The servo taking over the plant at state ``x0``: its reference starts at the joint's state.

    A first-order position servo ties the joint's velocity to its position
    error (``v = w_s (r_p - p) = 0``): a moving joint's velocity jumps to 0, an
    impulse on the modes, applied exactly.
    """
    iface = command_interface(interface)
    servo = servo or Servo()
    check_acceleration_model(model, iface)
    x = np.array(x0, dtype=float).ravel()
    rp, rv = float(x[0]), float(x[1])
    if iface is CommandInterface.POSITION and not servo.ideal and x[1] != 0.0:
        x = x + (model.B() / model.b0) * (-x[1])  # every velocity jumps with the joint's
    return ServoState(x=x, reference_position=rp, reference_velocity=rv)


def servo_setpoint(state: ServoState, value: float, interval_s: float, interface: CommandInterface | str) -> ServoState:
    """A new setpoint, due ``interval_s`` (s) from now: the input held until then (module docstring).

    ``effort``: the force itself; ``velocity``: ``(s - r_v) / h``; ``position``:
    ``2 (s - r_p - r_v h) / h^2``.
    """
    iface = command_interface(interface)
    h = float(interval_s)
    if iface is CommandInterface.EFFORT:
        a = float(value)
    elif iface is CommandInterface.VELOCITY:
        a = (value - state.reference_velocity) / h
    else:
        a = 2.0 * (value - state.reference_position - state.reference_velocity * h) / (h * h)
    return ServoState(
        x=state.x,
        reference_position=state.reference_position,
        reference_velocity=state.reference_velocity,
        acceleration=a,
        setpoint=float(value),
    )


def servo_advance(
    model: ModalModel,
    state: ServoState,
    h: float,
    interface: CommandInterface | str,
    servo: Servo | None = None,
    arrive: bool = False,
) -> ServoState:
    """The plant and reference ``h`` seconds later, exactly, with the input of ``state`` held.

    ``arrive``: ``h`` ends where the setpoint is due; the reference is then
    set to it exactly (drops the rounding of the rebuilt acceleration).
    """
    iface = command_interface(interface)
    servo = servo or Servo()
    if h <= 0.0:
        return state
    n = model.n_states
    if iface is CommandInterface.EFFORT:
        Phi, Gam = step_matrices(model.A(), model.B(), h)
        x = Phi @ state.x + Gam * state.acceleration
        return ServoState(
            x=x,
            reference_position=float(x[0]),
            reference_velocity=float(x[1]),
            acceleration=state.acceleration,
            setpoint=state.setpoint,
        )
    Phi, Gam = servo_matrices(model, h, servo)
    z = Phi @ np.concatenate([state.x, [state.reference_position, state.reference_velocity]]) + Gam * state.acceleration
    rp, rv = float(z[n]), float(z[n + 1])
    if arrive and state.setpoint is not None:
        if iface is CommandInterface.VELOCITY:
            rv = state.setpoint
        else:
            rp = state.setpoint
    return ServoState(
        x=z[:n], reference_position=rp, reference_velocity=rv, acceleration=state.acceleration, setpoint=state.setpoint
    )


def simulate_servo(
    model: ModalModel,
    x0,
    values,
    dt: float,
    interface: CommandInterface | str,
    servo: Servo | None = None,
) -> ServoRun:
    """The plant under a sequence of setpoints, through its servo, exactly.

    Parameters
    ----------
    model : ModalModel
        The plant (for velocity / position: an acceleration-input model, ``c = 0``).
    x0 : array_like
        Plant state before the first setpoint ``[p, v, q_1, q_1', ...]``.
    values : array_like
        One setpoint per sample (held over ``[t_k, t_{k+1})``): force (N) for
        ``effort``, the velocity (m/s) or position (m) due at ``t_{k+1}`` otherwise.
        Append hold setpoints to see the plant settle after a move.
    dt : float
        Sample period (s).
    interface : CommandInterface or str
    servo : Servo, optional
        Default: ideal.  Ignored for ``effort``.

    Returns
    -------
    ServoRun
    """
    iface = command_interface(interface)
    servo = servo or Servo()
    s = np.asarray(values, dtype=float).ravel()
    state = servo_start(model, x0, iface, servo)
    K = s.size
    states = np.empty((K + 1, model.n_states))
    rp = np.empty(K + 1)
    rv = np.empty(K + 1)
    acc = np.empty(K)
    states[0], rp[0], rv[0] = state.x, state.reference_position, state.reference_velocity
    for k in range(K):
        state = servo_setpoint(state, s[k], dt, iface)
        acc[k] = state.acceleration
        state = servo_advance(model, state, dt, iface, servo, arrive=True)
        states[k + 1], rp[k + 1], rv[k + 1] = state.x, state.reference_position, state.reference_velocity
    return ServoRun(states=states, reference_positions=rp, reference_velocities=rv, accelerations=acc)


__all__ = [
    "Servo",
    "ServoRun",
    "ServoState",
    "servo_advance",
    "servo_matrices",
    "servo_setpoint",
    "servo_start",
    "simulate_servo",
]
