"""Figures of the availability analysis (Dzamba & Enright 2014, sec. 1, 3.1, 4).

All on the Agg canvas, outside pyplot; each takes ``ax=None`` and returns the figure.

* :func:`sky_map_figure`: stars in the field per boresight, Mollweide projection, with the
  galactic plane (Figs. 4, 5, 14). Right ascension follows the astronomical convention: it
  increases to the **left** (east left, the sky seen from inside the celestial sphere), with
  0 h at the centre of the map and 12 h at both edges.
* :func:`static_curve_figure`: availability against the detection threshold m_t (Fig. 6).
* :func:`dynamic_figure`: spatial dynamic availability against slew rate (Fig. 11).
* :func:`track_figure`, :func:`track_nmin_figure`: along-track availability against track
  inclination (Figs. 16-17).
* :func:`threshold_figure`: m_t against slew rate (Fig. 10 read sideways).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from pathlib import Path

import matplotlib as mpl
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from starsense.analysis.availability import (
    N_MIN_LOST_IN_SPACE,
    N_MIN_TRACKING,
    DynamicAvailability,
    StaticAvailability,
    ThresholdCurve,
    TrackAvailability,
)
from starsense.geometry.projection import radec_to_vectors, vectors_to_radec
from starsense.plotting.figure import figure_and_axes, new_figure, save_png
from starsense.units import DEG, RAD_TO_DEG

__all__ = [
    "dynamic_figure",
    "galactic_plane_radec",
    "save_figure",
    "sky_map_figure",
    "static_curve_figure",
    "threshold_figure",
    "track_figure",
    "track_nmin_figure",
]


def save_figure(fig: Figure, path: Path | str, dpi: int = 110) -> Path:
    """Write a figure as PNG atomically (creating the folder) and return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return save_png(fig, path, dpi)


def _map_x(ra_rad: ArrayLike) -> NDArray[np.float64]:
    """Return the Mollweide abscissa of a right ascension: RA increases to the left."""
    x = -np.asarray(ra_rad, dtype=float)
    return (x + np.pi) % (2.0 * np.pi) - np.pi


@functools.lru_cache(maxsize=1)
def galactic_plane_radec(n: int = 721) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return ICRS (RA, Dec), rad, of the galactic equator b = 0, l = 0 ... 360 deg (astropy)."""
    # astropy (a heavy library, lazy as everywhere): the noqa is needed because plotting/ lifts
    # TID253 for matplotlib, and with it ruff's allow-list of PLC0415
    import astropy.units as u  # noqa: PLC0415
    from astropy.coordinates import SkyCoord  # noqa: PLC0415

    plane = SkyCoord(
        l=np.linspace(0.0, 360.0, n) * u.deg, b=np.zeros(n) * u.deg, frame="galactic"
    ).icrs
    return plane.ra.rad, plane.dec.rad


def _broken_line(ra: ArrayLike, dec: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return map abscissae with NaN inserted where the line wraps around the map's edge."""
    x = _map_x(ra)
    jumps = np.flatnonzero(np.abs(np.diff(x)) > np.pi) + 1
    return np.insert(x, jumps, np.nan), np.insert(np.asarray(dec, float), jumps, np.nan)


def _ra_ticks(ax: Axes) -> None:
    xt = np.arange(-150, 151, 30) * DEG
    ax.set_xticks(xt)
    ax.set_xticklabels([f"{round((-x * RAD_TO_DEG) % 360 / 15)}h" for x in xt], fontsize=8)
    ax.tick_params(axis="y", labelsize=8)


def _count_image(
    boresights: NDArray[np.float64], counts: NDArray[np.intp], resolution_deg: float
) -> tuple[NDArray[np.float64], ...]:
    """Return pixel edges, centres and the nearest orientation's count for each map pixel."""
    nx = round(360.0 / resolution_deg)
    ny = round(180.0 / resolution_deg)
    lon_edges = np.linspace(-np.pi, np.pi, nx + 1)
    lat_edges = np.linspace(-np.pi / 2, np.pi / 2, ny + 1)
    lon_c = 0.5 * (lon_edges[1:] + lon_edges[:-1])
    lat_c = 0.5 * (lat_edges[1:] + lat_edges[:-1])
    lon_g, lat_g = np.meshgrid(lon_c, lat_c)
    vec = radec_to_vectors(np.mod(-lon_g.ravel(), 2 * np.pi), lat_g.ravel())
    _, idx = cKDTree(boresights).query(vec)
    image = counts[idx].reshape(ny, nx).astype(float)
    return lon_edges, lat_edges, lon_c, lat_c, image


def sky_map_figure(
    boresights: NDArray[np.float64],
    counts: ArrayLike,
    title: str,
    *,
    sparse: bool = False,
    n_min: int = N_MIN_LOST_IN_SPACE,
    tracks: Sequence[NDArray[np.float64]] = (),
    resolution_deg: float = 1.0,
    ax: Axes | None = None,
) -> Figure:
    """Draw the stars in the field per boresight, Mollweide, with the galactic plane.

    The paper's Figs. 4, 5 and 14.

    Parameters
    ----------
    boresights : ndarray, shape (M, 3)
        ICRS unit vectors of the orientations.
    counts : array_like, shape (M,)
        Stars in the field at each orientation.
    title : str
        Title of the map.
    sparse : bool
        Emphasise star-sparse regions (the paper's Figs. 5 and 14): colours reversed and
        saturated at ``2 n_min + 2`` stars, orientations with fewer than `n_min` stars outlined
        in black.
    n_min : int
        Stars needed.
    tracks : sequence of ndarray, shape (K, 3)
        Boresight tracks to draw (e.g. great circles).
    resolution_deg : float
        Pixel size of the map image, deg; each pixel takes the nearest orientation's count.
    ax : matplotlib Axes with the Mollweide projection, optional
        Where to draw (default: a new figure).

    Returns
    -------
    matplotlib.figure.Figure
    """
    counts = np.asarray(counts)
    if ax is None:
        fig = new_figure(9.0, 5.2)
        ax = fig.add_subplot(projection="mollweide")
    fig = ax.figure
    lon_edges, lat_edges, lon_c, lat_c, image = _count_image(boresights, counts, resolution_deg)
    if sparse:
        top = 2 * n_min + 2
        cmap = mpl.colormaps["magma_r"]
        label = f"stars in field (colours reversed; >= {top} saturates)"
    else:
        top = max(int(np.percentile(counts, 99)), n_min + 1)
        cmap = mpl.colormaps["viridis"]
        label = f"stars in field (>= {top} saturates)"
    bounds = np.arange(-0.5, top + 1.0, 1.0)
    norm = mpl.colors.BoundaryNorm(bounds, cmap.N, extend="max")
    mesh = ax.pcolormesh(
        lon_edges,
        lat_edges,
        np.minimum(image, top),
        cmap=cmap,
        norm=norm,
        shading="flat",
        rasterized=True,
    )
    if sparse:
        ax.contour(lon_c, lat_c, image, levels=[n_min - 0.5], colors="k", linewidths=0.6)
    gx, gy = _broken_line(*galactic_plane_radec())
    ax.plot(
        gx,
        gy,
        color="tab:red" if not sparse else "tab:cyan",
        lw=1.4,
        ls="--",
        label="galactic plane (b = 0)",
    )
    for k, track in enumerate(tracks):
        tx, ty = _broken_line(*vectors_to_radec(np.asarray(track, dtype=float)))
        ax.plot(tx, ty, color="lime", lw=1.0, label="tracks" if k == 0 else None)
    _ra_ticks(ax)
    ax.grid(True, alpha=0.35)
    ax.set_title(title, fontsize=10)
    ticks = np.arange(0, top + 1, max(1, top // 10))
    fig.colorbar(
        mesh, ax=ax, orientation="horizontal", shrink=0.6, pad=0.06, label=label, ticks=ticks
    )
    ax.legend(loc="lower right", fontsize=7, framealpha=0.7)
    return fig


def static_curve_figure(res: StaticAvailability, ax: Axes | None = None) -> Figure:
    """Draw availability against the detection threshold m_t, N_min = 1 ... 4 (Fig. 6)."""
    fig, ax = figure_and_axes(ax, 7.5, 4.6)
    styles = {1: ":", 2: "-", 3: "-", 4: "--"}
    for k, curve in sorted(res.curve.items()):
        ax.plot(res.mag_grid, 100 * curve, styles.get(k, "-."), label=f"N_min = {k}")
    ax.axvline(res.max_mag, color="k", lw=0.8, ls=":")
    ax.set_xlabel("stellar detection threshold m_t (V)")
    ax.set_ylabel("spatial static availability (%)")
    ax.set_title(
        f"Availability against m_t, {res.catalog}, {res.fov}, {res.n_orientations} "
        "orientations (cf. paper Fig. 6)",
        fontsize=9,
    )
    ax.set_ylim(0, 101)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def dynamic_figure(results: Sequence[DynamicAvailability], ax: Axes | None = None) -> Figure:
    """Draw spatial dynamic availability against slew rate, N_min = 2 and 3 (Fig. 11)."""
    fig, ax = figure_and_axes(ax, 7.5, 4.6)
    colours = ("tab:blue", "tab:orange", "tab:green", "tab:red")
    for res, colour in zip(results, colours, strict=False):
        for k, style in ((N_MIN_TRACKING, "--"), (N_MIN_LOST_IN_SPACE, "-")):
            if k in res.by_n_min:
                ax.plot(
                    res.rates_deg_s,
                    100 * res.by_n_min[k],
                    style,
                    color=colour,
                    label=f"{res.curve.label}, N_min = {k}",
                )
    ax.set_xlabel("slew rate |w| (deg/s)")
    ax.set_ylabel("spatial dynamic availability (%)")
    ax.set_ylim(0, 101)
    ax.set_title("Spatial dynamic availability (cf. paper Fig. 11)", fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def track_figure(
    results: Sequence[TrackAvailability], n_min: int, ax: Axes | None = None
) -> Figure:
    """Draw along-track availability against inclination at several rates (Figs. 16, 17).

    The spatial dynamic availability at each rate is a dotted horizontal line.
    """
    fig, ax = figure_and_axes(ax, 7.5, 4.6)
    cmap = mpl.colormaps["plasma"]
    for j, res in enumerate(results):
        colour = cmap(0.85 * j / max(1, len(results) - 1))
        ax.plot(
            res.inclinations_deg,
            100 * res.by_n_min[n_min],
            "-",
            color=colour,
            label=f"{res.rate_deg_s:g} deg/s",
        )
        ax.axhline(100 * res.spatial[n_min], color=colour, ls=":", lw=1)
    ax.set_xlabel("track inclination i (deg)")
    ax.set_ylabel("along-track dynamic availability (%)")
    ax.set_xlim(-90, 90)
    ax.set_ylim(0, 101)
    node = results[0].node_deg if results else 0.0
    fig_no = {N_MIN_TRACKING: "16", N_MIN_LOST_IN_SPACE: "17"}.get(n_min, "16-17")
    ax.set_title(
        f"Along-track availability, N_min = {n_min}, node RA {node:g} deg "
        f"(dotted: spatial; cf. paper Fig. {fig_no})",
        fontsize=9,
    )
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, title="slew rate")
    return fig


def track_nmin_figure(res: TrackAvailability, ax: Axes | None = None) -> Figure:
    """Draw along-track availability against inclination at one rate, N_min = 2 and 3.

    The spatial dynamic availability is a dotted horizontal line (one rate of Figs. 16-17).
    """
    fig, ax = figure_and_axes(ax, 7.5, 4.6)
    for k, colour in zip(
        sorted(res.by_n_min), ("tab:blue", "tab:orange", "tab:green"), strict=False
    ):
        ax.plot(
            res.inclinations_deg, 100 * res.by_n_min[k], "-", color=colour, label=f"N_min = {k}"
        )
        ax.axhline(100 * res.spatial[k], color=colour, ls=":", lw=1)
    ax.set_xlabel("track inclination i (deg)")
    ax.set_ylabel("along-track dynamic availability (%)")
    ax.set_xlim(-90, 90)
    ax.set_ylim(0, 101)
    ax.set_title(
        f"Along-track availability at {res.rate_deg_s:g} deg/s, node RA {res.node_deg:g} deg "
        "(dotted: spatial; cf. paper Figs. 16-17)",
        fontsize=9,
    )
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def threshold_figure(
    curves: Sequence[ThresholdCurve], rates_rad_s: ArrayLike, ax: Axes | None = None
) -> Figure:
    """Draw m_t against slew rate (rad/s given, deg/s drawn) for each threshold curve."""
    fig, ax = figure_and_axes(ax, 7.0, 4.2)
    rates = np.asarray(rates_rad_s, dtype=float)
    for c in curves:
        m = c(rates)
        ax.plot(rates * RAD_TO_DEG, np.where(np.isfinite(m), m, np.nan), "-", label=c.label)
    ax.set_xlabel("slew rate |w| (deg/s)")
    ax.set_ylabel("detection threshold m_t(w)")
    ax.set_title("Faintest magnitude detected against slew rate", fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return fig
