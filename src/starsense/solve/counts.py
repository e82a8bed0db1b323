"""How far a solve got, stage by stage: the counts a user reads when a frame fails."""

from __future__ import annotations

import functools
import math
import time

import numpy as np

from starsense.geometry.attitude import radec_roll_of_matrix
from starsense.solve.solution import Deferred, Solution

__all__ = [
    "detection_counts",
    "identification_counts",
    "max_candidates",
    "misfit_solution",
    "ms",
    "too_many_message",
]


def ms(t0: float) -> float:
    """Return the milliseconds since ``t0`` (a :func:`time.perf_counter` reading)."""
    return (time.perf_counter() - t0) * 1e3


def detection_counts(image, det) -> dict:
    """Return the detector's per-stage counts, saturation judged on the frame's full scale.

    Parameters
    ----------
    image : ndarray, shape (rows, columns)
        The frame as detected.
    det : Detections
        Its detections (:attr:`starsense.detect.Detections.counts`).

    Returns
    -------
    dict
        ``pixels_above_threshold``, ``hot_pixels``, ``candidates``, ``rejected_size``,
        ``rejected_faint``, ``rejected_shape``, ``saturated`` (detections with a pixel at the
        sensor's saturation or, for an integer frame, at its type's full scale: kept, but
        their centroids are less sure), ``detections``.
    """
    counts = dict(det.counts)
    a = np.asarray(image)
    if a.dtype.kind in "ui" and len(det) and not det.saturated.any():
        full = np.iinfo(a.dtype).max
        counts["saturated"] = int(np.count_nonzero(det.peak_counts >= full))
    return counts


def identification_counts(ident) -> dict:
    """Return the identification's counts: patterns tried, hypotheses, best probability.

    Parameters
    ----------
    ident : Identification
        The answer of the identifier (summed over the field ranges of an unknown field).

    Returns
    -------
    dict
        ``patterns_tried``, ``hypotheses_verified`` and ``best_false_match_probability`` (the
        least false-match probability of any hypothesis verified; 1 when none got that far).
    """
    return {
        "patterns_tried": int(ident.n_patterns_tried),
        "hypotheses_verified": int(ident.n_candidates),
        "best_false_match_probability": float(ident.best_false_match_probability),
    }


def max_candidates(shape) -> int:
    """Return the most detections a frame of ``shape`` can hold as stars.

    One per 1,000 pixels, at least 500: 786 for a 1024 x 768 frame, where the ESA frames give
    22-313 (matched filter, no known optics); real stars closer than ~30 pixels on average
    blend, and identification uses only the brightest tens.
    """
    return max(500, int(shape[0]) * int(shape[1]) // 1000)


def too_many_message(n: int, shape, *, limit: int, then: str) -> str:
    """Say why ``n`` detections of a frame of ``shape`` (rows, columns) are not stars."""
    return (
        f"{n} candidates, more than a frame of {shape[1]} x {shape[0]} pixels can hold as stars "
        f"({limit}): noise or clutter passed the detection (then: {then})"
    )


def misfit_solution(n_detections: int, ident, why: str, *, time_ms: float, stages):
    """Return the unsolved result of a frame identified whose attitude does not fit its stars.

    A smeared frame's stars are centroided over their streaks as a body rate predicts them
    (:mod:`starsense.solve.streaks`); a rate fitted wrong (a spurious roll turns and shortens
    the predicted streaks across the field) leaves the capsules short of the streaks and the
    centroids tens of pixels along them: an attitude fitted to those is not reported. ``why``
    says how the stars disagree with it.
    """
    why = f"identified, but {why}: the streaks' model does not fit this frame"
    return Solution("unverified", why, n_detections=n_detections, time_ms=time_ms,
                    stage_ms=stages, counts=identification_counts(ident))  # fmt: skip


def solved(points, ident, att, *, fov, apparent, time_ms, stages, radial, sensor) -> Solution:
    """Return the Solution of a solved frame.

    Parameters
    ----------
    points : CentroidPoints
        The centroids solved.
    ident : identification result
        The matches.
    att : AttitudeSolution
        The attitude and its covariance.
    fov : float
        The field across the columns, rad.
    apparent : dict
        How the references were placed (apparent places).
    time_ms : float
        The solve's time so far, ms.
    stages : dict
        Times of the stages, ms.
    radial : RadialFit or None
        The fitted camera of an unknown one.
    sensor : Sensor or None
    """
    n, shape = len(points.x), points.shape
    ra, dec, roll = radec_roll_of_matrix(att.matrix)
    if sensor is not None:
        focal = sensor.focal_length_px
    elif radial is not None:
        focal = radial.focal_px
    else:
        focal = shape[1] / 2.0 / math.tan(fov / 2.0)
    centroids = np.empty((n, 2))
    centroids[:, 0], centroids[:, 1] = points.x, points.y
    near_miss = ident.message.partition("; near miss")[2]
    return Solution.of(
        "solved",
        f"{ident.n_matches} of {n} {points.what} matched ({ident.algorithm})",
        ra_rad=ra,
        dec_rad=dec,
        roll_rad=roll,
        fov_rad=float(fov),
        n_detections=n,
        n_matched=int(ident.n_matches),
        rmse_rad=float(att.residual_rms_rad),
        false_match_probability=float(ident.false_match_probability),
        sigma_rad=tuple(np.sqrt(att.covariance_rad2.diagonal()).tolist()),
        time_ms=time_ms,
        stage_ms=stages,
        # a fit's matrix is made a Rotation when the solution's is first read
        rotation=Deferred(functools.partial(getattr, att, "rotation")),
        matches=tuple(zip(ident.detection_index.tolist(), ident.catalog_id.tolist(), strict=True)),
        centroids_px=centroids,
        image_shape=tuple(shape),
        focal_px=focal,
        distortion=None if radial is None else radial.to_dict(),
        apparent=apparent,
        sensor=sensor,
        counts=identification_counts(ident),
        # a near miss accepted on the frame's fainter stars says so (starsense.solve.near_miss)
        notes=(f"near miss{near_miss}",) if near_miss else (),
    )
