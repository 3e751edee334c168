"""A move under Coulomb friction as returned (:class:`FrictionProfile`), built from an extremal or from samples.

Both builders run the independent check first (the event-located friction
simulation with matrix exponentials: rest at the target, and still at rest
after it) and return nothing that fails it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import SolverError
from ..model.boundary import MoveProblem
from ..results import BangBangProfile
from ..simulation.exact import PiecewiseConstant
from ..tolerances import FINAL_STATE_RTOL
from .certificate import SAMPLED_CLAIM, FrictionCertificate, FrictionStatus, certify_friction
from .contact import FrictionRun, FrictionSystem
from .extremal import Extremal
from .sampled_certificate import SAMPLED_PATTERN_CLAIM, certify_sampled
from .sampled_lp import FrictionLP


@dataclass
class FrictionProfile:
    """A bang-bang move under Coulomb friction and its checks.

    Attributes
    ----------
    problem : MoveProblem
    coulomb_force : float
        ``F`` (N).
    switch_times, levels : ndarray
        Interior switches (s) and ``+-u_max`` on each interval.
    duration : float
        Move time (s).
    final_state : ndarray
        State at ``duration`` from the exact friction simulation (absolute).
    final_state_error, final_state_error_relative : float
        Distance from rest at the target (state units; relative to each state's scale).
    reversals : ndarray
        Times (s) where the rigid body reverses (the costate jumps there).
    certificate : FrictionCertificate
    frictionless_duration : float
        The certified frictionless optimum ``T*`` (s).
    lower_bound : float or None
        Proved lower bound on any move under this friction (s), see :func:`rigid_friction_time`.
    continuation_steps : int
    solve_time_s : float
    """

    problem: MoveProblem
    coulomb_force: float
    switch_times: np.ndarray
    levels: np.ndarray
    duration: float
    final_state: np.ndarray
    final_state_error: float
    final_state_error_relative: float
    reversals: np.ndarray
    certificate: FrictionCertificate
    frictionless_duration: float
    lower_bound: float | None
    continuation_steps: int = 0
    solve_time_s: float = 0.0
    method: str = "time_optimal_friction"
    #: Sample period (s) of an ``exact_sampled`` move (its levels are held this long each), else None.
    sample_period: float | None = None
    #: Velocity sign on every sample of an ``exact_sampled`` move (+1 / -1; 0 where the body is held: a stick
    #: arc), the pattern its certificate (:mod:`.sampled_certificate`) is about; else None.
    sample_pattern: np.ndarray | None = None
    #: An exact sampled move (``exact_sampled``) found on the way to an uncertified bang-bang one, or None:
    #: the zero-order-hold planner falls back on it when no sequence near this move passes its check.
    alternative: FrictionProfile | None = None
    #: The event-located run (matrix exponentials) that checked an ``exact_sampled`` move, or None: its
    #: segments and events give the states at any instant in closed form (the zero-order-hold planner's
    #: states at the command rate, without locating the same events again).
    exact_run: FrictionRun | None = field(default=None, repr=False, compare=False)

    @property
    def certified(self) -> bool:
        """Whether the extremal certificate passed (necessary conditions, see the claim)."""
        return bool(self.certificate.passed)

    def input(self) -> PiecewiseConstant:
        """The input as a :class:`PiecewiseConstant`."""
        return PiecewiseConstant.from_switches(self.switch_times, self.levels, self.duration)

    def to_dict(self) -> dict:
        """JSON-friendly summary."""
        return {
            "method": self.method,
            "coulomb_force": float(self.coulomb_force),
            "duration": float(self.duration),
            "switch_times": [float(t) for t in self.switch_times],
            "levels": [float(v) for v in self.levels],
            "final_state": [float(v) for v in self.final_state],
            "final_state_error": float(self.final_state_error),
            "final_state_error_relative": float(self.final_state_error_relative),
            "reversals": [float(t) for t in self.reversals],
            "frictionless_duration": float(self.frictionless_duration),
            "added_time_s": float(self.duration - self.frictionless_duration),
            "lower_bound_s": None if self.lower_bound is None else float(self.lower_bound),
            "certified": self.certified,
            "certificate": self.certificate.to_dict(),
            "continuation_steps": int(self.continuation_steps),
            "solve_time_s": float(self.solve_time_s),
        }


def better(a: FrictionProfile | None, b: FrictionProfile | None) -> FrictionProfile | None:
    """The certified one, else the shorter."""
    if a is None or b is None:
        return a if b is None else b
    if a.certified != b.certified:
        return a if a.certified else b
    return a if a.duration <= b.duration else b


def try_assemble(ext, y, base, lb, steps, t0) -> FrictionProfile | None:
    try:
        return assemble_friction(ext, y, base, lb, steps, t0)
    except SolverError:
        return None  # missed the target in the exact check: not a move


def check_sampled(lp: FrictionLP, u: np.ndarray):
    """``(u, x(T), run, relative error, deviation)`` if the sequence rests at the target in the exact
    event-located friction simulation (and stays there), else None."""
    problem = lp.problem
    dt, K = lp.dt, u.size
    T = K * dt
    check = FrictionSystem.for_model(problem.model, lp.F)
    pc = PiecewiseConstant.from_samples(u, dt)
    # one run (was two): the error scale's points, the end and the rest a while later; the scale's points
    # split each sample into m equal parts (at least 129 points, as before), so the run steps with two
    # segment lengths, dt and dt / m, whose matrix exponentials are cached (129 points spread over the
    # move made every segment a new length: two matrix exponentials per segment, most of the check)
    m = max(1, math.ceil(128 / K))
    grid = (np.arange(m * K + 1) / m) * dt
    grid[-1] = T
    run = check.run(problem.x0, pc, np.append(grid, T + max(T, 1.0)))
    xT, x_after = run.states[-2], run.states[-1]
    xf, I = lp.xf, lp.I
    sc = np.max(np.abs(run.states[:-1] - xf), axis=0)
    sc = np.where(sc > 0.0, sc, 1.0)
    dev = (xT - xf)[I]
    rel = float(np.max(np.abs(dev) / sc[I]))
    drift = float(np.max(np.abs((x_after - xT)[I]) / sc[I]))
    if not (rel <= FINAL_STATE_RTOL and drift <= FINAL_STATE_RTOL and np.max(np.abs(u)) <= problem.u_max):
        return None
    return u, xT, run, rel, dev


def sampled_profile(lp: FrictionLP, sol, base: BangBangProfile, lb, steps: int, t0: float) -> FrictionProfile | None:
    """The fewest-sample move itself (piecewise constant, exact after correction), or None if it misses.

    The corrected commands are checked first, then the LP's own (a correction can move a command held
    inside the friction band past it, so that the body slips where the LP has it stuck)."""
    problem = lp.problem
    corrected = lp.exact_commands(sol)
    raw = np.clip(sol.u, -problem.u_max, problem.u_max)
    for u in (corrected, raw):
        if u is not None:
            checked = check_sampled(lp, u)
            if checked is not None:
                break
    else:
        return None
    u, xT, run, rel, dev = checked
    dt, K = lp.dt, sol.u.size
    T = K * dt
    cert = sampled_certificate(lp, sol.pattern, u)
    reversals = reversal_times(run, T)
    return FrictionProfile(
        problem=problem,
        coulomb_force=lp.F,
        switch_times=dt * np.arange(1, K),
        levels=u,
        duration=float(T),
        final_state=xT,
        final_state_error=float(np.max(np.abs(dev))),
        final_state_error_relative=rel,
        reversals=reversals,
        certificate=cert,
        frictionless_duration=float(base.duration),
        lower_bound=lb,
        continuation_steps=steps,
        solve_time_s=time.perf_counter() - t0,
        sample_period=dt,
        sample_pattern=np.asarray(sol.pattern, float).copy(),
        exact_run=run,
    )


def sampled_certificate(lp: FrictionLP, pattern: np.ndarray, u: np.ndarray) -> FrictionCertificate:
    """The certificate of an exact sampled move: ``SAMPLED_PATTERN`` if its pattern's discrete-time Pontryagin
    conditions hold (:func:`~.sampled_certificate.certify_sampled`), else ``SAMPLED``; never ``passed``."""
    pc = certify_sampled(lp, pattern, u)
    n = lp.problem.model.n_states
    lam = np.zeros(n)
    if pc.costate_final.size == lp.I.size:
        lam[lp.I] = pc.costate_final
    where = f"{u.size} samples at {1.0 / lp.dt:.4g} Hz, {pc.stuck_samples} of them stuck (stick arcs)"
    if pc.passed:
        return FrictionCertificate.unproved(
            costate_final=lam,
            message=(
                f"no continuous extremal: the least-peak sequence of its velocity-sign/stick pattern, {where} "
                f"(peak {pc.peak:.9g} N, proved bound {pc.peak_lower_bound:.9g} N; exact, checked)"
            ),
            status=FrictionStatus.SAMPLED_PATTERN,
            claim=SAMPLED_PATTERN_CLAIM,
        )
    return FrictionCertificate.unproved(
        costate_final=lam,
        message=(
            f"no extremal found: the fewest samples found for its velocity-sign pattern, {where} (exact, "
            f"checked; not proved optimal: {pc.message})"
        ),
        status=FrictionStatus.SAMPLED,
        claim=SAMPLED_CLAIM,
    )


def assemble_friction(
    ext: Extremal, y: np.ndarray, base: BangBangProfile, lb, steps: int, t0: float
) -> FrictionProfile:
    problem = ext.problem
    t_sw, T, _lam = ext.unpack(y)
    u = PiecewiseConstant.from_switches(t_sw, ext.levels, T)
    # the independent check: full event-located simulation, no mode locking; and rest after T
    run = ext.check.run(problem.x0, u, [T, T + max(T, 1.0)])
    xT, x_after = run.states
    dev = (xT - ext.xf)[ext.I]
    err = float(np.max(np.abs(dev)))
    rel = float(np.max(np.abs(dev) / ext.s[ext.I]))
    drift = float(np.max(np.abs((x_after - xT)[ext.I]) / ext.s[ext.I]))
    if not (rel <= FINAL_STATE_RTOL and drift <= FINAL_STATE_RTOL):
        raise SolverError(
            f"friction planner missed the target in the exact friction simulation: relative final-state error "
            f"{rel:.3e} (drift after arrival {drift:.3e}); nothing is returned"
        )
    cert = certify_friction(ext, y)
    reversals = reversal_times(run, T)
    return FrictionProfile(
        problem=problem,
        coulomb_force=ext.sys.F,
        switch_times=np.asarray(t_sw, float),
        levels=ext.levels.copy(),
        duration=float(T),
        final_state=xT,
        final_state_error=err,
        final_state_error_relative=rel,
        reversals=reversals,
        certificate=cert,
        frictionless_duration=float(base.duration),
        lower_bound=lb,
        continuation_steps=steps,
        solve_time_s=time.perf_counter() - t0,
    )


def reversal_times(run, T: float) -> np.ndarray:
    """Times (s) of the velocity reversals of an event-located run, before the arrival at ``T``."""
    return np.array([t for t, kind, _ in run.events if kind == "reversal" and t < T * (1.0 - 1e-12)])
