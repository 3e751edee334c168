"""Time-optimal, robust time-optimal and input-shaped moves side by side, with a Ruckig baseline.

For each model (Wie-Bernstein benchmark, 3-mode flexible beam) and move, in one run:

* ``time_optimal`` and ``robust_time_optimal`` (order 1; ``--robust-orders``);
* the rigid-body time-optimal bang-bang shaped by ZV, ZVD, EI, UM-ZV, UM-ZVD (``plan_move``);
* a jerk-limited rigid move from Ruckig (PyPI ``ruckig``), unshaped and shaped the same way:
  ``a_max = |b0| u_max``, ``v_max = sqrt(gamma a_max)`` (the bang-bang's peak velocity),
  ``j_max = a_max / (Td_1 / 4)`` (acceleration ramps over a quarter period of the first mode).
  The force is ``u = a / b0`` (``c = 0``): piecewise linear, so it is simulated exactly with the
  input as an extra state driven by the (piecewise-constant) jerk.  For shapers with negative
  impulses ``a_max`` is lowered until the shaped force stays within ``u_max``.

Every figure comes from the exact matrix-exponential simulation (``core.simulation``): duration,
peak command, residual vibration at the nominal model and with every modal frequency scaled by
0.9 and 1.1, and the worst over 21 ratios in [0.9, 1.1].  Residual vibration is in percent of what
a step of ``u_max`` leaves (worst mode).

    python bench/shaping_comparison.py
    python bench/shaping_comparison.py --goals 1.0 0.05 --robust-orders 1 2
"""

from __future__ import annotations

import argparse
import os
import sys
import time


def _args() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--goals", type=float, nargs=2, default=[1.0, 0.05], help="move for the benchmark and for the beam")
    p.add_argument("--robust-orders", type=int, nargs="*", default=[1], dest="orders")
    p.add_argument("--error", type=float, default=0.1, help="relative frequency error (default 0.1)")
    p.add_argument("--blas-threads", type=int, default=1, dest="blas", help="OpenBLAS threads (0: library default)")
    return p.parse_args()


ARGS = _args()
if ARGS.blas > 0:  # tiny matrices: BLAS threads only cost, and the machine is shared
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(ARGS.blas)

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Trajectory

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from flexmotion_ros.core import load_config, rest_to_rest, simulate
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.shaping.shaped_profile import largest_level, shape
from flexmotion_ros.core.shaping.shapers import design
from flexmotion_ros.core.simulation.exact import PiecewiseConstant, modal_amplitudes

SHAPERS = ["zv", "zvd", "ei", "um_zv", "um_zvd"]


def ruckig_jerk(gamma: float, a_max: float, v_max: float, j_max: float) -> PiecewiseConstant:
    """Ruckig's time-optimal jerk-limited rest-to-rest move of ``gamma``: its jerk, piecewise constant."""
    inp = InputParameter(1)
    inp.current_position, inp.target_position = [0.0], [gamma]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [v_max], [a_max], [j_max]
    traj = Trajectory(1)
    if Ruckig(1).calculate(inp, traj) not in (Result.Working, Result.Finished):
        raise RuntimeError("ruckig failed")
    prof = traj.profiles[0][0]
    t = np.array(prof.t, dtype=float)
    keep = t > 0.0
    return PiecewiseConstant(np.concatenate([[0.0], np.cumsum(t[keep])]), np.array(prof.j, dtype=float)[keep])


def jerk_system(model):
    """Model + input as a state: x' = A x + B u, u' = jerk / b0."""
    A, B = model.A(), model.B()
    n = A.shape[0]
    Ae = np.zeros((n + 1, n + 1))
    Ae[:n, :n], Ae[:n, n] = A, B
    Be = np.zeros(n + 1)
    Be[n] = 1.0 / model.b0
    return Ae, Be


def force_at_breaks(jerk: PiecewiseConstant, b0: float) -> np.ndarray:
    """u = a / b0 at the breaks of the jerk (a piecewise linear: its extremes are there)."""
    return np.concatenate([[0.0], np.cumsum(jerk.levels * np.diff(jerk.breaks))]) / b0


class Move:
    """A command to evaluate: piecewise-constant force, or piecewise-constant jerk (Ruckig)."""

    def __init__(self, name, u=None, jerk=None, plan_time=0.0, note=""):
        self.name, self.u, self.jerk, self.plan_time, self.note = name, u, jerk, plan_time, note

    @property
    def duration(self):
        return (self.u or self.jerk).duration

    def final(self, model, x0):
        if self.u is not None:
            return simulate(model, x0, self.u, times=[self.u.duration])[0]
        Ae, Be = jerk_system(model)
        return simulate((Ae, Be), np.append(x0, 0.0), self.jerk, times=[self.jerk.duration])[0][:-1]

    def peak(self, b0):
        return self.u.max_abs() if self.u is not None else float(np.max(np.abs(force_at_breaks(self.jerk, b0))))


def evaluate(move: Move, model, pb, T_star, err):
    w, z, b = (np.asarray(v, dtype=float) for v in (model.omega, model.zeta, model.b))

    def resid(r):
        m = model.with_changes(omega=tuple(w * r))
        x = move.final(m, pb.x0)
        step = np.abs(b) * pb.u_max / ((w * r) ** 2 * np.sqrt(1 - z * z))
        return float(np.max(100.0 * modal_amplitudes(m, x) / step)), x

    nominal, x = resid(1.0)
    rigid_err = abs(x[0] - pb.target) + abs(x[1])
    band = [resid(r)[0] for r in np.linspace(1 - err, 1 + err, 21)]
    return {
        "method": move.name,
        "T": move.duration,
        "added": move.duration - T_star,
        "peak": move.peak(model.b0),
        "nominal": nominal,
        "lo": resid(1 - err)[0],
        "hi": resid(1 + err)[0],
        "worst": max(band),
        "rigid_err": rigid_err,
        "plan_ms": 1e3 * move.plan_time,
        "note": move.note,
    }


def ruckig_moves(model, pb, gamma):
    um = pb.u_max
    a_max = abs(model.b0) * um
    td1 = 2 * np.pi / model.omega_d[0]
    j_max = a_max / (td1 / 4.0)
    out = []
    t0 = time.perf_counter()
    jerk = ruckig_jerk(gamma, a_max, np.sqrt(abs(gamma) * a_max), j_max)
    out.append(Move("ruckig", jerk=jerk, plan_time=time.perf_counter() - t0, note=f"j_max={j_max:.4g}"))
    for name in SHAPERS:
        t0 = time.perf_counter()
        s = design(name, model.omega, model.zeta)

        def shaped_at(a, s=s):  # negative shapers: the largest acceleration whose shaped force fits
            jk = shape(ruckig_jerk(gamma, a, np.sqrt(abs(gamma) * a), j_max), s)
            return float(np.max(np.abs(force_at_breaks(jk, model.b0)))) * abs(model.b0), jk

        a, shaped = largest_level(shaped_at, a_max, a_max / s.abs_sum)
        note = "" if a == a_max else f"a_max lowered to {a / a_max:.3f}x"
        out.append(Move(f"ruckig+{name}", jerk=shaped, plan_time=time.perf_counter() - t0, note=note))
    return out


def run_case(title, cfg, gamma, orders, err):
    model = cfg.model
    pb = rest_to_rest(model, cfg.u_max, gamma)
    moves = []
    t_star = None
    for method in ["time_optimal"] + [f"robust_time_optimal:{k}" for k in orders] + SHAPERS:
        name, _, k = method.partition(":")
        c = cfg.with_changes(method=name, options={**cfg.options, "robust_order": int(k)} if k else cfg.options)
        t0 = time.perf_counter()
        r = plan_move(c, pb)
        dt = time.perf_counter() - t0
        label = f"robust_time_optimal (order {k})" if k else name
        note = ""
        if k:
            note = f"{len(r.continuous.switch_times)} switches, certified={r.continuous.certified}"
        elif name == "time_optimal":
            t_star = r.continuous.duration
            note = f"{len(r.continuous.switch_times)} switches, certified={r.continuous.certified}"
        elif r.info.get("rigid_level", cfg.u_max) < cfg.u_max:
            note = f"rigid level lowered to {r.info['rigid_level'] / cfg.u_max:.3f} u_max"
        moves.append(Move(label, u=r.continuous.input(), plan_time=dt, note=note))
    moves += ruckig_moves(model, pb, gamma)
    rows = [evaluate(m, model, pb, t_star, err) for m in moves]
    print(f"\n{title}: goal {gamma:g}, u_max {cfg.u_max:g}, omega {', '.join(f'{w:.4g}' for w in model.omega)} rad/s")
    e = 100 * err
    print(
        f"{'method':32s} {'T (s)':>9s} {'added':>8s} {'peak|u|':>8s} {'resid %':>9s} "
        f"{f'-{e:g}%':>8s} {f'+{e:g}%':>8s} {'worst':>8s} {'rigid err':>9s} {'plan ms':>8s}  note"
    )
    for r in rows:
        print(
            f"{r['method']:32s} {r['T']:9.5f} {r['added']:8.4f} {r['peak']:8.4g} {r['nominal']:9.2e} "
            f"{r['lo']:8.3f} {r['hi']:8.3f} {r['worst']:8.3f} {r['rigid_err']:9.1e} {r['plan_ms']:8.1f}  {r['note']}"
        )
    return rows


def main() -> None:
    here = os.path.join(os.path.dirname(__file__), "..", "config")
    print(
        "residual vibration: % of a step of u_max, worst mode, exact simulation; "
        f"+/-{100 * ARGS.error:g}%: every modal frequency scaled; worst: 21 ratios in the band"
    )
    t0 = time.perf_counter()
    run_case(
        "Wie-Bernstein benchmark",
        load_config(os.path.join(here, "wie_bernstein.yaml")),
        ARGS.goals[0],
        ARGS.orders,
        ARGS.error,
    )
    run_case(
        "3-mode flexible beam",
        load_config(os.path.join(here, "flexible_beam_3mode.yaml")),
        ARGS.goals[1],
        ARGS.orders,
        ARGS.error,
    )
    print(f"\ntotal {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
