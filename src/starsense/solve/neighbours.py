"""The fit of given stars with the catalogue stars whose light reaches their windows.

The forward model's fit (:func:`starsense.model.fit.fit_windows`) of the stars a solve fits
(:mod:`starsense.solve.refine`) draws every catalogue star whose light reaches a window:

1. the detections' lit sums give the frame's zero point (electrons of a magnitude-0 star: the
   median over the brightest), or, without them, a first fit of the identified stars alone;
2. every catalogue star within reach of a window (its box, the PSF's extent and the streak) is
   predicted from its magnitude and that zero point; one too faint to matter (below a tenth of
   a pixel's noise over its PSF) is left out, the rest are drawn at their predicted flux (and
   move with the attitude); a fitted star's own catalogue row is not drawn again, a close
   companion is;
3. the fit is made with them; where its fluxes move the zero point by more than
   :data:`ZERO_POINT_AGREES` (a lit sum misses a wide PSF's wings), the neighbours are
   predicted again and the fit repeated from its attitude. A fit that did not converge (the
   model does not place the stars: :func:`~starsense.model.fit.fit_windows` stops it) is not
   repeated: its fluxes measure nothing, and its attitude is not a start.
"""

from __future__ import annotations

import math

import numpy as np

from starsense.model.fit import fit_windows
from starsense.model.psf import psf_of
from starsense.model.selection import psf_noise_e, streak_px
from starsense.model.windows import window_half_px
from starsense.solve.in_view import SAME_STAR_PX

__all__ = ["catalogue_neighbours", "fit_with_neighbours", "frame_zero_point", "reach_px"]

#: stars whose fluxes set the zero point
ZERO_POINT_STARS = 7
#: the neighbours are fitted again when the fit's zero point differs by more than this
#: (a lit sum misses a PSF's wings): a 5 % flux error of a neighbour at the noise's level is
#: below a tenth of its pull
ZERO_POINT_AGREES = 0.05
#: a neighbour below this fraction of a pixel's noise (over its PSF's area) is left out
NEGLIGIBLE_NOISE = 0.1


def catalogue_neighbours(
    sensor, plain, *, sky, place, rotation, reach_px: float, zero_point: float, noise_e: float
):
    """Return catalogue neighbours of the fitted stars: (apparent places, electrons)."""
    mags, tree = sky.mags, sky.tree
    pixel_rad = 1.0 / sensor.focal_length_px
    lists = tree.query_ball_point(plain, 2.0 * math.sin(0.5 * reach_px * pixel_rad))
    owner = np.repeat(np.arange(len(plain)), [len(v) for v in lists])
    if owner.size == 0:
        return np.zeros((0, 3)), np.zeros(0)
    near = np.unique(np.concatenate([np.asarray(v, dtype=int) for v in lists]))
    # not a fitted star itself: each one's own row is the catalogue star nearest it within
    # SAME_STAR_PX (another catalogue's copy sits its catalogue errors away). A companion
    # closer than that is a star of its own: drawn where it is, at its catalogue flux, its
    # light does not move the fitted star's position (merged into it, a companion of flux
    # ratio f at d px would pull it by ~f d / (1 + f), a tenth of a pixel for a bright double)
    d_own, own = tree.query(
        plain, k=1, distance_upper_bound=2.0 * math.sin(0.5 * SAME_STAR_PX * pixel_rad)
    )
    near = np.setdiff1d(near, own[np.isfinite(d_own)])
    electrons = zero_point * 10.0 ** (-0.4 * mags[near])
    keep = electrons >= NEGLIGIBLE_NOISE * noise_e
    near, electrons = near[keep], electrons[keep]
    v = place(near)
    cam_z = v @ rotation.as_matrix()[2]
    front = cam_z > 0
    return v[front], electrons[front]


def frame_zero_point(fluxes, mags) -> float | None:
    """Electrons of a magnitude-0 star: the median over the brightest fitted stars."""
    ok = np.isfinite(fluxes) & (fluxes > 0) & np.isfinite(mags)
    if not ok.any():
        return None
    idx = np.flatnonzero(ok)
    top = idx[np.argsort(-fluxes[idx])[:ZERO_POINT_STARS]]
    return float(np.median(fluxes[top] / 10.0 ** (-0.4 * mags[top])))


def fit_with_neighbours(
    image, sensor, rotation, *, stars, first, zero_point, sky, place, rate, opts, last=None
):
    """Fit ``stars`` (plain, reference, mags) with the catalogue neighbours reaching them.

    At the zero point ``zero_point`` (electrons of a magnitude-0 star), again if the fit's
    fluxes move it (a lit sum misses a PSF's wings). ``first``: a fit of the identified stars
    alone (its attitude, rate and fluxes the start), or None. ``last``, a dict, receives how
    the last fit started: ``start`` (attitude), ``rate``, ``neighbours`` and ``electrons``
    (the neighbours drawn) and ``fluxes`` (the stars' starting electrons).

    Returns
    -------
    ModelFit, (int, int)
        The fit, and the stars fitted and the neighbours drawn.
    """
    plain, ref, mags = stars
    fit, zp = first, zero_point
    n_fitted = 0 if fit is None else len(fit.fluxes_e)  # the first fit: no neighbours
    nv = np.zeros((0, 3))
    for _ in range(2):
        start = rotation if fit is None else fit.rotation
        nv, ne = catalogue_neighbours(
            sensor,
            plain,
            sky=sky,
            place=place,
            rotation=start,
            reach_px=reach_px(sensor, rate),
            zero_point=zp,
            noise_e=psf_noise_e(sensor, rate),
        )
        if fit is first and fit is not None and not len(nv) and n_fitted == len(ref):
            break
        own = zp * 10.0 ** (-0.4 * mags)  # fitted fluxes where a fit has them
        if fit is not None:
            got = fit.fluxes_e[:n_fitted]
            own[:n_fitted] = np.where(np.isfinite(got) & (got > 0), got, own[:n_fitted])
        start_rate = rate if fit is None else fit.rate_rad_s
        if last is not None:
            last.update(start=start, rate=start_rate, neighbours=nv, electrons=ne, fluxes=own)
        fit = fit_windows(
            image,
            sensor,
            start,
            vectors=ref,
            rate_rad_s=start_rate,
            fixed_vectors=nv,
            fixed_electrons=ne,
            fluxes_e=own,
            **opts,
        )
        n_fitted = len(ref)
        if not fit.converged:  # its fluxes are not a measurement: the zero point stands
            break
        new = frame_zero_point(fit.fluxes_e[: len(ref)], mags)
        if new is None or abs(new / zp - 1.0) < ZERO_POINT_AGREES or not len(nv):
            break
        zp = new
    return fit, (len(ref), len(nv))


def reach_px(sensor, rate) -> float:
    """How far from a star a neighbour's light may reach its window, px."""
    psf = psf_of(sensor)
    streak = 0.0 if rate is None else streak_px(sensor, rate)
    return window_half_px(psf) * math.sqrt(2.0) + psf.radius_px + streak
