"""Tools every sampled planner shares: sample vectors, LP variable scales, exact corrections.

A zero-order-hold sequence ``u_0 .. u_{K-1}`` reaches ``x(K dt) = e^{A K dt} x0 +
sum_k g_{K-1-k} u_k``; the linear programs of the sampled planners work on
the rows ``g_k`` (:func:`sample_vectors`) in the units of
:func:`lp_state_scale`, and their solutions are made exact by a least-norm
change of the free samples (:func:`correct_arrival`,
:func:`least_norm_correction`).
"""

from __future__ import annotations

import numpy as np

from ..simulation.modal_response import ModalResponse


def sample_vectors(system: ModalResponse, K: int, dt: float) -> np.ndarray:
    """``g_m = e^{A m dt} Gamma(dt)`` for ``m = 0..K-1``, shape ``(K, n)``."""
    gam = system.input_integral(np.array([dt]))[0]
    return system.expm_x_many(dt * np.arange(K), gam)


#: Widest ``(n, K)`` system solved by ``np.linalg.lstsq`` (LAPACK ``gelsd``): with 16 rows it
#: segfaulted between 3 and 4.8 million columns (a 13-hour move at 100 Hz, um_zvd fuzz case 875);
#: wider ones go through a QR factorisation of the tall transpose, whose workspace stays small.
LSTSQ_MAX_COLUMNS = 1_000_000


def min_norm_solve(M: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The least-squares solution of ``M y = r`` of least norm (``M``: ``(n, K)``, few rows, many columns).

    ``np.linalg.lstsq`` up to :data:`LSTSQ_MAX_COLUMNS` columns; past it ``M^T = Q R`` (reduced QR),
    ``y = Q z`` with ``z`` the least-norm solution of ``R^T z = r``: the same answer (``y`` lies in the
    row space of ``M``, where ``Q`` is an isometry).
    """
    if M.shape[1] <= LSTSQ_MAX_COLUMNS:
        return np.linalg.lstsq(M, r, rcond=None)[0]
    Q, R = np.linalg.qr(M.T, mode="reduced")
    z = np.linalg.lstsq(R.T, r, rcond=None)[0]
    return Q @ z


# --------------------------------------------------------------------- helpers
def lp_state_scale(system: ModalResponse, x0: np.ndarray, u_max: float, T: float) -> np.ndarray:
    """How large each (shifted) state gets during a move of length ``T``: the unit of LP variables.

    A coarse cousin of :func:`.reachable_set.state_scale` (the scale final-state
    errors are judged against), kept apart on purpose: the LPs' conditioning
    depends on it, and with the finer error scale HiGHS fails on the 1 kHz
    limited LP of ``bench/fuel_limits.py`` (status 4, solve error).
    """
    s = np.abs(x0) + u_max * np.max(np.abs(system.input_integral(np.linspace(0.0, T, 33))), axis=0)
    return np.where(s > 0.0, s, 1.0)


def correct_arrival(G: np.ndarray, w: np.ndarray, u: np.ndarray, movable: np.ndarray) -> np.ndarray:
    """Least-norm change of ``u[movable]`` that makes ``G^T u = w`` exact (to rounding).

    The LP solution misses ``w`` by its feasibility tolerance; the change is
    of that size, so it does not disturb the constraints' margins.
    """
    u = u.copy()
    idx = np.flatnonzero(movable)
    if idx.size < G.shape[1]:
        return u
    for _ in range(3):
        r = w - G.T @ u
        du = min_norm_solve(G[idx].T, r)
        u[idx] += du
    return u


def least_norm_correction(
    G: np.ndarray, w: np.ndarray, u: np.ndarray, u_max: float, rounds: int = 4
) -> np.ndarray | None:
    """Change ``u`` least (weighted by slack) so that ``G^T u = w``, keeping ``|u| <= u_max``.

    ``G``: ``(K, n)``, row ``k`` the final-state effect of sample ``k``.
    Samples at the bound do not move; the others move in proportion to their
    slack.  Returns None if no such change exists within ``rounds`` passes.
    """
    u = np.clip(u, -u_max, u_max)
    for _ in range(rounds):
        r = w - G.T @ u
        slack = u_max - np.abs(u)
        wts = np.where(slack > 1e-12 * u_max, slack, 0.0)
        if np.count_nonzero(wts) < G.shape[1]:
            return None
        M = G.T * wts  # (n, K): columns scaled by slack
        y = min_norm_solve(M, r)
        du = wts * y
        ok = np.abs(u + du) <= u_max
        u = np.clip(u + du, -u_max, u_max)
        if ok.all() and np.max(np.abs(w - G.T @ u)) <= 1e-15 * max(1.0, float(np.max(np.abs(w)))):
            break
    return u
