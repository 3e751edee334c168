"""The figures of a plan that the planner reports (``last_plan.*`` on /diagnostics)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..core.results import PlanResult


def plan_summary(result: PlanResult, plan_time_s: float) -> dict[str, Any]:
    """The plan's figures, by name.

    Parameters
    ----------
    result : PlanResult
        A plan with a sampled command sequence.
    plan_time_s : float
        How long planning took (s).

    Returns
    -------
    dict
        ``method``, ``duration_s`` (s), ``samples`` (samples), ``minimal``,
        ``certified`` (``"n/a"`` if the method has no certificate),
        ``continuous_duration_s`` (s; NaN without a continuous profile),
        ``final_state_error``, ``plan_time_s`` (s) and ``peak_command``
        (largest ``|u|``, N; 0 for an empty sequence).
    """
    s = result.sampled
    cont = result.continuous
    certified = getattr(cont, "certified", None)
    return {
        "method": result.method,
        "duration_s": float(s.duration),
        "samples": int(s.samples),
        "minimal": bool(s.minimal),
        "certified": "n/a" if certified is None else bool(certified),
        "continuous_duration_s": float(cont.duration) if cont is not None else float("nan"),
        "final_state_error": float(s.final_state_error),
        "plan_time_s": float(plan_time_s),
        "peak_command": float(np.max(np.abs(s.commands))) if s.samples else 0.0,
        **({"chosen_method": result.info["chosen_method"]} if "chosen_method" in result.info else {}),
    }


__all__ = ["plan_summary"]
