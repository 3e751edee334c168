"""Certified time-optimal bang-bang moves (seed section 2.3).

Method
------
Work in time-to-go ``tau = T - t``.  For a co-state direction ``nu`` (``nu =
-lambda(T)`` up to a positive factor) the Pontryagin input is
``u(tau) = u_max sgn(nu^T e^{A tau} B)`` and the final state is::

    F(nu, T) = e^{A T} x0 + grad h_T(nu),   h_T(nu) = u_max int_0^T |nu^T e^{A tau} B| dtau

``h_T`` is the support function of the set reachable in time ``T``: convex in
``nu``.  ``x0`` can be brought to rest in time ``T`` iff
``m(T) = min {h_T(nu) : nu^T w = 1} >= 1`` with ``w = -e^{A T} x0``, and ``m``
is non-decreasing in ``T``.  So the optimal time is the root of ``m(T) = 1``:

1. *Inner* (fixed ``T``): minimise the convex ``h_T`` on the hyperplane with a
   damped Newton method.  Convexity makes this globally convergent from any
   start; no guess of the number of switches is needed: the switches are the
   zeros of the switching function at the current ``nu``, found on a grid.
2. *Outer*: safeguarded Newton on ``m(T) = 1`` (``dm/dT`` by the envelope
   theorem), bracketed from below by the rigid-body optimum.
3. *Polish*: Newton on ``F(nu, T) = 0`` jointly (quadratic convergence) to
   machine precision.

The planner tries, in order, each stage only if the one before found no
certified optimum: the rigid body's optimum when it leaves every mode at rest
(or nearly: :func:`~.fallbacks.cluster_fallback`), the warm start of a replan
(:mod:`.warm_start`), the fast paths (:func:`_lean_path`, :func:`_fast_path`: guess a switch
structure from a smoothed co-state, Newton on the switch times), then the
full solver (:mod:`.costate_solver`: steps 1-3 above, bounded work) and its
fallbacks (:mod:`.fallbacks`).  ``profile.extra["solver_path"]`` says which
answered.

Every candidate of every stage goes through the same check
(:func:`.assembly.assemble`): the final state by matrix-exponential
simulation, optimality by the Pontryagin certificate
(:mod:`flexmotion_ros.core.time_optimal.certificate`).  A profile whose final
state misses the target is never returned.
"""

from __future__ import annotations

import copy
import math
import time

import numpy as np

from ..errors import SolverError
from ..model.boundary import MoveProblem
from ..results import BangBangProfile, CertificateStatus, SolverPath, optimal_or_zeros
from ..simulation.modal_response import ModalResponse
from ..simulation.prepared import PreparedMove, prepare
from ..tolerances import AT_REST, FINAL_STATE_RTOL, MAX_SWITCHES
from .assembly import assemble
from .costate_solver import BangBangSolution, smoothed_start, solve_bang_bang, solve_costate
from .fallbacks import cluster_fallback, duality_fallback, end_blip_fallback, refusal_reason, structure_fallback
from .lean import MAX_MODES as LEAN_MAX_MODES
from .lean import MAX_POINTS as LEAN_MAX_POINTS
from .lean import LeanMove, smoothed_guess, structure_from_samples
from .lean import refine as lean_refine
from .reachable_set import Shooting, rescale, state_scale
from .rigid_body import rigid_profile, rigid_time
from .structure_guess import newton_from_guess
from .switching import POINTS_PER_HALF_PERIOD, fastest_frequency
from .warm_start import WarmStart, WarmTools, warm_path

__all__ = ["FINAL_STATE_RTOL", "BangBangSolution", "plan_time_optimal", "rigid_time", "solve_bang_bang", "state_scale"]

#: The fast path's second guess, if the first fails: smoothed inner problems at
#: this finer level, from the warm start (sharper near-tangencies of ``S``:
#: short blips of the optimum show).  0: no second guess.
FINE_SMOOTHING = 2e-4
#: Try the guess-Newton-certify fast path (:mod:`.structure_guess`) before the
#: full solver.  This changes speed, and possibly the last bits of the result
#: (both paths converge to the same optimum from different starts); the
#: verdict is the certificate's either way: the fast path returns only a
#: profile that passed the same simulation and certificate as the full
#: solver's, and otherwise the full solver runs (tests compare both).
FAST_PATH = True
#: A rigid optimum missing the target by less than this (relative) is tried
#: first with a notch at its switch (:func:`~.fallbacks.cluster_fallback`): the structure
#: of a machine tuned near a multiple of a period, whose notch is too narrow
#: for the switching function to show.  Accepted only within ``GAP_RTOL``.
NEAR_RIGID = 1e-5
#: Try the lean variant of the fast path (:mod:`.lean`: one smoothing level on
#: a coarse grid, fused closed forms) first; it answers most small plans in a
#: fraction of the fast path's time, and hands over to it (unchanged) when it
#: finds nothing.  Only with :data:`FAST_PATH`.
LEAN_PATH = True
#: If the fast path finds nothing, try it once more from a warm start whose smoothed inner
#: problems damp the Newton steps their line search cuts short
#: (:func:`~.costate_solver.smoothed_start` with ``damping``), before the full solver (which
#: starts from the undamped one, as before).
DAMPED_START = True
#: ... on moves whose sampling grid at the warm start's duration has at most this many points (8
#: per half period of the fastest mode): the singular Hessians are those of coarse grids; on long
#: moves the second try cost up to 2.6 s (fuzz case 2371, 280,000 points) and answered none of the
#: 10,000 (the longest it answered: 16,543 points, case 8695).
DAMPED_MAX_POINTS = 20_000
#: What the warm start of a replan (:mod:`.warm_start`) runs on: the lean path's pieces.
WARM_TOOLS = WarmTools(
    lean_move=LeanMove, refine=lean_refine, structure_of=structure_from_samples, newton=newton_from_guess
)


def plan_time_optimal(problem: MoveProblem | PreparedMove, warm_start: WarmStart | None = None) -> BangBangProfile:
    """Time-optimal bang-bang input for a move to rest, with certificate.

    Parameters
    ----------
    problem : MoveProblem or PreparedMove
        Model, bound, initial state and target (see :mod:`.boundary`); a
        :class:`~flexmotion_ros.core.simulation.prepared.PreparedMove` reuses
        its responses (an attached optimum is not reused: this solves).
    warm_start : WarmStart, optional
        A guess of the switch structure (:func:`.warm_start.remainder`: the
        rest of the plan being executed, when replanning from a nearby state).
        Tried first (:func:`.warm_start.warm_path`); if it yields no certified
        optimum the planner solves cold, as without it.  The answer is the
        certified optimum either way.

    Returns
    -------
    BangBangProfile

    Raises
    ------
    SolverError
        If no profile passes the exact final-state check.
    """
    t0 = time.perf_counter()
    move = prepare(problem)
    problem = move.problem
    model, um = problem.model, problem.u_max
    system = move.response
    x0 = move.x0.copy()
    if not np.any(np.abs(x0) > AT_REST):
        profile = assemble(problem, system, np.zeros(system.n), 0.0, np.empty(0), np.array([1.0]), t0, 0)
        profile.extra["solver_path"] = SolverPath.AT_REST
        return profile
    rigid = rigid_profile(model, um, x0, problem.include_position)
    T_low = rigid.duration
    rigid_miss = _rigid_residual(system, x0, um, rigid)
    if rigid_miss <= 1e-13:  # the rigid optimum leaves every mode at rest: optimal
        nu = np.zeros(system.n)
        nu[: system.r] = rigid.nu
        roots = np.sort(T_low - rigid.switch_times)
        profile = assemble(problem, system, nu, T_low, roots, np.sign(rigid.levels[::-1]), t0, 0)
        profile.extra["solver_path"] = SolverPath.RIGID
        return profile
    if rigid_miss <= NEAR_RIGID:
        # nearly: the optimum is the rigid one with a notch below rounding at a switch
        nu = np.zeros(system.n)
        nu[: system.r] = rigid.nu
        sh = Shooting(system, x0, um, T_low)
        roots = np.sort(T_low - rigid.switch_times)
        signs = np.sign(rigid.levels[::-1])
        profile = cluster_fallback(problem, system, sh, nu * sh.s, T_low, roots, signs, t0, T_low, assemble)
        if profile is not None:
            return profile
    # a first guess: the rigid time plus a quarter period of the slowest mode
    T_init = T_low + (0.5 * math.pi / min(model.omega) if model.omega else 0.0)
    warm_error = None
    if warm_start is not None and FAST_PATH:
        try:
            warm = warm_path(problem, system, x0, warm_start, t0, T_low, assemble, WARM_TOOLS)
        except Exception as exc:  # noqa: BLE001 - a guess only: whatever went wrong, the cold solver decides
            warm, warm_error = None, repr(exc)
        if warm is not None:
            return warm
    lean_error = None
    if FAST_PATH and LEAN_PATH:
        lean, lean_error = _lean_path(problem, system, x0, t0, T_low, T_init)
        lean_error = lean_error or warm_error
        if lean is not None:
            if lean_error is not None:  # a bug in the warm start: visible, though the answer stands
                lean.extra["fast_path_error"] = lean_error
            return lean
    sh = Shooting(system, x0, um, T_init)
    T_lb = T_low * (1.0 - 1e-12)
    start = smoothed_start(sh, T_lb, T_init)
    fast_error = None
    if FAST_PATH:
        fast, fast_error = _fast_path(problem, system, copy.copy(sh), start, t0, T_low)
        points = start[1] * fastest_frequency(system) / math.pi * POINTS_PER_HALF_PERIOD
        if fast is None and fast_error is None and DAMPED_START and sh.short_steps and points <= DAMPED_MAX_POINTS:
            # again from a warm start whose inner solves damp the steps their line search cuts short (a
            # short move of many modes: the undamped one can stop a factor 2-20 below T*); the full
            # solver below still starts from ``start``, as before
            try:
                damped = smoothed_start(copy.copy(sh), T_lb, T_init, damping=True)
            except Exception as exc:  # noqa: BLE001 - a guess only: the full solver decides
                damped, fast_error = None, repr(exc)
            if damped is not None:
                fast, fast_error = _fast_path(problem, system, copy.copy(sh), damped, t0, T_low, damping=True)
            if fast is not None:
                fast.extra["fast_path_stage"] = "damped"
        fast_error = fast_error or lean_error
        if fast is not None:
            if fast_error is not None:  # a bug in the lean path: visible, though the answer stands
                fast.extra["fast_path_error"] = fast_error
            return fast
    # the full solver, exactly as without the fast path (``sh`` is untouched)
    nuh, T, roots, signs, residual = solve_costate(sh, T_lb, T_init, start)
    try:
        profile = assemble(problem, system, nuh / sh.s, T, roots, signs, t0, sh.evaluations, T_low)
    except SolverError as miss:
        profile = cluster_fallback(problem, system, sh, nuh, T, roots, signs, t0, T_low, assemble)
        if profile is None:
            profile = structure_fallback(problem, system, sh, nuh, T, roots, signs, t0, T_low, assemble)
        if profile is None:
            w_fast = fastest_frequency(system)
            fastest_period = 2.0 * math.pi / w_fast if w_fast > 0.0 else 0.0
            if math.isinf(residual):  # the work budget ran out: say so, not only the miss it left
                raise SolverError(
                    f"time-optimal planner did not converge within its work budget ({sh.evaluations} exact "
                    f"co-state evaluations, {model.n_modes} modes): no switch structure it found reaches the "
                    f"target (the last one: {roots.size} switches over {T:.4g} s, relative final-state error "
                    f"{getattr(miss, 'relative_error', math.nan):.1e}, tolerance {FINAL_STATE_RTOL:.0e}); "
                    f"{refusal_reason(T_low, fastest_period)}"
                ) from miss
            # the structures found miss the target: the same facts, after what was missed
            refusal = SolverError(
                f"{str(miss).removesuffix('; nothing is returned')}; {refusal_reason(T_low, fastest_period)}"
            )
            refusal.relative_error = getattr(miss, "relative_error", math.nan)
            raise refusal from miss
    if profile.certificate.status is CertificateStatus.FAILED:  # a blip at the end the certificate cannot prove
        profile = end_blip_fallback(problem, system, sh, profile, t0, T_low, assemble) or profile
    if not profile.certificate.passed:  # a notch whose sign is at rounding: the gap to a dual bound may prove it
        profile = duality_fallback(problem, system, profile, t0, T_low, assemble) or profile
    profile.extra.setdefault("solver_path", SolverPath.FULL)
    if fast_error is not None:  # a bug in the fast path: visible, though the answer stands
        profile.extra["fast_path_error"] = fast_error
    return profile


def _rigid_residual(system: ModalResponse, x0: np.ndarray, u_max: float, rigid) -> float:
    """Relative final-state error of the rigid body's optimum on the whole machine (0: it is optimal)."""
    if rigid.duration == 0.0 or system.n == system.r:
        return 0.0 if system.n == system.r else math.inf
    T = rigid.duration
    roots = np.sort(T - rigid.switch_times)
    signs = np.sign(rigid.levels[::-1])
    G = system.input_integral(np.append(roots, T))
    jump = 2.0 * u_max * signs[:-1]
    xT = system.expm_x(T, x0) + u_max * signs[-1] * G[-1] + jump @ G[:-1]
    return float(np.max(np.abs(xT) / state_scale(system, x0, u_max, T)))


def _fast_path(
    problem: MoveProblem,
    system: ModalResponse,
    sh: Shooting,
    start: tuple[np.ndarray, float],
    t0: float,
    T_low: float,
    damping: bool = False,
) -> tuple[BangBangProfile | None, str | None]:
    """Guess, Newton, certify (:mod:`.structure_guess`).

    The switch-time Newton runs from the structure of the smoothed co-state
    ``start`` (then, if that fails, of a finer smoothing level:
    :data:`FINE_SMOOTHING`), skipping the exact inner problems.  Every
    candidate goes through the same exact simulation and certificate as the
    full solver's result (:func:`assemble`), and is kept only if the
    final-state check and the certificate's full sign test pass (not merely
    the gap to the rigid bound: that close to it, the full solver decides).

    ``sh`` is the shooting problem ``start`` (:func:`smoothed_start`'s scaled
    co-state and duration, s) was computed for, modified here (pass a copy);
    ``t0`` the ``perf_counter`` at the start of planning (s); ``T_low`` the
    rigid body's proved lower bound (s).  Returns ``(profile, error)``: the
    certified profile (``extra["solver_path"] = "fast"``,
    ``extra["fast_path_candidates"]``) or None (the full solver runs), and
    the ``repr`` of an exception raised inside (a bug: recorded by the
    caller in ``extra["fast_path_error"]``) or None.  ``damping``: ``start``
    came from damped inner solves (:func:`smoothed_start`); so does the
    finer guess.
    """

    candidates = 0
    sh0 = copy.copy(sh)  # the scale of ``start``

    def check(nuh, T, roots, signs):
        nonlocal candidates
        candidates += 1
        try:
            # raises SolverError unless the final-state error is within FINAL_STATE_RTOL
            profile = assemble(problem, system, nuh / sh.s, T, roots, signs, t0, sh.evaluations, T_low)
        except SolverError:  # the target missed: no structure information either
            return None, None, 0.0
        cert = profile.certificate
        if cert.status is CertificateStatus.OPTIMAL:
            return profile, None, 0.0
        return None, cert.details.get("zeros_tau"), float(cert.details.get("sign0", 0.0))

    try:
        nuh = rescale(sh, start[0], start[1])
        tried = []  # switch structures tried (not to be tried again)
        profile = newton_from_guess(sh, nuh, start[1], check, tried, max_switches=MAX_SWITCHES)
        if profile is None and FINE_SMOOTHING:
            # a second guess from finer smoothing: short blips of the optimum
            # that the first level rounds off show up as sign changes (a
            # structure already tried is not tried again)
            sh = copy.copy(sh0)
            nuh, T = smoothed_start(sh, T_low * (1.0 - 1e-12), start[1], (FINE_SMOOTHING,), start[0], damping)
            profile = newton_from_guess(sh, rescale(sh, nuh, T), T, check, tried, max_switches=MAX_SWITCHES)
    except Exception as exc:  # noqa: BLE001 - whatever went wrong, the full solver decides
        return None, repr(exc)
    if profile is not None:
        profile.extra["solver_path"] = SolverPath.FAST
        profile.extra["fast_path_candidates"] = candidates  # extremals certified (1 + structure corrections)
    return profile, None


def _lean_path(
    problem: MoveProblem,
    system: ModalResponse,
    x0: np.ndarray,
    t0: float,
    T_low: float,
    T_init: float,
) -> tuple[BangBangProfile | None, str | None]:
    """The fast path on fused closed forms (:mod:`.lean`); None if it finds no certified profile.

    Guess from one smoothed level on a coarse grid, switch-time Newton with
    the structure corrections of :func:`~.structure_guess.newton_from_guess`,
    and the same exact simulation and certificate as every path
    (:func:`assemble`): only an ``OPTIMAL`` certificate is accepted.
    Only for models of at most :data:`~.lean.MAX_MODES` modes and moves whose
    coarse grid has at most :data:`~.lean.MAX_POINTS` points.
    Returns ``(profile, error)`` as :func:`_fast_path` does.
    """
    if not isinstance(system, ModalResponse) or system.w.size > LEAN_MAX_MODES:
        return None, None
    lm = LeanMove(system, x0, problem.u_max, T_init)
    if lm.grid_points(T_init) > LEAN_MAX_POINTS:
        return None, None
    candidates = 0

    def check(nuh, T, roots, signs):
        nonlocal candidates
        candidates += 1
        return optimal_or_zeros(lambda: assemble(problem, system, nuh / lm.s, T, roots, signs, t0, 0, T_low))

    try:
        nuh, T, tau, S = smoothed_guess(lm, T_low * (1.0 - 1e-12), T_init)
        profile = newton_from_guess(
            None,
            nuh,
            T,
            check,
            max_switches=MAX_SWITCHES,
            refine=lambda roots, sign0, nuh, T: lean_refine(lm, roots, sign0, nuh, T),
            structure=structure_from_samples(tau, S, system.n),
        )
    except Exception as exc:  # noqa: BLE001 - whatever went wrong, the fast path and the full solver decide
        return None, repr(exc)
    if profile is not None:
        profile.extra["solver_path"] = SolverPath.FAST
        profile.extra["fast_path_stage"] = "lean"
        profile.extra["fast_path_candidates"] = candidates
    return profile, None
