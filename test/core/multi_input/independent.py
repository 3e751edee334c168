"""Independent computations for the multi-input tests (no planner code, no closed forms).

The system matrices are built here from the model's parameters; states, switching
functions and integrals come from ``scipy.linalg.expm``; weak-duality bounds use
co-states from the planner's certificate or from an independent linear program
(``scipy.optimize.linprog``, interior point).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm
from scipy.optimize import brentq, linprog


def matrices(model) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B)`` in the state order ``[p1, v1, .., pk, vk, q1, q1', ..]`` from the parameters."""
    k, N, m = len(model.rigid_bodies), len(model.omega), len(model.inputs)
    n = 2 * (k + N)
    A = np.zeros((n, n))
    B = np.zeros((n, m))
    for j in range(k):
        A[2 * j, 2 * j + 1] = 1.0
        A[2 * j + 1, 2 * j + 1] = model.c[j]
        B[2 * j + 1] = model.b0[j]
    for l in range(N):
        r = 2 * k + 2 * l
        w, z = model.omega[l], model.zeta[l]
        A[r, r + 1] = 1.0
        A[r + 1, r] = -w * w
        A[r + 1, r + 1] = -2 * z * w
        B[r + 1] = model.b[l]
    return A, B


def reduced(problem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A, B, x0)`` of the shifted move, free positions dropped."""
    A, B = matrices(problem.model)
    x = problem.x0.copy()
    keep = []
    for j, t in enumerate(problem.targets):
        if t is not None:
            x[2 * j] -= t
            keep.append(2 * j)
        keep.append(2 * j + 1)
    keep += list(range(2 * problem.model.k, A.shape[0]))
    return A[np.ix_(keep, keep)], B[keep], x[keep]


def final_state(problem, breaks, rows) -> np.ndarray:
    """Reduced shifted final state under a piecewise-constant input (one expm per interval)."""
    A, B, x = reduced(problem)
    n, m = B.shape
    for h, u in zip(np.diff(breaks), rows):
        M = np.zeros((n + m, n + m))
        M[:n, :n] = A
        M[:n, n:] = B
        E = expm(M * h)
        x = E[:n, :n] @ x + E[:n, n:] @ np.asarray(u, float)
    return x


def relative_error(problem, x_final, duration, u_max) -> float:
    """``max |x(T)| / excursion``: the excursion of a full-bound push held for the duration, and ``|x0|``."""
    A, B, x0 = reduced(problem)
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A
    M[:n, n:] = B
    scale = np.abs(x0) + 1e-300
    for t in np.linspace(0, duration, 41)[1:]:
        G = expm(M * t)[:n, n:]
        scale = np.maximum(scale, np.abs(G) @ np.asarray(u_max) + np.abs(expm(A * t) @ x0))
    return float(np.max(np.abs(x_final) / scale))


def support(A, B, nu, T, u_max, grid_points: int = 4000) -> float:
    """``sum_i u_max_i int_0^T |nu^T e^{A tau} B_i| dtau``: zeros bracketed on a grid, refined by brentq,
    each piece integrated exactly by the augmented exponential."""
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A
    M[:n, n:] = B
    grid = np.linspace(0.0, T, grid_points + 1)
    E = expm(A * (grid[1] - grid[0]))
    S = np.empty((grid.size, m))
    x = B.copy()
    for k in range(grid.size):
        S[k] = nu @ x
        x = E @ x
    total = 0.0
    top = float(np.max(np.abs(S)))
    for i in range(m):
        if np.max(np.abs(S[:, i])) <= 1e-9 * top:
            # a singular input: S_i is rounding noise; bound its integral from above (conservative)
            total += u_max[i] * T * 2.0 * float(np.max(np.abs(S[:, i])))
            continue
        f = lambda t, i=i: float(nu @ expm(A * t) @ B[:, i])
        cuts = [0.0]
        for k in np.flatnonzero(np.sign(S[1:, i]) * np.sign(S[:-1, i]) < 0):
            cuts.append(brentq(f, grid[k], grid[k + 1], xtol=1e-15 * T))
        cuts.append(T)
        gam = [expm(M * t)[:n, n + i] for t in cuts]
        total += u_max[i] * sum(abs(float(nu @ (b - a))) for a, b in zip(gam[:-1], gam[1:]))
    return total


def proves_infeasible(problem, nu, T) -> bool:
    """Weak duality: ``nu^T (-e^{A T} x0) > h_T(nu)`` proves that no admissible input reaches rest by ``T``."""
    A, B, x0 = reduced(problem)
    value = float(nu @ (-(expm(A * T) @ x0)))
    return value > support(A, B, nu, T, problem.u_max)


def costate_final(problem, profile) -> np.ndarray:
    """``nu = -lambda(T)`` from the certificate's ``lambda_0`` (``lambda(t) = e^{-A^T t} lambda_0``)."""
    A, _, _ = reduced(problem)
    return -expm(-A.T * profile.duration) @ np.asarray(profile.certificate.costate_initial, float)


def lp_costate(problem, T, samples: int = 1000) -> np.ndarray:
    """A co-state direction from the zero-order-hold least-peak LP at ``T`` (HiGHS interior point)."""
    A, B, x0 = reduced(problem)
    n, m = B.shape
    dt = T / samples
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A
    M[:n, n:] = B
    gam = expm(M * dt)[:n, n:]
    E = expm(A * dt)
    cols = []
    g = gam.copy()
    for _ in range(samples):  # j samples to go
        cols.append(g)
        g = E @ g
    G = np.stack(cols, axis=0)  # (K, n, m)
    scale = np.maximum(np.max(np.abs(G), axis=(0, 2)) * samples * np.max(problem.u_max), np.abs(x0))
    scale = np.where(scale > 0, scale, 1.0)
    Aeq = np.concatenate([G[:, :, i].T * problem.u_max[i] for i in range(m)], axis=1) / scale[:, None]
    w = -(expm(A * T) @ x0) / scale
    K = Aeq.shape[1]
    # min t  s.t. Aeq v = w, -t <= v <= t
    c = np.zeros(K + 1)
    c[-1] = 1.0
    from scipy import sparse

    I = sparse.identity(K, format="csr")
    one = sparse.csr_matrix(np.ones((K, 1)))
    A_ub = sparse.vstack([sparse.hstack([I, -one]), sparse.hstack([-I, -one])])
    res = linprog(
        c,
        A_ub=A_ub,
        b_ub=np.zeros(2 * K),
        A_eq=np.hstack([Aeq, np.zeros((n, 1))]),
        b_eq=w,
        bounds=[(None, None)] * K + [(0, None)],
        method="highs-ipm",
    )
    assert res.status == 0, res.message
    return np.asarray(res.eqlin.marginals, float) / scale


def zoh_lp_peak(problem, K: int, dt: float, method: str = "highs-ipm") -> tuple[float, np.ndarray]:
    """Least peak fraction of any ZOH sequence of ``K`` samples reaching rest, and the LP's co-state."""
    A, B, x0 = reduced(problem)
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A
    M[:n, n:] = B
    gam = expm(M * dt)[:n, n:]
    E = expm(A * dt)
    cols = []
    g = gam.copy()
    for _ in range(K):
        cols.append(g)
        g = E @ g
    G = np.stack(cols, axis=0)
    Aeq = np.concatenate([G[:, :, i].T * problem.u_max[i] for i in range(m)], axis=1)
    scale = np.maximum(np.max(np.abs(Aeq), axis=1) * K, 1e-300)
    Aeq = Aeq / scale[:, None]
    w = -(expm(A * K * dt) @ x0) / scale
    V = Aeq.shape[1]
    c = np.zeros(V + 1)
    c[-1] = 1.0
    A_ub = np.vstack([np.hstack([np.eye(V), -np.ones((V, 1))]), np.hstack([-np.eye(V), -np.ones((V, 1))])])
    res = linprog(
        c,
        A_ub=A_ub,
        b_ub=np.zeros(2 * V),
        A_eq=np.hstack([Aeq, np.zeros((n, 1))]),
        b_eq=w,
        bounds=[(None, None)] * V + [(0, None)],
        method=method,
    )
    assert res.status == 0, res.message
    nu = np.asarray(res.eqlin.marginals, float)
    # the weak-duality bound from that co-state, evaluated here: t >= nu^T w / sum |nu^T col|
    bound = float(nu @ w) / float(np.sum(np.abs(nu @ Aeq)))
    return float(res.x[-1]), np.array([bound])
