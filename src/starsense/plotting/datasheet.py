"""Figures of the datasheet: the noise-equivalent angle over the sky."""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from starsense.geometry.attitude import vectors_to_radec
from starsense.plotting.figure import figure_and_axes
from starsense.units import RAD_TO_ARCSEC

__all__ = ["nea_sky_figure"]


def nea_sky_figure(sheet, ax: Axes | None = None) -> Figure:
    """Draw the cross-boresight NEA (arcsec) at each boresight, Mollweide (RA increasing left).

    Parameters
    ----------
    sheet : Datasheet
        With ``boresights`` (M, 3) and ``nea_cross_rad`` (M,).
    ax : Axes, optional
        A Mollweide axes to draw on.
    """
    if ax is None:
        fig, ax = figure_and_axes(None, 8.0, 4.6)
        ax.remove()
        ax = fig.add_subplot(projection="mollweide")
    fig = ax.figure
    ra, dec = vectors_to_radec(sheet.boresights)
    x = -np.angle(np.exp(1j * np.asarray(ra)))  # RA 0 at the centre, increasing to the left
    nea = np.asarray(sheet.nea_cross_rad) * RAD_TO_ARCSEC
    ok = np.isfinite(nea)
    sc = ax.scatter(x[ok], np.asarray(dec)[ok], c=nea[ok], s=6, cmap="viridis")
    if (~ok).any():
        ax.scatter(x[~ok], np.asarray(dec)[~ok], c="red", s=6, label="no attitude (< 2 stars)")
        ax.legend(loc="lower right", fontsize=8)
    fig.colorbar(
        sc,
        ax=ax,
        orientation="horizontal",
        pad=0.06,
        shrink=0.6,
        label="NEA cross-boresight, 1 sigma (arcsec)",
    )
    ax.grid(True, alpha=0.3)
    ax.set_xticklabels([])
    ax.set_title(f"{sheet.sensor}: noise-equivalent angle over the sky")
    return fig
