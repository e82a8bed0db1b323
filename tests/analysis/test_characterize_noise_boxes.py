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


def test_the_noise_map_places_each_box_where_its_noise_is():
    """A frame whose left half reads noise 2 and right half 6 (a warm amplifier): the map's
    boxes left of the middle read 2 and right of it 6 (the median of 24 boxes within 5 %: a
    box's robust sigma scatters ~4 %), every left box below every right one, and the box
    centres tile the frame a box apart."""
    rng = np.random.default_rng(7)
    rows, cols = 6 * BOX_PX, 8 * BOX_PX
    sigma = np.where(np.arange(cols) < cols // 2, 2.0, 6.0)[None, :]
    frame = 300.0 + sigma * rng.standard_normal((rows, cols))
    got = frame_noise(frame)
    assert len(got.box_xy) == 48
    left = got.box_xy[:, 0] < cols / 2
    noise = np.sqrt(got.box_variances)
    assert abs(np.median(noise[left]) - 2.0) < 0.05 * 2.0
    assert abs(np.median(noise[~left]) - 6.0) < 0.05 * 6.0
    assert noise[left].max() < 3.0 < noise[~left].min()
    np.testing.assert_allclose(np.unique(got.box_xy[:, 0]), (np.arange(8) + 0.5) * BOX_PX - 0.5)
    np.testing.assert_allclose(np.unique(got.box_xy[:, 1]), (np.arange(6) + 0.5) * BOX_PX - 0.5)
