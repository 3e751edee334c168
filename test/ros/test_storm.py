"""A small seeded storm (issue 16), the same script as ``bench/storm.py`` with fewer requests.

Planner and plant run as their own processes (the ``ros2 run`` code: planning
in forked children), lockstep; 40 requests over every interface, 20 % invalid,
20 % mid-move.  Timing figures (stop answers within 50 ms, stream gaps) are
the bench's (recorded in bench/README.md); here only what must hold under any
load: no crash, no internal error text, every invalid request refused with a
reason, every mid-move stop applied within its look-ahead, settled moves at
the target at rest, the hold last.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_a_seeded_storm_crashes_nothing_refuses_every_invalid_request_and_settles_exactly():
    cmd = [sys.executable, str(ROOT / "bench" / "storm.py"), "--requests", "40", "--modes", "lockstep"]
    cmd += ["--seed", "11", "--json", "--max-seconds", "90"]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=180, check=False)
    assert proc.returncode == 0, proc.stderr[-3000:]
    r = json.loads(proc.stdout.strip().splitlines()[-1])
    assert r["sent"] == 40, r
    assert r["crashes"] == {} and r["exit_status"] == {"planner": 0, "plant": 0}, r
    assert r["internal_error_texts"] == 0, r["internal_examples"]
    # a too-early arrival can only be judged by planning it: a newer goal may supersede it first (counted)
    unjudged = r["early_sent"] - r["early_refused"]
    assert r["invalid_refused"] == r["invalid_sent"] - unjudged, (r["invalid_unrefused"], r["invalid_sent"])
    # each stop starts within the look-ahead it was planned with; one planned again (its plan overran the
    # look-ahead on a loaded machine, or the timeline changed) says so in its answer and is counted apart
    assert r["mid_move_stops"] >= 1, r
    assert r["stops_within_lead"] == r["mid_move_stops"] - r["stops_overran"], (
        r["stop_after_samples"],
        r["late_stop_texts"],
    )
    assert r["stops_overran"] <= r["mid_move_stops"] // 2, r["stops_overran"]  # replanning is the exception
    assert all(ms < 1000.0 for ms in r["stop_answer_ms"]), r["stop_answer_ms"]  # 50 ms: the bench's figure
    assert r["settled_checked"] >= 1 and r["settled_ok"] == r["settled_checked"], r["settled_max_error"]
    assert r["last_command"] == 0.0
