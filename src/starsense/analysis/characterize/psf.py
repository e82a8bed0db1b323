"""The PSF's width from the forward model fitted to the matched stars; its change across the field.

Each frame's matched stars are fitted by maximum likelihood
(:func:`starsense.model.fit.fit_windows` with ``fit_width=True``: the attitude, every star's flux
and each window's background free, the PSF's shape the sensor's and its width a parameter).
The width's 1-sigma is the inverse Fisher information's, or the pixels' own scatter's (the
sandwich of the fit's scores) where that is larger: a lens's PSF is not exactly the model's.
Frames combine by inverse variance (:func:`~.values.weighted_mean`, raised by the Birge ratio
when they disagree).

Across the field the stars are split by ``u = r^2 / r_corner^2`` (r from the detector centre)
into :data:`ZONES` zones, each frame's zone with at least :data:`MIN_ZONE_STARS` stars fitted on
its own; the zones' widths are fitted by the sensor's own law
(:meth:`starsense.sensor.Sensor.psf_sigma_at`), ``sigma(u) = s0 + (s_corner - s0) u``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from starsense.analysis.characterize.values import weighted_mean
from starsense.errors import InputError
from starsense.model.fit import ModelFit, fit_windows

__all__ = ["MIN_ZONE_STARS", "ZONES", "FieldPSF", "fit_frame", "psf_across_field", "width_sigma"]

#: radial zones across the field (equal steps of r^2: equal areas of a round field)
ZONES = 3
#: a zone of a frame is fitted when it holds at least this many matched stars (the attitude's
#: three angles are fitted with it)
MIN_ZONE_STARS = 4


def fit_frame(image, sensor, rotation, *, vectors, start_e=None) -> ModelFit:
    """Fit the model with a free PSF width to one frame's stars (module docstring)."""
    return fit_windows(
        image,
        sensor,
        rotation,
        vectors=vectors,
        fit_width=True,
        fluxes_e=start_e,
        abort_chi2=math.inf,
    )


def width_sigma(fit: ModelFit) -> float:
    """Return the fitted width's 1-sigma, px: Fisher's, or the pixels' scatter's where larger."""
    k = 3  # after the attitude's three angles (no rate fitted)
    var = float(fit.covariance[k, k])
    if fit.robust_covariance is not None and np.isfinite(fit.robust_covariance[k, k]):
        var = max(var, float(fit.robust_covariance[k, k]))
    return math.sqrt(var) if var > 0 else math.nan


@dataclass(frozen=True)
class FieldPSF:
    """The PSF's width across the field.

    Attributes
    ----------
    u : ndarray (Z,)
        Each zone's mean ``r^2 / r_corner^2``.
    sigma_px, sigma_err_px : ndarray (Z,)
        Each zone's width and its 1-sigma, px (NaN: no frame had enough stars in it).
    n_stars : ndarray (Z,)
        Stars fitted in each zone (all frames).
    centre_px, centre_err_px, corner_px, corner_err_px : float
        The law's width at the centre and in the corners, with their 1-sigma (NaN when fewer
        than two zones were measured).
    """

    u: np.ndarray
    sigma_px: np.ndarray
    sigma_err_px: np.ndarray
    n_stars: np.ndarray
    centre_px: float = math.nan
    centre_err_px: float = math.nan
    corner_px: float = math.nan
    corner_err_px: float = math.nan

    @property
    def told(self) -> bool:
        """Whether the change across the field was measured."""
        return math.isfinite(self.corner_px)


def _zone_of(xy, sensor) -> tuple[np.ndarray, np.ndarray]:
    det = sensor.detector
    cx, cy = 0.5 * (det.columns - 1), 0.5 * (det.rows - 1)
    u = ((xy[:, 0] - cx) ** 2 + (xy[:, 1] - cy) ** 2) / (cx**2 + cy**2)
    u = np.minimum(u, 1.0)
    return u, np.minimum((u * ZONES).astype(int), ZONES - 1)


def psf_across_field(frames, sensors, rotations) -> FieldPSF:
    """Fit the width zone by zone over the frames, then the law across the field.

    Parameters
    ----------
    frames : list of SolvedFrame
    sensors : list of Sensor
        Each frame's working sensor (:func:`~.working.working_sensor`).
    rotations : list of Rotation
        Each frame's attitude (the calibration's).

    Returns
    -------
    FieldPSF
    """
    vals = [[] for _ in range(ZONES)]
    errs = [[] for _ in range(ZONES)]
    us = [[] for _ in range(ZONES)]
    counts = np.zeros(ZONES, dtype=int)
    for fr, sensor, rot in zip(frames, sensors, rotations, strict=True):
        u, zone = _zone_of(fr.stars.centroids_px, sensor)
        for z in range(ZONES):
            sel = zone == z
            if sel.sum() < MIN_ZONE_STARS:
                continue
            try:
                fit = fit_frame(fr.image, sensor, rot, vectors=fr.stars.vectors[sel])
            except (InputError, np.linalg.LinAlgError):
                continue
            s = width_sigma(fit)
            if not (fit.converged and math.isfinite(s)):
                continue
            vals[z].append(fit.psf_sigma_px)
            errs[z].append(s)
            us[z].extend(u[sel])
            counts[z] += int(sel.sum())
    mean = np.full(ZONES, np.nan)
    err = np.full(ZONES, np.nan)
    uz = (np.arange(ZONES) + 0.5) / ZONES
    for z in range(ZONES):
        if vals[z]:
            mean[z], err[z], _ = weighted_mean(vals[z], errs[z])
            uz[z] = float(np.mean(us[z]))
    ok = np.isfinite(mean)
    out = FieldPSF(uz, mean, err, counts)
    if ok.sum() < 2:
        return out
    design = np.column_stack([1.0 - uz[ok], uz[ok]])  # sigma = s0 (1 - u) + s_corner u
    w = 1.0 / err[ok] ** 2
    a = design.T @ (design * w[:, None])
    coef = np.linalg.solve(a, design.T @ (w * mean[ok]))
    cov = np.linalg.inv(a)
    dof = int(ok.sum()) - 2
    if dof > 0:  # raised when the zones scatter about the law more than their sigmas
        chi2 = float(np.sum(w * (mean[ok] - design @ coef) ** 2))
        cov = cov * max(chi2 / dof, 1.0)
    return FieldPSF(
        uz,
        mean,
        err,
        counts,
        centre_px=float(coef[0]),
        centre_err_px=float(math.sqrt(cov[0, 0])),
        corner_px=float(coef[1]),
        corner_err_px=float(math.sqrt(cov[1, 1])),
    )
