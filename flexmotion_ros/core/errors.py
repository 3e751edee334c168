"""Exceptions raised by the numerical core.

Every error names the offending parameter and the allowed range, so that a
node can report it verbatim (log, diagnostics, service answer) and a command
line can print it as a one-line message.
"""

from __future__ import annotations


class FlexmotionError(ValueError):
    """Base class: invalid input.  ``parameter`` names what was wrong."""

    def __init__(self, parameter: str, message: str) -> None:
        super().__init__(f"{parameter}: {message}")
        self.parameter = parameter
        self.reason = message


class ModelError(FlexmotionError):
    """A non-physical or uncontrollable model."""


class GoalError(FlexmotionError):
    """A goal that cannot be planned (non-finite, outside limits, ...)."""


class SolverError(RuntimeError):
    """A planner could not produce a profile that passes its own checks.

    A profile that failed its exact final-state check is never returned: the
    planner raises this instead.
    """


class ConfigError(FlexmotionError):
    """A configuration file or parameter set that cannot be used."""


class UnreachableError(SolverError):
    """The sampled system cannot reach the target at this rate (e.g. ``omega dt`` a multiple of ``pi``)."""
