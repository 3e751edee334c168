"""A lower bound on the optimal time by weak duality, proved from one co-state direction.

For any ``nu`` and ``T' > 0``, every input with ``|u| <= u_max`` reaches from
``x0`` at ``T'`` a state ``x`` with ``nu^T x <= nu^T e^{A T'} x0 + h_{T'}(nu)``,
``h_{T'}(nu) = u_max int_0^T' |S(tau)| dtau``, ``S(tau) = nu^T e^{A tau} B``.
So if ``nu^T w > h_{T'}(nu)`` with ``w = -e^{A T'} x0``, no input brings
``x0`` to rest at ``T'``, nor sooner (the sets that can be steered to rest
grow with the time).  The co-state of a bang-bang extremal makes this
inequality tight at its own ``T``; a little below it, it holds with a margin
of the order of ``dT`` that does not depend on how well the sign of ``S`` is
resolved inside a cluster of switches (where ``S`` is at rounding, it adds
nothing to the integral).  That is where the Pontryagin sign test cannot
decide: a notch of switches a microsecond wide.

The integral is bounded from above with proof: on each interval of the
profile (sign ``sigma``), ``int |S| = int sigma S + 2 int (sigma S)^-``; the
first term in closed form (:meth:`input_integral`), the second by samples
and the bound on ``|S''|`` (on a cell, ``sigma S`` is at least the smaller
end value minus ``|S''| h^2 / 8``), cells refined where that bound is
positive, plus the rounding of every term.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import null_space

from ..tolerances import GAP_RTOL

#: Uniform samples per interval of the profile, plus a geometric grading towards its ends.
SAMPLES = 64
#: Bisections of the cells where the sampled bound of ``(sigma S)^-`` is positive.
REFINEMENTS = 6
#: Rounding allowance, in units of ``eps`` times the magnitudes of the terms.
ROUNDING = 64.0


#: Relative gaps below ``T`` tried by :func:`proved_lower_bound` by default: the certificate's only.
CERTIFY_GAPS = (0.5 * GAP_RTOL,)
#: ... and for the bound an uncertified profile reports (the first one proved, smallest first).
REPORT_GAPS = (0.5 * GAP_RTOL, 1e-6, 1e-4, 1e-3, 1e-2, 3e-2, 0.1, 0.3)


def proved_lower_bound(
    system, x0: np.ndarray, u_max: float, T: float, switch_times, levels, gaps: tuple[float, ...] = CERTIFY_GAPS
) -> tuple[float, np.ndarray] | None:
    """``T (1 - g)`` (s) for the first ``g`` of ``gaps`` at which no move reaches rest, and the co-state; else None.

    The co-state direction is that of the profile's switches: the null
    direction of ``S = 0`` at every switch (the extremal's, when there is
    one), oriented by the profile's first level; any direction would give a
    valid bound, this one a tight one.

    Parameters
    ----------
    system : ModalResponse (or compatible)
        The linear system in time-to-go form (``switching``, ``input_integral``,
        ``expm_x``, ``switching_magnitude``, ``switching_derivative_bounds``).
    x0 : ndarray
        Initial state in the system's coordinates (the target at the origin).
    u_max : float
        Input bound.
    T : float
        The profile's duration (s).
    switch_times, levels : ndarray
        The profile (forward time, s; levels ``+-u_max``).
    gaps : tuple of float
        Relative distances below ``T`` to try, smallest first.
    """
    n = int(system.n)
    tau_sw = np.sort(T - np.asarray(switch_times, float))
    sign_tau = np.sign(np.asarray(levels, float))[::-1]
    eye = np.eye(n)
    if tau_sw.size:
        rows = np.stack([system.switching(eye[i], tau_sw) for i in range(n)], axis=1)
        col = np.max(np.abs(rows), axis=0)
        col[col == 0.0] = 1.0
        if not np.all(np.isfinite(rows / col)):
            return None
        N = null_space(rows / col, rcond=0.0)
        nu = (N[:, -1] if N.shape[1] else np.linalg.svd(rows / col)[2][-1]) / col
    else:
        nu = eye[n - 1].copy()  # no switch: any direction is a bound; the velocity-like state's
    if not np.all(np.isfinite(nu)) or not np.any(nu):
        return None
    for gap in gaps:
        T_proved = T * (1.0 - gap)
        for cand in (nu, -nu):
            if _infeasible(system, np.asarray(x0, float), u_max, T_proved, cand, tau_sw, sign_tau):
                return T_proved, cand
    return None


def _infeasible(system, x0, u_max, T1, nu, tau_sw, sign_tau) -> bool:
    """Whether ``nu^T w(T1) > h_{T1}(nu)`` with proof (an upper bound of ``h``, rounding allowed for)."""
    eAx = system.expm_x(T1, x0)
    lhs = -float(nu @ eAx)
    eps = np.finfo(float).eps
    magnitude = float(system.switching_magnitude(nu, T1)[0])
    d2 = float(system.switching_derivative_bounds(nu, T1)[1])
    edges = np.concatenate([[0.0], tau_sw[tau_sw < T1], [T1]])
    signs = sign_tau[: edges.size - 1]
    G = system.input_integral(edges)
    closed = float(np.sum(signs * np.diff(G @ nu)))  # int sigma S, interval by interval
    wrong = 0.0  # an upper bound of int (sigma S)^-
    for k in range(edges.size - 1):
        a, b = edges[k], edges[k + 1]
        if not b > a:
            continue
        s = np.unique(np.concatenate([np.linspace(0.0, 1.0, SAMPLES + 1), np.geomspace(1e-12, 0.5, 40)]))
        s = np.unique(np.concatenate([s, 1.0 - s]))
        x = a + (b - a) * s
        for level in range(REFINEMENTS + 1):
            v = signs[k] * system.switching(nu, x) - ROUNDING * eps * magnitude
            h = np.diff(x)
            low = np.minimum(v[:-1], v[1:]) - d2 * h * h / 8.0  # sigma S on each cell is at least this
            bad = low < 0.0
            if not np.any(bad) or level == REFINEMENTS:
                wrong += float(np.sum(h[bad] * -low[bad]))
                break
            x = np.unique(np.concatenate([x, 0.5 * (x[:-1] + x[1:])[bad]]))
    h_upper = u_max * (closed + 2.0 * wrong + ROUNDING * eps * magnitude * T1)
    lhs_rounding = ROUNDING * eps * float(np.abs(nu) @ np.abs(eAx))
    return lhs - lhs_rounding > h_upper
