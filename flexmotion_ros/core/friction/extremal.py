"""The bang-bang extremal of a move under Coulomb friction: unknowns, residual, Newton.

Shared by the planner (:mod:`.time_optimal`) and its certificate
(:mod:`.certificate`).
"""

from __future__ import annotations

import math

import numpy as np

from ..model.boundary import MoveProblem
from ..simulation.exact import PiecewiseConstant
from .contact import STICK, FrictionRun, FrictionSystem

#: Newton on the extremal has converged when the scaled residual is below this.
NEWTON_TOL = 1e-12
#: Halvings of a Newton step before the solve gives up (was 20: a direction that needs a step below
#: 1/256 was, in the fuzz profile, one that never converged, and each halving costs an exact run).
LINE_SEARCH_HALVINGS = 8


class Extremal:
    """Shooting map of the hybrid Pontryagin conditions for one problem and friction force."""

    def __init__(self, problem: MoveProblem, levels: np.ndarray, F: float, scale: np.ndarray) -> None:
        m = problem.model
        self.problem = problem
        self.sys = FrictionSystem.for_model(m, F, closed_form=True)
        self.check = FrictionSystem.for_model(m, F)  # matrix exponentials: the independent check
        self.x0 = problem.x0
        self.xf = m.rest_state(problem.target if problem.target is not None else 0.0)
        self.I = np.arange(m.n_states) if problem.include_position else np.arange(1, m.n_states)
        self.levels = levels
        self.L = levels.size - 1
        self.s = scale
        self.sig_scale = 1.0
        #: Residual evaluations left (shared by the caller across solves: a list of one int); None: no limit.
        self.budget: list[int] | None = None
        #: The switching rows' columns in ``(t_j, T)`` (unscaled) to start :meth:`newton` from: an earlier
        #: solve's (None: differences).
        self.block_start: np.ndarray | None = None
        #: After :meth:`newton` (unscaled): the block differenced at its starting point (None if it started from
        #: ``block_start`` or had no reversal) and the block of its last iterate.
        self.block_first: np.ndarray | None = None
        self.block_last: np.ndarray | None = None
        #: ``(y, run)`` of the last point evaluated with the Jacobian, its run recorded (differences resume it).
        self._jac_run: tuple[np.ndarray, FrictionRun] | None = None

    def unpack(self, y: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
        lam = np.zeros(self.sys.n)
        lam[self.I] = y[self.L + 1 :]
        return y[: self.L], float(y[self.L]), lam

    def valid(self, y: np.ndarray) -> bool:
        t, T = y[: self.L], y[self.L]
        return bool(T > 0.0 and (self.L == 0 or (t[0] > 0.0 and t[-1] < T and np.all(np.diff(t) > 0.0))))

    def costates(self, run: FrictionRun, lamT: np.ndarray):
        """``Lambda(t)`` with ``lambda(t) = Lambda(t) lambda(T)`` at every segment start (backward sweep).

        ``Lambda(t)^T`` is also the sensitivity ``dx(T)/dx(t)`` of the hybrid flow: ``e^{A h}`` on
        each segment and the saltation matrix at each reversal (None if the contact sticks).
        """
        sysf = self.sys
        n = sysf.n
        Lam = np.eye(n)
        out = [None] * len(run.segments)
        lengths = run.lengths if len(run.lengths) == len(run.segments) else None
        for i in range(len(run.segments) - 1, -1, -1):
            t0, t1, mode, level = run.segments[i]
            if mode == STICK:
                return None
            # the run's own step length: its step matrices are cached (t1 - t0 may differ in the last bit
            # and cost a second closed form per segment, a fifth of a Newton residual)
            Lam = sysf.transition(lengths[i] if lengths is not None else t1 - t0).T @ Lam
            out[i] = Lam
            if i > 0 and run.segments[i - 1][2] != mode:  # a reversal at t0: saltation matrix
                xc = run.starts[i]
                fm = sysf.field(xc, run.segments[i - 1][3], run.segments[i - 1][2])
                fp = sysf.field(xc, level, mode)
                Sal = np.eye(n) + np.outer(fp - fm, sysf.contact.C) / float(sysf.contact.C @ fm)
                Lam = Sal.T @ Lam
        return out

    def residual(self, y: np.ndarray, want_lam_jac: bool = False, column: int = -1, below: float = math.inf):
        """The scaled conditions at ``y`` (and, with ``want_lam_jac``, the Jacobian but for the switching
        rows' columns in ``(t_j, T)``, and whether the run reverses).

        ``column``: ``y`` differs from the last point evaluated with ``want_lam_jac`` in ``y[column]`` only (a
        difference): the exact run resumes at the switch before it (the same numbers, the common part of
        the run not repeated).  ``below``: the Jacobian only if the residual's largest entry is below this (a
        line-search trial that does not lower the residual has no use for it): ``(r, None, False)`` otherwise."""
        if self.budget is not None:
            if self.budget[0] <= 0:
                return None  # out of evaluations: the solve fails (the caller moves on)
            self.budget[0] -= 1
        t_sw, T, lam = self.unpack(y)
        u = PiecewiseConstant.from_switches(t_sw, self.levels, T)
        lock = float(t_sw[-1]) if self.L else 0.0
        base = self._jac_run
        if column >= 1 and base is not None and np.array_equal(y[:column], base[0][:column]):
            # the breaks and levels up to the switch before y[column] are the base run's
            run = self.sys.run(self.x0, u, [T], lock_after=lock, resume=(base[1], column - 1))
        else:
            run = self.sys.run(self.x0, u, [T], lock_after=lock, record=want_lam_jac)
        if want_lam_jac:
            self._jac_run = (y.copy(), run)
        xT = run.states[0]
        r1 = (xT - self.xf)[self.I] / self.s[self.I]
        Lams = self.costates(run, lam)
        if Lams is None:
            return None
        at = segment_at(run, t_sw)
        rows = []
        for i in at:
            rows.append(self.sys.B @ Lams[i])
        rows = np.array(rows).reshape(self.L, -1)
        sigma = rows @ lam / self.sig_scale
        fT = self.sys.field(xT, float(self.levels[-1]), run.segments[-1][2])
        H = 1.0 + float(lam @ fT)
        r = np.concatenate([r1, sigma, [H]])
        if not want_lam_jac:
            return r
        if not float(np.max(np.abs(r))) < below:
            return r, None, False
        # Jacobian: in lambda(T) exactly; in (t_j, T) in closed form along the exact trajectory
        # (the costate does not depend on x between reversals; through reversal times it does:
        # those columns of the switching rows are differenced by the caller)
        nI, L, A, B = self.I.size, self.L, self.sys.A, self.sys.B
        J = np.zeros((r.size, L + 1 + nI))
        dx = np.empty((self.sys.n, L + 1))
        AB, ATlam = A @ B, A.T @ lam
        for j, i in enumerate(at):
            dx[:, j] = Lams[i].T @ B * (self.levels[j] - self.levels[j + 1])
            lam_j = Lams[i] @ lam
            J[nI + j, j] = -float(AB @ lam_j) / self.sig_scale
            J[nI + j, L] = float((Lams[i].T @ B) @ ATlam) / self.sig_scale
        dx[:, L] = fT
        J[:nI, : L + 1] = dx[self.I] / self.s[self.I, None]
        J[-1, : L + 1] = (lam @ A) @ dx
        J[nI : nI + L, L + 1 :] = rows[:, self.I] / self.sig_scale
        J[-1, L + 1 :] = fT[self.I]
        reversals = any(kind == "reversal" for _, kind, _ in run.events)
        return r, J, reversals

    def newton(
        self, y: np.ndarray, max_iter: int = 30, halvings: int = LINE_SEARCH_HALVINGS
    ) -> tuple[bool, np.ndarray, float]:
        """Damped Newton on the extremal conditions from ``y``; returns ``(converged, y, residual)``.

        ``halvings``: trial steps of the line search (``1, 1/2, 1/4, ...``); a Newton step whose
        ``halvings`` trials all fail to lower the residual ends the solve (not converged)."""
        out = self.residual(y, True)
        if out is None:
            return False, y, math.inf
        r, J, reversals = out
        rn = float(np.max(np.abs(r)))
        nz, nI, L = self.L + 1, self.I.size, self.L
        sw = slice(nI, nI + L)  # the switching rows
        block = None  # their columns in (t_j, T) by differences, or updated along the steps (Broyden)
        fresh = False
        if self.block_start is not None and self.block_start.shape == (L, nz):
            # an earlier solve's block (the continuation's last force, or a failed solve's start): treated as an
            # updated one, so a step it misleads takes the differences again
            block = self.block_start / self.sig_scale
        at_start = True
        refreshed = 0  # differences taken again after an updated block's step failed (at most once a solve)
        for _ in range(max_iter):
            if rn <= NEWTON_TOL:
                return True, y, rn
            if reversals and L and block is None:
                # one-sided differences (one evaluation per column, not two): an O(h) error of ~1e-7 in
                # these columns slows Newton's last steps only slightly, and the residual, not the
                # Jacobian, decides convergence; the evaluations are what a failing solve burns
                knots = np.concatenate([[0.0], y[:nz]])
                hstep = min(1e-7 * y[self.L], 0.25 * float(np.min(np.diff(knots))))
                for j in range(nz):
                    yp = y.copy()
                    yp[j] += hstep
                    if not self.valid(yp):
                        yp[j] -= 2.0 * hstep
                        if not self.valid(yp):
                            return False, y, rn
                    rp = self.residual(yp, column=j)
                    if rp is None:
                        return False, y, rn
                    J[sw, j] = (rp - r)[sw] / (yp[j] - y[j])
                block, fresh = J[sw, :nz].copy(), True
                if at_start:
                    self.block_first = block * self.sig_scale
            elif reversals and L:
                J[sw, :nz] = block  # the differences of an earlier iterate, updated by the steps since
            step, *_ = np.linalg.lstsq(J, -r, rcond=None)
            tt = 1.0
            for _ in range(halvings):
                yc = y + tt * step
                if self.valid(yc):
                    oc = self.residual(yc, True, below=rn)
                    if oc is not None and float(np.max(np.abs(oc[0]))) < rn:
                        break
                tt *= 0.5
            else:
                if block is not None and not fresh and not refreshed:
                    # an updated block may mislead: differences again before giving up (once: a solve that
                    # fails again leaves the continuation's budget to smaller steps of the force)
                    block, refreshed = None, 1
                    continue
                return rn <= 1e3 * NEWTON_TOL, y, rn
            if block is not None and oc[2]:
                # Broyden's update of the difference columns: two exact runs tell how the switching rows
                # moved along the step; the analytic columns (in lambda) are the new iterate's.  Differences
                # at every iterate were most of a solve's runs (L + 1 of L + 2 per step)
                d = yc - y
                dt_ = d[:nz]
                moved = (oc[0] - r)[sw] - oc[1][sw, nz:] @ d[nz:]
                nn = float(dt_ @ dt_)
                block = block + np.outer(moved - block @ dt_, dt_) / nn if nn > 0.0 else None
                fresh = False
            else:
                block = None
            y = yc
            r, J, reversals = oc
            rn = float(np.max(np.abs(r)))
            at_start = False
            self.block_last = None if block is None else block * self.sig_scale
        return rn <= NEWTON_TOL, y, rn


def segment_at(run: FrictionRun, times: np.ndarray) -> list[int]:
    """Index of the segment of ``run`` that starts nearest each of ``times`` (s), the first of equals.

    A switch time is a break of the input, so a segment starts exactly there: looked up, not searched (the
    search, ``argmin |starts - t|``, stays for a time that is not a segment start)."""
    first: dict[float, int] = {}
    for i, seg in enumerate(run.segments):
        first.setdefault(seg[0], i)
    out = []
    starts = None
    for t in np.asarray(times, float).tolist():
        i = first.get(t)
        if i is None:
            if starts is None:
                starts = np.array([seg[0] for seg in run.segments])
            i = int(np.argmin(np.abs(starts - t)))
        out.append(i)
    return out


def sigma_scale(ext: Extremal, y: np.ndarray) -> float:
    """Scale of ``B^T lambda`` (fixed during one Newton solve)."""
    lam = ext.unpack(y)[2]
    return max(float(np.max(np.abs(lam))) * float(np.max(np.abs(ext.sys.B))), 1e-300)


def newton_solve(
    problem: MoveProblem,
    levels: np.ndarray,
    F: float,
    scale: np.ndarray,
    y: np.ndarray,
    max_iter: int = 20,
    budget: list[int] | None = None,
    halvings: int = LINE_SEARCH_HALVINGS,
    block: np.ndarray | None = None,
) -> tuple[bool, Extremal, np.ndarray]:
    """Newton on the extremal conditions for ``levels`` from ``y``: ``(converged, extremal, y)``.

    ``budget``: residual evaluations left, shared across solves (``[n]``, decremented in place);
    ``halvings``: see :meth:`Extremal.newton`; ``block``: see :attr:`Extremal.block_start`.
    """
    ext = Extremal(problem, levels, F, scale)
    ext.budget = budget
    ext.block_start = block
    ext.sig_scale = sigma_scale(ext, y)
    ok, y_new, _ = ext.newton(y, max_iter=max_iter, halvings=halvings)
    return ok, ext, y_new
