"""The solver's last step: the attitude fitted to the identified stars' pixels (the forward model).

Once a frame is identified and a first attitude fitted to the centroids, the attitude (and the
body rate, when the frame is smeared) is refined by maximum likelihood on the pixels around the
identified stars (:func:`starsense.model.fit.fit_windows`): each star's flux and each window's
background are free, and the catalogue stars whose light reaches a window are in the model:

1. a first fit of the identified stars alone gives their fluxes, hence the frame's zero point
   (electrons of a magnitude-0 star: the median over the brightest);
2. every catalogue star within reach of a window (its box, the PSF's extent and the streak) is
   predicted from its magnitude and that zero point; one too faint to matter (below a tenth of
   a pixel's noise over its PSF) is left out, one bright enough to be measured (25 times that
   noise) is fitted like the identified stars, the rest are drawn at their predicted flux;
3. the fit is repeated with them, from the first fit's attitude.

The solution's covariance is the inverse Fisher information at the fit (the Cramer-Rao bound of
the model), which the datasheet predicts. A fit that does not converge, whose pixels disagree
with the model (reduced chi-square above :data:`MAX_REDUCED_CHI2`) or that moves the attitude
further than :data:`MAX_MOVE_SIGMAS` of the centroid solution's own sigma keeps the centroid
attitude and says why.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from starsense.errors import InputError
from starsense.model.fit import ModelFit, fit_windows, pixel_variance, window_half_px
from starsense.model.psf import psf_of
from starsense.solve.blends import streak_body_rate

__all__ = [
    "MAX_MOVE_SIGMAS",
    "MAX_REDUCED_CHI2",
    "Refinement",
    "refine_attitude",
    "refined_attitude",
]

#: a model fit whose pixels' reduced chi-square exceeds this does not describe the frame
MAX_REDUCED_CHI2 = 4.0
#: a model fit further than this many centroid sigmas from the centroid attitude is refused
MAX_MOVE_SIGMAS = 8.0
#: two catalogue directions closer than this are one star, rad (0.2 arcsec)
SAME_STAR_RAD = 1e-6
#: stars whose fluxes set the zero point
ZERO_POINT_STARS = 7
#: a neighbour below this fraction of a pixel's noise (over its PSF's area) is left out
NEGLIGIBLE_NOISE = 0.1
#: a neighbour above this many times a pixel's noise (over its PSF's area) is fitted
MEASURED_NOISE = 25.0


@dataclass(frozen=True)
class Refinement:
    """What the model fit made of a frame.

    Attributes
    ----------
    fit : ModelFit or None
        The fit (None when it was not used).
    used : bool
        Whether the fit's attitude replaced the centroid one.
    note : str
        Why not, or what was modelled.
    n_neighbours : int
        Catalogue neighbours in the model.
    """

    fit: ModelFit | None
    used: bool
    note: str
    n_neighbours: int = 0


def _neighbours(sensor, plain, ref, *, sky, rotation, reach_px: float, zero_point: float,
                noise_e: float):  # fmt: skip
    """Return catalogue neighbours of the matched stars: (vectors, electrons, fitted?)."""
    vectors, mags, tree = sky
    pixel_rad = 1.0 / sensor.focal_length_px
    lists = tree.query_ball_point(plain, 2.0 * math.sin(0.5 * reach_px * pixel_rad))
    owner = np.repeat(np.arange(len(plain)), [len(v) for v in lists])
    if owner.size == 0:
        return np.zeros((0, 3)), np.zeros(0), np.zeros(0, bool)
    near = np.concatenate([np.asarray(v, dtype=int) for v in lists])
    # not a matched star itself (any of them)
    d_min = np.min(np.linalg.norm(vectors[near][:, None, :] - plain[None, :, :], axis=2), axis=1)
    keep = d_min > SAME_STAR_RAD
    near, owner = near[keep], owner[keep]
    near, first = np.unique(near, return_index=True)
    owner = owner[first]
    electrons = zero_point * 10.0 ** (-0.4 * mags[near])
    keep = electrons >= NEGLIGIBLE_NOISE * noise_e
    near, owner, electrons = near[keep], owner[keep], electrons[keep]
    # the matched star's apparent-place shift applies to its neighbours (same direction)
    v = vectors[near] + (ref[owner] - plain[owner])
    v /= np.linalg.norm(v, axis=1)[:, None]
    cam_z = v @ rotation.as_matrix()[2]
    front = cam_z > 0
    return v[front], electrons[front], (electrons >= MEASURED_NOISE * noise_e)[front]


def _zero_point(fluxes, mags) -> float | None:
    """Electrons of a magnitude-0 star: the median over the brightest fitted stars."""
    ok = np.isfinite(fluxes) & (fluxes > 0) & np.isfinite(mags)
    if not ok.any():
        return None
    idx = np.flatnonzero(ok)
    top = idx[np.argsort(-fluxes[idx])[:ZERO_POINT_STARS]]
    return float(np.median(fluxes[top] / 10.0 ** (-0.4 * mags[top])))


def refine_attitude(image, sensor, rotation, ref, plain, mags, *, sky, cog_sigma_rad,
                    rate_rad_s=None) -> Refinement:  # fmt: skip
    """Fit the attitude to the pixels of the identified stars (module docstring).

    Parameters
    ----------
    image : ndarray (rows, columns)
        The frame, counts.
    sensor : Sensor
    rotation : Rotation
        The centroid solution's attitude.
    ref, plain : ndarray (K, 3)
        The identified stars' reference directions (apparent places) and catalogue places.
    mags : ndarray (K,)
        Their catalogue magnitudes (in the band of ``sky``).
    sky : (vectors, mags, tree)
        Every catalogue star that may light a window.
    cog_sigma_rad : ndarray (3,)
        The centroid solution's 1-sigma per axis, rad.
    rate_rad_s : ndarray (3,), optional
        The body rate of a smeared frame (its streaks'), fitted from there; None: at rest.

    Returns
    -------
    Refinement
    """
    fit_rate = rate_rad_s is not None
    rate = np.zeros(3) if rate_rad_s is None else np.asarray(rate_rad_s, float)
    try:
        first = fit_windows(image, sensor, rotation, ref, rate_rad_s=rate, fit_rate=fit_rate)
        zp = _zero_point(first.fluxes_e, np.asarray(mags, float))
        fit, n_nbr = first, 0
        if zp is not None:
            psf = psf_of(sensor)
            noise_e = math.sqrt(pixel_variance(sensor.detector, 0.0, sensor.exposure_s)) * (
                math.sqrt(4.0 * math.pi) * psf.sigma_px
            )
            streak = np.linalg.norm(rate) * sensor.exposure_s * sensor.focal_length_px
            reach = window_half_px(psf) * math.sqrt(2.0) + psf.radius_px + streak
            nv, ne, nfree = _neighbours(
                sensor, plain, ref, sky=sky, rotation=first.rotation, reach_px=reach,
                zero_point=zp, noise_e=noise_e,
            )  # fmt: skip
            if len(nv):
                fit = fit_windows(
                    image, sensor, first.rotation, np.concatenate([ref, nv[nfree]]),
                    rate_rad_s=first.rate_rad_s, fit_rate=fit_rate,
                    fixed_vectors=nv[~nfree], fixed_electrons=ne[~nfree],
                )  # fmt: skip
                n_nbr = len(nv)
    except (InputError, np.linalg.LinAlgError) as exc:
        return Refinement(None, False, f"model fit not used: {exc}")
    return _judged(fit, rotation, cog_sigma_rad, n_nbr)


def _judged(fit: ModelFit, rotation, cog_sigma_rad, n_nbr: int) -> Refinement:
    """Accept the fit, or say why the centroid attitude stays."""
    if not fit.converged:
        return Refinement(fit, False, "model fit did not converge", n_nbr)
    if not math.isfinite(fit.reduced_chi2) or fit.reduced_chi2 > MAX_REDUCED_CHI2:
        why = f"reduced chi-square {fit.reduced_chi2:.3g} > {MAX_REDUCED_CHI2:g}"
        return Refinement(fit, False, f"model fit not used: the pixels disagree ({why})", n_nbr)
    if not np.all(np.isfinite(fit.sigma_axes_rad)):
        return Refinement(fit, False, "model fit not used: singular information", n_nbr)
    from starsense.geometry.attitude import small_rotation_angles  # noqa: PLC0415

    move = np.abs(small_rotation_angles(fit.rotation, rotation))
    scale = np.hypot(np.asarray(cog_sigma_rad, float), fit.sigma_axes_rad)
    if np.any(move > MAX_MOVE_SIGMAS * scale):
        return Refinement(
            fit, False,
            f"model fit not used: {float(np.max(move / scale)):.1f} sigma from the centroids'",
            n_nbr,
        )  # fmt: skip
    return Refinement(fit, True, f"model fit ({fit.n_pixels} px, {n_nbr} neighbours)", n_nbr)


def refined_attitude(image, att, sensor, db, ident, *, places, streaks, sky):
    """Return the solver's attitude refined on the pixels, and a note saying how.

    Parameters
    ----------
    image : ndarray
        The frame, counts.
    att : AttitudeSolution
        The attitude fitted to the centroids.
    sensor : Sensor
    db : identification database
        Its ``mags`` (in ``db.params.band``) give the matched stars' magnitudes.
    ident : identification result
        The matches (``catalog_index`` into ``db``).
    places : (ndarray, ndarray)
        The matched stars' catalogue and apparent places (K, 3).
    streaks : StreakCentroids or None
        The streaks of a smeared frame (their rate starts the fit's), None at rest.
    sky : (vectors, mags, tree)
        The catalogue's stars in the band of ``db``.

    Returns
    -------
    AttitudeSolution, tuple of str
    """
    plain, ref = places
    index = np.asarray(ident.catalog_index)
    rate = None
    if streaks is not None:  # smeared: the fit starts from the streaks' rate
        rate = streak_body_rate(sensor, att.rotation.apply(ref), streaks.streaks_px)
    done = refine_attitude(
        image, sensor, att.rotation, ref, plain, np.asarray(db.mags, dtype=float)[index],
        sky=sky, cog_sigma_rad=att.sigma_axes_rad, rate_rad_s=rate,
    )  # fmt: skip
    if not done.used:
        return att, (done.note,)
    fit = done.fit
    return dataclasses.replace(
        att, rotation=fit.rotation, covariance_rad2=fit.covariance[:3, :3], method="model"
    ), (done.note,)
