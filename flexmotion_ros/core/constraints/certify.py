"""A second, independent formulation of the limited planner's feasibility question.

HiGHS's "infeasible" verdict on the limit LP of :mod:`.lp` decides claims
("``K - 1`` samples cannot meet the limits", "no number of samples can").  A
verdict is used as a proof only when a second method agrees: this module
builds the same question in another formulation and asks HiGHS's interior
point method (and, if that gives no verdict, its dual simplex) about it.

Formulation: every state at every sample is a variable (``x_1 .. x_K``, the
full modal state in physical coordinates ``[p, v, q_1, q_1', ...]``), linked by
the exact step ``x_{k+1} = Phi x_k + Gamma u_k`` with ``Phi, Gamma`` from
:func:`~flexmotion_ros.core.simulation.exact.step_matrices` (matrix
exponential of the augmented matrix, not the modal closed forms of
:mod:`.responses`); limits are variable bounds (velocity, deflection at the
samples), rows for the deflection between samples (the planner's cuts) and for
the slew rate; ``|u_k| <= u_max``.  Every limit is scaled by ``scale`` (the
caller passes ``1 + LOOSEN`` so that "infeasible" is not a rounding artefact).

:func:`prefix_feasible` asks the same without the arrival: if the limits
cannot be held over the first ``M`` samples whatever the commands, no move of
any length meets them (a ``K``-sample move held at rest after it would).
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy.optimize import linprog
from scipy.sparse import coo_matrix, csr_matrix

from ..model.boundary import MoveProblem
from ..simulation.exact import step_matrices
from .limits import Cut, Limits

#: The methods asked, in order, until one gives a verdict (status 0 or 2).
METHODS = ("highs-ipm", "highs-ds")


def _build(
    problem: MoveProblem, K: int, dt: float, limits: Limits, scale: float, cuts: list[Cut], arrive: bool
) -> dict:
    model = problem.model
    A, B = model.A(), model.B()
    n = A.shape[0]
    Phi, Gam = step_matrices(A, B, dt)
    x0 = np.asarray(problem.x0, float)
    nv = K + n * K  # u_0..u_{K-1}, x_1..x_K

    def xcol(k: int, i) -> np.ndarray:  # column of state i at sample k >= 1
        return K + n * (k - 1) + np.asarray(i)

    r, c, v = [], [], []
    beq = np.zeros(n * K)
    ii = np.arange(n)
    for k in range(K):
        rows = n * k + ii
        r += [rows, rows]
        c += [xcol(k + 1, ii), np.full(n, k)]
        v += [np.ones(n), -Gam]
        if k == 0:
            beq[rows] = Phi @ x0
        else:
            r.append(np.repeat(rows, n))
            c.append(np.tile(xcol(k, ii), n))
            v.append(-Phi.ravel())
    Aeq = coo_matrix((np.concatenate(v), (np.concatenate(r), np.concatenate(c))), shape=(n * K, nv)).tocsr()
    lo = np.full(nv, -np.inf)
    hi = np.full(nv, np.inf)
    lo[:K], hi[:K] = -problem.u_max, problem.u_max
    ks = np.arange(1, K + 1)
    if limits.velocity_max is not None:
        vm = limits.velocity_max * scale
        lo[xcol(ks, 1)], hi[xcol(ks, 1)] = -vm, vm
    for i, qm in enumerate(limits.deflection_max or ()):
        if math.isfinite(qm):
            lo[xcol(ks, 2 + 2 * i)], hi[xcol(ks, 2 + 2 * i)] = -qm * scale, qm * scale
    if arrive:
        xf = model.rest_state(problem.target if problem.target is not None else 0.0)
        last = xcol(K, ii)
        lo[last], hi[last] = xf, xf
        if problem.target is None:  # final position free
            lo[last[0]], hi[last[0]] = -np.inf, np.inf
    ur, uc, uv, ub = [], [], [], []
    row = 0
    for cut in cuts:  # q_i(k dt + s) = e_q^T (Phi_s x_k + Gamma_s u_k), a relaxation of the continuous limit
        if cut.k >= K or limits.deflection_max is None:
            continue
        Ps, Gs = step_matrices(A, B, cut.s)
        j = 2 + 2 * cut.mode
        qm = limits.deflection_max[cut.mode] * scale
        const = float(Ps[j] @ x0) if cut.k == 0 else 0.0
        for sgn in (1.0, -1.0):
            cols = [cut.k]
            vals = [sgn * Gs[j]]
            if cut.k > 0:
                cols += list(xcol(cut.k, ii))
                vals += list(sgn * Ps[j])
            ur += [row] * len(cols)
            uc += cols
            uv += vals
            ub.append(qm - sgn * const)
            row += 1
    if limits.slew_rate is not None:  # |u_k - u_{k-1}| <= slew dt, u_{-1} = 0 (and u_K = 0 on arrival)
        s = limits.slew_rate * dt * scale
        last_edge = K + 1 if arrive else K
        for k in range(last_edge):
            for sgn in (1.0, -1.0):
                if k < K:
                    ur.append(row)
                    uc.append(k)
                    uv.append(sgn)
                if k > 0:
                    ur.append(row)
                    uc.append(k - 1)
                    uv.append(-sgn)
                ub.append(s)
                row += 1
    Aub = csr_matrix((uv, (ur, uc)), shape=(row, nv)) if row else None
    return {
        "A_eq": Aeq,
        "b_eq": beq,
        "A_ub": Aub,
        "b_ub": np.array(ub) if row else None,
        "bounds": np.column_stack([lo, hi]),
    }


def _ask(kw: dict, both: bool = False, deadline: float = math.inf) -> tuple[bool | None, str]:
    """HiGHS's verdict; with ``both``, "infeasible" needs the interior point AND the dual simplex method.

    Past ``deadline`` (``time.perf_counter()``) HiGHS stops: no verdict (None), never "infeasible".
    """
    nv = kw["bounds"].shape[0]
    said = []
    for method in METHODS:
        opts = {} if not math.isfinite(deadline) else {"time_limit": max(0.5, deadline - time.perf_counter())}
        res = linprog(np.zeros(nv), method=method, options=opts, **kw)
        if res.status == 0:
            return True, method
        if res.status == 2:
            said.append(method)
            if not both:
                return False, method
    if both and len(said) == len(METHODS):
        return False, " and ".join(said)
    return None, "no verdict" if not said else f"only {said[0]} said infeasible"


def feasible(
    problem: MoveProblem,
    K: int,
    dt: float,
    limits: Limits,
    scale: float = 1.0,
    cuts: list[Cut] | None = None,
    deadline: float = math.inf,
) -> tuple[bool | None, str]:
    """Does a ``K``-sample sequence reach rest at the target with every limit (times ``scale``) held?

    Returns ``(verdict, method)``: ``verdict`` None when HiGHS decided neither way.
    """
    return _ask(_build(problem, K, dt, limits, scale, list(cuts or ()), True), deadline=deadline)


def prefix_feasible(
    problem: MoveProblem, M: int, dt: float, limits: Limits, scale: float = 1.0
) -> tuple[bool | None, str]:
    """Can the limits (times ``scale``) be held over the first ``M`` samples, with no arrival asked?

    ``False`` only when both HiGHS methods (interior point and dual simplex)
    say so: then no move of any length meets the limits.
    """
    return _ask(_build(problem, M, dt, limits, scale, [], False), both=True)
