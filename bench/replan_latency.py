"""Replanning latency from arbitrary moving, vibrating states (issue 14), with today's solver.

Models: lumped flexible links as in ``planner_latency.py`` (``chain``: n+1 masses
of 0.5 kg, 400 N/m springs, 0.4 N s/m dampers, force on the first mass;
n = 1, 2, 3 modes; ``u_max = 10 N``).  For each, a nominal rest-to-rest move
(the distance a rigid body covers in ``--move-s``) is planned at ``--rate``;
then ``--states`` replanning instants are drawn along it (10 %..90 % of the
move), and the state the timeline predicts there is disturbed (an impulse of
up to ``--kick`` N s on the actuated mass plus a random swing of each mode of
up to ``--swing`` of its excursion in the move): an arbitrary moving,
vibrating state.  From it, in one run:

* ``r2r``: the nominal rest-to-rest move's continuous plan (20 repeats), the reference
  the other columns compare with (same run, same load);
* ``cont``: ``plan_move`` without a rate -- the certified continuous plan;
* ``sampled``: ``plan_move`` at ``--rate`` -- the exact ZOH plan a node needs to stream;
* ``replan``: ``execution.replan.replan`` -- carry the estimate to the splice
  (10 samples ahead), decide, and plan at ``--rate`` (what the node calls).

Wall-time latency median / p99 / max (ms) over the states, and failures
(a plan the solver refused: the current plan would go on).

    python bench/replan_latency.py
    python bench/replan_latency.py --states 200 --rate 500
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.errors import FlexmotionError
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.model.boundary import rest_to_rest, state_to_rest
from flexmotion_ros.core.model.builders import chain
from flexmotion_ros.execution.replan import ReplanStatus, replan
from flexmotion_ros.execution.timeline import Segment, predicted_state

LEAD = 10


def stats(ms: list[float]) -> str:
    if not ms:
        return f"{'-':>8} {'-':>8} {'-':>8}"
    a = np.array(ms)
    return f"{np.median(a):8.2f} {np.percentile(a, 99):8.2f} {np.max(a):8.2f}"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--states", type=int, default=100, help="replanning states per model")
    p.add_argument("--rate", type=float, default=1000.0, help="command rate (Hz)")
    p.add_argument("--move-s", type=float, default=1.0, dest="move_s", help="rigid-body time of the nominal move (s)")
    p.add_argument("--kick", type=float, default=0.5, help="largest impulse on the actuated mass (N s)")
    p.add_argument("--swing", type=float, default=0.3, help="largest added swing, fraction of each mode's excursion")
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args()
    rng = np.random.default_rng(a.seed)
    print(
        f"# replanning latency (issue 14): python {platform.python_version()}, numpy {np.__version__}, "
        f"{os.cpu_count()} CPU(s), load {os.getloadavg()[0]:.1f}; {a.states} states per model, {a.rate:g} Hz, "
        f"kick <= {a.kick} N s, swing <= {a.swing:.0%} of the move's"
    )
    print(
        f"{'modes':>5} {'move m':>7} {'T nom s':>8} | {'r2r med':>8} | {'cont med':>8} {'p99':>8} {'max':>8} | "
        f"{'ZOH med':>8} {'p99':>8} {'max':>8} | {'rpl med':>8} {'p99':>8} {'max':>8} | {'failed':>6}"
    )
    print("-" * 125)
    for n in (1, 2, 3):
        built = chain([0.5] * (n + 1), [400.0] * n, [0.4] * n)
        model = built.model
        u_max = 10.0
        gamma = 0.5 * abs(model.b0) * u_max * a.move_s**2  # bang-bang rigid move of move_s
        cfg = PlannerConfig(model=model, u_max=u_max, rate_hz=a.rate)
        nominal = plan_move(cfg, rest_to_rest(model, u_max, gamma), a.rate).sampled
        seg = Segment(np.asarray(nominal.commands, float), np.asarray(nominal.states, float), start=0)
        excursion = np.max(np.abs(nominal.states[:, 2::2]), axis=0)
        r2r = []
        for _ in range(20):
            t0 = time.perf_counter()
            plan_move(cfg, rest_to_rest(model, u_max, gamma), None)
            r2r.append(1e3 * (time.perf_counter() - t0))
        cont, sampled, full, failed = [], [], [], 0
        for _ in range(a.states):
            k = int(rng.uniform(0.1, 0.9) * seg.samples)
            x = predicted_state([seg], k).copy()
            x += model.B() * rng.uniform(-a.kick, a.kick)  # an impulse: every velocity jumps by its gain
            x[2::2] += a.swing * excursion * rng.uniform(-1.0, 1.0, n)
            problem = state_to_rest(model, u_max, x, gamma)
            try:
                t0 = time.perf_counter()
                plan_move(cfg, problem, None)
                cont.append(1e3 * (time.perf_counter() - t0))
                t0 = time.perf_counter()
                plan_move(cfg, problem, a.rate)
                sampled.append(1e3 * (time.perf_counter() - t0))
            except FlexmotionError:
                failed += 1
                continue
            t0 = time.perf_counter()
            out = replan([seg], k, LEAD, x, k, config=cfg, target=gamma)
            took = 1e3 * (time.perf_counter() - t0)
            if out.status is ReplanStatus.REPLANNED:
                full.append(took)
            elif out.status is ReplanStatus.FAILED:
                failed += 1
        print(
            f"{n:5d} {gamma:7.3g} {nominal.duration:8.3f} | {np.median(r2r):8.2f} | {stats(cont)} | {stats(sampled)} | "
            f"{stats(full)} | {failed:6d}"
        )


if __name__ == "__main__":
    main()
