"""Zeros of the switching function ``S(tau) = nu^T e^{A tau} B``.

Pontryagin's principle (seed eqs. 2.33-2.35) makes the time-optimal input
``u = -u_max sgn(lambda^T B)``; with ``lambda(t) = e^{A^T (T - t)} lambda(T)``
and time-to-go ``tau = T - t`` the sign is that of
``S(tau) = nu^T e^{A tau} B`` (``nu = -lambda(T)``).  Its zeros are the
switching times.

The zeros are bracketed on a grid fine enough for the fastest mode
(:func:`sample_grid`, or :func:`root_grid`, graded by the modes still
ringing), blocks of cells proved zero-free skipped (:mod:`.zero_free`),
isolated with proof by Taylor bounds (:func:`isolate_roots`) and refined,
all at once, by a safeguarded Newton iteration (:mod:`.root_refine`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..errors import SolverError
from ..kernels import backend
from ..kernels import roots as kernel_roots
from .root_refine import hermite_root, refine_roots
from .zero_free import cell_points, cells_to_examine


class SwitchingSystem(Protocol):
    """What the planners need of a linear system (see :class:`ModalResponse`)."""

    n: int

    def switching(self, nu: np.ndarray, tau: np.ndarray, derivative: bool = False): ...

    def expm_B(self, tau: np.ndarray) -> np.ndarray: ...

    def input_integral(self, tau: np.ndarray) -> np.ndarray: ...

    def expm_x(self, tau: float, x: np.ndarray) -> np.ndarray: ...

    def A_x(self, x: np.ndarray) -> np.ndarray: ...

    def switching_derivative_bounds(self, nu: np.ndarray, tau_max: float) -> tuple[float, float]: ...


#: Grid points per half period of the fastest damped mode.
POINTS_PER_HALF_PERIOD = 8
#: :func:`root_grid`: past ``tau = GRID_DECAY / (zeta omega)`` a mode's term of ``S`` is below
#: ``e^-GRID_DECAY`` (about 2e-16) of its start, under the rounding noise of ``S``; the grid's
#: spacing then follows the fastest mode still ringing.
GRID_DECAY = 36.0
#: Grade :func:`root_grid` at all (False: the uniform grid of :func:`sample_grid`, as before).
GRADED_ROOT_GRID = True
#: :func:`root_grid` returns the uniform grid unless the graded one is shorter than this share of it.
GRADED_SHARE = 0.7
MIN_GRID_POINTS = 64
#: Refuse a grid longer than this (a move of millions of periods: minutes of
#: work and gigabytes; the budgets of ``plan_move`` refuse such goals first).
MAX_GRID_POINTS = 20_000_000


def fastest_frequency(system) -> float:
    """Largest damped frequency (rad/s) of ``system``, 0 for a rigid body."""
    wd = getattr(system, "wd", None)
    return float(np.max(wd)) if wd is not None and np.size(wd) else 0.0


def sample_grid(system, T: float, density: float = 1.0) -> np.ndarray:
    """Sample times on ``[0, T]`` for bracketing zeros of ``S`` (read-only).

    The last few grids are kept on ``system`` and returned again for the same
    ``(T, density)``: the switching function's trigonometric basis is cached by
    the grid's identity (:meth:`ModalResponse._trig_basis`), so every
    evaluation at one ``T`` (root isolation, norms, a trust-region solve)
    shares one basis instead of recomputing ``exp``, ``sin`` and ``cos`` on
    thousands of points each time (measured: 46 % of a 400 s, 4-mode plan).
    """
    memo = getattr(system, "_grid_memo", None)
    key = (float(T), float(density))
    if memo is not None and key in memo:
        return memo[key]
    grid = _new_grid(system, T, density)
    grid.flags.writeable = False
    if memo is None:
        memo = {}
        try:
            system._grid_memo = memo
        except AttributeError:  # a system that takes no attributes: no memo
            return grid
    if len(memo) >= GRID_MEMO:
        memo.pop(next(iter(memo)))
    memo[key] = grid
    return grid


#: Grids kept per system by :func:`sample_grid`.
GRID_MEMO = 6


def root_grid(system, T: float, density: float = 1.0) -> np.ndarray:
    """Sample times on ``[0, T]`` for :func:`isolate_roots`, graded by the modes still ringing (read-only).

    :func:`sample_grid`'s spacing (``POINTS_PER_HALF_PERIOD`` points per half
    period of the fastest mode) on the stretch where that mode's term of ``S``
    is above ``e^-GRID_DECAY`` of its start; past it, the spacing of the
    fastest mode still ringing, and so on (each stretch at least
    ``MIN_GRID_POINTS / 2`` points).  The proof of :func:`isolate_roots`
    holds on any grid (its derivative bounds are local: ``|S^(K+1)|`` on
    ``[a, inf)`` with every term decayed to ``a``); the grid only sets how
    much bisection it needs.  On a long move whose fast modes are damped
    (a 311 s stop of a 2.6 rad/s mode that barely decays, with a 17 rad/s
    mode gone after 7 s) the root isolation of every exact evaluation then
    samples the ringing modes, not the whole move at the fastest mode's
    spacing: 2,300 points instead of 12,849.  The uniform grid (the same
    object as :func:`sample_grid`'s) if grading saves less than
    :data:`GRADED_SHARE`, or for systems without decay rates.  Memoised as
    :func:`sample_grid` is (the switching function's basis is cached by the
    grid's identity).
    """
    sig, wd = getattr(system, "sig", None), getattr(system, "wd", None)
    if not GRADED_ROOT_GRID or sig is None or wd is None or not np.size(wd):
        return sample_grid(system, T, density)
    memo = getattr(system, "_grid_memo", None)
    key = (float(T), float(density), "graded")
    if memo is not None and key in memo:
        return memo[key]
    uniform = sample_grid(system, T, density)
    if uniform.size < 4 * MIN_GRID_POINTS:
        return uniform
    memo = getattr(system, "_grid_memo", None)  # (created by sample_grid on first use)
    grid = _graded(np.asarray(sig, float), np.asarray(wd, float), T, density)
    if grid is None or not grid.size < GRADED_SHARE * uniform.size:
        grid = uniform
    else:
        grid.flags.writeable = False
    if memo is not None:
        if len(memo) >= GRID_MEMO:
            memo.pop(next(iter(memo)))
        memo[key] = grid
    return grid


def _graded(sig: np.ndarray, wd: np.ndarray, T: float, density: float) -> np.ndarray | None:
    """The points of :func:`root_grid` (None if no mode decays within ``T``)."""
    with np.errstate(divide="ignore"):
        life = np.where(sig > 0.0, GRID_DECAY / np.maximum(sig, 1e-300), math.inf)
    ends = np.unique(np.concatenate([life[life < T], [T]]))
    if ends.size == 1:
        return None
    pieces, a = [], 0.0
    for b in ends:
        alive = wd[life > a]
        w = float(np.max(alive)) if alive.size else 0.0
        n = max(MIN_GRID_POINTS // 2, math.ceil((b - a) * w / math.pi * POINTS_PER_HALF_PERIOD * density))
        if not n <= MAX_GRID_POINTS:
            return None  # sample_grid's refusal stands
        pieces.append(np.linspace(a, b, n + 1)[:-1])
        a = b
    pieces.append(np.array([T]))
    return np.concatenate(pieces)


def _new_grid(system, T: float, density: float) -> np.ndarray:
    wmax = fastest_frequency(system)
    n = MIN_GRID_POINTS
    if wmax > 0.0:
        n = max(n, math.ceil(T * wmax / math.pi * POINTS_PER_HALF_PERIOD))
    n = math.ceil(n * density)
    if not n <= MAX_GRID_POINTS:  # also NaN/inf: a move no budget check stopped (direct core calls)
        raise SolverError(
            f"the move spans {T:.4g} s, about {T * wmax / math.pi:.3g} half periods of the fastest mode "
            f"({wmax:.4g} rad/s): over the work budget of the time-optimal solver; move less far"
        )
    return np.linspace(0.0, T, n + 1)


MAX_DEPTH = 40
#: ``1 / j!`` for the Taylor bounds of :func:`isolate_roots` (orders up to 20).
_INV_FACTORIAL = 1.0 / np.array([math.factorial(j) for j in range(21)], dtype=float)


@dataclass
class RootIsolation:
    """Zeros of ``S`` on ``[0, T]``, isolated with proof.

    Attributes
    ----------
    roots : ndarray
        Sign changes of ``S`` (time-to-go, s), increasing, refined to machine precision.
    sign0 : float
        Sign of ``S`` on ``[0, roots[0])``.
    unproved : int
        Cells where neither zero-freeness nor monotonicity could be proved
        within :data:`MAX_DEPTH` bisections or a work budget (a tangency, a
        cluster of zeros closer than ``T / 2**MAX_DEPTH``, or ``S`` at the
        level of rounding noise).  Zero means every sign change of
        ``S`` on ``[0, T]`` is in ``roots`` and there are no others.
    """

    roots: np.ndarray
    sign0: float
    unproved: int


TAYLOR_ORDER = 8


def isolate_roots(
    system,
    nu: np.ndarray,
    T: float,
    grid: np.ndarray | None = None,
    order: int = TAYLOR_ORDER,
    magnitude: float | None = None,
    compiled: bool = False,
) -> RootIsolation:
    """All sign changes of ``S`` on ``[0, T]``, isolated with proof.

    On a cell ``[a, b]`` of width ``h``, Taylor's theorem at ``a`` with the
    derivatives ``S^(j)(a)``, ``j <= K``, and a global bound ``M`` on
    ``|S^(K+1)|`` bounds ``S'`` on the cell::

        |S'(t) - S'(a)| <= sum_{j=2..K} |S^(j)(a)| h^(j-1)/(j-1)! + M h^K/K! =: R

    The cell holds no zero if ``S(a)``, ``S(b)`` have one sign and
    ``|S(a)| + |S(b)| > (|S'(a)| + R) h``; it holds exactly one if they
    differ and ``|S'(a)| > R`` (``S`` monotone).  Other cells are halved.
    Local derivatives matter: for short moves ``S`` is a small difference of
    large terms, and global Lipschitz bounds would prove nothing.  Close
    clusters of zeros (a short blip between two samples, three zeros in one
    cell), which sampling signs alone misses, are found this way.  A sample
    point (grid point or bisection midpoint) where ``|S|`` is at rounding
    level is moved off it first: ``S`` there may round to exactly 0, and a
    zero sign at a cell end would hide a sign change from both neighbouring
    cells.  ``order``
    is ``K``: higher proves more cells without bisection, lower is cheaper
    per cell.  ``magnitude``: ``system.switching_magnitude(nu, T)[0]`` when
    the caller has it (the certificate needs it three times).  ``compiled``:
    the bisection and refinement by :func:`~..kernels.roots.isolate_and_refine`
    when the compiled kernels are active and ``system`` offers its closed
    form (``switching_terms``, a ``ModalResponse``) (the same proof; roots equal to rounding, which
    near a tangency is ~1e-12 of ``T``: only the certificate, whose checks
    carry tolerances, asks for it; the solver's iterations, where such a
    difference can steer a hard case elsewhere, keep the numpy reference).
    """
    if grid is None:
        grid = sample_grid(system, T)
    K = order
    local = getattr(system, "switching_derivative_bound_from", None)

    def bound(a: np.ndarray) -> np.ndarray | float:
        """Bound on ``|S^(K+1)|`` over cells starting at ``a``."""
        return local(nu, K + 1, a) if local is not None else system.switching_derivative_bound(nu, K + 1)

    # 1 / (j-1)! for j = 2..K (the Taylor terms of S'), and 1 / K!
    inv_fact = _INV_FACTORIAL[1:K, None]
    inv_fact_K = float(_INV_FACTORIAL[K])
    mag0 = system.switching_magnitude(nu, T)[0] if magnitude is None else magnitude
    grid = np.asarray(grid, dtype=float)
    noise = 1e3 * np.finfo(float).eps * mag0
    budget = 4 * grid.size + 1000  # cells in work at once; beyond it, stop proving
    sign0 = _sign_at_zero(system, nu)
    # cells proved zero-free by the rigid part's dominance are dropped before
    # any sampling: the work then scales with where S can vanish, not with T
    cells = cells_to_examine(system, nu, grid, noise)
    if cells is None:
        points = grid
        D = np.array(system.switching(nu, points, order=K))  # (K+1, len(points))
    else:
        idx = cell_points(cells)  # grid points the kept cells need
        points = grid[idx]
        if idx.size >= SHARED_BASIS_SHARE * grid.size and not grid.flags.writeable and _takes_rows(system):
            # most of a planner's grid: its trigonometric basis once per T, not per co-state
            D = np.array(system.switching(nu, grid, order=K, rows=idx))
        else:
            D = np.array(system.switching(nu, points, order=K))
    # a zero sitting on an interior grid point (symmetric profiles put one at
    # T/2) has a sign decided by rounding: move such points off it (a point
    # next to a dropped cell is not near a zero: that cell's proof covers the move)
    noisy = np.flatnonzero(np.abs(D[0]) <= noise)
    noisy = noisy[(points[noisy] > grid[0]) & (points[noisy] < grid[-1])]
    if noisy.size:
        prev = np.searchsorted(grid, points[noisy]) - 1  # the grid point before each
        points = points.copy()
        points[noisy] -= (points[noisy] - grid[prev]) / 3.0
        D[:, noisy] = np.array(system.switching(nu, points[noisy], order=K))
    if cells is None:
        a, b = points[:-1], points[1:]
        Da = D[:, :-1]
        Sb, dSb = D[0, 1:], D[1, 1:]
    else:
        ia, ib = np.searchsorted(idx, cells), np.searchsorted(idx, cells + 1)
        a, b = points[ia], points[ib]
        Da = D[:, ia]
        Sb, dSb = D[0, ib], D[1, ib]
    if compiled and backend.ACTIVE and hasattr(system, "switching_terms"):
        # the same bisection and refinement, compiled: one call instead of ~25 numpy calls per level
        rigid_bound, amp = system.switching_derivative_bound_terms(nu, K + 1)
        roots, unproved = kernel_roots.isolate_and_refine(
            np.ascontiguousarray(a, dtype=float),
            np.ascontiguousarray(b, dtype=float),
            np.ascontiguousarray(Da, dtype=float),
            np.ascontiguousarray(Sb, dtype=float),
            np.ascontiguousarray(dSb, dtype=float),
            *system.switching_terms(nu, K),
            rigid_bound,
            amp,
            float(noise),
            int(budget),
            MAX_DEPTH,
            _INV_FACTORIAL[1:K],
            float(inv_fact_K),
            16.0 * np.finfo(float).eps * float(mag0),
        )
        return RootIsolation(roots, sign0, int(unproved))
    br_a, br_b, br_Sa, br_Sb, br_da, br_db = [], [], [], [], [], []
    unproved = 0
    for depth in range(MAX_DEPTH + 1):
        h = b - a
        Sa, dSa = Da[0], Da[1]
        hp = np.cumprod(np.broadcast_to(h, (K, h.size)), axis=0)  # h^j for j = 1..K
        R = np.sum(np.abs(Da[2:]) * hp[: K - 1] * inv_fact, axis=0) + bound(a) * hp[K - 1] * inv_fact_K
        change = np.sign(Sa) * np.sign(Sb) < 0
        free = ~change & (np.abs(Sa) + np.abs(Sb) > (np.abs(dSa) + R) * h)
        mono = np.abs(dSa) > R
        one = change & mono
        br_a.append(a[one])
        br_b.append(b[one])
        br_Sa.append(Sa[one])
        br_Sb.append(Sb[one])
        br_da.append(dSa[one])
        br_db.append(dSb[one])
        todo = ~(free | mono)  # a monotone cell without sign change holds no zero
        if not todo.any():
            break
        a, b, Da, Sb, dSb = a[todo], b[todo], Da[:, todo], Sb[todo], dSb[todo]
        if depth == MAX_DEPTH or a.size > budget:
            # give up proving: keep plain sign changes, report the cells
            unproved = int(a.size)
            last = np.sign(Da[0]) * np.sign(Sb) < 0
            br_a.append(a[last])
            br_b.append(b[last])
            br_Sa.append(Da[0][last])
            br_Sb.append(Sb[last])
            br_da.append(Da[1][last])
            br_db.append(dSb[last])
            break
        mid = 0.5 * (a + b)
        Dm = np.array(system.switching(nu, mid, order=K))
        # likewise a midpoint on a zero (a switch at T/2 when the grid point
        # there was dropped): S(mid) may round to exactly 0, and a zero sign
        # at a cell end hides the sign change from both halves
        for frac in (1.0 / 3.0, 2.0 / 3.0):
            on_zero = np.flatnonzero(np.abs(Dm[0]) <= noise)
            if not on_zero.size:
                break
            mid[on_zero] = a[on_zero] + frac * (b[on_zero] - a[on_zero])
            Dm[:, on_zero] = np.array(system.switching(nu, mid[on_zero], order=K))
        a, b = np.concatenate([a, mid]), np.concatenate([mid, b])
        Da = np.concatenate([Da, Dm], axis=1)
        Sb = np.concatenate([Dm[0], Sb])
        dSb = np.concatenate([Dm[1], dSb])
    a = np.concatenate(br_a)
    if a.size == 0:
        return RootIsolation(np.empty(0), sign0, unproved)
    b = np.concatenate(br_b)

    def fS(t):
        return system.switching(nu, t, derivative=True)

    Sa, Sb = np.concatenate(br_Sa), np.concatenate(br_Sb)
    start = hermite_root(a, b, Sa, Sb, np.concatenate(br_da), np.concatenate(br_db))
    roots = np.sort(refine_roots(fS, a, b, Sa, Sb, mag0, start=start))
    return RootIsolation(roots, sign0, unproved)


#: When the cells left to examine need at least this share of a planner's (read-only,
#: cached) grid, the switching function is evaluated from the whole grid's basis
#: (``ModalResponse.switching(..., rows=)``): computed once per duration, shared by
#: the co-states of every evaluation at that duration.
SHARED_BASIS_SHARE = 0.25


def _takes_rows(system) -> bool:
    """Whether ``system.switching`` evaluates a subset of a grid from the grid's basis (``rows=``)."""
    return bool(getattr(system, "SWITCHING_TAKES_ROWS", False))


def _sign_at_zero(system, nu: np.ndarray) -> float:
    """Sign of ``S`` just after ``tau = 0`` (of ``S'`` if ``S(0) = 0``; 1 if both vanish)."""
    S0, dS0 = system.switching(nu, np.zeros(1), derivative=True)
    return float(np.sign(S0[0]) or np.sign(dS0[0]) or 1.0)


def find_roots(system, nu: np.ndarray, T: float, grid: np.ndarray | None = None):
    """Sign changes of ``S`` on ``(0, T)``: ``(roots, sign0)`` (see :func:`isolate_roots`).

    The planners' working version: Taylor order 4 (cheaper per cell; the
    certificate uses the full order).
    """
    iso = isolate_roots(system, nu, T, grid, order=4)
    return iso.roots, iso.sign0
