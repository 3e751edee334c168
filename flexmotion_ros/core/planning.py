"""One entry point for every planning method: ``plan_move(config, problem)``.

A *method* turns a :class:`MoveProblem` into a continuous profile (anything
with ``duration``, ``input()`` and ``to_dict()``) and, given a rate, the
exact zero-order-hold command sequence a node streams.  Methods register
themselves with :func:`register_method`; modules listed in
:data:`METHOD_MODULES` are imported on first use.  The nodes and the command
line only ever call :func:`plan_move`, so a new method appears in both.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from .boundary import MoveProblem
from .config import METHODS, PlannerConfig
from .errors import FlexmotionError
from .profile import SampledProfile
from .simulation import PiecewiseConstant


class ContinuousProfile(Protocol):
    """What every method's continuous result offers."""

    duration: float

    def input(self) -> PiecewiseConstant: ...

    def to_dict(self) -> dict: ...


@dataclass
class PlanResult:
    """A planned move.

    Attributes
    ----------
    method : str
    problem : MoveProblem
    continuous : ContinuousProfile or None
        The continuous-time profile (None if a method plans only sampled).
    sampled : SampledProfile or None
        The exact command sequence at the requested rate (None if no rate).
    info : dict
        Method-specific figures (added time, robustness, ...), JSON-friendly.
    """

    method: str
    problem: MoveProblem
    continuous: Any = None
    sampled: SampledProfile | None = None
    info: dict = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """Move time (s): the sampled one if sampled, else the continuous one."""
        if self.sampled is not None:
            return self.sampled.duration
        return float(self.continuous.duration)

    def summary(self) -> dict:
        """JSON-friendly summary: the continuous profile's fields, then the sampled ones."""
        out: dict = {"method": self.method}
        if self.continuous is not None:
            out.update(self.continuous.to_dict())
        out["method"] = self.method
        if self.sampled is not None:
            out.update(self.sampled.to_dict())
        out.update(self.info)
        return out


Planner = Callable[[PlannerConfig, MoveProblem, "float | None"], PlanResult]
_PLANNERS: dict[str, Planner] = {}

#: Modules that register methods when imported (the core's own first).
METHOD_MODULES: list[str] = [
    "flexmotion_ros.core.shaping_methods",
    "flexmotion_ros.core.friction_methods",
    "flexmotion_ros.core.limit_methods",
]


def register_method(name: str, description: str, planner: Planner) -> None:
    """Make ``name`` a valid ``method`` for the nodes and the command line."""
    _PLANNERS[name] = planner
    METHODS[name] = description


def load_methods() -> None:
    """Import every module in :data:`METHOD_MODULES` (each registers its methods)."""
    for module in METHOD_MODULES:
        importlib.import_module(module)


def plan_move(config: PlannerConfig, problem: MoveProblem, rate_hz: float | None = None) -> PlanResult:
    """Plan ``problem`` with ``config.method``; with ``rate_hz``, also the exact sampled sequence.

    Raises
    ------
    FlexmotionError
        Bad input (named parameter and allowed range).
    SolverError
        No profile passed its own final-state check.
    """
    load_methods()
    planner = _PLANNERS.get(config.method)
    if planner is None:
        raise FlexmotionError("method", f"must be one of {sorted(_PLANNERS)}, got {config.method!r}")
    result = planner(config, problem, rate_hz)
    if result.sampled is not None and result.sampled.commands.size:
        peak = float(np.max(np.abs(result.sampled.commands)))
        if peak > problem.u_max:  # the bound is never exceeded, whatever the method
            raise FlexmotionError("u_max", f"method {config.method} produced |u| = {peak} > u_max = {problem.u_max}")
    return result


def _plan_time_optimal(config: PlannerConfig, problem: MoveProblem, rate_hz: float | None) -> PlanResult:
    from .time_optimal import plan_time_optimal
    from .zoh import plan_zoh

    continuous = plan_time_optimal(problem)
    sampled = plan_zoh(problem, rate_hz, continuous) if rate_hz else None
    return PlanResult("time_optimal", problem, continuous, sampled)


register_method("time_optimal", METHODS["time_optimal"], _plan_time_optimal)
