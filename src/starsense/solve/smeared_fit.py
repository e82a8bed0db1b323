"""A frame fitted at rest that the pixels reject: fitted again with the body rate free.

Short streaks (too short to re-centroid) leave a frame to be fitted at rest first
(:mod:`starsense.solve.refine`); where the streaks suggest a smear long enough to matter the
likelihood decides whether it is real (:func:`smeared_fit`).
"""

from __future__ import annotations

import numpy as np

from starsense.errors import InputError
from starsense.model.fit import fit_windows
from starsense.model.psf import psf_of
from starsense.solve.neighbours import fit_with_neighbours
from starsense.solve.streak_model import MIN_STREAK_SIGMAS

__all__ = ["smeared_fit"]

#: the chi-square drop that keeps the rate: the likelihood-ratio test of 3 more parameters at a
#: false alarm of 1e-3 (``scipy.stats.chi2.isf(1e-3, 3)``)
RATE_EVIDENCE_CHI2 = 16.27


def smeared_fit(fit, keywords, *, stars, hint, zero_point):
    """Return the fit of ``stars`` with the body rate free (and its counts), or None.

    A frame whose streaks are too short to re-centroid is fitted at rest first; it is fitted
    again with the rate free, started at ``hint`` (the rate the measured streaks suggest: the
    likelihood is even in the rate, flat at rest, so a fit started there stays), where the
    hint draws a streak of at least ``MIN_STREAK_SIGMAS`` PSF sigmas (shorter, the smear
    lengthens the image by under 15 %: a width fitted between the axes costs under 1 % of the
    stars' position information). Whether the fit at rest was rejected does not decide: the
    chi-square of faint stars' pixels barely sees a smear that doubles their width along the
    streak (and halves the information there), the likelihood ratio of the two models does. It
    is kept where the likelihood ratio says so: the model at rest, fitted again on the same
    pixels (the streaks' windows) with the same neighbours, has a chi-square higher by more
    than :data:`RATE_EVIDENCE_CHI2` (3 rate parameters at a false alarm of 1e-3), and the
    rate fitted draws streaks as long as the hint had to (a tiny rate that takes up a
    model's small misfit of many bright stars is no smear).
    """
    image, sensor = keywords["image"], keywords["sensor"]
    shortest = MIN_STREAK_SIGMAS * psf_of(sensor).sigma_px
    if _longest_px(sensor, fit.rotation, stars[1], hint) < shortest:
        return None  # too short to matter: an image 15 % longer, < 1 % of the information lost
    opts = dict(keywords["opts"], fit_rate=True)
    last = {}
    try:
        moving = fit_with_neighbours(
            image,
            sensor,
            fit.rotation,
            stars=stars,
            first=None,
            zero_point=zero_point,
            sky=keywords["sky"],
            place=keywords["place"],
            rate=np.asarray(hint, float),
            opts=opts,
            last=last,
        )
        if not moving[0].converged:
            return None
        # the model at rest on the same pixels, with the same neighbours: the ratio's other side
        rest = fit_windows(
            image,
            sensor,
            last["start"],
            vectors=stars[1],
            rate_rad_s=np.zeros(3),
            fixed_vectors=last["neighbours"],
            fixed_electrons=last["electrons"],
            fluxes_e=last["fluxes"],
            window_rate_rad_s=last["rate"],
            **dict(keywords["opts"], fit_rate=False),
        )
    except (InputError, np.linalg.LinAlgError):
        return None
    if rest.n_pixels != moving[0].n_pixels or not rest.chi2 - moving[0].chi2 > RATE_EVIDENCE_CHI2:
        return None
    if _longest_px(sensor, moving[0].rotation, stars[1], moving[0].rate_rad_s) < shortest:
        return None  # the rate fitted draws streaks too short to matter: the frame is at rest
    return moving


def _longest_px(sensor, rotation, vectors, rate) -> float:
    """Return the longest streak body rate ``rate`` draws of stars ``vectors`` (ICRS), px."""
    cam = rotation.apply(vectors)  # the stars in the camera frame
    turn = np.linalg.norm(np.cross(np.asarray(rate, float), cam), axis=1)
    return float(np.max(turn, initial=0.0)) * sensor.exposure_s * sensor.focal_length_px
