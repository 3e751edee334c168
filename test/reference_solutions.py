"""Independent reference computations for the time-optimal property tests.

Nothing here calls the planner: closed-form rigid-body minimum times
(:func:`rigid_min_time`, :func:`closed_form_double_integrator`), the final state by
OUR matrix-exponential simulation relative to the move's scale, the sign of the
certificate's switching function on a dense grid, and optimality proofs by weak
duality (:func:`lower_bound_gap`, :func:`proved_optimality`).  Used by
``test_solver_properties`` and ``test_rigid_body`` (which also
checks :func:`rigid_min_time` against the textbook formula).
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import note
from hypothesis.errors import InvalidArgument
from scipy.linalg import expm
from scipy.optimize import brentq, linprog

from flexmotion_ros.core import (
    ModalModel,
    MoveProblem,
    PiecewiseConstant,
    final_state,
    simulate,
)

# a one-phase stop within this much (relative to the move's scale) of the target counts as landing on
# it: 64 eps, the rounding of the closed-form stop distance; it lowers the bound by at most
# 2 sqrt(STOP_RTOL) ~ 2.4e-7 relative, and only where the stop lands there
STOP_RTOL = 64.0 * np.finfo(float).eps
OPT_DELTA = 1e-3  # relative optimality that must be proved by weak duality (see proved_optimality)


def safe_note(text: str) -> None:
    """``hypothesis.note`` that also works outside a ``@given`` test."""
    try:
        note(text)
    except InvalidArgument:
        pass


# ---------------------------------------------------- independent rigid time
def _rigid_phase(b0: float, c: float, v0: float, u: float, t: float) -> tuple[float, float]:
    """Displacement and final velocity of ``p'' = c p' + b0 u`` over ``t`` from velocity ``v0``."""
    if c == 0.0:
        return v0 * t + 0.5 * b0 * u * t * t, v0 + b0 * u * t
    x = c * t
    em1 = math.expm1(x)  # e^{ct} - 1 without cancellation (c t is often ~1e-5)
    v = v0 + v0 * em1 + b0 * u * em1 / c
    return v0 * em1 / c + b0 * u * _expm1_minus_x(x) / (c * c), v


def _expm1_minus_x(x: float) -> float:
    """``e^x - 1 - x`` to full relative precision (a series where the difference cancels)."""
    if abs(x) > 0.1:
        return math.expm1(x) - x
    term, total = x * x / 2.0, 0.0
    for k in range(3, 30):
        total += term
        term *= x / k
    return total


def _stop_time(b0: float, c: float, v: float, u: float) -> float:
    """Time for input ``u`` (opposing ``v``) to bring velocity ``v`` to zero."""
    a = b0 * u  # acceleration sign opposes v
    if c == 0.0:
        return -v / a
    # v(t) = (v + a/c) e^{ct} - a/c = 0
    return -math.log1p(v * c / a) / c  # = log((a/c) / (v + a/c)) / c, without cancellation


def rigid_min_time(
    model: ModalModel, u_max: float, p: float, v: float, fixed_position: bool, stop_atol: float = 0.0
) -> float:
    """Minimum time to bring the rigid body from ``(p, v)`` to rest (at 0 if ``fixed_position``).

    ``stop_atol``: a one-bang stop that ends within this distance of 0 counts as landing on it
    (besides :data:`STOP_RTOL`): the minimum time to come to rest within that distance of the target,
    for a plan whose own final position is that far off (near the switching curve the exact minimum
    grows as the square root of the offset).

    At most one switch.  For each order (``sigma u_max`` then ``-sigma u_max``) the
    second phase is the stop from the velocity reached, so the final position is a
    continuous, monotone function of the first phase's length ``t1`` on the range
    where the second phase can stop the body; its root is bracketed and refined.
    """
    b0, c = model.b0, model.c
    if not fixed_position:
        return 0.0 if v == 0.0 else _stop_time(b0, c, v, -math.copysign(u_max, b0 * v))
    if p == 0.0 and v == 0.0:
        return 0.0
    a = abs(b0) * u_max
    natural = max(abs(v) / a, math.sqrt(abs(p) / a))
    best = math.inf
    for sigma in (1.0, -1.0):
        u1, u2 = sigma * u_max, -sigma * u_max
        s = math.copysign(1.0, b0 * u1)  # direction the first phase pushes

        def end(t1, u1=u1, u2=u2, s=s):
            d1, v1 = _rigid_phase(b0, c, v, u1, t1)
            if s * v1 <= 0.0:  # already stopped (or moving against s): no second phase
                return p + d1, t1
            t2 = _stop_time(b0, c, v1, u2)
            return p + d1 + _rigid_phase(b0, c, v1, u2, t2)[0], t1 + t2

        # the second phase can stop the body once s * v1 >= 0
        t_lo = 0.0 if s * v >= 0.0 else _stop_time(b0, c, v, u1)
        f_lo = end(t_lo)[0]
        if t_lo > 0.0 and abs(f_lo) <= max(STOP_RTOL * max(abs(p), abs(v) * t_lo, a * t_lo * t_lo), stop_atol):
            # one full bang against v stops the body on the target (within rounding): past t_lo the
            # final position is flat (quadratic in t1 - t_lo), so a root search there would add
            # ~sqrt(rounding) to the time; the closed-form stop is the candidate
            best = min(best, t_lo)
            continue
        if s * f_lo > 0.0:
            continue  # overshoots even with the shortest first phase
        if f_lo == 0.0:
            best = min(best, end(t_lo)[1])
            continue
        h = natural
        while s * end(t_lo + h)[0] < 0.0:
            h *= 2.0
        t1 = brentq(lambda t: end(t)[0], t_lo, t_lo + h, xtol=1e-300, rtol=1e-15)
        best = min(best, end(t1)[1])
    return best


def closed_form_double_integrator(a: float, x: float, v: float) -> float:
    """Textbook minimum time of ``x'' = a u``, ``|u| <= 1``, from ``(x, v)`` to the origin."""
    if x + v * abs(v) / (2 * a) > 0:
        return v / a + 2.0 * math.sqrt(x / a + v * v / (2 * a * a))
    return -v / a + 2.0 * math.sqrt(-x / a + v * v / (2 * a * a))


# ----------------------------------------------------------- the checks
def move_scale(problem: MoveProblem, u: PiecewiseConstant) -> tuple[np.ndarray, np.ndarray]:
    """Our own final state (absolute) and each state's excursion from the target during the move."""
    T = u.duration
    times = np.unique(np.concatenate([u.breaks, np.linspace(0.0, T, 201)]))
    X = simulate(problem.model, problem.x0, u, times=times)
    _, scale = deviation_from_target(problem, X)
    return X[-1], scale


def deviation_from_target(problem: MoveProblem, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """States ``X`` (rows) minus the target's rest state, and each state's largest excursion (>0).

    Without a target (final position free) the position column is dropped.
    """
    target = problem.model.rest_state(problem.target if problem.target is not None else 0.0)
    dev = X - target
    if problem.target is None:
        dev = dev[:, 1:]
    scale = np.max(np.abs(dev), axis=0)
    return dev, np.where(scale > 0.0, scale, 1.0)


def final_error_relative(problem: MoveProblem, u: PiecewiseConstant) -> float:
    _, scale = move_scale(problem, u)
    xT = final_state(problem.model, problem.x0, u)
    target = problem.model.rest_state(problem.target if problem.target is not None else 0.0)
    dev = xT - target
    if problem.target is None:
        dev = dev[1:]
    return float(np.max(np.abs(dev) / scale))


def shifted_system(problem: MoveProblem):
    A, B = problem.model.A(), problem.model.B()
    x0 = problem.x0.copy()
    if problem.target is None:
        return A[1:, 1:], B[1:], x0[1:]
    x0[0] -= problem.target
    return A, B, x0


def check_switching_signs(problem: MoveProblem, profile) -> None:
    """The certificate's co-state gives each level's sign: ``S(tau) = nu^T e^{A tau} B`` on a
    dense grid (time-to-go ``tau = T - t``, our own expm) has the sign of the level."""
    A, B, _ = shifted_system(problem)
    T = profile.duration
    nu = -np.asarray(profile.certificate.costate_final, float)
    assert np.all(np.isfinite(nu)) and np.any(nu)
    wmax = max(problem.model.omega) if problem.model.omega else 0.0
    m = int(min(max(400, 16 * T * wmax / math.pi), 40000))
    h = T / m
    E_h = expm(A * h)
    eB = B.copy()
    S = np.empty(m + 1)
    for k in range(m + 1):
        S[k] = nu @ eB
        eB = E_h @ eB
    tau = h * np.arange(m + 1)
    levels = np.asarray(profile.levels, float)
    breaks = np.concatenate([[0.0], profile.switch_times, [T]])
    t = T - tau
    idx = np.clip(np.searchsorted(breaks, t, side="right") - 1, 0, levels.size - 1)
    inner = breaks[1:-1]
    dist = np.min(np.abs(t[:, None] - inner[None, :]), axis=1) if inner.size else np.full(m + 1, np.inf)
    away = (dist > 2 * h) & (tau > 2 * h) & (tau < T - 2 * h)
    big = np.abs(S) > 1e-9 * np.max(np.abs(S))
    bad = away & big & (np.sign(S) != np.sign(levels[idx]))
    assert not np.any(bad), f"co-state's switching function has the wrong sign at t = {t[bad][:5]}"


def _cell_zero(f, dt: float) -> float:
    """The sign change of ``f`` in ``[0, dt]``, to float resolution (the split must be exact there).

    Brent first; where it stalls (100 iterations at ``xtol = 1e-16 dt``: a zero whose ``f`` is at rounding
    level, hypothesis seed 21) bisection, which halves to the resolution of the floats in ~60 steps.
    """
    try:
        return brentq(f, 0.0, dt, xtol=1e-16 * dt, rtol=1e-15)
    except RuntimeError:
        lo, hi, flo = 0.0, dt, f(0.0)
        while True:
            mid = 0.5 * (lo + hi)
            if mid in (lo, hi):
                return mid
            fm = f(mid)
            if fm == 0.0:
                return mid
            if (fm < 0.0) == (flo < 0.0):
                lo, flo = mid, fm
            else:
                hi = mid


def lower_bound_gap(
    problem: MoveProblem,
    T_short: float,
    nu_hint: np.ndarray | None = None,
    use_lp: bool = True,
) -> float:
    """Independent proof that ``T_short`` is too short (so ``T*`` is near-optimal).

    Weak duality for continuous inputs: for ANY ``nu``, an input reaching the target
    in ``T'`` satisfies ``nu^T (-e^{A T'} x0) <= u_max int_0^T' |nu^T e^{A tau} B| dtau``;
    a ``nu`` violating it proves ``T'`` infeasible.  The integral is computed here
    exactly (expm of the augmented matrix), cell by cell on a fine grid, each cell
    split at the zero of ``nu^T e^{A tau} B`` when it changes sign.  Candidates for
    ``nu``: ``nu_hint`` (the certificate's co-state), then the dual vector of a
    phase-1 linear program over a fine zero-order hold on ``[0, T']``; if that LP
    reaches the target, ``T*`` was not minimal and ``-inf`` is returned.

    Returns the largest relative gap found (``> 0`` proves infeasibility).
    """
    A, B, x0 = shifted_system(problem)
    n = A.shape[0]
    um = problem.u_max
    rate = max(max(problem.model.omega, default=0.0), abs(problem.model.c))  # fastest time constant
    N = int(min(max(1000, math.ceil(2.0 * T_short * rate)), 40000))
    dt = T_short / N
    aug = np.zeros((n + 1, n + 1))
    aug[:n, :n] = A
    aug[:n, n] = B

    def phi_gamma(h):
        Eh = expm(aug * h)
        return Eh[:n, :n], Eh[:n, n]

    Phi, Gam = phi_gamma(dt)
    E = np.empty((N + 1, n, n))  # E[m] = e^{A m dt}
    E[0] = np.eye(n)
    for m in range(N):
        E[m + 1] = Phi @ E[m]
    w = -expm(A * T_short) @ x0

    def gap(nu: np.ndarray) -> float:
        nu = nu / np.max(np.abs(nu))
        S = E @ B @ nu  # S at tau = m dt
        R = np.einsum("j,mjk->mk", nu, E[:N])  # nu^T e^{A m dt}
        cells = np.abs(R @ Gam)
        for m in np.flatnonzero(S[:-1] * S[1:] < 0.0):  # a zero inside the cell: split it there
            r = R[m]
            s0 = _cell_zero(lambda s, r=r: r @ (expm(A * s) @ B), dt)
            G0 = phi_gamma(s0)[1]
            cells[m] = abs(r @ G0) + abs(r @ (Gam - G0))
        integral = um * float(np.sum(cells))
        return (float(nu @ w) - integral) / max(integral, 1e-300)

    best = -math.inf
    if nu_hint is not None and np.all(np.isfinite(nu_hint)) and np.any(nu_hint):
        best = gap(np.asarray(nu_hint, float))
        if best > 0.0 or not use_lp:
            return best
    G = E[:N] @ Gam  # g_m: effect of the sample m steps before the end
    scale = np.abs(x0) + um * np.sum(np.abs(G), axis=0)
    scale = np.where(scale > 0.0, scale, 1.0)
    res = linprog(
        np.concatenate([np.zeros(N), np.ones(2 * n)]),
        A_eq=np.hstack([(G / scale).T, np.eye(n), -np.eye(n)]),
        b_eq=w / scale,
        bounds=[(-um, um)] * N + [(0.0, None)] * (2 * n),
        method="highs",
    )
    assert res.status == 0, res.message
    if res.fun <= 1e-12:
        return -math.inf  # a sampled input reaches the target in T_short
    return max(best, gap(np.asarray(res.eqlin.marginals, float) / scale))


def proved_optimality(problem: MoveProblem, profile) -> float:
    """Smallest relative ``delta`` for which ``(1 - delta) T*`` is proved infeasible.

    Feasibility is monotone in the time (arrive earlier, then hold at rest), so one
    proof at ``(1 - delta) T*`` shows ``T*`` optimal to ``delta``.  The certificate's
    co-state is tried first at small ``delta`` (where its first-order gap dominates);
    the independent LP dual at ``OPT_DELTA`` last.  ``inf`` if nothing proves it.
    """
    T = profile.duration
    nu_cert = -np.asarray(profile.certificate.costate_final, float)
    for delta in (1e-6, 1e-5, 1e-4, OPT_DELTA):
        if lower_bound_gap(problem, (1.0 - delta) * T, nu_cert, use_lp=False) > 0.0:
            return delta
    gap = lower_bound_gap(problem, (1.0 - OPT_DELTA) * T, None)
    safe_note(f"LP weak-duality gap at (1 - {OPT_DELTA:g}) T*: {gap:.3e}")
    return OPT_DELTA if gap > 0.0 else math.inf


# ------------------------------------------- own propagation, no package code
def expm_pieces(problem: MoveProblem, durations, levels) -> np.ndarray:
    """States (absolute) after each held level, by ``scipy.linalg.expm`` of ``[[A, B], [0, 0]]``.

    Shares nothing with the package's simulation: one exponential per
    distinct duration, then exact products.  Row 0 is ``problem.x0``.
    """
    A, B = problem.model.A(), problem.model.B()
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n] = A
    M[:n, n] = B
    cache: dict[float, np.ndarray] = {}
    x = np.append(np.asarray(problem.x0, float), 0.0)
    out = [x[:n].copy()]
    for h, u in zip(durations, levels):
        h = float(h)
        if h not in cache:
            cache[h] = expm(M * h)
        x[n] = u
        x = cache[h] @ x
        out.append(x[:n].copy())
    return np.array(out)


def bang_bang_final_error(problem: MoveProblem, profile) -> float:
    """Final-state error of a bang-bang profile, each state relative to its excursion along the motion (own expm)."""
    breaks = np.concatenate([[0.0], profile.switch_times, [profile.duration]])
    parts = np.maximum(1, np.ceil(np.diff(breaks) / (profile.duration / 200.0))).astype(int)
    X = expm_pieces(problem, np.repeat(np.diff(breaks) / parts, parts), np.repeat(profile.levels, parts))
    dev = X - problem.model.rest_state(problem.target)
    scale = np.max(np.abs(dev), axis=0)
    return float(np.max(np.abs(dev[-1]) / np.where(scale > 0, scale, 1.0)))


def assert_certified_exact(problem: MoveProblem, profile) -> None:
    """A returned time-optimal profile: certified, at the target at rest by our own expm, within the bound."""
    assert profile.certified, profile.certificate.message
    assert bang_bang_final_error(problem, profile) <= 1e-9
    assert np.all(np.abs(profile.levels) <= problem.u_max)


def sampled_final_error(problem: MoveProblem, commands, dt: float, reach: bool = False) -> float:
    """Final-state error of a command sequence relative to each state's excursion (own expm).

    ``reach=True``: relative to the larger of the excursion and what the
    actuator could do in the move's time (:func:`one_sample_reach` over the
    whole move), the planners' definition of the error scale, computed here
    independently.  For moves that use a millionth of the actuator (1e-15 m)
    the trajectory's own excursion is at the rounding level of the commands.
    """
    u = np.asarray(commands, float)
    X = expm_pieces(problem, np.full(u.size, dt), u)
    dev, scale = deviation_from_target(problem, X)
    if reach:
        scale = np.maximum(scale, one_sample_reach(problem, max(u.size, 1) * dt))
    return float(np.max(np.abs(dev[-1]) / scale))


def one_sample_reach(problem: MoveProblem, dt: float) -> np.ndarray:
    """How far a full-bound input moves each state within one sample ``dt`` (own expm, 17 instants)."""
    A, B = problem.model.A(), problem.model.B()
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n] = A
    M[:n, n] = B
    reach = np.zeros(n)
    for tau in np.linspace(dt / 16.0, dt, 16):
        reach = np.maximum(reach, np.abs(expm(M * tau)[:n, n]) * problem.u_max)
    return reach if problem.target is not None else reach[1:]
