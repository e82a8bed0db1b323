"""Detection and centroiding (ST-16 logic of Dzamba & Enright 2014, sec. 1.2)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import erf

from starsense.detect import StarDetector, detect_stars, estimate_background, hot_pixel_mask
from starsense.errors import InputError
from starsense.photometry.sensitivity import Sensitivity
from starsense.render.noise import apply_noise
from starsense.render.smear import streak_stamp_expected
from starsense.sensor import DetectionThresholds, load_sensor


def pixel_gaussian(shape, x0, y0, sigma, flux):
    """Independent construction: a Gaussian integrated over each pixel (centres at integers)."""
    rows, cols = shape
    s = np.sqrt(2) * sigma
    x = np.arange(cols)
    y = np.arange(rows)
    gx = 0.5 * (erf((x + 0.5 - x0) / s) - erf((x - 0.5 - x0) / s))
    gy = 0.5 * (erf((y + 0.5 - y0) / s) - erf((y - 0.5 - y0) / s))
    return flux * np.outer(gy, gx)


LOGIC = DetectionThresholds(lit_pixel_counts=120, min_pixels=6, min_integrated_counts=1000)


@pytest.mark.parametrize("method", ["cog", "iwcog", "gauss"])
@pytest.mark.parametrize(("x0", "y0"), [(20.0, 15.0), (20.37, 15.81), (19.5, 14.5)])
def test_noiseless_symmetric_star_centroids_within_001_px(method, x0, y0):
    # CoG of a pixel-integrated Gaussian wholly inside the window is unbiased up to a pixel-phase
    # term ~exp(-2 pi^2 sigma^2) (1e-19 px at 1.5 px); the fit is exact for noiseless data.
    image = pixel_gaussian((32, 40), x0, y0, 1.5, 50_000.0)
    det = StarDetector(LOGIC, method, margin_px=6)(image)
    assert len(det) == 1
    assert det.x[0] == pytest.approx(x0, abs=0.01)
    assert det.y[0] == pytest.approx(y0, abs=0.01)


def test_min_pixels_and_integrated_intensity_rules():
    img = np.zeros((10, 30))
    img[2, 1:6] = 300  # 5 lit pixels: rejected
    img[5, 1:7] = 300  # 6 lit pixels, 1800 counts: accepted
    img[8, 10:16] = 166.5  # 6 lit pixels, 999 counts: rejected
    img[8, 20:26] = 166.9  # 6 lit pixels, 1001.4 counts: accepted
    det = detect_stars(img, LOGIC)
    assert len(det) == 2
    assert sorted(det.n_pixels.tolist()) == [6, 6]
    assert det.integrated_counts[0] == pytest.approx(1800)  # brightest first
    assert det.n_candidates == 4


def test_connectivity_4_versus_8():
    img = np.zeros((12, 12))
    for i in range(8):  # a diagonal line of 8 lit pixels
        img[2 + i, 2 + i] = 500
    eight = detect_stars(
        img,
        DetectionThresholds(
            lit_pixel_counts=120, min_pixels=6, min_integrated_counts=1000, connectivity=8
        ),
    )
    four = detect_stars(
        img,
        DetectionThresholds(
            lit_pixel_counts=120, min_pixels=6, min_integrated_counts=1000, connectivity=4
        ),
    )
    assert len(eight) == 1 and eight.n_pixels[0] == 8
    assert len(four) == 0 and four.n_candidates == 8  # eight single-pixel regions


def test_peak_saturation_and_bbox():
    img = pixel_gaussian((30, 30), 14.2, 15.6, 1.5, 2e5)
    img = np.minimum(np.round(img), 4095)
    det = StarDetector(LOGIC, saturation_counts=4095)(img)
    assert det.saturated[0] and det.peak_counts[0] == 4095
    r0, r1, c0, c1 = det.bbox[0]
    assert r0 <= 15 < r1 and c0 <= 14 < c1


def test_background_gradient_hot_pixels_and_stars():
    rng = np.random.default_rng(3)
    rows, cols = 300, 400
    yy, xx = np.mgrid[0:rows, 0:cols]
    truth_bg = 200 + 0.1 * xx + 0.05 * yy
    img = truth_bg + rng.normal(0, 10, (rows, cols))
    pos = np.column_stack([rng.uniform(15, cols - 15, 30), rng.uniform(15, rows - 15, 30)])
    for x, y in pos:
        img += pixel_gaussian((rows, cols), x, y, 1.3, 4000.0)
    hot = np.column_stack([rng.integers(5, cols - 5, 20), rng.integers(5, rows - 5, 20)])
    img[hot[:, 1], hot[:, 0]] += 3000.0
    bg = estimate_background(img, box_px=50)
    # away from stars the map follows the gradient to a few noise sigma / sqrt(box pixels)
    assert np.median(np.abs(bg.level - truth_bg)) < 2.0
    assert bg.noise == pytest.approx(10, rel=0.15)
    assert hot_pixel_mask(img, bg)[hot[:, 1], hot[:, 0]].all()
    det = StarDetector(
        DetectionThresholds(lit_pixel_counts=1, min_pixels=4, min_integrated_counts=500),
        background="auto",
        threshold_sigma=5,
    )(img)
    found = np.column_stack([det.x, det.y])
    d_star = np.min(np.linalg.norm(found[:, None] - pos[None], axis=2), axis=0)
    assert (d_star < 0.5).all()  # every star found
    d_hot = np.min(np.linalg.norm(found[:, None] - hot[None], axis=2), axis=0)
    assert (d_hot > 2).all()  # no hot pixel reported as a star


def test_rendered_star_round_trip():
    # render -> detect: a static m = 3 ST-16 star (5,100 e-, 33,000 counts) with shot and read
    # noise. CoG noise: shot 1.5 px / sqrt(5,100) = 0.021 px; read noise 23 counts over the ~130
    # pixels of the window (lit radius ~3.6 px + 2 px margin) adds 23 sqrt(sum x^2) / 33,000
    # ~ 0.025 px: ~0.033 px in all, so 0.1 px is 3 sigma.
    s = load_sensor("st16")
    e = float(Sensitivity.for_sensor(s, "reed").electrons(3.0))
    stamp, r0, c0 = streak_stamp_expected(s, x0=30.3, y0=20.6, x1=30.3, y1=20.6, electrons=e)
    counts = apply_noise(stamp, s, rng=np.random.default_rng(0))
    det = StarDetector.for_sensor(s)(counts)
    assert len(det) == 1
    assert det.x[0] + c0 == pytest.approx(30.3, abs=0.1)
    assert det.y[0] + r0 == pytest.approx(20.6, abs=0.1)


def test_empty_image_gives_no_detections():
    det = detect_stars(np.zeros((50, 60)), LOGIC)
    assert len(det) == 0 and det.n_candidates == 0


@pytest.mark.parametrize(
    ("image", "kwargs", "message"),
    [
        (np.zeros((3, 3, 3)), {}, "image must be 2-D"),
        (np.full((4, 4), np.nan), {}, r"image has 16 non-finite \(NaN or inf\) pixel"),
        (np.zeros((4, 4)), {"centroid": "median"}, "centroid must be one of"),
        (np.zeros((4, 4)), {"threshold_sigma": -1.0}, "threshold_sigma must be > 0"),
        (np.zeros((4, 4)), {"background": "sky"}, "background must be 'auto'"),
    ],
)
def test_bad_input(image, kwargs, message):
    with pytest.raises(InputError, match=message):
        detect_stars(image, LOGIC, **kwargs)


def test_bad_logic_values():
    with pytest.raises(InputError, match=r"detection\.connectivity must be 4 or 8"):
        DetectionThresholds(connectivity=5)
    with pytest.raises(InputError, match=r"detection.lit_pixel_counts = -1 is out of range"):
        DetectionThresholds(lit_pixel_counts=-1)


def test_esa_frames_detect_stars_not_hot_pixels(shared_dir):
    from PIL import Image

    sensor = load_sensor("esa_blackfly")
    frames = sorted((shared_dir / "data/images/esa").glob("*.tiff"))
    assert len(frames) == 8
    for path in frames:
        image = np.array(Image.open(path))
        det = StarDetector(sensor.detection, background="auto", threshold_sigma=5)(image)
        # measured 22-118 per frame; a broken background would give thousands or none
        assert 15 <= len(det) <= 200, path.name
        bg = estimate_background(image)
        hot = np.argwhere(hot_pixel_mask(image, bg))
        if len(hot):
            d = np.min(np.hypot(det.x[:, None] - hot[None, :, 1], det.y[:, None] - hot[None, :, 0]))
            assert d > 0.5
