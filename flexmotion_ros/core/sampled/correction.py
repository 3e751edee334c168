"""The exact correction of a linear program's sequence: ``G^T u = w`` to rounding, within the bound.

A linear program's solution meets its equality rows only to the solver's
feasibility tolerance; the sampled planners change it least (the least-norm
change of the samples with slack) so that the final state is exact to
rounding, and never past ``u_max``.  Every corrected sequence still goes
through the exact simulation of :func:`.check.verified_samples`.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import qr


def _least_norm_solver(GS: np.ndarray):
    """``r -> du``: the least-norm solution of ``GS^T du = r`` (as ``np.linalg.lstsq``).

    Factorised once (economic QR ``GS = Q R``, then the SVD of the small ``R``)
    so repeated corrections on the same samples cost two small products.  The
    rank cut-off is lstsq's default: ``eps * max(GS.shape) * s_max``.
    """
    if GS.shape[0] > GRAM_ROWS and GS.shape[0] > 64 * GS.shape[1]:
        return _gram_solver(GS)
    Q, R = qr(GS, mode="economic", check_finite=False)
    # thin SVD: with fewer samples than states (a move of a few samples) R is
    # wide, and the full SVD's Vt would have more rows than singular values
    Ur, sv, Vt = np.linalg.svd(R, full_matrices=False)
    keep = sv > np.finfo(float).eps * max(GS.shape) * (sv[0] if sv.size else 0.0)
    QU = (Q @ Ur)[:, keep]
    inv = 1.0 / sv[keep]
    Vk = Vt[keep]
    return lambda r: QU @ (inv * (Vk @ r))


#: Past this many samples (rows) the least-norm change is solved through the ``n x n`` Gram matrix: a QR of
#: a ``K x n`` matrix and its ``Q`` product cost ~0.9 s at 2.4e6 samples (a 40 min move at 1 kHz), two per count.
GRAM_ROWS = 100_000


def _gram_solver(GS: np.ndarray):
    """``r -> du``: the least-norm solution of ``GS^T du = r`` through ``C = GS^T GS`` (``du = GS C^+ r``).

    Squares the condition number (the rank cut-off is ``eps * n`` of ``C``'s largest eigenvalue instead of
    lstsq's ``eps * K`` of the singular values): :func:`_correct_on` refines the residual three times, and
    the result still has to land exactly (:func:`lands_exactly`) and pass the exact simulation.
    """
    lam, V = np.linalg.eigh(GS.T @ GS)
    keep = lam > np.finfo(float).eps * GS.shape[1] * max(float(lam[-1]), 0.0)
    Vk = V[:, keep]
    inv = 1.0 / lam[keep]
    return lambda r: GS @ (Vk @ (inv * (Vk.T @ r)))


def correct_exactly(
    G: np.ndarray, w: np.ndarray, u: np.ndarray, u_max: float, on: np.ndarray | None = None
) -> np.ndarray | None:
    """Make ``G^T u = w`` exact (to rounding) with a least-norm change on samples with slack.

    ``on`` (a boolean mask, optional): change only these samples (the LP's
    free windows: a few per switch, so the factorised matrix is
    ``O(switches) x n`` instead of ``K x n``); None if they are fewer than
    the states.  Without it the change spreads over every sample with slack.
    None also when the change would exceed the bound.
    """
    if on is None:
        return _correct_on(G, w, u, u_max, None)
    if np.count_nonzero(on) < G.shape[1]:
        return None
    return _correct_on(G, w, u, u_max, np.flatnonzero(on))


def exact_candidates(G: np.ndarray, w: np.ndarray, u: np.ndarray, u_max: float, free: np.ndarray):
    """Corrections of an LP point ``u`` to try in turn, computed only when asked for.

    A least-norm correction on the LP's free windows (``O(switches)``
    samples, not ``K``), then on every sample with slack; or, at a degenerate
    vertex (``t* = u_max``, every command saturated, nothing to adjust), the
    LP point itself.
    """
    if not free.all():
        cand = correct_exactly(G, w, u, u_max, on=free)
        if cand is not None:
            yield cand
    cand = correct_exactly(G, w, u, u_max)
    if cand is not None:
        yield cand
    yield np.clip(u, -u_max, u_max)


def lands_exactly(G: np.ndarray, w: np.ndarray, u: np.ndarray) -> bool:
    """``G^T u = w`` to rounding: the test a corrected sequence passes before the exact simulation."""
    return bool(np.max(np.abs(G.T @ u - w)) <= 1e-12 * max(float(np.max(np.abs(w))), 1.0))


def _correct_on(G: np.ndarray, w: np.ndarray, u: np.ndarray, u_max: float, allowed: np.ndarray | None):
    """:func:`correct_exactly` with the change on ``allowed`` sample indices (None: all)."""
    u = np.clip(u, -u_max, u_max)
    S_prev = solve = None
    for _ in range(3):
        r = w - G.T @ u
        slack = u_max - np.abs(u)
        if allowed is None:
            S = np.flatnonzero(slack > 1e-9 * u_max)
            if S.size < G.shape[1]:
                S = np.argsort(-slack)[: max(G.shape[1], 1)]
        else:
            S = allowed[slack[allowed] > 1e-9 * u_max]
            if S.size < G.shape[1]:
                S = allowed[np.argsort(-slack[allowed])[: max(G.shape[1], 1)]]
        if solve is None or not np.array_equal(S, S_prev):  # reuse the factorisation
            # every sample (S is then 0..K-1): G itself, no K x n copy (270 MB at 2.4e6 samples, 14 states)
            solve, S_prev = _least_norm_solver(G if S.size == G.shape[0] else G[S]), S
        du = solve(r)
        u = u.copy()
        u[S] += du
        if np.max(np.abs(u)) > u_max:
            over = np.max(np.abs(u)) - u_max
            if over > 1e-12 * u_max:
                return None
            u = np.clip(u, -u_max, u_max)
    return u
