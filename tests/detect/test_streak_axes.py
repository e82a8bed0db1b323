"""The streak measure of all windows at once equals the window-by-window measure it replaced
(a window cut at the frame's edges)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from starsense.detect.clip import MAD_TO_SIGMA
from starsense.detect.streak import streak_axes


def _one_by_one(image, x, y, *, half_px, threshold, level=0.0, threshold_sigma=None):
    """The reference: one window at a time, scipy's labelling and a 2 x 2 eigh per window."""
    a = np.asarray(image)
    rows, cols = a.shape
    out = np.full((len(x), 2, 2), np.nan)
    for i, (xc, yc) in enumerate(zip(np.asarray(x, float), np.asarray(y, float), strict=True)):
        r0, c0 = round(yc) - half_px, round(xc) - half_px
        w = 2 * half_px + 1
        # the window cut at the frame's edges: its pixels off the frame are never lit
        sub = np.full((w, w), np.nan)
        ra, rb, ca, cb = max(r0, 0), min(r0 + w, rows), max(c0, 0), min(c0 + w, cols)
        sub[ra - r0 : rb - r0, ca - c0 : cb - c0] = a[ra:rb, ca:cb]
        cut = threshold
        if level is None:
            border = np.concatenate([sub[0], sub[-1], sub[1:-1, 0], sub[1:-1, -1]])
            border = border[np.isfinite(border)]
            if len(border) == 0:
                continue
            base = float(np.median(border))
            if threshold_sigma is not None:
                noise = MAD_TO_SIGMA * float(np.median(np.abs(border - base)))
                cut = max(threshold, threshold_sigma * noise)
            sub = sub - base
        else:
            sub = sub - level
        labels, _ = ndimage.label(np.nan_to_num(sub, nan=-np.inf) > cut, structure=np.ones((3, 3)))
        lit = np.argwhere(labels > 0)
        if len(lit) < 3:
            continue
        near = lit[np.argmin(np.hypot(lit[:, 0] - (yc - r0), lit[:, 1] - (xc - c0)))]
        mine = labels == labels[near[0], near[1]]
        wgt = np.where(mine, np.nan_to_num(sub), 0.0)
        total = wgt.sum()
        py, px = np.nonzero(mine)
        v = wgt[py, px]
        cx, cy = v @ px / total, v @ py / total
        dx, dy = px - cx, py - cy
        m = np.array([[v @ dx**2, v @ (dx * dy)], [v @ (dx * dy), v @ dy**2]]) / total
        lam, vec = np.linalg.eigh(m)
        e = vec[:, 1]
        out[i] = 12.0 * (lam[1] - lam[0]) * np.outer(e, e)
    return out


def _frame(rng, n_stars, length_px, sigma_px, shape=(120, 160)):
    """Streaks of random direction and brightness on a noisy pedestal, uint16."""
    rows, cols = shape
    yy, xx = np.mgrid[0:rows, 0:cols]
    img = rng.normal(100.0, 3.0, shape)
    xs, ys = rng.uniform(-5, cols + 5, n_stars), rng.uniform(-5, rows + 5, n_stars)
    for x0, y0 in zip(xs, ys, strict=True):
        ang, flux = rng.uniform(0, np.pi), rng.uniform(200, 5000)
        for t in np.linspace(-0.5, 0.5, 24):
            cx, cy = x0 + t * length_px * np.cos(ang), y0 + t * length_px * np.sin(ang)
            img += flux / 24 * np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * sigma_px**2))
    return np.clip(np.round(img), 0, 65535).astype(np.uint16), xs, ys


@pytest.mark.parametrize("seed", range(12))
def test_all_windows_at_once_equal_one_by_one(seed):
    rng = np.random.default_rng(seed)
    img, xs, ys = _frame(rng, 8, rng.uniform(0, 30), rng.uniform(0.6, 2.5))
    # centroids near the stars (and some anywhere: empty windows, windows off the frame)
    x = np.concatenate([xs + rng.normal(0, 1, len(xs)), rng.uniform(0, 160, 4)])
    y = np.concatenate([ys + rng.normal(0, 1, len(ys)), rng.uniform(0, 120, 4)])
    half = int(rng.integers(3, 25))
    for level, tsig in ((100.0, None), (None, None), (None, 5.0)):
        kw = {"half_px": half, "threshold": 15.0, "level": level, "threshold_sigma": tsig}
        got, ref = streak_axes(img, x, y, **kw), _one_by_one(img, x, y, **kw)
        # the same windows measured (NaN where the reference has NaN) ...
        np.testing.assert_array_equal(np.isnan(got), np.isnan(ref))
        # ... and the same moments up to the order of float64 summation (~1e-16 per term of
        # a few hundred pixel sums: 1e-12 of the largest element bounds it)
        scale = np.nanmax(np.abs(ref)) if np.isfinite(ref).any() else 1.0
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * scale)


def test_no_window_and_no_centroid():
    img = np.zeros((20, 20), np.uint16)
    assert streak_axes(img, [], [], half_px=3, threshold=1.0).shape == (0, 2, 2)
    assert np.isnan(streak_axes(img, [1.0], [1.0], half_px=5, threshold=1.0)).all()
    assert np.isnan(streak_axes(img, [10.0], [10.0], half_px=5, threshold=1.0)).all()


def _cut_streak(length_px, sigma_px, ang, gaps, neighbour_offset_px=None):
    """A bright noiseless streak on a zero pedestal, dark across it at ``gaps`` (t, px wide)."""
    shape = (121, 121)
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]].astype(float)
    img = np.zeros(shape)
    ux, uy = np.cos(ang), np.sin(ang)

    def draw(x0, y0):
        for t in np.linspace(-0.5, 0.5, 64):
            cx, cy = x0 + t * length_px * ux, y0 + t * length_px * uy
            img[:] += 4000 / 64 * np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * sigma_px**2))

    draw(60.3, 60.6)
    if neighbour_offset_px is not None:  # a parallel streak beside it
        draw(60.3 - neighbour_offset_px * uy, 60.6 + neighbour_offset_px * ux)
    whole = img.copy()
    along = (xx - 60.3) * ux + (yy - 60.6) * uy
    for t, width in gaps:
        img[np.abs(along - t) < width / 2] = 0.0
    return whole, img


def _length(axes):
    return float(np.sqrt(axes[0, 0, 0] + axes[0, 1, 1]))


@pytest.mark.parametrize("seed", range(12))
def test_collinear_pieces_bridge_into_the_whole_streak(seed):
    """A faint streak breaks where its ridge dips below the threshold: bridged along its line
    the pieces measure as the unbroken streak; left as they are, the centroid's piece is short."""
    rng = np.random.default_rng(seed)
    sigma, length, ang = rng.uniform(0.6, 1.5), rng.uniform(20, 40), rng.uniform(0, np.pi)
    band = 2.5 * sigma + 1.0  # the solver's capsule half-width
    # two gaps of 1.5-2.5 px (wide enough to part 8-connected pixels at any angle) on either
    # side of the centre, no wider than the band
    gaps = [(-length / 4, rng.uniform(1.5, 2.5)), (length / 5, rng.uniform(1.5, 2.5))]
    whole, cut = _cut_streak(length, sigma, ang, gaps)
    kw = {"half_px": 40, "threshold": 5.0}
    ref = _length(streak_axes(whole, [60.3], [60.6], **kw))
    alone = _length(streak_axes(cut, [60.3], [60.6], **kw))
    bridged = _length(streak_axes(cut, [60.3], [60.6], bridge_px=band, **kw))
    # the centre piece spans the middle ~45 % of the streak
    assert alone < 0.7 * ref, (alone, ref)
    # the gaps' few pixels (each under 2.5 px of a 20-40 px streak) take little of the moments:
    # within 5 % of the unbroken streak
    assert abs(bridged - ref) < 0.05 * ref, (bridged, ref)


def test_a_parallel_neighbour_is_not_bridged():
    """A streak beside the star's (4 bands away across its line) stays out of its measure."""
    sigma = 0.8
    band = 2.5 * sigma + 1.0
    _, alone = _cut_streak(30.0, sigma, 0.4, [])
    _, pair = _cut_streak(30.0, sigma, 0.4, [], neighbour_offset_px=4 * band)
    kw = {"half_px": 40, "threshold": 5.0}
    np.testing.assert_allclose(
        streak_axes(pair, [60.3], [60.6], bridge_px=band, **kw),
        streak_axes(alone, [60.3], [60.6], **kw),
        rtol=0,
        atol=1e-9,
    )


@pytest.mark.parametrize("seed", range(8))
def test_a_bright_star_at_rest_does_not_bridge_to_a_neighbour(seed):
    """A bright star at rest is a round lit disc several PSF sigmas wide at a low threshold;
    its moments' axis is the noise's. A fainter neighbour a band beyond its disc, on that axis,
    stays out of its measure: bridged along it, the pair measured as a streak (10-12 px in a
    crowded field at rest, read as smeared)."""
    rng = np.random.default_rng(seed)
    sigma = rng.uniform(1.2, 2.0)
    band = 2.5 * sigma + 1.0  # the solver's capsule half-width
    yy, xx = np.mgrid[0:81, 0:81].astype(float)

    def star(x0, y0, peak):
        return peak * np.exp(-((xx - x0) ** 2 + (yy - y0) ** 2) / (2 * sigma**2))

    x0, y0 = 40.0 + rng.uniform(-0.5, 0.5), 40.0 + rng.uniform(-0.5, 0.5)
    alone = star(x0, y0, 5000.0) + rng.normal(0.0, 1.0, xx.shape)  # 5000 counts, noise 1
    threshold = 5.0
    kw = {"half_px": 30, "threshold": threshold}
    axis = np.linalg.eigh(streak_axes(alone, [x0], [y0], **kw)[0])[1][:, -1]  # the noise's
    disc = sigma * np.sqrt(2.0 * np.log(5000.0 / threshold))  # the lit discs' radii
    other = sigma * np.sqrt(2.0 * np.log(200.0 / threshold))
    # the discs parted by 1.5 px (8-connected regions never touch) up to the band: in reach
    d = disc + other + rng.uniform(1.5, band)
    pair = alone + star(x0 + d * axis[0], y0 + d * axis[1], 200.0)
    unbridged = streak_axes(pair, [x0], [y0], **kw)
    assert np.sqrt(np.trace(unbridged[0])) < 1.0  # round: the noise's elongation only
    np.testing.assert_array_equal(streak_axes(pair, [x0], [y0], bridge_px=band, **kw), unbridged)


def test_windows_in_chunks_equal_all_at_once(monkeypatch):
    import starsense.detect.streak as streak_module

    rng = np.random.default_rng(3)
    img, xs, ys = _frame(rng, 8, 20.0, 1.2)
    kw = {"half_px": 20, "threshold": 15.0, "level": 100.0}
    whole = streak_axes(img, xs, ys, **kw)
    monkeypatch.setattr(streak_module, "WINDOW_PIXELS", 3 * 41 * 41)  # three windows a chunk
    parts = streak_axes(img, xs, ys, **kw)
    np.testing.assert_array_equal(whole, parts)
