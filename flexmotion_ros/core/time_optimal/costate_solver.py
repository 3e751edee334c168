"""The full solver's co-state iterations: smoothed warm start, exact inner problems, bounded work (seed 2.30-2.37).

Work in time-to-go ``tau = T - t``.  For a co-state direction ``nu`` the
Pontryagin input is ``u(tau) = u_max sgn(nu^T e^{A tau} B)``; the optimal time
is the root of ``m(T) = 1``, ``m(T) = min {h_T(nu) : nu^T w = 1}`` the convex
inner problem of :mod:`.reachable_set`.  :func:`solve_costate`:

1. *Warm start* (:func:`smoothed_start`): smoothed, discretised inner problems
   at decreasing smoothing bring ``T`` close to the optimum, blind to the
   number of switches.
2. *Inner* (fixed ``T``): the exact convex problem by a trust-region Newton
   method gives a co-state direction, hence a switch structure.
3. *Switch-time Newton* (:func:`~.switch_newton.structure_newton`) from that
   structure, with structure corrections; else a safeguarded Newton on
   ``m(T) = 1`` and, as a last resort, the full-accuracy nested iteration and
   a joint Newton polish.

The work is bounded: past :func:`evaluation_budget` exact evaluations the
iteration stops and the planner's bounded structure search
(:mod:`.fallbacks`) takes over.  Nothing here is checked: the planner
(:mod:`.solver`) simulates and certifies whatever comes out.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np

from ..errors import SolverError
from ..tolerances import MAX_SWITCHES, POLISH_TOL
from .reachable_set import Shooting, bracketed_step, outer_newton, polish, rescale
from .smoothed_dual import inner_smooth
from .switch_newton import structure_newton
from .switching import POINTS_PER_HALF_PERIOD, fastest_frequency
from .trust_region import inner_exact

__all__ = [
    "BangBangSolution",
    "evaluation_budget",
    "smoothed_start",
    "solve_bang_bang",
    "solve_costate",
]

#: Smoothing levels (relative to the mean |S|) of the warm-start stage.
SMOOTHING = (0.02, 0.002)
#: Steps on the duration per smoothing level.
SMOOTH_OUTER = 12
#: After a failed switch-time Newton at the smoothed start, the iteration on ``T``
#: continues from there with this share of the work budget, then (if it found no
#: extremal) restarts from the first guess ``T_init`` (0: only that, as before issue 15's tail work).
CONTINUE_SHARE = 0.1
#: Evaluations of the exact shooting map after which the full solver stops
#: and the bounded structure search (:func:`~.fallbacks.structure_fallback`) takes over:
#: the work of a plan is bounded whatever the model (measured on the random
#: models of ``bench/fuzz.py`` and the property tests: certified answers needed
#: up to 191, a stop of a 937-unit motion with 316 switches).  Since the
#: bracket of ``T*`` is narrowed from above only by converged inner solves,
#: 6-8 mode models that ran out at 400 converge with more (fuzz seed 15,
#: cases 0..2999: 6 of the 9 refused at 400 plan, certified, with 521-992
#: evaluations, 0.6-1.1 s).  Evaluations on long grids cost more: the budget
#: falls to :data:`MIN_EVALUATIONS` as the grid grows past
#: :data:`BUDGET_GRID_POINTS` (:func:`evaluation_budget`), so a refusal stays
#: within a few seconds whatever the move.
MAX_EVALUATIONS = 1200
#: The budget on the longest grids (the one before the bracket was proved).
MIN_EVALUATIONS = 400
#: Grid points (bracketing grid of the switching function) up to which the
#: full :data:`MAX_EVALUATIONS` are allowed.
BUDGET_GRID_POINTS = 10_000


def evaluation_budget(system, T: float) -> int:
    """Exact co-state evaluations the full solver may spend at duration ``T`` (s).

    :data:`MAX_EVALUATIONS` on grids up to :data:`BUDGET_GRID_POINTS` points,
    then in proportion to the grid's length (the cost of one evaluation),
    never below :data:`MIN_EVALUATIONS`.
    """
    points = T * fastest_frequency(system) / math.pi * POINTS_PER_HALF_PERIOD
    scaled = MAX_EVALUATIONS * BUDGET_GRID_POINTS / max(points, 1.0)
    return int(max(MIN_EVALUATIONS, min(MAX_EVALUATIONS, scaled)))


def smoothed_start(
    sh: Shooting,
    T_low: float,
    T_init: float,
    levels: tuple[float, ...] = SMOOTHING,
    nuh: np.ndarray | None = None,
    damping: bool = False,
) -> tuple[np.ndarray, float]:
    """Co-state direction (scaled) and time (s) from smoothed inner problems.

    Cheap, robust and blind to the number of switches: decreasing smoothing
    (``levels``) brings ``T`` close to the optimum.  The first stage of
    :func:`solve_costate`, and the guesses of the fast path.  ``nuh``: a warm start
    (scaled), if any.  Leaves ``sh`` unchanged.

    Within a level the smoothing is ``eps = level / (u_max T)``: ``level``
    times the mean ``|S|`` of a minimiser with ``m = 1`` (``h = u_max int
    |S| = 1``), a function of ``T`` alone, so the ``m(T)`` the bracket
    narrows on is one continuous function.  Before (c32a8c3), each solve took
    ``eps`` from the mean ``|S|`` of its own start: ``m`` jumped between
    neighbouring ``T`` (1.0808 at 172.715 s, 0.990 at 172.665 s), the
    bracket crawled to the jump and each level spent all its
    :data:`SMOOTH_OUTER` steps.  (Fixing ``eps T`` from a level's first
    solve, where ``m`` may be far from 1, scaled it badly: two 7-mode moves
    were refused.)  ``damping``: the inner solves damp the Newton steps
    their line search cuts short (:func:`~.smoothed_dual.inner_smooth`).
    """
    T = max(T_init, T_low, 1e-300)
    for level in levels:
        lo, hi = T_low, math.inf
        for _ in range(SMOOTH_OUTER):
            nuh, m, dm = inner_smooth(sh, T, nuh, level, smoothing=level / (sh.u_max * T), damping=damping)
            if m > 0.0 and abs(math.log(m)) < 1e-3:
                break
            T, lo, hi = bracketed_step(T, m, dm, lo, hi)
    return nuh, T


def solve_costate(
    sh: Shooting, T_low: float, T_init: float, start: tuple[np.ndarray, float] | None = None
) -> tuple[np.ndarray, float, np.ndarray, np.ndarray, float]:
    """Optimal time and co-state direction.  ``T_low`` is a proved lower bound (may be 0).

    ``start``: the result of :func:`smoothed_start` for the same ``sh``,
    ``T_low`` and ``T_init``, if already computed (it is deterministic).

    1. A smoothed, discretised version of the convex inner problem at the
       first guess, then the exact one (trust region), give a co-state
       direction and so a switch structure (any number of switches).
    2. Newton on switch times, co-state and ``T`` together converges
       quadratically from that structure; wrong structures are corrected from
       the zeros of the switching function (:func:`structure_newton`).
    3. If that fails, the exact inner problem drives a safeguarded Newton
       iteration on ``log m(T) = 0`` until ``m`` is within 1e-3 of 1 and step 2
       is tried again; as a last resort the nested iteration runs to full
       accuracy and a joint Newton polish on ``(nu, T)`` finishes.
    The caller certifies whatever comes out.
    """
    # smoothed inner problems (cheap, robust, any structure) bring T close to
    # the optimum ...
    nuh, T = start if start is not None else smoothed_start(sh, T_low, T_init)
    # ... where the exact inner problem gives the switch structure
    early = _StructureProbe(sh, T, T_low) if PROBE_BELOW > 0.0 else None
    nuh, m, dm, e = inner_exact(sh, T, nuh, max_iter=30, rtol=1e-12, probe=early)
    if early is not None and early.found is not None:
        sh.s = early.scale  # the scale the extremal's co-state is in
        return early.found
    nuh = rescale(sh, nuh, T)
    found = structure_newton(sh, nuh, T, e.roots, float(e.signs[0]), T_low)
    if found is not None:
        return found
    # otherwise exact inner problems on T, trying the switch-time Newton
    # whenever m comes markedly closer to 1.  First from the exact solve just
    # made (a restart from the first guess walked back up to it: 5 of 14 exact
    # solves of a 259-switch stop; it refused a 6-mode moving start whose
    # first-guess iterations crawled on unproved bounds), with a share of the
    # work budget; if that finds no extremal, from the first guess.
    budget = evaluation_budget(sh.sys, T)
    attempts = [(T, nuh, abs(m - 1.0), sh.evaluations + CONTINUE_SHARE * budget)] if CONTINUE_SHARE > 0.0 else []
    attempts.append((max(T_init, T_low, 1e-300), None, math.inf, math.inf))
    scale = sh.s
    for T, nuh_a, tried_gap, limit in attempts:
        if nuh_a is None:  # afresh, as if the first attempt had not been made
            sh.s = scale
            nuh_a = inner_smooth(sh, T, None, SMOOTHING[0])[0]
        found, nuh, T, e_last, converged = _iterate_on_duration(sh, T, nuh_a, tried_gap, T_low, limit)
        e = e_last if e_last is not None else e
        if found is not None:
            return found
        if converged or sh.evaluations > evaluation_budget(sh.sys, T):
            break
    if sh.evaluations > evaluation_budget(sh.sys, T):
        return nuh, T, e.roots, e.signs, math.inf
    # last resort: full-accuracy nested iteration, then the joint Newton polish
    nuh, T = outer_newton(lambda T, v: inner_exact(sh, T, v, rtol=1e-15)[:3], T_low, T, nuh, tol=1e-11, max_outer=20)
    nuh = rescale(sh, nuh, T)
    nuh, T, e, r = polish(sh, nuh, T)
    if r > POLISH_TOL:  # sharpen with switch times as unknowns, from the polished structure
        found = structure_newton(sh, nuh, T, e.roots, float(e.signs[0]), T_low)
        if found is not None:
            return found
    return nuh, T, e.roots, e.signs, r


#: The first exact inner solve of :func:`solve_costate` tries the switch-time Newton from each new
#: switch structure of its iterates once the trust-region step's predicted decrease of ``h`` is below
#: this (relative), and stops at the first extremal it finds (:class:`_StructureProbe`).  0: only from
#: the solve's end (as before issue 15's tail6 pass).  The solve oscillates between neighbouring
#: structures for 20-30 exact evaluations at the smoothed duration (fuzz cases 205, 388, 1039: 1.5 ms
#: each) while the structure that converges already shows in the first few.
PROBE_BELOW = 3e-4
#: Newton steps a probe's structure gets before :func:`~.switch_newton.structure_newton` checks it.
PROBE_STEPS = 12


class _StructureProbe:
    """``probe`` of :func:`~.trust_region.inner_exact`: the switch-time Newton from each new structure.

    Called at every iterate of the exact inner solve at ``T`` (s); once the
    predicted relative decrease is below :data:`PROBE_BELOW`, an iterate whose
    switch structure (first sign, number of switches) was not tried yet is
    handed to :func:`~.switch_newton.structure_newton` (on a copy of ``sh``
    rescaled to ``T``: the solve goes on in its own scale).  The first
    extremal found is kept in ``found`` (in the scale ``scale``) and stops
    the solve.  Nothing is trusted: the planner certifies it as any other.
    """

    def __init__(self, sh: Shooting, T: float, T_low: float) -> None:
        self.sh, self.T, self.T_low = sh, T, T_low
        self.tried: set[tuple[float, int]] = set()
        self.found = None
        self.scale = sh.s

    def __call__(self, nuh: np.ndarray, e, pred: float) -> bool:
        key = (float(e.signs[0]), int(e.roots.size))
        if pred > PROBE_BELOW or key in self.tried:
            return False
        self.tried.add(key)
        sp = copy.copy(self.sh)
        # a few Newton steps per structure: from a right one Newton converges in a few; a wrong one
        # crawls through all 30 (fuzz 582, 601: 30 ms per probe)
        found = structure_newton(sp, rescale(sp, nuh, self.T), self.T, e.roots, key[0], self.T_low, PROBE_STEPS)
        self.sh.evaluations = sp.evaluations
        if found is None:
            return False
        self.found, self.scale = found, sp.s
        return True


def _iterate_on_duration(sh: Shooting, T: float, nuh: np.ndarray, tried_gap: float, T_low: float, limit: float):
    """Exact inner problems on ``T`` from ``(T, nuh)``, the switch-time Newton tried as ``m`` nears 1.

    ``tried_gap``: ``|m - 1|`` at the last switch-time Newton attempt (inf:
    none yet); ``limit``: stop past this many evaluations (and past the work
    budget).  Returns ``(found, nuh, T, e, converged)``: ``found`` the
    extremal of :func:`~.switch_newton.structure_newton` or None, the last
    iterate and evaluation, and whether ``m(T) = 1`` was reached (to 1e-11).
    """
    lo, hi = T_low, math.inf
    e = None
    for _ in range(60):
        if sh.evaluations > min(limit, evaluation_budget(sh.sys, T)):  # bounded work
            return None, nuh, T, e, False
        before = sh.evaluations
        nuh, m, dm, e = inner_exact(sh, T, nuh, max_iter=15, rtol=1e-9)
        # an unconverged inner solve gives an upper bound on m(T) only: m < 1 proves T short,
        # m >= 1 proves nothing; solve on at this T before the bracket is narrowed from above
        # (a bracket closed on an unproved bound made the iteration crawl to a wrong T and
        # refuse valid 6-8 mode models after 400 evaluations)
        restarted = False
        while m >= 1.0 and sh.evaluations - before > 15 and sh.evaluations <= evaluation_budget(sh.sys, T):
            before, m_before = sh.evaluations, m
            nuh_next, m, dm, e = inner_exact(sh, T, nuh, max_iter=15, rtol=1e-9)
            if not m < m_before * (1.0 - 1e-9):  # no progress (a collapsed trust region)
                if restarted:
                    break
                # once from the smoothed problem's minimiser at this T (a fresh start)
                restarted = True
                nuh_next, m, dm, e = inner_exact(
                    sh, T, inner_smooth(sh, T, nuh, SMOOTHING[-1])[0], max_iter=15, rtol=1e-9
                )
            nuh = nuh_next
        if e.roots.size > MAX_SWITCHES:
            raise SolverError(
                f"the optimal move needs about {e.roots.size} switches over {T:.4g} s (more than "
                f"{MAX_SWITCHES}): the actuator is too weak for this state; raise u_max or start "
                "from a calmer state"
            )
        gap = abs(m - 1.0)
        # the switch structure is often right long before T is: try the
        # switch-time Newton whenever m has come markedly closer to 1
        if gap < 0.5 and gap < 0.25 * tried_gap or tried_gap == math.inf:
            tried_gap = gap
            nuh = rescale(sh, nuh, T)
            found = structure_newton(sh, nuh, T, e.roots, float(e.signs[0]), T_low)
            if found is not None:
                return found, nuh, T, e, True
        if gap <= 1e-11:
            return None, nuh, T, e, True
        T, lo, hi = bracketed_step(T, m, dm, lo, hi)
    return None, nuh, T, e, False


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
    sh = Shooting(system, x0, u_max, max(T_init, 1e-300))
    nuh, T, roots, signs, _ = solve_costate(sh, T_low, T_init)
    switch_times = np.clip(np.sort(T - roots), 0.0, T)
    return BangBangSolution(nuh / sh.s, float(T), switch_times, u_max * signs[::-1])
