"""Integrated structure/control design (seed section 2.4): the search for the structure that moves fastest.

The design problem and its objective ``J`` are :mod:`.design_problem`; the
designable parameters and their ranges are :mod:`.design_space`.  This module
minimises ``J`` over the bounds (:func:`optimize_design`) and writes the
result as a parameter file.

Why grid + bracketing + local refine
------------------------------------
``T*`` is *continuous* in the parameters: the set reachable in time ``T`` with
``|u| <= u_max`` depends continuously on ``(A, B, T)`` and, for a controllable
single-input system, grows strictly with ``T``, so the first ``T`` at which it
contains the start cannot jump.  But ``T*`` is *not differentiable* everywhere:
where the switch structure changes (a switch enters at ``t = 0`` or ``T``, two
switches merge) or the rigid-body bound ``T* >= T_rigid`` is attained, it has
kinks, and it has many local minima (e.g. every stiffness for which the rigid
bang-bang leaves no vibration).  Gradient methods stall at kinks and only find
the nearest local minimum.  Hence:

1. a global grid (log-spaced for ranges spanning a decade or more): by
   continuity, the grid minimum is within the variation of ``J`` over one cell
   of the global minimum, and it brackets a local minimum;
2. a local refine that needs only continuity and local unimodality, never
   derivatives, started from the best grid cells (every grid local minimum
   within one cell's variation of the best): golden-section search on the
   bracket ``[x_{i-1}, x_{i+1}]`` for one parameter, a bounded Nelder-Mead
   simplex in the neighbouring cells for two or three.

The reported design is the best *certified* point evaluated, so it is never
worse than the grid.  A point whose solve fails (``SolverError``) or whose
model is non-physical counts as infeasible (``+inf``).  Every value is cached
by parameter value: no design point is solved twice.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..config import PlannerConfig, dump_parameters
from ..errors import InputError, SolverError
from ..model.builders import BuiltModel
from .problem import DesignObjective, DesignProblem, Evaluation
from .space import build, design_parameters


@dataclass
class DesignResult:
    """The best structure for the task(s).

    Attributes
    ----------
    problem : DesignProblem
    best : dict
        Optimal parameter values.
    evaluation : Evaluation
        The objective, move times and plans there (certified).
    start : dict
        Starting parameter values.
    start_evaluation : Evaluation
        The same at the starting design.
    built : BuiltModel
        The physical model at the optimum.
    config : PlannerConfig
        The input configuration with the optimal model.
    grid_axes : tuple of ndarray
        Grid values of each parameter.
    grid_objective : ndarray
        ``J`` on the grid (``inf`` where infeasible), shape ``len(axes)`` each.
    evaluations : list of Evaluation
        Every point evaluated, in order.
    wall_time_s : float
    """

    problem: DesignProblem
    best: dict
    evaluation: Evaluation
    start: dict
    start_evaluation: Evaluation
    built: BuiltModel
    config: PlannerConfig
    grid_axes: tuple
    grid_objective: np.ndarray
    evaluations: list = field(default_factory=list)
    wall_time_s: float = 0.0

    @property
    def objective(self) -> float:
        return self.evaluation.objective

    @property
    def certified(self) -> bool | None:
        """Every move at the optimum certified optimal (None: the method has no certificate)."""
        return self.evaluation.certified

    def to_dict(self) -> dict:
        """JSON-friendly summary."""
        names = self.problem.names
        start = self.start_evaluation
        return {
            "builder": self.problem.builder,
            "method": self.problem.config.method,
            "best": self.best,
            "objective_s": self.objective,
            "times_s": list(self.evaluation.times),
            "certified": self.certified,
            "start": self.start,
            "start_objective_s": start.objective if start.feasible else None,
            "start_status": start.status,
            "improvement_s": (start.objective - self.objective) if start.feasible else None,
            "tasks": [{"gamma": t.gamma, "weight": t.weight} for t in self.problem.tasks],
            "bounds": {p.name: [p.lower, p.upper, p.scale] for p in self.problem.parameters},
            "model": self.built.model.to_dict(),
            "physical": design_parameters(self.problem.builder, self.built.parameters),
            "evaluations": len(self.evaluations),
            "failed": sum(1 for e in self.evaluations if not e.feasible),
            "wall_time_s": self.wall_time_s,
            "points": [e.to_dict(names) for e in self.evaluations],
        }


def default_grid(n_parameters: int) -> int:
    """Grid points per parameter: 41 for one parameter, 15 for two, 7 for three."""
    return {1: 41, 2: 15}.get(n_parameters, 7)


def _brent(f, a: float, b: float, tol: float, penalty: float) -> None:
    """Brent's bounded minimisation on ``[a, b]`` (golden section + parabolic steps).

    Parabolic steps speed up smooth minima; where ``J`` has a kink or a
    failed point (``inf``, passed as the finite ``penalty``) the parabola is
    rejected and Brent takes golden-section steps, which need only
    unimodality.  Values are cached by ``f``'s owner.
    """
    from scipy.optimize import minimize_scalar

    def g(u: float) -> float:
        v = f(u)
        return v if math.isfinite(v) else penalty

    minimize_scalar(g, bounds=(a, b), method="bounded", options={"xatol": tol, "maxiter": 200})


def _candidates(J: np.ndarray, max_refine: int) -> list[tuple[int, ...]]:
    """Grid local minima worth refining: the best, and those within one cell's variation of it."""
    finite = np.isfinite(J)
    if not finite.any():
        return []
    best = np.unravel_index(int(np.argmin(np.where(finite, J, np.inf))), J.shape)
    minima, spread = [], 0.0
    for idx in np.ndindex(*J.shape):
        if not finite[idx]:
            continue
        nb = [J[tuple(n)] for n in _neighbours(idx, J.shape)]
        if all(J[idx] <= v for v in nb):
            minima.append(idx)
        if idx == best:
            spread = max((abs(v - J[idx]) for v in nb if math.isfinite(v)), default=0.0)
    minima.sort(key=lambda i: J[i])
    return [i for i in minima if J[i] - J[best] <= spread][:max_refine]


def _neighbours(idx, shape):
    for d in np.ndindex(*(3,) * len(shape)):
        n = [i + di - 1 for i, di in zip(idx, d)]
        if any(x != i for x, i in zip(n, idx)) and all(0 <= x < s for x, s in zip(n, shape)):
            yield n


def optimize_design(
    problem: DesignProblem,
    grid: int | Sequence[int] | None = None,
    xtol: float = 1e-5,
    max_refine: int = 3,
    workers: int = 1,
) -> DesignResult:
    """Choose the structural parameters that make the (weighted) move time shortest.

    Parameters
    ----------
    problem : DesignProblem
    grid : int or sequence of int, optional
        Grid points per parameter (>= 3); default :func:`default_grid`.
    xtol : float
        Refine until the bracket / simplex is this small, as a fraction of the
        parameter's (log-)range.
    max_refine : int
        At most this many grid minima are refined.
    workers : int
        Processes for the grid phase (the refine is sequential).

    Returns
    -------
    DesignResult

    Raises
    ------
    SolverError
        No design point in the bounds gave a certified (and robust) move.
    """
    t0 = time.perf_counter()
    p = len(problem.parameters)
    sizes = (
        [default_grid(p)] * p if grid is None else ([int(grid)] * p if np.isscalar(grid) else [int(g) for g in grid])
    )
    if len(sizes) != p or any(not 3 <= g <= 2001 for g in sizes):
        raise InputError("grid", f"needs {p} value(s), each in [3, 2001] points, got {sizes}")
    if int(workers) < 1:
        raise InputError("workers", f"must be >= 1 process, got {workers}")
    if not (math.isfinite(xtol) and 0.0 < xtol < 1.0):
        raise InputError("xtol", f"must be in (0, 1) (fraction of the range), got {xtol}")
    f = DesignObjective(problem)
    start = problem.start()
    start_ev = f(list(start.values()))  # first: bad method options surface here, before the sweep
    axes_u = [np.linspace(0.0, 1.0, g) for g in sizes]
    axes = tuple(np.array([par.from_unit(u) for u in au]) for par, au in zip(problem.parameters, axes_u))
    points = [tuple(ax[i] for ax, i in zip(axes, idx)) for idx in np.ndindex(*sizes)]
    evs = f.many(points, workers)
    J = np.array([e.objective for e in evs]).reshape(sizes)
    for idx in _candidates(J, max_refine):
        lo = [au[max(i - 1, 0)] for au, i in zip(axes_u, idx)]
        hi = [au[min(i + 1, len(au) - 1)] for au, i in zip(axes_u, idx)]
        if p == 1:
            _brent(lambda u: f.unit([u]), lo[0], hi[0], xtol, penalty=10.0 * float(np.nanmax(J[np.isfinite(J)])) + 1.0)
        else:
            _nelder_mead(f, [au[i] for au, i in zip(axes_u, idx)], lo, hi, xtol)
    inside = [e for e in f.cache.values() if problem.contains(e.values)]  # the start may lie outside
    best_ev = min(inside, key=lambda e: e.objective)
    if not best_ev.feasible:
        reasons = sorted({e.status.split(":")[0] for e in inside})
        raise SolverError(
            f"no design in the bounds gave a certified{' robust' if problem.robustness else ''} move "
            f"({len(f.cache)} points tried; failures: {', '.join(reasons)})"
        )
    best = problem.values_dict(best_ev.values)
    built = build(problem.builder, problem.base, best)
    return DesignResult(
        problem=problem,
        best=best,
        evaluation=best_ev,
        start=start,
        start_evaluation=start_ev,
        built=built,
        config=problem.config.with_changes(model=built.model),
        grid_axes=axes,
        grid_objective=J,
        evaluations=[f.cache[k] for k in f.order],
        wall_time_s=time.perf_counter() - t0,
    )


def _nelder_mead(f: DesignObjective, u0, lo, hi, xtol: float) -> None:
    """Bounded Nelder-Mead in the cells around ``u0`` (derivative-free, copes with kinks)."""
    from scipy.optimize import minimize

    u0 = np.asarray(u0, dtype=float)
    lo, hi = np.asarray(lo), np.asarray(hi)
    simplex = [u0]
    for j in range(u0.size):  # half a cell towards the roomier side along each axis
        v = u0.copy()
        v[j] += 0.5 * (hi[j] - u0[j]) if hi[j] - u0[j] >= u0[j] - lo[j] else -0.5 * (u0[j] - lo[j])
        simplex.append(v)
    minimize(
        f.unit,
        u0,
        method="Nelder-Mead",
        bounds=list(zip(lo, hi)),
        options={"initial_simplex": np.array(simplex), "xatol": xtol, "fatol": 1e-12, "maxfev": 60 * u0.size},
    )


def result_parameters(result: DesignResult) -> dict[str, Any]:
    """Flat parameters of the designed configuration: the planner's (model at the optimum, the
    input's ``u_max``, ``rate_hz``, method, options) plus the ``design:`` section at the optimum."""
    params = result.config.to_parameters()
    for key in ("limits.position_min", "limits.position_max"):
        if not math.isfinite(params[key]):
            del params[key]
    params.update(design_parameters(result.problem.builder, result.built.parameters))
    return params


def write_design(path, result: DesignResult, header: str = "") -> None:
    """Write the designed configuration as a ROS 2 parameter file (loads with ``load_config``)."""
    from pathlib import Path

    Path(path).write_text(dump_parameters(result_parameters(result), header))
