"""Figures of the slew tolerance (Dzamba & Enright 2014, Figs. 9-10).

On the Agg canvas, outside pyplot; each takes ``ax=None`` and returns the figure.
"""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib as mpl
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from starsense.analysis.slew import SlewResult
from starsense.plotting.figure import figure_and_axes

__all__ = ["intensity_figure", "tolerance_figure"]


def tolerance_figure(results: Sequence[SlewResult], ax: Axes | None = None) -> Figure:
    """Draw the tolerable cross-axis slew rate against magnitude, one line per result (Fig. 10).

    Open triangles mark magnitudes detected at every rate simulated.
    """
    fig, ax = figure_and_axes(ax, 7.5, 4.8)
    for res, style in zip(results, ("o-", "s--", "^-."), strict=False):
        tol = np.array([np.nan if r is None else r for r in res.tolerable_rate_deg_s])
        ax.plot(res.magnitudes, tol, style, label=f"{res.model} model", ms=4)
        capped = np.asarray(res.capped)
        if capped.any():
            ax.plot(res.magnitudes[capped], tol[capped], "k^", ms=6, mfc="none")
    ax.set_xlabel("stellar magnitude m")
    ax.set_ylabel("tolerable cross-axis slew rate (deg/s)")
    name = results[0].sensor_name if results else ""
    ax.set_title(f"{name}: fastest slew at which a star is still detected (cf. paper Fig. 10)")
    ax.grid(True, alpha=0.3)
    ax.legend(title="open triangles: detected at every rate simulated", fontsize=8)
    return fig


def intensity_figure(res: SlewResult, ax: Axes | None = None) -> Figure:
    """Draw the mean integrated intensity of detections against slew rate (Fig. 9)."""
    fig, ax = figure_and_axes(ax, 8.5, 4.8)
    cmap = mpl.colormaps["viridis"]
    n = len(res.magnitudes)
    step = max(1, n // 8)
    for k, i in enumerate(range(0, n, step)):
        ax.plot(
            res.rates_deg_s,
            res.mean_intensity_counts[i],
            "-",
            color=cmap(k / max(1, (n - 1) // step)),
            label=f"m = {res.magnitudes[i]:.2f}",
        )
    ax.axhline(res.threshold_counts, color="k", ls=":", lw=1, label="integrated threshold")
    ax.set_yscale("log")
    ax.set_xlabel("cross-axis slew rate (deg/s)")
    ax.set_ylabel("integrated intensity of detections (counts)")
    ax.set_title(f"{res.sensor_name}, {res.model} model: intensity against rate (cf. paper Fig. 9)")
    ax.grid(True, which="both", alpha=0.3)
    fig.legend(loc="outside right upper", fontsize=8)
    return fig
