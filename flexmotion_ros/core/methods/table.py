"""The method table and its one entry point: ``plan_move(config, problem, rate_hz)``.

A *method* turns a :class:`~flexmotion_ros.core.model.boundary.MoveProblem`
into a continuous profile (anything with ``duration``, ``input()`` and
``to_dict()``) and, given a rate, the exact zero-order-hold command sequence a
node streams.  Every method is a module of this package, imported here by
name, so the table is visible to any static tool; the nodes and the command
line only ever call :func:`plan_move`, so a new method appears in both.
The names are also :data:`~flexmotion_ros.core.config.METHOD_NAMES` (the
configuration validates ``method`` against them without importing the
planners); this module checks that both lists agree.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..config import METHOD_NAMES, PlannerConfig, check_rate_hz
from ..errors import ConfigError, SolverError
from ..model.boundary import MoveProblem
from ..parameters import METHOD_OPTIONS, ParameterInfo
from ..results import PlanResult
from ..simulation.prepared import PreparedMove, prepare
from ..time_optimal.warm_start import WarmStart
from . import auto_robust, fixed_time, friction, limited, min_fuel, robust, shaped, time_optimal
from .already_there import plan_already_there
from .common import check_move_budget

Planner = Callable[[PlannerConfig, "MoveProblem | PreparedMove", "float | None"], PlanResult]


@dataclass(frozen=True, kw_only=True)
class Method:
    """One row of the method table.

    Attributes
    ----------
    name : str
        The ``method`` parameter's value.
    description : str
        One line for parameter descriptors and ``--help``.
    planner : callable
        ``planner(config, move, rate_hz) -> PlanResult``: ``move`` a
        :class:`MoveProblem` or the :class:`PreparedMove` :func:`plan_move`
        builds once, ``rate_hz`` already validated (Hz) or None.
    options : tuple of ParameterInfo
        The options it reads (type, unit, range; ``required_by``), from the
        registry :data:`~flexmotion_ros.core.parameters.METHOD_OPTIONS`.
    """

    name: str
    description: str
    planner: Planner
    options: tuple[ParameterInfo, ...] = ()


def _rows() -> dict[str, Method]:
    rows = [Method(name=time_optimal.METHOD_NAME, description=time_optimal.DESCRIPTION, planner=time_optimal.plan)]
    rows += [Method(name=n, description=d, planner=p) for n, (d, p) in shaped.SHAPER_METHODS.items()]
    for module in (robust, friction, fixed_time, min_fuel, limited, auto_robust):
        rows.append(Method(name=module.METHOD_NAME, description=module.DESCRIPTION, planner=module.plan))
    return {
        row.name: Method(
            name=row.name,
            description=row.description,
            planner=row.planner,
            options=tuple(p for p in METHOD_OPTIONS if row.name in p.methods),
        )
        for row in rows
    }


#: Every planning method, by name (the default, ``time_optimal``, first).
METHODS: dict[str, Method] = _rows()
if tuple(METHODS) != METHOD_NAMES:  # pragma: no cover - a programming error, caught by any import
    raise ImportError(f"method table {tuple(METHODS)} and config.METHOD_NAMES {METHOD_NAMES} disagree")


def plan_move(
    config: PlannerConfig, problem: MoveProblem, rate_hz: float | None = None, *, warm_start: WarmStart | None = None
) -> PlanResult:
    """Plan ``problem`` with ``config.method``; with ``rate_hz``, also the exact sampled sequence.

    The responses of ``problem`` are built once here (:func:`prepare`) and
    passed down to every planner of the method.  ``rate_hz`` (Hz) is
    validated once here (:func:`~flexmotion_ros.core.config.check_rate_hz`:
    in ``(0, 1e6]``); ``None`` or ``0`` means no rate given (methods that
    need one then use ``config.rate_hz``, validated with the configuration).
    ``warm_start`` (:class:`~flexmotion_ros.core.time_optimal.warm_start.WarmStart`,
    e.g. the rest of the plan being executed) speeds up method ``time_optimal``
    from a nearby state; the other methods ignore it.  The answer does not depend on it.

    Raises
    ------
    InputError
        Bad input (named parameter and allowed range); a goal whose
        rigid-body minimum time exceeds ``config.max_move_duration_s``
        (:func:`~.common.check_move_budget`).
    SolverError
        No profile passed its own checks (final state, bound).
    """
    method = METHODS.get(config.method)
    if method is None:
        raise ConfigError("method", f"must be one of {sorted(METHODS)}, got {config.method!r}")
    rate = check_rate_hz(rate_hz) if rate_hz else None
    move = prepare(problem)
    check_move_budget(config, move.problem, rate)
    # a move shorter than the resolution is answered "already there", whatever the method
    result = plan_already_there(config, move, rate)
    if result is None and warm_start is not None and method.name == time_optimal.METHOD_NAME:
        result = time_optimal.plan(config, move, rate, warm_start)
    if result is None:
        result = method.planner(config, move, rate)
    if result.sampled is not None and result.sampled.commands.size:
        peak = float(np.max(np.abs(result.sampled.commands)))
        if peak > problem.u_max:  # the bound is never exceeded, whatever the method: a planner fault
            raise SolverError(
                f"method {config.method} produced |u| = {peak} > u_max = {problem.u_max}; nothing is returned"
            )
    return result
