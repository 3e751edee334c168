"""Planning time of the ``min_fuel`` and ``limited`` methods, and the move time each limit costs.

Wie-Bernstein benchmark (m1 = m2 = k = 1, |u| <= 1 N) moving ``--goal`` (default 2.0 m: T* = 5.03 s)
at ``--rate`` (default 1000 Hz).  Every figure is checked on the exact matrix-exponential
simulation by the planners themselves (a profile that misses is never returned).

Tables:

1. reference: the time-optimal bang-bang and its zero-order-hold optimum;
2. minimum fuel at ``--fuel-factor`` x T* (default 1.2): continuous bang-off-bang (dual Newton),
   sampled LP with windows from the continuous co-state, and the full LP without windows;
   the fuel/time curve (9 points, T* .. 2 T*);
3. limits (each alone, then all together): velocity ``--v-frac`` x the unlimited peak,
   deflection ``--q-frac`` x the unlimited peak, slew ``--slew`` N/s: samples, added time,
   proved fewest, LP solves, planning time.

Planning times are CPU time of this process (``time.process_time``, ``--clock cpu``, the default: the
machine is shared) or wall time (``--clock wall``); the header says which, with the load average.
``FLEXMOTION_TREE=<checkout>`` plans with the package of another checkout (an A/B of two trees with
the same bench, e.g. ``FLEXMOTION_TREE=/work/main``).

    python bench/fuel_limits.py
    python bench/fuel_limits.py --rate 250 --goal 1.0
    python bench/fuel_limits.py --limits-only --repeat 3
    python bench/fuel_limits.py --limits-only --only all --repeat 7
"""

from __future__ import annotations

import argparse
import os
import sys
import time


def _args() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--goal", type=float, default=2.0)
    p.add_argument("--rate", type=float, default=1000.0)
    p.add_argument("--fuel-factor", type=float, default=1.2, dest="fuel_factor")
    p.add_argument("--v-frac", type=float, default=0.8, dest="v_frac")
    p.add_argument("--q-frac", type=float, default=0.6, dest="q_frac")
    p.add_argument("--slew", type=float, default=10.0)
    p.add_argument("--skip-limits", action="store_true", dest="skip_limits")
    p.add_argument("--limits-only", action="store_true", dest="limits_only", help="table 3 only")
    p.add_argument(
        "--only",
        choices=("velocity", "deflection", "slew", "all"),
        action="append",
        help="table 3: only these rows (repeatable; 'all': all three limits together)",
    )
    p.add_argument("--repeat", type=int, default=1, help="plan each limited case this many times (median)")
    p.add_argument(
        "--budget", type=float, default=None, help="the limited planner's wall-clock budget (s; default its own)"
    )
    p.add_argument("--clock", choices=("cpu", "wall"), default="cpu", help="planning time: process CPU or wall")
    p.add_argument("--blas-threads", type=int, default=1, dest="blas", help="OpenBLAS threads (0: library default)")
    return p.parse_args()


ARGS = _args()
if ARGS.blas > 0:  # tiny matrices: BLAS threads only cost, and the machine is shared
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(ARGS.blas)

import numpy as np

TREE = os.environ.get("FLEXMOTION_TREE") or os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path.insert(0, TREE)
from flexmotion_ros.core import (
    ModalModel,
    plan_time_optimal,
    plan_time_optimal_zoh,
    rest_to_rest,
)
from flexmotion_ros.core.constraints import planner as limited_planner
from flexmotion_ros.core.constraints.limits import Limits
from flexmotion_ros.core.constraints.planner import plan_limited_zoh
from flexmotion_ros.core.errors import FlexmotionError
from flexmotion_ros.core.fuel.curve import fuel_time_curve
from flexmotion_ros.core.fuel.lp import plan_min_fuel_zoh
from flexmotion_ros.core.fuel.min_fuel import plan_min_fuel

CLOCK = time.process_time if ARGS.clock == "cpu" else time.perf_counter


def timed(f, *a, **k):
    t = CLOCK()
    out = f(*a, **k)
    return out, CLOCK() - t


def row(cols, widths):
    return "  ".join(str(c).ljust(w) for c, w in zip(cols, widths))


def main() -> None:
    model = ModalModel(b0=0.5, c=0.0, omega=[2**0.5], zeta=[0.0], b=[1.0])
    problem = rest_to_rest(model, 1.0, ARGS.goal)
    rate = ARGS.rate
    print(f"Wie-Bernstein, goal {ARGS.goal} m, u_max 1 N, rate {rate:g} Hz")
    print(f"# tree {os.path.abspath(TREE)}, {ARGS.clock} clock, load average {os.getloadavg()[0]:.1f}")
    to, t_to = timed(plan_time_optimal, problem)
    z, t_z = timed(plan_time_optimal_zoh, problem, rate, to)
    print(
        f"\n1. reference: T* = {to.duration:.6f} s ({t_to * 1e3:.0f} ms), ZOH {z.samples} samples "
        f"({z.duration:.3f} s, {t_z * 1e3:.0f} ms, fewest proved: {z.minimal})"
    )

    if not ARGS.limits_only:
        _fuel(problem, rate, to)
    if not ARGS.skip_limits:
        _limits(problem, rate, z)


def _fuel(problem, rate, to) -> None:
    T = ARGS.fuel_factor * to.duration
    cont, t_c = timed(plan_min_fuel, problem, T, to)
    win, t_w = timed(plan_min_fuel_zoh, problem, rate, T, to, nu_guess=cont.costate)
    full, t_f = timed(plan_min_fuel_zoh, problem, rate, T, to)
    curve, t_cv = timed(fuel_time_curve, problem, 2.0 * to.duration, 9, None, to)
    w = [34, 14, 14, 12, 10]
    print(
        f"\n2. minimum fuel, move time {T:.4f} s = {ARGS.fuel_factor} T* (time-optimal fuel u_max T* = {to.duration:.4f} N s)"
    )
    print(row(["planner", "fuel (N s)", "gap (N s)", "LP vars", "time (ms)"], w))
    print(
        row(
            [
                "continuous bang-off-bang",
                f"{cont.fuel:.6f}",
                f"{cont.fuel - cont.fuel_lower_bound:.1e}",
                "-",
                f"{t_c * 1e3:.0f}",
            ],
            w,
        )
    )
    for name, s, t in (("sampled LP, windows from co-state", win, t_w), ("sampled LP, all samples free", full, t_f)):
        gap = s.extra["fuel"] - s.extra["fuel_lower_bound"]
        print(row([name, f"{s.extra['fuel']:.6f}", f"{gap:.1e}", 2 * s.extra["lp_free_samples"], f"{t * 1e3:.0f}"], w))
    print(
        f"fuel/time curve, 9 points T*..2T*: {t_cv * 1e3:.0f} ms; fuel = "
        + ", ".join(f"{f:.3f}" for f in curve.fuel)
        + " N s at T = "
        + ", ".join(f"{x:.2f}" for x in curve.move_times)
        + " s"
    )


def _limits(problem, rate, z) -> None:
    if ARGS.budget is not None:  # a loaded machine can pass the wall-clock budget on CPU seconds of work
        limited_planner.TIME_BUDGET_S = ARGS.budget
    peak_v = float(np.max(np.abs(z.states[:, 1])))
    peak_q = float(np.max(np.abs(z.states[:, 2])))
    both = Limits(ARGS.v_frac * peak_v, (ARGS.q_frac * peak_q,), ARGS.slew)
    print(f"\n3. limits (unlimited ZOH peaks: |v| {peak_v:.4f} m/s, |q| {peak_q:.4f} m; slew unlimited)")
    w = [34, 8, 11, 8, 6, 6, 10, 44]
    print(row(["limit", "samples", "added (s)", "fewest", "LPs", "cuts", "time (s)", "proof of K-1 infeasible"], w))
    cases = [
        (f"velocity_max {both.velocity_max:.4f} m/s", both.only("velocity_max")),
        (f"deflection_max {both.deflection_max[0]:.4f} m", both.only("deflection_max")),
        (f"slew_rate {ARGS.slew:g} N/s", both.only("slew_rate")),
        ("all three", both),
    ]
    keys = ("velocity", "deflection", "slew", "all")
    for key, (name, lim) in zip(keys, cases):
        if ARGS.only and key not in ARGS.only:
            continue
        try:
            runs = [timed(plan_limited_zoh, problem, rate, lim, z) for _ in range(max(ARGS.repeat, 1))]
        except FlexmotionError as exc:  # a refusal or an honest failure is a row too
            print(row([name, "-", "-", "-", "-", "-", "-", f"{type(exc).__name__}: {exc}"], w), flush=True)
            continue
        r = runs[0][0]
        t = float(np.median([x[1] for x in runs]))
        print(
            row(
                [
                    name,
                    r.sampled.samples,
                    f"{r.added_time_s:.3f}",
                    "proved" if r.minimal else f">={r.lower_bound_samples}",
                    r.lp_solves,
                    r.cuts,
                    f"{t:.2f}",
                    r.extra["lower_bound_proof"],
                ],
                w,
            ),
            flush=True,
        )

    print(f"# load average after the table: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
