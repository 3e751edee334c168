"""One entry point for one or several inputs: the configuration, the move, the budgets and the plan.

The command line and the nodes call these functions and never ask which
kind of machine they have: a parameter set with ``model.inputs`` is a
multi-input machine (:class:`~.config.MultiPlannerConfig`, planned by
:func:`~.methods.plan_multi_move`); any other is the single-input machine of
:class:`~flexmotion_ros.core.config.PlannerConfig`, planned by
:func:`~flexmotion_ros.core.methods.table.plan_move`, unchanged.

=========================  =======================================  ==========================================
function                   one input                                several inputs
=========================  =======================================  ==========================================
:func:`config_from_any`    ``config_from_parameters``               ``multi_config_from_parameters``
:func:`move_problem`       ``state_to_rest`` (target float / None)  ``multi_state_to_rest`` (k targets / None)
:func:`check_budgets`      ``check_move_budget``, ``_samples``      ``check_multi_move_budget``
:func:`plan`               ``plan_move``                            ``plan_multi_move`` (+ the bound check)
=========================  =======================================  ==========================================
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..config import PlannerConfig, check_move_samples, config_from_parameters
from ..errors import ConfigError, SolverError
from ..methods.common import check_move_budget
from ..methods.table import plan_move
from ..model.boundary import MoveProblem, state_to_rest
from ..model.modal_model import ModalModel
from ..parameter_checks import check_parameters
from ..parameter_file import read_parameter_file
from ..results import PlanResult
from ..simulation.exact import modal_amplitudes
from .config import MultiPlannerConfig, check_multi_move_budget, multi_config_from_parameters
from .methods import MultiPlanResult, plan_multi_move
from .model import MultiModel
from .problem import MultiMoveProblem, multi_state_to_rest

#: Either configuration.
AnyConfig = PlannerConfig | MultiPlannerConfig
#: Either model.
AnyModel = ModalModel | MultiModel

#: Parameters that only a multi-input model reads (refused in a single-input file: a forgotten ``model.inputs``).
MULTI_ONLY = ("model.rigid_bodies", "model.mode_names", "sync", "fuel_weights")
#: Parameters that are one double for one input and may be lists for several.
LIST_FOR_MULTI = ("model.b0", "model.c", "u_max")


def _set(value: Any) -> bool:
    return value is not None and not (isinstance(value, (list, tuple)) and not value)


def is_multi(params: Mapping[str, Any]) -> bool:
    """Whether flat parameters describe a multi-input machine: ``model.inputs`` is set (non-empty)."""
    return _set(params.get("model.inputs"))


def config_from_any(params: Mapping[str, Any]) -> AnyConfig:
    """The validated configuration of flat ROS parameters, one input or several.

    A single-input parameter set with a list where one double belongs
    (``model.b0``, ``model.c``, ``u_max``) or with a multi-input name
    (``model.rigid_bodies``, ``sync``, ...) is refused: it says to set
    ``model.inputs``.

    Raises
    ------
    ConfigError, ModelError
        Naming the parameter.
    """
    if is_multi(params):
        config = multi_config_from_parameters(params)
        check_joint_names(config, params.get("joint_names"))  # a node parameter: the same verdict here
        check_single_input_features(config, params)  # node parameters too
        return config
    for name in LIST_FOR_MULTI:
        if isinstance(params.get(name), (list, tuple)) and params.get(name):
            raise ConfigError(
                name,
                f"is a list ({list(params[name])}): lists are for multi-input models (set model.inputs, one name "
                "per input); a single-input model takes one double here",
            )
    for name in MULTI_ONLY:
        if _set(params.get(name)):
            raise ConfigError(name, "is read by multi-input models only: set model.inputs (one name per input)")
    config = config_from_parameters(params)
    check_joint_names(config, params.get("joint_names"))
    return config


#: Planner features for one input only (issue 14), with the value a several-input planner takes.
SINGLE_INPUT_ONLY: tuple[tuple[str, str], ...] = (("output", "stream"), ("command_interface", "effort"))


def check_single_input_features(config: AnyConfig, params: Mapping[str, Any]) -> None:
    """Refuse, for several inputs, the planner's one-input features (the node and ``flexmotion plan`` alike).

    Several inputs stream forces on ``commands`` only: ``output: trajectory``,
    a velocity / position ``command_interface`` and closed-loop replanning
    (``feedback.replan_period_s``) are one-input features for now.

    Raises
    ------
    ConfigError
        Naming the parameter.
    """
    if not isinstance(config, MultiPlannerConfig):
        return
    m = config.model.m
    for name, default in SINGLE_INPUT_ONLY:
        given = params.get(name)
        if given is not None and given != default:
            raise ConfigError(
                name,
                f"is one-input only for now, got {given!r} with {m} inputs (model.inputs): use {default!r} "
                "(a force stream on 'commands')",
            )
    period = params.get("feedback.replan_period_s")
    if isinstance(period, (int, float)) and not isinstance(period, bool) and period > 0.0:
        raise ConfigError(
            "feedback.replan_period_s",
            f"closed-loop replanning is one-input only for now, got {period} s with {m} inputs (model.inputs): "
            "set it to 0.0",
        )


def check_joint_names(config: AnyConfig, names) -> tuple[str, ...]:
    """The joints of ``commands`` (node parameter ``joint_names``), one per input, unique; empty: the inputs.

    Checked here so that ``flexmotion plan`` and the planner node give the same
    verdict on a file (a single-input model has one joint, ``joint_name``).

    Raises
    ------
    ConfigError
        Naming ``joint_names``: another count than the inputs, or a name repeated.
    """
    given = tuple(str(n) for n in (names or ()))
    if not isinstance(config, MultiPlannerConfig):
        if len(given) > 1:
            raise ConfigError("joint_names", f"a single-input model has one joint (joint_name), got {list(given)}")
        return given
    model = config.model
    out = given or tuple(model.inputs)
    if len(out) != model.m:
        raise ConfigError(
            "joint_names", f"needs one joint per input {list(model.inputs)} ({model.m}), got {len(out)}: {list(out)}"
        )
    if len(set(out)) != len(out):
        raise ConfigError("joint_names", f"names must be unique, got {list(out)}")
    return out


def load_any_config(path: str | Path, node_name: str | None = "flexmotion_planner") -> AnyConfig:
    """Read, check (names and ROS types: the nodes' check) and validate a parameter file, one input or several."""
    params = read_parameter_file(path, node_name)
    check_parameters(params)
    return config_from_any(params)


def state_size(model: AnyModel) -> int:
    """Length of the state vector: ``2 + 2 N`` for one input, ``2 k + 2 N`` for several."""
    return model.n_states if isinstance(model, MultiModel) else 2 + 2 * model.n_modes


def rigid_body_names(model: AnyModel, single_name: str = "rigid_body") -> tuple[str, ...]:
    """The rigid-body coordinates' names (``single_name`` for a single-input model)."""
    return tuple(model.rigid_bodies) if isinstance(model, MultiModel) else (single_name,)


def mode_names(model: AnyModel) -> tuple[str, ...]:
    """The modes' names (``mode_1`` ... unless a multi-input file names them)."""
    if isinstance(model, MultiModel):
        return tuple(model.mode_names)
    return tuple(f"mode_{i + 1}" for i in range(model.n_modes))


def body_positions(model: AnyModel, x: np.ndarray) -> np.ndarray:
    """The rigid bodies' positions in state(s) ``x`` (shape ``(..., k)``; ``k = 1`` for one input)."""
    x = np.asarray(x, float)
    k = model.k if isinstance(model, MultiModel) else 1
    return x[..., 0 : 2 * k : 2]


def rest_state(model: AnyModel, positions) -> np.ndarray:
    """The equilibrium at ``positions`` (a float for one input; one per rigid body, or one for all, for several)."""
    if isinstance(model, MultiModel):
        p = np.broadcast_to(np.asarray(positions, float).ravel(), (model.k,)) if np.size(positions) == 1 else positions
        return model.rest_state(p)
    return model.rest_state(float(np.asarray(positions, float).ravel()[0]))


def state_at_rest(model: AnyModel, x: np.ndarray, tol: float) -> bool:
    """Every rigid-body velocity and every modal amplitude at most ``tol``."""
    x = np.asarray(x, float)
    if not isinstance(model, MultiModel):
        return bool(abs(x[1]) <= tol and np.all(modal_amplitudes(model, x) <= tol))
    k = model.k
    modal = np.concatenate([[0.0, 0.0], x[2 * k :]])  # the modal part with a dummy rigid body in front
    return bool(np.all(np.abs(x[1 : 2 * k : 2]) <= tol) and np.all(modal_amplitudes(model, modal) <= tol))


def move_problem(config: AnyConfig, x0: np.ndarray, target) -> MoveProblem | MultiMoveProblem:
    """The move from state ``x0`` to rest at ``target``: a float for one input, one per rigid body for several.

    ``None`` stops: every final position free.
    """
    if isinstance(config, MultiPlannerConfig):
        goal = None if target is None else [float(v) for v in np.asarray(target, float).ravel()]
        return multi_state_to_rest(config.model, config.u_max, x0, goal)
    t = None if target is None else float(np.asarray(target, float).ravel()[0])
    return state_to_rest(config.model, config.u_max, x0, t)


def check_budgets(config: AnyConfig, problem, rate_hz: float | None = None) -> None:
    """The move budgets (duration and samples), refused in microseconds before any planning (a GoalError)."""
    if isinstance(config, MultiPlannerConfig):
        check_multi_move_budget(config, problem, rate_hz)
        return
    check_move_budget(config, problem)
    check_move_samples(config, problem, rate_hz)


def plan(config: AnyConfig, problem, rate_hz: float | None = None, *, warm_start=None) -> PlanResult | MultiPlanResult:
    """Plan ``problem`` with ``config``: ``plan_move`` for one input, ``plan_multi_move`` for several.

    ``warm_start``: a :class:`~flexmotion_ros.core.time_optimal.warm_start.WarmStart`
    for one input (``plan_move``'s; ignored for several).

    Every multi-input sampled command is checked against its input's bound
    here too (never exceeded, whatever the method).

    Raises
    ------
    InputError
        Bad input, naming the parameter.
    SolverError
        No profile passed its own checks.
    """
    if not isinstance(config, MultiPlannerConfig):
        return plan_move(config, problem, rate_hz, warm_start=warm_start)
    result = plan_multi_move(
        problem,
        config.method,
        rate_hz=rate_hz,
        sync=config.sync,
        options=config.options,
        fuel_weights=config.fuel_weights,
        resolution_hz=config.rate_hz,  # "already there" without a rate: at the node's rate, as for one input
    )
    s = result.sampled
    if s is not None and s.commands.size:
        peak, u_max = np.max(np.abs(s.commands), axis=0), np.asarray(config.u_max, float)
        if np.any(peak > u_max):
            i = int(np.argmax(peak / u_max))
            raise SolverError(
                f"method {config.method} produced |u_{config.model.inputs[i]}| = {peak[i]} > u_max = "
                f"{config.u_max[i]}; nothing is returned"
            )
    return result


def n_inputs(config: AnyConfig) -> int:
    """``m``: the values of one command sample."""
    return config.model.m if isinstance(config, MultiPlannerConfig) else 1


def bounds_text(config: AnyConfig) -> str:
    """``u_max`` for a log line: ``1`` or ``[30, 50]``."""
    u = np.atleast_1d(np.asarray(config.u_max, float))
    return f"{u[0]:g}" if u.size == 1 else "[" + ", ".join(f"{v:g}" for v in u) + "]"


def positions_text(position) -> str:
    """A position or positions for a log line (``1.5`` or ``[3, 2]``, 9 significant digits)."""
    p = np.atleast_1d(np.asarray(position, float))
    if p.size == 1:
        return f"{p[0]:.9g}"
    return "[" + ", ".join(f"{v:.9g}" for v in p) + "]"


def finite_or_keep(values) -> np.ndarray:
    """Targets as floats, NaN meaning "keep this rigid body's target"."""
    out = np.asarray(values, float).ravel()
    if np.any(np.isinf(out)):
        j = int(np.flatnonzero(np.isinf(out))[0])
        raise ConfigError(f"goal[{j}]", f"must be finite, got {out[j]}")
    return out


def keep_targets(targets: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """``targets`` with every NaN (keep) replaced by the same rigid body's entry of ``kept``."""
    t = np.asarray(targets, float).copy()
    missing = np.isnan(t)
    t[missing] = np.asarray(kept, float)[missing]
    return t


def is_stop(target) -> bool:
    """A request without target: stop."""
    return target is None or (isinstance(target, float) and math.isnan(target))


__all__ = [
    "LIST_FOR_MULTI",
    "MULTI_ONLY",
    "AnyConfig",
    "AnyModel",
    "body_positions",
    "bounds_text",
    "check_budgets",
    "SINGLE_INPUT_ONLY",
    "check_joint_names",
    "check_single_input_features",
    "config_from_any",
    "finite_or_keep",
    "is_multi",
    "is_stop",
    "keep_targets",
    "load_any_config",
    "mode_names",
    "move_problem",
    "n_inputs",
    "plan",
    "positions_text",
    "rest_state",
    "rigid_body_names",
    "state_at_rest",
    "state_size",
]
