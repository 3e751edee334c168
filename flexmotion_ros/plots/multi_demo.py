"""The closed-loop demo's figure for several inputs: every drive's command, every axis, every sway (PNG, Agg).

Panels, top to bottom: the command of each input (N, dashed bounds); the
position of each rigid body with its target (m); each mode's coordinate (the
model's unit); the residual of each axis on a log scale (distance to the
target plus the largest sway amplitude, as a fraction of the move).  After
the last recorded sample the exact zero-input continuation of the plant's last
state is drawn dashed (matrix exponentials, :mod:`flexmotion_ros.core.multi_input.exact`),
so residual sway would show.
"""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from ..core.multi_input.exact import VectorPiecewise, simulate, system_of
from ..core.multi_input.model import MultiModel
from ..core.simulation.exact import modal_amplitudes

#: Periods of the slowest mode shown after the last recorded sample.
PERIODS_AFTER = 3.0
#: Residuals below this (fraction of the move) are drawn at it (a log axis has no zero).
FLOOR = 1e-16


def continuation(model: MultiModel, t_last: float, x_last: np.ndarray, periods: float = PERIODS_AFTER, n: int = 600):
    """Exact zero-input motion of ``x_last`` for ``periods`` of the slowest mode: times (s) and states."""
    w = min(model.omega) if model.n_modes else 1.0
    span = periods * 2.0 * np.pi / w
    t = np.linspace(0.0, span, n)
    A, B = system_of(model)
    zero = VectorPiecewise(np.array([0.0, span]), np.zeros((1, model.m)))
    return t_last + t, simulate(A, B, x_last, zero, t)


def sway(model: MultiModel, X: np.ndarray) -> np.ndarray:
    """Each mode's free-vibration amplitude in states ``X`` (shape ``(..., N)``)."""
    k = model.k
    modal = np.concatenate([np.zeros(X.shape[:-1] + (2,)), X[..., 2 * k :]], axis=-1)
    return modal_amplitudes(model, modal)


def plot_multi_demo(
    path: str,
    t_cmd: np.ndarray,
    commands: np.ndarray,
    u_max: Sequence[float],
    t_x: np.ndarray,
    X: np.ndarray,
    targets: Sequence[float],
    start: Sequence[float],
    model: MultiModel,
    title: str,
    t_arrival: float | None = None,
) -> None:
    """Write the figure of a multi-input demo move to ``path`` (PNG).

    Parameters
    ----------
    t_cmd, commands : ndarray
        Sample times (s) and the ``(K + 1, m)`` commands sent (N).
    u_max : sequence of float
        Each input's bound (N).
    t_x, X : ndarray
        Plant sample times (s) and states (rows in the model's state order).
    targets, start : sequence of float
        Each rigid body's target and start position (m).
    t_arrival : float, optional
        Measured arrival (s), marked on every panel.
    """
    k, N = model.k, model.n_modes
    t_after, X_after = continuation(model, float(t_x[-1]), X[-1])
    move = max(float(np.max(np.abs(np.asarray(targets) - np.asarray(start)))), 1e-12)
    fig, axes = plt.subplots(4, 1, figsize=(9, 11), sharex=True)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    ax = axes[0]
    for i, name in enumerate(model.inputs):
        c = colors[i % len(colors)]
        ax.step(t_cmd, commands[:, i], where="post", color=c, label=f"{name} (|u| <= {u_max[i]:g} N)")
        ax.axhline(u_max[i], color=c, ls=":", lw=0.8)
        ax.axhline(-u_max[i], color=c, ls=":", lw=0.8)
    ax.set_ylabel("command (N)")
    ax.legend(loc="upper right", fontsize=8)
    ax = axes[1]
    for j, name in enumerate(model.rigid_bodies):
        c = colors[j % len(colors)]
        ax.plot(t_x, X[:, 2 * j], color=c, label=f"{name} (rigid body)")
        ax.plot(t_after, X_after[:, 2 * j], color=c, ls="--", lw=0.8)
        ax.axhline(targets[j], color=c, ls=":", lw=0.8)
    ax.set_ylabel("position (m)")
    ax.legend(loc="lower right", fontsize=8)
    ax = axes[2]
    for i, name in enumerate(model.mode_names):
        c = colors[(k + i) % len(colors)]
        ax.plot(t_x, X[:, 2 * k + 2 * i], color=c, label=name)
        ax.plot(t_after, X_after[:, 2 * k + 2 * i], color=c, ls="--", lw=0.8)
    ax.set_ylabel("modal coordinate (model unit)")
    if N:
        ax.legend(loc="upper right", fontsize=8)
    ax = axes[3]
    amps, amps_after = sway(model, X), sway(model, X_after)
    for j, name in enumerate(model.rigid_bodies):
        c = colors[j % len(colors)]
        r = np.abs(X[:, 2 * j] - targets[j]) + np.abs(X[:, 2 * j + 1])
        ra = np.abs(X_after[:, 2 * j] - targets[j]) + np.abs(X_after[:, 2 * j + 1])
        ax.semilogy(t_x, np.maximum(r / move, FLOOR), color=c, label=f"{name}: |p - target| + |v|")
        ax.semilogy(t_after, np.maximum(ra / move, FLOOR), color=c, ls="--", lw=0.8)
    for i, name in enumerate(model.mode_names):
        c = colors[(k + i) % len(colors)]
        ax.semilogy(t_x, np.maximum(amps[:, i] / move, FLOOR), color=c, alpha=0.7, label=f"{name} amplitude")
        ax.semilogy(t_after, np.maximum(amps_after[:, i] / move, FLOOR), color=c, ls="--", lw=0.8, alpha=0.7)
    ax.axhline(1e-6, color="k", ls=":", lw=0.8)
    ax.set_ylabel("residual / move")
    ax.set_xlabel("time (s); dashed: exact zero-input continuation after the last plant sample")
    ax.legend(loc="lower left", fontsize=8)
    if t_arrival is not None:
        for a in axes:
            a.axvline(t_arrival, color="k", lw=0.6, alpha=0.5)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


__all__ = ["PERIODS_AFTER", "continuation", "plot_multi_demo", "sway"]
