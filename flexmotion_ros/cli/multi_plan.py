"""``flexmotion plan`` for several inputs: goals per rigid body, the whole start state, the JSON with rows of m.

The one-input output is :mod:`.plan_cmd`'s, unchanged; this module holds
what several inputs add: parsing ``--goal 3.0,2.0`` (one target per rigid
body) and ``--initial-state`` (the whole state in the model's order), and
the text summary of a :class:`~flexmotion_ros.core.multi_input.MultiPlanResult`.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.errors import GoalError
from ..core.multi_input.config import MultiPlannerConfig
from ..core.multi_input.dispatch import state_size


def numbers(text: str | None, name: str) -> list[float] | None:
    """``"3.0,2.0"`` (commas or spaces) as floats; None if not given.

    Raises
    ------
    GoalError
        Naming ``name``: not numbers, or none.
    """
    if text is None:
        return None
    flag = "--" + name.replace("_", "-")
    parts = [p for p in str(text).replace(",", " ").split() if p]
    if not parts:
        raise GoalError(name, f"{flag} needs at least one number, got {text!r}")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise GoalError(name, f"{flag} takes numbers separated by commas (e.g. 3.0,2.0), got {text!r}") from None
    for v in values:
        if not math.isfinite(v):
            raise GoalError(name, f"must be finite, got {v}")
    return values


def initial_state(config, values: list[float] | None) -> np.ndarray | None:
    """The whole start state (``--initial-state``) checked against the model's state order; None if not given."""
    if values is None:
        return None
    n = state_size(config.model)
    if len(values) != n:
        if isinstance(config, MultiPlannerConfig):
            order = ", ".join(config.model.state_names())
        else:
            order = "p, v, " + ", ".join(f"q{i + 1}, q{i + 1}'" for i in range(config.model.n_modes))
        raise GoalError("initial_state", f"needs the whole state, {n} values in the order [{order}]; got {len(values)}")
    return np.asarray(values, float)


def stop_positions(config: MultiPlannerConfig, out: dict, sampled_states) -> None:
    """Where a stop (final positions free) ends, per rigid body: ``stop_positions`` / ``sampled_stop_positions``."""
    k = config.model.k
    if "final_state" in out:
        out["stop_positions"] = [float(v) for v in out["final_state"][0 : 2 * k : 2]]
    if sampled_states is not None:
        out["sampled_stop_positions"] = [float(v) for v in np.asarray(sampled_states)[-1, 0 : 2 * k : 2]]


def _row(values, zero: float) -> str:
    return "[" + ", ".join("0" if abs(v) <= zero else f"{v:+.6g}" for v in values) + "]"


def text(out: dict, inputs: tuple[str, ...], rigid_bodies: tuple[str, ...], limit: int = 8) -> str:
    """Human-readable summary of a multi-input plan (``MultiPlanResult.summary()`` plus the CLI's fields)."""
    lines = [f"method            {out['method']}  (inputs {', '.join(inputs)}; sync {out.get('sync', '-')})"]
    if "duration" in out:
        lines.append(f"duration          {out['duration']:.9f} s")
    if "switch_times" in out:
        sw = out["switch_times"]
        shown = ", ".join(f"{t:.9f}" for t in sw[:limit]) or "-"
        more = f", ... ({len(sw)} in all)" if len(sw) > limit else ""
        lines.append(f"switch times      {shown}{more} s (any input)")
    if "levels" in out:
        rows = out["levels"]
        zero = 1e-9 * max((abs(v) for r in rows for v in r), default=0.0)
        shown = "; ".join(_row(r, zero) for r in rows[:limit]) + (
            f"; ... ({len(rows)} rows)" if len(rows) > limit else ""
        )
        lines.append(f"levels            {shown}")
    if "final_state_error" in out:
        lines.append(
            f"final-state error {out['final_state_error']:.3e} (relative {out.get('final_state_error_relative', 0.0):.1e})"
        )
    if "stop_positions" in out:
        where = ", ".join(f"{n} {p:.9f}" for n, p in zip(rigid_bodies, out["stop_positions"]))
        lines.append(f"stops at          {where} (final positions free)")
    if "certified" in out:
        cert = out.get("certificate") or {}
        lines.append(f"certified         {out['certified']} ({cert.get('message', '-')})")
        if "lower_bound" in cert:
            lines.append(f"lower bound       {cert['lower_bound']:.9f} s (proved: no move is shorter)")
    if "solve_time_s" in out:
        lines.append(f"solve time        {out['solve_time_s'] * 1e3:.2f} ms (continuous)")
    if "samples" in out:
        cmds = np.asarray(out["commands"], float).reshape(-1, len(inputs))
        peak = np.max(np.abs(cmds), axis=0) if cmds.size else np.zeros(len(inputs))
        lines += [
            f"rate              {out['rate_hz']:g} Hz",
            f"samples           {out['samples']} ({out['sampled_duration']:.6f} s, "
            f"{'proved fewest' if out['minimal'] else 'not proved fewest'})",
            f"sampled error     {out['sampled_final_state_error']:.3e}",
            *(
                [
                    "sampled stops at  "
                    + ", ".join(f"{n} {p:.9f}" for n, p in zip(rigid_bodies, out["sampled_stop_positions"]))
                ]
                if "sampled_stop_positions" in out
                else []
            ),
            f"sampled solve     {out['sampled_solve_time_s'] * 1e3:.2f} ms (plan in all: {out['plan_time_s'] * 1e3:.2f} ms)",
            "peak command      " + ", ".join(f"{n} {p:.9g}" for n, p in zip(inputs, peak)),
        ]
    return "\n".join(lines)


__all__ = ["initial_state", "numbers", "stop_positions", "text"]
