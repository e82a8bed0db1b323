"""The pieces of a long faint streak joined into one detection before identification.

A star smeared over many PSF widths lights a narrow ridge; where its light per pixel is a few
noise sigmas the noise takes the ridge below the threshold here and there, and the detector
finds pieces of it, each centroided somewhere along the streak instead of at its middle (the
star's place at mid-exposure): identification then matches only the few stars bright enough to
stay whole. The brightest streaks give the body rate (:func:`~starsense.solve.streak_model.
streak_model`), which draws every star's streak where it lies; detections on one such streak
(within the PSF's width of its line, together no longer than it) are one star's pieces,
joined into one detection, their light summed. Its place is the centre of gravity over the
capsule the rate draws there (every pixel within a few PSF sigmas of the streak, lit or not),
moved until it stays, started at the middle of the pieces' lit span: where an end of the streak
fades under the threshold the span's middle misses the star's, the capsule does not. A frame
whose streaks are short, or whose brightest detections are not streaks, is left as it is.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.spatial import cKDTree

from starsense.detect.streak import SYSTEMATIC
from starsense.solve.streak_model import (
    CAPSULE_PAD_PX,
    CAPSULE_SIGMAS,
    MIN_STREAK_SIGMAS,
    N_RATE_STARS,
    streak_model,
)
from starsense.solve.streaks import capsule_centroids, streak_measure

__all__ = ["joined_pieces"]


def joined_pieces(solver, image, det):
    """Return the detections ``det`` with each long streak's pieces joined (module docstring).

    Parameters
    ----------
    solver : Solver
        Its sensor (None: nothing is joined), settings and detection logic.
    image : ndarray, shape (rows, columns)
        The frame, counts.
    det : Detections

    Returns
    -------
    Detections
        ``det`` itself where nothing is joined.
    """
    sensor = solver.sensor
    if sensor is None or len(det) < 3:
        return det
    sigma = float(sensor.detector.psf_sigma_px)
    measure = streak_measure(solver)
    box = det.bbox
    extent = np.maximum(box[:, 1] - box[:, 0], box[:, 3] - box[:, 2])
    order = np.argsort(-det.integrated_counts, kind="stable")
    shortest = MIN_STREAK_SIGMAS * sigma + 2.0 * measure["margin_px"]  # re-centroided from
    if np.median(extent[order[:N_RATE_STARS]]) < shortest:
        return det  # the brightest are no streaks: at rest, or too short to break
    model, _ = streak_model(
        sensor, image, (det.x, det.y), order=order, extent_px=extent.astype(float), **measure
    )
    if model is None:
        return det
    streaks = model(det.x, det.y)
    radius = CAPSULE_SIGMAS * sigma + CAPSULE_PAD_PX
    groups = _streak_groups(det, streaks, width=radius)
    if all(len(g) == 1 for g in groups):
        return det
    places = _span_middles(det, groups, streaks)
    joined = np.array([len(g) > 1 for g in groups])
    places[joined] = _capsule_places(image, places[joined], model, measure["level"], radius)
    return _merged(det, groups, places)


def _capsule_places(image, places, model, level, radius: float) -> np.ndarray:
    """Return joined streaks' places moved to their light's centre over their whole capsule.

    The lit span's middle misses where an end of the streak fades under the threshold; the
    centre of gravity over the capsule the rate draws there (every pixel within ``radius`` of
    the streak, lit or not), moved until it stays, is the star's mid-exposure place, as after
    identification (:func:`starsense.solve.streaks.capsule_centroids`).
    """
    x, y = places[:, 0].copy(), places[:, 1].copy()
    seg = model(x, y) * (1.0 + SYSTEMATIC)
    half = math.ceil(float(np.hypot(seg[:, 0], seg[:, 1]).max()) + radius + 2.0)
    gx, gy, total, _, _, r0, c0 = capsule_centroids(
        image, x, y, seg=seg, half=half, level=level, radius=radius
    )
    found = np.isfinite(gx) & (total > 0)
    return np.column_stack([np.where(found, gx + c0, x), np.where(found, gy + r0, y)])


def _streak_groups(det, streaks, *, width: float) -> list[np.ndarray]:
    """Return the detections grouped by the streak they lie on: a streak's pieces joined.

    ``streaks`` (N, 2): each detection's streak as the rate draws it there, px. Two detections
    lie on one streak when each is within ``width`` of the other's line and within its length
    along it; pieces are joined, closest first, while together they span no more than the
    streak (its lit ends lie within ``width`` of its ends): two stars on one line stay two.
    """
    xy = np.column_stack([det.x, det.y])
    length = np.hypot(streaks[:, 0], streaks[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        along = np.where(length[:, None] > 0, streaks / length[:, None], 0.0)
    # each detection's lit extent along its streak: its box's corners projected on the line
    corners = _corners(det.bbox)
    pairs = cKDTree(xy).query_pairs(float(np.max(length, initial=0.0)), output_type="ndarray")
    if len(pairs) == 0:
        return [np.array([i]) for i in range(len(xy))]
    i, j = pairs[:, 0], pairs[:, 1]
    d = xy[j] - xy[i]
    s = np.einsum("ij,ij->i", d, along[i])
    cross = np.abs(d[:, 0] * along[i, 1] - d[:, 1] * along[i, 0])
    cross_j = np.abs(d[:, 0] * along[j, 1] - d[:, 1] * along[j, 0])
    ok = (cross <= width) & (cross_j <= width) & (np.abs(s) <= np.minimum(length[i], length[j]))
    i, j, s = i[ok], j[ok], np.abs(s[ok])
    parent = np.arange(len(xy))

    def root(k):
        while parent[k] != k:
            parent[k] = parent[parent[k]]
            k = parent[k]
        return k

    members = {k: [k] for k in range(len(xy))}
    for a, c in zip(i[np.argsort(s)], j[np.argsort(s)], strict=True):
        ra, rc = root(a), root(c)
        if ra == rc:
            continue
        joined = members[ra] + members[rc]
        if _span(corners[joined], along[ra]) > length[ra] + 2.0 * width:
            continue  # longer than one star's streak: two stars on one line
        parent[rc] = ra
        members[ra] = joined
        del members[rc]
    return [np.asarray(m) for m in members.values()]


def _corners(bbox) -> np.ndarray:
    """Return the (x, y) centres of the corner pixels of boxes (row0, row1, col0, col1)."""
    b = np.asarray(bbox, dtype=float)
    return np.stack(
        [b[:, [2, 0]], b[:, [3, 0]] - [1.0, 0.0], b[:, [2, 1]] - [0.0, 1.0], b[:, [3, 1]] - 1.0],
        axis=1,
    )


def _span(corners, direction) -> float:
    """Return the extent of boxes' ``corners`` (M, 4, 2) (x, y) along ``direction``, px."""
    proj = corners @ direction
    return float(proj.max() - proj.min())


def _span_middles(det, groups, streaks) -> np.ndarray:
    """Return each group's place (G, 2): a joined one's at the middle of its lit span.

    Along the streak's line the middle of the boxes' corners (whose PSF margins are alike at
    both ends); across it, the pieces' mean weighted by their light.
    """
    xy = np.column_stack([det.x, det.y])
    corners = _corners(det.bbox)
    places = np.empty((len(groups), 2))
    for k, g in enumerate(groups):
        if len(g) == 1:
            places[k] = xy[g[0]]
            continue
        e = streaks[g[0]] / np.hypot(*streaks[g[0]])
        n = np.array([-e[1], e[0]])
        proj = corners[g].reshape(-1, 2) @ e
        w = np.maximum(det.integrated_counts[g], 1e-12)
        places[k] = e * 0.5 * (proj.max() + proj.min()) + n * np.average(xy[g] @ n, weights=w)
    return places


def _merged(det, groups, places):
    """Return ``det`` with each group of detections made one at ``places``, brightest first.

    A joined streak's light, pixels and box are its pieces' together.
    """
    light = np.array([det.integrated_counts[g].sum() for g in groups])
    order = np.argsort(-light, kind="stable")
    groups = [groups[k] for k in order]
    places = np.asarray(places)[order]
    b = det.bbox
    out = {f.name: getattr(det, f.name) for f in dataclasses.fields(det)}
    out.update(
        x=places[:, 0].astype(float),
        y=places[:, 1].astype(float),
        integrated_counts=light[order],
        n_pixels=np.array([det.n_pixels[g].sum() for g in groups]),
        peak_counts=np.array([det.peak_counts[g].max() for g in groups]),
        saturated=np.array([det.saturated[g].any() for g in groups]),
        fit_ok=np.array([det.fit_ok[g].all() for g in groups]),
        bbox=np.array(
            [[b[g, 0].min(), b[g, 1].max(), b[g, 2].min(), b[g, 3].max()] for g in groups]
        ),
    )
    out["extra"] = {k: v for k, v in det.extra.items() if k != "rank"}
    out["extra"]["joined_pieces"] = len(det) - len(groups)
    return type(det)(**out)
