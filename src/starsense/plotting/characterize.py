"""Figures of a characterised camera: PSF across the field, zero point, photon transfer."""

from __future__ import annotations

import math

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from starsense.plotting.figure import figure_and_axes, new_figure

__all__ = ["characterize_figure", "psf_field_axes", "transfer_axes", "zero_point_axes"]


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


def characterize_figure(ch) -> Figure:
    """Return the three panels side by side (``characterize --plot``)."""
    fig = new_figure(15.0, 4.2)
    axes = fig.subplots(1, 3)
    psf_field_axes(ch, axes[0])
    zero_point_axes(ch, axes[1])
    transfer_axes(ch, axes[2])
    return fig
