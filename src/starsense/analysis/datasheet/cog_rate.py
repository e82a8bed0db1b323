"""The datasheet's prediction under slew for a centre-of-gravity tracker (``refine="cog"``).

Each star of the field is a streak whose capsule centroid's noise, bias and the covariance the
solver assumes come from :mod:`starsense.analysis.datasheet.streak_noise`; the default solver,
which fits the forward model, is predicted by
:func:`starsense.analysis.datasheet.model_noise.model_nea_at_rate` instead.
"""

from __future__ import annotations

import numpy as np

from starsense.analysis.datasheet.field import field_stars_cam, propagated_covariance
from starsense.analysis.datasheet.merges import match_chances, streaks_px_of
from starsense.analysis.datasheet.predict import (
    StarModel,
    camera_offsets,
    dropped_stars,
    error_kinds,
)
from starsense.analysis.datasheet.streak_noise import blend_cov_px2, is_streaked, streak_errors

__all__ = ["nea_at_rate"]


def nea_at_rate(
    model: StarModel,
    fov,
    matrices,
    *,
    rates_rad_s,
    vectors,
    magnitudes,
    margin_px=2,
    catalogue=None,
    detectable=None,
):
    """Return the 1-sigma (cross, roll) of attitudes at body rates, rad, from smeared stars.

    Each star of the field is a streak (the attitude's rate over the exposure): its centroid's
    noise, bias (a streak cut by the frame's edge) and the covariance the solver assumes come
    from :func:`starsense.analysis.datasheet.streak_noise.streak_errors` (the solver's capsule
    over the whole streak, or the detector's box where the streaks are short), with the blends
    of the other stars' streaks across each capsule
    (:func:`~starsense.analysis.datasheet.streak_noise.blend_cov_px2`; in the detector's boxes
    the rest model's confusion), and go through the solver's weights (``2 / trace`` of its
    assumed covariance) as at rest (:func:`starsense.analysis.datasheet.field.
    propagated_covariance`, the anisotropic form of :func:`nea_at`'s propagation), with the
    PRNU, calibration residual of :func:`error_kinds` and catalogue error added per star. The
    solver's robust fit drops (:func:`~starsense.analysis.datasheet.predict.dropped_stars`) are left
    out.

    Parameters
    ----------
    model : StarModel
    fov : RectangularFov
        The sensor's field.
    matrices : ndarray (M, 3, 3)
        Attitudes, ICRS -> camera.
    rates_rad_s : ndarray (M, 3)
        Body rate of each attitude, camera frame, rad/s.
    vectors, magnitudes : ndarray (N, 3), (N,)
        The stars the tracker uses (those it detects at the rate), ICRS.
    margin_px : int
        The detector's centroid margin, px.
    catalogue : ndarray (N, 3), optional
        Each star's database position less its rendered one, ICRS, rad: added to the star's
        centroid bias (the fit meets both alike).
    detectable : (ndarray (K, 3), ndarray (K,)), optional
        Every star the frames hold down to the faintest detected at the rate (ICRS, V): a
        star whose detection runs into their streaks is not matched, one lit in pieces seldom
        (:func:`starsense.analysis.datasheet.merges.match_chances`). None: all are matched.

    Returns
    -------
    cross, roll : ndarray (M,)
        rad; NaN where fewer than two stars are in the field.
    """
    sensor = model.sensor
    pairs = field_stars_cam(fov, np.asarray(matrices), np.asarray(vectors))
    rates = np.asarray(rates_rad_s, dtype=float).reshape(-1, 3)[pairs.point]
    mags, z = np.asarray(magnitudes)[pairs.star], pairs.v_cam[:, 2]
    centres, streaks = streaks_px_of(sensor, pairs.v_cam, rates)
    length = np.hypot(streaks[:, 0], streaks[:, 1])
    # the solver re-centroids a frame over the streaks when its streaks are long (per frame)
    frame_len = np.zeros(pairs.n_pointings)
    np.maximum.at(frame_len, pairs.point, length)
    capsule = np.array([is_streaked(sensor, float(v), margin_px) for v in frame_len])
    electrons = model.sensitivity.electrons(mags)
    cov = np.full((len(mags), 2, 2), np.nan)
    bias = np.full((len(mags), 2), np.nan)
    solver = np.full((len(mags), 2, 2), np.nan)
    for flag in (True, False):
        at = np.flatnonzero(capsule[pairs.point] == flag)
        got = streak_errors(sensor, electrons[at], centres[at], streaks_px=streaks[at],
                            capsule=flag, margin_px=margin_px, frames=pairs.point[at])  # fmt: skip
        cov[at], bias[at], solver[at] = got.cov_px2, got.bias_px, got.solver_cov_px2
    chance = np.ones(len(mags))  # of being matched: a streak run into, or lit in pieces
    if detectable is not None:
        chance = match_chances(model, fov, matrices=matrices, rates_rad_s=rates_rad_s,
                               detectable=detectable, frames=pairs.point,
                               centres_px=centres, streaks_px=streaks, electrons=electrons,
                               cov_px2=cov)  # fmt: skip
    if model.neighbours is not None:  # the other stars' streaks across each capsule
        sig = np.sqrt(0.5 * np.trace(solver, axis1=1, axis2=2))
        for i in np.flatnonzero(np.isfinite(sig) & capsule[pairs.point]):
            cov[i] += blend_cov_px2(
                electrons[i],
                streaks[i],
                sig[i],
                sigma_px=sensor.detector.psf_sigma_px,
                neighbours=model.neighbours,
            )
    box = ~capsule[pairs.point]  # the detector's windows: the confusion of the rest model
    conf = model.star_sigmas_rad(mags[box], z[box], "confusion") / (model.pixel_rad * z[box])
    cov[box] += (conf**2)[:, None, None] * np.eye(2)
    scale = (model.pixel_rad * z) ** 2  # px^2 -> rad^2, the pinhole's angle per pixel
    weights = 2.0 / (np.trace(solver, axis1=1, axis2=2) * scale)  # rad^-2
    weights = np.where(np.isfinite(weights), weights, 0.0)
    proj = np.eye(3) - pairs.v_cam[:, :, None] * pairs.v_cam[:, None, :]
    if catalogue is not None:  # the database's offsets, camera frame, px
        off = camera_offsets(pairs, matrices, catalogue)
        bias = bias + off[:, :2] / np.sqrt(scale)[:, None]
    bias3 = np.einsum("pij,pj->pi", proj, np.column_stack([bias, np.zeros(len(bias))]))
    bias3 *= np.sqrt(scale)[:, None]
    dropped = dropped_stars(pairs, weights, np.nan_to_num(bias3)) | (chance <= 0)
    weights[dropped], cov[dropped], bias[dropped] = 0.0, 0.0, 0.0
    other = sum(
        model.star_sigmas_rad(mags, z, k) ** 2
        for k in error_kinds(sensor)
        if k in ("prnu", "residual")
    )
    err = cov + bias[:, :, None] * bias[:, None, :]
    err3 = np.zeros((len(mags), 3, 3))
    err3[:, :2, :2] = err * scale[:, None, None]
    err3[:, :2, :2] += (
        np.asarray(other + 0.0)[..., None, None] * np.eye(2) if np.ndim(other) else 0.0
    )
    err3 = proj @ err3 @ proj
    # a star matched in a fraction of the frames: that fraction of its information (its
    # weight in the fit's normal matrix, its weight squared times its error in the sum)
    some = chance > 0
    err3[some] /= chance[some, None, None]
    return propagated_covariance(pairs, weights * chance, err3)
