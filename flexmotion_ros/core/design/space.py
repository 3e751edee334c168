"""The structural design space: which builder parameters can vary, their ranges, building models.

A design (:mod:`.design`) varies one to three physical parameters of a
builder (:mod:`.builders`: ``two_mass``, ``crane``, ``chain``) around a
starting set; this module names those parameters, holds their physical
ranges, validates a starting set, builds the model at given values, and maps
a structure to and from the ``design:`` section of a parameter file.

Parameter names
---------------
The builders' argument names: ``m1, m2, k, d`` (two_mass); ``cart_mass,
payload_mass, cable_length, g, zeta`` (crane); for a chain one element of a
list, 0-based: ``masses[i]``, ``springs[i]``, ``dampers[i]``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ConfigError
from ..model.builders import BUILDERS, BuiltModel

_POS, _NONNEG = (0.0, True, math.inf, False), (0.0, False, math.inf, False)
#: Physical range of each designable parameter: (low, low excluded, high, high excluded, unit).
PARAMETER_RANGES: dict[str, dict[str, tuple]] = {
    "two_mass": {"m1": (*_POS, "kg"), "m2": (*_POS, "kg"), "k": (*_POS, "N/m"), "d": (*_NONNEG, "N s/m")},
    "crane": {
        "cart_mass": (*_POS, "kg"),
        "payload_mass": (*_POS, "kg"),
        "cable_length": (*_POS, "m"),
        "g": (*_POS, "m/s^2"),
        "zeta": (0.0, False, 1.0, True, ""),
    },
    "chain": {"masses": (*_POS, "kg"), "springs": (*_POS, "N/m"), "dampers": (*_NONNEG, "N s/m")},
}
#: Defaults of the optional builder arguments.
_OPTIONAL = {"two_mass": {"d": 0.0}, "crane": {"g": 9.81, "zeta": 0.0}, "chain": {"dampers": None, "force_on": 0}}
_REQUIRED = {
    "two_mass": ("m1", "m2", "k"),
    "crane": ("cart_mass", "payload_mass", "cable_length"),
    "chain": ("masses", "springs"),
}
INDEXED_PARAMETER = re.compile(r"^(masses|springs|dampers)\[(\d+)\]$")
MAX_PARAMETERS = 3


def range_text(rng: tuple) -> str:
    lo, lo_x, hi, hi_x, unit = rng
    unit = f" {unit}" if unit else ""
    if math.isinf(hi):
        return f"{'>' if lo_x else '>='} {lo:g}{unit}"
    return f"in {'(' if lo_x else '['}{lo:g}, {hi:g}{')' if hi_x else ']'}{unit}"


def in_range(x: float, rng: tuple) -> bool:
    lo, lo_x, hi, hi_x, _ = rng
    return (x > lo if lo_x else x >= lo) and (x < hi if hi_x else x <= hi)


def check_builder(builder: str) -> str:
    if builder not in BUILDERS:
        raise ConfigError("design.builder", f"must be one of {sorted(BUILDERS)}, got {builder!r}")
    return builder


def normalise_base(builder: str, base: Mapping[str, Any]) -> dict[str, Any]:
    """The builder's full argument set: ``base`` plus defaults; unknown or missing names refused."""
    check_builder(builder)
    known = set(_REQUIRED[builder]) | set(_OPTIONAL[builder])
    for key in base:
        if key not in known:
            raise ConfigError(f"design.{key}", f"is not a parameter of builder {builder}; known: {sorted(known)}")
    for key in _REQUIRED[builder]:
        if key not in base:
            raise ConfigError(f"design.{key}", f"is required by builder {builder} (its starting value)")
    out = {**_OPTIONAL[builder], **base}

    def num(key, v):
        try:
            return float(v)
        except (TypeError, ValueError):
            raise ConfigError(f"design.{key}", f"must be a number, got {v!r}") from None

    def physical(key, v, rng):
        x = num(key, v)
        if not (math.isfinite(x) and in_range(x, rng)):
            raise ConfigError(f"design.{key}", f"must be {range_text(rng)}, got {x}")
        return x

    ranges = PARAMETER_RANGES[builder]
    if builder != "chain":
        return {k: physical(k, v, ranges[k]) for k, v in out.items()}
    for key in ("masses", "springs", "dampers"):
        if out[key] is not None:
            out[key] = [physical(f"{key}[{i}]", v, ranges[key]) for i, v in enumerate(np.atleast_1d(out[key]))]
    if out["dampers"] is None:
        out["dampers"] = [0.0] * len(out["springs"])
    fo = num("force_on", out["force_on"])
    if fo != int(fo):
        raise ConfigError("design.force_on", f"must be a mass index (integer), got {out['force_on']}")
    out["force_on"] = int(fo)
    return out


def build(builder: str, base: Mapping[str, Any], values: Mapping[str, float] | None = None) -> BuiltModel:
    """The physical model with some parameters replaced (names as in the module docstring)."""
    kw = {k: (list(v) if isinstance(v, list) else v) for k, v in base.items()}
    for name, value in (values or {}).items():
        m = INDEXED_PARAMETER.match(name)
        if m:
            kw[m.group(1)][int(m.group(2))] = float(value)
        else:
            kw[name] = float(value)
    return BUILDERS[builder](**kw)


def parameter_value(base: Mapping[str, Any], name: str) -> float:
    """The value of a (possibly indexed) parameter in ``base``."""
    m = INDEXED_PARAMETER.match(name)
    return float(base[m.group(1)][int(m.group(2))]) if m else float(base[name])


@dataclass(frozen=True)
class DesignParameter:
    """One free structural parameter.

    Attributes
    ----------
    name : str
        Builder argument name (``k``, ``cable_length``, ``springs[1]``, ...).
    lower, upper : float
        Bounds (the parameter's unit), ``lower < upper``, both physical.
    scale : str
        ``"linear"``, ``"log"`` or ``"auto"`` (log when ``upper / lower >= 10``).
    """

    name: str
    lower: float
    upper: float
    scale: str = "auto"

    def to_unit(self, x: float) -> float:
        """Search coordinate in ``[0, 1]`` (linear or logarithmic in the value)."""
        if self.scale == "log":
            return math.log(x / self.lower) / math.log(self.upper / self.lower)
        return (x - self.lower) / (self.upper - self.lower)

    def from_unit(self, u: float) -> float:
        """Inverse of :meth:`to_unit`; the bounds exactly at 0 and 1."""
        if u <= 0.0:
            return self.lower
        if u >= 1.0:
            return self.upper
        if self.scale == "log":
            return self.lower * (self.upper / self.lower) ** u
        return self.lower + u * (self.upper - self.lower)


# --------------------------------------------------------------- parameter files
def design_parameters(builder: str, physical: Mapping[str, Any]) -> dict[str, Any]:
    """Flat ``design.*`` parameters describing a structure (for a parameter file)."""
    out: dict[str, Any] = {"design.builder": builder}
    for k, v in physical.items():
        out[f"design.{k}"] = list(v) if isinstance(v, (list, tuple)) else v
    return out


def split_parameters(params: Mapping[str, Any]) -> tuple[str | None, dict[str, Any], dict[str, Any]]:
    """``(builder, base, planner_params)`` from flat parameters with an optional ``design:`` section."""
    planner = {k: v for k, v in params.items() if not k.startswith("design.")}
    design = {k[len("design.") :]: v for k, v in params.items() if k.startswith("design.")}
    builder = design.pop("builder", None)
    return (None if builder is None else str(builder)), design, planner
