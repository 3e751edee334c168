"""The design problem and its objective: the weighted optimal move time of a structure.

A *design problem* is a physical builder (:mod:`.builders`: ``two_mass``,
``crane``, ``chain``) with a starting set of physical parameters, one to three
of those parameters free within bounds, and one rest-to-rest task or a
weighted set of them.  The objective is the weighted optimal move time::

    J(theta) = sum_i w_i T*_i(theta)      (s)

where ``T*_i`` is the move time of task ``i`` with the configured profile type
(``time_optimal`` by default; any method registered in :mod:`.planning`, e.g.
a robust one, via :func:`~.planning.plan_move`).  Optionally a robustness
requirement makes a design infeasible when its profile leaves more than
``max_residual`` of vibration on models whose frequencies are off by up to
``frequency_error``.

The free parameters and their ranges are :mod:`.design_space`; the search
for the best structure is :func:`~.design.optimize_design`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..config import PlannerConfig, config_from_parameters
from ..errors import ConfigError, GoalError, InputError, ModelError, SolverError
from ..model.boundary import rest_to_rest
from ..model.builders import BUILDERS
from ..simulation.exact import final_state, modal_amplitudes
from .space import (
    INDEXED_PARAMETER,
    MAX_PARAMETERS,
    PARAMETER_RANGES,
    DesignParameter,
    build,
    check_builder,
    in_range,
    normalise_base,
    parameter_value,
    range_text,
    split_parameters,
)


@dataclass(frozen=True)
class RobustnessRequirement:
    """Residual vibration allowed when the modal frequencies are off.

    The planned input is simulated exactly on models with every ``omega``
    scaled by ``1 + e`` for ``samples`` values of ``e`` spread over
    ``[-frequency_error, frequency_error]``; the largest mode amplitude left
    after the move must not exceed ``max_residual`` (the modal coordinates'
    unit, m for the builders: the largest spring deflection / payload offset).
    """

    frequency_error: float
    max_residual: float
    samples: int = 4

    def __post_init__(self) -> None:
        e, r = float(self.frequency_error), float(self.max_residual)
        if not (math.isfinite(e) and 0.0 < e < 1.0):
            raise InputError("frequency_error", f"must be in (0, 1) (relative), got {e}")
        if not (math.isfinite(r) and r > 0.0):
            raise InputError("max_residual", f"must be finite and > 0 (m), got {r}")
        if int(self.samples) < 2:
            raise InputError("robust_samples", f"must be >= 2, got {self.samples}")

    def residual(self, model, x0: np.ndarray, u) -> float:
        """Worst residual mode amplitude of input ``u`` over the frequency errors."""
        worst = 0.0
        for e in np.linspace(-self.frequency_error, self.frequency_error, int(self.samples)):
            m = model.with_changes(omega=tuple(w * (1.0 + e) for w in model.omega))
            x = final_state(m, x0, u)
            worst = max(worst, float(np.max(modal_amplitudes(m, x), initial=0.0)))
        return worst


@dataclass(frozen=True)
class Task:
    """A rest-to-rest move of ``gamma`` (m or rad) from 0, weighted by ``weight`` (> 0)."""

    gamma: float
    weight: float = 1.0


@dataclass(frozen=True)
class DesignProblem:
    """What to design.

    Attributes
    ----------
    builder : str
        ``two_mass``, ``crane`` or ``chain``.
    base : dict
        All builder arguments: the starting design.
    parameters : tuple of DesignParameter
        The free parameters (1 to 3).
    tasks : tuple of Task
    config : PlannerConfig
        ``u_max``, ``method``, options, limits, ``rate_hz``; its model is
        replaced by the designed one.
    robustness : RobustnessRequirement or None
    require_certified : bool
        Count a design only if no move failed its optimality certificate
        (methods without a certificate, e.g. input shapers, are not excluded).
    """

    builder: str
    base: dict
    parameters: tuple[DesignParameter, ...]
    tasks: tuple[Task, ...]
    config: PlannerConfig
    robustness: RobustnessRequirement | None = None
    require_certified: bool = True

    def __post_init__(self) -> None:
        check_builder(self.builder)
        base = normalise_base(self.builder, self.base)
        object.__setattr__(self, "base", base)
        build(self.builder, base)  # the starting design must itself be physical
        params = tuple(self._check_parameter(p, base) for p in self.parameters)
        if not 1 <= len(params) <= MAX_PARAMETERS:
            raise InputError("param", f"give 1 to {MAX_PARAMETERS} design parameters, got {len(params)}")
        names = [p.name for p in params]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise InputError(f"param {min(dup)}", "given more than once")
        object.__setattr__(self, "parameters", params)
        if not self.tasks:
            raise GoalError("goal", "give at least one task (--goal GAMMA)")
        tasks = []
        for i, t in enumerate(self.tasks):
            try:
                g, w = float(t.gamma), float(t.weight)
            except (TypeError, ValueError):
                raise GoalError(
                    f"goal[{i}]", f"goal and weight must be numbers, got {t.gamma!r}, {t.weight!r}"
                ) from None
            self.config.check_goal(g)
            if g == 0.0:
                raise GoalError("goal", "must be non-zero: a zero move takes no time for every design")
            if not (math.isfinite(w) and w > 0.0):
                raise GoalError(f"weight[{i}]", f"must be finite and > 0, got {w}")
            tasks.append(Task(g, w))
        object.__setattr__(self, "tasks", tuple(tasks))
        self._check_corners()

    def _check_parameter(self, p: DesignParameter, base: dict) -> DesignParameter:
        name = p.name
        m = INDEXED_PARAMETER.match(name)
        ranges = PARAMETER_RANGES[self.builder]
        key = m.group(1) if m else name
        if key not in ranges or (self.builder == "chain") != bool(m):
            known = list(ranges) if self.builder != "chain" else [f"{k}[i]" for k in ranges]
            raise InputError(f"param {name}", f"is not a design parameter of {self.builder}; one of {known}")
        if m and int(m.group(2)) >= len(base[key]):
            raise InputError(f"param {name}", f"index must be in [0, {len(base[key]) - 1}] for this chain")
        rng = ranges[key]
        try:
            lo, hi = float(p.lower), float(p.upper)
        except (TypeError, ValueError):
            raise InputError(f"param {name}", f"bounds must be numbers, got {p.lower!r}:{p.upper!r}") from None
        allowed = f"need finite LO < HI, both {range_text(rng)}"
        if not (math.isfinite(lo) and math.isfinite(hi)) or lo >= hi:
            raise InputError(f"param {name}", f"bounds {lo}:{hi}: {allowed}")
        for which, v in (("lower", lo), ("upper", hi)):
            if not in_range(v, rng):
                raise InputError(f"param {name}", f"{which} bound {v} is not physical: {allowed}")
        scale = p.scale
        if scale not in ("auto", "linear", "log"):
            raise InputError(f"param {name}", f"scale must be auto, linear or log, got {scale!r}")
        if scale == "log" and lo <= 0.0:
            raise InputError(f"param {name}", f"a log scale needs lower bound > 0, got {lo}")
        if scale == "auto":
            scale = "log" if lo > 0.0 and hi / lo >= 10.0 else "linear"
        return DesignParameter(name, lo, hi, scale)

    def _check_corners(self) -> None:
        """Every corner of the bounds box must give a physical model (e.g. not overdamped)."""
        for corner in np.ndindex(*(2,) * len(self.parameters)):
            values = {p.name: (p.lower, p.upper)[c] for p, c in zip(self.parameters, corner)}
            try:
                build(self.builder, self.base, values)
            except (ModelError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:  # e.g. overflow
                desc = ", ".join(f"{k}={v:g}" for k, v in values.items())
                raise InputError(
                    f"param {self.parameters[0].name}", f"bounds give a non-physical model at {desc}: {exc}"
                ) from None

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    def start(self) -> dict[str, float]:
        """The starting values of the free parameters."""
        return {n: parameter_value(self.base, n) for n in self.names}

    def contains(self, values: Sequence[float]) -> bool:
        """Whether ``values`` lie within the bounds."""
        return all(p.lower <= v <= p.upper for p, v in zip(self.parameters, values))

    def values_dict(self, values: Sequence[float]) -> dict[str, float]:
        return dict(zip(self.names, (float(v) for v in values)))


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
    from ..methods.table import plan_move

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
            plan = plan_move(config, move)
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
    from ..time_optimal.rigid_body import rigid_time

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
            import multiprocessing as mp

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
