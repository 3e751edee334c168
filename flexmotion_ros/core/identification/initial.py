"""First estimates of the modes: OKID/ERA on block-averaged data, ranked by the exact fit.

Machines are sampled far faster than they vibrate (1 kHz for a 0.4 Hz crane):
at the full rate the poles crowd ``z = 1`` and any realization is
ill-conditioned.  So the first estimate works on block averages of ``s``
samples: averaging input and output with the same filter keeps their
relation (the system and the filter commute), cuts the noise by ``sqrt(s)``
and spreads the poles around the unit circle.  Each ``s = 1, 2, 4, ...``
(while at least :data:`MIN_COARSE_SAMPLES` blocks remain) gives
Markov parameters (:func:`~flexmotion_ros.core.identification.era.observer_markov`)
and ERA realizations of a few orders; every complex pole pair that completes a
cycle within the record, below the block rate's Nyquist frequency, is a
candidate mode; each realization proposes its ``N`` most energetic ones
(largest ``|C v| |w^T B| / sqrt(1 - |lambda|^2)``).  The proposals are ranked by
the residual of the exact full-rate model with the best linear parameters
(:meth:`~flexmotion_ros.core.identification.forward.ForwardModel.linear_fit`),
so a wrong block size or a spurious pole simply loses.  One more proposal
comes from residual spectra (:func:`spectral_start`), for data too noisy for
a realization.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import minimize_scalar

from .data import IdentificationData
from .era import era, observer_markov
from .forward import ForwardModel

#: Fewest blocks a block size must leave (the ARX fit needs many more rows than parameters).
MIN_COARSE_SAMPLES = 150
#: Hankel block rows and columns (coarse samples spanned: twice this).
HANKEL_SIZE = 40
#: Extra ERA orders tried above the rigid body plus 2 N (room for noise poles).
EXTRA_ORDERS = (0, 2, 4)
#: Candidate modes must have a damping ratio below this (lighter than critically damped, by far).
MAX_CANDIDATE_ZETA = 0.5
#: ... and lie below this fraction of the block rate's Nyquist frequency.
COARSE_NYQUIST_FRACTION = 0.8
#: Zero padding of the residual spectra of :func:`spectral_start` (finer peaks).
SPECTRAL_PADDING = 4
#: Spectral peaks tried per mode, and the damping ratios tried at each.
SPECTRAL_PEAKS = 5
SPECTRAL_ZETAS = (0.005, 0.02, 0.08)
#: Candidates of the first scan for the rigid body's viscous term.
RIGID_C_GRID = 25
#: Two proposals whose frequencies all agree to this relative tolerance are one.
SAME_START_RTOL = 0.02


@dataclass(frozen=True, kw_only=True)
class Start:
    """A first estimate: modal frequencies (rad/s) and damping ratios, and where it came from."""

    omega: tuple[float, ...]
    zeta: tuple[float, ...]
    c: float = 0.0
    rss: float = math.inf
    block: int = 1
    order: int = 0


def block_average(x: np.ndarray, s: int) -> np.ndarray:
    """Means of consecutive blocks of ``s`` samples (a trailing partial block dropped)."""
    n = (x.shape[0] // s) * s
    return x[:n].reshape(n // s, s, *x.shape[1:]).mean(axis=1)


def rigid_states(data: IdentificationData) -> int:
    """States the rigid body adds to a realization: 2 if any output reads position, else 1."""
    return 2 if any(o.kind == "position" and o.rigid_weight != 0.0 for o in data.outputs) else 1


def _candidates(A, B, C, h: float, duration: float, nyquist: float) -> list[tuple[float, float, float]]:
    """``(omega, zeta, energy)`` of each admissible complex pole pair of a coarse realization."""
    lam, V = np.linalg.eig(A)
    W = np.linalg.inv(V)
    out = []
    for i, z in enumerate(lam):
        if z.imag <= 0.0 or abs(z) >= 1.0 + 1e-9 or abs(z) == 0.0:
            continue
        s = np.log(z) / h
        w = abs(s)
        zeta = -s.real / w
        wd = s.imag
        if not (0.0 <= zeta < MAX_CANDIDATE_ZETA) or wd * duration < 2.0 * math.pi:
            continue
        if w > COARSE_NYQUIST_FRACTION * nyquist:
            continue
        energy = float(np.linalg.norm(C @ V[:, i]) * abs(W[i] @ B[:, 0]) / math.sqrt(max(1.0 - abs(z) ** 2, 1e-300)))
        out.append((float(w), float(zeta), energy))
    return out


def _distinct(starts: list[Start], new: Start) -> bool:
    for s in starts:
        if all(abs(a - b) <= SAME_START_RTOL * b for a, b in zip(sorted(new.omega), sorted(s.omega))):
            return False
    return True


def rigid_viscous_estimate(data: IdentificationData) -> float:
    """A first ``c`` (1/s): the rigid body alone fitted to the data, ``c`` scanned then polished.

    Drag matters long before it shows in a realization: over a 5 m move a
    ``c`` of -0.05 1/s moves the cart by decimetres, far more than a swing.
    Candidates ``0`` and ``-k / T`` for ``k`` from 0.01 to 100 (``T`` the
    record), then a bounded scalar search around the best.
    """
    fm = ForwardModel(data, 0)
    T = data.duration

    def rss(c: float) -> float:
        return float(fm.linear_fit(c, [], [])[1].sum())

    grid = np.concatenate([[0.0], -np.geomspace(0.01, 100.0, RIGID_C_GRID) / T])
    scores = [rss(c) for c in grid]
    k = int(np.argmin(scores))
    if k == 0:
        return 0.0
    lo = grid[min(k + 1, grid.size - 1)]
    hi = grid[k - 1]
    sol = minimize_scalar(rss, bounds=(lo, hi), method="bounded", options={"xatol": 1e-4 / T})
    return float(sol.x) if sol.fun < scores[k] else float(grid[k])


def spectral_start(data: IdentificationData, n_modes: int, c: float = 0.0) -> Start | None:
    """A first estimate that does not need a realization: modes one at a time from residual spectra.

    With ``k`` modes found, fit them (and the rigid body) linearly, take the
    Hann-windowed, zero-padded amplitude spectrum of each output's residual
    (normalised by its level) and try its :data:`SPECTRAL_PEAKS` highest local
    maxima in the admissible range, each with the damping ratios
    :data:`SPECTRAL_ZETAS`; the exact full-rate fit picks mode ``k + 1``.
    Where a realization is swamped by noise (a mode seen at 0 dB through a
    non-collocated sensor) the matched filter of a spectrum still finds it.
    """
    n = data.samples
    window = np.hanning(n)
    freqs = 2.0 * math.pi * np.fft.rfftfreq(SPECTRAL_PADDING * n, data.dt)
    lo = 2.0 * math.pi / data.duration
    hi = COARSE_NYQUIST_FRACTION * data.nyquist
    omega: list[float] = []
    zeta: list[float] = []
    for k in range(n_modes):
        fm = ForwardModel(data, k)
        theta, _ = fm.linear_fit(c, omega, zeta)
        spectrum = np.zeros(freqs.size)
        for y, p in zip(fm.y, fm.predict(theta)):
            r = y - p
            spectrum += np.abs(
                np.fft.rfft(window * (r - r.mean()) / max(float(np.std(r)), 1e-300), SPECTRAL_PADDING * n)
            )
        peak = (spectrum[1:-1] > spectrum[:-2]) & (spectrum[1:-1] >= spectrum[2:])
        idx = np.flatnonzero(peak) + 1
        idx = idx[(freqs[idx] >= lo) & (freqs[idx] <= hi)]
        # a found mode's own window main lobe (+-2 bins of the record) is not a new mode
        lobe = 4.0 * math.pi / data.duration
        idx = [i for i in idx if all(abs(freqs[i] - w) > max(SAME_START_RTOL * w, lobe) for w in omega)]
        if not idx:
            return None
        best = sorted(idx, key=lambda i: -spectrum[i])[:SPECTRAL_PEAKS]
        fm_next = ForwardModel(data, k + 1)
        trials = [(float(freqs[i]), z) for i in best for z in SPECTRAL_ZETAS]
        scores = [float(fm_next.linear_fit(c, omega + [w], zeta + [z])[1].sum()) for w, z in trials]
        w, z = trials[int(np.argmin(scores))]
        omega.append(w)
        zeta.append(z)
    order = np.argsort(omega)
    return Start(omega=tuple(omega[i] for i in order), zeta=tuple(zeta[i] for i in order), c=c, block=0)


def initial_estimates(
    data: IdentificationData, n_modes: int, keep: int = 3, extra: tuple[Start, ...] = ()
) -> tuple[list[Start], np.ndarray]:
    """The ``keep`` best distinct first estimates of ``n_modes`` modes, best first.

    Parameters
    ----------
    data : IdentificationData
    n_modes : int
    keep : int
        How many distinct proposals to return.
    extra : tuple of Start
        Proposals from elsewhere (a prior model's frequencies and damping),
        ranked with the rest; their ``c`` is replaced by the data's first estimate.

    Returns
    -------
    starts : list of Start
        Ranked by the full-rate residual (``rss``).  Empty if no realization
        proposed ``n_modes`` admissible modes.
    singular_values : ndarray
        Hankel singular values of the winning block size (normalised by the largest).
    """
    fm = ForwardModel(data, n_modes)
    c0 = rigid_viscous_estimate(data)
    if n_modes == 0:
        _, rss = fm.linear_fit(c0, [], [])
        return [Start(omega=(), zeta=(), c=c0, rss=float(rss.sum()))], np.zeros(0)
    Y = np.column_stack([o.samples for o in data.outputs])
    nr = rigid_states(data)
    proposals: list[Start] = [replace(st, c=c0) for st in extra]  # the data's c beats a belief
    spectral = spectral_start(data, n_modes, c0)
    if spectral is not None:
        proposals.append(spectral)
    svs: dict[int, np.ndarray] = {}
    s = 1
    while data.samples // s >= MIN_COARSE_SAMPLES:
        uc, yc = block_average(data.u, s), block_average(Y, s)
        h = s * data.dt
        for add in EXTRA_ORDERS:
            r = nr + 2 * n_modes + add
            p = 2 * r + 4
            rows = min(HANKEL_SIZE, max(r + 2, (uc.size - p) // 4))
            if uc.size < 4 * p * (1 + Y.shape[1]) or rows < r:
                continue
            markov = observer_markov(uc, yc, p, 2 * rows + 1)
            A, B, C, _, S = era(markov, r, rows, rows)
            svs.setdefault(s, S / S[0])
            found = _candidates(A, B, C, h, data.duration, math.pi / h)
            if len(found) >= n_modes:
                best = sorted(found, key=lambda t: -t[2])[:n_modes]
                best.sort()
                proposals.append(
                    Start(omega=tuple(b[0] for b in best), zeta=tuple(b[1] for b in best), c=c0, block=s, order=r)
                )
        s *= 2
    ranked: list[Start] = []
    for st in proposals:
        if len(st.omega) != n_modes or len({round(w, 9) for w in st.omega}) != n_modes:
            continue
        _, rss = fm.linear_fit(st.c, st.omega, st.zeta)
        ranked.append(Start(omega=st.omega, zeta=st.zeta, c=st.c, rss=float(rss.sum()), block=st.block, order=st.order))
    ranked.sort(key=lambda st: st.rss)
    out: list[Start] = []
    for st in ranked:
        if _distinct(out, st):
            out.append(st)
        if len(out) == keep:
            break
    winner = out[0].block if out else 1
    return out, svs.get(winner, np.zeros(0))
