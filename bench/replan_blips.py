#!/usr/bin/env python3
"""Cold vs warm-started replans from a state on a nominal optimum: does the cold planner add a blip?

Samples as ``test/core/time_optimal/test_warm_start.py``'s ``replans`` strategy
(seeded, case ``i`` = ``numpy.random.default_rng(i)``): a 1-3 mode model
(omega log-uniform 0.3..30 rad/s, neighbours 1.05..4x apart, undamped or
zeta in 0..0.3, b and b0 of magnitude 0.1..10, friction for half), u_max
log-uniform 0.1..10, a rest-to-rest nominal optimum of 1e-2..1e2 natural
distances, a state on it at 5..95 % of its duration, disturbed by 0, 1e-6,
1e-3, 1e-2 or 1e-1 of each coordinate's excursion.  Plans it cold and with
the warm start (the rest of the nominal plan) and prints every case where
the two differ in switch count or duration (relative > 1e-9), where either is not
certified ``OPTIMAL``, or where the sign margin is below 1e-6, with both
certificates' status.  The last line
counts them.

Usage::

    OPENBLAS_NUM_THREADS=1 python bench/replan_blips.py --first 0 --cases 300
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import math

import numpy as np

from flexmotion_ros.core import ModalModel, plan_time_optimal, rest_to_rest, state_to_rest
from flexmotion_ros.core.errors import SolverError
from flexmotion_ros.core.results import CertificateStatus
from flexmotion_ros.core.simulation.exact import PiecewiseConstant, simulate
from flexmotion_ros.core.time_optimal.warm_start import remainder


def state_on(profile, t: float) -> np.ndarray:
    u = PiecewiseConstant.from_switches(profile.switch_times, profile.levels, profile.duration)
    return simulate(profile.problem.model, profile.problem.x0, u, times=[t])[0]


def log_uniform(r, lo: float, hi: float) -> float:
    return 10 ** r.uniform(math.log10(lo), math.log10(hi))


def sign(r) -> float:
    return float(r.choice([1.0, -1.0]))


def model(r) -> ModalModel:
    n = int(r.integers(1, 4))
    w = [log_uniform(r, 0.3, 30.0)]
    for _ in range(n - 1):
        w.append(w[-1] * r.uniform(1.05, 4.0))
    undamped = r.random() < 0.5
    zeta = [0.0 if undamped else r.uniform(0.0, 0.3) for _ in w]
    b = [sign(r) * log_uniform(r, 0.1, 10.0) for _ in w]
    b0 = sign(r) * log_uniform(r, 0.1, 10.0)
    c = -w[0] * log_uniform(r, 1e-2, 3.0) if r.random() < 0.5 else 0.0
    return ModalModel(b0=b0, c=c, omega=tuple(w), zeta=tuple(zeta), b=tuple(b))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("--cases", type=int, default=300)
    args = ap.parse_args()
    differ = blips = planned = not_optimal = 0
    for seed in range(args.first, args.first + args.cases):
        r = np.random.default_rng(seed)
        m, um, size = model(r), log_uniform(r, 0.1, 10.0), log_uniform(r, 1e-2, 1e2)
        target = sign(r) * m.natural_distance(um) * size
        try:
            nominal = plan_time_optimal(rest_to_rest(m, um, target))
        except SolverError:
            continue
        t = r.uniform(0.05, 0.95) * nominal.duration
        x = state_on(nominal, t)
        eps = r.choice([0.0, 1e-6, 1e-3, 1e-2, 1e-1])
        scale = np.max(np.abs([state_on(nominal, s) for s in np.linspace(0.0, nominal.duration, 9)]), axis=0)
        units = np.where(r.random(x.size) < 0.3, 0.0, r.choice([1.0, -1.0], x.size) * r.uniform(0.1, 1.0, x.size))
        problem = state_to_rest(m, um, x + eps * scale * units, target)
        try:
            cold = plan_time_optimal(problem)
            warm = plan_time_optimal(problem, remainder(nominal, t))
        except SolverError:
            continue
        planned += 1
        dT = (cold.duration - warm.duration) / warm.duration
        other = cold.switch_times.size != warm.switch_times.size or abs(dT) > 1e-9
        differ += other
        blips += other and cold.switch_times.size > warm.switch_times.size
        weak = (
            cold.certificate.status != CertificateStatus.OPTIMAL or warm.certificate.status != CertificateStatus.OPTIMAL
        )
        not_optimal += weak
        if other or weak or cold.certificate.min_margin < 1e-6:
            print(
                f"seed={seed} modes={len(m.omega)} eps={eps:g} switches cold {cold.switch_times.size} "
                f"warm {warm.switch_times.size} dT/T={dT:.2e} margin cold {cold.certificate.min_margin:.1e} "
                f"warm {warm.certificate.min_margin:.1e} status cold {cold.certificate.status} "
                f"warm {warm.certificate.status} path {cold.extra.get('solver_path')}"
            )
    print(
        f"# {planned} replans: {differ} differ, {blips} with more switches cold than warm, "
        f"{not_optimal} not certified OPTIMAL (cold or warm)"
    )


if __name__ == "__main__":
    main()
