"""Certified time-optimal bang-bang moves (seed section 2.3).

Method
------
Work in time-to-go ``tau = T - t``.  For a co-state direction ``nu`` (``nu =
-lambda(T)`` up to a positive factor) the Pontryagin input is
``u(tau) = u_max sgn(nu^T e^{A tau} B)`` and the final state is::

    F(nu, T) = e^{A T} x0 + grad h_T(nu),   h_T(nu) = u_max int_0^T |nu^T e^{A tau} B| dtau

``h_T`` is the support function of the set reachable in time ``T``: convex in
``nu``.  ``x0`` can be brought to rest in time ``T`` iff
``m(T) = min {h_T(nu) : nu^T w = 1} >= 1`` with ``w = -e^{A T} x0``, and ``m``
is non-decreasing in ``T``.  So the optimal time is the root of ``m(T) = 1``:

1. *Inner* (fixed ``T``): minimise the convex ``h_T`` on the hyperplane with a
   damped Newton method.  Convexity makes this globally convergent from any
   start; no guess of the number of switches is needed: the switches are the
   zeros of the switching function at the current ``nu``, found on a grid.
2. *Outer*: safeguarded Newton on ``m(T) = 1`` (``dm/dT`` by the envelope
   theorem), bracketed from below by the rigid-body optimum.
3. *Polish*: Newton on ``F(nu, T) = 0`` jointly (quadratic convergence) to
   machine precision.

The result is then checked independently: the final state by
matrix-exponential simulation, optimality by the Pontryagin certificate
(:mod:`flexmotion_ros.core.certificate`).  A profile whose final state misses
the target is never returned.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from .boundary import MoveProblem
from .certificate import Certificate, certify
from .errors import SolverError
from .modal_response import ModalResponse
from .model import ModalModel
from .profile import BangBangProfile
from .simulation import PiecewiseConstant, simulate
from .switching import find_roots, sample_grid

#: Accept a profile whose relative final-state error is below this.
FINAL_STATE_RTOL = 1e-9
#: The Newton polish has converged when the scaled final state is below this.
POLISH_TOL = 1e-12
#: Switch-structure corrections tried before the fallback.
MAX_STRUCTURE_UPDATES = 5


@dataclass
class _Eval:
    roots: np.ndarray  # switching times-to-go
    signs: np.ndarray  # sign of S on each tau-interval (len(roots) + 1)
    F: np.ndarray  # scaled final state
    grad: np.ndarray  # scaled grad h
    h: float
    eAx: np.ndarray  # e^{A T} x0 (unscaled)
    H: np.ndarray | None = None  # scaled Hessian of h
    FT: np.ndarray | None = None  # scaled dF/dT


class _Shooting:
    """The final-state map and its derivatives for one problem."""

    def __init__(self, system, x0: np.ndarray, u_max: float, T_scale: float) -> None:
        self.sys = system
        self.x0 = x0
        self.u_max = u_max
        self.set_scale(T_scale)
        self.evaluations = 0

    def set_scale(self, T: float) -> None:
        """Per-state scale: how large each state gets during a move of length ``T``."""
        grid = np.linspace(0.0, T, 65)
        G = self.sys.input_integral(grid)
        s = np.abs(self.x0) + self.u_max * np.max(np.abs(G), axis=0)
        self.s = np.where(s > 0.0, s, 1.0)

    def evaluate(self, nuh: np.ndarray, T: float, jac: bool = True) -> _Eval:
        self.evaluations += 1
        sys, s, um = self.sys, self.s, self.u_max
        nu = nuh / s
        roots, sign0 = find_roots(sys, nu, T, sample_grid(sys, T))
        L = roots.size
        signs = sign0 * (1.0 - 2.0 * (np.arange(L + 1) % 2))
        G = sys.input_integral(np.append(roots, T))
        grad = um * (signs[-1] * G[-1] + 2.0 * (signs[:-1, None] * G[:-1]).sum(axis=0))
        eAx = sys.expm_x(T, self.x0)
        e = _Eval(roots, signs, (eAx + grad) / s, grad / s, float(nu @ grad), eAx)
        if jac:
            g = sys.expm_B(roots) / s if L else np.zeros((0, s.size))
            if L:
                _, dS = sys.switching(nu, roots, derivative=True)
                wts = 2.0 * um / np.maximum(np.abs(dS), 1e-300)
                e.H = (g.T * wts) @ g
            else:
                e.H = np.zeros((s.size, s.size))
            e.FT = (sys.A_x(eAx) + um * signs[-1] * sys.expm_B(np.array([T]))[0]) / s
        return e


def _null_basis(v: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the complement of ``v`` (columns)."""
    Q, _ = np.linalg.qr(v.reshape(-1, 1), mode="complete")
    return Q[:, 1:]


def _trust_step(g: np.ndarray, H: np.ndarray, radius: float) -> tuple[np.ndarray, bool]:
    """Minimise ``g.d + d.H.d/2`` over ``|d| <= radius`` (``H`` PSD, exact, by eigenvalues).

    Returns the step and whether it is the unconstrained Newton step.
    """
    lam, V = np.linalg.eigh(H)
    lam = np.maximum(lam, 0.0)
    gh = V.T @ g
    tiny = 1e-14 * max(float(lam[-1]), 1e-300)
    if lam[0] > tiny:
        d = -(gh / lam)
        if np.linalg.norm(d) <= radius:
            return V @ d, True
    # find mu > 0 with |d(mu)| = radius (More-Sorensen Newton on 1/|d|)
    mu = max(float(np.linalg.norm(g)) / radius - float(lam[0]), 1e-300)
    for _ in range(50):
        d = -(gh / (lam + mu))
        nd = float(np.linalg.norm(d))
        if abs(nd - radius) <= 1e-3 * radius:
            break
        dnd = -float(np.sum(gh**2 / (lam + mu) ** 3)) / nd  # d|d|/dmu
        mu_new = mu - (nd - radius) / dnd * (nd / radius)
        mu = mu_new if mu_new > 0.0 else 0.1 * mu
    return V @ d, False


def _inner(sh: _Shooting, T: float, nuh: np.ndarray | None, max_iter: int = 100, rtol: float = 1e-14):
    """Minimise ``h_T`` on ``{nu : nu^T w = 1}`` (convex), by a trust-region Newton method.

    Returns ``(nuh, m, dm/dT, eval)``.
    """
    w = -sh.sys.expm_x(T, sh.x0) / sh.s
    if nuh is None or float(nuh @ w) <= 0.0:
        nuh = w / float(w @ w)
    else:
        nuh = nuh / float(nuh @ w)
    Z = _null_basis(w)
    e = sh.evaluate(nuh, T)
    radius = 0.5 * float(np.linalg.norm(nuh))
    for _ in range(max_iter):
        g = Z.T @ e.grad
        Hr = Z.T @ e.H @ Z
        d, newton = _trust_step(g, Hr, radius)
        pred = -float(g @ d + 0.5 * d @ Hr @ d)
        if pred <= rtol * max(e.h, 1e-300) or radius <= 1e-15 * float(np.linalg.norm(nuh)):
            break
        cand = nuh + Z @ d
        ec = sh.evaluate(cand, T)
        rho = (e.h - ec.h) / pred
        if rho < 0.25:
            radius = 0.25 * float(np.linalg.norm(d))
        elif rho > 0.75 and not newton:
            radius *= 2.0
        if ec.h < e.h:
            nuh, e = cand, ec
    nu = nuh / sh.s
    S_T = float(sh.sys.switching(nu, np.array([T]))[0])
    dm = sh.u_max * abs(S_T) + e.h * float(nu @ sh.sys.A_x(e.eAx))
    return nuh, e.h, dm, e


def _polish(sh: _Shooting, nuh: np.ndarray, T: float, max_iter: int = 40):
    """Newton on ``F(nu, T) = 0`` jointly; ``nu`` kept on the unit sphere."""
    nuh = nuh / np.linalg.norm(nuh)
    e = sh.evaluate(nuh, T)
    r = float(np.max(np.abs(e.F)))
    for _ in range(max_iter):
        if r <= 4.0 * np.finfo(float).eps:
            break
        Z = _null_basis(nuh)
        J = np.column_stack([e.H @ Z, e.FT])
        step, *_ = np.linalg.lstsq(J, -e.F, rcond=1e-14)
        t = 1.0
        improved = False
        for _ in range(12):
            cand = nuh + t * (Z @ step[:-1])
            cand /= np.linalg.norm(cand)
            Tc = T + t * step[-1]
            if Tc > 0.0:
                ec = sh.evaluate(cand, Tc)
                rc = float(np.max(np.abs(ec.F)))
                if rc < r:
                    improved = True
                    break
            t *= 0.5
        if not improved:
            break
        nuh, T, e, r = cand, Tc, ec, rc
    return nuh, T, e, r


def _inner_smooth(sh: _Shooting, T: float, nuh: np.ndarray | None, eps_rel: float, max_iter: int = 50):
    """Smoothed, discretised inner problem: a warm start for the exact one.

    ``|S|`` is replaced by ``sqrt(S^2 + eps^2) - eps`` and the integral by the
    trapezoidal rule on the bracketing grid: a smooth, strictly convex
    function of ``nu``, so Newton's method with a line search converges fast
    from any start, whatever the number of switches.
    """
    sys, s, um = sh.sys, sh.s, sh.u_max
    grid = sample_grid(sys, T)
    wq = np.full(grid.size, grid[1] - grid[0])
    wq[[0, -1]] *= 0.5
    Gm = sys.expm_B(grid) / s
    eAx = sys.expm_x(T, sh.x0)
    w = -eAx / s
    if nuh is None or float(nuh @ w) <= 0.0:
        nuh = w / float(w @ w)
    else:
        nuh = nuh / float(nuh @ w)
    Z = _null_basis(w)
    S = Gm @ nuh
    # smoothing scale: a fraction of the mean |S| at the start (fixed during this solve)
    eps = eps_rel * max(float(wq @ np.abs(S)) / T, 1e-300)

    def value(S):
        return um * float(wq @ (np.sqrt(S * S + eps * eps) - eps))

    f = value(S)
    for _ in range(max_iter):
        sq = np.sqrt(S * S + eps * eps)
        g = Z.T @ (um * (Gm.T @ (wq * S / sq)))
        GZ = Gm @ Z
        Hr = um * ((GZ.T * (wq * eps * eps / sq**3)) @ GZ)
        try:
            dy = -np.linalg.solve(Hr, g)
        except np.linalg.LinAlgError:
            dy = -g
        dec = -float(g @ dy)
        if dec <= 1e-14 * f:
            break
        t = 1.0
        step = Z @ dy
        dS = Gm @ step
        for _ in range(40):
            fc = value(S + t * dS)
            if fc <= f - 0.25 * t * dec:
                break
            t *= 0.5
        else:
            break
        nuh = nuh + t * step
        S = S + t * dS
        f = fc
    nu = nuh / s
    mu = um * float(wq @ (S * S / np.sqrt(S * S + eps * eps)))  # Lagrange multiplier nu.grad h
    dm = um * (math.sqrt(S[-1] ** 2 + eps * eps) - eps) + mu * float(nu @ sys.A_x(eAx))
    return nuh, f, dm


def _outer(inner, T_low: float, T: float, nuh, tol: float, max_outer: int = 100):
    """Safeguarded Newton on ``log m(T) = 0`` in ``log T`` (``m`` non-decreasing).

    ``inner(T, nuh) -> (nuh, m, dm/dT)``.  ``m`` behaves like a power of ``T``
    (for short moves a high one: the reachable set of an integrator chain
    grows like ``T^k``), so Newton in logarithms converges where Newton on
    ``m - 1`` would jump far; steps are capped at a factor 4 and kept inside
    the bracket.
    """
    lo, hi = T_low, math.inf
    for _ in range(max_outer):
        nuh, m, dm = inner(T, nuh)
        if abs(m - 1.0) <= tol:
            break
        if m < 1.0:
            lo = max(lo, T)
        else:
            hi = min(hi, T)
        if m > 0.0 and dm > 0.0:
            elasticity = T * dm / m  # d log m / d log T
            Tn = T * math.exp(max(-math.log(4.0), min(math.log(4.0), -math.log(m) / elasticity)))
        else:
            Tn = math.nan
        if not (lo < Tn < hi):
            Tn = 2.0 * T if math.isinf(hi) else (0.5 * (lo + hi) if lo > 0.0 else 0.5 * hi)
        if abs(Tn - T) <= 1e-15 * T:
            break
        T = Tn
    return nuh, T


def _rescale(sh: _Shooting, nuh: np.ndarray, T: float) -> np.ndarray:
    nu = nuh / sh.s
    sh.set_scale(T)
    return nu * sh.s


def _refine_switches(sh: _Shooting, roots: np.ndarray, sign0: float, nuh: np.ndarray, T: float, max_iter: int = 30):
    """Newton on switch times, co-state and duration together, for a fixed switch structure.

    Unknowns ``(tau_1..tau_L, nu, T)``; equations: final state zero (n),
    switching function zero at each switch (L), one normalisation of ``nu``.
    Square for any ``L``; all derivatives in closed form, no root finding.

    Returns ``(ok, roots, nuh, T, residual)``; ``ok`` is False if the
    structure broke (switches crossed or left ``(0, T)``) or Newton stalled.
    """
    sys, s, um = sh.sys, sh.s, sh.u_max
    L, n = roots.size, s.size
    signs = sign0 * (1.0 - 2.0 * (np.arange(L + 1) % 2))
    jump = 2.0 * um * signs[:-1]  # (s_{j-1} - s_j) u_max
    nuh = nuh / np.linalg.norm(nuh)
    anchor = nuh.copy()

    def residual(tau, nuh, T):
        G = sys.input_integral(np.append(tau, T))
        eAx = sys.expm_x(T, sh.x0)
        F = (eAx + um * signs[-1] * G[-1] + jump @ G[:-1]) / s
        g = sys.expm_B(tau) / s if L else np.zeros((0, n))
        S = g @ nuh
        return np.concatenate([F, S * gscale, [anchor @ nuh - 1.0]]), g, eAx

    gscale = 1.0
    tau = roots.copy()
    r, g, eAx = residual(tau, nuh, T)
    if L:
        gscale = 1.0 / max(float(np.max(np.linalg.norm(g, axis=1))), 1e-300)
        r, g, eAx = residual(tau, nuh, T)
    rn = float(np.max(np.abs(r)))
    for _ in range(max_iter):
        if rn <= 16.0 * np.finfo(float).eps:
            break
        J = np.zeros((n + L + 1, L + n + 1))
        J[:n, :L] = (g * jump[:, None]).T  # dF/dtau_j = jump_j e^{A tau_j} B / s
        J[:n, -1] = (sys.A_x(eAx) + um * signs[-1] * sys.expm_B(np.array([T]))[0]) / s
        if L:
            _, dS = sys.switching(nuh / s, tau, derivative=True)
            J[n : n + L, :L] = np.diag(dS * gscale)
            J[n : n + L, L : L + n] = g * gscale
        J[-1, L : L + n] = anchor
        try:
            step = np.linalg.solve(J, -r)
        except np.linalg.LinAlgError:
            step, *_ = np.linalg.lstsq(J, -r, rcond=None)
        if np.max(np.abs(np.append(step[:L], step[-1]))) <= 4.0 * np.finfo(float).eps * T:
            break  # converged: the step is below rounding of the times
        t = 1.0
        for _ in range(12 if rn > POLISH_TOL else 3):
            tau_c = tau + t * step[:L]
            T_c = T + t * step[-1]
            nu_c = nuh + t * step[L : L + n]
            if T_c > 0.0 and (L == 0 or (tau_c[0] > 0.0 and tau_c[-1] < T_c and np.all(np.diff(tau_c) > 0.0))):
                r_c, g_c, eAx_c = residual(tau_c, nu_c, T_c)
                rn_c = float(np.max(np.abs(r_c)))
                if rn_c < rn:
                    break
            t *= 0.5
        else:
            break
        tau, nuh, T, r, g, eAx, rn = tau_c, nu_c, T_c, r_c, g_c, eAx_c, rn_c
    if L:  # nu and -nu both vanish at the switches: take the one whose signs match
        first = 0.5 * tau[0]
        if np.sign(sys.switching(nuh / s, np.array([first]))[0]) != sign0:
            nuh = -nuh
    return rn <= POLISH_TOL, tau, nuh, T, rn


def _structure_newton(sh: _Shooting, nuh: np.ndarray, T: float, roots=None, sign0: float = 1.0):
    """Switch-time Newton from the switch structure of ``nuh`` at ``T``, with structure updates.

    ``roots``/``sign0``: the structure if already known for ``nuh`` at ``T``.
    Returns ``(nuh, T, roots, signs, residual)`` of a converged extremal (its
    switching function changes sign exactly at its switches), or None.
    """
    if roots is None:
        roots, sign0 = find_roots(sh.sys, nuh / sh.s, T, sample_grid(sh.sys, T))
    nuh_r, T_r = nuh, T
    for _ in range(MAX_STRUCTURE_UPDATES):
        ok, roots_r, nuh_r, T_r, r = _refine_switches(sh, roots, sign0, nuh_r, T_r)
        if not ok:
            return None
        # an extremal switches exactly where S changes sign; if S changes sign
        # elsewhere too, the structure was wrong: adopt S's zeros and refine again
        iso_roots, iso_sign0 = find_roots(sh.sys, nuh_r / sh.s, T_r, sample_grid(sh.sys, T_r))
        if (
            iso_roots.size == roots_r.size
            and iso_sign0 == sign0
            and np.allclose(iso_roots, roots_r, rtol=0.0, atol=1e-9 * T_r)
        ):
            signs = sign0 * (1.0 - 2.0 * (np.arange(roots_r.size + 1) % 2))
            return nuh_r, T_r, roots_r, signs, r
        roots, sign0 = iso_roots, iso_sign0
    return None


def _solve(sh: _Shooting, T_low: float, T_init: float) -> tuple[np.ndarray, float, np.ndarray, np.ndarray, float]:
    """Optimal time and co-state direction.  ``T_low`` is a proved lower bound (may be 0).

    1. A smoothed, discretised version of the convex inner problem at the
       first guess, then the exact one (trust region), give a co-state
       direction and so a switch structure (any number of switches).
    2. Newton on switch times, co-state and ``T`` together converges
       quadratically from that structure; wrong structures are corrected from
       the zeros of the switching function (:func:`_structure_newton`).
    3. If that fails, the exact inner problem drives a safeguarded Newton
       iteration on ``log m(T) = 0`` until ``m`` is within 1e-3 of 1 and step 2
       is tried again; as a last resort the nested iteration runs to full
       accuracy and a joint Newton polish on ``(nu, T)`` finishes.
    The caller certifies whatever comes out.
    """
    T = max(T_init, T_low, 1e-300)
    nuh, _, _ = _inner_smooth(sh, T, None, 0.05)

    def exact(T, v, rtol=1e-9):
        v, m, dm, _ = _inner(sh, T, v, rtol=rtol)
        return v, m, dm

    # the switch structure at the first guess is often already right: try the
    # switch-time Newton from there, then again after the outer iteration
    nuh, _, _, e = _inner(sh, T, nuh, rtol=1e-9)
    found = _structure_newton(sh, nuh, T, e.roots, float(e.signs[0]))
    if found is not None:
        return found
    nuh, T = _outer(exact, T_low, T, nuh, tol=1e-3)
    nuh = _rescale(sh, nuh, T)
    found = _structure_newton(sh, nuh, T)
    if found is not None:
        return found
    nuh, T = _outer(lambda T, v: exact(T, v, 1e-15), T_low, T, nuh, tol=1e-11)
    nuh = _rescale(sh, nuh, T)
    nuh, T, e, r = _polish(sh, nuh, T)
    return nuh, T, e.roots, e.signs, r


@dataclass
class BangBangSolution:
    """Raw solver output for a linear system in time-to-go form.

    Attributes
    ----------
    nu : ndarray
        Dual direction ``-lambda(T)`` (any positive scale).
    duration : float
        Optimal time ``T`` (s).
    switch_times : ndarray
        Forward switching times (s).
    levels : ndarray
        Input on each interval (``+-u_max``).
    """

    nu: np.ndarray
    duration: float
    switch_times: np.ndarray
    levels: np.ndarray


def solve_bang_bang(system, x0: np.ndarray, u_max: float, T_low: float, T_init: float) -> BangBangSolution:
    """Time-optimal bang-bang input bringing ``x0`` to the origin, for any system object.

    ``system`` must offer what :class:`ModalResponse` offers (``n``, ``A()``,
    ``B()``, ``expm_B``, ``input_integral``, ``expm_x``, ``A_x``,
    ``switching(nu, tau, order=k)``, ``switching_magnitude``,
    ``switching_derivative_bound`` and an array ``wd`` of its oscillation
    frequencies, used for the grid).  ``T_low`` must be a proved lower bound
    (0 if none); ``T_init`` a first guess.  The result is not yet checked:
    simulate it and certify it (:func:`~flexmotion_ros.core.certificate.certify`).
    """
    x0 = np.asarray(x0, dtype=float)
    sh = _Shooting(system, x0, u_max, max(T_init, 1e-300))
    nuh, T, roots, signs, _ = _solve(sh, T_low, T_init)
    switch_times = np.sort(T - roots)
    return BangBangSolution(nuh / sh.s, float(T), switch_times, u_max * signs[::-1])


def rigid_time(model: ModalModel, u_max: float, x0: np.ndarray, include_position: bool) -> float:
    """Time-optimal move of the rigid body alone (s): a lower bound for the full model.

    The modes add constraints but no freedom (the blocks are decoupled), so
    the full model can never be faster.
    """
    a = abs(model.b0) * u_max
    c = model.c
    if not include_position:
        v = abs(x0[0]) if x0.size else 0.0
        if c == 0.0:
            return v / a
        return math.log1p(-c * v / a) / -c
    p, v = float(x0[0]), float(x0[1])
    if model.b0 < 0.0:
        p, v = -p, -v
    if c == 0.0:
        X, V = p / a, v / a
        if X > -V * abs(V) / 2.0:
            return V + 2.0 * math.sqrt(X + V * V / 2.0)
        return -V + 2.0 * math.sqrt(-X + V * V / 2.0)
    # viscous rigid body: one switch at most (real eigenvalues); Newton on the
    # switch time and T from the frictionless solution, else the general solver
    rigid = model.with_changes(omega=(), zeta=(), b=())
    x = np.array([p, v]) * np.sign(model.b0)
    guess = rigid_time(rigid.with_changes(c=0.0), u_max, np.array([p, v]), True)
    sh = _Shooting(ModalResponse(rigid, True), x, u_max, guess)
    X, V = p / a, v / a
    first = -1.0 if X > -V * abs(V) / 2.0 else 1.0  # forward level before the switch (c = 0)
    t_sw = 0.5 * (guess + first * V)  # c = 0 switch time: v + first*a*t_sw hits the curve
    tau0 = np.array([min(max(guess - t_sw, 1e-3 * guess), 0.999 * guess)])
    nuh = np.ones(2)
    ok, _, _, T, _ = _refine_switches(sh, tau0, -first * np.sign(model.b0), nuh, guess)
    if ok:
        return T
    return _solve(sh, 0.0, guess)[1]


def plan_time_optimal(problem: MoveProblem) -> BangBangProfile:
    """Time-optimal bang-bang input for a move to rest, with certificate.

    Parameters
    ----------
    problem : MoveProblem
        Model, bound, initial state and target (see :mod:`.boundary`).

    Returns
    -------
    BangBangProfile

    Raises
    ------
    SolverError
        If no profile passes the exact final-state check.
    """
    t0 = time.perf_counter()
    model, um = problem.model, problem.u_max
    system = ModalResponse(model, problem.include_position)
    x0 = problem.shifted_initial()
    if not np.any(x0):
        return _assemble(problem, system, np.zeros(system.n), 0.0, np.empty(0), np.array([1.0]), t0, 0)
    T_low = rigid_time(model, um, x0, problem.include_position)
    # a first guess: the rigid time plus a quarter period of the slowest mode
    T_init = T_low + (0.5 * math.pi / min(model.omega) if model.omega else 0.0)
    sh = _Shooting(system, x0, um, T_init)
    nuh, T, roots, signs, _ = _solve(sh, T_low * (1.0 - 1e-12), T_init)
    return _assemble(problem, system, nuh / sh.s, T, roots, signs, t0, sh.evaluations)


def _assemble(problem, system, nu, T, roots_tau, signs_tau, t0, evaluations) -> BangBangProfile:
    um = problem.u_max
    switch_times = np.sort(T - roots_tau)
    levels = um * signs_tau[::-1]
    u = PiecewiseConstant.from_switches(switch_times, levels, T)
    x0s = problem.shifted_initial()
    states = simulate((system.A(), system.B()), x0s, u)
    xT = states[-1]
    scale = np.abs(x0s) + np.max(np.abs(states), axis=0)
    scale = np.where(scale > 0.0, scale, 1.0)
    err = float(np.max(np.abs(xT))) if xT.size else 0.0
    rel = float(np.max(np.abs(xT) / scale)) if xT.size else 0.0
    if T > 0.0:
        cert = certify(system, nu, T, um, switch_times, levels, states)
    else:
        cert = Certificate(True, np.zeros(system.n), np.zeros(system.n), 0.0, 0, 0, True, 1.0, 0.0, "already at rest")
    final_abs = _absolute_final(problem, u)
    profile = BangBangProfile(
        problem=problem,
        switch_times=switch_times,
        levels=levels,
        duration=float(T),
        final_state=final_abs,
        final_state_error=err,
        final_state_error_relative=rel,
        certificate=cert,
        solve_time_s=time.perf_counter() - t0,
        iterations=evaluations,
    )
    if not rel <= FINAL_STATE_RTOL:
        raise SolverError(
            f"time-optimal planner missed the target: relative final-state error {rel:.3e} "
            f"(tolerance {FINAL_STATE_RTOL:.0e}); nothing is returned"
        )
    return profile


def _absolute_final(problem: MoveProblem, u: PiecewiseConstant) -> np.ndarray:
    """Final full state in absolute coordinates, by exact simulation."""
    return simulate(problem.model, problem.x0, u, times=[u.duration])[0]
