"""Method ``limited``: fewest samples under velocity, deflection and slew-rate limits.

``limited``
    Fewest zero-order-hold samples that reach rest exactly while every limit
    holds at and between the samples.  Parameters:

    * ``limits.velocity_max`` (m/s, ``> 0``): rigid-body velocity;
    * ``limits.deflection_max`` (list, one per mode, ``> 0``; ``.inf``: no limit);
    * ``limits.slew_rate`` (N/s, ``> 0``): ``|u_k - u_{k-1}| <= slew_rate / rate_hz``,
      from and to 0 at the ends;
    * ``limits.report_each`` (bool, default false): also plan with each limit
      alone and report the time each one costs (``info["added_time_by_limit_s"]``).

It plans at the node's rate: without ``rate_hz`` (``flexmotion plan`` without
``--rate``) it uses ``config.rate_hz`` and say so in ``info["rate_source"]``.
"""

from __future__ import annotations

from ..config import PlannerConfig
from ..constraints.limits import Limits
from ..constraints.planner import plan_limited_zoh
from ..errors import ConfigError
from ..model.boundary import MoveProblem
from ..parameters import METHOD_OPTIONS
from ..results import PlanResult
from ..sampled.zoh import plan_time_optimal_zoh
from ..simulation.prepared import PreparedMove, prepare
from .common import SampledInput, planning_rate

#: The limits (from the registry, :data:`~flexmotion_ros.core.parameters.METHOD_OPTIONS`).
LIMIT_OPTIONS = tuple(p.name for p in METHOD_OPTIONS if "limited" in p.methods)


# ------------------------------------------------------------------- limited
def limits_from_options(config: PlannerConfig) -> tuple[Limits, bool]:
    """The :class:`Limits` in ``config.options`` (validated) and ``limits.report_each``."""
    opts = config.options
    unknown = sorted(k for k in opts if k.startswith("limits.") and k not in LIMIT_OPTIONS)
    if unknown:
        raise ConfigError(unknown[0], f"unknown limit; known: {', '.join(LIMIT_OPTIONS)}")
    q = opts.get("limits.deflection_max")
    if q is not None and not isinstance(q, (list, tuple)):
        q = [q] if config.model.n_modes == 1 else q
        if not isinstance(q, list):
            raise ConfigError(
                "limits.deflection_max", f"must be a list with one value > 0 per mode ({config.model.n_modes})"
            )
    each = opts.get("limits.report_each", False)
    if not isinstance(each, bool):
        raise ConfigError("limits.report_each", f"must be true or false, got {each!r}")
    lim = Limits(opts.get("limits.velocity_max"), tuple(q) if q is not None else None, opts.get("limits.slew_rate"))
    return lim.validated(config.model), each


def plan(config: PlannerConfig, problem: MoveProblem | PreparedMove, rate_hz: float | None) -> PlanResult:
    move = prepare(problem)  # responses built once for every planner below
    problem = move.problem
    limits, each = limits_from_options(config)
    rate, source = planning_rate(config, rate_hz)
    unlimited = plan_time_optimal_zoh(move, rate)
    result = plan_limited_zoh(problem, rate, limits, unlimited)
    info: dict = {"rate_source": source, "unlimited_duration": unlimited.duration, **result.to_dict()}
    if each and len(limits.active) > 1:
        by = {}
        for name in limits.active:
            by[name] = plan_limited_zoh(problem, rate, limits.only(name), unlimited).added_time_s
        info["added_time_by_limit_s"] = by
    elif limits.active:
        info["added_time_by_limit_s"] = {limits.active[0]: result.added_time_s} if len(limits.active) == 1 else {}
    message = (
        "fewest samples proved (relaxation infeasible below)"
        if result.minimal
        else (f"not proved fewest: no sequence below {result.lower_bound_samples} samples")
    )
    cont = SampledInput(result.sampled, "limited", result.minimal, message)
    return PlanResult(method="limited", problem=problem, continuous=cont, sampled=result.sampled, info=info)


METHOD_NAME = "limited"
DESCRIPTION = "fewest samples under velocity, deflection and slew-rate limits (LP)"
