"""The compiled tracking kernel (``starsense.identify._trackc``) against the NumPy form.

Pairing must be equal bit for bit (the same squared chords summed in the same order, the same
comparisons). The attitude fit solves the same problem by another algorithm (Davenport's K
matrix and Jacobi rotations instead of LAPACK's SVD; TRIAD instead of scipy's align_vectors):
both are backward stable, so the attitude matrices agree to a few hundred ulp of their unit
entries, 1e-12 here (the test's random pairs are well conditioned: the smallest singular value
of B is bounded away from 0, so no error amplification beyond ~1e2 applies), and the residual
angles to 1e-12 rad. The covariance sandwich sums the same products in another order: 1e-12
relative to its largest entry. End to end, tracking with and without the kernel must give the
same statuses, modes, matches, and attitudes and covariances to those tolerances.
"""

from __future__ import annotations

import math
import shutil

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from starsense.attitude.covariance import SINGULAR_RCOND, fisher_covariance
from starsense.attitude.svd import wahba_matrix
from starsense.catalog import load_catalog
from starsense.errors import SingularGeometryError
from starsense.geometry.attitude import small_rotation_angles
from starsense.identify import track_kernels as tk
from starsense.identify.tracking import TrackingIdentifier
from starsense.render.scene import render_frame
from starsense.sensor import load_sensor
from starsense.solve.solver import Solver
from starsense.solve.tracking import Prior, track_frame

needs_kernel = pytest.mark.skipif(not tk.COMPILED, reason="compiled kernel not built")

DEG = math.pi / 180


def test_the_kernel_is_built_where_a_compiler_exists():
    # setup.py builds it as an optional extension: a machine with a C compiler that ends up
    # without it runs the NumPy form silently, which this makes visible
    if shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler on this machine: the NumPy form is the one in use")
    assert tk.COMPILED


def _units(rng, n):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1)[:, None]


@needs_kernel
@settings(max_examples=300, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(0, 40),
    m=st.integers(0, 40),
    near=st.floats(1e-6, 1e-2),
    radius=st.floats(1e-5, 0.3),
    ratio=st.floats(1.01, 5.0),
)
def test_pair_equals_numpy_bit_for_bit(seed, n, m, near, radius, ratio):
    rng = np.random.default_rng(seed)
    v = _units(rng, n)
    cam = _units(rng, m)
    k = min(n, m)
    # some predicted stars close to detections, some twins (ambiguous), some repeated
    cam[:k] = v[:k] + near * rng.normal(size=(k, 3))
    if m > 2:
        cam[-1] = cam[0] + near * rng.normal(size=3)
        cam[-2] = cam[1]
    bound2 = (2 * math.sin(radius / 2)) ** 2
    a = tk.pair_numpy(v, cam, bound2=bound2, ratio=ratio)
    b = tk.pair_compiled(v, cam, bound2=bound2, ratio=ratio)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1]) and a[2] == b[2]
    assert b[0].dtype == b[1].dtype == np.int64


def _pairs(seed, n, noise):
    rng = np.random.default_rng(seed)
    truth = Rotation.random(random_state=rng).as_matrix()
    ref = _units(rng, n)
    body = ref @ truth.T + noise * rng.normal(size=(n, 3))
    body /= np.linalg.norm(body, axis=1)[:, None]
    return rng, body, ref


@needs_kernel
@settings(max_examples=300, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 40), noise=st.floats(0.0, 1e-2))
def test_weighted_fit_equals_svd(seed, n, noise):
    rng, body, ref = _pairs(seed, n, noise)
    w = rng.uniform(0.05, 20.0, n)
    c1, r1, h1 = wahba_matrix(body, ref, w)
    c2, r2, h2 = tk.fit_compiled(body, ref, w, two_exact=False)
    # the two round differently, and the fitted rotation is known to the float epsilon times
    # the attitude profile matrix's sigma_1 / sigma_2 (two stars a few degrees apart with
    # weights 100 apart: 7,500, so 1.7e-12): 4 of that, and never tighter than 1e-12
    sv = np.linalg.svd(np.einsum("i,ij,ik->jk", w, body, ref), compute_uv=False)
    tol = max(1e-12, 4.0 * np.finfo(float).eps * sv[0] / sv[1])
    np.testing.assert_allclose(c2, c1, rtol=0, atol=tol)
    np.testing.assert_allclose(c2 @ c2.T, np.eye(3), rtol=0, atol=1e-14)  # a rotation
    assert np.linalg.det(c2) > 0
    np.testing.assert_allclose(r2, r1, rtol=0, atol=tol)
    np.testing.assert_allclose(h2, h1, rtol=0, atol=tol)


@needs_kernel
@settings(max_examples=300, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 40), noise=st.floats(0.0, 1e-2))
def test_equal_weight_fit_equals_estimate_matrix(seed, n, noise):
    # two pairs: the first aligned exactly (align_vectors with an infinite primary weight)
    _, body, ref = _pairs(seed, n, noise)
    c1, r1, _ = wahba_matrix(body, ref, two_exact=True)
    c2, r2, _ = tk.fit_compiled(body, ref, np.ones(n), two_exact=True)
    np.testing.assert_allclose(c2, c1, rtol=0, atol=1e-12)
    np.testing.assert_allclose(r2, r1, rtol=0, atol=1e-12)


@needs_kernel
@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 40))
def test_sandwich_equals_numpy(seed, n):
    rng = np.random.default_rng(seed)
    body = _units(rng, n)
    g = rng.normal(size=(n, 3, 2)) * 1e-4
    a = rng.normal(size=(n, 2, 2))
    cov = a @ a.transpose(0, 2, 1) + 0.01 * np.eye(2)  # positive definite
    w = rng.uniform(1e8, 1e10, n)
    inv = np.linalg.inv(np.einsum("i,ijk->jk", w, np.eye(3) - body[:, :, None] * body[:, None]))
    p1 = tk.sandwich_numpy(body, g, cov, w=w, inv=inv)
    p2 = tk.sandwich_compiled(body, g, cov, w=w, inv=inv)
    # summed in another order: each entry differs by at most a few hundred ulp of the sum of
    # the absolute values of its terms (the forward error bound of a sum of products)
    a = np.abs
    skew = np.zeros((n, 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = body[:, 2], body[:, 1], body[:, 0]
    skew += skew.transpose(0, 2, 1)
    noise = a(g) @ a(cov) @ a(g).transpose(0, 2, 1)
    terms = a(inv) @ np.einsum("i,iaj,iab,ibk->jk", w**2, a(skew), noise, a(skew)) @ a(inv)
    assert np.all(np.abs(p2 - p1) <= 1e-13 * terms)


@needs_kernel
@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(0, 40), m=st.integers(0, 12))
def test_unblended_equals_numpy_bit_for_bit(seed, n, m):
    # crowded predicted fields (neighbours at and around the blend distance), some stars behind
    # the camera (NaN), matched stars drawn from the finite ones
    rng = np.random.default_rng(seed)
    near = np.sort(rng.choice(10 * n + 1, size=n, replace=False))
    x, y = rng.uniform(0, 60, n), rng.uniform(0, 60, n)
    x[: n // 3] = np.round(x[: n // 3])  # whole pixels: distances exactly at the blend distance
    y[: n // 3] = np.round(y[: n // 3])
    x[rng.random(n) < 0.1] = np.nan
    finite = near[np.isfinite(x)]
    cat = rng.choice(finite, size=min(m, len(finite)), replace=False) if len(finite) else near[:0]
    blend = float(rng.choice([3.0, 5.0, rng.uniform(1, 10)]))
    got = tk.unblended_compiled(cat, near, x=x, y=y, blend_px=blend)
    ref = tk.unblended_numpy(cat, near, x=x, y=y, blend_px=blend)
    assert got.dtype == bool and np.array_equal(got, ref)
    # and against the distances themselves, star by star
    ok = np.isfinite(x)
    for c, alone in zip(cat, got, strict=True):
        i = int(np.flatnonzero(near == c)[0])
        d = np.hypot(x[ok] - x[i], y[ok] - y[i])
        others = d[near[ok] != c]
        assert alone == (len(others) == 0 or bool(others.min() > blend))


@pytest.fixture(scope="module")
def st16():
    return load_sensor("st16")


@needs_kernel
@pytest.mark.parametrize("seed", range(6))
def test_tracking_with_and_without_the_kernel_agree(st16, seed, monkeypatch):
    """Seeded ST-16 frames at rest and slewing, priors near and far: the same answers."""
    cat = load_catalog("hipparcos")
    rng = np.random.default_rng(seed)
    att = Rotation.random(random_state=rng)
    d = rng.normal(size=3)
    d[2] *= 0.2
    rate = (0.0, 0.5, 1.0)[seed % 3] * DEG * d / np.linalg.norm(d)
    image = render_frame(st16, att, cat, rate_rad_s=rate, max_mag=6.5, rng=seed).image
    # a close prior (tracking), and one 0.3 deg off claiming 0.01 deg (tracking fails)
    off = Rotation.from_rotvec(0.3 * DEG * _units(rng, 1)[0]) * att
    priors = [
        Prior(att, np.eye(3) * (0.01 * DEG) ** 2, rate, np.eye(3) * (0.005 * DEG) ** 2),
        Prior(off, np.eye(3) * (0.01 * DEG) ** 2, rate, np.eye(3) * (0.005 * DEG) ** 2),
    ]
    runs = []
    for kernel in (True, False):
        if not kernel:
            monkeypatch.setattr(tk, "_trackc", None)
        solver = Solver(st16, background="known", centroid_sigma_px="snr")
        runs.append([track_frame(solver, image, p) for p in priors])
    for a, b in zip(*runs, strict=True):
        assert (a.mode, a.status) == (b.mode, b.status)
        assert a.solution.matches == b.solution.matches
        assert a.has_attitude == b.has_attitude
        if a.has_attitude:
            e = small_rotation_angles(a.solution.rotation, b.solution.rotation)
            assert np.abs(e).max() < 1e-12
        if a.covariance_rad2 is not None:
            np.testing.assert_allclose(
                a.covariance_rad2,
                b.covariance_rad2,
                rtol=0,
                atol=1e-12 * np.abs(b.covariance_rad2).max(),
            )
    assert runs[0][0].mode == "tracking"


@pytest.fixture(scope="module")
def st16_db(st16):
    return Solver(st16, background="known").identifier(2 * st16.half_fov_rad[0]).database


@needs_kernel
@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n_stars=st.integers(0, 25),
    n_spurious=st.integers(0, 6),
    noise_px=st.floats(0.0, 3.0),
    prior_deg=st.floats(0.0, 0.5),
    search_deg=st.floats(0.005, 1.0),
)
def test_identifier_with_and_without_the_kernel_agree(
    st16, st16_db, seed, n_stars, n_spurious, noise_px, prior_deg, search_deg
):
    """Detections from database stars (centroid noise, spurious ones), priors near and far."""
    db, f = st16_db, st16.focal_length_px
    rng = np.random.default_rng(seed)
    att = Rotation.random(random_state=rng)
    centre = att.inv().apply([0, 0, 1])
    near = np.sort(db.tree.query_ball_point(centre, 2 * math.sin(8 * DEG)))
    pick = rng.permutation(near)[:n_stars]
    body = att.apply(db.vectors[pick]) if len(pick) else np.zeros((0, 3))
    body = np.vstack([body, _units(rng, n_spurious) * [0.1, 0.1, 1]]) + rng.normal(
        scale=noise_px / f, size=(len(pick) + n_spurious, 3)
    )
    body[:, 2] = np.abs(body[:, 2]) + 0.5
    body /= np.linalg.norm(body, axis=1)[:, None]
    prior = Rotation.from_rotvec(prior_deg * DEG * _units(rng, 1)[0]) * att
    ident = TrackingIdentifier(st16_db, min_match_radius_rad=2.0 / f)
    kw = {"search_radius_rad": search_deg * DEG, "field_radius_rad": 0.2}
    if len(body) == 0:
        return
    a = ident(body, prior, **kw)
    saved = tk._trackc
    try:
        tk._trackc = None
        b = ident(body, prior, **kw)
    finally:
        tk._trackc = saved
    assert (a.status, a.n_ambiguous) == (b.status, b.n_ambiguous)
    assert np.array_equal(a.detection_index, b.detection_index)
    assert np.array_equal(a.catalog_index, b.catalog_index)
    assert (a.rotation is None) == (b.rotation is None)
    if a.rotation is not None:
        assert (a.rotation * b.rotation.inv()).magnitude() < 1e-12
    if a.n_matches >= 2:
        np.testing.assert_allclose(a.residual_rms_rad, b.residual_rms_rad, rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(
            a.false_match_probability, b.false_match_probability, rtol=1e-9, atol=1e-300
        )
        np.testing.assert_allclose(a.innovation_rad, b.innovation_rad, rtol=0, atol=1e-12)


@needs_kernel
@settings(max_examples=300, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 40),
    spread=st.floats(1e-4, 1.0),
    degenerate=st.sampled_from(["none", "one", "antipodal"]),
)
def test_fisher_inverse_equals_fisher_covariance(seed, n, spread, degenerate):
    # the stars of a field of `spread` rad; degenerate sets: one direction, or its antipode
    rng = np.random.default_rng(seed)
    body = np.column_stack([spread * rng.normal(size=(n, 2)), np.ones(n)])
    body /= np.linalg.norm(body, axis=1)[:, None]
    if degenerate == "one":
        body[:] = body[0]
    elif degenerate == "antipodal":
        body[1::2] = -body[0]
        body[::2] = body[0]
    sigma = rng.uniform(1e-6, 1e-4, n)
    got = tk.fisher_inverse_compiled(body, sigma, rcond=SINGULAR_RCOND)
    try:
        ref = fisher_covariance(body, sigma)
    except SingularGeometryError:
        assert got is False
        return
    assert got is not False
    # the inverse of a matrix of condition number k is known to k x rounding: 1e-16 k
    k = np.linalg.cond(np.linalg.inv(ref))
    np.testing.assert_allclose(got, ref, rtol=0, atol=max(1e-12, 1e-15 * k) * np.abs(ref).max())


@needs_kernel
@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 300), noise=st.floats(0.0, 1e-2))
def test_one_call_fit_is_the_fit_and_the_fisher_inverse(seed, n, noise):
    # weighted_fit: fit_compiled with weights sigma^-2 and fisher_inverse_compiled of the same
    # stars in one call (the same C cores; past 256 stars its weights are allocated)
    rng, body, ref = _pairs(seed, n, noise)
    sigma = rng.uniform(1e-6, 1e-4, n)
    c, resid, chord2, cov, loss = tk.weighted_fit_compiled(body, ref, sigma, rcond=SINGULAR_RCOND)
    c1, r1, h1 = tk.fit_compiled(body, ref, sigma**-2.0, two_exact=False)
    cov1 = tk.fisher_inverse_compiled(body, sigma, rcond=SINGULAR_RCOND)
    # the weights from C's pow against NumPy's power: equal or one ulp apart, which the
    # eigenvector carries at most to its conditioning (test_weighted_fit_equals_svd's bound)
    w = sigma**-2.0
    sv = np.linalg.svd(np.einsum("i,ij,ik->jk", w, body, ref), compute_uv=False)
    tol = max(1e-12, 4.0 * np.finfo(float).eps * sv[0] / sv[1])
    np.testing.assert_allclose(c, c1, rtol=0, atol=tol)
    np.testing.assert_allclose(resid, r1, rtol=0, atol=tol)
    np.testing.assert_allclose(chord2, h1, rtol=0, atol=tol)
    if cov1 is False:
        assert cov is False
    else:
        np.testing.assert_array_equal(cov, cov1)  # the same function of the same numbers
    # the loss: 1/2 sum chord2 w, summed in order here and by NumPy's dot there
    assert loss == pytest.approx(0.5 * float(chord2 @ w), rel=1e-12, abs=1e-300)
