"""Shaped rigid-body commands, continuous and sampled at the node's rate.

A shaper (``core.shapers``) convolved with a command ``u``::

    u_s(t) = sum_i A_i u(t - t_i)

cancels the residual vibration of its design modes whatever ``u`` is, and,
since ``sum A_i = 1`` and the plant is linear and time-invariant, brings the
rigid body to the same final state as ``u`` (``shape`` of the rigid
time-optimal bang-bang therefore still ends at rest at the target).

The bound ``|u| <= u_max``
--------------------------
* Positive shapers (ZV, ZVD, ZVDD, MZV, EI family): ``u_s(t)`` is a convex
  combination of values of ``u``, so ``|u_s| <= max |u|``: the bound holds
  for *any* command within it.
* Shapers with negative impulses (SNA, UM): ``|u_s| <= sum |A_i| max |u|``.
  Applied to a step, the partial sums of ``A`` decide the peak (UM and SNA
  with ``P <= 2`` keep it); applied to a bang-bang they keep it only if every
  constant segment outlasts the shaper (then at most one transition is in
  progress at a time).  When a shaped bang-bang would exceed ``u_max``, the
  rigid command's level is lowered until it does not (``level`` in the
  result); this lengthens the move.  The bound is never exceeded.

The sampled version at the node's rate: :mod:`.sampled_shaped`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..errors import GoalError, SolverError
from ..model.boundary import MoveProblem
from ..simulation.exact import (
    PiecewiseConstant,
    modal_amplitudes,
)
from ..time_optimal.solver import plan_time_optimal
from ..tolerances import FINAL_STATE_RTOL, RESIDUAL_RTOL
from .sensitivity import command_vibration
from .shaped_command import ShapedCommand, exact_end
from .shaper import Shaper

#: Steps of a shaped command closer than this many ``eps T`` (``T`` its duration) are one step.
BREAK_MERGE_ULPS = 16


def shape(u: PiecewiseConstant, shaper: Shaper) -> PiecewiseConstant:
    """Exact convolution of a piecewise-constant command with a shaper."""
    T = u.duration + shaper.duration
    # sum_i A_i u(t - t_i) as a sum of steps: u jumps by J_k at its breaks b_k, so the shaped
    # command jumps by A_i J_k at t_i + b_k.  The running sum of the sorted steps (extended
    # precision) replaces one evaluation of u per impulse at every piece: 6,561 impulses (an
    # 8-mode ZVD) on 13,000 pieces were 0.6 s, now a sort (one: the breaks are the sorted step
    # times, a second sort by np.unique was a third of an 8-mode UM-ZVD plan).
    jumps = np.diff(np.concatenate([[0.0], u.levels, [0.0]]))
    at = (shaper.times[:, None] + u.breaks[None, :]).ravel()
    weight = (np.asarray(shaper.amplitudes, float)[:, None] * jumps[None, :]).ravel()
    order = np.argsort(at, kind="stable")
    at_sorted = at[order]
    # the distinct step times, less those within rounding of the previous distinct one (coincident
    # switches of shifted copies: sums t_i + b_k below T carry a few eps T).  It was 1e-12 T: on
    # 8-mode UM-ZVD commands of 81,000-407,000 s (fuzz cases 257, 362, 886) that merged real steps
    # 0.1-0.4 us apart, and the residual vibration the 390,625 unit impulses must cancel came out
    # 2e-8 to 3e-7 of a step (the ideal convolution: 1e-17); the planner refused them
    merge = BREAK_MERGE_ULPS * np.finfo(float).eps * max(T, 1e-300)
    breaks = at_sorted[np.concatenate([[True], np.diff(at_sorted) > merge])]
    breaks[-1] = T
    mids = 0.5 * (breaks[:-1] + breaks[1:])
    running = np.cumsum(weight[order].astype(np.longdouble))
    count = np.searchsorted(at_sorted, mids, side="right")
    levels = np.where(count > 0, running[np.maximum(count - 1, 0)], 0.0).astype(float)
    return PiecewiseConstant(breaks, levels)


def shape_function(f: Callable[[np.ndarray], np.ndarray], shaper: Shaper) -> Callable[[np.ndarray], np.ndarray]:
    """A shaped reference ``t -> sum A_i f(t - t_i)`` (step, ramp, any trajectory with ``f = f(0)`` for t < 0)."""

    def shaped(t):
        t = np.asarray(t, dtype=float)
        return sum(a * f(t - ti) for ti, a in zip(shaper.times, shaper.amplitudes))

    return shaped


def step_command(level: float, duration: float) -> PiecewiseConstant:
    """A constant command ``level`` held for ``duration`` (s)."""
    return PiecewiseConstant(np.array([0.0, float(duration)]), np.array([float(level)]))


def rigid_command(problem: MoveProblem, level: float) -> PiecewiseConstant:
    """Time-optimal bang-bang for the rigid body alone with ``|u| <= level``.

    Rest-to-rest or motion-to-rest moves whose modes start at rest (what
    shaping can serve); the modes are ignored.
    """
    model = problem.model
    b0, c = model.b0, model.c
    a = abs(b0) * level  # largest acceleration (units/s^2)
    p0, v0 = float(problem.x0[0]), float(problem.x0[1])
    if problem.target is None or (v0 == 0.0 and c == 0.0):  # closed forms
        if problem.target is None:  # one pulse against the velocity
            T = abs(v0) / a if c == 0.0 else math.log1p(-c * abs(v0) / a) / -c
            return PiecewiseConstant(np.array([0.0, T]), np.array([-math.copysign(level, v0 * b0)]))
        gamma = problem.target - p0
        T = 2.0 * math.sqrt(abs(gamma) / a)
        s = math.copysign(level, gamma * b0)
        return PiecewiseConstant(np.array([0.0, 0.5 * T, T]), np.array([s, -s]))
    rigid = model.with_changes(omega=(), zeta=(), b=(), names=())
    sub = MoveProblem(rigid, level, problem.x0[:2], problem.target)
    return plan_time_optimal(sub).input()


@dataclass
class ShapedProfile:
    """A shaped rigid-body move and its checks.

    Attributes
    ----------
    problem : MoveProblem
    shaper : Shaper
    command : PiecewiseConstant
        The shaped input (N or the model's input unit), ``|u| <= u_max``.
    rigid : PiecewiseConstant
        The unshaped rigid-body command.
    level : float
        Bound used for the rigid command (``u_max`` unless lowered to keep a
        negative shaper's output within ``u_max``).
    final_state : ndarray
        State at the end (absolute), exact simulation.
    final_state_error : float
        Largest rigid-body error (position, velocity) at the end.
    residual : ndarray
        Residual vibration amplitude of each mode (modal units), exact simulation.
    residual_percent : ndarray
        The same relative to a step of ``u_max`` (see :mod:`.sensitivity`).
    """

    problem: MoveProblem
    shaper: Shaper
    command: PiecewiseConstant
    rigid: PiecewiseConstant
    level: float
    final_state: np.ndarray
    final_state_error: float
    final_state_error_relative: float
    residual: np.ndarray
    residual_percent: np.ndarray
    solve_time_s: float = 0.0
    method: str = "shaped"
    extra: dict = field(default_factory=dict)

    @property
    def duration(self) -> float:
        return self.command.duration

    def input(self) -> PiecewiseConstant:
        return self.command

    def to_dict(self) -> dict:
        """JSON-friendly summary (same keys as a time-optimal profile where they apply)."""
        return {
            "method": self.method,
            "duration": float(self.duration),
            "switch_times": [float(t) for t in self.command.breaks[1:-1]],
            "levels": [float(v) for v in self.command.levels],
            "final_state": [float(v) for v in self.final_state],
            "final_state_error": float(self.final_state_error),
            "final_state_error_relative": float(self.final_state_error_relative),
            "certified": False,
            "certificate": {"passed": False, "message": "input-shaped: not time-optimal, no Pontryagin certificate"},
            "solve_time_s": float(self.solve_time_s),
            "shaper": self.shaper.to_dict(),
            "rigid_level": float(self.level),
            "residual": [float(v) for v in self.residual],
            "residual_percent": [float(v) for v in self.residual_percent],
        }


def largest_level(peak_at, u_max: float, safe: float, rtol: float = 1e-6):
    """Largest rigid-command level ``L <= u_max`` whose shaped command peaks at most ``u_max``.

    ``peak_at(L) -> (peak, payload)``.  ``safe`` is a level known to fit
    (``u_max / sum |A_i|``).  Multiplicative steps ``L <- L u_max / peak``
    find a fitting level; bisection between it and the lowest level above it
    that does not fit then recovers the time lost by overshooting (overlaps
    of shifted copies disappear as the rigid move lengthens).  Returns
    ``(L, payload)``; the payload always fits.
    """
    lim = u_max * (1.0 + 1e-12)
    level, bad = u_max, None
    best = None
    for _ in range(40):
        peak, payload = peak_at(level)
        if peak <= lim:
            best = (level, payload)
            break
        bad = level
        level *= u_max / peak * (1.0 - 1e-9)
    if best is None:
        peak, payload = peak_at(safe)
        best, bad = (safe, payload), bad if bad is not None else u_max
    if bad is not None:  # bisect towards the largest fitting level
        lo, hi = best[0], bad
        while hi - lo > rtol * hi:
            mid = 0.5 * (lo + hi)
            peak, payload = peak_at(mid)
            if peak <= lim:
                lo, best = mid, (mid, payload)
            else:
                hi = mid
    return best


def plan_shaped(problem: MoveProblem, shaper: Shaper, method: str = "shaped") -> ShapedProfile:
    """Shape the rigid-body time-optimal move with ``shaper``; ``|u| <= u_max`` always.

    Raises
    ------
    GoalError
        If the modes are not at rest initially (shaping cannot cancel vibration already present),
        or the command, as stored in double precision, does not cancel the vibration the shaper
        cancels (residual vibrations more than ``RESIDUAL_RTOL`` of a step apart: a very long move).
    """
    t0 = time.perf_counter()
    model, um = problem.model, problem.u_max
    if np.any(problem.x0[2:]):
        raise GoalError("initial_state", "input shaping needs the modes at rest at the start (q = q' = 0)")
    if problem.is_at_rest():  # nothing to do: an empty command
        command = rigid = PiecewiseConstant(np.zeros(1), np.zeros(0))
        return ShapedProfile(
            problem,
            shaper,
            command,
            rigid,
            um,
            problem.x0.copy(),
            0.0,
            0.0,
            np.zeros(model.n_modes),
            np.zeros(model.n_modes),
            time.perf_counter() - t0,
            method,
        )

    def shaped_at(lv: float):
        r = rigid_command(problem, lv)
        if r.duration <= 1e-10 * shaper.duration:
            raise GoalError(
                "goal",
                f"the move is too small to shape: its {r.duration:.3g} s rigid command "
                f"vanishes next to the {shaper.duration:.3g} s shaper in floating point",
            )
        c = shape(r, shaper)
        return c.max_abs(), (r, c)

    level, (rigid, command) = largest_level(shaped_at, um, um / shaper.abs_sum)
    command = ShapedCommand(command.breaks, np.clip(command.levels, -um, um), rigid, shaper.parts())

    xT, rigid_states = exact_end(model, problem.x0, command)  # a long command: by its factors
    target = problem.target
    rigid_err = np.array([0.0 if target is None else xT[0] - target, xT[1]])
    shifted = rigid_states - np.array([target if target is not None else 0.0, 0.0])
    scale = np.max(np.abs(shifted), axis=0)
    # break times carry rounding ~eps T, so velocity errors ~eps T a persist between impulses and the
    # position integrates them over the move: its scale includes max|v| T (matters when T_shaper >> T_rigid)
    scale[0] += scale[1] * command.duration
    scale = np.where(scale > 0.0, scale, 1.0)
    rel = float(np.max(np.abs(rigid_err) / scale))
    if not rel <= FINAL_STATE_RTOL:
        raise SolverError(f"shaped move missed the target: relative rigid-body error {rel:.3e}; nothing is returned")
    residual = modal_amplitudes(model, xT)
    w, z, b = (np.asarray(v, dtype=float) for v in (model.omega, model.zeta, model.b))
    step_amp = np.abs(b) * um / (w * w * np.sqrt(1.0 - z * z))
    vib = command_vibration(command, w, z, um) if model.n_modes else np.zeros(0)
    # the simulation is of the convolution itself (by its factors past MAX_SIMULATED_PIECES), the
    # impulse sum of the command as stored: they differ when the stored command does not realise
    # the convolution (e.g. steps of its shifted copies merged or rounded on a very long move)
    off = np.abs(residual - step_amp * vib) / step_amp
    if np.any(off > RESIDUAL_RTOL):
        i = int(np.argmax(off))
        raise GoalError(
            "goal",
            f"{method}: the {command.duration:.6g} s shaped command ({command.levels.size} pieces, "
            f"{shaper.times.size} shaper impulses of total size {shaper.abs_sum:.6g}) does not cancel mode {i + 1} "
            f"({w[i]:.4g} rad/s) in double precision: residual vibration {vib[i]:.2e} of a full step where the "
            f"shaper leaves {residual[i] / step_amp[i]:.2e} (at most {RESIDUAL_RTOL:g} apart); "
            "shorten the move or shape fewer modes",
        )
    return ShapedProfile(
        problem,
        shaper,
        command,
        rigid,
        level,
        xT,
        float(np.max(np.abs(rigid_err))),
        rel,
        residual,
        100.0 * vib,
        time.perf_counter() - t0,
        method,
    )
