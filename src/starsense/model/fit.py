"""The attitude (and rate) by maximum likelihood on the identified stars' pixels; its Fisher bound.

The pixels of the stars' windows (:mod:`starsense.model.windows`) are independent, each normal
about the model ``mu_j`` with the detector's variance (:func:`pixel_variance`): shot noise on
the expected electrons, read noise, dark current, DSNU, PRNU and the ADC's quantisation. The
likelihood is maximised by Gauss-Newton over the geometric parameters ``p`` (the attitude's
error rotation ``theta``, and the body rate when the frame is smeared), with each star's flux and
each group's background as linear nuisance parameters eliminated at every step (variable
projection: the Schur complement of the normal equations). Weights follow the model
(iteratively reweighted). A pixel at the ADC's top or the full well is left out of the sums (it
says only that the light reached the clip); a pixel read at the ADC's floor (a background
clipped at zero) is censored: its likelihood is that of any value below the floor
(:mod:`starsense.model.pixels`).

At the solution the Fisher information of ``p``, nuisance parameters marginalised, is

    S = sum_g C_g - B_g^T A_g^-1 B_g,  A = L W L^T, B = L W J^T, C = J W J^T

(``L`` the linear parameters' derivatives, the star templates and ones; ``J`` the geometric
ones; ``W`` the inverse variances): the Cramer-Rao bound of the model, reported as the
solution's covariance ``S^-1``. The same sum over a predicted frame is the datasheet's
noise-equivalent angle (:func:`fisher_information`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from starsense.model.misfit import covariance_pulls, sandwich
from starsense.model.pixels import pixel_terms, pixel_variance
from starsense.model.problem import Problem, linearised, set_up
from starsense.model.psf import PixelPSF, pixel_psf, psf_of

try:  # the normal equations' sums, compiled (setup.py)
    import starsense.model._modelc as _modelc
except ImportError:  # pragma: no cover - built without a C compiler: the NumPy form
    _modelc = None

__all__ = ["ModelFit", "fit_windows"]

#: Gauss-Newton stops when its last step was below this fraction of each parameter's sigma
#: (what is left, ~the square of the step in sigma for a quadratic convergence, is nothing)
STEP_TOL_SIGMAS = 0.1
#: ... and the information changed by less than this fraction since the step before: it is
#: the fluxes' squares over the pixels' variances, whose fluxes and backgrounds a fit started
#: from given ones (or near the ADC's floor, where the likelihood is not a least-squares one)
#: may still be moving
INFO_RTOL = 0.02
MAX_ITERATIONS = 10


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
    psf_sigma_px : float
        The PSF's width at the fit (the given one unless fitted), px.
    robust_covariance : ndarray, shape (P, P)
        The sandwich ``S^-1 M S^-1``, ``M`` the sum over the groups of the outer products of
        their scores (nuisances eliminated): what the pixels' own scatter says, whatever the
        model's noise (its expectation is ``covariance`` when the model is right).
    robust_noise : ndarray, shape (P,)
        The relative noise of ``robust_covariance``'s diagonal where the model is right (its
        variances, sums of the groups' scores squared, scatter by this fraction: about
        ``sqrt(2 / G)`` for G groups of equal weight, more where a few bright stars dominate).
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
    psf_sigma_px: float = 0.0
    robust_covariance: np.ndarray | None = None
    robust_noise: np.ndarray | None = None

    @property
    def sigma_axes_rad(self) -> np.ndarray:
        """1-sigma of the attitude per camera axis (x, y cross-boresight, z roll), rad."""
        return np.sqrt(np.diag(self.covariance)[:3])

    @property
    def reduced_chi2(self) -> float:
        """chi2 / dof (about 1 when the model describes the pixels)."""
        return self.chi2 / max(self.dof, 1)


def _normal_equations(lin, jac, weight, resid):
    """Schur-complement system of the geometric parameters (module docstring)."""
    if _modelc is not None:
        a, b, c, u, v = _sums(lin, jac, weight, resid)
    else:
        a = np.einsum("gmn,gn,gkn->gmk", lin, weight, lin)
        b = np.einsum("gmn,gn,gpn->gmp", lin, weight, jac)
        c = np.einsum("gpn,gn,gqn->gpq", jac, weight, jac)
        u = np.einsum("gmn,gn->gm", lin, weight * resid)
        v = np.einsum("gpn,gn->gp", jac, weight * resid)
    empty = np.einsum("gmm->gm", a) <= 0.0  # padded slots and starved groups
    a[empty[:, :, None] & np.eye(a.shape[1], dtype=bool)[None]] = 1.0
    a_inv_b = np.linalg.solve(a, b)
    a_inv_u = np.linalg.solve(a, u[..., None])[..., 0]
    per_group = c - np.einsum("gmp,gmq->gpq", b, a_inv_b)  # each group's information
    scores = v - np.einsum("gmp,gm->gp", b, a_inv_u)  # each group's, nuisances eliminated
    return per_group.sum(axis=0), scores, a_inv_b, a_inv_u, per_group


def _sums(lin, jac, weight, resid):
    """Return ``A, B, C, u, v`` of :func:`_normal_equations` by the compiled kernel."""
    (g, m, n), p = lin.shape, jac.shape[1]
    out = (np.empty((g, m, m)), np.empty((g, m, p)), np.empty((g, p, p)), np.empty((g, m)),
           np.empty((g, p)))  # fmt: skip
    args = (np.ascontiguousarray(x, dtype=float) for x in (lin, jac, weight, resid))
    _modelc.normal_equations(*args, g, m, p, n, *out)
    return out


def fit_windows(
    image,
    sensor,
    rotation: Rotation,
    *,
    vectors,
    rate_rad_s=(0.0, 0.0, 0.0),
    fit_rate: bool = False,
    fit_width: bool = False,
    fixed_vectors=None,
    fixed_electrons=None,
    psf: PixelPSF | None = None,
    fluxes_e=None,
    abort_chi2: float = math.inf,
    window_rate_rad_s=None,
) -> ModelFit:
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
    fit_width : bool
        Fit the PSF's width too (its shape kept): the optics' width is uncertain.
    fixed_vectors, fixed_electrons : ndarray, optional
        Catalogue neighbours drawn at fixed fluxes (electrons), moving with the attitude.
    psf : PixelPSF, optional
        The PSF (default: the sensor's).
    fluxes_e : ndarray, shape (S,), optional
        Starting electrons of ``vectors`` (all > 0; e.g. the detections' sums): the fit then
        starts with a Gauss-Newton step; without them it first solves for the fluxes alone.
    abort_chi2 : float
        Stop (not converged) when, a step past the start, the pixels' reduced chi-square
        exceeds this and their misfit pulls the attitude
        (:func:`starsense.model.misfit.misfit_pulls`): the model does not place the stars, the
        rest of the fit is wasted.
    window_rate_rad_s : array_like, shape (3,), optional
        Lay the windows around the tracks of this rate (default: the starting rate's): two
        fits on one set of pixels (a likelihood ratio of two models).

    Returns
    -------
    ModelFit
    """
    psf = psf or psf_of(sensor)
    v_free = np.asarray(vectors, float).reshape(-1, 3)
    v_fix = np.zeros((0, 3)) if fixed_vectors is None else np.asarray(fixed_vectors, float)
    f_fix = np.zeros(0) if fixed_electrons is None else np.asarray(fixed_electrons, float)
    rate = np.asarray(rate_rad_s, float).copy()
    window_rate = None if window_rate_rad_s is None else np.asarray(window_rate_rad_s, float)
    pb = set_up(
        image, sensor, rotation, rate=rate, psf=psf, sources=(v_free, v_fix, f_fix),
        flags=(fit_rate, fit_width), window_rate=window_rate,
    )  # fmt: skip
    if not pb.parts:
        raise np.linalg.LinAlgError("no star's window lies on the detector")
    n_geo = 6 if fit_rate else 3
    lin_values = _start(pb, psf, rotation, rate, fluxes_e)
    n_lin = int(pb.free.sum()) + sum(p.windows.n_groups for p in pb.parts)
    converged, it, prev_info = False, 0, None
    for it in range(1, MAX_ITERATIONS + 1):
        terms = linearised(pb, psf, rotation, rate=rate, lin_values=lin_values)
        pix, s, scores, s_groups, eqs = _step_sums(pb, terms)
        step = np.linalg.solve(s, scores.sum(axis=0))
        if not np.all(np.isfinite(step)):  # a model with no light left in its windows
            raise np.linalg.LinAlgError("the fit diverged (a step that is not finite)")
        dlins = [a_inv_u - np.einsum("gmp,p->gm", a_inv_b, step) for *_, a_inv_b, a_inv_u, _ in eqs]
        lin_values = [lv + d for lv, d in zip(lin_values, dlins, strict=True)]
        rotation = Rotation.from_rotvec(step[:3]) * rotation
        if fit_rate:
            rate = rate + step[3:n_geo]
        if fit_width:
            width = float(
                np.clip(psf.sigma_px + step[n_geo], 0.25 * psf.sigma_px, 4.0 * psf.sigma_px)
            )
            psf = pixel_psf(psf.spec, width)
        # the pixels' scatter about the model sets the scale of a step
        dof = max(pb.n_pixels - len(step) - n_lin, 1)
        scatter = max(1.0, sum(float(c.sum()) for *_, c in pix) / dof)
        sigma = np.sqrt(np.clip(np.diag(np.linalg.inv(s)), 0.0, None) * scatter)
        info = np.diag(s)
        settled = prev_info is not None and np.all(np.abs(info - prev_info) <= INFO_RTOL * info)
        prev_info = info
        if np.all(np.abs(step) <= STEP_TOL_SIGMAS * sigma) and settled:
            converged = True
            break
        if (
            it >= 2
            and scatter > abort_chi2
            and covariance_pulls(*sandwich(s, scores, s_groups), reduced_chi2=scatter)
        ):
            break  # one step from the start: the model does not place the stars
    if converged:  # the information, scores and chi-square of where the last step reached
        # (not of where it started: the model is linear in the fluxes and backgrounds and the
        # geometric step is small, so the pixels move by the linear change; their variance
        # follows them). A fit that did not converge is not used: its last state stands.
        terms = [
            (lin, jac, mu + np.einsum("gm,gmn->gn", d, lin) + np.einsum("gpn,p->gn", jac, step))
            for (lin, jac, mu), d in zip(terms, dlins, strict=True)
        ]
        pix, s, scores, s_groups, _ = _step_sums(pb, terms)
    out = np.full(len(v_free), np.nan)
    for p, lv in zip(pb.parts, lin_values, strict=True):
        out[pb.kept[p.mine]] = p.fluxes(lv)
    cov, robust, robust_noise = sandwich(s, scores, s_groups)
    n_par = len(step) + sum(int(lin.any(axis=2).sum()) for lin, _, _ in terms)
    n_pix = pb.n_pixels
    return ModelFit(
        rotation=rotation,
        rate_rad_s=rate,
        covariance=cov,
        robust_covariance=robust,
        fluxes_e=out,
        chi2=sum(float(c.sum()) for *_, c in pix),
        dof=n_pix - n_par,
        n_pixels=n_pix,
        iterations=it,
        converged=converged,
        psf_sigma_px=psf.sigma_px,
        robust_noise=robust_noise,
    )


def _start(pb: Problem, psf: PixelPSF, rotation, rate, fluxes_e) -> list[np.ndarray]:
    """Return each part's starting linear values: the fluxes given, or fitted at the start.

    Given fluxes (all > 0) start the fit, so that its first step has a Jacobian; without them
    the fluxes and backgrounds are solved for first at the starting geometry.
    """
    lin_values = [np.zeros((p.windows.n_groups, p.windows.n_slots + 1)) for p in pb.parts]
    n_free = int(pb.free.sum())
    start = None if fluxes_e is None else np.asarray(fluxes_e, dtype=float)
    if start is not None and start.shape == (n_free,) and np.all(start > 0):
        for p, lv in zip(pb.parts, lin_values, strict=True):
            lv[p.windows.group[p.mine], p.windows.slot[p.mine]] = start[pb.kept[p.mine]]
        return lin_values
    det, te = pb.sensor.detector, pb.sensor.exposure_s
    used = np.concatenate([p.data[p.use] for p in pb.parts])
    var = pixel_variance(det, np.median(used) if used.size else 0.0, te)
    terms = linearised(pb, psf, rotation, rate=rate, lin_values=lin_values)
    return [
        lv + _normal_equations(lin, jac, p.use / var, p.data - mu)[3]
        for p, lv, (lin, jac, mu) in zip(pb.parts, lin_values, terms, strict=True)
    ]


def _step_sums(pb: Problem, terms):
    """Return the parts' pixel terms and the normal equations summed over their groups.

    ``(pix, S, scores, per-group information, the parts' equations)``: the groups of all
    parts in one sum (the likelihood is a sum over groups).
    """
    det, te = pb.sensor.detector, pb.sensor.exposure_s
    pix = [
        pixel_terms(det, mu, p.data, use=p.use, exposure_s=te)
        for p, (_, _, mu) in zip(pb.parts, terms, strict=True)
    ]
    eqs = [
        _normal_equations(lin, jac, wt, r)
        for (lin, jac, _), (wt, r, _) in zip(terms, pix, strict=True)
    ]
    s = sum(e[0] for e in eqs)
    scores = np.concatenate([e[1] for e in eqs])
    s_groups = np.concatenate([e[4] for e in eqs])
    return pix, s, scores, s_groups, eqs
