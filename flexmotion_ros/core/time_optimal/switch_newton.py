"""Newton on switch times for a fixed switch structure, with structure correction.

Given a guess of the switch structure (number of switches, first level),
the final-state conditions are smooth functions of the switch times and the
duration, and Pontryagin's condition says the switching function vanishes
at each switch: one square system in ``(tau_1..tau_L, nu, T)`` for any ``L``,
solved by Newton's method with closed-form derivatives.  If the converged
co-state's switching function changes sign elsewhere too, the structure was
wrong; its zeros become the new structure.
"""

from __future__ import annotations

import numpy as np

from ..tolerances import GAP_RTOL, POLISH_TOL
from .reachable_set import Shooting
from .root_refine import root_tolerance
from .switching import find_roots, root_grid

#: Switch-structure corrections tried before giving up.
MAX_STRUCTURE_UPDATES = 5
#: Up to this many switches the Newton system is solved whole (LU with
#: pivoting: robust when a cluster makes S' tiny); beyond, by elimination.
DENSE_UP_TO = 200
#: A Newton run stopped by a step below the rounding of the times has
#: converged if its residual is within this many rounding units of the
#: times (``eps T``) times the largest slope of the residual.
ROUNDING_FLOOR = 64.0
#: Neighbouring switches closer than this (relative to ``T``) that a Newton
#: step carries past each other are a merging pair (``structure_guess.MERGE_RTOL``'s
#: value: the pair its caller would remove after the run).
MERGE_RTOL = 1e-3
#: ... once the same pair has blocked this many full steps in a row (a pair
#: crossing once may part again: merged at the first crossing, fuzz cases 1057
#: and 2336 went from the fast path to the full solver; at 3, none of 0..2499).
MERGE_AFTER = 3
#: With ``merge``, a run whose residual falls by less than this fraction in
#: :data:`CRAWL_STEPS` steps in a row stops unconverged (its caller edits the
#: structure): damped steps of 1/256 .. 1/2048 crawled through all 30 steps
#: (fuzz case 544: 4 such runs, half of its fast path's time).
CRAWL_DECREASE = 0.01
CRAWL_STEPS = 5


def refine_switches(
    sh: Shooting,
    roots: np.ndarray,
    sign0: float,
    nuh: np.ndarray,
    T: float,
    max_iter: int = 30,
    merge: bool = False,
):
    """Newton on switch times, co-state and duration together, for a fixed switch structure.

    Unknowns ``(tau_1..tau_L, nu, T)``; equations: final state zero (n),
    switching function zero at each switch (L), one normalisation of ``nu``.
    Square for any ``L``; all derivatives in closed form, no root finding.

    ``merge``: when full Newton steps would carry the same pair of neighbouring
    switches closer than :data:`MERGE_RTOL` ``T`` past each other
    :data:`MERGE_AFTER` times in a row, the pair is merging (a blip shrinking to nothing): it is removed and Newton goes
    on with ``L - 2`` switches (the first level unchanged; the returned
    ``roots`` then has that size).  Without it the step is halved until the
    pair stays ordered, and the run crawls (fuzz case 2380: 24 halved steps;
    544: 30 steps without converging, then the same pair removed by the caller).
    With ``merge`` a run that crawls for :data:`CRAWL_STEPS` steps also stops
    (unconverged): the structure search, not halving, moves on.

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
    floor = 0.0  # the residual that rounding the times alone leaves (see below)
    eps = np.finfo(float).eps
    blocked, blocked_pair = 0, None  # steps in a row whose full length the same pair of switches blocked
    crawled = 0  # steps in a row that reduced the residual by less than CRAWL_DECREASE
    for it in range(max_iter):
        if rn <= 16.0 * eps:
            break
        fT = (sys.A_x(eAx) + um * signs[-1] * sys.expm_B(np.array([T]))[0]) / s
        dS = sys.switching(nuh / s, tau, derivative=True)[1] if L else np.zeros(0)
        step = _newton_step(g * jump[:, None], fT, dS * gscale, g * gscale, anchor, r, n, L)
        if np.max(np.abs(np.append(step[:L], step[-1]))) <= 4.0 * eps * T:
            # converged: the step is below rounding of the times.  The plan's
            # switch times are ``T - tau`` (absolute precision eps T), so the
            # residual cannot be pushed below what a change of the times by
            # that much makes: on a 2000 s move of a 60 rad/s mode about 3e-11,
            # over POLISH_TOL (the certified optimum was refused and searched
            # again, 0.4 s).  The exact check and the certificate decide as ever.
            slopes = np.abs(fT)
            if L:
                slopes = np.concatenate([slopes, np.abs(g * jump[:, None]).ravel(), np.abs(dS * gscale)])
            floor = ROUNDING_FLOOR * eps * T * float(np.max(slopes))
            break
        k = merging_pair(tau, step[:L], T) if merge else None
        blocked = blocked + 1 if k is not None and k == blocked_pair else int(k is not None)
        blocked_pair = k
        if blocked >= MERGE_AFTER and it + 1 < max_iter:
            return refine_switches(sh, np.delete(tau, [k, k + 1]), sign0, nuh, T, max_iter - it - 1, merge)
        accepted = damped_step(tau, nuh, T, step, rn, residual)
        if accepted is None:
            break
        crawled = crawled + 1 if merge and accepted[-1] > (1.0 - CRAWL_DECREASE) * rn else 0
        tau, nuh, T, r, g, eAx, rn = accepted
        if crawled >= CRAWL_STEPS:  # halved steps that barely move: this structure is not converging
            break
    if L:  # nu and -nu both vanish at the switches: take the one whose signs match
        first = 0.5 * tau[0]
        if np.sign(sys.switching(nuh / s, np.array([first]))[0]) != sign0:
            nuh = -nuh
    return rn <= max(POLISH_TOL, floor), tau, nuh, T, rn


def merging_pair(tau: np.ndarray, dtau: np.ndarray, T: float) -> int | None:
    """Index ``k`` of the one pair ``(tau_k, tau_k+1)`` (s) that the full step ``dtau`` carries past each other, or None.

    Only a pair closer than ``MERGE_RTOL T`` counts, and only if it is the
    step's one crossing, with the first switch still after ``tau = 0`` (a
    switch leaving there would change the first level).
    """
    if tau.size < 2:
        return None
    new = tau + dtau
    crossed = np.flatnonzero(np.diff(new) <= 0.0)
    if crossed.size != 1 or new[0] <= 0.0:
        return None
    k = int(crossed[0])
    return k if tau[k + 1] - tau[k] <= MERGE_RTOL * T else None


def damped_step(
    tau: np.ndarray, nuh: np.ndarray, T: float, step: np.ndarray, rn: float, residual, halvings: int = 12
) -> tuple | None:
    """The Newton ``step`` on (switch times ``tau``, co-state ``nuh``, ``T``), halved until the residual drops.

    A candidate must keep ``0 < tau_1 < ... < tau_L < T``; ``residual(tau, nu, T)`` returns ``(r, g, extra)``.
    Converged to within ``POLISH_TOL``: one more full step if it helps, no line search.  Returns
    ``(tau, nu, T, r, g, extra, |r|_inf)`` of the accepted point, or None if none of the step and its
    ``halvings - 1`` halvings improves on ``rn``.
    """
    L, n = tau.size, nuh.size
    t = 1.0
    for _ in range(halvings if rn > POLISH_TOL else 1):
        tau_c = tau + t * step[:L]
        T_c = T + t * float(step[-1])
        nu_c = nuh + t * step[L : L + n]
        if T_c > 0.0 and (L == 0 or (tau_c[0] > 0.0 and tau_c[-1] < T_c and np.all(np.diff(tau_c) > 0.0))):
            r_c, g_c, extra_c = residual(tau_c, nu_c, T_c)
            rn_c = float(np.max(np.abs(r_c)))
            if rn_c < rn:
                return tau_c, nu_c, T_c, r_c, g_c, extra_c, rn_c
        t *= 0.5
    return None


def _newton_step(Gj, fT, D, Gs, anchor, r, n: int, L: int) -> np.ndarray:
    """Solve the arrow-shaped Newton system of :func:`refine_switches`.

    Unknowns ``(dtau (L), dnu (n), dT)``; rows: final state ``Gj^T dtau + fT dT``
    (n), switch conditions ``D dtau + Gs dnu`` (L, ``D`` diagonal), and the
    normalisation ``anchor . dnu``.  Eliminating ``dtau`` leaves an
    ``(n+1) x (n+1)`` system, so the cost is ``O(L n^2)``: optima with
    thousands of switches (a weak actuator killing a large vibration) stay cheap.
    """
    rF, rS, ra = r[:n], r[n : n + L], r[-1]
    if 0 < L <= DENSE_UP_TO:
        return _dense_step(Gj, fT, D, Gs, anchor, r, n, L)
    scale = float(np.max(np.abs(D))) if L else 1.0
    if L == 0 or np.min(np.abs(D)) > 1e-12 * scale:
        Dinv = 1.0 / D if L else np.zeros(0)
        A = Gj.T  # (n, L)
        M = -(A * Dinv) @ Gs if L else np.zeros((n, n))
        K = np.zeros((n + 1, n + 1))
        K[:n, :n] = M
        K[:n, n] = fT
        K[n, :n] = anchor
        rhs = np.concatenate([-rF + (A @ (Dinv * rS) if L else 0.0), [-ra]])
        try:
            sol = np.linalg.solve(K, rhs)
        except np.linalg.LinAlgError:
            sol, *_ = np.linalg.lstsq(K, rhs, rcond=None)
        dnu, dT = sol[:n], sol[n]
        dtau = Dinv * (-rS - Gs @ dnu) if L else np.zeros(0)
        return np.concatenate([dtau, dnu, [dT]])
    if L > 2000:
        return np.zeros(L + n + 1)  # a tangency among thousands of switches: give up
    return _dense_step(Gj, fT, D, Gs, anchor, r, n, L)


def _dense_step(Gj, fT, D, Gs, anchor, r, n: int, L: int) -> np.ndarray:
    """The same Newton system solved whole (pivoting copes with clustered switches, S' ~ 0)."""
    J = np.zeros((n + L + 1, L + n + 1))
    J[:n, :L] = Gj.T
    J[:n, -1] = fT
    J[n : n + L, :L] = np.diag(D)
    J[n : n + L, L : L + n] = Gs
    J[-1, L : L + n] = anchor
    try:
        return np.linalg.solve(J, -r)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(J, -r, rcond=None)[0]


def structure_newton(
    sh: Shooting, nuh: np.ndarray, T: float, roots=None, sign0: float = 1.0, T_low: float = 0.0, max_iter: int = 30
):
    """Switch-time Newton from the switch structure of ``nuh`` at ``T``, with structure updates.

    ``roots``/``sign0``: the structure if already known for ``nuh`` at ``T``.
    ``T_low``: a proved lower bound on the optimal time.  ``max_iter``: Newton steps per structure.
    Returns ``(nuh, T, roots, signs, residual)`` of a converged extremal (its
    switching function changes sign exactly at its switches), or None.
    """
    if roots is None:
        roots, sign0 = find_roots(sh.sys, nuh / sh.s, T, root_grid(sh.sys, T))
    nuh_r, T_r = nuh, T
    for _ in range(MAX_STRUCTURE_UPDATES):
        ok, roots_r, nuh_r, T_r, r = refine_switches(sh, roots, sign0, nuh_r, T_r, max_iter)
        if not ok:
            return None
        # an extremal switches exactly where S changes sign; if S changes sign
        # elsewhere too, the structure was wrong: adopt S's zeros and refine again
        iso_roots, iso_sign0 = find_roots(sh.sys, nuh_r / sh.s, T_r, root_grid(sh.sys, T_r))
        if (
            iso_roots.size == roots_r.size
            and iso_sign0 == sign0
            and np.all(np.abs(iso_roots - roots_r) <= root_tolerance(sh.sys, nuh_r / sh.s, T_r, roots_r))
        ) or T_r - T_low <= GAP_RTOL * T_r:
            # (or within rounding of a proved lower bound: optimal whatever the
            # sign test says, e.g. in a cluster of switches below rounding)
            signs = sign0 * (1.0 - 2.0 * (np.arange(roots_r.size + 1) % 2))
            return nuh_r, T_r, roots_r, signs, r
        roots, sign0 = updated_structure(roots_r, sign0, iso_roots, iso_sign0)
    return None


def updated_structure(roots: np.ndarray, sign0: float, zeros: np.ndarray, zsign0: float):
    """The switch structure to try after a converged but wrong one.

    New sign changes of ``S`` come in pairs (a dip through zero): keep the
    converged switches and insert each new pair as a *narrow* blip at its
    middle (a tenth of its width), so that the profile, and with it the
    final state, barely changes and Newton starts close.  Otherwise (a pair
    vanished, or no clean pairing) take the zeros as they are.
    """
    pairs = new_pairs(roots, sign0, zeros, zsign0)
    if pairs is None:
        return zeros, zsign0
    a, b = pairs
    mid, half = 0.5 * (a + b), 0.05 * (b - a)
    return np.sort(np.concatenate([roots, mid - half, mid + half])), sign0


def new_pairs(roots: np.ndarray, sign0: float, zeros: np.ndarray, zsign0: float):
    """The sign changes ``zeros`` (s) has beyond ``roots`` (s), as adjacent pairs ``(a, b)``, or None.

    None when they do not pair cleanly: a different first sign, no more
    zeros than switches, an odd surplus, or new zeros not adjacent in pairs.
    """
    if zsign0 != sign0 or zeros.size <= roots.size or (zeros.size - roots.size) % 2:
        return None
    k = np.clip(np.searchsorted(roots, zeros), 1, max(roots.size, 1)) - 1
    near = np.zeros(zeros.size, dtype=bool)
    if roots.size:
        d = np.minimum(np.abs(zeros - roots[k]), np.abs(zeros - roots[np.minimum(k + 1, roots.size - 1)]))
        gaps = np.diff(np.concatenate([[0.0], roots]))
        near = d <= 1e-3 * max(float(np.min(gaps[gaps > 0.0], initial=1.0)), 1e-12)
    new = zeros[~near]
    if new.size != zeros.size - roots.size:
        return None
    idx = np.flatnonzero(~near)
    if np.any(np.diff(idx)[::2] != 1):  # new zeros are not adjacent pairs
        return None
    return new[::2], new[1::2]


def primal_newton(sh: Shooting, roots: np.ndarray, sign0: float, T: float, max_iter: int = 40):
    """Newton on the final-state conditions alone, in the switch times and ``T`` (no co-state).

    For a cluster of switches closer than the switching function can resolve
    (its sign inside the cluster is below rounding, so the co-state equations
    of :func:`refine_switches` cannot be met to ``POLISH_TOL``), while the
    final state is still a smooth, well-scaled function of the switch times.
    Unknowns ``(tau_1..tau_L, T)``, equations ``x(T) = 0`` (``n``): the
    least-norm Newton step when ``L + 1 != n``, with backtracking.  The
    result says nothing about optimality: the caller certifies it (by the gap
    to a proved lower bound).

    Returns ``(ok, roots, T, residual)``: ``ok`` when the scaled final state
    is below ``POLISH_TOL`` with the switches inside ``(0, T)`` and ordered.
    """
    sys, s, um = sh.sys, sh.s, sh.u_max
    L = roots.size
    signs = sign0 * (1.0 - 2.0 * (np.arange(L + 1) % 2))
    jump = 2.0 * um * signs[:-1]

    def final(tau, T):
        G = sys.input_integral(np.append(tau, T))
        eAx = sys.expm_x(T, sh.x0)
        return (eAx + um * signs[-1] * G[-1] + jump @ G[:-1]) / s, eAx

    def valid(tau, T):
        return T > 0.0 and (L == 0 or (tau[0] > 0.0 and tau[-1] < T and np.all(np.diff(tau) > 0.0)))

    tau, F, eAx = roots.copy(), *final(roots, T)
    rn = float(np.max(np.abs(F)))
    for _ in range(max_iter):
        if rn <= 16.0 * np.finfo(float).eps:
            break
        J = np.empty((s.size, L + 1))
        if L:
            J[:, :L] = (sys.expm_B(tau) * jump[:, None]).T / s[:, None]
        J[:, L] = (sys.A_x(eAx) + um * signs[-1] * sys.expm_B(np.array([T]))[0]) / s
        step = np.linalg.lstsq(J, -F, rcond=None)[0]
        t = 1.0
        for _ in range(12):
            tau_c, T_c = tau + t * step[:L], T + t * step[L]
            if valid(tau_c, T_c):
                F_c, eAx_c = final(tau_c, T_c)
                rn_c = float(np.max(np.abs(F_c)))
                if rn_c < rn:
                    break
            t *= 0.5
        else:
            break
        tau, T, F, eAx, rn = tau_c, T_c, F_c, eAx_c, rn_c
    return rn <= POLISH_TOL and valid(tau, T), tau, T, rn


def split_candidates(roots: np.ndarray, sign0: float, T: float, widths=(1e-4, 1e-3, 1e-2)):
    """Structures with one switch split into a tight triple (a notch), flattest-first order is the caller's.

    Near a structure whose move time is a multiple of a mode's period (the
    rigid optimum nearly leaves a mode at rest), the optimum grows a narrow
    notch at a switch: three switches within ``~|detuning|`` of each other,
    whose switching-function sign is below rounding.  Yields ``(roots, sign0)``
    for each switch and each half-width (relative to ``T``).
    """
    for j in range(roots.size):
        for w in widths:
            d = w * T
            trio = np.array([roots[j] - d, roots[j], roots[j] + d])
            cand = np.sort(np.concatenate([np.delete(roots, j), trio]))
            if cand[0] > 0.0 and cand[-1] < T and np.all(np.diff(cand) > 0.0):
                yield cand, sign0
