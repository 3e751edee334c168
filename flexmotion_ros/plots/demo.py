"""The closed-loop demo's figure: command, position, deflections and residual vibration after arrival (PNG, Agg).

The recorded part comes from the plant's ``joint_states``; the part after the
last recorded sample is the exact free response of the plant's last measured
state with zero input (:func:`continuation`, matrix exponentials), drawn
dashed and labelled as computed, so the residual vibration the move leaves is
visible for a few periods of the slowest mode.
"""

from __future__ import annotations

import ast
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from ..core.model.builders import BUILDERS
from ..core.model.modal_model import ModalModel
from ..core.simulation.exact import PiecewiseConstant, modal_amplitudes, simulate

#: Periods of the slowest mode shown after the last recorded sample.
PERIODS_AFTER = 3.0
#: Residual panel: the level (fraction of the move) that must be readable, drawn as a line.
RESIDUAL_MARK = 1e-3

_HEADER = re.compile(r"^#\s*flexmotion model ([\w-]+):\s*(.*)$")
_PAIR = re.compile(r"(\w+)=(\[[^\]]*\]|[^,]+)")


@dataclass(frozen=True)
class PhysicalMeaning:
    """What the rigid-body coordinate and each modal coordinate are, with units.

    Attributes
    ----------
    position : str
        Name of the rigid-body coordinate ``p`` (e.g. "centre of mass").
    deflections : tuple of str
        Name of each modal coordinate.
    unit : str or None
        Their common unit ("m"), or None when unknown.
    source : str
        Where the meaning comes from.
    """

    position: str
    deflections: tuple[str, ...]
    unit: str | None
    source: str

    @classmethod
    def unknown(cls, mode_names: Sequence[str]) -> PhysicalMeaning:
        """No physical map: ``p`` is the rigid-body coordinate, each ``q_i`` a modal coordinate, units unknown."""
        return cls(
            "rigid-body coordinate p",
            tuple(f"{n} (modal coordinate)" for n in mode_names),
            None,
            "no physical map in the parameter file",
        )


def _meaning_of_builder(kind: str, n_modes: int) -> tuple[str, tuple[str, ...]]:
    if kind == "crane":
        return "centre of mass (cart + payload)", ("payload offset from the cart",)
    if kind == "two_mass":
        return "centre of mass (both masses)", ("spring deflection x1 - x2",)
    return "centre of mass (all masses)", tuple(f"mode {i + 1}: largest spring deflection" for i in range(n_modes))


def meaning_from_file(path: str | Path, model: ModalModel) -> PhysicalMeaning:
    """The physical meaning of a parameter file's model, if the file says which builder made it.

    ``flexmotion model`` writes a header ``# flexmotion model KIND: name=value, ...``.
    The model is rebuilt from those values and used only if it equals the
    file's model (relative 1e-9 on ``b0``, ``omega``, ``b``, ``zeta``): an
    edited file falls back to :meth:`PhysicalMeaning.unknown`.

    Parameters
    ----------
    path : str or Path
        The ROS 2 parameter file.
    model : ModalModel
        The model read from it (nominal, before any plant model error).

    Returns
    -------
    PhysicalMeaning
    """
    try:
        lines = Path(path).read_text().splitlines()
    except OSError:
        return PhysicalMeaning.unknown(model.names)
    for line in lines:
        m = _HEADER.match(line.strip())
        if not m:
            continue
        kind = m.group(1).replace("-", "_")
        if kind not in BUILDERS:
            break
        try:
            kwargs = {k: ast.literal_eval(v.strip()) for k, v in _PAIR.findall(m.group(2))}
            built = BUILDERS[kind](**kwargs)
        except Exception:  # noqa: BLE001 -- any unreadable header means: meaning unknown
            break
        b = built.model
        same = len(b.omega) == len(model.omega) and all(
            np.allclose(np.asarray(x, float), np.asarray(y, float), rtol=1e-9, atol=1e-12)
            for x, y in ((b.b0, model.b0), (b.omega, model.omega), (b.b, model.b), (b.zeta, model.zeta))
        )
        if not same:
            break
        position, deflections = _meaning_of_builder(kind, len(model.omega))
        return PhysicalMeaning(position, deflections, "m", f"flexmotion model {m.group(1)} header")
    return PhysicalMeaning.unknown(model.names)


def continuation(model: ModalModel, t_last: float, x_last: np.ndarray, periods: float = PERIODS_AFTER, n: int = 800):
    """Exact free response (zero input) of ``model`` from the state ``x_last`` at ``t_last``.

    Parameters
    ----------
    model : ModalModel
        The plant's (true) model.
    t_last : float
        Time of the last measured state (s).
    x_last : ndarray
        That state ``[p, v, q1, q1', ...]``.
    periods : float
        Length of the window in periods of the slowest mode (``2 pi / omega_d``).
    n : int
        Number of points.

    Returns
    -------
    t : ndarray
        Times (s), from ``t_last``.
    X : ndarray, shape ``(n, 2 + 2 N)``
        States.
    """
    window = periods * 2.0 * math.pi / float(np.min(model.omega_d)) if len(model.omega) else 1.0
    tau = np.linspace(0.0, window, n)
    X = simulate(model, np.asarray(x_last, float), PiecewiseConstant(np.array([0.0]), np.array([])), tau)
    return t_last + tau, X


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
    *,
    model: ModalModel,
    start: float = 0.0,
    meaning: PhysicalMeaning | None = None,
    t_arrival: float | None = None,
    t_move_end: float | None = None,
    t_after: np.ndarray | None = None,
    states_after: np.ndarray | None = None,
) -> Figure:
    """Write the demo figure and return it.

    Four panels on one time axis that runs past the last recorded sample by
    the post-arrival window: the streamed command; the position ``p``
    (planned, measured, continued); each modal deflection; the residual
    (distance from the goal and each mode's vibration amplitude, as a
    fraction of the move, log scale).

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
        The planner's predicted position per sample (s, unit of ``p``).
    goal : float
        Target position (unit of ``p``).
    mode_names : sequence of str
        One name per mode.
    title : str
        Figure title.
    model : ModalModel
        The plant's model (modal amplitudes of the residual panel).
    start : float
        Start position (unit of ``p``); the move is ``|goal - start|``.
    meaning : PhysicalMeaning, optional
        Names and unit of the coordinates (default: unknown, "modal coordinate").
    t_arrival : float, optional
        Arrival time (s), marked by a vertical line (none when the plant did not arrive).
    t_move_end : float, optional
        End of the last command of the move (s), marked by a vertical line.
    t_after, states_after : ndarray, optional
        The exact zero-input continuation after the last recorded sample (:func:`continuation`).

    Returns
    -------
    matplotlib.figure.Figure
        The figure (saved to ``path``, left open for inspection).
    """
    meaning = meaning or PhysicalMeaning.unknown(mode_names)
    unit = f" ({meaning.unit})" if meaning.unit else " (unit of the model)"
    move = abs(goal - start) or 1.0
    t_state = np.asarray(t_state, float)
    states = np.asarray(states, float).reshape(len(t_state), -1) if len(t_state) else np.empty((0, 2))
    has_after = t_after is not None and states_after is not None and len(t_after) > 0
    t_end = float(t_after[-1]) if has_after else (float(t_state[-1]) if len(t_state) else 1.0)
    after_label = "computed: zero-input free response"

    fig, axes = plt.subplots(4, 1, figsize=(12, 11), sharex=True, constrained_layout=True)
    ax_u, ax_p, ax_q, ax_r = axes
    if len(t_command):
        dt = t_command[-1] - t_command[-2] if len(t_command) > 1 else 0.0
        ax_u.step(
            np.append(t_command, t_command[-1] + dt),
            np.append(command, command[-1]),
            where="post",
            lw=1.2,
            color="C0",
            label="command (streamed, zero-order hold)",
        )
        if has_after:
            ax_u.plot(
                [t_command[-1] + dt, t_end], [0.0, 0.0], ls="--", lw=1.2, color="C0", label="zero input (computed)"
            )
    ax_u.axhline(u_max, ls="--", lw=0.8, color="grey", label=f"+/- u_max = {u_max:g} N")
    ax_u.axhline(-u_max, ls="--", lw=0.8, color="grey")
    ax_u.set_ylim(-1.35 * u_max, 1.35 * u_max)
    ax_u.set_ylabel("command u (N)")

    p_name = meaning.position
    if len(planned_t):
        ax_p.plot(planned_t, planned_position, lw=3, alpha=0.35, color="C1", label=f"planned {p_name}")
    if len(t_state):
        ax_p.plot(t_state, states[:, 0], lw=1.2, color="C0", label=f"plant {p_name} (joint_states)")
    if has_after:
        ax_p.plot(t_after, states_after[:, 0], ls="--", lw=1.2, color="C0", label=after_label)
    ax_p.axhline(goal, ls=":", lw=0.8, color="k", label=f"goal {goal:g}{unit}")
    ax_p.set_ylabel(f"{p_name}\np{unit}")

    for i, name in enumerate(meaning.deflections[: len(mode_names)]):
        color = f"C{i % 10}"
        if len(t_state):
            ax_q.plot(t_state, states[:, 2 + 2 * i], lw=1.0, color=color, label=f"{name} (joint_states)")
        if has_after:
            ax_q.plot(t_after, states_after[:, 2 + 2 * i], ls="--", lw=1.0, color=color, label=f"{name}, {after_label}")
    if has_after:
        ax_q.annotate(
            "shaded: after the last plant sample, the exact free response\n"
            "of its last measured state with zero input (computed, not measured)",
            xy=(float(t_after[0]), 0.0),
            xycoords=("data", "axes fraction"),
            xytext=(4, 4),
            textcoords="offset points",
            fontsize=7,
            color="0.3",
        )
    ax_q.axhline(0.0, lw=0.5, color="k")
    ax_q.set_ylabel(("deflection" if meaning.unit else "modal coordinate") + unit)

    floor = 1e-16
    peak = RESIDUAL_MARK
    lowest = RESIDUAL_MARK
    for t, X, ls, suffix in ((t_state, states, "-", " (joint_states)"), (t_after, states_after, "--", " (computed)")):
        if t is None or X is None or not len(t):
            continue
        ep = np.abs(X[:, 0] - goal) / move
        amp = np.atleast_2d(modal_amplitudes(model, X)) / move
        series = [("|p - goal|", ep, "k")] + [
            (f"{n} amplitude" + (f" ({what})" if meaning.unit else ""), amp[:, i], f"C{i % 10}")
            for i, (n, what) in enumerate(zip(mode_names, meaning.deflections))
        ]
        for name, v, color in series:
            v = np.maximum(v, floor)
            ax_r.semilogy(t, v, ls=ls, lw=1.0, color=color, label=name + suffix)
            above = v[v > floor]  # a zero (e.g. the rest state at t = 0) does not stretch the axis
            peak = max(peak, float(np.max(v)))
            lowest = min(lowest, float(np.min(above))) if above.size else lowest
    ax_r.axhline(RESIDUAL_MARK, ls=":", lw=0.8, color="grey", label=f"{RESIDUAL_MARK:g} of the move")
    ax_r.set_ylim(max(floor, min(lowest / 3.0, 1e-6)), 3.0 * peak)
    ax_r.set_ylabel("residual / move (-)")
    ax_r.set_xlabel("time since the first command (s)")

    for ax in axes:
        if has_after:
            ax.axvspan(float(t_after[0]), t_end, color="0.93", zorder=0)
        if t_move_end is not None and t_move_end != t_arrival:
            ax.axvline(t_move_end, lw=0.8, color="C2", ls="-.", label="end of the last command" if ax is ax_p else None)
        if t_arrival is not None:
            ax.axvline(t_arrival, lw=0.8, color="C3", ls="-.", label="arrival" if ax is ax_p else None)
        ax.grid(True, lw=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    ax_r.set_xlim(0.0, t_end)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.savefig(path, dpi=110)
    return fig
