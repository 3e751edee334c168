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
* ``stage``: its ZOH stage alone (``plan_time_optimal_zoh`` given the continuous optimum), median;
* ``rpl cold``: ``execution.replan.replan(..., warm_start=False)`` -- carry the
  estimate to the splice (10 samples ahead), decide, and plan at ``--rate``
  from nothing;
* ``rpl warm``: the same with the plan being executed (the nominal one) as
  the planner's warm start (what the node calls: ``warm_start=True``, the
  default): Newton from the rest of its switch structure, the cold solver if
  that yields no certified optimum;
* ``hit``: how many warm replans the warm start answered (the others fell
  back to the cold solver); ``dT`` / ``dsw``: the largest difference between
  the cold and the warm certified optimum's duration / switch times (s), and
  ``dK`` the largest difference of their sample counts, over every state.

Latency median / p99 / max (ms) over the states, wall time or with ``--clock cpu``
the process's CPU time (``time.process_time``: what the wall time would be on an
idle core; the numerics run single-threaded), and failures
(a plan the solver refused: the current plan would go on).

``--ab`` adds a second table, the linear-program backend before and after
(``core.linear_program``): for every state, alternating which goes first so
that both see the same load, the ZOH stage alone (``plan_time_optimal_zoh``
given the continuous optimum) and the cold replan, with the LPs solved
through ``scipy.optimize.linprog`` (``linprog``: how the ZOH stage solved
them before) and by HiGHS directly (``highspy``); ``CPU``: the cold replan's
median thread CPU time (ms), what its wall time would be on an idle core;
``same`` counts the states whose two ZOH sequences are identical bit for bit.
A third table times the ZOH stage alone of ``planner_latency.py``'s 5 s move
(1-8 modes) with both backends the same way.

    python bench/replan_latency.py
    python bench/replan_latency.py --states 200 --rate 500
    python bench/replan_latency.py --states 100 --ab
    python bench/replan_latency.py --states 100 --clock cpu
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
from flexmotion_ros.core import linear_program
from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.errors import FlexmotionError
from flexmotion_ros.core.linear_program import LpBackend
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.model.boundary import rest_to_rest, state_to_rest
from flexmotion_ros.core.model.builders import chain
from flexmotion_ros.core.sampled.zoh import plan_time_optimal_zoh
from flexmotion_ros.execution.replan import ReplanStatus, replan
from flexmotion_ros.execution.timeline import Segment, predicted_state

LEAD = 10
#: The clock of the latency columns (``--clock``): wall time, or the process's CPU time.
CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}
clock = CLOCKS["wall"]


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
    p.add_argument("--ab", action="store_true", help="also: ZOH stage and cold replan, LPs by linprog vs highspy")
    p.add_argument("--clock", choices=sorted(CLOCKS), default="wall", help="the latency columns' clock")
    a = p.parse_args()
    global clock
    clock = CLOCKS[a.clock]
    rng = np.random.default_rng(a.seed)
    print(
        f"# replanning latency (issue 14): python {platform.python_version()}, numpy {np.__version__}, "
        f"{os.cpu_count()} CPU(s), load {os.getloadavg()[0]:.1f}; {a.states} states per model, {a.rate:g} Hz, "
        f"kick <= {a.kick} N s, swing <= {a.swing:.0%} of the move's; clock: {a.clock}"
    )
    print(
        f"{'modes':>5} {'T nom s':>8} | {'r2r med':>7} | {'cont med':>8} {'p99':>7} | {'ZOH med':>8} {'p99':>7} | "
        f"{'stage':>6} | "
        f"{'cold med':>8} {'p99':>7} {'max':>7} | {'warm med':>8} {'p99':>7} {'max':>7} | {'hit':>7} "
        f"{'dT s':>7} {'dsw s':>7} {'dK':>3} | {'failed':>6}"
    )
    print("-" * 150)
    ab_rows = []
    for n in (1, 2, 3):
        built = chain([0.5] * (n + 1), [400.0] * n, [0.4] * n)
        model = built.model
        u_max = 10.0
        gamma = 0.5 * abs(model.b0) * u_max * a.move_s**2  # bang-bang rigid move of move_s
        cfg = PlannerConfig(model=model, u_max=u_max, rate_hz=a.rate)
        planned = plan_move(cfg, rest_to_rest(model, u_max, gamma), a.rate)
        nominal = planned.sampled
        # the segment records its plan, as the node's do: the warm start is the rest of it at the splice
        seg = Segment(np.asarray(nominal.commands, float), np.asarray(nominal.states, float), start=0, info=planned)
        excursion = np.max(np.abs(nominal.states[:, 2::2]), axis=0)
        r2r = []
        for _ in range(20):
            t0 = clock()
            plan_move(cfg, rest_to_rest(model, u_max, gamma), None)
            r2r.append(1e3 * (clock() - t0))
        cont, sampled, stage, full, warm, failed = [], [], [], [], [], 0
        ab = {key: [] for key in ("zoh_lp", "zoh_hs", "rpl_lp", "rpl_hs", "cpu_lp", "cpu_hs")}
        identical = 0
        hits, dT, dsw, dK = 0, 0.0, 0.0, 0
        for _ in range(a.states):
            k = int(rng.uniform(0.1, 0.9) * seg.samples)
            x = predicted_state([seg], k).copy()
            x += model.B() * rng.uniform(-a.kick, a.kick)  # an impulse: every velocity jumps by its gain
            x[2::2] += a.swing * excursion * rng.uniform(-1.0, 1.0, n)
            problem = state_to_rest(model, u_max, x, gamma)
            try:
                t0 = clock()
                optimum = plan_move(cfg, problem, None).continuous
                cont.append(1e3 * (clock() - t0))
                t0 = clock()
                plan_move(cfg, problem, a.rate)
                sampled.append(1e3 * (clock() - t0))
                t0 = clock()
                plan_time_optimal_zoh(problem, a.rate, optimum)
                stage.append(1e3 * (clock() - t0))
            except FlexmotionError:
                failed += 1
                continue
            t0 = clock()
            out = replan([seg], k, LEAD, x, k, config=cfg, target=gamma, warm_start=False)
            took = 1e3 * (clock() - t0)
            t0 = clock()
            out_w = replan([seg], k, LEAD, x, k, config=cfg, target=gamma, warm_start=True)
            took_w = 1e3 * (clock() - t0)
            if out.status is not ReplanStatus.REPLANNED or out_w.status is not ReplanStatus.REPLANNED:
                failed += 1
                continue
            full.append(took)
            warm.append(took_w)
            c, w = out.result.continuous, out_w.result.continuous
            if c is not None and w is not None:
                hits += w.extra.get("fast_path_stage") == "warm"
                dT = max(dT, abs(c.duration - w.duration))
                same = c.switch_times.size == w.switch_times.size
                dsw = max(dsw, float(np.max(np.abs(c.switch_times - w.switch_times), initial=0.0)) if same else np.inf)
            dK = max(dK, abs(out.result.sampled.commands.size - out_w.result.sampled.commands.size))
            if a.ab:
                identical += ab_once(ab, len(full) % 2 == 0, cfg, problem, optimum, seg, k, x, gamma, a.rate)
        print(
            f"{n:5d} {nominal.duration:8.3f} | {np.median(r2r):7.2f} | {stats(cont)[:17]} | {stats(sampled)[:17]} | "
            f"{np.median(stage) if stage else float('nan'):6.2f} | "
            f"{stats(full)} | {stats(warm)} | {hits:3d}/{len(warm):<3d} {dT:7.1e} {dsw:7.1e} {dK:3d} | {failed:6d}"
        )
        if a.ab:
            ab_rows.append((n, ab, identical))
    if a.ab:
        print()
        print("# LP backend A/B, same states, alternating order: ZOH stage alone and cold replan (ms)")
        print(
            f"{'modes':>5} | {'ZOH linprog':>11} {'p99':>7} | {'ZOH highspy':>11} {'p99':>7} {'ratio':>6} | "
            f"{'rpl linprog':>11} {'p99':>7} | {'rpl highspy':>11} {'p99':>7} {'ratio':>6} | "
            f"{'CPU linprog':>11} {'CPU highspy':>11} | {'same':>7}"
        )
        print("-" * 138)
        for n, ab, identical in ab_rows:
            med = {key: float(np.median(v)) for key, v in ab.items()}
            p99 = {key: float(np.percentile(v, 99)) for key, v in ab.items()}
            print(
                f"{n:5d} | {med['zoh_lp']:11.2f} {p99['zoh_lp']:7.2f} | {med['zoh_hs']:11.2f} {p99['zoh_hs']:7.2f} "
                f"{med['zoh_hs'] / med['zoh_lp']:6.2f} | {med['rpl_lp']:11.2f} {p99['rpl_lp']:7.2f} | "
                f"{med['rpl_hs']:11.2f} {p99['rpl_hs']:7.2f} {med['rpl_hs'] / med['rpl_lp']:6.2f} | "
                f"{med['cpu_lp']:11.2f} {med['cpu_hs']:11.2f} | "
                f"{identical:3d}/{len(ab['zoh_lp']):<3d}"
            )
        zoh_5s_ab(10, a.rate)


def zoh_5s_ab(repeats: int, rate: float) -> None:
    """``--ab``: the ZOH stage alone of ``planner_latency.py``'s 5 s move (rigid-body time 5 s), both LP backends.

    Chains of n+1 masses as there (``force_on=0``), n = 1, 2, 3, 5, 8; the
    continuous optimum is planned once, then ``plan_time_optimal_zoh`` is timed
    ``repeats`` times per backend, alternating.
    """
    print()
    print(f"# LP backend A/B: ZOH stage alone of planner_latency.py's 5 s move at {rate:g} Hz, {repeats} repeats (ms)")
    print(
        f"{'modes':>5} {'K':>6} | {'linprog med':>11} {'min':>7} | {'highspy med':>11} {'min':>7} {'ratio':>6} | {'same':>5}"
    )
    print("-" * 72)
    default = linear_program.DEFAULT_BACKEND
    try:
        for n in (1, 2, 3, 5, 8):
            model = chain([0.5] * (n + 1), [400.0] * n, [0.4] * n, force_on=0).model
            problem = rest_to_rest(model, 10.0, abs(model.b0) * 10.0 * 5.0**2 / 4.0)
            optimum = plan_move(PlannerConfig(model=model, u_max=10.0), problem, None).continuous
            times = {LpBackend.SCIPY: [], LpBackend.HIGHSPY: []}
            out = {}
            for r in range(repeats):
                order = (LpBackend.SCIPY, LpBackend.HIGHSPY) if r % 2 == 0 else (LpBackend.HIGHSPY, LpBackend.SCIPY)
                for backend in order:
                    linear_program.DEFAULT_BACKEND = backend
                    t0 = clock()
                    out[backend] = plan_time_optimal_zoh(problem, rate, optimum).commands
                    times[backend].append(1e3 * (clock() - t0))
            lp, hs = np.array(times[LpBackend.SCIPY]), np.array(times[LpBackend.HIGHSPY])
            same = np.array_equal(out[LpBackend.SCIPY], out[LpBackend.HIGHSPY])
            print(
                f"{n:5d} {out[LpBackend.HIGHSPY].size:6d} | {np.median(lp):11.2f} {lp.min():7.2f} | "
                f"{np.median(hs):11.2f} {hs.min():7.2f} {np.median(hs) / np.median(lp):6.2f} | {str(same):>5}"
            )
    finally:
        linear_program.DEFAULT_BACKEND = default


def ab_once(ab: dict, linprog_first: bool, cfg, problem, continuous, seg, k, x, gamma, rate) -> int:
    """One state of the ``--ab`` table: ZOH stage and cold replan with each LP backend; 1 if both ZOH sequences agree."""
    order = (LpBackend.SCIPY, LpBackend.HIGHSPY) if linprog_first else (LpBackend.HIGHSPY, LpBackend.SCIPY)
    commands = {}
    default = linear_program.DEFAULT_BACKEND
    try:
        for backend in order:
            linear_program.DEFAULT_BACKEND = backend  # what solve_lp uses when not told
            tag = "lp" if backend is LpBackend.SCIPY else "hs"
            t0 = clock()
            zoh = plan_time_optimal_zoh(problem, rate, continuous)
            ab[f"zoh_{tag}"].append(1e3 * (clock() - t0))
            commands[tag] = zoh.commands
            t0, c0 = clock(), time.thread_time()
            replan([seg], k, LEAD, x, k, config=cfg, target=gamma, warm_start=False)
            ab[f"rpl_{tag}"].append(1e3 * (clock() - t0))
            ab[f"cpu_{tag}"].append(1e3 * (time.thread_time() - c0))
    finally:
        linear_program.DEFAULT_BACKEND = default
    return int(np.array_equal(commands["lp"], commands["hs"]))


if __name__ == "__main__":
    main()
