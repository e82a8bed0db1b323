"""Every detection held against the identified sky, each at its own centroid noise.

The identification's verification pairs detections and database stars within one radius for
the frame, four times the sigma its median residual implies
(:class:`starsense.identify.verify.Verifier`), and only among its brightest ``max_detections``.
A frame's centroids are not alike: a bright star's lies within a few hundredths of a pixel,
a faint one's within a few tenths. One radius from the median leaves out the faint true stars
(in a smeared frame, half the stars the database holds in the field), and with them the
lever arm the roll needs.

Once the attitude is known, :func:`rematched` holds every detection against the database
stars of the field, at four times its own sigma (its centroid's, from its signal and the
detector's noise, :func:`starsense.detect.centroid.cog_sigma_px`, and the identified
attitude's share, ``residual_rms / sqrt(matches)``): 1 true pair in 3,000 is left out
(``exp(-8)``). A pair is added only where it is unambiguous and unlikely by chance:

* one database star within the detection's radius, and no other detection within it;
* the chance of a database star within that radius of a random point, at the field's density
  of database stars, at most ``MAX_CHANCE`` (a faint noise detection, whose radius is wide,
  is not paired).

The matches the identification made stand; the attitude is fitted afterwards to all of them,
by the robust fit that drops the odd outlier (:func:`starsense.attitude.robust.robust_attitude`).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable

import numpy as np

from starsense.detect.centroid import cog_sigma_px

__all__ = ["MATCH_SIGMAS", "MAX_CHANCE", "detection_sigmas_px", "rematched", "scaled"]

#: the radius, in sigmas of a detection's direction (1 true pair in 3,000 outside it)
MATCH_SIGMAS = 4.0
#: the largest chance that a random point has a database star within its radius
MAX_CHANCE = 1e-3


def detection_sigmas_px(sensor, det, *, margin_px: int, shape) -> Callable[[], np.ndarray] | None:
    """Return what computes every detection's centroid sigma per axis, px, when called.

    None without a sensor. Called only where :func:`rematched` needs it.
    """
    if sensor is None:
        return None
    idx = np.arange(len(det))
    return functools.partial(
        cog_sigma_px, det, idx, detector=sensor.detector, margin_px=margin_px, shape=shape
    )


def scaled(sigma, factor: float) -> Callable[[], np.ndarray]:
    """Return what gives ``sigma`` (an array, or a callable returning one) times ``factor``."""
    return lambda: np.asarray(sigma() if callable(sigma) else sigma, dtype=float) * factor


def rematched(ident, database, vectors, *, sigma_rad):
    """Return the identification with every unambiguous detection paired (module docstring).

    Parameters
    ----------
    ident : Identification
        A solved identification of a known field (scale 1).
    database : IdentificationDatabase
        The database it was identified against.
    vectors : ndarray, shape (N, 3)
        The detections' camera-frame unit vectors (those identified).
    sigma_rad : ndarray, shape (N,), or a callable returning it
        Each detection's per-axis direction noise, rad; a callable is called only when a
        free detection has a database star within the widest radius ``MAX_CHANCE`` allows.

    Returns
    -------
    Identification
        ``ident`` itself when nothing is added, else with the added pairs (detections in
        order).
    """
    v = np.asarray(vectors, dtype=float)
    matched_d = np.asarray(ident.detection_index, dtype=np.int64)
    matched_c = np.asarray(ident.catalog_index, dtype=np.int64)
    if not ident.solved or ident.scale != 1.0 or len(v) == len(matched_d) or len(matched_d) < 3:
        return ident
    r = ident.rotation.as_matrix()  # ICRS -> camera
    cos_edge = float(v[:, 2].min())  # the field's cone: the farthest detection from the axis
    reach = math.acos(min(max(cos_edge, -1.0), 1.0))
    boresight = r[2]
    chord = 2.0 * math.sin(0.5 * min(reach + 1e-3, math.pi / 2))
    near = np.asarray(database.tree.query_ball_point(boresight, chord), dtype=np.int64)
    if len(near) == 0:
        return ident
    cam = database.vectors[near] @ r.T
    solid_angle = 2.0 * math.pi * (1.0 - math.cos(reach + 1e-3))
    density = len(near) / solid_angle  # database stars per steradian
    free_d = np.ones(len(v), dtype=bool)
    free_d[matched_d] = False
    # angles (small): chord between unit vectors, detections x field stars
    sep = np.sqrt(np.maximum(2.0 - 2.0 * (v @ cam.T), 0.0))
    # a pair needs a radius within MAX_CHANCE, so a star that close to a free detection: where
    # there is none, nothing is added and the detections' sigmas are not needed
    widest = math.sqrt(MAX_CHANCE / (math.pi * density)) * (1.0 + 1e-9)
    if not (sep[free_d] <= widest).any():
        return ident
    sigma = np.asarray(sigma_rad() if callable(sigma_rad) else sigma_rad, dtype=float)
    att = ident.residual_rms_rad / math.sqrt(len(matched_d))
    radius = MATCH_SIGMAS * np.hypot(sigma, att if math.isfinite(att) else 0.0)
    free_c = ~np.isin(near, matched_c)
    within = sep <= radius[:, None]
    n_stars = within.sum(axis=1)
    n_dets = within.sum(axis=0)
    chance = density * math.pi * radius**2
    add_d, add_c = [], []
    for d in np.flatnonzero(free_d & (n_stars == 1) & (chance <= MAX_CHANCE)):
        j = int(np.flatnonzero(within[d])[0])
        if free_c[j] and n_dets[j] == 1:
            add_d.append(int(d))
            add_c.append(int(near[j]))
    if not add_d:
        return ident
    det = np.concatenate([matched_d, add_d])
    cat = np.concatenate([matched_c, add_c])
    order = np.argsort(det, kind="stable")
    det, cat = det[order], cat[order]
    return dataclasses.replace(
        ident,
        detection_index=det,
        catalog_index=cat,
        catalog_id=np.asarray(database.ids)[cat],
        message=f"{ident.message}; {len(add_d)} more at each detection's own centroid noise",
    )
