"""Newton on the switch times of the inputs, for a fixed switch structure.

Unknowns: each active input's switch times (time-to-go) ``tau_ij``, the
co-state direction ``nu`` and one scalar: the duration ``T`` (minimum time)
or the peak fraction ``rho`` (lowest peak at a fixed ``T``).  Equations: the
final state is zero (``n``), input ``i``'s switching function vanishes at
each of its switches (``L_i``), one normalisation of ``nu``.  Square for any
structure; all derivatives in closed form.

A :class:`Setting` restricts the problem to a subset of the inputs and a
subspace: with singular inputs ``J`` (``B_i^T lambda = 0`` identically) the
others are solved with ``nu`` in the orthogonal complement of what ``J``
reaches (and only that component of the final state); then ``J`` steers the
rest, inside its reachable subspace, with a fixed drive from the others.
The structure search around this Newton is in :mod:`.structure`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..tolerances import POLISH_TOL
from .response import MultiResponse

#: Singular values below this (relative) are dropped from the fallback step of a singular Jacobian.
SINGULAR_STEP_RCOND = 1e-10


@dataclass
class Extremal:
    """A converged extremal: per input its switch times (time-to-go) and first sign, ``nu`` (scaled), ``T``, ``rho``.

    Inactive inputs (see :class:`Setting`) have no switches and first sign 0.
    """

    roots: list
    sign0: list
    nuh: np.ndarray
    T: float
    rho: float
    residual: float


@dataclass(frozen=True)
class Setting:
    """Which inputs move (``active``), the co-state subspace ``V`` (orthonormal columns, scaled state), a fixed drive.

    ``base``: a state (unscaled) added to the final state, e.g. the fixed
    contribution of inputs solved before.  The final-state equations are
    projected on ``V`` (``V^T F = 0``) and ``nu = V y``.  ``min_norm_steps``:
    where a Newton step fails and the Jacobian is singular, retry with the
    minimum-norm (truncated SVD) step, and take that step throughout when the
    Jacobian is singular by its shape (fewer switches than final-state
    equations: a family of co-states); a last resort, as it slows the
    ordinary searches (more iterations on structures that are wrong anyway).
    """

    active: np.ndarray
    V: np.ndarray | None = None
    base: np.ndarray | None = None
    min_norm_steps: bool = False

    @classmethod
    def full(cls, m: int) -> Setting:
        return cls(np.ones(m, dtype=bool))


def signs_of(sign0: float, L: int) -> np.ndarray:
    """Levels' signs on the ``L + 1`` intervals in time-to-go, alternating from ``sign0``."""
    return sign0 * (1.0 - 2.0 * (np.arange(L + 1) % 2))


def refine(
    resp: MultiResponse,
    x0,
    u_max,
    s,
    roots,
    sign0,
    nuh,
    T,
    rho,
    free_time: bool,
    setting: Setting | None = None,
    max_iter: int = 40,
):
    """Newton on ``(tau, nu, T or rho)``; returns ``(ok, roots, nuh, T, rho, residual)``."""
    m, n = resp.m, resp.n
    setting = setting or Setting.full(m)
    act = setting.active
    V = np.eye(n) if setting.V is None else setting.V
    r_dim = V.shape[1]
    base = np.zeros(n) if setting.base is None else np.asarray(setting.base, float)
    u_max = np.asarray(u_max, float)
    L = [r.size if act[i] else 0 for i, r in enumerate(roots)]
    inp = np.concatenate([np.full(Li, i) for i, Li in enumerate(L)] + [np.empty(0, int)]).astype(int)
    Lt = inp.size
    signs = [signs_of(sign0[i], L[i]) for i in range(m)]
    jumpsign = np.concatenate([2.0 * signs[i][:-1] for i in range(m)] + [np.empty(0)])  # 2 s_{i,j-1}
    last = np.array([signs[i][-1] if act[i] else 0.0 for i in range(m)])
    y = V.T @ nuh
    y = y / np.linalg.norm(y)
    anchor = y.copy()
    ar = np.arange(Lt)

    def split(tau_all):
        out, k = [], 0
        for Li in L:
            out.append(tau_all[k : k + Li])
            k += Li
        return out

    def residual(tau_all, y, T, rho):
        GT = resp.input_integral(np.array([T]))[0]  # (n, m)
        eAx = resp.expm_x(T, x0)
        drive = GT @ (u_max * last)
        g = np.zeros((0, n))
        if Lt:
            Gt = resp.input_integral_cols(tau_all, inp)  # (Lt, n)
            drive = drive + (u_max[inp] * jumpsign) @ Gt
            g = resp.expm_B_cols(tau_all, inp) / s
        F = V.T @ ((eAx + base + rho * drive) / s)
        S = g @ (V @ y)
        return np.concatenate([F, S * gscale, [anchor @ y - 1.0]]), g, eAx, drive

    def line_search(step):
        """The first halving of ``step`` that lowers the residual and keeps the switches ordered; None if none."""
        t = 1.0
        for _ in range(14 if rn > POLISH_TOL else 1):
            tau_c = tau + t * step[:Lt]
            y_c = y + t * step[Lt : Lt + r_dim]
            T_c = T + t * step[-1] if free_time else T
            rho_c = rho if free_time else rho + t * step[-1]
            ok = T_c > 0.0 and rho_c > 0.0
            if ok:
                for part in split(tau_c):
                    if part.size and (part[0] <= 0.0 or part[-1] >= T_c or np.any(np.diff(part) <= 0.0)):
                        ok = False
                        break
            if ok:
                r_c, g_c, eAx_c, drive_c = residual(tau_c, y_c, T_c, rho_c)
                rn_c = float(np.max(np.abs(r_c)))
                if rn_c < rn:
                    return tau_c, y_c, T_c, rho_c, r_c, g_c, eAx_c, drive_c, rn_c
            t *= 0.5
        return None

    tau = np.concatenate([roots[i] for i in range(m) if act[i]] + [np.empty(0)])
    gscale = np.ones(Lt)
    r, g, eAx, drive = residual(tau, y, T, rho)
    if Lt:
        gscale = 1.0 / np.maximum(np.linalg.norm(g, axis=1), 1e-300)
        r, g, eAx, drive = residual(tau, y, T, rho)
    rn = float(np.max(np.abs(r)))
    # fewer switch times (+ T or rho) than final-state equations: those equations do not involve nu, so
    # the Jacobian is singular by its shape (a degenerate move, e.g. an input mirroring another's drive on
    # the modes) and a family of co-states fits; the minimum-norm step keeps nu nearest the warm start,
    # whose sign pattern it came from, where a plain solve throws it anywhere in the family.  Only as a
    # last resort: on a structure that merely lacks switches the plain step fails fast, these do not
    family = setting.min_norm_steps and Lt + 1 < r_dim
    for _ in range(max_iter):
        if rn <= 16.0 * np.finfo(float).eps:
            break
        J = np.zeros((r_dim + Lt + 1, Lt + r_dim + 1))
        if Lt:
            J[:r_dim, :Lt] = V.T @ (rho * (u_max[inp] * jumpsign)[:, None] * g).T
            dS = resp.switching_all((V @ y) / s, tau, 1)[1][inp, ar]
            J[r_dim : r_dim + Lt, :Lt] = np.diag(dS * gscale)
            J[r_dim : r_dim + Lt, Lt : Lt + r_dim] = (g @ V) * gscale[:, None]
        if free_time:
            eB = resp.expm_B(np.array([T]))[0]  # (n, m)
            J[:r_dim, -1] = V.T @ ((resp.A_x(eAx) + rho * eB @ (u_max * last)) / s)
        else:
            J[:r_dim, -1] = V.T @ (drive / s)
        J[-1, Lt : Lt + r_dim] = anchor
        if family:
            step = np.linalg.lstsq(J, -r, rcond=SINGULAR_STEP_RCOND)[0]
        else:
            try:
                step = np.linalg.solve(J, -r)
            except np.linalg.LinAlgError:
                step = np.linalg.lstsq(J, -r, rcond=None)[0]
        if not np.all(np.isfinite(step)):
            break
        eps = 4 * np.finfo(float).eps
        if np.max(np.abs(step[:Lt]), initial=0.0) <= eps * T and abs(step[-1]) <= eps * (T if free_time else rho):
            break
        accepted = line_search(step)
        if accepted is None and setting.min_norm_steps and rn > POLISH_TOL:
            sv = np.linalg.svd(J, compute_uv=False)
            if sv[-1] <= SINGULAR_STEP_RCOND * sv[0]:
                # a singular Jacobian (a family of co-states: e.g. two inputs switching together with
                # cancelling drives on a mode): the minimum-norm step on its well-determined part
                accepted = line_search(np.linalg.lstsq(J, -r, rcond=SINGULAR_STEP_RCOND)[0])
        if accepted is None:
            break
        tau, y, T, rho, r, g, eAx, drive, rn = accepted
    return rn <= POLISH_TOL, split(tau), V @ y, T, rho, rn


def drive_of(resp: MultiResponse, u_max, roots, sign0, T: float, rho: float, active) -> np.ndarray:
    """``rho sum_i u_max_i int_0^T e^{A tau} B_i s_i(tau) dtau`` over the active inputs (unscaled state)."""
    u_max = np.asarray(u_max, float)
    out = np.zeros(resp.n)
    GT = resp.input_integral(np.array([T]))[0]
    for i in range(resp.m):
        if not active[i]:
            continue
        sg = signs_of(sign0[i], roots[i].size)
        out += u_max[i] * sg[-1] * GT[:, i]
        if roots[i].size:
            Gt = resp.input_integral_cols(roots[i], np.full(roots[i].size, i))
            out += u_max[i] * (2.0 * sg[:-1]) @ Gt
    return rho * out
