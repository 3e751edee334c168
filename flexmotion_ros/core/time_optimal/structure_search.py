"""A bounded search over switch structures on the final-state conditions alone (the solver's last resort).

When the co-state iterations end on a structure that misses the target, the
optimum usually differs from it by a narrow pair of switches (a notch) that
the switching function cannot show: its sign there is below rounding.  The
final state, however, is a smooth, well-scaled function of the switch times.
This module tries a fixed, small set of structures, each a known one (the
solver's, the rigid body's) with one notch added at one of
:data:`LOCATIONS` places or one switch split into a triple, and solves the
final-state conditions for each by :func:`~.switch_newton.primal_newton`
(no co-state).  The work is bounded (at most ``len(bases) x (LOCATIONS +
switches) x len(WIDTHS)`` Newton runs of at most :data:`NEWTON_STEPS` steps),
whatever the model.

Nothing here is trusted: the caller simulates and certifies every candidate
as it comes, and stops at the first certified one.
"""

from __future__ import annotations

import numpy as np

from .reachable_set import Shooting
from .switch_newton import primal_newton

#: Places (fractions of ``T``) tried for an added notch.
LOCATIONS = 24
#: Notch half-widths tried (relative to ``T``).
WIDTHS = (1e-3, 1e-2)
#: Newton steps per structure.
NEWTON_STEPS = 15
#: Two candidates with durations this close (relative) and the same number of
#: switches, every switch as close, are one.
SAME_RTOL = 1e-9


def notch_candidates(sh: Shooting, bases: list[tuple[np.ndarray, float]], T: float):
    """Structures reaching the target, from ``bases`` plus one notch: yields ``(T, roots, sign0)`` as found.

    Parameters
    ----------
    sh : Shooting
        The problem (state scale for durations near ``T``).
    bases : list of (ndarray, float)
        Known structures: switch times-to-go (s, increasing) and the sign of
        ``S`` before the first.
    T : float
        Duration (s) the bases belong to.

    Yields
    ------
    tuple of (float, ndarray, float)
        Duration (s), switch times-to-go (s) and first sign of each distinct
        structure whose final state the Newton run brought below
        ``POLISH_TOL``.  A generator: the caller stops at the first one it
        certifies (a certified extremal is the optimum, whatever the order).
    """
    found: list[tuple[float, np.ndarray, float]] = []
    for roots, sign0 in bases:
        for cand in _with_a_notch(roots, T, sh.s.size):
            if not (cand[0] > 0.0 and cand[-1] < T and np.all(np.diff(cand) > 0.0)):
                continue
            ok, tau, T_c, _ = primal_newton(sh, cand, sign0, T, max_iter=NEWTON_STEPS)
            if ok and not any(_same(T_c, tau, sign0, f) for f in found):
                found.append((T_c, tau, sign0))
                yield T_c, tau, sign0


def _with_a_notch(roots: np.ndarray, T: float, n: int):
    """``roots`` with notches added: enough switches for ``n`` final-state conditions (``L + 1 >= n``).

    One pair short: a narrow pair at one of :data:`LOCATIONS` places, or one
    switch split into three.  More pairs short (several modes tuned near
    whole periods at once): one switch split into ``2 m + 1`` equally spaced.
    """
    m = max(1, -(-(n - 1 - roots.size) // 2))  # pairs needed, at least one
    places = (np.arange(LOCATIONS) + 0.5) / LOCATIONS * T
    for w in WIDTHS:
        d = w * T
        if m == 1:
            for c in places:
                yield np.sort(np.concatenate([roots, [c - d, c + d]]))
        offsets = d * np.arange(-m, m + 1)
        for j in range(roots.size):
            yield np.sort(np.concatenate([np.delete(roots, j), roots[j] + offsets]))


def _same(T_c: float, tau: np.ndarray, sign0: float, other: tuple[float, np.ndarray, float]) -> bool:
    T_o, tau_o, sign_o = other
    return (
        sign0 == sign_o
        and tau.size == tau_o.size
        and abs(T_c - T_o) <= SAME_RTOL * T_c
        and bool(np.all(np.abs(tau - tau_o) <= SAME_RTOL * T_c))
    )
