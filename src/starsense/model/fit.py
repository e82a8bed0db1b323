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

from starsense._workspace import scratch
from starsense.model.misfit import covariance_pulls, sandwich
from starsense.model.pixels import pixel_terms, pixel_variance
from starsense.model.psf import PixelPSF, pixel_psf, psf_of
from starsense.model.tracks import node_positions, track_nodes
from starsense.model.windows import MAX_WORK, Windows, evaluate, make_windows

try:  # the normal equations' sums, compiled (setup.py)
    import starsense.model._modelc as _modelc
except ImportError:  # pragma: no cover - built without a C compiler: the NumPy form
    _modelc = None

__all__ = [
    "WINDOW_HALF_SIGMAS",
    "ModelFit",
    "fit_windows",
    "window_half_px",
]

#: a star's box reaches this many PSF sigmas (+1 px) beyond its track
WINDOW_HALF_SIGMAS = 3.5
#: Gauss-Newton stops when its last step was below this fraction of each parameter's sigma
#: (what is left, ~the square of the step in sigma for a quadratic convergence, is nothing)
STEP_TOL_SIGMAS = 0.1
#: ... and the information changed by less than this fraction since the step before: it is
#: the fluxes' squares over the pixels' variances, whose fluxes and backgrounds a fit started
#: from given ones (or near the ADC's floor, where the likelihood is not a least-squares one)
#: may still be moving
INFO_RTOL = 0.02
#: the width's central difference, a fraction of the width
WIDTH_STEP = 2e-3
MAX_ITERATIONS = 10


def window_half_px(psf: PixelPSF) -> float:
    """Half-size of a star's box beyond its track, px."""
    return WINDOW_HALF_SIGMAS * psf.sigma_px + 1.0


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
    g = windows.n_groups
    return e.reshape(g, -1), use.reshape(g, -1)


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


#: most float64 values of a fit's arrays kept in the thread's work buffer between fits (16 MB);
#: a larger fit allocates its own
MAX_KEPT_VALUES = 1 << 21


def _zeros(n: int) -> np.ndarray:
    """Return ``n`` float64 zeros, in this thread's work buffer for the model when they fit.

    Reused by the next fit: freshly mapped pages cost more to fault in than the kernel takes
    to fill them (~1 ms a fit of 20,000 pixels). The buffer's length is a power of two, so
    that fits of other sizes share it; one fit at a time holds it (no fit runs inside another).
    """
    if n > MAX_KEPT_VALUES:
        return np.zeros(n)
    out = scratch("model.fit", (1 << max(int(n) - 1, 0).bit_length(),), np.float64)[:n]
    out.fill(0.0)
    return out


@dataclass
class _Problem:
    """What stays fixed while the fit iterates: the sources, windows, data and quadrature."""

    sensor: object
    vectors: np.ndarray
    free: np.ndarray
    fluxes: np.ndarray
    windows: Windows
    data: np.ndarray
    use: np.ndarray
    fractions: np.ndarray
    weights: np.ndarray
    fit_rate: bool
    fit_width: bool
    kept: np.ndarray
    buffers: tuple | None = None

    def out(self, n_par: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return the model's arrays, laid out once for the fit (:func:`evaluate`'s ``out``).

        The linear design (its last row ones), the fixed light, the Jacobian of ``n_par``
        parameters.
        """
        w = self.windows
        if self.buffers is None or self.buffers[2].shape[1] != n_par:
            g, m, (h, wd) = w.n_groups, w.n_slots, w.shape
            flat = _zeros(g * h * wd * (m + 2 + n_par))
            a, b = g * (m + 1) * h * wd, g * (m + 2) * h * wd
            lin = flat[:a].reshape(g, m + 1, h, wd)
            lin[:, -1] = 1.0  # the background's
            self.buffers = (lin, flat[a:b].reshape(g, h, wd), flat[b:].reshape(g, n_par, h, wd))
        return self.buffers


def _setup(
    image, sensor, rotation, rate, psf, v_free, v_fix, f_fix, fit_rate, fit_width, window_rate=None
):
    """Lay out the windows around the sources' tracks and read their pixels.

    The tracks at ``window_rate`` where given (else at the rate's).
    """
    allv = np.concatenate([v_free, v_fix])
    free = np.r_[np.ones(len(v_free), bool), np.zeros(len(v_fix), bool)]
    lay = {"sigma_px": psf.sigma_px, "max_nodes": MAX_WORK}  # nodes bounded by the fit's work
    moving = fit_rate or bool(np.any(rate))
    frac, wts, nodes = track_nodes(
        sensor, (v_free, allv), rotation, rate_rad_s=rate, moving=moving, **lay
    )
    if window_rate is not None:  # the windows laid around the tracks of another rate
        nodes = track_nodes(
            sensor, (v_free, allv), rotation, rate_rad_s=window_rate, moving=True, **lay
        )[2]
    windows, kept = make_windows(
        nodes.x, nodes.y, half_px=window_half_px(psf), shape=image.shape, free=free
    )
    data, use = _data(image, windows, sensor.detector)
    fluxes = np.r_[np.zeros(len(v_free)), f_fix][kept]
    return _Problem(
        sensor,
        allv[kept],
        free[kept],
        fluxes,
        windows,
        data,
        use,
        frac,
        wts,
        fit_rate,
        fit_width,
        kept,
    )


def _linearised(pb: _Problem, psf: PixelPSF, rotation, rate, lin_values):
    """Return the linear design (G, M+1, N), the geometric Jacobian (G, P, N) and the model."""
    sensor, w = pb.sensor, pb.windows
    nodes = node_positions(
        sensor,
        pb.vectors,
        rotation,
        rate_rad_s=rate,
        exposure_s=sensor.exposure_s,
        fractions=pb.fractions,
        weights=pb.weights,
        fit_rate=pb.fit_rate,
    )
    fl = pb.fluxes
    fl[pb.free] = lin_values[w.group[pb.free], w.slot[pb.free]]  # the Jacobian at these fluxes
    exact = pb.fit_width and psf.spec.is_gaussian  # the width's derivative in closed form
    out = pb.out(nodes.dx.shape[-1] + int(exact))
    ev = evaluate(w, psf, nodes, fluxes=fl, width=exact, out=out)
    g_n, m = w.n_groups, w.n_slots
    lin = out[0].reshape(g_n, m + 1, -1)
    jac = ev.jacobian.reshape(g_n, ev.jacobian.shape[1], -1)
    if pb.fit_width and not exact:  # d mu / d sigma by a central difference of the width
        h = WIDTH_STEP * psf.sigma_px
        sides = []
        for sign in (1.0, -1.0):
            other = pixel_psf(psf.spec, psf.sigma_px + sign * h)
            e = evaluate(w, other, nodes, fluxes=fl, gradient=False)
            sides.append(e.fixed + np.einsum("gm,gmhw->ghw", lin_values[:, :m], e.templates))
        dw = (sides[0] - sides[1]) / (2.0 * h)
        jac = np.concatenate([jac, dw.reshape(g_n, 1, -1)], axis=1)
    mu = ev.fixed.reshape(g_n, -1) + np.einsum("gm,gmn->gn", lin_values, lin)
    return lin, jac, mu


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
    det, te = sensor.detector, sensor.exposure_s
    v_free = np.asarray(vectors, float).reshape(-1, 3)
    v_fix = np.zeros((0, 3)) if fixed_vectors is None else np.asarray(fixed_vectors, float)
    f_fix = np.zeros(0) if fixed_electrons is None else np.asarray(fixed_electrons, float)
    rate = np.asarray(rate_rad_s, float).copy()
    window_rate = None if window_rate_rad_s is None else np.asarray(window_rate_rad_s, float)
    pb = _setup(
        image, sensor, rotation, rate, psf, v_free, v_fix, f_fix, fit_rate, fit_width, window_rate
    )
    n_geo = 6 if fit_rate else 3
    lin_values = np.zeros((pb.windows.n_groups, pb.windows.n_slots + 1))
    weight = pb.use / pixel_variance(det, np.median(pb.data[pb.use]) if pb.use.any() else 0, te)
    start = None if fluxes_e is None else np.asarray(fluxes_e, dtype=float)
    w = pb.windows
    if start is not None and start.shape == (len(v_free),) and np.all(start > 0):
        fr = pb.free  # the given fluxes start the fit: its first step has a Jacobian
        lin_values[w.group[fr], w.slot[fr]] = start[pb.kept[fr]]  # free: the given vectors
    else:  # the fluxes first, at the starting geometry
        lin, jac, mu = _linearised(pb, psf, rotation, rate, lin_values)
        lin_values = lin_values + _normal_equations(lin, jac, weight, pb.data - mu)[3]
    converged, it, s, scores, prev_info = False, 0, np.eye(3), np.zeros((1, 3)), None
    s_groups = np.eye(3)[None]
    for it in range(1, MAX_ITERATIONS + 1):
        lin, jac, mu = _linearised(pb, psf, rotation, rate, lin_values)
        weight, resid, chi2 = pixel_terms(det, mu, pb.data, use=pb.use, exposure_s=te)
        s, scores, a_inv_b, a_inv_u, s_groups = _normal_equations(lin, jac, weight, resid)
        step = np.linalg.solve(s, scores.sum(axis=0))
        if not np.all(np.isfinite(step)):  # a model with no light left in its windows
            raise np.linalg.LinAlgError("the fit diverged (a step that is not finite)")
        dlin = a_inv_u - np.einsum("gmp,p->gm", a_inv_b, step)
        lin_values = lin_values + dlin
        rotation = Rotation.from_rotvec(step[:3]) * rotation
        if fit_rate:
            rate = rate + step[3:n_geo]
        if fit_width:
            width = float(
                np.clip(psf.sigma_px + step[n_geo], 0.25 * psf.sigma_px, 4.0 * psf.sigma_px)
            )
            psf = pixel_psf(psf.spec, width)
        # the pixels' scatter about the model sets the scale of a step
        dof = max(int(pb.use.sum()) - len(step) - lin.shape[1] * lin.shape[0], 1)
        scatter = max(1.0, float(chi2.sum()) / dof)
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
        mu = mu + np.einsum("gm,gmn->gn", dlin, lin) + np.einsum("gpn,p->gn", jac, step)
        weight, resid, chi2 = pixel_terms(det, mu, pb.data, use=pb.use, exposure_s=te)
        s, scores, _, _, s_groups = _normal_equations(lin, jac, weight, resid)
    n_pix = int(pb.use.sum())
    out = np.full(len(v_free), np.nan)
    fr = pb.free
    out[pb.kept[fr]] = lin_values[pb.windows.group[fr], pb.windows.slot[fr]]
    cov, robust, robust_noise = sandwich(s, scores, s_groups)
    n_par = jac.shape[1] + int((lin.any(axis=2)).sum())
    return ModelFit(
        rotation=rotation,
        rate_rad_s=rate,
        covariance=cov,
        robust_covariance=robust,
        fluxes_e=out,
        chi2=float(chi2.sum()),
        dof=n_pix - n_par,
        n_pixels=n_pix,
        iterations=it,
        converged=converged,
        psf_sigma_px=psf.sigma_px,
        robust_noise=robust_noise,
    )
