"""What a tracked frame computes only when read, and the per-frame shortcuts of tracking.

A tracked frame keeps its attitude as a matrix: the Rotation, (RA, Dec, roll), the covariance
and its 1-sigma errors, the match and centroid tables are computed when first read
(:class:`~starsense.solve.solution.Deferred`). Each must equal, bit for bit, what the same
function gives from the values read (the computation is the same, only later), and pickle,
copy and ``dataclasses.replace`` must keep values, not the calls. The identifier's checked
path and the sensor's unprojection skip checks and copies, not arithmetic: equal bit for bit.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from starsense.catalog import load_catalog
from starsense.errors import InputError
from starsense.geometry.attitude import radec_roll_from_attitude
from starsense.geometry.projection import tangent_to_vectors
from starsense.identify.tracking import TrackingIdentifier
from starsense.render.scene import render_frame
from starsense.sensor import load_sensor
from starsense.solve.solution import Deferred, Solution
from starsense.solve.solver import Solver
from starsense.solve.tracking import Prior, track_frame

DEG = math.pi / 180


@pytest.fixture(scope="module")
def st16():
    return load_sensor("st16")


@pytest.fixture(scope="module")
def tracked(st16):
    """Frames tracked from a 0.01 deg prior at rest and at 1 deg/s, with their truth."""
    hip = load_catalog("hipparcos")
    solver = Solver(st16, background="known", centroid_sigma_px="snr")
    out = []
    for seed, rate_deg_s in [(3, 0.0), (4, 1.0)]:
        rng = np.random.default_rng(seed)
        att = Rotation.random(random_state=rng)
        w = rate_deg_s * DEG * np.array([0.7, -0.7, 0.1])
        frame = render_frame(st16, att, hip, rate_rad_s=w, max_mag=6.5, rng=seed)
        err = Rotation.from_rotvec(rng.normal(0.0, 0.01 * DEG, 3))
        prior = Prior(err * att, np.eye(3) * (0.01 * DEG) ** 2, w, np.eye(3) * (0.005 * DEG) ** 2)
        result = track_frame(solver, frame.image, prior)
        assert result.mode == "tracking" and result.solution.solved, result.solution.message
        out.append((frame, result))
    return out


def test_deferred_fields_equal_their_computation(tracked):
    for frame, result in tracked:
        sol = result.solution
        # nothing derived has been computed yet: the frame's own values are still calls
        assert isinstance(sol.__dict__["_rotation"], Deferred)
        assert isinstance(result.__dict__["_covariance_rad2"], Deferred)
        ra, dec, roll = radec_roll_from_attitude(sol.rotation)
        assert (sol.ra_rad, sol.dec_rad, sol.roll_rad) == (float(ra), float(dec), float(roll))
        cov = result.covariance_rad2
        assert cov.shape == (3, 3) and np.all(np.linalg.eigvalsh(cov) > 0)
        assert sol.sigma_rad == tuple(np.sqrt(cov.diagonal()).tolist())
        assert result.covariance_rad2 is cov  # computed once, then kept
        assert len(sol.matches) == sol.n_matched and sol.centroids_px.shape == (
            sol.n_detections,
            2,
        )
        # the attitude is the truth's to its own 1-sigma errors (5 sigma: two frames)
        e = (sol.rotation * frame.truth.attitude.inv()).as_rotvec()
        assert np.all(np.abs(e) < 5 * np.asarray(sol.sigma_rad)), (e, sol.sigma_rad)


def test_pickle_copy_and_replace_keep_values(tracked):
    _, result = tracked[1]
    again = pickle.loads(pickle.dumps(result))
    assert again.solution.ra_rad == result.solution.ra_rad
    np.testing.assert_array_equal(again.covariance_rad2, result.covariance_rad2)
    assert copy.copy(result.solution).roll_rad == result.solution.roll_rad
    moved = dataclasses.replace(result.solution, message="x")
    assert moved.sigma_rad == result.solution.sigma_rad and moved.message == "x"


def test_a_deferred_value_is_computed_once_and_only_when_read():
    calls = []

    def angles():
        calls.append(1)
        return (1.0, 0.5, 0.25)

    shared = _once(angles)
    sol = Solution(
        "solved",
        ra_rad=Deferred(shared, index=0),
        dec_rad=Deferred(shared, index=1),
        roll_rad=Deferred(shared, index=2),
    )
    assert calls == []
    assert (sol.ra_rad, sol.dec_rad, sol.roll_rad, sol.roll_deg) == (1.0, 0.5, 0.25, 0.25 / DEG)
    assert calls == [1]
    # equal to the same solution given the values (dataclass equality reads the fields)
    assert sol == Solution("solved", ra_rad=1.0, dec_rad=0.5, roll_rad=0.25)
    assert Solution("no_stars").rotation is None and Solution("no_stars").ra_rad is None


def _once(fn):
    got = []

    def call():
        if not got:
            got.append(fn())
        return got[0]

    return call


def test_identifier_checked_path_equals_the_call(st16):
    db = Solver(st16, background="known").identifier(2 * st16.half_fov_rad[0]).database
    rng = np.random.default_rng(11)
    att = Rotation.random(random_state=rng)
    centre = att.inv().apply([0, 0, 1])
    near = np.sort(db.tree.query_ball_point(centre, 2 * math.sin(6 * DEG)))
    x, y = st16.project(db.vectors[near] @ att.as_matrix().T)
    on = near[(x > 50) & (x < 2540) & (y > 50) & (y < 1890)][:8]
    body = att.apply(db.vectors[on]) + rng.normal(0, 1e-5, (len(on), 3))
    prior = Rotation.from_rotvec([0.02 * DEG, -0.01 * DEG, 0.0]) * att
    ident = TrackingIdentifier(db)
    kw = {"search_radius_rad": 0.1 * DEG, "field_radius_rad": 0.2}
    for cand in (None, near[:20]):
        a = ident(body, prior, candidates=cand, **kw)
        unit = body / np.sqrt(np.add.reduce(body * body, axis=1))[:, None]
        b = ident.match_checked(unit, prior.as_matrix(), candidates=cand, **kw)
        assert a.status == b.status == "verified"
        for f in dataclasses.fields(a):
            if f.name != "time_ms":
                np.testing.assert_array_equal(getattr(a, f.name), getattr(b, f.name), f.name)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    n=st.integers(0, 50),
    offset=st.tuples(st.floats(-30, 30), st.floats(-30, 30)),
)
def test_unproject_equals_the_gnomonic_reference(st16, seed, n, offset):
    # the pinhole unprojection is tangent_to_vectors of the focal-plane point: the same
    # quotients and norm (u^2 + w^2 + 1 summed in that order), bit for bit
    sensor = dataclasses.replace(
        st16,
        optics=dataclasses.replace(
            st16.optics, principal_offset_x_px=offset[0], principal_offset_y_px=offset[1]
        ),
    )
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(-500, 3100, n), rng.uniform(-500, 2400, n)
    cx, cy = sensor.principal_point_px
    f = sensor.focal_length_px
    ref = tangent_to_vectors(np.stack([(x - cx) / f, (y - cy) / f], axis=-1))
    np.testing.assert_array_equal(sensor.unproject(x, y), ref)


def test_unproject_refuses_non_finite_pixels(st16):
    with pytest.raises(InputError, match="pixel coordinates must be finite"):
        st16.unproject(np.array([10.0, np.nan]), np.array([3.0, 4.0]))


def test_a_solution_stored_at_once_is_the_dataclass():
    # Solution.of stores what Solution(...) stores: every field, the deferred ones in their
    # slots (computed when read), fresh dicts for the defaults; a status that is none refused
    values = dict(
        ra_rad=0.1,
        dec_rad=Deferred(lambda: 0.2),
        roll_rad=0.3,
        fov_rad=0.25,
        n_detections=20,
        n_matched=15,
        sigma_rad=(1e-5, 1e-5, 1e-4),
        matches=((0, 7), (1, 9)),
        centroids_px=np.ones((2, 2)),
        image_shape=(960, 1280),
        notes=("a note",),
    )
    made, stored = Solution("solved", "m", **values), Solution.of("solved", "m", **values)
    assert made.__dict__.keys() == stored.__dict__.keys()
    for name in (f.name for f in dataclasses.fields(Solution)):
        a, b = getattr(made, name), getattr(stored, name)
        assert np.array_equal(a, b) if isinstance(a, np.ndarray) else a == b, name
    assert stored.dec_rad == 0.2 and stored.solved
    bare = Solution.of("no_match")
    assert bare.stage_ms == {} and bare.stage_ms is not Solution.of("no_match").stage_ms
    assert bare.counts == {} and bare.matches == () and bare.rotation is None
    with pytest.raises(InputError, match="status must be one of"):
        Solution.of("sovled")
    with pytest.raises(TypeError, match="no field"):
        Solution.of("solved", ra_deg=1.0)
