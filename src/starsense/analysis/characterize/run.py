"""Characterise a camera from its night-sky frames: solve them, then measure what they tell.

:func:`characterize` composes the steps, one module each: solve the frames (:mod:`.frames`),
calibrate the optics (:func:`starsense.solve.calibration.calibrate`), measure each frame's
background and noise and the gain from the photon transfer (:mod:`.noise`), fit the forward
model with a free PSF width to the matched stars (:mod:`.psf`, with each frame's noise,
:mod:`.working`), fit the zero point to their fluxes (:mod:`.photometry`) and map the hot
pixels (:mod:`.hot`). :mod:`.camera` turns the result into a sensor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from starsense.analysis.characterize.frames import (
    SolvedFrame,
    frame_name,
    nominal_sensor,
    solve_frames,
)
from starsense.analysis.characterize.hot import HotPixels, hot_pixels
from starsense.analysis.characterize.noise import (
    PhotonTransfer,
    frame_noise,
    photon_transfer,
)
from starsense.analysis.characterize.photometry import ZeroPoint, zero_point
from starsense.analysis.characterize.psf import FieldPSF, fit_frame, psf_across_field, width_sigma
from starsense.analysis.characterize.residual import lens_residual_px, star_residuals
from starsense.analysis.characterize.values import weighted_mean
from starsense.analysis.characterize.working import working_sensor
from starsense.errors import InputError
from starsense.sensor import Sensor, load_sensor
from starsense.solve.calibration import Calibration, calibrate

__all__ = ["FIT_ORDER", "Characterisation", "FrameResult", "characterize"]

#: the optics' parameters tried, most first: a set the stars cannot constrain drops its last
FIT_ORDER = (
    ("focal_length", "principal_point", "k1", "k2", "p1", "p2"),
    ("focal_length", "principal_point", "k1", "k2"),
    ("focal_length", "principal_point", "k1"),
    ("focal_length", "k1"),
    ("focal_length",),
)


@dataclass(frozen=True)
class FrameResult:
    """What one frame gave.

    Attributes
    ----------
    name : str
    n_matched : int
        Matched stars.
    psf_sigma_px, psf_sigma_err_px : float
        The frame's fitted width and its 1-sigma (NaN: the fit failed).
    reduced_chi2 : float
        The fit's, with the frame's measured noise (about 1 when the model describes it).
    level_counts, noise_counts : float
        Sky level and per-pixel noise, counts.
    exposure_s : float or None
    """

    name: str
    n_matched: int
    psf_sigma_px: float
    psf_sigma_err_px: float
    reduced_chi2: float
    level_counts: float
    noise_counts: float
    exposure_s: float | None


@dataclass(frozen=True, eq=False)
class Characterisation:
    """Everything measured on the frames (:func:`characterize`).

    Attributes
    ----------
    base : Sensor
        The sensor the measured values replace values of (the user's, or a nominal one).
    base_given : bool
        Whether the user gave it.
    calibration : Calibration
    frames : list of FrameResult
    noises : list of FrameNoise
    transfer : PhotonTransfer
    psf_sigma_px, psf_sigma_err_px : float
        The width over all frames and stars, px.
    field_psf : FieldPSF
    zero : ZeroPoint or None
    hot : HotPixels
    gain_used : float
        The gain the fluxes were converted with (measured, else the base's), counts/e.
    skipped : dict
        Frames that did not solve: name -> status.
    exposures_s : tuple of float or None
    lens_residual : (float, float, float)
        What the calibrated lens leaves, its 1-sigma and the stars' rms, px per axis
        (:func:`~.residual.lens_residual_px`).
    residual_map : (ndarray (N, 2), ndarray (N, 2))
        Every matched star's centroid and residual after the calibration, px
        (:func:`~.residual.star_residuals`).
    """

    base: Sensor
    base_given: bool
    calibration: Calibration
    frames: list
    noises: list
    transfer: PhotonTransfer
    psf_sigma_px: float
    psf_sigma_err_px: float
    field_psf: FieldPSF
    zero: ZeroPoint | None
    hot: HotPixels
    gain_used: float
    skipped: dict = field(default_factory=dict)
    exposures_s: tuple | None = None
    lens_residual: tuple = (math.nan, math.nan, math.nan)
    residual_map: tuple = (np.zeros((0, 2)), np.zeros((0, 2)))

    @property
    def names(self) -> list[str]:
        """The frames used."""
        return [f.name for f in self.frames]


def _calibrated(solved: list[SolvedFrame], start: Sensor) -> Calibration:
    """Fit the optics, dropping what the stars cannot constrain (:data:`FIT_ORDER`)."""
    stars = [fr.stars for fr in solved]
    last = None
    for names in FIT_ORDER:
        try:
            return calibrate(stars, start, fit=names)
        except InputError as exc:
            last = exc
    raise InputError(f"characterize: the optics cannot be calibrated from these frames: {last}")


def _exposures(exposures_s, n: int) -> tuple | None:
    if exposures_s is None:
        return None
    e = [float(x) for x in np.atleast_1d(np.asarray(exposures_s, dtype=float))]
    if len(e) == 1:
        e = e * n
    if len(e) != n:
        raise InputError(f"exposures_s: {len(e)} values for {n} frames; give one, or one a frame")
    bad = [x for x in e if not (math.isfinite(x) and x > 0)]
    if bad:
        raise InputError(f"exposures_s must be finite numbers > 0 s, got {bad[0]!r}")
    return tuple(e)


def characterize(
    frames,
    sensor=None,
    *,
    catalog="hipparcos",
    exposures_s=None,
    obs_time=None,
) -> Characterisation:
    """Solve the frames and measure the camera from them (module docstring).

    Parameters
    ----------
    frames : sequence of path or ndarray
        Night-sky frames of one camera (image files or 2-D arrays of counts).
    sensor : Sensor, str or Path, optional
        The base sensor: its values are kept for what the frames cannot tell. None: the optics
        are unknown and a nominal sensor stands in (:func:`~.frames.nominal_sensor`).
    catalog : Catalog or str
        The catalogue to identify with (default the bundled Hipparcos).
    exposures_s : float or sequence of float, optional
        The exposure of every frame, or of each, s: the zero point is then per second.
    obs_time : str, optional
        UTC time of the frames (else each file's header).

    Returns
    -------
    Characterisation

    Raises
    ------
    InputError
        No frames, an unreadable one, frames of another size than the sensor's, exposures that
        do not match the frames, or no frame that solves.
    """
    frames = list(frames)
    exp_all = _exposures(exposures_s, len(frames))
    base = (
        None if sensor is None else (sensor if isinstance(sensor, Sensor) else load_sensor(sensor))
    )
    solved, skipped = solve_frames(frames, base, catalog=catalog, obs_time=obs_time)
    if not solved:
        raise InputError(
            f"characterize: no frame solved ({', '.join(f'{k}: {v}' for k, v in skipped.items())})"
        )
    start = base if base is not None else nominal_sensor(solved)
    cal = _calibrated(solved, start)
    noises = [frame_noise(fr.image) for fr in solved]
    transfer = photon_transfer(noises, start.detector.bias_counts)
    gain = transfer.gain_counts_per_e if transfer.told else start.detector.gain_counts_per_e
    if not (math.isfinite(gain) and gain > 0):
        gain = start.detector.gain_counts_per_e
    sensors = [working_sensor(cal.sensor, n, gain_counts_per_e=gain) for n in noises]
    order = {frame_name(f, k): k for k, f in enumerate(frames)}
    exposures = None if exp_all is None else tuple(exp_all[order[fr.name]] for fr in solved)
    results, mags, fluxes, star_exp = [], [], [], []
    for k, (fr, ws, rot, nz) in enumerate(zip(solved, sensors, cal.rotations, noises, strict=True)):
        try:
            fit = fit_frame(fr.image, ws, rot, vectors=fr.stars.vectors)
            width, err, chi2 = fit.psf_sigma_px, width_sigma(fit), fit.reduced_chi2
            if not fit.converged:
                width, err = math.nan, math.nan
            mags.append(fr.mags_v)
            fluxes.append(fit.fluxes_e * gain)
            if exposures is not None:
                star_exp.append(np.full(len(fr.mags_v), exposures[k]))
        except (InputError, np.linalg.LinAlgError):
            width, err, chi2 = math.nan, math.nan, math.nan
        results.append(
            FrameResult(
                fr.name,
                len(fr.mags_v),
                width,
                err,
                chi2,
                nz.level_counts,
                nz.noise_counts,
                None if exposures is None else exposures[k],
            )
        )
    psf_mean, psf_err, _ = weighted_mean(
        [r.psf_sigma_px for r in results], [r.psf_sigma_err_px for r in results]
    )
    field_psf = psf_across_field(solved, sensors, cal.rotations)
    zero = None
    if mags:
        zero = zero_point(
            np.concatenate(mags),
            np.concatenate(fluxes),
            None if exposures is None else np.concatenate(star_exp),
        )
    xy, res, res_mags = star_residuals(solved, cal)
    return Characterisation(
        base=start,
        base_given=base is not None,
        calibration=cal,
        frames=results,
        noises=noises,
        transfer=transfer,
        psf_sigma_px=psf_mean,
        psf_sigma_err_px=psf_err,
        field_psf=field_psf,
        zero=zero,
        hot=hot_pixels([fr.image for fr in solved]),
        gain_used=float(gain),
        skipped=skipped,
        exposures_s=exposures,
        lens_residual=lens_residual_px(res_mags, 0.5 * np.sum(res * res, axis=1)),
        residual_map=(xy, res),
    )
