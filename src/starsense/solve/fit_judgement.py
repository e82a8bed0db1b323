"""Whether the forward model's fit of a frame is used, and the covariance it reports.

The solution's covariance is the inverse Fisher information at the fit (the Cramer-Rao bound of
the model), which the datasheet predicts. Where the pixels scatter more than the model allows
(a reduced chi-square above :data:`SCALED_CHI2`: a lens's PSF a little off the TOML's, a camera
whose gain or read noise differ from the sensor's), each axis's variance is raised to what the
pixels' own scatter gives (the sandwich of the groups' scores: a profile error symmetric about
the stars, which does not move them, does not raise it) and the note says so. Above
:data:`MAX_REDUCED_CHI2`, a fit whose misfit also pulls the attitude
(:func:`starsense.model.misfit.misfit_pulls`: the stars' scores scatter beyond what the pixels'
excess explains, as where the sensor's PSF or optics do not describe a real camera's) does
not place the stars, and the model-free centroids' attitude is kept (the fit stops a step
past its start); a fit whose misfit is a profile error about the stars (a lens's Airy or
Moffat PSF drawn as a Gaussian of its width, which bright stars show as a reduced chi-square
of 4-10) stands, with the sandwich's sigmas.
Where the frame's chi-square shows nothing but some windows pull the attitude more than the
model's noise allows (a streak's end or an overlap drawn wrong: the groups' scores scatter
beyond the Fisher bound by :data:`LOCAL_MISFIT_SIGMAS` of their own noise), the sandwich gives
the sigmas too.
A fit that does not converge keeps the centroid attitude and says why. At rest, so does a fit
that moves the attitude further than :data:`MAX_MOVE_SIGMAS` of the two solutions' sigmas from
the centroid attitude (a move that shifts no star by :data:`MAX_MOVE_PX` is kept: the two
estimators of an imperfectly known PSF's centre may disagree by that much), unless most
centroids agree with the fit at least as well as with their own attitude (the median of their
normalised residuals, :func:`starsense.attitude.robust.median_misfit`, no larger at the fit's):
a least-squares attitude follows a blend or two that the median, and the fit, ignore (ten
centroids, two of them 7-12 of their sigmas off on blends, moved theirs 200 arcsec and 8 of its
sigmas from a fit 4 arcsec from the truth; their median residual was 2.7 sigma at their own
attitude and 1.2 at the fit's). A fit that moves every star off its centroid raises that median
and stays refused. A smeared frame's
streak centroids are no such reference: their attitude's sigma leaves out where along its
streak each centroid lies, and a 1 s frame at 1 deg/s (48 px streaks) had its centroid attitude
5-15 of those sigmas off while the fit refused for moving from it was within its own sigma.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from starsense.geometry.attitude import small_rotation_angles
from starsense.model.fit import ModelFit
from starsense.model.misfit import misfit_pulls, sandwich_exceeds

__all__ = [
    "LOCAL_MISFIT_SIGMAS",
    "MAX_MOVE_PX",
    "MAX_MOVE_SIGMAS",
    "MAX_REDUCED_CHI2",
    "SCALED_CHI2",
    "Refinement",
    "judged",
    "local_misfit",
    "robust_covariance",
]

#: a fit whose pixels' reduced chi-square exceeds this has its covariance scaled by it (the
#: chi-square of a right model over N ~ 10^3 pixels lies within 1 +- 0.1)
SCALED_CHI2 = 1.3
#: a fit whose pixels' reduced chi-square exceeds this, and whose misfit pulls the attitude
#: (:func:`starsense.model.misfit.misfit_pulls`), does not describe the frame (a camera's PSF
#: and optics the sensor does not give): the model-free centroids' attitude is kept. Above
#: :data:`SCALED_CHI2` otherwise, the covariance is the sandwich's.
MAX_REDUCED_CHI2 = 4.0
#: a model fit further than this many centroid sigmas from the centroid attitude is refused...
MAX_MOVE_SIGMAS = 8.0
#: ...when it also moves a star by more than this, px: a real lens's asymmetric PSF puts a
#: centre of gravity a fraction of a pixel from a symmetric profile's centre, a wrong
#: solution is pixels to degrees away
MAX_MOVE_PX = 0.25


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


#: a sandwich variance above the Fisher bound's by this many of its own relative noise
#: (:attr:`~starsense.model.fit.ModelFit.robust_noise`) is a misfit
LOCAL_MISFIT_SIGMAS = 3.0


def local_misfit(fit: ModelFit) -> bool:
    """Whether the groups' scores scatter more than the model's noise allows, on an axis.

    The sandwich (:attr:`~starsense.model.fit.ModelFit.robust_covariance`) estimates each
    axis's variance from the groups' scores: about the Fisher bound's when the model describes
    every window, above it when some windows pull the attitude (a streak's clipped end, an
    overlap the model draws wrong) even where the frame's reduced chi-square, summed over
    every pixel, shows nothing. Above the bound by :data:`LOCAL_MISFIT_SIGMAS` of the
    estimate's own noise (:attr:`~starsense.model.fit.ModelFit.robust_noise`) is a misfit.
    """
    beyond = sandwich_exceeds(
        fit.covariance,
        fit.robust_covariance,
        fit.robust_noise,
        scale=1.0,
        sigmas=LOCAL_MISFIT_SIGMAS,
    )
    return bool(beyond)


def robust_covariance(fit: ModelFit) -> np.ndarray:
    """Return the sandwich covariance, each axis at least the Fisher bound's."""
    cov, rob = fit.covariance, fit.robust_covariance
    if rob is None or not np.all(np.isfinite(rob)):
        return cov * fit.reduced_chi2
    scale = np.sqrt(np.maximum(np.diag(rob) / np.diag(cov), 1.0))
    return cov * np.outer(scale, scale)


def judged(
    fit: ModelFit, sensor, rotation, *, cog_sigma_rad, counts, also="", misfit=None
) -> Refinement:
    """Accept the fit (its covariance scaled by a reduced chi-square above 1), or say why not.

    ``counts``: the stars fitted and the neighbours drawn; ``also``: appended to the note of
    an accepted fit (why no larger fit was made); ``misfit``: ``misfit(rotation=R)``, the
    median of the centroids' normalised residuals at an attitude (None: the move rule alone).
    """
    n_stars, n_nbr = counts
    bad = fit.reduced_chi2 > MAX_REDUCED_CHI2 and misfit_pulls(fit)
    if not math.isfinite(fit.reduced_chi2) or bad:
        why = (
            f"reduced chi-square {fit.reduced_chi2:.3g} > {MAX_REDUCED_CHI2:g}, and the misfit "
            "moves the stars"
        )
        return Refinement(
            fit, False, f"model fit not used: the pixels disagree with the model ({why})", n_nbr
        )
    if not fit.converged:
        return Refinement(fit, False, "model fit did not converge", n_nbr)
    if not np.all(np.isfinite(fit.sigma_axes_rad)) or not math.isfinite(fit.reduced_chi2):
        return Refinement(fit, False, "model fit not used: singular information", n_nbr)
    note = f"model fit ({fit.n_pixels} px, {n_stars} stars, {n_nbr} neighbours){also}"
    local = local_misfit(fit)
    if fit.reduced_chi2 > SCALED_CHI2:  # the pixels scatter more than the model says
        fit = dataclasses.replace(fit, covariance=robust_covariance(fit))
        note += (
            f"; sigmas from the pixels' own scatter (reduced chi-square {fit.reduced_chi2:.3g}: "
            "they scatter more than the sensor's PSF and noise model allow)"
        )
    elif local:
        fit = dataclasses.replace(fit, covariance=robust_covariance(fit))
        note += (
            "; sigmas from the stars' own scatter (some windows' pixels pull the attitude more "
            "than the model's noise allows)"
        )
    move = np.abs(small_rotation_angles(fit.rotation, rotation))
    scale = np.hypot(np.asarray(cog_sigma_rad, float), fit.sigma_axes_rad)
    det = sensor.detector
    edge = 0.5 * math.hypot(det.columns, det.rows)  # the farthest a star sits from the axis, px
    moved_px = math.hypot(move[0], move[1]) * sensor.focal_length_px + move[2] * edge
    # a smeared frame's centroids (its streaks') are no reference for the fit: their attitude's
    # sigma leaves out where along its streak each centroid lies. The frame is smeared when the
    # fit draws a motion (a rate fitted: attitude and rate, 6 parameters, 7 with the PSF's
    # width; or given); a fit at rest that also fits the width has 4
    smeared = fit.covariance.shape[0] >= 6 or bool(np.any(fit.rate_rad_s != 0.0))
    far = np.any(move > MAX_MOVE_SIGMAS * scale) and moved_px > MAX_MOVE_PX
    if not smeared and far and not _centroids_agree(misfit, fit.rotation, rotation):
        return Refinement(
            fit,
            False,
            f"model fit not used: {float(np.max(move / scale)):.1f} sigma from the centroids'",
            n_nbr,
        )
    return Refinement(fit, True, note, n_nbr)


def _centroids_agree(misfit, fitted, centroid) -> bool:
    """Whether most centroids sit as close to the ``fitted`` attitude as to their own."""
    if misfit is None:
        return False
    return misfit(rotation=fitted) <= misfit(rotation=centroid)
