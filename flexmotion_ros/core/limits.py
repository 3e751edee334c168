"""Fewest samples under velocity, deflection and slew-rate limits.

Real machines add limits the bang-bang theory ignores: a rigid-body velocity
limit ``|v(t)| <= v_max``, a limit on each mode's deflection (structural
stress) ``|q_i(t)| <= q_max_i`` and a slew-rate limit on the command
``|u_k - u_{k-1}| <= slew dt`` (including from and to the hold value 0 at
the ends: the actuator starts and ends at rest).  At a fixed rate the
states at the samples are linear in the commands, so for a sample count
``K`` "every limit holds and the target is reached exactly" is a linear
feasibility problem (scipy HiGHS; the constrained states are LP variables
with the sparse one-step recursion ``x_{k+1} = Phi x_k + Gamma u_k``, the
other states only enter through their final value).

The fewest samples
------------------
Feasibility is monotone in ``K``: a ``K``-sample move can hold zero for one
more sample (the target is an equilibrium, every limit holds at rest, and
the slew limit already admits the step from ``u_{K-1}`` to 0).  So the
fewest samples are found by galloping up from the unlimited ZOH optimum
(:func:`~flexmotion_ros.core.zoh.plan_zoh`, a lower bound: every limit only
removes sequences) and bisecting.

Between samples
---------------
* Velocity: under a constant input ``v(t) = v_inf + (v_k - v_inf) e^{c t}``
  (or linear for ``c = 0``) is monotone, so the limit at the samples is the
  limit everywhere: exact, nothing to add.
* Slew rate: a zero-order hold has no in-between command; the limit is on
  successive samples.
* Deflection: ``q_i`` oscillates within a sample.  Its maximum over each
  sample interval has a closed form (the zeros of ``q_i'`` under constant
  input are ``atan2`` expressions), evaluated on the exact
  matrix-exponential states.  Where it exceeds the limit, the constraint at
  that instant (linear in the commands) is added as a *cut* and the LP is
  solved again.  Cuts are necessary conditions, so the LP with cuts stays a
  relaxation of the continuous-time problem: its infeasibility at ``K - 1``
  still proves that ``K - 1`` samples cannot work, and a solution that
  passes the exact check is feasible for the true problem.

Exactness: the accepted LP is solved with the limits tightened by a relative
``1e-7`` margin, then its arrival is corrected to rounding (least-norm change
on unsaturated samples) and everything is checked on the exact simulation.
The LPs that prove a count infeasible loosen the limits by ``1e-9`` instead
(above HiGHS's feasibility tolerance), so "infeasible" is not a rounding
artefact; the proof is HiGHS's infeasibility verdict, not a Farkas certificate
checked independently (the tests re-check it with a second formulation).

Speed: every LP has all ``K`` commands as variables (state limits bind on long
arcs, so the windows of :mod:`.zoh` do not apply), and its cost grows faster
than ``K``.  To keep their number small at the node's rate, the count is first
found at rates 4, 16, ... times lower (at least 150 samples) with *scaled* LPs:
``t*(K)``, the smallest factor on every state and slew limit that ``K``
samples need, is non-increasing, ``t* > 1`` proves infeasibility and a secant
on ``t*`` finds ``t* = 1`` in a few probes.  The real-valued crossing is
extrapolated linearly in ``dt`` to the full rate, where feasibility LPs gallop
from that guess and bisect (at 1 kHz the scaled LPs' extra rows cost more
than the probes they save).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy import sparse
from scipy.optimize import linprog

from .boundary import MoveProblem
from .errors import FlexmotionError, GoalError, SolverError
from .min_fuel import (
    HIGHS_OPTIONS,
    correct_arrival,
    sample_vectors,
    state_scale,
    verified_samples,
)
from .modal_response import ModalResponse
from .model import ModalModel, check_positive
from .profile import SampledProfile
from .zoh import plan_zoh

#: Relative margin by which the accepted LP tightens every limit (absorbs the arrival correction).
MARGIN = 1e-7
#: Relative loosening of the limits in the LPs that prove a sample count infeasible
#: (above the solver's feasibility tolerance, so that "infeasible" is not a rounding artefact).
PROOF_SLACK = 1e-9
#: Give up (raise) beyond this many times the unlimited sample count.
MAX_FACTOR = 64
MAX_CUT_ROUNDS = 12
#: Above this many samples the interior-point solver (with crossover) beats the simplex,
#: whose pivot count grows with the number of samples.
IPM_SAMPLES = 300


@dataclass(frozen=True)
class Limits:
    """State and slew limits (``None`` or ``inf``: no limit).

    Attributes
    ----------
    velocity_max : float or None
        Rigid-body velocity limit (m/s or rad/s), ``> 0``.
    deflection_max : tuple of float or None
        Per-mode deflection limit (the modal coordinate's unit), ``> 0``
        each (``inf`` for a mode without limit); one entry per mode.
    slew_rate : float or None
        Command slew-rate limit (N/s), ``> 0``.
    """

    velocity_max: float | None = None
    deflection_max: tuple[float, ...] | None = None
    slew_rate: float | None = None

    def validated(self, model: ModalModel) -> Limits:
        """A copy with infinite limits dropped; raises naming the parameter and range."""
        v = _positive_or_none("limits.velocity_max", self.velocity_max, "m/s")
        s = _positive_or_none("limits.slew_rate", self.slew_rate, "N/s")
        q = None
        if self.deflection_max is not None:
            seq = [self.deflection_max] if np.isscalar(self.deflection_max) else list(self.deflection_max)
            if len(seq) != model.n_modes:
                raise FlexmotionError(
                    "limits.deflection_max", f"needs one entry per mode ({model.n_modes}), got {len(seq)}"
                )
            vals = [_positive_or_none(f"limits.deflection_max[{i}]", x, "") for i, x in enumerate(seq)]
            q = tuple(math.inf if x is None else x for x in vals)
            if all(math.isinf(x) for x in q):
                q = None
        return Limits(v, q, s)

    @property
    def active(self) -> list[str]:
        """Names of the limits that are set."""
        out = []
        if self.velocity_max is not None:
            out.append("velocity_max")
        if self.deflection_max is not None:
            out.append("deflection_max")
        if self.slew_rate is not None:
            out.append("slew_rate")
        return out

    def only(self, name: str) -> Limits:
        """Just one of the limits."""
        return Limits(**{name: getattr(self, name)})

    def to_dict(self) -> dict:
        return {
            "velocity_max": self.velocity_max,
            "deflection_max": list(self.deflection_max) if self.deflection_max is not None else None,
            "slew_rate": self.slew_rate,
        }


def _positive_or_none(name: str, value, unit: str) -> float | None:
    if value is None:
        return None
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise FlexmotionError(name, f"must be a number > 0{(' ' + unit) if unit else ''} (or .inf: no limit), got {value!r}") from None
    if math.isinf(x) and x > 0:
        return None
    if not math.isfinite(x) or x <= 0.0:
        raise FlexmotionError(name, f"must be > 0{(' ' + unit) if unit else ''} (or .inf: no limit), got {x}")
    return x


# ------------------------------------------------------- in-between maxima
def deflection_peaks(model: ModalModel, states: np.ndarray, commands: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact ``max |q_i(t)|`` over each sample interval, and where it occurs.

    Parameters
    ----------
    states : ndarray, shape ``(K + 1, 2N + 2)``
        States at the samples (full state ``[p, v, q_1, q_1', ...]``).
    commands : ndarray, shape ``(K,)``
        The held commands.

    Returns
    -------
    peak, at : ndarray, shape ``(K, N)``
        The peak and the time within the interval (s, in ``[0, dt]``).
    """
    K = commands.size
    N = model.n_modes
    if N == 0 or K == 0:
        return np.zeros((K, N)), np.zeros((K, N))
    w = np.asarray(model.omega)
    sig = np.asarray(model.zeta) * w
    wd = model.omega_d
    b = np.asarray(model.b)
    q0, qd0 = states[:-1, 2::2], states[:-1, 3::2]
    q1 = states[1:, 2::2]
    qss = commands[:, None] * b / w**2
    e0 = q0 - qss
    # e' = exp(-sig s) (P cos(wd s) + Q sin(wd s)): zeros where tan(wd s) = -P/Q
    P = qd0
    Q = (-sig * qd0 - w**2 * e0) / wd
    theta0 = np.mod(np.arctan2(-P, Q), np.pi)
    peak = np.maximum(np.abs(q0), np.abs(q1))
    at = np.where(np.abs(q1) > np.abs(q0), dt, 0.0)
    C1 = (qd0 + sig * e0) / wd
    jmax = math.ceil(float(np.max(wd)) * dt / math.pi) + 1
    for j in range(jmax):
        s = (theta0 + j * np.pi) / wd
        inside = (s > 0.0) & (s < dt)
        if not inside.any():
            continue
        s = np.where(inside, s, 0.0)
        q = qss + np.exp(-sig * s) * (e0 * np.cos(wd * s) + C1 * np.sin(wd * s))
        better = inside & (np.abs(q) > peak)
        peak = np.where(better, np.abs(q), peak)
        at = np.where(better, s, at)
    return peak, at


# ------------------------------------------------------------- the LP
@dataclass
class _Cut:
    k: int  # sample interval
    mode: int
    s: float  # time within the interval (s)


class _LimitLP:
    """The feasibility LP for one problem, rate and set of limits, for any ``K``."""

    def __init__(self, problem: MoveProblem, dt: float, limits: Limits) -> None:
        self.problem = problem
        self.dt = dt
        self.limits = limits
        self.um = problem.u_max
        self.model = problem.model
        self.sys = ModalResponse(problem.model, problem.include_position)
        self.x0 = problem.shifted_initial()
        self.r = self.sys.r
        n = self.sys.n
        # one-step matrices from the closed forms (the check uses matrix exponentials)
        self.Phi = np.column_stack([self.sys.expm_x(dt, e) for e in np.eye(n)])
        self.Gam = self.sys.input_integral(np.array([dt]))[0]
        self.vel = limits.velocity_max is not None
        qmax = limits.deflection_max or ()
        self.modes = [i for i, qm in enumerate(qmax) if math.isfinite(qm)]
        self.qmax = np.array([qmax[i] for i in self.modes]) if self.modes else np.zeros(0)
        self.wq = np.asarray(self.model.omega)[self.modes] if self.modes else np.zeros(0)
        # states handled by recursion variables; the others by their final value only
        rec = ([self.r - 1] if self.vel else []) + [j for i in self.modes for j in (self.r + 2 * i, self.r + 2 * i + 1)]
        self.dense_states = [j for j in range(n) if j not in rec]
        self.cuts: list[_Cut] = []
        self.solves = 0
        self._at_cache: dict = {}
        self._check_initial()

    def _check_initial(self) -> None:
        x = self.problem.x0
        if self.vel and abs(x[1]) > self.limits.velocity_max:
            raise GoalError("initial_velocity", f"|{x[1]}| exceeds limits.velocity_max = {self.limits.velocity_max}")
        for i, qm in zip(self.modes, self.qmax):
            if abs(x[2 + 2 * i]) > qm:
                raise GoalError("initial_state", f"mode {i} deflection {x[2 + 2 * i]} exceeds limits.deflection_max[{i}] = {qm}")

    def solve(self, K: int, margin: float = 0.0, smooth: bool = False, scaled: bool = False):
        """Commands ``u_0..u_{K-1}`` (forward) meeting every constraint, or None if infeasible.

        ``scaled``: instead, minimise ``t`` with every state and slew limit
        multiplied by ``t`` and return ``(t*, u)`` (``(inf, None)`` if even
        unlimited states cannot reach the target).  Feasible for every ``K``
        from the unlimited optimum on, so no solve has to detect
        infeasibility (slow for the interior-point method, minutes on long
        moves); ``K`` is feasible iff ``t* <= 1``, and ``t*(K)``, non-increasing,
        guides the search.

        ``smooth`` (the accepted solve): also keep each limited deflection
        within its (tightened) limit at the middle of every sample and
        minimise the total variation ``sum |u_k - u_{k-1}|`` (with 0 before
        and after).  A bare feasibility vertex chatters at the sample rate
        where a state rides its limit (the sampled mode's zero near ``z = -1``),
        and a deflection chattering at its limit overshoots between samples.
        Without deflection limits a slew limit already keeps the command
        smooth, and the TV variables double the LP: then they are left out.
        """
        self.solves += 1
        dt, um, sysm = self.dt, self.um, self.sys
        keep = 1.0 - margin
        nv = K if self.vel else 0
        nm = len(self.modes)
        tv = smooth and (self.limits.slew_rate is None or bool(self.modes))
        ntv = K + 1 if tv else 0
        otv = K + nv + 2 * K * nm  # offset of the total-variation variables
        nvar = otv + ntv + (1 if scaled else 0)
        ot = nvar - 1  # the scale t of every state and slew limit (scaled mode)
        ov = K  # offset of v_1..v_K
        oq = K + nv  # offset of mode blocks: mode j, sample k (1..K): oq + j*2K + 2(k-1) + {0, 1}
        rows, cols, vals, beq = [], [], [], []
        nrow = 0
        # final values of the other states: sum_k g_{K-1-k} u_k = w_K (scaled by state size)
        if self.dense_states:
            G = sample_vectors(sysm, K, dt)[::-1]  # forward order
            w = -sysm.expm_x(K * dt, self.x0)
            sc = state_scale(sysm, self.x0, um, K * dt)
            for j in self.dense_states:
                rows.append(np.full(K, nrow))
                cols.append(np.arange(K))
                vals.append(um * G[:, j] / sc[j])
                beq.append(w[j] / sc[j])
                nrow += 1
        if self.vel:  # vh_{k+1} - a vh_k - (gam um / vmax) uh_k = 0, vh = v / vmax
            vm = self.limits.velocity_max
            a = self.Phi[self.r - 1, self.r - 1]
            g = self.Gam[self.r - 1] * um / vm
            k = np.arange(K)
            rows += [nrow + k, nrow + k, nrow + k[1:]]
            cols += [ov + k, k, ov + k[1:] - 1]
            vals += [np.ones(K), np.full(K, -g), np.full(K - 1, -a)]
            beq += [a * self.x0[self.r - 1] / vm] + [0.0] * (K - 1)
            nrow += K
        for j, (i, qm, wi) in enumerate(zip(self.modes, self.qmax, self.wq)):
            # scaled mode state (q / qmax, q' / (omega qmax))
            ix = self.r + 2 * i
            D = np.array([qm, qm * wi])
            Ph = self.Phi[ix : ix + 2, ix : ix + 2] / D[:, None] * D[None, :]
            Gh = self.Gam[ix : ix + 2] * um / D
            xh0 = self.x0[ix : ix + 2] / D
            base = oq + j * 2 * K
            for c in range(2):
                k = np.arange(K)
                r_ = nrow + 2 * k + c
                rows += [r_, r_, r_[1:], r_[1:]]
                cols += [base + 2 * k + c, k, base + 2 * (k[1:] - 1), base + 2 * (k[1:] - 1) + 1]
                vals += [np.ones(K), np.full(K, -Gh[c]), np.full(K - 1, -Ph[c, 0]), np.full(K - 1, -Ph[c, 1])]
            b_ = np.zeros(2 * K)
            b_[:2] = Ph @ xh0
            beq.append(b_)
            nrow += 2 * K
        A_eq = sparse.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(nrow, nvar))
        b_eq = np.concatenate([np.atleast_1d(np.asarray(x, float)) for x in beq])
        # inequalities: slew and cuts
        ur, uc, uv, bub = [], [], [], []
        nub = 0
        if self.limits.slew_rate is not None and K > 1:
            sh = self.limits.slew_rate * dt / um * keep
            k = np.arange(1, K)
            for sgn in (1.0, -1.0):
                ur += [nub + k - 1, nub + k - 1]
                uc += [k, k - 1]
                uv += [np.full(K - 1, sgn), np.full(K - 1, -sgn)]
                if scaled:  # sgn (u_k - u_{k-1}) - sh t <= 0
                    ur.append(nub + k - 1)
                    uc.append(np.full(K - 1, ot))
                    uv.append(np.full(K - 1, -sh))
                    bub.append(np.zeros(K - 1))
                else:
                    bub.append(np.full(K - 1, sh))
                nub += K - 1
        if tv:
            # t_k >= |u_k - u_{k-1}|, k = 0..K, u_{-1} = u_K = 0
            k = np.arange(K + 1)
            for sgn in (1.0, -1.0):
                r_ = nub + k
                ur += [r_, r_[:-1], r_[1:]]
                uc += [otv + k, k[:-1], k[:-1]]
                uv += [np.full(K + 1, -1.0), np.full(K, sgn), np.full(K, -sgn)]
                bub.append(np.zeros(K + 1))
                nub += K + 1
        if smooth:  # |q(k dt + dt/2)| <= keep, all k at once
            for j, (i, qm, wi) in enumerate(zip(self.modes, self.qmax, self.wq)):
                Ps, Gs = self._at(0.5 * dt, self.r + 2 * i)
                cu = Gs * um / qm
                base = oq + j * 2 * K
                k = np.arange(1, K)
                const0 = float(Ps @ self.x0[self.r + 2 * i : self.r + 2 * i + 2]) / qm
                for sgn in (1.0, -1.0):
                    r_ = nub + np.arange(K)
                    ur += [r_, r_[1:], r_[1:]]
                    uc += [np.arange(K), base + 2 * (k - 1), base + 2 * (k - 1) + 1]
                    uv += [np.full(K, sgn * cu), np.full(K - 1, sgn * Ps[0]), np.full(K - 1, sgn * Ps[1] * wi)]
                    b_ = np.full(K, keep)
                    b_[0] -= sgn * const0
                    bub.append(b_)
                    nub += K
        for cut in self.cuts:
            if cut.k >= K:
                continue
            j = self.modes.index(cut.mode)
            ix = self.r + 2 * cut.mode
            qm, wi = self.qmax[j], self.wq[j]
            Ps, Gs = self._at(cut.s, ix)
            # q(k dt + s) / qmax = Ps . (q_k, q'_k) / qmax + Gs um uh_k / qmax
            cu = Gs * um / qm
            if cut.k == 0:
                const = float(Ps @ self.x0[ix : ix + 2]) / qm
                idx, cv = [cut.k], [cu]
            else:
                base = oq + j * 2 * K + 2 * (cut.k - 1)
                const = 0.0
                idx, cv = [cut.k, base, base + 1], [cu, Ps[0], Ps[1] * wi]
            if scaled:
                idx, cv = idx + [ot], cv + [0.0]
            for sgn in (1.0, -1.0):
                ur.append(np.full(len(idx), nub))
                uc.append(np.array(idx))
                c_ = sgn * np.array(cv)
                if scaled:
                    c_[-1] = -1.0  # sgn q / qmax - t <= -sgn const
                uv.append(c_)
                bub.append(np.array([(0.0 if scaled else keep) - sgn * const]))
                nub += 1
        if scaled:  # state limits scaled by t: +-x_k - t <= 0 (sample states before the end)
            chains = ([(ov, 1)] if self.vel else []) + [(oq + j * 2 * K, 2) for j in range(nm)]
            for off, stride in chains:
                idx = off + stride * np.arange(K - 1)
                for sgn in (1.0, -1.0):
                    r_ = nub + np.arange(K - 1)
                    ur += [r_, r_]
                    uc += [idx, np.full(K - 1, ot)]
                    uv += [np.full(K - 1, sgn), np.full(K - 1, -1.0)]
                    bub.append(np.zeros(K - 1))
                    nub += K - 1
            if self.limits.slew_rate is not None:  # |u_0|, |u_{K-1}| <= sh t
                sh = self.limits.slew_rate * dt / um
                for k in (0, K - 1):
                    for sgn in (1.0, -1.0):
                        ur.append(np.array([nub, nub]))
                        uc.append(np.array([k, ot]))
                        uv.append(np.array([sgn, -sh]))
                        bub.append(np.zeros(1))
                        nub += 1
        A_ub = None
        b_ub = None
        if nub:
            A_ub = sparse.csr_matrix((np.concatenate(uv), (np.concatenate(ur), np.concatenate(uc))), shape=(nub, nvar))
            b_ub = np.concatenate(bub)
        lo = np.full(nvar, -np.inf)
        hi = np.full(nvar, np.inf)
        lo[:K], hi[:K] = -1.0, 1.0
        lim = math.inf if scaled else keep  # scaled: the limits are rows with t
        if self.limits.slew_rate is not None and not scaled:  # from and to the hold value 0
            sh = min(1.0, self.limits.slew_rate * dt / um * keep)
            for k in (0, K - 1):
                lo[k], hi[k] = -sh, sh
        if self.vel:
            lo[ov : ov + K], hi[ov : ov + K] = -lim, lim
            lo[ov + K - 1] = hi[ov + K - 1] = 0.0  # at rest at the end
        for j in range(nm):
            base = oq + j * 2 * K
            lo[base : base + 2 * K : 2], hi[base : base + 2 * K : 2] = -lim, lim
            lo[base + 2 * K - 2 : base + 2 * K] = 0.0  # at rest at the end
            hi[base + 2 * K - 2 : base + 2 * K] = 0.0
        cost = np.zeros(nvar)
        if scaled:
            lo[ot], cost[ot] = 0.0, 1.0
        else:
            cost[otv:] = 1.0
        bounds = np.column_stack([lo, hi])
        method = self._method(K)
        res = linprog(cost, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=b_eq, bounds=bounds, method=method, options=HIGHS_OPTIONS)
        if res.status not in (0, 2) and method != "highs":  # the interior-point method gave up: simplex
            res = linprog(cost, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=b_eq, bounds=bounds, method="highs", options=HIGHS_OPTIONS)
        if res.status == 2:
            return (math.inf, None) if scaled else None
        if res.status != 0:
            raise SolverError(f"limited planner: linear program at {K} samples failed ({res.message})")
        if scaled:
            return float(res.x[ot]), um * res.x[:K]
        return um * res.x[:K]

    def _method(self, K: int) -> str:
        """HiGHS solver: with state chains (velocity, deflection) the interior-point method
        is several times faster on long moves than the simplex, whose pivot count grows
        with ``K``; with the slew limit alone (no chains) the simplex is faster (measured)."""
        return "highs-ipm" if K > IPM_SAMPLES and (self.vel or self.modes) else "highs"

    def _at(self, s: float, ix: int) -> tuple[np.ndarray, float]:
        """Row ``ix`` of ``e^{A s}`` (its 2x2 mode block) and of ``Gamma(s)``: ``q(t + s)`` from ``x(t)``, ``u``."""
        key = (s, ix)
        if key not in self._at_cache:
            n = self.sys.n
            e = np.zeros(n)
            row = np.empty(2)
            for c in range(2):
                e[:] = 0.0
                e[ix + c] = 1.0
                row[c] = self.sys.expm_x(s, e)[ix]
            self._at_cache[key] = (row, float(self.sys.input_integral(np.array([s]))[0][ix]))
        return self._at_cache[key]

    def exact_commands(self, u: np.ndarray) -> np.ndarray:
        """Correct the arrival to rounding on unsaturated samples (the LP meets it to its tolerance)."""
        K = u.size
        G = sample_vectors(self.sys, K, self.dt)[::-1]
        w = -self.sys.expm_x(K * self.dt, self.x0)
        sc = state_scale(self.sys, self.x0, self.um, K * self.dt)
        movable = np.abs(u) < self.um * (1.0 - 1e-9)
        if self.limits.slew_rate is not None:
            movable[[0, -1]] = False  # keep the end steps inside the slew limit
        out = correct_arrival(G / sc, w / sc, u, movable)
        return np.clip(out, -self.um, self.um)

    def violations(self, u: np.ndarray) -> tuple[dict, list[_Cut]]:
        """Exact peaks (at and between samples) on the matrix-exponential states, and cuts for violations."""
        from .simulation import simulate_samples

        states = simulate_samples(self.model, self.problem.x0, u, self.dt)
        peaks: dict = {}
        cuts: list[_Cut] = []
        ok = True
        if self.vel:  # monotone within a sample: the samples hold the maximum
            peaks["velocity"] = float(np.max(np.abs(states[:, 1])))
            ok &= peaks["velocity"] <= self.limits.velocity_max
        if self.modes:
            pk, at = deflection_peaks(self.model, states, u, self.dt)
            at_samples = np.max(np.abs(states[:, 2::2]), axis=0)
            peaks["deflection"] = [float(x) for x in np.max(pk, axis=0)] if u.size else [0.0] * self.model.n_modes
            peaks["deflection_at_samples"] = [float(x) for x in at_samples]
            for j, (i, qm) in enumerate(zip(self.modes, self.qmax)):
                if at_samples[i] > qm:
                    ok = False
                bad = np.flatnonzero(pk[:, i] > qm)
                for k in bad:
                    if 0.0 < at[k, i] < self.dt:
                        cuts.append(_Cut(int(k), i, float(at[k, i])))
                    else:
                        ok = False
        if self.limits.slew_rate is not None and u.size:
            steps = np.abs(np.diff(np.concatenate([[0.0], u, [0.0]])))
            peaks["slew"] = float(np.max(steps)) / self.dt
            ok &= bool(np.max(steps) <= self.limits.slew_rate * self.dt)
        peaks["ok"] = bool(ok and not cuts)
        return peaks, cuts


# --------------------------------------------------------------- search
@dataclass
class LimitedProfile:
    """The fewest-sample move under limits.

    Attributes
    ----------
    sampled : SampledProfile
        The commands (``method = "limited"``), checked exactly.
    limits : Limits
    unlimited_samples : int
        The ZOH optimum without limits (proved fewest by :func:`plan_zoh`).
    lower_bound_samples : int
        No sequence with fewer samples satisfies every limit (LP relaxation infeasible).
    minimal : bool
        ``sampled.samples == lower_bound_samples``.
    added_time_s : float
        Extra move time over the unlimited ZOH optimum (s).
    peaks : dict
        Exact maxima over the whole move, between samples included.
    lp_solves, cuts : int
    """

    sampled: SampledProfile
    limits: Limits
    unlimited_samples: int
    lower_bound_samples: int
    minimal: bool
    added_time_s: float
    peaks: dict
    lp_solves: int
    cuts: int
    solve_time_s: float = 0.0
    extra: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {
            "limits": self.limits.to_dict(),
            "unlimited_samples": self.unlimited_samples,
            "limited_samples": self.sampled.samples,
            "limited_lower_bound_samples": self.lower_bound_samples,
            "limited_minimal": self.minimal,
            "added_time_s": self.added_time_s,
            "peaks": self.peaks,
            "lp_solves": self.lp_solves,
            "cuts": self.cuts,
        }


class _Search:
    """Fewest samples of the relaxation (limits at the samples plus cuts) at one rate.

    Each probe solves the scaled LP: ``t*(K)``, the smallest factor on every
    state and slew limit that ``K`` samples need, non-increasing in ``K``.
    ``t* > 1 + PROOF_SLACK`` proves ``K`` (and every shorter count)
    infeasible; ``t* <= 1`` shows the relaxation feasible.  The next probe is
    the secant estimate of ``t*(K) = 1`` from the nearest probes, kept inside
    the bracket, with bisection when the bracket stops halving.
    """

    def __init__(self, lp: _LimitLP, proved: int, K_cap: int) -> None:
        self.lp = lp
        self.proved = proved  # every K < proved is infeasible
        self.K_cap = K_cap
        self.t: dict[int, float] = {}

    def _cap(self, K: int) -> None:
        if K > self.K_cap:
            names = ", ".join(f"limits.{n}" for n in self.lp.limits.active)
            raise GoalError(
                names, f"no move within {self.K_cap} samples ({self.K_cap * self.lp.dt:.4g} s) satisfies the limits; relax them"
            )

    def forget_feasible(self) -> None:
        """After new cuts: feasible probes may no longer be (infeasible ones stay infeasible)."""
        self.t = {k: v for k, v in self.t.items() if v > 1.0}

    def t_star(self, K: int) -> float:
        if K < self.proved:
            return math.inf
        if K not in self.t:
            self._cap(K)
            t, _ = self.lp.solve(K, scaled=True)
            self.t[K] = t
            if t > 1.0 + PROOF_SLACK:
                self.proved = max(self.proved, K + 1)  # monotone: nothing shorter either
        return self.t[K]

    def feasible(self, K: int) -> bool:
        """Feasibility LP with the limits loosened by ``PROOF_SLACK`` (infeasible: proved)."""
        if K < self.proved:
            return False
        if K in self.t and self.t[K] <= 1.0:
            return True
        self._cap(K)
        if self.lp.solve(K, -PROOF_SLACK) is None:
            self.proved = max(self.proved, K + 1)  # monotone: nothing shorter either
            self.t[K] = math.inf
            return False
        self.t[K] = 1.0
        return True

    def fewest_feasible(self, guess: int) -> int:
        """Fewest feasible ``K`` by feasibility LPs: gallop from ``guess`` (either way), then bisect.

        At the full rate a near guess makes this cheaper than the scaled LPs
        (their extra rows cost more than the probes they save on long moves).
        """
        K = max(guess, self.proved)
        if self.feasible(K):
            hi, step = K, 1
            while hi - step >= self.proved and self.feasible(hi - step):
                hi -= step
                step *= 2
        else:
            step, hi = 1, K + 1
            while not self.feasible(hi):
                step *= 2
                hi += step
        while hi > self.proved:  # bisect: feasibility is monotone in K
            mid = (self.proved + hi) // 2
            if self.feasible(mid):
                hi = mid
        return hi

    def crossing(self) -> float | None:
        """Real-valued ``K`` where the secant of ``t*`` through the two nearest probes crosses 1."""
        s = self.slope()
        best = min(((k, v) for k, v in self.t.items() if math.isfinite(v)), key=lambda kv: abs(kv[1] - 1.0), default=None)
        if s is None or best is None:
            return None
        return best[0] + (1.0 - best[1]) / s

    def slope(self) -> float | None:
        """``dt*/dK`` near ``t* = 1`` from the two probes closest to it (None if unknown)."""
        pts = sorted(((k, v) for k, v in self.t.items() if math.isfinite(v)), key=lambda kv: abs(kv[1] - 1.0))[:2]
        if len(pts) < 2 or pts[0][1] == pts[1][1]:
            return None
        (k1, t1), (k2, t2) = pts
        s = (t2 - t1) / (k2 - k1)
        return s if s < 0.0 else None

    def fewest(self, guess: int, slope: float | None = None) -> int:
        """Fewest ``K`` with ``t*(K) <= 1``, searching from ``guess``.

        ``slope``: an estimate of ``dt*/dK`` (from a coarser rate) for the first step.
        """
        K = max(guess, self.proved)
        step = 1
        widths: list[int] = []
        for _ in range(200):
            self.t_star(K)
            feas = [k for k, v in self.t.items() if v <= 1.0 and k >= self.proved]
            hi = min(feas) if feas else None
            below = [k for k, v in self.t.items() if v > 1.0 and (hi is None or k < hi)]
            lo = max([self.proved - 1, *below])  # every K <= lo needs t* > 1
            if hi is not None and hi <= lo + 1:
                return hi
            s = self.slope() or slope
            best = min(((k, v) for k, v in self.t.items() if math.isfinite(v)), key=lambda kv: abs(kv[1] - 1.0), default=None)
            cand = None
            if s is not None and best is not None:
                cand = math.ceil(best[0] + (1.0 - best[1]) / s - 1e-9)  # smallest K the secant calls feasible
                if cand in self.t:  # the estimate sits on a probe: test its neighbour
                    cand = cand - 1 if self.t[cand] <= 1.0 else cand + 1
            if hi is None:  # nothing feasible yet: go up, at least a doubling step past lo
                cand = lo + step if cand is None else max(cand, lo + 1)
                if cand <= max(self.t, default=lo):
                    cand = lo + step
                step *= 2
            else:
                widths.append(hi - lo)
                stalled = len(widths) >= 3 and widths[-1] > widths[-3] // 2
                if cand is None or stalled or not lo < cand < hi or cand in self.t:
                    cand = (lo + hi) // 2
                    widths.clear()
            K = cand
        raise SolverError("limited planner: the sample-count search did not converge")


#: Coarser planning rates (factor between levels) used to guess the sample count; the
#: coarsest has at least ``COARSE_SAMPLES`` samples.
COARSE_FACTOR = 4
COARSE_SAMPLES = 150


def _guess(problem: MoveProblem, rate: float, limits: Limits, T0: float) -> tuple[float | None, float | None]:
    """Limited move time (s) extrapolated from coarser rates and ``dt*/dK`` at ``rate`` (Nones if too short to coarsen)."""
    rates = []
    r = rate / COARSE_FACTOR
    while r * T0 >= COARSE_SAMPLES:
        rates.append(r)
        r /= COARSE_FACTOR
    if not rates:
        return None, None
    times: list[tuple[float, float]] = []  # (dt, T)
    slope = None
    for r in reversed(rates):  # coarsest first
        dt = 1.0 / r
        lp = _LimitLP(problem, dt, limits)
        K0 = plan_zoh(problem, r).samples
        if times:
            T_pred = times[-1][1] if len(times) == 1 else _extrapolate(times, dt)
            guess = max(K0, round(T_pred / dt))
        else:
            guess = K0
        search = _Search(lp, K0, max(K0 * MAX_FACTOR, K0 + 1000))
        K = search.fewest(guess, None if slope is None else slope * COARSE_FACTOR)
        slope = search.slope()  # dt*/dK at this rate; a K at the next rate is COARSE_FACTOR times finer
        # where t* crosses 1 between the samples: extrapolating it, not the whole count, avoids
        # a rounding error of up to a coarse sample in the guess
        crossing = search.crossing()
        times.append((dt, (crossing if crossing is not None and K - 1 <= crossing <= K else K) * dt))
    T = times[-1][1] if len(times) == 1 else _extrapolate(times, 1.0 / rate)
    return T, None if slope is None else slope / COARSE_FACTOR


def _extrapolate(times: list[tuple[float, float]], dt: float) -> float:
    """Linear extrapolation of ``T(dt)`` from the last two levels (the ZOH error is first order in ``dt``)."""
    (d1, t1), (d2, t2) = times[-2], times[-1]
    return t2 + (t2 - t1) / (d2 - d1) * (dt - d2)


def plan_limited(
    problem: MoveProblem,
    rate_hz: float,
    limits: Limits,
    unlimited: SampledProfile | None = None,
) -> LimitedProfile:
    """Fewest zero-order-hold samples at ``rate_hz`` reaching rest exactly under ``limits``.

    Coarser rates (factors of 4) first give a guess of the sample count, so
    that only a few full-size linear programs are solved at ``rate_hz``:
    a gallop from the guess, a bisection, and the accepted solve.

    Raises
    ------
    FlexmotionError
        A limit out of range, or an initial state already outside a limit.
    GoalError
        No move within ``MAX_FACTOR`` times the unlimited sample count meets the limits.
    SolverError
        No sequence passed the exact checks.
    """
    t0 = time.perf_counter()
    rate = check_positive("rate_hz", rate_hz, "Hz")
    dt = 1.0 / rate
    limits = limits.validated(problem.model)
    lp = _LimitLP(problem, dt, limits)  # validates the initial state against the limits
    if unlimited is None:
        unlimited = plan_zoh(problem, rate)
    K0 = unlimited.samples
    if not limits.active or K0 == 0:
        prof = verified_samples(problem, unlimited.commands, dt, "limited", unlimited.minimal, unlimited.lower_bound_samples, None, {}, t0)
        peaks, _ = lp.violations(unlimited.commands)
        return LimitedProfile(prof, limits, K0, unlimited.lower_bound_samples, unlimited.minimal, 0.0, peaks, 0, 0, time.perf_counter() - t0)
    search = _Search(lp, K0 if unlimited.minimal else unlimited.lower_bound_samples, max(K0 * MAX_FACTOR, K0 + 1000))
    T_guess, _ = _guess(problem, rate, limits, K0 * dt)
    coarse_time = time.perf_counter() - t0

    def attempt(K: int):
        """The accepted (smooth, tightened) solve at ``K`` after exact checks; cuts added on the way."""
        for _ in range(MAX_CUT_ROUNDS):
            cut_added = False
            for margin in (MARGIN, 1e-5):
                u = lp.solve(K, margin, smooth=True)
                if u is None:
                    return None  # a larger margin cannot help
                u = lp.exact_commands(u)
                peaks, cuts = lp.violations(u)
                if cuts:
                    lp.cuts.extend(cuts)
                    cut_added = True
                    break
                if peaks["ok"]:
                    return u, peaks
            if not cut_added:
                return None
        return None

    # the fewest samples of the relaxation near the guess, then the accepted (smooth) solve there;
    # solves that turn out infeasible are the slow ones, so the smooth solve runs only where
    # the relaxation is feasible
    if T_guess is None:  # a short move: the scaled LPs are cheap and need fewer probes
        K = search.fewest(search.proved)
    else:
        K = search.fewest_feasible(max(search.proved, math.ceil(T_guess / dt - 1e-9)))
    accepted = None
    for _ in range(8):
        n_cuts = len(lp.cuts)
        for cand in range(K, K + 3):
            res = attempt(cand)
            if res is not None:
                accepted = (cand, *res)
                break
            if len(lp.cuts) > n_cuts:
                break  # new cuts: the relaxation's fewest may have moved up
        if accepted is not None:
            break
        search.forget_feasible()
        K = search.fewest(K) if T_guess is None else search.fewest_feasible(K)
    if accepted is None:
        raise SolverError("limited planner: no sequence passed the exact limit checks")
    K, u, peaks = accepted
    proved = search.proved
    minimal = K == proved
    prof = verified_samples(problem, u, dt, "limited", minimal, proved, None, {}, t0)
    return LimitedProfile(
        sampled=prof,
        limits=limits,
        unlimited_samples=K0,
        lower_bound_samples=proved,
        minimal=bool(minimal),
        added_time_s=(prof.samples - K0) * dt,
        peaks=peaks,
        lp_solves=lp.solves,
        cuts=len(lp.cuts),
        solve_time_s=time.perf_counter() - t0,
        extra={"coarse_guess_s": T_guess, "coarse_time_s": coarse_time, "samples_guess": None if T_guess is None else math.ceil(T_guess / dt - 1e-9)},
    )
