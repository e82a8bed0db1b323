"""Hot pixels of a frame: single pixels far above the background that no star's PSF explains.

:func:`hot_pixel_mask` marks them against a frame's background and noise
(:mod:`starsense.detect.background`); the detector leaves them out of its candidates.
"""

from __future__ import annotations

import numpy as np

from starsense._validate import positive_float
from starsense.detect.background import Background
from starsense.detect.subtract import floor_threshold
from starsense.errors import InputError

try:
    import starsense.detect._framec as _framec
except ImportError:  # built without a C compiler: the NumPy form below
    _framec = None

__all__ = ["HOT_PIXEL_SIGMA", "hot_pixel_mask"]


#: excess over the background of a hot pixel, in noise sigmas (hot_pixel_mask)
HOT_PIXEL_SIGMA = 8.0


def hot_pixel_mask(
    image,
    background: Background,
    *,
    threshold_sigma: float = HOT_PIXEL_SIGMA,
    subtracted=None,
    candidates=None,
) -> np.ndarray:
    """Isolated pixels or pixel pairs far brighter than all around them (hot pixels, hits).

    A pixel is hot when it exceeds the background by ``threshold_sigma`` noise while its 8
    neighbours all stay near the background (below 3 noise sigma, or below 15 % of the pixel's
    excess for very bright ones). A star, even an undersampled one (PSF sigma 0.8 px puts ~40 %
    of the peak in the nearest neighbours), always lights some neighbours; a defective pixel
    does not. Defects come in adjacent pairs too (a pixel and its brighter 4-neighbour: charge
    shared with the next row, random-telegraph pixels of CMOS sensors read at high gain, two
    to three dozen per 1280 x 960 frame at 10 ms): a pixel above the threshold, at least as
    bright as its brightest 4-neighbour, and the 10 pixels around the two all below the same
    limit marks both. A star centred between two pixels lights the pixels beside the pair
    with ~45 % of its peak (PSF sigma 0.8 px; 25 % at 0.6 px, with the pixel's own width).
    Pixels on the frame's border are judged by the neighbours they have. The
    neighbours are examined only around the pixels above the threshold (a few thousand on a
    real frame), not over the whole frame.

    Parameters
    ----------
    image : array_like, shape (rows, columns)
        Frame, counts.
    background : Background
        Its background; the noise map is used when there is one.
    threshold_sigma : float
        Excess over the background of a hot pixel, in noise sigmas (> 0).
    subtracted : ndarray, shape (rows, columns), optional
        ``image`` minus ``background.level`` in float32, when the caller has it already
        (saves a whole-frame copy); computed here otherwise.
    candidates : ndarray of int, optional
        Flat indices (ascending) of the pixels of ``subtracted`` above ``threshold_sigma``
        times the frame's lowest noise (:func:`~starsense.detect.subtract.subtract_level` with
        :func:`~starsense.detect.subtract.floor_threshold`), when the caller has them.

    Returns
    -------
    ndarray of bool, shape (rows, columns)
    """
    threshold_sigma = positive_float(threshold_sigma, "threshold_sigma")
    if subtracted is None:
        sub = np.asarray(image, dtype=np.float32) - np.asarray(background.level, dtype=np.float32)
    else:
        sub = np.asarray(subtracted, dtype=np.float32)
        if sub.shape != np.shape(image):
            raise InputError(f"subtracted has shape {sub.shape}, the image {np.shape(image)}")
    # candidates above the threshold at the lowest noise (one pass, no float frame), then the
    # exact per-pixel test on those only
    if candidates is None:
        flat = np.flatnonzero(sub > floor_threshold(background, threshold_sigma))
    else:
        flat = np.asarray(candidates, dtype=np.intp)
    r, c = np.divmod(flat, sub.shape[1])
    hot = np.zeros(sub.shape, dtype=bool)
    if r.size == 0:
        return hot
    n_here = np.maximum(np.broadcast_to(background.noise_at(flat), flat.shape), np.float32(1e-12))
    if _framec is not None:
        # the tests below, candidate by candidate (_framec.c): the same float32 comparisons
        n_here = np.ascontiguousarray(n_here, dtype=np.float32)
        rows, cols = sub.shape
        args = (np.ascontiguousarray(sub), rows, cols, flat.astype(np.int64), n_here, flat.size)
        _framec.hot(*args, threshold_sigma, hot.view(np.uint8))
        return hot
    above = sub[r, c] > threshold_sigma * n_here
    r, c, n_here = r[above], c[above], n_here[above]
    rows, cols = sub.shape
    # the largest of the 8 neighbours; outside the frame counts as "no neighbour" (repeating
    # the edge would make the pixel its own neighbour and hide every hot pixel on the border)
    neighbours = _ring_max(sub, r, c, [(dr, dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1)])
    allowed = np.maximum(3.0 * n_here, 0.15 * sub[r, c])
    quiet = neighbours < allowed
    hot[r[quiet], c[quiet]] = True
    # pairs: the pixel with its brightest 4-neighbour, the 10 pixels around the two quiet
    r, c, allowed = r[~quiet], c[~quiet], allowed[~quiet]
    steps = np.array([(-1, 0), (1, 0), (0, -1), (0, 1)])
    side = np.stack([_ring_max(sub, r, c, [tuple(s)]) for s in steps], axis=1)
    best = steps[np.argmax(side, axis=1)] if r.size else np.empty((0, 2), int)
    for (dr, dc), ring in _PAIR_RINGS.items():
        these = (best[:, 0] == dr) & (best[:, 1] == dc)
        rr, cc = r[these], c[these]
        quiet = (_ring_max(sub, rr, cc, ring) < allowed[these]) & (
            sub[rr, cc] >= sub[(rr + dr).clip(0, rows - 1), (cc + dc).clip(0, cols - 1)]
        )
        hot[rr[quiet], cc[quiet]] = True
        hot[(rr[quiet] + dr).clip(0, rows - 1), (cc[quiet] + dc).clip(0, cols - 1)] = True
    return hot


#: the 10 pixels around a pair made of a pixel and its neighbour at (dr, dc): the 4 x 3 (or
#: 3 x 4) box around the two, less the two
_PAIR_RINGS = {
    (dr, dc): [
        (i, j)
        for i in range(min(0, dr) - 1, max(0, dr) + 2)
        for j in range(min(0, dc) - 1, max(0, dc) + 2)
        if (i, j) not in ((0, 0), (dr, dc))
    ]
    for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1))
}


def _ring_max(sub: np.ndarray, r: np.ndarray, c: np.ndarray, offsets) -> np.ndarray:
    """Return the largest of ``sub`` at (r + dr, c + dc) over ``offsets`` ((0, 0) skipped).

    Positions outside the frame do not count (-inf when none is inside).
    """
    rows, cols = sub.shape
    out = np.full(r.size, -np.inf, dtype=np.float32)
    for dr, dc in offsets:
        if dr == 0 and dc == 0:
            continue
        rr, cc = r + dr, c + dc
        inside = (rr >= 0) & (rr < rows) & (cc >= 0) & (cc < cols)
        np.maximum(out, sub[rr.clip(0, rows - 1), cc.clip(0, cols - 1)], out=out, where=inside)
    return out
