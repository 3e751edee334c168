"""The multi-input method table and its one entry point, :func:`plan_multi_move`.

=====================  ==========================================================================
method                 multi-input planner
=====================  ==========================================================================
``time_optimal``       certified minimum time (:mod:`.time_optimal`), ``sync``; at a rate the
                       exact ZOH optimum with the proof for one sample fewer (:mod:`.zoh`)
shapers (``zv`` ...)   the same shaper on every input (:mod:`.shaped`), from rest
``fixed_time``         every part at its lowest peak arriving at ``arrival_time`` (:mod:`.fixed_time`)
``min_fuel``           least ``sum_i c_i int |u_i|`` (``fuel_weights``) in ``move_time``, at a rate (:mod:`.fuel`)
=====================  ==========================================================================

Refused with the reason (:data:`REFUSED`): ``robust_time_optimal``,
``time_optimal_friction``, ``limited``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from ..errors import ConfigError, InputError
from ..shaping.shapers import SHAPERS, check_negative_amplitude, check_tolerance, design
from .fixed_time import plan_multi_fixed_time, plan_multi_fixed_time_zoh
from .fuel import plan_multi_min_fuel_zoh
from .problem import MultiMoveProblem
from .results import MultiProfile, MultiSampledProfile, SyncMode
from .shaped import plan_multi_shaped, sample_profile, unique_modes
from .time_optimal import check_sync, plan_multi_time_optimal
from .zoh import plan_multi_time_optimal_zoh

#: Methods that plan multi-input models.
MULTI_METHODS: tuple[str, ...] = ("time_optimal", *SHAPERS, "fixed_time", "min_fuel")

#: Methods refused on multi-input models, with the reason.
REFUSED: dict[str, str] = {
    "robust_time_optimal": "the frequency-derivative (robust) conditions are planned for one input only; "
    "use a shaper (zvd, ei, ...) for robustness with several inputs",
    "time_optimal_friction": "Coulomb friction (event-located simulation and its certificate) is modelled "
    "for one input only",
    "limited": "velocity, deflection and slew-rate limits are planned for one input only",
}


@dataclass(frozen=True, kw_only=True)
class MultiPlanResult:
    """A planned multi-input move.

    Attributes
    ----------
    method : str
    problem : MultiMoveProblem
    continuous : MultiProfile or None
        None for methods planned at a rate only (``min_fuel``).
    sampled : MultiSampledProfile or None
        The exact ZOH sequence ``(K, m)`` at the requested rate.
    info : dict
    """

    method: str
    problem: MultiMoveProblem
    continuous: MultiProfile | None = None
    sampled: MultiSampledProfile | None = None
    info: dict = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """Move time (s): the sampled one if sampled, else the continuous one."""
        if self.sampled is not None:
            return self.sampled.duration
        return float(self.continuous.duration) if self.continuous is not None else 0.0

    def summary(self) -> dict:
        """The JSON of ``flexmotion plan --json`` for ``m > 1``: the continuous fields, then the sampled ones."""
        out: dict = {"method": self.method}
        if self.continuous is not None:
            out.update(self.continuous.to_dict())
        if self.sampled is not None:
            out.update(self.sampled.to_dict())
            out["sampled_solve_time_s"] = float(self.sampled.solve_time_s)
            out.update({k: v for k, v in self.sampled.extra.items() if k.startswith("fuel")})
        out["method"] = self.method
        out.update(self.info)
        return out


def check_multi_method(method: str) -> str:
    """``method`` if multi-input models support it, else :class:`ConfigError` naming it and the reason."""
    if method in REFUSED:
        raise ConfigError("method", f"{method} is not available for multi-input models: {REFUSED[method]}")
    if method not in MULTI_METHODS:
        raise ConfigError("method", f"must be one of {list(MULTI_METHODS)} for a multi-input model, got {method!r}")
    return method


def _option(options: Mapping, name: str, method: str):
    if name not in options:
        raise InputError(name, f"method {method} needs {name}")
    return options[name]


def plan_multi_move(
    problem: MultiMoveProblem,
    method: str = "time_optimal",
    rate_hz: float | None = None,
    sync: str | SyncMode = SyncMode.TIME,
    options: Mapping | None = None,
    fuel_weights=None,
) -> MultiPlanResult:
    """Plan ``problem`` with ``method``; with ``rate_hz``, also the exact sampled sequence.

    Parameters
    ----------
    problem : MultiMoveProblem
    method : str
        One of :data:`MULTI_METHODS`.
    rate_hz : float, optional
        Command rate (Hz); required by ``min_fuel``.
    sync : {"time", "none", "phase"}
        For ``time_optimal`` (see :class:`~.results.SyncMode`).
    options : mapping
        ``arrival_time`` (s, ``fixed_time``), ``move_time`` (s, ``min_fuel``),
        ``shaper.tolerance``, ``shaper.negative_amplitude`` (shapers).
    fuel_weights : sequence of float, optional
        ``c_i`` of eq. 2.38, one per input (``min_fuel``; default all 1).

    Raises
    ------
    InputError
        Bad input, naming the parameter; a refused method names the reason.
    SolverError
        No profile passed its own checks.
    """
    check_multi_method(method)
    mode = check_sync(sync)
    options = dict(options or {})
    info: dict = {}
    if method == "time_optimal":
        cont = plan_multi_time_optimal(problem, mode)
        samp = plan_multi_time_optimal_zoh(problem, rate_hz, cont) if rate_hz else None
    elif method == "fixed_time":
        T = _option(options, "arrival_time", method)
        cont = plan_multi_fixed_time(problem, T)
        samp = plan_multi_fixed_time_zoh(problem, T, rate_hz) if rate_hz else None
    elif method == "min_fuel":
        if not rate_hz:
            raise InputError("rate_hz", "method min_fuel plans multi-input moves at a rate: give rate_hz > 0")
        cont = None
        samp = plan_multi_min_fuel_zoh(problem, _option(options, "move_time", method), rate_hz, fuel_weights)
    else:
        omega, zeta = unique_modes(problem.model)
        if not omega:
            raise InputError("method", f"{method}: the model has no mode to shape for; use time_optimal")
        shaper = design(
            method,
            omega,
            zeta,
            check_tolerance(options.get("shaper.tolerance", 0.05)),
            check_negative_amplitude(options.get("shaper.negative_amplitude", 0.75)),
        )
        cont = plan_multi_shaped(problem, shaper, method)
        samp = sample_profile(problem, cont, rate_hz) if rate_hz else None
        info["shaper_duration"] = shaper.duration
    return MultiPlanResult(method=method, problem=problem, continuous=cont, sampled=samp, info=info)
