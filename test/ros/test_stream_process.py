"""The command stream in a process of its own (the executable): the hold arrives whatever ends the planner.

The planner executable forks a stream process before ``rclpy.init``
(:mod:`flexmotion_ros.execution.stream_process`); the deadline loop and the
``commands`` publisher live there.  If the planner's process dies mid-move
-- here SIGKILL: no handler, no shutdown -- the stream process sees the end of
its request pipe and ends the move with the hold, then exits.
"""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import numpy as np
from std_msgs.msg import Float64

from .conftest import wait_for
from .test_safety import ROOT, planner_process


def _children(pid: int) -> list[int]:
    try:
        return [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
    except FileNotFoundError:
        return []


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(") ")[1].split()[0] != "Z"
    except (FileNotFoundError, IndexError):
        return False


def wait_for_planner(probe) -> None:
    """Until the planner reads our goals and its stream process's writer has matched our commands reader."""
    wait_for(lambda: probe.goal_pub.get_subscription_count() >= 1, 30.0, "the planner's ~/goal")
    wait_for(
        lambda: (st := probe.planner_status()) is not None and int(st[2]["command_subscribers"]) >= 1,
        30.0,
        "the planner matching our commands subscription (writer side, in the stream process)",
    )


def test_the_planner_killed_mid_move_the_stream_process_sends_the_hold_and_ends(ros):
    # in-process stream (the old main): SIGKILL leaves the last command at full force, no hold follows
    probe = ros.probe
    proc = planner_process(ROOT)
    try:
        wait_for_planner(probe)
        children = _children(proc.pid)
        assert len(children) == 3, children  # planning: goals and stops; the stream
        probe.goal_pub.publish(Float64(data=1.0))
        wait_for(lambda: probe.command_values().size >= 200, 30.0, "1 s of commands")
        os.kill(proc.pid, signal.SIGKILL)
        proc.communicate(timeout=10.0)
        wait_for(lambda: not any(_alive(c) for c in children), 10.0, "the planner's children ending")
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    time.sleep(0.3)  # the last samples in flight
    u = probe.command_values()
    assert 200 <= u.size < 844, f"{u.size} commands: the move was not cut off mid-way"
    assert np.all(u[:-1] != 0.0)  # bang-bang: full force until the kill
    assert u[-1] == 0.0, f"the last command is {u[-1]!r}, not the hold"


def _thread_names(pid: int) -> list[str]:
    names = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            names.append((task / "comm").read_text().strip())
        except FileNotFoundError:
            pass
    return names


def test_a_real_time_stream_process_publishes_asynchronously(ros):
    # synchronous, the deadline loop pushed each sample into the readers' shared-memory ports under locks shared
    # with their processes (publishes blocked 3-27 ms in the 1 kHz storm); under stream_priority the stream
    # process's writer is asynchronous: Fast DDS gives it a sending thread of its own (dds.asyn.0.1, beside the
    # participant's dds.asyn.0.0), and the commands still arrive, the hold last
    probe = ros.probe
    proc = planner_process(ROOT, "stream_priority:=50")
    try:
        wait_for_planner(probe)
        streams = [c for c in _children(proc.pid) if any(n.startswith("dds.") for n in _thread_names(c))]
        assert len(streams) == 1, streams  # the stream process: the only child with a DDS participant
        names = _thread_names(streams[0])
        assert sum(n.startswith("dds.asyn") for n in names) >= 2, names
        probe.goal_pub.publish(Float64(data=0.2))
        wait_for(lambda: probe.command_values().size >= 50, 30.0, "commands")
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.communicate(timeout=15.0)
        except Exception:  # noqa: BLE001 -- killed below
            proc.kill()
            proc.communicate()
    time.sleep(0.3)
    assert probe.command_values()[-1] == 0.0  # the hold, flushed before the publisher went
