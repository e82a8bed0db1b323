"""The compiled hashing kernel (``starsense.identify._hashc``) against the NumPy form.

Both a known field and an unknown one (the scale of the tangent plane fitted) are compared. The
pattern descriptors and the hash look-up are the same operations in the same order: equal
bit for bit (the ratios to 4 ulp: NumPy may take ``arcsin`` from its own vectorised routine,
the kernel from the C library). The verification fits the attitude by Davenport's q method
where the NumPy form takes the SVD; both are exact to rounding, so a solve matches the same
detections to the same stars after the same number of patterns and hypotheses, with rotations
equal to 1e-11 rad (measured: < 1e-13 rad). The residuals of true pairs are differences of unit
vectors ~1e-4 rad long, so a 1e-13 rad change of the attitude changes them by ~1e-9
relatively; the false-match probability, a binomial tail whose exponent is the ~15 extra
matches, follows them with ~20x that: 1e-6 relative bounds both with a margin.
"""

from __future__ import annotations

import math
import shutil

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from identify_helpers import SYNTH_FOV_RAD

from starsense.errors import InputError
from starsense.identify import HashIdentifier, build_database
from starsense.identify import hash_kernels as hk
from starsense.identify.centroid_sets import centroid_sets
from starsense.identify.patterns import breadth_first_combinations
from starsense.identify.result import validate_vectors
from starsense.solve.pinhole import pinhole_vectors

needs_kernel = pytest.mark.skipif(not hk.KERNEL_BUILT, reason="compiled kernel not built")
SIZE = (960, 1280)
#: relative agreement of residuals and false-match probabilities (module docstring)
REL = 1e-6
#: rotations agree to this, rad (module docstring)
ROT_RAD = 1e-11
#: the module-scoped identifiers are not reset between examples, and need not be
FIXTURE = HealthCheck.function_scoped_fixture


def test_the_kernel_is_built_where_a_compiler_exists():
    # setup.py builds it as an optional extension: a machine with a C compiler that ends up
    # without it runs the NumPy form silently, which this makes visible
    if shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler on this machine: the NumPy form is the one in use")
    assert hk.KERNEL_BUILT


@pytest.fixture(scope="module")
def pair(db15):
    """The same identifier twice: compiled, and the NumPy form."""
    compiled = HashIdentifier(db15)
    if hk.KERNEL_BUILT:
        assert compiled.compiled
    return compiled, HashIdentifier(db15, compiled=False)


def _frame_vectors(rng, n: int, spread: float, duplicate: bool) -> np.ndarray:
    v = np.column_stack([rng.normal(0, spread, (n, 2)), np.ones(n)])
    if duplicate and n > 4:
        v[int(rng.integers(1, n))] = v[0]  # a star listed twice: patterns without a shape
    return v / np.linalg.norm(v, axis=1)[:, None]


@needs_kernel
@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(4, 16),
    spread=st.sampled_from([1e-3, 0.05, 0.3]),
    duplicate=st.booleans(),
)
def test_descriptors_equal_the_numpy_form(seed, n, spread, duplicate):
    rng = np.random.default_rng(seed)
    v = _frame_vectors(rng, n, spread, duplicate)
    n_pat = min(n, 12)
    combos = breadth_first_combinations(12, 4)
    combos = combos[(combos < n_pat).all(axis=1)]
    ref = list(hk.descriptors_numpy(v, combos))
    det, ratios, largest = hk.descriptors_compiled(v, n_pat)
    assert len(det) == len(ref)
    if not ref:
        return
    np.testing.assert_array_equal(det, np.array([r[0] for r in ref]))
    # 4 ulp: arcsin may come from NumPy's vectorised routine (module docstring)
    np.testing.assert_array_max_ulp(ratios, np.array([r[1] for r in ref]), maxulp=4)
    np.testing.assert_array_max_ulp(largest, np.array([r[2] for r in ref]), maxulp=4)


@needs_kernel
@settings(
    max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    index=st.integers(0, 10**9),
    shift=st.lists(st.floats(-0.008, 0.008), min_size=5, max_size=5),
)
def test_lookup_equals_the_numpy_form(pair, index, shift):
    compiled, reference = pair
    db = reference.database
    # the ratios of a database pattern, moved by up to 1.6 x the pattern error: hits, near
    # misses and bin edges
    ratios = np.clip(db.pattern_ratios[index % len(db.patterns)] + np.asarray(shift), 0, 1)
    np.testing.assert_array_equal(
        compiled._kernel.lookup(ratios), reference._lookup(ratios.astype(np.float64))
    )


@needs_kernel
@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 40),
    log_scale=st.floats(-6, 6),
    bad=st.sampled_from(["none", "nan", "inf", "zero", "behind", "edge"]),
)
def test_unit_vectors_equal_validate_vectors(seed, n, log_scale, bad):
    rng = np.random.default_rng(seed)
    v = rng.normal(0, 0.2, (n, 3)) * 10.0**log_scale
    v[:, 2] = np.abs(v[:, 2]) + 10.0**log_scale
    row = int(rng.integers(n))
    if bad != "none":
        v[row] = {
            "nan": [0.0, np.nan, 1.0],
            "inf": [np.inf, 0.0, 1.0],
            "zero": [0.0, 0.0, 0.0],
            "behind": [0.1, 0.0, -1.0],
            "edge": [1.0, 0.0, 0.0],  # z = 0: behind the camera for validate_vectors
        }[bad]
    out = hk.unit_vectors_compiled(v)
    if bad == "none":
        np.testing.assert_array_equal(out, validate_vectors(v))  # bit for bit
    else:
        assert out is None  # the caller runs validate_vectors, which raises
        with pytest.raises(InputError):
            validate_vectors(v)


def test_unit_vectors_leave_other_inputs_to_validate_vectors():
    for bad in ([[0.0, 0.0, 1.0]], np.ones((3, 2)), np.ones(3), np.ones((2, 3), np.float32)):
        assert hk.unit_vectors_compiled(bad) is None


@needs_kernel
@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(0, 40),
    fov_deg=st.floats(0.5, 120.0),
    shape=st.tuples(st.integers(1, 5000), st.integers(1, 5000)),
    bad=st.sampled_from(["none", "none", "nan", "inf", "-inf"]),
)
def test_pinhole_vectors_equal_the_numpy_form(seed, n, fov_deg, shape, bad):
    rng = np.random.default_rng(seed)
    # positions on the detector and off it (a star's centroid may come from outside the frame)
    x = rng.uniform(-0.5, 1.5, n) * shape[1]
    y = rng.uniform(-0.5, 1.5, n) * shape[0]
    if bad != "none" and n:
        (x if rng.integers(2) else y)[int(rng.integers(n))] = float(bad)
    fov = math.radians(fov_deg)
    if bad == "none" or not n:
        out = pinhole_vectors(x, y, shape=shape, fov_rad=fov)
        np.testing.assert_array_equal(
            out, pinhole_vectors(x, y, shape=shape, fov_rad=fov, compiled=False)
        )
    else:  # the kernel says no; the NumPy form raises
        assert hk.pinhole_vectors_compiled(x, y, centre=(0.0, 0.0), f_px=1.0) is None
        for compiled in (True, False):
            with pytest.raises(InputError, match="finite"):
                pinhole_vectors(x, y, shape=shape, fov_rad=fov, compiled=compiled)


def test_pinhole_vectors_leave_other_inputs_to_the_numpy_form():
    x = np.arange(5.0)
    for a, b in (
        (x, x[:4]),
        (x.reshape(5, 1), x.reshape(5, 1)),
        (x.astype(np.float32), x),
        ([1.0], x),
    ):
        assert hk.pinhole_vectors_compiled(a, b, centre=(0.0, 0.0), f_px=1.0) is None
    # lists, float32 and strided views give the NumPy form's values
    xy = np.random.default_rng(1).uniform(0, 100, (2, 9))
    for a, b in (
        (list(xy[0]), list(xy[1])),
        (xy[0].astype(np.float32), xy[1]),
        (xy[0, ::2], xy[1, ::2]),
    ):
        np.testing.assert_array_equal(
            pinhole_vectors(a, b, shape=(100, 100), fov_rad=0.2),
            pinhole_vectors(a, b, shape=(100, 100), fov_rad=0.2, compiled=False),
        )


def _assert_same(a, b):
    assert a.status == b.status
    assert (a.n_patterns_tried, a.n_candidates) == (b.n_patterns_tried, b.n_candidates)
    np.testing.assert_array_equal(a.detection_index, b.detection_index)
    np.testing.assert_array_equal(a.catalog_index, b.catalog_index)
    assert math.isclose(a.best_false_match_probability, b.best_false_match_probability, rel_tol=REL)
    if a.solved:
        assert (a.rotation * b.rotation.inv()).magnitude() < ROT_RAD
        assert math.isclose(a.residual_rms_rad, b.residual_rms_rad, rel_tol=REL)
        assert math.isclose(a.false_match_probability, b.false_match_probability, rel_tol=REL)


@needs_kernel
@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    seed=st.integers(0, 2**31),
    which=st.integers(0, 6),
    noise_px=st.sampled_from([0.1, 0.3, 1.0, 3.0]),
    n_false=st.integers(0, 8),
    drop=st.sampled_from([0.0, 0.3, 0.5]),
)
def test_solves_equal_the_numpy_form(pair, hipparcos, seed, which, noise_px, n_false, drop):
    sets = centroid_sets(
        hipparcos,
        7,
        fov_rad=SYNTH_FOV_RAD,
        image_size=SIZE,
        noise_px=noise_px,
        n_false=n_false,
        drop_fraction=drop,
        seed=seed,
    )
    xy = sets[which]
    v = pinhole_vectors(xy[:, 0], xy[:, 1], shape=SIZE, fov_rad=SYNTH_FOV_RAD)
    compiled, reference = pair
    _assert_same(compiled(v, SYNTH_FOV_RAD), reference(v, SYNTH_FOV_RAD))


@pytest.fixture(scope="module")
def pair_unknown(hipparcos):
    """Both forms on a multi-scale database (10-20 deg), for frames of unknown field."""
    db = build_database(hipparcos, math.radians(20), math.radians(10), patterns_per_field=50)
    return HashIdentifier(db), HashIdentifier(db, compiled=False)


@needs_kernel
@settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    seed=st.integers(0, 2**31),
    fov_deg=st.floats(11.0, 19.0),
    assumed_deg=st.floats(12.0, 18.0),
    noise_px=st.sampled_from([0.3, 1.0]),
    n_false=st.integers(0, 5),
)
def test_unknown_field_solves_equal_the_numpy_form(
    pair_unknown, hipparcos, seed, fov_deg, assumed_deg, noise_px, n_false
):
    # the scale of the tangent plane is fitted: the same scale to 1e-9 (a few rounds of least
    # squares on tangent points, each exact to rounding)
    sets = centroid_sets(
        hipparcos, 1, fov_rad=math.radians(fov_deg), noise_px=noise_px, n_false=n_false, seed=seed
    )
    xy = sets[0]
    assumed = math.radians(assumed_deg)
    v = pinhole_vectors(xy[:, 0], xy[:, 1], shape=SIZE, fov_rad=assumed)
    compiled, reference = pair_unknown
    a = compiled(v, assumed_fov_rad=assumed)
    b = reference(v, assumed_fov_rad=assumed)
    _assert_same(a, b)
    if a.solved:
        assert math.isclose(a.scale, b.scale, rel_tol=1e-9)
        assert math.isclose(a.fov_rad, b.fov_rad, rel_tol=1e-9)


@needs_kernel
@settings(
    max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(seed=st.integers(0, 2**31), n=st.integers(4, 30))
def test_failures_equal_the_numpy_form(pair, seed, n):
    # random directions in the field: every hypothesis verified fails the false-match test
    # (or none is found), the same ones in both forms
    rng = np.random.default_rng(seed)
    v = _frame_vectors(rng, n, 0.09, duplicate=False)
    compiled, reference = pair
    a, b = compiled(v, SYNTH_FOV_RAD), reference(v, SYNTH_FOV_RAD)
    assert a.status == "no_match"
    _assert_same(a, b)


@needs_kernel
def test_timeout_in_the_kernel(db15, hipparcos):
    sets = centroid_sets(hipparcos, 3, fov_rad=SYNTH_FOV_RAD, image_size=SIZE)
    xy = sets[1]
    v = pinhole_vectors(xy[:, 0], xy[:, 1], shape=SIZE, fov_rad=SYNTH_FOV_RAD)
    ident = HashIdentifier(db15, timeout_s=1e-12)
    out = ident(v, SYNTH_FOV_RAD)
    assert (out.status, out.n_patterns_tried) == ("timeout", 0)
    assert HashIdentifier(db15)(v, SYNTH_FOV_RAD).solved


def test_the_numpy_form_is_the_fallback(db15):
    assert not HashIdentifier(db15, compiled=False).compiled


@needs_kernel
@settings(
    max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(seed=st.integers(0, 2**31), n=st.integers(6, 30), budget=st.integers(0, 120))
def test_a_pattern_budget_stops_both_forms_at_the_same_pattern(pair, seed, n, budget):
    # random directions never identify: with a budget below the frame's patterns both forms
    # stop after exactly that many, having verified the same hypotheses (no wall clock in it)
    rng = np.random.default_rng(seed)
    v = _frame_vectors(rng, n, 0.09, duplicate=False)
    compiled, reference = pair
    unbounded = compiled(v, SYNTH_FOV_RAD)
    a = compiled(v, SYNTH_FOV_RAD, max_patterns=budget)
    b = reference(v, SYNTH_FOV_RAD, max_patterns=budget)
    _assert_same(a, b)
    if budget < unbounded.n_patterns_tried:
        assert (a.status, a.n_patterns_tried) == ("timeout", budget)
        assert f"{budget} patterns (the budget)" in a.message
    else:  # the budget is not reached: the unbounded answer
        _assert_same(a, unbounded)


@needs_kernel
def test_a_budget_the_solve_fits_in_changes_nothing(db15, hipparcos):
    sets = centroid_sets(hipparcos, 3, fov_rad=SYNTH_FOV_RAD, image_size=SIZE)
    xy = sets[1]
    v = pinhole_vectors(xy[:, 0], xy[:, 1], shape=SIZE, fov_rad=SYNTH_FOV_RAD)
    ident = HashIdentifier(db15)
    free = ident(v, SYNTH_FOV_RAD)
    assert free.solved
    _assert_same(ident(v, SYNTH_FOV_RAD, max_patterns=free.n_patterns_tried), free)
    if free.n_patterns_tried > 1:  # one pattern fewer than it needed: it stops there
        short = ident(v, SYNTH_FOV_RAD, max_patterns=free.n_patterns_tried - 1)
        assert (short.status, short.n_patterns_tried) == ("timeout", free.n_patterns_tried - 1)
