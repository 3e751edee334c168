"""Fixed arrival time, the Newton steps: switch times and bound ``u'`` at a fixed duration ``T``.

Closed-form final state and Jacobian (``Gamma(tau) = int_0^tau e^{As} B ds``):
:func:`polish` brings the move exactly to rest at ``T``;
:func:`polish_with_costate` adds Pontryagin's switching conditions for one
co-state when there are more switches than states; :func:`continue_in_time`
follows the solution from ``T*`` to ``T_req`` with the switch structure fixed
(tangent predictor, one Newton correction per step).  The planner is
:func:`~.fixed_time.plan_fixed_time`.
"""

from __future__ import annotations

import numpy as np

from ..results import BangBangProfile
from ..simulation.prepared import PreparedMove


def polish(move: PreparedMove, T: float, switch_times: np.ndarray, signs: np.ndarray, bound: float, max_iter: int = 30):
    """Newton on ``(t_1..t_L, u')`` with the duration fixed at ``T``: final state exactly at rest.

    ``x(T) = e^{AT} x0 + u' sum_k sign_k (Gamma(T - t_k) - Gamma(T - t_{k+1}))``
    with ``Gamma(tau) = int_0^tau e^{As} B ds``; ``dx/dt_j = u' (sign_{j-1} - sign_j) e^{A (T - t_j)} B``.
    """
    sys = move.response
    x0 = move.x0
    scale = np.abs(x0) + bound * np.max(np.abs(sys.input_integral(np.linspace(0.0, T, 65))), axis=0)
    scale = np.where(scale > 0.0, scale, 1.0)
    eAx = sys.expm_x(T, x0)
    L = switch_times.size

    def resid(z):
        t, ub = z[:L], z[L]
        G = sys.input_integral(T - np.concatenate([[0.0], t, [T]]))
        contrib = (signs[:, None] * (G[:-1] - G[1:])).sum(axis=0)
        return (eAx + ub * contrib) / scale, contrib

    def jacobian(z, contrib):
        J = np.empty((contrib.size, L + 1))
        if L:
            J[:, :L] = (z[L] * (signs[:-1] - signs[1:])[:, None] * sys.expm_B(T - z[:L])).T / scale[:, None]
        J[:, L] = contrib / scale
        return J

    z, r = _damped_newton(np.concatenate([switch_times, [bound]]), resid, jacobian, L, T, max_iter)
    return z[:L], float(z[L]), float(np.max(np.abs(r)))


def _damped_newton(z, resid, jacobian, L: int, T: float, max_iter: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Newton on ``z = (t_1..t_L, u', ...)`` with step halving; the last ``(z, residual)``.

    A step is taken only if it keeps ``0 < t_1 < ... < t_L < T`` and ``u' > 0`` and lowers the largest
    residual; it stops at rounding (``4 eps``), after ``max_iter`` steps or 20 halvings without progress.
    ``resid(z)`` returns ``(residual, contrib)``, ``jacobian(z, contrib)`` the Jacobian there.
    """
    r, contrib = resid(z)
    rn = float(np.max(np.abs(r)))
    for _ in range(max_iter):
        if rn <= 4.0 * np.finfo(float).eps:
            break
        step, *_ = np.linalg.lstsq(jacobian(z, contrib), -r, rcond=None)
        h = 1.0
        for _ in range(20):
            zc = z + h * step
            tc = zc[:L]
            if zc[L] > 0.0 and (L == 0 or (tc[0] > 0.0 and tc[-1] < T and np.all(np.diff(tc) > 0.0))):
                rc, cc = resid(zc)
                rcn = float(np.max(np.abs(rc)))
                if rcn < rn:
                    break
            h *= 0.5
        else:
            break
        z, r, contrib, rn = zc, rc, cc, rcn
    return z, r


#: Relative final-state residual at which a continuation step is accepted.  Newton on the
#: closed forms stalls at rounding, ``~ eps (1 + omega_max T)`` of the excursion (phases of
#: ``omega T``): 1e-13 refused a 100 s move with a 42 rad/s mode at 3e-13 and sent it to the
#: root-find (17 full solves).  The returned move is judged by the exact check (``FINAL_STATE_RTOL``)
#: and the certificate, not by this.
CONTINUATION_RTOL = 1e-10
#: Most continuation steps (each one Newton solve); past it the root-find takes over.
MAX_CONTINUATION_STEPS = 60


def polish_with_costate(
    move: PreparedMove, T: float, switch_times: np.ndarray, signs: np.ndarray, bound: float, nu: np.ndarray
):
    """Newton on ``(t_1..t_L, u', nu)``: at rest at ``T`` and ``S(T - t_j) = 0`` at every switch.

    With more switches than states (``L + 1 > n``) the arrival equations alone
    leave a family of exact moves; :func:`polish` lands on one near its start,
    not on the optimum, whose certificate then fails until the root-find has
    ``T*(u')`` to 1e-10 (fuzz case 227: 17 time-optimal solves).  Adding
    Pontryagin's switching conditions for one co-state (``nu`` normalised
    against the reference's direction) makes the system square.  Returns
    ``(switch_times, u', residual)``.
    """
    sys = move.response
    x0 = move.x0
    n = x0.size
    L = switch_times.size
    scale = np.abs(x0) + bound * np.max(np.abs(sys.input_integral(np.linspace(0.0, T, 65))), axis=0)
    scale = np.where(scale > 0.0, scale, 1.0)
    eAx = sys.expm_x(T, x0)
    ref = np.asarray(nu, float) * scale
    ref = ref / np.linalg.norm(ref)

    def resid(z):
        t, ub, nus = z[:L], z[L], z[L + 1 :]
        G = sys.input_integral(T - np.concatenate([[0.0], t, [T]]))
        contrib = (signs[:, None] * (G[:-1] - G[1:])).sum(axis=0)
        S = sys.switching(nus / scale, T - t)
        return np.concatenate([(eAx + ub * contrib) / scale, S, [nus @ ref - 1.0]]), contrib

    def jacobian(z, contrib):
        t, ub, nus = z[:L], z[L], z[L + 1 :]
        J = np.zeros((n + L + 1, L + 1 + n))
        E = sys.expm_B(T - t) / scale  # rows: e^{A tau_j} B in scaled units
        J[:n, :L] = (ub * (signs[:-1] - signs[1:])[:, None] * E).T
        J[:n, L] = contrib / scale
        _, dS = sys.switching(nus / scale, T - t, derivative=True)
        J[n : n + L, :L] = np.diag(-dS)
        J[n : n + L, L + 1 :] = E
        J[n + L, L + 1 :] = ref
        return J

    z, r = _damped_newton(np.concatenate([switch_times, [bound], ref]), resid, jacobian, L, T, 30)
    return z[:L], float(z[L]), float(np.max(np.abs(r[:n])))


def _continuation_tangent(move: PreparedMove, T: float, t_sw: np.ndarray, signs: np.ndarray, ub: float):
    """``d(t_1..t_L, u')/dT`` along the fixed-structure solution curve (least squares), or None."""
    sys = move.response
    L = t_sw.size
    # dx(T)/dT at fixed switches: A e^{AT} x0 + u' (sign_0 e^{AT} B + sum_j (sign_j - sign_{j-1}) e^{A (T - t_j)} B)
    jumps = np.concatenate([[signs[0]], signs[1:] - signs[:-1]])
    dF = sys.A_x(sys.expm_x(T, move.x0)) + ub * (jumps[:, None] * sys.expm_B(T - np.concatenate([[0.0], t_sw]))).sum(
        axis=0
    )
    G = sys.input_integral(T - np.concatenate([[0.0], t_sw, [T]]))
    J = np.empty((dF.size, L + 1))
    if L:
        J[:, :L] = (ub * (signs[:-1] - signs[1:])[:, None] * sys.expm_B(T - t_sw)).T
    J[:, L] = (signs[:, None] * (G[:-1] - G[1:])).sum(axis=0)
    scale = np.max(np.abs(J), axis=1)
    scale = np.where(scale > 0.0, scale, 1.0)
    d, *_ = np.linalg.lstsq(J / scale[:, None], -dF / scale, rcond=None)
    return d if np.all(np.isfinite(d)) else None


def continue_in_time(move: PreparedMove, best: BangBangProfile, T_req: float):
    """Follow ``(switch times, u')`` from ``T*`` to ``T_req`` with the switch structure fixed.

    A tangent predictor (the curve's derivative in ``T``) and one Newton
    correction per step; the step doubles on success and shrinks on failure.
    The work is bounded: at most :data:`MAX_CONTINUATION_STEPS` Newton solves
    on the switches (the number of switches, not ``T``, sets each one's cost).
    Returns ``(switch_times, u')`` or None if a step fails (the structure changes).
    """
    signs = np.sign(best.levels)
    T, t_sw, ub = best.duration, best.switch_times.copy(), move.u_max
    step = 0.25
    for _ in range(MAX_CONTINUATION_STEPS):
        if T >= T_req:
            return t_sw, ub
        T_new = min(T_req, T * (1.0 + step))
        d = _continuation_tangent(move, T, t_sw, signs, ub)
        if d is not None:
            t_g, ub_g = t_sw + (T_new - T) * d[:-1], ub + (T_new - T) * d[-1]
        if (
            d is None
            or ub_g <= 0.0
            or (t_g.size and (t_g[0] <= 0.0 or t_g[-1] >= T_new or np.any(np.diff(t_g) <= 0.0)))
        ):
            t_g, ub_g = t_sw * (T_new / T), ub * (T / T_new) ** 2  # the rigid body's scaling
        t_new, ub_new, res = polish(move, T_new, t_g, signs, ub_g)
        if res <= CONTINUATION_RTOL and ub_new > 0.0:
            T, t_sw, ub = T_new, t_new, ub_new
            step = min(2.0 * step, 1.0)
        else:
            step *= 0.25
            if step < 1e-4:
                return None
    return (t_sw, ub) if T >= T_req else None
