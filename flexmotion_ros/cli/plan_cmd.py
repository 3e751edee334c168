"""``flexmotion plan``: plan one move offline from a parameter file."""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import yaml

from ..core.config import load_config
from ..core.errors import ConfigError, GoalError
from ..core.methods.table import plan_move
from ..core.model.boundary import motion_to_rest, rest_to_rest, state_to_rest
from ..core.model.modal_model import check_positive


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("plan", help="plan a move from rest (or from a velocity) and print it")
    p.add_argument("--config", required=True, help="ROS 2 parameter file (model, u_max, rate_hz, ...)")
    p.add_argument("--goal", type=float, help="target position (m or rad); the move starts at rest at 0")
    p.add_argument("--initial-velocity", type=float, dest="initial_velocity", help="initial rigid-body velocity")
    p.add_argument("--rate", type=float, help="also plan the exact zero-order-hold sequence at this rate (Hz)")
    p.add_argument("--method", help="profile type (overrides the file's 'method')")
    p.add_argument("--robust-order", type=int, dest="robust_order", help="derivative order for robust methods")
    p.add_argument(
        "--option",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="method option as a ROS parameter (repeatable), e.g. coulomb_force=0.2",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def config_from_args(args: argparse.Namespace):
    """The file's configuration with ``--method`` / ``--robust-order`` applied."""
    config = load_config(args.config)
    if getattr(args, "method", None):
        config = config.with_changes(method=args.method)
    if getattr(args, "robust_order", None) is not None:
        config = config.with_changes(options={**config.options, "robust_order": args.robust_order})
    for item in getattr(args, "option", None) or []:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise ConfigError("--option", f"expected NAME=VALUE, got {item!r}")
        config = config.with_changes(options={**config.options, name.strip(): yaml.safe_load(value)})
    return config


def problem_from_args(config, goal: float | None, initial_velocity: float | None):
    """The move a ``plan``-like command asks for (shared by other commands)."""
    if goal is None and initial_velocity is None:
        raise GoalError("goal", "give --goal GAMMA, --initial-velocity NU, or both")
    for name, v in (("goal", goal), ("initial_velocity", initial_velocity)):
        if v is not None and not math.isfinite(v):
            raise GoalError(name, f"must be finite, got {v}")
    model, um = config.model, config.u_max
    if goal is not None:
        config.check_goal(goal)
    if initial_velocity is None:
        return rest_to_rest(model, um, goal)
    if goal is None:
        return motion_to_rest(model, um, initial_velocity)
    x0 = model.rest_state()
    x0[1] = initial_velocity
    return state_to_rest(model, um, x0, goal)


def run(args: argparse.Namespace) -> int:
    config = config_from_args(args)
    problem = problem_from_args(config, args.goal, args.initial_velocity)
    rate = None if args.rate is None else check_positive("rate_hz", args.rate, "Hz")
    result = plan_move(config, problem, rate_hz=rate)
    out = result.summary()
    if args.json:
        print(json.dumps(out))
        return 0
    print(_text(out))
    return 0


def _times(values, unit: str = "", limit: int = 12) -> str:
    """A short list: the first values, then how many more."""
    values = list(values)
    text = ", ".join(f"{v:.9f}" if unit else f"{v:+g}" for v in values[:limit]) or "-"
    if len(values) > limit:
        text += f", ... ({len(values)} in all)"
    return text + (f" {unit}" if unit else "")


def _text(out: dict) -> str:
    """Human-readable summary of :meth:`PlanResult.summary` (any method)."""
    lines = [f"method            {out['method']}"]
    if "duration" in out:
        lines.append(f"duration          {out['duration']:.9f} s")
    if "switch_times" in out:
        lines.append(f"switch times      {_times(out['switch_times'], 's')}")
    if "levels" in out:
        lines.append(f"levels            {_times(out['levels'])}")
    if "final_state_error" in out:
        rel = out.get("final_state_error_relative")
        lines.append(
            f"final-state error {out['final_state_error']:.3e}" + (f" (relative {rel:.1e})" if rel is not None else "")
        )
    if "certified" in out:
        message = (out.get("certificate") or {}).get("message", "-")
        lines.append(f"certified         {out['certified']} ({message})")
    if "solve_time_s" in out:
        lines.append(f"solve time        {out['solve_time_s'] * 1e3:.2f} ms")
    if "samples" in out:
        lines += [
            f"rate              {out['rate_hz']:g} Hz",
            f"samples           {out['samples']} ({out['sampled_duration']:.6f} s, "
            f"{'proved fewest' if out['minimal'] else 'not proved fewest'})",
            f"sampled error     {out['sampled_final_state_error']:.3e}",
            f"peak command      {np.max(np.abs(out['commands'])) if out['commands'] else 0.0:.9g}",
        ]
    return "\n".join(lines)
