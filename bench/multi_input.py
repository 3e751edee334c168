#!/usr/bin/env python3
"""Multi-input planning (issue 12): latency, and what a user would otherwise do.

Table 1 -- latency, m = 2 and 3 inputs, N = 2..6 coupled modes: chains of
N+1 masses (0.5 kg, 400 N/m, 0.4 N s/m), forces at the ends (m = 2) or at
both ends and the middle (m = 3), rest-to-rest moves whose rigid-body time is
1 s and 5 s.  In one run, on the same problems:

* the certified continuous plan (``plan_multi_time_optimal``): wall time
  median / p95 over cold repeats, CPU time median, and beside it the
  single-input certified planner on the same chain with one force (a
  same-run reference for the machine's speed and load); certified or not, and ``delta``: the
  certificate's weak-duality bound proves no input arrives by ``(1 - delta) T*``;
* the exact 1 kHz plan (continuous plan + ``plan_multi_time_optimal_zoh``):
  samples, median wall time, ``K - 1`` proved infeasible or not;
* CasADi + IPOPT: free final time, piecewise-constant inputs on ``N`` equal
  intervals, multiple shooting with the EXACT discretisation (closed form,
  symbolic in ``h = T / N``), ``|u_i| <= u_max_i``, final state at rest;
  initial guess: the rigid bodies' minimum-time move stretched by 30 %.  Its
  ``T``, ``T - T*`` and IPOPT solve time.

Table 2 -- against a time-synchronised rigid-body profile per axis (Ruckig,
acceleration limits ``|b0| u_max``, infinite jerk: the rigid bodies' own
optimum) shaped by ZV / ZVD on every mode: duration and residual vibration
(largest modal amplitude after the move, nominal model and with every
frequency 10 % higher), for a two-axis gantry and a two-force chain.

Table 3 -- the 1 kHz plan of 5 s two-axis (gantry) moves.

Usage::

    OPENBLAS_NUM_THREADS=1 python bench/multi_input.py [--repeats 20] [--casadi-n 100] [--no-casadi]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # tiny matrices: threads only hurt
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import math
import platform
import time

import numpy as np
from scipy.linalg import expm

from flexmotion_ros.core import chain, plan_time_optimal, rest_to_rest
from flexmotion_ros.core.multi_input import (
    MultiModel,
    VectorPiecewise,
    gantry,
    multi_chain,
    multi_rest_to_rest,
    plan_multi_move,
    plan_multi_time_optimal,
    plan_multi_time_optimal_zoh,
)
from flexmotion_ros.core.multi_input import exact as _exact
from flexmotion_ros.core.multi_input.shaped import rigid_only
from flexmotion_ros.core.shaping.shaped_profile import shape
from flexmotion_ros.core.shaping.shapers import design
from flexmotion_ros.core.simulation import exact as _single_exact
from flexmotion_ros.core.simulation.exact import PiecewiseConstant

MODES = (2, 3, 4, 5, 6)
RIGID_TIMES = (1.0, 5.0)
RATE = 1000.0


def chain_model(n_modes: int, m: int):
    act = (0, n_modes) if m == 2 else (0, n_modes // 2 if n_modes >= 2 else 1, n_modes)
    if m == 3 and len(set(act)) < 3:
        act = (0, 1, n_modes)
    u_max = [10.0, 6.0, 8.0][:m]
    return multi_chain([0.5] * (n_modes + 1), [400.0] * n_modes, [0.4] * n_modes, actuated=act, u_max=u_max)


def distance_for(model: MultiModel, u_max, rigid_time: float) -> float:
    a = float(np.abs(model.B0[0]) @ np.asarray(u_max))
    return a * rigid_time**2 / 4.0


def timed(fn, repeats: int):
    """Wall and CPU times (s) of cold calls, and the last result.

    CPU time (this process) is reported beside the wall time: on a shared,
    loaded machine the wall time includes waiting for a core.
    """
    wall, cpu, result = [], [], None
    for _ in range(repeats):
        _exact._step_cached.cache_clear()  # cold: no matrix exponential reused
        t0, c0 = time.perf_counter(), time.process_time()
        result = fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return np.array(wall), np.array(cpu), result


def timed_single(fn, repeats: int):
    """Wall times (s) of cold calls of a single-input planner (its own expm cache cleared)."""
    out, result = [], None
    for _ in range(repeats):
        _single_exact._step_cached.cache_clear()
        t0 = time.perf_counter()
        result = fn()
        out.append(time.perf_counter() - t0)
    return np.array(out), result


# ------------------------------------------------------------------ CasADi
def discretisation_casadi(model: MultiModel, h):
    """``Phi(h)``, ``Gamma(h)`` (n x m) in closed form, symbolic in ``h`` (CasADi SX)."""
    import casadi as ca

    n, m, k = model.n_states, model.m, model.k
    Phi = ca.SX.zeros(n, n)
    Gam = ca.SX.zeros(n, m)
    B0, Bm = model.B0, model.Bm
    for j, c in enumerate(model.c):
        r = 2 * j
        if c == 0.0:
            Phi[r, r], Phi[r, r + 1], Phi[r + 1, r + 1] = 1, h, 1
            g0, g1 = h * h / 2, h
        else:
            e = ca.exp(c * h)
            Phi[r, r], Phi[r, r + 1], Phi[r + 1, r + 1] = 1, (e - 1) / c, e
            g0, g1 = ((e - 1) / c - h) / c, (e - 1) / c
        for i in range(m):
            Gam[r, i], Gam[r + 1, i] = B0[j, i] * g0, B0[j, i] * g1
    for l, (w, z) in enumerate(zip(model.omega, model.zeta)):
        r = 2 * k + 2 * l
        s, wd = z * w, w * math.sqrt(1 - z * z)
        E, C, S = ca.exp(-s * h), ca.cos(wd * h), ca.sin(wd * h)
        Phi[r, r] = E * (C + s / wd * S)
        Phi[r, r + 1] = E * S / wd
        Phi[r + 1, r] = -E * w * w / wd * S
        Phi[r + 1, r + 1] = E * (C - s / wd * S)
        for i in range(m):
            Gam[r, i] = Bm[l, i] * (1 - E * (C + s / wd * S)) / (w * w)
            Gam[r + 1, i] = Bm[l, i] * E * S / wd
    return Phi, Gam


def casadi_direct(problem, N: int) -> dict:
    """Free-final-time direct multiple shooting with IPOPT, m inputs."""
    import casadi as ca

    model = problem.model
    n, m = model.n_states, model.m
    U = problem.u_max
    A, B = model.A(), model.B()
    x0 = problem.x0 - problem.target_state()
    rig = plan_multi_time_optimal(rigid_only(problem, 1.0)[0])
    T_r = rig.duration
    T0 = 1.3 * T_r
    # guess: the rigid optimum stretched to T0 (reaches the rigid targets exactly, c = 0)
    mids = (np.arange(N) + 0.5) * T0 / N
    u_guess = rig.input()(mids * T_r / T0) * (T_r / T0) ** 2
    aug = np.zeros((n + m, n + m))
    aug[:n, :n], aug[:n, n:] = A, B
    E = expm(aug * T0 / N)
    xs = [x0]
    for uk in u_guess:
        xs.append(E[:n, :n] @ xs[-1] + E[:n, n:] @ uk)
    X_guess = np.array(xs).T
    scale = np.maximum(np.max(np.abs(X_guess), axis=1), 1e-6 * np.max(np.abs(x0)))
    opti = ca.Opti()
    T = opti.variable()
    Uv = opti.variable(m, N)
    Xs = opti.variable(n, N + 1)
    hs = ca.SX.sym("h")
    disc = ca.Function("disc", [hs], list(discretisation_casadi(model, hs)))
    Phi, Gam = disc(T / N)
    D = ca.diag(ca.DM(scale))
    Dinv = ca.diag(ca.DM(1.0 / scale))
    opti.minimize(T)
    for kk in range(N):
        opti.subject_to(Xs[:, kk + 1] == Dinv @ (Phi @ (D @ Xs[:, kk]) + Gam @ Uv[:, kk]))
    opti.subject_to(Xs[:, 0] == x0 / scale)
    opti.subject_to(Xs[:, N] == 0)
    for i in range(m):
        opti.subject_to(opti.bounded(-U[i], Uv[i, :], U[i]))
    opti.subject_to(opti.bounded(0.2 * T_r, T, 20.0 * T_r))
    opti.set_initial(T, T0)
    opti.set_initial(Uv, u_guess.T)
    opti.set_initial(Xs, X_guess / scale[:, None])
    opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "tol": 1e-10, "max_iter": 3000, "sb": "yes"})
    t0 = time.perf_counter()
    try:
        sol = opti.solve()
        ok = True
    except RuntimeError:
        sol = opti.debug
        ok = False
    wall = time.perf_counter() - t0
    stats = opti.stats()
    return {
        "T": float(sol.value(T)),
        "ok": ok and stats.get("success", False),
        "solve_s": float(stats.get("t_wall_total", wall)) if ok else wall,
    }


# ------------------------------------------------------------ Ruckig + shapers
def ruckig_shaped(problem, shaper_name: str | None):
    """Time-synchronised rigid-body profile per axis (Ruckig, infinite jerk), every input shaped for all modes.

    Gantry (``b0`` diagonal): axis ``j``'s acceleration is produced by its own
    drive.  One rigid body (chain): the acceleration is shared by the inputs
    in proportion to their reach ``|b0_i| u_max_i``.  Returns the command.
    """
    from ruckig import InputParameter, Ruckig, Trajectory

    model = problem.model
    k, U = model.k, problem.u_max
    B0 = model.B0
    if k == 1:
        share = np.sign(B0[0]) * U / float(np.abs(B0[0]) @ U)  # u = share * a
        amax = [float(np.abs(B0[0]) @ U)]
    else:
        share = None
        amax = [abs(B0[j, j]) * U[j] for j in range(k)]
    inp = InputParameter(k)
    inp.current_position = list(problem.x0[0 : 2 * k : 2])
    inp.target_position = [float(t) for t in problem.targets]
    inp.max_velocity = [1e6] * k
    inp.max_acceleration = amax
    inp.max_jerk = [math.inf] * k
    traj = Trajectory(k)
    Ruckig(k).calculate(inp, traj)
    cmds = []
    for prof in traj.profiles[0]:
        t = np.concatenate([[0.0], np.cumsum(prof.t)])
        keep = np.concatenate([[True], np.diff(t) > 0])
        br = t[keep]
        acc = np.array(prof.a[: t.size - 1])[np.diff(t) > 0]
        if br[-1] < traj.duration:
            br, acc = np.append(br, traj.duration), np.append(acc, 0.0)
        cmds.append(PiecewiseConstant(br, acc))
    inputs = []
    for i in range(model.m):
        if share is not None:
            u = PiecewiseConstant(cmds[0].breaks, cmds[0].levels * share[i])
        else:
            u = PiecewiseConstant(cmds[i].breaks, cmds[i].levels / B0[i, i])
        inputs.append(u)
    if shaper_name is not None:
        groups = model.mode_groups()
        sh = design(shaper_name, [model.omega[g[0]] for g in groups], [model.zeta[g[0]] for g in groups])
        inputs = [shape(u, sh) for u in inputs]
    T = max(u.duration for u in inputs)
    breaks = np.unique(np.concatenate([u.breaks for u in inputs]))
    mids = 0.5 * (breaks[:-1] + breaks[1:])
    rows = np.column_stack([u(mids) for u in inputs])
    return VectorPiecewise(breaks, rows), T


def residual(problem, u: VectorPiecewise, omega_scale: float = 1.0) -> float:
    """Largest modal amplitude after ``u`` on the model with every frequency scaled (modal coordinate)."""
    m0 = problem.model
    model = MultiModel(
        inputs=m0.inputs,
        rigid_bodies=m0.rigid_bodies,
        b0=m0.b0,
        c=m0.c,
        omega=tuple(w * omega_scale for w in m0.omega),
        zeta=m0.zeta,
        b=m0.b,
    )
    A, B = model.A(), model.B()
    xT = _exact.simulate(A, B, problem.x0, u, times=[u.duration])[0]
    k = model.k
    q, qd = xT[2 * k :: 2], xT[2 * k + 1 :: 2]
    w = np.asarray(model.omega)
    sig = w * np.asarray(model.zeta)
    return float(np.max(np.hypot(q, (qd + sig * q) / model.omega_d)))


# --------------------------------------------------------------------- main
def latency_table(args) -> None:
    head = (
        f"{'m':>2} {'N':>2} {'move m':>7} {'T* s':>9} {'cont wall ms':>12} {'p95':>6} {'cpu ms':>6} {'1-in ms':>7} {'cert':>4} "
        f"{'delta':>6} {'1kHz K':>6} {'1kHz wall':>9} {'cpu ms':>6} {'K-1':>3} "
        f"{'CasADi T s':>10} {'T-T* ms':>8} {'CasADi ms':>9} {'IPOPT':>5}"
    )
    print(head)
    print("-" * len(head))
    aims = []
    for m in (2, 3):
        for n in args.modes:
            built = chain_model(n, m)
            for tr in RIGID_TIMES:
                gamma = distance_for(built.model, built.u_max, tr)
                p = multi_rest_to_rest(built.model, built.u_max, [gamma])
                plan_multi_time_optimal(p)  # warm-up
                t_cont, c_cont, prof = timed(lambda pr=p: plan_multi_time_optimal(pr), args.repeats)
                # same-run reference: the single-input certified planner on the same chain, one force
                one = chain([0.5] * (n + 1), [400.0] * n, [0.4] * n, force_on=0).model
                p1 = rest_to_rest(one, 10.0, abs(one.b0) * 10.0 * tr**2 / 4.0)
                t_one, _ = timed_single(lambda pr=p1: plan_time_optimal(pr), args.repeats)
                reps = max(3, args.repeats // 4)
                t_zoh, c_zoh, sp = timed(
                    lambda pr=p: plan_multi_time_optimal_zoh(pr, RATE, plan_multi_time_optimal(pr)), reps
                )
                delta = (prof.duration - prof.certificate.lower_bound) / prof.duration
                row = (
                    f"{m:>2} {n:>2} {gamma:>7.4g} {prof.duration:>9.5f} {1e3 * np.median(t_cont):>12.2f} "
                    f"{1e3 * np.percentile(t_cont, 95):>6.1f} {1e3 * np.median(c_cont):>6.1f} {1e3 * np.median(t_one):>7.2f} "
                    f"{'yes' if prof.certified else 'NO':>4} {delta:>6.0e} "
                    f"{sp.samples:>6d} {1e3 * np.median(t_zoh):>9.1f} {1e3 * np.median(c_zoh):>6.1f} "
                    f"{'yes' if sp.minimal else 'no':>3} "
                )
                if not args.no_casadi:
                    cas = casadi_direct(p, args.casadi_n)
                    row += (
                        f"{cas['T']:>10.5f} {1e3 * (cas['T'] - prof.duration):>8.2f} {1e3 * cas['solve_s']:>9.0f} "
                        f"{'ok' if cas['ok'] else 'FAIL':>5}"
                    )
                print(row, flush=True)
                if m == 2 and n <= 4:
                    aims.append((float(np.median(t_cont)), float(np.median(c_cont))))
    print("-" * len(head))
    print(
        "aim: certified two-input plan, up to 4 modes, median < 20 ms: worst median "
        f"{1e3 * max(a[0] for a in aims):.1f} ms wall, {1e3 * max(a[1] for a in aims):.1f} ms CPU"
    )


def comparison_table() -> None:
    g = gantry(10.0, 40.0, 5.0, 2.0, trolley_force=30.0, bridge_force=50.0)
    c = chain_model(3, 2)
    cases = [
        ("gantry 3,2 m", multi_rest_to_rest(g.model, g.u_max, [3.0, 2.0])),
        ("gantry 8,1 m", multi_rest_to_rest(g.model, g.u_max, [8.0, 1.0])),
        ("chain N=3 0.2 m", multi_rest_to_rest(c.model, c.u_max, [0.2])),
    ]
    head = f"{'move':<16} {'profile':<26} {'duration s':>10} {'peak/u_max':>11} {'residual':>9} {'res. +10%':>9}"
    print(head)
    print("-" * len(head))
    for name, p in cases:
        rows = []
        prof = plan_multi_time_optimal(p)
        rows.append(("time-optimal (certified)", prof.input(), prof.duration))
        for sh in ("zv", "zvd"):
            r = plan_multi_move(p, sh)
            rows.append((f"rigid optimum + {sh} (ours)", r.continuous.input(), r.continuous.duration))
        for sh in (None, "zv", "zvd"):
            u, T = ruckig_shaped(p, sh)
            rows.append((f"Ruckig{' + ' + sh if sh else ''}", u, T))
        for label, u, T in rows:
            peak = float(np.max(np.abs(u.levels) / p.u_max))
            print(f"{name:<16} {label:<26} {T:>10.4f} {peak:>11.4f} {residual(p, u):>9.1e} {residual(p, u, 1.1):>9.1e}")
    print("-" * len(head))


def gantry_1khz(repeats: int) -> None:
    g = gantry(10.0, 40.0, 5.0, 2.0, trolley_force=30.0, bridge_force=50.0)
    head = (
        f"{'goal m':<12} {'T* s':>8} {'K':>6} {'minimal':>7} {'cont wall ms':>12} "
        f"{'1kHz total wall ms':>18} {'p95':>6} {'cpu ms':>6}"
    )
    print(head)
    print("-" * len(head))
    worst, worst_cpu = 0.0, 0.0
    for goal in ([12.5, 5.0], [6.0, 5.6], [12.0, 1.0]):
        p = multi_rest_to_rest(g.model, g.u_max, goal)
        t_c, _, prof = timed(lambda pr=p: plan_multi_time_optimal(pr), repeats)
        t_z, c_z, sp = timed(lambda pr=p: plan_multi_time_optimal_zoh(pr, RATE, plan_multi_time_optimal(pr)), repeats)
        worst, worst_cpu = max(worst, float(np.median(t_z))), max(worst_cpu, float(np.median(c_z)))
        print(
            f"{str(goal):<12} {prof.duration:>8.4f} {sp.samples:>6d} {'yes' if sp.minimal else 'no':>7} "
            f"{1e3 * np.median(t_c):>12.1f} {1e3 * np.median(t_z):>18.1f} {1e3 * np.percentile(t_z, 95):>6.1f} "
            f"{1e3 * np.median(c_z):>6.1f}"
        )
    print("-" * len(head))
    print(
        f"aim: 1 kHz plan of a 5 s two-axis move < 100 ms: worst median {1e3 * worst:.1f} ms wall, "
        f"{1e3 * worst_cpu:.1f} ms CPU"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=20, help="repeats per move for the latency statistics")
    ap.add_argument("--casadi-n", type=int, default=100, help="control intervals of the direct method")
    ap.add_argument("--modes", type=int, nargs="*", default=list(MODES))
    ap.add_argument("--no-casadi", action="store_true")
    args = ap.parse_args()
    print(
        f"# flexmotion multi-input planning (issue 12): python {platform.python_version()}, numpy {np.__version__}, "
        f"{os.cpu_count()} CPU(s), load {os.getloadavg()[0]:.1f}; {args.repeats} cold repeats; CasADi N = {args.casadi_n}"
    )
    print("\n## 1. latency: chains of N+1 masses, m forces, rest-to-rest (rigid time 1 s and 5 s)")
    latency_table(args)
    print("\n## 2. against Ruckig (time-synchronised rigid profile per axis) shaped by ZV / ZVD on every mode")
    comparison_table()
    print("\n## 3. 1 kHz plans of 5 s two-axis gantry moves")
    gantry_1khz(max(5, args.repeats // 2))


if __name__ == "__main__":
    main()
