"""Time-optimal moves under rigid-body Coulomb friction: the bang-bang extremal by continuation.

The friction model and the exact event-located simulator are :mod:`.friction`.

Time-optimal moves
------------------
With ``|u| = u_max > F`` the contact never sticks during a bang-bang move,
the velocity only crosses zero transversally, and the system is piecewise
linear.  The hybrid maximum principle gives ``u = -u_max sgn(B^T lambda)``,
``lambda' = -A^T lambda`` between events and a jump of ``lambda`` along
``C^T`` at each velocity reversal (``lambda^- = S^T lambda^+``, ``S`` the
saltation matrix), which keeps the Hamiltonian continuous.  The switch times,
the duration and ``lambda(T)`` are found by Newton's method on these
conditions (final state, ``B^T lambda(t_j) = 0``, ``H = 0``), by continuation
in ``F`` from the certified frictionless optimum.  The result is checked by
the exact friction simulation (rest at the target) and certified as a
Pontryagin extremal (sign structure proved per costate piece).  The friction
system is not linear, so the extremal is *not* proved globally optimal; the
rigid-body friction optimum is reported as a proved lower bound (c = 0, from
rest).  The extremal conditions are checked by :mod:`.friction_certificate`;
the zero-order-hold version is :mod:`.friction_zoh`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..errors import InputError, SolverError
from ..model.boundary import MoveProblem
from ..model.modal_model import ModalModel
from ..results import BangBangProfile
from ..simulation.exact import PiecewiseConstant
from ..time_optimal.solver import plan_time_optimal
from ..tolerances import FINAL_STATE_RTOL
from .certificate import (
    FrictionCertificate,
    certify_friction,
    same_switches,
    switching_zeros,
)
from .contact import FrictionSystem
from .extremal import Extremal


def check_coulomb_force(coulomb_force, u_max: float) -> float:
    """``coulomb_force`` as float if in ``[0, u_max)`` N, else raise (names the parameter)."""
    try:
        F = float(coulomb_force)
    except (TypeError, ValueError):
        raise InputError(
            "coulomb_force", f"must be a number in [0, u_max) = [0, {u_max:g}) N, got {coulomb_force!r}"
        ) from None
    if not (math.isfinite(F) and 0.0 <= F < u_max):
        raise InputError(
            "coulomb_force",
            f"must be in [0, u_max) = [0, {u_max:g}) N (at F >= u_max the machine cannot start), got {F}",
        )
    return F


def rigid_friction_time(
    model: ModalModel, u_max: float, coulomb_force: float, x0, target: float | None
) -> float | None:
    """Proved lower bound (s) on any rest-to-rest move under rigid-body friction, or None.

    For ``c = 0`` from rest: while ``v > 0`` the acceleration lies in
    ``[-a2, a1]`` (``a1 = |b0| (u_max - F)``, ``a2 = |b0| (u_max + F)``), so
    ``v(t) <= min(a1 t, a2 (T - t))`` and the distance ``|gamma| <= T^2 a1 a2 / (2 (a1 + a2))``.
    The modes add constraints only, so the full model is never faster.
    """
    x0 = np.asarray(x0, float)
    if target is None or model.c != 0.0 or np.any(x0[1:]):
        return None
    gamma = abs(target - x0[0])
    a1 = abs(model.b0) * (u_max - coulomb_force)
    a2 = abs(model.b0) * (u_max + coulomb_force)
    return math.sqrt(2.0 * gamma * (a1 + a2) / (a1 * a2))


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


def plan_time_optimal_friction(problem: MoveProblem, coulomb_force: float) -> FrictionProfile:
    """Bang-bang move to rest under rigid-body Coulomb friction, checked by exact simulation.

    Parameters
    ----------
    problem : MoveProblem
        Model, bound, initial state, target (``None``: final position free).
    coulomb_force : float
        ``F`` in ``[0, u_max)`` (N).

    Returns
    -------
    FrictionProfile
        Rests at the target in the exact friction simulation; ``certified``
        if it is a proved Pontryagin extremal (see the module notes).

    Raises
    ------
    FlexmotionError
        ``coulomb_force`` out of range.
    SolverError
        If continuation from the frictionless optimum fails or the result
        misses the target in the exact friction simulation.
    """
    t0 = time.perf_counter()
    F = check_coulomb_force(coulomb_force, problem.u_max)
    base = plan_time_optimal(problem)
    model = problem.model
    lb = rigid_friction_time(model, problem.u_max, F, problem.x0, problem.target)
    if base.duration == 0.0:
        cert = FrictionCertificate(
            passed=True,
            switch_residual=0.0,
            extra_zeros=0,
            unproved_cells=0,
            sign_consistent=True,
            hamiltonian_max_abs=0.0,
            costate_final=np.zeros(model.n_states),
            message="already at rest",
        )
        return FrictionProfile(
            problem=problem,
            coulomb_force=F,
            switch_times=np.empty(0),
            levels=base.levels,
            duration=0.0,
            final_state=problem.x0.copy(),
            final_state_error=0.0,
            final_state_error_relative=0.0,
            reversals=np.empty(0),
            certificate=cert,
            frictionless_duration=0.0,
            lower_bound=lb,
            continuation_steps=0,
            solve_time_s=time.perf_counter() - t0,
        )
    levels = np.asarray(base.levels, float)
    # per-state scale: how large each state gets during the frictionless move
    u0 = base.input()
    grid = np.linspace(0.0, base.duration, 65)
    fs0 = FrictionSystem.for_model(model, 0.0, closed_form=True)
    xs = fs0.run(problem.x0, u0, grid).states
    xf = model.rest_state(problem.target if problem.target is not None else 0.0)
    scale = np.max(np.abs(xs - xf), axis=0) + np.abs(problem.x0 - xf)
    scale = np.where(scale > 0.0, scale, 1.0)
    lam0 = np.asarray(base.certificate.costate_final, float)
    y = np.concatenate([base.switch_times, [base.duration], lam0])

    def solve(levels, F_try, y):
        ext = Extremal(problem, levels, F_try, scale)
        ext.sig_scale = _sigma_scale(ext, y)
        ok, y_new, _ = ext.newton(y)
        return ok, ext, y_new

    done, step, steps = 0.0, F, 0
    ext = None
    strict = True  # follow structure changes; False: keep the structure (a feasible move, not an extremal)
    while ext is None or done < F:
        F_try = min(F, done + step)
        ok, ext_new, y_new = solve(levels, F_try, y)
        steps += 1
        lev_new = levels
        if ok and strict:
            # the sign changes of B^T lambda must be the switches: re-solve with switches where they are
            ok = False
            for _ in range(4):
                zeros, sign0 = switching_zeros(ext_new, y_new)
                if zeros is None:
                    break
                if same_switches(zeros, ext_new.unpack(y_new)[0], y_new[ext_new.L]):
                    ok = True
                    break
                lev_new = problem.u_max * sign0 * (1.0 - 2.0 * (np.arange(zeros.size + 1) % 2))
                ok2, ext_new, y_new = solve(lev_new, F_try, np.concatenate([zeros, y_new[ext_new.L :]]))
                if not ok2:
                    break
        if ok:
            levels, y, done, ext = lev_new, y_new, F_try, ext_new
            step = min(2.0 * step, F - done) if done < F else step
        else:
            step *= 0.5
            if step < 1e-2 * max(F, 1e-300):
                # a pair of switches may have merged (its interval shrinks to zero where the
                # structure ends): drop the closest pair and re-solve at the last friction force
                t_sw, T_cur = y[: levels.size - 1], y[levels.size - 1]
                gaps = np.diff(t_sw)
                dropped = False
                if gaps.size and gaps.min() < 0.1 * T_cur and steps <= 200:
                    k = int(np.argmin(gaps))
                    lev2, y2 = np.delete(levels, [k + 1, k + 2]), np.delete(y, [k, k + 1])
                    ok2, ext2, y2 = solve(lev2, done, y2)
                    if ok2:
                        levels, y, ext, dropped = lev2, y2, ext2, True
                        step = max(F - done, 0.0) * 0.25
                if not dropped and strict:
                    # the switching function changes sign where the structure cannot follow (e.g. at a
                    # velocity reversal, where the costate jumps): go on with this structure; the move
                    # stays exact and is checked, the certificate will say it is not an extremal
                    strict, dropped = False, True
                    step = max(F - done, 0.0)
                if not dropped:
                    raise SolverError(
                        f"friction planner: continuation from the frictionless optimum stalled at coulomb_force = {done:g} N "
                        f"(the switch structure changes); nothing is returned"
                    )
    return _assemble_friction(ext, y, base, lb, steps, t0)


def _sigma_scale(ext: Extremal, y: np.ndarray) -> float:
    """Scale of ``B^T lambda`` (fixed during one Newton solve)."""
    lam = ext.unpack(y)[2]
    return max(float(np.max(np.abs(lam))) * float(np.max(np.abs(ext.sys.B))), 1e-300)


def _assemble_friction(
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
    reversals = np.array([t for t, kind, _ in run.events if kind == "reversal" and t < T * (1.0 - 1e-12)])
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
