"""``flexmotion plan``: plan one move offline from a parameter file (one input or several, :mod:`.multi_plan`)."""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from ..core.errors import ConfigError, GoalError
from ..core.model.boundary import motion_to_rest, rest_to_rest, state_to_rest
from ..core.model.modal_model import check_positive
from ..core.multi_input.config import MultiPlannerConfig
from ..core.multi_input.dispatch import check_budgets, config_from_any, move_problem
from ..core.multi_input.dispatch import plan as plan_move  # plan_move, or plan_multi_move for several inputs
from ..core.parameter_checks import check_parameters
from ..core.parameter_file import read_parameter_file
from ..core.ros_types import parse_parameter_value
from . import multi_plan


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("plan", help="plan a move from rest (or from a velocity) and print it")
    p.add_argument("--config", required=True, help="ROS 2 parameter file (model, u_max, rate_hz, ...)")
    p.add_argument(
        "--goal",
        help="target position (m or rad); several rigid bodies: one each, e.g. 3.0,2.0; the move starts at rest at 0",
    )
    p.add_argument("--initial-velocity", type=float, dest="initial_velocity", help="initial rigid-body velocity")
    p.add_argument(
        "--initial-state",
        dest="initial_state",
        help="the whole start state, comma-separated, in the state order [p1, v1, ..., pk, vk, q1, q1', ...] "
        "(moving and vibrating); without --goal the move stops with the final positions free",
    )
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
    """The file's parameters with ``--method``, ``--robust-order`` and ``--option`` applied, checked once.

    Every name must be known and every value of its ROS type
    (:func:`~flexmotion_ros.core.parameter_checks.check_parameters`, the nodes' check
    too): ``--option`` values are typed by rcl's rules, as ``-p NAME:=VALUE`` is.
    """
    params = read_parameter_file(args.config, "flexmotion_planner")
    if getattr(args, "method", None):
        params["method"] = args.method
    if getattr(args, "robust_order", None) is not None:
        params["robust_order"] = args.robust_order
    for item in getattr(args, "option", None) or []:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise ConfigError("--option", f"expected NAME=VALUE, got {item!r}")
        params[name] = parse_parameter_value(value, name)
    check_parameters(params)
    return config_from_any(params)


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


def _problem(config, args: argparse.Namespace):
    """The move of ``--goal`` (one value, or one per rigid body), ``--initial-state`` / ``--initial-velocity``."""
    goal = multi_plan.numbers(args.goal, "goal")
    x0 = multi_plan.initial_state(config, multi_plan.numbers(getattr(args, "initial_state", None), "initial_state"))
    multi = isinstance(config, MultiPlannerConfig)
    if x0 is not None and args.initial_velocity is not None:
        raise GoalError("initial_state", "give --initial-state or --initial-velocity, not both")
    if goal is not None:
        if multi:
            goal = config.check_goal(goal)
        elif len(goal) != 1:
            raise GoalError("goal", f"this single-input model takes one target, got {len(goal)}: {goal}")
        else:
            goal = goal[0]
    if x0 is None and not multi:
        return problem_from_args(config, goal, args.initial_velocity)
    if args.initial_velocity is not None:
        raise GoalError("initial_velocity", "a multi-input model takes the whole start state: --initial-state")
    if goal is None and x0 is None:
        raise GoalError("goal", "give --goal (one target per rigid body), --initial-state, or both")
    if x0 is None:
        x0 = config.model.rest_state()
    elif not multi and goal is not None:
        config.check_goal(goal)
    return move_problem(config, x0, goal)


def run(args: argparse.Namespace) -> int:
    config = config_from_args(args)
    problem = _problem(config, args)
    rate = None if args.rate is None else check_positive("rate_hz", args.rate, "Hz")
    multi = isinstance(config, MultiPlannerConfig)
    if rate is not None or multi:  # the node's budgets: refused before planning, in microseconds
        check_budgets(config, problem, rate)
    t0 = time.perf_counter()
    result = plan_move(config, problem, rate_hz=rate)
    plan_time = time.perf_counter() - t0
    if multi:
        return _run_multi(args, config, result, plan_time)
    out = result.summary()
    if result.sampled is not None:
        # the sampled plan's own solve time, and the whole call (what a node waits for before streaming)
        out["sampled_solve_time_s"] = float(result.sampled.solve_time_s)
        out["plan_time_s"] = float(plan_time)
    if args.goal is None:  # a stop: the final position is free, say where it is
        if "final_state" in out:
            out["stop_position"] = float(out["final_state"][0])
        if result.sampled is not None:
            out["sampled_stop_position"] = float(result.sampled.states[-1][0])
    if args.json:
        print(json.dumps(out))
        return 0
    print(_text(out))
    return 0


def _run_multi(args: argparse.Namespace, config: MultiPlannerConfig, result, plan_time: float) -> int:
    """The multi-input JSON (levels: rows of m; commands: K rows of m) or text."""
    out = result.summary()
    if result.sampled is not None:
        out["plan_time_s"] = float(plan_time)
    if args.goal is None:
        multi_plan.stop_positions(config, out, None if result.sampled is None else result.sampled.states)
    if args.json:
        print(json.dumps(out))
        return 0
    print(multi_plan.text(out, config.model.inputs, config.model.rigid_bodies))
    return 0


#: Levels below this fraction of the largest one are rounding noise of an LP or a Newton solve: printed as 0.
LEVEL_ZERO = 1e-9


def _times(values, unit: str = "", limit: int = 12, zero: float = 0.0) -> str:
    """A short list: the first values, then how many more; ``|v| <= zero`` printed as 0."""
    values = list(values)
    text = ", ".join(f"{v:.9f}" if unit else ("0" if abs(v) <= zero else f"{v:+g}") for v in values[:limit]) or "-"
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
        zero = LEVEL_ZERO * max((abs(v) for v in out["levels"]), default=0.0)
        rounded = any(0.0 < abs(v) <= zero for v in out["levels"])
        note = f"  (|level| <= {LEVEL_ZERO:g} of the largest printed as 0)" if rounded else ""
        lines.append(f"levels            {_times(out['levels'], zero=zero)}{note}")
    if "final_state_error" in out:
        rel = out.get("final_state_error_relative")
        lines.append(
            f"final-state error {out['final_state_error']:.3e}" + (f" (relative {rel:.1e})" if rel is not None else "")
        )
    if "stop_position" in out:
        lines.append(f"stops at          {out['stop_position']:.9f} (final position free)")
    if "certified" in out:
        cert = out.get("certificate") or {}
        claim = cert.get("claim") or out.get("optimality")
        if claim:  # the checks passed prove only what the claim says
            verdict = "checks passed" if out["certified"] else "checks FAILED"
            lines.append(f"certificate       {verdict} ({cert.get('message', '-')}): {claim}")
        else:
            lines.append(f"certified         {out['certified']} ({cert.get('message', '-')})")
    if "lower_bound_s" in out:
        lines.append(f"lower bound       {out['lower_bound_s']:.9f} s (proved: no move is shorter)")
    if "solve_time_s" in out:
        lines.append(
            f"solve time        {out['solve_time_s'] * 1e3:.2f} ms" + (" (continuous)" if "samples" in out else "")
        )
    if "samples" in out:
        lines += [
            f"rate              {out['rate_hz']:g} Hz",
            f"samples           {out['samples']} ({out['sampled_duration']:.6f} s, "
            f"{'proved fewest' if out['minimal'] else 'not proved fewest'})",
            f"sampled error     {out['sampled_final_state_error']:.3e}",
            *(
                [f"sampled stops at  {out['sampled_stop_position']:.9f} (final position free)"]
                if "sampled_stop_position" in out
                else []
            ),
            f"sampled solve     {out['sampled_solve_time_s'] * 1e3:.2f} ms (plan_move in all: "
            f"{out['plan_time_s'] * 1e3:.2f} ms)",
            f"peak command      {np.max(np.abs(out['commands'])) if out['commands'] else 0.0:.9g}",
        ]
    return "\n".join(lines)
