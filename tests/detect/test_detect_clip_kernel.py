"""The compiled clipping kernel (``starsense.detect._clipc``) against the NumPy form of clip.py.

Both run the same algorithm on the same sorted rows with the same float32 / float64
operations, so every value must be equal, bit for bit: no tolerance.
"""

from __future__ import annotations

import math
import shutil

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from starsense.detect import background, clip


def test_the_kernel_is_built_where_a_compiler_exists():
    # setup.py builds it as an optional extension: a machine with a C compiler that ends up
    # without it runs the slower NumPy form silently, which this makes visible
    if shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler on this machine: the NumPy form is the one in use")
    assert clip._clipc is not None


needs_kernel = pytest.mark.skipif(clip._clipc is None, reason="compiled kernel not built")


def _cells(seed: int, integer_step: int, missing: float, constant: bool) -> np.ndarray:
    rng = np.random.default_rng(seed)
    shape = (int(rng.integers(1, 5)), int(rng.integers(1, 5)), int(rng.integers(1, 600)))
    cells = rng.normal(rng.uniform(-50, 3000), rng.uniform(0.2, 80), shape)
    cells[rng.random(shape) < 0.04] += rng.uniform(10, 20000)  # stars
    cells[rng.random(shape) < 0.01] -= rng.uniform(10, 500)  # cold pixels
    if integer_step:
        cells = np.round(cells / integer_step) * integer_step  # quantised: many ties
    if constant:
        cells[0, 0] = 42.0  # a noiseless box (zero MAD: nothing clipped)
    cells = cells.astype(np.float32)
    cells[rng.random(shape) < missing] = np.nan
    cells[-1, -1, : shape[-1] // 2 + 1] = np.nan  # a box at least half missing
    return cells


@needs_kernel
@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    step=st.sampled_from([0, 1, 16]),
    missing=st.sampled_from([0.0, 0.1, 1.0]),
    constant=st.booleans(),
    k=st.sampled_from([1.0, 2.5, 3.0]),
)
def test_kernel_clipping_equals_the_numpy_form(seed, step, missing, constant, k):
    cells = _cells(seed, step, missing, constant)
    got = clip.sigma_clip_boxes(cells, k)
    expected = clip._clip_sorted_numpy(np.sort(cells, axis=-1), k)
    for name, g, e in zip(("median", "low", "high", "kept"), got, expected, strict=True):
        assert g.dtype == e.dtype and g.shape == e.shape, name
        np.testing.assert_array_equal(g, e, err_msg=name)


@needs_kernel
@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    step=st.sampled_from([0, 1, 16]),
    kept=st.sampled_from([0.0, 0.5, 0.95, 1.0]),
)
def test_kernel_mad_equals_the_numpy_form(seed, step, kept):
    # short rows (<= 256 samples, deviations sorted) and long rows (bisection) alike
    cells = np.nan_to_num(_cells(seed, step, 0.0, False), nan=0.0)
    keep = np.random.default_rng(seed + 1).random(cells.shape) < kept
    got = clip.robust_sigma(cells, keep)
    expected = clip._robust_sigma_numpy(cells, keep)
    np.testing.assert_array_equal(got, expected)
    assert np.isnan(got[keep.sum(-1) == 0]).all()  # nothing kept: no noise estimate


@needs_kernel
def test_kernel_refuses_buffers_of_the_wrong_size():
    s = np.zeros((2, 10), np.float32)
    med, kept = np.empty(3), np.empty(2, np.int64)  # med sized for 3 rows
    low, high = np.empty(2, np.float32), np.empty(2, np.float32)
    with pytest.raises(ValueError, match="med has 24 bytes, expected 16"):
        clip._clipc.clip_sorted(s, 2, 10, 3.0, clip.MAD_TO_SIGMA, 10, med, low, high, kept)


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    dtype=st.sampled_from([np.uint8, np.int8, np.uint16, np.int16, ">i2", ">u2"]),
)
def test_integer_samples_sorted_as_integers_clip_the_same(seed, dtype):
    # sorting the integers and converting them is sorting their (exact) float32 values
    info = np.iinfo(dtype)
    rng = np.random.default_rng(seed)
    shape = (int(rng.integers(1, 4)), int(rng.integers(1, 4)), int(rng.integers(1, 400)))
    counts = rng.normal(rng.uniform(info.min, info.max), rng.uniform(0.5, 50), shape)
    counts[rng.random(shape) < 0.05] = info.max  # saturated stars
    counts = np.clip(np.round(counts), info.min, info.max).astype(dtype)
    cells = counts.astype(np.float32)
    got = clip.sigma_clip_boxes(cells, 3.0, counts=counts)
    expected = clip.sigma_clip_boxes(cells, 3.0)
    for name, g, e in zip(("median", "low", "high", "kept"), got, expected, strict=True):
        np.testing.assert_array_equal(g, e, err_msg=name)
    # and both are the NumPy form's on np.sort's rows (the kernel sorts the integers itself)
    reference = clip._clip_sorted_numpy(np.sort(cells, axis=-1), 3.0)
    for name, g, e in zip(("median", "low", "high", "kept"), got, reference, strict=True):
        np.testing.assert_array_equal(g, e, err_msg=name)


@needs_kernel
@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), kept=st.sampled_from([0.3, 0.9, 1.0]))
def test_kernel_mad_with_kept_nans_and_infinities_equals_the_numpy_form(seed, kept):
    # the kernel sorts only the kept samples: kept NaN and inf must land where np.sort of the
    # row (the others set to +inf) puts them, and signed zeros must not change the MAD
    rng = np.random.default_rng(seed)
    cells = _cells(seed, int(rng.choice([0, 1])), 0.0, False)
    odd = rng.random(cells.shape)
    cells[odd < 0.05] = np.nan
    cells[(odd >= 0.05) & (odd < 0.08)] = np.inf
    cells[(odd >= 0.08) & (odd < 0.10)] = -np.inf
    cells[(odd >= 0.10) & (odd < 0.15)] = np.float32(-0.0)
    cells[(odd >= 0.15) & (odd < 0.20)] = np.float32(0.0)
    keep = rng.random(cells.shape) < kept
    got = clip.robust_sigma(cells, keep)
    v = np.sort(np.where(keep, cells, np.float32(np.inf)), axis=-1)
    n = keep.sum(-1)
    expected = np.empty(n.shape)
    for i in np.ndindex(n.shape):  # the previous kernel path: MAD of the sorted rows' first n
        row = np.ascontiguousarray(v[i][None, :])
        out = np.empty(1)
        clip._clipc.mad_sorted(row, 1, row.shape[-1], np.array([n[i]], np.int64), out)
        expected[i] = clip.MAD_TO_SIGMA * out[0]
    np.testing.assert_array_equal(got, expected)


@needs_kernel
def test_kernel_refuses_an_unknown_sample_type():
    med, kept = np.empty(1), np.empty(1, np.int64)
    low, high = np.empty(1, np.float32), np.empty(1, np.float32)
    args = (np.zeros(4, np.float32), "d", 1, 4, 3.0, clip.MAD_TO_SIGMA, 10)
    with pytest.raises(ValueError, match="kind d is not one of"):
        clip._clipc.clip_rows(*args, med, low, high, kept)


def _background_frame(seed: int, dtype, tile: int = 0) -> np.ndarray:
    """Glow + noise + stars + hot and cold pixels, of a camera's sample type.

    With ``tile``, the frame is a whole number of ``tile``-pixel boxes each way (the regular
    mesh, whose noise the fused kernel takes).
    """
    rng = np.random.default_rng(seed)
    rows, cols = int(rng.integers(40, 200)), int(rng.integers(40, 260))
    if tile:
        rows, cols = tile * int(rng.integers(1, 5)), tile * int(rng.integers(1, 6))
    yy, xx = np.mgrid[0:rows, 0:cols]
    level = rng.uniform(5, 3000) + rng.uniform(0, 200) * (xx / cols) * (yy / rows)
    frame = rng.normal(level, rng.uniform(0.5, 120), (rows, cols))
    hits = rng.random((rows, cols))
    frame[hits < 0.01] += rng.uniform(100, 40000)  # stars, hot pixels
    frame[hits > 0.995] -= rng.uniform(10, 500)  # cold pixels
    if np.dtype(dtype).kind in "iu":
        info = np.iinfo(dtype)
        step = int(rng.choice([1, 16]))
        frame = np.clip(np.round(frame / step) * step, info.min, info.max)
    return frame.astype(dtype)


@needs_kernel
@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    dtype=st.sampled_from(
        [np.uint8, np.int8, np.uint16, np.int16, ">i2", ">u2", np.float32, ">f4", np.float64]
    ),
    box=st.sampled_from([16, 32, 64]),
    full=st.booleans(),
    tiled=st.booleans(),
)
def test_background_with_the_kernels_equals_the_numpy_form(seed, dtype, box, full, tiled):
    # the kernels gather the samples, sort the boxes, clip them and take the residuals' MAD
    # themselves (gather, clip_rows, mad_resid); the NumPy form gathers, subtracts and sorts
    # with NumPy: the same level and noise, bit for bit
    frame = _background_frame(seed, dtype, box if tiled else 0)
    got = background.estimate_background(frame, box_px=box, full_noise_map=full)
    saved = clip._clipc, background._clipc
    try:
        clip._clipc = background._clipc = None
        expected = background.estimate_background(frame, box_px=box, full_noise_map=full)
    finally:
        clip._clipc, background._clipc = saved
    np.testing.assert_array_equal(got.level, expected.level)
    assert got.noise == expected.noise and got.step == expected.step
    if full:
        np.testing.assert_array_equal(got.noise_map, expected.noise_map)
    else:
        np.testing.assert_array_equal(got.surface.rows_w, expected.surface.rows_w)


@needs_kernel
def test_residual_kernel_refuses_a_level_map_too_small():
    cells, low, high = (
        np.zeros((1, 1, 4), np.float32),
        np.zeros(1, np.float32),
        np.ones(1, np.float32),
    )
    with pytest.raises(ValueError, match="bad shape"):
        # a 2 x 2 mesh sample every 2nd pixel needs a 3 x 3 map
        clip._clipc.mad_resid(
            cells, np.zeros((2, 2), np.float32), 2, 1, 1, 2, 2, 2, low, high, np.empty(1)
        )


def _mad_reference(cells, level, every, low, high):
    """Per box: the MAD of the kept residuals, as robust_sigma sorts them (float32 values)."""
    ny, nx, m = cells.shape
    my = mx = math.isqrt(m)
    out = np.empty((ny, nx))
    for by in range(ny):
        for bx in range(nx):
            rows = (by * my + np.arange(my)) * every
            cols = (bx * mx + np.arange(mx)) * every
            lev = level[np.ix_(rows, cols)].ravel()
            x = cells[by, bx]
            keep = (x >= low[by * nx + bx]) & (x <= high[by * nx + bx])
            r = np.sort((x - lev)[keep])  # float32
            n = len(r)
            if n == 0:
                out[by, bx] = np.nan
                continue
            med = 0.5 * (float(r[(n - 1) // 2]) + float(r[n // 2]))
            d = np.sort(np.abs(r - np.float32(med)))
            out[by, bx] = 0.5 * (float(d[(n - 1) // 2]) + float(d[n // 2]))
    return out


@needs_kernel
@settings(max_examples=80, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    step=st.sampled_from([0, 1, 16]),
    side=st.sampled_from([1, 2, 3, 8, 32]),
    outlier=st.sampled_from([0.0, 1e3, 1e7]),
    flat=st.booleans(),
)
def test_residual_mad_equals_a_sorted_reference(seed, step, side, outlier, flat):
    # the fused residual kernel against a plain sort of each box's kept residuals: the same
    # two order statistics, so the same value bit for bit, on quantised data (ties), a box
    # holding one huge outlier, flat boxes and boxes of 1 to 1,024 samples
    rng = np.random.default_rng(seed)
    ny, nx, every = int(rng.integers(1, 4)), int(rng.integers(1, 4)), int(rng.integers(1, 3))
    m = side * side
    cells = rng.normal(rng.uniform(0, 3000), 0.0 if flat else rng.uniform(0.3, 50), (ny, nx, m))
    if step:
        cells = np.round(cells / step) * step
    cells[..., 0] += outlier
    cells = cells.astype(np.float32)
    rows, cols = ny * side * every, nx * side * every
    yy, xx = np.mgrid[0:rows, 0:cols]
    level = (cells.mean() + rng.uniform(-5, 5) * (xx / cols + yy / rows)).astype(np.float32)
    wide = rng.random() < 0.5  # bounds keeping everything, or the middle of each box
    low = np.where(wide, -np.inf, np.percentile(cells, 10, axis=-1).ravel()).astype(np.float32)
    high = np.where(wide, np.inf, np.percentile(cells, 90, axis=-1).ravel()).astype(np.float32)
    got = np.empty((ny, nx))
    geometry = (cols, ny, nx, side, side, every)
    clip._clipc.mad_resid(cells, level, *geometry, low, high, got)
    np.testing.assert_array_equal(got, _mad_reference(cells, level, every, low, high))
