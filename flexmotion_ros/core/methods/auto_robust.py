"""Method ``auto_robust``: the fastest method whose insensitivity covers the frequency interval.

Each mode's frequency is known only to an interval ``[auto_robust.omega_min_i,
auto_robust.omega_max_i]`` (rad/s; an identification's 95 % intervals, which
the planner node writes when it adopts one; unset: ``omega_i (1 +- auto_robust.relative_error)``).
The candidates, in this order -- ``time_optimal``, ``robust_time_optimal``
of order 1 and 2, the shapers ``zv``, ``zvd``, ``ei``, ``zvdd``, ``ei2`` --
are planned with the method table's own planners, and for each the worst
residual vibration over the interval is computed from its command (the sampled
one when there is a rate): per mode, on a grid of :data:`GRID` frequencies
across the interval at the model's damping, the residual vibration relative to
what a step of ``u_max`` leaves (from rest,
:func:`~flexmotion_ros.core.shaping.sensitivity.command_vibration`, the
measure behind the reported insensitivity; from a vibrating start, with that
vibration carried at the perturbed frequency too: :func:`worst_vibration`).  The shortest candidate whose
worst case is at most ``robustness.tolerance`` (default 0.05) is chosen; if
none is, the one with the smallest worst case, and the result says so.

``info["auto_robust"]`` reports the choice, the interval, and every
candidate's duration and worst-case vibration; ``info["chosen_method"]`` the
chosen method (with its order).  Like every method, the chosen plan was checked
by its own planner against the exact simulation; the sensitivity here only
chooses.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from ..config import PlannerConfig
from ..errors import ConfigError, InputError, SolverError
from ..model.boundary import MoveProblem
from ..results import PlanResult
from ..shaping.sensitivity import command_vibration
from ..simulation.exact import PiecewiseConstant
from ..simulation.prepared import PreparedMove, prepare
from . import robust, shaped, time_optimal

METHOD_NAME = "auto_robust"
DESCRIPTION = (
    "the fastest of time_optimal, robust_time_optimal (order 1, 2) and the zv/zvd/ei/zvdd/ei2 shapers whose "
    "residual vibration stays within robustness.tolerance over auto_robust.omega_min..omega_max"
)
#: Frequencies checked across each mode's interval.
GRID = 201
#: Candidates: (label, method, extra options), the order in which ties are broken.
CANDIDATES: tuple[tuple[str, str, dict], ...] = (
    ("time_optimal", "time_optimal", {}),
    ("robust_time_optimal (order 1)", "robust_time_optimal", {"robust_order": 1}),
    ("robust_time_optimal (order 2)", "robust_time_optimal", {"robust_order": 2}),
    ("zv", "zv", {}),
    ("zvd", "zvd", {}),
    ("ei", "ei", {}),
    ("zvdd", "zvdd", {}),
    ("ei2", "ei2", {}),
)
DEFAULT_RELATIVE_ERROR = 0.02
DEFAULT_TOLERANCE = 0.05


def _planner(method: str):
    if method == "time_optimal":
        return time_optimal.plan
    if method == "robust_time_optimal":
        return robust.plan
    return shaped.SHAPER_METHODS[method][1]


def interval(config: PlannerConfig) -> tuple[np.ndarray, np.ndarray]:
    """Each mode's frequency interval (rad/s) from the options (validated; :class:`ConfigError` naming the option)."""
    model = config.model
    w = np.asarray(model.omega, float)
    lo_raw, hi_raw = config.options.get("auto_robust.omega_min"), config.options.get("auto_robust.omega_max")
    err = config.options.get("auto_robust.relative_error", DEFAULT_RELATIVE_ERROR)
    try:
        err = float(err)
    except (TypeError, ValueError):
        err = math.nan
    if not 0.0 <= err < 1.0:
        raise ConfigError("auto_robust.relative_error", f"must be in [0, 1) (fraction), got {err!r}")
    if (lo_raw is None) != (hi_raw is None):
        raise ConfigError("auto_robust.omega_min/omega_max", "give both (one value per mode, rad/s) or neither")
    if lo_raw is None:
        return w * (1.0 - err), w * (1.0 + err)
    lo, hi = np.asarray(lo_raw, float).ravel(), np.asarray(hi_raw, float).ravel()
    for name, arr in (("auto_robust.omega_min", lo), ("auto_robust.omega_max", hi)):
        if arr.size != w.size:
            raise ConfigError(name, f"needs one value per mode ({w.size}), got {arr.size}")
    for i in range(w.size):
        if not (math.isfinite(lo[i]) and math.isfinite(hi[i]) and 0.0 < lo[i] <= hi[i]):
            raise ConfigError(
                f"auto_robust.omega_min[{i}]", f"needs 0 < omega_min <= omega_max (rad/s), got {lo[i]}..{hi[i]}"
            )
    return lo, hi


def worst_vibration(
    u: PiecewiseConstant, config: PlannerConfig, lo: np.ndarray, hi: np.ndarray, x0: np.ndarray | None = None
) -> float:
    """Largest residual vibration of ``u`` from ``x0`` over every mode's interval, relative to a step of ``u_max``'s.

    From rest this is :func:`~flexmotion_ros.core.shaping.sensitivity.command_vibration`
    with ``u_ref = u_max``.  A move from a vibrating state (``x0``'s modal part)
    also carries that vibration, which the plan cancels only at the nominal
    frequency: with ``s = -zeta w + i w_d`` and ``z = q' - conj(s) q`` (so
    ``|z| = w_d`` x the amplitude), ``z(T) = e^{sT} z(0) + (b / s) sum_k u_k
    (e^{s (T - t_k)} - e^{s (T - t_{k+1})})`` exactly, on every frequency of the grid.
    """
    model = config.model
    x0 = model.rest_state() if x0 is None else np.asarray(x0, float)
    if not np.any(x0[2:]):
        worst = 0.0
        for i, z in enumerate(model.zeta):
            grid = np.linspace(lo[i], hi[i], GRID)
            worst = max(worst, float(np.max(command_vibration(u, grid, z, config.u_max))))
        return worst
    T = float(u.breaks[-1])
    worst = 0.0
    for i, (z, b) in enumerate(zip(model.zeta, model.b)):
        w = np.linspace(lo[i], hi[i], GRID)
        wd = w * math.sqrt(1.0 - z * z)
        s = -z * w + 1j * wd
        q0, dq0 = x0[2 + 2 * i], x0[3 + 2 * i]
        zT = np.exp(s * T) * (dq0 - np.conj(s) * q0)
        e = np.exp(np.outer(s, T - u.breaks))  # (grid, breaks)
        zT = zT + (b / s) * ((e[:, :-1] - e[:, 1:]) @ u.levels)
        step = abs(b) * config.u_max / (w * w * math.sqrt(1.0 - z * z))
        worst = max(worst, float(np.max(np.abs(zT) / wd / step)))
    return worst


def plan(config: PlannerConfig, problem: MoveProblem | PreparedMove, rate_hz: float | None) -> PlanResult:
    move = prepare(problem)
    problem = move.problem
    t0 = time.perf_counter()
    lo, hi = interval(config)
    tol = config.options.get("robustness.tolerance", DEFAULT_TOLERANCE)
    tol = float(tol)
    if not 0.0 < tol < 1.0:
        raise ConfigError("robustness.tolerance", f"must be in (0, 1) (fraction, 0.05 = 5 %), got {tol!r}")
    if not problem.model.n_modes:
        result = time_optimal.plan(config, move, rate_hz)
        report = {"chosen": "time_optimal", "note": "no mode: nothing to be robust to", "candidates": []}
        return PlanResult(
            method=METHOD_NAME,
            problem=problem,
            continuous=result.continuous,
            sampled=result.sampled,
            info={**result.info, "auto_robust": report, "chosen_method": "time_optimal"},
        )
    rows = []
    best: tuple[float, float, str, PlanResult] | None = None  # (covers?0:1 then duration/worst, ...)
    fallback: tuple[float, str, PlanResult] | None = None
    for label, method, extra in CANDIDATES:
        cfg = replace(config, method=method, options={**config.options, **extra})
        try:
            result = _planner(method)(cfg, move, rate_hz)
        except (InputError, SolverError) as exc:
            rows.append({"method": label, "refused": str(exc)})
            continue
        if result.sampled is not None:
            u = PiecewiseConstant.from_samples(result.sampled.commands, 1.0 / rate_hz)
        else:
            u = result.continuous.input() if hasattr(result.continuous, "input") else result.continuous.command
        worst = worst_vibration(u, config, lo, hi, problem.x0)
        rows.append({"method": label, "duration_s": float(result.duration), "worst_vibration": worst})
        if worst <= tol and (best is None or result.duration < best[0]):
            best = (float(result.duration), worst, label, result)
        if fallback is None or worst < fallback[0]:
            fallback = (worst, label, result)
        if best is not None and method == "time_optimal":
            break  # nothing is faster than the time-optimal move
    if best is None and fallback is None:
        raise SolverError(
            "auto_robust: no candidate method could plan this move: "
            + "; ".join(f"{r['method']}: {r.get('refused', '')}" for r in rows)
        )
    if best is not None:
        _, worst, label, chosen = best
        note = f"the fastest whose residual stays within {tol:g} over the interval"
    else:
        worst, label, chosen = fallback
        note = f"none stays within {tol:g} over the interval: the most robust"
    report = {
        "chosen": label,
        "note": note,
        "worst_vibration": worst,
        "tolerance": tol,
        "omega_min": [float(x) for x in lo],
        "omega_max": [float(x) for x in hi],
        "candidates": rows,
        "selection_time_s": time.perf_counter() - t0,
    }
    return PlanResult(
        method=METHOD_NAME,
        problem=problem,
        continuous=chosen.continuous,
        sampled=chosen.sampled,
        info={**chosen.info, "auto_robust": report, "chosen_method": label},
    )


__all__ = ["CANDIDATES", "DESCRIPTION", "METHOD_NAME", "interval", "plan", "worst_vibration"]
