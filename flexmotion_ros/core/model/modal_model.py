"""The modal model of a flexible machine (seed eqs. 2.1-2.3, 2.6-2.7).

A rigid body (position ``p``, velocity ``v``) plus ``N`` lightly damped
vibration modes, driven by one bounded input ``u``::

    p'' = c p' + b0 u
    q_i'' = -omega_i**2 q_i - 2 zeta_i omega_i q_i' + b_i u

State order: ``[p, v, q_1, q_1', ..., q_N, q_N']``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError
from ..tolerances import REPEATED_FREQUENCY_RTOL


def _finite(name: str, value: float) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ModelError(name, f"must be a finite number, got {value!r}") from None
    if not math.isfinite(x):
        raise ModelError(name, f"must be finite, got {x}")
    return x


def check_positive(name: str, value: float, unit: str = "") -> float:
    """Return ``value`` as float if finite and > 0, else raise :class:`ModelError`."""
    x = _finite(name, value)
    if x <= 0.0:
        raise ModelError(name, f"must be > 0{(' ' + unit) if unit else ''}, got {x}")
    return x


@dataclass(frozen=True)
class ModalModel:
    """Rigid body plus ``N`` vibration modes, one input.

    Parameters
    ----------
    b0 : float
        Rigid-body input gain (acceleration per unit input, e.g. 1/kg).  Non-zero.
    c : float
        Rigid-body viscous term (1/s), ``c <= 0``.
    omega : sequence of float
        Undamped natural frequencies (rad/s), each ``> 0``, no two equal.
    zeta : sequence of float
        Damping ratios, each in ``[0, 1)``.
    b : sequence of float
        Modal input gains, each non-zero (a zero gain is an uncontrollable mode).
    """

    b0: float
    c: float = 0.0
    omega: tuple[float, ...] = ()
    zeta: tuple[float, ...] = ()
    b: tuple[float, ...] = ()
    names: tuple[str, ...] = field(default=(), compare=False)

    def __post_init__(self) -> None:
        b0 = _finite("model.b0", self.b0)
        if b0 == 0.0:
            raise ModelError("model.b0", "must be non-zero (the rigid body would be uncontrollable)")
        c = _finite("model.c", self.c)
        if c > 0.0:
            raise ModelError("model.c", f"must be <= 0 1/s (viscous term), got {c}")
        omega = tuple(self._seq("model.omega", self.omega))
        zeta = tuple(self._seq("model.zeta", self.zeta))
        b = tuple(self._seq("model.b", self.b))
        if not (len(omega) == len(zeta) == len(b)):
            raise ModelError(
                "model.omega/zeta/b",
                f"must have the same length, got {len(omega)}, {len(zeta)}, {len(b)}",
            )
        for i, (w, z, bi) in enumerate(zip(omega, zeta, b)):
            if w <= 0.0:
                raise ModelError(f"model.omega[{i}]", f"must be > 0 rad/s, got {w}")
            if not 0.0 <= z < 1.0:
                raise ModelError(f"model.zeta[{i}]", f"must be in [0, 1), got {z}")
            if bi == 0.0:
                raise ModelError(
                    f"model.b[{i}]",
                    "must be non-zero: a mode with zero input gain is uncontrollable",
                )
        for i in range(len(omega)):
            for j in range(i + 1, len(omega)):
                if abs(omega[i] - omega[j]) <= REPEATED_FREQUENCY_RTOL * max(omega[i], omega[j]):
                    raise ModelError(
                        f"model.omega[{j}]",
                        f"repeats model.omega[{i}] = {omega[i]} rad/s: two modes at one "
                        "frequency are not controllable with one input; merge them",
                    )
        object.__setattr__(self, "b0", b0)
        object.__setattr__(self, "c", c)
        object.__setattr__(self, "omega", omega)
        object.__setattr__(self, "zeta", zeta)
        object.__setattr__(self, "b", b)
        names = tuple(self.names) or tuple(f"mode_{i + 1}" for i in range(len(omega)))
        if len(names) != len(omega):
            raise ModelError("model.names", f"needs one name per mode ({len(omega)})")
        object.__setattr__(self, "names", names)

    @staticmethod
    def _seq(name: str, values: Sequence[float] | float) -> list[float]:
        if np.isscalar(values):
            values = [values]  # type: ignore[list-item]
        return [_finite(f"{name}[{i}]", v) for i, v in enumerate(values)]  # type: ignore[arg-type]

    # ------------------------------------------------------------------ sizes
    @property
    def n_modes(self) -> int:
        """Number of vibration modes ``N``."""
        return len(self.omega)

    @property
    def n_states(self) -> int:
        """State dimension ``2N + 2``."""
        return 2 * self.n_modes + 2

    @property
    def omega_d(self) -> np.ndarray:
        """Damped natural frequencies ``omega_i sqrt(1 - zeta_i^2)`` (rad/s)."""
        w = np.asarray(self.omega)
        z = np.asarray(self.zeta)
        return w * np.sqrt(1.0 - z * z)

    def state_names(self) -> list[str]:
        """Names of the state components, in state order."""
        out = ["p", "v"]
        for name in self.names:
            out += [name, name + "_dot"]
        return out

    # --------------------------------------------------------------- matrices
    def A(self) -> np.ndarray:
        """State matrix of eqs. 2.2-2.3 (block diagonal)."""
        n = self.n_states
        A = np.zeros((n, n))
        A[0, 1] = 1.0
        A[1, 1] = self.c
        for i, (w, z) in enumerate(zip(self.omega, self.zeta)):
            k = 2 + 2 * i
            A[k, k + 1] = 1.0
            A[k + 1, k] = -w * w
            A[k + 1, k + 1] = -2.0 * z * w
        return A

    def B(self) -> np.ndarray:
        """Input vector of eqs. 2.2-2.3, shape ``(n_states,)``."""
        B = np.zeros(self.n_states)
        B[1] = self.b0
        B[3::2] = self.b
        return B

    def modal_form(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Modal form of eqs. 2.6-2.7.

        Returns
        -------
        A_tilde, B_tilde, M : ndarray
            ``x = M x_tilde``; each mode block of ``A_tilde`` is
            ``[[-zeta w, w_d], [-w_d, -zeta w]]``; the rigid block is unchanged.
        """
        n = self.n_states
        M = np.eye(n)
        for i, (z, wd) in enumerate(zip(self.zeta, self.omega_d)):
            k = 2 + 2 * i
            M[k : k + 2, k : k + 2] = [[1.0 / wd, 0.0], [-z / math.sqrt(1.0 - z * z), 1.0]]
        Minv = np.linalg.inv(M)
        return Minv @ self.A() @ M, Minv @ self.B(), M

    def rest_state(self, position: float = 0.0) -> np.ndarray:
        """The equilibrium at rest at ``position`` (m or rad)."""
        x = np.zeros(self.n_states)
        x[0] = position
        return x

    def with_changes(self, **changes: object) -> ModalModel:
        """A copy with some parameters replaced (validated again)."""
        params = dict(b0=self.b0, c=self.c, omega=self.omega, zeta=self.zeta, b=self.b, names=self.names)
        params.update(changes)
        if "omega" in changes and "names" not in changes and len(params["omega"]) != len(self.names):  # type: ignore[arg-type]
            params["names"] = ()
        return ModalModel(**params)  # type: ignore[arg-type]

    def natural_distance(self, u_max: float) -> float:
        """A move distance on the scale of the first mode (m or rad).

        ``|b0| u_max / omega_1**2``: the distance covered by a full-force
        rigid-body move lasting about ``2 / omega_1``.  Moves far below it are
        quasi-static for every mode; far above it, long relative to a period.
        Rigid-only models use 1.
        """
        if not self.omega:
            return 1.0
        return abs(self.b0) * u_max / min(self.omega) ** 2

    def to_dict(self) -> dict[str, object]:
        """Parameters as plain Python values (for YAML / JSON)."""
        return {
            "b0": self.b0,
            "c": self.c,
            "omega": list(self.omega),
            "zeta": list(self.zeta),
            "b": list(self.b),
        }
