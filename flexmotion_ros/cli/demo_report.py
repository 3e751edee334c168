"""``flexmotion demo`` for one input: when the plant arrived, the summary and the figure (:mod:`.demo_cmd` runs it).

Arrival is the end of the last command once the plant stays within the
tolerance of the goal, at rest, from then on (1e-6 of the move in lockstep,
1e-2 in real time), so it is never earlier than the planned, proved-optimal
duration; entering the band earlier is reported as such.
"""

from __future__ import annotations

import math

import numpy as np


def report(
    demo, t_req: float, cmds: list, sts: list, diag: dict, planned_t: np.ndarray, planned_p: np.ndarray, K: int
) -> int:
    """Print the one-input demo's summary and write its figure; 0 if the plant arrived (or a model error was asked)."""
    from ..core.simulation.exact import modal_amplitudes
    from ..plots.demo import continuation, meaning_from_file, plot_demo

    model = demo.plant_cfg.model
    goal = float(demo.args.goal)
    move = abs(goal - demo.plant_cfg.initial_position) or 1.0
    u = np.array([c[1] for c in cmds])
    t_recv = np.array([c[0] for c in cmds])
    X = np.array([s[1] for s in sts])
    values = diag.get("values", {})
    t_cmd = demo.dt * np.arange(u.size)  # sample k is due at k / rate
    if demo.args.realtime:
        # joint_states stamps against the first command's due time (the path's first stamp)
        t_x = np.array([s[0] for s in sts]) - planned_t[0]
        tol = 1e-2
    else:
        t_x = demo.dt * np.arange(1, len(X) + 1)  # state after each command
        tol = 1e-6
    ok = (
        (np.abs(X[:, 0] - goal) <= tol * move)
        & np.all(modal_amplitudes(model, X) <= tol * move, axis=-1)
        & (np.abs(X[:, 1]) <= tol * move)
    )
    # arrival: from the first sample after which the plant stays at the goal, at rest
    bad = np.flatnonzero(~ok)
    arrived = bool(ok[-1])
    i_arr = (bad[-1] + 1) if bad.size else 0
    x_end = X[-1]
    amps = modal_amplitudes(model, x_end)
    planned = K * demo.dt
    stream_wall = t_recv[K] - t_recv[0] if len(t_recv) > K else math.nan
    lines = [
        f"move                 {demo.plant_cfg.initial_position:g} -> {goal:g}  ({demo.config_path})",
        (
            f"planned duration     {planned:.6f} s  ({K} samples at {demo.rate:g} Hz; continuous optimum "
            f"{float(values.get('last_plan.continuous_duration_s', 'nan')):.6f} s, certified {values.get('last_plan.certified', '?')})"
        ),
        f"goal -> first command {(t_recv[0] - t_req) * 1e3:.1f} ms (planning {float(values.get('last_plan.plan_time_s', 'nan')) * 1e3:.1f} ms)",
    ]
    # arrival: the end of the last command of the move (it cannot come before the planned, hence
    # proved-optimal-or-longer, duration), provided the plant is within tol of the goal, at rest, from then on;
    # entering the tol band earlier is reported as such, not as an arrival
    t_arr = None
    if arrived:
        t_band = float(t_x[i_arr])
        t_arr = max(t_band, planned)
        clock = "plant time" if not demo.args.realtime else "wall clock"
        what = f"the end of the last command, sample {K}" if t_arr == planned else "the first sample in the band"
        lines.append(
            f"measured arrival     {t_arr:.6f} s ({clock}; {what}) -- from then on within {tol:g} of the move "
            f"in position, velocity and every mode"
        )
        if t_band < planned - 0.5 * demo.dt:
            optimum = float(values.get("last_plan.continuous_duration_s", "nan"))
            lines.append(
                f"                     (inside that {tol:g} band already from {t_band:.6f} s: a tolerance band, "
                f"not an arrival; the proved optimum is {optimum:.6f} s)"
            )
    else:
        lines.append(
            f"measured arrival     none: not within {tol:g} of the move by the last sample (see the residuals)"
        )
    lines += [
        (
            f"stream               received here over {stream_wall:.6f} s ({K} commands + hold); sent with period median "
            f"{float(values.get('last_plan.stream_period_median_ms', 'nan')):.3f} ms, p99 "
            f"{float(values.get('last_plan.stream_period_p99_ms', 'nan')):.3f} ms, max {float(values.get('last_plan.stream_period_max_ms', 'nan')):.3f} ms"
        ),
        f"peak |command|       {np.max(np.abs(u)):.9g} N (u_max {demo.config.u_max:g})",
        f"final position error {x_end[0] - goal:+.3e}   final velocity {x_end[1]:+.3e}",
    ]
    meaning = meaning_from_file(demo.config_path, demo.config.model)
    unit = f" {meaning.unit}" if meaning.unit else ""
    for name, what, a in zip(model.names, meaning.deflections, amps):
        what = f"amplitude of the {what}" if meaning.unit else "modal coordinate, unit of the model"
        lines.append(f"residual {name:<11} {a:.3e}{unit}  ({a / move:.1e} of the move; {what})")
    if demo.args.realtime:
        p = diag.get("plant", {})
        lines.append(
            f"plant (real time)    {p.get('commands_applied', '?')} commands applied from their {demo.args.apply_at} times; "
            f"worst arrival -> integration lag {float(p.get('max_lag_ms', 'nan')):.1f} ms; timeouts {p.get('timeouts', '?')}"
        )
    if demo.args.omega_scale:
        lines.append(
            f"plant model error    omega x {demo.args.omega_scale}: the planner used {list(demo.config.model.omega)} rad/s"
        )
    print("\n".join(lines))
    if demo.args.plot:
        title = f"flexmotion demo: {goal:g} in {planned:.4f} s ({'real time' if demo.args.realtime else 'lockstep'} plant, {demo.rate:g} Hz)"
        if demo.args.omega_scale:
            title += f", plant omega x {demo.args.omega_scale}"
        t_after, X_after = continuation(model, float(t_x[-1]), x_end)
        plot_demo(
            demo.args.plot,
            t_cmd,
            u,
            demo.config.u_max,
            t_x,
            X,
            planned_t - planned_t[0],
            planned_p,
            goal,
            model.names,
            title,
            model=model,
            start=demo.plant_cfg.initial_position,
            meaning=meaning,
            t_arrival=t_arr,
            t_move_end=planned,
            t_after=t_after,
            states_after=X_after,
        )
        print(
            f"plot                 {demo.args.plot} (after the last plant sample at {t_x[-1]:.3f} s: the exact "
            f"zero-input continuation of its state, {t_after[-1] - t_after[0]:.2f} s)"
        )
    return 0 if arrived or demo.args.omega_scale else 1
