"""Monte Carlo of the whole tracker."""

from __future__ import annotations

import numpy as np
import pytest

from starsense.analysis.montecarlo import run_montecarlo
from starsense.errors import InputError
from starsense.scale import dask_client
from starsense.sensor import load_sensor


@pytest.fixture(scope="module")
def st16_static():
    # 24 random attitudes, static, all Hipparcos stars rendered: ~4 s
    return run_montecarlo(load_sensor("st16"), n_trials=24, rng=3)


def test_st16_static_solves_every_frame_and_never_wrongly(st16_static):
    # the ST-16 sees >= 3 stars at m_t 5.5 in ~99.9 % of the sky (availability section), so
    # 24 random attitudes all solve with overwhelming probability; none may be wrong
    assert st16_static.wrong_rate == 0.0
    assert st16_static.solve_rate == 1.0


def test_errors_agree_with_predicted_covariance(st16_static):
    # The predicted sigma counts photon and read noise of each centroid. Over 24 frames the rms of
    # the actual errors has a relative spread of ~1/sqrt(2 x 24) = 15 % per axis; measured
    # actual/predicted ratios are 0.9-1.0 across the boresight and ~0.75 in roll (the prediction
    # is conservative there). Bounds 0.5-1.5 allow 3 sigma plus that known bias.
    ratio = st16_static.rms_error_arcsec / st16_static.rms_predicted_arcsec
    assert np.all((ratio > 0.5) & (ratio < 1.5)), ratio
    # roll, about the boresight, is the weak axis (lever arm ~ half the field)
    assert st16_static.rms_error_arcsec[2] > 3 * st16_static.rms_error_arcsec[:2].max()


def test_reproducible():
    a = run_montecarlo(load_sensor("st16"), n_trials=2, rng=11, max_mag=6.0)
    b = run_montecarlo(load_sensor("st16"), n_trials=2, rng=11, max_mag=6.0)
    assert np.array_equal(a.errors_arcsec, b.errors_arcsec)


def test_bad_input():
    with pytest.raises(InputError, match="n_trials must be >= 1, got 0"):
        run_montecarlo(load_sensor("st16"), n_trials=0)
    with pytest.raises(InputError, match="rate_rad_s must be >= 0"):
        run_montecarlo(load_sensor("st16"), n_trials=1, rate_rad_s=np.radians(-1))


def test_dask_run_identical_to_in_process():
    # trial k draws from the k-th child seed wherever it runs: the same frames, the same answers
    pytest.importorskip("distributed")

    sensor = load_sensor("st16")
    local = run_montecarlo(sensor, n_trials=4, rng=21, max_mag=6.0)
    with dask_client("local:2", processes=False) as client:
        remote = run_montecarlo(sensor, n_trials=4, rng=21, max_mag=6.0, client=client)
    assert np.array_equal(local.errors_rad, remote.errors_rad)
    assert np.array_equal(local.truth_quat, remote.truth_quat)
    assert local.statuses == remote.statuses


@pytest.mark.slow
def test_fast_read_out_keeps_the_measured_errors():
    """The datasheet's measured / predicted ratios with either read-out: the same frames (same
    attitudes, so the same prediction), other noise draws; the mean squared error per axis
    (the ratio squared, times the prediction) must agree within 4 standard errors of the paired
    difference, the Monte Carlo noise of 400 frames (~10% in the ratio)."""
    sensor = load_sensor("st16")
    fast = run_montecarlo(sensor, n_trials=400, rng=5)
    exact = run_montecarlo(sensor, n_trials=400, rng=5, fast_noise=False)
    assert fast.n_wrong == exact.n_wrong == 0
    assert fast.n_solved == exact.n_solved == 400
    np.testing.assert_array_equal(fast.truth_quat, exact.truth_quat)  # the same attitudes
    for sq in (
        lambda e: 0.5 * (e[:, 0] ** 2 + e[:, 1] ** 2),  # cross-boresight, per axis
        lambda e: e[:, 2] ** 2,  # roll
    ):
        d = sq(fast.errors_rad) - sq(exact.errors_rad)
        assert abs(d.mean()) < 4 * d.std(ddof=1) / np.sqrt(len(d))
    # the stars each frame shows: detection unchanged in the mean
    m = fast.n_matched - exact.n_matched
    assert abs(m.mean()) < 4 * max(m.std(ddof=1), 0.5) / np.sqrt(len(m))


def test_rendered_sky_is_at_the_epoch_of_the_solvers_catalogue():
    # A narrow field is identified on Gaia DR3 (epoch 2016.0) while the frames are rendered from
    # Hipparcos (epoch 1991.25). Against Gaia as the independent reference, Hipparcos carried
    # to 2016.0 agrees to a median 0.03 arcsec (its proper motions' ~1 mas/yr errors over 25
    # years); left at 1991.25 the median is 0.46 arcsec, which alone would exceed the NEA of a
    # long-focus design. Bounds: 0.06 and 0.3 arcsec, a factor 2 from each measured median.
    from scipy.spatial import cKDTree

    from starsense.analysis.inputs import at_epoch
    from starsense.catalog import load_catalog
    from starsense.identify.fields import deep_catalog_available

    if not deep_catalog_available():
        pytest.skip("the bundled Gaia catalogue is not installed")
    hip, gaia = load_catalog("hipparcos"), load_catalog("gaia")
    bright = hip.brighter_than("V", 8.0)
    tree = cKDTree(gaia.vectors)
    arcsec = np.pi / 180 / 3600

    def median_miss(cat):
        d, _ = tree.query(cat.vectors, distance_upper_bound=3 * arcsec)
        return float(np.median(d[np.isfinite(d)])) / arcsec

    moved = at_epoch(bright, gaia.epoch_yr)
    assert moved.epoch_yr == gaia.epoch_yr
    assert median_miss(moved) < 0.06
    assert median_miss(bright) > 0.3
    assert at_epoch(moved, gaia.epoch_yr) is moved
