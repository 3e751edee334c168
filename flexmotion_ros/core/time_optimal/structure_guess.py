"""Fast path of the time-optimal planner: guess a switch structure, Newton, certify.

The full solver (:func:`~flexmotion_ros.core.time_optimal.costate_solver.solve_costate`) reaches the
switch structure through the *exact* convex inner problem (proved root
isolation at every trust-region step), which dominates its cost.  Most moves
do not need it: the sign changes of the switching function of the *smoothed*
inner problem's co-state (the warm start the full solver computes anyway)
already give the structure, or one a simple edit away from it.  This module
runs the switch-time Newton
(:func:`~flexmotion_ros.core.switch_newton.refine_switches`) from there and
hands every converged extremal to a check (the planner's exact simulation and
Pontryagin certificate), with structure edits:

* a converged extremal whose switching function changes sign elsewhere too
  (the certificate's proved zeros) gets those zeros, as in
  :func:`~flexmotion_ros.core.switch_newton.structure_newton`;
* a Newton run that fails because two neighbouring switches merge (a
  spurious pair from a near-tangency of the smoothed switching function), or
  because a switch leaves ``(0, T)``, restarts without them.

Nothing here is trusted: only what the check accepts is returned, and the
caller runs the full solver otherwise.  So the fast path can only make the
planner faster, never less certified.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .reachable_set import Shooting
from .switch_newton import new_pairs, refine_switches, updated_structure
from .switching import root_grid, sample_grid
from .zero_free import examined_points

#: Newton runs (first structure + edits) before the fast path gives up.
MAX_TRIES = 4
#: Extra Newton runs for structures with a pulse in one dip only (:func:`one_dip_structures`),
#: when the edits of :data:`MAX_TRIES` find nothing.
MAX_ALTERNATIVES = 8
#: Points sampled inside a dip of ``S`` to measure how deep it goes.
DIP_SAMPLES = 5
#: Two structures with the same first sign and number of switches, every
#: switch within this (relative to ``T``) of the other's, are the same one.
SAME_RTOL = 1e-3
#: Two switches closer than this (relative to ``T``) where a Newton run
#: failed are taken as a spurious pair merging.
MERGE_RTOL = 1e-3
#: Two neighbouring switches of a converged Newton run closer than this (relative to ``T``) are one
#: point: a pulse of zero width (to rounding), dropped before the candidate is certified.  A run that
#: converged with a pair collapsed onto a switch (gaps of 1e-16 T: the 3-mode 1 s move of
#: ``bench/planner_latency.py``) otherwise cost a failed certificate, whose zeros then gave the same
#: structure without the pair.
COINCIDENT_RTOL = 1e-12
#: Two converged extremals with the same first sign and number of switches, every switch and ``T``
#: within this (relative to ``T``) of the other's, are the same candidate: one rejected by the check
#: is not checked again (Newton runs from different structures often converge to it: fuzz case 1446,
#: 7 modes, certified the same 15-switch extremal 8 times, 6 ms each, from the one-dip alternatives).
SAME_EXTREMAL_RTOL = 1e-8
#: Sampling density of the structure guess (times the planners' grid).
GRID_DENSITY = 4.0
#: Guess on :func:`~.switching.root_grid` (graded by the modes still ringing; False: the uniform grid).
GRADED_GUESS = True
#: A local minimum of ``|S|`` below this fraction of its maximum is a near-zero.
NEAR_ZERO = 1e-2
#: ... and below this, one even if the switches are not too few.
VERY_NEAR_ZERO = 1e-3

#: ``check(nuh, T, roots, signs) -> (accepted, zeros, sign0)``: ``accepted`` is
#: the certified result or None; then ``zeros`` (time-to-go, s) and ``sign0``
#: are the proved sign changes of the candidate's switching function and its
#: first sign, or ``zeros`` is None if the candidate failed for another reason.
Check = Callable[[np.ndarray, float, np.ndarray, np.ndarray], tuple[object | None, np.ndarray | None, float]]


def newton_from_guess(
    sh: Shooting,
    nuh: np.ndarray,
    T: float,
    check: Check,
    tried: list[tuple[float, np.ndarray]] | None = None,
    max_switches: int | None = None,
    refine: Callable | None = None,
    structure: tuple[np.ndarray, float] | None = None,
    switching: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
) -> object | None:
    """Certified extremal from the switch structure of a co-state guess, or None.

    Parameters
    ----------
    sh : Shooting
        The problem (its state scale ``sh.s`` should be the one for ``T``).
    nuh : ndarray
        Scaled co-state direction guess (``nu * sh.s``), e.g. from
        :func:`~flexmotion_ros.core.time_optimal.smoothed_dual.inner_smooth`.
    T : float
        Duration guess (s).
    check : Check
        Certifies a converged candidate ``(nuh, T, roots, signs)`` (scaled
        co-state, duration in s, switch times-to-go in s, sign of ``S`` on
        each interval in time-to-go order); see :data:`Check`.
    tried : list, optional
        Structures ``(sign0, roots)`` already tried (by an earlier guess) and
        not to be tried again; extended in place with this call's.
    max_switches : int, optional
        Give up on a structure with more switches than this (the planner's
        ``time_optimal.MAX_SWITCHES``: its full solver refuses such moves
        with a clear error).  None: no limit.
    refine : callable, optional
        ``refine(roots, sign0, nuh, T) -> (ok, roots, nuh, T, residual)``,
        the switch-time Newton; default :func:`refine_switches` on ``sh`` (``merge=True``)
        (the lean path passes its own, :func:`~.lean.refine`).
    structure : tuple of (ndarray, float), optional
        The first structure (switch times-to-go in s, first sign) if already
        guessed; default :func:`guess_structure` of ``nuh`` at ``T``.
    switching : callable, optional
        ``switching(nuh, tau) -> S``: the switching function of the scaled
        co-state ``nuh`` at times-to-go ``tau`` (s), to rank the one-dip
        alternatives (:func:`one_dip_structures`); default from ``sh``.
        None and no ``sh``: the edits alone (a chain of at most
        :data:`MAX_TRIES` runs).

    Returns
    -------
    object or None
        What ``check`` accepted, or None if no structure tried led to it.
    """
    roots, sign0 = structure if structure is not None else guess_structure(sh, nuh, T)
    if refine is None:

        def refine(roots, sign0, nuh, T):
            return refine_switches(sh, roots, sign0, nuh, T, merge=True)

    if switching is None and sh is not None:

        def switching(nuh, tau):
            return sh.sys.switching(nuh / sh.s, tau)

    if tried is None:
        tried = []
    # Depth-first: each structure's edit first (the chain of edits, at most MAX_TRIES deep), then
    # the one-dip alternatives (:func:`one_dip_structures`) of the extremals on the way, deepest dip first.
    pending = [(roots, sign0, nuh, T, 0)]
    rejected: list[tuple[float, np.ndarray, float]] = []  # extremals the check rejected: (sign0, tau, T)
    runs = 0
    while pending and runs < MAX_TRIES + MAX_ALTERNATIVES:
        roots, sign0, nuh, T, depth = pending.pop()
        if depth >= MAX_TRIES or (max_switches is not None and roots.size > max_switches):
            continue
        if any(_same_structure(roots, sign0, r, s, T) for s, r in tried):
            continue  # back to a structure that failed (here or in an earlier guess)
        runs += 1
        ok, tau, nuh_r, T_r, _ = refine(roots, sign0, nuh, T)
        if tau.size == roots.size:  # a run that merged a pair (refine_switches' merge) tried a smaller structure
            tried.append((sign0, roots))
        if not (np.isfinite(T_r) and T_r > 0.0 and np.all(np.isfinite(nuh_r))):
            continue
        if ok:
            tau = drop_coincident(tau, T_r)
            if any(_same_extremal(tau, sign0, T_r, *seen) for seen in rejected):
                continue  # rejected already, its edits and alternatives queued then: nothing new here
            signs = sign0 * (1.0 - 2.0 * (np.arange(tau.size + 1) % 2))
            accepted, zeros, zsign0 = check(nuh_r, T_r, tau, signs)
            if accepted is not None:
                return accepted
            rejected.append((sign0, tau, T_r))
            if zeros is None:
                continue
            if switching is not None:
                alternatives = one_dip_structures(tau, sign0, zeros, zsign0, lambda x, nu=nuh_r: switching(nu, x))
                pending.extend((r, sign0, nuh_r, T_r, depth + 1) for r in reversed(alternatives))
            # converged, but S changes sign elsewhere too: adopt its zeros
            edited = updated_structure(tau, sign0, zeros, zsign0)
        else:
            edited = _drop_merged(tau, sign0, T_r)
            if edited is None:
                continue
        pending.append((*edited, nuh_r, T_r, depth + 1))
    return None


def one_dip_structures(
    tau: np.ndarray, sign0: float, zeros: np.ndarray, zsign0: float, switching: Callable[[np.ndarray], np.ndarray]
) -> list[np.ndarray]:
    """Structures with a narrow pulse added in one dip of ``S`` only, deepest dip first.

    A converged extremal with switches ``tau`` (times-to-go, s) whose
    switching function ``S`` dips through zero in several places (``zeros``:
    its proved sign changes) is a wrong structure, and
    :func:`~.switch_newton.updated_structure` puts a pulse in every dip (or
    takes the zeros as they are).  The optimum often needs only one: the
    pulse changes the co-state, and with it the other dips vanish (fuzz case
    6328, 4 modes: 8 dips, the optimum has a pulse of 48 us in the deepest;
    case 1678, 1 mode: one dip and a sign change near the end, the optimum
    has the pulse only).  As an exchange method adds the most violated
    constraint, these are ``tau`` plus one pair at the point of largest
    violation of one dip, in decreasing order of that violation (at most
    :data:`MAX_ALTERNATIVES`); empty when they would only repeat the edit
    (one clean pair).

    A dip is two consecutive new zeros (not within rounding of a switch) on
    the same arc of the extremal; an odd new zero on the first arc (a sign
    change near ``tau = 0``) or the last (near ``T``) is left out, elsewhere
    its arc has no dip.

    Parameters
    ----------
    tau : ndarray
        Switch times-to-go of the extremal (s), increasing.
    sign0 : float
        Sign of ``S`` before the first switch.
    zeros : ndarray
        Sign changes of its ``S`` (s) the certificate proved, increasing.
    zsign0 : float
        Sign of ``S`` before the first of ``zeros``.
    switching : callable
        ``S`` of the extremal at times-to-go (s).

    Returns
    -------
    list of ndarray
        Switch times-to-go (s) of each structure, first sign ``sign0``.
    """
    zeros = np.asarray(zeros, float)
    if zeros.size == 0:
        return []
    clean = new_pairs(tau, sign0, zeros, zsign0)
    if clean is not None and clean[0].size < 2:
        return []  # the edit itself
    arc = np.searchsorted(tau, zeros)
    if tau.size:  # zeros within rounding of a switch are that switch
        gaps = np.diff(np.concatenate([[0.0], tau]))
        tol = 1e-3 * max(float(np.min(gaps[gaps > 0.0], initial=1.0)), 1e-12)
        near = np.minimum(
            np.abs(zeros - tau[np.clip(arc - 1, 0, tau.size - 1)]), np.abs(zeros - tau[np.clip(arc, 0, tau.size - 1)])
        )
        zeros, arc = zeros[near > tol], arc[near > tol]
    a, b = [], []
    for k in np.unique(arc):
        z = zeros[arc == k]
        if z.size % 2:
            if k == 0:
                z = z[1:]
            elif k == tau.size:
                z = z[:-1]
            else:
                continue
        a.extend(z[::2])
        b.extend(z[1::2])
    if not a:
        return []
    a, b = np.array(a), np.array(b)
    # S at DIP_SAMPLES points inside each dip; the expected sign there is that of the extremal's arc
    x = a[:, None] + (b - a)[:, None] * (np.arange(1, DIP_SAMPLES + 1) / (DIP_SAMPLES + 1))[None, :]
    signs = sign0 * (1.0 - 2.0 * (np.arange(tau.size + 1) % 2))
    expected = signs[np.searchsorted(tau, 0.5 * (a + b))]
    violation = -expected[:, None] * switching(x.ravel()).reshape(x.shape)
    worst = np.argmax(violation, axis=1)
    rows = np.arange(a.size)
    centre, half = x[rows, worst], 0.05 * (b - a)
    order = np.argsort(-violation[rows, worst], kind="stable")[:MAX_ALTERNATIVES]
    return [np.sort(np.concatenate([tau, [centre[k] - half[k], centre[k] + half[k]]])) for k in order]


def guess_structure(sh: Shooting, nuh: np.ndarray, T: float) -> tuple[np.ndarray, float]:
    """Switch structure guessed from the switching function ``S`` of ``nuh`` at ``T``.

    The sign changes of ``S`` on a fine grid (:data:`GRID_DENSITY` times the
    planners' sampling grid; linear interpolation), plus narrow pairs of
    switches where ``S`` nearly touches zero (a smoothed co-state rounds off
    short blips of the optimum): at every local minimum of ``|S|`` below
    :data:`VERY_NEAR_ZERO` of its maximum, and, if the switches are fewer
    than ``n - 1`` (fewer than that reach only a thin set of states, so an
    optimum rarely has fewer), at the deepest ones below :data:`NEAR_ZERO`,
    then by splitting the flattest zeros into three.  Nothing is proved: a
    guess needs no more, and the certificate isolates the zeros of the
    final candidate with proof.

    Parameters
    ----------
    sh : Shooting
        The problem.
    nuh : ndarray
        Scaled co-state direction (``nu * sh.s``).
    T : float
        Duration (s).

    Returns
    -------
    roots : ndarray
        Guessed switch times-to-go (s), increasing, inside ``(0, T)``.
    sign0 : float
        Sign of ``S`` before the first of them.
    """
    # graded by the modes still ringing (a guess: the certificate proves whatever comes of it)
    grid = root_grid(sh.sys, T, density=GRID_DENSITY) if GRADED_GUESS else sample_grid(sh.sys, T, density=GRID_DENSITY)
    h = grid[1] - grid[0]  # the finest spacing (a graded grid's first stretch): the width of added pairs
    nu = nuh / sh.s
    # where the rigid part dominates the modes by a margin, S neither changes
    # sign nor nearly touches zero: those blocks need no sampling
    top = float(np.max(np.abs(sh.sys.switching(nu, np.array([0.0, T]))))) + float(sh.sys.switching_magnitude(nu, T)[0])
    grid = examined_points(sh.sys, nu, grid, NEAR_ZERO * top)
    S, dS = sh.sys.switching(nu, grid, derivative=True)
    sg = np.sign(S)
    nz = np.flatnonzero(sg)
    if nz.size == 0:
        return np.empty(0), 1.0
    k = np.flatnonzero(sg[nz[:-1]] != sg[nz[1:]])  # exact zeros carry no sign: skipped
    i, j = nz[k], nz[k + 1]
    roots = grid[i] + (grid[j] - grid[i]) * S[i] / (S[i] - S[j])
    sign0 = float(sg[nz[0]])
    missing = (sh.sys.n - roots.size) // 2  # pairs short of n - 1 switches (rounded up)
    a = np.abs(S)
    top = float(np.max(a))
    # local minima of |S| without a sign change: a pair would make a dip there
    m = np.flatnonzero((a[1:-1] < a[:-2]) & (a[1:-1] <= a[2:]) & (sg[:-2] == sg[2:])) + 1
    m = m[np.argsort(a[m])]
    deep = int(np.count_nonzero(a[m] < VERY_NEAR_ZERO * top))
    m = m[a[m] < NEAR_ZERO * top]
    centres = list(grid[m][: max(missing, deep)])
    # then the flattest zeros (smallest |S'| relative to max|S| / T): three zeros nearby
    if len(centres) < missing and roots.size:
        slope = np.abs(np.interp(roots, grid, dS)) * T / top
        centres += list(roots[np.argsort(slope)][: missing - len(centres)])
    pairs = np.array([[c - 0.25 * h, c + 0.25 * h] for c in centres]).reshape(-1, 2)
    pairs = pairs[(pairs[:, 0] > 0.0) & (pairs[:, 1] < T)].ravel()
    return (np.unique(np.concatenate([roots, pairs])) if pairs.size else roots), sign0


def _same_structure(a: np.ndarray, sa: float, b: np.ndarray, sb: float, T: float) -> bool:
    """Whether two switch structures are the same one (see :data:`SAME_RTOL`)."""
    return sa == sb and a.size == b.size and bool(np.all(np.abs(a - b) <= SAME_RTOL * T))


def _same_extremal(tau: np.ndarray, sign0: float, T: float, sign0_b: float, tau_b: np.ndarray, T_b: float) -> bool:
    """Whether two converged extremals are the same candidate (see :data:`SAME_EXTREMAL_RTOL`)."""
    tol = SAME_EXTREMAL_RTOL * T
    return (
        sign0 == sign0_b and tau.size == tau_b.size and abs(T - T_b) <= tol and bool(np.all(np.abs(tau - tau_b) <= tol))
    )


def drop_coincident(tau: np.ndarray, T: float) -> np.ndarray:
    """Switch times-to-go ``tau`` (s, ascending) without the pairs of neighbours within ``COINCIDENT_RTOL T``.

    Such a pair bounds an interval of zero width (to rounding): without it the
    input is the same, and the signs outside the pair are unchanged.
    """
    while tau.size >= 2:
        gaps = np.diff(tau)
        k = int(np.argmin(gaps))
        if not gaps[k] <= COINCIDENT_RTOL * T:
            break
        tau = np.delete(tau, [k, k + 1])
    return tau


def _drop_merged(tau: np.ndarray, sign0: float, T: float) -> tuple[np.ndarray, float] | None:
    """The structure without a merging pair of switches or a switch at an end, or None.

    ``tau`` are the switch times-to-go (s) where a Newton run stopped.  A
    pair of neighbours closer than ``MERGE_RTOL T`` is removed (the sign
    outside the pair is unchanged); a first switch within that of ``tau = 0``
    is removed and the first level flips; a last one near ``T`` is removed.
    """
    tol = MERGE_RTOL * T
    if tau.size == 0:
        return None
    if tau.size >= 2:
        gaps = np.diff(tau)
        k = int(np.argmin(gaps))
        if gaps[k] <= tol:
            return np.delete(tau, [k, k + 1]), sign0
    if tau[0] <= tol:
        return tau[1:], -sign0
    if tau[-1] >= T - tol:
        return tau[:-1], sign0
    return None
