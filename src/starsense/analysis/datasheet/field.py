"""Attitude noise over the sky: per-star sigmas through eq. 21, pointing by pointing.

For every attitude of a set (quasi-uniform boresights, or the Monte Carlo's true attitudes),
the catalogue stars inside the sensor's rectangular field are found once
(:func:`starsense.analysis.availability.field.field_pairs`), put in the camera frame, and
their per-star information ``1 / sigma_i^2`` summed into the attitude Fisher matrix (Fialho &
Mortari 2019, eq. 21, :func:`starsense.attitude.covariance.fisher_components`). The inverse,
in the camera frame, gives the 1-sigma cross-boresight (rms of the x and y axes) and roll
(about z) of that attitude.

The stars are those the solver fits its attitude to, each counted by its chance of being in a
frame's fit (:mod:`starsense.analysis.datasheet.stars`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from starsense.analysis.availability.field import field_pairs_cam
from starsense.attitude.covariance import (
    SINGULAR_RCOND,
    fisher_components,
    fisher_from_components,
)

__all__ = [
    "FieldStarsCam",
    "axis_sigmas",
    "field_stars_cam",
    "fisher_per_pointing",
    "propagated_covariance",
    "propagated_sigmas",
    "sandwich_terms",
]


class FieldStarsCam:
    """The (pointing, star) pairs of a set of attitudes, with camera-frame star vectors.

    Parameters
    ----------
    point : ndarray (P,) of int
        Pointing of each pair.
    star : ndarray (P,) of int
        Catalogue index of each pair.
    v_cam : ndarray (P, 3)
        Star unit vector in the camera frame.
    n_pointings : int
        Number of attitudes.
    """

    def __init__(self, point, star, v_cam, *, n_pointings: int) -> None:
        self.point = point
        self.star = star
        self.v_cam = v_cam
        self.n_pointings = int(n_pointings)

    def counts(self, mask: NDArray[np.bool_] | None = None) -> NDArray[np.intp]:
        """Return the stars per pointing (only the pairs in ``mask`` if given)."""
        p = self.point if mask is None else self.point[mask]
        return np.bincount(p, minlength=self.n_pointings)


def field_stars_cam(fov, matrices: NDArray[np.float64], vectors: NDArray[np.float64], *, tree=None):
    """Return the :class:`FieldStarsCam` of attitudes ``matrices`` (M, 3, 3), ICRS -> camera."""
    point, star, v_cam = field_pairs_cam(fov, matrices, vectors, tree=tree)
    return FieldStarsCam(point, star, v_cam, n_pointings=matrices.shape[0])


def fisher_per_pointing(
    pairs: FieldStarsCam, weights: NDArray[np.float64], shape=None
) -> np.ndarray:
    """Return eq. 21 per pointing, camera frame, (M, 3, 3) rad^-2.

    Parameters
    ----------
    pairs : FieldStarsCam
        Stars in the field of each attitude.
    weights : ndarray (P,)
        Information of each pair's star, ``1 / sigma^2``, rad^-2 (0 drops the pair).
    shape : (ndarray (P,), ndarray (P,)), optional
        ``(a, c)``: each star's information is ``w (I + D)`` in the image plane, not ``w I``,
        with ``D = [[a, c], [c, -a]]`` (a PSF that is not round is located better across its
        long axis than along it); its part ``sum w T^T D T`` is added (``T`` a rotation's move
        of the star in its tangent plane, along the pixel axes there). Default: round.
    """
    comp = fisher_components(pairs.v_cam, weights)
    if shape is not None:
        comp = np.column_stack([comp, _shape_components(pairs.v_cam, weights, shape)])
    sums = np.zeros((pairs.n_pointings, comp.shape[1]))
    point = np.asarray(pairs.point)
    if point.size and np.all(point[1:] >= point[:-1]):  # grouped by pointing: segment sums
        starts = np.searchsorted(point, np.arange(pairs.n_pointings))
        held = np.bincount(point, minlength=pairs.n_pointings) > 0
        sums[held] = np.add.reduceat(comp, starts[held], axis=0)
    else:
        np.add.at(sums, point, comp)
    f = fisher_from_components(sums[:, :7])
    if shape is not None:
        xx, yy, zz, xy, xz, yz = sums[:, 7:].T
        f = f + np.stack([np.stack([xx, xy, xz], -1), np.stack([xy, yy, yz], -1),
                          np.stack([xz, yz, zz], -1)], -2)  # fmt: skip
    return f


def _shape_components(v_cam, weights, shape) -> np.ndarray:
    """Return the six terms (xx, yy, zz, xy, xz, yz) of ``w T^T D T`` per pair (P, 6).

    ``T`` (2 x 3) takes a small rotation to the star's move in its tangent plane, along the
    pixel rows' direction there (``e1``, the camera x axis made normal to the star) and
    ``e2 = v x e1``: ``T^T T = I - v v^T``, eq. 21's round part, of which this is the
    anisotropic rest (the pixel axes seen from the star, as eq. 21 sees the pixel there).
    """
    a, c = (np.asarray(t, dtype=float) for t in shape)
    v = np.asarray(v_cam, dtype=float)
    e1 = np.zeros_like(v)
    e1[:, 0] = 1.0
    e1 -= v[:, :1] * v
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(v, e1)
    # the move of v under theta is theta x v; its e_k part is e_k . (theta x v) = (v x e_k) . theta
    t = np.stack([np.cross(v, e1), np.cross(v, e2)], axis=1)
    d = np.empty((len(a), 2, 2))
    d[:, 0, 0], d[:, 1, 1], d[:, 0, 1], d[:, 1, 0] = a, -a, c, c
    m = np.einsum("pai,pab,pbj->pij", t, d, t) * np.asarray(weights, dtype=float)[:, None, None]
    return np.column_stack([m[:, 0, 0], m[:, 1, 1], m[:, 2, 2], m[:, 0, 1], m[:, 0, 2], m[:, 1, 2]])


def axis_sigmas(fishers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return the 1-sigma cross-boresight (per axis, rms of x and y) and roll of each Fisher.

    Parameters
    ----------
    fishers : ndarray (M, 3, 3)
        Camera-frame attitude Fisher matrices, rad^-2.

    Returns
    -------
    cross, roll : ndarray (M,)
        rad; NaN where the matrix is singular (fewer than two usable stars).
    """
    f = np.asarray(fishers, dtype=float)
    eig = np.linalg.eigvalsh(f)
    ok = eig[:, 0] > SINGULAR_RCOND * np.maximum(eig[:, -1], np.finfo(float).tiny)
    cross = np.full(len(f), np.nan)
    roll = np.full(len(f), np.nan)
    if ok.any():
        p = np.linalg.inv(f[ok])
        cross[ok] = np.sqrt(0.5 * (p[:, 0, 0] + p[:, 1, 1]))
        roll[ok] = np.sqrt(p[:, 2, 2])
    return cross, roll


def propagated_sigmas(
    pairs: FieldStarsCam,
    weights: NDArray[np.float64],
    error_rad: NDArray[np.float64],
    *,
    presence: NDArray[np.float64] | None = None,
    shape=None,
    efficient: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Return the attitude error a per-star error makes through the weighted estimate, rad.

    The estimator weights each star by ``weights`` (its NEA information, eq. 21); a star
    carrying an independent error of ``error_rad`` (1 sigma per axis: a sub-pixel bias met at a
    random phase, a PRNU-driven shift, a calibration residual) moves the estimate by the
    weighted least-squares sandwich ``F^-1 G F^-1``, with ``F = sum w (I - r r^T)`` and
    ``G = sum w^2 e^2 (I - r r^T)``: an error, not a weight, so stars with small errors do not
    hide the others.

    Parameters
    ----------
    pairs : FieldStarsCam
        Stars in the field of each attitude.
    weights : ndarray (P,)
        The estimator's weight of each pair, rad^-2.
    error_rad : ndarray (P,)
        Each pair's error, 1 sigma per axis, rad.
    presence : ndarray (P,), optional
        The chance each pair's star is in the fit (detected): both sums are their expectations
        over the frames, ``sum p w`` and ``sum p w^2 e^2``. Default: every star, always.
    shape, efficient
        A PSF that is not round, and whether the error is the noise of the fit that weighs
        (:func:`sandwich_terms`).

    Returns
    -------
    cross, roll : ndarray (M,)
        rad (rms of x and y; about z); NaN where F is singular.
    """
    terms = sandwich_terms(
        pairs, weights, error_rad, presence=presence, shape=shape, efficient=efficient
    )
    return _sandwich(*terms)


def sandwich_terms(
    pairs: FieldStarsCam, weights, error_rad, *, presence=None, shape=None, efficient=False
) -> tuple[np.ndarray, np.ndarray]:
    """Return ``F = sum p w (I - r r^T)`` and ``G = sum p w^2 e^2 (I - r r^T)`` per attitude.

    The two sums (M, 3, 3) of :func:`propagated_sigmas`' sandwich ``F^-1 G F^-1``
    (``weights`` (P,) rad^-2 and ``error_rad`` (P,) rad per pair, a non-finite one counting as
    0; ``presence`` (P,) the chance each star is in the fit, default 1). With ``shape``
    (:func:`fisher_per_pointing`) the weights are ``w (I + D)``, and the error is round
    (``e^2 I``: G's shape follows), or, with ``efficient``, the inverse of each star's
    information (the noise of an efficient fit: ``G = F``).
    """
    w = np.where(np.isfinite(weights), weights, 0.0)
    e2 = np.where(np.isfinite(error_rad), np.asarray(error_rad, dtype=float) ** 2, 0.0)
    p = 1.0 if presence is None else np.asarray(presence, dtype=float)
    f = fisher_per_pointing(pairs, p * w, shape)
    if shape is None:
        return f, fisher_per_pointing(pairs, p * w * w * e2)
    if efficient:  # each star's error covariance is the inverse of its information: G = F
        return f, f
    # G = sum w^2 e^2 J^T (I + D)^2 J, and (I + D)^2 = (1 + a^2 + c^2) I + 2 D
    a, c = (np.asarray(t, dtype=float) for t in shape)
    k = 1.0 + a * a + c * c
    return f, fisher_per_pointing(pairs, p * w * w * e2 * k, (2.0 * a / k, 2.0 * c / k))


def _sandwich(f: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return cross and roll (rad) of ``F^-1 G F^-1`` per pointing; NaN where F is singular."""
    eig = np.linalg.eigvalsh(f)
    ok = eig[:, 0] > SINGULAR_RCOND * np.maximum(eig[:, -1], np.finfo(float).tiny)
    cross = np.full(len(f), np.nan)
    roll = np.full(len(f), np.nan)
    if ok.any():
        finv = np.linalg.inv(f[ok])
        cov = finv @ g[ok] @ finv
        cross[ok] = np.sqrt(0.5 * (cov[:, 0, 0] + cov[:, 1, 1]))
        roll[ok] = np.sqrt(cov[:, 2, 2])
    return cross, roll


def propagated_covariance(
    pairs: FieldStarsCam, weights: NDArray[np.float64], cov_rad2: NDArray[np.float64]
) -> tuple[np.ndarray, np.ndarray]:
    """Return the attitude error per-star error covariances make through the weighted estimate.

    :func:`propagated_sigmas` for errors that are not the same on both axes (a streak's
    centroid is worse along it than across): the weighted least-squares sandwich
    ``F^-1 G F^-1`` with ``F = sum w (I - r r^T)`` and ``G = sum w^2 [r]x^T C [r]x``, ``C``
    each star's 3 x 3 error covariance in the plane normal to it (for ``C = e^2 (I - r r^T)``
    this is :func:`propagated_sigmas`).

    Parameters
    ----------
    pairs : FieldStarsCam
        Stars in the field of each attitude.
    weights : ndarray (P,)
        The estimator's weight of each pair, rad^-2.
    cov_rad2 : ndarray (P, 3, 3)
        Each pair's error covariance (camera frame), rad^2.

    Returns
    -------
    cross, roll : ndarray (M,)
        rad (rms of x and y; about z); NaN where F is singular.
    """
    w = np.where(np.isfinite(weights), weights, 0.0)
    c = np.where(np.isfinite(cov_rad2), np.asarray(cov_rad2, dtype=float), 0.0)
    r = np.asarray(pairs.v_cam, dtype=float)
    skew = np.zeros((len(r), 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -r[:, 2], r[:, 1], -r[:, 0]
    skew -= np.transpose(skew, (0, 2, 1))
    terms = (w * w)[:, None, None] * np.einsum("pji,pjk,pkl->pil", skew, c, skew)
    g = np.zeros((pairs.n_pointings, 3, 3))
    np.add.at(g, np.asarray(pairs.point), terms)
    f = fisher_per_pointing(pairs, w)
    return _sandwich(f, g)
