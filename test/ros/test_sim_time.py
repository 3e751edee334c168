"""``use_sim_time: true``: the command stream runs on the node's ROS clock, so ``/clock`` drives it.

Old main streamed at the wall-clock rate whatever ``/clock`` did.
"""

from __future__ import annotations

import time

import numpy as np
from rosgraph_msgs.msg import Clock

from flexmotion_ros.nodes import messages

from .conftest import FAST, wait_for

T0 = 100.0  # s, simulated


def test_stream_advances_only_as_clock_advances(ros):
    planner = ros.planner(use_sim_time=True, **{"state.source": "assumed"})
    ros.connected(planner, subscribers=1)
    clock = ros.probe.create_publisher(Clock, "/clock", 10)

    def set_clock(t: float) -> None:
        clock.publish(Clock(clock=messages.to_time(t)))

    def ros_now() -> float:
        return planner.get_clock().now().nanoseconds * 1e-9

    def until_clock(t: float) -> None:
        def reached() -> bool:
            set_clock(t)
            return abs(ros_now() - t) < 1e-9

        wait_for(reached, 10.0, f"/clock at {t} s")

    until_clock(T0)
    out = planner.request(1.0, execute=True, source="test")
    assert out.ok and out.segment.samples == 222, out
    assert abs(out.start_time - T0) < 1e-9, out.start_time  # the first command is due now, in ROS time
    dt = 1.0 / FAST["rate_hz"]
    time.sleep(0.5)  # 0.5 s of wall time, /clock frozen: only the sample due now went out (100 at the wall rate)
    assert planner.stream.samples_sent == 1, planner.stream.samples_sent
    until_clock(T0 + 20.5 * dt)  # 0.1025 s on: samples 0..20 are due
    wait_for(lambda: planner.stream.samples_sent >= 21, 5.0, "21 samples")
    time.sleep(0.3)
    assert planner.stream.samples_sent == 21, planner.stream.samples_sent
    assert not planner.stream.idle
    for k in range(1, 13):  # the rest of the 1.11 s move, in 0.1 s steps of simulated time
        until_clock(T0 + 20.5 * dt + 0.1 * k)
    wait_for(lambda: planner.stream.idle, 5.0, "the end of the move")
    assert planner.stream.samples_sent == 223  # every command and the hold, none skipped
    wait_for(lambda: len(ros.probe.commands) >= 223, 5.0, "223 commands at the probe")
    np.testing.assert_array_equal(ros.probe.command_values(), np.append(out.segment.commands, 0.0))
    # the deadlines were on the simulated clock: sample k sent at ROS time >= T0 + k dt
    sent = np.array(planner.stream.sent_times)
    assert np.all(sent >= T0 + dt * np.arange(sent.size) - 1e-9), sent[:5]
    assert sent[-1] < T0 + 2.0


def test_without_sim_time_the_stream_keeps_the_wall_clock(ros):
    planner = ros.planner(**{"state.source": "assumed"})
    ros.connected(planner, subscribers=1)
    out = planner.request(1.0, execute=True, source="test")
    t0 = time.monotonic()
    wait_for(lambda: planner.stream.idle, 10.0, "the end of the move")
    assert out.ok and planner.stream.samples_sent == 223
    assert 1.0 < time.monotonic() - t0 < 3.0  # 1.115 s of wall time
    sent = np.array(planner.stream.sent_times)
    assert abs(sent[0] - t0) < 1.0  # monotonic seconds, as before
