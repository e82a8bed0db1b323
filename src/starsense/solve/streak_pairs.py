"""A smeared star's pair holds only where its capsule lies on the star's streak.

In a smeared frame a faint star is detected in pieces, and the verification pairs a detection
with a database star within a radius as wide as a streak is long (the pieces lie anywhere
along it). A noise blob or another star's piece beside the streak falls in that radius too.
Its capsule (:mod:`starsense.solve.streaks`) then holds no light of the star's streak: the
centroid lies tens of pixels along and several to tens across the star's track. Its sigma
is the mean of its axes, so such a pair is a few sigma off and the robust fit keeps it.

Across its streak a centroid is known to its capsule: a capsule that holds the streak's ridge
has its centre within its radius of the streak's line, whatever the pieces along it.
:func:`on_streaks` drops, worst first, the pair whose centroid lies across its star's predicted
streak by more than the capsule's radius plus ``MATCH_SIGMAS`` of its own across-track sigma,
refitting after each, while more than three pairs remain.

:func:`smeared_fit` then fits the attitude as a smeared frame needs it: those pairs dropped,
each star's reference moved to where its capsule lands with its neighbours' streaks, and its
along-track sigma grown where its capsule chases a neighbour's light
(:func:`starsense.solve.blends.streak_reference`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from starsense.attitude.robust import median_misfit, robust_attitude
from starsense.solve.blends import streak_reference
from starsense.solve.rematch import MATCH_SIGMAS
from starsense.solve.streaks import CAPSULE_PAD_PX, CAPSULE_SIGMAS

__all__ = ["across_excess", "on_streaks", "smeared_fit"]


def across_excess(sensor, streaks, ref, *, rotation) -> np.ndarray:
    """Return how far each centroid lies across its star's streak beyond what it can, px.

    ``streaks`` (:class:`~starsense.solve.streaks.StreakCentroids`, K) are the matched stars'
    capsule centroids, ``ref`` (K, 3) their reference directions and ``rotation`` an attitude
    (reference to camera). The limit is the capsule's radius (``CAPSULE_SIGMAS`` PSF sigmas
    plus ``CAPSULE_PAD_PX``) plus ``MATCH_SIGMAS`` of the centroid's sigma across the streak.
    Positive: the capsule does not hold the streak's ridge. A star without a streak gives
    -inf.
    """
    seg = np.asarray(streaks.streaks_px, dtype=float)
    length = np.hypot(seg[:, 0], seg[:, 1])
    safe = np.where(length > 0.0, length, 1.0)
    normal = np.column_stack([-seg[:, 1], seg[:, 0]]) / safe[:, None]
    x, y = sensor.project(rotation.apply(np.asarray(ref, dtype=float)))
    across = np.abs((streaks.x - x) * normal[:, 0] + (streaks.y - y) * normal[:, 1])
    var = np.einsum("ki,kij,kj->k", normal, np.asarray(streaks.cov_px2, dtype=float), normal)
    radius = CAPSULE_SIGMAS * float(sensor.detector.psf_sigma_px) + CAPSULE_PAD_PX
    excess = across - radius - MATCH_SIGMAS * np.sqrt(np.maximum(var, 0.0))
    return np.where((length > 0.0) & np.isfinite(excess), excess, -np.inf)


def on_streaks(fit, pairs, *, sensor, pixel_rad: float):
    """Return the fit and the pairs without those whose centroid lies off their streak.

    ``fit`` is :func:`~starsense.attitude.robust.robust_attitude`'s ``(attitude, keep)`` on
    every pair of ``pairs``: the identification, then per pair (K rows each) the camera
    vectors, the reference vectors, the sigmas (px; ``pixel_rad`` rad each), the
    :class:`~starsense.solve.streaks.StreakCentroids` and the detections' indices. The pair
    worst across its streak (:func:`across_excess`) is dropped and the rest refitted while one
    lies beyond and more than three remain. Returns ``fit`` and ``pairs`` alike (the
    identification without the dropped pairs).
    """
    att, keep = fit
    ident, body, ref, sigma, streaks, matched = pairs
    sigma_rad = np.asarray(sigma, dtype=float) * pixel_rad
    on = np.ones(len(body), dtype=bool)
    while on.sum() > 3:
        excess = np.full(len(body), -np.inf)
        excess[on] = across_excess(sensor, _rows(streaks, on), ref[on], rotation=att.rotation)
        worst = int(np.argmax(excess))
        if excess[worst] <= 0.0:
            break
        on[worst] = False
        att, keep = robust_attitude(body[on], ref[on], sigma_rad[on])
    if on.all():
        return fit, pairs
    ident = dataclasses.replace(
        ident,
        detection_index=np.asarray(ident.detection_index)[on],
        catalog_index=np.asarray(ident.catalog_index)[on],
        catalog_id=np.asarray(ident.catalog_id)[on],
    )
    return (att, keep), (ident, *(_rows(a, on) for a in (body, ref, sigma, streaks, matched)))


def smeared_fit(fit, pairs, *, sensor, pixel_rad: float, database, sky, points):
    """Return the attitude of a smeared frame, its identification and its median misfit.

    ``fit`` and ``pairs`` are as :func:`on_streaks` takes them, ``database`` the identification
    database, ``sky`` the stars that may lie in a capsule
    (:func:`starsense.solve.blends.streak_photocentres`) and ``points`` the frame's detections
    (where each capsule started). The pairs off their streaks are dropped
    (:func:`on_streaks`); the references are moved to the capsules' photocentres, each sigma
    grown along its streak by its capsule's gain, and the attitude refitted
    (:func:`starsense.solve.blends.streak_reference`). Returns ``(attitude, identification,
    misfit)``: the matched stars' median residual in their sigmas
    (:func:`starsense.attitude.robust.median_misfit`).
    """
    (att, keep), (ident, body, ref, sigma, streaks, matched) = on_streaks(
        fit, pairs, sensor=sensor, pixel_rad=pixel_rad
    )
    held, grow = streak_reference(
        sensor, database, ref, index=ident.catalog_index, rotation=att.rotation,
        streaks=streaks.streaks_px, pixel_rad=pixel_rad,
        starts_px=np.column_stack([points.x[matched], points.y[matched]]), sky=sky,
        electrons=streaks.electrons, clipped=streaks.clipped,
    )  # fmt: skip
    sigma_rad = np.asarray(sigma, dtype=float) * _along_grown(streaks, grow) * pixel_rad
    if held is not ref or (grow > 1.0).any():
        att, keep = robust_attitude(body, held, sigma_rad)
    return att, ident, median_misfit(body, held, sigma_rad, rotation=att.rotation, keep=keep)


def _along_grown(streaks, grow) -> np.ndarray:
    """Return the factor on each mean-of-axes sigma for its along-track sigma grown ``grow``."""
    seg = np.asarray(streaks.streaks_px, dtype=float)
    length = np.hypot(seg[:, 0], seg[:, 1])
    u = seg / np.where(length > 0.0, length, 1.0)[:, None]
    normal = np.column_stack([-u[:, 1], u[:, 0]])
    cov = np.asarray(streaks.cov_px2, dtype=float)
    along = np.einsum("ki,kij,kj->k", u, cov, u)
    across = np.einsum("ki,kij,kj->k", normal, cov, normal)
    total = along + across
    safe = np.where(total > 0.0, total, 1.0)
    return np.where(total > 0.0, np.sqrt((grow**2 * along + across) / safe), 1.0)


def _rows(a, on):
    """``a``'s rows ``on`` (every array field of a dataclass of per-pair arrays)."""
    if dataclasses.is_dataclass(a):
        return dataclasses.replace(
            a,
            **{
                f.name: np.asarray(getattr(a, f.name))[on]
                for f in dataclasses.fields(a)
                if getattr(a, f.name) is not None
            },
        )
    return np.asarray(a)[on]
