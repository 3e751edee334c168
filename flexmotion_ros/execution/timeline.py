"""The stream's timeline: planned command sequences at global sample indices.

A *timeline* is a list of :class:`Segment` s ordered by start index.  Each
segment holds a planned command sequence and the states it is predicted to
produce; a later segment takes over from its start index (a *splice*), so
the state at any future sample follows from the segments alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: Command while at rest (N): every target is an equilibrium (A x_f = 0).  Several inputs: zero on every
#: input (the node publishes ``HOLD`` as ``m`` zeros).
HOLD = 0.0


def is_hold(value) -> bool:
    """``value`` (a command: one float, or one per input) is the hold: zero on every input."""
    return value is not None and not np.any(np.asarray(value, float) != HOLD)


def command_text(value) -> str:
    """A command for a log line: ``0.5`` or ``[30, -50]`` (9 significant digits)."""
    v = np.atleast_1d(np.asarray(value, float))
    return f"{v[0]:.9g}" if np.ndim(value) == 0 else "[" + ", ".join(f"{x:.9g}" for x in v) + "]"


@dataclass
class Segment:
    """A planned command sequence on the stream's timeline.

    Mutable on purpose: the stream sets :attr:`start` when it installs the
    segment and :attr:`started_at` when it sends the first command.

    Attributes
    ----------
    commands : ndarray
        ``u_i`` for ``i = 0..K-1`` (N), each sent for one sample period: shape ``(K,)``
        for one input, ``(K, m)`` for several (one row per sample).
    states : ndarray
        Predicted states before each command and after the last (``K + 1`` rows).
    start : int
        Global sample index of ``commands[0]`` (set when installed; -1 before).
    info : Any
        The caller's record (the plan).
    started_at : float or None
        Clock time (s) at which ``commands[0]`` was sent (None until then).
    """

    commands: np.ndarray
    states: np.ndarray
    start: int = -1
    info: Any = None
    started_at: float | None = field(default=None, repr=False)

    @property
    def samples(self) -> int:
        """Number of commands ``K`` (samples)."""
        return int(self.commands.shape[0]) if self.commands.ndim else int(self.commands.size)

    def command(self, i: int):
        """Command ``i``: a float for one input, a row of ``m`` values for several."""
        c = self.commands[i]
        return float(c) if self.commands.ndim == 1 else c

    @property
    def end(self) -> int:
        """Global index (samples) of the explicit hold sample after the last command."""
        return self.start + self.samples

    def state_at(self, k: int) -> np.ndarray:
        """Predicted state before global sample ``k`` (at rest after the end)."""
        i = min(max(k - self.start, 0), self.samples)
        return self.states[i]


def predicted_state(timeline: Sequence[Segment], k: int) -> np.ndarray | None:
    """The state the timeline reaches at global sample ``k`` (None if the timeline is empty).

    Parameters
    ----------
    timeline : sequence of Segment
        Installed segments, ordered by start index (samples).
    k : int
        Global sample index (samples).

    Returns
    -------
    ndarray or None
        The predicted state before command ``k`` is applied: the state of the
        last segment that has started by ``k`` (the first one if none has).
    """
    if not timeline:
        return None
    seg = timeline[0]
    for s in timeline[1:]:
        if s.start <= k:
            seg = s
    return seg.state_at(k)


__all__ = ["HOLD", "Segment", "command_text", "is_hold", "predicted_state"]
