"""Figures of a trade study: its Pareto fronts, and a trade row against the varied keys.

On the Agg canvas, outside pyplot; each takes ``ax=None`` and returns the figure.
"""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from starsense.analysis.trade.study import PARETO, TradeStudy
from starsense.plotting.figure import figure_and_axes

__all__ = ["FIGURE_STEMS", "front_figure", "row_figure", "trade_figures"]

#: the file stems of :func:`trade_figures`, in order: each Pareto front, then two rows
FIGURE_STEMS = (*(f"pareto_{name}" for name in PARETO), "nea_cross", "fastest_99")

_LABELS = {
    "nea_cross": "NEA cross-boresight, sky median (arcsec)",
    "nea_roll": "NEA roll, sky median (arcsec)",
    "fastest_99": "fastest rate keeping 99 % lost in space (deg/s)",
    "aperture_m": "aperture (mm)",
}
_SCALE = {"aperture_m": 1e3}


def front_figure(study: TradeStudy, front: str, ax: Axes | None = None) -> Figure:
    """Draw one Pareto front: every design, the optimal ones joined, capped values marked.

    The fronts are those of :data:`~starsense.analysis.trade.study.PARETO`.

    Parameters
    ----------
    study : TradeStudy
    front : str
        A key of ``PARETO``.
    ax : Axes, optional

    Returns
    -------
    Figure
    """
    fig, ax = figure_and_axes(ax, 7.0, 4.8)
    (ky, _), (kx, _) = PARETO[front]
    x = np.array([_v(r.value(kx)) * _SCALE.get(kx, 1.0) for r in study.rows])
    y = np.array([_v(r.value(ky)) * _SCALE.get(ky, 1.0) for r in study.rows])
    on = np.array([bool((r.pareto or {}).get(front)) for r in study.rows])
    capped = np.array([bool(r.rows and kx in r.rows and r.rows[kx]["capped"]) for r in study.rows])
    ax.plot(x[~on], y[~on], "o", mfc="none", color="0.5", label="design")
    order = np.argsort(x[on])
    ax.plot(x[on][order], y[on][order], "o-", color="C3", label="Pareto-optimal")
    if capped.any():
        ax.plot(x[capped], y[capped], "^", mfc="none", color="k", ms=9, label="at the grid's end")
    for r, xi, yi, o in zip(study.rows, x, y, on, strict=True):
        if o and np.isfinite(xi) and np.isfinite(yi):
            ax.annotate(
                str(r.index), (xi, yi), fontsize=7, xytext=(3, 3), textcoords="offset points"
            )
    ax.set_xlabel(_LABELS.get(kx, kx))
    ax.set_ylabel(_LABELS.get(ky, ky))
    ax.set_yscale("log")
    ax.set_title(f"trade: {ky} against {kx} ({len(study.rows)} designs)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def row_figure(study: TradeStudy, row: str = "nea_cross", ax: Axes | None = None) -> Figure:
    """Draw a trade row against the first varied key, one line per value of the second.

    Parameters
    ----------
    study : TradeStudy
    row : str
        A trade row key (``nea_cross``, ``limiting_magnitude``, ...).
    ax : Axes, optional

    Returns
    -------
    Figure
    """
    fig, ax = figure_and_axes(ax, 7.0, 4.8)
    keys = study.keys
    if not keys:
        return fig
    groups: dict = {}
    for r in study.rows:
        tag = tuple((k, r.values[k]) for k in keys[1:2])
        groups.setdefault(tag, []).append((r.values[keys[0]], _v(r.value(row))))
    for tag, pts in groups.items():
        pts.sort()
        label = ", ".join(f"{k} = {v:g}" for k, v in tag) or None
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", label=label)
    ax.set_xlabel(keys[0])
    ax.set_ylabel(_LABELS.get(row, row))
    ax.grid(True, alpha=0.3)
    if len(groups) > 1:
        ax.legend(fontsize=8)
    return fig


def trade_figures(study: TradeStudy) -> dict[str, Figure]:
    """Return the trade's figures by file stem: each Pareto front and NEA against the keys."""
    out = {f"pareto_{name}": front_figure(study, name) for name in PARETO}
    out["nea_cross"] = row_figure(study, "nea_cross")
    out["fastest_99"] = row_figure(study, "fastest_99")
    return out


def _v(value) -> float:
    return float("nan") if value is None else float(value)
