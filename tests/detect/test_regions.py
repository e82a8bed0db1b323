"""Sparse labelling and vectorised window centroids (starsense.detect.regions) against scipy."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from starsense.detect import regions
from starsense.detect.centroid import cog
from starsense.detect.regions import label_pixels, region_centroids


@pytest.mark.parametrize("connectivity", [4, 8])
@pytest.mark.parametrize(
    ("shape", "fill"),
    [((60, 80), 0.3), ((1, 50), 0.5), ((50, 1), 0.5), ((40, 40), 0.0), ((33, 47), 0.6)],
)
def test_label_pixels_is_ndimage_label(shape, fill, connectivity):
    # scipy.ndimage.label over the whole frame is the reference: same regions, same numbering
    # (raster order of each region's first pixel); regions touching the right edge must not
    # join those starting the next row
    rng = np.random.default_rng(int(fill * 10) + connectivity)
    mask = rng.random(shape) < fill
    mask[:, -1] |= rng.random(shape[0]) < 0.5
    mask[:, 0] |= rng.random(shape[0]) < 0.5
    structure = ndimage.generate_binary_structure(2, 1 if connectivity == 4 else 2)
    expected, n_expected = ndimage.label(mask, structure=structure)
    idx = np.flatnonzero(mask)
    lab, n = label_pixels(idx, shape, connectivity)
    assert n == n_expected
    assert np.array_equal(lab, expected.ravel()[idx])


@pytest.mark.parametrize("chunk", [None, 1, 40, 300])
def test_region_centroids_is_the_per_window_cog(chunk, monkeypatch):
    # the per-star cog() over each window (box grown by the margin, cut at the frame) is the
    # reference; float64 sums in a different order: equal to 1e-9 px. The windows are taken in
    # chunks of pixels (bounded memory): a chunk smaller than one window, than two, and the
    # default must all give the reference
    if chunk is not None:
        monkeypatch.setattr(regions, "_CHUNK_PIXELS", chunk)
    rng = np.random.default_rng(3)
    sub = rng.normal(0, 1, (50, 70)).astype(np.float32)
    yy, xx = np.mgrid[0:50, 0:70]
    for x0, y0 in [(10.3, 12.7), (0.4, 25.0), (68.8, 49.2), (40.0, 30.0)]:
        sub += (200 * np.exp(-((xx - x0) ** 2 + (yy - y0) ** 2) / 2.0)).astype(np.float32)
    mask = sub > 8.0
    idx = np.flatnonzero(mask)
    lab, n = label_pixels(idx, sub.shape)
    keep = np.arange(n, 0, -1)  # any order
    x, y, peaks, boxes, ok = region_centroids(
        sub, sub, idx=idx, lab=lab, keep=keep, core=None, margin=2
    )
    labels = ndimage.label(mask, structure=np.ones((3, 3)))[0]
    for i, k in enumerate(keep):
        rr, cc = np.nonzero(labels == k)
        r0, r1, c0, c1 = rr.min(), rr.max() + 1, cc.min(), cc.max() + 1
        assert tuple(boxes[i]) == (r0, r1, c0, c1)
        assert peaks[i] == sub[rr, cc].max()
        wr0, wc0 = max(r0 - 2, 0), max(c0 - 2, 0)
        ex, ey = cog(sub[wr0 : r1 + 2, wc0 : c1 + 2], wr0, wc0)
        assert ok[i]
        assert x[i] == pytest.approx(ex, abs=1e-9) and y[i] == pytest.approx(ey, abs=1e-9)
