"""Seeded fuzz of ``time_optimal_friction`` and ``limited`` on random models (issue 18).

Every case is reproducible from ``(--seed, case index)`` alone (``numpy`` ``default_rng([seed, index])``).
The distribution is the issue's:

* N = 1..4 modes, omega log-uniform in 0.3..60 rad/s (distinct: ratios >= 1.02), zeta 0..0.3,
  b_i = +-[0.1, 2], b0 log-uniform 0.1..5, c in [-1, 0] for a quarter of the models (else 0),
  u_max log-uniform 0.1..10;
* rest-to-rest moves of 1e-3..1e3 (log-uniform, random sign) of the natural scale
  ``|b0| u_max / omega_1^2`` (the distance full force covers in ``1 / omega_1`` seconds);
* Coulomb force 0.02..0.5 u_max (friction); velocity limit 0.3..0.95 of the peak rigid-body velocity
  of the certified unlimited time-optimal move (limited); 100 Hz.

Checks of every result, independent of the planners:

* friction: the continuous move and the sampled sequence are replayed by the event-located friction
  simulation with matrix exponentials (``FrictionSystem`` without the closed-form fast path): rest at the
  target at the end and still at rest ``T`` seconds later, ``|u| <= u_max``, duration not below the proved
  rigid-body friction bound;
* limited: the sequence is replayed by ``simulate_samples`` (matrix exponentials): arrival, ``|u| <= u_max``,
  ``|v| <= v_max`` at the samples (monotone in between); where the planner claims the fewest samples, an
  independent LP (every state a variable, ``scipy.linalg.expm`` steps, limits loosened by 1e-9) must find
  ``K - 1`` samples infeasible; every "no move satisfies the limits" verdict is cross-checked by the same LP
  over doubling horizons (up to 16 x the unlimited move).

Each case runs in a worker process under a wall-clock guard (``--guard`` s); a case past it is killed and
counted as a hang.

    python bench/fuzz_friction_limited.py --cases 1000 --seed 18
    python bench/fuzz_friction_limited.py --cases 200 --methods limited --guard 60
    python bench/fuzz_friction_limited.py --methods time_optimal_friction --indices 28,492
"""

from __future__ import annotations

import argparse
import math
import multiprocessing as mp
import os
import re
import sys
import time
import traceback

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np
from scipy.linalg import expm
from scipy.optimize import linprog
from scipy.sparse import coo_matrix

# FLEXMOTION_TREE: plan with the package of another checkout (an A/B of two trees with the same bench)
sys.path.insert(0, os.environ.get("FLEXMOTION_TREE") or os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from flexmotion_ros.core import ModalModel, MoveProblem, PlannerConfig, plan_time_optimal  # noqa: E402
from flexmotion_ros.core.errors import InputError, UnreachableError  # noqa: E402
from flexmotion_ros.core.friction.contact import FrictionSystem  # noqa: E402
from flexmotion_ros.core.methods.table import plan_move  # noqa: E402
from flexmotion_ros.core.simulation.exact import simulate, simulate_samples  # noqa: E402

RATE_HZ = 100.0
CHECK_LP_TIME_S = 20.0  # per HiGHS method in the independent LP; past it the check says "undecided"
METHODS = ("time_optimal_friction", "limited")


# ------------------------------------------------------------------ the cases
def make_case(seed: int, index: int) -> dict:
    """The random model, move and option of case ``index`` (reproducible from ``(seed, index)``)."""
    rng = np.random.default_rng([seed, index])
    N = int(rng.integers(1, 5))
    while True:
        omega = np.sort(np.exp(rng.uniform(math.log(0.3), math.log(60.0), N)))
        if N == 1 or np.all(omega[1:] / omega[:-1] >= 1.02):
            break
    zeta = rng.uniform(0.0, 0.3, N)
    b = rng.choice([-1.0, 1.0], N) * rng.uniform(0.1, 2.0, N)
    b0 = float(np.exp(rng.uniform(math.log(0.1), math.log(5.0))))
    c = -float(rng.uniform(0.0, 1.0)) if rng.random() < 0.25 else 0.0
    u_max = float(np.exp(rng.uniform(math.log(0.1), math.log(10.0))))
    scale = b0 * u_max / float(omega[0]) ** 2
    move = float(rng.choice([-1.0, 1.0]) * np.exp(rng.uniform(math.log(1e-3), math.log(1e3))) * scale)
    return {
        "index": index,
        "model": {"b0": b0, "c": c, "omega": omega.tolist(), "zeta": zeta.tolist(), "b": b.tolist()},
        "u_max": u_max,
        "goal": move,
        "coulomb_fraction": float(rng.uniform(0.02, 0.5)),
        "velocity_fraction": float(rng.uniform(0.3, 0.95)),
    }


def build(case: dict) -> tuple[ModalModel, MoveProblem]:
    m = case["model"]
    model = ModalModel(b0=m["b0"], c=m["c"], omega=tuple(m["omega"]), zeta=tuple(m["zeta"]), b=tuple(m["b"]))
    return model, MoveProblem(model, case["u_max"], [0.0] * model.n_states, case["goal"])


def reproducer(case: dict, method: str, option: dict) -> str:
    """Python lines that replay one case with the core API."""
    m = case["model"]
    return (
        f"m = ModalModel(b0={m['b0']!r}, c={m['c']!r}, omega={tuple(m['omega'])!r}, zeta={tuple(m['zeta'])!r}, "
        f"b={tuple(m['b'])!r}); p = MoveProblem(m, {case['u_max']!r}, [0.0] * m.n_states, {case['goal']!r}); "
        f"plan_move(PlannerConfig(model=m, u_max={case['u_max']!r}, method={method!r}, options={option!r}), p, {RATE_HZ})"
    )


def peak_velocity(problem: MoveProblem) -> float:
    """Peak |v| of the certified unlimited time-optimal move (exact states at the switches: v is
    monotone on every constant-input arc for c <= 0)."""
    to = plan_time_optimal(problem)
    knots = np.concatenate([[0.0], np.asarray(to.switch_times, float), [to.duration]])
    states = simulate(problem.model, problem.x0, to.input(), times=knots)
    return float(np.max(np.abs(states[:, 1])))


# ------------------------------------------------------- independent checks
def state_space_lp(problem: MoveProblem, K: int, dt: float, v_max: float, slack: float = 1e-9) -> bool | None:
    """Is there a ``K``-sample sequence to rest at the target with ``|v_k| <= v_max (1 + slack)``?

    A formulation of its own: every state a variable, step matrices from ``scipy.linalg.expm`` of the
    augmented matrix, sparse rows, HiGHS.  None if HiGHS decides neither way with either method within
    ``CHECK_LP_TIME_S`` each (case 869's 313-sample LP stalled HiGHS for minutes: counted as a planner
    hang, though the planner took 0.3 s).
    """
    model = problem.model
    A, B = model.A(), model.B()
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n] = A * dt, B * dt
    E = expm(M)
    Phi, Gam = E[:n, :n], E[:n, n]
    x0 = np.asarray(problem.x0, float)
    xf = model.rest_state(problem.target)
    nv = K + n * K  # u_0..u_{K-1}, x_1..x_K
    rows, cols, vals = [], [], []
    beq = np.zeros(n * K)
    for k in range(K):
        base = n * k
        for i in range(n):
            rows += [base + i, base + i]
            cols += [K + n * k + i, k]
            vals += [1.0, -Gam[i]]
            if k == 0:
                beq[base + i] = Phi[i] @ x0
            else:
                rows += [base + i] * n
                cols += list(K + n * (k - 1) + np.arange(n))
                vals += list(-Phi[i])
    Aeq = coo_matrix((vals, (rows, cols)), shape=(n * K, nv)).tocsr()
    lo = np.full(nv, -np.inf)
    hi = np.full(nv, np.inf)
    lo[:K], hi[:K] = -problem.u_max, problem.u_max
    vel = K + n * np.arange(K) + 1
    lo[vel], hi[vel] = -v_max * (1.0 + slack), v_max * (1.0 + slack)
    lo[K + n * (K - 1) :] = hi[K + n * (K - 1) :] = xf
    for method in ("highs-ipm", "highs-ds"):
        res = linprog(
            np.zeros(nv),
            A_eq=Aeq,
            b_eq=beq,
            bounds=np.column_stack([lo, hi]),
            method=method,
            options={"time_limit": CHECK_LP_TIME_S},
        )
        if res.status in (0, 2):
            return res.status == 0
    return None


def check_friction(problem: MoveProblem, F: float, result) -> str | None:
    """None if the continuous move and the sampled sequence pass the independent friction checks."""
    exact = FrictionSystem.for_model(problem.model, F)  # matrix exponentials, event-located
    xf = problem.model.rest_state(problem.target)
    out = []
    cont = result.continuous
    for name, u, T in (
        ("continuous", cont.input(), cont.duration),
        ("sampled", result.sampled.input(), result.sampled.duration),
    ):
        levels = np.asarray(u.levels, float) if hasattr(u, "levels") else None
        if levels is not None and levels.size and float(np.max(np.abs(levels))) > problem.u_max:
            out.append(f"{name}: |u| above u_max")
        if T == 0.0:
            continue
        grid = np.concatenate([np.linspace(0.0, T, 201), [2.0 * T + 1.0]])
        xs = exact.run(problem.x0, u, grid).states
        scale = np.maximum(np.max(np.abs(xs - xf), axis=0), 1e-300)  # each state's excursion
        dev = np.abs(xs[-2:] - xf) / scale  # at T and T + 1 s later
        if float(np.max(dev)) > 1e-6:
            out.append(f"{name}: not at rest at the target (relative {float(np.max(dev)):.1e})")
    lb = cont.lower_bound
    if lb is not None and cont.duration < lb * (1.0 - 1e-9):
        out.append(f"faster than the rigid-body friction bound ({cont.duration} < {lb})")
    if float(np.max(np.abs(result.sampled.commands), initial=0.0)) > problem.u_max:
        out.append("sampled |u| above u_max")
    return "; ".join(out) or None


def check_limited(problem: MoveProblem, v_max: float, result) -> tuple[str | None, str]:
    """(failure or None, what the independent LP said about the fewest-samples claim)."""
    s = result.sampled
    u = s.commands
    out = []
    if float(np.max(np.abs(u), initial=0.0)) > problem.u_max:
        out.append("|u| above u_max")
    states = simulate_samples(problem.model, problem.x0, u, s.dt)
    xf = problem.model.rest_state(problem.target)
    scale = np.maximum(np.max(np.abs(states - xf), axis=0), 1e-300)
    rel = float(np.max(np.abs(states[-1] - xf) / scale))
    if rel > 1e-8:
        out.append(f"misses the target (relative {rel:.1e})")
    if float(np.max(np.abs(states[:, 1]))) > v_max * (1.0 + 1e-12):
        out.append(f"velocity {float(np.max(np.abs(states[:, 1]))):.6g} above the limit {v_max:.6g}")
    claim = "not claimed"
    if s.minimal and s.samples > 1:
        feas = state_space_lp(problem, s.samples - 1, s.dt, v_max)
        claim = {True: "FALSE (K - 1 feasible)", False: "confirmed", None: "undecided"}[feas]
        if feas:
            out.append("claims the fewest samples but the independent LP finds K - 1 feasible")
    return ("; ".join(out) or None), claim


def cross_check_infeasible(problem: MoveProblem, v_max: float, K0: int) -> str:
    """An independent LP over doubling horizons K0 .. 16 K0: 'refuted at K' or 'not refuted'."""
    K = max(K0, 1)
    while K <= 16 * max(K0, 1):
        if state_space_lp(problem, K, 1.0 / RATE_HZ, v_max, slack=-1e-6):
            return f"REFUTED: a {K}-sample sequence meets the limit"
        K *= 2
    return "not refuted up to 16 x the unlimited move"


def stick_arc(problem: MoveProblem, F: float, cont) -> bool:
    """Whether a sampled friction move holds the body on the way (a stick arc): in the event-located friction
    simulation the rigid-body velocity is zero at two consecutive sample instants before the end (the body
    at rest for a whole sample).  Read off the simulation, not the planner; False for a bang-bang move."""
    h = getattr(cont, "sample_period", None)
    if h is None or cont.duration == 0.0:
        return False
    K = int(round(cont.duration / h))
    v = FrictionSystem.for_model(problem.model, F).run(problem.x0, cont.input(), h * np.arange(K + 1)).states[:, 1]
    rest = np.abs(v) <= 1e-12 * max(float(np.max(np.abs(v))), 1e-300)
    return bool(np.any(rest[1:K] & rest[2 : K + 1]))


# ----------------------------------------------------------------- one case
def reason_of(exc: BaseException) -> str:
    """The refusal's reason with numbers removed (a key for counting)."""
    text = str(exc).split(";")[0]
    text = re.sub(r"[-+]?\d[\d.e+-]*", "#", text)
    return text[:90]


def run_case(method: str, seed: int, index: int) -> dict:
    case = make_case(seed, index)
    model, problem = build(case)
    out = {"index": index, "method": method, "N": model.n_modes}
    try:
        if method == "time_optimal_friction":
            option = {"coulomb_force": case["coulomb_fraction"] * case["u_max"]}
        else:
            option = {"limits.velocity_max": case["velocity_fraction"] * peak_velocity(problem)}
    except Exception as exc:  # the reference itself failed (not the planner under test)
        out.update(status="skipped", reason=f"reference plan failed: {type(exc).__name__}: {exc}"[:160])
        return out
    out["reproducer"] = reproducer(case, method, option)
    config = PlannerConfig(model=model, u_max=case["u_max"], method=method, options=option)
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        result = plan_move(config, problem, RATE_HZ)
    except (InputError, UnreachableError) as exc:
        out.update(status="refused", time_s=time.perf_counter() - t0, reason=f"{type(exc).__name__}: {reason_of(exc)}")
        if method == "limited" and "limits" in str(exc):
            K0 = math.ceil(plan_time_optimal(problem).duration * RATE_HZ)
            out["cross_check"] = cross_check_infeasible(problem, option["limits.velocity_max"], K0)
        return out
    except Exception as exc:
        out.update(
            status="error",
            time_s=time.perf_counter() - t0,
            reason=f"{type(exc).__name__}: {reason_of(exc)}",
            traceback=traceback.format_exc()[-600:],
        )
        return out
    out["time_s"] = time.perf_counter() - t0
    out["cpu_s"] = time.process_time() - c0  # this process's CPU time: less sensitive to a loaded machine
    out["duration_s"] = float(getattr(result.continuous, "duration", math.nan))
    out["status"] = "plan"
    if method == "time_optimal_friction":
        out["certified"] = bool(result.continuous.certified)
        cert = result.continuous.certificate
        out["cert_status"] = str(getattr(cert, "status", "passed" if cert.passed else "failed"))
        out["check"] = check_friction(problem, option["coulomb_force"], result)
        out["stick"] = stick_arc(problem, option["coulomb_force"], result.continuous)
    else:
        out["certified"] = bool(result.sampled.minimal)
        out["proof"] = str(result.info.get("lower_bound_proof", ""))
        out["check"], out["claim"] = check_limited(problem, option["limits.velocity_max"], result)
    return out


# ---------------------------------------------------------- guarded workers
def _worker(conn) -> None:
    while True:
        job = conn.recv()
        if job is None:
            return
        try:
            conn.send(run_case(*job))
        except Exception as exc:  # never leave the parent waiting
            conn.send({"index": job[2], "method": job[0], "status": "error", "reason": f"harness: {exc}"})


def _cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` so far (Linux ``/proc``; wall-clock fallback: inf)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return math.inf


class Guarded:
    """One worker process; a case past ``guard`` seconds is killed and reported as a hang.

    ``clock="cpu"``: the guard counts the worker's CPU seconds (on a loaded machine a wall-clock guard
    kills cases for the machine's load, not their work); a case is still killed after ``WALL_FACTOR``
    times the guard in wall-clock time."""

    WALL_FACTOR = 20.0

    def __init__(self, guard: float, clock: str = "wall") -> None:
        self.guard = guard
        self.clock = clock
        self.ctx = mp.get_context("fork")
        self._start()

    def _start(self) -> None:
        self.conn, child = self.ctx.Pipe()
        self.proc = self.ctx.Process(target=_worker, args=(child,), daemon=True)
        self.proc.start()

    def run(self, method: str, seed: int, index: int) -> dict:
        self.conn.send((method, seed, index))
        if self.clock == "cpu":
            cpu0, t0 = _cpu_seconds(self.proc.pid), time.perf_counter()
            while time.perf_counter() - t0 < self.WALL_FACTOR * self.guard:
                if self.conn.poll(0.25):
                    return self.conn.recv()
                if _cpu_seconds(self.proc.pid) - cpu0 > self.guard:
                    break
        elif self.conn.poll(self.guard):
            return self.conn.recv()
        self.proc.kill()
        self.proc.join()
        self._start()
        return {"index": index, "method": method, "status": "hang", "time_s": self.guard}

    def close(self) -> None:
        self.conn.send(None)
        self.proc.join(5.0)


# ------------------------------------------------------------------ summary
def summary(method: str, rows: list[dict]) -> list[str]:
    n = len(rows)
    by = {s: [r for r in rows if r["status"] == s] for s in ("plan", "refused", "error", "hang", "skipped")}
    plans = by["plan"]
    times = np.array([r["time_s"] for r in rows if "time_s" in r])
    cert = sum(r.get("certified", False) for r in plans)
    failed = [r for r in plans if r.get("check")]
    lines = [
        f"{method}: {n} cases: {len(plans)} plans ({cert} certified, {len(failed)} failed an independent check), "
        f"{len(by['refused'])} refused, {len(by['error'])} errors, {len(by['hang'])} hangs, {len(by['skipped'])} skipped",
    ]
    if times.size:
        lines.append(
            f"  time (plan_move, s): median {np.median(times):.3f}  p99 {np.percentile(times, 99):.3f}  "
            f"max {np.max(times):.3f}  (hangs counted at the guard)"
        )
    cpu = np.array([r["cpu_s"] for r in plans if "cpu_s" in r])
    if cpu.size:
        lines.append(f"  CPU time of the plans (s): median {np.median(cpu):.3f}  p99 {np.percentile(cpu, 99):.3f}")
    if plans and method == "limited":
        claims = {}
        for r in plans:
            claims[r.get("claim")] = claims.get(r.get("claim"), 0) + 1
        lines.append(
            "  fewest-samples claims vs independent LP at K - 1: " + ", ".join(f"{k}: {v}" for k, v in claims.items())
        )
        proofs = {}
        for r in plans:
            proofs[r.get("proof")] = proofs.get(r.get("proof"), 0) + 1
        lines.append("  proofs: " + ", ".join(f"{k}: {v}" for k, v in proofs.items()))
    if plans and method != "limited":
        st = {}
        for r in plans:
            st[r.get("cert_status")] = st.get(r.get("cert_status"), 0) + 1
        lines.append("  certificate status: " + ", ".join(f"{k}: {v}" for k, v in st.items()))
        cls = {}
        for r in plans:
            key = f"{r.get('cert_status')}{' (stick arc)' if r.get('stick') else ''}"
            cls[key] = cls.get(key, 0) + 1
        lines.append("  by class: " + ", ".join(f"{k}: {v}" for k, v in sorted(cls.items())))
    for kind in ("refused", "error", "skipped"):
        reasons: dict[str, list] = {}
        for r in by[kind]:
            reasons.setdefault(r.get("reason", "?"), []).append(r["index"])
        for why, idx in sorted(reasons.items(), key=lambda kv: -len(kv[1])):
            lines.append(f"  {kind} x{len(idx)}: {why}  (cases {idx[:6]})")
    for r in by["refused"]:
        if "cross_check" in r:
            lines.append(f"  verdict of case {r['index']} cross-checked: {r['cross_check']}")
    for r in failed[:10]:
        lines.append(f"  check failed, case {r['index']}: {r['check']}")
    if by["hang"]:
        lines.append(f"  hangs: cases {[r['index'] for r in by['hang']][:20]}")
    return lines


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", type=int, default=1000)
    p.add_argument("--seed", type=int, default=18)
    p.add_argument("--first", type=int, default=0, help="index of the first case")
    p.add_argument("--methods", default=",".join(METHODS), help="comma-separated subset of " + ", ".join(METHODS))
    p.add_argument("--guard", type=float, default=60.0, help="guard per case (s; see --guard-clock)")
    p.add_argument(
        "--guard-clock",
        choices=("wall", "cpu"),
        default="wall",
        dest="guard_clock",
        help="what the guard counts: wall-clock time, or the worker's CPU time (a loaded machine)",
    )
    p.add_argument("--indices", default="", help="comma-separated case indices to run instead of --first/--cases")
    p.add_argument("--show", type=int, default=-1, help="print the reproducer of this case index and exit")
    p.add_argument("--verbose", action="store_true")
    args = p.parse_args()
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    for m in methods:
        if m not in METHODS:
            p.error(f"--methods: unknown method {m!r}; allowed: {', '.join(METHODS)}")
    if args.show >= 0:
        for m in methods:
            print(run_case(m, args.seed, args.show))
        return
    import flexmotion_ros

    load = os.getloadavg()[0]
    print(
        f"# fuzz seed {args.seed}, cases "
        f"{args.indices if args.indices else f'{args.first}..{args.first + args.cases - 1}'}, {RATE_HZ:g} Hz, guard {args.guard:g} s ({args.guard_clock}), "
        f"package {os.path.dirname(flexmotion_ros.__file__)}, load average {load:.2f} on {os.cpu_count()} CPUs"
    )
    pool = Guarded(args.guard, args.guard_clock)
    t_all = time.perf_counter()
    try:
        for m in methods:
            rows = []
            indices = (
                [int(i) for i in args.indices.split(",") if i.strip()]
                if args.indices
                else range(args.first, args.first + args.cases)
            )
            for i in indices:
                r = pool.run(m, args.seed, i)
                rows.append(r)
                if args.verbose or r["status"] in ("error", "hang") or r.get("check"):
                    print(
                        f"  [{m} {i}] {r['status']} {r.get('time_s', 0):.3f}s cpu {r.get('cpu_s', 0):.3f}s "
                        f"T {r.get('duration_s', 0):.6g}s {r.get('cert_status', '')}{' stick_arc' if r.get('stick') else ''} "
                        f"{r.get('reason', '')} "
                        f"{r.get('check') or ''}"
                        f"{' proof ' + repr(r['proof']) + ' claim ' + repr(r.get('claim')) if 'proof' in r else ''}",
                        flush=True,
                    )
            print("\n".join(summary(m, rows)), flush=True)
    finally:
        pool.close()
    print(f"# total wall {time.perf_counter() - t_all:.0f} s")


if __name__ == "__main__":
    main()
