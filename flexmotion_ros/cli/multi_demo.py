"""``flexmotion demo`` for several inputs: the summary of every axis and the figure (:mod:`.demo_cmd` runs it).

The arrival is judged as for one input, on every axis at once: the first
sample after which every rigid body is within the tolerance of its target,
still, and every sway amplitude within the tolerance (1e-6 of the move in
lockstep), never before the end of the last command.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.multi_input.dispatch import positions_text

#: ``pose.position`` fields carrying the first three rigid bodies' targets in ``~/move``.
POSE_AXES = ("x", "y", "z")


def _at_goal(model, X: np.ndarray, goal: np.ndarray, tol: float) -> np.ndarray:
    """Per sample: every rigid body within ``tol`` of its target, every velocity and sway amplitude within ``tol``."""
    from ..plots.multi_demo import sway  # matplotlib only when reporting

    k = model.k
    near = np.all(np.abs(X[:, 0 : 2 * k : 2] - goal) <= tol, axis=1)
    still = np.all(np.abs(X[:, 1 : 2 * k : 2]) <= tol, axis=1)
    calm = np.all(sway(model, X) <= tol, axis=1) if model.n_modes else np.ones(len(X), bool)
    return near & still & calm


def report(demo, t_req: float, cmds: list, sts: list, diag: dict, K: int) -> int:
    """Print the multi-input demo's summary and write its figure; 0 if every axis arrived (or a model error was asked)."""
    from ..plots.multi_demo import plot_multi_demo, sway

    args, config, plant = demo.args, demo.config, demo.plant_cfg
    model = plant.model
    goal = np.asarray(args.goal, float)
    start = np.broadcast_to(np.asarray(plant.initial_position, float), goal.shape)
    move = float(np.max(np.abs(goal - start))) or 1.0
    u = np.array([c[1] for c in cmds], float).reshape(len(cmds), model.m)
    t_recv = np.array([c[0] for c in cmds])
    X = np.array([s[1] for s in sts])
    values = diag.get("values", {})
    dt = demo.dt
    t_cmd = dt * np.arange(len(u))
    if args.realtime:
        t_x = np.array([s[0] for s in sts]) - float(sts[0][0]) + dt
        tol = 1e-2
    else:
        t_x = dt * np.arange(1, len(X) + 1)
        tol = 1e-6
    ok = _at_goal(model, X, goal, tol * move)
    bad = np.flatnonzero(~ok)
    arrived = bool(ok[-1])
    planned = K * dt
    t_arr = max(float(t_x[(bad[-1] + 1) if bad.size else 0]), planned) if arrived else None
    x_end = X[-1]
    lines = [
        f"move                 {positions_text(start)} -> {positions_text(goal)}  ({demo.config_path}; "
        f"rigid bodies {list(model.rigid_bodies)}, inputs {list(model.inputs)})",
        (
            f"planned duration     {planned:.6f} s  ({K} samples at {demo.rate:g} Hz; continuous optimum "
            f"{float(values.get('last_plan.continuous_duration_s', 'nan')):.6f} s, certified "
            f"{values.get('last_plan.certified', '?')}, sync {config.sync})"
        ),
        f"goal -> first command {(t_recv[0] - t_req) * 1e3:.1f} ms (planning "
        f"{float(values.get('last_plan.plan_time_s', 'nan')) * 1e3:.1f} ms)",
    ]
    if arrived:
        lines.append(
            f"measured arrival     {t_arr:.6f} s (every axis together; {'plant time' if not args.realtime else 'wall clock'}) "
            f"-- from then on within {tol:g} of the move in every position, velocity and sway"
        )
    else:
        lines.append(
            f"measured arrival     none: not within {tol:g} of the move by the last sample (see the residuals)"
        )
    peak = np.max(np.abs(u), axis=0)
    lines.append(
        "peak |command|       "
        + ", ".join(f"{n} {p:.9g} N (u_max {b:g})" for n, p, b in zip(model.inputs, peak, config.u_max))
    )
    for j, name in enumerate(model.rigid_bodies):
        lines.append(
            f"axis {name:<15} final position error {x_end[2 * j] - goal[j]:+.3e}   final velocity {x_end[2 * j + 1]:+.3e}"
        )
    for name, a in zip(model.mode_names, sway(model, X[-1:])[0]):
        lines.append(f"residual {name:<11} {a:.3e}  ({a / move:.1e} of the move; modal coordinate)")
    if args.omega_scale:
        lines.append(
            f"plant model error    omega x {args.omega_scale}: the planner used {list(config.model.omega)} rad/s"
        )
    stream_wall = t_recv[K] - t_recv[0] if len(t_recv) > K else math.nan
    lines.append(f"stream               received here over {stream_wall:.6f} s ({K} command rows of {model.m} + hold)")
    print("\n".join(lines))
    if args.plot:
        title = (
            f"flexmotion demo: {positions_text(goal)} in {planned:.4f} s "
            f"({'real time' if args.realtime else 'lockstep'} plant, {demo.rate:g} Hz, {model.m} drives)"
        )
        plot_multi_demo(args.plot, t_cmd, u, config.u_max, t_x, X, goal, start, model, title, t_arr)
        print(
            f"plot                 {args.plot} (every drive, axis and sway; dashed: the exact zero-input continuation)"
        )
    return 0 if arrived or args.omega_scale else 1


__all__ = ["POSE_AXES", "report"]
