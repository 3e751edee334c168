"""Input shapers: impulse sequences that cancel residual vibration (seed section 2.1.3).

A shaper is a sequence of impulses ``A_i`` at times ``t_i`` (``t_1 = 0``,
``sum A_i = 1``).  Convolved with any command, it leaves the residual
vibration of a mode ``(omega, zeta)`` multiplied by (Singer & Seering 1990;
Singhose, Seering & Singer 1994)::

    V(omega, zeta) = e^{-zeta omega t_n} | sum_i A_i e^{zeta omega t_i} e^{i omega_d t_i} |

(the vibration relative to one unit impulse at ``t_n``).  ``V`` depends on
``omega t`` only, so every shaper is designed for ``omega = 1 rad/s`` and its
times divided by the design frequency.  ``K = exp(-zeta pi / sqrt(1 - zeta^2))``,
``Td = 2 pi / omega_d``.

Families (``exact``: closed form; otherwise the defining constraints are
solved numerically, by continuation in ``zeta`` from the undamped closed form,
and the result is checked against those constraints before it is returned;
those solvers, and :func:`impulse_vibration`, live in
:mod:`~flexmotion_ros.core.numerical_shapers`):

=========  =======================================================  ==============
name       definition                                               how
=========  =======================================================  ==============
zv         ``[1, K]/(1+K)`` at ``0, Td/2``                          exact
zvd        ``[1, 2K, K^2]/(1+K)^2`` at ``0, Td/2, Td`` (dV/dw = 0)  exact
zvdd       ``[1, 3K, 3K^2, K^3]/(1+K)^3`` (d2V/dw2 = 0 too)         exact
mzv        3 impulses at ``0, 3Td/8, 3Td/4`` (zero vibration)       exact
ei         ``V = tol`` and ``dV/dw = 0`` at ``omega``, zeros on     exact if zeta=0
           both sides (Singhose et al. 1994)
ei2        zero at ``omega``, two humps of height ``tol``           exact if zeta=0
ei3        three humps of height ``tol`` (middle one at ``omega``)  exact if zeta=0
sna        ``[1, -P, P]``, P specified (Singhose et al. 1997/2004)  exact if zeta=0
um_zv      ``[1, -1, 1]`` (unity magnitude, = sna with P = 1)       exact if zeta=0
um_zvd     ``[1, -1, 1, -1, 1]`` with dV/dw = 0                     numerical
=========  =======================================================  ==============

Several modes: :func:`design` convolves one shaper per mode, or (``zv``,
``zvd``, ``zvdd``) designs one positive shaper for all modes at once
(:func:`multi_mode_direct`: a linear program on a time grid, shortest to the
grid step), which is usually shorter than the convolution.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import InputError, SolverError
from ..linear_program import LpStatus, solve_lp
from .numerical_shapers import ei_unit, negative_unit
from .shaper import Shaper


# --------------------------------------------------------------- unit designs
def _K(zeta: float) -> float:
    return math.exp(-zeta * math.pi / math.sqrt(1.0 - zeta * zeta))


def _td(zeta: float) -> float:
    """Damped period (s) for omega = 1 rad/s."""
    return 2.0 * math.pi / math.sqrt(1.0 - zeta * zeta)


def _zv_n(zeta: float, derivatives: int) -> tuple[np.ndarray, np.ndarray]:
    """ZV with ``derivatives`` zero frequency derivatives: ``[1, K]`` convolved ``derivatives+1`` times."""
    K = _K(zeta)
    n = derivatives + 1
    a = np.array([math.comb(n, k) * K**k for k in range(n + 1)])
    return 0.5 * _td(zeta) * np.arange(n + 1), a / a.sum()


def _mzv(zeta: float) -> tuple[np.ndarray, np.ndarray]:
    # undamped: a1 + a2 e^{i 3pi/4} + a1 e^{i 3pi/2} = 0 with a1 = 1 - 1/sqrt2, a2 = sqrt2 - 1;
    # damping: weight impulse i by K'^i, K' = e^{-sigma 3Td/8}, which keeps the sum zero exactly.
    s = math.sqrt(1.0 - zeta * zeta)
    Kp = math.exp(-0.75 * zeta * math.pi / s)
    a1 = 1.0 - 1.0 / math.sqrt(2.0)
    a = np.array([a1, (math.sqrt(2.0) - 1.0) * Kp, a1 * Kp * Kp])
    return _td(zeta) * np.array([0.0, 0.375, 0.75]), a / a.sum()


@dataclass(frozen=True, kw_only=True)
class ShaperKind:
    """One row of the shaper table: a name, what it is, and its unit-frequency impulse sequence.

    Attributes
    ----------
    name : str
        The ``method`` / ``flexmotion shaper`` name.
    description : str
        One line for ``--help`` and parameter descriptors.
    unit : callable
        ``unit(zeta, tolerance, negative_amplitude) -> (times, amplitudes)`` at
        ``omega = 1`` rad/s (times in s; the caller scales them by ``1 / omega``).
    exact : callable
        ``exact(zeta) -> bool``: whether the sequence is a closed form (True) or
        a numerically solved one (False).
    """

    name: str
    description: str
    unit: Callable[[float, float, float], tuple[np.ndarray, np.ndarray]]
    exact: Callable[[float], bool]


def _closed(zeta: float) -> bool:
    return True


def _closed_if_undamped(zeta: float) -> bool:
    return zeta == 0.0


def _solved(zeta: float) -> bool:
    return False


#: Every shaper, one row each (like Klipper's ``INPUT_SHAPERS``), in help order.
SHAPER_TABLE: tuple[ShaperKind, ...] = (
    ShaperKind(
        name="zv", description="zero vibration (2 impulses, Td/2)", unit=lambda z, v, p: _zv_n(z, 0), exact=_closed
    ),
    ShaperKind(
        name="zvd",
        description="zero vibration and derivative (3 impulses, Td)",
        unit=lambda z, v, p: _zv_n(z, 1),
        exact=_closed,
    ),
    ShaperKind(
        name="zvdd",
        description="zero vibration, two derivatives (4 impulses, 1.5 Td)",
        unit=lambda z, v, p: _zv_n(z, 2),
        exact=_closed,
    ),
    ShaperKind(
        name="mzv",
        description="modified ZV: 3 positive impulses over 0.75 Td",
        unit=lambda z, v, p: _mzv(z),
        exact=_closed,
    ),
    ShaperKind(
        name="ei",
        description="extra-insensitive, one hump of height tolerance",
        unit=lambda z, v, p: ei_unit(z, v, 1),
        exact=_closed_if_undamped,
    ),
    ShaperKind(
        name="ei2",
        description="two-hump extra-insensitive",
        unit=lambda z, v, p: ei_unit(z, v, 2),
        exact=_closed_if_undamped,
    ),
    ShaperKind(
        name="ei3",
        description="three-hump extra-insensitive",
        unit=lambda z, v, p: ei_unit(z, v, 3),
        exact=_closed_if_undamped,
    ),
    ShaperKind(
        name="sna",
        description="specified negative amplitude [1, -P, P] (P = shaper.negative_amplitude)",
        unit=lambda z, v, p: negative_unit(z, p),
        exact=_closed_if_undamped,
    ),
    ShaperKind(
        name="um_zv",
        description="unity-magnitude ZV [1, -1, 1]",
        unit=lambda z, v, p: negative_unit(z, 1.0),
        exact=_closed_if_undamped,
    ),
    ShaperKind(
        name="um_zvd",
        description="unity-magnitude ZVD [1, -1, 1, -1, 1]",
        unit=lambda z, v, p: negative_unit(z, None),
        exact=_solved,
    ),
)

#: Shaper names and one-line descriptions (from :data:`SHAPER_TABLE`).
SHAPERS: dict[str, str] = {kind.name: kind.description for kind in SHAPER_TABLE}
_BY_NAME = {kind.name: kind for kind in SHAPER_TABLE}


def _unit(name: str, zeta: float, tolerance: float, negative_amplitude: float) -> tuple[np.ndarray, np.ndarray, bool]:
    kind = _BY_NAME.get(name)
    if kind is None:
        raise InputError("shaper", f"must be one of {sorted(SHAPERS)}, got {name!r}")
    return (*kind.unit(zeta, tolerance, negative_amplitude), kind.exact(zeta))


def check_tolerance(value) -> float:
    """Validate ``shaper.tolerance`` (EI vibration limit V, fraction): ``0 < V < 0.5``."""
    v = _number("shaper.tolerance", value)
    if not 0.0 < v < 0.5:
        raise InputError("shaper.tolerance", f"must be in (0, 0.5) (fraction, 0.05 = 5 %), got {v}")
    return v


def check_negative_amplitude(value) -> float:
    """Validate ``shaper.negative_amplitude`` (SNA P): ``0.5 < P <= 2``."""
    p = _number("shaper.negative_amplitude", value)
    if not 0.5 < p <= 2.0:
        raise InputError("shaper.negative_amplitude", f"must be in (0.5, 2] (0.5 is ZV), got {p}")
    return p


def _number(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(name, f"must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise InputError(name, f"must be finite, got {v}")
    return v


def _check_mode(i: int, w: float, z: float) -> tuple[float, float]:
    w = _number(f"omega[{i}]", w)
    z = _number(f"zeta[{i}]", z)
    if w <= 0.0:
        raise InputError(f"omega[{i}]", f"must be > 0 rad/s, got {w}")
    if not 0.0 <= z < 1.0:
        raise InputError(f"zeta[{i}]", f"must be in [0, 1), got {z}")
    return w, z


def design(
    name: str, omega, zeta, tolerance: float = 0.05, negative_amplitude: float = 0.75, multimode: str = "convolve"
) -> Shaper:
    """Shaper ``name`` for one or several modes.

    Parameters
    ----------
    name : str
        A key of :data:`SHAPERS`.
    omega, zeta : float or sequence of float
        Design frequencies (rad/s) and damping ratios.
    tolerance : float
        EI vibration limit ``V`` (fraction).
    negative_amplitude : float
        SNA negative amplitude ``P``.
    multimode : {"convolve", "direct"}
        Several modes: convolve one shaper per mode, or design one shaper for
        all modes at once (``zv``, ``zvd``, ``zvdd`` only).
    """
    if name not in SHAPERS:
        raise InputError("shaper", f"must be one of {sorted(SHAPERS)}, got {name!r}")
    omega = np.atleast_1d(np.asarray(omega, dtype=float))
    zeta = np.atleast_1d(np.asarray(zeta, dtype=float))
    if omega.size == 0 or omega.size != zeta.size:
        raise InputError("omega/zeta", f"need one damping ratio per frequency, got {omega.size} and {zeta.size}")
    modes = [_check_mode(i, w, z) for i, (w, z) in enumerate(zip(omega, zeta))]
    tolerance = check_tolerance(tolerance)
    negative_amplitude = check_negative_amplitude(negative_amplitude)
    params: dict = {}
    if name.startswith("ei"):
        params["tolerance"] = tolerance
    if name == "sna":
        params["negative_amplitude"] = negative_amplitude
    if multimode not in ("convolve", "direct"):
        raise InputError("shaper.multimode", f"must be 'convolve' or 'direct', got {multimode!r}")
    if multimode == "direct" and len(modes) > 1:
        if name not in ("zv", "zvd", "zvdd"):
            raise InputError("shaper.multimode", f"'direct' is available for zv, zvd, zvdd, not {name}")
        return multi_mode_direct([m[0] for m in modes], [m[1] for m in modes], {"zv": 0, "zvd": 1, "zvdd": 2}[name])
    out = None
    for w, z in modes:
        t, a, exact = _unit(name, z, tolerance, negative_amplitude)
        s = Shaper(name, t / w, a, (w,), (z,), exact, params)
        out = s if out is None else out.convolve(s)
    if len(modes) == 1:
        return out
    return Shaper(name, out.times, out.amplitudes, out.omega, out.zeta, out.exact, params, out.factors)


def multi_mode_direct(omega, zeta, derivatives: int = 0, points_per_period: int = 400) -> Shaper:
    """One positive shaper with zero vibration (and ``derivatives`` frequency derivatives) for every mode.

    Impulses on a grid of step ``h = Td_min / points_per_period``; for ``K``
    steps the constraints ``sum A = 1``, ``A >= 0`` and, for each mode and
    ``d <= derivatives``, ``sum A_k t_k^d e^{-lambda t_k} = 0`` are linear in
    ``A``: feasibility is a linear program, monotone in ``K`` (later impulses
    may be zero), so bisection gives the shortest grid shaper.  Its amplitudes
    are then made exact (least-norm solve on the support).  Shortest to within
    one grid step ``h``; numerical.
    """
    w = np.asarray(omega, dtype=float)
    z = np.asarray(zeta, dtype=float)
    s = np.sqrt(1.0 - z * z)
    h = float(np.min(2.0 * np.pi / (w * s))) / points_per_period

    def constraints(K):
        t = h * np.arange(K + 1)
        rows = [np.ones(K + 1)]
        for wi, zi, si in zip(w, z, s):
            e = np.exp(wi * (zi * (t - t[-1]) + 1j * si * t))  # scaled: no overflow
            for d in range(derivatives + 1):
                v = e * (t / t[-1]) ** d
                rows += [v.real, v.imag]
        M = np.array(rows)
        rhs = np.zeros(M.shape[0])
        rhs[0] = 1.0
        return t, M, rhs

    def feasible(K):
        t, M, rhs = constraints(K)
        res = solve_lp(cost=np.zeros(K + 1), A_eq=M, b_eq=rhs, lower=0.0, upper=np.inf)
        return (t, res.x, M, rhs) if res.status is LpStatus.OPTIMAL else None

    conv = float(np.sum(0.5 * (derivatives + 1) * 2.0 * np.pi / (w * s)))
    hi = math.ceil(conv / h) + 2
    while feasible(hi) is None:
        hi *= 2
        if hi > 1_000_000:
            raise SolverError("direct multi-mode shaper: no feasible grid shaper")
    lo = 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if feasible(mid) is None:
            lo = mid
        else:
            hi = mid
    t, a, M, rhs = feasible(hi)
    support = np.flatnonzero(a > 1e-10)
    da = np.linalg.lstsq(M[:, support], rhs - M[:, support] @ a[support], rcond=None)[0]
    a_s = a[support] + da
    if np.any(a_s < 0.0):
        raise SolverError("direct multi-mode shaper: exact amplitudes left the positive orthant")
    name = {0: "zv", 1: "zvd", 2: "zvdd"}[derivatives]
    ts = t[support]
    return Shaper(
        name,
        ts - ts[0],
        a_s,
        tuple(float(v) for v in w),
        tuple(float(v) for v in z),
        False,
        {"multimode": "direct", "grid_step_s": h},
    )
