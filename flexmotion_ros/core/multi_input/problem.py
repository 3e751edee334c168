"""A multi-input move to rest (seed section 2.1.2 with ``k`` rigid bodies).

Every move ends at rest.  Each rigid body has its own target position or a
free final position (``None``).  The state is shifted so that the target is
the origin; the positions of free rigid bodies are dropped (their velocities
must still reach zero).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, GoalError
from .model import MultiModel


def check_bounds(values, m: int, name: str = "u_max") -> np.ndarray:
    """``m`` finite positive bounds, or :class:`ConfigError` naming ``name[i]``."""
    vals = list(np.atleast_1d(np.asarray(values, dtype=object)).ravel()) if values is not None else []
    if len(vals) == 1 and m > 1:
        vals = vals * m
    if len(vals) != m:
        raise ConfigError(name, f"needs {m} values (one per input), got {len(vals)}")
    out = np.empty(m)
    for i, v in enumerate(vals):
        try:
            x = float(v)
        except (TypeError, ValueError):
            raise ConfigError(f"{name}[{i}]", f"must be a finite number > 0, got {v!r}") from None
        if not math.isfinite(x) or x <= 0.0:
            raise ConfigError(f"{name}[{i}]", f"must be finite and > 0, got {x}")
        out[i] = x
    return out


@dataclass(frozen=True)
class MultiMoveProblem:
    """A move of a :class:`MultiModel` to rest.

    Attributes
    ----------
    model : MultiModel
    u_max : ndarray
        One bound per input (``|u_i| <= u_max[i]``).
    x0 : ndarray
        Full initial state in the model's state order.
    targets : tuple of (float or None)
        Final position per rigid body; ``None``: free.
    """

    model: MultiModel
    u_max: np.ndarray
    x0: np.ndarray
    targets: tuple = ()

    def __post_init__(self) -> None:
        model = self.model
        object.__setattr__(self, "u_max", check_bounds(self.u_max, model.m))
        x0 = np.asarray(self.x0, dtype=float).ravel()
        if x0.size != model.n_states:
            raise GoalError(
                "initial_state",
                f"must have {model.n_states} entries ({', '.join(model.state_names())}), got {x0.size}",
            )
        bad = [i for i, v in enumerate(x0) if not math.isfinite(v)]
        if bad:
            raise GoalError("initial_state", f"{model.state_names()[bad[0]]} must be finite, got {x0[bad[0]]}")
        object.__setattr__(self, "x0", x0)
        targets = tuple(self.targets) if self.targets is not None else ()
        if not targets:
            targets = (None,) * model.k
        if len(targets) != model.k:
            raise GoalError(
                "goal", f"needs one target per rigid body {list(model.rigid_bodies)} ({model.k}), got {len(targets)}"
            )
        out = []
        for j, t in enumerate(targets):
            if t is None:
                out.append(None)
                continue
            try:
                v = float(t)
            except (TypeError, ValueError):
                raise GoalError(f"goal[{j}]", f"must be a finite position, got {t!r}") from None
            if not math.isfinite(v):
                raise GoalError(f"goal[{j}]", f"must be a finite position ({model.rigid_bodies[j]}), got {v}")
            out.append(v)
        object.__setattr__(self, "targets", tuple(out))

    # ------------------------------------------------------------ reduction
    @property
    def kept(self) -> np.ndarray:
        """Indices of the full state kept in the reduced (shifted) state: free positions dropped."""
        keep = np.ones(self.model.n_states, dtype=bool)
        for j, t in enumerate(self.targets):
            if t is None:
                keep[2 * j] = False
        return np.flatnonzero(keep)

    @property
    def has_position(self) -> tuple[bool, ...]:
        """Per rigid body: whether its final position is specified."""
        return tuple(t is not None for t in self.targets)

    def target_state(self) -> np.ndarray:
        """Full rest state at the targets (free positions: 0, ignored)."""
        return self.model.rest_state([0.0 if t is None else t for t in self.targets])

    def shifted_initial(self) -> np.ndarray:
        """``x0 - x_f`` restricted to the kept states (eq. 2.16)."""
        return (self.x0 - self.target_state())[self.kept]

    def is_at_rest(self) -> bool:
        """Already at rest at the targets."""
        return not np.any(self.shifted_initial())

    def sub(self, inputs: Sequence[int], bodies: Sequence[int], modes: Sequence[int]) -> MultiMoveProblem:
        """The same move restricted to a decoupled part of the model."""
        k = self.model.k
        idx = [s for j in bodies for s in (2 * j, 2 * j + 1)] + [
            s for l in modes for s in (2 * k + 2 * l, 2 * k + 2 * l + 1)
        ]
        return MultiMoveProblem(
            self.model.submodel(inputs, bodies, modes),
            self.u_max[list(inputs)],
            self.x0[idx],
            tuple(self.targets[j] for j in bodies),
        )


def multi_rest_to_rest(model: MultiModel, u_max, goal, start=None) -> MultiMoveProblem:
    """From rest at ``start`` (default 0) to rest at ``goal`` (one position per rigid body)."""
    goal = [None if g is None else g for g in np.atleast_1d(np.asarray(goal, dtype=object))]
    start = np.zeros(model.k) if start is None else np.asarray(start, dtype=float)
    return MultiMoveProblem(model, u_max, model.rest_state(start), tuple(goal))


def multi_state_to_rest(model: MultiModel, u_max, x0, goal=None) -> MultiMoveProblem:
    """From any (moving, vibrating) state ``x0`` to rest at ``goal`` (``None``: every position free)."""
    targets = () if goal is None else tuple(np.atleast_1d(np.asarray(goal, dtype=object)))
    return MultiMoveProblem(model, u_max, np.asarray(x0, dtype=float), targets)
