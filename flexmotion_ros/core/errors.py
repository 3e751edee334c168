"""The one error hierarchy of the package.

``FlexmotionError`` is the root: a caller that wants "anything of ours" catches
it alone.  Below it:

* :class:`InputError` (also a ``ValueError``): the input was wrong.  It names
  the offending ``parameter`` and the ``reason`` (what was wrong and the allowed
  range), so that a node reports it verbatim (log, diagnostics, service answer)
  and the command line prints it as one line.  Subclasses say which input:
  :class:`ModelError`, :class:`GoalError`, :class:`ConfigError`.
* :class:`SolverError` (also a ``RuntimeError``): the input was valid but no
  profile passed the planner's own checks (final state, bound, certificate).
  A profile that failed its exact final-state check is never returned: the
  planner raises this instead.  :class:`UnreachableError` is the sampled
  system that cannot reach the target at the rate at all.
"""

from __future__ import annotations


class FlexmotionError(Exception):
    """Root of every error the package raises on purpose."""


class InputError(FlexmotionError, ValueError):
    """Invalid input; ``parameter`` names it, ``reason`` says what was wrong and the allowed range."""

    def __init__(self, parameter: str, reason: str) -> None:
        super().__init__(f"{parameter}: {reason}")
        self.parameter = parameter
        self.reason = reason


class ModelError(InputError):
    """A non-physical or uncontrollable model."""


class GoalError(InputError):
    """A goal that cannot be planned (non-finite, outside limits, ...)."""


class ConfigError(InputError):
    """A configuration file or parameter set that cannot be used."""


class SolverError(FlexmotionError, RuntimeError):
    """A planner could not produce a profile that passes its own checks (the message says which)."""


class UnreachableError(SolverError):
    """The sampled system cannot reach the target at this rate (e.g. ``omega dt`` a multiple of ``pi``)."""
