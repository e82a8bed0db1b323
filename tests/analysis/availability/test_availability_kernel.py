"""Availability kernels: counts against brute force, monotonicity, threshold curves, tracks."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from starsense.analysis.availability import (
    AvailabilityAnalysis,
    FieldStars,
    ThresholdCurve,
    sky_attitudes,
    track_family_attitudes,
)
from starsense.geometry.fov import CircularFov, RectangularFov, count_in_fov


def random_sky(n: int, seed: int, mag_range=(0.0, 6.0)):
    """Isotropic random stars with uniform magnitudes."""
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    return v, rng.uniform(*mag_range, n)


FOVS = [
    CircularFov(math.radians(7.5)),
    RectangularFov(math.radians(10.1), math.radians(7.6)),
    CircularFov(math.radians(40.0)),
]


# -- the count kernel against brute force -------------------------------------------------------


@pytest.mark.parametrize("fov", FOVS, ids=["circ7.5", "rect", "circ40"])
def test_field_stars_counts_equal_brute_force(fov):
    vectors, mags = random_sky(3000, seed=1)
    attitudes = Rotation.random(400, rng=np.random.default_rng(2))
    field = FieldStars.build(fov, attitudes, vectors, mags)
    inside = fov.contains(attitudes, vectors)  # (M, N), the exact test on every pair
    for m_t in (1.0, 3.3, 6.0, np.inf):
        brute = (inside & (mags <= m_t)[None, :]).sum(axis=1)
        np.testing.assert_array_equal(field.counts(m_t), brute)
    np.testing.assert_array_equal(field.counts(), count_in_fov(fov, attitudes, vectors))


@pytest.mark.parametrize("fov", FOVS[:2], ids=["circ7.5", "rect"])
def test_kth_magnitude_equals_sorted_brute_force(fov):
    vectors, mags = random_sky(2000, seed=3)
    attitudes = Rotation.random(200, rng=np.random.default_rng(4))
    field = FieldStars.build(fov, attitudes, vectors, mags)
    inside = fov.contains(attitudes, vectors)
    for k in (1, 2, 3, 4, 7):
        expected = np.array(
            [np.sort(mags[row])[k - 1] if row.sum() >= k else np.inf for row in inside]
        )
        np.testing.assert_array_equal(field.kth_magnitude(k), expected)
        # availability is the empirical distribution function of the k-th magnitude
        for m_t in (2.0, 4.5):
            brute = np.mean((inside & (mags <= m_t)[None, :]).sum(axis=1) >= k)
            assert field.availability(m_t, k) == pytest.approx(brute, abs=1e-15)


def test_empty_fields_and_no_pairs():
    vectors = np.array([[0.0, 0.0, 1.0]])
    attitudes = Rotation.from_rotvec([[math.pi / 2, 0, 0], [math.pi, 0, 0]])  # boresight away
    field = FieldStars.build(CircularFov(0.1), attitudes, vectors, [3.0])
    np.testing.assert_array_equal(field.counts(), [0, 0])
    assert field.availability(10.0, 1) == 0.0
    assert np.all(np.isinf(field.kth_magnitude(1)))


# -- monotonicity -------------------------------------------------------------------------------


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    n=st.integers(200, 2000),
    m1=st.floats(0.0, 6.0),
    m2=st.floats(0.0, 6.0),
    half_deg=st.floats(3.0, 20.0),
    grow=st.floats(1.0, 2.0),
)
def test_availability_monotone(seed, n, m1, m2, half_deg, grow):
    vectors, mags = random_sky(n, seed)
    lo, hi = min(m1, m2), max(m1, m2)
    _, attitudes = sky_attitudes(500, roll_rad=None, rng=seed)
    small = FieldStars.build(CircularFov(math.radians(half_deg)), attitudes, vectors, mags)
    large = FieldStars.build(CircularFov(math.radians(half_deg * grow)), attitudes, vectors, mags)
    for k in (1, 2, 3, 4):
        # non-decreasing in m_t
        assert small.availability(lo, k) <= small.availability(hi, k)
        # non-decreasing in field size (the smaller cone is inside the larger one)
        assert small.availability(hi, k) <= large.availability(hi, k)
        # non-increasing in N_min
        assert small.availability(hi, k + 1) <= small.availability(hi, k)
    # a vectorised call equals the scalar calls
    grid = np.linspace(0, 6, 13)
    np.testing.assert_array_equal(
        small.availability(grid, 3), [small.availability(g, 3) for g in grid]
    )


def test_availability_monotone_in_rectangular_field_size():
    vectors, mags = random_sky(3000, seed=5)
    _, attitudes = sky_attitudes(2000, roll_rad=None, rng=5)
    a = FieldStars.build(RectangularFov(0.10, 0.08), attitudes, vectors, mags)
    b = FieldStars.build(RectangularFov(0.14, 0.08), attitudes, vectors, mags)
    c = FieldStars.build(RectangularFov(0.14, 0.12), attitudes, vectors, mags)
    for k in (2, 3, 4):
        for m_t in (2.0, 3.0, 4.0):
            assert a.availability(m_t, k) <= b.availability(m_t, k) <= c.availability(m_t, k)
    assert np.all(a.counts() <= b.counts()) and np.all(b.counts() <= c.counts())


def test_roll_matters_only_for_rectangular_fields():
    vectors, mags = random_sky(3000, seed=6)
    res = {}
    for roll in (0.0, 37.0):
        for fov in (CircularFov(0.13), RectangularFov(0.17, 0.13)):
            an = AvailabilityAnalysis(
                vectors, mags, fov, max_mag=6.0, n_orientations=3000, roll_rad=np.radians(roll)
            )
            res[roll, type(fov).__name__] = an.sky.counts()
    np.testing.assert_array_equal(res[0.0, "CircularFov"], res[37.0, "CircularFov"])
    assert np.any(res[0.0, "RectangularFov"] != res[37.0, "RectangularFov"])


# -- threshold curves -------------------------------------------------------------------------


def test_threshold_curve_interpolates_and_clamps():
    c = ThresholdCurve(np.radians([0.0, 1.0, 2.0]), [6.0, 5.0, 3.0], max_rate_rad_s=np.radians(4.0))
    np.testing.assert_allclose(c(np.radians([0.0, 0.5, 1.5, 2.0, 3.0, 4.0])), [6, 5.5, 4, 3, 3, 3])
    assert c(np.radians([4.5]))[0] == -np.inf
    assert ThresholdCurve.constant(5.75)([0.0, 3.0, 100.0]).tolist() == [5.75] * 3


def test_threshold_curve_from_tolerance_inverts_fig10():
    # magnitude -> tolerable rate (a made-up Fig. 10): 3 -> 4 deg/s, 4 -> 2, 5 -> 1, 6 never
    c = ThresholdCurve.from_tolerance([3.0, 4.0, 5.0, 6.0], [*np.radians([4.0, 2.0, 1.0]), None])
    np.testing.assert_allclose(c(np.radians([1.0, 1.5, 2.0, 3.0, 4.0])), [5.0, 4.5, 4.0, 3.5, 3.0])
    assert c([0.0])[0] == 5.0  # below the faintest detected magnitude's rate: that magnitude
    assert c(np.radians([4.1]))[0] == -np.inf  # faster than the brightest magnitude tolerates
    # a fainter star that "tolerates" more than a brighter one (Monte Carlo noise) is lowered to
    # the brighter one's rate: conservative, as slew.magnitude_threshold
    d = ThresholdCurve.from_tolerance([3.0, 4.0, 5.0], np.radians([1.5, 2.0, 1.0]))
    np.testing.assert_allclose(d(np.radians([1.0, 1.5])), [5.0, 4.0])
    assert d(np.radians([2.0]))[0] == -np.inf
    # capped magnitudes (detected at every simulated rate) hold m_t beyond the grid
    e = ThresholdCurve.from_tolerance(
        [2.0, 4.0],
        np.radians([10.0, 2.0]),
        capped=[True, False],
        grid_max_rate_rad_s=np.radians(10.0),
    )
    np.testing.assert_allclose(e(np.radians([2.0, 6.0, 10.0, 50.0])), [4.0, 3.0, 2.0, 2.0])


def test_threshold_curve_from_slew_result():
    result = SimpleNamespace(
        magnitudes=np.array([2.0, 3.0, 4.0, 5.0, 6.0]),
        rates_rad_s=np.radians(np.linspace(0.0, 10.0, 41)),
        tolerable_rate_rad_s=[*np.radians([10.0, 5.0, 2.5, 1.2]), None],
        capped=np.array([True, False, False, False, False]),
        sensor_name="st16",
        model="reed",
    )
    c = ThresholdCurve.from_slew(result)
    assert c.label == "st16, reed model"
    assert c(np.radians([1.2]))[0] == pytest.approx(5.0)
    assert c(np.radians([2.5]))[0] == pytest.approx(4.0)
    assert c(np.radians([20.0]))[0] == 2.0
    d = ThresholdCurve.from_tolerance_dict(
        {
            "magnitudes": [3, 4],
            "tolerable_rate_deg_s": [2.0, 1.0],
            "capped": [False, False],
            "rates_deg_s": [0, 5],
            "sensor": "x",
            "model": "reed",
        }
    )
    assert d(np.radians([1.5]))[0] == pytest.approx(3.5)


# -- spatial dynamic and along-track ----------------------------------------------------------


def test_dynamic_with_constant_curve_equals_static():
    vectors, mags = random_sky(4000, seed=7)
    an = AvailabilityAnalysis(
        vectors, mags, CircularFov(math.radians(7.5)), max_mag=5.0, n_orientations=4000
    )
    dyn = an.dynamic(ThresholdCurve.constant(4.0), np.radians([0.0, 1.0, 7.0]), n_min=3)
    static = an.static(3, max_mag=4.0)
    np.testing.assert_array_equal(dyn.availability, [static.availability] * 3)
    # the catalogue cut caps the threshold
    dyn = an.dynamic(ThresholdCurve.constant(9.0), np.radians([1.0]), n_min=2)
    assert dyn.threshold_mag[0] == 5.0
    assert dyn.availability[0] == an.static(2).availability


def test_track_family_geometry():
    att = track_family_attitudes(np.radians([-60.0, 0.0, 45.0]), 360, node_rad=np.radians(30.0))
    assert len(att) == 3 * 360
    m = att.as_matrix().reshape(3, 360, 3, 3)
    boresight = m[:, :, 2, :]
    motion = m[:, :, 0, :]  # camera +x along the track
    # boresights are on great circles through the node with max declination |i|
    np.testing.assert_allclose(
        np.degrees(np.arcsin(boresight[..., 2])).max(axis=1), [60.0, 0.0, 45.0], atol=1e-9
    )
    node = [math.cos(math.radians(30)), math.sin(math.radians(30)), 0.0]
    np.testing.assert_allclose(boresight[:, 0, :], [node] * 3, atol=1e-12)
    # +x is the direction of motion: the next sample lies ahead
    step = boresight[:, 1:, :] - boresight[:, :-1, :]
    assert np.all(np.einsum("tkj,tkj->tk", step, motion[:, :-1, :]) > 0)


def test_track_availability_in_unit_interval_and_rate_independent_for_constant_curve():
    vectors, mags = random_sky(3000, seed=8)
    an = AvailabilityAnalysis(
        vectors, mags, CircularFov(math.radians(7.5)), max_mag=6.0, n_orientations=2000
    )
    curve = ThresholdCurve(np.radians([0.0, 2.0]), [5.0, 2.0])
    incl = np.arange(-90.0, 90.1, 15.0)
    for rate in (0.0, 1.0, 3.0):
        tr = an.track(
            curve, np.radians(rate), n_min=3, inclinations=np.radians(incl), n_samples=200
        )
        assert tr.availability.shape == (13,)
        assert np.all((tr.availability >= 0) & (tr.availability <= 1))
        assert tr.min <= tr.mean <= tr.max
        # per track: fraction of the samples seeing >= 3 stars <= m_t, counted by brute force
        att = track_family_attitudes(np.radians(incl), 200)
        keep = mags <= tr.threshold_mag
        counts = count_in_fov(an.fov, att, vectors[keep]).reshape(13, 200)
        np.testing.assert_allclose(tr.availability, (counts >= 3).mean(axis=1))
    flat = ThresholdCurve.constant(3.0)
    a = an.track(flat, np.radians(0.5), inclinations=np.radians(incl), n_samples=200).availability
    b = an.track(flat, np.radians(3.0), inclinations=np.radians(incl), n_samples=200).availability
    np.testing.assert_array_equal(a, b)


def test_track_mean_approaches_spatial_for_constant_threshold():
    """With m_t independent of rate, averaging along great circles samples the same sky.

    On an isotropic sky every direction has the same expected availability, so the mean over
    the track family estimates the spatial value. It is not the same estimator: all tracks of
    one family cross at their two nodes, so the two fields at the nodes carry ~8 % of the
    samples (2 x 2 x 7.5 deg of every 360 deg track) against 0.9 % of the sky, and the track
    mean moves with whether those fields happen to be rich or poor. Over seeds 0-5 of this sky
    (availability ~0.6) the single-family difference reached 0.037, hence 0.05; averaging 12
    families with nodes spread along the equator shares that weight out, and the difference
    stayed below 0.01, hence 0.02. (The real sky is not isotropic: there the node's place with
    respect to the galactic plane moves the mean by several percent, as in the paper's
    Table 2.)
    """
    vectors, mags = random_sky(4000, seed=0)
    an = AvailabilityAnalysis(
        vectors, mags, CircularFov(math.radians(7.5)), max_mag=6.0, n_orientations=10_000
    )
    curve = ThresholdCurve.constant(1.1)  # ~3 stars per field: availability ~0.6
    spatial = an.static(3, max_mag=1.1).availability
    assert 0.4 < spatial < 0.8
    one = an.track(
        curve,
        np.radians(1.0),
        n_min=3,
        inclinations=np.radians(np.arange(-90, 91, 2.0)),
        n_samples=500,
    )
    assert one.spatial[3] == spatial
    assert one.mean == pytest.approx(spatial, abs=0.05)
    means = [
        an.track(
            curve,
            np.radians(1.0),
            n_min=3,
            inclinations=np.radians(np.arange(-90, 91, 10.0)),
            n_samples=500,
            node_rad=np.radians(node),
        ).mean
        for node in np.arange(0.0, 180.0, 15.0)
    ]
    assert np.mean(means) == pytest.approx(spatial, abs=0.02)
