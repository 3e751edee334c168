"""The structure of a limited move: runs of constant level or slew ramps, and windows between them.

A limited optimum is mostly *runs*: full force, a constant level that rides a
state limit (``u = 0`` at the velocity limit of a free rigid body, the static
level at a deflection limit), or a ramp at the slew limit.  Only samples near
the changes need to be free LP variables (:class:`~flexmotion_ros.core.limit_lp.Segments`).
The runs of one solution (at a coarser rate, or a neighbouring sample count)
are mapped to another by normalised time ``m / K``; the windows (``width``
free samples at both ends of every run) absorb where the changes move.
"""

from __future__ import annotations

import numpy as np

from .segments import LPSolution, Segments

#: Steps of a reference profile within this (normalised command) of 0 or one slew step form a run.
STEP_TOL = 1e-6


def profile_runs(v: np.ndarray, step: float | None, min_len: int = 3) -> list[tuple[int, int, float]]:
    """Maximal runs ``(start, end, slope)`` of ``v`` (normalised commands): constant, or ``+-step`` per sample.

    ``step`` is the slew step in the same units (None: no slew limit, no ramps).
    """
    d = np.diff(np.asarray(v, float))
    cls = np.full(d.size, 9.0)
    cls[np.abs(d) <= STEP_TOL] = 0.0
    if step:
        cls[np.abs(d - step) <= STEP_TOL * max(1.0, step)] = 1.0
        cls[np.abs(d + step) <= STEP_TOL * max(1.0, step)] = -1.0
    runs = []
    i = 0
    while i < d.size:
        j = i
        while j + 1 < d.size and cls[j + 1] == cls[i]:
            j += 1
        if cls[i] != 9.0 and j + 2 - i >= min_len:  # steps i..j: samples i..j+1
            runs.append((i, j + 2, float(cls[i])))
        i = j + 1
    return runs


def map_runs(runs: list[tuple[int, int, float]], K_ref: int, K: int, width: int, min_len: int = 2) -> Segments:
    """Runs of a ``K_ref``-sample profile placed on ``K`` samples, each shrunk by ``width`` at both ends."""
    f = K / K_ref
    out = []
    for a, b, s in runs:
        A = max(int(round(a * f)) + width, out[-1][1] if out else 0)
        B = int(round(b * f)) - width
        if B - A >= min_len:
            out.append((A, B, s))
    return Segments.from_runs(K, [(a, b, s) for a, b, s in out if a >= width and b <= K - width])


def solution_runs(sol: LPSolution, um: float, step: float | None, min_len: int = 3) -> list[tuple[int, int, float]]:
    """Runs of a solved LP (its commands divided by ``u_max`` and its scale ``t``)."""
    return profile_runs(sol.u / (um * sol.t), step * 1.0 if step else None, min_len)
