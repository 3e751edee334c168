"""A seeded storm of requests against ``flexmotion_planner`` and ``flexmotion_plant`` as separate processes (issue 16).

The test suite's stiff two-mode machine (b0 1, omega [5, 13] rad/s, zeta
[0.01, 0.02], b [1, -0.7], u_max 10 N, 200 Hz, position limits +-3 m) runs as
two processes (the code ``ros2 run`` runs), lockstep and/or real time; this
script is a third process over real DDS (an isolated domain unless
``ROS_DOMAIN_ID`` is set) and sends ``--requests`` requests over ``~/goal``,
``~/joint_trajectory``, ``~/move``, ``~/plan`` and ``~/stop`` (seeded):

* 20 % invalid: NaN, outside the position limits, an unknown joint, a
  negative or too early ``time_from_start``;
* 20 % mid-move: a stop (half) or a new goal while a move plays;
* the rest valid from wherever the machine is; half of the valid goals wait
  until the move has settled (then, lockstep, the plant must be at the target
  and at rest).

It reports, per mode:

* crashes (a node process that died) and internal error texts (an answer or
  a log line naming a Python exception, ``unexpected`` or a traceback): 0;
* invalid requests refused with a reason (service answers; topic requests
  from the planner's log);
* mid-move stops: answered within 50 ms (round trip here), and applied within
  the look-ahead (the stop's first sample at most ``look-ahead`` samples after
  the request, from the planner's answer);
* stream gaps: the largest interval between consecutive commands at the
  planner (DDS source timestamps, recorded by ``command_recorder.py`` in a
  process of its own; the stream holds while idle), against two periods;
  and beside it a bare deadline loop (``deadline_probe.py``) at the same
  rate and priority, one pinned to each CPU: a stream gap during which the
  loop pinned to the CPU the stream thread slept or woke on was late too is
  a machine stall (counted apart, ``gaps_machine_stall``), as is the
  hypervisor's stolen time;
* settled lockstep moves at the target at rest (plant state, 1e-9);
* the planner's RSS at the start and the end (and every 1000 requests), and optionally
  for a while after the storm (a transient the idle heap trim hands back, or growth).

    python bench/storm.py                                # 1000 requests, lockstep and real time
    python bench/storm.py --requests 10000 --modes lockstep --no-settle --rss-tail-seconds 90   # memory over 10,000
    python bench/storm.py --requests 60 --modes lockstep --json            # what the test suite runs

OpenBLAS threads are set to 1 before numpy loads (tiny matrices: threading only costs).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
if "ROS_DOMAIN_ID" not in os.environ:
    os.environ["ROS_DOMAIN_ID"] = str(random.SystemRandom().randint(1, 100))
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
from deadline_probe import steal_ticks  # noqa: E402 -- beside this script
from storm_nodes import (  # noqa: E402 -- beside this script
    INTERNAL,
    LIMIT,
    PARAMS,
    RATE_HZ,
    Storm,
    family_pss_mb,
    goal_request,
    rss_mb,
    start_node,
    stop_processes,
    trajectory,
)
from storm_report import print_report, stop_summary, stream_gaps  # noqa: E402 -- beside this script


def _args() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--requests", type=int, default=1000, help="requests per mode")
    p.add_argument("--modes", nargs="+", default=["lockstep", "realtime"], choices=["lockstep", "realtime"])
    p.add_argument("--seed", type=int, default=16)
    p.add_argument("--max-seconds", type=float, default=900.0, help="bound per mode (s): stop sending after it")
    p.add_argument(
        "--no-settle", action="store_true", help="never wait for a move to start or settle (fast: for memory)"
    )
    p.add_argument("--rate", type=float, default=RATE_HZ, help="command rate (Hz)")
    p.add_argument(
        "--no-probe",
        action="store_true",
        help="do not run the bare deadline loop (bench/deadline_probe.py) beside the nodes",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object per mode")
    p.add_argument(
        "--rss-tail-seconds",
        type=float,
        default=0.0,
        help="after the last request, sample the planner's RSS every 5 s for this long (s): transient or growth",
    )
    p.add_argument("-p", dest="planner_params", action="append", default=[], help="planner parameter NAME:=VALUE")
    return p.parse_args()


def stream_priority(args: argparse.Namespace) -> int:
    """The planner's ``stream_priority`` among the ``-p`` parameters (0 when not set)."""
    for item in args.planner_params:
        name, _, value = item.partition(":=")
        if name.strip() == "stream_priority":
            return int(float(value))
    return 0


def run_mode(args, mode: str) -> dict:
    rng = random.Random(args.seed)
    ns = f"/storm_{os.getpid()}_{mode}"
    tmp = Path(tempfile.mkdtemp(prefix="flexmotion_storm_"))
    params = tmp / "storm.yaml"
    params.write_text(PARAMS.format(rate=float(args.rate), low=-LIMIT, high=LIMIT))
    planner_log, plant_log = tmp / "planner.log", tmp / "plant.log"
    lockstep = mode == "lockstep"
    plant = start_node("plant_node", ns, params, [f"lockstep:={'true' if lockstep else 'false'}"], plant_log)
    # the commands are recorded by a process of their own (bench/command_recorder.py): this one is busy
    commands_out = tmp / "commands.npz"
    recorder = subprocess.Popen(
        [sys.executable, str(ROOT / "bench" / "command_recorder.py"), "--topic", f"{ns}/commands"]
        + ["--out", str(commands_out), "--priority", str(max(0, stream_priority(args) - 2))]
    )
    # the stream process traces every sample it sends (stream_trace.py): a gap is then the sender's or the transport's
    trace_out = tmp / "stream_trace.npy"
    planner = start_node(
        "planner_node", ns, params, list(args.planner_params), planner_log, {"FLEXMOTION_STREAM_TRACE": str(trace_out)}
    )
    storm = Storm(ns)
    # one bare loop pinned to each CPU: a stall of one virtual CPU is seen only by what runs on it
    probe_outs = {} if args.no_probe else {c: tmp / f"probe_cpu{c}.npy" for c in sorted(os.sched_getaffinity(0))}
    probes = [
        subprocess.Popen(
            [sys.executable, str(ROOT / "bench" / "deadline_probe.py"), "--rate", repr(float(args.rate))]
            + ["--seconds", repr(args.max_seconds + 120.0), "--priority", str(stream_priority(args)), "--out"]
            + [str(out), "--cpu", str(c)]
        )
        for c, out in probe_outs.items()
    ]
    steal0 = steal_ticks()
    load0 = [round(x, 2) for x in os.getloadavg()]
    out: dict = {"mode": mode, "requests": args.requests, "seed": args.seed, "rate_hz": float(args.rate)}
    stops: list[dict] = []
    invalid = {"sent": 0, "refused_answers": 0, "unrefused": []}
    topic_invalid = 0
    early = 0  # too-early arrivals: judged only by planning, so a newer goal may supersede one before it is
    settled: list[float] = []
    settled_bad: list[dict] = []
    internal_answers: list[str] = []
    rss: list[tuple[int, float]] = []
    rss_tail: list[tuple[float, float, float]] = []
    kinds: dict[str, int] = {}
    t_start = time.monotonic()

    def alive() -> bool:
        return planner.poll() is None and plant.poll() is None

    def wait(pred, timeout: float) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if pred():
                return True
            if not alive():
                return False
            time.sleep(0.002)
        return False

    def planner_value(key: str, default: str = "") -> str:
        with storm.lock:
            return storm.planner_status.get(key, default)

    def moving() -> bool:
        return planner_value("state") == "moving"

    def settle(target: float | None, timeout: float = 20.0, how: str = "") -> None:
        """Wait until the move to ``target`` (None: any) has ended; lockstep: the plant there, at rest."""
        if target is not None and not wait(lambda: planner_value("target") == f"{target:.9g}", 2.0):
            return  # superseded, refused or already there: nothing to check
        t0 = time.monotonic()
        if not wait(lambda: storm.planner_status.get("stamp", 0) > t0 and not moving(), timeout):
            return
        if not lockstep:
            return
        if target is None:  # the planner reports its rest position to 9 digits only: nothing exact to check
            return
        rest = target
        if planner_value("target") != f"{rest:.9g}":
            return

        def error(x: np.ndarray) -> float:  # position, velocity, every modal coordinate and speed
            return max(abs(x[0] - rest), *np.abs(x[1:]))

        # the lockstep plant may lag the stream by seconds (its own process, under load; at 1 kHz it may still
        # stand at the previous target, holding): wait until it stands still at the target, at rest, or for
        # 30 s; then the state it stands still at is what is judged
        x = None
        end = time.monotonic() + 30.0
        while time.monotonic() < end:
            with storm.lock:
                a = None if storm.state is None else storm.state.copy()
            time.sleep(0.1)
            with storm.lock:
                b = None if storm.state is None else storm.state.copy()
            if a is not None and b is not None and np.max(np.abs(a - b)) <= 1e-10:
                x = b
                if error(x) <= 1e-9:
                    break
        if x is None:
            return
        err = error(x)
        settled.append(err)
        if err > 1e-9:
            settled_bad.append({"how": how, "target": rest, "state": x.tolist()})

    def answer_text(resp) -> str:
        if resp is None:
            return "no answer"
        if hasattr(resp, "plan"):
            return resp.plan.header.frame_id
        return resp.message

    def note(resp, expect_refusal: bool) -> None:
        text = answer_text(resp)
        if INTERNAL.search(text):
            internal_answers.append(text)
        if expect_refusal:
            invalid["sent"] += 1
            refused = text.startswith("error: ") and len(text) > len("error: ") + 10
            if resp is not None and hasattr(resp, "success"):
                refused = not resp.success and len(text) > 10
            invalid["refused_answers"] += refused
            if not refused:
                invalid["unrefused"].append(text)

    try:
        ok = wait(
            lambda: (
                storm.goal_pub.get_subscription_count() >= 1
                and planner_value("streaming_ready") == "true"
                and int(planner_value("command_subscribers", "0") or 0) >= 2  # the plant and the recorder
                and storm.move.service_is_ready()
                and storm.stop.service_is_ready()
                and storm.plan.service_is_ready()
                and int(storm.plant_status.get("joint_states_subscribers", 0)) >= 2
            ),
            180.0,  # a loaded machine has taken over 60 s to import the planner
        )
        if not ok:
            raise RuntimeError(f"discovery failed (planner {planner.poll()}, plant {plant.poll()}); logs in {tmp}")
        time.sleep(0.5)
        rss.append((0, rss_mb(planner.pid)))
        Float64 = storm.types["Float64"]
        Trigger = storm.types["Trigger"]
        for i in range(args.requests):
            if not alive() or time.monotonic() - t_start > args.max_seconds:
                break
            r = rng.random()
            if r < 0.2:  # invalid
                kind = rng.choice(["nan_topic", "limits_move", "limits_plan", "joint_topic", "negative_time", "early"])
                kinds["invalid:" + kind] = kinds.get("invalid:" + kind, 0) + 1
                if kind == "nan_topic":
                    storm.goal_pub.publish(Float64(data=math.nan))
                    topic_invalid += 1
                elif kind == "limits_move":
                    resp, _ = storm.call(storm.move, goal_request(storm, rng.choice([-1, 1]) * rng.uniform(3.5, 1e6)))
                    note(resp, True)
                elif kind == "limits_plan":
                    resp, _ = storm.call(storm.plan, goal_request(storm, rng.choice([math.inf, -4.0, 1e300])))
                    note(resp, True)
                elif kind == "joint_topic":
                    storm.jt_pub.publish(trajectory(storm, ["gripper"], 1.0, 0.0))
                    topic_invalid += 1
                elif kind == "negative_time":
                    storm.jt_pub.publish(trajectory(storm, ["rigid_body"], 1.0, -1.0))
                    topic_invalid += 1
                else:  # arrival before the time-optimal one (refused by default)
                    storm.jt_pub.publish(trajectory(storm, ["rigid_body"], rng.choice([-2.5, 2.5]), 0.01))
                    topic_invalid += 1
                    early += 1
                continue
            if r < 0.4:  # mid-move: a stop or a new goal while a move plays
                if not moving():
                    resp, _ = storm.call(storm.move, goal_request(storm, rng.uniform(-2.5, 2.5)))
                    note(resp, False)
                    if not args.no_settle:
                        wait(moving, 2.0)
                        time.sleep(rng.uniform(0.0, 0.3))
                if rng.random() < 0.5:
                    kinds["mid:stop"] = kinds.get("mid:stop", 0) + 1
                    was_moving = moving()
                    resp, rt = storm.call(storm.stop, Trigger.Request())
                    note(resp, False)
                    m = re.search(r"(\d+) samples after the request \(look-ahead (\d+)\)", answer_text(resp))
                    stops.append(
                        {
                            "answer_s": rt,
                            "moving": was_moving,
                            "after": int(m.group(1)) if m else None,
                            "lead": int(m.group(2)) if m else None,
                            "replanned": bool(re.search(r"; planned \d+ times", answer_text(resp))),
                            "leads": int(w.group(1))
                            if (w := re.search(r"within (\d+) look-aheads", answer_text(resp)))
                            else 1,
                            "text": answer_text(resp)[:300],
                        }
                    )
                else:
                    kinds["mid:goal"] = kinds.get("mid:goal", 0) + 1
                    x = rng.uniform(-2.5, 2.5)
                    if rng.random() < 0.5:
                        storm.goal_pub.publish(Float64(data=x))
                    else:
                        resp, _ = storm.call(storm.move, goal_request(storm, x))
                        note(resp, False)
                continue
            # valid, from wherever the machine is
            x = rng.uniform(-2.5, 2.5)
            kind = rng.choice(["goal", "trajectory", "move", "plan", "stop"])
            kinds["valid:" + kind] = kinds.get("valid:" + kind, 0) + 1
            if kind == "goal":
                storm.goal_pub.publish(Float64(data=x))
            elif kind == "trajectory":
                storm.jt_pub.publish(trajectory(storm, ["rigid_body"], x, rng.choice([0.0, 4.0])))
            elif kind == "move":
                resp, _ = storm.call(storm.move, goal_request(storm, x))
                note(resp, False)
            elif kind == "plan":
                resp, _ = storm.call(storm.plan, goal_request(storm, x))
                note(resp, False)
            else:
                resp, _ = storm.call(storm.stop, Trigger.Request())
                note(resp, False)
            if kind in ("goal", "trajectory", "move") and not args.no_settle and rng.random() < 0.5:
                settle(x, how=kind)
            if (i + 1) % 1000 == 0:
                rss.append((i + 1, rss_mb(planner.pid)))
        sent = i + 1
        settle(None, 30.0)
        time.sleep(0.5)
        rss.append((sent, rss_mb(planner.pid)))
        # A reading right after the storm can catch heap the planner frees and hands back when
        # idle (execution/heap.py, at most every 30 s): sample on to tell a transient from growth.
        tail_start = time.monotonic()
        while time.monotonic() - tail_start < args.rss_tail_seconds:
            time.sleep(5.0)
            rss_tail.append((time.monotonic() - tail_start, rss_mb(planner.pid), family_pss_mb(planner.pid)))
    finally:
        teardown_ns = time.time_ns()  # the stream's gaps are judged up to here (shutdown reconfigures DDS)
        crashed, status = stop_processes({"planner": planner, "plant": plant}, storm, recorder, probes)
    steal_s = (steal_ticks() - steal0) / os.sysconf("SC_CLK_TCK")
    duration = time.monotonic() - t_start
    log = planner_log.read_text()
    internal_log = [line for line in log.splitlines() if INTERNAL.search(line)]
    internal_log += [line for line in plant_log.read_text().splitlines() if INTERNAL.search(line)]
    topic_refused = len(re.findall(r"(~/goal|~/joint_trajectory): refused: ", log))
    early_refused = len(re.findall(r"~/joint_trajectory: refused: .*time_from_start: 0.01 s is before", log))
    stream = stream_gaps(commands_out, trace_out, probe_outs, args.rate, teardown_ns)
    out.update(
        sent=sent,
        duration_s=duration,
        kinds=kinds,
        crashes=crashed,
        exit_status=status,
        internal_error_texts=len(internal_answers) + len(internal_log),
        internal_examples=(internal_answers + internal_log)[:5],
        invalid_sent=invalid["sent"] + topic_invalid,
        invalid_refused=invalid["refused_answers"] + min(topic_refused, topic_invalid),
        invalid_topic_sent=topic_invalid,
        topic_refusals_logged=topic_refused,
        invalid_unrefused=invalid["unrefused"][:5],
        early_sent=early,
        early_refused=early_refused,
        **stop_summary(stops),
        load_average=[round(x, 2) for x in os.getloadavg()],
        load_at_start=load0,
        steal_s=steal_s,
        settled_checked=len(settled),
        settled_ok=int(sum(e <= 1e-9 for e in settled)),
        settled_max_error=float(max(settled)) if settled else math.nan,
        settled_over_1e9=settled_bad[:5],
        goals_superseded=int(float(planner_value("goals_superseded", "0") or 0)),
        goals_cancelled=int(float(planner_value("goals_cancelled", "0") or 0)),
        rss_mb=rss,
        rss_tail_mb=rss_tail,
        logs=str(tmp),
        **stream,
    )
    return out


def main() -> None:
    args = _args()
    import rclpy

    rclpy.init(args=[])
    try:
        results = [run_mode(args, m) for m in args.modes]
    finally:
        rclpy.try_shutdown()
    if args.json:
        for r in results:
            print(json.dumps(r))
        return
    print_report(results, args)


if __name__ == "__main__":
    main()
