"""The storm's stream analysis and its printed report (``bench/storm.py``).

:func:`stream_gaps` judges the commands one run's recorder received (DDS
source timestamps) against two periods, with the stream process's trace
(``gap_trace.classify``: each gap's cause, and whether the bare loop pinned
to the stream thread's CPU was late too -- a machine stall) and the pinned
loops' own gaps; :func:`print_report` prints every mode's result.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
from deadline_probe import overlapping_gaps
from gap_trace import classify, own_gaps, requests_path, stall_counts

#: A mid-move stop's answer (round trip) within this counts as answered in time (s).
STOP_ANSWER_BUDGET_S = 0.050


def stream_gaps(
    commands_out: Path, trace_out: Path, probe_outs: dict[int, Path], rate_hz: float, teardown_ns: int
) -> dict:
    """The stream's gaps over two periods, explained, and the pinned loops' (the keys of ``storm.py``'s JSON)."""
    args_rate = float(rate_hz)
    recorded = np.load(commands_out) if commands_out.exists() else {"send_ns": np.zeros(0, np.int64), "values": []}
    t = np.asarray(recorded["send_ns"], dtype=np.int64)
    last = float(recorded["values"][-1]) if t.size else math.nan
    t = t[t < teardown_ns]
    gaps_ms = np.diff(t) * 1e-6 if t.size > 1 else np.array([0.0])
    two_periods_ns = int(2e9 / args_rate)
    by_cpu = {c: np.load(f) for c, f in probe_outs.items() if f.exists()}
    if t.size > 1:  # the loops ran from before the first command to after the last: the stream's span only
        by_cpu = {c: v[(v >= t[0]) & (v <= t[-1])] for c, v in by_cpu.items()}
    shared = np.zeros(max(int(np.sum(np.diff(t) > two_periods_ns)), 0) if t.size > 1 else 0, dtype=bool)
    for v in by_cpu.values():  # a stream gap overlapping a gap of any of the loops (before they were pinned: the one)
        if t.size > 1:
            shared |= overlapping_gaps(t, v, two_periods_ns)[1]
    probe_by_cpu = {
        c: {
            "wakes": int(v.size),
            "gaps_over_two_periods": int(np.sum(np.diff(v) > two_periods_ns)) if v.size > 1 else 0,
            "gap_max_ms": float(np.diff(v).max() * 1e-6) if v.size > 1 else 0.0,
        }
        for c, v in by_cpu.items()
    }
    trace = np.load(trace_out) if trace_out.exists() else np.zeros((0, 11))
    requests_out = Path(requests_path(str(trace_out)))
    requests = np.load(requests_out) if requests_out.exists() else None
    explained = classify(t, trace, two_periods_ns, probes_by_cpu=by_cpu, requests=requests)
    causes: dict[str, int] = {}
    for g in explained:
        causes[g["cause"]] = causes.get(g["cause"], 0) + 1
    stalls = stall_counts(explained)
    sender = own_gaps(trace, two_periods_ns, teardown_ns) if len(trace) else np.zeros((0, 2))
    return dict(
        last_command=last,
        commands=int(t.size),
        gap_max_ms=float(gaps_ms.max()),
        gaps_over_two_periods=int(np.sum(gaps_ms > 2e3 / args_rate)),
        gap_at_ns=[[int(t[i]), round(float(gaps_ms[i]), 1)] for i in np.flatnonzero(gaps_ms > 2e3 / args_rate)[:40]],
        largest_gaps=[[int(t[i]), round(float(gaps_ms[i]), 1)] for i in np.argsort(gaps_ms)[::-1][:10]],
        gaps_shared_with_probe=int(shared.sum()),
        # the loop pinned to the CPU the stream thread slept or woke on was late too: the machine stalled that CPU
        gap_stalls=stalls,
        gaps_machine_stall=stalls.get("same CPU", 0),
        gaps_not_machine_stall=len(explained) - stalls.get("same CPU", 0),
        gap_causes_machine_stall={
            c: sum(g["cause"] == c and g["stall"] == "same CPU" for g in explained) for c in causes
        },
        gaps_not_machine_stall_explained=[g for g in explained if g["stall"] != "same CPU"][:40],
        gap_causes=causes,
        # the bare loop (another process) was late too during the gap: the machine stalled both (by cause)
        gap_causes_probe_late={
            c: sum(g["cause"] == c and (g.get("probe_ms") or 0.0) > 1.5e3 / args_rate for g in explained)
            for c in causes
        },
        gaps_explained=explained[:40],
        sender_gaps_over_two_periods=len(sender),
        sender_gap_max_ms=float(sender[:, 1].max()) if len(sender) else 0.0,
        traced_samples=len(trace),
        probe_by_cpu=probe_by_cpu,
        probe_wakes=sum(v["wakes"] for v in probe_by_cpu.values()),
        probe_gaps_over_two_periods=sum(v["gaps_over_two_periods"] for v in probe_by_cpu.values()),
        probe_gap_max_ms=max((v["gap_max_ms"] for v in probe_by_cpu.values()), default=0.0),
        gap_p999_ms=float(np.percentile(gaps_ms, 99.9)),
    )


def stop_summary(stops: list[dict]) -> dict:
    """The mid-move stops' figures (the keys of ``storm.py``'s JSON) from each stop's record."""
    mid_stops = [s for s in stops if s["moving"] and s["after"] is not None]
    return dict(
        stops=len(stops),
        mid_move_stops=len(mid_stops),
        stop_answer_ms=[round(s["answer_s"] * 1e3, 3) for s in mid_stops],
        stops_within_50ms=sum(s["answer_s"] <= STOP_ANSWER_BUDGET_S for s in mid_stops),
        # a stop whose plan overran its look-ahead (or found the timeline changed) is planned again from further
        # ahead; its answer says "planned N times": the others must start within the look-ahead they were given
        stops_overran=sum(s["replanned"] for s in mid_stops),
        # a ready stop is taken within READY_STOP_LEADS look-aheads (its answer says how many)
        stops_within_lead=sum(s["after"] <= s["lead"] * s["leads"] for s in mid_stops if not s["replanned"]),
        stop_after_samples=[s["after"] for s in mid_stops],
        late_stop_texts=[s["text"] for s in mid_stops if not s["replanned"] and s["after"] > s["lead"] * s["leads"]],
    )


def print_report(results: list[dict], args) -> None:
    """Every mode's result as text (``storm.py`` without ``--json``)."""
    load = os.getloadavg()
    print(f"load average at the start of each mode: {[r['load_at_start'] for r in results]}")
    print(
        f"storm: {args.requests} requests per mode, seed {args.seed}, {args.rate:g} Hz two-mode machine, planner and "
        f"plant as processes; load average {load[0]:.1f} on {os.cpu_count()} CPUs"
    )
    for r in results:
        ans = np.array(r["stop_answer_ms"]) if r["stop_answer_ms"] else np.array([math.nan])
        after = np.array(r["stop_after_samples"] or [math.nan], float)
        print()
        print(f"[{r['mode']}] {r['sent']} requests in {r['duration_s']:.1f} s; mix {r['kinds']}")
        print(f"  crashes                      {r['crashes'] or 0}   exit status {r['exit_status']}")
        print(f"  internal error texts         {r['internal_error_texts']}  {r['internal_examples']}")
        print(
            f"  invalid refused with reason  {r['invalid_refused']}/{r['invalid_sent']} "
            f"(topics: {r['topic_refusals_logged']} refusals logged for {r['invalid_topic_sent']} sent; too-early "
            f"arrivals, judged only by planning: {r['early_refused']} of {r['early_sent']} refused, the others "
            "superseded by a newer goal before planned)"
        )
        print(
            f"  mid-move stops               {r['mid_move_stops']} (of {r['stops']} stops): answered within 50 ms "
            f"{r['stops_within_50ms']}, answer ms median {np.median(ans):.1f} p99 {np.percentile(ans, 99):.1f} "
            f"max {ans.max():.1f}; applied within the look-ahead {r['stops_within_lead']}, samples after the request "
            f"median {np.nanmedian(after):.0f} max {np.nanmax(after):.0f} ({r['stops_overran']} overran and were replanned)"
        )
        print(
            f"  stream                       {r['commands']} commands; gap max {r['gap_max_ms']:.1f} ms "
            f"(p99.9 {r['gap_p999_ms']:.2f} ms); gaps over two periods ({2e3 / args.rate:g} ms): "
            f"{r['gaps_over_two_periods']}; last command {r['last_command']}"
        )
        print(
            f"  the gaps' causes             {r['gap_causes']}; the sender's own gaps (its trace, "
            f"{r['traced_samples']} samples): {r['sender_gaps_over_two_periods']}, max {r['sender_gap_max_ms']:.1f} ms; "
            f"of them with the bare loop late too {r['gap_causes_probe_late']}"
        )
        if r["probe_wakes"]:
            per_cpu = "; ".join(
                f"CPU {c}: {v['wakes']} wake-ups, {v['gaps_over_two_periods']} gaps over two periods, max "
                f"{v['gap_max_ms']:.1f} ms"
                for c, v in r["probe_by_cpu"].items()
            )
            print(
                f"  bare deadline loops (pinned)  {per_cpu}; stream gaps overlapping one of theirs: "
                f"{r['gaps_shared_with_probe']} of {r['gaps_over_two_periods']}; "
                f"CPU stolen by the hypervisor meanwhile: {r['steal_s']:.2f} s"
            )
            print(
                f"  machine stalls               {r['gaps_machine_stall']} of {r['gaps_over_two_periods']} gaps (the "
                f"loop pinned to the stream thread's CPU late too; by cause {r['gap_causes_machine_stall']}); not: "
                f"{r['gaps_not_machine_stall']} {r['gap_stalls']}"
            )
            for g in r["gaps_not_machine_stall_explained"][:10]:
                print(f"    not a machine stall: {g}")
        if r["mode"] == "lockstep":
            print(
                f"  settled moves at rest        {r['settled_ok']}/{r['settled_checked']} at the target, at rest "
                f"(max error {r['settled_max_error']:.2g})"
            )
        print(f"  goals superseded / cancelled {r['goals_superseded']} / {r['goals_cancelled']}")
        print("  planner RSS MB               " + ", ".join(f"{n}: {m:.1f}" for n, m in r["rss_mb"]))
        if r["rss_tail_mb"]:
            print(
                "  after the storm, s: RSS MB (PSS MB with its child processes) "
                + ", ".join(f"{t:.0f}: {m:.1f} ({f:.1f})" for t, m, f in r["rss_tail_mb"])
            )
