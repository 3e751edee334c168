"""Method ``time_optimal`` (the default): the certified bang-bang optimum and its exact ZOH sequence.

A move of a few samples whose fastest mode barely turns over it (a stop
requested just before a move ends, a tiny correction) is planned sampled-first: its continuous optimum lives on a
time scale far below a sample, where the switching function is a
near-polynomial small difference of large terms (seconds of work for the
continuous solver, and nothing a node streams), while the fewest-samples
linear programs are tiny and their minimality is proved by weak duality from
the rigid body's lower bound.  The continuous profile is then not computed
(``continuous`` is None; ``info["continuous"]`` says why).
"""

from __future__ import annotations

import math
import time

from ..config import PlannerConfig
from ..model.boundary import MoveProblem
from ..results import PlanResult
from ..sampled.zoh import fewest_samples, plan_time_optimal_zoh, reaches_rest_within
from ..simulation.prepared import PreparedMove, prepare
from ..time_optimal.rigid_body import rigid_time
from ..time_optimal.solver import plan_time_optimal
from ..time_optimal.warm_start import WarmStart

#: A move whose rigid-body lower bound is at most this many samples is planned sampled-first.
SHORT_MOVE_SAMPLES = 64
#: ... and its fastest mode turns by at most this much (rad) over that bound: below it the
#: switching function is a near-polynomial, the continuous solver's ill-conditioned regime.
SHORT_MOVE_PHASE = 2.0
#: ... trying this many sample counts above the bound before the continuous solver is asked.
SHORT_MOVE_EXTRA = 48


def plan(
    config: PlannerConfig,
    problem: MoveProblem | PreparedMove,
    rate_hz: float | None,
    warm_start: WarmStart | None = None,
) -> PlanResult:
    """The certified optimum (and its exact ZOH sequence at ``rate_hz``); ``warm_start``: a guess of its switches."""
    move = prepare(problem)  # responses built once for every planner below
    problem = move.problem
    if rate_hz:
        short = _short_move(move, rate_hz)
        if short is not None:
            return short
    continuous = plan_time_optimal(move, warm_start)
    sampled = plan_time_optimal_zoh(move.with_continuous(continuous), rate_hz, continuous) if rate_hz else None
    return PlanResult(method="time_optimal", problem=problem, continuous=continuous, sampled=sampled)


def _short_move(move: PreparedMove, rate_hz: float) -> PlanResult | None:
    """The fewest samples of a move of a few samples, without its continuous optimum (None: not short)."""
    t0 = time.perf_counter()
    dt = 1.0 / rate_hz
    problem = move.problem
    T_rigid = rigid_time(problem.model, problem.u_max, move.x0, problem.include_position)
    K_lo = max(1, math.ceil(T_rigid / dt * (1.0 - 1e-12)))
    wmax = max(problem.model.omega, default=0.0)
    if K_lo > SHORT_MOVE_SAMPLES or wmax * T_rigid > SHORT_MOVE_PHASE:
        return None
    # one LP first: a move that cannot arrive within the whole range is not short (a small correction of a
    # vibrating state: a rigid-body bound of a few samples, an answer of 100+; the search tried 48 counts, 0.5 s)
    if reaches_rest_within(move, dt, K_lo + SHORT_MOVE_EXTRA) is False:
        return None
    sampled = fewest_samples(move, dt, K_lo, K_lo + SHORT_MOVE_EXTRA, None, None, t0)
    if sampled is None:
        return None
    info = {
        "continuous": "not computed: a move of a few samples; the sampled count is proved fewest by the rigid-body "
        "bound and weak duality (minimal)",
        "plan_time_s": time.perf_counter() - t0,
    }
    return PlanResult(method="time_optimal", problem=problem, continuous=None, sampled=sampled, info=info)


METHOD_NAME = "time_optimal"
DESCRIPTION = "certified time-optimal bang-bang (zero-order hold at rate_hz)"
