"""The fuel/time trade-off: minimum fuel versus move time, continuous and sampled.

With the target at rest, a move that arrives early can hold zero (no fuel)
until any later time, so the minimum fuel ``J(T)`` is non-increasing in
``T``.  Its end points: ``J(T*) = u_max T*`` (at ``T*`` the bang-bang input
is the only admissible one) and ``J(T_max)`` = the minimum fuel with the
arrival time *free* in ``[T*, T_max]`` (monotonicity puts that optimum at
``T_max``).  As ``T_max -> inf`` it tends to the fuel of the unconstrained
time problem (for a rigid body with ``c = 0``: zero for rest-to-rest, the
momentum ``|v0 / b0|`` to stop a moving one).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import GoalError, SolverError
from ..model.boundary import MoveProblem
from ..model.modal_model import check_positive
from ..results import BangBangProfile
from ..simulation.prepared import PreparedMove, prepare
from ..time_optimal.solver import plan_time_optimal
from .lp import check_move_time, min_fuel_lp, plan_min_fuel_zoh
from .min_fuel import plan_min_fuel


@dataclass
class FuelCurve:
    """Minimum fuel versus move time.

    Attributes
    ----------
    move_times : ndarray
        ``T`` (s), from ``T*`` to ``T_max``.
    fuel : ndarray
        Continuous-time minimum fuel ``J(T)`` (N s); ``fuel[0] = u_max T*``.
    sampled_move_times, sampled_fuel : ndarray or None
        The same for the ZOH problem at ``rate_hz`` (``K dt``, exact LP optimum).
    time_optimal_time : float
        ``T*`` (s).
    """

    move_times: np.ndarray
    fuel: np.ndarray
    time_optimal_time: float
    sampled_move_times: np.ndarray | None = None
    sampled_fuel: np.ndarray | None = None
    profiles: list = field(default_factory=list, repr=False)

    def to_dict(self) -> dict:
        out = {
            "time_optimal_time": float(self.time_optimal_time),
            "move_times": [float(t) for t in self.move_times],
            "fuel": [float(f) for f in self.fuel],
        }
        if self.sampled_fuel is not None:
            out["sampled_move_times"] = [float(t) for t in self.sampled_move_times]
            out["sampled_fuel"] = [float(f) for f in self.sampled_fuel]
        return out


def fuel_time_curve(
    problem: MoveProblem | PreparedMove,
    longest_time: float,
    points: int = 9,
    rate_hz: float | None = None,
    time_optimal: BangBangProfile | None = None,
) -> FuelCurve:
    """The fuel/time trade-off between ``T*`` and ``longest_time`` (equally spaced move times).

    With ``rate_hz`` also the exact sampled curve at the same times (rounded up
    to whole samples; ``rate_hz`` is checked by :func:`plan_min_fuel_zoh`).
    ``problem`` may be a :class:`PreparedMove` (its responses are reused).

    Raises
    ------
    SolverError
        A point without a continuous bang-off-bang solution (singular arc):
        use the sampled curve (:func:`sampled_fuel_curve`).
    """
    move = prepare(problem)
    problem = move.problem
    if time_optimal is None:
        time_optimal = plan_time_optimal(move)
    T_star = time_optimal.duration
    T_max = check_move_time(longest_time, T_star)
    if not isinstance(points, (int, np.integer)) or points < 2:
        raise GoalError("points", f"must be an integer >= 2, got {points}")
    times = T_star + (T_max - T_star) * np.linspace(0.0, 1.0, points)
    fuel, profiles = [], []
    for T in times:
        # each point starts from its own coarse LP: more robust than continuation in T (the
        # pulse structure changes along the curve), and about as fast
        p = plan_min_fuel(move, T, time_optimal)
        fuel.append(p.fuel)
        profiles.append(p)
    curve = FuelCurve(times, np.array(fuel), T_star, profiles=profiles)
    if rate_hz is not None:
        s_times, s_fuel = [], []
        for T, p in zip(times, profiles):
            sp = plan_min_fuel_zoh(
                move, rate_hz, T, time_optimal, nu_guess=None if p.extra.get("time_optimal") else p.costate
            )
            s_times.append(sp.duration)
            s_fuel.append(sp.extra["fuel"])
        curve.sampled_move_times = np.array(s_times)
        curve.sampled_fuel = np.array(s_fuel)
    return curve


def sampled_fuel_curve(
    problem: MoveProblem | PreparedMove,
    rate_hz: float,
    longest_time: float,
    points: int = 9,
    time_optimal: BangBangProfile | None = None,
) -> FuelCurve:
    """The exact sampled trade-off: minimum ZOH fuel for sample counts from the fewest to ``longest_time``.

    The first point is the fewest samples that arrive at all (the sampled
    time optimum, :func:`~flexmotion_ros.core.zoh.plan_time_optimal_zoh`); ``move_times``
    are ``K dt``.  ``fuel`` holds the sampled fuel (there is no continuous curve).
    ``problem`` may be a :class:`PreparedMove` (its responses are reused);
    ``rate_hz`` (Hz, ``> 0``) is checked here: a public entry point.
    """
    from ..sampled.zoh import plan_time_optimal_zoh

    rate = check_positive("rate_hz", rate_hz, "Hz")
    dt = 1.0 / rate
    move = prepare(problem)
    problem = move.problem
    if time_optimal is None:
        time_optimal = plan_time_optimal(move)
    T_max = check_move_time(longest_time, time_optimal.duration)
    if not isinstance(points, (int, np.integer)) or points < 2:
        raise GoalError("points", f"must be an integer >= 2, got {points}")
    K_lo = plan_time_optimal_zoh(move, rate, time_optimal).samples
    K_hi = max(K_lo, math.floor(T_max / dt * (1.0 + 1e-12)))
    Ks = np.unique(np.round(np.linspace(K_lo, K_hi, points)).astype(int))
    system = move.response
    x0 = move.x0.copy()
    fuel = []
    nu = None
    for K in Ks:
        sol = min_fuel_lp(system, x0, problem.u_max, int(K), dt, nu)
        if sol is None:
            raise SolverError(f"min_fuel: {K} samples infeasible although the sampled time optimum needs {K_lo}")
        fuel.append(sol.fuel)
        nu = sol.nu  # windows from the neighbour: accepted only if the full duality gap closes
    times = Ks * dt
    return FuelCurve(times, np.array(fuel), time_optimal.duration, times, np.array(fuel))
