"""The final attitude of a solve, robust to a blended or double star."""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy.special import gammaincinv

from starsense.attitude.estimate import estimate_attitude

__all__ = [
    "MIN_DOF_LOWERED",
    "MISFIT_SIGMAS",
    "OUTLIER_SIGMA",
    "RESIDUALS_P",
    "SCATTER_STARS",
    "median_misfit",
    "pair_disagreements",
    "pair_outliers",
    "pair_scatter",
    "residual_scaled",
    "residuals_beyond_noise",
    "robust_attitude",
]


#: a matched star whose residual exceeds this many of its own 1-sigma (per axis, so ~ sqrt(2)
#: sigma expected in angle) is dropped from the final attitude: a blend or a close double star
OUTLIER_SIGMA = 7.0
#: an attitude whose kept stars lie a median of more than this many of their own sigma from it
#: does not fit its measurements (right ones: 1.18); the solver reports no attitude
MISFIT_SIGMAS = 10.0
#: the chance, for stars whose sigmas are right, that their residuals' chi-square exceeds the
#: bound :func:`residuals_beyond_noise` tests
RESIDUALS_P = 1e-3
#: the fewest degrees of freedom (2 N - 3 for N stars) whose residuals may lower a covariance
#: (:func:`residual_scaled`): 20, eleven or more stars
MIN_DOF_LOWERED = 20
#: the stars from which :func:`robust_attitude` (``scatter=True``) measures their own scatter:
#: with fewer, a star or two centroided off their light weigh in each right star's median (one
#: 30-sigma blend among 5 stars hid in the scatter it raised in 3 % of draws, 2 among 6 in
#: 24 %, 2 among 8 in 1.1 %, 2 among 10 in 0.1 %; 2 or 3 among 12 or 16, none in 1,000)
SCATTER_STARS = 8


def pair_disagreements(body, reference) -> np.ndarray:
    """Return ``|angle(body_i, body_j) - angle(reference_i, reference_j)|``, rad, (N, N).

    The measured angle between two stars less the catalogue's: it does not depend on the
    attitude (:func:`pair_outliers`, :func:`pair_scatter`).
    """
    return np.abs(_pair_angles(body) - _pair_angles(reference))


def _off_diagonal(z: np.ndarray) -> np.ndarray:
    """Each row of the (N, N) ``z`` without its diagonal element, (N, N - 1)."""
    n = len(z)
    # the flat matrix less its first element, cut into rows of n + 1 that each end on the next
    # diagonal element
    return z.reshape(-1)[1:].reshape(n - 1, n + 1)[:, :-1].reshape(n, n - 1)


def _row_medians(off: np.ndarray) -> np.ndarray:
    """np.median(off, axis=1) (the mean of the middle two of an even count), without its cost."""
    m = off.shape[1]
    lo, hi = (m - 1) // 2, m // 2
    part = np.partition(off, (lo, hi), axis=1)
    return 0.5 * (part[:, lo] + part[:, hi])


def pair_scatter(body, reference, *, disagreements=None) -> float:
    """Return the stars' per-axis noise as their angles to each other show it, rad.

    The angle between two right stars, measured less catalogue, is a normal error of variance
    ``2 sigma^2`` for stars of per-axis sigma ``sigma`` (each one's error along the line joining
    them), whatever the attitude: its absolute value over ``sqrt(2)`` is half-normal of scale
    sigma. Each star's median over its pairs, then the median over the stars, over the
    half-normal median (0.674): stars centroided off their light (fewer than half) touch only
    their own pairs, a minority of each right star's, and no fit is pulled by them.

    Parameters
    ----------
    body, reference : ndarray (N, 3)
        Measured (camera) and catalogue (ICRS) unit vectors of the matched stars, N >= 3.
    disagreements : ndarray (N, N), optional
        :func:`pair_disagreements` of the same stars, when already computed.

    Returns
    -------
    float
        The estimated 1-sigma direction noise per axis, rad.
    """
    d = pair_disagreements(body, reference) if disagreements is None else disagreements
    per_star = _row_medians(_off_diagonal(d))
    return float(_row_medians(per_star[None, :])[0]) / (_HALF_NORMAL_MEDIAN * math.sqrt(2.0))


def pair_outliers(body, reference, sigma_rad, *, disagreements=None) -> np.ndarray:
    """Return the stars whose angles to the others disagree with the catalogue's.

    The angle between two stars does not depend on the attitude: measured less catalogue, it
    is a normal error of variance ``sigma_i^2 + sigma_j^2`` (each star's error along the line
    joining them). A star centroided far from its own light (two streaks crossing, a capsule
    slid onto a neighbour) disagrees with most others; a right one agrees with every right one.
    A star is an outlier when the median of its normalised disagreements exceeds
    ``OUTLIER_SIGMA`` times the median of a half-normal (0.674): the median ignores the other
    outliers as long as they are fewer than half. Unlike the residuals of a fit, which one
    heavily weighted outlier can drag onto itself, this cannot be masked.

    Parameters
    ----------
    body, reference : ndarray (N, 3)
        Measured (camera) and catalogue (ICRS) unit vectors of the matched stars.
    sigma_rad : ndarray (N,)
        Each star's 1-sigma direction noise per axis, rad.
    disagreements : ndarray (N, N), optional
        :func:`pair_disagreements` of the same stars, when already computed.

    Returns
    -------
    ndarray of bool (N,)
        True for an outlier (none when fewer than 5 stars, or half or more disagree).
    """
    n = len(body)
    if n < 5:
        return np.zeros(n, dtype=bool)
    var = sigma_rad[:, None] ** 2 + sigma_rad[None, :] ** 2
    d = pair_disagreements(body, reference) if disagreements is None else disagreements
    z = d / np.sqrt(var)
    off = _off_diagonal(z)  # each row without its diagonal (a star against itself)
    if np.isnan(off).any():  # a sigma of zero: the medians of the values there are
        np.fill_diagonal(z, np.nan)
        median = np.nanmedian(z, axis=1)
    else:
        median = _row_medians(off)
    bad = median > OUTLIER_SIGMA * _HALF_NORMAL_MEDIAN
    return bad if 2 * bad.sum() < n else np.zeros(n, dtype=bool)


def _pair_angles(v: np.ndarray) -> np.ndarray:
    """Return the angles between every two of the unit vectors ``v`` (N, 3), rad, (N, N).

    ``2 asin(c / 2)`` of their chords ``c = sqrt(2 - 2 v_i . v_j)`` (one matrix product): the
    dot product's rounding (1e-16) moves the chord squared by as much, an angle of 1e-3 rad
    (two stars a few pixels apart) by 1e-13 rad, far below any centroid's noise. A star's
    angle to itself is 0.
    """
    chord = np.sqrt(np.maximum(2.0 - 2.0 * (v @ v.T), 0.0))
    out = 2.0 * np.arcsin(np.minimum(0.5 * chord, 1.0))
    np.fill_diagonal(out, 0.0)
    return out


#: the median of |x| for a unit normal x
_HALF_NORMAL_MEDIAN = 0.6744897501960817


def robust_attitude(
    body, reference, sigma_rad, *, max_drop: int = 5, keep=None, fit=None, scatter: bool = False
):
    """Estimate the attitude, dropping the stars whose residual is an outlier.

    A blended or double star is identified right but centroided at the photocentre of the
    pair: its residual is many of its own sigma, and left in it pulls the attitude. The stars
    whose angles to the others disagree with the catalogue's are dropped first
    (:func:`pair_outliers`: several gross outliers, one of which a fit would follow); then,
    while the worst residual exceeds ``OUTLIER_SIGMA`` sigma and more than three stars remain,
    that star is dropped and the attitude re-estimated (SVD, Wahba weights 1 / sigma^2).

    With ``scatter``, the sigmas given are a floor, not a measurement (a centroid list, whose
    noise nothing states): where the fit at them would test a star as an outlier, they are
    first raised to the stars' own scatter (:func:`pair_scatter`, from at least
    ``SCATTER_STARS`` stars). At sigmas below the centroids' true noise the drops take right
    stars (1 px centroids tested at 0.3 px: about one star in nine beyond 7 sigma) and leave a
    subset that agrees with a pulled attitude: sets of 1 px noise solved 1.0-1.13 arcmin off
    where the fit of all their matched stars was 0.5 arcmin off. The pairs' medians ignore the
    stars centroided off their light (fewer than half), which the drops then test as before;
    where the floor drops nothing, nothing changes (a larger sigma drops nothing either).

    Parameters
    ----------
    body, reference : ndarray (N, 3)
        Measured (camera) and catalogue (ICRS) unit vectors of the matched stars.
    sigma_rad : float or ndarray (N,)
        Each star's 1-sigma direction noise, rad.
    max_drop : int
        Most stars dropped.
    keep : ndarray (N,) of bool, optional
        The stars to start from (a refit after a first one's outliers), in place of
        :func:`pair_outliers`'.
    fit : callable, optional
        ``fit(body, reference, sigma) -> AttitudeSolution``, the weighted SVD fit of vectors
        already checked (unit, finite, sigma > 0), raising SingularGeometryError as
        :func:`~starsense.attitude.estimate_attitude` does: a faster form of the same
        estimator (the solver's compiled one, equal to rounding). Default:
        ``estimate_attitude(..., method="svd")``, which checks its input.
    scatter : bool
        The sigmas are a floor, raised to the stars' own scatter where it decides a drop
        (without ``keep``).

    Returns
    -------
    AttitudeSolution, and the mask of the stars kept (N,)
    """
    fit = _svd if fit is None else fit
    n = len(body)
    sigma = np.asarray(sigma_rad, dtype=float)
    sigma = np.full(n, float(sigma)) if sigma.ndim == 0 else np.broadcast_to(sigma, (n,))
    if keep is None:
        att = fit(body, reference, sigma)
        keep = np.ones(n, dtype=bool)
        if float((att.residuals_rad / sigma).max()) <= _NO_PAIR_OUTLIER:
            return att, keep  # no pair outlier (_NO_PAIR_OUTLIER), none to drop: the usual case
        if n >= 5:
            d = pair_disagreements(body, reference)
            if scatter and n >= SCATTER_STARS:
                own = pair_scatter(body, reference, disagreements=d)
                if own > float(sigma.min()):
                    sigma = np.maximum(sigma, own)
                    att = fit(body, reference, sigma)
                    if float((att.residuals_rad / sigma).max()) <= _NO_PAIR_OUTLIER:
                        return att, keep
            keep = ~pair_outliers(body, reference, sigma, disagreements=d)
            if not keep.all():
                att = fit(body[keep], reference[keep], sigma[keep])
    else:
        keep = np.array(keep, dtype=bool)
        att = fit(body[keep], reference[keep], sigma[keep])
    n_kept = int(np.count_nonzero(keep))
    for _ in range(max_drop):
        if n_kept <= 3:
            break
        z = att.residuals_rad / sigma[keep]
        worst = int(np.argmax(z))
        if z[worst] <= OUTLIER_SIGMA:
            break
        keep[np.flatnonzero(keep)[worst]] = False  # the first of the worst, as over all N
        n_kept -= 1
        att = fit(body[keep], reference[keep], sigma[keep])
    return att, keep


#: The largest residual, in its own sigmas, of a fit to all the matched stars that leaves every
#: pair below :func:`pair_outliers`' threshold: by the triangle inequality on the sphere, stars
#: i and j whose residuals to an attitude are r_i and r_j disagree with the catalogue's angle
#: between them by at most r_i + r_j <= max_k(r_k / sigma_k) (sigma_i + sigma_j), at most
#: sqrt(2) max_k(r_k / sigma_k) times their pair's sigma. Below it pair_outliers would find
#: no outlier and the N^2 angles are not computed. A relative 1e-9 below the bound, far beyond
#: rounding; it is below OUTLIER_SIGMA, so such a fit has no residual to drop either.
_NO_PAIR_OUTLIER = OUTLIER_SIGMA * _HALF_NORMAL_MEDIAN / math.sqrt(2.0) * (1.0 - 1e-9)


def _svd(body, reference, sigma):
    return estimate_attitude(body, reference, sigma, method="svd")


def median_misfit(body, reference, sigma_rad, *, rotation, keep=None) -> float:
    """Return the median of the stars' residuals to an attitude in units of their own sigma.

    ``body`` (N, 3) camera-frame and ``reference`` (N, 3) unit vectors, ``sigma_rad`` (N,) or a
    number, ``rotation`` reference -> camera, ``keep`` (N,) the stars to count (default all).
    Right measurements give about 1.18 (the median of a 2-d residual of per-axis sigma 1);
    measurements all off their stars by many of their sigmas give that many.
    """
    body = np.asarray(body, dtype=float)
    keep = np.ones(len(body), bool) if keep is None else np.asarray(keep, bool)
    if not keep.any():
        return 0.0
    seen = rotation.apply(np.asarray(reference, dtype=float)[keep])
    angle = np.linalg.norm(np.cross(body[keep], seen), axis=1)
    sigma = np.broadcast_to(np.asarray(sigma_rad, dtype=float), (len(body),))[keep]
    return float(np.median(angle / sigma))


def residual_scaled(att):
    """Return ``att`` with its covariance scaled to what its residuals show.

    The covariance of a Wahba fit assumes the stars' sigmas; where the residuals scatter more
    (``2 loss / (2 N - 3)`` above 1: a centroid pulled by light its sigma does not hold, a
    lens's distortion left), the variance is scaled by that ratio (the Birge ratio), so the
    reported sigma stays what the stars show. Where they scatter less (bright stars given a
    sigma meant for faint ones), it is lowered only as far as the chi-square's 95 % upper bound
    (``chi2 / chi2_0.05(dof)``), and only with :data:`MIN_DOF_LOWERED` degrees of freedom:
    with few stars the ratio scatters and a sigma below the stars' own would be a guess.
    """
    dof = att.chi2_dof
    if dof <= 0 or not np.isfinite(att.loss):
        return att
    chi2 = 2.0 * float(att.loss)
    if chi2 > dof:
        scale = chi2 / dof
    elif dof >= MIN_DOF_LOWERED:
        scale = min(1.0, chi2 / _chi2_quantile(dof, 0.05))
    else:
        return att
    return att.replaced(covariance_rad2=np.asarray(att.covariance_rad2) * scale)


@functools.lru_cache(maxsize=1024)
def _chi2_quantile(dof: int, q: float) -> float:
    """Return the ``q`` quantile of a chi-square of ``dof`` degrees of freedom (cached)."""
    return 2.0 * float(gammaincinv(0.5 * dof, q))


def residuals_beyond_noise(att, p: float = RESIDUALS_P) -> bool:
    """Whether the residuals of ``att`` scatter beyond what the stars' sigmas allow.

    True where their chi-square (``2 loss``) exceeds the upper ``p`` quantile of a chi-square
    of ``2 N - 3`` degrees of freedom: the stars' sigmas, or their model, do not describe them.
    """
    dof = att.chi2_dof
    if dof <= 0 or not np.isfinite(att.loss):
        return False
    return 2.0 * float(att.loss) > _chi2_quantile(dof, 1.0 - p)
