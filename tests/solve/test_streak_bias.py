"""The centroid error of a clipped streak over its sub-pixel phase, against the renderer."""

from __future__ import annotations

import numpy as np
import pytest

from starsense.detect.streak import SYSTEMATIC, streak_centroids
from starsense.render.psf import Box
from starsense.render.smear import segment_expected
from starsense.solve.streak_bias import saturated_streak_bias_px


def _measured_rms(streak, n_e, *, sigma, sat_e, radius, rng, n=200):
    """Rms per axis of the capsule centroid of streaks rendered by the scene's own quadrature
    (``render.smear.segment_expected``) at random sub-pixel phases, clipped at ``sat_e``."""
    box = Box(0, 81, 0, 81)
    errs, sums = [], []
    for _ in range(n):
        cx, cy = 40.0 + rng.uniform(-0.5, 0.5), 40.0 + rng.uniform(-0.5, 0.5)
        img = segment_expected(
            x0=cx - streak[0] / 2, y0=cy - streak[1] / 2, x1=cx + streak[0] / 2,
            y1=cy + streak[1] / 2, sigma_px=sigma, electrons=n_e, box=box,
        )  # fmt: skip
        img = np.minimum(img, sat_e)
        gx, gy, total = streak_centroids(
            img[None], np.array([cx]), np.array([cy]),
            streaks=(np.asarray(streak) * (1 + SYSTEMATIC))[None], radius=radius,
        )[:3]  # fmt: skip
        errs.append(0.5 * ((gx[0] - cx) ** 2 + (gy[0] - cy) ** 2))
        sums.append(total[0])
    return float(np.sqrt(np.mean(errs))), float(np.mean(sums))


@pytest.mark.parametrize("seed", range(16))
def test_rms_over_phases_matches_rendered_streaks(seed):
    rng = np.random.default_rng(seed)
    sigma = rng.uniform(0.5, 1.5)
    length, ang = rng.uniform(6.0, 30.0), rng.uniform(0.0, np.pi)
    streak = length * np.array([np.cos(ang), np.sin(ang)])
    radius = 2.5 * sigma + 1.0
    sat_e = 1000.0
    # from just clipped to far past it: the ridge's peak per electron is about
    # 1 / (length sqrt(2 pi) sigma') with sigma' the pixel-widened PSF
    n_e = sat_e * length * 2.5 * np.sqrt(sigma**2 + 1 / 12) * rng.uniform(1.5, 30.0)
    measured, total = _measured_rms(streak, n_e, sigma=sigma, sat_e=sat_e, radius=radius, rng=rng)
    got = saturated_streak_bias_px(
        streak, [total], sigma_px=sigma, saturation_e=sat_e, radius_px=radius,
        segment_px=length * (1 + SYSTEMATIC),
    )[0]  # fmt: skip
    # 200 random phases give the rms to ~5 % (its sampling error, 1/sqrt(2n)); the model
    # averages a 4 x 4 phase grid and starts the capsule on the truth (the centroider moves
    # it, and stops once it moves less than 0.01 px): within 30 % or 0.01 px
    assert got == pytest.approx(measured, rel=0.30, abs=0.01), (got, measured)


def test_unclipped_and_static_streaks_add_nothing():
    out = saturated_streak_bias_px(
        [10.0, 0.0], [10.0, 100.0], sigma_px=1.0, saturation_e=1e6, radius_px=3.5, segment_px=12
    )
    np.testing.assert_array_equal(out, 0.0)
    assert (
        saturated_streak_bias_px(
            [0.0, 0.0], [1e9], sigma_px=1.0, saturation_e=10.0, radius_px=3.5, segment_px=0.0
        )[0]
        == 0.0
    )
