"""Window detection of tracking: the vectorised streak centroid against the one-region loop."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from starsense.detect.streak import streak_centroid, streak_centroids
from starsense.detect.window_kernels import label_windows
from starsense.detect.windows import union_area
from starsense.render.star_stamp import render_star_stamp
from starsense.sensor import load_sensor


@pytest.fixture(scope="module")
def st16():
    return load_sensor("st16")


def test_streak_centroids_equal_the_one_region_loop(st16):
    # all regions at once must give what streak_centroid gives each alone (same
    # masks, same iteration and stop rule); only the summation order differs, so the
    # centroids agree to rounding (1e-9 px, far below the 0.1 px centroid noise) and the
    # boxes exactly. Stamps of different streak directions and lengths, noisy, with starting
    # points off the streak so that the iteration moves; plus an empty plane (no centroid)
    # and a start far off the plane (its capsule misses the plane: no centroid).
    # The starts are within 3 px of the star's mid-exposure point, the stamp's centre (to half
    # a pixel): the planes' background is the bias-subtracted read noise, of mean zero, so a
    # start whose window misses the star finds no counts (with a bias of 0 the noise clipped at
    # zero had a positive mean and gave such a window a centroid of noise).
    rng = np.random.default_rng(7)
    radius = 2.5 * st16.detector.psf_sigma_px + 1.0
    planes, starts, streaks = [], [], []
    for k in range(12):
        angle, length = rng.uniform(0, np.pi), rng.uniform(3.0, 20.0)
        streak = (length * np.cos(angle), length * np.sin(angle))
        img = render_star_stamp(
            st16, 3000.0, streak_px=streak, offset_px=rng.uniform(-0.5, 0.5, 2), rng=k, pad_sigma=8
        )
        centre = (np.array(img.shape[::-1], float) - 1) / 2  # (x, y), px
        img = img[:41, :41].astype(float) - st16.detector.bias_counts
        planes.append(np.pad(img, ((0, 41 - img.shape[0]), (0, 41 - img.shape[1]))))
        starts.append(centre + rng.uniform(-3, 3, 2))
        streaks.append(streak)
    planes.append(np.zeros((41, 41)))
    starts.append(np.array([20.0, 20.0]))
    streaks.append((5.0, 0.0))
    planes.append(planes[0])
    starts.append(np.array([200.0, -150.0]))
    streaks.append((5.0, 0.0))
    starts = np.array(starts)
    x, y, counts, boxes, spread = streak_centroids(
        np.stack(planes), starts[:, 0], starts[:, 1], streaks=np.array(streaks), radius=radius
    )
    for i, plane in enumerate(planes):
        ref = streak_centroid(plane, *starts[i], streak=streaks[i], radius=radius)
        if ref is None:
            assert np.isnan(x[i]) and np.isnan(y[i]) and np.isnan(counts[i])
            continue
        np.testing.assert_allclose([x[i], y[i]], ref[:2], rtol=0, atol=1e-9)
        np.testing.assert_allclose(counts[i], ref[2], rtol=1e-12)
        assert tuple(boxes[i]) == tuple(ref[3])
        np.testing.assert_allclose(spread[i], ref[4], rtol=1e-9)
    assert np.isnan(x[-2]) and np.isnan(x[-1])
    assert np.all(np.isfinite(x[:-2]))


def test_union_area_counts_the_covered_pixels():
    # the exact union of overlapping, nested, touching and disjoint boxes against a raster
    # of the pixels (an independent count: a boolean image with each box painted in)
    rng = np.random.default_rng(3)
    for n in (1, 2, 5, 30):
        r0, c0 = rng.integers(0, 80, n), rng.integers(0, 80, n)
        boxes = np.column_stack([r0, r0 + rng.integers(1, 30, n), c0, c0 + rng.integers(1, 30, n)])
        if n == 5:
            boxes[1] = [boxes[0, 0] + 1, boxes[0, 1], boxes[0, 2], boxes[0, 3]]  # nested
            boxes[2] = [boxes[0, 1], boxes[0, 1] + 4, boxes[0, 2], boxes[0, 3]]  # touching
        paint = np.zeros((120, 120), bool)
        for a, b, c, d in boxes:
            paint[a:b, c:d] = True
        assert union_area(boxes) == paint.sum()


@pytest.mark.parametrize("connectivity", [4, 8])
def test_window_labels_equal_a_3d_labelling(connectivity):
    # the windows labelled as one tall 2-D image must give scipy's 3-D labelling with a
    # structure that connects only within a window: same labels, same order, none across
    lit = np.random.default_rng(5).random((12, 21, 17)) > 0.8
    lit[3, -1, :] = lit[4, 0, :] = True  # touching rows of neighbouring windows
    structure = np.zeros((3, 3, 3), bool)
    structure[1] = ndimage.generate_binary_structure(2, 1 if connectivity == 4 else 2)
    ref, n_ref = ndimage.label(lit, structure=structure)
    got, n = label_windows(lit, connectivity)
    assert n == n_ref
    np.testing.assert_array_equal(got, ref)
