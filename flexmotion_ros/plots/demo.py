"""The closed-loop demo's figure: command, position and modal deflections (PNG, Agg)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np


def plot_demo(
    path: str | Path,
    t_command: np.ndarray,
    command: np.ndarray,
    u_max: float,
    t_state: np.ndarray,
    states: np.ndarray,
    planned_t: np.ndarray,
    planned_position: np.ndarray,
    goal: float,
    mode_names: Sequence[str],
    title: str = "",
) -> Path:
    """Write the demo figure.

    Parameters
    ----------
    path : str or Path
        Output PNG.
    t_command, command : ndarray
        Sample times (s) and commands (N) as streamed (zero-order hold).
    u_max : float
        Actuator bound (N), drawn as dashed lines.
    t_state, states : ndarray
        Times (s) and plant states ``[p, v, q1, q1', ...]`` from ``joint_states``.
    planned_t, planned_position : ndarray
        The planner's predicted position (m or rad) per sample.
    goal : float
        Target position (m or rad).
    mode_names : sequence of str
        One name per mode.
    title : str

    Returns
    -------
    Path
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True, constrained_layout=True)
    ax_u, ax_p, ax_q = axes
    if len(t_command):
        ax_u.step(
            np.append(t_command, t_command[-1] + (t_command[-1] - t_command[-2] if len(t_command) > 1 else 0.0)),
            np.append(command, command[-1]),
            where="post",
            lw=1.2,
            color="C0",
            label="command (streamed)",
        )
    for s in (1, -1):
        ax_u.axhline(s * u_max, ls="--", lw=0.8, color="grey")
    ax_u.set_ylabel("command u (N)")
    ax_u.legend(loc="upper right", fontsize=8)

    if len(planned_t):
        ax_p.plot(planned_t, planned_position, lw=3, alpha=0.35, color="C1", label="planned")
    if len(t_state):
        ax_p.plot(t_state, states[:, 0], lw=1.2, color="C0", label="plant (joint_states)")
    ax_p.axhline(goal, ls=":", lw=0.8, color="k", label=f"goal {goal:g}")
    ax_p.set_ylabel("position (m or rad)")
    ax_p.legend(loc="lower right", fontsize=8)

    if len(t_state):
        for i, name in enumerate(mode_names):
            ax_q.plot(t_state, states[:, 2 + 2 * i], lw=1.0, label=name)
    ax_q.axhline(0.0, lw=0.5, color="k")
    ax_q.set_ylabel("modal deflection")
    ax_q.set_xlabel("time since the first command (s)")
    if mode_names:
        ax_q.legend(loc="upper right", fontsize=8)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
