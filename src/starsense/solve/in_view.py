"""The stars in view the model fit draws beside the identified ones: every star the frame shows.

Identification verifies a frame on its brightest detections and pairs only those; the forward
model's attitude is fitted to every star the detector found, which the datasheet's noise sums
over. Once the attitude is known each unmatched detection is looked up in the sky catalogue:
the nearest star within the reach of a detection's centroid (the PSF's core, and half a streak
on a smeared frame, whose pieces lie anywhere along it) joins the fit, with its flux free, when
the frame's zero point predicts it above the noise of a PSF's area (a noise detection beside a
star too faint to be seen adds nothing). A star the catalogue holds is where the catalogue puts
it whatever lit the pixel near it: the fit weighs its window by the light it finds there. Its
reference direction is its apparent place, as the identified stars' are.

The fit's work is bounded: on a frame of long streaks over a crowded field the brightest are
added until their windows would hold :data:`IN_VIEW_PIXELS` pixels (the faint ones left carry
little of the information).
"""

from __future__ import annotations

import math

import numpy as np

from starsense.model.windows import MAX_WINDOW_PIXELS

__all__ = ["DETECTABLE_SNR", "IN_VIEW_PIXELS", "room_for", "stars_in_view"]

#: an added star's predicted flux over the noise of a PSF's area (read, dark, background) at
#: least this: below it the detector's threshold could not have been passed by the star
DETECTABLE_SNR = 3.0
#: the pixels the windows of the fitted stars may hold (half the most a fit may hold: room for
#: the padding of their groups to one shape)
IN_VIEW_PIXELS = MAX_WINDOW_PIXELS // 2
#: a detection's centroid lies within this many PSF sigmas (plus a pixel) of its star at rest
REACH_SIGMAS = 2.0


def stars_in_view(
    sensor,
    rotation,
    *,
    detections,
    matched,
    plain,
    sky,
    place,
    min_electrons_e: float,
    zero_point_e: float,
    streak_px: float = 0.0,
    max_stars: int | None = None,
):
    """Return the sky stars lit by the unmatched detections: (plain, reference, mags).

    Parameters
    ----------
    sensor : Sensor
    rotation : Rotation
        The frame's attitude (ICRS -> camera).
    detections : ndarray (N, 2)
        Every detection's centroid (x, y), px.
    matched : ndarray of int
        The identified detections.
    plain : ndarray (K, 3)
        The identified stars' catalogue places.
    sky : SkyStars
        The catalogue's stars.
    place : callable
        ``place(rows of sky) -> (M, 3)``: their apparent places
        (:func:`starsense.solve.references.sky_places`).
    min_electrons_e : float
        An added star's predicted electrons at least this.
    zero_point_e : float
        Electrons of a magnitude-0 star.
    streak_px : float
        The streaks' length, px (0 at rest).
    max_stars : int, optional
        The most stars added (the brightest): the fit's work is bounded.

    Returns
    -------
    plain, ref : ndarray (M, 3)
    mags : ndarray (M,)
    """
    vectors, mags, tree = sky.vectors, sky.mags, sky.tree
    plain = np.asarray(plain, float)
    free = np.ones(len(detections), dtype=bool)
    free[np.asarray(matched, dtype=int)] = False
    none = np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
    if not free.any():
        return none
    xy = np.asarray(detections, float)[free]
    icrs = rotation.inv().apply(sensor.unproject(xy[:, 0], xy[:, 1]))
    reach = REACH_SIGMAS * sensor.detector.psf_sigma_px + 1.0 + 0.5 * streak_px
    chord = 2.0 * math.sin(0.5 * reach / sensor.focal_length_px)
    dist, near = tree.query(icrs, distance_upper_bound=chord)
    near = np.unique(near[np.isfinite(dist)])
    if near.size == 0:
        return none
    if len(plain):  # not an identified star (their own light)
        taken = tree.query_ball_point(plain, 2.0 * math.sin(0.5 * 0.5 / sensor.focal_length_px))
        near = np.setdiff1d(near, np.fromiter((i for t in taken for i in t), int))
    bright = zero_point_e * 10.0 ** (-0.4 * mags[near]) >= min_electrons_e
    near = near[bright]
    if max_stars is not None:
        near = near[np.argsort(mags[near], kind="stable")[: max(int(max_stars), 0)]]
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
