"""The background mesh's natural cubic spline weights (NumPy) against scipy's CubicSpline."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import CubicSpline

from starsense.detect import axis_weights, mesh
from starsense.detect.axis_weights import AxisWeights, interpolation_matrix
from starsense.detect.background import estimate_background
from starsense.detect.mesh import natural_spline_weights


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), m=st.integers(3, 40))
def test_weights_are_scipy_natural_cubic_spline(seed, m):
    rng = np.random.default_rng(seed)
    knots = np.cumsum(rng.uniform(0.5, 80.0, m))  # box centres: uneven spacing allowed
    x = np.sort(rng.uniform(knots[0], knots[-1], 300))
    x[:2] = knots[0], knots[-1]  # the ends themselves
    expected = CubicSpline(knots, np.eye(m), bc_type="natural")(x)
    got = natural_spline_weights(knots, x)
    # the same spline, by another float64 evaluation: the second derivatives solve a
    # diagonally dominant tridiagonal system (condition <= 3), so the two agree to a few
    # hundred ulps of the weights (which are <= ~1.2)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)


def test_weights_reproduce_a_line_and_interpolate_the_knots():
    knots = np.array([31.5, 95.5, 159.5, 223.5, 287.5, 351.5, 415.5, 479.5])
    x = np.linspace(knots[0], knots[-1], 1001)
    w = natural_spline_weights(knots, x)
    np.testing.assert_allclose(w @ (3.0 * knots - 7.0), 3.0 * x - 7.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(w.sum(axis=1), 1.0, rtol=0, atol=1e-13)
    np.testing.assert_allclose(natural_spline_weights(knots, knots), np.eye(knots.size), atol=1e-13)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    m=st.integers(1, 30),
    kind=st.sampled_from(["cubic", "linear"]),
)
def test_local_form_is_the_dense_matrix(seed, m, kind):
    """The spline's local form (long axes) against the dense weight matrix, to 1e-12."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(max(m, 2), 400))
    centres = np.sort(rng.choice(np.arange(n) + 0.5 * rng.integers(0, 2), m, replace=False))
    dense = interpolation_matrix(centres, n, kind)
    local = AxisWeights(centres, n, kind, dense_limit=0)
    assert not local.dense and AxisWeights(centres, n, kind).dense
    v = 1000.0 + 50.0 * rng.standard_normal((m, 5))
    # the same spline evaluated two ways in float64 (the tridiagonal system is diagonally
    # dominant, condition <= 3): they agree to ~100 ulps of values of ~1,000, far below 1e-9
    scale = np.abs(v).max()
    np.testing.assert_allclose(local.apply(v), dense @ v, rtol=0, atol=1e-12 * scale)
    pix = rng.integers(0, n, 50)
    np.testing.assert_allclose(local.apply(v, pix), dense[pix] @ v, rtol=0, atol=1e-12 * scale)
    col = rng.integers(0, 5, 50)
    np.testing.assert_allclose(
        local.pairs(v, pix, col), (dense @ v)[pix, col], rtol=0, atol=1e-12 * scale
    )


def _glow(shape, seed):
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]]
    glow = 1000.0 + 0.05 * xx + 0.03 * yy + 40.0 * np.sin(xx / 90.0) * np.cos(yy / 70.0)
    return (glow + rng.normal(0.0, 10.0, shape)).astype(np.uint16)


@pytest.mark.parametrize("kind", ["cubic", "linear"])
def test_background_in_local_form_is_the_dense_background(monkeypatch, kind):
    """A frame's background with every axis in local form equals the dense one."""
    img = _glow((300, 500), 3)
    idx = np.random.default_rng(4).integers(0, img.size, 400)
    results = []
    for limit in (axis_weights.DENSE_LIMIT, 0):
        monkeypatch.setattr(axis_weights, "DENSE_LIMIT", limit)
        mesh._axis_weights.cache_clear()
        full = estimate_background(img, interpolation=kind)
        lazy = estimate_background(img, interpolation=kind, full_noise_map=False)
        results.append((full.level, full.noise_map, lazy.noise_at(idx), lazy.noise_grid(3)))
    mesh._axis_weights.cache_clear()
    assert isinstance(lazy.surface.cols_w, AxisWeights)  # the local form was exercised
    # the dense path rounds its whole-frame product to float32 (one term per mesh column, 8
    # here): a few float32 ulps of the ~1,000-count level; the noise is the MAD of the samples
    # minus that level, so it inherits the same few ulps of the level
    ulp = float(np.spacing(np.float32(np.abs(results[0][0]).max())))
    for dense, local in zip(*results, strict=True):
        np.testing.assert_allclose(local, dense, rtol=0, atol=8 * ulp)


def test_long_thin_frame_in_bounded_memory():
    """A 1 x 20,000 frame: the dense weights took ~0.25 GB (n^2 / box), the local form ~2 MB."""
    img = _glow((1, 20_000), 5)
    mesh._axis_weights.cache_clear()
    tracemalloc.start()
    try:
        bg = estimate_background(img)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
        mesh._axis_weights.cache_clear()
    # the frame is 40 kB; its samples, mesh and maps a few hundred kB: 20 MB leaves room for
    # the allocator's and NumPy's temporaries while the dense weights (20,000 x 312 float64,
    # 50 MB each, several at once) cannot fit
    assert peak < 20e6, peak
    assert bg.level.shape == img.shape
    assert abs(float(np.median(bg.level)) - float(np.median(img))) < 10.0


def test_noise_at_in_blocks_is_the_whole_gather(monkeypatch):
    """NoiseSurface.at in blocks of pixels (a bright frame lights millions): the same numbers."""
    from starsense.detect import surface

    img = _glow((200, 300), 7)
    lazy = estimate_background(img, full_noise_map=False)
    idx = np.random.default_rng(8).integers(0, img.size, 5000)
    whole = lazy.noise_at(idx)
    monkeypatch.setattr(surface, "_AT_BLOCK_NUMBERS", 37)  # blocks of a few pixels
    np.testing.assert_array_equal(lazy.noise_at(idx), whole)
