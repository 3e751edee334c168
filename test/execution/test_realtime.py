"""Scheduling of the threads that share the stream's interpreter lock (``execution/realtime.py``).

Run in a child process: the test process's own threads keep their scheduling.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = r"""
import os, threading, time
from flexmotion_ros.execution.realtime import lower_threads, normal_scheduling, raise_threads

stop = threading.Event()
def idle():
    stop.wait()
def numeric():
    stop.wait()
threads = [threading.Thread(target=idle, name="flexmotion-light"),
           threading.Thread(target=numeric, name="flexmotion-learn")]
for t in threads:
    t.start()
error = raise_threads(7, keep_normal=("flexmotion-learn",))
if error:
    print("REFUSED", error)
else:
    pol = lambda t: os.sched_getscheduler(t.native_id)
    main_id = threading.get_native_id()
    print("RAISED", pol(threads[0]) == os.SCHED_FIFO, pol(threads[1]) == os.SCHED_OTHER,
          os.sched_getscheduler(main_id) == os.SCHED_FIFO, os.sched_getparam(threads[0].native_id).sched_priority)
    new = threading.Thread(target=lambda: (normal_scheduling(), stop.wait()), name="flexmotion-identify")
    born = threading.Thread(target=stop.wait, name="born")
    born.start(); new.start(); time.sleep(0.05)
    print("INHERITED", os.sched_getscheduler(born.native_id) == os.SCHED_FIFO,
          os.sched_getscheduler(new.native_id) == os.SCHED_OTHER)
    lower_threads(keep_fifo=("born",))
    print("LOWERED", pol(threads[0]) == os.SCHED_OTHER, os.sched_getscheduler(main_id) == os.SCHED_OTHER,
          os.sched_getscheduler(born.native_id) == os.SCHED_FIFO)
    threads += [new, born]
stop.set()
for t in threads:
    t.join()
"""


@pytest.mark.skipif(not hasattr(os, "sched_setscheduler"), reason="Linux scheduling only")
def test_every_thread_but_the_numeric_ones_goes_fifo_and_threads_born_later_inherit_it():
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env, timeout=60, check=True
    )
    lines = dict(line.split(" ", 1) for line in out.stdout.strip().splitlines())
    if "REFUSED" in lines:
        # no CAP_SYS_NICE / rtprio limit: the node warns and keeps normal scheduling; the text says so
        assert "refused" in lines["REFUSED"] and "normal scheduling" in lines["REFUSED"]
        pytest.skip(f"SCHED_FIFO not permitted here: {lines['REFUSED']}")
    assert lines["RAISED"] == "True True True 7"
    assert lines["INHERITED"] == "True True"
    assert lines["LOWERED"] == "True True True"


def _garbage(n: int) -> None:
    for _ in range(n):
        a: list = []
        a.append(a)  # a cycle: only a collection frees it


def test_the_slack_collector_collects_only_what_fits_before_the_next_deadline_or_has_waited_too_long():
    import gc

    from flexmotion_ros.execution.realtime import SlackCollector

    t = {"now": 0.0, "step": 0.004}

    def clock() -> float:  # every reading 4 ms later: a measured collection costs 4 ms
        t["now"] += t["step"]
        return t["now"]

    col = SlackCollector(fraction=0.5, force_after_s=(1.0, 5.0, 60.0), clock=clock)
    young = gc.get_threshold()[0]
    was = gc.isenabled()
    try:
        gc.enable()
        col.enable()
        assert not gc.isenabled()  # automatic collection off while enabled
        gc.collect()
        _garbage(2 * young)
        assert gc.get_count()[0] >= young  # due, and not collected automatically
        col(0.001)  # no cost known yet: the first collection runs (and is measured: 4 ms)
        assert col.collections[0] == 1 and gc.get_count()[0] < young
        assert col.expected_cost(0) == 0.004
        _garbage(2 * young)
        col(0.005)  # 4 ms does not fit in half of 5 ms: it waits
        col(0.005)
        assert col.collections[0] == 1
        col(0.010)  # fits in half of 10 ms
        assert col.collections[0] == 2 and col.forced[0] == 0
        _garbage(2 * young)
        col(0.001)
        t["now"] += 1.5  # due for longer than force_after_s[0] = 1 s: collected anyway
        col(0.001)
        assert col.collections[0] == 3 and col.forced[0] == 1
        col.disable()
        assert gc.isenabled()
    finally:
        col.disable()
        if was:
            gc.enable()
        else:
            gc.disable()


def test_a_primed_slack_collector_knows_every_generations_cost_before_the_first_sample():
    # unprimed, a generation's expected cost is 0 until its first collection, so the first sample after it is due
    # collects it whatever it costs: in the stream process a full collection at the first sample took 55-96 ms
    import gc

    from flexmotion_ros.execution.realtime import SlackCollector

    t = {"now": 0.0}

    def clock() -> float:  # every reading 4 ms later: a measured collection costs 4 ms
        t["now"] += 0.004
        return t["now"]

    col = SlackCollector(fraction=0.5, force_after_s=(1.0, 5.0, 60.0), clock=clock)
    was = gc.isenabled()
    try:
        col.enable(prime=True, freeze=True)
        assert not gc.isenabled()
        assert [col.expected_cost(g) for g in range(3)] == [0.004, 0.004, 0.004]
        assert gc.get_freeze_count() > 0  # the heap so far is permanent: later full collections skip it
        _garbage(2 * gc.get_threshold()[0])
        col(0.001)  # due, but its known cost does not fit in the slack: it waits
        assert col.collections == [0, 0, 0]
    finally:
        col.disable()
        gc.unfreeze()
        if was:
            gc.enable()
        else:
            gc.disable()
