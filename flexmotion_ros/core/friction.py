"""Coulomb friction (seed eqs. 2.8-2.11): exact simulation and time-optimal moves.

Model
-----
One friction contact with sliding velocity ``y = C x`` and Coulomb force ``F``::

    x' = A x + B u - F g sgn(C x)              (sliding, y != 0)
    x' = A x + B u + g lam,  C x' = 0          (stuck: y = 0 and |lam| <= F)

``g`` is the state derivative per newton of friction force (``C g > 0``: the
force opposes the sliding velocity).  While stuck the contact force ``lam``
holds ``y`` at zero: ``lam = -a``, ``a(x, u) = C (A x + B u) / (C g)`` (the
net applied force at the contact, N), so the stuck dynamics are linear too,
``x' = P (A x + B u)`` with ``P = I - g C / (C g)``: the constraint force
enters every state that ``g`` touches.  The contact breaks loose when
``|a|`` exceeds ``F``.

Assumption for a :class:`ModalModel` (:func:`rigid_contact`): friction acts
on the rigid-body coordinate only, ``g = |b0| e_v``, ``y = v`` (friction on
the guide of the whole machine, proportional to mass: the generalised
friction force on every vibration mode is zero).  Then ``a = sgn(b0) u``:
the rigid body sticks while ``|u| <= F`` and the modes keep moving under
``u`` unchanged.  Friction at a physical point of the structure (the cart of
a crane, one mass of a chain) is :func:`contact_at_coordinate`; there the
stuck point changes the modal dynamics through ``P``.

Exactness
---------
Between events the dynamics are affine with constant input, propagated with
:func:`~flexmotion_ros.core.simulation.step_matrices` (matrix exponentials).
Events (the sliding velocity reaching zero, a stuck contact breaking loose)
are located on the exact solution: in closed form when ``C A = alpha C``
(the rigid-body contact: ``y`` obeys a scalar linear ODE), otherwise
bracketed on a grid of 1/16 of the fastest period with a cubic Hermite dip
test and refined by Brent's method on the matrix-exponential solution.  The
simulator never steps over an event.

Time-optimal moves
------------------
With ``|u| = u_max > F`` the contact never sticks during a bang-bang move,
the velocity only crosses zero transversally, and the system is piecewise
linear.  The hybrid maximum principle gives ``u = -u_max sgn(B^T lambda)``,
``lambda' = -A^T lambda`` between events and a jump of ``lambda`` along
``C^T`` at each velocity reversal (``lambda^- = S^T lambda^+``, ``S`` the
saltation matrix), which keeps the Hamiltonian continuous.  The switch times,
the duration and ``lambda(T)`` are found by Newton's method on these
conditions (final state, ``B^T lambda(t_j) = 0``, ``H = 0``), by continuation
in ``F`` from the certified frictionless optimum.  The result is checked by
the exact friction simulation (rest at the target) and certified as a
Pontryagin extremal (sign structure proved per costate piece).  The friction
system is not linear, so the extremal is *not* proved globally optimal; the
rigid-body friction optimum is reported as a proved lower bound (c = 0, from
rest).  The zero-order-hold version is a linear program for a fixed pattern
of velocity signs (reversals on sample instants): :func:`plan_friction_zoh`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm
from scipy.optimize import brentq, linprog

from .boundary import MoveProblem
from .errors import FlexmotionError, GoalError, SolverError
from .modal_response import ModalResponse
from .model import ModalModel, check_positive
from .profile import BangBangProfile, SampledProfile
from .simulation import PiecewiseConstant, step_matrices
from .switching import isolate_roots, sample_grid
from .time_optimal import FINAL_STATE_RTOL, plan_time_optimal

STICK = 0  # mode of a stuck contact (sliding modes are +1, -1)
#: Newton on the extremal has converged when the scaled residual is below this.
NEWTON_TOL = 1e-12
SWITCH_RESIDUAL_TOL = 1e-8
HAMILTONIAN_TOL = 1e-6


# ----------------------------------------------------------------- the contact
@dataclass(frozen=True)
class Contact:
    """One Coulomb friction contact.

    Attributes
    ----------
    g : ndarray, shape ``(n,)``
        ``x'`` per newton of friction force (e.g. ``|b0| e_v`` for the rigid body).
    C : ndarray, shape ``(n,)``
        Sliding velocity ``y = C x`` (m/s).
    force : float
        Coulomb force ``F >= 0`` (N, the input's unit).
    """

    g: np.ndarray
    C: np.ndarray
    force: float

    def __post_init__(self) -> None:
        g = np.asarray(self.g, float).ravel()
        C = np.asarray(self.C, float).ravel()
        F = float(self.force)
        if not (math.isfinite(F) and F >= 0.0):
            raise FlexmotionError("coulomb_force", f"must be finite and >= 0 N, got {self.force}")
        if g.shape != C.shape or not float(C @ g) > 0.0:
            raise FlexmotionError("friction contact", "needs C g > 0 (friction must oppose the sliding velocity)")
        object.__setattr__(self, "g", g)
        object.__setattr__(self, "C", C)
        object.__setattr__(self, "force", F)


def rigid_contact(model: ModalModel, coulomb_force: float) -> Contact:
    """Friction ``F sgn(v)`` on the rigid-body coordinate of ``model`` (see module notes)."""
    g = np.zeros(model.n_states)
    g[1] = abs(model.b0)
    C = np.zeros(model.n_states)
    C[1] = 1.0
    return Contact(g, C, coulomb_force)


def contact_at_coordinate(built, index: int, coulomb_force: float) -> Contact:
    """Friction at physical coordinate ``index`` of a :class:`~.builders.BuiltModel` (inside the structure).

    With ``Phi = modal_to_physical`` and the physical mass matrix ``M`` the
    generalised effect of a force on coordinate ``j`` is ``Phi^{-1} M^{-1} e_j``
    (mass-orthogonal modes); the sliding velocity is row ``j`` of ``Phi`` on
    the velocity states.  Needs the builder's masses (``two_mass``, ``crane``,
    ``chain``).
    """
    p = built.parameters
    if "masses" in p:
        masses = np.asarray(p["masses"], float)
    elif "m1" in p:
        masses = np.array([p["m1"], p["m2"]], float)
    elif "cart_mass" in p:
        masses = np.array([p["cart_mass"], p["payload_mass"]], float)
    else:
        raise FlexmotionError("friction contact", f"no masses known for a {built.kind!r} model")
    Phi = np.asarray(built.modal_to_physical, float)
    if not 0 <= index < Phi.shape[0]:
        raise FlexmotionError("friction contact", f"coordinate index must be in [0, {Phi.shape[0] - 1}], got {index}")
    eff = np.linalg.solve(Phi, np.eye(Phi.shape[0])[index] / masses)  # modal accelerations per N
    n = built.model.n_states
    g = np.zeros(n)
    C = np.zeros(n)
    g[1::2] = eff
    C[1::2] = Phi[index]
    return Contact(g, C, coulomb_force)


# ------------------------------------------------------------------ simulation
@dataclass
class FrictionRun:
    """An exact friction simulation.

    Attributes
    ----------
    states : ndarray
        States at the requested times.
    segments : list of tuple
        ``(t0, t1, mode, level)``: ``mode`` +1/-1 sliding, 0 stuck; constant input ``level``.
    events : list of tuple
        ``(t, kind, x)`` with ``kind`` in ``"reversal"``, ``"stick"``, ``"slip"``.
    """

    states: np.ndarray
    segments: list = field(default_factory=list)
    events: list = field(default_factory=list)
    starts: list = field(default_factory=list)  # state at the start of each segment


class FrictionSystem:
    """``x' = A x + B u - F g sgn(C x)`` with sticking; exact event-located simulation."""

    def __init__(self, A: np.ndarray, B: np.ndarray, contact: Contact) -> None:
        self.A = np.ascontiguousarray(A, float)
        self.B = np.ascontiguousarray(B, float).ravel()
        self.contact = contact
        self.n = self.A.shape[0]
        c = contact
        self.Cg = float(c.C @ c.g)
        self.F = c.force
        self.P = np.eye(self.n) - np.outer(c.g, c.C) / self.Cg
        self.PA = self.P @ self.A
        self.PB = self.P @ self.B
        CA = c.C @ self.A
        self.alpha = float(CA @ c.C) / float(c.C @ c.C)
        # y = C x obeys a scalar ODE when C A = alpha C: closed-form events
        self.scalar = bool(np.max(np.abs(CA - self.alpha * c.C)) <= 1e-14 * (np.max(np.abs(CA)) + 1e-300)) or not np.any(CA)
        nz = np.flatnonzero(c.C)
        self.unit = int(nz[0]) if nz.size == 1 and c.C[nz[0]] == 1.0 else None
        self._wmax = {}
        self.fast: _ClosedForm | None = None

    @classmethod
    def for_model(cls, model: ModalModel, coulomb_force: float, closed_form: bool = False) -> FrictionSystem:
        """Rigid-body friction on ``model``; ``closed_form=True`` propagates with the modal
        closed forms (the planners' fast path) instead of matrix exponentials."""
        system = cls(model.A(), model.B(), rigid_contact(model, coulomb_force))
        if closed_form:
            system.fast = _ClosedForm(model)
        return system

    def transition(self, h: float) -> np.ndarray:
        """``e^{A h}`` (sliding modes)."""
        if self.fast is not None:
            return self.fast.steps(h)[0]
        return step_matrices(self.A, self.B, h)[0]

    # --------------------------------------------------------------- pieces
    def applied(self, x: np.ndarray, level: float) -> float:
        """Net applied force at the contact ``a = C (A x + B u) / (C g)`` (N)."""
        return float(self.contact.C @ (self.A @ x + self.B * level)) / self.Cg

    def mode_at_rest(self, x: np.ndarray, level: float) -> int:
        """With ``y = 0``: stick if ``|a| <= F``, else slide in the direction of ``a``."""
        a = self.applied(x, level)
        return int(np.sign(a)) if abs(a) > self.F else STICK

    def field(self, x: np.ndarray, level: float, mode: int) -> np.ndarray:
        """``x'`` in ``mode``."""
        if mode == STICK:
            return self.PA @ x + self.PB * level
        return self.A @ x + self.B * level - self.F * mode * self.contact.g

    def _affine(self, mode: int, level: float) -> tuple[np.ndarray, np.ndarray]:
        if mode == STICK:
            return self.PA, self.PB * level
        return self.A, self.B * level - self.F * mode * self.contact.g

    def advance(self, x: np.ndarray, level: float, mode: int, h: float) -> np.ndarray:
        """Exact state after ``h`` seconds in ``mode`` (matrix exponentials)."""
        if h <= 0.0:
            return x.copy()
        if self.fast is not None:
            Phi, Gam, Gg = self.fast.steps(h)
            if mode == STICK:  # rigid body held: p and v = 0 stay, the modes move under u
                out = Phi @ x + Gam * level
                out[:2] = x[0], 0.0
                return out
            return Phi @ x + Gam * level - (self.F * mode) * Gg
        if mode == STICK:
            Phi, Gam = step_matrices(self.PA, self.PB, h)
            out = Phi @ x + Gam * level
        else:
            Phi, Gam = step_matrices(self.A, self.B, h)
            _, Gg = step_matrices(self.A, self.contact.g, h)
            out = Phi @ x + Gam * level - (self.F * mode) * Gg
        if mode == STICK:
            self._zero_y(out)
        return out

    def _zero_y(self, x: np.ndarray) -> None:
        if self.unit is not None:
            x[self.unit] = 0.0

    # ---------------------------------------------------------------- events
    def next_event(self, x: np.ndarray, level: float, mode: int, h: float) -> float | None:
        """Earliest event time in ``(0, h]`` for the current mode, or None."""
        C = self.contact.C
        if self.scalar:
            if mode == STICK:
                return None  # a = C B u / C g is constant while y = 0
            y0 = float(C @ x)
            beta = float(C @ self.B) * level - self.F * mode * self.Cg
            if y0 * mode <= 0.0 or beta * mode >= 0.0:
                return None  # already at zero (moving away) or not decelerating
            al = self.alpha
            if al == 0.0:
                tau = -y0 / beta
            else:
                z = -al * y0 / (al * y0 + beta)
                tau = math.log1p(z) / al if z > -1.0 else math.inf
            return tau if 0.0 < tau <= h else None
        M, m = self._affine(mode, level)
        if mode == STICK:
            w = C @ self.A / self.Cg
            k0 = float(C @ self.B) * level / self.Cg
            roots = [self._first_root(M, m, x, w, k0 - self.F, h), self._first_root(M, m, x, w, k0 + self.F, h)]
        else:
            roots = [self._first_root(M, m, x, C, 0.0, h, start_sign=mode)]
        roots = [r for r in roots if r is not None]
        return min(roots) if roots else None

    def _omega_max(self, M: np.ndarray) -> float:
        key = M.tobytes()
        if key not in self._wmax:
            self._wmax[key] = float(np.max(np.abs(np.linalg.eigvals(M).imag), initial=0.0))
        return self._wmax[key]

    def _first_root(self, M, m, x0, w, k, h, start_sign=None) -> float | None:
        """First zero in ``(0, h]`` of ``r(t) = w.x(t) + k``, ``x' = M x + m`` (exact solution)."""
        wmax = self._omega_max(M)
        cells = max(4, math.ceil(h * wmax * 16.0 / (2.0 * math.pi))) if wmax > 0.0 else 4
        cells = min(cells, 100000)
        d = h / cells
        Phi, Gam = _affine_step(M, m, d)
        xs = np.empty((cells + 1, x0.size))
        xs[0] = x0
        for i in range(cells):
            xs[i + 1] = Phi @ xs[i] + Gam
        r = xs @ w + k
        dr = (xs @ M.T + m) @ w
        s0 = start_sign if start_sign is not None else (np.sign(r[0]) or np.sign(dr[0]))
        if r[0] * s0 <= 0.0:
            # starting on the surface (an event just happened) with a rounding residue of the
            # wrong sign: remove the residue, so the motion away from the surface is no root
            k = k - r[0]
            r = r - r[0]
            r[0] = s0 * 1e-300
        scale = float(np.max(np.abs(r))) + 1e-300
        for i in range(cells):
            a, b = r[i], r[i + 1]
            if a * b <= 0.0:
                lo_t, hi_t = 0.0, d
            else:
                # cubic Hermite dip: a double zero hidden between two samples
                ss = np.linspace(0.0, 1.0, 9)[1:-1]
                h00, h10 = 2 * ss**3 - 3 * ss**2 + 1, ss**3 - 2 * ss**2 + ss
                h01, h11 = -2 * ss**3 + 3 * ss**2, ss**3 - ss**2
                cub = h00 * a + h10 * d * dr[i] + h01 * b + h11 * d * dr[i + 1]
                j = int(np.argmin(cub * np.sign(a)))
                if cub[j] * np.sign(a) > 0.05 * scale:
                    continue
                tm = ss[j] * d
                xm = _affine_apply(M, m, xs[i], tm)
                if (xm @ w + k) * a > 0.0:
                    continue
                lo_t, hi_t = 0.0, tm
            xi = xs[i]

            def f(t, xi=xi):
                return float(_affine_apply(M, m, xi, t) @ w + k)

            fb = f(hi_t)
            if lo_t == 0.0 and i == 0:
                # leaving the surface at t = 0: step back from hi_t until f has the start sign
                t1, f1 = hi_t, fb
                while f1 * s0 <= 0.0 and t1 > 1e-12 * d:
                    hi_t, fb = t1, f1
                    t1 *= 0.5
                    f1 = f(t1)
                if f1 * s0 <= 0.0:
                    continue  # no excursion away from the surface: nothing to find here
                lo_t, fa = t1, f1
            else:
                fa = f(lo_t) if lo_t > 0.0 else a
            if fb == 0.0:
                return i * d + hi_t
            if fa * fb > 0.0:
                continue
            t = lo_t if fa == 0.0 else brentq(f, lo_t, hi_t, xtol=4e-16 * max(h, 1e-300), rtol=8.9e-16)
            tau = i * d + t
            if tau > 0.0:
                return tau
        return None

    # ------------------------------------------------------------- simulate
    def run(self, x0, u: PiecewiseConstant, times=None, lock_after: float = math.inf) -> FrictionRun:
        """Exact states at ``times`` (default ``u.breaks``); input zero after ``u.duration``.

        ``lock_after``: no events after this time (the mode is frozen), for
        the planner's smooth shooting map only.
        """
        times = u.breaks if times is None else np.atleast_1d(np.asarray(times, float))
        order = np.argsort(times, kind="stable")
        out = np.empty((times.size, self.n))
        x = np.array(x0, dtype=float)
        levels, breaks = u.levels, u.breaks
        k = 0
        level = float(levels[0]) if levels.size else 0.0
        y = float(self.contact.C @ x)
        mode = int(np.sign(y)) if y != 0.0 else self.mode_at_rest(x, level)
        t = 0.0
        run = FrictionRun(out)
        ti = 0
        while ti < times.size:
            target = float(times[order[ti]])
            t_int = float(breaks[k + 1]) if k < levels.size else math.inf
            seg_end = min(t_int, target)
            if seg_end > t:
                if mode != STICK and t < lock_after:
                    y = float(self.contact.C @ x)
                    if y * mode <= 0.0:  # at (or, by rounding, just past) zero velocity
                        new = self.mode_at_rest(x, level)
                        if new != mode:
                            run.events.append((t, "stick" if new == STICK else "reversal", x.copy()))
                        self._zero_y(x)
                        mode = new
                h = seg_end - t
                tau = self.next_event(x, level, mode, h) if t < lock_after else None
                step = h if tau is None else tau
                run.starts.append(x.copy())
                x = self.advance(x, level, mode, step)
                run.segments.append((t, t + step, mode, level))
                t = t + step if tau is not None and tau < h else seg_end
                if tau is not None:
                    if mode == STICK:
                        mode = int(np.sign(self.applied(x, level)))
                        run.events.append((t, "slip", x.copy()))
                    else:
                        if self.unit is not None:
                            x[self.unit] = 0.0
                        new = self.mode_at_rest(x, level)
                        run.events.append((t, "stick" if new == STICK else "reversal", x.copy()))
                        mode = new
                    continue
            if t >= target:
                out[order[ti]] = x
                ti += 1
                continue
            if t >= t_int:  # next input level
                k += 1
                level = float(levels[k]) if k < levels.size else 0.0
                if mode == STICK:
                    new = self.mode_at_rest(x, level)
                    if mode == STICK and new != STICK:
                        run.events.append((t, "slip", x.copy()))
                    mode = new
        return run


class _ClosedForm:
    """``e^{A h}``, ``int_0^h e^{A s} B ds`` and the friction term in closed form (modal blocks)."""

    def __init__(self, model: ModalModel) -> None:
        self.model = model
        self.resp = ModalResponse(model, True)
        self.n = model.n_states
        self._cache: dict[float, tuple] = {}

    def steps(self, h: float):
        hit = self._cache.get(h)
        if hit is not None:
            return hit
        r = self.resp
        n = self.n
        Phi = np.zeros((n, n))
        ch = r.c * h
        Phi[0, 0] = 1.0
        Phi[0, 1] = h * (math.expm1(ch) / ch if ch != 0.0 else 1.0)
        Phi[1, 1] = math.exp(ch)
        if r.w.size:
            E, C, S = (a[0] for a in r._mode_trig(np.array([h])))
            s_wd = r.sig / r.wd
            i = 2 + 2 * np.arange(r.w.size)
            Phi[i, i] = E * (C + s_wd * S)
            Phi[i, i + 1] = E * S / r.wd
            Phi[i + 1, i] = -E * r.w**2 / r.wd * S
            Phi[i + 1, i + 1] = E * (C - s_wd * S)
        Gam = r.input_integral(np.array([h]))[0]
        Gg = np.zeros(n)
        Gg[:2] = Gam[:2] * (abs(r.b0) / r.b0)  # friction acts on the rigid body only
        if len(self._cache) > 4096:
            self._cache.clear()
        out = (Phi, Gam, Gg)
        self._cache[h] = out
        return out


def _affine_step(M: np.ndarray, m: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """``x(h) = Phi x + Gam`` for ``x' = M x + m`` (``m`` a constant vector)."""
    Phi, Gam = step_matrices(M, m, h) if np.any(m) else (step_matrices(M, np.zeros(M.shape[0]), h)[0], np.zeros(M.shape[0]))
    return Phi, Gam


def _affine_apply(M: np.ndarray, m: np.ndarray, x: np.ndarray, h: float) -> np.ndarray:
    """Exact ``x(h)`` for one odd step length (uncached: keeps the shared cache for sample periods)."""
    n = M.shape[0]
    Z = np.zeros((n + 1, n + 1))
    Z[:n, :n] = M
    Z[:n, n] = m
    E = expm(Z * h)
    return E[:n, :n] @ x + E[:n, n]


def simulate_coulomb(model: ModalModel, x0, u: PiecewiseConstant, coulomb_force: float, times=None) -> np.ndarray:
    """Exact states of ``model`` with Coulomb friction ``coulomb_force`` (N) on the rigid body.

    Parameters
    ----------
    model : ModalModel
    x0 : array_like
        Full initial state ``[p, v, q1, q1', ...]``.
    u : PiecewiseConstant
        Input (zero after ``u.duration``).
    coulomb_force : float
        Friction force ``F >= 0`` (N): ``v' = c v + b0 u - |b0| F sgn(v)``;
        stuck while ``v = 0`` and ``|u| <= F`` (the modes keep moving).
    times : array_like, optional
        Report times (s); default ``u.breaks``.

    Returns
    -------
    ndarray, shape ``(len(times), n_states)``
    """
    system = FrictionSystem(model.A(), model.B(), rigid_contact(model, coulomb_force))
    return system.run(x0, u, times).states


def simulate_contact(A, B, contact: Contact, x0, u: PiecewiseConstant, times=None) -> FrictionRun:
    """Exact simulation of any linear system with one friction contact (states and events)."""
    return FrictionSystem(A, B, contact).run(x0, u, times)


# --------------------------------------------------------- time-optimal move
def check_coulomb_force(coulomb_force, u_max: float) -> float:
    """``coulomb_force`` as float if in ``[0, u_max)`` N, else raise (names the parameter)."""
    try:
        F = float(coulomb_force)
    except (TypeError, ValueError):
        raise FlexmotionError("coulomb_force", f"must be a number in [0, u_max) = [0, {u_max:g}) N, got {coulomb_force!r}") from None
    if not (math.isfinite(F) and 0.0 <= F < u_max):
        raise FlexmotionError(
            "coulomb_force", f"must be in [0, u_max) = [0, {u_max:g}) N (at F >= u_max the machine cannot start), got {F}"
        )
    return F


def rigid_friction_time(model: ModalModel, u_max: float, coulomb_force: float, x0, target: float | None) -> float | None:
    """Proved lower bound (s) on any rest-to-rest move under rigid-body friction, or None.

    For ``c = 0`` from rest: while ``v > 0`` the acceleration lies in
    ``[-a2, a1]`` (``a1 = |b0| (u_max - F)``, ``a2 = |b0| (u_max + F)``), so
    ``v(t) <= min(a1 t, a2 (T - t))`` and the distance ``|gamma| <= T^2 a1 a2 / (2 (a1 + a2))``.
    The modes add constraints only, so the full model is never faster.
    """
    x0 = np.asarray(x0, float)
    if target is None or model.c != 0.0 or np.any(x0[1:]):
        return None
    gamma = abs(target - x0[0])
    a1 = abs(model.b0) * (u_max - coulomb_force)
    a2 = abs(model.b0) * (u_max + coulomb_force)
    return math.sqrt(2.0 * gamma * (a1 + a2) / (a1 * a2))


@dataclass
class FrictionCertificate:
    """Evidence that a bang-bang move under friction is a Pontryagin extremal of the piecewise system.

    Attributes
    ----------
    passed : bool
        ``B^T lambda`` vanishes at every switch, changes sign nowhere else
        (proved per costate piece, :func:`~.switching.isolate_roots`), has the
        sign of ``-u`` on every interval, and ``H = 0`` along the move.
    switch_residual : float
        ``max_j |B^T lambda(t_j)|`` relative to ``max_t |B^T lambda(t)|``.
    extra_zeros, unproved_cells : int
    sign_consistent : bool
    hamiltonian_max_abs : float
    costate_final : ndarray
        ``lambda(T)`` (``H = 1 + lambda^T x'``).
    claim : str
        What is and is not proved.
    message : str
    """

    passed: bool
    switch_residual: float
    extra_zeros: int
    unproved_cells: int
    sign_consistent: bool
    hamiltonian_max_abs: float
    costate_final: np.ndarray
    claim: str
    message: str = "ok"

    def to_dict(self) -> dict:
        """JSON-friendly summary."""
        return {
            "passed": bool(self.passed),
            "switch_residual": float(self.switch_residual),
            "extra_zeros": int(self.extra_zeros),
            "unproved_cells": int(self.unproved_cells),
            "sign_consistent": bool(self.sign_consistent),
            "hamiltonian_max_abs": float(self.hamiltonian_max_abs),
            "costate_final": [float(v) for v in self.costate_final],
            "claim": self.claim,
            "message": self.message,
        }


@dataclass
class FrictionProfile:
    """A bang-bang move under Coulomb friction and its checks.

    Attributes
    ----------
    problem : MoveProblem
    coulomb_force : float
        ``F`` (N).
    switch_times, levels : ndarray
        Interior switches (s) and ``+-u_max`` on each interval.
    duration : float
        Move time (s).
    final_state : ndarray
        State at ``duration`` from the exact friction simulation (absolute).
    final_state_error, final_state_error_relative : float
        Distance from rest at the target (state units; relative to each state's scale).
    reversals : ndarray
        Times (s) where the rigid body reverses (the costate jumps there).
    certificate : FrictionCertificate
    frictionless_duration : float
        The certified frictionless optimum ``T*`` (s).
    lower_bound : float or None
        Proved lower bound on any move under this friction (s), see :func:`rigid_friction_time`.
    continuation_steps : int
    solve_time_s : float
    """

    problem: MoveProblem
    coulomb_force: float
    switch_times: np.ndarray
    levels: np.ndarray
    duration: float
    final_state: np.ndarray
    final_state_error: float
    final_state_error_relative: float
    reversals: np.ndarray
    certificate: FrictionCertificate
    frictionless_duration: float
    lower_bound: float | None
    continuation_steps: int = 0
    solve_time_s: float = 0.0
    method: str = "time_optimal_friction"

    @property
    def certified(self) -> bool:
        """Whether the extremal certificate passed (necessary conditions, see the claim)."""
        return bool(self.certificate.passed)

    def input(self) -> PiecewiseConstant:
        """The input as a :class:`PiecewiseConstant`."""
        return PiecewiseConstant.from_switches(self.switch_times, self.levels, self.duration)

    def to_dict(self) -> dict:
        """JSON-friendly summary."""
        return {
            "method": self.method,
            "coulomb_force": float(self.coulomb_force),
            "duration": float(self.duration),
            "switch_times": [float(t) for t in self.switch_times],
            "levels": [float(v) for v in self.levels],
            "final_state": [float(v) for v in self.final_state],
            "final_state_error": float(self.final_state_error),
            "final_state_error_relative": float(self.final_state_error_relative),
            "reversals": [float(t) for t in self.reversals],
            "frictionless_duration": float(self.frictionless_duration),
            "added_time_s": float(self.duration - self.frictionless_duration),
            "lower_bound_s": None if self.lower_bound is None else float(self.lower_bound),
            "certified": self.certified,
            "certificate": self.certificate.to_dict(),
            "continuation_steps": int(self.continuation_steps),
            "solve_time_s": float(self.solve_time_s),
        }


class _Extremal:
    """Shooting map of the hybrid Pontryagin conditions for one problem and friction force."""

    def __init__(self, problem: MoveProblem, levels: np.ndarray, F: float, scale: np.ndarray) -> None:
        m = problem.model
        self.problem = problem
        self.sys = FrictionSystem.for_model(m, F, closed_form=True)
        self.check = FrictionSystem.for_model(m, F)  # matrix exponentials: the independent check
        self.x0 = problem.x0
        self.xf = m.rest_state(problem.target if problem.target is not None else 0.0)
        self.I = np.arange(m.n_states) if problem.include_position else np.arange(1, m.n_states)
        self.levels = levels
        self.L = levels.size - 1
        self.s = scale
        self.sig_scale = 1.0

    def unpack(self, y: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
        lam = np.zeros(self.sys.n)
        lam[self.I] = y[self.L + 1 :]
        return y[: self.L], float(y[self.L]), lam

    def valid(self, y: np.ndarray) -> bool:
        t, T = y[: self.L], y[self.L]
        return bool(T > 0.0 and (self.L == 0 or (t[0] > 0.0 and t[-1] < T and np.all(np.diff(t) > 0.0))))

    def costates(self, run: FrictionRun, lamT: np.ndarray):
        """``Lambda(t)`` with ``lambda(t) = Lambda(t) lambda(T)`` at every segment start (backward sweep).

        ``Lambda(t)^T`` is also the sensitivity ``dx(T)/dx(t)`` of the hybrid flow: ``e^{A h}`` on
        each segment and the saltation matrix at each reversal (None if the contact sticks).
        """
        sysf = self.sys
        n = sysf.n
        Lam = np.eye(n)
        out = [None] * len(run.segments)
        for i in range(len(run.segments) - 1, -1, -1):
            t0, t1, mode, level = run.segments[i]
            if mode == STICK:
                return None
            Lam = sysf.transition(t1 - t0).T @ Lam
            out[i] = Lam
            if i > 0 and run.segments[i - 1][2] != mode:  # a reversal at t0: saltation matrix
                xc = run.starts[i]
                fm = sysf.field(xc, run.segments[i - 1][3], run.segments[i - 1][2])
                fp = sysf.field(xc, level, mode)
                Sal = np.eye(n) + np.outer(fp - fm, sysf.contact.C) / float(sysf.contact.C @ fm)
                Lam = Sal.T @ Lam
        return out

    def residual(self, y: np.ndarray, want_lam_jac: bool = False):
        t_sw, T, lam = self.unpack(y)
        u = PiecewiseConstant.from_switches(t_sw, self.levels, T)
        run = self.sys.run(self.x0, u, [T], lock_after=float(t_sw[-1]) if self.L else 0.0)
        xT = run.states[0]
        r1 = (xT - self.xf)[self.I] / self.s[self.I]
        Lams = self.costates(run, lam)
        if Lams is None:
            return None
        starts = np.array([seg[0] for seg in run.segments])
        rows = []
        for tj in t_sw:
            i = int(np.argmin(np.abs(starts - tj)))
            rows.append(self.sys.B @ Lams[i])
        rows = np.array(rows).reshape(self.L, -1)
        sigma = rows @ lam / self.sig_scale
        fT = self.sys.field(xT, float(self.levels[-1]), run.segments[-1][2])
        H = 1.0 + float(lam @ fT)
        r = np.concatenate([r1, sigma, [H]])
        if not want_lam_jac:
            return r
        # Jacobian: in lambda(T) exactly; in (t_j, T) in closed form along the exact trajectory
        # (the costate does not depend on x between reversals; through reversal times it does:
        # those columns of the switching rows are differenced by the caller)
        nI, L, A, B = self.I.size, self.L, self.sys.A, self.sys.B
        J = np.zeros((r.size, L + 1 + nI))
        dx = np.empty((self.sys.n, L + 1))
        for j in range(L):
            i = int(np.argmin(np.abs(starts - t_sw[j])))
            dx[:, j] = Lams[i].T @ B * (self.levels[j] - self.levels[j + 1])
            lam_j = Lams[i] @ lam
            J[nI + j, j] = -float((A @ B) @ lam_j) / self.sig_scale
            J[nI + j, L] = float((Lams[i].T @ B) @ (A.T @ lam)) / self.sig_scale
        dx[:, L] = fT
        J[:nI, : L + 1] = dx[self.I] / self.s[self.I, None]
        J[-1, : L + 1] = (lam @ A) @ dx
        J[nI : nI + L, L + 1 :] = rows[:, self.I] / self.sig_scale
        J[-1, L + 1 :] = fT[self.I]
        reversals = any(kind == "reversal" for _, kind, _ in run.events)
        return r, J, reversals

    def newton(self, y: np.ndarray, max_iter: int = 30) -> tuple[bool, np.ndarray, float]:
        """Damped Newton on the extremal conditions from ``y``; returns ``(converged, y, residual)``."""
        out = self.residual(y, True)
        if out is None:
            return False, y, math.inf
        r, J, reversals = out
        rn = float(np.max(np.abs(r)))
        nz, nI, L = self.L + 1, self.I.size, self.L
        for _ in range(max_iter):
            if rn <= NEWTON_TOL:
                return True, y, rn
            if reversals and L:
                knots = np.concatenate([[0.0], y[:nz]])
                hstep = min(1e-7 * y[self.L], 0.25 * float(np.min(np.diff(knots))))
                for j in range(nz):
                    yp, ym = y.copy(), y.copy()
                    yp[j] += hstep
                    ym[j] -= hstep
                    if not (self.valid(yp) and self.valid(ym)):
                        return False, y, rn
                    rp, rm = self.residual(yp), self.residual(ym)
                    if rp is None or rm is None:
                        return False, y, rn
                    J[nI : nI + L, j] = (rp - rm)[nI : nI + L] / (2.0 * hstep)
            step, *_ = np.linalg.lstsq(J, -r, rcond=None)
            tt = 1.0
            for _ in range(20):
                yc = y + tt * step
                if self.valid(yc):
                    oc = self.residual(yc, True)
                    if oc is not None and float(np.max(np.abs(oc[0]))) < rn:
                        break
                tt *= 0.5
            else:
                return rn <= 1e3 * NEWTON_TOL, y, rn
            y = yc
            r, J, reversals = oc
            rn = float(np.max(np.abs(r)))
        return rn <= NEWTON_TOL, y, rn


def plan_time_optimal_friction(problem: MoveProblem, coulomb_force: float) -> FrictionProfile:
    """Bang-bang move to rest under rigid-body Coulomb friction, checked by exact simulation.

    Parameters
    ----------
    problem : MoveProblem
        Model, bound, initial state, target (``None``: final position free).
    coulomb_force : float
        ``F`` in ``[0, u_max)`` (N).

    Returns
    -------
    FrictionProfile
        Rests at the target in the exact friction simulation; ``certified``
        if it is a proved Pontryagin extremal (see the module notes).

    Raises
    ------
    FlexmotionError
        ``coulomb_force`` out of range.
    SolverError
        If continuation from the frictionless optimum fails or the result
        misses the target in the exact friction simulation.
    """
    t0 = time.perf_counter()
    F = check_coulomb_force(coulomb_force, problem.u_max)
    base = plan_time_optimal(problem)
    model = problem.model
    lb = rigid_friction_time(model, problem.u_max, F, problem.x0, problem.target)
    if base.duration == 0.0:
        cert = FrictionCertificate(True, 0.0, 0, 0, True, 0.0, np.zeros(model.n_states), "already at rest")
        return FrictionProfile(problem, F, np.empty(0), base.levels, 0.0, problem.x0.copy(), 0.0, 0.0, np.empty(0), cert, 0.0, lb, 0, time.perf_counter() - t0)
    levels = np.asarray(base.levels, float)
    # per-state scale: how large each state gets during the frictionless move
    u0 = base.input()
    grid = np.linspace(0.0, base.duration, 65)
    fs0 = FrictionSystem.for_model(model, 0.0, closed_form=True)
    xs = fs0.run(problem.x0, u0, grid).states
    xf = model.rest_state(problem.target if problem.target is not None else 0.0)
    scale = np.max(np.abs(xs - xf), axis=0) + np.abs(problem.x0 - xf)
    scale = np.where(scale > 0.0, scale, 1.0)
    lam0 = np.asarray(base.certificate.costate_final, float)
    y = np.concatenate([base.switch_times, [base.duration], lam0])

    def solve(levels, F_try, y):
        ext = _Extremal(problem, levels, F_try, scale)
        ext.sig_scale = _sigma_scale(ext, y)
        ok, y_new, _ = ext.newton(y)
        return ok, ext, y_new

    done, step, steps = 0.0, F, 0
    ext = None
    strict = True  # follow structure changes; False: keep the structure (a feasible move, not an extremal)
    while ext is None or done < F:
        F_try = min(F, done + step)
        ok, ext_new, y_new = solve(levels, F_try, y)
        steps += 1
        lev_new = levels
        if ok and strict:
            # the sign changes of B^T lambda must be the switches: re-solve with switches where they are
            ok = False
            for _ in range(4):
                zeros, sign0 = _switching_zeros(ext_new, y_new)
                if zeros is None:
                    break
                if _same_switches(zeros, ext_new.unpack(y_new)[0], y_new[ext_new.L]):
                    ok = True
                    break
                lev_new = problem.u_max * sign0 * (1.0 - 2.0 * (np.arange(zeros.size + 1) % 2))
                ok2, ext_new, y_new = solve(lev_new, F_try, np.concatenate([zeros, y_new[ext_new.L :]]))
                if not ok2:
                    break
        if ok:
            levels, y, done, ext = lev_new, y_new, F_try, ext_new
            step = min(2.0 * step, F - done) if done < F else step
        else:
            step *= 0.5
            if step < 1e-2 * max(F, 1e-300):
                # a pair of switches may have merged (its interval shrinks to zero where the
                # structure ends): drop the closest pair and re-solve at the last friction force
                t_sw, T_cur = y[: levels.size - 1], y[levels.size - 1]
                gaps = np.diff(t_sw)
                dropped = False
                if gaps.size and gaps.min() < 0.1 * T_cur and steps <= 200:
                    k = int(np.argmin(gaps))
                    lev2, y2 = np.delete(levels, [k + 1, k + 2]), np.delete(y, [k, k + 1])
                    ok2, ext2, y2 = solve(lev2, done, y2)
                    if ok2:
                        levels, y, ext, dropped = lev2, y2, ext2, True
                        step = max(F - done, 0.0) * 0.25
                if not dropped and strict:
                    # the switching function changes sign where the structure cannot follow (e.g. at a
                    # velocity reversal, where the costate jumps): go on with this structure; the move
                    # stays exact and is checked, the certificate will say it is not an extremal
                    strict, dropped = False, True
                    step = max(F - done, 0.0)
                if not dropped:
                    raise SolverError(
                        f"friction planner: continuation from the frictionless optimum stalled at coulomb_force = {done:g} N "
                        f"(the switch structure changes); nothing is returned"
                    )
    return _assemble_friction(ext, y, base, lb, steps, t0)


def _sigma_scale(ext: _Extremal, y: np.ndarray) -> float:
    """Scale of ``B^T lambda`` (fixed during one Newton solve)."""
    lam = ext.unpack(y)[2]
    return max(float(np.max(np.abs(lam))) * float(np.max(np.abs(ext.sys.B))), 1e-300)


def _assemble_friction(ext: _Extremal, y: np.ndarray, base: BangBangProfile, lb, steps: int, t0: float) -> FrictionProfile:
    problem = ext.problem
    t_sw, T, _lam = ext.unpack(y)
    u = PiecewiseConstant.from_switches(t_sw, ext.levels, T)
    # the independent check: full event-located simulation, no mode locking; and rest after T
    run = ext.check.run(problem.x0, u, [T, T + max(T, 1.0)])
    xT, x_after = run.states
    dev = (xT - ext.xf)[ext.I]
    err = float(np.max(np.abs(dev)))
    rel = float(np.max(np.abs(dev) / ext.s[ext.I]))
    drift = float(np.max(np.abs((x_after - xT)[ext.I]) / ext.s[ext.I]))
    if not (rel <= FINAL_STATE_RTOL and drift <= FINAL_STATE_RTOL):
        raise SolverError(
            f"friction planner missed the target in the exact friction simulation: relative final-state error "
            f"{rel:.3e} (drift after arrival {drift:.3e}); nothing is returned"
        )
    cert = _certify_friction(ext, y)
    reversals = np.array([t for t, kind, _ in run.events if kind == "reversal" and t < T * (1.0 - 1e-12)])
    return FrictionProfile(
        problem=problem,
        coulomb_force=ext.sys.F,
        switch_times=np.asarray(t_sw, float),
        levels=ext.levels.copy(),
        duration=float(T),
        final_state=xT,
        final_state_error=err,
        final_state_error_relative=rel,
        reversals=reversals,
        certificate=cert,
        frictionless_duration=float(base.duration),
        lower_bound=lb,
        continuation_steps=steps,
        solve_time_s=time.perf_counter() - t0,
    )


CLAIM = (
    "Pontryagin extremal of the piecewise-linear friction system (hybrid maximum principle, costate jumps at "
    "velocity reversals): necessary conditions only; global time-optimality is not proved (friction makes the "
    "reachable sets non-convex); lower_bound_s is a proved bound"
)


def _same_switches(zeros: np.ndarray, t_sw: np.ndarray, T: float) -> bool:
    return zeros.size == t_sw.size and bool(np.all(np.abs(zeros - t_sw) <= 1e-9 * T))


def _switching_zeros(ext: _Extremal, y: np.ndarray):
    """Sign changes of ``B^T lambda`` on ``(0, T)`` (proved per costate piece) and the sign of ``u`` at the start.

    Returns ``(zeros, sign0)``, or ``(None, 0)`` if the contact sticks or a cell is unproved.
    """
    zeros, unproved, _, lam0 = _zeros_detail(ext, y)
    if zeros is None or unproved:
        return None, 0.0
    return zeros, float(-np.sign(ext.sys.B @ lam0) or 1.0)


def _zeros_detail(ext: _Extremal, y: np.ndarray):
    t_sw, T, lam = ext.unpack(y)
    sysf = ext.sys
    u = PiecewiseConstant.from_switches(t_sw, ext.levels, T)
    run = sysf.run(ext.problem.x0, u, [T], lock_after=float(t_sw[-1]) if ext.L else 0.0)
    Lams = ext.costates(run, lam)
    if Lams is None:
        return None, 0, 0.0, lam
    system = ModalResponse(ext.problem.model, True)
    segs = run.segments
    # costate pieces: maximal runs of segments without a reversal
    pieces, start = [], 0
    for i in range(1, len(segs) + 1):
        if i == len(segs) or segs[i][2] != segs[i - 1][2]:
            pieces.append((start, i - 1))
            start = i
    unproved = 0
    sig_max = 0.0
    found = []
    for a, b in pieces:
        ta, tb = segs[a][0], segs[b][1]
        nu = -np.linalg.solve(sysf.transition(segs[b][1] - segs[b][0]).T, Lams[b] @ lam)  # -lambda(tb^-)
        length = tb - ta
        iso = isolate_roots(system, nu, length, sample_grid(system, length, density=2.0))
        unproved += iso.unproved
        found += list(tb - iso.roots)
        grid = np.linspace(0.0, length, 257)
        sig_max = max(sig_max, float(np.max(np.abs(system.switching(nu, grid)))))
    found = np.sort(np.array(found))
    found = found[(found > 0.0) & (found < T)]
    return found, unproved, sig_max, Lams[0] @ lam


def _certify_friction(ext: _Extremal, y: np.ndarray) -> FrictionCertificate:
    """Check the hybrid Pontryagin conditions along the exact friction trajectory."""
    t_sw, T, lam = ext.unpack(y)
    sysf = ext.sys
    u = PiecewiseConstant.from_switches(t_sw, ext.levels, T)
    run = sysf.run(ext.problem.x0, u, [T], lock_after=float(t_sw[-1]) if ext.L else 0.0)
    Lams = ext.costates(run, lam)
    found, unproved, sig_max, _ = _zeros_detail(ext, y)
    if Lams is None or found is None:
        return FrictionCertificate(False, math.inf, 0, 0, False, math.inf, lam, CLAIM, "the contact sticks during the move")
    segs = run.segments
    extra = 0
    sign_ok = True
    tol = 1e-9 * T
    matched = np.zeros(t_sw.size, bool)
    for z in found:
        k = int(np.argmin(np.abs(t_sw - z))) if t_sw.size else -1
        if k >= 0 and not matched[k] and abs(t_sw[k] - z) <= tol:
            matched[k] = True
        else:
            extra += 1
    extra += int(np.count_nonzero(~matched))
    # sign on every segment (between switches and reversals: B^T lambda jumps at a reversal),
    # and the Hamiltonian at every segment start
    starts = np.array([s[0] for s in segs])
    for i, (t0i, t1i, _, level) in enumerate(segs):
        if t1i <= t0i:
            continue
        h = 0.5 * (t1i - t0i)
        sig = float(sysf.B @ np.linalg.solve(sysf.transition(h).T, Lams[i] @ lam))  # lambda at the midpoint
        if np.sign(-sig) != np.sign(level):
            sign_ok = False
    H = [1.0 + float((Lams[i] @ lam) @ sysf.field(run.starts[i], segs[i][3], segs[i][2])) for i in range(len(segs))]
    ham = float(np.max(np.abs(H)))
    sig_sw = [float(sysf.B @ (Lams[int(np.argmin(np.abs(starts - tj)))] @ lam)) for tj in t_sw]
    resid = float(np.max(np.abs(sig_sw)) / sig_max) if t_sw.size and sig_max > 0 else 0.0
    reasons = []
    if resid > SWITCH_RESIDUAL_TOL:
        reasons.append(f"switching function not zero at a switch (residual {resid:.2e})")
    if extra:
        reasons.append(f"switching function has {extra} sign change(s) that are not switches")
    if unproved:
        reasons.append(f"{unproved} cell(s) not proved zero-free")
    if not sign_ok:
        reasons.append("levels do not follow u = -u_max sgn(B^T lambda)")
    if not ham <= HAMILTONIAN_TOL:
        reasons.append(f"Hamiltonian not zero (max |H| = {ham:.2e})")
    return FrictionCertificate(not reasons, resid, extra, unproved, sign_ok, ham, lam, CLAIM, "; ".join(reasons) or "ok")


# ------------------------------------------------------------ sampled version
def _velocity_pattern(K: int, dt: float, first: int, reversals: np.ndarray, stretch: float) -> np.ndarray:
    """Sign of ``v`` on each sample interval, reversals (times ``stretch``) moved to the nearest instant."""
    s = np.full(K, float(first))
    for tc in reversals:
        j = round(tc * stretch / dt)
        if 0 < j < K:
            s[j:] *= -1.0
    return s


def _window(K: int, centres: np.ndarray, width: int) -> np.ndarray:
    free = np.zeros(K, dtype=bool)
    for c in centres:
        free[max(0, c - width) : min(K, c + width + 1)] = True
    free[:width] = True
    free[K - width :] = True
    return free


def _friction_lp(problem: MoveProblem, F: float, K: int, dt: float, s: np.ndarray, sigma: np.ndarray, free: np.ndarray):
    """Least-peak commands reaching rest in ``K`` samples for a fixed velocity-sign pattern ``s``.

    Samples outside ``free`` are held at ``sigma_k t`` (the continuous
    levels); the free ones and the peak ``t`` are the unknowns.  Minimise
    ``t`` subject to ``|u_k| <= t``, the final state at rest (the friction
    on interval ``k`` is the known ``-F s_k``) and the velocity signs
    ``s_k v_k >= 0``, ``s_k v_{k+1} >= 0`` at every instant (with ``c <= 0``,
    ``v`` is monotone on a sample, so it keeps its sign between instants too;
    where the pattern changes sign, ``v = 0``).  Returns ``(u, t, G, w)`` or
    None; ``G^T u = w`` is the full final-state condition.
    """
    model = problem.model
    n = model.n_states
    cf = _ClosedForm(model)
    Phi, Gam, Gg = cf.steps(dt)
    resp = cf.resp
    m = np.arange(K)[::-1]  # samples to go after sample k
    G = resp.expm_x_many(dt * m, Gam)  # (K, n): effect of u_k on x_K
    Hf = resp.expm_x_many(dt * m, Gg)  # effect of the friction on interval k (times -F s_k)
    xf = model.rest_state(problem.target if problem.target is not None else 0.0)
    x0 = problem.x0 - xf
    I = np.arange(n) if problem.include_position else np.arange(1, n)
    w_full = -resp.expm_x(K * dt, x0) + F * (s @ Hf)
    G, w = G[:, I], w_full[I]
    Fi = np.flatnonzero(free)
    fixed = ~free
    nF = Fi.size
    # equality: G_F^T u_F + t G_fixed^T sigma = w
    A_eq = np.column_stack([G[Fi].T, (G[fixed] * sigma[fixed, None]).sum(axis=0)])
    # velocities at instants 1..K-1: v_j = a_j + Dv_j . (u_F, t), by the exact recursion
    ev, gv, fv = Phi[1, 1], Gam[1], Gg[1]
    a = np.empty(K + 1)
    vt = np.empty(K + 1)  # response to the fixed samples at unit peak
    a[0], vt[0] = x0[1], 0.0
    sig_fixed = np.where(fixed, sigma, 0.0)
    for k in range(K):
        a[k + 1] = ev * a[k] - F * fv * s[k]
        vt[k + 1] = ev * vt[k] + gv * sig_fixed[k]
    j = np.arange(1, K)[:, None]
    lag = j - 1 - Fi[None, :]
    Dv = np.column_stack([np.where(lag >= 0, gv * ev ** np.maximum(lag, 0), 0.0), vt[1:K]])
    a = a[1:K]
    left, right = s[:-1], s[1:]  # signs of the intervals either side of instant j
    change = left != right
    ub_v = np.vstack([-left[:, None] * Dv, -(right[change])[:, None] * Dv[change]])  # -s v_j <= 0
    b_v = np.concatenate([left * a, right[change] * a[change]])
    ub_u = np.zeros((2 * nF, nF + 1))
    ub_u[np.arange(nF), np.arange(nF)] = 1.0
    ub_u[nF + np.arange(nF), np.arange(nF)] = -1.0
    ub_u[:, -1] = -1.0
    cost = np.zeros(nF + 1)
    cost[-1] = 1.0
    res = linprog(
        cost,
        A_ub=np.vstack([ub_u, ub_v]),
        b_ub=np.concatenate([np.zeros(2 * nF), b_v]),
        A_eq=A_eq,
        b_eq=w,
        bounds=[(None, None)] * nF + [(0.0, None)],
        method="highs",
    )
    if res.status != 0:
        return None
    t = float(res.x[-1])
    u = sigma * t
    u[Fi] = res.x[:nF]
    return u, t, G, w


def plan_friction_zoh(
    problem: MoveProblem, coulomb_force: float, rate_hz: float, continuous: FrictionProfile | None = None, max_extra: int = 50
) -> SampledProfile:
    """Zero-order-hold commands at ``rate_hz`` reaching rest exactly under rigid-body friction.

    The velocity-sign pattern of the continuous friction extremal is kept,
    with each reversal moved to the nearest sample instant; for that pattern
    the problem is a linear program (:func:`_friction_lp`).  Sample counts
    from ``ceil(T / dt)`` up are tried until the least peak is within
    ``u_max``; the commands are then made exact (least-norm correction of
    :mod:`.zoh`) and checked by the exact event-located friction simulation.

    Returns
    -------
    SampledProfile
        ``states`` from the friction simulation; ``minimal`` False (fewest
        only within the fixed pattern); ``lower_bound_samples`` from the
        proved rigid-body bound when there is one.

    Raises
    ------
    SolverError
        No sequence within ``max_extra`` samples of the continuous move passes
        the exact check.
    """
    from .zoh import (
        _correct,  # the least-norm exact correction of the frictionless planner
    )

    t0 = time.perf_counter()
    rate = check_positive("rate_hz", rate_hz, "Hz")
    dt = 1.0 / rate
    F = check_coulomb_force(coulomb_force, problem.u_max)
    if continuous is None:
        continuous = plan_time_optimal_friction(problem, F)
    T = continuous.duration
    model, um = problem.model, problem.u_max
    if T == 0.0:
        states = simulate_coulomb(model, problem.x0, PiecewiseConstant([0.0], []), F, [0.0])
        return SampledProfile(problem, np.empty(0), dt, states, 0.0, 0.0, True, 0, None, time.perf_counter() - t0, "time_optimal_friction")
    if T / dt > 5e6:
        raise GoalError("rate_hz", f"a {T:.3g} s move at {rate:g} Hz needs over 5e6 samples; lower the rate")
    check = FrictionSystem.for_model(model, F)
    xf = model.rest_state(problem.target if problem.target is not None else 0.0)
    I = np.arange(model.n_states) if problem.include_position else np.arange(1, model.n_states)
    first = int(np.sign(model.b0 * continuous.levels[0])) if problem.x0[1] == 0.0 else int(np.sign(problem.x0[1]))
    lb = continuous.lower_bound
    lower = math.ceil(lb / dt * (1.0 - 1e-12)) if lb is not None else 0
    K = max(1, math.ceil(T / dt * (1.0 - 1e-12)))
    last_reason = "no feasible linear program"
    K0 = K
    for K in range(K0, K0 + max_extra + 1):
        sol = None
        stretch = K * dt / T
        mids = (np.arange(K) + 0.5) * dt / stretch
        sigma = np.sign(continuous.input()(mids))
        sigma[sigma == 0.0] = float(continuous.levels[-1] > 0) * 2.0 - 1.0
        centres = np.round(np.concatenate([continuous.switch_times, continuous.reversals]) * stretch / dt).astype(int)
        patterns = [_velocity_pattern(K, dt, first, continuous.reversals, stretch)]
        if continuous.reversals.size:
            patterns.append(np.full(K, float(first)))  # a sequence without reversal may exist too
        for s in patterns:
            for width in (4, 16, 64):
                cand = _friction_lp(problem, F, K, dt, s, sigma, _window(K, centres, width))
                if cand is not None and cand[1] <= um * (1.0 + 1e-12):
                    sol = cand
                    break
                if cand is not None:
                    last_reason = f"least peak {cand[1]:.6g} > u_max"
            if sol is not None:
                break
        if sol is None:
            continue
        u, _t_star, G, w = sol
        # exact final state for this pattern (the friction term is a constant of w)
        u = _correct(G, w, u, um)
        if u is None:
            continue
        states = check.run(problem.x0, PiecewiseConstant.from_samples(u, dt), dt * np.arange(K + 1)).states
        dev = (states[-1] - xf)[I]
        sc = np.max(np.abs(states - xf), axis=0)[I]
        sc = np.where(sc > 0.0, sc, 1.0)
        rel = float(np.max(np.abs(dev) / sc))
        if rel <= FINAL_STATE_RTOL and np.max(np.abs(u)) <= um:
            sp = SampledProfile(
                problem=problem,
                commands=u,
                dt=dt,
                states=states,
                final_state_error=float(np.max(np.abs(dev))),
                final_state_error_relative=rel,
                minimal=K == lower,
                lower_bound_samples=lower,
                continuous=None,
                solve_time_s=time.perf_counter() - t0,
                method="time_optimal_friction",
            )
            sp.extra.update({"coulomb_force": F, "peak_command": float(np.max(np.abs(u))), "extra_samples": K - K0})
            return sp
        last_reason = f"exact friction simulation misses the target (relative error {rel:.2e})"
    raise SolverError(f"sampled friction planner: no sequence within {max_extra} samples of the continuous move ({last_reason})")
