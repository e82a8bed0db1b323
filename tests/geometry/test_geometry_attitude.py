"""Attitude conventions: (RA, Dec, roll) round trips, the roll/east convention, error angles."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from starsense.errors import InputError
from starsense.geometry.attitude import (
    angular_separation,
    attitude_from_radec_roll,
    boresight,
    east_north,
    radec_roll_from_attitude,
    radec_roll_from_matrix,
    radec_roll_of_matrix,
    radec_to_vectors,
    small_rotation_angles,
    vectors_to_radec,
)

HALF_PI = 0.5 * np.pi
TWO_PI = 2.0 * np.pi

# Rotations are compared by the angle of r1 * r2^-1; 1e-9 rad is far above the ~1e-15 rad
# rounding of the conversions and far below anything physically meaningful (0.2 mas).
ROT_TOL_RAD = 1e-9

angle_ra = st.floats(0.0, TWO_PI, exclude_max=True)
angle_roll = st.floats(-4 * np.pi, 4 * np.pi)
dec_any = st.floats(-HALF_PI, HALF_PI)
# Distances from a pole, from exactly 0 through the ill-conditioned 1e-16..1e-6 rad range.
pole_offset = st.one_of(st.just(0.0), st.floats(1e-18, 1e-3))
quaternion = st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4).filter(
    lambda q: np.linalg.norm(q) > 1e-3
)


def rotation_distance(r1: Rotation, r2: Rotation) -> np.ndarray:
    return (r1 * r2.inv()).magnitude()


@settings(deadline=None)
@given(ra=angle_ra, dec=dec_any, roll=angle_roll)
def test_rotation_round_trips_through_radec_roll(ra: float, dec: float, roll: float) -> None:
    rot = attitude_from_radec_roll(ra, dec, roll)
    back = attitude_from_radec_roll(*radec_roll_from_attitude(rot))
    assert rotation_distance(rot, back) < ROT_TOL_RAD


@settings(deadline=None)
@given(ra=angle_ra, offset=pole_offset, south=st.booleans(), roll=angle_roll)
def test_rotation_round_trips_near_poles(
    ra: float, offset: float, south: bool, roll: float
) -> None:
    dec = (HALF_PI - offset) * (-1.0 if south else 1.0)
    rot = attitude_from_radec_roll(ra, dec, roll)
    ra2, dec2, roll2 = radec_roll_from_attitude(rot)
    assert 0.0 <= ra2 < TWO_PI and 0.0 <= roll2 < TWO_PI and abs(dec2) <= HALF_PI
    assert rotation_distance(rot, attitude_from_radec_roll(ra2, dec2, roll2)) < ROT_TOL_RAD


@settings(deadline=None)
@given(q=quaternion)
def test_arbitrary_rotation_round_trips(q: list[float]) -> None:
    rot = Rotation.from_quat(q)
    assert rotation_distance(rot, attitude_from_radec_roll(*radec_roll_from_attitude(rot))) < (
        ROT_TOL_RAD
    )


@settings(deadline=None, max_examples=300)
@given(
    q=quaternion,
    ra=angle_ra,
    offset=pole_offset,
    south=st.booleans(),
    roll=st.sampled_from([0.0, HALF_PI, np.pi, 1.3]),
)
def test_radec_roll_from_matrix_equals_the_rotation_form(q, ra, offset, south, roll) -> None:
    # the same NumPy operations on the same matrix: equal bit for bit, for any rotation and
    # at and near the poles (and at the roll angles whose matrices hold exact zeros)
    dec = (HALF_PI - offset) * (-1.0 if south else 1.0)
    for rot in (Rotation.from_quat(q), attitude_from_radec_roll(ra, dec, roll)):
        ref = tuple(float(a) for a in radec_roll_from_attitude(rot))
        assert radec_roll_from_matrix(rot.as_matrix()) == ref


@given(
    q=quaternion,
    ra=angle_ra,
    offset=pole_offset,
    south=st.booleans(),
    roll=st.sampled_from([0.0, HALF_PI, np.pi, 1.3]),
)
def test_radec_roll_of_matrix_equals_the_numpy_form_to_rounding(q, ra, offset, south, roll):
    # the same formulas on Python floats: the C library's sin, cos and atan2 may differ from
    # NumPy's in the last bit, which a few operations carry to a few ulp of the angle: 4 ulp of
    # 2 pi (np.spacing(2 pi) = 8.9e-16 rad) bounds them (3 ulp of pi, 1.3e-15, seen); angles
    # compared on the circle (0 and 2 pi are one angle)
    dec = (HALF_PI - offset) * (-1.0 if south else 1.0)
    for rot in (Rotation.from_quat(q), attitude_from_radec_roll(ra, dec, roll)):
        m = rot.as_matrix()
        for got, ref in zip(radec_roll_of_matrix(m), radec_roll_from_matrix(m), strict=True):
            assert isinstance(got, float)
            gap = abs(got - ref) % (2 * np.pi)
            assert min(gap, 2 * np.pi - gap) <= 4 * np.spacing(2 * np.pi)


@settings(deadline=None)
@given(ra=angle_ra, dec=st.floats(-HALF_PI + 1e-3, HALF_PI - 1e-3), roll=angle_roll)
def test_angles_round_trip_away_from_poles(ra: float, dec: float, roll: float) -> None:
    ra2, dec2, roll2 = radec_roll_from_attitude(attitude_from_radec_roll(ra, dec, roll))
    # Angles are compared on the circle; 1e-9 rad over-covers the 1/cos(dec) <= 1e3 conditioning.
    assert abs(np.angle(np.exp(1j * (ra2 - ra)))) < 1e-9
    assert dec2 == pytest.approx(dec, abs=1e-12)
    assert abs(np.angle(np.exp(1j * (roll2 - roll)))) < 1e-9


def test_pole_convention_ra_zero() -> None:
    for dec in (HALF_PI, -HALF_PI):
        rot = attitude_from_radec_roll([0.3, 2.0, 5.0], dec, [1.0, 2.0, 3.0])
        ra, dec2, roll = radec_roll_from_attitude(rot)
        np.testing.assert_array_equal(ra, 0.0)
        np.testing.assert_allclose(dec2, dec, atol=1e-15)
        assert np.all(rotation_distance(rot, attitude_from_radec_roll(ra, dec2, roll)) < 1e-12)


def test_batch_round_trip_of_random_rotations() -> None:
    rot = Rotation.random(20_000, rng=np.random.default_rng(7))
    ra, dec, roll = radec_roll_from_attitude(rot)
    assert ra.shape == dec.shape == roll.shape == (20_000,)
    assert np.all(rotation_distance(rot, attitude_from_radec_roll(ra, dec, roll)) < ROT_TOL_RAD)


def image_xy(ra0: float, dec0: float, roll: float, ra: float, dec: float) -> np.ndarray:
    """Gnomonic camera-plane position (x/z, y/z) of a star for a given pointing."""
    v = attitude_from_radec_roll(ra0, dec0, roll).apply(radec_to_vectors(ra, dec))
    assert v[2] > 0
    return v[:2] / v[2]


@pytest.mark.parametrize(("ra0", "dec0"), [(0.0, 0.0), (1.0, 0.3), (4.0, -1.2), (2.5, 1.5)])
def test_roll_zero_north_is_up_and_east_is_left(ra0: float, dec0: float) -> None:
    step = 1e-3
    north = image_xy(ra0, dec0, 0.0, ra0, dec0 + step)
    # Up in the image is towards row 0, i.e. -y; same column.
    assert north[1] < 0 and abs(north[0]) < 1e-12
    east = image_xy(ra0, dec0, 0.0, ra0 + step / np.cos(dec0), dec0)
    # Seen from inside the sphere, east is to the LEFT of north-up (-x). The row moves only by
    # the curvature of the parallel of declination, which bends towards the nearer pole by
    # step^2 tan(dec) / 2 (up, -y, in the north).
    assert east[0] < 0
    curvature = -0.5 * step**2 * np.tan(dec0)
    assert abs(east[1] - curvature) < 1e-2 * abs(curvature) + 1e-12


@pytest.mark.parametrize(("ra0", "dec0"), [(0.0, 0.0), (1.0, 0.3), (4.0, -1.2)])
def test_roll_plus_90_puts_north_left(ra0: float, dec0: float) -> None:
    north = image_xy(ra0, dec0, HALF_PI, ra0, dec0 + 1e-3)
    # Counter-clockwise from up, in the displayed image (row 0 on top): left, i.e. -x.
    assert north[0] < 0 and abs(north[1]) < 1e-12


@pytest.mark.parametrize("roll", [0.1, 0.7, 2.0, 3.5, 5.9])
def test_roll_turns_north_counter_clockwise_from_up(roll: float) -> None:
    ra0, dec0 = 2.0, 0.4
    north = image_xy(ra0, dec0, roll, ra0, dec0 + 1e-4)
    east = image_xy(ra0, dec0, roll, ra0 + 1e-4 / np.cos(dec0), dec0)
    # In displayed-image coordinates (right = +x, up = -y) the direction of north makes the
    # angle `roll` counter-clockwise from up: (-sin roll, -cos roll) in (x, y).
    np.testing.assert_allclose(
        north / np.linalg.norm(north), [-np.sin(roll), -np.cos(roll)], atol=1e-6
    )
    np.testing.assert_allclose(
        east / np.linalg.norm(east), [-np.cos(roll), np.sin(roll)], atol=1e-4
    )
    # Not mirrored: east is 90 deg counter-clockwise from north in the displayed image for
    # every roll; with y pointing down that makes the planar cross product north x east < 0
    # (north = up = (0, -1), east = left = (-1, 0) gives -1).
    assert north[0] * east[1] - north[1] * east[0] < 0


def test_camera_frame_is_right_handed_and_rows_match_axes() -> None:
    rot = attitude_from_radec_roll([0.1, 3.0, 6.0], [-0.5, 0.2, 1.4], [0.0, 1.0, 4.0])
    m = rot.as_matrix()
    np.testing.assert_allclose(np.linalg.det(m), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.cross(m[:, 0], m[:, 1]), m[:, 2], atol=1e-12)
    np.testing.assert_allclose(
        boresight(rot), radec_to_vectors([0.1, 3.0, 6.0], [-0.5, 0.2, 1.4]), atol=1e-12
    )
    np.testing.assert_allclose(rot.apply(boresight(rot)), [[0, 0, 1]] * 3, atol=1e-12)


def test_euler_equivalent() -> None:
    ra, dec, roll = 1.3, -0.4, 2.2
    euler = Rotation.from_euler("ZYZ", [ra, HALF_PI - dec, roll - HALF_PI])
    assert rotation_distance(attitude_from_radec_roll(ra, dec, roll).inv(), euler) < 1e-12


def test_east_north_triad() -> None:
    east, north = east_north([0.2, 4.0], [0.3, -1.0])
    np.testing.assert_allclose(
        np.cross(east, north), radec_to_vectors([0.2, 4.0], [0.3, -1.0]), atol=1e-15
    )


def test_radec_vectors_round_trip_and_shapes() -> None:
    rng = np.random.default_rng(3)
    ra = rng.uniform(0, TWO_PI, 1000)
    dec = np.arcsin(rng.uniform(-1, 1, 1000))
    v = radec_to_vectors(ra, dec)
    assert v.shape == (1000, 3)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, atol=1e-15)
    ra2, dec2 = vectors_to_radec(v)
    np.testing.assert_allclose(ra2, ra, atol=1e-12)
    np.testing.assert_allclose(dec2, dec, atol=1e-12)
    assert radec_to_vectors(0.0, 0.0).shape == (3,)
    ra_s, dec_s = vectors_to_radec([0.0, -1.0, 0.0])
    assert ra_s == pytest.approx(1.5 * np.pi) and dec_s == 0.0
    assert vectors_to_radec([0.0, 0.0, 2.0]) == (0.0, HALF_PI)
    ra_neg, _ = vectors_to_radec([1.0, -1e-300, 0.0])
    assert 0.0 <= ra_neg < TWO_PI


def test_angular_separation_is_accurate_at_all_scales() -> None:
    u = np.array([1.0, 0.0, 0.0])
    for angle in (1e-12, 1e-6, 0.5, np.pi / 2, np.pi - 1e-9, np.pi):
        v = np.array([np.cos(angle), np.sin(angle), 0.0])
        assert angular_separation(u, v) == pytest.approx(angle, rel=1e-12, abs=1e-15)
    w = radec_to_vectors(np.linspace(0, 1, 5), 0.0)
    np.testing.assert_allclose(angular_separation(w, u), np.linspace(0, 1, 5), atol=1e-15)


def test_small_rotation_angles_axes() -> None:
    r_true = attitude_from_radec_roll(
        np.array([1.0, 2.0]), np.array([0.2, -0.3]), np.array([0.5, 4.0])
    )
    delta = np.array([[1e-5, 0.0, 0.0], [0.0, -2e-5, 3e-4]])
    r_est = Rotation.from_rotvec(delta) * r_true  # error applied in the camera frame
    np.testing.assert_allclose(small_rotation_angles(r_true, r_est), delta, atol=1e-15)
    # A pure roll error changes roll only, a cross-boresight error moves the boresight.
    ra, dec, roll = 1.0, 0.2, 0.5
    e_roll = small_rotation_angles(
        attitude_from_radec_roll(ra, dec, roll), attitude_from_radec_roll(ra, dec, roll + 1e-4)
    )
    assert abs(e_roll[2]) == pytest.approx(1e-4, rel=1e-9)
    np.testing.assert_allclose(e_roll[:2], 0.0, atol=1e-15)
    e_point = small_rotation_angles(
        attitude_from_radec_roll(ra, dec, roll), attitude_from_radec_roll(ra, dec + 1e-5, roll)
    )
    assert np.hypot(*e_point[:2]) == pytest.approx(1e-5, rel=1e-6)
    assert abs(e_point[2]) < 1e-12


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: radec_to_vectors(0.0, 2.0), r"dec_rad = 2\.0 .*\[-pi/2, pi/2\]"),
        (lambda: radec_to_vectors(np.nan, 0.0), r"ra_rad = nan .*finite"),
        (lambda: attitude_from_radec_roll(0.0, 0.0, np.inf), r"roll_rad = inf .*finite"),
        (lambda: attitude_from_radec_roll(0.0, -1.6, 0.0), r"dec_rad = -1\.6 .*range"),
        (lambda: attitude_from_radec_roll([0.0, 1.0], [0.0, 1.0, 0.2], 0.0), r"do not broadcast"),
        (lambda: vectors_to_radec([0.0, 0.0, 0.0]), r"zero vector"),
        (lambda: vectors_to_radec([[1.0, 0.0]]), r"shape \(N, 3\).*\(1, 2\)"),
        (lambda: angular_separation([1.0, np.nan, 0.0], [1.0, 0.0, 0.0]), r"u = nan"),
        (lambda: boresight(np.eye(3)), r"rot must be a scipy Rotation"),
        (
            lambda: small_rotation_angles(Rotation.random(2, rng=1), Rotation.random(3, rng=1)),
            r"same length.*2 and 3",
        ),
    ],
)
def test_bad_input_raises_input_error(call, match: str) -> None:
    with pytest.raises(InputError, match=match):
        call()
