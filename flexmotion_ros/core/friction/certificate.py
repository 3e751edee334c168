"""Certificate of a bang-bang move under Coulomb friction: the hybrid Pontryagin conditions.

Along the exact friction trajectory of a move from
:func:`~.time_optimal.plan_time_optimal_friction` the switching
function ``B^T lambda`` (with the costate jumps at velocity reversals) must
vanish at every switch, change sign nowhere else (proved per costate piece by
:func:`~.switching.isolate_roots`), have the sign of ``-u`` on every interval,
and the Hamiltonian must be zero.  These are necessary conditions only: the
friction system is not linear, so global time-optimality is not proved
(:data:`CLAIM`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

from ..model.boundary import MoveProblem
from ..simulation.exact import PiecewiseConstant
from ..simulation.modal_response import ModalResponse
from ..time_optimal.switching import isolate_roots, sample_grid
from ..tolerances import HAMILTONIAN_TOL, SWITCH_RESIDUAL_TOL
from .extremal import LINE_SEARCH_HALVINGS, Extremal, newton_solve

CLAIM = (
    "Pontryagin extremal of the piecewise-linear friction system (hybrid maximum principle, costate jumps at "
    "velocity reversals): necessary conditions only; global time-optimality is not proved (friction makes the "
    "reachable sets non-convex); lower_bound_s is a proved bound"
)


class FrictionStatus(str, Enum):
    """What was proved about a move under friction (:attr:`FrictionCertificate.status`).

    None of them claims global time-optimality (friction makes the reachable
    sets non-convex); every returned move passed the exact event-located check
    (rest at the target, ``|u| <= u_max``) whatever its status.
    """

    #: The hybrid Pontryagin conditions hold, with the sign structure proved per costate piece (:data:`CLAIM`).
    EXTREMAL = "extremal"
    #: An exact bang-bang move whose extremal check failed (the message says which condition).
    NOT_EXTREMAL = "exact_not_extremal"
    #: An exact piecewise-constant move (the fewest-sample LP at a coarse rate); no extremal was found.
    SAMPLED = "exact_sampled"
    #: An exact sampled move (often with stick arcs) whose discrete-time Pontryagin conditions for its own
    #: velocity-sign/stick pattern were checked by LP duality (:mod:`.sampled_certificate`): the least peak
    #: for that pattern at its sample count.  Weaker than ``EXTREMAL``: the pattern and the count are
    #: searched, nothing continuous is claimed, so :attr:`FrictionCertificate.passed` stays False.
    SAMPLED_PATTERN = "exact_sampled_pattern_optimal"
    #: Already at rest at the target: nothing to do.
    AT_REST = "at_rest"

    def __str__(self) -> str:
        return str(self.value)

    @property
    def sampled(self) -> bool:
        """Whether the move is a sampled one (``SAMPLED`` or ``SAMPLED_PATTERN``: levels held per sample)."""
        return self in (FrictionStatus.SAMPLED, FrictionStatus.SAMPLED_PATTERN)


#: What an ``exact_sampled`` move claims.
SAMPLED_CLAIM = (
    "exact piecewise-constant move (the fewest samples found at a coarse rate for its velocity-sign pattern, "
    "checked by the event-located friction simulation); no optimality is claimed; lower_bound_s is a proved bound"
)


@dataclass(frozen=True, kw_only=True)
class FrictionCertificate:
    """Evidence that a bang-bang move under friction is a Pontryagin extremal of the piecewise system.

    Frozen and keyword-only: build it with every value final.

    Attributes
    ----------
    passed : bool
        ``B^T lambda`` vanishes at every switch, changes sign nowhere else
        (proved per costate piece, :func:`~.switching.isolate_roots`), has the
        sign of ``-u`` on every interval, and ``H = 0`` along the move.
    switch_residual : float
        ``max_j |B^T lambda(t_j)|`` relative to ``max_t |B^T lambda(t)|``.
    extra_zeros, unproved_cells : int
    sign_consistent : bool
    hamiltonian_max_abs : float
    costate_final : ndarray
        ``lambda(T)`` (``H = 1 + lambda^T x'``).
    claim : str
        What is and is not proved (default :data:`CLAIM`).
    message : str
        Why it failed, ``"ok"``, or a note (``"already at rest"``).
    status : FrictionStatus
        What was proved (default: ``EXTREMAL`` if ``passed``, else ``NOT_EXTREMAL``).
    """

    passed: bool
    switch_residual: float
    extra_zeros: int
    unproved_cells: int
    sign_consistent: bool
    hamiltonian_max_abs: float
    costate_final: np.ndarray
    claim: str = CLAIM
    message: str = "ok"
    status: FrictionStatus | None = None

    @classmethod
    def unproved(
        cls, *, message: str, costate_final: np.ndarray, claim: str = CLAIM, status: FrictionStatus | None = None
    ) -> FrictionCertificate:
        """A certificate that proves nothing (every check failed or was not run), saying why in ``message``."""
        return cls(
            passed=False,
            switch_residual=math.inf,
            extra_zeros=0,
            unproved_cells=0,
            sign_consistent=False,
            hamiltonian_max_abs=math.inf,
            costate_final=costate_final,
            claim=claim,
            message=message,
            status=status,
        )

    def __post_init__(self) -> None:
        if self.status is None:
            status = FrictionStatus.EXTREMAL if self.passed else FrictionStatus.NOT_EXTREMAL
            object.__setattr__(self, "status", status)

    def to_dict(self) -> dict:
        """JSON-friendly summary."""
        return {
            "passed": bool(self.passed),
            "switch_residual": float(self.switch_residual),
            "extra_zeros": int(self.extra_zeros),
            "unproved_cells": int(self.unproved_cells),
            "sign_consistent": bool(self.sign_consistent),
            "hamiltonian_max_abs": float(self.hamiltonian_max_abs),
            "costate_final": [float(v) for v in self.costate_final],
            "claim": self.claim,
            "message": self.message,
            "status": str(self.status),
        }


def same_switches(zeros: np.ndarray, t_sw: np.ndarray, T: float) -> bool:
    return zeros.size == t_sw.size and bool(np.all(np.abs(zeros - t_sw) <= 1e-9 * T))


def switching_zeros(ext: Extremal, y: np.ndarray):
    """Sign changes of ``B^T lambda`` on ``(0, T)`` (proved per costate piece) and the sign of ``u`` at the start.

    Returns ``(zeros, sign0)``, or ``(None, 0)`` if the contact sticks or a cell is unproved.
    """
    zeros, unproved, _, lam0 = _zeros_detail(ext, y)
    if zeros is None or unproved:
        return None, 0.0
    return zeros, float(-np.sign(ext.sys.B @ lam0) or 1.0)


def _zeros_detail(ext: Extremal, y: np.ndarray):
    t_sw, T, lam = ext.unpack(y)
    sysf = ext.sys
    u = PiecewiseConstant.from_switches(t_sw, ext.levels, T)
    run = sysf.run(ext.problem.x0, u, [T], lock_after=float(t_sw[-1]) if ext.L else 0.0)
    Lams = ext.costates(run, lam)
    if Lams is None:
        return None, 0, 0.0, lam
    system = ModalResponse(ext.problem.model, True)
    segs = run.segments
    # costate pieces: maximal runs of segments without a reversal
    pieces, start = [], 0
    for i in range(1, len(segs) + 1):
        if i == len(segs) or segs[i][2] != segs[i - 1][2]:
            pieces.append((start, i - 1))
            start = i
    unproved = 0
    sig_max = 0.0
    found = []
    for a, b in pieces:
        ta, tb = segs[a][0], segs[b][1]
        nu = -np.linalg.solve(sysf.transition(segs[b][1] - segs[b][0]).T, Lams[b] @ lam)  # -lambda(tb^-)
        length = tb - ta
        iso = isolate_roots(system, nu, length, sample_grid(system, length, density=2.0))
        unproved += iso.unproved
        found += list(tb - iso.roots)
        grid = np.linspace(0.0, length, 257)
        sig_max = max(sig_max, float(np.max(np.abs(system.switching(nu, grid)))))
    found = np.sort(np.array(found))
    found = found[(found > 0.0) & (found < T)]
    return found, unproved, sig_max, Lams[0] @ lam


def certify_friction(ext: Extremal, y: np.ndarray) -> FrictionCertificate:
    """Check the hybrid Pontryagin conditions along the exact friction trajectory."""
    t_sw, T, lam = ext.unpack(y)
    sysf = ext.sys
    u = PiecewiseConstant.from_switches(t_sw, ext.levels, T)
    run = sysf.run(ext.problem.x0, u, [T], lock_after=float(t_sw[-1]) if ext.L else 0.0)
    Lams = ext.costates(run, lam)
    found, unproved, sig_max, _ = _zeros_detail(ext, y)
    if Lams is None or found is None:
        return FrictionCertificate.unproved(message="the contact sticks during the move", costate_final=lam)
    segs = run.segments
    extra = 0
    sign_ok = True
    tol = 1e-9 * T
    matched = np.zeros(t_sw.size, bool)
    for z in found:
        k = int(np.argmin(np.abs(t_sw - z))) if t_sw.size else -1
        if k >= 0 and not matched[k] and abs(t_sw[k] - z) <= tol:
            matched[k] = True
        else:
            extra += 1
    extra += int(np.count_nonzero(~matched))
    # sign on every segment (between switches and reversals: B^T lambda jumps at a reversal),
    # and the Hamiltonian at every segment start
    starts = np.array([s[0] for s in segs])
    for i, (t0i, t1i, _, level) in enumerate(segs):
        if t1i <= t0i:
            continue
        h = 0.5 * (t1i - t0i)
        sig = float(sysf.B @ np.linalg.solve(sysf.transition(h).T, Lams[i] @ lam))  # lambda at the midpoint
        if np.sign(-sig) != np.sign(level):
            sign_ok = False
    H = [1.0 + float((Lams[i] @ lam) @ sysf.field(run.starts[i], segs[i][3], segs[i][2])) for i in range(len(segs))]
    ham = float(np.max(np.abs(H)))
    sig_sw = [float(sysf.B @ (Lams[int(np.argmin(np.abs(starts - tj)))] @ lam)) for tj in t_sw]
    resid = float(np.max(np.abs(sig_sw)) / sig_max) if t_sw.size and sig_max > 0 else 0.0
    reasons = []
    if resid > SWITCH_RESIDUAL_TOL:
        reasons.append(f"switching function not zero at a switch (residual {resid:.2e})")
    if extra:
        reasons.append(f"switching function has {extra} sign change(s) that are not switches")
    if unproved:
        reasons.append(f"{unproved} cell(s) not proved zero-free")
    if not sign_ok:
        reasons.append("levels do not follow u = -u_max sgn(B^T lambda)")
    if not ham <= HAMILTONIAN_TOL:
        reasons.append(f"Hamiltonian not zero (max |H| = {ham:.2e})")
    return FrictionCertificate(
        passed=not reasons,
        switch_residual=resid,
        extra_zeros=extra,
        unproved_cells=unproved,
        sign_consistent=sign_ok,
        hamiltonian_max_abs=ham,
        costate_final=lam,
        claim=CLAIM,
        message="; ".join(reasons) or "ok",
    )


#: Re-solves with the switches moved to the sign changes of B^T lambda.
CONSISTENCY_ROUNDS = 4


def consistent_switches(
    problem: MoveProblem,
    ext: Extremal,
    y: np.ndarray,
    F: float,
    scale: np.ndarray,
    budget: list[int] | None = None,
    resolve_evals: int | None = None,
    halvings: int = LINE_SEARCH_HALVINGS,
) -> tuple[Extremal, np.ndarray] | None:
    """Move the switches to the sign changes of ``B^T lambda`` and re-solve until they agree; None if not.

    ``budget``: residual evaluations left, shared with the caller (``[n]``, decremented in place);
    ``resolve_evals``: at most this many of them for each re-solve (None: no cap of its own);
    ``halvings``: line-search trials of the re-solves (see :meth:`~.extremal.Extremal.newton`).
    """
    for _ in range(CONSISTENCY_ROUNDS):
        zeros, sign0 = switching_zeros(ext, y)
        if zeros is None:
            return None
        if same_switches(zeros, ext.unpack(y)[0], y[ext.L]):
            return ext, y
        levels = problem.u_max * sign0 * (1.0 - 2.0 * (np.arange(zeros.size + 1) % 2))
        local = budget
        if resolve_evals is not None:
            local = [resolve_evals if budget is None else min(resolve_evals, budget[0])]
        left = local[0] if local is not None else 0
        ok, ext, y = newton_solve(
            problem, levels, F, scale, np.concatenate([zeros, y[ext.L :]]), budget=local, halvings=halvings
        )
        if budget is not None and local is not budget:
            budget[0] -= left - local[0]
        if not ok:
            return None
    return None
