"""Figure of a structure design: move time over the parameter (a map for two), optimum marked."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from ..core.design.optimize import DesignResult
from ..core.design.problem import rigid_bound
from ..core.design.space import PARAMETER_RANGES


def _label(result: DesignResult, name: str) -> str:
    unit = PARAMETER_RANGES[result.problem.builder][name.split("[")[0]][4]
    return f"{name} ({unit})" if unit else name


def plot_design(result: DesignResult, path: str) -> Figure:
    """Write the figure to ``path`` (PNG) and return it.

    One parameter: the weighted move time at every evaluated point (grid and
    refine), each task's time for a set of tasks, infeasible points as
    crosses, the start and the optimum.  Two parameters: a colour map of the
    grid with the refine points; three: the map over the first two at the
    optimal third's nearest grid value.

    Failed or infeasible points are drawn on top of everything (black
    crosses; in one dimension on a rug along the bottom axis, with their
    values in the legend) so the optimum marker cannot hide them; the
    parameter bounds are two vertical lines, not a shading.

    Parameters
    ----------
    result : DesignResult
        The design to draw.
    path : str
        Output PNG.

    Returns
    -------
    matplotlib.figure.Figure
    """
    pb = result.problem
    names = pb.names
    fig, ax = plt.subplots(figsize=(10.0, 4.8))
    evs = result.evaluations
    best, start = result.best, result.start
    title = f"{pb.builder}: {pb.config.method} move time, goal " + ", ".join(f"{t.gamma:g}" for t in pb.tasks)
    if len(names) == 1:
        par = pb.parameters[0]
        inside = [e for e in evs if par.lower <= e.values[0] <= par.upper]  # the start may lie outside
        ok = sorted((e for e in inside if e.feasible), key=lambda e: e.values[0])
        x = np.array([e.values[0] for e in ok])
        ax.plot(
            x,
            [e.objective for e in ok],
            ".-",
            color="C0",
            lw=1.2,
            ms=4,
            label="weighted move time" if len(pb.tasks) > 1 else "move time",
        )
        ax.plot(x, [rigid_bound(pb, e.values) for e in ok], "--", color="0.4", lw=0.8, label="rigid-body bound")
        if len(pb.tasks) > 1:
            for i, t in enumerate(pb.tasks):
                ax.plot(
                    x,
                    [e.times[i] for e in ok],
                    "-",
                    lw=0.8,
                    alpha=0.7,
                    label=f"goal {t.gamma:g} alone (weight {t.weight:g})",
                )
        bad = sorted(e.values[0] for e in inside if not e.feasible)
        if bad:
            shown = ", ".join(f"{v:.4g}" for v in bad[:4]) + (", ..." if len(bad) > 4 else "")
            for v in bad:
                ax.axvline(v, color="k", lw=0.6, ls=":", zorder=7)
            ax.plot(
                bad,
                [0.04] * len(bad),
                "x",
                color="k",
                ms=9,
                mew=2.0,
                transform=ax.get_xaxis_transform(),  # x in data, y in axes fraction: a rug above the axis
                clip_on=False,
                zorder=8,
                label=f"infeasible / failed ({len(bad)}): {names[0]} = {shown}",
            )
        for v in (par.lower, par.upper):
            ax.axvline(v, color="0.5", lw=0.8, ls="-.", zorder=1)
        ax.plot([], [], color="0.5", lw=0.8, ls="-.", label=f"bounds [{par.lower:g}, {par.upper:g}]")
        if bad and ok:  # room under the lowest point for the rug of failed points
            ys = [e.objective for e in ok] + [rigid_bound(pb, e.values) for e in ok]
            lo, hi = min(ys), max(ys)
            ax.set_ylim(lo - 0.2 * (hi - lo or 1.0), hi + 0.05 * (hi - lo or 1.0))
        if result.start_evaluation.feasible:
            ax.plot([start[names[0]]], [result.start_evaluation.objective], "s", color="C2", ms=7, label="start")
        ax.plot(
            [best[names[0]]],
            [result.objective],
            "*",
            color="C3",
            ms=14,
            label=f"optimum {names[0]} = {best[names[0]]:.6g}: {result.objective:.6f} s",
        )
        if par.scale == "log":
            ax.set_xscale("log")
        ax.set_xlabel(_label(result, names[0]))
        ax.set_ylabel("move time (s)")
        ax.grid(True, alpha=0.3)
    else:
        xa, ya = result.grid_axes[0], result.grid_axes[1]
        J = result.grid_objective
        if J.ndim == 3:
            k = int(np.argmin(np.abs(result.grid_axes[2] - best[names[2]])))
            J = J[:, :, k]
            title += f"  ({names[2]} = {result.grid_axes[2][k]:.4g})"
        Z = np.where(np.isfinite(J), J, np.nan).T
        # smooth colours inside the bounds; cells only if some points failed (gouraud cannot skip them)
        shading = "gouraud" if np.isfinite(Z).all() else "nearest"
        mesh = ax.pcolormesh(xa, ya, Z, shading=shading, cmap="viridis")
        ax.set_xlim(pb.parameters[0].lower, pb.parameters[0].upper)
        ax.set_ylim(pb.parameters[1].lower, pb.parameters[1].upper)
        fig.colorbar(mesh, ax=ax, label="move time (s)")
        if np.isfinite(Z).sum() >= 4 and np.nanmax(Z) > np.nanmin(Z):
            ax.contour(xa, ya, Z, levels=10, colors="w", linewidths=0.5, alpha=0.6)
        bad = np.argwhere(~np.isfinite(J))
        if bad.size:
            ax.plot(
                xa[bad[:, 0]],
                ya[bad[:, 1]],
                "x",
                color="m",
                ms=8,
                mew=2.0,
                zorder=8,
                clip_on=False,
                label=f"infeasible / failed ({len(bad)})",
            )
        on_grid = {(float(a), float(b)) for a in xa for b in ya}
        refine = [e for e in evs if e.feasible and len(names) == 2 and tuple(e.values) not in on_grid]
        if refine:
            ax.plot(
                [e.values[0] for e in refine],
                [e.values[1] for e in refine],
                ".",
                color="w",
                ms=3,
                label="refine",
                clip_on=False,
            )
        ax.plot([start[names[0]]], [start[names[1]]], "s", color="C2", ms=7, label="start", clip_on=False, zorder=5)
        ax.plot(
            [best[names[0]]],
            [best[names[1]]],
            "*",
            color="C3",
            ms=15,
            clip_on=False,
            zorder=6,
            label=f"optimum: {result.objective:.6f} s",
        )
        for axis, p in zip("xy", pb.parameters[:2]):
            if p.scale == "log":
                getattr(ax, f"set_{axis}scale")("log")
        ax.set_xlabel(_label(result, names[0]))
        ax.set_ylabel(_label(result, names[1]))
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02 if len(names) == 1 else 1.25, 1.0))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return fig
