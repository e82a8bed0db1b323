"""Centroid noise of tracked stars, a robust attitude fit, and the covariance of that fit.

Each star's centroid error (pixels) has the covariance

    C_i = (sigma_psf^2 / N_i) I_2 + (sigma_r^2 / N_i^2) S_i + (1 / (12 N_i)) l_i l_i^T

with ``N_i`` the star's electrons: photon noise of the PSF; read noise ``sigma_r`` over the
centroid window, ``S_i`` the 2 x 2 sum of (pixel - centroid)(pixel - centroid)^T over it (the
window along the streak, :func:`starsense.detect.streak.streak_centroid`; for a static star
the isotropic form of :func:`starsense.detect.centroid.cog_sigma_px`); and the streak ``l_i``
(start to end, px) adding l l^T / 12 per photon (a uniform spread along it). The SVD estimator
weighs star ``i`` by the mean of the two axes, ``sigma_i^2 = tr(C_i) / 2``; the covariance of
that estimator is the sandwich

    P = F^-1 (sum_i w_i^2 J_i^T N_i J_i) F^-1,    F = sum_i w_i (I - b_i b_i^T),  w_i = sigma_i^-2

with ``J_i = -[b_i]x`` and ``N_i = G_i C_i G_i^T`` the centroid covariance carried to the unit
vector (``G_i`` the 3 x 2 derivative of the sensor's unprojection). For isotropic noise it is the
inverse Fisher matrix of Fialho & Mortari 2019, eq. 21 (:mod:`starsense.attitude.covariance`);
along a streak it is larger in the axis the streaks point along and smaller across it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from starsense.attitude.covariance import SINGULAR_RCOND, fisher_covariance
from starsense.attitude.solution import AttitudeSolution
from starsense.attitude.svd import wahba_matrix
from starsense.detect.centroid import cog_sigma_px
from starsense.detect.streak import columns
from starsense.identify.track_kernels import (
    fisher_inverse_compiled,
    fit_compiled,
    sandwich_compiled,
    sandwich_numpy,
)

__all__ = [
    "OUTLIER_SIGMA",
    "StarNoise",
    "fit_robust",
    "fit_robust_matrix",
    "rms_angle",
    "star_noise",
]

_EYE2 = np.eye(2)

#: A star whose residual exceeds this many of its own sigmas is dropped from the fit (a 2-D
#: residual goes past 4 sigma by chance with probability exp(-8) = 3e-4)
OUTLIER_SIGMA = 4.0


@dataclass(frozen=True)
class StarNoise:
    """Per-star centroid covariance of matched detections (module docstring).

    Attributes
    ----------
    sensor : Sensor
    x, y : ndarray, shape (N,)
        Centroids, px.
    cov_px2 : ndarray, shape (N, 2, 2)
        ``C_i``, px^2 (x = column, y = row).
    """

    sensor: object
    x: np.ndarray
    y: np.ndarray
    cov_px2: np.ndarray

    @property
    def sigma_rad(self) -> np.ndarray:
        """Mean-of-axes 1-sigma of each star, rad (the estimator weighs by its inverse square)."""
        trace = self.cov_px2[:, 0, 0] + self.cov_px2[:, 1, 1]
        return np.sqrt(0.5 * trace) / self.sensor.focal_length_px

    def subset(self, keep) -> StarNoise:
        """Return the noise of the stars ``keep``."""
        return StarNoise(self.sensor, self.x[keep], self.y[keep], self.cov_px2[keep])

    def attitude_covariance(self, body: np.ndarray, fisher_inv=None) -> np.ndarray:
        """Return the covariance of the weighted SVD attitude from these stars, rad^2 (3, 3).

        Parameters
        ----------
        body : ndarray, shape (N, 3)
            The stars' measured camera-frame unit vectors.
        fisher_inv : ndarray, shape (3, 3), optional
            ``F^-1`` of these stars and weights, rad^2, when already computed (the
            ``covariance_rad2`` of :func:`fit_robust`'s solution).
        """
        h = 0.5
        x, y, n = self.x, self.y, len(self.x)
        # x + h, x - h at y; then x at y + h, y - h: one unprojection
        v = self.sensor.unproject(
            np.concatenate([x + h, x - h, x, x]), np.concatenate([y, y, y + h, y - h])
        )
        gx = (v[:n] - v[n : 2 * n]) / (2 * h)
        gy = (v[2 * n : 3 * n] - v[3 * n :]) / (2 * h)
        g = np.empty((n, 3, 2))
        g[:, :, 0], g[:, :, 1] = gx, gy
        w = 1.0 / self.sigma_rad**2
        inv = fisher_inv
        if inv is None:
            fisher = np.einsum("i,ijk->jk", w, np.eye(3) - body[:, :, None] * body[:, None, :])
            inv = np.linalg.inv(fisher)
        got = sandwich_compiled(body, g, self.cov_px2, w=w, inv=inv)
        return sandwich_numpy(body, g, self.cov_px2, w=w, inv=inv) if got is None else got


def star_noise(
    solver, det, matched, *, rate_rad_s, vectors=None, half_turn=None, margin_px=None
) -> StarNoise:
    """Return the centroid noise of detections ``matched`` (module docstring).

    With ``centroid_sigma_px`` a number, every star gets that isotropic sigma; with "snr" the
    photon, read-noise and streak terms above.

    Parameters
    ----------
    solver : Solver
        With a sensor.
    det : Detections
        Frame detections (``extra["spread_px2"]``, shape (N, 2, 2), where centroided along a
        streak).
    matched : ndarray of int, shape (N,)
        The detections used.
    rate_rad_s : array_like, shape (3,) or None
        Body rate, camera frame, rad/s.
    vectors : ndarray, shape (N, 3), optional
        The detections' camera-frame unit vectors, when already computed.
    half_turn : ndarray, shape (3, 3), optional
        The rotation by ``rate_rad_s x exposure / 2``, when already computed.
    margin_px : int, optional
        The CoG window's margin (default: the solver's detector's).
    """
    sensor = solver.sensor
    x, y = det.x[matched], det.y[matched]
    n = len(matched)
    eye = _EYE2  # broadcast over the stars
    sigma_px = solver.settings.centroid_sigma_px
    if sigma_px != "snr":
        var = np.full((n, 1, 1), float(sigma_px) ** 2)
        return StarNoise(sensor, x, y, var * eye)
    detector = sensor.detector
    margin = margin_px
    if margin is None:
        margin = 2 if solver.settings.background != "known" else solver.detector.margin_px
    spread = det.extra.get("spread_px2")
    spread = np.full((n, 2, 2), np.nan) if spread is None else spread[matched]
    n_e = np.maximum(det.integrated_counts[matched] / detector.gain_counts_per_e, 1.0)
    along = np.isfinite(spread[:, 0, 0])  # centroided over the streak's own window
    # photon and read noise over the streak's window (NaN where there was none)
    cov = (detector.psf_sigma_px**2 / n_e)[:, None, None] * eye + (
        detector.read_noise_e**2 / n_e**2
    )[:, None, None] * spread
    if not along.all():  # the others: the CoG over the region's box
        frame = (detector.rows, detector.columns)
        cog = cog_sigma_px(det, matched, detector=detector, margin_px=margin, shape=frame)
        cog = (cog**2)[:, None, None]
        cog = cog * eye
        cog[along] = cov[along]
        cov = cog
    if rate_rad_s is None or not np.asarray(rate_rad_s).any():
        return StarNoise(sensor, x, y, cov)
    b = sensor.unproject(x, y) if vectors is None else vectors
    h = half_turn
    if h is None:
        h = Rotation.from_rotvec(np.asarray(rate_rad_s, dtype=float) * sensor.exposure_s / 2.0)
        h = h.as_matrix()
    # start and end of each streak, projected at once
    px, py = sensor.project(np.concatenate([b @ h.T, b @ h]))
    streak = columns(px[n:] - px[:n], py[n:] - py[:n])
    # a uniform spread over the streak: L^2 / 12 per photon along it
    cov += streak[:, :, None] * streak[:, None, :] / (12.0 * n_e)[:, None, None]
    return StarNoise(sensor, x, y, cov)


def _svd_fit(body, ref, sigma):
    """Weighted SVD attitude matrix (body ~ C ref), the residual angles, rad, and chords^2.

    The estimator of :class:`~starsense.attitude.svd.SvdEstimator` with weights ``sigma^-2``
    and the residual angles of :func:`~starsense.attitude.solution.wahba_residuals` (from the
    chord), on matrices: no Rotation per fit (:func:`~starsense.identify.track_kernels.
    attitude.svd.wahba_matrix`, compiled where built).
    """
    w = sigma**-2.0
    got = fit_compiled(body, ref, w, two_exact=False)
    return wahba_matrix(body, ref, w) if got is None else got


def _fisher_covariance(body, sigma):
    """:func:`~starsense.attitude.covariance.fisher_covariance`, compiled where built."""
    got = fisher_inverse_compiled(body, sigma, rcond=SINGULAR_RCOND)
    if got is None or got is False:  # no kernel; or the reference's error to raise
        return fisher_covariance(body, sigma)
    return got


def fit_robust_matrix(body, ref, sigma):
    """:func:`fit_robust` with the attitude as a matrix (no Rotation is built).

    Returns
    -------
    matrix : ndarray, shape (3, 3)
        The attitude (ICRS -> camera), orthonormal to rounding (an SVD's U V^T).
    covariance_rad2 : ndarray, shape (3, 3)
        ``F^-1`` of the stars kept, rad^2.
    residuals_rad : ndarray, shape (M,)
        Residual angles of the stars kept, rad.
    loss : float
        Wahba's loss of the fit.
    keep : ndarray of int, shape (M,)
        The indices of the stars kept.
    """
    # the estimator's check first: SingularGeometryError for stars that fix no attitude (a
    # subset dropped to is checked again at the end)
    cov = _fisher_covariance(body, sigma)
    keep = np.arange(len(body))
    c, resid, chord2 = _svd_fit(body, ref, sigma)
    while len(keep) > 3:
        z = resid / sigma[keep]
        worst = int(z.argmax())
        if z[worst] <= OUTLIER_SIGMA:
            break
        keep = np.delete(keep, worst)
        c, resid, chord2 = _svd_fit(body[keep], ref[keep], sigma[keep])
    if len(keep) < len(body):
        cov = _fisher_covariance(body[keep], sigma[keep])
    return c, cov, resid, 0.5 * float(np.add.reduce(chord2 / sigma[keep] ** 2)), keep


def fit_robust(body, ref, sigma):
    """SVD attitude with the worst star dropped while its residual exceeds OUTLIER_SIGMA.

    A blend with a faint neighbour or a cosmic-ray hit in a star's window biases its centroid
    by many sigma; one such star would set the attitude error of the whole frame. At least
    three stars are kept.

    Parameters
    ----------
    body, ref : ndarray, shape (N, 3)
        Measured camera-frame and catalogue ICRS unit vectors.
    sigma : ndarray, shape (N,)
        Per-star 1-sigma, rad (weights sigma^-2).

    Returns
    -------
    AttitudeSolution, ndarray of int
        The fit (SVD, as :func:`~starsense.attitude.estimate_attitude` with "svd"), and the
        indices of the stars kept.
    """
    c, cov, resid, loss, keep = fit_robust_matrix(body, ref, sigma)
    att = AttitudeSolution(
        # c is orthogonal to rounding (an SVD's U V^T): scipy's re-normalisation is skipped
        rotation=Rotation.from_matrix(c, assume_valid=True),
        covariance_rad2=cov,
        residual_rms_rad=rms_angle(resid),
        residuals_rad=resid,
        method="svd",
        n_stars=len(keep),
        loss=loss,
    )
    return att, keep


def rms_angle(resid: np.ndarray) -> float:
    """Return the rms of residual angles, rad (as :func:`fit_robust` reports it)."""
    return math.sqrt(float(np.add.reduce(resid * resid)) / len(resid))
