"""Modal models from the physical parameters users think in.

Each builder returns a :class:`BuiltModel`: the :class:`ModalModel` plus the
map from modal coordinates back to physical ones.

* :func:`two_mass`: two masses, a spring and a damper, force on mass 1
  (the Wie-Bernstein benchmark with ``m1 = m2 = k = 1``; seed eqs. 2.4-2.5).
* :func:`crane`: overhead crane (cart, payload on a cable; small angles).
* :func:`chain`: ``n`` masses in a line joined by springs and dampers, force on
  one of them, by modal decomposition.

Modal coordinates are scaled so that each ``q_i`` is the largest spring
deflection of its mode (m): deflection limits then read directly.  For the
crane, ``q_1`` is the payload's horizontal offset from the cart (m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import eigh

from ..errors import ModelError
from .modal_model import ModalModel, check_positive


@dataclass(frozen=True)
class BuiltModel:
    """A modal model and its physical meaning.

    Attributes
    ----------
    model : ModalModel
    coordinates : tuple of str
        Names of the physical coordinates.
    modal_to_physical : ndarray, shape ``(len(coordinates), N + 1)``
        ``y = modal_to_physical @ [p, q_1, ..., q_N]`` (velocities likewise).
    kind : str
        Builder name.
    parameters : dict
        The physical parameters it was built from.
    notes : dict
        Extra facts (e.g. how far damping is from proportional).
    """

    model: ModalModel
    coordinates: tuple[str, ...]
    modal_to_physical: np.ndarray
    kind: str
    parameters: dict
    notes: dict = field(default_factory=dict)

    def physical_positions(self, x: np.ndarray) -> np.ndarray:
        """Physical positions from modal state(s) ``x`` (``[..., p, v, q1, q1', ...]``)."""
        x = np.asarray(x, dtype=float)
        coords = np.concatenate([x[..., :1], x[..., 2::2]], axis=-1)
        return coords @ self.modal_to_physical.T


def _nonneg(name: str, value: float) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ModelError(name, f"must be a finite number >= 0, got {value!r}") from None
    if not math.isfinite(x) or x < 0.0:
        raise ModelError(name, f"must be finite and >= 0, got {x}")
    return x


def chain(masses, springs, dampers=None, force_on: int = 0) -> BuiltModel:
    """``n`` masses joined in a line by springs (and dampers), force on one mass.

    Parameters
    ----------
    masses : sequence of float
        Masses (kg), each ``> 0``; at least 2.
    springs : sequence of float
        Stiffness between mass ``i`` and ``i+1`` (N/m), each ``> 0``.
    dampers : sequence of float, optional
        Damping in parallel with each spring (N s/m), each ``>= 0``.  Modal
        damping uses the diagonal of the modal damping matrix; its largest
        relative off-diagonal term is reported in ``notes``.
    force_on : int
        Index of the mass the actuator pushes.

    Returns
    -------
    BuiltModel
    """
    m = np.array([check_positive(f"masses[{i}]", v, "kg") for i, v in enumerate(masses)])
    n = m.size
    if n < 2:
        raise ModelError("masses", "needs at least 2 masses (one spring)")
    k = np.array([check_positive(f"springs[{i}]", v, "N/m") for i, v in enumerate(springs)])
    if k.size != n - 1:
        raise ModelError("springs", f"needs {n - 1} values (one between each pair of masses), got {k.size}")
    d = np.zeros(n - 1) if dampers is None else np.array([_nonneg(f"dampers[{i}]", v) for i, v in enumerate(dampers)])
    if d.size != n - 1:
        raise ModelError("dampers", f"needs {n - 1} values, got {d.size}")
    if not 0 <= int(force_on) < n:
        raise ModelError("force_on", f"must be a mass index in [0, {n - 1}], got {force_on}")
    K = np.zeros((n, n))
    D = np.zeros((n, n))
    for i in range(n - 1):
        for mat, val in ((K, k[i]), (D, d[i])):
            mat[i, i] += val
            mat[i + 1, i + 1] += val
            mat[i, i + 1] -= val
            mat[i + 1, i] -= val
    F = np.zeros(n)
    F[int(force_on)] = 1.0
    lam, Phi = eigh(K, np.diag(m))  # mass-normalised: Phi^T M Phi = I
    lam = np.maximum(lam, 0.0)
    order = np.argsort(lam)
    lam, Phi = lam[order], Phi[:, order]
    m_tot = float(m.sum())
    omegas, zetas, gains = [], [], []
    columns = [np.ones(n)]
    Dm = Phi.T @ D @ Phi
    for i in range(1, n):
        phi = Phi[:, i]
        defl = phi[:-1] - phi[1:]
        j = int(np.argmax(np.abs(defl)))
        alpha = defl[j]  # q_i = alpha * eta_i: the largest spring deflection, positive
        w = math.sqrt(lam[i])
        omegas.append(w)
        zetas.append(Dm[i, i] / (2.0 * w))
        gains.append(alpha * float(phi @ F))
        columns.append(phi / alpha)
    off = Dm[1:, 1:] - np.diag(np.diag(Dm[1:, 1:]))
    diag = np.abs(np.diag(Dm[1:, 1:]))
    coupling = float(np.max(np.abs(off)) / np.max(diag)) if diag.size > 1 and np.max(diag) > 0 else 0.0
    zmax = max(zetas) if zetas else 0.0
    if zmax >= 1.0:
        raise ModelError("dampers", f"give modal damping ratio {zmax:.3g} >= 1 (overdamped mode); reduce them")
    model = ModalModel(b0=1.0 / m_tot, c=0.0, omega=tuple(omegas), zeta=tuple(zetas), b=tuple(gains))
    return BuiltModel(
        model=model,
        coordinates=tuple(f"x{i + 1}" for i in range(n)),
        modal_to_physical=np.column_stack(columns),
        kind="chain",
        parameters={"masses": m.tolist(), "springs": k.tolist(), "dampers": d.tolist(), "force_on": int(force_on)},
        notes={"damping_coupling": coupling},
    )


def two_mass(m1: float, m2: float, k: float, d: float = 0.0) -> BuiltModel:
    """Two masses, spring ``k`` (N/m) and damper ``d`` (N s/m) between them, force on mass 1.

    ``omega = sqrt(k (1/m1 + 1/m2))``, ``b0 = 1/(m1 + m2)``, and the mode
    coordinate is the spring deflection ``x1 - x2`` with gain ``1/m1``.
    """
    built = chain([m1, m2], [k], [d], force_on=0)
    return BuiltModel(
        built.model,
        built.coordinates,
        built.modal_to_physical,
        "two_mass",
        {"m1": float(m1), "m2": float(m2), "k": float(k), "d": float(d)},
        built.notes,
    )


def crane(
    cart_mass: float | None,
    payload_mass: float | None,
    cable_length: float,
    g: float = 9.81,
    zeta: float = 0.0,
    input: str = "force",
) -> BuiltModel:
    """Overhead crane: force on the cart, payload on a cable (small swing angles).

    Parameters
    ----------
    cart_mass, payload_mass : float
        Masses (kg).
    cable_length : float
        Cable length (m).
    g : float
        Gravity (m/s^2).
    zeta : float
        Damping ratio of the swing (air drag), in ``[0, 1)``.
    input : str
        ``"force"`` (N on the cart) or ``"acceleration"`` (the cart's
        acceleration, m/s^2, imposed by a velocity- or position-controlled
        drive: see :func:`crane_acceleration`; the masses are then not used).

    Notes
    -----
    With ``s = L theta`` the payload's offset from the cart, the linearised
    equations give ``omega^2 = g (M + m) / (M L)``, ``s'' + omega^2 s = -f / M``,
    and the centre of mass ``p`` moves as ``p'' = f / (M + m)``.
    """
    kind = _input_kind(input)
    if kind == "acceleration":
        return crane_acceleration(cable_length, g, zeta)
    M = check_positive("cart_mass", cart_mass, "kg")
    mp = check_positive("payload_mass", payload_mass, "kg")
    L = check_positive("cable_length", cable_length, "m")
    gg = check_positive("g", g, "m/s^2")
    w = math.sqrt(gg * (M + mp) / (M * L))
    model = ModalModel(b0=1.0 / (M + mp), c=0.0, omega=(w,), zeta=(float(zeta),), b=(-1.0 / M,), names=("swing",))
    mtot = M + mp
    return BuiltModel(
        model=model,
        coordinates=("cart", "payload"),
        modal_to_physical=np.array([[1.0, -mp / mtot], [1.0, M / mtot]]),
        kind="crane",
        parameters={"cart_mass": M, "payload_mass": mp, "cable_length": L, "g": gg, "zeta": float(zeta)},
    )


#: The forms of a builder's input: the actuator's force, or the acceleration a servo imposes on the driven body.
INPUT_KINDS = ("force", "acceleration")


def _input_kind(value: str) -> str:
    if value not in INPUT_KINDS:
        raise ModelError("input", f"must be one of {list(INPUT_KINDS)}, got {value!r}")
    return value


def crane_acceleration(cable_length: float, g: float = 9.81, zeta: float = 0.0) -> BuiltModel:
    """Overhead crane whose cart's acceleration is the input (velocity- or position-controlled drive).

    Parameters
    ----------
    cable_length : float
        Cable length ``L`` (m).
    g : float
        Gravity (m/s^2).
    zeta : float
        Damping ratio of the swing, in ``[0, 1)``.

    Notes
    -----
    With the cart's acceleration ``a`` prescribed, the pendulum's linearised
    equation is ``theta'' = -(g / L) theta - a / L`` whatever the masses (the
    drive supplies whatever force that takes).  The rigid body is the cart
    itself (``p``: cart position, ``b0 = 1``, ``c = 0``: ``p'' = a``) and the
    mode coordinate is the payload's horizontal offset from the cart
    ``s = L theta`` (m): ``s'' = -(g / L) s - a``, so ``omega = sqrt(g / L)``
    and ``b = -1`` (``-1 / L`` in the angle).  At rest ``s = 0`` and the
    payload is above the goal.  ``u_max`` is then the cart's acceleration
    bound (m/s^2).
    """
    L = check_positive("cable_length", cable_length, "m")
    gg = check_positive("g", g, "m/s^2")
    w = math.sqrt(gg / L)
    model = ModalModel(b0=1.0, c=0.0, omega=(w,), zeta=(float(zeta),), b=(-1.0,), names=("swing",))
    return BuiltModel(
        model=model,
        coordinates=("cart", "payload"),
        modal_to_physical=np.array([[1.0, 0.0], [1.0, 1.0]]),
        kind="crane",
        parameters={"cable_length": L, "g": gg, "zeta": float(zeta), "input": "acceleration"},
        notes={"input": "cart acceleration (m/s^2)", "mode": "payload offset from the cart (m)"},
    )


def two_mass_acceleration(m2: float, k: float, d: float = 0.0) -> BuiltModel:
    """Two masses and a spring, mass 1's acceleration imposed (a servo-driven base), mass 2 carried.

    ``s = x1 - x2`` (spring deflection, m): ``m2 x2'' = k s + d s'``, so
    ``s'' = a - (k / m2) s - (d / m2) s'``: ``omega = sqrt(k / m2)``,
    ``zeta = d / (2 sqrt(k m2))``, ``b = 1``; the rigid body is mass 1
    (``b0 = 1``).  Mass 1's own mass does not enter.
    """
    m = check_positive("m2", m2, "kg")
    kk = check_positive("k", k, "N/m")
    dd = _nonneg("d", d)
    w = math.sqrt(kk / m)
    z = dd / (2.0 * math.sqrt(kk * m))
    if z >= 1.0:
        raise ModelError("d", f"gives damping ratio {z:.3g} >= 1 (overdamped); reduce it")
    model = ModalModel(b0=1.0, c=0.0, omega=(w,), zeta=(z,), b=(1.0,))
    return BuiltModel(
        model=model,
        coordinates=("x1", "x2"),
        modal_to_physical=np.array([[1.0, 0.0], [1.0, -1.0]]),
        kind="two_mass",
        parameters={"m2": m, "k": kk, "d": dd, "input": "acceleration"},
        notes={"input": "acceleration of mass 1 (m/s^2)", "mode": "spring deflection x1 - x2 (m)"},
    )


BUILDERS = {"two_mass": two_mass, "crane": crane, "chain": chain}
