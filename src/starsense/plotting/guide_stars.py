"""Figures of the guide-star analysis (Lin et al. 2024), on the Agg canvas outside pyplot.

* :func:`triangle_ratio_figure` - probability of accuracy better than the threshold against the
  average FOV ratio of the guide stars' triangles, one panel per sigma, one line per
  configuration (the paper's Figs. 5 and 6).
* :func:`area_layout_figure` - the attitude-determination areas in the focal plane, with the
  science square and the lens circle, in degrees of field angle (the paper's Fig. 1).

Each takes ``ax=`` (draw into existing axes) or creates its own figure, and returns the figure.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import matplotlib
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from numpy.typing import ArrayLike, NDArray

from starsense.analysis.guide_stars import GuideStarTable
from starsense.geometry.areas import AreaLayout, polygon_centroid
from starsense.plotting.figure import new_figure
from starsense.units import ARCSEC

__all__ = ["CONFIG_LABELS", "area_layout_figure", "field_angle_deg", "triangle_ratio_figure"]

CONFIG_LABELS = {
    "one": "one area (1)",
    "two_adjacent": "two adjacent (1, 2)",
    "two_symmetric": "two symmetric (1, 3)",
    "three": "three (1, 2, 3)",
    "four": "four (1-4)",
}
"""Legend labels of the configurations of Lin et al. 2024, Table 1."""
_MARKERS = ("v", "s", "D", "^", "o")


def field_angle_deg(xy: ArrayLike) -> NDArray[np.float64]:
    """Return the field angle along each axis of tangent-plane points: ``atan(x)``, deg.

    Parameters
    ----------
    xy : array_like, shape (..., 2)
        Tangent-plane points.

    Returns
    -------
    ndarray, shape (..., 2)
        Field angles, deg.
    """
    return np.degrees(np.arctan(np.asarray(xy, dtype=np.float64)))


def triangle_ratio_figure(
    table: GuideStarTable,
    *,
    sigmas_rad: Sequence[float] = (0.1 * ARCSEC, 0.3 * ARCSEC),
    n_bins: int = 10,
    ax: Sequence[Axes] | None = None,
) -> Figure:
    """Plot the probability of accuracy better than the threshold against the triangle ratio.

    One panel per sigma, one line per configuration of ``table``; each point is one of
    ``n_bins`` equal-count bins of the trials' average FOV ratio of the triangles
    (:meth:`GuideStarTable.by_triangle_ratio`). Lin et al. 2024, Figs. 5 (sigma = 0.1 arcsec)
    and 6 (0.3 arcsec).

    Parameters
    ----------
    table : GuideStarTable
        The simulated Table 1, with these sigmas.
    sigmas_rad : sequence of float
        Sigmas of the panels, rad.
    n_bins : int
        Equal-count bins per line.
    ax : sequence of Axes or None
        One axes per sigma to draw into (default: a new figure with a row of panels).

    Returns
    -------
    Figure
    """
    if ax is None:
        fig = new_figure(10.0, 4.3)
        axes = fig.subplots(1, len(sigmas_rad), sharey=True, squeeze=False)[0]
    else:
        axes = list(ax)
        fig = axes[0].figure
    for panel, sigma, fig_no in zip(axes, sigmas_rad, ("5", "6", "", ""), strict=False):
        for k, config in enumerate(table.probability_mc):
            ratio, prob, _count = table.by_triangle_ratio(config, sigma, n_bins)
            panel.plot(
                ratio,
                100.0 * prob,
                marker=_MARKERS[k % len(_MARKERS)],
                ms=4,
                lw=1.2,
                label=CONFIG_LABELS.get(config, config),
            )
        panel.set_xlabel("average FOV ratio of the guide stars' triangles")
        panel.set_title(
            f"σ = {sigma / ARCSEC:g}″" + (f" (cf. paper Fig. {fig_no})" if fig_no else ""),
            fontsize=10,
        )
        panel.set_ylim(0, 101)
        panel.grid(True, alpha=0.3)
    axes[0].set_ylabel(f"P(accuracy < {table.threshold_arcsec:g}″) (%)")
    axes[0].legend(fontsize=8, loc="lower right")  # the lower right of sigma = 0.1 is empty
    return fig


def _draw_frame(ax: Axes, layout: AreaLayout) -> None:
    """Draw the lens circle and the science square of ``layout``, when it has them."""
    if layout.lens_radius is not None:
        t = np.linspace(0.0, 2.0 * math.pi, 721)
        circle = layout.lens_radius * np.stack([np.cos(t), np.sin(t)], axis=-1)
        c = field_angle_deg(circle)
        ax.plot(c[:, 0], c[:, 1], "k--", lw=1.0, label="lens circle")
    if layout.science_half is not None:
        h = layout.science_half
        sq = field_angle_deg([[-h, -h], [h, -h], [h, h], [-h, h], [-h, -h]])
        ax.fill(sq[:, 0], sq[:, 1], color="0.88", ec="0.3", lw=1.0, label="science detector")
        ax.text(0.0, 0.0, "science", ha="center", va="center", fontsize=9, color="0.3")


def area_layout_figure(layout: AreaLayout, title: str, ax: Axes | None = None) -> Figure:
    """Draw the attitude-determination areas of ``layout`` in the focal plane, deg of field angle.

    Parameters
    ----------
    layout : starsense.geometry.areas.AreaLayout
        Areas in tangent-plane coordinates; the science square (``science_half``) and the lens
        circle (``lens_radius``) are drawn when the layout has them.
    title : str
        The axes' title.
    ax : Axes or None
        Axes to draw into (default: a new figure).

    Returns
    -------
    Figure
    """
    if ax is None:
        fig = new_figure(5.4, 5.0)
        ax = fig.add_subplot()
    else:
        fig = ax.figure
    _draw_frame(ax, layout)
    cmap = matplotlib.colormaps["tab10"]
    for k, area in enumerate(layout.areas):
        v = field_angle_deg(area.vertices)
        ax.fill(v[:, 0], v[:, 1], color=cmap(k % 10), alpha=0.55, ec=cmap(k % 10), lw=1.0)
        cx, cy = polygon_centroid(v)
        ax.text(cx, cy, area.name, ha="center", va="center", fontsize=10, fontweight="bold")
    ax.set_aspect("equal")
    ax.set_xlabel("field angle along +x (deg)")
    ax.set_ylabel("field angle along +y (deg)")
    ax.set_title(title, fontsize=9)
    ax.grid(True, alpha=0.3)
    if layout.lens_radius is not None or layout.science_half is not None:
        ax.legend(fontsize=7, loc="upper right", framealpha=0.8)
    return fig
