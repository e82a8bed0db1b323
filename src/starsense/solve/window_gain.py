"""How far a capsule's centre of gravity follows the capsule: its window gain.

The solver centroids a smeared star over a capsule around its streak, moved to its centre of
gravity until it stays (:func:`starsense.detect.streak.streak_centroids`). Alone in it, the
streak's light is held whole wherever the capsule lies near it: moved along, the window's centre
of gravity stays. Where a neighbour's streak reaches the capsule's end, the window takes in or
leaves its light as it moves: moved by ``d`` along the streak, its centre of gravity moves by
``J d``, the window's gain (:func:`window_gain`). Each of the centroider's ``ITERATIONS`` moves
then carries the last one's error on by ``J``, and the noise of the window's light (and any
error of the model's start, streak or places) lands ``1 + J + ... + J^5`` times over
(:func:`noise_growth`; ``1 / (1 - J)`` when it converges). In a frame of a 768 x 512 CCD at
1 deg/s, a gain of 0.9 turned 0.02 px of streak length into 0.3 px of a V 5.6 star's centroid.
"""

from __future__ import annotations

import math

import numpy as np

from starsense.detect.streak import ITERATIONS

__all__ = ["noise_growth", "window_gain"]


def noise_growth(gain) -> np.ndarray:
    """Return how many times a capsule centroid's along-track error lands, at window ``gain``.

    ``1 + J + ... + J^(ITERATIONS - 1)`` for a gain ``J`` (negative gains, a window that
    moves back, count as 0): each move of the centroider carries the last one's error on by
    ``J``. Linear at the noiseless fixed point: the gain changes over the pixels a noisy one
    wanders, and the spread it gives holds to a factor of 2 (``tests/solve/test_blends.py``).
    """
    j = np.clip(np.asarray(gain, dtype=float), 0.0, None)
    return sum(j**i for i in range(ITERATIONS))


def window_gain(plane, centre, seg, *, radius: float) -> float:
    """Return how far the capsule's centre of gravity moves along per pixel it is moved, px/px.

    The capsule (the pixels whose centres lie within ``radius`` of the segment ``seg`` centred
    on ``centre``, as :func:`starsense.detect.streak.streak_centroids` takes them) is moved
    one pixel either way along the segment over ``plane``'s light: a central difference over
    the pixels its ends take in and leave (one pixel smooths their steps). 0 for a streak
    alone (its light is within the window either way); near 1 where the window's end runs
    along a neighbour's streak.
    """
    seg = np.asarray(seg, dtype=float)
    u = seg / math.hypot(*seg)
    centre = np.asarray(centre, dtype=float)
    # the pixels either capsule can hold: its segment's ends one pixel either way, and radius
    ends = centre + np.array([[-0.5], [0.5]]) * seg + np.array([[-1.0], [1.0]])[:, :, None] * u
    lo = np.maximum(np.floor(ends.reshape(-1, 2).min(axis=0) - radius), 0).astype(int)
    hi = np.minimum(np.ceil(ends.reshape(-1, 2).max(axis=0) + radius) + 1, plane.shape[::-1])
    hi = hi.astype(int)
    sub = np.asarray(plane, dtype=float)[lo[1] : hi[1], lo[0] : hi[0]]
    rows, cols = np.indices(sub.shape, dtype=float)
    rows += lo[1]
    cols += lo[0]
    got = []
    for c in (centre + u, centre - u):
        t = np.clip(((cols - c[0]) * seg[0] + (rows - c[1]) * seg[1]) / (seg @ seg), -0.5, 0.5)
        inside = np.hypot(cols - c[0] - t * seg[0], rows - c[1] - t * seg[1]) <= radius
        w = np.where(inside, sub, 0.0)
        total = w.sum()
        if total <= 0.0:
            return 0.0
        got.append(np.array([(w * cols).sum(), (w * rows).sum()]) / total)
    return float((got[0] - got[1]) @ u / 2.0)
