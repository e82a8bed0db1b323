"""Hot and warm pixels: isolated pixels that stand out of the background in every frame.

A star lights its neighbours, a defective pixel does not
(:func:`starsense.detect.hot_pixels.hot_pixel_mask`). A pixel is *hot* when it is such an
isolated excess of at least :data:`HOT_SIGMA` noise sigmas in every frame, *warm* when it is one
of at least :data:`WARM_SIGMA` in every frame and not hot. With several frames a noise spike
or a particle hit, which falls on other pixels in each, is ruled out by the "every frame"
(a pixel over 3 sigma by chance in each of k frames: 1e-3^k); one frame cannot tell a
defect from a hit, which the result says.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from starsense.detect.background import estimate_background
from starsense.detect.hot_pixels import hot_pixel_mask

__all__ = ["HOT_SIGMA", "WARM_SIGMA", "HotPixels", "hot_pixels"]

#: excess of a hot pixel over the background, noise sigmas
HOT_SIGMA = 8.0
#: excess of a warm pixel, noise sigmas
WARM_SIGMA = 4.0


@dataclass(frozen=True, eq=False)
class HotPixels:
    """The defect map of a camera.

    Attributes
    ----------
    map : ndarray (rows, columns) of uint8
        0 good, 1 warm, 2 hot.
    excess_counts : ndarray (H,)
        Each hot pixel's median excess over the background, counts.
    n_frames : int
    note : str
        What the frames cannot tell (one frame: a hit looks like a hot pixel).
    """

    map: np.ndarray
    excess_counts: np.ndarray
    n_frames: int
    note: str = ""

    @property
    def hot_fraction(self) -> float:
        """Fraction of the pixels that are hot."""
        return float(np.count_nonzero(self.map == 2)) / self.map.size

    @property
    def warm_fraction(self) -> float:
        """Fraction of the pixels that are warm (not hot)."""
        return float(np.count_nonzero(self.map == 1)) / self.map.size


def hot_pixels(images) -> HotPixels:
    """Map the pixels that stand out, isolated, in every frame (module docstring).

    Parameters
    ----------
    images : sequence of ndarray (rows, columns)
        The frames, counts, all of one size.

    Returns
    -------
    HotPixels
    """
    hot = warm = None
    excess = []
    for image in images:
        a = np.asarray(image, dtype=np.float32)
        bg = estimate_background(a)
        sub = a - np.asarray(bg.level, dtype=np.float32)
        h = hot_pixel_mask(a, bg, threshold_sigma=HOT_SIGMA, subtracted=sub)
        w = hot_pixel_mask(a, bg, threshold_sigma=WARM_SIGMA, subtracted=sub)
        hot = h if hot is None else hot & h
        warm = w if warm is None else warm & w
        excess.append(sub)
    n = len(excess)
    out = np.zeros(hot.shape, dtype=np.uint8)
    out[warm] = 1
    out[hot] = 2
    level = np.median(np.stack([e[hot] for e in excess]), axis=0) if hot.any() else np.zeros(0)
    note = (
        ""
        if n > 1
        else "one frame: a particle hit or a noise spike cannot be told from a hot pixel"
    )
    return HotPixels(out, np.asarray(level, dtype=float), n, note)
