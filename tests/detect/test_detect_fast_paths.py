"""The fast paths of the background and hot-pixel code against their plain whole-frame forms."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from starsense.detect import estimate_background, hot_pixel_mask
from starsense.detect.clip import (
    MAD_TO_SIGMA,
    _rank_of,
    _ranked,
    _robust_sigma_numpy,
    _rows_at,
    _run_mad,
    robust_sigma,
)
from starsense.detect.mesh import _interpolation_matrix, interpolate_mesh
from starsense.errors import InputError


def _hot_reference(image, bg, threshold_sigma=8.0):
    """The definition over the whole frame: scipy's maximum filters, -inf outside.

    A pixel above the threshold is hot when its 8 neighbours are quiet; else, with its brightest
    4-neighbour (not brighter than itself) as a pair, when the 10 pixels around the pair are.
    """
    sub = np.asarray(image, np.float32) - np.asarray(bg.level, np.float32)
    footprint = np.ones((3, 3), bool)
    footprint[1, 1] = False
    neighbours = ndimage.maximum_filter(sub, footprint=footprint, mode="constant", cval=-np.inf)
    noise = np.maximum(bg.noise_map if bg.noise_map is not None else bg.noise, np.float32(1e-12))
    limit = np.maximum(3.0 * noise, 0.15 * sub)
    above = sub > threshold_sigma * noise
    hot = above & (neighbours < limit)
    padded = np.pad(sub, 2, constant_values=-np.inf)
    rows, cols = sub.shape
    steps = [(-1, 0), (1, 0), (0, -1), (0, 1)]
    side = np.stack([padded[2 + dr : 2 + dr + rows, 2 + dc : 2 + dc + cols] for dr, dc in steps])
    best = np.argmax(side, axis=0)
    for r, c in zip(*np.nonzero(above & ~hot), strict=True):
        dr, dc = steps[best[r, c]]
        box = padded[2 + r + min(0, dr) - 1 : 2 + r + max(0, dr) + 2,
                     2 + c + min(0, dc) - 1 : 2 + c + max(0, dc) + 2].copy()  # fmt: skip
        box[1 - min(0, dr), 1 - min(0, dc)] = -np.inf  # the pixel
        box[1 - min(0, dr) + dr, 1 - min(0, dc) + dc] = -np.inf  # its partner
        partner = padded[2 + r + dr, 2 + c + dc]
        if box.max() < limit[r, c] and sub[r, c] >= partner:
            hot[r, c] = True
            if 0 <= r + dr < rows and 0 <= c + dc < cols:
                hot[r + dr, c + dc] = True
    return hot


@pytest.mark.parametrize("seed", range(4))
def test_hot_pixel_mask_matches_the_whole_frame_definition(seed):
    rng = np.random.default_rng(seed)
    img = 200.0 + 8.0 * rng.standard_normal((97, 131))
    img += np.linspace(0, 60, 131)[None, :]  # a glow, so the noise map varies
    spots = rng.integers(0, [97, 131], (60, 2))
    img[spots[:, 0], spots[:, 1]] += rng.uniform(0, 2000, 60)  # isolated and touching spikes
    img[0, 0] += 900.0  # corner
    img[50, 130] += 900.0  # edge
    img[20, 20:22] += 900.0  # a pair: hot together
    img[70:72, 100] += [900.0, 700.0]  # a vertical pair
    img[80, 30:32] += [900.0, 500.0]  # a pair with a star-like neighbour: not hot
    img[81, 31] += 400.0
    img[60:63, 60:63] += 400.0  # a flat blob
    bg = estimate_background(img, box_px=16)
    expected = _hot_reference(img, bg)
    assert expected.sum() >= 10  # the test exercises real hot pixels
    assert np.array_equal(hot_pixel_mask(img, bg), expected)
    sub = img.astype(np.float32) - bg.level
    assert np.array_equal(hot_pixel_mask(img, bg, subtracted=sub), expected)
    strict = hot_pixel_mask(img, bg, threshold_sigma=20.0)
    assert np.array_equal(strict, _hot_reference(img, bg, 20.0))


def test_hot_pixel_pairs_are_hot_and_stars_between_two_pixels_are_not():
    rng = np.random.default_rng(5)
    img = 100.0 + 4.0 * rng.standard_normal((64, 96))
    img[20, 20:22] += 300.0  # a horizontal pair
    img[40:42, 70] += [300.0, 200.0]  # a vertical pair
    # a star of PSF sigma 0.6 px centred between two pixels (the undersampled extreme): its
    # pixels beside the pair get ~25 % of the pair's light
    y, x = np.mgrid[0:64, 0:96]
    img += 600.0 * np.exp(-((x - 50.0) ** 2 + (y - 30.5) ** 2) / (2 * 0.6**2))
    bg = estimate_background(img, box_px=16)
    hot = hot_pixel_mask(img, bg)
    assert hot[20, 20:22].all() and hot[40:42, 70].all()
    assert not hot[28:34, 47:54].any()
    assert hot.sum() == 4


def test_hot_pixel_mask_without_candidates_and_bad_subtracted():
    img = np.full((20, 30), 100.0)
    bg = estimate_background(img + np.random.default_rng(0).normal(0, 1, img.shape), box_px=10)
    assert not hot_pixel_mask(img, bg).any()
    with pytest.raises(InputError, match="subtracted has shape"):
        hot_pixel_mask(img, bg, subtracted=np.zeros((20, 29), np.float32))


@pytest.mark.parametrize(("rows", "cols", "kind"), [(768, 1024, "cubic"), (101, 37, "linear")])
def test_interpolate_mesh_is_the_matrix_product(rows, cols, kind):
    rng = np.random.default_rng(1)
    ny, nx = 12, 7
    mesh = 1000.0 + 50.0 * rng.standard_normal((ny, nx))
    wy = _interpolation_matrix(np.linspace(4, rows - 5, ny), rows, kind)
    wx = _interpolation_matrix(np.linspace(3, cols - 4, nx), cols, kind)
    got = interpolate_mesh(wy, mesh, wx)
    assert got.dtype == np.float32 and got.shape == (rows, cols)
    # the whole-frame product is float32: each pixel sums one term per mesh column (7), each
    # rounded to a float32 ulp of ~1,000 (6.1e-5), so 8 ulps of the mesh's scale are allowed
    ulp = float(np.spacing(np.float32(np.abs(mesh).max())))
    np.testing.assert_allclose(got, wy @ mesh @ wx.T, rtol=0, atol=8 * ulp)


@pytest.mark.parametrize("integer", [False, True])
def test_run_mad_is_the_median_of_the_sorted_deviations(integer):
    """Bisection over the run's two halves against sorting the deviations (ties, NaN, empty)."""
    rng = np.random.default_rng(7)
    cells = rng.normal(0.0, 3.0, (40, 9, 50)).astype(np.float32)
    if integer:
        cells = np.round(cells).astype(np.float32)  # many ties, as in quantised frames
    cells[rng.random(cells.shape) < 0.2] = np.nan
    s = np.sort(cells, axis=-1)
    n = np.isfinite(s).sum(-1)
    lo = rng.integers(0, np.maximum(n // 3, 1))
    hi = np.maximum(lo, n - rng.integers(0, np.maximum(n // 3, 1)))
    hi[0, 0] = lo[0, 0]  # an empty run
    med = _ranked(s, lo, hi - lo)
    got = _run_mad(s, lo, hi, med)
    for idx in np.ndindex(lo.shape):
        run = s[idx][lo[idx] : hi[idx]]
        if run.size == 0:
            assert np.isnan(got[idx])
            continue
        dev = np.sort(np.abs(run - np.float32(med[idx])))  # float32, as the clipping computes it
        expected = 0.5 * (float(dev[(run.size - 1) // 2]) + float(dev[run.size // 2]))
        assert got[idx] == expected  # the same float32 values are picked: exact


def test_interpolate_flat_mesh_is_exact():
    # a constant frame's background must be exactly its value: any rounding above it would
    # light every pixel of a frame whose noise is zero
    wy = _interpolation_matrix(np.linspace(31.5, 736.5, 12), 768, "cubic")
    wx = _interpolation_matrix(np.linspace(31.5, 992.5, 16), 1024, "cubic")
    got = interpolate_mesh(wy, np.full((12, 16), 500.0), wx)
    assert np.all(got == np.float32(500.0))


@pytest.mark.parametrize("inclusive", [False, True])
def test_rank_of_is_searchsorted_in_the_run(inclusive):
    """The blocked search against np.searchsorted per row, clamped to the run (ties, NaN)."""
    rng = np.random.default_rng(11)
    cells = np.round(rng.normal(0.0, 20.0, (7, 5, 300))).astype(np.float32)  # many ties
    cells[rng.random(cells.shape) < 0.1] = np.nan
    s = np.sort(cells, axis=-1)  # NaN last
    n = np.isfinite(s).sum(-1)
    lo = rng.integers(0, np.maximum(n // 3, 1))
    hi = np.maximum(lo, n - rng.integers(0, np.maximum(n // 3, 1)))
    x = np.where(rng.random(lo.shape) < 0.5, rng.normal(0, 20, lo.shape), 0.0).astype(np.float32)
    x[0, 0] = np.nan
    got = _rank_of(_rows_at(s), lo, hi, x, inclusive)
    side = "right" if inclusive else "left"
    for idx in np.ndindex(lo.shape):
        finite = s[idx][: n[idx]]
        expected = 0 if np.isnan(x[idx]) else np.searchsorted(finite, x[idx], side=side)
        assert got[idx] == min(max(expected, lo[idx]), hi[idx])


@pytest.mark.parametrize("form", ["as used", "numpy"])
@pytest.mark.parametrize("samples", [50, 300])
def test_robust_sigma_is_the_mad_of_the_kept_samples(samples, form):
    # every path (the compiled kernel when built; in NumPy, short rows sort their deviations,
    # long rows search for their median) against the definition, sample by sample:
    # 1.4826 x the median of |x - median(x)| over the kept
    robust = robust_sigma if form == "as used" else _robust_sigma_numpy

    rng = np.random.default_rng(samples)
    cells = np.round(rng.normal(0.0, 4.0, (6, 5, samples))).astype(np.float32)
    keep = rng.random(cells.shape) < 0.8
    keep[0, 0] = False  # a box with nothing kept
    got = robust(cells, keep)
    for idx in np.ndindex(keep.shape[:-1]):
        x = cells[idx][keep[idx]]
        if x.size == 0:
            assert np.isnan(got[idx])
            continue
        med = np.float32(
            0.5 * (float(np.sort(x)[(x.size - 1) // 2]) + float(np.sort(x)[x.size // 2]))
        )
        dev = np.sort(np.abs(x - med))
        expected = MAD_TO_SIGMA * 0.5 * (float(dev[(x.size - 1) // 2]) + float(dev[x.size // 2]))
        assert got[idx] == pytest.approx(expected, rel=1e-12)
