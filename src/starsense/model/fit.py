"""The attitude (and rate) by maximum likelihood on the identified stars' pixels; its Fisher bound.

The pixels of the stars' windows (:mod:`starsense.model.windows`) are independent, each normal
about the model ``mu_j`` with the detector's variance (:func:`pixel_variance`): shot noise on
the expected electrons, read noise, dark current, DSNU, PRNU and the ADC's quantisation. The
likelihood is maximised by Gauss-Newton over the geometric parameters ``p`` (the attitude's
error rotation ``theta``, and the body rate when the frame is smeared), with each star's flux and
each group's background as linear nuisance parameters eliminated at every step (variable
projection: the Schur complement of the normal equations). Weights follow the model
(iteratively reweighted). A pixel at the ADC's top or the full well is censored (it says only
that the light reached the clip): it is left out of the sums, as is a pixel read at zero where
the bias sits within three read-noise sigmas of zero (a clipped background).

At the solution the Fisher information of ``p``, nuisance parameters marginalised, is

    S = sum_g C_g - B_g^T A_g^-1 B_g,  A = L W L^T, B = L W J^T, C = J W J^T

(``L`` the linear parameters' derivatives, the star templates and ones; ``J`` the geometric
ones; ``W`` the inverse variances): the Cramer-Rao bound of the model, reported as the
solution's covariance ``S^-1``. The same sum over a predicted frame is the datasheet's
noise-equivalent angle (:func:`fisher_information`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from starsense.model.psf import PixelPSF, psf_of
from starsense.model.tracks import node_positions, time_nodes
from starsense.model.windows import Windows, evaluate, make_windows

__all__ = ["WINDOW_HALF_SIGMAS", "ModelFit", "fit_windows", "pixel_variance", "window_half_px"]

#: a star's box reaches this many PSF sigmas (+1 px) beyond its track
WINDOW_HALF_SIGMAS = 3.5
#: Gauss-Newton stops when the last step moved no star by more than this, px
STEP_TOL_PX = 1e-3
MAX_ITERATIONS = 12


def window_half_px(psf: PixelPSF) -> float:
    """Half-size of a star's box beyond its track, px."""
    return WINDOW_HALF_SIGMAS * psf.sigma_px + 1.0


def pixel_variance(detector, mu_e, exposure_s: float) -> np.ndarray:
    """Variance of a pixel's reading, electrons^2, about the expected signal ``mu_e``.

    Shot noise on the signal and the dark charge, read noise, DSNU, PRNU (``(prnu mu)^2``) and
    the ADC's quantisation (``1 / (12 g^2)``, g counts per electron).
    """
    mu = np.maximum(np.asarray(mu_e, dtype=float), 0.0)
    dark = detector.dark_current_e_s * exposure_s
    return (
        mu
        + dark
        + detector.read_noise_e**2
        + detector.dsnu_e**2
        + (detector.prnu_fraction * mu) ** 2
        + 1.0 / (12.0 * detector.gain_counts_per_e**2)
    )


@dataclass(frozen=True)
class ModelFit:
    """The maximum-likelihood fit of a frame's windows.

    Attributes
    ----------
    rotation : Rotation
        Mid-exposure attitude, ICRS to camera.
    rate_rad_s : ndarray, shape (3,)
        Body rate, camera frame, rad/s (the given one when not fitted).
    covariance : ndarray, shape (P, P)
        Inverse Fisher information of the geometric parameters (theta, rad^2; then the rate,
        (rad/s)^2), nuisance parameters marginalised.
    fluxes_e : ndarray, shape (S,)
        Fitted electrons of the free sources (the input order; NaN for one not modelled).
    chi2 : float
        Sum of squared normalised residuals over the pixels used.
    dof : int
        Pixels used less parameters fitted.
    n_pixels : int
        Pixels used.
    iterations : int
    converged : bool
    """

    rotation: Rotation
    rate_rad_s: np.ndarray
    covariance: np.ndarray
    fluxes_e: np.ndarray
    chi2: float
    dof: int
    n_pixels: int
    iterations: int
    converged: bool

    @property
    def sigma_axes_rad(self) -> np.ndarray:
        """1-sigma of the attitude per camera axis (x, y cross-boresight, z roll), rad."""
        return np.sqrt(np.diag(self.covariance)[:3])

    @property
    def reduced_chi2(self) -> float:
        """chi2 / dof (about 1 when the model describes the pixels)."""
        return self.chi2 / max(self.dof, 1)


def _data(image, windows: Windows, detector) -> tuple[np.ndarray, np.ndarray]:
    """Return the windows' pixels in electrons above the bias (G, N) and which are usable."""
    h, w = windows.shape
    rows = windows.row0[:, None, None] + np.arange(h)[None, :, None]
    cols = windows.col0[:, None, None] + np.arange(w)[None, None, :]
    on = windows.on
    r = np.clip(rows, 0, image.shape[0] - 1)
    c = np.clip(cols, 0, image.shape[1] - 1)
    counts = np.asarray(image)[r, c].astype(float)
    e = (counts - detector.bias_counts) / detector.gain_counts_per_e
    use = on & (counts < detector.saturation_counts - 0.5) & (e < 0.999 * detector.full_well_e)
    read_counts = detector.read_noise_e * detector.gain_counts_per_e
    if detector.bias_counts < 3.0 * read_counts:  # a background clipped at zero: censored
        use &= counts > 0.5
    g = windows.n_groups
    return e.reshape(g, -1), use.reshape(g, -1)


def _normal_equations(lin, jac, weight, resid):
    """Schur-complement system of the geometric parameters (module docstring)."""
    a = np.einsum("gmn,gn,gkn->gmk", lin, weight, lin)
    empty = np.einsum("gmm->gm", a) <= 0.0  # padded slots and starved groups
    a[empty[:, :, None] & np.eye(a.shape[1], dtype=bool)[None]] = 1.0
    b = np.einsum("gmn,gn,gpn->gmp", lin, weight, jac)
    c = np.einsum("gpn,gn,gqn->gpq", jac, weight, jac)
    u = np.einsum("gmn,gn->gm", lin, weight * resid)
    v = np.einsum("gpn,gn->gp", jac, weight * resid)
    a_inv_b = np.linalg.solve(a, b)
    a_inv_u = np.linalg.solve(a, u[..., None])[..., 0]
    s = (c - np.einsum("gmp,gmq->gpq", b, a_inv_b)).sum(axis=0)
    grad = (v - np.einsum("gmp,gm->gp", b, a_inv_u)).sum(axis=0)
    return s, grad, a_inv_b, a_inv_u


def fit_windows(
    image, sensor, rotation: Rotation, vectors, *, rate_rad_s=(0.0, 0.0, 0.0),
    fit_rate: bool = False, fixed_vectors=None, fixed_electrons=None, psf: PixelPSF | None = None,
) -> ModelFit:  # fmt: skip
    """Fit the attitude (and rate) to the pixels around the given stars (module docstring).

    Parameters
    ----------
    image : ndarray, shape (rows, columns)
        The frame, counts.
    sensor : Sensor
    rotation : Rotation
        Starting attitude (the centre-of-gravity solution), ICRS to camera.
    vectors : ndarray, shape (S, 3)
        ICRS directions of the identified stars (their fluxes are fitted).
    rate_rad_s : array_like, shape (3,)
        Starting (or known) body rate, camera frame, rad/s.
    fit_rate : bool
        Fit the rate too (a smeared frame).
    fixed_vectors, fixed_electrons : ndarray, optional
        Catalogue neighbours drawn at fixed fluxes (electrons), moving with the attitude.
    psf : PixelPSF, optional
        The PSF (default: the sensor's).

    Returns
    -------
    ModelFit
    """
    psf = psf or psf_of(sensor)
    det, te = sensor.detector, sensor.exposure_s
    v_free = np.asarray(vectors, float).reshape(-1, 3)
    v_fix = np.zeros((0, 3)) if fixed_vectors is None else np.asarray(fixed_vectors, float)
    f_fix = np.zeros(0) if fixed_electrons is None else np.asarray(fixed_electrons, float)
    allv = np.concatenate([v_free, v_fix])
    free = np.r_[np.ones(len(v_free), bool), np.zeros(len(v_fix), bool)]
    rate = np.asarray(rate_rad_s, float).copy()
    ends = node_positions(sensor, v_free, rotation, rate, te, fractions=np.array([-0.5, 0.5]),
                          weights=np.array([0.5, 0.5]))  # fmt: skip
    length = float(np.nanmax(np.hypot(*(np.diff(ends.x), np.diff(ends.y))))) if len(v_free) else 0
    frac, wts = time_nodes(length if (fit_rate or np.any(rate)) else 0.0, psf.sigma_px)
    nodes = node_positions(sensor, allv, rotation, rate, te, fractions=frac, weights=wts,
                           fit_rate=fit_rate)  # fmt: skip
    windows, kept = make_windows(
        nodes.x, nodes.y, half_px=window_half_px(psf), shape=image.shape, free=free
    )
    allv, free = allv[kept], free[kept]
    fluxes = np.r_[np.zeros(len(v_free)), f_fix][kept]
    data, use = _data(image, windows, det)
    n_par = 6 if fit_rate else 3
    m = windows.n_slots
    g_n = windows.n_groups
    lin_values = np.zeros((g_n, m + 1))
    weight = use / pixel_variance(det, np.median(data[use]) if use.any() else 0.0, te)
    converged, it = False, 0
    s = np.eye(n_par)
    for it in range(1, MAX_ITERATIONS + 1):
        nodes = node_positions(sensor, allv, rotation, rate, te, fractions=frac, weights=wts,
                               fit_rate=fit_rate)  # fmt: skip
        for s_i in np.flatnonzero(free):  # the Jacobian at the current fluxes
            fluxes[s_i] = lin_values[windows.group[s_i], windows.slot[s_i]]
        ev = evaluate(windows, psf, nodes, fluxes, free=free)
        lin = np.concatenate([ev.templates, np.ones((g_n, 1, *windows.shape))], axis=1)
        lin = lin.reshape(g_n, m + 1, -1)
        jac = ev.jacobian.reshape(g_n, n_par, -1)
        mu = ev.fixed.reshape(g_n, -1) + np.einsum("gm,gmn->gn", lin_values, lin)
        if it > 1:
            weight = use / pixel_variance(det, mu, te)
        if it == 1:  # the fluxes first, at the starting geometry
            _, _, _, a_inv_u = _normal_equations(lin, jac, weight, data - mu)
            lin_values = lin_values + a_inv_u
            continue
        s, grad, a_inv_b, a_inv_u = _normal_equations(lin, jac, weight, data - mu)
        step = np.linalg.solve(s, grad)
        lin_values = lin_values + a_inv_u - np.einsum("gmp,p->gm", a_inv_b, step)
        rotation = Rotation.from_rotvec(step[:3]) * rotation
        if fit_rate:
            rate = rate + step[3:]
        moved = np.linalg.norm(step[:3]) * sensor.focal_length_px
        if fit_rate:
            moved += np.linalg.norm(step[3:]) * te * sensor.focal_length_px
        if moved < STEP_TOL_PX:
            converged = True
            break
    resid = data - mu
    chi2 = float((weight * resid * resid).sum())
    n_pix = int(use.sum())
    out = np.full(len(v_free), np.nan)
    idx = kept[free]
    out[idx] = lin_values[windows.group[free], windows.slot[free]]
    return ModelFit(
        rotation=rotation,
        rate_rad_s=rate,
        covariance=np.linalg.inv(s),
        fluxes_e=out,
        chi2=chi2,
        dof=n_pix - n_par - int((lin.any(axis=2)).sum()),
        n_pixels=n_pix,
        iterations=it,
        converged=converged,
    )
