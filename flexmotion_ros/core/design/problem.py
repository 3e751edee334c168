"""The objective of a structure design, the weighted optimal move time, and the design problem from a parameter file.

A *design problem* (:mod:`.statement`) is a physical builder (:mod:`~flexmotion_ros.core.model.builders`: ``two_mass``,
``crane``, ``chain``) with a starting set of physical parameters, one to three
of those parameters free within bounds, and one rest-to-rest task or a
weighted set of them.  The objective is the weighted optimal move time::

    J(theta) = sum_i w_i T*_i(theta)      (s)

where ``T*_i`` is the move time of task ``i`` with the configured profile type
(``time_optimal`` by default; any method of
:mod:`~flexmotion_ros.core.methods.table`, e.g. a robust one, via its ``plan_move``).  Optionally a robustness
requirement makes a design infeasible when its profile leaves more than
``max_residual`` of vibration on models whose frequencies are off by up to
``frequency_error``.

The free parameters and their ranges are :mod:`.space`; the search for the
best structure is :func:`~.optimize.optimize_design`.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..config import config_from_parameters
from ..errors import ConfigError, GoalError, ModelError, SolverError
from ..methods import table
from ..model.boundary import rest_to_rest
from ..model.builders import BUILDERS
from ..time_optimal.rigid_body import rigid_time
from .space import DesignParameter, build, check_builder, normalise_base, split_parameters
from .statement import DesignProblem, RobustnessRequirement, Task


@dataclass
class Evaluation:
    """The objective at one design point.

    Attributes
    ----------
    values : tuple of float
        Parameter values (in :attr:`DesignProblem.names` order).
    objective : float
        ``sum w_i T_i`` (s); ``inf`` if infeasible or failed.
    times : tuple of float
        Move time of each task (s), ``nan`` where it failed.
    certified : bool or None
        Every task's profile carries a passed optimality certificate; None
        if the method issues none (e.g. input shapers, not optimal anyway).
    status : str
        ``"ok"`` or why the point is infeasible.
    residual : float or None
        Worst residual vibration under frequency error (with a requirement).
    solve_time_s : float
        Wall time spent planning this point (s).
    plans : tuple
        The :class:`~.planning.PlanResult` of each task (empty on failure).
    """

    values: tuple[float, ...]
    objective: float
    times: tuple[float, ...]
    certified: bool | None
    status: str
    residual: float | None = None
    solve_time_s: float = 0.0
    plans: tuple = ()

    @property
    def feasible(self) -> bool:
        return math.isfinite(self.objective)

    def to_dict(self, names: Sequence[str]) -> dict:
        return {
            "values": dict(zip(names, self.values)),
            "objective": self.objective if self.feasible else None,
            "times": [t if math.isfinite(t) else None for t in self.times],
            "certified": self.certified,
            "status": self.status,
            "residual": self.residual,
        }


def evaluate_point(problem: DesignProblem, values: Sequence[float]) -> Evaluation:
    """Plan every task on the design ``values`` (no cache; see :class:`DesignObjective`)."""
    values = tuple(float(v) for v in values)
    t0 = time.perf_counter()
    nan = (math.nan,) * len(problem.tasks)
    try:
        built = build(problem.builder, problem.base, problem.values_dict(values))
    except (ModelError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        return Evaluation(values, math.inf, nan, False, f"model: {exc}", None, time.perf_counter() - t0)
    config = problem.config.with_changes(model=built.model)
    plans, times, certs, worst = [], [], [], 0.0
    for task in problem.tasks:
        move = rest_to_rest(built.model, config.u_max, task.gamma)
        try:
            plan = table.plan_move(config, move)  # looked up at each call (tests replace it)
        except SolverError as exc:
            return Evaluation(values, math.inf, nan, False, f"solver: {exc}", None, time.perf_counter() - t0)
        plans.append(plan)
        times.append(float(plan.continuous.duration if plan.continuous is not None else plan.duration))
        certs.append(getattr(plan.continuous, "certified", None))  # None: the method has no certificate
        if problem.robustness is not None:
            u = plan.continuous.input() if plan.continuous is not None else plan.sampled.input()
            worst = max(worst, problem.robustness.residual(built.model, move.x0, u))
    certified = False if any(c is not None and not c for c in certs) else (None if None in certs else True)
    objective = float(sum(t.weight * T for t, T in zip(problem.tasks, times)))
    status = "ok"
    if problem.robustness is not None and worst > problem.robustness.max_residual:
        status = f"robustness: residual {worst:.3g} > max_residual {problem.robustness.max_residual:g}"
        objective = math.inf
    elif problem.require_certified and certified is False:
        status = "not certified"
        objective = math.inf
    residual = worst if problem.robustness is not None else None
    return Evaluation(
        values, objective, tuple(times), certified, status, residual, time.perf_counter() - t0, tuple(plans)
    )


def rigid_bound(problem: DesignProblem, values: Sequence[float]) -> float:
    """``sum w_i T_rigid,i`` (s): the weighted rigid-body optimum, a lower bound on ``J`` (closed form)."""
    model = build(problem.builder, problem.base, problem.values_dict(values)).model
    u = problem.config.u_max
    return float(
        sum(
            t.weight * rigid_time(model, u, rest_to_rest(model, u, t.gamma).shifted_initial(), True)
            for t in problem.tasks
        )
    )


def _evaluate_star(args):  # module level: picklable for worker processes
    return evaluate_point(*args)


class DesignObjective:
    """``J(values)`` with a cache keyed by parameter value: no point is solved twice."""

    def __init__(self, problem: DesignProblem) -> None:
        self.problem = problem
        self.cache: dict[tuple[float, ...], Evaluation] = {}
        self.order: list[tuple[float, ...]] = []

    def __call__(self, values: Sequence[float]) -> Evaluation:
        key = tuple(float(v) for v in values)
        ev = self.cache.get(key)
        if ev is None:
            ev = evaluate_point(self.problem, key)
            self._store(key, ev)
        return ev

    def _store(self, key, ev) -> None:
        self.cache[key] = ev
        self.order.append(key)

    def many(self, points: Sequence[Sequence[float]], workers: int = 1) -> list[Evaluation]:
        """Evaluate many points; new ones in ``workers`` processes if > 1 (fork start method)."""
        keys = [tuple(float(v) for v in p) for p in points]
        todo = list(dict.fromkeys(k for k in keys if k not in self.cache))
        if workers > 1 and len(todo) > 1:
            with mp.get_context("fork").Pool(int(workers)) as pool:
                evs = pool.map(
                    _evaluate_star, [(self.problem, k) for k in todo], chunksize=max(1, len(todo) // (4 * workers))
                )
            for k, ev in zip(todo, evs):
                self._store(k, ev)
        else:
            for k in todo:
                self._store(k, evaluate_point(self.problem, k))
        return [self.cache[k] for k in keys]

    @property
    def solves(self) -> int:
        """Design points evaluated (each plans every task once)."""
        return len(self.cache)

    def unit(self, u: Sequence[float]) -> float:
        """Objective at search coordinates ``u`` (in ``[0, 1]^p``)."""
        ps = self.problem.parameters
        return self([p.from_unit(float(np.clip(x, 0.0, 1.0))) for p, x in zip(ps, u)]).objective


def problem_from_parameters(
    params: Mapping[str, Any],
    bounds: Mapping[str, tuple[float, float]] | Sequence[DesignParameter],
    goals: Sequence[float],
    weights: Sequence[float] | None = None,
    builder: str | None = None,
    overrides: Mapping[str, Any] | None = None,
    robustness: RobustnessRequirement | None = None,
    config_changes: Mapping[str, Any] | None = None,
) -> tuple[DesignProblem, list[str]]:
    """A design problem from a parameter file's flat parameters plus command-line choices.

    The starting structure is ``design.builder`` and ``design.<argument>``
    (``builder`` / ``overrides`` replace them); ``u_max``, ``rate_hz``,
    ``method``, limits and options come from the planner parameters.  Returns
    the problem and notes (e.g. the file's modal model differs from the
    structure's).
    """
    file_builder, base, planner = split_parameters(params)
    builder = builder or file_builder
    if builder is None:
        raise ConfigError(
            "design.builder",
            f"not set: a modal model carries no physical parameters; add a 'design:' section "
            f"(builder: one of {sorted(BUILDERS)}, and its arguments) or pass --builder and --set",
        )
    check_builder(builder)
    if builder != file_builder and file_builder is not None:
        base = {}
    base = normalise_base(builder, {**base, **(overrides or {})})
    start = build(builder, base)
    config = config_from_parameters({**planner, **{f"model.{k}": v for k, v in start.model.to_dict().items()}})
    if config_changes:
        changes = dict(config_changes)
        if "options" in changes:  # added to the file's options, not replacing them
            changes["options"] = {**config.options, **changes["options"]}
        config = config.with_changes(**changes)
    notes = []
    if any(k.startswith("model.") for k in planner):
        file_model = config_from_parameters(planner).model
        a, b = file_model.to_dict(), start.model.to_dict()
        same = all(np.size(a[k]) == np.size(b[k]) and np.allclose(a[k], b[k], rtol=1e-9, atol=1e-12) for k in a)
        if not same:
            notes.append(
                "the file's model section is not the starting structure (design section / --builder / --set); the structure is used"
            )
    if isinstance(bounds, Mapping):
        bounds = [DesignParameter(n, lo, hi) for n, (lo, hi) in bounds.items()]
    weights = [1.0] * len(goals) if weights is None else list(weights)
    if len(weights) != len(goals):
        raise GoalError("weight", f"give one weight per goal ({len(goals)}), got {len(weights)}")
    tasks = tuple(Task(g, w) for g, w in zip(goals, weights))
    return DesignProblem(builder, base, tuple(bounds), tasks, config, robustness), notes
