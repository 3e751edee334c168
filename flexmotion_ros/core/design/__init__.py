"""Structure design (seed section 2.4): the structure whose time-optimal move is the shortest."""

from .optimize import DesignResult, optimize_design, write_design
from .problem import (
    DesignObjective,
    DesignProblem,
    Evaluation,
    evaluate_point,
    problem_from_parameters,
)
from .space import PARAMETER_RANGES, DesignParameter, build

__all__ = [
    "DesignObjective",
    "DesignParameter",
    "DesignProblem",
    "DesignResult",
    "Evaluation",
    "PARAMETER_RANGES",
    "build",
    "evaluate_point",
    "optimize_design",
    "problem_from_parameters",
    "write_design",
]
