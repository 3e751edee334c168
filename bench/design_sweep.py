"""Time of a 200-point structure-design sweep with certified time-optimal solves.

Each point builds the physical model, plans the move with ``plan_move``
(certified time-optimal: solve + exact-simulation check + Pontryagin
certificate) and counts it only if certified.  Prints one table row per case:
total wall time, per-solve latency (mean / median / p95 / max), failures.

    python bench/design_sweep.py                   # all cases, 1 process
    python bench/design_sweep.py --workers 2       # grid in 2 processes
    python bench/design_sweep.py --cases k_regular --points 200
    python bench/design_sweep.py --cases k_regular --profile   # where the time goes

OpenBLAS threads are set to 1 before numpy loads (tiny matrices: threading
only costs); ``--blas-threads 0`` leaves the library default to compare.
"""

from __future__ import annotations

import argparse
import os
import sys
import time


def _args() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--points", type=int, default=200, help="design points per case")
    p.add_argument("--workers", type=int, default=1, help="processes for the sweep")
    p.add_argument("--cases", nargs="*", default=None, help="subset of cases (default: all)")
    p.add_argument("--profile", action="store_true", help="also profile part of the first case")
    p.add_argument("--blas-threads", type=int, default=1, dest="blas", help="OpenBLAS threads (0: library default)")
    return p.parse_args()


ARGS = _args()
if ARGS.blas > 0:
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(ARGS.blas)

import numpy as np

from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.design.problem import DesignObjective, DesignProblem, Task
from flexmotion_ros.core.design.space import DesignParameter
from flexmotion_ros.core.model.builders import two_mass


def _cpu() -> float:
    """CPU time of this process and its finished children (s): the load-independent cost."""
    import resource

    ch = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + ch.ru_utime + ch.ru_stime


def cases(n: int) -> dict[str, tuple[DesignProblem, list[tuple[float, ...]]]]:
    cfg = PlannerConfig(model=two_mass(1.0, 1.0, 1.0).model)
    crane_cfg = cfg.with_changes(u_max=50.0)
    out = {}

    def one(name, builder, base, param, lo, hi, goal, config):
        p = DesignParameter(param, lo, hi)
        pb = DesignProblem(builder, base, (p,), (Task(goal),), config)
        q = pb.parameters[0]
        out[name] = (pb, [(q.from_unit(u),) for u in np.linspace(0.0, 1.0, n)])

    tm = {"m1": 1.0, "m2": 1.0, "k": 1.0}
    one("k_regular", "two_mass", tm, "k", 0.5, 8.0, 1.0, cfg)  # below the zero-vibration stiffness pi^2
    one("k_across_zero_vib", "two_mass", tm, "k", 0.5, 20.0, 1.0, cfg)  # crosses k = pi^2 (degenerate optimum)
    one("chain3_spring", "chain", {"masses": [1.0, 1.0, 1.0], "springs": [1.0, 1.0]}, "springs[1]", 0.5, 4.0, 1.0, cfg)
    crane = {"cart_mass": 20.0, "payload_mass": 5.0, "cable_length": 2.0, "zeta": 0.005}
    pb = DesignProblem(
        "crane",
        crane,
        (DesignParameter("cable_length", 0.5, 3.0), DesignParameter("payload_mass", 2.0, 8.0)),
        (Task(2.0),),
        crane_cfg,
    )
    nx = max(2, round(np.sqrt(n / 2.0)))
    ny = max(2, n // nx)
    pts = [
        (pb.parameters[0].from_unit(a), pb.parameters[1].from_unit(b))
        for a in np.linspace(0, 1, nx)
        for b in np.linspace(0, 1, ny)
    ]
    out[f"crane_{nx}x{ny}"] = (pb, pts)
    return out


def main() -> int:
    todo = cases(ARGS.points)
    if ARGS.cases:
        todo = {k: v for k, v in todo.items() if any(k.startswith(c) for c in ARGS.cases)}
    blas = os.environ.get("OPENBLAS_NUM_THREADS", "default")
    print(
        f"# design sweep: {ARGS.points} points/case, workers={ARGS.workers}, OpenBLAS threads={blas}, "
        f"cpus={os.cpu_count()}, load avg={os.getloadavg()[0]:.2f}"
    )
    print(
        "| case | points | certified | failed | wall (s) | CPU (s) | per point wall mean / median / p95 / max (ms) | repeat (cached, s) |"
    )
    print("| --- | ---: | ---: | ---: | ---: | ---: | --- | ---: |")
    for name, (pb, pts) in todo.items():
        f = DesignObjective(pb)
        f(pts[0])  # warm-up: imports, caches (not counted)
        f.cache.clear()
        f.order.clear()
        t0, c0 = time.perf_counter(), _cpu()
        evs = f.many(pts, ARGS.workers)
        wall, cpu = time.perf_counter() - t0, _cpu() - c0
        t1 = time.perf_counter()
        f.many(pts, ARGS.workers)
        again = time.perf_counter() - t1
        lat = np.array([e.solve_time_s for e in evs]) * 1e3
        ok = sum(1 for e in evs if e.feasible and e.certified)
        print(
            f"| {name} | {len(evs)} | {ok} | {len(evs) - ok} | {wall:.2f} | {cpu:.2f} | "
            f"{lat.mean():.1f} / {np.median(lat):.1f} / {np.percentile(lat, 95):.1f} / {lat.max():.1f} | {again:.4f} |"
        )
        for e in evs:
            if not (e.feasible and e.certified):
                print(f"|   failed at {dict(zip(pb.names, e.values))}: {e.status[:100]} | | | | | | | |")
        sys.stdout.flush()
    if ARGS.profile:
        import cProfile
        import pstats

        name, (pb, pts) = next(iter(todo.items()))
        f = DesignObjective(pb)
        prof = cProfile.Profile()
        prof.runcall(f.many, pts[:: max(1, len(pts) // 40)])
        print(f"\n# where a sweep's time goes ({name}, every {max(1, len(pts) // 40)}th point; cumulative s)")
        pstats.Stats(prof, stream=sys.stdout).sort_stats("cumulative").print_stats(18)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
