"""Quick extraction (``starsense.detect.quick``): its kernel, its statistics, what it declines.

The compiled kernel (``_quickc``) does the NumPy form's arithmetic in the same order, so the
subtracted frame and the lit pixels are equal bit for bit; the clipped box statistics are
float64 sums in another order (NumPy sums pairwise), equal to within rounding. The NumPy form
of the clipped statistics is checked against astropy's ``sigma_clip``, and the background
against the known level and noise of rendered frames.
"""

from __future__ import annotations

import contextlib
import shutil

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from starsense.detect import StarDetector, quick
from starsense.detect.mesh import MeshSampler
from starsense.errors import InputError
from starsense.sensor import DetectionThresholds

QUICKC = quick._quickc
needs_kernel = pytest.mark.skipif(QUICKC is None, reason="compiled kernel not built")


def test_the_kernel_is_built_where_a_compiler_exists():
    if shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler on this machine: the NumPy forms are the ones in use")
    assert QUICKC is not None


@contextlib.contextmanager
def numpy_forms():
    saved = quick._quickc
    try:
        quick._quickc = None
        yield
    finally:
        quick._quickc = saved


def _frame(seed, rows, cols, dtype, *, level=400.0, sigma=12.0, n_stars=20):
    """A glow, Gaussian stars (sigma 1.2 px) and Gaussian noise, in ``dtype`` (rounded)."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:rows, 0:cols]
    img = level + 30.0 * xx / cols - 20.0 * yy / rows + rng.normal(0.0, sigma, (rows, cols))
    xs, ys = rng.uniform(3, cols - 3, n_stars), rng.uniform(3, rows - 3, n_stars)
    for x, y, f in zip(xs, ys, rng.uniform(500, 20000, n_stars), strict=True):
        img += f / (2 * np.pi * 1.44) * np.exp(-((xx - x) ** 2 + (yy - y) ** 2) / (2 * 1.44))
    if np.dtype(dtype).kind in "iu":
        info = np.iinfo(dtype)
        img = np.clip(np.round(img), info.min, info.max)
    return img.astype(dtype), np.column_stack([xs, ys])


@needs_kernel
@settings(max_examples=100, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    rows=st.integers(8, 260),
    cols=st.integers(8, 260),
    dtype=st.sampled_from(["u1", "<u2", "<i2", "<f4", "<f8"]),
    sigma=st.floats(0.5, 40.0),
    k=st.floats(1.0, 8.0),
    floor=st.floats(0.0, 50.0),
)
def test_the_kernel_equals_the_numpy_form(seed, rows, cols, dtype, sigma, k, floor):
    level = 100.0 if dtype == "u1" else 400.0
    a, _ = _frame(seed, rows, cols, dtype, level=level, sigma=sigma, n_stars=5)
    bg = quick.quick_background(a)
    with numpy_forms():
        ref = quick.quick_background(a)
    # float64 sums in another order: the box means and deviations agree to ~1e-13 relative
    # (a sample at a clipping bound, where the two could part, has probability ~0)
    np.testing.assert_allclose(bg.level_mesh, ref.level_mesh, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(bg.noise_mesh, ref.noise_mesh, rtol=1e-9, atol=1e-9)
    assert bg.floor_fraction == ref.floor_fraction  # a count of equal values: exact
    sub, idx, noise = quick.quick_subtract(a, bg, k=k, floor=floor)
    sub = sub.copy()
    with numpy_forms():
        sub_ref, idx_ref, noise_ref = quick.quick_subtract(a, bg, k=k, floor=floor)
    # the same background in: the same float operations in the same order, bit for bit
    np.testing.assert_array_equal(sub, sub_ref)
    np.testing.assert_array_equal(idx, idx_ref)
    np.testing.assert_array_equal(noise, noise_ref)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(3, 300), outliers=st.integers(0, 20))
def test_clipped_statistics_equal_astropy_sigma_clip(seed, n, outliers):
    from astropy.stats import sigma_clip

    rng = np.random.default_rng(seed)
    x = rng.normal(50.0, 3.0, n)
    x[: min(outliers, n)] += rng.uniform(20, 500, min(outliers, n))  # stars in the box
    mean, sd, kept = quick._clipped_stats(x[None, None, :], True, 3.0)
    clipped = sigma_clip(
        x, sigma=3.0, maxiters=quick.MAX_CLIP_ITERATIONS, cenfunc="mean",
        stdfunc=lambda v, axis=None: np.std(v, axis=axis, ddof=1),
    )  # fmt: skip
    good = clipped.compressed()
    assert int(kept[0, 0]) == good.size
    # the same samples kept: the same statistics to rounding
    np.testing.assert_allclose(mean[0, 0], good.mean(), rtol=1e-12)
    np.testing.assert_allclose(sd[0, 0], good.std(ddof=1), rtol=1e-10)


def test_truncated_gaussian_correction_is_the_exact_one():
    from scipy import stats

    # the standard deviation of a unit Gaussian truncated at +-3
    exact = stats.truncnorm(-3.0, 3.0).std()
    assert quick.TRUNCATED_SD_3SIGMA == pytest.approx(exact, rel=1e-6)


@pytest.mark.parametrize("dtype", ["<u2", "<f4"])
def test_background_recovers_the_known_level_and_noise(dtype):
    a, _ = _frame(3, 480, 640, dtype, sigma=12.0, n_stars=40)
    bg = quick.quick_background(a)
    mesh = MeshSampler(a.shape, box_px=64, every=4, interpolation="linear")
    true_level = 400.0 + 30.0 * mesh.cc[None, :] / 640 - 20.0 * mesh.rc[:, None] / 480
    # a box mean of 256 samples: 12 / 16 = 0.75 counts (1 sigma); 3 x 3 medians of them a
    # little less; faint star wings raise a few; 0.3 noise sigma = 3.6 counts is > 4 sigma
    assert np.max(np.abs(bg.level_mesh - true_level)) < 0.3 * 12.0
    # the clipped standard deviation over 0.98658: unbiased; each box's to ~4.4 % (1 sigma),
    # the median over 80 boxes to well under 2 %; rounding to integers adds 1/12 count^2
    assert bg.noise == pytest.approx(np.sqrt(12.0**2 + (1 / 12 if dtype == "<u2" else 0)), rel=0.02)


def test_detections_are_the_rendered_stars():
    a, truth = _frame(5, 400, 600, "<u2", sigma=10.0, n_stars=25)
    det = StarDetector(
        DetectionThresholds(lit_pixel_counts=1.0, min_pixels=3, min_integrated_counts=0.0),
        background="quick", threshold_sigma=5.0, min_snr=5.0,
    )(a)  # fmt: skip
    d = np.hypot(det.x[:, None] - truth[None, :, 0], det.y[:, None] - truth[None, :, 1])
    # every detection is a rendered star (CoG of a 1.2 px PSF at SNR > 20: well under 0.5 px,
    # unless two stars blend), and nearly all stars of >= 500 counts are found
    assert np.all(d.min(axis=1) < 1.0)
    assert np.sum(d.min(axis=0) < 1.0) >= 22


def test_noise_clipped_at_zero_is_declined():
    rng = np.random.default_rng(1)
    a = np.maximum(rng.normal(0.5, 2.0, (300, 400)), 0.0).astype(np.float32)  # ADC zero
    a[150:153, 200:203] += 500.0
    bg = quick.quick_background(a)
    assert bg.floor_fraction > 0.3  # ~40 % of the samples sit at 0
    det = StarDetector(DetectionThresholds(), background="quick", threshold_sigma=5.0)(a)
    assert len(det) == 0


def test_coarsely_quantised_integers_are_declined():
    rng = np.random.default_rng(2)
    a = np.round(rng.normal(40.0, 0.8, (300, 400))).astype(np.uint8)  # noise under 3 steps
    a[150:153, 200:203] = 200
    det = StarDetector(DetectionThresholds(), background="quick", threshold_sigma=5.0)(a)
    assert len(det) == 0


def test_quick_is_a_background_mode_and_others_are_refused():
    StarDetector(background="quick")
    with pytest.raises(InputError, match="'auto', 'quick'"):
        StarDetector(background="fast")
