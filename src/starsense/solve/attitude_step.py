"""A solved frame's attitude: from its matched centroids, then from its pixels (the model).

Once a frame is identified, :func:`frame_attitude` fits the attitude to the matched centroids
(the robust fit of :mod:`starsense.attitude.robust`; a smeared frame's centroids over its
streaks, :mod:`starsense.solve.streaks`, whose body rate starts the model's), then, with a
sensor and a frame, fits the sensor's forward model to the stars' pixels
(:mod:`starsense.solve.refine`). The centroids' attitude, where it stands, reports its
covariance scaled to what its residuals show (:func:`starsense.attitude.robust.
residual_scaled`); a smeared frame's does not where they scatter beyond their model
(:func:`starsense.attitude.robust.residuals_beyond_noise`): a rate or a streak model wrong
enough to scatter them also moves every centroid along its streak the same way, an error of
the attitude that no residual shows, and no attitude is reported.
"""

from __future__ import annotations

import dataclasses
import functools
import time

import numpy as np

from starsense.attitude.robust import (
    MISFIT_SIGMAS,
    median_misfit,
    residual_scaled,
    residuals_beyond_noise,
    robust_attitude,
)
from starsense.solve.attitude_fit import kernel_fit
from starsense.solve.counts import misfit_solution, ms, solved
from starsense.solve.references import matched_references, sky_places
from starsense.solve.refine import refined_attitude
from starsense.solve.streak_model import streak_body_rate
from starsense.solve.streaks import ShortStreaks
from starsense.solve.unknown_optics import refine_identification

__all__ = ["frame_attitude", "solution_of"]


def solution_of(solver, points, ident, *, database, vectors, fov, k1, sigma_px, obs_time, image,
                timing):  # fmt: skip
    """Return the Solution of an identified frame (or list of centroids): its attitude.

    An unknown camera (no sensor) first has its focal length and radial distortion fitted to
    the matches (:func:`starsense.solve.unknown_optics.refine_identification`; ``k1``: the
    identification's guess); then :func:`frame_attitude`. ``fov``: the field the matches
    were made at, rad; ``timing``: (the call's start, its stages' times, ms).
    """
    t0, stages = timing
    t3 = time.perf_counter()
    radial = None
    if solver.sensor is None:  # an unknown camera: fit its focal length and radial distortion
        ident, radial, vectors, fov = refine_identification(
            ident, database, np.column_stack([points.x, points.y]), flux=points.ranking,
            shape=points.shape, fov_rad=fov, k1=k1, catalog=solver.catalog,
        )  # fmt: skip
    got = frame_attitude(
        solver, points, ident, db=database, vectors=vectors, sigma_px=sigma_px,
        pixel_rad=fov / points.shape[1], obs_time=obs_time, image=image,
    )  # fmt: skip
    if isinstance(got, str):  # the streaks' model does not fit: no attitude
        return misfit_solution(len(points.x), ident, got, time_ms=ms(t0), stages=stages)
    att, apparent, notes = got
    stages["attitude_ms"] = ms(t3)
    sol = solved(
        points, ident, att, fov=fov, apparent=apparent, time_ms=ms(t0), stages=stages,
        radial=radial, sensor=solver.sensor,
    )  # fmt: skip
    return dataclasses.replace(sol, notes=(*sol.notes, *notes)) if notes else sol


def frame_attitude(solver, points, ident, *, db, vectors, sigma_px, pixel_rad, obs_time, image):
    """Return (attitude, apparent places' record, notes), or why a smeared frame misfits.

    Parameters
    ----------
    solver : Solver
    points : CentroidPoints
        The frame's centroids.
    ident : identification result
        Its matches (``detection_index`` into ``points``, ``catalog_index`` into ``db``).
    db : identification database
    vectors : ndarray (N, 3)
        The centroids' camera-frame unit vectors.
    sigma_px : callable
        ``sigma_px(matched, x, vectors) -> (vectors, sigma px, streaks or None)``: the matched
        centroids as the attitude takes them (a smeared frame's over its streaks).
    pixel_rad : float
        The angle of a pixel, rad.
    obs_time : str, astropy.time.Time or None
    image : ndarray or None
        The frame (None: centroids only, no model fit).

    Returns
    -------
    (AttitudeSolution, dict, tuple of str), or str
        The attitude, how the references were placed and what the fit noted; or, for a smeared
        frame whose stars lie more than ``MISFIT_SIGMAS`` of their sigmas (median) from the
        attitude fitted to their streaks, or (no model fit standing) whose residuals exceed
        their noise, how they disagree.
    """
    matched = np.asarray(ident.detection_index)
    ref, apparent, places = matched_references(solver, db, ident, obs_time=obs_time)
    body, sigma, streaks = sigma_px(matched, points.x, vectors[matched])
    listed = points.what == "centroids"  # a list: its sigma stated, not measured (no pixels)
    att, keep = robust_attitude(body, ref, sigma * pixel_rad, fit=kernel_fit, scatter=listed)
    misfit = functools.partial(median_misfit, body, ref, sigma * pixel_rad)  # at an attitude
    rate = hint = None  # smeared: the body rate the streaks give (starts the model fit's)
    if isinstance(streaks, ShortStreaks):  # too short to re-centroid: the rate they suggest
        hint, streaks = streaks.rate_rad_s, None
    if streaks is not None:  # smeared: centroids over the streaks, which must fit them
        rate = streak_body_rate(solver.sensor, body, streaks.streaks_px)
        miss = misfit(rotation=att.rotation, keep=keep)
        if miss > MISFIT_SIGMAS:
            return (
                f"the matched stars lie {miss:.0f} times their sigma (median) from the attitude "
                "fitted to their streaks"
            )
    notes = ()
    if image is not None and solver.settings.refine == "model":  # the forward model's fit
        sky = solver.sky_stars(db.params.band)
        att, notes = refined_attitude(
            image,
            att,
            solver.sensor,
            db=db,
            ident=ident,
            places=places,
            rate_rad_s=rate,
            rate_hint_rad_s=hint,
            sky=sky,
            place=sky_places(solver, sky, obs_time=obs_time),
            points=points,
            misfit=misfit,
        )
    if att.method != "model" and streaks is not None and residuals_beyond_noise(att):
        # smeared, no fit of the pixels stands, and the streak centroids scatter beyond their
        # model: the rate or the streaks' model is wrong, which also moves every centroid
        # along its streak the same way, an error the residuals do not show; no attitude
        return (
            f"the matched stars' residuals about the attitude fitted to their streaks exceed "
            f"their noise (chi-square {2.0 * float(att.loss):.0f} on {int(att.chi2_dof)} degrees "
            "of freedom, past its 0.1 % point)"
        )
    if att.method != "model":  # the centroids' attitude: as sure as its residuals allow
        att = residual_scaled(att)
    return att, apparent, notes
