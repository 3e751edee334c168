"""The final-state error of a move and the scale it is judged against (one definition for every planner).

A planner accepts a profile or a sampled sequence only if its *relative
final-state error* (:func:`relative_final_state_error`) is at most
:data:`~flexmotion_ros.core.tolerances.FINAL_STATE_RTOL`.  The scale is
:func:`state_scale`: how large each state can get in a move of that length,
whatever the profile.
"""

from __future__ import annotations

import numpy as np

#: The sample points of :func:`state_scale` on ``[0, 1]`` (times ``T``), built once.
_UNIT_GRID = np.concatenate([np.linspace(0.0, 1.0, 65), np.geomspace(1e-6, 1.0, 61)])


def state_scale(system, x0: np.ndarray, u_max: float, T: float) -> np.ndarray:
    """How large each state can get in a move of length ``T`` (state units).

    The scale against which every final-state error is judged (see
    :data:`~flexmotion_ros.core.tolerances.FINAL_STATE_RTOL`)::

        s_i = f_i(x0, T) + u_max * max_{0 <= tau <= T} |Gamma_i(tau)|

    with ``Gamma(tau) = int_0^tau e^{A s} B ds`` (the state a unit input held
    for ``tau`` reaches from rest, in N^-1 times the state's unit) and
    ``f(x0, T)`` the free motion's size: ``|x0|``, with a mode's position and
    velocity sharing one vibration amplitude and the rigid-body position
    carried along by the initial speed for ``T``.  Entries that come out 0
    are set to 1.  It does not depend on the profile, so a profile that barely
    excites a mode is not judged against that mode's tiny excursion.

    Parameters
    ----------
    system : ModalResponse
        Closed-form responses (anything with ``input_integral``; ``w``, ``r``,
        ``sig`` and ``wd`` refine the free motion).
    x0 : ndarray
        Shifted initial state (state units: m, m/s, modal coordinates).
    u_max : float
        Input bound (N).
    T : float
        Move length (s), ``> 0``.

    Returns
    -------
    ndarray
        One positive scale per state entry (state units).
    """
    # uniform points plus geometric ones near 0: a fast, damped mode peaks
    # (and decays) long before T on a long move
    G = system.input_integral(T * _UNIT_GRID)
    s = _free_motion_scale(system, np.asarray(x0, dtype=float), T) + u_max * np.max(np.abs(G), axis=0)
    return np.where(s > 0.0, s, 1.0)


def _free_motion_scale(system, x0: np.ndarray, T: float) -> np.ndarray:
    """How large the initial state alone makes each state over ``[0, T]``.

    A mode's position and velocity share one vibration amplitude (a mode
    released with speed only still swings), and an initial speed carries the
    position along; for systems without that structure, ``|x0|``.
    """
    out = np.abs(x0).copy()
    w = getattr(system, "w", None)
    r = getattr(system, "r", None)
    if w is None or r is None or out.size != r + 2 * np.size(w):
        return out
    if r == 2:
        out[0] += abs(x0[1]) * T
    q, qd = x0[r::2], x0[r + 1 :: 2]
    amp = np.hypot(q, (qd + system.sig * q) / system.wd)
    out[r::2] = np.maximum(out[r::2], amp)
    out[r + 1 :: 2] = np.maximum(out[r + 1 :: 2], amp * w)
    return out


def relative_final_state_error(deviation: np.ndarray, scale: np.ndarray) -> float:
    """``max_i |deviation_i| / scale_i`` (dimensionless): the figure compared with ``FINAL_STATE_RTOL``.

    Parameters
    ----------
    deviation : ndarray
        Final state minus the target's rest state (state units).
    scale : ndarray
        :func:`state_scale` of the move (state units), same shape.
    """
    deviation = np.asarray(deviation, dtype=float)
    return float(np.max(np.abs(deviation) / scale)) if deviation.size else 0.0
