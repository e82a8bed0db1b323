"""Neighbours in a detection's window: where the detector's centroid of a star at rest lands.

The detector centroids a star over its window: the box of its lit pixels grown by the margin
(:mod:`starsense.detect.regions`). A catalogue neighbour whose light reaches that window pulls
the centre of gravity towards it, and where the two stars' lit footprints touch they are one
region whose box holds both. The close-double photocentre (:func:`starsense.solve.blends.
photocentres`, within :func:`~starsense.solve.blends.blend_radius_px`) covers pairs the PSF
cannot separate; a bright star's footprint reaches further: a V 2.6 star and a V 4.5 neighbour
3.6 px apart (PSF sigma 1.06 px, 10-bit) lit one region centred 0.6 px off the bright star, and
its frame's roll was 9.6 times its prediction.

:func:`box_reference` gives each matched star the place the centre of gravity of its window
lands on a noiseless rendering of it and of every catalogue star whose PSF reaches the window
(pixel-integrated Gaussians, fluxes from the catalogue magnitudes; with the frame's zero point,
each pixel clipped where the detector clips), less where it lands on the star alone: the same
window, the same weights (``power`` 1: the counts, 2: their squares). The window is the one the
detector used, read off its detection, so the rule needs no model of the threshold.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import ndtr

from starsense.attitude.robust import robust_attitude
from starsense.solve.blends import SAME_STAR_RAD, blend_radius_px, frame_zero_point_e, photocentres

__all__ = ["box_fit", "box_reference", "window_fields", "window_shifts_px"]

#: a neighbour's PSF reaches a window from this many sigma beyond it
_REACH_SIGMAS = 4.0
#: a shift below this is left out, px (a centroid's noise is 1e-3 px at 1e6 electrons)
_FLOOR_PX = 1e-3


def window_shifts_px(owner, xy, flux, *, windows, sigma_px: float, clip=None, power: int = 1):
    """Return how far each window's centre of gravity lands from where it lands on its star.

    Parameters
    ----------
    owner : ndarray (S,) of int
        The window each source lights, 0..K-1; each window's first source is its star, the
        others its neighbours.
    xy : ndarray (S, 2)
        The sources, px.
    flux : ndarray (S,)
        Their light, electrons (or any unit when ``clip`` is None).
    windows : ndarray (K, 4) of int
        The centroid windows (row0, row1, col0, col1, half-open), px.
    sigma_px : float
        The PSF's Gaussian sigma, px.
    clip : float, optional
        Where a pixel clips, in ``flux``'s unit.
    power : {1, 2}
        The centroider's weights: the counts or their squares.

    Returns
    -------
    ndarray (K, 2)
        (dx, dy), px; zeros where a window holds no light.
    """
    owner = np.asarray(owner, dtype=int)
    xy = np.asarray(xy, dtype=float)
    win = np.asarray(windows, dtype=int).reshape(-1, 4)
    n_win = len(win)
    star = np.ones(len(owner), dtype=bool)
    star[1:] = owner[1:] != owner[:-1]
    size = np.max(win[:, [1, 3]] - win[:, [0, 2]], axis=0)  # the largest window: (rows, cols)
    rows = win[:, 0, None] + np.arange(size[0])  # (K, H) pixel centres, padded
    cols = win[:, 2, None] + np.arange(size[1])
    in_rows, in_cols = rows < win[:, 1, None], cols < win[:, 3, None]

    def profile(at, centre):  # a unit Gaussian's integral over each pixel
        return ndtr((at + 0.5 - centre[:, None]) / sigma_px) - ndtr(
            (at - 0.5 - centre[:, None]) / sigma_px
        )

    py = profile(rows[owner], xy[:, 1]) * in_rows[owner]
    px = profile(cols[owner], xy[:, 0]) * in_cols[owner]
    stamps = np.asarray(flux, dtype=float)[:, None, None] * py[:, :, None] * px[:, None, :]
    planes = np.zeros((2, n_win, size[0], size[1]))
    np.add.at(planes[0], owner, stamps)
    planes[1, owner[star]] = stamps[star]
    if clip is not None:
        planes = np.minimum(planes, clip)
    w = planes**power
    total = w.sum(axis=(2, 3))
    ok = np.all(total > 0.0, axis=0)
    safe = np.where(total > 0.0, total, 1.0)
    gx = np.einsum("akhw,kw->ak", w, cols.astype(float)) / safe
    gy = np.einsum("akhw,kh->ak", w, rows.astype(float)) / safe
    return np.where(ok[:, None], np.column_stack([gx[0] - gx[1], gy[0] - gy[1]]), 0.0)


def box_reference(sensor, ref, plain, *, rotation, mags, windows, sky, zero_point_e=None,
                  power: int = 1) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Return ``ref`` with each star moved to where its detection window's centroid lands.

    Parameters
    ----------
    sensor : Sensor
        The camera (projection, PSF sigma, clip level).
    ref : ndarray (K, 3)
        The matched stars' reference directions (apparent places of ``plain``).
    plain : ndarray (K, 3)
        Their catalogue directions, in the frame of ``sky``.
    rotation : Rotation
        The attitude, reference to camera (a first fit: the neighbours' offsets in pixels).
    mags : ndarray (K,)
        The matched stars' magnitudes, in ``sky``'s band.
    windows : ndarray (K, 4) of int
        The windows their centroids were taken over: row0, row1, col0, col1, half-open.
    sky : (vectors, mags, tree)
        Every catalogue star that may light a window (the matched star itself among them).
    zero_point_e : float, optional
        Electrons of a magnitude-0 star in this frame: pixels are then clipped at the
        detector's :attr:`~starsense.sensor.detector.Detector.clip_e` (None: not clipped).
    power : {1, 2}
        The detector's centroid weights (counts, or their squares).

    Returns
    -------
    vectors : ndarray (K, 3)
        Unit vectors; ``ref``'s where no window holds a neighbour's light.
    moved : ndarray (K,) of bool
        The stars whose windows hold a neighbour's light.
    """
    sigma = float(sensor.detector.psf_sigma_px)
    sky_vectors, sky_mags, sky_tree = sky
    m = rotation.as_matrix()  # reference -> camera (the matrix: Rotation's calls cost more)
    cam = plain @ m.T
    x0, y0 = sensor.project(cam)
    win = np.asarray(windows, dtype=float)
    # the window's farthest corner from the star, and the PSF's tail beyond it, px
    dx = np.maximum(np.abs(win[:, 2] - 0.5 - x0), np.abs(win[:, 3] - 0.5 - x0))
    dy = np.maximum(np.abs(win[:, 0] - 0.5 - y0), np.abs(win[:, 1] - 0.5 - y0))
    reach = np.hypot(dx, dy) + _REACH_SIGMAS * sigma
    clip = None if zero_point_e is None else float(sensor.detector.clip_e)
    scale = 1.0 if zero_point_e is None else float(zero_point_e)
    out = np.array(ref, dtype=float)
    moved = np.zeros(len(plain), dtype=bool)
    # every star's neighbours in one query (not a loop over the stars)
    centre = sensor.unproject(x0, y0)
    side = sensor.unproject(x0 + reach, y0)
    angle = np.arccos(np.clip(np.einsum("ij,ij->i", centre, side), -1.0, 1.0))
    lists = sky_tree.query_ball_point(plain, 2.0 * np.sin(0.5 * angle))
    owner = np.repeat(np.arange(len(plain)), [len(v) for v in lists])
    if owner.size == 0:
        return out, moved
    near = np.concatenate([np.asarray(v, dtype=int) for v in lists])
    other = np.linalg.norm(sky_vectors[near] - plain[owner], axis=1) > SAME_STAR_RAD
    owner, near = owner[other], near[other]
    xn, yn = sensor.project(sky_vectors[near] @ m.T)
    tail = _REACH_SIGMAS * sigma + 0.5  # a neighbour's PSF reaches the window
    can = (xn > win[owner, 2] - tail) & (xn < win[owner, 3] - 1.0 + tail)
    can &= (yn > win[owner, 0] - tail) & (yn < win[owner, 1] - 1.0 + tail)
    # a neighbour of f moves a star of F by less than f / F times its distance from it (plus
    # the window's pixel); one whose pull is below the floor is left out (most are faint)
    own_e = scale * 10.0 ** (-0.4 * np.asarray(mags, dtype=float))
    if clip is not None:  # a clipped star holds at most its clipped light
        own_e = np.minimum(own_e, clip * 2.0 * math.pi * sigma**2)
    pull = scale * 10.0 ** (-0.4 * np.asarray(sky_mags)[near]) / own_e[owner]
    can &= pull * (np.hypot(xn - x0[owner], yn - y0[owner]) + 1.0) >= _FLOOR_PX
    owner, near, xn, yn = owner[can], near[can], xn[can], yn[can]
    if owner.size == 0:
        return out, moved
    # each window's star first, then its neighbours
    stars = np.unique(owner)
    src_owner = np.concatenate([stars, owner])
    order = np.argsort(src_owner, kind="stable")
    src_owner = src_owner[order]
    xy = np.column_stack([np.append(x0[stars], xn), np.append(y0[stars], yn)])[order]
    src_mags = np.append(np.asarray(mags, dtype=float)[stars], np.asarray(sky_mags)[near])[order]
    slot = np.searchsorted(stars, src_owner)
    shift = window_shifts_px(
        slot, xy, scale * 10.0 ** (-0.4 * src_mags), windows=np.asarray(windows)[stars],
        sigma_px=sigma, clip=clip, power=power,
    )  # fmt: skip
    big = np.hypot(shift[:, 0], shift[:, 1]) >= _FLOOR_PX
    if not big.any():
        return out, moved
    k, shift = stars[big], shift[big]
    there = sensor.unproject(x0[k] + shift[:, 0], y0[k] + shift[:, 1])
    new = ref[k] + (there - cam[k]) @ m
    out[k] = new / np.linalg.norm(new, axis=1)[:, None]
    moved[k] = True
    return out, moved


def box_fit(fit, pairs, *, sensor, pixel_rad: float, database, sky, points):
    """Return the attitude of a frame at rest with each star at its window's photocentre.

    ``fit`` is :func:`~starsense.attitude.robust.robust_attitude`'s ``(attitude, keep)`` on
    ``pairs``: the identification, the camera vectors (K, 3), the reference vectors (K, 3,
    with the close doubles' photocentres of ``database``,
    :func:`starsense.solve.blends.photocentres`), the sigmas (K,) px (``pixel_rad`` rad each)
    and the matched detections' indices (K,) into ``points``, whose ``windows`` and
    ``window_power`` are the detector's (:class:`~starsense.solve.centroids.CentroidPoints`).
    The frame's zero point comes from the matched detections' lit sums (``points.flux``, in
    electrons where ``points.windows`` is given). A star whose window holds a neighbour of
    ``sky`` has its reference replaced by :func:`box_reference`'s, and the attitude is
    refitted; otherwise ``fit``'s attitude is returned.
    """
    att, keep = fit
    ident, body, ref, sigma, matched = pairs
    index = np.asarray(ident.catalog_index, dtype=int)
    plain = np.asarray(database.vectors)[index]
    mags = np.asarray(database.mags, dtype=float)[index]
    pc = photocentres(
        database.vectors, database.mags, database.tree, index=index,
        radius_rad=blend_radius_px(sensor.detector.psf_sigma_px) * pixel_rad,
    )  # fmt: skip
    own = ref - pc + plain  # the references without the close doubles' photocentres
    own /= np.linalg.norm(own, axis=1)[:, None]
    electrons = np.asarray(points.flux, dtype=float)[matched] / sensor.detector.gain_counts_per_e
    saturated = None if points.saturated is None else np.asarray(points.saturated)[matched]
    held, moved = box_reference(
        sensor, own, plain, rotation=att.rotation, mags=mags,
        windows=np.asarray(points.windows)[matched], sky=sky,
        zero_point_e=frame_zero_point_e(electrons, saturated, mags), power=points.window_power,
    )  # fmt: skip
    if not moved.any():
        return att
    held = np.where(moved[:, None], held, ref)
    # the first fit's outliers stay out, unless their windows' neighbours explain them
    sigma_rad = np.asarray(sigma, dtype=float) * pixel_rad
    return robust_attitude(body, held, sigma_rad, keep=keep | moved)[0]


def window_fields(det, detector, shape) -> dict:
    """Return :class:`~starsense.solve.centroids.CentroidPoints`' window fields of detections.

    ``det`` are a :class:`~starsense.detect.threshold.StarDetector`'s detections of a frame of
    ``shape`` (rows, columns): each window is the detection's box grown by the detector's
    margin and cut at the frame's edges (:func:`starsense.detect.regions.region_centroids`).
    A Gaussian-fit centroid does not follow a window's centre of gravity: no windows then.
    """
    if detector.centroid == "gauss" or len(det) == 0:
        return {}
    m, box = int(detector.margin_px), np.asarray(det.bbox, dtype=int)
    windows = np.column_stack([
        np.maximum(box[:, 0] - m, 0), np.minimum(box[:, 1] + m, shape[0]),
        np.maximum(box[:, 2] - m, 0), np.minimum(box[:, 3] + m, shape[1]),
    ])  # fmt: skip
    power = 2 if detector.centroid == "iwcog" else 1
    return {"windows": windows, "window_power": power, "saturated": np.asarray(det.saturated)}
