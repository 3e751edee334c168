#!/usr/bin/env python3
"""One line per case of ``bench/fuzz.py``'s random models, guarded by CPU time (a shared machine).

The cases, options and the independent check are ``bench/fuzz.py``'s own
(``draw_case``, ``options_for``, ``run_case``: ``plan_move`` and the plan's
own ``scipy.linalg.expm`` propagation); this driver only prints each case as
it finishes (so a long run can be read, resumed with ``--first`` and
compared case by case between two trees) and puts the per-case guard on the
process's CPU time (``ITIMER_PROF``) instead of the wall clock: on a machine
shared by several jobs at ``nice`` 10, wall-clock times were 10-20 times the
CPU times and a 30 s wall guard counted 0.8 s cases as hangs.

Each line: ``method index N=modes rest|mov 'kind' wall=ms cpu=ms cert=... | reason``;
``wall`` is ``plan_move`` alone, ``cpu`` the case's CPU time including the check.

Usage::

    OPENBLAS_NUM_THREADS=1 nice -n 10 python bench/fuzz_cases.py --method min_fuel --cases 1000
    OPENBLAS_NUM_THREADS=1 python bench/fuzz_cases.py --method fixed_time --only 5,227 --modes-at-most 4
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import signal
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fuzz  # noqa: E402 (bench/fuzz.py: the cases and the check)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--method", required=True)
    ap.add_argument("--cases", type=int, default=1000)
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("--only", default=None, help="comma-separated case indices")
    ap.add_argument("--seed", type=int, default=15)
    ap.add_argument("--rate", type=float, default=100.0)
    ap.add_argument("--timeout", type=float, default=30.0, help="per-case guard on CPU time (s)")
    ap.add_argument("--max-modes", type=int, default=8)
    ap.add_argument("--modes-at-most", type=int, default=None)
    args = ap.parse_args()
    signal.signal(signal.SIGPROF, fuzz._alarm)
    # run_case arms fuzz.TIMER[0]: the guard on this process's CPU time (ITIMER_PROF, SIGPROF).  Patching
    # signal.ITIMER_REAL (as before) did nothing, TIMER having read it at import: the guard stayed on the
    # wall clock and, SIGALRM having no handler here, its first expiry killed the whole run.
    fuzz.TIMER[0] = signal.ITIMER_PROF
    indices = [int(i) for i in args.only.split(",")] if args.only else range(args.first, args.first + args.cases)
    for i in indices:
        case = fuzz.draw_case(args.seed, i, args.max_modes)
        if args.modes_at_most is not None and case.model.n_modes > args.modes_at_most:
            continue
        c0 = time.process_time()
        o = fuzz.run_case(args.method, case, args.rate, args.timeout)
        cpu = time.process_time() - c0
        print(
            f"{args.method} {i} N={case.model.n_modes} {'mov' if case.moving else 'rest'} {o.kind!r} "
            f"wall={o.seconds * 1e3:.1f} cpu={cpu * 1e3:.1f} cert={o.certified} | {o.reason}",
            flush=True,
        )


if __name__ == "__main__":
    main()
