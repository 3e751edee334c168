"""The dual of the continuous minimum-fuel problem and its evaluation budget (see :mod:`.min_fuel`).

``d(nu) = nu^T w - u_max int_0^T (|S(tau)| - 1)_+ dtau``: each evaluation
isolates the crossings of ``|S| = 1`` over ``[0, T]`` with proof, so its work
grows with the root grid (``T`` times the fastest frequency); the budget of
one plan is counted in root-grid points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..simulation.modal_response import ModalResponse
from ..time_optimal.switching import isolate_roots, sample_grid

#: Most evaluations of the dual (each isolates the crossings of ``|S| = 1`` over ``[0, T]``) per
#: Newton start, line searches included: converging starts took 6-25 on the fuzz cases.
MAX_DUAL_EVALUATIONS = 40
#: Root-grid points over all dual evaluations of one plan (every start, line searches included):
#: each evaluation isolates the crossings over the whole root grid, so its work grows with the grid
#: (``T`` times the fastest frequency).  Fuzz case 73 (7 modes, a 853 s move, 120,742 points):
#: 82 evaluations without converging; short moves keep :data:`MAX_DUAL_EVALUATIONS` per start.
DUAL_WORK_BUDGET = 3_000_000
#: Fewest dual evaluations a plan is allowed, however long its grid.
MIN_DUAL_EVALUATIONS = 16


def dual_evaluation_budget(system: ModalResponse, T: float) -> int:
    """Dual evaluations allowed for one plan: :data:`DUAL_WORK_BUDGET` over the root grid's size, clipped."""
    points = sample_grid(system, T).size
    return int(min(2 * MAX_DUAL_EVALUATIONS, max(MIN_DUAL_EVALUATIONS, DUAL_WORK_BUDGET // max(points, 1))))


class _Offset:
    """``S(tau) - offset`` for :func:`isolate_roots` (crossings of ``S = offset``).

    It evaluates on the wrapped system's grid with that system's cached
    trigonometric basis (``rows=``) and local derivative bounds (``S - offset``
    has the derivatives of ``S``): before, each dual evaluation built a fresh
    grid whose basis (``exp``, ``sin``, ``cos`` at every point) was never reused.
    """

    def __init__(self, system: ModalResponse, offset: float) -> None:
        self.sys = system
        self.offset = offset
        self.wd = system.wd
        self.SWITCHING_TAKES_ROWS = bool(getattr(system, "SWITCHING_TAKES_ROWS", False))
        local = getattr(system, "switching_derivative_bound_from", None)
        if local is not None:
            self.switching_derivative_bound_from = local

    def switching(self, nu, tau, derivative=False, order=None, rows=None):
        if rows is not None:
            out = self.sys.switching(nu, tau, derivative=derivative, order=order, rows=rows)
        else:
            out = self.sys.switching(nu, tau, derivative=derivative, order=order)
        if isinstance(out, tuple):
            return (out[0] - self.offset,) + tuple(out[1:])
        return out - self.offset

    def switching_derivative_bound(self, nu, order):
        return self.sys.switching_derivative_bound(nu, order)

    def switching_magnitude(self, nu, tau_max):
        m0, m1 = self.sys.switching_magnitude(nu, tau_max)
        return m0 + abs(self.offset), m1


@dataclass
class DualEval:
    breaks: np.ndarray  # time-to-go breakpoints 0 .. T
    levels: np.ndarray  # -1/0/+1 on each tau-interval
    crossings: np.ndarray
    value: float
    grad: np.ndarray  # w - reached (unscaled)
    fuel: float
    unproved: int


def dual_eval(system: ModalResponse, nu: np.ndarray, w: np.ndarray, T: float, um: float) -> DualEval:
    grid = sample_grid(system, T)  # one read-only grid per T (memoised): its basis is cached
    up = isolate_roots(_Offset(system, 1.0), nu, T, grid=grid)
    dn = isolate_roots(_Offset(system, -1.0), nu, T, grid=grid)
    cross = np.unique(np.concatenate([up.roots, dn.roots]))
    cross = cross[(cross > 0.0) & (cross < T)]
    breaks = np.concatenate([[0.0], cross, [T]])
    mids = 0.5 * (breaks[:-1] + breaks[1:])
    S = system.switching(nu, mids)
    levels = np.where(S > 1.0, 1.0, np.where(S < -1.0, -1.0, 0.0))
    Gam = system.input_integral(breaks)
    dG = Gam[1:] - Gam[:-1]
    reached = um * (levels @ dG)
    on = levels != 0.0
    fuel = um * float(np.sum(np.diff(breaks)[on]))
    # d = nu^T w - u_max sum_on (sgn nu^T dGamma - length) = nu^T (w - reached) + fuel
    value = float(nu @ (w - reached)) + fuel
    return DualEval(breaks, levels, cross, value, w - reached, fuel, up.unproved + dn.unproved)
