"""Planning time and added move time of ``time_optimal_friction`` and ``fixed_time`` at 1 kHz.

Cases (about 5 s moves): the Wie-Bernstein benchmark (m1 = m2 = k = 1, |u| <= 1 N) moving 2.0 m
(T* = 5.03 s), and the overhead crane of ``config/crane.yaml`` (|u| <= 50 N) moving 8.0 m.
For each case the time-optimal reference, then Coulomb friction on the rigid body at several
forces (continuous extremal + exact ZOH sequence), then fixed arrival times (continuous least-peak
move + ZOH at exactly round(T_req * rate) samples).  Every profile is checked by the planners on the
exact simulation (matrix exponentials; with friction the event-located piecewise simulation).

    python bench/friction_fixed_time.py
    python bench/friction_fixed_time.py --rate 250 --repeat 3

OpenBLAS threads are set to 1 before numpy loads (tiny matrices: threading only costs).
"""

from __future__ import annotations

import argparse
import os
import time


def _args() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rate", type=float, default=1000.0, help="command rate (Hz)")
    p.add_argument("--repeat", type=int, default=1, help="repeat each plan, report the fastest")
    p.add_argument(
        "--clock",
        choices=("wall", "cpu"),
        default="wall",
        help="wall time, or this process's CPU time (loaded machines)",
    )
    return p.parse_args()


ARGS = _args()
for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import numpy as np

from flexmotion_ros.core import (
    ModalModel,
    load_config,
    plan_time_optimal,
    plan_time_optimal_zoh,
    rest_to_rest,
)
from flexmotion_ros.core.errors import SolverError
from flexmotion_ros.core.friction.time_optimal import plan_time_optimal_friction
from flexmotion_ros.core.friction.zoh import plan_time_optimal_friction_zoh
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.sampled.fixed_time import plan_fixed_time_zoh
from flexmotion_ros.core.time_optimal.fixed_time import plan_fixed_time

CLOCK = time.process_time if ARGS.clock == "cpu" else time.perf_counter


def timed(fn, *args):
    best, out = float("inf"), None
    for _ in range(ARGS.repeat):
        t0 = CLOCK()
        out = fn(*args)
        best = min(best, CLOCK() - t0)
    return out, best * 1e3


def main() -> None:
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    crane = load_config(os.path.join(root, "config", "crane.yaml"))
    wb = ModalModel(b0=0.5, omega=[2**0.5], zeta=[0.0], b=[1.0])
    cases = [
        ("wie-bernstein 2 m", rest_to_rest(wb, 1.0, 2.0), [0.05, 0.1, 0.2, 0.3]),
        ("crane 8 m", rest_to_rest(crane.model, crane.u_max, 8.0), [2.5, 5.0, 10.0, 20.0]),
    ]
    rate, dt = ARGS.rate, 1.0 / ARGS.rate
    print(
        f"rate {rate:g} Hz, load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs, best of {ARGS.repeat}, "
        f"{ARGS.clock} clock"
    )
    head = (
        f"{'case':18s} {'method':22s} {'option':>12s} {'T (s)':>10s} {'+T (s)':>9s} {'cert':>5s} "
        f"{'samples':>8s} {'+samp (s)':>9s} {'peak |u|':>9s} {'cont ms':>8s} {'ZOH ms':>8s}"
    )
    print(head)
    print("-" * len(head))
    for name, problem, forces in cases:
        best, t_c = timed(plan_time_optimal, problem)
        zoh, t_z = timed(plan_time_optimal_zoh, problem, rate, best)
        T0, K0 = best.duration, zoh.samples
        um = problem.u_max
        print(
            f"{name:18s} {'time_optimal':22s} {'-':>12s} {T0:10.6f} {0.0:9.6f} {best.certified!s:>5s} "
            f"{K0:8d} {0.0:9.3f} {np.max(np.abs(zoh.commands)):9.4g} {t_c:8.1f} {t_z:8.1f}"
        )
        for F in forces:
            try:
                prof, t_c = timed(plan_time_optimal_friction, problem, F)
                sp, t_z = timed(plan_time_optimal_friction_zoh, problem, F, rate, prof)
            except SolverError as exc:
                print(f"{name:18s} {'time_optimal_friction':22s} {F:10.3g} N  failed: {exc}")
                continue
            print(
                f"{name:18s} {'time_optimal_friction':22s} {F:10.3g} N {prof.duration:10.6f} {prof.duration - T0:9.6f} "
                f"{prof.certified!s:>5s} {sp.samples:8d} {(sp.samples - K0) * dt:9.3f} "
                f"{np.max(np.abs(sp.commands)):9.4g} {t_c:8.1f} {t_z:8.1f}"
            )
        for factor in (1.1, 1.5, 2.0):
            T_req = factor * T0
            prof, t_c = timed(plan_fixed_time, problem, T_req)
            sp, t_z = timed(plan_fixed_time_zoh, problem, T_req, rate, prof)
            print(
                f"{name:18s} {'fixed_time':22s} {T_req:10.4f} s {prof.duration:10.6f} {prof.duration - T0:9.6f} "
                f"{prof.certified!s:>5s} {sp.samples:8d} {(sp.samples - K0) * dt:9.3f} "
                f"{np.max(np.abs(sp.commands)) / um:9.4g} {t_c:8.1f} {t_z:8.1f}"
            )
    # the shipped example through the method table, as the node and the CLI plan it
    cfg = load_config(os.path.join(root, "config", "friction_example.yaml"))
    ex = rest_to_rest(cfg.model, cfg.u_max, 1.0)
    res, t_pm = timed(plan_move, cfg, ex, rate)
    status = res.info.get("friction_status", "certified" if res.continuous.certified else "not certified")
    print(
        f"\nconfig/friction_example.yaml, goal 1.0, plan_move at {rate:g} Hz: {t_pm:.1f} ms "
        f"(continuous {res.continuous.duration:.6f} s, {status}; {res.sampled.samples} samples)"
    )
    print()
    print("+T: added time over the time-optimal move; +samp: added samples x dt over the time-optimal ZOH;")
    print("peak |u|: friction rows in N, fixed_time rows as a fraction of u_max (the least peak);")
    print("cert: friction = proved Pontryagin extremal of the piecewise system; fixed_time = certified")
    print("time-optimal for the bound used (so that bound is the lowest).")


if __name__ == "__main__":
    main()
