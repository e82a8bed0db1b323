"""The stars in view the model fit draws beside the identified ones: every star the model sees.

Identification verifies a frame on its brightest detections and pairs only those; the forward
model's attitude is fitted to every catalogue star on the detector that the frame's zero point
predicts above the noise of its footprint (:func:`starsense.model.selection.fitted_min_electrons`),
detected or not: the fit's stars are the model's choice, not the extraction's, and the
datasheet sums its noise over the same stars. Each joins with its flux free, at its apparent
place: a star fainter than predicted adds little information and no bias.

The fit's work is bounded: on a frame of long streaks over a crowded field the brightest are
added until their windows would hold :data:`IN_VIEW_PIXELS` pixels (the faint ones left carry
little of the information).
"""

from __future__ import annotations

import math

import numpy as np

from starsense.model.boxes import MAX_WINDOW_PIXELS
from starsense.model.selection import faintest_mag

__all__ = ["IN_VIEW_PIXELS", "room_for", "stars_in_view"]

#: the pixels the windows of the fitted stars may hold (half the most a fit may hold: room for
#: the padding of their groups to one shape)
IN_VIEW_PIXELS = MAX_WINDOW_PIXELS // 2
#: two catalogue places closer than this are the same star as an identified one, px
SAME_STAR_PX = 0.5


def stars_in_view(
    sensor,
    rotation,
    *,
    plain,
    sky,
    place,
    min_electrons_e: float,
    zero_point_e: float,
    max_stars: int | None = None,
):
    """Return the catalogue stars on the detector the fit adds: (plain, reference, mags).

    Parameters
    ----------
    sensor : Sensor
    rotation : Rotation
        The frame's attitude (ICRS -> camera).
    plain : ndarray (K, 3)
        The identified stars' catalogue places (not added again).
    sky : SkyStars
        The catalogue's stars.
    place : callable
        ``place(rows of sky) -> (M, 3)``: their apparent places
        (:func:`starsense.solve.references.sky_places`).
    min_electrons_e : float
        An added star's predicted electrons at least this.
    zero_point_e : float
        Electrons of a magnitude-0 star.
    max_stars : int, optional
        The most stars added (the brightest): the fit's work is bounded.

    Returns
    -------
    plain, ref : ndarray (M, 3)
    mags : ndarray (M,)
    """
    vectors, mags, tree = sky.vectors, sky.mags, sky.tree
    none = np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
    if zero_point_e <= 0 or not math.isfinite(zero_point_e):
        return none
    faint = faintest_mag(zero_point_e, min_electrons_e)
    det = sensor.detector
    hx, hy = sensor.half_fov_rad
    half_diagonal = math.atan(math.hypot(math.tan(hx), math.tan(hy)))
    axis = rotation.inv().apply([0.0, 0.0, 1.0])
    near = np.asarray(tree.query_ball_point(axis, 2.0 * math.sin(0.5 * half_diagonal)), int)
    near = near[mags[near] <= faint]
    if near.size == 0:
        return none
    cam = rotation.apply(vectors[near])
    x, y = sensor.project(cam)
    on = (cam[:, 2] > 0) & (x >= -0.5) & (x <= det.columns - 0.5)
    on &= (y >= -0.5) & (y <= det.rows - 0.5)
    near = near[on]
    plain = np.asarray(plain, float)
    if len(plain) and near.size:  # not an identified star (their own light)
        same = 2.0 * math.sin(0.5 * SAME_STAR_PX / sensor.focal_length_px)
        taken = tree.query_ball_point(plain, same)
        near = np.setdiff1d(near, np.fromiter((i for t in taken for i in t), int))
    near = near[np.argsort(mags[near], kind="stable")]
    if max_stars is not None:
        near = near[: max(int(max_stars), 0)]
    return vectors[near], place(near), mags[near]


def room_for(sensor, n_fitted: int, *, half_px: float, rate_rad_s=None) -> int:
    """Return how many stars may join ``n_fitted`` before their windows pass the budget.

    A star's window is its track's box padded by ``half_px`` on each side: at the rate
    ``rate_rad_s`` (camera frame, rad/s) a star near the boresight moves
    ``f T (|w_y|, |w_x|)`` px over the exposure.
    """
    side = 2.0 * half_px + 1.0
    sx = sy = 0.0
    if rate_rad_s is not None:
        scale = sensor.focal_length_px * sensor.exposure_s
        sx, sy = scale * abs(float(rate_rad_s[1])), scale * abs(float(rate_rad_s[0]))
    return max(int(IN_VIEW_PIXELS / ((side + sx) * (side + sy))) - int(n_fitted), 0)
