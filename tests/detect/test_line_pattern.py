"""Row and column fixed pattern (starsense.detect.pattern) and the local filtered noise.

Truths by construction: a banding of known offsets added to white noise is measured back to
the noise of a line mean; white noise alone carries no significant pattern and is untouched.
"""

from __future__ import annotations

import numpy as np
import pytest

from starsense.detect import StarDetector
from starsense.detect.matched import gaussian_correlate, local_noise_ratio
from starsense.detect.pattern import remove_line_pattern
from starsense.sensor import DetectionThresholds


def test_row_banding_is_measured_and_removed():
    rng = np.random.default_rng(4)
    bands = (0.3 * rng.standard_normal(768)).astype(np.float32)  # 0.3 of the noise
    sub = rng.standard_normal((768, 1024)).astype(np.float32) + bands[:, None]
    found = remove_line_pattern(sub, 1.0)
    # the rms of the offsets: 0.3 to its sampling error (0.3 / sqrt(2 x 768) ~ 2.5 %) plus the
    # noise of each line mean (1 / 32 in quadrature); 8 % allowed
    assert found["row_pattern_counts"] == pytest.approx(np.std(bands), rel=0.08)
    assert found["column_pattern_counts"] == 0.0
    # what is left of each row's offset is the noise of its mean: 1 / sqrt(1024) = 0.031
    assert np.std(sub.mean(axis=1)) < 0.05


def test_white_noise_has_no_line_pattern():
    sub = np.random.default_rng(5).standard_normal((768, 1024)).astype(np.float32)
    before = sub.copy()
    assert remove_line_pattern(sub, 1.0) == {
        "row_pattern_counts": 0.0,
        "column_pattern_counts": 0.0,
    }
    np.testing.assert_array_equal(sub, before)


def test_local_filtered_noise_rises_over_a_blotchy_pattern_only():
    # waves of 60 px of 0.8 noise over the right third pass the PSF filter almost whole: the
    # local ratio rises there (white: 1 / (2 sqrt(pi) 1.2) = 0.235; with the waves ~0.6) and
    # stays the frame's elsewhere
    rng = np.random.default_rng(6)
    y, x = np.mgrid[0:768, 0:1026].astype(np.float32)
    frame = rng.standard_normal(x.shape).astype(np.float32)
    frame[:, 684:] += 0.8 * np.cos(2 * np.pi * (x[:, 684:] + 0.5 * y[:, 684:]) / 60.0)
    filtered = gaussian_correlate(frame, 1.2)
    local = local_noise_ratio(filtered, np.float32(1.0), ratio=0.3)
    right = local[:, -2:]
    assert np.all(right > 0.45)
    assert np.all(local[:, :6] == np.float32(0.3))


def _banded_with_stars(rng):
    """White noise of 3 counts, row banding of 1.5 counts, 6 stars at 7 sigma (matched filter)."""
    image = 100 + 3 * rng.standard_normal((768, 1024)) + 1.5 * rng.standard_normal((768, 1))
    y, x = np.mgrid[0:768, 0:1024]
    at = [
        (150.3, 100.6),
        (400.7, 300.2),
        (650.5, 500.5),
        (900.1, 200.8),
        (300.4, 600.3),
        (800, 700),
    ]
    # 7 sigma: 110 counts / (3 sqrt(4 pi) 1.5 px) for the detector's default PSF of 1.5 px
    for cx, cy in at:
        image += (
            160 / (2 * np.pi * 1.5**2) * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * 1.5**2))
        )
    return image, np.array(at)


def test_banding_removed_keeps_faint_stars():
    # with the banding measured and removed, the 7 sigma stars are all found and no row lights
    # as a string of candidates (the frame's measured filtered noise also absorbs this
    # banding: the stars are found without the removal too; the removal's own check is above)
    image, at = _banded_with_stars(np.random.default_rng(7))
    logic = DetectionThresholds(lit_pixel_counts=1.0, min_pixels=3, min_integrated_counts=0.0)
    det = StarDetector(
        logic, background="auto", threshold_sigma=5.0, matched_filter=True, min_snr=5
    )(image)
    assert det.counts["row_pattern_counts"] > 1.0
    found = np.hypot(det.x[:, None] - at[:, 0], det.y[:, None] - at[:, 1]).min(axis=0) < 1.0
    assert found.sum() >= 5
    assert len(det) <= len(at) + 2


@pytest.mark.parametrize("mapped", [False, True])
@pytest.mark.parametrize("axis", [1, 0])
def test_compiled_line_offsets_are_the_numpy_form(monkeypatch, mapped, axis):
    import starsense.detect.pattern as pattern

    if pattern._framec is None:
        pytest.skip("the compiled kernel was not built (no C compiler)")
    rng = np.random.default_rng(7 + axis + 2 * mapped)
    sub = (rng.standard_normal((97, 131)) * 3.0).astype(np.float32)
    sub[10:14, 20:24] += 400.0  # a star, above the cut
    sub[40, :] += 30.0  # a whole row above the cut: no pixel of it kept, offset 0
    noise = rng.uniform(0.5, 2.0, sub.shape).astype(np.float32) if mapped else 1.7
    compiled = pattern.line_offsets(sub, noise, axis)
    monkeypatch.setattr(pattern, "_framec", None)
    reference = pattern.line_offsets(sub, noise, axis)
    # the same pixels kept (float32 comparisons alike); the sums in another order: float64
    # rounding, ~1e-16 of a sum of ~100 values of a few counts
    np.testing.assert_allclose(compiled, reference, rtol=1e-12, atol=1e-12)
    if axis == 1 and not mapped:
        assert compiled[40] == 0.0
