"""A box with no sky pixel (a bright star or a saturated blob covering it) leaves the frame's
noise measured from the other boxes, without a warning.

The noise of every box came from ``np.nanmedian`` over its kept pixels: a box with none warned
"All-NaN slice encountered" on every ``starsense characterize`` of such a frame (found by the
bad-input sweep, bench/bad_input_sweep.py).
"""

from __future__ import annotations

import numpy as np

from starsense.analysis.characterize.noise import BOX_PX, frame_noise


def test_a_box_without_sky_is_left_out_quietly():
    rng = np.random.default_rng(50)
    sigma, level = 5.0, 200.0
    frame = level + sigma * rng.standard_normal((8 * BOX_PX, 8 * BOX_PX))
    # a blob 3 boxes wide at 4000 counts: every pixel of the boxes inside it is clipped
    y, x = np.mgrid[: frame.shape[0], : frame.shape[1]]
    frame[(y - 4 * BOX_PX) ** 2 + (x - 4 * BOX_PX) ** 2 < (1.5 * BOX_PX) ** 2] = 4000.0
    noise = frame_noise(frame)  # warnings are errors in this suite
    # the sky's own noise from the other boxes: ~40 boxes of ~1000 pixels, a robust estimate
    # within a few percent; 10 % leaves room for the blob's edge in its neighbours
    assert abs(noise.noise_counts - sigma) < 0.1 * sigma
    # the level is the median over boxes: the blob's few boxes do not move it (1 count is
    # 0.2 sigma, far above the median's scatter of ~0.03 counts over 64 box means)
    assert abs(noise.level_counts - level) < 1.0
