"""Warm start of the time-optimal planner from a plan being executed (replanning from a nearby state).

A node that replans during a move always has the plan it is executing.  The
remainder of a time-optimal plan from its instant ``t_s`` is itself
time-optimal from the state it reaches there (Bellman), with the same final
co-state ``nu = -lambda(T)`` and the same switch times-to-go ``tau = T - t``
(the ones still ahead).  A state near that trajectory (a small disturbance, a
small model error, an estimate) has an optimum with, usually, the same
structure and nearby switch times: the switch-time Newton
(:func:`~.lean.refine`) from there converges in a few iterations, without the
smoothed convex problems that find a structure from nothing.

:func:`remainder` turns a certified profile and the elapsed time into a
:class:`WarmStart`; :func:`warm_path` runs Newton (with the structure edits of
:func:`~.structure_guess.newton_from_guess`) from it and hands every converged
candidate to the planner's own exact simulation and Pontryagin certificate;
only a profile with an ``OPTIMAL`` certificate is returned.  Otherwise (the
disturbance changed the structure beyond what the edits repair) it returns
None and the planner solves cold, unchanged.  A warm start changes the
planning time, never the certified answer.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..model.boundary import MoveProblem
from ..results import BangBangProfile, SolverPath, optimal_or_zeros
from ..simulation.modal_response import ModalResponse
from ..tolerances import MAX_SWITCHES

#: A switch closer than this (relative to the remaining duration) to the splice is dropped from the guess:
#: Newton cannot keep it inside ``(0, T)`` when the state moved it a little earlier.
EDGE_RTOL = 1e-6
#: Newton iterations per structure: from a nearby state the remainder's structure converges in a few; a guess
#: that needs more is far off, and the cold solver is cheaper than insisting.
MAX_ITER = 12
#: Candidates certified (the first structure and one edit from the certificate's zeros) before the cold solver
#: takes over.
MAX_CANDIDATES = 2
#: A candidate within this (relative) of the rigid body's lower bound is left to the cold solver: Newton
#: there converges to rounding-level extremals up to 4e-9 below the bound (seen: a 2-mode move, 6.668 s).
NEAR_RIGID_RTOL = 1e-9
#: Tries of each Newton step's line search (the full step, then halved): from a nearby state's structure the
#: full step or its half is taken (366 of 392 steps on bench/replan_latency.py's warm hits, none needed more
#: than 4 tries); a step that 4 cannot improve means a structure that is wrong, and 12 tries cost 12 exact
#: evaluations before saying so.
HALVINGS = 4
#: Newton runs in all (the remainder's structure and its edits) before the cold solver takes over: a warm
#: start answered after at most 4 in random 1-3 mode replans; converged but wrong extremals whose
#: certificate's zeros led from edit to edit took 8-9 runs, 10 ms, on bench/replan_latency.py's 3-mode states.
MAX_RUNS = 4
#: Newton from the remainder's structure that stops (not converged) with a residual (relative to the state's
#: scale) above this gives up the warm start: the state is far from the remainder's, and the edits of
#: :func:`guesses` rarely converge from there.  Below it a switch is usually missing at an end (a disturbance
#: generically adds one): the edits answer.  With this, :data:`HALVINGS` and :data:`MAX_RUNS`, on 294 random
#: 1-3 mode replans (disturbances 1e-7..1e-1 of the move's excursions) the warm start answered 81 (86 before)
#: and the warm median fell from 6.6 to 5.0 ms of CPU, the cold one 5.3 ms.
NEAR_RESIDUAL = 1e-3
#: Where :func:`guesses` puts a switch added at an end (time-to-go, fraction of the duration).
EDGE_GUESS = 0.02


@dataclass(frozen=True, kw_only=True)
class WarmStart:
    """A guess of a time-optimal move's switch structure, e.g. the rest of a plan being executed.

    Attributes
    ----------
    roots : ndarray
        Switch times-to-go (s), ascending, inside ``(0, duration)``.
    sign0 : float
        Sign of the input on the last interval (just before arrival), +1 or -1.
    nu : ndarray
        Final co-state direction ``-lambda(T)`` (any positive factor) in the
        planner's state (without the position when the final position is free).
    duration : float
        Duration guess (s).
    include_position : bool
        Whether the state includes the rigid-body position (the final position is given).
    """

    roots: np.ndarray
    sign0: float
    nu: np.ndarray
    duration: float
    include_position: bool


def remainder(profile: BangBangProfile | None, elapsed: float) -> WarmStart | None:
    """The rest of ``profile`` after ``elapsed`` seconds as a warm start (None if there is none).

    Parameters
    ----------
    profile : BangBangProfile or None
        A certified time-optimal profile (the plan being executed).
    elapsed : float
        Time since its start (s) at the instant the new plan starts.

    Returns
    -------
    WarmStart or None
        None without a profile, a passed certificate or time left.
    """
    if profile is None or not math.isfinite(elapsed) or elapsed < 0.0:
        return None
    cert = profile.certificate
    T = float(profile.duration)
    left = T - elapsed
    if cert is None or not cert.passed or not left > 0.0 or profile.levels.size == 0:
        return None
    nu = -np.asarray(cert.costate_final, dtype=float)
    if not (np.all(np.isfinite(nu)) and np.any(nu)):
        return None
    roots = np.sort(T - np.asarray(profile.switch_times, dtype=float))
    roots = roots[(roots > EDGE_RTOL * left) & (roots < left * (1.0 - EDGE_RTOL))]
    return WarmStart(
        roots=roots,
        sign0=float(np.sign(profile.levels[-1])) or 1.0,
        nu=nu,
        duration=left,
        include_position=bool(profile.problem.include_position),
    )


def guesses(warm: WarmStart, T: float, lm, structure_of: Callable):
    """Structures to start Newton from: the remainder's, then edits a disturbance most often makes.

    1. the remainder's switches;
    2. the sign changes of its switching function ``S(tau) = nu^T e^{A tau} B``
       sampled on the lean grid, with a narrow pair wherever ``|S|`` nearly
       touches zero (``structure_of``: :func:`~.lean.structure_from_samples`): a disturbance
       turns such a near-tangency into a notch;
    3. each of those with one switch more at the end (a rest-to-rest
       optimum's ``S`` vanishes at arrival) or at the splice
       (time-to-go :data:`EDGE_GUESS` of ``T`` from there).

    Newton moves the switches from there to their place; duplicates are skipped by the caller.
    """
    base = [(warm.roots, warm.sign0)]
    yield base[0]  # before sampling S: the remainder's structure answers most warm starts that answer
    tau = np.linspace(0.0, T, lm.grid_points(T) + 1)
    S = lm.response.switching(warm.nu, tau)
    sampled = structure_of(tau, S, lm.n)
    if sampled[0].size != warm.roots.size or sampled[1] != warm.sign0:
        base.append(sampled)
        yield sampled
    d = EDGE_GUESS * T
    for roots, sign0 in base:
        if roots.size == 0 or roots[0] > 2.0 * d:
            yield np.concatenate([[d], roots]), -sign0
        if roots.size == 0 or roots[-1] < T - 2.0 * d:
            yield np.concatenate([roots, [T - d]]), sign0


@dataclass(frozen=True, kw_only=True)
class WarmTools:
    """The solver's pieces :func:`warm_path` runs on, passed in by the solver.

    This module sits beside :mod:`.lean` and :mod:`.structure_guess` (not
    above them), which keeps the core's import chains short.

    Attributes
    ----------
    lean_move : callable
        :class:`~.lean.LeanMove` ``(response, x0, u_max, T_scale)``.
    refine : callable
        :func:`~.lean.refine` ``(lm, roots, sign0, nuh, T, max_iter)``.
    structure_of : callable
        :func:`~.lean.structure_from_samples` ``(tau, S, n)``.
    newton : callable
        :func:`~.structure_guess.newton_from_guess`.
    """

    lean_move: Callable
    refine: Callable
    structure_of: Callable
    newton: Callable


#: ``assemble(problem, system, nu, T, roots_tau, signs_tau, t0, evaluations, T_low) -> BangBangProfile``:
#: the planner's exact simulation and certificate (raises :class:`SolverError` if the target is missed).
Assemble = Callable[..., BangBangProfile]


def warm_path(
    problem: MoveProblem,
    system,
    x0: np.ndarray,
    warm: WarmStart,
    t0: float,
    T_low: float,
    assemble: Assemble,
    tools: WarmTools,
) -> BangBangProfile | None:
    """Switch-time Newton from ``warm``, certified by ``assemble``; None if no candidate is ``OPTIMAL``.

    Parameters
    ----------
    problem : MoveProblem
        The move (model, ``u_max`` in N, initial state, target).
    system : ModalResponse
        Its closed-form responses (the planner's state).
    x0 : ndarray
        Shifted initial state (state units).
    warm : WarmStart
        The guess.
    t0 : float
        ``time.perf_counter()`` at the start of planning (s).
    T_low : float
        Proved lower bound on the optimal time (s): the rigid body's.
    assemble : callable
        The planner's simulation and certificate (:data:`Assemble`).
    tools : WarmTools
        The lean path's pieces and the structure-editing Newton.

    Returns
    -------
    BangBangProfile or None
        ``extra["solver_path"] = "fast"``, ``extra["fast_path_stage"] = "warm"``.
    """
    if (
        not isinstance(system, ModalResponse)
        or warm.roots.size == 0  # the last bang: its co-state says nothing of the notch a disturbance needs
        or warm.include_position != problem.include_position
        or warm.nu.size != system.n
        or warm.roots.size > MAX_SWITCHES
    ):
        return None
    T = max(float(warm.duration), T_low)
    lm = tools.lean_move(system, x0, problem.u_max, T)
    nuh = warm.nu * lm.s
    candidates = 0

    def check(nuh, T, roots, signs):
        nonlocal candidates
        if candidates >= MAX_CANDIDATES:
            return None, None, 0.0  # no more edits: the cold solver decides
        candidates += 1
        if not T > T_low * (1.0 + NEAR_RIGID_RTOL):
            return None, None, 0.0  # at the rigid bound to rounding: the cold solver's cluster logic decides
        return optimal_or_zeros(
            lambda: assemble(problem, system, nuh / lm.s, T, roots, signs, t0, lm.evaluations, T_low)
        )

    nuh = nuh / np.linalg.norm(nuh)
    first = tools.refine(lm, warm.roots, warm.sign0, nuh, T, MAX_ITER, HALVINGS)
    converged, residual = first[0], first[4]
    if not converged and not residual <= NEAR_RESIDUAL:
        # far from the remainder's structure: its edits rarely converge there, and cost more than the cold
        # solver (bench/replan_latency.py, 3 modes: up to 10 ms, the warm replan's median 1.6x the cold one)
        return None

    runs = 1

    def refine(roots, sign0, nuh, T):
        nonlocal runs
        if roots is warm.roots:  # the remainder's run, done above
            return first
        if runs >= MAX_RUNS:  # a non-finite duration stops the structure edits at once
            return False, roots, nuh, math.nan, math.inf
        runs += 1
        return tools.refine(lm, roots, sign0, nuh, T, MAX_ITER, HALVINGS)

    tried: list = []
    profile = None
    for structure in guesses(warm, T, lm, tools.structure_of):
        profile = tools.newton(
            None, nuh, T, check, tried, max_switches=MAX_SWITCHES, refine=refine, structure=structure
        )
        if profile is not None or candidates >= MAX_CANDIDATES or runs >= MAX_RUNS:
            break
    if profile is not None:
        profile.extra["solver_path"] = SolverPath.FAST
        profile.extra["fast_path_stage"] = "warm"
        profile.extra["fast_path_candidates"] = candidates
    return profile


__all__ = [
    "NEAR_RIGID_RTOL",
    "EDGE_GUESS",
    "EDGE_RTOL",
    "MAX_CANDIDATES",
    "HALVINGS",
    "MAX_ITER",
    "MAX_RUNS",
    "NEAR_RESIDUAL",
    "WarmStart",
    "WarmTools",
    "guesses",
    "remainder",
    "warm_path",
]
