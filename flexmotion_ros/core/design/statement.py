"""What a structure design is asked: the builder, its free parameters and bounds, the moves, a robustness requirement.

:class:`DesignProblem` checks itself when made (a known builder, 1 to 3 free
physical parameters with bounds whose every corner builds a physical model,
non-zero goals with positive weights); :class:`Task` is one weighted
rest-to-rest move, :class:`RobustnessRequirement` the residual vibration
allowed under a relative frequency error.  The objective over such a problem
and the problem built from a parameter file are :mod:`.problem`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..config import PlannerConfig
from ..errors import GoalError, InputError, ModelError
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
