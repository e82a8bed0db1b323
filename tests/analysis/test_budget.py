"""The error budget: per-star errors propagated as errors (not weights), detector
non-uniformity and the calibration residual rendered into the frames and in the budget, and the
Monte Carlo's rms moving as the budget says."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from starsense.analysis.datasheet import datasheet
from starsense.analysis.datasheet.field import (
    FieldStarsCam,
    axis_sigmas,
    fisher_per_pointing,
    propagated_sigmas,
)
from starsense.analysis.datasheet.terms import prnu_centroid_px
from starsense.render import scene
from starsense.sensor import load_sensor


def _pairs(n: int, seed: int = 0) -> FieldStarsCam:
    rng = np.random.default_rng(seed)
    v = np.column_stack([rng.uniform(-0.1, 0.1, (n, 2)), np.ones(n)])
    v /= np.linalg.norm(v, axis=1)[:, None]
    return FieldStarsCam(np.zeros(n, int), np.arange(n), v, n_pointings=1)


def test_equal_errors_propagate_like_noise():
    # equal weights and equal errors e: the sandwich F^-1 (w^2 e^2 F / w) F^-1 = e^2 F^-1 / ...
    # reduces to the Fisher bound of stars of sigma e (an invariant of least squares)
    pairs = _pairs(30)
    e = np.full(30, 2e-5)
    c, r = propagated_sigmas(pairs, np.full(30, 7.0), e)
    c0, r0 = axis_sigmas(fisher_per_pointing(pairs, 1.0 / e**2))
    np.testing.assert_allclose([c[0], r[0]], [c0[0], r0[0]], rtol=1e-9)


def test_small_errors_do_not_hide_large_ones():
    # one star in thirty without bias: as weights (1/bias^2) it would dominate and the row
    # collapse to ~0; as an error its value stays near the others' propagated error
    pairs = _pairs(30)
    e = np.full(30, 2e-5)
    e[0] = 2e-7
    c, _ = propagated_sigmas(pairs, np.ones(30), e)
    c_all, _ = propagated_sigmas(pairs, np.ones(30), np.full(30, 2e-5))
    assert c[0] > 0.9 * c_all[0]
    c_w, _ = axis_sigmas(fisher_per_pointing(pairs, 1.0 / e**2))
    assert c_w[0] < 0.5 * c_all[0]  # what the weights did: the unbiased star hides the rest


def test_prnu_lever_of_a_gaussian():
    # a centre-of-mass centroid moves by p / sqrt(8 pi) px for a well-sampled Gaussian (the
    # integral of g^2 x^2 over the plane; terms module); 1 % PRNU: 0.00199 px
    st16 = load_sensor("st16")
    s = st16.with_(detector=dataclasses.replace(st16.detector, prnu_fraction=0.01))
    assert prnu_centroid_px(s) == pytest.approx(0.01 / math.sqrt(8 * math.pi), rel=0.01)
    assert prnu_centroid_px(st16) == 0.0


def _total(sheet) -> float:
    row = sheet.budget[-1]
    assert row.term.startswith("total")
    return row.cross_arcsec


@pytest.mark.slow
def test_budget_moves_the_monte_carlo_as_it_says(monkeypatch):
    # the two runs are paired (the same attitudes and the same noise draws), which needs the
    # same read-out in both: the fast read-out does not model PRNU, so both use apply_noise
    monkeypatch.setattr(scene, "fast_read_out", lambda *args, **kwargs: None)
    base = load_sensor("st16")
    worse = base.with_(
        detector=dataclasses.replace(base.detector, prnu_fraction=0.01),
        optics=dataclasses.replace(base.optics, distortion_residual_px=0.1),
    )
    kw = {"n_trials": 80, "n_orientations": 300, "rng": 4, "n_rate_trials": 1}
    s0, s1 = datasheet(base, **kw), datasheet(worse, **kw)
    terms = {r.term.split(" (")[0]: r for r in s1.budget}
    assert "detector non-uniformity: PRNU 1 %" in terms
    assert "field-of-view spatial error" in terms
    assert terms["field-of-view spatial error"].cross_arcsec > 0.5 * _total(s0)
    assert "detector non-uniformity" in s1.budget[-1].source  # in the total
    # the same attitudes in both runs: the measured error grows as the prediction at those
    # attitudes (temporal noise, bias and the two rendered terms) grows. The scale is the
    # median normalised error (robust ratio): one frame in 80 can hold a > 5 sigma outlier
    # that dominates an rms; 80 frames know the median to ~10 %, each run
    mc0, mc1 = s0.monte_carlo, s1.monte_carlo
    assert mc1.cross_predicted_arcsec > 2.0 * mc0.cross_predicted_arcsec  # the terms matter
    assert mc1.cross_ratio_robust / mc0.cross_ratio_robust == pytest.approx(1.0, rel=0.25)
    assert mc1.roll_ratio_robust / mc0.roll_ratio_robust == pytest.approx(1.0, rel=0.25)
    assert _total(s1) > 2.0 * _total(s0)  # and the sky's budget says so too
    assert mc1.wrong == 0


def test_field_dependent_psf_widens_the_corner_stars_noise():
    from starsense.analysis.datasheet.predict import StarModel

    base = load_sensor("st16")
    wide = base.with_(optics=dataclasses.replace(base.optics, psf_sigma_corner_px=3.0))
    m0 = StarModel.build(base, model="reed", bright_mag=4.0, faint_mag=5.5)
    m1 = StarModel.build(wide, model="reed", bright_mag=4.0, faint_mag=5.5)
    mags = np.array([5.0, 5.0])
    # z of a star at the centre and in the corner (tan^2 = corner^2 / f^2)
    det = base.detector
    corner = math.hypot(0.5 * (det.columns - 1), 0.5 * (det.rows - 1)) / base.focal_length_px
    z = np.array([1.0, 1.0 / math.sqrt(1.0 + corner**2)])
    s0, s1 = m0.star_sigmas_rad(mags, z), m1.star_sigmas_rad(mags, z)
    assert s1[0] == pytest.approx(s0[0])  # the centre keeps the detector's PSF
    # a 3 px PSF spreads a star's light over 4x the pixels of a 1.5 px one: its read-noise
    # share of the centroid noise grows; the corner star is noisier than with the static PSF
    assert s1[1] > 1.2 * s0[1]
