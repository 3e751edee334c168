"""A co-state for a given bang-bang profile with the largest sign margin (one small LP).

When a profile has fewer switches than the state has dimensions minus one,
the co-states ``nu`` whose switching function ``S(tau) = nu^T e^{A tau} B``
vanishes at its switches form a subspace of dimension above one, and the
planner's Newton returns one of them, not necessarily one whose sign
matches the profile everywhere: its ``S`` may, for instance, be tiny near
the end and change sign there, which the certificate cannot count as a
proof (:func:`~.certificate.end_gap`).  Another member of the subspace may
certify the same profile with a clear margin.  This module finds the member
that maximizes the smallest signed value ``sign_k S(tau) / w(tau)`` over
samples of every interval (``w``: how much ``S`` can be expected there, zero
at a switch), by :func:`~flexmotion_ros.core.linear_program.solve_lp`.  Whatever it returns is
only a candidate: the certificate checks it like any other.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import null_space

from ..linear_program import LpStatus, solve_lp

#: Samples per interval of the profile (and on a geometric scale in the last one).
SAMPLES = 24


def widest_costate(
    system, T: float, switch_times: np.ndarray, levels: np.ndarray, extra_tau: np.ndarray | None = None
) -> np.ndarray | None:
    """A co-state direction ``nu`` (time-to-go convention of ``system.switching``) for the profile, or None.

    Parameters
    ----------
    system : ModalResponse (or compatible)
        The linear system (``switching`` linear in ``nu``, ``n`` states).
    T : float
        Duration (s).
    switch_times, levels : ndarray
        The profile (forward time, s; levels ``+-u_max``).
    extra_tau : ndarray, optional
        More samples (time-to-go, s), e.g. where a previous answer's ``S``
        changed sign between the regular samples (a dip narrower than their
        spacing): cutting planes.

    Returns
    -------
    ndarray or None
        ``nu`` with ``S = 0`` at every switch and ``sgn S`` equal to the
        level's sign at every sample, with the largest margin; None if no
        such ``nu`` exists on the samples (or the LP fails).
    """
    n = int(system.n)
    tau_sw = np.sort(T - np.asarray(switch_times, float))
    sign_tau = np.sign(np.asarray(levels, float))[::-1]  # sign of S on each time-to-go interval
    edges = np.concatenate([[0.0], tau_sw, [T]])
    pts, sgn, wt = [], [], []
    for k in range(edges.size - 1):
        a, b = edges[k], edges[k + 1]
        if not b > a:
            continue
        s = np.linspace(0.0, 1.0, SAMPLES + 2)[1:-1]
        if extra_tau is not None:
            inside = (extra_tau - a) / (b - a)
            s = np.concatenate([s, inside[(inside > 0.0) & (inside < 1.0)]])
        tau = a + (b - a) * s
        # S grows from a switch like the distance to it: weight the margin so
        w = np.minimum(s if k > 0 else np.ones_like(s), 1.0 - s if k < edges.size - 2 else np.ones_like(s))
        if k == 0:  # the last interval (time-to-go from 0): down to tiny tau
            g = np.geomspace(1e-9, 1.0, SAMPLES) * (b - a) * 0.5
            tau, w = np.concatenate([tau, g]), np.concatenate([w, np.minimum(1.0, 1.0 - g / (b - a))])
        pts.append(tau)
        sgn.append(np.full(tau.size, sign_tau[k]))
        wt.append(w)
    tau = np.concatenate(pts)
    eye = np.eye(n)
    Bt = np.stack([system.switching(eye[i], tau) for i in range(n)], axis=1)  # S = Bt @ nu
    Bs = np.stack([system.switching(eye[i], tau_sw) for i in range(n)], axis=1) if tau_sw.size else np.zeros((0, n))
    col = np.max(np.abs(Bt), axis=0)
    col[col == 0.0] = 1.0
    Bt, Bs = Bt / col, Bs / col
    N = null_space(Bs) if Bs.shape[0] else eye
    if N.shape[1] == 0:
        return None
    G = (np.concatenate(sgn) / np.concatenate(wt).clip(1e-300))[:, None] * (Bt @ N)  # rows: sign * S / w
    m = N.shape[1]
    # maximize t subject to G c >= t, |c_i| <= 1
    c_obj = np.zeros(m + 1)
    c_obj[-1] = -1.0
    A_ub = np.hstack([-G, np.ones((G.shape[0], 1))])
    lower = np.full(m + 1, -1.0)
    lower[-1] = -np.inf
    if not np.isfinite(A_ub).all():
        return None
    res = solve_lp(cost=c_obj, A_ub=A_ub, b_ub=np.zeros(G.shape[0]), lower=lower, upper=1.0)
    if res.status is not LpStatus.OPTIMAL or not res.x[-1] > 0.0:
        return None
    return (N @ res.x[:m]) / col
