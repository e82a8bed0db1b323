"""Frames drawn by the forward model itself: static stars at a known attitude, no noise."""

from __future__ import annotations

import numpy as np

from starsense.model.psf import pixel_psf
from starsense.model.tracks import node_positions, time_nodes
from starsense.model.windows import evaluate, make_windows


def model_image(sensor, vectors, rotation, flux_range, *, background_e=0.0):
    """Return ``(expected e-, kept, fluxes)``: the stars ``vectors`` drawn by the model.

    Each star kept by the windows (8 px boxes) gets a flux log-spaced over ``flux_range``
    (electrons, faintest first), on a flat ``background_e``; the image is in electrons.
    """
    det = sensor.detector
    psf = pixel_psf(sensor.psf, det.psf_sigma_px)
    frac, wts = time_nodes(0.0, psf.sigma_px)
    nodes = node_positions(
        sensor, vectors, rotation, rate_rad_s=np.zeros(3), exposure_s=sensor.exposure_s,
        fractions=frac, weights=wts,
    )  # fmt: skip
    windows, kept = make_windows(nodes.x, nodes.y, half_px=8.0, shape=(det.rows, det.columns),
                                 free=np.ones(len(vectors), bool))  # fmt: skip
    fluxes = np.geomspace(*flux_range, len(kept))
    ev = evaluate(windows, psf, nodes, fluxes=fluxes, gradient=False)
    slots = np.zeros((windows.n_groups, windows.n_slots))
    slots[windows.group, windows.slot] = fluxes
    light = np.einsum("gmhw,gm->ghw", ev.templates, slots)
    image = np.full((det.rows, det.columns), float(background_e))
    h, w = windows.shape
    for g in range(windows.n_groups):
        r0, c0 = windows.row0[g], windows.col0[g]
        rr = slice(max(r0, 0), min(r0 + h, det.rows))
        cc = slice(max(c0, 0), min(c0 + w, det.columns))
        image[rr, cc] += light[g, rr.start - r0 : rr.stop - r0, cc.start - c0 : cc.stop - c0]
    return image, kept, fluxes
