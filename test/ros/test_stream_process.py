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


def test_the_planner_killed_mid_move_the_stream_process_sends_the_hold_and_ends(ros):
    # in-process stream (the old main): SIGKILL leaves the last command at full force, no hold follows
    probe = ros.probe
    proc = planner_process(ROOT)
    try:
        wait_for(lambda: probe.goal_pub.get_subscription_count() >= 1, 30.0, "the planner's ~/goal")
        wait_for(
            lambda: (st := probe.planner_status()) is not None and int(st[2]["command_subscribers"]) >= 1,
            30.0,
            "the planner matching our commands subscription (writer side, in the stream process)",
        )
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
