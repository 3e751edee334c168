"""Numerically solved input shapers: the EI family, SNA and UM-ZVD (seed section 2.1.3).

Holds the residual-vibration function :func:`impulse_vibration` and the unit
designs (``omega = 1 rad/s``, times in s) whose defining constraints on it have
no closed form for a damped mode: extra-insensitive shapers with one, two or
three humps (Singhose, Seering & Singer 1994; Singhose et al. 1997) and the
negative-amplitude shapers SNA ``[1, -P, P]`` and UM-ZVD ``[1, -1, 1, -1, 1]``.
Each starts from its undamped closed form and is continued in ``zeta`` with
``fsolve``, then Newton-polished and checked against its constraints
(:data:`CONSTRAINT_TOL`).  :func:`~flexmotion_ros.core.shapers.design` turns
these unit designs into :class:`~flexmotion_ros.core.shapers.Shaper` objects.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import fsolve

from ..errors import SolverError
from ..tolerances import CONSTRAINT_TOL

#: Largest damping step of the continuation from the undamped closed forms.
ZETA_STEP = 0.02


def impulse_vibration(times, amplitudes, omega, zeta) -> np.ndarray:
    """Residual vibration of impulses for modes ``(omega, zeta)`` (fraction; broadcast).

    ``e^{-zeta omega t_n} |sum A_i e^{zeta omega t_i} e^{i omega_d t_i}|``, evaluated as
    ``|sum A_i e^{omega (zeta (t_i - t_n) + i sqrt(1 - zeta^2) t_i)}|`` (no overflow).
    """
    t = np.asarray(times, dtype=float)
    a = np.asarray(amplitudes, dtype=float)
    w = np.asarray(omega, dtype=float)[..., None]
    z = np.asarray(zeta, dtype=float)[..., None]
    total = 0.0
    for k in range(0, t.size, IMPULSE_CHUNK):  # a million impulses x 8 modes: chunks bound the memory
        tk = t[k : k + IMPULSE_CHUNK]
        expo = w * (z * (tk - t[-1]) + 1j * np.sqrt(1.0 - z * z) * tk)
        total = total + np.sum(a[k : k + IMPULSE_CHUNK] * np.exp(expo), axis=-1)
    return np.abs(total)


#: Impulses per chunk of :func:`impulse_vibration` (bounds its temporaries to a few MB per mode).
IMPULSE_CHUNK = 65536


# ---------------------------------------------------- undamped closed forms
def _ei_undamped(V: float, humps: int) -> tuple[np.ndarray, np.ndarray]:
    """Closed forms for zeta = 0 (Singhose, Seering & Singer 1994; Singhose et al. 1997)."""
    if humps == 1:
        a = [(1 + V) / 4, (1 - V) / 2, (1 + V) / 4]
    elif humps == 2:
        X = (V * V * (math.sqrt(1.0 - V * V) + 1.0)) ** (1.0 / 3.0)
        a1 = (3 * X * X + 2 * X + 3 * V * V) / (16 * X)
        a = [a1, 0.5 - a1, 0.5 - a1, a1]
    else:
        a1 = (1 + 3 * V + 2 * math.sqrt(2 * V * (V + 1))) / 16
        a2 = (1 - V) / 4
        a = [a1, a2, 1 - 2 * (a1 + a2), a2, a1]
    return math.pi * np.arange(len(a)), np.array(a)


def _sna_undamped(P: float) -> tuple[np.ndarray, np.ndarray]:
    # 1 - P e^{i th2} + P e^{i th3} = 0  =>  th2,3 = pi/2 -+ arcsin(1/(2P))
    d = math.asin(1.0 / (2.0 * P))
    return np.array([0.0, 0.5 * math.pi - d, 0.5 * math.pi + d]), np.array([1.0, -P, P])


def _um_zvd_undamped() -> tuple[np.ndarray, np.ndarray]:
    # time-symmetric: W = e^{i a}(2 cos a - 2 cos b + 1); W = 0 and W' = 0 (double zero)
    def f(x):
        a, b = x
        return [2 * math.cos(a) - 2 * math.cos(b) + 1, -a * math.sin(a) + b * math.sin(b)]

    a, b = fsolve(f, [2.3, 1.7], xtol=1e-13)
    return np.array([0.0, a - b, a, a + b, 2 * a]), np.array([1.0, -1.0, 1.0, -1.0, 1.0])


# ------------------------------------------------- constraint-based solutions
def _W(t, a, r, zeta, deriv: int = 0):
    """``sum a_i (nu (t_i - t_n))^deriv e^{r nu (t_i - t_n)}``, ``nu = zeta + i s``: V = |W(r)|, W' = dW/dr."""
    nu = zeta + 1j * math.sqrt(1.0 - zeta * zeta)
    d = t - t[-1]
    with np.errstate(over="ignore", invalid="ignore"):  # far trial ratios during the solve
        return np.sum(a * (nu * d) ** deriv * np.exp(r * nu * d))


class _Design:
    """Unknowns and equations of a numerically solved shaper at one damping ratio.

    ``x = [free amplitudes, t_2..t_n, free hump ratios, free zero ratios]``.
    """

    def __init__(
        self,
        n: int,
        fixed_amps,
        hump_at_1: bool,
        zero_at_1: bool,
        deriv_at_1: bool,
        n_humps: int,
        n_zeros: int,
        tol: float,
    ) -> None:
        self.n, self.fixed_amps, self.tol = n, fixed_amps, tol
        self.hump_at_1, self.zero_at_1, self.deriv_at_1 = hump_at_1, zero_at_1, deriv_at_1
        self.nh, self.nz = n_humps, n_zeros

    def unpack(self, x):
        n = self.n
        if self.fixed_amps is None:
            a, x = x[:n], x[n:]
        else:
            a = np.asarray(self.fixed_amps, dtype=float)
        t = np.concatenate([[0.0], x[: n - 1]])
        return a, t, x[n - 1 : n - 1 + self.nh], x[n - 1 + self.nh :]

    def pack(self, a, t, rh, rz):
        parts = [] if self.fixed_amps is not None else [a]
        return np.concatenate(parts + [t[1:], rh, rz])

    def equations(self, x, zeta):
        a, t, rh, rz = self.unpack(x)
        eq = []
        if self.fixed_amps is None:
            eq.append(a.sum() - 1.0)
        if self.zero_at_1:
            W = _W(t, a, 1.0, zeta)
            eq += [W.real, W.imag]
        if self.deriv_at_1:
            W1 = _W(t, a, 1.0, zeta, 1)
            eq += [W1.real, W1.imag]
        humps = ([1.0] if self.hump_at_1 else []) + list(rh)
        for r in humps:
            W, W1 = _W(t, a, r, zeta), _W(t, a, r, zeta, 1)
            eq += [abs(W) ** 2 - self.tol**2, (np.conj(W) * W1).real]
        for r in rz:
            W = _W(t, a, r, zeta)
            eq += [W.real, W.imag]
        return np.array(eq, dtype=float)


def _extrema(t, a, zeta, count_min: int, count_max: int):
    """Local minima/maxima of V(r) nearest r = 1 on each side (initial guesses of zeros/humps)."""
    r = np.linspace(0.02, 1.98, 19601)
    V = impulse_vibration(t, a, r, zeta)
    inner = np.arange(1, r.size - 1)
    mins = r[inner[(V[inner] <= V[inner - 1]) & (V[inner] < V[inner + 1])]]
    maxs = r[inner[(V[inner] >= V[inner - 1]) & (V[inner] > V[inner + 1])]]
    maxs = maxs[np.abs(maxs - 1.0) > 1e-3]
    mins = mins[np.abs(mins - 1.0) > 1e-3]

    def nearest(v, k):
        lo = np.sort(v[v < 1.0])[::-1][:k]
        hi = np.sort(v[v > 1.0])[:k]
        if lo.size < k or hi.size < k:
            raise SolverError("shaper design: undamped vibration curve lacks the expected zeros/humps")
        return np.sort(np.concatenate([lo, hi]))

    return nearest(mins, count_min // 2), nearest(maxs, count_max // 2) if count_max else np.empty(0)


def _solve_continuation(design: _Design, t0, a0, rh0, rz0, zeta: float, name: str):
    """Solve ``design`` at ``zeta`` by continuation from its undamped solution ``(t0, a0, rh0, rz0)``."""
    x = design.pack(a0, t0, rh0, rz0)
    steps = max(1, math.ceil(zeta / ZETA_STEP)) if zeta > 0.0 else 0
    for z in np.linspace(0.0, zeta, steps + 1)[1:] if steps else []:
        x_new, info, ier, _ = fsolve(design.equations, x, args=(z,), full_output=True, xtol=1e-14)
        if ier != 1 and np.max(np.abs(info["fvec"])) > CONSTRAINT_TOL:
            raise SolverError(
                f"shaper {name}: constraints could not be solved at zeta = {z:.3g} (the multi-hump EI "
                "designs exist for light damping only; use zvd or zvdd for heavily damped modes)"
            )
        x = x_new
    # Newton polish to machine precision (finite-difference Jacobian is enough: square, smooth)
    for _ in range(3):
        F = design.equations(x, zeta)
        if np.max(np.abs(F)) <= 1e-15:
            break
        h = 1e-7
        J = np.column_stack(
            [(design.equations(x + h * e, zeta) - design.equations(x - h * e, zeta)) / (2 * h) for e in np.eye(x.size)]
        )
        x = x - np.linalg.lstsq(J, F, rcond=None)[0]
    F = design.equations(x, zeta)
    a, t, rh, rz = design.unpack(x)
    if not np.max(np.abs(F)) <= CONSTRAINT_TOL or np.any(np.diff(t) <= 0.0):
        raise SolverError(
            f"shaper {name}: numerical design failed at zeta = {zeta:.3g} (residual {np.max(np.abs(F)):.1e})"
        )
    return a, t, rh, rz


def ei_unit(zeta: float, V: float, humps: int) -> tuple[np.ndarray, np.ndarray]:
    """Extra-insensitive unit shaper (``omega = 1 rad/s``) with ``humps`` humps of height ``V``.

    Parameters
    ----------
    zeta : float
        Damping ratio, ``0 <= zeta < 1``.
    V : float
        Vibration tolerance (fraction).
    humps : {1, 2, 3}
        EI, two-hump EI or three-hump EI.

    Returns
    -------
    times, amplitudes : ndarray
        Impulse times (s) and positive amplitudes summing to 1; the closed
        form if ``zeta == 0``.

    Raises
    ------
    SolverError
        If the constraints cannot be solved or the solution is not a valid
        EI shaper (``V > tol`` between the outer zeros, or an amplitude <= 0).
    """
    t0, a0 = _ei_undamped(V, humps)
    if zeta == 0.0:
        return t0, a0
    n = humps + 2
    n_zeros = {1: 2, 2: 2, 3: 4}[humps]
    n_humps = {1: 0, 2: 2, 3: 2}[humps]
    rz0, rh0 = _extrema(t0, a0, 0.0, n_zeros, n_humps)
    design = _Design(
        n, None, hump_at_1=humps != 2, zero_at_1=humps == 2, deriv_at_1=False, n_humps=n_humps, n_zeros=n_zeros, tol=V
    )
    a, t, _, rz = _solve_continuation(design, t0, a0, rh0, rz0, zeta, f"ei{humps}")
    # the design is what it claims only if V <= tol between the outer zeros
    r = np.linspace(rz[0], rz[-1], 4001)
    if np.max(impulse_vibration(t, a, r, zeta)) > V * (1.0 + 1e-6) or np.any(a <= 0.0):
        raise SolverError(f"shaper ei{humps}: no valid design at zeta = {zeta:.3g}")
    return t, a


def negative_unit(zeta: float, P: float | None) -> tuple[np.ndarray, np.ndarray]:
    """SNA ``[1, -P, P]`` (``P = None``: UM-ZVD); exact at zeta = 0 except UM-ZVD.

    Parameters
    ----------
    zeta : float
        Damping ratio, ``0 <= zeta < 1``.
    P : float or None
        Negative amplitude (``0.5 < P <= 2``; ``P = 1`` is UM-ZV), or None
        for UM-ZVD ``[1, -1, 1, -1, 1]``.

    Returns
    -------
    times, amplitudes : ndarray
        Impulse times (s) for ``omega = 1 rad/s`` and the amplitudes.

    Raises
    ------
    SolverError
        If the constraints cannot be solved at ``zeta``.
    """
    if P is None:
        t0, a0 = _um_zvd_undamped()
        design = _Design(5, a0, False, True, True, 0, 0, 0.0)
    else:
        t0, a0 = _sna_undamped(P)
        if zeta == 0.0:
            return t0, a0
        design = _Design(3, a0, False, True, False, 0, 0, 0.0)
    a, t, _, _ = _solve_continuation(design, t0, a0, np.empty(0), np.empty(0), zeta, "negative")
    return t, a
