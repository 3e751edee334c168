"""``flexmotion model`` for several drives: ``gantry``, ``chain --actuated``, ``two-mass --actuated``.

The parameter file is written as a
:class:`~flexmotion_ros.core.multi_input.config.MultiPlannerConfig` writes
itself (``model.inputs``, flat row-major ``b0`` and ``b``, one ``u_max`` per
input); its header says what the inputs, rigid bodies and modes are and
gives the map back to the physical coordinates
(:attr:`~flexmotion_ros.core.multi_input.builders.MultiBuiltModel.modal_to_physical`).
"""

from __future__ import annotations

import argparse

import numpy as np

from ..core.errors import ModelError
from ..core.model.measurement import MeasurementKind, MeasurementMap
from ..core.multi_input.builders import MultiBuiltModel, gantry, multi_chain, multi_two_mass
from ..core.multi_input.config import MultiPlannerConfig
from ..core.parameter_file import dump_parameters


def indices(text: str) -> list[int]:
    """``"0,3"`` -> ``[0, 3]`` (the actuated masses)."""
    try:
        return [int(v) for v in text.replace(",", " ").split()]
    except ValueError:
        raise ModelError("actuated", f"must be mass indices such as 0,3, got {text!r}") from None


def bounds(text: str | None) -> list[float] | None:
    """``"30,50"`` -> ``[30.0, 50.0]`` (one force bound per drive)."""
    if text is None:
        return None
    try:
        return [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        raise ModelError("u_max", f"must be numbers such as 30,50 (N, one per drive), got {text!r}") from None


def _u_max(a: argparse.Namespace, m: int):
    values = bounds(getattr(a, "u_max_list", None))
    if values is None:
        return float(a.u_max)
    if len(values) not in (1, m):
        raise ModelError("u_max", f"needs one bound per actuated mass ({m}) or one for all, got {len(values)}")
    return values if len(values) == m else values * m


def build_gantry(a: argparse.Namespace) -> MultiBuiltModel:
    return gantry(
        a.trolley_mass,
        a.bridge_mass,
        a.payload_mass,
        a.rope_length,
        a.g,
        trolley_force=a.trolley_force,
        bridge_force=a.bridge_force,
        zeta=a.zeta,
    )


def build_chain(a: argparse.Namespace) -> MultiBuiltModel:
    act = indices(a.actuated)
    return multi_chain(a.masses, a.springs, a.dampers, act, _u_max(a, len(act)))


def build_two_mass(a: argparse.Namespace) -> MultiBuiltModel:
    act = indices(a.actuated)
    return multi_two_mass(a.m1, a.m2, a.k, a.d, act, _u_max(a, len(act)))


def physical_map(built: MultiBuiltModel) -> list[str]:
    """One line per physical coordinate: ``name = c1 p_1 + ... + cN q_N`` (positions; velocities alike)."""
    model = built.model
    names = [*model.rigid_bodies, *model.mode_names]
    lines = []
    for coord, row in zip(built.coordinates, np.asarray(built.modal_to_physical, float)):
        terms = [f"{c:+.9g} {n}" for c, n in zip(row, names) if c != 0.0]
        lines.append(f"{coord} = {' '.join(terms) if terms else '0'}")
    return lines


def text(built: MultiBuiltModel, kind: str, rate_hz: float) -> str:
    """The parameter file of ``built`` with a header: what it is and the map to physical coordinates."""
    config = MultiPlannerConfig(model=built.model, u_max=built.u_max, rate_hz=rate_hz)
    params = config.to_parameters()
    for key in ("limits.position_min", "limits.position_max", "max_move_duration_s", "max_move_samples"):
        del params[key]
    model = built.model
    # what the machine's sensors read (the plant's 'measurements' topic): the builder's physical coordinates
    sensors = MeasurementMap(
        names=tuple(built.coordinates),
        map=np.asarray(built.modal_to_physical, float),
        kinds=(MeasurementKind.POSITION,) * len(built.coordinates),
        rigid=model.k,
    )
    params.update(sensors.to_parameters())
    desc = ", ".join(f"{k}={v}" for k, v in built.parameters.items())
    header = [
        f"flexmotion model {kind}: {desc}",
        f"{model.m} inputs {list(model.inputs)} (commands, in this order), {model.k} rigid bodies "
        f"{list(model.rigid_bodies)}, {model.n_modes} modes {list(model.mode_names)}; normal: {model.is_normal}",
        "physical coordinates (positions; velocities alike) from the state's positions:",
        *(f"  {line}" for line in physical_map(built)),
    ]
    return dump_parameters(params, "".join(f"# {h}\n" for h in header))


__all__ = ["bounds", "build_chain", "build_gantry", "build_two_mass", "indices", "physical_map", "text"]
