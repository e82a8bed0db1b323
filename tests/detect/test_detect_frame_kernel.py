"""The compiled whole-frame kernels (``starsense.detect._framec``) against their NumPy forms.

Each kernel runs the algorithm of its NumPy form with the same float32 operations in the same
order (built without fused multiply-adds), so every value must be equal, bit for bit: no
tolerance. The NumPy forms are what runs where the kernel was not built; they are checked
here against independent references (scipy.ndimage, np.median) as well.
"""

from __future__ import annotations

import contextlib
import shutil

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

from starsense.detect import (
    StarDetector,
    background,
    estimate_background,
    hot_pixel_mask,
    hot_pixels,
    matched,
    regions,
)
from starsense.sensor import DetectionThresholds

FRAMEC = matched._framec
needs_kernel = pytest.mark.skipif(FRAMEC is None, reason="compiled kernel not built")


def test_the_kernel_is_built_where_a_compiler_exists():
    # setup.py builds it as an optional extension: a machine with a C compiler that ends up
    # without it runs the slower NumPy forms silently, which this makes visible
    if shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler on this machine: the NumPy forms are the ones in use")
    assert FRAMEC is not None


@contextlib.contextmanager
def numpy_forms():
    """Run the NumPy forms: every module that uses the kernel sees none, until the end."""
    modules = (matched, regions, hot_pixels)
    saved = [m._framec for m in modules]
    try:
        for m in modules:
            m._framec = None
        yield
    finally:
        for m, kernel in zip(modules, saved, strict=True):
            m._framec = kernel


def _frame(seed: int, rows: int, cols: int, n_stars: int, n_hot: int) -> np.ndarray:
    """Glow + Gaussian stars + hot pixels and hot pairs + noise, float32 counts."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:rows, 0:cols]
    img = 300.0 + 40.0 * (xx / cols) + rng.normal(0.0, rng.uniform(1.0, 20.0), (rows, cols))
    for _ in range(n_stars):
        x, y, s = rng.uniform(0, cols), rng.uniform(0, rows), rng.uniform(0.5, 2.5)
        img += rng.uniform(50, 5000) * np.exp(-((xx - x) ** 2 + (yy - y) ** 2) / (2 * s * s))
    for _ in range(n_hot):
        r, c = int(rng.integers(0, rows)), int(rng.integers(0, cols))
        img[r, c] += rng.uniform(200, 4000)
        if rng.random() < 0.5:  # a pair: the pixel and a 4-neighbour
            dr, dc = [(-1, 0), (1, 0), (0, -1), (0, 1)][int(rng.integers(0, 4))]
            img[np.clip(r + dr, 0, rows - 1), np.clip(c + dc, 0, cols - 1)] += rng.uniform(
                100, 2000
            )
    if rng.random() < 0.5:
        img = np.round(img / 16.0) * 16.0  # quantised in steps, many ties
    return img.astype(np.float32)


frames = st.builds(
    _frame,
    seed=st.integers(0, 2**31 - 1),
    rows=st.integers(1, 90),
    cols=st.integers(1, 90),
    n_stars=st.integers(0, 12),
    n_hot=st.integers(0, 12),
)


@needs_kernel
@settings(max_examples=60, deadline=None)
@given(frame=frames, sigma=st.floats(0.2, 4.0))
def test_kernel_correlation_equals_the_numpy_form(frame, sigma):
    got = matched.gaussian_correlate(frame, sigma)
    with numpy_forms():
        expected = matched.gaussian_correlate(frame, sigma)
    np.testing.assert_array_equal(got.view(np.uint32), expected.view(np.uint32))


def test_numpy_correlation_is_scipy_gaussian_filter():
    # the independent reference: scipy's filter of the same kernel; float32 sums in another
    # order differ by a few ulps of the frame's largest values (~1e-6 relative)
    frame = _frame(3, 70, 85, 8, 4)
    for sigma in (0.6, 1.3, 2.5):
        ref = ndimage.gaussian_filter(frame, sigma, mode="nearest", truncate=3.0)
        with numpy_forms():
            got = matched.gaussian_correlate(frame, sigma)
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-5 * np.abs(frame).max())


@needs_kernel
@settings(max_examples=100, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    n=st.integers(1, 3000),
    ties=st.sampled_from([0.0, 0.3, 0.9]),
    scale=st.sampled_from([1e-30, 1.0, 1e30]),
)
def test_kernel_median_is_numpy_median(seed, n, ties, scale):
    rng = np.random.default_rng(seed)
    z = (rng.standard_normal(n) * scale).astype(np.float32)
    z[rng.random(n) < ties] = rng.choice([0.0, -0.0, 1.0])  # repeated values, signed zeros
    expected = np.median(z)
    got = FRAMEC.median(z, n, np.empty(n, np.uint32))
    assert np.float32(got) == expected  # -0.0 == 0.0: the same value either way
    assert matched._median_in_place(z.copy()) == expected


def _sparse_mask(seed: int, rows: int, cols: int, fill: float) -> np.ndarray:
    rng = np.random.default_rng(seed)
    mask = rng.random((rows, cols)) < fill
    return ndimage.binary_dilation(mask) if rng.random() < 0.5 else mask  # blobs or speckle


@settings(max_examples=80, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    rows=st.integers(1, 60),
    cols=st.integers(1, 60),
    fill=st.sampled_from([0.01, 0.1, 0.4, 0.9]),
    connectivity=st.sampled_from([4, 8]),
)
def test_labels_are_scipy_ndimage_labels_with_and_without_the_kernel(
    seed, rows, cols, fill, connectivity
):
    mask = _sparse_mask(seed, rows, cols, fill)
    structure = ndimage.generate_binary_structure(2, 1 if connectivity == 4 else 2)
    ref, n_ref = ndimage.label(mask, structure=structure)
    idx = np.flatnonzero(mask)
    for form in (regions.label_pixels, regions._label_pixels_numpy):
        labels, n = form(idx, mask.shape, connectivity)
        assert n == n_ref and labels.dtype == np.int32
        np.testing.assert_array_equal(labels, ref.ravel()[idx])


@needs_kernel
@settings(max_examples=40, deadline=None)
@given(frame=frames, threshold_sigma=st.sampled_from([3.0, 5.0, 8.0]))
def test_kernel_hot_pixels_equal_the_numpy_form(frame, threshold_sigma):
    if frame.shape[0] < 4 or frame.shape[1] < 4:
        bg = background.constant_background(float(np.median(frame)), float(frame.std()) + 1.0)
    else:
        bg = estimate_background(frame, box_px=4, full_noise_map=frame.size % 2 == 0)
    got = hot_pixel_mask(frame, bg, threshold_sigma=threshold_sigma)
    with numpy_forms():
        expected = hot_pixel_mask(frame, bg, threshold_sigma=threshold_sigma)
    np.testing.assert_array_equal(got, expected)


@needs_kernel
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_detections_with_and_without_the_kernels_are_identical(seed):
    frame = _frame(seed, 240, 320, 40, 15)
    detector = StarDetector(
        DetectionThresholds(min_pixels=2, min_integrated_counts=0.0),
        background="auto",
        threshold_sigma=5.0,
        matched_filter=True,
        min_snr=5.0,
        psf_sigma_px=1.2,
    )
    got = detector(frame)
    with numpy_forms():
        expected = detector(frame)
    assert len(got) > 5 and got.counts == expected.counts
    for name in ("x", "y", "integrated_counts", "n_pixels", "peak_counts", "bbox"):
        np.testing.assert_array_equal(getattr(got, name), getattr(expected, name), err_msg=name)


@needs_kernel
def test_kernel_refuses_buffers_of_the_wrong_size():
    a = np.zeros((4, 5), np.float32)
    out = np.empty((4, 4), np.float32)  # one column short
    taps = np.ones(2, np.float32)
    with pytest.raises(ValueError, match="out: buffer of 64 bytes, 80 needed"):
        FRAMEC.correlate(a, 4, 5, taps, 1, out)
