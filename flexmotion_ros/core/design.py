"""Integrated structure/control design (seed section 2.4): the structure that moves fastest.

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

Parameter names
---------------
The builders' argument names: ``m1, m2, k, d`` (two_mass); ``cart_mass,
payload_mass, cable_length, g, zeta`` (crane); for a chain one element of a
list, 0-based: ``masses[i]``, ``springs[i]``, ``dampers[i]``.

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
import re
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .boundary import rest_to_rest
from .builders import BUILDERS, BuiltModel
from .config import ConfigError, PlannerConfig, config_from_parameters, dump_parameters
from .errors import FlexmotionError, GoalError, ModelError, SolverError
from .simulation import final_state, modal_amplitudes

_POS, _NONNEG = (0.0, True, math.inf, False), (0.0, False, math.inf, False)
#: Physical range of each designable parameter: (low, low excluded, high, high excluded, unit).
PARAMETER_RANGES: dict[str, dict[str, tuple]] = {
    "two_mass": {"m1": (*_POS, "kg"), "m2": (*_POS, "kg"), "k": (*_POS, "N/m"), "d": (*_NONNEG, "N s/m")},
    "crane": {
        "cart_mass": (*_POS, "kg"),
        "payload_mass": (*_POS, "kg"),
        "cable_length": (*_POS, "m"),
        "g": (*_POS, "m/s^2"),
        "zeta": (0.0, False, 1.0, True, ""),
    },
    "chain": {"masses": (*_POS, "kg"), "springs": (*_POS, "N/m"), "dampers": (*_NONNEG, "N s/m")},
}
#: Defaults of the optional builder arguments.
_OPTIONAL = {"two_mass": {"d": 0.0}, "crane": {"g": 9.81, "zeta": 0.0}, "chain": {"dampers": None, "force_on": 0}}
_REQUIRED = {"two_mass": ("m1", "m2", "k"), "crane": ("cart_mass", "payload_mass", "cable_length"), "chain": ("masses", "springs")}
_INDEXED = re.compile(r"^(masses|springs|dampers)\[(\d+)\]$")
MAX_PARAMETERS = 3


def _range_text(rng: tuple) -> str:
    lo, lo_x, hi, hi_x, unit = rng
    unit = f" {unit}" if unit else ""
    if math.isinf(hi):
        return f"{'>' if lo_x else '>='} {lo:g}{unit}"
    return f"in {'(' if lo_x else '['}{lo:g}, {hi:g}{')' if hi_x else ']'}{unit}"


def _in_range(x: float, rng: tuple) -> bool:
    lo, lo_x, hi, hi_x, _ = rng
    return (x > lo if lo_x else x >= lo) and (x < hi if hi_x else x <= hi)


def _check_builder(builder: str) -> str:
    if builder not in BUILDERS:
        raise ConfigError("design.builder", f"must be one of {sorted(BUILDERS)}, got {builder!r}")
    return builder


def normalise_base(builder: str, base: Mapping[str, Any]) -> dict[str, Any]:
    """The builder's full argument set: ``base`` plus defaults; unknown or missing names refused."""
    _check_builder(builder)
    known = set(_REQUIRED[builder]) | set(_OPTIONAL[builder])
    for key in base:
        if key not in known:
            raise ConfigError(f"design.{key}", f"is not a parameter of builder {builder}; known: {sorted(known)}")
    for key in _REQUIRED[builder]:
        if key not in base:
            raise ConfigError(f"design.{key}", f"is required by builder {builder} (its starting value)")
    out = {**_OPTIONAL[builder], **base}

    def num(key, v):
        try:
            return float(v)
        except (TypeError, ValueError):
            raise ConfigError(f"design.{key}", f"must be a number, got {v!r}") from None

    def physical(key, v, rng):
        x = num(key, v)
        if not (math.isfinite(x) and _in_range(x, rng)):
            raise ConfigError(f"design.{key}", f"must be {_range_text(rng)}, got {x}")
        return x

    ranges = PARAMETER_RANGES[builder]
    if builder != "chain":
        return {k: physical(k, v, ranges[k]) for k, v in out.items()}
    for key in ("masses", "springs", "dampers"):
        if out[key] is not None:
            out[key] = [physical(f"{key}[{i}]", v, ranges[key]) for i, v in enumerate(np.atleast_1d(out[key]))]
    if out["dampers"] is None:
        out["dampers"] = [0.0] * len(out["springs"])
    fo = num("force_on", out["force_on"])
    if fo != int(fo):
        raise ConfigError("design.force_on", f"must be a mass index (integer), got {out['force_on']}")
    out["force_on"] = int(fo)
    return out


def build(builder: str, base: Mapping[str, Any], values: Mapping[str, float] | None = None) -> BuiltModel:
    """The physical model with some parameters replaced (names as in the module docstring)."""
    kw = {k: (list(v) if isinstance(v, list) else v) for k, v in base.items()}
    for name, value in (values or {}).items():
        m = _INDEXED.match(name)
        if m:
            kw[m.group(1)][int(m.group(2))] = float(value)
        else:
            kw[name] = float(value)
    return BUILDERS[builder](**kw)


def parameter_value(base: Mapping[str, Any], name: str) -> float:
    """The value of a (possibly indexed) parameter in ``base``."""
    m = _INDEXED.match(name)
    return float(base[m.group(1)][int(m.group(2))]) if m else float(base[name])


@dataclass(frozen=True)
class DesignParameter:
    """One free structural parameter.

    Attributes
    ----------
    name : str
        Builder argument name (``k``, ``cable_length``, ``springs[1]``, ...).
    lower, upper : float
        Bounds (the parameter's unit), ``lower < upper``, both physical.
    scale : str
        ``"linear"``, ``"log"`` or ``"auto"`` (log when ``upper / lower >= 10``).
    """

    name: str
    lower: float
    upper: float
    scale: str = "auto"

    def to_unit(self, x: float) -> float:
        """Search coordinate in ``[0, 1]`` (linear or logarithmic in the value)."""
        if self.scale == "log":
            return math.log(x / self.lower) / math.log(self.upper / self.lower)
        return (x - self.lower) / (self.upper - self.lower)

    def from_unit(self, u: float) -> float:
        """Inverse of :meth:`to_unit`; the bounds exactly at 0 and 1."""
        if u <= 0.0:
            return self.lower
        if u >= 1.0:
            return self.upper
        if self.scale == "log":
            return self.lower * (self.upper / self.lower) ** u
        return self.lower + u * (self.upper - self.lower)


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
            raise FlexmotionError("frequency_error", f"must be in (0, 1) (relative), got {e}")
        if not (math.isfinite(r) and r > 0.0):
            raise FlexmotionError("max_residual", f"must be finite and > 0 (m), got {r}")
        if int(self.samples) < 2:
            raise FlexmotionError("robust_samples", f"must be >= 2, got {self.samples}")

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
        _check_builder(self.builder)
        base = normalise_base(self.builder, self.base)
        object.__setattr__(self, "base", base)
        build(self.builder, base)  # the starting design must itself be physical
        params = tuple(self._check_parameter(p, base) for p in self.parameters)
        if not 1 <= len(params) <= MAX_PARAMETERS:
            raise FlexmotionError("param", f"give 1 to {MAX_PARAMETERS} design parameters, got {len(params)}")
        names = [p.name for p in params]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise FlexmotionError(f"param {min(dup)}", "given more than once")
        object.__setattr__(self, "parameters", params)
        if not self.tasks:
            raise GoalError("goal", "give at least one task (--goal GAMMA)")
        tasks = []
        for i, t in enumerate(self.tasks):
            try:
                g, w = float(t.gamma), float(t.weight)
            except (TypeError, ValueError):
                raise GoalError(f"goal[{i}]", f"goal and weight must be numbers, got {t.gamma!r}, {t.weight!r}") from None
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
        m = _INDEXED.match(name)
        ranges = PARAMETER_RANGES[self.builder]
        key = m.group(1) if m else name
        if key not in ranges or (self.builder == "chain") != bool(m):
            known = list(ranges) if self.builder != "chain" else [f"{k}[i]" for k in ranges]
            raise FlexmotionError(f"param {name}", f"is not a design parameter of {self.builder}; one of {known}")
        if m and int(m.group(2)) >= len(base[key]):
            raise FlexmotionError(f"param {name}", f"index must be in [0, {len(base[key]) - 1}] for this chain")
        rng = ranges[key]
        try:
            lo, hi = float(p.lower), float(p.upper)
        except (TypeError, ValueError):
            raise FlexmotionError(f"param {name}", f"bounds must be numbers, got {p.lower!r}:{p.upper!r}") from None
        allowed = f"need finite LO < HI, both {_range_text(rng)}"
        if not (math.isfinite(lo) and math.isfinite(hi)) or lo >= hi:
            raise FlexmotionError(f"param {name}", f"bounds {lo}:{hi}: {allowed}")
        for which, v in (("lower", lo), ("upper", hi)):
            if not _in_range(v, rng):
                raise FlexmotionError(f"param {name}", f"{which} bound {v} is not physical: {allowed}")
        scale = p.scale
        if scale not in ("auto", "linear", "log"):
            raise FlexmotionError(f"param {name}", f"scale must be auto, linear or log, got {scale!r}")
        if scale == "log" and lo <= 0.0:
            raise FlexmotionError(f"param {name}", f"a log scale needs lower bound > 0, got {lo}")
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
                raise FlexmotionError(f"param {self.parameters[0].name}", f"bounds give a non-physical model at {desc}: {exc}") from None

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
    from .planning import plan_move

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
    return Evaluation(values, objective, tuple(times), certified, status, residual, time.perf_counter() - t0, tuple(plans))


def rigid_bound(problem: DesignProblem, values: Sequence[float]) -> float:
    """``sum w_i T_rigid,i`` (s): the weighted rigid-body optimum, a lower bound on ``J`` (closed form)."""
    from .time_optimal import rigid_time

    model = build(problem.builder, problem.base, problem.values_dict(values)).model
    u = problem.config.u_max
    return float(sum(t.weight * rigid_time(model, u, rest_to_rest(model, u, t.gamma).shifted_initial(), True) for t in problem.tasks))


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
                evs = pool.map(_evaluate_star, [(self.problem, k) for k in todo], chunksize=max(1, len(todo) // (4 * workers)))
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
    sizes = [default_grid(p)] * p if grid is None else ([int(grid)] * p if np.isscalar(grid) else [int(g) for g in grid])
    if len(sizes) != p or any(not 3 <= g <= 2001 for g in sizes):
        raise FlexmotionError("grid", f"needs {p} value(s), each in [3, 2001] points, got {sizes}")
    if int(workers) < 1:
        raise FlexmotionError("workers", f"must be >= 1 process, got {workers}")
    if not (math.isfinite(xtol) and 0.0 < xtol < 1.0):
        raise FlexmotionError("xtol", f"must be in (0, 1) (fraction of the range), got {xtol}")
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


# --------------------------------------------------------------- parameter files
def design_parameters(builder: str, physical: Mapping[str, Any]) -> dict[str, Any]:
    """Flat ``design.*`` parameters describing a structure (for a parameter file)."""
    out: dict[str, Any] = {"design.builder": builder}
    for k, v in physical.items():
        out[f"design.{k}"] = list(v) if isinstance(v, (list, tuple)) else v
    return out


def split_parameters(params: Mapping[str, Any]) -> tuple[str | None, dict[str, Any], dict[str, Any]]:
    """``(builder, base, planner_params)`` from flat parameters with an optional ``design:`` section."""
    planner = {k: v for k, v in params.items() if not k.startswith("design.")}
    design = {k[len("design.") :]: v for k, v in params.items() if k.startswith("design.")}
    builder = design.pop("builder", None)
    return (None if builder is None else str(builder)), design, planner


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
    _check_builder(builder)
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
        same = all(
            np.size(a[k]) == np.size(b[k]) and np.allclose(a[k], b[k], rtol=1e-9, atol=1e-12) for k in a
        )
        if not same:
            notes.append("the file's model section is not the starting structure (design section / --builder / --set); the structure is used")
    if isinstance(bounds, Mapping):
        bounds = [DesignParameter(n, lo, hi) for n, (lo, hi) in bounds.items()]
    weights = [1.0] * len(goals) if weights is None else list(weights)
    if len(weights) != len(goals):
        raise GoalError("weight", f"give one weight per goal ({len(goals)}), got {len(weights)}")
    tasks = tuple(Task(g, w) for g, w in zip(goals, weights))
    return DesignProblem(builder, base, tuple(bounds), tasks, config, robustness), notes


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
