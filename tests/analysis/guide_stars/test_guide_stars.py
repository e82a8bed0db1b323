"""Guide-star distribution for multi-area attitude determination (Lin et al. 2024)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from starsense.analysis import guide_stars as gs
from starsense.analysis.guide_stars.metrics import chi_cdf
from starsense.attitude.covariance import covariance, fisher_matrix
from starsense.errors import InputError
from starsense.geometry.sampling import random_attitudes
from starsense.references import lin2024
from starsense.units import ARCSEC, DEG

FOV_RAD = lin2024.CAMERA_FOV_DEG * DEG


def test_lin2024_segment_area_057():
    # sec. 2.2: pi (sqrt(2) V / 2)^2 - V^2 = 0.57 V^2 (the paper rounds 0.5708)
    assert gs.attitude_area("four") == pytest.approx(math.pi / 2 - 1, rel=1e-12)
    assert round(gs.attitude_area("four"), 2) == 0.57
    assert gs.attitude_area("one") == pytest.approx(gs.attitude_area("four") / 4)


def test_segment_area_by_sampling():
    xy = np.random.default_rng(0).uniform(-0.75, 0.75, (400_000, 2))
    frac = np.mean(gs.area_index(xy) > 0)
    assert frac * 1.5**2 == pytest.approx(0.5708, abs=0.005)


def test_area_index_points():
    pts = [[0.0, 0.0], [0.6, 0.0], [0.0, 0.6], [-0.6, 0.0], [0.0, -0.6], [0.69, 0.69], [0.6, 0.3]]
    assert gs.area_index(pts).tolist() == [0, 1, 2, 3, 4, 0, 1]


def test_lattice_symmetric_25_per_area():
    _, area = gs.lattice_points()
    assert [int(np.sum(area == k)) for k in (1, 2, 3, 4)] == [25, 25, 25, 25]


@pytest.mark.parametrize("config", list(gs.CONFIGURATIONS))
def test_placements_in_configuration_and_cover_it(config):
    xy = gs.sample_placements(config, n_trials=500, rng=1)
    assert xy.shape == (500, 5, 2)
    assert np.all(gs.in_configuration(xy, config))
    area = gs.area_index(xy)
    for k in gs.CONFIGURATIONS[config]:
        assert np.all((area == k).any(axis=1))
    # five distinct stars per placement
    d = np.linalg.norm(xy[:, :, None] - xy[:, None, :], axis=-1) + np.eye(5)
    assert np.all(d > 1e-9)


def test_triangle_ratio_right_triangle():
    # one triangle of area 1/2 V^2 over 0.5708 V^2
    xy = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    assert gs.triangle_fov_ratio(xy) == pytest.approx(0.5 / (math.pi / 2 - 1))
    assert gs.triangle_fov_ratio(xy, "one") == pytest.approx(0.5 / gs.AREA_OF_SEGMENT)


def test_batch_covariance_matches_limits():
    vec = gs.focal_to_vectors(gs.sample_placements("three", n_trials=4, rng=2), FOV_RAD)
    s = 0.1 * ARCSEC
    for k in range(4):
        ref = covariance(fisher_matrix(vec[k], np.full(5, s**-2)))
        np.testing.assert_allclose(gs.batch_covariance(vec, s)[k], ref, rtol=1e-9)


def test_batched_svd_matches_estimate_attitude():
    vec = gs.focal_to_vectors(gs.sample_placements("two_adjacent", n_trials=20, rng=3), FOV_RAD)
    z = np.random.default_rng(4).standard_normal((20, 5, 2))
    att = random_attitudes(20, 5)
    s = 0.2 * ARCSEC
    fast = gs.monte_carlo_errors(vec, s, noise=z, attitudes=att)
    slow = gs.monte_carlo_errors(vec, s, noise=z, attitudes=att, batched=False)
    np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-11)


def test_probability_within_isotropic_closed_forms():
    s2 = 1.0
    t = 1.3
    iso = np.eye(3) * s2
    # 2 dof: Rayleigh; 3 dof: Maxwell
    assert gs.probability_within(iso, t, "pointing") == pytest.approx(1 - math.exp(-t * t / 2))
    maxwell = math.erf(t / math.sqrt(2)) - math.sqrt(2 / math.pi) * t * math.exp(-t * t / 2)
    assert gs.probability_within(iso, t, "total") == pytest.approx(maxwell, abs=1e-6)


@pytest.mark.parametrize(("config", "sigma"), [("two_symmetric", 0.1), ("one", 0.05)])
def test_mc_agrees_with_analytic_10000(config, sigma):
    tab = gs.simulate_table1([sigma * ARCSEC], [config], n_trials=10_000, rng=7)
    assert abs(tab.probability_mc[config][0] - tab.probability_analytic[config][0]) < 0.03


def test_mc_agrees_with_analytic_total_metric():
    tab = gs.simulate_table1(
        [0.02 * ARCSEC], ["four"], n_trials=4000, fov_rad=8.5 * DEG, metric="total", rng=3
    )
    assert abs(tab.probability_mc["four"][0] - tab.probability_analytic["four"][0]) < 0.03


@pytest.mark.parametrize("sigma", [0.1, 0.2])
def test_lin2024_table1_ordering(sigma):
    # paper, Table 1 (%): sigma 0.2: one 0.44, adj 24.45, sym 46.10, three 39.18, four 98.99;
    # sigma 0.1: one 1.65, adj 54.67, sym 94.21, three 90.94, four 99.87. Four highest, one
    # lowest, the two-area layouts and three between.
    tab = gs.simulate_table1([sigma * ARCSEC], n_trials=5000, rng=11)
    for p in (tab.probability_mc, tab.probability_analytic):
        v = {k: p[k][0] for k in p}
        assert v["one"] < min(v["two_adjacent"], v["two_symmetric"], v["three"])
        assert v["four"] > max(v["two_adjacent"], v["two_symmetric"], v["three"])
        paper = {k: lin2024.TABLE1_PERCENT[k][lin2024.TABLE1_SIGMAS_ARCSEC.index(sigma)] for k in v}
        assert min(paper, key=paper.get) == min(v, key=v.get) == "one"
        assert max(paper, key=paper.get) == max(v, key=v.get) == "four"


def test_reproducible():
    a = gs.simulate_table1([0.1 * ARCSEC], ["three"], n_trials=300, rng=5)
    b = gs.simulate_table1([0.1 * ARCSEC], ["three"], n_trials=300, rng=5)
    assert a.probability_mc["three"][0] == b.probability_mc["three"][0]


@pytest.mark.parametrize("sigma", [0.0, -0.1, float("nan")])
def test_bad_sigma(sigma):
    with pytest.raises(InputError, match="sigma_rad"):
        gs.simulate_table1([sigma * ARCSEC], n_trials=10)
    with pytest.raises(InputError, match="sigma_rad"):
        gs.batch_covariance(np.tile([0.0, 0.0, 1.0], (1, 3, 1)), sigma)


def test_unknown_configuration():
    with pytest.raises(InputError, match="configuration = 'five'"):
        gs.simulate_table1(configurations=["five"], n_trials=10)
    with pytest.raises(InputError, match="not known"):
        gs.sample_placements("diagonal", n_trials=10)


def test_bad_inputs_other():
    with pytest.raises(InputError, match="n_stars"):
        gs.sample_placements("one", n_trials=10, n_stars=2)
    with pytest.raises(InputError, match="cannot cover"):
        gs.sample_placements("four", n_trials=10, n_stars=3)
    with pytest.raises(InputError, match="metric"):
        gs.error_norm(np.zeros(3), "roll")
    with pytest.raises(InputError, match="at least 3 guide stars"):
        gs.triangle_fov_ratio(np.zeros((2, 2)))


def test_edge_units_read_back_as_given():
    # radians inside; the arcsec and deg of the results (JSON, report) are the values given at
    # the edge, not x * ARCSEC / ARCSEC (0.2 would read back as 0.20000000000000004)
    sig = (0.2, 0.123456789, 0.1, 0.05)
    tab = gs.simulate_table1([s * ARCSEC for s in sig], ["four"], n_trials=20, identify=False)
    assert tab.sigma_arcsec == sig
    assert tab.fov_deg == lin2024.CAMERA_FOV_DEG
    assert tab.threshold_arcsec == lin2024.TABLE1_THRESHOLD_ARCSEC
    assert gs.simulate_table1(n_trials=20, identify=False).as_dict()["paper_percent"] is not None


def test_chi_cdf_is_scipy_stats():
    # an independent computation: scipy.stats' chi (3 dof) and Rayleigh (chi, 2 dof) CDFs;
    # agreement to a few ulp of 1 (the closed form and the incomplete gamma are both exact)

    x = np.linspace(0.0, 8.0, 4001)
    np.testing.assert_allclose(chi_cdf(x, 2), stats.rayleigh.cdf(x), rtol=0, atol=1e-15)
    np.testing.assert_allclose(chi_cdf(x, 3), stats.chi(3).cdf(x), rtol=0, atol=1e-15)
