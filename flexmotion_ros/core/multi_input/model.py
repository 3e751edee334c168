"""The multi-input modal model (seed eq. 2.1 with ``m`` inputs).

``k`` rigid-body coordinates and ``N`` vibration modes driven by ``m`` bounded
inputs ``|u_i| <= u_max_i`` (eqs. 2.21-2.22)::

    p_j'' = c_j p_j' + sum_i b0[j, i] u_i                       j = 1..k
    q_l'' = -omega_l**2 q_l - 2 zeta_l omega_l q_l' + sum_i b[l, i] u_i   l = 1..N

State order ``[p_1, v_1, ..., p_k, v_k, q_1, q_1', ..., q_N, q_N']``.

Controllability (PBH test with all inputs) reduces, for this block-diagonal
``A``, to two rank conditions: the rows of ``b0`` are independent (every
rigid body has its own eigenvalue-0 left eigenvector, whose product with
``B`` is its row of ``b0``), and for every group of modes sharing one
eigenvalue (repeated ``omega`` and ``zeta``) the rows of ``b`` are
independent.  Normality (each input alone controls the system, Hermes-LaSalle)
is the same test with one column of ``B``: it needs ``k <= 1``, every gain of
that input non-zero and no repeated eigenvalue.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError
from ..model.modal_model import ModalModel
from ..tolerances import REPEATED_FREQUENCY_RTOL

#: Singular values below this (relative to the largest row norm) count as zero in the rank tests.
RANK_RTOL = 1e-9


def _finite(name: str, value) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ModelError(name, f"must be a finite number, got {value!r}") from None
    if not math.isfinite(x):
        raise ModelError(name, f"must be finite, got {x}")
    return x


def _names(name: str, values, count: int | None, default: str) -> tuple[str, ...]:
    if values is None or len(values) == 0:
        if count is None:
            raise ModelError(name, "must list at least one name")
        return tuple(f"{default}_{i + 1}" for i in range(count))
    out = tuple(str(v) for v in values)
    if any(not v for v in out):
        raise ModelError(name, "names must be non-empty strings")
    if len(set(out)) != len(out):
        dup = next(v for v in out if out.count(v) > 1)
        raise ModelError(name, f"names must be unique, {dup!r} appears twice")
    return out


def _matrix(name: str, values, rows: int, cols: int) -> tuple[tuple[float, ...], ...]:
    arr = np.asarray(values, dtype=object)
    flat = list(arr.ravel()) if arr.ndim else [values]
    if len(flat) != rows * cols:
        raise ModelError(name, f"must have {rows} x {cols} = {rows * cols} entries (row-major), got {len(flat)}")
    vals = [_finite(f"{name}[{i}]", v) for i, v in enumerate(flat)]
    return tuple(tuple(vals[r * cols : (r + 1) * cols]) for r in range(rows))


def _rank(rows: np.ndarray) -> int:
    if rows.size == 0:
        return 0
    scale = float(np.max(np.linalg.norm(rows, axis=1)))
    if scale == 0.0:
        return 0
    sv = np.linalg.svd(rows / scale, compute_uv=False)
    return int(np.count_nonzero(sv > RANK_RTOL))


@dataclass(frozen=True)
class MultiModel:
    """``k`` rigid bodies, ``N`` modes, ``m`` inputs (validated, controllable).

    Parameters
    ----------
    inputs : sequence of str
        Input (actuated joint) names, ``m >= 1``.
    rigid_bodies : sequence of str
        Rigid-body coordinate names, ``k >= 0``.
    b0 : k x m nested sequence
        Rigid-body input gains (acceleration per unit input, e.g. 1/kg).
    c : sequence of float
        Rigid-body viscous terms (1/s), each ``<= 0``.
    omega : sequence of float
        Natural frequencies (rad/s), each ``> 0``; any order, repeats allowed
        when the inputs together control them.
    zeta : sequence of float
        Damping ratios in ``[0, 1)``.
    b : N x m nested sequence
        Modal input gains.
    mode_names : sequence of str, optional
        Default ``mode_1 .. mode_N``.

    Raises
    ------
    ModelError
        Naming the parameter; an uncontrollable model names the mode or rigid
        body and the inputs that fail to reach it.
    """

    inputs: tuple[str, ...]
    rigid_bodies: tuple[str, ...]
    b0: tuple[tuple[float, ...], ...]
    c: tuple[float, ...]
    omega: tuple[float, ...] = ()
    zeta: tuple[float, ...] = ()
    b: tuple[tuple[float, ...], ...] = ()
    mode_names: tuple[str, ...] = field(default=(), compare=False)

    def __post_init__(self) -> None:
        inputs = _names("model.inputs", self.inputs, None, "u")
        m = len(inputs)
        bodies = tuple(self.rigid_bodies) if self.rigid_bodies is not None else ()
        bodies = _names("model.rigid_bodies", bodies, 0, "p") if bodies else ()
        k = len(bodies)
        c = tuple(_finite(f"model.c[{j}]", v) for j, v in enumerate(np.atleast_1d(np.asarray(self.c, dtype=object))))
        if len(c) != k:
            raise ModelError("model.c", f"needs one value per rigid body ({k}), got {len(c)}")
        for j, cj in enumerate(c):
            if cj > 0.0:
                raise ModelError(f"model.c[{j}]", f"must be <= 0 1/s (viscous term), got {cj}")
        b0 = _matrix("model.b0", self.b0, k, m) if k else ()
        omega = tuple(_finite(f"model.omega[{i}]", v) for i, v in enumerate(np.atleast_1d(self.omega)))
        zeta = tuple(_finite(f"model.zeta[{i}]", v) for i, v in enumerate(np.atleast_1d(self.zeta)))
        N = len(omega)
        if len(zeta) != N:
            raise ModelError("model.zeta", f"needs one damping ratio per mode ({N}), got {len(zeta)}")
        for i, (w, z) in enumerate(zip(omega, zeta)):
            if w <= 0.0:
                raise ModelError(f"model.omega[{i}]", f"must be > 0 rad/s, got {w}")
            if not 0.0 <= z < 1.0:
                raise ModelError(f"model.zeta[{i}]", f"must be in [0, 1), got {z}")
        b = _matrix("model.b", self.b, N, m) if N else ()
        names = _names("model.mode_names", self.mode_names, N, "mode") if N else ()
        if len(names) != N:
            raise ModelError("model.mode_names", f"needs one name per mode ({N}), got {len(names)}")
        if k + N == 0:
            raise ModelError("model.rigid_bodies", "the model needs at least one rigid body or one mode")
        for attr, val in (
            ("inputs", inputs),
            ("rigid_bodies", bodies),
            ("b0", b0),
            ("c", c),
            ("omega", omega),
            ("zeta", zeta),
            ("b", b),
            ("mode_names", names),
        ):
            object.__setattr__(self, attr, val)
        self._check_controllable()

    # ------------------------------------------------------------------ sizes
    @property
    def m(self) -> int:
        """Number of inputs."""
        return len(self.inputs)

    @property
    def k(self) -> int:
        """Number of rigid bodies."""
        return len(self.rigid_bodies)

    @property
    def n_modes(self) -> int:
        """Number of vibration modes ``N``."""
        return len(self.omega)

    @property
    def n_states(self) -> int:
        """State dimension ``2 k + 2 N``."""
        return 2 * (self.k + self.n_modes)

    @property
    def B0(self) -> np.ndarray:
        """``b0`` as a ``(k, m)`` array."""
        return np.array(self.b0, dtype=float).reshape(self.k, self.m)

    @property
    def Bm(self) -> np.ndarray:
        """``b`` as an ``(N, m)`` array."""
        return np.array(self.b, dtype=float).reshape(self.n_modes, self.m)

    @property
    def omega_d(self) -> np.ndarray:
        """Damped natural frequencies (rad/s)."""
        w, z = np.asarray(self.omega, float), np.asarray(self.zeta, float)
        return w * np.sqrt(1.0 - z * z)

    def state_names(self) -> list[str]:
        """Names of the state components, in state order."""
        out = []
        for name in self.rigid_bodies:
            out += [name, name + "_dot"]
        for name in self.mode_names:
            out += [name, name + "_dot"]
        return out

    # --------------------------------------------------------------- matrices
    def A(self) -> np.ndarray:
        """State matrix (block diagonal), shape ``(n, n)``."""
        n = self.n_states
        A = np.zeros((n, n))
        for j, cj in enumerate(self.c):
            A[2 * j, 2 * j + 1] = 1.0
            A[2 * j + 1, 2 * j + 1] = cj
        for i, (w, z) in enumerate(zip(self.omega, self.zeta)):
            r = 2 * self.k + 2 * i
            A[r, r + 1] = 1.0
            A[r + 1, r] = -w * w
            A[r + 1, r + 1] = -2.0 * z * w
        return A

    def B(self) -> np.ndarray:
        """Input matrix, shape ``(n, m)``."""
        B = np.zeros((self.n_states, self.m))
        if self.k:
            B[1 : 2 * self.k : 2] = self.B0
        if self.n_modes:
            B[2 * self.k + 1 :: 2] = self.Bm
        return B

    def rest_state(self, positions=None) -> np.ndarray:
        """The equilibrium at rest at ``positions`` (one per rigid body; default 0)."""
        x = np.zeros(self.n_states)
        if positions is not None:
            x[0 : 2 * self.k : 2] = np.asarray(positions, dtype=float)
        return x

    # -------------------------------------------------------- controllability
    def mode_groups(self) -> list[list[int]]:
        """Modes grouped by a shared eigenvalue (repeated ``omega`` and ``zeta``)."""
        lam = [complex(-z * w, w * math.sqrt(1.0 - z * z)) for w, z in zip(self.omega, self.zeta)]
        groups: list[list[int]] = []
        for i, li in enumerate(lam):
            for g in groups:
                lj = lam[g[0]]
                if abs(li - lj) <= REPEATED_FREQUENCY_RTOL * max(abs(li), abs(lj)):
                    g.append(i)
                    break
            else:
                groups.append([i])
        return groups

    def _check_controllable(self) -> None:
        inputs = self.inputs
        B = self.B()
        for i, name in enumerate(inputs):
            if not np.any(B[:, i]):
                raise ModelError(
                    "model.b0/b",
                    f"input {name!r} reaches no rigid body and no mode (all its gains are 0); remove it",
                )
        if self.k:
            B0 = self.B0
            for j in range(self.k):
                if not np.any(B0[j]):
                    raise ModelError(
                        f"model.b0[{j}]",
                        f"rigid body {self.rigid_bodies[j]!r} is reached by no input (its row of b0 is zero): "
                        "uncontrollable; give at least one input a non-zero gain on it",
                    )
            if _rank(B0) < self.k:
                reach = [inputs[i] for i in range(self.m) if np.any(B0[:, i])]
                raise ModelError(
                    "model.b0",
                    f"rigid bodies {list(self.rigid_bodies)} are not controllable: inputs {reach} move them only "
                    f"along {_rank(B0)} independent direction(s) (rank of b0 < k = {self.k}); "
                    "each rigid body needs its own independent row of b0",
                )
        if self.n_modes:
            Bm = self.Bm
            for g in self.mode_groups():
                rows = Bm[g]
                if len(g) == 1 and not np.any(rows):
                    i = g[0]
                    raise ModelError(
                        f"model.b[{i}]",
                        f"mode {self.mode_names[i]!r} ({self.omega[i]} rad/s) is reached by no input "
                        f"(inputs {list(inputs)} all have gain 0 on it): uncontrollable",
                    )
                if _rank(rows) < len(g):
                    reach = [inputs[i] for i in range(self.m) if np.any(rows[:, i])]
                    names = [self.mode_names[i] for i in g]
                    raise ModelError(
                        f"model.omega[{g[-1]}]",
                        f"modes {names} share {self.omega[g[0]]} rad/s (and damping): inputs {reach} reach them "
                        f"along only {_rank(rows)} independent direction(s), fewer than the {len(g)} modes: "
                        "uncontrollable; repeated frequencies need as many independent input-gain rows (b)",
                    )

    def normality(self) -> tuple[str | None, ...]:
        """Per input: None if it alone controls the system (normal, Hermes-LaSalle), else why not."""
        out: list[str | None] = []
        groups = [g for g in self.mode_groups() if len(g) > 1]
        for i, name in enumerate(self.inputs):
            reason = None
            if self.k > 1:
                reason = f"{name} alone cannot steer {self.k} rigid bodies independently"
            elif self.k == 1 and self.B0[0, i] == 0.0:
                reason = f"{name} does not reach rigid body {self.rigid_bodies[0]!r}"
            else:
                zero = [self.mode_names[l] for l in range(self.n_modes) if self.Bm[l, i] == 0.0]
                if zero:
                    reason = f"{name} does not reach mode(s) {zero}"
                elif groups:
                    reason = f"{name} alone cannot control modes sharing one frequency {[self.mode_names[l] for l in groups[0]]}"
            out.append(reason)
        return tuple(out)

    @property
    def is_normal(self) -> bool:
        """Every input alone controls the system (no singular arcs: every input bang-bang)."""
        return all(r is None for r in self.normality())

    # ---------------------------------------------------------- conversions
    @classmethod
    def from_modal(cls, model: ModalModel, input_name: str = "u", rigid_body_name: str = "rigid_body") -> MultiModel:
        """The single-input :class:`ModalModel` as a ``m = k = 1`` model (for cross-checks)."""
        return cls(
            inputs=(input_name,),
            rigid_bodies=(rigid_body_name,),
            b0=((model.b0,),),
            c=(model.c,),
            omega=model.omega,
            zeta=model.zeta,
            b=tuple((v,) for v in model.b),
            mode_names=model.names,
        )

    def submodel(self, inputs: Sequence[int], bodies: Sequence[int], modes: Sequence[int]) -> MultiModel:
        """The model restricted to some inputs, rigid bodies and modes (a decoupled part)."""
        B0, Bm = self.B0, self.Bm
        return MultiModel(
            inputs=tuple(self.inputs[i] for i in inputs),
            rigid_bodies=tuple(self.rigid_bodies[j] for j in bodies),
            b0=tuple(tuple(B0[j, i] for i in inputs) for j in bodies),
            c=tuple(self.c[j] for j in bodies),
            omega=tuple(self.omega[l] for l in modes),
            zeta=tuple(self.zeta[l] for l in modes),
            b=tuple(tuple(Bm[l, i] for i in inputs) for l in modes),
            mode_names=tuple(self.mode_names[l] for l in modes),
        )

    def to_dict(self) -> dict[str, object]:
        """The parameter-file layout (flat row-major matrices)."""
        return {
            "inputs": list(self.inputs),
            "rigid_bodies": list(self.rigid_bodies),
            "b0": [float(v) for row in self.b0 for v in row],
            "c": list(self.c),
            "omega": list(self.omega),
            "zeta": list(self.zeta),
            "b": [float(v) for row in self.b for v in row],
        }
