#!/usr/bin/env python3
"""Fuzz the planners over random models (issue 15): every plan checked, every refusal counted.

Random cases, seeded and reproducible (case ``i`` of seed ``s`` is the same
whatever ``--cases`` and ``--methods``), drawn as the issue's audit did:

* ``N`` = 1..``--max-modes`` (default 8) modes, frequencies log-uniform in
  0.3..60 rad/s, neighbours at least 5 % apart (distinct), ``zeta`` uniform
  in 0..0.3, ``b_i`` uniform in [-2, 2] (at least 0.05 away from 0), ``b0``
  log-uniform in 0.1..5, ``c`` uniform in [-1, 0] for a quarter of the
  models (else 0), ``u_max`` log-uniform in 0.1..10;
* moves log-uniform in 1e-3..1e3 of ``model.natural_distance(u_max)``, of
  either sign; a fifth of them from a moving, vibrating state (velocity and
  every mode's deflection and rate of the move's own scale).

Every returned plan is checked here, independently of the planner: the
continuous profile and the command sequence are propagated by
``scipy.linalg.expm`` of the augmented matrix ``[[A, B], [0, 0]]`` (one
exponential per piece; the package's own simulation is not used), the final
state compared with the target's rest state relative to the trajectory's own
excursion (per state), and ``|u| <= u_max`` checked.  A plan whose check
fails is counted as ``check failed`` (a wrong answer, worse than a crash).

Each case runs under a guard (``signal.setitimer``; no subprocess; on the
wall clock, or with ``--clock cpu`` on the process's user CPU time, so that
a hang does not depend on the machine's load): past ``--timeout`` seconds it
is interrupted at the next Python bytecode and counted as a hang (a long call inside HiGHS is only interrupted
when it returns: the time recorded is then the real one).

Usage::

    OPENBLAS_NUM_THREADS=1 python bench/fuzz.py --cases 10000 --methods time_optimal
    OPENBLAS_NUM_THREADS=1 python bench/fuzz.py --cases 1000 --methods zv,zvd,ei,robust_time_optimal,\\
        fixed_time,min_fuel --rate 100

``--show N`` prints the N slowest cases and every crash with a line that
rebuilds it (``--only I`` reruns case ``I``; ``--only I,J,K`` a list).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import math
import platform
import re
import signal
import time
import traceback
from collections import Counter, defaultdict
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm

from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.errors import FlexmotionError, InputError
from flexmotion_ros.core.methods.table import METHODS, plan_move
from flexmotion_ros.core.model.boundary import MoveProblem, state_to_rest
from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.core.time_optimal.rigid_body import rigid_time

#: The clock of a case's time: wall (``time.perf_counter``) or, with ``--clock cpu``, this
#: process's CPU time (``time.process_time``: far less sensitive to other jobs on a shared machine).
CLOCK = [time.perf_counter]
#: The per-case guard's timer: wall clock, or (``--clock cpu``) this process's user CPU time.
TIMER = [signal.ITIMER_REAL]
#: Independent check: final state within this of the target, relative to each state's excursion.
CHECK_RTOL = 1e-8
#: Longest command sequence checked sample by sample (longer ones: every 10th sample's state is skipped).
MAX_CHECKED_SAMPLES = 2_000_000


# ------------------------------------------------------------------ cases
@dataclass
class Case:
    index: int
    model: ModalModel
    u_max: float
    x0: np.ndarray
    target: float | None
    moving: bool

    def problem(self) -> MoveProblem:
        return state_to_rest(self.model, self.u_max, self.x0, self.target)

    def describe(self) -> str:
        m = self.model
        return (
            f"ModalModel(b0={m.b0!r}, c={m.c!r}, omega={m.omega!r}, zeta={m.zeta!r}, b={m.b!r}); "
            f"u_max={self.u_max!r}; x0={self.x0.tolist()!r}; target={self.target!r}"
        )


def draw_case(seed: int, index: int, max_modes: int) -> Case:
    """Case ``index`` of ``seed`` (its own generator: independent of the other cases)."""
    rng = np.random.default_rng([seed, index])
    n = int(rng.integers(1, max_modes + 1))
    while True:
        w = np.sort(np.exp(rng.uniform(math.log(0.3), math.log(60.0), n)))
        if n == 1 or np.all(w[1:] / w[:-1] >= 1.05):
            break
    zeta = rng.uniform(0.0, 0.3, n)
    b = rng.uniform(0.05, 2.0, n) * rng.choice([-1.0, 1.0], n)
    b0 = float(np.exp(rng.uniform(math.log(0.1), math.log(5.0))))
    c = float(-rng.uniform(0.0, 1.0)) if rng.random() < 0.25 else 0.0
    model = ModalModel(b0=b0, c=c, omega=tuple(map(float, w)), zeta=tuple(map(float, zeta)), b=tuple(map(float, b)))
    u_max = float(np.exp(rng.uniform(math.log(0.1), math.log(10.0))))
    size = float(np.exp(rng.uniform(math.log(1e-3), math.log(1e3))))
    d = model.natural_distance(u_max) * size * float(rng.choice([-1.0, 1.0]))
    x0 = np.zeros(model.n_states)
    moving = bool(rng.random() < 0.2)
    if moving:  # a moving, vibrating start of the move's own scale
        v = abs(model.b0) * u_max / float(w[0]) * size
        x0[1] = v * rng.uniform(-1.0, 1.0)
        for i in range(n):
            static = abs(b[i]) * u_max / w[i] ** 2 * size
            x0[2 + 2 * i] = static * rng.uniform(-1.0, 1.0)
            x0[3 + 2 * i] = static * w[i] * rng.uniform(-1.0, 1.0)
    return Case(index, model, u_max, x0, d, moving)


def options_for(method: str, case: Case) -> dict:
    """Options a method needs (extensible: add a row for a new method)."""
    problem = case.problem()
    T_rigid = rigid_time(problem.model, problem.u_max, problem.shifted_initial(), problem.include_position)
    slow = 2.0 * math.pi / min(case.model.omega)
    table = {
        "time_optimal_friction": {"coulomb_force": 0.2 * case.u_max},
        "fixed_time": {"arrival_time": 1.5 * T_rigid + slow},
        "limited": {"limits.velocity_max": 1.5 * abs(case.x0[1]) + abs(case.model.b0) * case.u_max * slow},
    }
    return dict(table.get(method, {}))


# --------------------------------------------------------- independent check
def _pieces_final(A: np.ndarray, B: np.ndarray, x0: np.ndarray, durations, levels):
    """States after each piece, by expm of the augmented matrix (own code, no package simulation)."""
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n] = A
    M[:n, n] = B
    x = np.append(x0, 0.0)
    out = [x0.copy()]
    cache: dict[float, np.ndarray] = {}
    for h, u in zip(durations, levels):
        E = cache.get(h)
        if E is None:
            E = expm(M * h)
            if len(cache) < 64:
                cache[h] = E
        x[n] = u
        x = E @ x
        out.append(x[:n].copy())
    return np.array(out)


def check_plan(problem: MoveProblem, result) -> str | None:
    """None if the plan is right, else what is wrong (own expm propagation)."""
    model = problem.model
    A, B = model.A(), model.B()
    target = model.rest_state(problem.target if problem.target is not None else 0.0)
    keep = slice(None) if problem.target is not None else slice(1, None)

    def judge(X: np.ndarray, what: str) -> str | None:
        dev = X - target
        scale = np.max(np.abs(dev[:, keep]), axis=0)
        scale = np.where(scale > 0.0, scale, 1.0)
        rel = float(np.max(np.abs(dev[-1, keep]) / scale))
        if not rel <= CHECK_RTOL:
            return f"{what}: final state off by {rel:.2e} of its excursion"
        return None

    cont = result.continuous
    if cont is not None and hasattr(cont, "switch_times") and hasattr(cont, "levels"):
        lv = np.asarray(cont.levels, float)
        if np.any(np.abs(lv) > problem.u_max):
            return "continuous: |u| > u_max"
        if cont.duration > 0.0:
            br = np.concatenate([[0.0], np.asarray(cont.switch_times, float), [cont.duration]])
            # pieces cut into parts of at most T/200: the excursion along the motion, not only at switches
            parts = np.maximum(1, np.ceil(np.diff(br) / (cont.duration / 200.0))).astype(int)
            X = _pieces_final(A, B, problem.x0, np.repeat(np.diff(br) / parts, parts), np.repeat(lv, parts))
            bad = judge(X, "continuous")
            if bad:
                return bad
    s = result.sampled
    if s is not None:
        u = np.asarray(s.commands, float)
        if u.size and float(np.max(np.abs(u))) > problem.u_max:
            return "sampled: |u| > u_max"
        if u.size > MAX_CHECKED_SAMPLES:
            return None
        n = A.shape[0]
        M = np.zeros((n + 1, n + 1))
        M[:n, :n] = A
        M[:n, n] = B
        E = expm(M * s.dt)
        Phi, Gam = E[:n, :n], E[:n, n]
        X = np.empty((u.size + 1, n))
        X[0] = problem.x0
        for k in range(u.size):
            X[k + 1] = Phi @ X[k] + Gam * u[k]
        return judge(X, "sampled")
    return None


# ------------------------------------------------------------------ guard
class Hang(BaseException):
    """The guard's timeout: a BaseException, so that no planner's ``except Exception`` (the fast
    paths record and survive their own errors) swallows it and runs on past the guard."""


def _alarm(signum, frame):
    raise Hang()


@dataclass
class Outcome:
    kind: str  # plan | refusal | crash | hang | check failed
    seconds: float
    reason: str = ""
    certified: bool | None = None
    #: With a rate: the sampled count proved fewest (``SampledProfile.minimal``); None without a sequence.
    minimal: bool | None = None
    #: A plan with no continuous profile (the sampled-first short moves: ``certified`` is then None).
    no_continuous: bool = False


def reason_key(text: str) -> str:
    """A refusal's message without its numbers (to count refusals by reason)."""
    text = re.sub(r"[-+]?\d[\d.eE+-]*", "#", text)
    return text[:110]


def run_case(method: str, case: Case, rate: float | None, timeout: float) -> Outcome:
    problem = case.problem()
    config = PlannerConfig(model=case.model, u_max=case.u_max, method=method, options=options_for(method, case))
    signal.setitimer(TIMER[0], timeout)
    t0 = CLOCK[0]()
    try:
        result = plan_move(config, problem, rate)
        dt = CLOCK[0]() - t0
    except Hang:
        return Outcome("hang", CLOCK[0]() - t0, f"over {timeout:g} s")
    except FlexmotionError as exc:
        dt = CLOCK[0]() - t0
        kind = "refusal (input)" if isinstance(exc, InputError) else "refusal (solver)"
        return Outcome(kind, dt, reason_key(str(exc)))
    except Exception as exc:  # noqa: BLE001 - a crash is what we count
        dt = CLOCK[0]() - t0
        tb = traceback.extract_tb(exc.__traceback__)[-1]
        return Outcome("crash", dt, f"{type(exc).__name__} at {os.path.basename(tb.filename)}:{tb.lineno}: {exc}"[:160])
    finally:
        signal.setitimer(TIMER[0], 0.0)
    bad = check_plan(problem, result)
    if bad:
        return Outcome("check failed", dt, bad)
    cert = getattr(result.continuous, "certified", None) if result.continuous is not None else None
    sampled = getattr(result, "sampled", None)
    minimal = bool(sampled.minimal) if sampled is not None and hasattr(sampled, "minimal") else None
    return Outcome("plan", dt, certified=cert, minimal=minimal, no_continuous=result.continuous is None)


# ----------------------------------------------------------------- report
@dataclass
class Tally:
    outcomes: list = field(default_factory=list)

    def add(self, o: Outcome, case: Case) -> None:
        self.outcomes.append((o, case))


def pct(x: np.ndarray, q: float) -> float:
    return float(np.percentile(x, q)) if x.size else math.nan


def report(method: str, tally: Tally, show: int) -> None:
    out = [o for o, _ in tally.outcomes]
    kinds = Counter(o.kind for o in out)
    plans = [o for o in out if o.kind == "plan"]
    cert = sum(1 for o in plans if o.certified)
    uncert = sum(1 for o in plans if o.certified is False)
    print(f"\n## {method}: {len(out)} cases")
    print(
        f"plans {kinds['plan']} (certified {cert}, not certified {uncert}), "
        f"refusals {kinds['refusal (input)'] + kinds['refusal (solver)']} "
        f"(input {kinds['refusal (input)']}, solver {kinds['refusal (solver)']}), "
        f"crashes {kinds['crash']}, hangs {kinds['hang']}, check failed {kinds['check failed']}"
    )
    sampled = [o for o in plans if o.minimal is not None]
    if sampled:
        print(
            f"sampled sequences {len(sampled)}: count proved fewest {sum(1 for o in sampled if o.minimal)}, "
            f"no continuous profile (sampled-first short moves) {sum(1 for o in plans if o.no_continuous)}"
        )
    by_n: dict[str, list[float]] = defaultdict(list)
    for o, c in tally.outcomes:
        key = f"N={c.model.n_modes}" if c.model.n_modes <= 4 else "N=5-8"
        by_n[key].append(o.seconds)
    by_n["all"] = [o.seconds for o in out]
    print(f"{'modes':>7} {'cases':>6} {'median ms':>10} {'p90 ms':>9} {'p99 ms':>9} {'p99.9 ms':>9} {'max ms':>10}")
    for key in sorted(by_n, key=lambda k: (k == "all", k)):
        t = np.array(by_n[key]) * 1e3
        print(
            f"{key:>7} {t.size:6d} {pct(t, 50):10.2f} {pct(t, 90):9.2f} {pct(t, 99):9.2f} "
            f"{pct(t, 99.9):9.2f} {float(np.max(t)):10.2f}"
        )
    reasons = Counter((o.kind, o.reason) for o in out if o.kind not in ("plan",))
    if reasons:
        print("refusals / failures by reason:")
        for (kind, why), k in reasons.most_common():
            print(f"  {k:6d}  {kind}: {why}")
    if show:
        print(f"slowest {show}:")
        ranked = sorted(tally.outcomes, key=lambda oc: -oc[0].seconds)[:show]
        for o, c in ranked:
            print(f"  case {c.index}: {o.seconds * 1e3:.1f} ms {o.kind} {o.reason} N={c.model.n_modes}")
        for o, c in tally.outcomes:
            if o.kind in ("crash", "hang", "check failed"):
                print(f"  {o.kind} case {c.index}: {c.describe()}")
        refused = [(o, c) for o, c in tally.outcomes if o.kind == "refusal (solver)"]
        if refused:
            print("solver refusals (case: modes, moving start, time):")
            print(
                "  "
                + ", ".join(
                    f"{c.index}: N={c.model.n_modes} {'moving' if c.moving else 'rest'} {o.seconds:.2f} s"
                    for o, c in refused[:40]
                )
            )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", type=int, default=1000)
    ap.add_argument("--methods", default="time_optimal", help="comma-separated; 'all' for every method")
    ap.add_argument("--seed", type=int, default=15)
    ap.add_argument("--rate", type=float, default=None, help="Hz; none: continuous plans only (where possible)")
    ap.add_argument(
        "--timeout", type=float, default=30.0, help="per-case guard (s): wall clock, or CPU time with --clock cpu"
    )
    ap.add_argument("--max-modes", type=int, default=8)
    ap.add_argument("--first", type=int, default=0, help="index of the first case")
    ap.add_argument("--only", default=None, help="run case I only (or a comma-separated list: I,J,K)")
    ap.add_argument("--show", type=int, default=0, help="print the N slowest cases, every crash and solver refusal")
    ap.add_argument(
        "--clock", choices=("wall", "cpu"), default="wall", help="time each case by wall clock or process CPU time"
    )
    ap.add_argument("--modes-at-most", type=int, default=None, help="run only the cases with at most this many modes")
    ap.add_argument("--modes-at-least", type=int, default=None, help="run only the cases with at least this many modes")
    ap.add_argument(
        "--partial-every", type=int, default=0, help="also print the table of the cases so far every N cases run"
    )
    args = ap.parse_args()
    methods = list(METHODS) if args.methods == "all" else [m.strip() for m in args.methods.split(",") if m.strip()]
    for m in methods:
        if m not in METHODS:
            raise SystemExit(f"--methods: unknown method {m!r}; one of {sorted(METHODS)}")
    signal.signal(signal.SIGALRM, _alarm)
    signal.signal(signal.SIGVTALRM, _alarm)
    if args.clock == "cpu":
        CLOCK[0] = time.process_time
        TIMER[0] = (
            signal.ITIMER_VIRTUAL
        )  # the guard on this process's CPU time too: hangs then do not depend on the load
    if args.only is not None:
        indices = [int(i) for i in args.only.split(",") if i.strip()]
    else:
        indices = range(args.first, args.first + args.cases)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else math.nan
    print(
        f"# flexmotion fuzz (issue 15): python {platform.python_version()}, numpy {np.__version__}, "
        f"{os.cpu_count()} CPU(s), load {load:.1f}; seed {args.seed}, cases "
        f"{args.only if args.only is not None else f'{args.first}..{args.first + args.cases - 1}'}, "
        f"rate {args.rate or 'none'} Hz, timeout {args.timeout:g} s, N <= {args.max_modes}, {args.clock} clock"
    )
    start = time.perf_counter()
    for method in methods:
        tally = Tally()
        try:
            for i in indices:
                case = draw_case(args.seed, i, args.max_modes)
                if args.modes_at_most is not None and case.model.n_modes > args.modes_at_most:
                    continue
                if args.modes_at_least is not None and case.model.n_modes < args.modes_at_least:
                    continue
                tally.add(run_case(method, case, args.rate, args.timeout), case)
                if args.partial_every and len(tally.outcomes) % args.partial_every == 0:
                    print(f"\n# partial: {len(tally.outcomes)} cases run, the last {i}", flush=True)
                    report(method, tally, 0)
        except KeyboardInterrupt:  # stopped (SIGINT): the table of the cases that finished
            last = tally.outcomes[-1][1].index if tally.outcomes else None
            print(f"\n# interrupted: {len(tally.outcomes)} cases finished, the last {last}", flush=True)
            report(method, tally, args.show)
            break
        report(method, tally, args.show)
    print(f"\n# wall time {time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
