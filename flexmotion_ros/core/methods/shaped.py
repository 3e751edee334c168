"""Methods for every input shaper.

The methods of every input shaper (:data:`SHAPER_METHODS`), and the options and robustness figures
they share with ``robust_time_optimal`` (:mod:`.robust`):

* one method per shaper name in :data:`~flexmotion_ros.core.shapers.SHAPERS`
  (the rigid-body time-optimal move shaped for every mode of the model);
* ``robust_time_optimal`` (option ``robust_order``, default 1).

Each :class:`~flexmotion_ros.core.planning.PlanResult` carries in ``info``:
the duration, the time-optimal duration and the time added over it, the
residual vibration at the nominal model (exact simulation) and the
insensitivity (width of the frequency-ratio interval with residual vibration
at most ``robustness.tolerance`` of a full step's, all modes scaled together).

Options (``config.options``, dotted ROS parameter names, with defaults):

=========================  =======  =============================================
``shaper.tolerance``       0.05     EI vibration limit V (fraction), in (0, 0.5)
``shaper.negative_amplitude`` 0.75  SNA negative amplitude P, in (0.5, 2]
``shaper.multimode``       convolve ``convolve`` or ``direct`` (zv, zvd, zvdd)
``robustness.tolerance``   0.05     tolerance of the reported insensitivity
``robust_order``           1        derivative order of robust_time_optimal
=========================  =======  =============================================
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..config import PlannerConfig
from ..errors import ConfigError, InputError, SolverError
from ..model.boundary import MoveProblem
from ..results import PlanResult
from ..shaping.sampled_shaped import sample_command
from ..shaping.sensitivity import (
    command_insensitivity,
    residual_amplitudes,
    shaper_insensitivity,
)
from ..shaping.shaped_profile import plan_shaped
from ..shaping.shapers import SHAPERS, check_negative_amplitude, check_tolerance, design
from ..simulation.exact import PiecewiseConstant
from ..simulation.prepared import PreparedMove, prepare
from ..time_optimal.rigid_body import rigid_time
from ..time_optimal.robust import check_order
from ..time_optimal.solver import plan_time_optimal

DEFAULT_OPTIONS = {
    "shaper.tolerance": 0.05,
    "shaper.negative_amplitude": 0.75,
    "shaper.multimode": "convolve",
    "robustness.tolerance": 0.05,
    "robust_order": 1,
}


def options(config: PlannerConfig) -> dict:
    """The shaping options of ``config`` with defaults, validated (raises :class:`ConfigError`)."""
    o = {k: config.options.get(k, v) for k, v in DEFAULT_OPTIONS.items()}
    try:
        o["shaper.tolerance"] = check_tolerance(o["shaper.tolerance"])
        o["shaper.negative_amplitude"] = check_negative_amplitude(o["shaper.negative_amplitude"])
        o["robust_order"] = check_order(o["robust_order"])
    except ConfigError:
        raise
    except InputError as exc:  # report it as a configuration error, same parameter and reason
        raise ConfigError(exc.parameter, exc.reason) from None
    if o["shaper.multimode"] not in ("convolve", "direct"):
        raise ConfigError("shaper.multimode", f"must be 'convolve' or 'direct', got {o['shaper.multimode']!r}")
    tol = o["robustness.tolerance"]
    try:
        tol = float(tol)
    except (TypeError, ValueError):
        tol = math.nan
    if not 0.0 < tol < 1.0:
        raise ConfigError(
            "robustness.tolerance", f"must be in (0, 1) (fraction, 0.05 = 5 %), got {o['robustness.tolerance']!r}"
        )
    o["robustness.tolerance"] = tol
    return o


def robustness_info(
    u: PiecewiseConstant,
    problem: MoveProblem,
    time_optimal_duration: float,
    tol: float,
    residual: np.ndarray | None = None,
) -> dict:
    """Duration, added time and robustness figures of a command (JSON-friendly).

    ``residual``: the modes' residual amplitudes if already simulated (else simulated here).
    """
    model = problem.model
    T = u.duration
    info = {
        "time_optimal_duration": float(time_optimal_duration),
        "added_time_s": float(T - time_optimal_duration),
        "added_time_percent": float(100.0 * (T / time_optimal_duration - 1.0)) if time_optimal_duration > 0 else 0.0,
    }
    if model.n_modes and T > 0.0:
        amp = residual_amplitudes(model, problem.x0, u) if residual is None else np.asarray(residual)
        w, z, b = (np.asarray(v, dtype=float) for v in (model.omega, model.zeta, model.b))
        step = np.abs(b) * problem.u_max / (w * w * np.sqrt(1.0 - z * z))
        ins = command_insensitivity(u, model, tol, problem.u_max)
        info.update(
            residual_amplitude=[float(a) for a in amp],
            residual_percent=float(np.max(100.0 * amp / step)),
            insensitivity=ins.to_dict(),
            insensitivity_width=float(ins.width),
        )
    return info


def _check_problem(method: str, problem: MoveProblem) -> None:
    if not problem.model.n_modes:
        raise ConfigError("method", f"{method} shapes vibration modes; the model has none (use time_optimal)")


def _time_optimal_bound(move: PreparedMove) -> tuple[float, str]:
    """The time-optimal duration ``T*`` (s), a proved lower bound for the shaped move, and a note.

    A shaped move needs ``T*`` only for its figures (time added, the sampled
    count's lower bound): when the time-optimal planner refuses the model
    (e.g. its work budget on an 8-mode model), the rigid body's own minimum
    time, also a proved lower bound, stands in and the note says so; the
    shaped plan itself does not depend on it.
    """
    try:
        return plan_time_optimal(move).duration, ""
    except SolverError as exc:
        problem = move.problem
        T = rigid_time(problem.model, problem.u_max, move.x0, problem.include_position)
        return T, f"time_optimal_duration is the rigid-body minimum time (time-optimal planner: {exc})"


def _shaper_planner(name: str):
    def planner(config: PlannerConfig, problem: MoveProblem | PreparedMove, rate_hz: float | None) -> PlanResult:
        move = prepare(problem)  # responses built once for every planner below
        problem = move.problem
        o = options(config)
        _check_problem(name, problem)
        t0 = time.perf_counter()
        model = problem.model
        shaper = design(
            name, model.omega, model.zeta, o["shaper.tolerance"], o["shaper.negative_amplitude"], o["shaper.multimode"]
        )
        profile = plan_shaped(problem, shaper, name)
        plan_time = time.perf_counter() - t0
        T_low, note = _time_optimal_bound(move)
        sampled = None
        if rate_hz:
            lower = max(1, math.ceil(T_low * rate_hz * (1.0 - 1e-12)))
            sampled = sample_command(move, profile.command, rate_hz, name, profile, lower)
        info = {"plan_time_s": plan_time, "shaper_duration": shaper.duration, "rigid_level": profile.level}
        info.update(robustness_info(profile.command, problem, T_low, o["robustness.tolerance"], profile.residual))
        if note:
            info["time_optimal_note"] = note
        # the shaper's own figure (Singhose's), per mode: independent of the command
        info["shaper_insensitivity_width"] = [
            float(shaper_insensitivity(shaper, o["robustness.tolerance"], i).width) for i in range(len(shaper.omega))
        ]
        return PlanResult(method=name, problem=problem, continuous=profile, sampled=sampled, info=info)

    return planner


#: One method per shaper: name -> (description, planner).
SHAPER_METHODS = {
    name: (f"input shaper: {desc} (shaped rigid-body time-optimal move)", _shaper_planner(name))
    for name, desc in SHAPERS.items()
}
