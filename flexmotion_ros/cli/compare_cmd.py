"""``flexmotion compare``: every planning method on one move, side by side.

For each method: duration, time added over the time-optimal move, residual
vibration at the nominal model (exact matrix-exponential simulation), the
worst residual vibration when all modal frequencies are off by up to
``--freq-error`` (closed-form impulse formula of ``core.sensitivity``), the
insensitivity width at ``--tolerance`` and the planning time.  Residual
vibration is in percent of what a step of ``u_max`` leaves (worst mode).
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from ..core.errors import FlexmotionError, InputError
from ..core.methods import METHODS, plan_move
from ..core.shaping.sensitivity import (
    command_curve,
    command_insensitivity,
    residual_amplitudes,
    worst_in_band,
)
from .plan_cmd import config_from_args, problem_from_args


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("compare", help="compare every planning method on one move (time, vibration, robustness)")
    p.add_argument("--config", required=True, help="ROS 2 parameter file (model, u_max, ...)")
    p.add_argument("--goal", type=float, help="target position (m or rad); the move starts at rest at 0")
    p.add_argument("--initial-velocity", type=float, dest="initial_velocity", help="initial rigid-body velocity")
    p.add_argument(
        "--freq-error",
        type=float,
        default=0.1,
        dest="freq_error",
        help="relative frequency error band for the worst residual (default 0.1)",
    )
    p.add_argument("--tolerance", type=float, default=0.05, help="vibration tolerance for the insensitivity (fraction)")
    p.add_argument("--methods", help="comma-separated methods (default: all)")
    p.add_argument(
        "--rate", type=float, help="compare the sampled commands at this rate (Hz) instead of the continuous ones"
    )
    p.add_argument("--robust-order", type=int, dest="robust_order", help="derivative order for robust_time_optimal")
    p.add_argument("--plot", help="write the sensitivity curves to this PNG file")
    p.add_argument("--json", action="store_true", help="print a JSON list of rows")
    p.set_defaults(func=run, method=None)


def _check(args: argparse.Namespace) -> None:
    e = args.freq_error
    if not (math.isfinite(e) and 0.0 < e < 1.0):
        raise InputError("freq_error", f"must be in (0, 1) (relative, 0.1 = 10 %), got {e}")
    t = args.tolerance
    if not (math.isfinite(t) and 0.0 < t < 1.0):
        raise InputError("tolerance", f"must be in (0, 1) (fraction, 0.05 = 5 %), got {t}")


def run(args: argparse.Namespace) -> int:
    _check(args)
    config = config_from_args(args)
    problem = problem_from_args(config, args.goal, args.initial_velocity)
    model, um = config.model, config.u_max
    if not model.n_modes:
        raise InputError("model.omega", "compare needs a model with at least one vibration mode")
    methods = [m.strip() for m in args.methods.split(",")] if args.methods else list(METHODS)
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise InputError("methods", f"unknown {unknown}; choose from {sorted(METHODS)}")
    if "time_optimal" in methods:
        methods.remove("time_optimal")
    methods.insert(0, "time_optimal")  # the reference for added time

    w, z, b = (np.asarray(v, dtype=float) for v in (model.omega, model.zeta, model.b))
    step = np.abs(b) * um / (w * w * np.sqrt(1.0 - z * z))
    e = args.freq_error
    ratios = np.linspace(max(0.05, 1.0 - 3.0 * e), 1.0 + 3.0 * e, 601)
    rows, curves, T_star = [], {}, None
    for m in methods:
        t0 = time.perf_counter()
        try:
            result = plan_move(config.with_changes(method=m), problem, rate_hz=args.rate)
        except FlexmotionError as exc:
            rows.append({"method": m, "error": str(exc)})
            continue
        plan_time = time.perf_counter() - t0
        u = result.sampled.input() if result.sampled is not None else result.continuous.input()
        if m == "time_optimal":
            T_star = float(result.continuous.duration)
        amp = residual_amplitudes(model, problem.x0, u)
        shaper = getattr(result.continuous, "shaper", None)
        rows.append(
            {
                "method": m,
                "duration_s": u.duration,
                "added_time_s": u.duration - T_star if T_star is not None else math.nan,
                "peak_command": u.max_abs(),
                "residual_percent": float(np.max(100.0 * amp / step)),
                # the classic figure of a shaper (the one shaper.tolerance is defined on): its impulse
                # sequence's residual at the nominal frequencies, in % of the unshaped command's, worst mode
                "shaper_residual_percent": (
                    None if shaper is None else float(100.0 * np.max(shaper.vibration(shaper.omega, shaper.zeta)))
                ),
                "worst_in_band_percent": 100.0 * worst_in_band(u, model, e, um),
                "insensitivity_width": command_insensitivity(u, model, args.tolerance, um).width,
                "plan_time_s": plan_time,
                "defaults": _defaults(result.info, args.rate, result.sampled),
            }
        )
        curves[m] = (ratios, np.max(command_curve(u, model, ratios, um), axis=1))
    if args.plot:
        from ..plots.compare import plot_sensitivity

        goal = f"goal {args.goal:g}" if args.goal is not None else f"stop from {args.initial_velocity:g}"
        durations = {r["method"]: r["duration_s"] for r in rows if "error" not in r}
        plot_sensitivity(curves, args.plot, 100.0 * args.tolerance, e, f"{args.config}: {goal}", durations=durations)
    if args.json:
        print(json.dumps(rows))
        return 0
    head = (
        f"{'method':20s} {'duration s':>11s} {'added s':>9s} {'peak |u|':>9s} {'move res %':>10s} "
        f"{'shaper V %':>10s} {'worst %':>9s} {'width':>7s} {'plan ms':>8s}"
    )
    print(
        "move res %: residual vibration the whole move leaves, in % of what a step of u_max leaves (worst mode)\n"
        "shaper V %: a shaper's own residual (its impulses alone, at the nominal frequencies), in % of the "
        "unshaped command's: the figure shaper.tolerance is defined on\n"
        f"worst %: move res % at worst over +/-{100 * e:g} % frequency error; width: frequency-ratio interval "
        f"with move res % <= {100 * args.tolerance:g} %"
    )
    print(head)
    for r in rows:
        if "error" in r:
            print(f"{r['method']:20s} error: {r['error']}")
            continue
        v = r["shaper_residual_percent"]
        print(
            f"{r['method']:20s} {r['duration_s']:11.6f} {r['added_time_s']:9.4f} {r['peak_command']:9.4g} "
            f"{r['residual_percent']:10.2e} {'-' if v is None else f'{v:.3f}':>10s} "
            f"{r['worst_in_band_percent']:9.3f} {r['insensitivity_width']:7.4f} {1e3 * r['plan_time_s']:8.1f}"
        )
    for r in rows:
        for note in r.get("defaults", []):
            print(f"{r['method']}: {note}")
    if args.plot:
        print(f"plot: {args.plot}")
    return 0


def _defaults(info: dict, rate: float | None, sampled) -> list[str]:
    """What a method took by default when the command line gave nothing (from its plan's ``info``)."""
    notes = []
    source = str(info.get("move_time_source", ""))
    if source.startswith("default") and "move_time" in info:
        notes.append(f"move_time {float(info['move_time']):.6f} s ({source}; none given)")
    limits = info.get("limits")
    if isinstance(limits, dict):
        unset = [k for k, v in limits.items() if v is None]
        if len(unset) == len(limits):
            notes.append(f"no limits given ({', '.join(unset)} unset): the sampled time-optimal move")
        elif unset:
            notes.append(f"{', '.join(unset)} unset (no limit)")
    if rate is None and sampled is not None and "rate_source" in info:
        notes.append(f"sampled at {1.0 / sampled.dt:g} Hz ({info['rate_source']}): its duration is the sampled one")
    return notes
