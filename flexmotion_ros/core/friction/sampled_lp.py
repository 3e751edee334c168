"""Sampled moves under rigid-body Coulomb friction as linear programs, one velocity-sign pattern at a time.

Between velocity reversals the friction force is a known constant (``-F sgn(v)``
on the rigid body), so for a fixed pattern ``s_k`` of velocity signs (one per
sample interval, reversals on sample instants) the zero-order-hold move is
linear: the state after ``K`` samples is ``Phi^K x0 + sum_k G_k u_k - F sum_k
s_k H_k`` and the velocity at every instant is linear in the commands.
:class:`FrictionLP` solves, for ``K`` samples and a pattern,

    min t   s.t.   |u_k| <= t,   arrival at rest exactly,   s v_j >= 0 at every instant
    (on both sides of it: ``v_j = 0`` where the pattern changes sign),

with the sign rows generated (only the violated ones are added, a few rounds;
with ``c <= 0`` the velocity is monotone within a sample, so signs at the
instants are signs everywhere).  ``t <= u_max`` means ``K`` samples suffice for
this pattern.

Which pattern, and how many samples, is :mod:`.pattern_search`.

A pattern entry 0 holds the body by friction for that sample (stuck:
``v = 0`` at both ends, ``|u_k| <= F``, no effect of ``u_k`` on the rigid
body, the modes driven as ever): moves that must rest on the way while the
modes are steered.

Nothing here is a proof of optimality: a pattern is a guess, and the LP is
exact only for it.  Every sequence a planner returns is checked by the
event-located friction simulation of :mod:`.contact`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter
from scipy.sparse import coo_matrix

from ..linear_program import LpMethod, LpStatus, solve_lp
from ..model.boundary import MoveProblem
from ..sampled.lp_tools import least_norm_correction
from ..tolerances import HIGHS_OPTIONS
from .chain_form import chain_matrix
from .closed_form import ClosedForm
from .lp_work import EffortSpent, lp_effort, lp_iteration_limit

#: HiGHS's presolve on the friction LPs.  Off: these LPs have nothing for it to remove (every sign condition
#: is a bound, the arrival rows are dense) and it cost a third of the solve: the 324 LPs of seed-18 fuzz
#: cases 0, 1, 3, 4, 6, 8, 10, 13 took 0.91-1.08 s CPU without it, 1.38 s with it, same optima (2026-12-05).
PRESOLVE = False
#: Most samples of a monotone pattern's LP solved by sign rows generated (``monotone_rows``).
MONOTONE_ROWS_MAX = 600
#: Rounds of sign-row generation of a monotone pattern's LP before the chain form is asked instead: the
#: structure search's feasible monotone LPs took one (seed-18 cases 0, 9, 13, 88, 93: 50 LPs; the first round
#: has the arrival rows alone, a few hundred microseconds); the infeasible ones of a move that must rest on
#: the way took 4-8 rounds of growing dense rows (case 1: 175 ms at 256 samples, 5 ms in chain form), and
#: two rounds made such moves 20 % slower (cases 0-149).
MONOTONE_ROUNDS = 1
#: Rounds of sign-row generation in a windowed LP.
SIGN_ROUNDS = 8
#: Upper bound on ``mu = 1 / t`` (a move that is already at rest needs no command at all).
MU_MAX = 1e12
#: A stuck sample holds ``|u| <= STICK_MARGIN F``: inside the friction band, so rounding cannot make it slip.
STICK_MARGIN = 1.0 - 1e-6


@dataclass(frozen=True, kw_only=True)
class FrictionSolution:
    """One solved sampled friction LP.

    Attributes
    ----------
    K : int
        Samples.
    u : ndarray
        Commands (N), ``|u_k| <= t``.
    t : float
        The least peak ``max |u_k|`` (N) for this pattern.
    pattern : ndarray
        Velocity sign on every sample interval (+1 / -1).
    G, w : ndarray
        Arrival rows: ``G^T u = w`` (the friction of the pattern is in ``w``).
    """

    K: int
    u: np.ndarray
    t: float
    pattern: np.ndarray
    G: np.ndarray
    w: np.ndarray


class FrictionLP:
    """The sampled friction LPs of one move, friction force and sample period.

    Parameters
    ----------
    problem : MoveProblem
    F : float
        Coulomb force on the rigid body (N).
    dt : float
        Sample period (s).
    effort_left : list of int, optional
        Shared effort budget of the LPs (see :attr:`effort_left`).
    monotone_rows : bool
        Signed LPs of monotone patterns by generated sign rows (the structure search's counts).
    """

    def __init__(
        self,
        problem: MoveProblem,
        F: float,
        dt: float,
        effort_left: list[int] | None = None,
        *,
        monotone_rows: bool = False,
    ) -> None:
        self.problem = problem
        #: Solve the signed LP of a monotone pattern of at most :data:`MONOTONE_ROWS_MAX` samples by sign rows
        #: generated where violated (see :meth:`solve`).
        self.monotone_rows = monotone_rows
        #: Effort (:func:`lp_effort`) the LPs may still spend, shared by the caller's LPs (``[n]``, decremented
        #: in place); an LP past it raises :class:`EffortSpent` instead of being solved.  None: no limit.
        self.effort_left = effort_left
        self.F = F
        self.dt = dt
        model = problem.model
        self.cf = ClosedForm(model)
        self.Phi, self.Gam, self.Gg = self.cf.steps(dt)
        self.ev, self.gv, self.fv = float(self.Phi[1, 1]), float(self.Gam[1]), float(self.Gg[1])
        self.xf = model.rest_state(problem.target if problem.target is not None else 0.0)
        self.x0 = np.asarray(problem.x0, float) - self.xf
        self.I = np.arange(model.n_states) if problem.include_position else np.arange(1, model.n_states)
        self._kd: dict[int, tuple] = {}
        self.solves = 0
        #: Rows plus columns of every LP solved (HiGHS's work grows with them): a load-independent budget.
        self.work = 0
        #: LPs that had a solution (whatever its peak): none at all says the samples are too coarse.
        self.feasible_solves = 0
        #: Set by :func:`fastest_samples` when more samples stopped changing the least peak.
        self.stalled = False
        # answers of :meth:`solve` by (K, pattern, signs): the count and pattern searches ask for the same LP
        # again (a fixed point that returns to its start, the template and the monotone search agreeing):
        # 284 of 2,503 LPs in seed-18 fuzz cases 0-99 at 100 Hz (2026-12-05); HiGHS is deterministic, so a
        # repeated LP is answered from here (the same object, read-only arrays)
        self._solved: dict[tuple, FrictionSolution | None] = {}

    def kdata(self, K: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(G, Hf, free, pw)``: effect of ``u_k`` and of unit friction on interval ``k`` on ``x_K``, the
        free response, and ``ev^j`` (velocity decay per sample, ``j = 0..K``)."""
        if K not in self._kd:
            if len(self._kd) > 8:
                self._kd.pop(next(iter(self._kd)))
            resp = self.cf.resp
            m = np.arange(K)[::-1] * self.dt
            G = resp.expm_x_many(m, self.Gam)[:, self.I]
            Hf = resp.expm_x_many(m, self.Gg)[:, self.I]
            free = resp.expm_x(K * self.dt, self.x0)[self.I]
            with np.errstate(under="ignore"):
                pw = self.ev ** np.arange(K + 1, dtype=float)
            self._kd[K] = (G, Hf, free, pw)
        return self._kd[K]

    def velocities(self, u: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Rigid-body velocity at instants ``0..K`` (the exact recursion, friction of pattern ``s``)."""
        s = np.asarray(s, float)
        drive = self.gv * np.asarray(u, float) * (s != 0.0) - (self.F * self.fv) * s  # stuck (0): no drive
        v = np.empty(drive.size + 1)
        v[0] = self.x0[1]
        # v_{k+1} = ev v_k + drive_k: a first-order recursion (C loop), the initial value as its state
        v[1:] = lfilter([1.0], [1.0, -self.ev], drive, zi=[self.ev * v[0]])[0]
        return v

    def stuck_rows(self, G: np.ndarray, stuck: np.ndarray) -> np.ndarray:
        """``G`` with the rigid-body effect of the stuck samples removed (friction cancels the command
        there; rigid body and modes are decoupled, so the modes keep theirs)."""
        if not stuck.any():
            return G
        G = G.copy()
        rigid = np.flatnonzero(self.I < 2)
        G[np.ix_(np.flatnonzero(stuck), rigid)] = 0.0
        return G

    def solve(
        self, K: int, s: np.ndarray, signs: bool = True, held: tuple[np.ndarray, np.ndarray] | None = None
    ) -> FrictionSolution | None:
        """Least-peak commands reaching rest in ``K`` samples for pattern ``s``; None if the LP has none.

        ``signs=False``: no sign constraints (the friction of ``s`` is a known disturbance only).
        ``held = (mask, sigma)``: samples where ``mask`` is True are held at ``sigma_k t`` (a window LP:
        only the others are free; HiGHS's presolve removes the held columns).

        Scaled form (100x faster in HiGHS than ``min t`` with ``|u_k| <= t`` rows): commands
        ``u = t z`` with ``|z_k| <= 1`` as bounds, ``mu = 1 / t`` maximised, the arrival
        ``G^T z = mu w``; the velocities are chain variables ``y_j = mu v_j``
        (``y_{j+1} = ev y_j + gv z_j - F fv s_j mu``), so every sign condition is a bound.
        """
        if held is not None:
            return self._solve(K, s, signs, held)
        s = np.asarray(s, float)
        key = (K, s.tobytes(), bool(signs))
        if key not in self._solved:
            sol, decided = None, False
            if self.monotone_rows and signs and 1 < K <= MONOTONE_ROWS_MAX and s[0] != 0.0 and np.all(s == s[0]):
                # a monotone pattern: its sign rows generated where violated (the LP of the arrival rows and a
                # few velocity rows, rounds until none is violated) is 2-3 x faster than the chain form at the
                # structure search's counts, the same optimum (seed-18 cases 88, 93, 13: 30 LPs, peaks within
                # 1e-9, commands within 1e-6); with reversals, or thousands of samples (the ZOH's full LPs:
                # case 22 went from 0.3 to 5.6 s), it was slower (more rows violated, more rounds)
                sol, decided = self._sign_rows(K, s, np.ones(K, dtype=bool), np.zeros(K), MONOTONE_ROUNDS)
            elif self.monotone_rows and not signs and 1 < K <= MONOTONE_ROWS_MAX and np.all(s != 0.0):
                # no sign conditions and no stuck sample: the chain's velocities are free, the LP is its arrival
                # rows (n_I rows, not n_I + K + 1)
                sol, decided = self._sign_rows(K, s, np.ones(K, dtype=bool), np.zeros(K), 1, signs=False)
            if not decided:
                sol = self._solve(K, s, signs, None)
            if sol is not None:
                for a in (sol.u, sol.pattern):
                    a.flags.writeable = False
            self._solved[key] = sol
        return self._solved[key]

    def _solve(
        self, K: int, s: np.ndarray, signs: bool, held: tuple[np.ndarray, np.ndarray] | None
    ) -> FrictionSolution | None:
        """:meth:`solve` without the memo."""
        G, Hf, free, pw = self.kdata(K)
        s = np.asarray(s, float)
        w = -free + self.F * (s @ Hf)
        stuck = s == 0.0
        G = self.stuck_rows(G, stuck)
        moves = (~stuck).astype(float)  # a stuck sample does not drive the rigid body
        iz, iy, imu = 0, K, 2 * K + 1  # columns: z_0..z_{K-1}, y_0..y_K, mu
        nv = 2 * K + 2
        A_eq = chain_matrix(G, w, self.x0[1], self.ev, -self.gv * moves, self.F * self.fv * s)
        A_ub = b_ub = None
        if stuck.any():  # held by friction: |u_k| <= F (a hair inside, so rounding cannot make it slip)
            ks = np.flatnonzero(stuck)
            n_s = ks.size
            r2 = np.repeat(np.arange(2 * n_s), 2)
            c2 = np.column_stack([np.concatenate([iz + ks, iz + ks]), np.full(2 * n_s, imu)]).ravel()
            v2 = np.column_stack([np.repeat([1.0, -1.0], n_s), np.full(2 * n_s, -self.F * STICK_MARGIN)]).ravel()
            A_ub = coo_matrix((v2, (r2, c2)), shape=(2 * n_s, nv)).tocsr()
            b_ub = np.zeros(2 * n_s)
        lo = np.full(nv, -np.inf)
        hi = np.full(nv, np.inf)
        lo[iz : iz + K], hi[iz : iz + K] = -1.0, 1.0
        if held is not None:
            mask, sigma = held
            lo[iz + np.flatnonzero(mask)] = hi[iz + np.flatnonzero(mask)] = np.asarray(sigma, float)[mask]
        lo[imu], hi[imu] = 0.0, MU_MAX
        left, right = s[:-1], s[1:]
        yj = iy + np.arange(1, K)
        if signs:  # s v_j >= 0 on both sides of every instant (v_j = 0 where the pattern changes sign)
            lo[yj] = np.where((left > 0) & (right > 0), 0.0, np.where((left < 0) & (right < 0), -np.inf, 0.0))
            hi[yj] = np.where((left < 0) & (right < 0), 0.0, np.where((left > 0) & (right > 0), np.inf, 0.0))
        else:  # at rest on both ends of a stuck sample, whatever the signs
            at_rest = (left == 0.0) | (right == 0.0)
            lo[yj[at_rest]] = hi[yj[at_rest]] = 0.0
        if K and stuck[-1]:
            lo[iy + K] = hi[iy + K] = 0.0
        cost = np.zeros(nv)
        cost[imu] = -1.0
        size = nv + A_eq.shape[0] + (0 if A_ub is None else A_ub.shape[0])
        if self.effort_left is not None:
            if lp_effort(size) > self.effort_left[0]:
                raise EffortSpent(f"an LP of {K} samples is past the effort budget")
            self.effort_left[0] -= lp_effort(size)
        self.solves += 1
        self.work += size
        res = solve_lp(
            cost=cost,
            A_ub=A_ub,
            b_ub=b_ub,
            A_eq=A_eq,
            b_eq=np.zeros(A_eq.shape[0]),
            lower=lo,
            upper=hi,
            method=LpMethod.DUAL_SIMPLEX,
            # 1e-10 (HIGHS_OPTIONS): a stick arc rides v = 0, HiGHS's default 1e-7 lets it creep
            iteration_limit=lp_iteration_limit(nv, A_eq.shape[0] + (0 if A_ub is None else A_ub.shape[0])),
            presolve=PRESOLVE,
            **HIGHS_OPTIONS,
        )
        if res.status is not LpStatus.OPTIMAL or res.x[imu] <= 0.0:
            return None
        self.feasible_solves += 1
        t = 1.0 / float(res.x[imu])
        u = res.x[iz : iz + K] * t
        return FrictionSolution(K=K, u=u, t=t, pattern=s.copy(), G=G, w=w)

    def solve_windowed(self, K: int, s: np.ndarray, free: np.ndarray, sigma: np.ndarray) -> FrictionSolution | None:
        """As :meth:`solve` with signs, but only the samples in ``free`` are variables (the others held at
        ``sigma_k t``), and the sign conditions are rows generated where violated (a few rounds).

        Small LPs (the free samples and ``mu``) whatever ``K``: the 1 kHz plans use this.
        """
        return self._sign_rows(K, s, free, sigma)[0]

    def _sign_rows(
        self,
        K: int,
        s: np.ndarray,
        free: np.ndarray,
        sigma: np.ndarray,
        rounds: int = SIGN_ROUNDS,
        signs: bool = True,
    ) -> tuple[FrictionSolution | None, bool]:
        """:meth:`solve_windowed` (at most ``rounds`` rounds) and whether it decided: True with the solution,
        or with None where an LP of the rounds had no optimum (its rows are a subset of the full LP's, so
        neither has one); False where the rounds ran out or an LP reached its iteration limit.
        ``signs=False``: no sign rows at all (the friction of ``s`` a known disturbance only)."""
        G, Hf, free_resp, pw = self.kdata(K)
        s = np.asarray(s, float)
        sigma = np.asarray(sigma, float)
        w = -free_resp + self.F * (s @ Hf)
        Fi = np.flatnonzero(free)
        Xi = np.flatnonzero(~free)
        nF = Fi.size
        # arrival: G_F^T z_F - mu w = -G_X^T sigma_X
        A_eq = np.column_stack([G[Fi].T, -w])
        b_eq = -(G[Xi].T @ sigma[Xi])
        # mu v_j = mu a_j + c_j + D_jF z_F, a: initial condition and friction, c: the held samples (z = sigma)
        a = self.velocities(np.zeros(K), s)
        held_u = np.zeros(K)
        held_u[Xi] = sigma[Xi]
        c = self.velocities(held_u, np.zeros(K)) - self.x0[1] * pw  # response to the held z alone
        change = np.flatnonzero(s[1:] != s[:-1]) + 1
        want: set[int] = set(change.tolist()) if signs else set()
        cost = np.zeros(nF + 1)
        cost[-1] = -1.0
        lower = np.append(np.full(nF, -1.0), 0.0)
        upper = np.append(np.ones(nF), MU_MAX)
        A_ub = b_ub = None
        res = None
        for _ in range(rounds):
            js = np.array(sorted(want), int)
            if js.size:
                lag = js[:, None] - 1 - Fi[None, :]
                D = np.where(lag >= 0, self.gv * pw[np.maximum(lag, 0)], 0.0)
                blocks = []
                rhs = []
                for sd in (s[js - 1], s[np.minimum(js, K - 1)]):  # -sd (mu a_j + c_j + D z) <= 0
                    blocks.append(np.column_stack([-sd[:, None] * D, -sd * a[js]]))
                    rhs.append(sd * c[js])
                A_ub, b_ub = np.vstack(blocks), np.concatenate(rhs)
            size = nF + 1 + A_eq.shape[0] + (0 if A_ub is None else A_ub.shape[0])
            if self.effort_left is not None:
                if lp_effort(size) > self.effort_left[0]:
                    raise EffortSpent(f"an LP of {K} samples is past the effort budget")
                self.effort_left[0] -= lp_effort(size)
            self.solves += 1
            self.work += size
            res = solve_lp(
                cost=cost,
                A_ub=A_ub,
                b_ub=b_ub,
                A_eq=A_eq,
                b_eq=b_eq,
                lower=lower,
                upper=upper,
                method=LpMethod.DUAL_SIMPLEX,
                iteration_limit=lp_iteration_limit(nF + 1, A_eq.shape[0] + (0 if A_ub is None else A_ub.shape[0])),
                presolve=PRESOLVE,
                **HIGHS_OPTIONS,
            )
            if res.status is not LpStatus.OPTIMAL or res.x[-1] <= 0.0:
                return None, res.status in (LpStatus.INFEASIBLE, LpStatus.UNBOUNDED, LpStatus.OPTIMAL)
            t = 1.0 / float(res.x[-1])
            u = sigma * t
            u[Fi] = res.x[:nF] * t
            if not signs:
                self.feasible_solves += 1
                return FrictionSolution(K=K, u=u, t=t, pattern=s.copy(), G=G, w=w), True
            v = self.velocities(u, s)
            scale = max(float(np.max(np.abs(v))), 1e-300)
            depth = np.minimum(s[:-1] * v[1:K], s[1:] * v[1:K])
            bad = set((np.flatnonzero(depth < -1e-12 * scale) + 1).tolist()) - want
            if not bad:
                self.feasible_solves += 1  # as the chain form counts its solutions
                return FrictionSolution(K=K, u=u, t=t, pattern=s.copy(), G=G, w=w), True
            local = [j for j in bad if depth[j - 1] <= depth[max(j - 2, 0)] and depth[j - 1] <= depth[min(j, K - 2)]]
            want |= set(local[:192]) | set(sorted(bad, key=lambda j: depth[j - 1])[:64])
        return None, False

    def exact_commands(self, sol: FrictionSolution) -> np.ndarray | None:
        """``sol.u`` corrected (least-norm, within ``u_max``) so that the arrival holds to rounding AND the
        velocity stays exactly zero where the LP has it at zero (reversal instants, stick arcs): there the
        true system reverses or sticks exactly as the pattern assumes.  None if the correction does not fit."""
        K = sol.K
        _, _, _, pw = self.kdata(K)
        v = self.velocities(sol.u, sol.pattern)
        a = self.velocities(np.zeros(K), sol.pattern)
        scale = max(float(np.max(np.abs(v))), 1e-300)
        js = np.flatnonzero(np.abs(v[1:K]) <= 1e-7 * scale) + 1
        lag = js[:, None] - 1 - np.arange(K)[None, :]
        D = np.where(lag >= 0, self.gv * pw[np.maximum(lag, 0)], 0.0)  # v_j = a_j + D_j u
        D[:, sol.pattern == 0.0] = 0.0  # a stuck sample does not move the rigid body
        G = np.column_stack([sol.G, D.T])
        w = np.concatenate([sol.w, -a[js]])
        return least_norm_correction(G, w, sol.u, self.problem.u_max)

    def pattern_of(self, u: np.ndarray, s: np.ndarray) -> np.ndarray:
        """The velocity sign on every interval of the move ``u`` made with friction pattern ``s``
        (the sign of the larger end; an interval at rest keeps the previous sign)."""
        v = self.velocities(u, s)
        mid = v[:-1] + v[1:]
        out = np.sign(mid)
        for k in range(out.size):
            if out[k] == 0.0:
                out[k] = out[k - 1] if k else (s[0] if s.size else 1.0)
        return out
