"""Newton on the switch times of every input, for a fixed switch structure, with structure correction.

Unknowns: each input's switch times (time-to-go) ``tau_ij``, the co-state
direction ``nu`` and one scalar: the duration ``T`` (minimum time) or the
peak fraction ``rho`` (lowest peak at a fixed ``T``).  Equations: the final
state is zero (``n``), input ``i``'s switching function vanishes at each of
its switches (``L_i``), one normalisation of ``nu``.  Square for any
structure; all derivatives in closed form.  If the converged co-state's
switching functions change sign elsewhere, the structure was wrong: their
zeros become the new structure (:func:`~flexmotion_ros.core.time_optimal.switch_newton.updated_structure`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..time_optimal.switch_newton import updated_structure
from ..time_optimal.switching import find_roots, root_tolerance, sample_grid
from ..tolerances import POLISH_TOL
from .response import MultiResponse

MAX_STRUCTURE_UPDATES = 6


@dataclass
class Extremal:
    """A converged extremal: per input its switch times (time-to-go) and first sign, ``nu`` (scaled), ``T``, ``rho``."""

    roots: list
    sign0: list
    nuh: np.ndarray
    T: float
    rho: float
    residual: float


def _signs(sign0: float, L: int) -> np.ndarray:
    return sign0 * (1.0 - 2.0 * (np.arange(L + 1) % 2))


def refine(resp: MultiResponse, x0, u_max, s, roots, sign0, nuh, T, rho, free_time: bool, max_iter: int = 40):
    """Newton on ``(tau, nu, T or rho)``; returns ``(ok, roots, nuh, T, rho, residual)``."""
    m, n = resp.m, resp.n
    u_max = np.asarray(u_max, float)
    L = [r.size for r in roots]
    inp = np.concatenate([np.full(Li, i) for i, Li in enumerate(L)] + [np.empty(0, int)]).astype(int)
    Lt = inp.size
    signs = [_signs(sign0[i], L[i]) for i in range(m)]
    jumpsign = np.concatenate([2.0 * signs[i][:-1] for i in range(m)] + [np.empty(0)])  # 2 s_{i,j-1}
    last = np.array([signs[i][-1] for i in range(m)])
    nuh = nuh / np.linalg.norm(nuh)
    anchor = nuh.copy()
    ar = np.arange(Lt)  # switch index, to pick each switch's own input

    def split(tau_all):
        out, k = [], 0
        for Li in L:
            out.append(tau_all[k : k + Li])
            k += Li
        return out

    def residual(tau_all, nuh, T, rho):
        GT = resp.input_integral(np.array([T]))[0]  # (n, m)
        eAx = resp.expm_x(T, x0)
        drive = GT @ (u_max * last)
        g = np.zeros((0, n))
        if Lt:
            Gt = resp.input_integral_cols(tau_all, inp)  # (Lt, n)
            drive = drive + (u_max[inp] * jumpsign) @ Gt
            g = resp.expm_B_cols(tau_all, inp) / s
        F = (eAx + rho * drive) / s
        S = g @ nuh
        return np.concatenate([F, S * gscale, [anchor @ nuh - 1.0]]), g, eAx, drive

    tau = np.concatenate(list(roots) + [np.empty(0)])
    gscale = np.ones(Lt)
    r, g, eAx, drive = residual(tau, nuh, T, rho)
    if Lt:
        gscale = 1.0 / np.maximum(np.linalg.norm(g, axis=1), 1e-300)
        r, g, eAx, drive = residual(tau, nuh, T, rho)
    rn = float(np.max(np.abs(r)))
    for _ in range(max_iter):
        if rn <= 16.0 * np.finfo(float).eps:
            break
        J = np.zeros((n + Lt + 1, Lt + n + 1))
        if Lt:
            J[:n, :Lt] = (rho * (u_max[inp] * jumpsign)[:, None] * g).T
            dS = resp.switching_all(nuh / s, tau, 1)[1][inp, ar]
            J[n : n + Lt, :Lt] = np.diag(dS * gscale)
            J[n : n + Lt, Lt : Lt + n] = g * gscale[:, None]
        if free_time:
            eB = resp.expm_B(np.array([T]))[0]  # (n, m)
            J[:n, -1] = (resp.A_x(eAx) + rho * eB @ (u_max * last)) / s
        else:
            J[:n, -1] = drive / s
        J[-1, Lt : Lt + n] = anchor
        try:
            step = np.linalg.solve(J, -r)
        except np.linalg.LinAlgError:
            step = np.linalg.lstsq(J, -r, rcond=None)[0]
        if not np.all(np.isfinite(step)):
            break
        if np.max(np.abs(step[:Lt]), initial=0.0) <= 4 * np.finfo(float).eps * T and abs(step[-1]) <= 4 * np.finfo(
            float
        ).eps * (T if free_time else rho):
            break
        t = 1.0
        for _ in range(14 if rn > POLISH_TOL else 1):
            tau_c = tau + t * step[:Lt]
            nu_c = nuh + t * step[Lt : Lt + n]
            T_c = T + t * step[-1] if free_time else T
            rho_c = rho if free_time else rho + t * step[-1]
            ok = T_c > 0.0 and rho_c > 0.0
            if ok:
                for part in split(tau_c):
                    if part.size and (part[0] <= 0.0 or part[-1] >= T_c or np.any(np.diff(part) <= 0.0)):
                        ok = False
                        break
            if ok:
                r_c, g_c, eAx_c, drive_c = residual(tau_c, nu_c, T_c, rho_c)
                rn_c = float(np.max(np.abs(r_c)))
                if rn_c < rn:
                    break
            t *= 0.5
        else:
            break
        tau, nuh, T, rho, r, g, eAx, drive, rn = tau_c, nu_c, T_c, rho_c, r_c, g_c, eAx_c, drive_c, rn_c
    return rn <= POLISH_TOL, split(tau), nuh, T, rho, rn


def structure(resp: MultiResponse, nu: np.ndarray, T: float):
    """Per input: sign changes of ``S_i`` on ``(0, T)`` (time-to-go) and its first sign."""
    grid = sample_grid(resp, T)
    roots, sign0 = [], []
    for i in range(resp.m):
        r, s0 = find_roots(resp.for_input(i), nu, T, grid)
        roots.append(r)
        sign0.append(float(s0))
    return roots, sign0


def end_candidates(resp: MultiResponse, nu: np.ndarray, T: float, roots, sign0, small: float = 0.02):
    """Structures with a short extra switch at an end of the move, for inputs whose ``|S_i|`` is small there.

    A nearly singular input (its ``S_i`` tiny against the others) often ends
    or starts with a blip far shorter than the smoothing can resolve: ``S_i``
    just touches zero at ``t = 0`` or ``t = T`` in the warm start.
    """
    ends = resp.switching_all(nu, np.array([0.0, T]))[0]  # (m, 2): tau = 0 (t = T), tau = T (t = 0)
    grid = sample_grid(resp, T)
    peak = np.max(np.abs(resp.switching_all(nu, grid)[0]), axis=1)
    near_T = [i for i in range(resp.m) if abs(ends[i, 1]) <= small * peak[i]]
    near_0 = [i for i in range(resp.m) if abs(ends[i, 0]) <= small * peak[i]]
    out = []
    for which in ((near_T, ()), ((), near_0), (near_T, near_0)):
        if not (which[0] or which[1]):
            continue
        r_new, s_new = [r.copy() for r in roots], list(sign0)
        for i in which[0]:  # a switch just after t = 0: tau just below T
            last = r_new[i][-1] if r_new[i].size else 0.0
            r_new[i] = np.append(r_new[i], last + 0.999 * (T - last))
        for i in which[1]:  # a switch just before t = T: tau just above 0, the first sign flips
            first = r_new[i][0] if r_new[i].size else T
            r_new[i] = np.insert(r_new[i], 0, 1e-3 * first)
            s_new[i] = -s_new[i]
        out.append((r_new, s_new))
    return out + dip_candidates(resp, nu, T, roots, sign0, small)


def dip_candidates(resp: MultiResponse, nu: np.ndarray, T: float, roots, sign0, small: float = 0.02, limit: int = 4):
    """Structures with a short blip (two switches) where some ``|S_i|`` dips close to zero without crossing.

    The smoothing rounds off the near-tangencies of the optimum's switching
    functions: a blip shorter than the smoothing width shows in the warm
    start as a dip of ``|S_i|``.  Candidates: every such dip at once, then
    each alone (deepest first, at most ``limit``).
    """
    grid = sample_grid(resp, T, density=2.0)
    S = resp.switching_all(nu, grid)[0]
    dips = []
    for i in range(resp.m):
        a = np.abs(S[i])
        peak = float(np.max(a)) or 1.0
        k = np.flatnonzero((a[1:-1] <= a[:-2]) & (a[1:-1] <= a[2:]) & (a[1:-1] <= small * peak)) + 1
        same_sign = np.sign(S[i, k - 1]) == np.sign(S[i, k + 1])
        for kk in k[same_sign]:
            dips.append((float(a[kk]) / peak, i, float(grid[kk])))
    dips.sort()
    dips = dips[:limit]
    if not dips:
        return []
    width = 0.25 * (grid[1] - grid[0])

    def with_blips(chosen):
        r_new = [np.asarray(r, float).copy() for r in roots]
        for _, i, t in chosen:
            r_new[i] = np.sort(np.concatenate([r_new[i], [t - width, t + width]]))
        return r_new, list(sign0)

    out = [with_blips(dips)]
    if len(dips) > 1:
        out += [with_blips([d]) for d in dips]
    return out


def repair(roots: list, sign0: list, T: float, rtol: float = 1e-4):
    """Drop pairs of switches closer than ``rtol T`` and switches within ``rtol T`` of an end; None if none."""
    out_r, out_s, changed = [], [], False
    for r, s0 in zip(roots, sign0):
        r = np.sort(np.asarray(r, float))
        keep = np.ones(r.size, dtype=bool)
        j = 0
        while j < r.size - 1:
            if keep[j] and r[j + 1] - r[j] < rtol * T:
                keep[j] = keep[j + 1] = False
                j += 2
            else:
                j += 1
        s_new = s0
        if r.size and keep[0] and r[0] < rtol * T:  # the first switch (tau near 0, t near T) leaves: sign flips
            keep[0] = False
            s_new = -s0
        if r.size and keep[-1] and r[-1] > T * (1.0 - rtol):
            keep[-1] = False
        changed = changed or not keep.all()
        out_r.append(r[keep])
        out_s.append(s_new)
    return (out_r, out_s) if changed else None


def _corrections(resp, x0, u_max, s, roots, sign0, nuh, T, rho, free_time):
    """Newton from one structure, then structure corrections from the converged zeros.

    Returns ``(extremal or None, last nuh, T, rho, roots)``: the last iterate
    feeds the end candidates when this fails.
    """
    last = (nuh, T, rho, roots)
    for _ in range(MAX_STRUCTURE_UPDATES):
        ok, roots_r, nuh_r, T_r, rho_r, res = refine(resp, x0, u_max, s, roots, sign0, nuh, T, rho, free_time)
        last = (nuh_r, T_r, rho_r, roots_r)
        if not ok:
            # a blip that should not be there collapses (two switches merge) or leaves through an end:
            # drop it and go on from where Newton stopped
            repaired = repair(roots_r, sign0, T_r)
            if repaired is None:
                return None, last
            roots, sign0 = repaired
            nuh, T, rho = nuh_r, T_r, rho_r
            continue
        if repair(roots_r, sign0, T_r, rtol=1e-12) is not None:
            # a blip converged to zero width (inserted narrow, Newton closed it): take the zeros
            # of the switching functions as they are instead
            zeros, zsign0 = structure(resp, nuh_r / s, T_r)
            if all(z.size == r.size for z, r in zip(zeros, roots)) and list(zsign0) == list(sign0):
                return None, last
            roots, sign0 = zeros, zsign0
            nuh, T, rho = nuh_r, T_r, rho_r
            continue
        nu = nuh_r / s
        # nu and -nu vanish at the same switches: take the one whose signs match
        iso_roots, iso_sign0 = structure(resp, nu, T_r)
        agree = sum(1 for i in range(resp.m) if iso_sign0[i] == sign0[i])
        if agree * 2 < resp.m:
            nuh_r = -nuh_r
            nu = -nu
            iso_sign0 = [-v for v in iso_sign0]
        same = True
        for i in range(resp.m):
            tol = root_tolerance(resp.for_input(i), nu, T_r, roots_r[i]) if roots_r[i].size else np.empty(0)
            if not (
                iso_roots[i].size == roots_r[i].size
                and iso_sign0[i] == sign0[i]
                and np.all(np.abs(iso_roots[i] - roots_r[i]) <= tol)
            ):
                same = False
        if same:
            return Extremal(roots_r, list(sign0), nuh_r, T_r, rho_r, res), last
        new_roots, new_sign0 = [], []
        for i in range(resp.m):
            r_i, s_i = updated_structure(roots_r[i], sign0[i], iso_roots[i], iso_sign0[i])
            new_roots.append(np.asarray(r_i, float))
            new_sign0.append(float(s_i))
        roots, sign0, nuh, T, rho = new_roots, new_sign0, nuh_r, T_r, rho_r
    return None, (nuh, T, rho, roots)


def structure_newton(
    resp: MultiResponse, x0, u_max, s, nuh, T, rho: float, free_time: bool, roots=None, sign0=None
) -> Extremal | None:
    """Switch-time Newton from the structure of ``nuh`` at ``T``, with structure updates; None if it fails.

    If the structure of the warm start does not lead to an extremal, structures
    with a short extra switch at an end of the move are tried
    (:func:`end_candidates`), from the warm start and from the last iterate.
    """
    if roots is None:
        roots, sign0 = structure(resp, nuh / s, T)
    ext, last = _corrections(resp, x0, u_max, s, roots, sign0, nuh, T, rho, free_time)
    if ext is not None:
        return ext
    tried = []
    for start_nuh, start_T, start_rho, start_roots, start_sign0 in (
        (nuh, T, rho, roots, sign0),
        (last[0], last[1], last[2], last[3], sign0),
    ):
        for cand_roots, cand_sign0 in end_candidates(resp, start_nuh / s, start_T, start_roots, start_sign0):
            key = (tuple(r.size for r in cand_roots), tuple(cand_sign0))
            if key in tried:
                continue
            tried.append(key)
            ext, _ = _corrections(resp, x0, u_max, s, cand_roots, cand_sign0, start_nuh, start_T, start_rho, free_time)
            if ext is not None:
                return ext
    return None
