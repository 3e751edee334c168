"""The command stream with several inputs (issue 12): rows of m values, the hold is zero on every input."""

from __future__ import annotations

import numpy as np

from flexmotion_ros.execution import HOLD, Segment
from flexmotion_ros.execution.command_stream import CommandStream
from flexmotion_ros.execution.timeline import command_text, is_hold

from .test_command_stream import RATE, FakeClock, make_stream


def rows(commands) -> Segment:
    u = np.asarray(commands, float)
    return Segment(u, np.zeros((u.shape[0] + 1, 8)))


def test_a_move_of_rows_then_one_hold():
    stream, _, rec = make_stream()
    seg = rows([[1.0, -2.0], [0.5, 0.0], [0.0, 3.0]])
    assert seg.samples == 3 and seg.command(1).tolist() == [0.5, 0.0]
    stream.start_now(seg)
    for _ in range(5):
        stream.step()
    assert [np.asarray(v).tolist() for v in rec.values[:3]] == [[1.0, -2.0], [0.5, 0.0], [0.0, 3.0]]
    assert rec.values[3] == HOLD and len(rec.values) == 4  # one hold, then silent (hold_when_idle False)
    assert rec.finished == [seg] and stream.idle


def test_stop_mid_move_holds_every_input_and_a_partly_zero_row_is_not_the_hold():
    stream, _, rec = make_stream()
    stream.start_now(rows([[1.0, 2.0], [0.0, 5.0], [0.0, 0.0]]))
    stream.step()
    stream.step()  # last sent: [0, 5]: the bridge still pushes
    halt = stream.stop("shutdown")
    assert halt.hold_sent and halt.held and halt.interrupted and rec.values[-1] == HOLD
    assert is_hold(HOLD) and is_hold([0.0, 0.0]) and not is_hold([0.0, 5.0]) and not is_hold(None)


def test_a_failed_hold_names_the_last_row():
    clock = FakeClock()
    sent: list = []

    def publish(value) -> None:
        if is_hold(value):
            raise OSError("publisher gone")
        sent.append(value)

    stream = CommandStream(RATE, publish, False, clock=clock, sleep=clock.sleep)
    stream.start_now(rows([[1.0, -2.5], [1.0, -2.5]]))
    stream.step()
    halt = stream.stop("shutdown")
    assert not halt.held and "the last command sent was [1, -2.5]" in halt.describe(), halt.describe()
    assert command_text(0.25) == "0.25" and command_text(np.array([0.0, 1.5])) == "[0, 1.5]"
