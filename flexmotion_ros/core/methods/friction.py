"""Method ``time_optimal_friction``: bang-bang moves under Coulomb friction on the rigid body.

Options are ROS parameters next to ``method`` in the parameter file
(``config.options``)::

    method: time_optimal_friction
    coulomb_force: 0.2     # N, in [0, u_max): friction on the rigid body

See ``config/friction_example.yaml``.
"""

from __future__ import annotations

from ..config import PlannerConfig
from ..friction.time_optimal import check_coulomb_force, plan_time_optimal_friction
from ..friction.zoh import plan_time_optimal_friction_zoh
from ..model.boundary import MoveProblem
from ..parameters import option
from ..results import PlanResult
from ..simulation.prepared import PreparedMove, prepare
from .common import required_option


def plan(config: PlannerConfig, problem: MoveProblem | PreparedMove, rate_hz: float | None) -> PlanResult:
    move = prepare(problem)  # responses built once for every planner below
    problem = move.problem
    raw = required_option(
        config, "coulomb_force", "time_optimal_friction", f"{option('coulomb_force').allowed} = [0, {problem.u_max:g})"
    )
    F = check_coulomb_force(raw, problem.u_max)
    continuous = plan_time_optimal_friction(problem, F, rate_hz)
    sampled = plan_time_optimal_friction_zoh(move, F, rate_hz, continuous) if rate_hz else None
    info = {
        "coulomb_force": F,
        "frictionless_duration": continuous.frictionless_duration,
        "added_time_s": continuous.duration - continuous.frictionless_duration,
        "optimality": continuous.certificate.claim,
        "friction_status": str(continuous.certificate.status),
    }
    if sampled is not None:
        info["sampled_extra_samples"] = int(sampled.extra.get("extra_samples", 0))
    return PlanResult(
        method="time_optimal_friction", problem=problem, continuous=continuous, sampled=sampled, info=info
    )


METHOD_NAME = "time_optimal_friction"
DESCRIPTION = "bang-bang under Coulomb friction on the rigid body (option coulomb_force, N); exact ZOH at rate_hz"
