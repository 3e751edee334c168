"""What a machine's sensors read: physical coordinates of the modal state (the ``measurements`` map).

A sensor reads one physical coordinate -- a cart's position, a rope angle, a
mass position, a tip acceleration -- which is a fixed combination of the
rigid-body positions and the modal coordinates (a builder's
``modal_to_physical`` row)::

    z = [p_1, ..., p_k, q_1, ..., q_N]          (positions of the model's coordinates)
    y_pos = map @ z                              (m, rad)
    y_vel = map @ z'                             (m/s)
    y_acc = map @ z''  = map @ (A x + B u) rows  (m/s^2: feeds the input through)

so, over the state ``x`` of any model with state matrices ``A``, ``B``,
``y = C x + D u`` exactly, with ``D`` non-zero only in acceleration rows
(:meth:`MeasurementMap.matrices`).

Parameters (the same names in the planner's and the plant's file):
``measurement.names`` (string array), ``measurement.map`` (double array,
row-major, ``len(names) x (k + N)``), ``measurement.kinds`` (string array, one
per name: ``position`` | ``velocity`` | ``acceleration``; default position).
Without them a machine measures its rigid-body position(s): names are the
rigid bodies' names, the map the identity on ``p``.

Sample convention (the plant's ``measurements`` topic and
:mod:`~flexmotion_ros.core.identification` alike): at ``t_k`` the machine has
state ``x_k`` and the command ``u_k`` is applied; the reading ``y_k = C x_k +
D u_k`` is taken just after, then the state evolves to ``x_{k+1}``.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import Enum
from typing import Any

import numpy as np

from ..errors import ConfigError
from .builders import BuiltModel
from .modal_model import ModalModel


class MeasurementKind(str, Enum):
    """What one channel reads of its physical coordinate (the values are the parameter's strings)."""

    POSITION = "position"
    VELOCITY = "velocity"
    ACCELERATION = "acceleration"

    def __str__(self) -> str:
        return str(self.value)


KIND_NAMES: tuple[str, ...] = tuple(k.value for k in MeasurementKind)

#: Parameter names, for messages.
NAMES, MAP, KINDS = "measurement.names", "measurement.map", "measurement.kinds"


@dataclass(frozen=True, kw_only=True, eq=False)
class MeasurementMap:
    """The measured channels of a machine.

    Attributes
    ----------
    names : tuple of str
        Physical coordinate names, one per channel (unique).
    map : ndarray, shape ``(m, k + N)``
        ``y_pos = map @ [p_1..p_k, q_1..q_N]`` (velocities and accelerations likewise).
    kinds : tuple of MeasurementKind
        What each channel reads.
    rigid : int
        Number of rigid-body coordinates ``k`` (the first ``k`` columns).
    """

    names: tuple[str, ...]
    map: np.ndarray
    kinds: tuple[MeasurementKind, ...]
    rigid: int = 1

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, MeasurementMap):
            return NotImplemented
        return (
            self.names == other.names
            and self.kinds == other.kinds
            and self.rigid == other.rigid
            and np.array_equal(self.map, other.map)
        )

    __hash__ = None  # type: ignore[assignment]  -- holds an array

    @property
    def channels(self) -> int:
        """Number of channels ``m``."""
        return len(self.names)

    @property
    def n_modes(self) -> int:
        """Number of modal columns ``N``."""
        return int(self.map.shape[1]) - self.rigid

    def rigid_weights(self) -> np.ndarray:
        """Weight of the rigid body in each channel (``map[:, 0]``; single rigid body)."""
        return self.map[:, 0].copy()

    def sees_modes(self) -> np.ndarray:
        """Per mode, whether any channel reads it (a non-zero modal column)."""
        return np.any(self.map[:, self.rigid :] != 0.0, axis=0)

    def matrices(self, A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``C`` (m, n) and ``D`` (m, inputs) with ``y = C x + D u`` for a state ``[p_1, v_1, .., q_1, q_1', ..]``.

        The positions are the even state entries and their velocities the odd
        ones (the layout of :class:`ModalModel` and of the multi-input model);
        accelerations are the velocity rows of ``A x + B u``.
        """
        A = np.asarray(A, float)
        B = np.asarray(B, float)
        if B.ndim == 1:
            B = B[:, None]
        n = A.shape[0]
        if n != 2 * self.map.shape[1]:
            raise ConfigError(
                MAP,
                f"has {self.map.shape[1]} columns, the model has {n // 2} coordinates "
                f"({self.rigid} rigid, {n // 2 - self.rigid} modal)",
            )
        P = np.zeros((n // 2, n))
        P[np.arange(n // 2), np.arange(0, n, 2)] = 1.0
        V = np.zeros((n // 2, n))
        V[np.arange(n // 2), np.arange(1, n, 2)] = 1.0
        C = np.zeros((self.channels, n))
        D = np.zeros((self.channels, B.shape[1]))
        for j, kind in enumerate(self.kinds):
            row = self.map[j]
            if kind is MeasurementKind.POSITION:
                C[j] = row @ P
            elif kind is MeasurementKind.VELOCITY:
                C[j] = row @ V
            else:
                C[j] = row @ V @ A
                D[j] = row @ V @ B
        return C, D

    def for_model(self, model: ModalModel) -> tuple[np.ndarray, np.ndarray]:
        """``C`` (m, 2N + 2) and ``D`` (m,) of a single-input :class:`ModalModel`."""
        C, D = self.matrices(model.A(), model.B())
        return C, D[:, 0]

    def to_parameters(self) -> dict[str, Any]:
        """``measurement.*`` as flat ROS parameters."""
        return {
            NAMES: list(self.names),
            MAP: [float(v) for v in self.map.ravel()],
            KINDS: [k.value for k in self.kinds],
        }


def default_map(n_modes: int, rigid_names: Sequence[str] = ("rigid_body",)) -> MeasurementMap:
    """The rigid-body position(s) only: what a machine without ``measurement.*`` measures."""
    k = len(rigid_names)
    M = np.zeros((k, k + n_modes))
    M[:, :k] = np.eye(k)
    return MeasurementMap(names=tuple(rigid_names), map=M, kinds=(MeasurementKind.POSITION,) * k, rigid=k)


def _names(value: Any) -> tuple[str, ...]:
    names = tuple(str(v) for v in (value or ()))
    for i, name in enumerate(names):
        if not name.strip():
            raise ConfigError(f"{NAMES}[{i}]", "must be a non-empty name")
    dup = next((n for n in names if names.count(n) > 1), None)
    if dup is not None:
        raise ConfigError(NAMES, f"names must be unique, {dup!r} appears twice")
    return names


def _kinds(value: Any, count: int) -> tuple[MeasurementKind, ...]:
    kinds = [str(v) for v in (value or ())]
    if not kinds:
        return (MeasurementKind.POSITION,) * count
    if len(kinds) != count:
        raise ConfigError(KINDS, f"needs one kind per name ({count}), got {len(kinds)}; allowed {list(KIND_NAMES)}")
    out = []
    for i, k in enumerate(kinds):
        if k not in KIND_NAMES:
            close = difflib.get_close_matches(k, KIND_NAMES, n=1, cutoff=0.6)
            hint = f" (closest: {close[0]!r})" if close else ""
            raise ConfigError(f"{KINDS}[{i}]", f"must be one of {list(KIND_NAMES)}, got {k!r}{hint}")
        out.append(MeasurementKind(k))
    return tuple(out)


def measurement_map(
    params: Mapping[str, Any], n_modes: int, rigid_names: Sequence[str] = ("rigid_body",)
) -> MeasurementMap:
    """The map from flat parameters (``measurement.names``, ``.map``, ``.kinds``); :func:`default_map` if unset.

    Parameters
    ----------
    params : mapping
        Flat parameters; missing or empty ``measurement.*`` entries are unset.
    n_modes : int
        Modes of the model (``N``).
    rigid_names : sequence of str
        Rigid-body coordinate names (``k`` of them).

    Raises
    ------
    ConfigError
        Naming the parameter: names without a map (or the reverse), a map of
        the wrong size, a non-finite entry, a channel that reads nothing, kinds
        not one per name or not a known kind.
    """
    k = len(rigid_names)
    names = _names(params.get(NAMES))
    raw = list(params.get(MAP) or ())
    kinds_given = list(params.get(KINDS) or ())
    if not names:
        if raw or kinds_given:
            raise ConfigError(NAMES, f"must name the channels of {MAP if raw else KINDS} (one name per row)")
        return default_map(n_modes, rigid_names)
    cols = k + n_modes
    if len(raw) != len(names) * cols:
        raise ConfigError(
            MAP,
            f"needs len(measurement.names) x (rigid bodies + modes) = {len(names)} x {cols} = {len(names) * cols} "
            f"values (row-major), got {len(raw)}",
        )
    try:
        M = np.array([float(v) for v in raw], dtype=float).reshape(len(names), cols)
    except (TypeError, ValueError):
        raise ConfigError(MAP, f"must be numbers, got {raw!r}") from None
    if not np.all(np.isfinite(M)):
        i = int(np.argmax(~np.isfinite(M.ravel())))
        raise ConfigError(f"{MAP}[{i}]", f"must be finite, got {M.ravel()[i]}")
    for j, name in enumerate(names):
        if not np.any(M[j] != 0.0):
            raise ConfigError(MAP, f"row {j} ({name!r}) is all zero: that channel would read nothing")
    return MeasurementMap(names=names, map=M, kinds=_kinds(kinds_given, len(names)), rigid=k)


def builder_map(built: BuiltModel) -> MeasurementMap:
    """The positions a builder's machine is measured at: its physical coordinates (``modal_to_physical``).

    A crane also reads its rope angle ``theta = s / L`` (rad; ``s`` the payload's offset from the cart).
    """
    names = list(built.coordinates)
    rows = [np.asarray(row, float) for row in built.modal_to_physical]
    length = built.parameters.get("cable_length")
    if built.kind == "crane" and length:
        names.append("rope_angle")
        rows.append(np.array([0.0, 1.0 / float(length)]))
    M = np.vstack(rows)
    return MeasurementMap(names=tuple(names), map=M, kinds=(MeasurementKind.POSITION,) * len(names))


def noise_levels(value: Any, channels: int, parameter: str = "plant.noise_std") -> np.ndarray:
    """Per-channel white-noise standard deviations from one value or one per channel (each >= 0, finite)."""
    vals = value if isinstance(value, (list, tuple, np.ndarray)) else [value]
    try:
        arr = np.array([float(v) for v in vals], dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(parameter, f"must be a number >= 0 or one per channel, got {value!r}") from None
    if arr.size == 0:
        arr = np.zeros(1)
    if arr.size not in (1, channels):
        raise ConfigError(parameter, f"needs one value or one per measured channel ({channels}), got {arr.size}")
    for i, s in enumerate(arr):
        if not (math.isfinite(s) and s >= 0.0):
            raise ConfigError(parameter, f"must be finite and >= 0 (units of the channel), got {s} at {i}")
    return np.broadcast_to(arr, (channels,)).copy()


__all__ = [
    "KIND_NAMES",
    "MeasurementKind",
    "MeasurementMap",
    "builder_map",
    "default_map",
    "measurement_map",
    "noise_levels",
]
