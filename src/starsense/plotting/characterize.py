"""Figures of a characterised camera: its PSF, zero point, photon transfer, noise and residuals.

The background noise and the stars' residuals after calibration are mapped over the detector.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from starsense.plotting.figure import figure_and_axes, new_figure

__all__ = [
    "characterize_figure",
    "noise_map_axes",
    "psf_field_axes",
    "residual_map_axes",
    "transfer_axes",
    "zero_point_axes",
]


def psf_field_axes(ch, ax: Axes | None = None) -> Figure:
    """Plot each field zone's PSF width against ``u = r^2 / r_corner^2`` and the fitted law.

    Parameters
    ----------
    ch : Characterisation
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = figure_and_axes(ax, 5.0, 4.0)
    fp = ch.field_psf
    ok = np.isfinite(fp.sigma_px)
    ax.errorbar(fp.u[ok], fp.sigma_px[ok], yerr=fp.sigma_err_px[ok], fmt="o", label="zones")
    if fp.told:
        u = np.linspace(0.0, 1.0, 50)
        ax.plot(u, fp.centre_px + (fp.corner_px - fp.centre_px) * u, "-", label="fit")
    if math.isfinite(ch.psf_sigma_px):
        ax.axhline(ch.psf_sigma_px, ls=":", color="grey", label="all stars")
    ax.set_xlabel("r^2 / r_corner^2")
    ax.set_ylabel("PSF sigma (px)")
    ax.set_title("PSF across the field")
    ax.legend(fontsize="small")
    return fig


def zero_point_axes(ch, ax: Axes | None = None) -> Figure:
    """Plot the stars' fitted fluxes against their V magnitudes and the zero point's line."""
    fig, ax = figure_and_axes(ax, 5.0, 4.0)
    z = ch.zero
    if z is None:
        ax.text(0.5, 0.5, "no zero point", ha="center", transform=ax.transAxes)
        return fig
    ax.plot(z.mags[z.kept], z.log10_flux[z.kept], ".", label="stars")
    ax.plot(z.mags[~z.kept], z.log10_flux[~z.kept], "x", label="clipped")
    m = np.linspace(np.min(z.mags), np.max(z.mags), 20)
    ax.plot(m, z.log10_counts - 0.4 * m, "-", label=f"slope -0.4, scatter {z.scatter_mag:.2f} mag")
    ax.set_xlabel("catalogue V (mag)")
    ax.set_ylabel("log10 counts" + (" / s" if z.per_second else ""))
    ax.set_title("Zero point")
    ax.legend(fontsize="small")
    return fig


def transfer_axes(ch, ax: Axes | None = None) -> Figure:
    """Plot the background boxes' variance against their level and the photon-transfer line."""
    fig, ax = figure_and_axes(ax, 5.0, 4.0)
    for k, n in enumerate(ch.noises):
        ax.plot(n.box_levels, n.box_variances, ".", ms=2, label=f"frame {k + 1}")
    tr = ch.transfer
    if tr.told:
        s = np.linspace(0.0, max(float(np.max(n.box_levels)) for n in ch.noises), 20)
        bias = ch.base.detector.bias_counts
        ax.plot(s, tr.floor_counts2 + tr.gain_counts_per_e * (s - bias), "k-", label="fit")
        ax.set_title(f"Photon transfer: gain {tr.gain_counts_per_e:.3g} counts/e")
    else:
        ax.set_title("Photon transfer: gain not told")
    ax.set_xlabel("level (counts)")
    ax.set_ylabel("variance (counts^2)")
    ax.legend(fontsize="small", markerscale=3)
    return fig


def noise_map_axes(ch, ax: Axes | None = None) -> Figure:
    """Map the first frame's per-pixel background noise over its boxes (counts rms).

    A structured pattern, a gradient or a warm corner shows where one noise for the whole
    detector (the sensor's read noise) does not hold.
    """
    fig, ax = figure_and_axes(ax, 5.0, 4.0)
    n = ch.noises[0] if ch.noises else None
    if n is None or not len(n.box_xy):
        ax.text(0.5, 0.5, "no background box", ha="center", transform=ax.transAxes)
        return fig
    det = ch.base.detector
    sc = ax.scatter(
        n.box_xy[:, 0],
        n.box_xy[:, 1],
        c=np.sqrt(n.box_variances),
        marker="s",
        s=30.0,
        cmap="viridis",
    )
    fig.colorbar(sc, ax=ax, label="noise (counts rms)")
    ax.set_xlim(0, det.columns)
    ax.set_ylim(det.rows, 0)  # rows down, as the frame is shown
    ax.set_aspect("equal")
    ax.set_xlabel("column (px)")
    ax.set_ylabel("row (px)")
    name = Path(ch.names[0]).name if ch.names else "frame 1"
    ax.set_title(f"Background noise: {name}", fontsize="medium")
    return fig


def residual_map_axes(ch, ax: Axes | None = None) -> Figure:
    """Map the matched stars' residuals after calibration, every frame, as arrows.

    The arrows are drawn ``scale`` times their length (stated); a pattern across the field is
    distortion the calibration's model does not hold, arrows at random are the stars' noise.
    """
    fig, ax = figure_and_axes(ax, 5.0, 4.0)
    xy, d = ch.residual_map
    det = ch.base.detector
    if not len(xy):
        ax.text(0.5, 0.5, "no matched star", ha="center", transform=ax.transAxes)
        return fig
    rms = float(np.sqrt(np.mean(d * d)))
    scale = 0.05 * det.columns / max(rms, 1e-6)  # an rms residual drawn 5 % of the width
    ax.quiver(
        xy[:, 0],
        xy[:, 1],
        d[:, 0],
        -d[:, 1],
        angles="xy",
        scale_units="xy",
        scale=1.0 / scale,
        width=0.003,
    )
    ax.set_xlim(0, det.columns)
    ax.set_ylim(det.rows, 0)
    ax.set_aspect("equal")
    ax.set_xlabel("column (px)")
    ax.set_ylabel("row (px)")
    ax.set_title(f"Residuals after calibration: {rms:.3f} px rms (x{scale:.0f})", fontsize="medium")
    return fig


def characterize_figure(ch) -> Figure:
    """Return the five panels (``characterize --plot``)."""
    fig = new_figure(15.0, 8.4)
    axes = fig.subplots(2, 3)
    psf_field_axes(ch, axes[0, 0])
    zero_point_axes(ch, axes[0, 1])
    transfer_axes(ch, axes[0, 2])
    noise_map_axes(ch, axes[1, 0])
    residual_map_axes(ch, axes[1, 1])
    axes[1, 2].set_axis_off()
    return fig
