"""The multi-input model from the parameter-file layout (flat, row-major matrices).

ROS parameters cannot nest arrays, so ``b0`` (``k x m``) and ``b``
(``N x m``) are flat lists, row-major::

    model:
      inputs: [trolley, bridge]          # m actuated joints
      rigid_bodies: [x, y]               # k rigid-body coordinates
      b0: [0.004, 0.0, 0.0, 0.0018]      # k x m (1/kg)
      c: [0.0, 0.0]
      omega: [1.85, 2.48]                # rad/s
      zeta: [0.0, 0.0]
      b: [0.0, -0.0006, -0.0025, 0.0]    # N x m
    u_max: [300.0, 500.0]                # one per input
    sync: time                           # time | none | phase
    fuel_weights: [1.0, 1.0]             # method min_fuel, one per input

``params`` may be nested (``{"model": {"b0": ...}}``), flat with dotted
names (``{"model.b0": ...}``), as :mod:`~flexmotion_ros.core.config` reads
them, or a whole parameter file as loaded (``{"/**": {"ros__parameters": ...}}``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, ModelError
from .model import MultiModel
from .problem import check_bounds

#: The parameter names this module reads (for the registry of :mod:`flexmotion_ros.core.parameters`).
PARAMETER_NAMES = (
    "model.inputs",
    "model.rigid_bodies",
    "model.b0",
    "model.c",
    "model.omega",
    "model.zeta",
    "model.b",
    "model.mode_names",
    "u_max",
    "sync",
    "fuel_weights",
)

#: Values of ``sync`` (see :class:`~flexmotion_ros.core.multi_input.results.SyncMode`).
SYNC_VALUES = ("time", "none", "phase")


def flatten(params: Mapping) -> dict:
    """Nested mappings -> dotted names (``{"model": {"b0": 1}}`` -> ``{"model.b0": 1}``)."""
    out: dict = {}
    for key, value in params.items():
        if key == "ros__parameters" and isinstance(value, Mapping):
            out.update(flatten(value))
        elif isinstance(value, Mapping) and "ros__parameters" in value:  # a node-name key such as "/**"
            out.update(flatten(value["ros__parameters"]))
        elif isinstance(value, Mapping):
            for sub, v in flatten(value).items():
                out[f"{key}.{sub}"] = v
        else:
            out[str(key)] = value
    return out


def _list(value) -> list:
    if value is None:
        return []
    if isinstance(value, (str, bytes)):
        return [value]
    return list(np.atleast_1d(np.asarray(value, dtype=object)).ravel())


def is_multi_input(params: Mapping) -> bool:
    """Whether a parameter set describes a multi-input model (``model.inputs`` given)."""
    return "model.inputs" in flatten(params)


def multi_model_from_parameters(params: Mapping) -> MultiModel:
    """The :class:`MultiModel` of a parameter set (see the module docstring for the layout).

    Raises
    ------
    ModelError
        Naming the parameter: wrong sizes, non-physical values, an
        uncontrollable model (names the mode or rigid body and the inputs).
    """
    p = flatten(params)
    inputs = [str(v) for v in _list(p.get("model.inputs"))]
    if not inputs:
        raise ModelError("model.inputs", "must list the m >= 1 input names, e.g. [trolley, bridge]")
    bodies = [str(v) for v in _list(p.get("model.rigid_bodies", ["rigid_body"]))]
    m, k = len(inputs), len(bodies)
    omega = _list(p.get("model.omega"))
    N = len(omega)
    c = _list(p.get("model.c", [0.0] * k))
    if len(c) == 1 and k > 1:
        c = c * k
    b0 = _list(p.get("model.b0"))
    b = _list(p.get("model.b"))
    if len(b0) != k * m:
        raise ModelError(
            "model.b0",
            f"must have k x m = {k} x {m} = {k * m} entries (row-major: rigid body, then input), got {len(b0)}",
        )
    if len(b) != N * m:
        raise ModelError(
            "model.b", f"must have N x m = {N} x {m} = {N * m} entries (row-major: mode, then input), got {len(b)}"
        )
    zeta = _list(p.get("model.zeta", [0.0] * N))
    names = [str(v) for v in _list(p.get("model.mode_names"))]
    return MultiModel(
        inputs=tuple(inputs),
        rigid_bodies=tuple(bodies),
        b0=b0,
        c=tuple(c),
        omega=tuple(omega),
        zeta=tuple(zeta),
        b=b,
        mode_names=tuple(names),
    )


def bounds_from_parameters(params: Mapping, model: MultiModel) -> np.ndarray:
    """``u_max`` as one positive bound per input (a single value applies to every input)."""
    p = flatten(params)
    values = _list(p.get("u_max"))
    if len(values) == 1:
        values = values * model.m
    if len(values) != model.m:
        raise ConfigError("u_max", f"needs one bound per input ({model.m}: {list(model.inputs)}), got {len(values)}")
    return check_bounds(values, model.m)


def check_sync(value) -> str:
    """``sync`` as one of :data:`SYNC_VALUES`, or :class:`ConfigError`."""
    s = str(value)
    if s not in SYNC_VALUES:
        raise ConfigError("sync", f"must be one of {list(SYNC_VALUES)}, got {value!r}")
    return s


@dataclass(frozen=True, kw_only=True)
class MultiSetup:
    """What a multi-input parameter set says besides the goal.

    Attributes
    ----------
    model : MultiModel
    u_max : ndarray
        One bound per input (N or the input's unit).
    sync : str
        ``time`` (default), ``none`` or ``phase``.
    fuel_weights : ndarray
        ``c_i`` of eq. 2.38 (default all 1).
    """

    model: MultiModel
    u_max: np.ndarray
    sync: str = "time"
    fuel_weights: np.ndarray | None = None


def multi_setup_from_parameters(params: Mapping) -> MultiSetup:
    """Model, bounds, ``sync`` and ``fuel_weights`` of a parameter set."""
    p = flatten(params)
    model = multi_model_from_parameters(p)
    u_max = bounds_from_parameters(p, model)
    sync = check_sync(p.get("sync", "time"))
    fw = p.get("fuel_weights")
    weights = check_bounds(fw, model.m, "fuel_weights") if fw is not None else np.ones(model.m)
    return MultiSetup(model=model, u_max=u_max, sync=sync, fuel_weights=weights)
