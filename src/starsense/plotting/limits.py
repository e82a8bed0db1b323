"""Figures of the physical limit (Fialho & Mortari 2019): Fig. 7, Table 2 and Fig. 8.

Each function takes ``ax=None`` (a new figure of its own size) or the axes to draw on, and
returns the figure; :func:`plot_brightest_curves` writes Fig. 7 to a PNG file atomically.
Inputs are radians except where a name says otherwise (the Table 2 figure plots mas, Fig. 8
arcsec, as the paper does).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from starsense.analysis.limits.brightest import BrightestCurve
from starsense.analysis.limits.centroid import check_aperture
from starsense.analysis.limits.result import limit_line
from starsense.plotting.figure import figure_and_axes, save_png
from starsense.references import fialho2019 as paper
from starsense.units import RAD_TO_ARCSEC

__all__ = [
    "brightest_curves_figure",
    "fov_table_figure",
    "merit_figure",
    "plot_brightest_curves",
]

_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:olive")


def brightest_curves_figure(
    curves: Sequence[BrightestCurve] | Mapping[str, BrightestCurve],
    *,
    catalog_name: str = "",
    diameter_m: float = 1.0,
    exposure_s: float = 1.0,
    ax: Axes | None = None,
) -> Figure:
    """Draw theta_rms over the N brightest stars with power-law extrapolations (paper Fig. 7).

    Parameters
    ----------
    curves : sequence of BrightestCurve, or mapping label -> BrightestCurve
        One curve per colour system (or catalogue), all for the same D and t.
    catalog_name : str
        Prefix of the curve labels.
    diameter_m, exposure_s : float
        The D (m) and t (s) the curves were computed for: the paper's G interval and its
        extrapolated values (given for D = 1 m, t = 1 s) are scaled by D^-2 t^-1/2 (eq. 23).
    ax : matplotlib Axes or None
        Where to draw; None for a new figure (Agg canvas, not registered with pyplot).

    Returns
    -------
    matplotlib.figure.Figure
    """
    check_aperture(diameter_m, exposure_s)
    items = list(curves.items()) if isinstance(curves, Mapping) else [(c.colour, c) for c in curves]
    scale = 1.0 / (diameter_m**2 * np.sqrt(exposure_s))
    unit = diameter_m == 1.0 and exposure_s == 1.0
    fig, ax = figure_and_axes(ax, 8.5, 5.8)
    prefix = f"{catalog_name} " if catalog_name else ""
    n_ext_max = max((c.n_extrapolated for _, c in items), default=paper.N_GALAXY)
    for k, (name, curve) in enumerate(items):
        col = _COLOURS[k % len(_COLOURS)]
        ax.plot(
            curve.n_stars,
            curve.theta_rms_rad,
            "-",
            color=col,
            lw=1.8,
            label=f"{prefix}{name}: N brightest stars",
        )
        n_ext = np.geomspace(max(curve.n_stars[-1] / 10.0, 2.0), curve.n_extrapolated, 60)
        ax.plot(
            n_ext,
            curve.extrapolate(n_ext),
            "--",
            color=col,
            lw=1.2,
            label=f"{name} power law, slope {curve.slope:.3f}",
        )
        ax.plot([curve.n_extrapolated], [curve.theta_extrapolated_rad], "o", color=col, ms=6)
    _paper_fig7_marks(ax, scale, unit)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(1.0, 10 * max(n_ext_max, paper.N_GALAXY))
    ax.set_xlabel("N, number of brightest catalogue stars used")
    if unit:
        ax.set_ylabel(
            r"$\theta_\mathrm{rms}$ (rad) for D = 1 m, t = 1 s  [= G, rad m$^2$ s$^{1/2}$]"
        )
    else:
        ax.set_ylabel(
            rf"$\theta_\mathrm{{rms}}$ (rad) for D = {diameter_m:g} m, t = {exposure_s:g} s"
        )
    ax.set_title(
        r"$\theta_\mathrm{rms}$ of an ideal whole-sky sensor over the N brightest stars"
        " (cf. paper Fig. 7)",
        fontsize=11,
    )
    ax.grid(True, which="major", alpha=0.35)
    ax.grid(True, which="minor", alpha=0.12)
    ax.legend(fontsize=8, loc="lower left")
    return fig


def _paper_fig7_marks(ax: Axes, scale: float, unit: bool) -> None:
    """Draw the paper's G band at N = 3e11 and its two extrapolated values."""
    n_gal = paper.N_GALAXY
    g_lo, g_hi = paper.G_INTERVAL
    lo, hi = g_lo * scale, g_hi * scale
    ax.fill_between(
        [n_gal / 2.5, n_gal * 2.5],
        lo,
        hi,
        color="tab:red",
        alpha=0.2,
        lw=0,
        label=f"paper's G interval [{g_lo:.0e}, {g_hi:.0e}]"
        + ("" if unit else r" / ($D^2 t^{1/2}$)"),
    )
    ax.axvline(n_gal, color="0.4", ls="-.", lw=0.9)
    ax.text(
        n_gal / 3.0,
        1.15 * hi,
        "3×10¹¹ stars\n(the Galaxy)",
        ha="right",
        va="bottom",
        fontsize=8,
        color="0.3",
    )
    for value, marker, which in zip(
        paper.FIG7_EXTRAPOLATED_RAD, "v^", ("lower", "upper"), strict=True
    ):
        ax.plot(
            [n_gal],
            [value * scale],
            marker,
            color="black",
            ms=8,
            ls="none",
            label=f"paper: {which} extrapolation {value * scale:.1e} rad",
        )


def plot_brightest_curves(
    curves: Sequence[BrightestCurve] | Mapping[str, BrightestCurve],
    path,
    *,
    catalog_name: str = "",
    diameter_m: float = 1.0,
    exposure_s: float = 1.0,
    dpi: int = 110,
) -> Path:
    """Write :func:`brightest_curves_figure` to the PNG file ``path`` and return the path."""
    fig = brightest_curves_figure(
        curves, catalog_name=catalog_name, diameter_m=diameter_m, exposure_s=exposure_s
    )
    return save_png(fig, path, dpi)


def fov_table_figure(
    fovs_deg,
    ours_mas,
    paper_mas,
    *,
    diameter_m: float = paper.TABLE2_DIAMETER_M,
    exposure_s: float = paper.TABLE2_EXPOSURE_S,
    ax: Axes | None = None,
) -> Figure:
    """Draw theta_rms of the FOV-limited ideal sensor against its FOV (paper Table 2).

    Parameters
    ----------
    fovs_deg : array (K,)
        FOV diameters, deg (the table's rows).
    ours_mas : array (K, 3)
        theta_rms of target 1, target 2 and both merged, mas; NaN where singular.
    paper_mas : array (K, 3)
        The paper's values, mas; NaN where it has none.
    diameter_m, exposure_s : float
        The sensor's D (m) and t (s), for the title.
    ax : matplotlib Axes or None
        Where to draw; None for a new figure.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = figure_and_axes(ax, 7.5, 5.0)
    fovs = np.asarray(fovs_deg, dtype=float)
    ours_mas, paper_mas = np.asarray(ours_mas, dtype=float), np.asarray(paper_mas, dtype=float)
    styles = [
        ("target 1", "o", "tab:blue"),
        ("target 2", "s", "tab:orange"),
        ("both", "D", "tab:green"),
    ]
    for k, (label, marker, col) in enumerate(styles):
        ok = np.isfinite(ours_mas[:, k])
        ax.plot(
            fovs[ok],
            ours_mas[ok, k],
            "-",
            marker=marker,
            color=col,
            label=f"{label}: this catalogue",
        )
        okp = np.isfinite(paper_mas[:, k])
        ax.plot(
            fovs[okp],
            paper_mas[okp, k],
            ":",
            marker=marker,
            mfc="none",
            color=col,
            label=f"{label}: paper Table 2 (2MASS)",
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xticks(fovs, [f"{f:g}°" for f in fovs])
    ax.minorticks_off()
    ax.set_xlabel("FOV diameter")
    ax.set_ylabel(r"$\theta_\mathrm{rms}$ (mas)")
    ax.set_title(
        f"FOV-limited ideal sensor, D = {diameter_m * 100:g} cm, "
        f"t = {exposure_s * 1000:g} ms (cf. paper Table 2)",
        fontsize=11,
    )
    ax.grid(True, which="major", alpha=0.35)
    ax.legend(fontsize=8, ncols=2)
    return fig


def merit_figure(
    g_rad_m2_s05: float,
    *,
    g_label: str,
    fovs_deg,
    heads_mas,
    merged_mas,
    sensor: tuple[float, float],
    sensors: Sequence[tuple[str, float, float]] = (),
    ax: Axes | None = None,
) -> Figure:
    """Draw theta_rms against the figure of merit D^2 t^1/2 with the limit lines (paper Fig. 8).

    Parameters
    ----------
    g_rad_m2_s05 : float
        G from the catalogue, rad m^2 s^1/2 (eq. 23).
    g_label : str
        Label of that line (catalogue and colour system).
    fovs_deg : array (K,)
        FOV diameters of the Table 2 sensors, deg.
    heads_mas : array (K, 2)
        theta_rms of the single heads at target 1 and 2, mas; NaN where singular.
    merged_mas : array (K,)
        theta_rms of both heads merged, mas; NaN where singular.
    sensor : (float, float)
        This report's sensor, D (m) and t (s), drawn as an ideal whole-sky sensor.
    sensors : sequence of (name, D^2 t^1/2 (m^2 s^1/2), theta_rms (arcsec))
        Real sensors to place on the plot.
    ax : matplotlib Axes or None
        Where to draw; None for a new figure.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = figure_and_axes(ax, 8.5, 6.0)
    d_t2, t_t2 = paper.TABLE2_DIAMETER_M, paper.TABLE2_EXPOSURE_S
    x_single = d_t2**2 * math.sqrt(t_t2)
    x_double = (paper.TWO_HEAD_DIAMETER_FACTOR * d_t2) ** 2 * math.sqrt(t_t2)
    x_user = sensor[0] ** 2 * math.sqrt(sensor[1])
    xs = [x_single, x_double, x_user] + [s[1] for s in sensors]
    x_lo, x_hi = min(1e-5, min(xs) / 5.0), max(1.0, max(xs) * 5.0)
    _limit_lines(ax, np.geomspace(x_lo, x_hi, 100), g_rad_m2_s05, g_label)
    _ideal_points(ax, x_single, x_double, fovs_deg, heads_mas, merged_mas)
    ax.plot(
        [x_user],
        [g_rad_m2_s05 / x_user * RAD_TO_ARCSEC],
        "*",
        color="tab:purple",
        mfc="none",
        mew=1.5,
        ms=16,
        ls="none",
        zorder=1,
        label=f"this sensor (D = {sensor[0]:g} m, t = {sensor[1]:g} s), whole sky",
    )
    if sensors:
        ax.plot(
            [s[1] for s in sensors],
            [s[2] for s in sensors],
            "o",
            color="tab:red",
            ms=7,
            ls="none",
            label="real sensors (your table)",
        )
        for name, fom, theta in sensors:
            ax.annotate(
                name,
                (fom, theta),
                xytext=(5, 4),
                textcoords="offset points",
                fontsize=7,
                color="tab:red",
            )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(x_lo, x_hi)
    ax.set_xlabel(r"figure of merit $D^2 t^{1/2}$ (m$^2$ s$^{1/2}$)")
    ax.set_ylabel(r"$\theta_\mathrm{rms}$ (arcsec)")
    ax.set_title(r"Attitude error against $D^2 t^{1/2}$ (cf. paper Fig. 8)", fontsize=11)
    ax.grid(True, which="major", alpha=0.35)
    ax.grid(True, which="minor", alpha=0.12)
    ax.legend(fontsize=8, loc="lower left")
    return fig


def _limit_lines(ax: Axes, x: np.ndarray, g: float, g_label: str) -> None:
    """Draw theta = G / (D^2 t^1/2) for the paper's G interval and the catalogue's G."""
    lo, hi = paper.G_INTERVAL
    ax.plot(
        x,
        limit_line(lo, x) * RAD_TO_ARCSEC,
        "-",
        color="black",
        lw=1.5,
        label=f"limit, paper's lower G = {lo:.0e}",
    )
    ax.plot(
        x,
        limit_line(hi, x) * RAD_TO_ARCSEC,
        "--",
        color="black",
        lw=1.5,
        label=f"limit, paper's upper G = {hi:.0e}",
    )
    ax.plot(
        x,
        limit_line(g, x) * RAD_TO_ARCSEC,
        ":",
        color="tab:purple",
        lw=2,
        label=f"{g_label} G = {g:.2e}",
    )


def _ideal_points(ax: Axes, x_single, x_double, fovs_deg, heads_mas, merged_mas) -> None:
    """Draw the FOV-limited ideal sensors of Table 2: single heads and two heads merged."""
    heads_mas = np.asarray(heads_mas, dtype=float)
    for k, (label, marker) in enumerate((("one head, target 1", "o"), ("one head, target 2", "^"))):
        y = [t / 1000.0 for t in heads_mas[:, k] if np.isfinite(t)]
        ax.plot(
            [x_single] * len(y),
            y,
            marker,
            color="tab:blue",
            mfc="none" if k else None,
            ls="none",
            label=f"ideal FOV-limited, {label}",
        )
    th2 = [(f, t) for f, t in zip(fovs_deg, merged_mas, strict=True) if np.isfinite(t)]
    ax.plot(
        [x_double] * len(th2),
        [t / 1000.0 for _, t in th2],
        "s",
        color="tab:orange",
        ls="none",
        label="ideal FOV-limited, two heads (D doubled)",
    )
    for fov, t in th2:
        ax.annotate(
            f"{fov:g}°",
            (x_double, t / 1000.0),
            xytext=(6, 0),
            textcoords="offset points",
            va="center",
            fontsize=7,
            color="tab:orange",
        )
    for fov, t in zip(fovs_deg, heads_mas[:, 0], strict=True):
        if np.isfinite(t):
            ax.annotate(
                f"{fov:g}°",
                (x_single, t / 1000.0),
                xytext=(-6, 0),
                textcoords="offset points",
                va="center",
                ha="right",
                fontsize=7,
                color="tab:blue",
            )
