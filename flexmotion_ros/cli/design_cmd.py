"""``flexmotion design``: the structural parameters that make a task's move shortest.

The starting structure is the parameter file's ``design:`` section (the
builder and its physical arguments, see ``config/design_two_mass.yaml``); a
file with only a modal model needs ``--builder`` and ``--set NAME=VALUE`` for
every required argument.  ``--set`` also overrides single values of the file.
"""

from __future__ import annotations

import argparse
import json
import math
import sys

from ..core.design.optimize import optimize_design, write_design
from ..core.design.problem import (
    RobustnessRequirement,
    problem_from_parameters,
    rigid_bound,
)
from ..core.design.space import PARAMETER_RANGES, DesignParameter
from ..core.errors import InputError
from ..core.parameter_checks import check_parameters
from ..core.parameter_file import read_parameter_file


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("design", help="choose structural parameters that make the optimal move shortest")
    p.add_argument("--config", required=True, help="ROS 2 parameter file (u_max, method, ...; design: section)")
    p.add_argument("--builder", choices=sorted(PARAMETER_RANGES), help="physical model (overrides design.builder)")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        dest="sets",
        help="starting value of a builder argument, e.g. k=1 or masses=1,1,1 (repeatable)",
    )
    p.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=LO:HI[:log|linear]",
        dest="params",
        help="free parameter and its bounds, e.g. k=0.5:20 or 'springs[1]=1:4' (repeatable, 1-3)",
    )
    p.add_argument(
        "--goal",
        action="append",
        type=float,
        default=[],
        metavar="GAMMA",
        help="rest-to-rest move (m or rad); repeat for a set of tasks",
    )
    p.add_argument(
        "--weight",
        action="append",
        type=float,
        default=None,
        metavar="W",
        help="weight of each --goal, in order (default 1 each)",
    )
    p.add_argument("--method", help="profile type (overrides the file's 'method')")
    p.add_argument("--robust-order", type=int, dest="robust_order", help="derivative order for robust methods")
    p.add_argument(
        "--frequency-error",
        type=float,
        dest="frequency_error",
        help="robustness requirement: relative frequency error to tolerate (with --max-residual)",
    )
    p.add_argument(
        "--max-residual",
        type=float,
        dest="max_residual",
        help="largest residual mode amplitude allowed under that error (m)",
    )
    p.add_argument("--grid", help="grid points per parameter, e.g. 41 or 15,15 (default 41 / 15 / 7)")
    p.add_argument("--xtol", type=float, default=1e-5, help="refine tolerance, fraction of each range")
    p.add_argument("--workers", type=int, default=1, help="processes for the grid sweep")
    p.add_argument("--plot", help="write a figure of move time over the parameter(s) (PNG)")
    p.add_argument("--output", help="write the designed configuration (ROS 2 parameter file)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def _parse_param(text: str) -> DesignParameter:
    name, sep, rng = text.partition("=")
    parts = rng.split(":")
    if not sep or not name or len(parts) not in (2, 3):
        raise InputError("param", f"expected NAME=LO:HI[:log|linear], got {text!r}")
    try:
        lo, hi = float(parts[0]), float(parts[1])
    except ValueError:
        raise InputError(f"param {name}", f"bounds must be numbers, got {rng!r}") from None
    return DesignParameter(name.strip(), lo, hi, parts[2] if len(parts) == 3 else "auto")


def _parse_set(text: str) -> tuple[str, object]:
    name, sep, value = text.partition("=")
    if not sep or not name:
        raise InputError("set", f"expected NAME=VALUE, got {text!r}")
    items = [v for v in value.replace(",", " ").split()]
    try:
        vals = [float(v) for v in items]
    except ValueError:
        raise InputError(f"design.{name}", f"must be a number or a list of numbers, got {value!r}") from None
    if name.strip() in ("masses", "springs", "dampers"):
        return name.strip(), vals
    if len(vals) != 1:
        raise InputError(f"design.{name}", f"must be one number, got {value!r}")
    return name.strip(), vals[0]


def _grid(text: str | None, n: int):
    if text is None:
        return None
    try:
        sizes = [int(v) for v in text.replace(",", " ").split()]
    except ValueError:
        raise InputError("grid", f"must be integers, e.g. 41 or 15,15; got {text!r}") from None
    return sizes * n if len(sizes) == 1 else sizes


def run(args: argparse.Namespace) -> int:
    params = read_parameter_file(args.config, "flexmotion_planner")
    check_parameters(params)  # unknown names and wrong ROS types: refused, as by plan and the nodes
    robust = None
    if (args.frequency_error is None) != (args.max_residual is None):
        raise InputError("frequency_error", "give both --frequency-error and --max-residual, or neither")
    if args.frequency_error is not None:
        robust = RobustnessRequirement(args.frequency_error, args.max_residual)
    if not args.params:
        raise InputError("param", "give at least one --param NAME=LO:HI")
    if not args.goal:
        raise InputError("goal", "give at least one --goal GAMMA")
    bounds = [_parse_param(t) for t in args.params]
    problem, notes = problem_from_parameters(
        params,
        bounds,
        args.goal,
        args.weight,
        builder=args.builder,
        overrides=dict(_parse_set(t) for t in args.sets),
        robustness=robust,
        config_changes=_config_changes(args),
    )
    for note in notes:
        sys.stderr.write(f"flexmotion: note: {note}\n")
    result = optimize_design(problem, grid=_grid(args.grid, len(bounds)), xtol=args.xtol, workers=args.workers)
    if args.output:
        header = (
            f"# flexmotion design: {problem.builder}, {_bounds_text(problem)}, goals {list(args.goal)}\n"
            f"# optimum {_values_text(problem, result.best)}: {result.objective:.9f} s "
            f"(start {_start_time(result)}); model below is the designed structure\n"
        )
        try:
            write_design(args.output, result, header)
        except OSError as exc:
            raise InputError("output", f"cannot write {args.output}: {exc.strerror}") from None
        sys.stderr.write(f"wrote {args.output}\n")
    if args.plot:
        from ..plots.design import plot_design

        try:
            plot_design(result, args.plot)
        except OSError as exc:
            raise InputError("plot", f"cannot write {args.plot}: {exc.strerror}") from None
        sys.stderr.write(f"wrote {args.plot}\n")
    if args.json:
        print(json.dumps(result.to_dict()))
        return 0
    print(_text(result))
    return 0


def _config_changes(args: argparse.Namespace) -> dict:
    changes: dict = {}
    if args.method:
        changes["method"] = args.method
    if args.robust_order is not None:
        changes["options"] = {"robust_order": args.robust_order}  # merged into the file's options
    return changes


def _unit(problem, name: str) -> str:
    key = name.split("[")[0]
    unit = PARAMETER_RANGES[problem.builder][key][4]
    return f" {unit}" if unit else ""


def _values_text(problem, values: dict) -> str:
    return ", ".join(f"{k} = {v:.9g}{_unit(problem, k)}" for k, v in values.items())


def _bounds_text(problem) -> str:
    return ", ".join(f"{p.name} in [{p.lower:g}, {p.upper:g}] ({p.scale})" for p in problem.parameters)


def _start_time(result) -> str:
    ev = result.start_evaluation
    return f"{ev.objective:.9f} s" if ev.feasible else f"failed: {ev.status}"


def _cert_text(certified) -> str:
    return {True: "certified", False: "NOT certified", None: "method gives no optimality certificate"}[certified]


def _text(result) -> str:
    pb, ev = result.problem, result.evaluation
    tasks = ", ".join(f"{t.gamma:g}" + (f" (w {t.weight:g})" if t.weight != 1.0 else "") for t in pb.tasks)
    lines = [
        f"design            {pb.builder}, {_bounds_text(pb)}",
        f"tasks             goal {tasks}; method {pb.config.method}; u_max {pb.config.u_max:g}",
        f"best              {_values_text(pb, result.best)}",
        f"move time         {result.objective:.9f} s ({_cert_text(result.certified)})",
    ]
    bound = rigid_bound(pb, ev.values)
    lines.append(f"rigid-body bound  {bound:.9f} s (lower bound; optimum {result.objective - bound:.3e} s above)")
    if len(pb.tasks) > 1:
        lines.append(f"per task          {', '.join(f'{t:.9f}' for t in ev.times)} s")
    if ev.residual is not None:
        lines.append(f"residual          {ev.residual:.3e} (max {pb.robustness.max_residual:g})")
    lines.append(f"starting design   {_values_text(pb, result.start)}: {_start_time(result)}")
    st = result.start_evaluation
    if st.feasible:
        gain = st.objective - result.objective
        lines.append(f"improvement       {gain:.9f} s ({100.0 * gain / st.objective:.2f} %)")
    n_grid = int(result.grid_objective.size)
    failed = sum(1 for e in result.evaluations if not e.feasible)
    lines += [
        f"evaluations       {len(result.evaluations)} design points ({n_grid} grid), {failed} infeasible",
        f"wall time         {result.wall_time_s:.2f} s",
    ]
    if not math.isfinite(result.objective):  # pragma: no cover - optimize_design raises instead
        lines.append("no feasible design")
    return "\n".join(lines)
