"""The switch-structure search around the switch-time Newton of :mod:`.newton`.

From the warm start's zeros (every sign change of each active ``S_i``,
isolated with proof), Newton converges to an extremal; if its switching
functions change sign elsewhere the structure was wrong and their zeros
become the new one (:func:`~flexmotion_ros.core.time_optimal.switch_newton.updated_structure`).
When Newton stalls, blips that collapse or leave through an end are dropped
(:func:`repair`); when the warm start's structure leads nowhere, candidates
with a short extra switch at an end (:func:`end_candidates`) or a blip where
some ``|S_i|`` dips near zero (:func:`dip_candidates`) are tried.
"""

from __future__ import annotations

import numpy as np

from ..time_optimal.root_refine import root_tolerance
from ..time_optimal.switch_newton import updated_structure
from ..time_optimal.switching import find_roots, sample_grid
from .newton import Extremal, Setting, refine
from .response import MultiResponse

MAX_STRUCTURE_UPDATES = 6


def structure(resp: MultiResponse, nu: np.ndarray, T: float, active=None):
    """Per input: sign changes of ``S_i`` on ``(0, T)`` (time-to-go) and its first sign (inactive: none, 0)."""
    grid = sample_grid(resp, T)
    roots, sign0 = [], []
    for i in range(resp.m):
        if active is not None and not active[i]:
            roots.append(np.empty(0))
            sign0.append(0.0)
            continue
        r, s0 = find_roots(resp.for_input(i), nu, T, grid)
        roots.append(r)
        sign0.append(float(s0))
    return roots, sign0


def end_candidates(resp: MultiResponse, nu: np.ndarray, T: float, roots, sign0, active, small: float = 0.02):
    """Structures with a short extra switch at an end of the move, for inputs whose ``|S_i|`` is small there.

    A nearly singular input (its ``S_i`` tiny against the others) often ends
    or starts with a blip far shorter than the smoothing can resolve: ``S_i``
    just touches zero at ``t = 0`` or ``t = T`` in the warm start.  Then the
    dip candidates (:func:`dip_candidates`).
    """
    ends = resp.switching_all(nu, np.array([0.0, T]))[0]  # (m, 2): tau = 0 (t = T), tau = T (t = 0)
    grid = sample_grid(resp, T)
    peak = np.max(np.abs(resp.switching_all(nu, grid)[0]), axis=1)
    idx = [i for i in range(resp.m) if active[i]]
    near_T = [i for i in idx if abs(ends[i, 1]) <= small * peak[i]]
    near_0 = [i for i in idx if abs(ends[i, 0]) <= small * peak[i]]
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
    return out + dip_candidates(resp, nu, T, roots, sign0, active, small)


def dip_candidates(resp: MultiResponse, nu: np.ndarray, T: float, roots, sign0, active, small=0.02, limit: int = 4):
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
        if not active[i]:
            continue
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


def _corrections(resp, x0, u_max, s, roots, sign0, nuh, T, rho, free_time, setting: Setting):
    """Newton from one structure, then structure corrections from the converged zeros.

    Returns ``(extremal or None, (nuh, T, rho, roots))``: the last iterate
    feeds the candidates when this fails.
    """
    act = setting.active
    last = (nuh, T, rho, roots)
    for _ in range(MAX_STRUCTURE_UPDATES):
        ok, roots_r, nuh_r, T_r, rho_r, res = refine(resp, x0, u_max, s, roots, sign0, nuh, T, rho, free_time, setting)
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
            zeros, zsign0 = structure(resp, nuh_r / s, T_r, act)
            if all(z.size == r.size for z, r in zip(zeros, roots)) and list(zsign0) == list(sign0):
                return None, last
            roots, sign0 = zeros, zsign0
            nuh, T, rho = nuh_r, T_r, rho_r
            continue
        nu = nuh_r / s
        # nu and -nu vanish at the same switches: take the one whose signs match
        iso_roots, iso_sign0 = structure(resp, nu, T_r, act)
        idx = [i for i in range(resp.m) if act[i]]
        agree = sum(1 for i in idx if iso_sign0[i] == sign0[i])
        if agree * 2 < len(idx):
            nuh_r = -nuh_r
            nu = -nu
            iso_sign0 = [-v for v in iso_sign0]
        same = True
        for i in idx:
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
            if not act[i]:
                new_roots.append(np.empty(0))
                new_sign0.append(0.0)
                continue
            r_i, s_i = updated_structure(roots_r[i], sign0[i], iso_roots[i], iso_sign0[i])
            new_roots.append(np.asarray(r_i, float))
            new_sign0.append(float(s_i))
        roots, sign0, nuh, T, rho = new_roots, new_sign0, nuh_r, T_r, rho_r
    return None, (nuh, T, rho, roots)


def structure_newton(
    resp: MultiResponse,
    x0,
    u_max,
    s,
    nuh,
    T,
    rho: float,
    free_time: bool,
    roots=None,
    sign0=None,
    setting: Setting | None = None,
) -> Extremal | None:
    """Switch-time Newton from the structure of ``nuh`` at ``T``, with structure updates; None if it fails.

    If the structure of the warm start does not lead to an extremal, the
    candidates of :func:`end_candidates` are tried, from the warm start and
    from the last iterate.
    """
    setting = setting or Setting.full(resp.m)
    if roots is None:
        roots, sign0 = structure(resp, nuh / s, T, setting.active)
    ext, last = _corrections(resp, x0, u_max, s, roots, sign0, nuh, T, rho, free_time, setting)
    if ext is not None:
        return ext
    tried = []
    for start_nuh, start_T, start_rho, start_roots in ((nuh, T, rho, roots), last):
        for cand_roots, cand_sign0 in end_candidates(resp, start_nuh / s, start_T, start_roots, sign0, setting.active):
            key = (tuple(r.size for r in cand_roots), tuple(cand_sign0))
            if key in tried:
                continue
            tried.append(key)
            ext, _ = _corrections(
                resp, x0, u_max, s, cand_roots, cand_sign0, start_nuh, start_T, start_rho, free_time, setting
            )
            if ext is not None:
                return ext
    return None
