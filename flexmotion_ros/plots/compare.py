"""Figure of ``flexmotion compare``: residual vibration versus frequency ratio, one curve per method."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np


def plot_sensitivity(
    curves: dict[str, tuple[np.ndarray, np.ndarray]],
    path: str,
    tolerance: float | None = None,
    band: float | None = None,
    title: str = "",
) -> None:
    """Write the sensitivity curves to ``path`` (PNG).

    Parameters
    ----------
    curves : dict
        Method name -> (frequency ratios, residual vibration in percent of a full step, worst mode).
    tolerance : float, optional
        Vibration tolerance (percent), drawn as a horizontal line.
    band : float, optional
        Relative frequency error, shaded as ``[1 - band, 1 + band]``.
    """
    fig, ax = plt.subplots(figsize=(9.0, 4.8))
    floor = 1e-3  # percent: the nominal zeros of exact methods would be -inf on the log scale
    peak = 0.0
    for i, (name, (r, v)) in enumerate(curves.items()):
        style = "-" if i < 10 else "--"
        ax.semilogy(r, np.maximum(v, floor), style, lw=1.3, label=name)
        peak = max(peak, float(np.max(v)))
    if band is not None:
        ax.axvspan(1.0 - band, 1.0 + band, color="0.9", zorder=0, label=f"+/-{100 * band:g} % frequency error")
    if tolerance is not None:
        ax.axhline(tolerance, color="k", lw=0.8, ls=":", label=f"{tolerance:g} % tolerance")
    ax.set_ylim(floor, max(2.0 * peak, 10.0 * (tolerance or 1.0)))
    ax.set_xlabel("frequency ratio  omega_true / omega_model (all modes)")
    ax.set_ylabel("residual vibration (% of a full step, worst mode)")
    ax.set_title(title or "Sensitivity to frequency error")
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
