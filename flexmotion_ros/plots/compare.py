"""Figure of ``flexmotion compare``: residual vibration versus frequency ratio, one curve per method."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

#: Colours (tab10 then a few more) and line styles; each method gets its own (colour, style) pair.
COLOURS = [f"C{i}" for i in range(10)] + ["#000000", "#b8860b", "#4b0082", "#2f4f4f", "#ff1493"]
STYLES = ["-", "--", "-.", ":"]


def method_styles(names: list[str]) -> dict[str, tuple[str, str]]:
    """A distinct ``(colour, line style)`` pair per method name, in order.

    Consecutive methods differ in both colour and style, so a curve lying on
    top of another stays visible.
    """
    # 15 colours and 4 styles are coprime: the first 60 pairs are all different
    return {name: (COLOURS[i % len(COLOURS)], STYLES[i % len(STYLES)]) for i, name in enumerate(names)}


def plot_sensitivity(
    curves: dict[str, tuple[np.ndarray, np.ndarray]],
    path: str,
    tolerance: float | None = None,
    band: float | None = None,
    title: str = "",
    durations: dict[str, float] | None = None,
) -> Figure:
    """Write the sensitivity curves to ``path`` (PNG) and return the figure.

    Parameters
    ----------
    curves : dict
        Method name -> (frequency ratios (-), residual vibration in percent of a full step, worst mode).
    path : str
        Output PNG.
    tolerance : float, optional
        Vibration tolerance (percent), drawn as a horizontal line.
    band : float, optional
        Relative frequency error, shaded as ``[1 - band, 1 + band]``.
    title : str
        Figure title.
    durations : dict, optional
        Method name -> move duration (s), written next to the name in the legend.

    Returns
    -------
    matplotlib.figure.Figure
    """
    durations = durations or {}
    fig, ax = plt.subplots(figsize=(10.5, 5.2))
    floor = 1e-3  # percent: the nominal zeros of exact methods would be -inf on the log scale
    peak = 0.0
    styles = method_styles(list(curves))
    width = max((len(n) for n in curves), default=0)
    for name, (r, v) in curves.items():
        colour, style = styles[name]
        label = f"{name:<{width}s}  {durations[name]:7.3f} s" if name in durations else name
        ax.semilogy(r, np.maximum(v, floor), ls=style, color=colour, lw=1.4, label=label)
        peak = max(peak, float(np.max(v)))
    if band is not None:
        ax.axvspan(1.0 - band, 1.0 + band, color="0.92", zorder=0, label=f"+/-{100 * band:g} % frequency error")
    if tolerance is not None:
        ax.axhline(tolerance, color="k", lw=0.8, ls=(0, (1, 3)), label=f"{tolerance:g} % tolerance")
    ax.set_ylim(floor, max(2.0 * peak, 10.0 * (tolerance or 1.0)))
    ax.set_xlabel("frequency ratio  omega_true / omega_model, all modes (-)")
    ax.set_ylabel("residual vibration (% of a u_max step, worst mode)")
    ax.set_title(title or "Sensitivity to frequency error")
    ax.grid(True, lw=0.3)
    legend = ax.legend(
        fontsize=7,
        loc="center left",
        bbox_to_anchor=(1.01, 0.5),
        title="method, move duration" if durations else "method",
        title_fontsize=7,
        prop={"family": "monospace", "size": 7},
    )
    legend.get_title().set_family("monospace")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    return fig
