"""Multi-input models from physical parameters, with the map back to physical coordinates.

* :func:`gantry`: trolley on a bridge, payload on a rope; the trolley drive
  pushes the trolley (x), the bridge drive the bridge with the trolley (y);
  small-angle pendulum per axis.  Two decoupled axes (not normal: each drive
  reaches one axis only).
* :func:`multi_chain`: masses in a line joined by springs (and dampers),
  forces at the ``actuated`` masses; the modes are shared (coupled).
* :func:`multi_two_mass`: two masses and a spring, ``actuated`` masses.

Each returns a :class:`MultiBuiltModel`: physical positions are
``modal_to_physical @ [p_1..p_k, q_1..q_N]`` (velocities likewise).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import eigh

from ..errors import ModelError
from ..model.modal_model import check_positive
from .model import MultiModel


@dataclass(frozen=True)
class MultiBuiltModel:
    """A multi-input model and its physical meaning.

    Attributes
    ----------
    model : MultiModel
    u_max : ndarray
        One bound per input (N).
    coordinates : tuple of str
        Names of the physical coordinates.
    modal_to_physical : ndarray, shape ``(len(coordinates), k + N)``
        ``y = modal_to_physical @ [p_1, ..., p_k, q_1, ..., q_N]``.
    kind : str
    parameters : dict
    notes : dict
    """

    model: MultiModel
    u_max: np.ndarray
    coordinates: tuple[str, ...]
    modal_to_physical: np.ndarray
    kind: str
    parameters: dict
    notes: dict = field(default_factory=dict)

    def physical_positions(self, x: np.ndarray) -> np.ndarray:
        """Physical positions from state(s) ``x`` in the model's state order."""
        x = np.asarray(x, dtype=float)
        k = self.model.k
        coords = np.concatenate([x[..., 0 : 2 * k : 2], x[..., 2 * k :: 2]], axis=-1)
        return coords @ self.modal_to_physical.T

    def to_parameters(self) -> dict:
        """The parameter-file layout: ``{"model": {...}, "u_max": [...]}``."""
        return {"model": self.model.to_dict(), "u_max": [float(v) for v in self.u_max]}


def gantry(
    trolley_mass: float,
    bridge_mass: float,
    payload_mass: float,
    rope_length: float,
    g: float = 9.81,
    trolley_force: float = 1.0,
    bridge_force: float = 1.0,
    zeta: float = 0.0,
) -> MultiBuiltModel:
    """Gantry crane: trolley (x) on a bridge (y), payload on a rope, small swing angles per axis.

    Parameters
    ----------
    trolley_mass, bridge_mass, payload_mass : float
        Masses (kg), ``> 0``.
    rope_length : float
        Rope length (m), ``> 0``.
    g : float
        Gravity (m/s^2).
    trolley_force, bridge_force : float
        Force bound of each drive (N), ``> 0``.
    zeta : float
        Swing damping ratio, in ``[0, 1)``.

    Notes
    -----
    Axis x moves the trolley (``M_x = m_t``), axis y the bridge with the
    trolley (``M_y = m_b + m_t``).  Per axis, as for a crane, with the
    payload's offset ``s = L theta`` from the carriage: the centre of mass
    ``p'' = F / (M + m_p)``, ``s'' + omega^2 s = -F / M`` with
    ``omega^2 = g (M + m_p) / (M L)``.  Positions: carriage
    ``p - m_p / (M + m_p) s``, payload ``p + M / (M + m_p) s``.
    """
    mt = check_positive("trolley_mass", trolley_mass, "kg")
    mb = check_positive("bridge_mass", bridge_mass, "kg")
    mp = check_positive("payload_mass", payload_mass, "kg")
    L = check_positive("rope_length", rope_length, "m")
    gg = check_positive("g", g, "m/s^2")
    fx = check_positive("trolley_force", trolley_force, "N")
    fy = check_positive("bridge_force", bridge_force, "N")
    z = float(zeta)
    if not 0.0 <= z < 1.0:
        raise ModelError("zeta", f"must be in [0, 1), got {z}")
    Mx, My = mt, mt + mb
    wx = math.sqrt(gg * (Mx + mp) / (Mx * L))
    wy = math.sqrt(gg * (My + mp) / (My * L))
    model = MultiModel(
        inputs=("trolley", "bridge"),
        rigid_bodies=("x", "y"),
        b0=((1.0 / (Mx + mp), 0.0), (0.0, 1.0 / (My + mp))),
        c=(0.0, 0.0),
        omega=(wx, wy),
        zeta=(z, z),
        b=((-1.0 / Mx, 0.0), (0.0, -1.0 / My)),
        mode_names=("sway_x", "sway_y"),
    )
    # y = T @ [p_x, p_y, s_x, s_y]
    T = np.array(
        [
            [1.0, 0.0, -mp / (Mx + mp), 0.0],  # trolley x
            [1.0, 0.0, Mx / (Mx + mp), 0.0],  # payload x
            [0.0, 1.0, 0.0, -mp / (My + mp)],  # bridge y
            [0.0, 1.0, 0.0, My / (My + mp)],  # payload y
        ]
    )
    return MultiBuiltModel(
        model=model,
        u_max=np.array([fx, fy]),
        coordinates=("trolley_x", "payload_x", "bridge_y", "payload_y"),
        modal_to_physical=T,
        kind="gantry",
        parameters={
            "trolley_mass": mt,
            "bridge_mass": mb,
            "payload_mass": mp,
            "rope_length": L,
            "g": gg,
            "trolley_force": fx,
            "bridge_force": fy,
            "zeta": z,
        },
    )


def _actuated(actuated: Sequence[int], n: int) -> tuple[int, ...]:
    try:
        idx = tuple(int(a) for a in actuated)
    except (TypeError, ValueError):
        raise ModelError("actuated", f"must be mass indices in [0, {n - 1}], got {actuated!r}") from None
    if not idx:
        raise ModelError("actuated", "needs at least one actuated mass")
    for a in idx:
        if not 0 <= a < n:
            raise ModelError("actuated", f"must be mass indices in [0, {n - 1}], got {a}")
    if len(set(idx)) != len(idx):
        raise ModelError("actuated", f"must not repeat a mass, got {list(idx)}")
    return idx


def multi_chain(
    masses: Sequence[float],
    springs: Sequence[float],
    dampers: Sequence[float] | None = None,
    actuated: Sequence[int] = (0,),
    u_max: Sequence[float] | float = 1.0,
) -> MultiBuiltModel:
    """``n`` masses in a line joined by springs, a force at each ``actuated`` mass (coupled modes).

    Parameters
    ----------
    masses : sequence of float
        Masses (kg), at least 2.
    springs : sequence of float
        Stiffness between neighbours (N/m).
    dampers : sequence of float, optional
        Damping in parallel with each spring (N s/m); modal damping from the
        diagonal of the modal damping matrix.
    actuated : sequence of int
        Indices of the masses with a force (one input each, named ``f<index>``).
    u_max : float or sequence of float
        Force bound per input (N).

    Notes
    -----
    One rigid body (the centre of mass, ``b0 = 1 / sum m``); mode ``l`` is
    scaled so that ``q_l`` is its largest spring deflection (m), and input
    ``i`` at mass ``a_i`` drives it with ``alpha_l phi_l[a_i]``.  A force at a
    node of a mode does not reach it (a zero gain: not normal).
    """
    m = np.array([check_positive(f"masses[{i}]", v, "kg") for i, v in enumerate(masses)])
    n = m.size
    if n < 2:
        raise ModelError("masses", "needs at least 2 masses (one spring)")
    k = np.array([check_positive(f"springs[{i}]", v, "N/m") for i, v in enumerate(springs)])
    if k.size != n - 1:
        raise ModelError("springs", f"needs {n - 1} values (one between each pair of masses), got {k.size}")
    d = np.zeros(n - 1) if dampers is None else np.array([float(v) for v in dampers])
    if d.size != n - 1 or np.any(~np.isfinite(d)) or np.any(d < 0.0):
        raise ModelError("dampers", f"needs {n - 1} finite values >= 0")
    act = _actuated(actuated, n)
    bounds = np.atleast_1d(np.asarray(u_max, dtype=float))
    if bounds.size == 1:
        bounds = np.full(len(act), float(bounds[0]))
    if bounds.size != len(act):
        raise ModelError("u_max", f"needs one bound per actuated mass ({len(act)}), got {bounds.size}")
    for i, v in enumerate(bounds):
        check_positive(f"u_max[{i}]", v, "N")
    K = np.zeros((n, n))
    D = np.zeros((n, n))
    for i in range(n - 1):
        for mat, val in ((K, k[i]), (D, d[i])):
            mat[i, i] += val
            mat[i + 1, i + 1] += val
            mat[i, i + 1] -= val
            mat[i + 1, i] -= val
    lam, Phi = eigh(K, np.diag(m))
    order = np.argsort(lam)
    lam, Phi = np.maximum(lam[order], 0.0), Phi[:, order]
    Dm = Phi.T @ D @ Phi
    omegas, zetas, rows, columns = [], [], [], [np.ones(n)]
    for l in range(1, n):
        phi = Phi[:, l]
        defl = phi[:-1] - phi[1:]
        alpha = defl[int(np.argmax(np.abs(defl)))]
        w = math.sqrt(lam[l])
        omegas.append(w)
        zetas.append(Dm[l, l] / (2.0 * w))
        gains = alpha * phi[list(act)]
        # a force at a node of the mode: exactly zero, not rounding noise
        gains = np.where(np.abs(gains) <= 1e-12 * float(np.max(np.abs(alpha * phi))), 0.0, gains)
        rows.append(tuple(float(v) for v in gains))
        columns.append(phi / alpha)
    if max(zetas, default=0.0) >= 1.0:
        raise ModelError("dampers", "give a modal damping ratio >= 1 (overdamped mode); reduce them")
    model = MultiModel(
        inputs=tuple(f"f{a}" for a in act),
        rigid_bodies=("x",),
        b0=(tuple(1.0 / float(m.sum()) for _ in act),),
        c=(0.0,),
        omega=tuple(omegas),
        zeta=tuple(zetas),
        b=tuple(rows),
    )
    return MultiBuiltModel(
        model=model,
        u_max=bounds,
        coordinates=tuple(f"x{i + 1}" for i in range(n)),
        modal_to_physical=np.column_stack(columns),
        kind="chain",
        parameters={"masses": m.tolist(), "springs": k.tolist(), "dampers": d.tolist(), "actuated": list(act)},
    )


def multi_two_mass(
    m1: float, m2: float, k: float, d: float = 0.0, actuated: Sequence[int] = (0, 1), u_max=1.0
) -> MultiBuiltModel:
    """Two masses, spring ``k`` (N/m), damper ``d`` (N s/m), forces at the ``actuated`` masses."""
    built = multi_chain([m1, m2], [k], [d], actuated, u_max)
    return MultiBuiltModel(
        model=built.model,
        u_max=built.u_max,
        coordinates=built.coordinates,
        modal_to_physical=built.modal_to_physical,
        kind="two_mass",
        parameters={"m1": float(m1), "m2": float(m2), "k": float(k), "d": float(d), "actuated": list(actuated)},
    )


MULTI_BUILDERS = {"gantry": gantry, "chain": multi_chain, "two_mass": multi_two_mass}
