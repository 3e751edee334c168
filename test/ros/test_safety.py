"""Safety (issue 11): whatever ends a move, the last command is the hold; Ctrl-C is clean; a stop is quick.

Real rclpy nodes over real DDS: the planner as its own process (the code
``ros2 run flexmotion_ros planner`` runs) for SIGINT / SIGTERM, in-process
through the standard lifecycle services for deactivation, and ``~/stop``
against a ready stop.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from flexmotion_ros.execution import lead_samples
from flexmotion_ros.execution.ready_stops import STOP_MARGIN_SAMPLES, STOP_PREP_DUTY
from flexmotion_ros.nodes.planner_node import PlannerNode

from .conftest import FAST, NAMESPACE, goal_request, overrides, wait_for

ROOT = Path(__file__).resolve().parents[2]
PLANNER = f"{NAMESPACE}/flexmotion_planner"
#: No plant here: the planner assumes where the machine is (open loop).
ASSUMED = {"state.source": "assumed"}


def planner_process(cwd: Path, *params: str) -> subprocess.Popen:
    """The planner executable (``python -m``) in the test's domain and namespace, silent while idle."""
    cmd = [
        sys.executable,
        "-m",
        "flexmotion_ros.nodes.planner_node",
        "--ros-args",
        "-r",
        f"__ns:={NAMESPACE}",
        "--params-file",
        str(ROOT / "config" / "wie_bernstein.yaml"),
        "-p",
        "rate_hz:=200.0",
        "-p",
        "publish_hold_when_idle:=false",
        "-p",
        "state.source:=assumed",
        *[a for p in params for a in ("-p", p)],
    ]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def interrupt_mid_move(ros, cwd: Path, sig: int) -> tuple[np.ndarray, int, str, str]:
    """Start the planner, move 1.0 (a 4.2 s move, 844 samples at 200 Hz), signal it 2 s in.

    Returns the commands received, the exit status, stdout and stderr.
    """
    probe = ros.probe
    proc = planner_process(cwd)
    try:
        # readiness from the writer side: the planner reports its matched command subscribers
        wait_for(lambda: probe.goal_pub.get_subscription_count() >= 1, 30.0, "the planner's ~/goal")
        wait_for(
            lambda: (st := probe.planner_status()) is not None and int(st[2]["command_subscribers"]) >= 1,
            30.0,
            "the planner matching our commands subscription",
        )
        probe.goal_pub.publish(Float64(data=1.0))
        wait_for(lambda: probe.command_values().size >= 400, 30.0, "2 s of commands")
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=20.0)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    time.sleep(0.3)  # the last samples in flight
    return probe.command_values(), proc.returncode, out, err


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_mid_move_ends_with_the_hold_exit_status_0_and_no_traceback(ros, sig):
    # old main: the last command was the full force (0.99987 N at 1 kHz) and no zero followed;
    # 5 of 16 Ctrl-C printed "RCLError: publisher's context is invalid" from the stream thread
    u, status, out, err = interrupt_mid_move(ros, ROOT, sig)
    assert 400 <= u.size < 844, f"{u.size} commands: the move was not cut off mid-way"
    assert np.all(u[:-1] != 0.0)  # bang-bang: full force until the signal
    assert u[-1] == 0.0, f"the last command is {u[-1]!r}, not the hold"
    assert status == 0, err
    assert "Traceback" not in err and "Traceback" not in out, err
    log = out + err
    assert "command stream stopped (shutdown): hold (0) sent" in log and "cut off" in log, log


def lifecycle(ros, transition: int) -> bool:
    client = ros.probe.create_client(ChangeState, f"{PLANNER}/change_state")
    assert client.wait_for_service(timeout_sec=10.0)
    req = ChangeState.Request()
    req.transition.id = transition
    return bool(ros.call(client, req).success)


def lifecycle_state(ros) -> str:
    client = ros.probe.create_client(GetState, f"{PLANNER}/get_state")
    assert client.wait_for_service(timeout_sec=10.0)
    return ros.call(client, GetState.Request()).current_state.label


def test_deactivating_mid_move_ends_with_the_hold_and_activating_streams_again(ros):
    planner = ros.planner(**ASSUMED)
    ros.connected(planner, subscribers=1)
    probe = ros.probe
    assert lifecycle_state(ros) == "active"
    resp = ros.call(probe.move, goal_request(1.0))
    assert resp.plan.header.frame_id != "" and not resp.plan.header.frame_id.startswith("error")
    samples = planner.installed[-1].samples  # 222 at 200 Hz
    wait_for(lambda: probe.command_values().size >= 60, 10.0, "the move under way")
    assert lifecycle(ros, Transition.TRANSITION_DEACTIVATE)
    assert lifecycle_state(ros) == "inactive"
    time.sleep(0.3)
    u = probe.command_values()
    assert u.size < samples + 1 and u[-1] == 0.0 and np.all(u[:-1] != 0.0)
    n = u.size
    assert planner.stream.halted is not None and planner.stream.halted.interrupted
    # inactive: goals are refused with the reason, nothing moves; /diagnostics says inactive
    resp = ros.call(probe.move, goal_request(0.0))
    assert resp.plan.header.frame_id.startswith("error: the planner is inactive")
    wait_for(lambda: (st := probe.planner_status()) is not None and st[2]["lifecycle"] == "inactive", 5.0, "status")
    assert probe.command_values().size == n
    # active again: the next move streams and ends with its own hold
    assert lifecycle(ros, Transition.TRANSITION_ACTIVATE)
    resp = ros.call(probe.move, goal_request(0.0))
    assert not resp.plan.header.frame_id.startswith("error"), resp.plan.header.frame_id
    seg = planner.installed[-1]
    wait_for(lambda: probe.command_values().size >= n + seg.samples + 1, 15.0, "the second move and its hold")
    u = probe.command_values()
    assert u[-1] == 0.0 and u.size == n + seg.samples + 1


def test_lifecycle_from_unconfigured_configure_refuses_a_bad_value_and_changes_nothing(ros):
    bad = PlannerNode(
        autostart=False,
        context=ros.context,
        namespace=NAMESPACE,
        parameter_overrides=overrides({**FAST, **ASSUMED, "model.zeta": [0.01, -0.5]}),
    )
    ros.add(bad)
    assert lifecycle_state(ros) == "unconfigured"
    assert not lifecycle(ros, Transition.TRANSITION_CONFIGURE)
    assert lifecycle_state(ros) == "unconfigured" and bad.lifecycle_state == "unconfigured"
    assert "model.zeta[1]" in str(bad._configure_error)  # noqa: SLF001 -- the one line the log got


def test_a_stop_takes_effect_within_a_few_samples_from_a_ready_stop(ros):
    # old main: ~/stop planned from the state a full look-ahead ahead (>= 1.5 x the slowest plan + 20 ms:
    # >= 10 samples at 200 Hz, 273 ms measured under load); now a ready stop starts a few samples after the request.
    # A ready stop is a few samples ahead of the stream: on a loaded machine the stream may pass it before
    # the request is served (then the stop is planned on demand); up to five moves are tried for one (a ready stop further than READY_STOP_LEADS look-aheads is not taken).
    planner = ros.planner(**ASSUMED)
    ros.connected(planner, subscribers=1)
    probe = ros.probe
    stops = planner.stop_preparer
    for attempt in range(5):
        target = 1.0 if attempt % 2 == 0 else 0.0
        resp = ros.call(probe.move, goal_request(target))
        assert not resp.plan.header.frame_id.startswith("error")
        move = planner.installed[-1]
        # the first stops a fresh process plans can be slow: the move may end before one is ready
        wait_for(lambda move=move: stops.ready() or planner.stream.snapshot()[0] > move.end, 10.0, "a ready stop")
        if not stops.ready():
            ans, ready = Trigger.Response(message="the move ended before a stop was ready"), False
            continue
        k_req = planner.stream.snapshot()[0]
        ans = ros.call(probe.stop, Trigger.Request())
        assert ans.success, ans.message
        wait_for(lambda move=move: planner.installed[-1] is not move, 10.0, "the stop installed")
        stop = planner.installed[-1]
        assert stop.info.target is None
        ready = "; a ready stop" in ans.message
        wait_for(lambda stop=stop: probe.command_values().size >= stop.end + 1, 10.0, "the stop and its hold")
        time.sleep(0.1)
        if ready:
            break
    assert ready, f"no ready stop was used in 5 moves: {ans.message}"
    latency = stop.start - k_req  # samples from the request to the stop's first command
    # the old main's look-ahead for the same planning time, its shortest possible stop latency
    old_lead = lead_samples(stops.plan_times, 0.05, 200.0)
    # ready stops are one preparer cycle apart: a planning time / STOP_PREP_DUTY (the preparer plans at most
    # that fraction of the time), and the earliest is at least STOP_MARGIN_SAMPLES ahead
    cycle = math.ceil((1.0 + 1.0 / STOP_PREP_DUTY) * max(stops.plan_times) * 200.0)
    bound = max(8, cycle + STOP_MARGIN_SAMPLES)
    assert 1 <= latency <= bound and latency <= old_lead, (latency, bound, old_lead, list(stops.plan_times))
    np.testing.assert_array_equal(stop.states[0], move.state_at(stop.start))  # from exactly the predicted state
    assert stop.info.result.sampled is not None  # a verified sampled plan, as every plan
    np.testing.assert_allclose(stop.states[-1][1:], 0.0, atol=1e-6)  # at rest: velocity and every mode
    assert stop.end <= move.end  # never later than the move itself would have come to rest
    u = probe.command_values()
    assert u[-1] == 0.0 and u.size == stop.end + 1
    assert np.array_equal(u[stop.start : stop.end], stop.commands)


def test_under_stream_priority_the_stream_process_runs_under_sched_fifo_and_the_planner_does_not(ros):
    """``stream_priority`` 50: the stream process's loop at SCHED_FIFO 50, its other threads 49, the planner 48,
    the goal-planning child 47 at each plan's start (the stop-planning child normal).

    The deadline loop and the ``commands`` publisher run in a process of their own (forked before
    ``rclpy.init``): nothing else holds that interpreter's lock.  In the planner's process the stream shared
    the lock with the executor, DDS callbacks and message building: a 1 kHz storm still had 295 of its own
    gaps over two periods (max 136 ms, ``bench/storm.py --rate 1000 -p stream_priority:=50``).
    """
    proc = planner_process(ROOT, "stream_priority:=50")
    try:
        wait_for(
            lambda: (st := ros.probe.planner_status()) is not None and st[2].get("lifecycle", "active") == "active",
            30.0,
            "the planner active",
        )
        wait_for(lambda: ros.probe.goal_pub.get_subscription_count() >= 1, 30.0, "the planner's ~/goal")
        time.sleep(0.5)

        def policies_of(pid: int) -> dict[int, tuple[int, int]]:
            out = {}
            for tid in [int(t) for t in os.listdir(f"/proc/{pid}/task")]:
                try:  # a short-lived worker thread may end meanwhile
                    out[tid] = (os.sched_getscheduler(tid), os.sched_getparam(tid).sched_priority)
                except (ProcessLookupError, FileNotFoundError):
                    pass
            return out

        planner = policies_of(proc.pid)
        children = [int(c) for c in Path(f"/proc/{proc.pid}/task/{proc.pid}/children").read_text().split()]
        child_policies = {c: policies_of(c) for c in children}
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=20.0)
    if "refused" in out + err:
        pytest.skip("SCHED_FIFO not permitted here (the node warned and kept normal scheduling)")
    assert "the command stream runs in process" in out + err and "under SCHED_FIFO 50" in out + err, out + err
    # the planner's threads share no lock with the stream: two steps below it (a stop's answer is not delayed
    # by ordinary processes), but the learner, which fits models in-process (flexmotion-learn), stays normal
    assert "this process's threads SCHED_FIFO 48" in out + err, out + err
    assert sorted(planner.values()).count((os.SCHED_OTHER, 0)) == 1, planner
    assert all(p in ((os.SCHED_FIFO, 48), (os.SCHED_OTHER, 0)) for p in planner.values()), planner
    streaming = [c for c, ps in child_policies.items() if (os.SCHED_FIFO, 50) in ps.values()]
    assert len(streaming) == 1 and len(children) == 3, child_policies  # planning: goals, stops; the stream
    threads = child_policies[streaming[0]]
    assert sorted(p for p in threads.values() if p[1] == 50) == [(os.SCHED_FIFO, 50)], threads
    assert all(p == (os.SCHED_FIFO, 49) for p in threads.values() if p[1] != 50), threads
    planning = [c for c in children if c not in streaming]
    # the goal-planning child waits boosted (SCHED_FIFO 47 for the first BOOST_BUDGET_S of each urgent plan, so
    # that a busy machine does not delay a move's first command); the stop-planning child stays normal
    kinds = sorted(sorted(set(child_policies[c].values())) for c in planning)
    assert kinds == [[(os.SCHED_OTHER, 0)], [(os.SCHED_FIFO, 47)]], child_policies
    assert "goal planning SCHED_FIFO 47 for the first 50 ms of each plan" in out + err, out + err
