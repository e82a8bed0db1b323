"""The compiled window kernel (``starsense.detect._windowc``) against the NumPy form.

Both cut the same windows, threshold in float32, label in scipy's raster order and sum each
region's lit pixels in the same order. The centroid sums (over a box grown by the margin, or a
streak's capsule) are summed in another order: exact for whole-number counts (every partial
sum of whole numbers below 2^53 is exact), so there every row must be equal bit for bit, except
the streak spread (a sum of products of non-integer offsets: equal to 1e-9 relative, far below
any use of it). For non-integer counts the centroids may differ by rounding only: 1e-9 px.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from starsense.catalog import load_catalog
from starsense.detect import window_kernels as wk
from starsense.detect.streak import windows_view
from starsense.detect.threshold import DetectionLogic, StarDetector
from starsense.detect.windows import WindowDetector
from starsense.geometry.attitude import attitude_from_radec_roll
from starsense.render.scene import render_frame
from starsense.sensor import load_sensor

needs_kernel = pytest.mark.skipif(wk._windowc is None, reason="compiled kernel not built")


def test_the_kernel_is_built_where_a_compiler_exists():
    # setup.py builds it as an optional extension: a machine with a C compiler that ends up
    # without it runs the NumPy form silently, which this makes visible
    if shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler on this machine: the NumPy form is the one in use")
    assert wk._windowc is not None


def _frame(rng, dtype, integer: bool):
    """A seeded frame: background, noise, round and streaked stars, hot pixels, a hole."""
    rows, cols = int(rng.integers(30, 160)), int(rng.integers(30, 160))
    level = rng.uniform(5, 60)
    img = rng.normal(level, rng.uniform(0.5, 6), (rows, cols))
    yy, xx = np.mgrid[:rows, :cols]
    for _ in range(int(rng.integers(0, 12))):
        x0, y0, s = rng.uniform(-3, cols + 3), rng.uniform(-3, rows + 3), rng.uniform(0.6, 2.5)
        lx, ly = rng.uniform(-12, 12, 2) * (rng.random() < 0.5)
        amp = rng.uniform(5, 200)
        for t in np.linspace(-0.5, 0.5, 7):  # a streak: PSFs along its segment
            img += amp / 7 * np.exp(-((xx - x0 - t * lx) ** 2 + (yy - y0 - t * ly) ** 2) / s / s)
    hot = rng.random((rows, cols)) < 0.005
    img[hot] += rng.uniform(20, 400, hot.sum())
    top = {np.uint8: 255, np.int16: 32767, np.uint16: 65535}.get(dtype, None)
    img = np.clip(img, 0, top) if top else img
    if integer:
        img = np.round(img)
    return img.astype(dtype)


def _case(seed, dtype, integer, per_window, streaked, connectivity):
    rng = np.random.default_rng(seed)
    img = _frame(rng, dtype, integer)
    rows, cols = img.shape
    k = int(rng.integers(1, 12))
    h = min(int(rng.integers(3, 40)), rows)
    w = min(int(rng.integers(3, 40)), cols)
    r0 = rng.integers(0, rows - h + 1, k)
    c0 = rng.integers(0, cols - w + 1, k)
    n_levels = k if per_window else 1
    level = rng.uniform(0, 60, n_levels)
    if integer:
        level = np.round(2 * level) / 2  # whole or half counts: the medians of whole counts
    threshold = wk.float32_below(rng.uniform(2, 40, n_levels))
    logic = DetectionLogic(
        lit_pixel_counts=1.0,
        min_pixels=int(rng.integers(1, 5)),
        min_integrated_counts=float(rng.uniform(0, 300)),
        connectivity=connectivity,
    )
    streaks = rng.uniform(-15, 15, (k, 2)) if streaked else None
    kw = {
        "corners": (r0, c0),
        "level": level.astype(np.float32),
        "threshold": threshold,
        "logic": logic,
        "sigma_px": float(rng.uniform(0.5, 2.5)),
        "streaks": streaks,
    }
    stack = windows_view(img[None], (h, w))[0, r0, c0]
    ref = wk.detect_stack_numpy(stack, img.shape, **kw)
    got = wk.detect_stack_compiled(img, (h, w), **kw)
    return ref, got


NAMES = ("x", "y", "counts", "pixels", "peak", "box", "spread")


@needs_kernel
@settings(max_examples=150, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    dtype=st.sampled_from([np.uint8, np.uint16, np.int16, np.int32, np.float32, np.float64]),
    per_window=st.booleans(),
    streaked=st.booleans(),
    connectivity=st.sampled_from([4, 8]),
)
def test_kernel_equals_the_numpy_form_on_whole_counts(
    seed, dtype, per_window, streaked, connectivity
):
    (ref, n_ref), (got, n_got) = _case(seed, dtype, True, per_window, streaked, connectivity)
    assert n_got == n_ref
    for name, g, e in zip(NAMES, got, ref, strict=True):
        assert g.shape == e.shape, name
        if name == "spread":
            np.testing.assert_allclose(g, e, rtol=1e-9, atol=1e-9, err_msg=name)
        else:
            np.testing.assert_array_equal(g, e, err_msg=name)


@needs_kernel
@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    per_window=st.booleans(),
    streaked=st.booleans(),
    connectivity=st.sampled_from([4, 8]),
)
def test_kernel_agrees_to_rounding_on_fractional_counts(seed, per_window, streaked, connectivity):
    (ref, n_ref), (got, n_got) = _case(seed, np.float64, False, per_window, streaked, connectivity)
    assert n_got == n_ref
    for name, g, e in zip(NAMES, got, ref, strict=True):
        assert g.shape == e.shape, name
        if name in ("pixels", "peak") or (name == "box" and not streaked):
            np.testing.assert_array_equal(g, e, err_msg=name)  # no centroid sum in them
        else:
            np.testing.assert_allclose(g, e, rtol=1e-9, atol=1e-9, err_msg=name)


@pytest.mark.parametrize("known", [True, False])
def test_window_detector_gives_the_same_detections_either_way(known):
    # the detector's own path choice: a rendered ST-16 frame (streaked) searched both ways
    sensor = load_sensor("st16")
    att = attitude_from_radec_roll(np.radians(250.0), np.radians(35.0), np.radians(10.0))
    rate = np.radians([0.7, 0.7, 0.1])
    cat = load_catalog("hipparcos")
    frame = render_frame(sensor, att, cat, rate_rad_s=rate, max_mag=5.75, rng=1)
    stars = frame.truth.stars
    centres = np.column_stack([stars.x_mid, stars.y_mid])
    centres = centres[(centres[:, 0] > 0) & (centres[:, 1] > 0)][:30]
    centres = centres[(centres[:, 0] < 2591) & (centres[:, 1] < 1943)]
    streaks = np.tile([[-8.8, 8.9]], (len(centres), 1))
    found = []
    for compiled in (True, False):
        wd = WindowDetector(StarDetector.for_sensor(sensor), sensor.detector, known, 5.0, compiled)
        found.append(wd(frame.image, centres, half_px=27, streaks_px=streaks).detections)
    a, b = found
    assert len(a.x) >= 5
    for name in ("x", "y", "integrated_counts", "n_pixels", "peak_counts", "bbox"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    np.testing.assert_allclose(a.extra["spread_px2"], b.extra["spread_px2"], rtol=1e-9)
    assert a.n_candidates == b.n_candidates and a.noise_counts == b.noise_counts


@needs_kernel
@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), k=st.integers(0, 40))
def test_kernel_union_area_equals_the_numpy_form(seed, k):
    # integer arithmetic both ways: equal; and bounded by the sum and the largest box
    rng = np.random.default_rng(seed)
    r0, c0 = rng.integers(-5, 60, k), rng.integers(-5, 60, k)
    boxes = np.column_stack([r0, r0 + rng.integers(0, 30, k), c0, c0 + rng.integers(0, 30, k)])
    got, ref = wk.union_area_compiled(boxes), wk.union_area_numpy(boxes)
    assert got == ref
    areas = (boxes[:, 1] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 2])
    assert (areas.max() if k else 0) <= got <= areas.sum()


@needs_kernel
@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(0, 40))
def test_kernel_apart_equals_the_numpy_form(seed, n):
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(0, 8, n), rng.uniform(0, 8, n)  # crowded: many within 2 px
    x[: n // 4] = np.round(x[: n // 4])  # and some exactly 2 px apart
    y[: n // 4] = np.round(y[: n // 4])
    order = rng.permutation(n)
    got, ref = wk.apart_compiled(x, y, order), wk.apart_numpy(x, y, order)
    np.testing.assert_array_equal(got, ref)
    kept = order[got]
    d = np.hypot(x[kept, None] - x[None, kept], y[kept, None] - y[None, kept])
    assert (d[~np.eye(len(kept), dtype=bool)] >= 2.0).all()


@needs_kernel
@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), k=st.integers(1, 40), n=st.integers(0, 60))
def test_kernel_count_inside_equals_the_numpy_form(seed, k, n):
    # the same rounding (half to even) and comparisons: equal; checked against a painted mask
    rng = np.random.default_rng(seed)
    r0, c0 = rng.integers(0, 60, k), rng.integers(0, 60, k)
    boxes = np.column_stack([r0, r0 + rng.integers(1, 30, k), c0, c0 + rng.integers(1, 30, k)])
    x, y = rng.uniform(-3, 95, n), rng.uniform(-3, 95, n)
    half = rng.random(n) < 0.3  # some on the half pixel, where the rounding decides
    x[half], y[half] = np.round(2 * x[half]) / 2, np.round(2 * y[half]) / 2
    x[: n // 8] = np.nan  # behind the camera: in no window
    got = wk.count_inside_compiled(boxes, x, y)
    assert got == wk.count_inside_numpy(boxes, x, y)
    paint = np.zeros((100, 100), bool)
    for a, b, c, d in boxes:
        paint[a:b, c:d] = True
    ok = np.isfinite(x)
    xi, yi = np.rint(x[ok]).astype(int), np.rint(y[ok]).astype(int)
    on = (xi >= 0) & (yi >= 0)
    assert got == int(paint[yi[on], xi[on]].sum())


def test_without_the_kernel_the_numpy_form_answers(monkeypatch):
    # a machine without a C compiler: the compiled entry points say so (None) and the
    # detector falls back to the NumPy form
    monkeypatch.setattr(wk, "_windowc", None)
    boxes = np.array([[0, 10, 0, 10], [5, 15, 5, 15]])
    assert wk.union_area_compiled(boxes) is None and wk.union_area_numpy(boxes) == 175
    # (0, 0) and (9.5 -> 10, 12) lie in a box, (20, 3) in none
    px, py = np.array([0.0, 9.5, 20.0]), np.array([0.0, 12.0, 3.0])
    assert wk.count_inside_compiled(boxes, px, py) is None
    assert wk.count_inside_numpy(boxes, px, py) == 2
    x = np.array([0.0, 1.0, 5.0])
    assert wk.apart_compiled(x, x, np.arange(3)) is None
    np.testing.assert_array_equal(wk.apart_numpy(x, x, np.arange(3)), [0, 2])
    # a flat frame at the ST-16's bias (its known background) with a 4 x 4 spot 500 counts over it
    camera = load_sensor("st16").detector
    img = np.full((40, 40), camera.bias_counts, np.uint16)
    img[18:22, 18:22] += 500
    logic = DetectionLogic(lit_pixel_counts=50.0, min_pixels=4, min_integrated_counts=100.0)
    wd = WindowDetector(StarDetector(logic), camera, True, 5.0)
    det = wd(img, np.array([[19.5, 19.5]]), half_px=8).detections
    assert len(det.x) == 1 and det.n_pixels[0] == 16
    assert det.x[0] == 19.5 and det.y[0] == 19.5  # a symmetric spot: its centre, exactly
