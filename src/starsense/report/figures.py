"""Stand-alone figures shared by the report and the command line.

:func:`brightest_curves_figure` draws Fialho & Mortari 2019 Fig. 7 from
:class:`~starsense.analysis.limits.BrightestCurve` results; :func:`plot_brightest_curves` writes
it to a PNG file (atomically: a temporary name, then a rename).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from starsense.analysis.limits import G_PAPER_INTERVAL, BrightestCurve, check_aperture
from starsense.report.page import new_figure

#: theta_rms at N = 3e11 read off the paper's lower and upper extrapolation curves (sec. 3.3),
#: rad, for D = 1 m and t = 1 s
PAPER_EXTRAPOLATED = (1.2e-14, 5.8e-14)

_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:olive")


def brightest_curves_figure(
    curves: Sequence[BrightestCurve] | Mapping[str, BrightestCurve],
    *,
    catalog_name: str = "",
    diameter_m: float = 1.0,
    exposure_s: float = 1.0,
) -> Figure:
    """theta_rms over the N brightest stars with power-law extrapolations (paper Fig. 7).

    Parameters
    ----------
    curves : sequence of BrightestCurve, or mapping label -> BrightestCurve
        One curve per colour system (or catalogue), all for the same D and t.
    catalog_name : str
        Prefix of the curve labels.
    diameter_m, exposure_s : float
        The D (m) and t (s) the curves were computed for: the paper's G interval and its
        extrapolated values (given for D = 1 m, t = 1 s) are scaled by D^-2 t^-1/2 (eq. 23).

    Returns
    -------
    matplotlib Figure (Agg canvas, not registered with pyplot)
    """
    check_aperture(diameter_m, exposure_s)
    items = list(curves.items()) if isinstance(curves, Mapping) else [(c.colour, c) for c in curves]
    scale = 1.0 / (diameter_m**2 * np.sqrt(exposure_s))
    unit = diameter_m == 1.0 and exposure_s == 1.0
    fig = new_figure(8.5, 5.8)
    ax = fig.add_subplot()
    prefix = f"{catalog_name} " if catalog_name else ""
    n_ext_max = max((c.n_extrapolated for _, c in items), default=3e11)
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
    n_gal = 3e11
    lo, hi = (g * scale for g in G_PAPER_INTERVAL)
    ax.fill_between(
        [n_gal / 2.5, n_gal * 2.5],
        lo,
        hi,
        color="tab:red",
        alpha=0.2,
        lw=0,
        label=f"paper's G interval [{G_PAPER_INTERVAL[0]:.0e}, {G_PAPER_INTERVAL[1]:.0e}]"
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
    for value, marker, which in zip(PAPER_EXTRAPOLATED, "v^", ("lower", "upper"), strict=True):
        ax.plot(
            [n_gal],
            [value * scale],
            marker,
            color="black",
            ms=8,
            ls="none",
            label=f"paper: {which} extrapolation {value * scale:.1e} rad",
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(1.0, 10 * max(n_ext_max, n_gal))
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
    path = Path(path)
    fig = brightest_curves_figure(
        curves, catalog_name=catalog_name, diameter_m=diameter_m, exposure_s=exposure_s
    )
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fig.savefig(fh, dpi=dpi, format="png")
        os.chmod(tmp, 0o644)  # mkstemp creates 0600
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path
