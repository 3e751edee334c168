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
and the result is checked against those constraints before it is returned):

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
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import fsolve, linprog

from .errors import FlexmotionError, SolverError

#: Shaper names and one-line descriptions.
SHAPERS: dict[str, str] = {
    "zv": "zero vibration (2 impulses, Td/2)",
    "zvd": "zero vibration and derivative (3 impulses, Td)",
    "zvdd": "zero vibration, two derivatives (4 impulses, 1.5 Td)",
    "mzv": "modified ZV: 3 positive impulses over 0.75 Td",
    "ei": "extra-insensitive, one hump of height tolerance",
    "ei2": "two-hump extra-insensitive",
    "ei3": "three-hump extra-insensitive",
    "sna": "specified negative amplitude [1, -P, P] (P = shaper.negative_amplitude)",
    "um_zv": "unity-magnitude ZV [1, -1, 1]",
    "um_zvd": "unity-magnitude ZVD [1, -1, 1, -1, 1]",
}

#: Largest damping step of the continuation from the undamped closed forms.
ZETA_STEP = 0.02
#: Defining constraints must hold to this (dimensionless) after solving.
CONSTRAINT_TOL = 1e-11


@dataclass(frozen=True)
class Shaper:
    """An impulse sequence.

    Attributes
    ----------
    name : str
    times : ndarray
        Impulse times (s), ``times[0] = 0``, increasing.
    amplitudes : ndarray
        Impulse amplitudes (dimensionless), summing to 1.
    omega, zeta : tuple of float
        Design frequencies (rad/s) and damping ratios, one per mode.
    exact : bool
        Closed form (True) or numerically solved constraints (False).
    params : dict
        Design parameters (``tolerance``, ``negative_amplitude``, ...).
    """

    name: str
    times: np.ndarray
    amplitudes: np.ndarray
    omega: tuple[float, ...]
    zeta: tuple[float, ...]
    exact: bool = True
    params: dict = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """Time of the last impulse (s): the delay the shaper adds."""
        return float(self.times[-1])

    @property
    def positive(self) -> bool:
        """All amplitudes >= 0: shaping never raises the peak of a command."""
        return bool(np.all(self.amplitudes >= 0.0))

    @property
    def abs_sum(self) -> float:
        """``sum |A_i|``: the worst-case peak gain on a bounded command."""
        return float(np.sum(np.abs(self.amplitudes)))

    def vibration(self, omega, zeta) -> np.ndarray:
        """Residual vibration ``V`` (fraction, not percent) for modes ``(omega, zeta)`` (broadcast)."""
        return impulse_vibration(self.times, self.amplitudes, omega, zeta)

    def convolve(self, other: Shaper) -> Shaper:
        """The shaper that applies ``self`` then ``other`` (impulses at equal times merged)."""
        t = (self.times[:, None] + other.times[None, :]).ravel()
        a = (self.amplitudes[:, None] * other.amplitudes[None, :]).ravel()
        return _merged(f"{self.name}*{other.name}", t, a, self.omega + other.omega,
                       self.zeta + other.zeta, self.exact and other.exact, {**self.params, **other.params})

    def to_dict(self) -> dict:
        """JSON-friendly description."""
        return {
            "name": self.name,
            "times": [float(v) for v in self.times],
            "amplitudes": [float(v) for v in self.amplitudes],
            "duration": self.duration,
            "omega": list(self.omega),
            "zeta": list(self.zeta),
            "exact": self.exact,
            "positive": self.positive,
            **{k: v for k, v in self.params.items()},
        }


def _merged(name, t, a, omega, zeta, exact, params) -> Shaper:
    order = np.argsort(t, kind="stable")
    t, a = t[order], a[order]
    tol = 1e-12 * max(float(t[-1]), 1e-300)
    keep_t, keep_a = [t[0]], [a[0]]
    for ti, ai in zip(t[1:], a[1:]):
        if ti - keep_t[-1] <= tol:
            keep_a[-1] += ai
        else:
            keep_t.append(ti)
            keep_a.append(ai)
    ta, aa = np.array(keep_t), np.array(keep_a)
    nz = aa != 0.0
    nz[0] = True
    return Shaper(name, ta[nz] - ta[0], aa[nz], tuple(omega), tuple(zeta), exact, params)


def impulse_vibration(times, amplitudes, omega, zeta) -> np.ndarray:
    """Residual vibration of impulses for modes ``(omega, zeta)`` (fraction; broadcast).

    ``e^{-zeta omega t_n} |sum A_i e^{zeta omega t_i} e^{i omega_d t_i}|``, evaluated as
    ``|sum A_i e^{omega (zeta (t_i - t_n) + i sqrt(1 - zeta^2) t_i)}|`` (no overflow).
    """
    t = np.asarray(times, dtype=float)
    a = np.asarray(amplitudes, dtype=float)
    w = np.asarray(omega, dtype=float)[..., None]
    z = np.asarray(zeta, dtype=float)[..., None]
    expo = w * (z * (t - t[-1]) + 1j * np.sqrt(1.0 - z * z) * t)
    return np.abs(np.sum(a * np.exp(expo), axis=-1))


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

    def __init__(self, n: int, fixed_amps, hump_at_1: bool, zero_at_1: bool, deriv_at_1: bool,
                 n_humps: int, n_zeros: int, tol: float) -> None:
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
        J = np.column_stack([(design.equations(x + h * e, zeta) - design.equations(x - h * e, zeta)) / (2 * h)
                             for e in np.eye(x.size)])
        x = x - np.linalg.lstsq(J, F, rcond=None)[0]
    F = design.equations(x, zeta)
    a, t, rh, rz = design.unpack(x)
    if not np.max(np.abs(F)) <= CONSTRAINT_TOL or np.any(np.diff(t) <= 0.0):
        raise SolverError(
            f"shaper {name}: numerical design failed at zeta = {zeta:.3g} (residual {np.max(np.abs(F)):.1e})"
        )
    return a, t, rh, rz


def _ei(zeta: float, V: float, humps: int) -> tuple[np.ndarray, np.ndarray]:
    t0, a0 = _ei_undamped(V, humps)
    if zeta == 0.0:
        return t0, a0
    n = humps + 2
    n_zeros = {1: 2, 2: 2, 3: 4}[humps]
    n_humps = {1: 0, 2: 2, 3: 2}[humps]
    rz0, rh0 = _extrema(t0, a0, 0.0, n_zeros, n_humps)
    design = _Design(n, None, hump_at_1=humps != 2, zero_at_1=humps == 2, deriv_at_1=False,
                     n_humps=n_humps, n_zeros=n_zeros, tol=V)
    a, t, _, rz = _solve_continuation(design, t0, a0, rh0, rz0, zeta, f"ei{humps}")
    # the design is what it claims only if V <= tol between the outer zeros
    r = np.linspace(rz[0], rz[-1], 4001)
    if np.max(impulse_vibration(t, a, r, zeta)) > V * (1.0 + 1e-6) or np.any(a <= 0.0):
        raise SolverError(f"shaper ei{humps}: no valid design at zeta = {zeta:.3g}")
    return t, a


def _negative(zeta: float, P: float | None) -> tuple[np.ndarray, np.ndarray]:
    """SNA ``[1, -P, P]`` (``P = None``: UM-ZVD); exact at zeta = 0 except UM-ZVD."""
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


def _unit(name: str, zeta: float, tolerance: float, negative_amplitude: float) -> tuple[np.ndarray, np.ndarray, bool]:
    if name in ("zv", "zvd", "zvdd"):
        return (*_zv_n(zeta, {"zv": 0, "zvd": 1, "zvdd": 2}[name]), True)
    if name == "mzv":
        return (*_mzv(zeta), True)
    if name in ("ei", "ei2", "ei3"):
        return (*_ei(zeta, tolerance, {"ei": 1, "ei2": 2, "ei3": 3}[name]), zeta == 0.0)
    if name == "sna":
        return (*_negative(zeta, negative_amplitude), zeta == 0.0)
    if name == "um_zv":
        return (*_negative(zeta, 1.0), zeta == 0.0)
    if name == "um_zvd":
        return (*_negative(zeta, None), False)
    raise FlexmotionError("shaper", f"must be one of {sorted(SHAPERS)}, got {name!r}")


def check_tolerance(value) -> float:
    """Validate ``shaper.tolerance`` (EI vibration limit V, fraction): ``0 < V < 0.5``."""
    v = _number("shaper.tolerance", value)
    if not 0.0 < v < 0.5:
        raise FlexmotionError("shaper.tolerance", f"must be in (0, 0.5) (fraction, 0.05 = 5 %), got {v}")
    return v


def check_negative_amplitude(value) -> float:
    """Validate ``shaper.negative_amplitude`` (SNA P): ``0.5 < P <= 2``."""
    p = _number("shaper.negative_amplitude", value)
    if not 0.5 < p <= 2.0:
        raise FlexmotionError("shaper.negative_amplitude", f"must be in (0.5, 2] (0.5 is ZV), got {p}")
    return p


def _number(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise FlexmotionError(name, f"must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise FlexmotionError(name, f"must be finite, got {v}")
    return v


def _check_mode(i: int, w: float, z: float) -> tuple[float, float]:
    w = _number(f"omega[{i}]", w)
    z = _number(f"zeta[{i}]", z)
    if w <= 0.0:
        raise FlexmotionError(f"omega[{i}]", f"must be > 0 rad/s, got {w}")
    if not 0.0 <= z < 1.0:
        raise FlexmotionError(f"zeta[{i}]", f"must be in [0, 1), got {z}")
    return w, z


def design(name: str, omega, zeta, tolerance: float = 0.05, negative_amplitude: float = 0.75,
           multimode: str = "convolve") -> Shaper:
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
        raise FlexmotionError("shaper", f"must be one of {sorted(SHAPERS)}, got {name!r}")
    omega = np.atleast_1d(np.asarray(omega, dtype=float))
    zeta = np.atleast_1d(np.asarray(zeta, dtype=float))
    if omega.size == 0 or omega.size != zeta.size:
        raise FlexmotionError("omega/zeta", f"need one damping ratio per frequency, got {omega.size} and {zeta.size}")
    modes = [_check_mode(i, w, z) for i, (w, z) in enumerate(zip(omega, zeta))]
    tolerance = check_tolerance(tolerance)
    negative_amplitude = check_negative_amplitude(negative_amplitude)
    params: dict = {}
    if name.startswith("ei"):
        params["tolerance"] = tolerance
    if name == "sna":
        params["negative_amplitude"] = negative_amplitude
    if multimode not in ("convolve", "direct"):
        raise FlexmotionError("shaper.multimode", f"must be 'convolve' or 'direct', got {multimode!r}")
    if multimode == "direct" and len(modes) > 1:
        if name not in ("zv", "zvd", "zvdd"):
            raise FlexmotionError("shaper.multimode", f"'direct' is available for zv, zvd, zvdd, not {name}")
        return multi_mode_direct([m[0] for m in modes], [m[1] for m in modes], {"zv": 0, "zvd": 1, "zvdd": 2}[name])
    out = None
    for w, z in modes:
        t, a, exact = _unit(name, z, tolerance, negative_amplitude)
        s = Shaper(name, t / w, a, (w,), (z,), exact, params)
        out = s if out is None else out.convolve(s)
    return out if len(modes) == 1 else Shaper(name, out.times, out.amplitudes, out.omega, out.zeta, out.exact, params)


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
        res = linprog(np.zeros(K + 1), A_eq=M, b_eq=rhs, bounds=[(0.0, None)] * (K + 1), method="highs")
        return (t, res.x, M, rhs) if res.status == 0 else None

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
    return Shaper(name, ts - ts[0], a_s, tuple(float(v) for v in w), tuple(float(v) for v in z), False,
                  {"multimode": "direct", "grid_step_s": h})
