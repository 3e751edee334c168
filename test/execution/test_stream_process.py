"""The command stream in a forked process (issue 16): the planner's proxy drives it exactly as the in-process stream.

A fake publisher in the child writes every sample to a file: what the child
sends must be the timeline the parent installed (a splice at a future sample,
a splice at a sample already sent refused), each move ending with the hold,
a stop mid-move cutting it off with the hold, and the parent's replay of the
shared ring giving the same samples, counts and segment events.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

# Run in a fresh interpreter: a fork is safe only from a process with one thread (pytest may have more).
SCRIPT = r"""
import json, os, sys, tempfile, time
import numpy as np
from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.execution.output import OutputSettings
from flexmotion_ros.execution.remote_stream import RemoteStream
from flexmotion_ros.execution.stream_process import StreamProcess
from flexmotion_ros.execution.stream_server import ChildSettings
from flexmotion_ros.execution.timeline import Segment

path = tempfile.mktemp()

def open_output(cfg):
    f = open(path, "a", buffering=1)
    return (lambda row: f.write(" ".join(repr(v) for v in row) + "\n"), lambda: 3, f.close)

def sent():
    with open(path) as f:
        return [float(line.split()[0]) for line in f]

def wait(pred, t=10.0):
    end = time.monotonic() + t
    while not pred():
        assert time.monotonic() < end, "timeout"
        time.sleep(0.01)

proc = StreamProcess.fork(open_output)
model = ModalModel(b0=1.0, omega=(5.0,), zeta=(0.01,), b=(1.0,))
cfg = ChildSettings(rate_hz=500.0, hold_when_idle=False, priority=0, inputs=1, output=OutputSettings(), model=model,
                    joint_name="j", topic="/commands", namespace="/", node_name="x", qos_depth=10, qos_reliable=True)
proc.call("configure", cfg)
events, samples, sent_log = [], [], []
rs = RemoteStream(proc, 500.0, False, on_start=lambda s: events.append(("start", s.start)),
                  on_finish=lambda s: events.append(("finish", s.start)),
                  on_sample=lambda k, u, t: samples.append((k, u)), on_publish=lambda u, t: sent_log.append(u))
out = {}
rs.start()
wait(lambda: proc.progress.matched == 3)
out["matched"] = rs.process.progress.matched
a = Segment(np.linspace(1.0, 2.0, 200), np.zeros((201, 3)))
k0 = rs.start_now(a)
k_next, timeline = rs.snapshot()
out["mirror"] = [s is a for s in timeline]
b = Segment(np.full(30, -1.0), np.zeros((31, 3)))
out["splice_ahead"] = rs.splice(b, k0 + 150)
out["splice_behind"] = rs.splice(Segment(np.ones(5), np.zeros((6, 3))), k0)
wait(lambda: rs.idle and ("finish", k0 + 150) in events)
time.sleep(0.1)
out["sent_move"] = sent() == list(a.commands[:150]) + list(b.commands) + [0.0]
out["events"] = events == [("start", k0), ("start", k0 + 150), ("finish", k0 + 150)]
out["replayed"] = [u for _, u in samples] == sent() and sent_log == sent() and rs.samples_sent == len(sent())
out["indices"] = [k for k, _ in samples] == list(range(k0, k0 + 181))
out["timing"] = len(rs.recent_timing(181)[0]) == 181
c = Segment(np.full(500, 0.5), np.zeros((501, 3)))
k1 = rs.start_now(c)
wait(lambda: len(sent()) > 181 + 20)
halt = rs.stop("shutdown")
time.sleep(0.1)
s = sent()
out["halt"] = [halt.cause.value, halt.hold_sent, halt.interrupted, halt.held]
out["stopped_with_hold"] = s[-1] == 0.0 and all(v == 0.5 for v in s[181:-1]) and len(s) < 181 + 500
out["again"] = rs.stop("shutdown") is halt
out["replayed_hold"] = sent_log[-1] == 0.0 and rs.samples_sent == len(s)
try:
    rs.start_now(Segment(np.ones(3), np.zeros((4, 3))))
    out["refused_when_stopped"] = False
except RuntimeError:
    out["refused_when_stopped"] = True
rs.close()
proc.close()
try:
    os.waitpid(proc.pid, os.WNOHANG)
    out["reaped"] = False
except ChildProcessError:
    out["reaped"] = True
print(json.dumps(out))
"""


def test_the_stream_process_plays_the_timeline_the_planner_installs_and_ends_with_the_hold():
    proc = subprocess.run(
        [sys.executable, "-c", SCRIPT], cwd=ROOT, capture_output=True, text=True, timeout=120, check=False
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["matched"] == 3  # the child's publisher's matched count, read from the shared header
    assert out["mirror"] == [True]  # the planner's own segment, with its record
    assert out["splice_ahead"] and not out["splice_behind"]  # the child decides: a sample already sent is refused
    assert out["sent_move"]  # the first segment up to the splice, the second, the hold: nothing else
    assert out["events"] and out["replayed"] and out["indices"] and out["timing"], out
    assert out["halt"] == ["stopped", True, True, True]  # cut off mid-move, the hold sent
    assert out["stopped_with_hold"] and out["again"] and out["replayed_hold"], out
    assert out["refused_when_stopped"] and out["reaped"], out
