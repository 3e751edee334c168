"""Figure of ``flexmotion identify``: measured and fitted response, residuals, spectrum with the modes."""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from ..core.identification.data import SensorOutput
from ..core.identification.response import OUTPUT_UNITS, OutputKind
from ..core.identification.result import IdentificationResult


def amplitude_spectrum(x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies (rad/s, DC dropped) and one-sided amplitude ``2 |FFT(x)| / N`` (unit of ``x``)."""
    n = x.size
    X = np.fft.rfft(x)
    w = 2.0 * np.pi * np.fft.rfftfreq(n, dt)
    return w[1:], 2.0 * np.abs(X[1:]) / n


def plot_identification(
    time,
    u,
    outputs: Sequence[SensorOutput],
    result: IdentificationResult,
    path: str,
    output_index: int = 0,
) -> Figure:
    """Write the identification figure to ``path`` (PNG) and return it.

    Panels: the command (N); measured and fitted output; the residual with
    the estimated noise band (+-2 sigma); the amplitude spectra of the
    measured output, the fit and the residual, with each identified mode's
    frequency (line) and 95 % interval (shaded).

    Parameters
    ----------
    time, u : array_like
        Sample times (s) and command (N).
    outputs : sequence of SensorOutput
        The measured outputs given to the identification.
    result : IdentificationResult
    path : str
        Output PNG.
    output_index : int
        Which output to draw.
    """
    t = np.asarray(time, dtype=float)
    y = np.asarray(outputs[output_index].samples, dtype=float)
    fit = result.fitted[output_index]
    info = result.outputs[output_index]
    kind = OutputKind(info.kind)
    unit = OUTPUT_UNITS[kind]
    resid = y - fit
    fig, axes = plt.subplots(4, 1, figsize=(10.5, 11.0), gridspec_kw={"height_ratios": [1, 2, 1.3, 2]})
    ax_u, ax_y, ax_r, ax_s = axes
    ax_u.step(t, u, where="post", color="C7", lw=0.9, label="command")
    ax_u.set_xlabel("time (s)")
    ax_u.set_ylabel("command (N)")
    ax_u.legend(loc="upper right")
    ax_y.plot(t, y, ".", ms=2.0, color="C0", label=f"measured {info.name}")
    ax_y.plot(t, fit, "-", lw=1.2, color="C3", label=f"fitted ({result.n_modes} mode(s)), {info.fit_percent:.2f} %")
    ax_y.set_xlabel("time (s)")
    ax_y.set_ylabel(f"{kind} ({unit})")
    ax_y.legend(loc="best")
    ax_r.plot(t, resid, lw=0.6, color="C2", label=f"residual (rms {info.fit_rms:.3g} {unit})")
    band = 2.0 * info.noise_std
    ax_r.axhspan(-band, band, color="C2", alpha=0.12, label=f"+-2 noise std ({info.noise_std:.3g} {unit})")
    ax_r.set_xlabel("time (s)")
    ax_r.set_ylabel(f"residual ({unit})")
    ax_r.legend(loc="upper right")
    dt = result.dt
    for x, style, label in (
        (y - y.mean(), "C0", "measured"),
        (fit - fit.mean(), "C3", "fitted"),
        (resid, "C2", "residual"),
    ):
        w, a = amplitude_spectrum(x, dt)
        ax_s.loglog(w, np.maximum(a, 1e-300), color=style, lw=0.8 if label != "fitted" else 1.2, label=label)
    for i, m in enumerate(result.modes):
        lo, hi = m.omega.interval
        _, zhi = m.zeta.interval
        ax_s.axvspan(lo, hi, color="C1", alpha=0.25)
        ax_s.axvline(
            m.omega.value,
            color="C1",
            ls="--",
            lw=1.0,
            label=(
                f"mode {i}: omega {m.omega.value:.6g} +- {hi - m.omega.value:.2g} rad/s, "
                f"zeta {m.zeta.value:.4g} +- {zhi - m.zeta.value:.2g} (95 %; shaded)"
            ),
        )
    ax_s.set_xlabel("frequency (rad/s)")
    ax_s.set_ylabel(f"amplitude ({unit})")
    ax_s.legend(loc="lower left", fontsize=8)
    ax_s.grid(True, which="both", alpha=0.3)
    fig.suptitle(
        f"identification: b0 {result.b0.value:.5g} +- {result.b0.std_error:.2g}, c {result.c.value:.3g} 1/s; "
        f"{result.samples} samples, {result.solve_time_s * 1e3:.0f} ms"
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return fig
