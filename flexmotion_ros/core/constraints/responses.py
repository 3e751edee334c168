"""Closed-form responses of the limited planner at ``K`` samples (no LP).

The linear program of :mod:`.limit_lp` writes every limited state through
these responses: the *limited blocks* (:class:`Block`: the rigid-body
velocity, or a mode's deflection and its rate, each scaled by its limit),
their per-``K`` powers and input responses (:class:`KData`: a run of
samples is crossed in one step with ``P^L``, the step response ``psi_L`` and
the ramp response ``R_L``), the limited states at every sample
(:func:`block_states`, by FFT) and a mode's deflection a time ``s`` into a
sample interval (:func:`deflection_row`, for the rows between samples).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import fftconvolve

from ..sampled.lp_tools import lp_state_scale, sample_vectors
from ..simulation.modal_response import ModalResponse
from .limits import Limits


@dataclass
class Block:
    """One limited block of the state: its response coordinates and their scales."""

    idx: list  # state indices (response coordinates)
    D: np.ndarray  # LP variable = state / D
    mode: int | None  # mode index (deflection limit) or None (velocity)


def limit_blocks(sysm: ModalResponse, limits: Limits, omega: np.ndarray) -> list[Block]:
    """The limited blocks: the velocity (if limited), then every mode with a finite deflection limit.

    Parameters
    ----------
    sysm : ModalResponse
        Exact response of the model (``r`` rigid-body states, then two per mode).
    limits : Limits
        The limits; a mode's deflection rate is scaled by ``q_max * omega``.
    omega : numpy.ndarray
        Natural frequencies of the modes (rad/s).

    Returns
    -------
    list of Block
    """
    r = sysm.r
    blocks: list[Block] = []
    if limits.velocity_max is not None:
        blocks.append(Block([r - 1], np.array([limits.velocity_max]), None))
    qmax = limits.deflection_max or ()
    for i, qm in enumerate(qmax):
        if math.isfinite(qm):
            blocks.append(Block([r + 2 * i, r + 2 * i + 1], np.array([qm, qm * omega[i]]), i))
    return blocks


class KData:
    """Per-``K`` closed forms: input responses, free response, powers of the limited blocks.

    Parameters
    ----------
    sysm : ModalResponse
        Exact response of the model.
    dt : float
        Sample period (s).
    x0 : numpy.ndarray
        Initial state (shifted so that the target is the origin).
    um : float
        Command limit ``u_max``; LP commands are normalised by it.
    blocks : list of Block
        The limited blocks.
    K : int
        Number of samples.

    Attributes
    ----------
    g : numpy.ndarray
        ``g_j = e^{A j dt} Gamma(dt)``, ``j = 0..K``.
    xf : numpy.ndarray
        Free response at every sample ``0..K``.
    w : numpy.ndarray
        Arrival right-hand side, ``-xf[K]``.
    sc : numpy.ndarray
        Scale of every state in the arrival rows.
    blk : list of tuple
        Per block ``(P, gh, psi, R)``: powers ``P[j]`` of its (scaled) transition,
        its response to a unit normalised command, step and ramp responses.
    """

    def __init__(self, sysm: ModalResponse, dt: float, x0: np.ndarray, um: float, blocks: list[Block], K: int) -> None:
        self.g = sample_vectors(sysm, K + 1, dt)  # g_j = e^{A j dt} Gamma(dt)
        self.xf = sysm.expm_x_many(dt * np.arange(K + 1), x0)  # free response at every sample
        self.w = -self.xf[K]
        self.sc = lp_state_scale(sysm, x0, um, K * dt)
        self.blk = []
        for b in blocks:
            d = len(b.idx)
            P = np.empty((K + 1, d, d))
            for c, j in enumerate(b.idx):
                e = np.zeros(sysm.n)
                e[j] = 1.0
                P[:, :, c] = sysm.expm_x_many(dt * np.arange(K + 1), e)[:, b.idx] * b.D[c] / b.D
            gh = self.g[:, b.idx] * um / b.D  # scaled block response to a unit (normalised) command
            psi = np.concatenate([np.zeros((1, d)), np.cumsum(gh[:K], axis=0)])  # step response
            R = np.concatenate([np.zeros((1, d)), np.cumsum(psi[:K], axis=0)])  # ramp response
            self.blk.append((P, gh, psi, R))


def block_states(kd: KData, blocks: list[Block], u: np.ndarray, um: float) -> list[np.ndarray]:
    """Limited component (scaled by its limit) of every block at samples ``0..K`` (closed forms, FFT).

    Parameters
    ----------
    kd : KData
        Closed forms at ``K`` samples.
    blocks : list of Block
        The limited blocks ``kd`` was built for.
    u : numpy.ndarray
        Commands (``K``), forward order.
    um : float
        Command limit ``u_max``.

    Returns
    -------
    list of numpy.ndarray
        One array of ``K + 1`` values per block.
    """
    K = kd.xf.shape[0] - 1
    v = u / um
    out = []
    for bi, b in enumerate(blocks):
        gh = kd.blk[bi][1][:, 0]
        forced = fftconvolve(v, gh[:K])[:K]  # sample k+1: sum_{m<=k} gh_{k-m} v_m
        out.append(np.concatenate([[0.0], forced]) + kd.xf[:, b.idx[0]] / b.D[0])
    return out


def deflection_row(sysm: ModalResponse, s: float, mode: int) -> tuple[np.ndarray, float]:
    """Row of mode ``mode``'s ``q`` in ``e^{A s}`` (its 2x2 block) and in ``Gamma(s)``.

    Parameters
    ----------
    sysm : ModalResponse
        Exact response of the model.
    s : float
        Time into the sample interval (s).
    mode : int
        Mode index.

    Returns
    -------
    row : numpy.ndarray
        Coefficients of ``(q, dq/dt)`` at the sample.
    gamma : float
        Coefficient of the held command.
    """
    ix = sysm.r + 2 * mode
    row = np.empty(2)
    for c in range(2):
        e = np.zeros(sysm.n)
        e[ix + c] = 1.0
        row[c] = sysm.expm_x(s, e)[ix]
    return row, float(sysm.input_integral(np.array([s]))[0][ix])
