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
    check_acceleration_model(model, iface)
    s = np.asarray(values, dtype=float).ravel()
    x = np.array(x0, dtype=float).ravel()
    n = model.n_states
    K = s.size
    states = np.empty((K + 1, n))
    rp = np.empty(K + 1)
    rv = np.empty(K + 1)
    acc = np.empty(K)
    if iface is CommandInterface.EFFORT:
        Phi, Gam = step_matrices(model.A(), model.B(), dt)
        states[0] = x
        for k in range(K):
            x = Phi @ x + Gam * s[k]
            states[k + 1] = x
        acc[:] = s
        rp[:] = states[:, 0]
        rv[:] = states[:, 1]
        return ServoRun(states=states, reference_positions=rp, reference_velocities=rv, accelerations=acc)
    if iface is CommandInterface.POSITION and not servo.ideal:
        # the first-order position servo ties the joint's velocity to its position error (0 from rest)
        dv = -x[1]  # v(0) = w_s (r_p(0) - p(0)) = 0: the reference starts at the joint's position
        if dv != 0.0:
            x = x + (model.B() / model.b0) * dv  # an impulse of joint acceleration: v and every mode velocity jump
    Phi, Gam = servo_matrices(model, dt, servo)
    z = np.concatenate([x, [x[0], x[1]]])
    states[0], rp[0], rv[0] = x, z[n], z[n + 1]
    for k in range(K):
        if iface is CommandInterface.VELOCITY:
            a = (s[k] - z[n + 1]) / dt
        else:
            a = 2.0 * (s[k] - z[n] - z[n + 1] * dt) / (dt * dt)
        z = Phi @ z + Gam * a
        # the reference is the setpoint at the sample instant (drops the rounding of a_k)
        z[n + (1 if iface is CommandInterface.VELOCITY else 0)] = s[k]
        acc[k] = a
        states[k + 1], rp[k + 1], rv[k + 1] = z[:n], z[n], z[n + 1]
    return ServoRun(states=states, reference_positions=rp, reference_velocities=rv, accelerations=acc)


__all__ = ["Servo", "ServoRun", "servo_matrices", "simulate_servo"]
