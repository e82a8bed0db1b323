"""Fields of view: exact solid angles, containment and fast counting."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

import starsense.geometry.fov as fov_module
from starsense.errors import InputError
from starsense.geometry.attitude import attitude_from_radec_roll, radec_to_vectors
from starsense.geometry.fov import CircularFov, RectangularFov, count_in_fov
from starsense.geometry.sampling import fibonacci_sphere, random_attitudes

DEG = math.pi / 180


def random_unit_vectors(n: int, seed: int) -> np.ndarray:
    v = np.random.default_rng(seed).normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_cube_face_is_one_sixth_of_the_sphere() -> None:
    # The gnomonic square of half-angle 45 deg is a cube face seen from the centre: 4 pi / 6.
    face = RectangularFov(math.pi / 4, math.pi / 4)
    assert face.solid_angle_sr == pytest.approx(4 * math.pi / 6, rel=1e-15)
    assert face.enclosing_radius_rad == pytest.approx(math.atan(math.sqrt(2)), rel=1e-15)


def test_circular_solid_angle_and_radius() -> None:
    assert CircularFov(math.pi).solid_angle_sr == pytest.approx(4 * math.pi, rel=1e-15)
    assert CircularFov(math.pi / 2).solid_angle_sr == pytest.approx(2 * math.pi, rel=1e-15)
    small = CircularFov(1e-4)
    assert small.solid_angle_sr == pytest.approx(math.pi * 1e-8, rel=1e-8)
    assert small.enclosing_radius_rad == 1e-4


@pytest.mark.parametrize(
    "fov",
    [
        RectangularFov(10 * DEG, 7.5 * DEG),
        RectangularFov(40 * DEG, 20 * DEG),
        CircularFov(12 * DEG),
        CircularFov(100 * DEG),
    ],
    ids=str,
)
def test_solid_angle_matches_fraction_of_fibonacci_points(fov) -> None:
    """The count of lattice points inside equals n Omega / (4 pi) within 3 binomial sd.

    3 sd of n independent uniform points is a generous bound for a quasi-uniform lattice,
    whose cap/region errors are several times smaller than the binomial sd.
    """
    n = 200_000
    points = fibonacci_sphere(n)
    att = attitude_from_radec_roll(1.1, 0.4, 0.3)
    count = int(fov.contains(att, points).sum())
    p = fov.solid_angle_sr / (4 * math.pi)
    assert abs(count - n * p) <= 3 * math.sqrt(n * p * (1 - p))


def test_rectangular_contains_edges_and_orientation() -> None:
    fov = RectangularFov(10 * DEG, 5 * DEG)
    identity = Rotation.identity()
    eps = 1e-9

    def direction(x_angle: float, y_angle: float) -> np.ndarray:
        v = np.array([math.tan(x_angle), math.tan(y_angle), 1.0])
        return v / np.linalg.norm(v)

    inside = [direction(10 * DEG - eps, 0), direction(-10 * DEG + eps, 5 * DEG - eps)]
    outside = [
        direction(10 * DEG + eps, 0),
        direction(0, 5 * DEG + eps),
        direction(7 * DEG, 6 * DEG),
    ]
    assert fov.contains(identity, np.array(inside)).all()
    assert not fov.contains(identity, np.array(outside)).any()
    # The point 7 deg across the columns is inside, 7 deg across the rows is not.
    assert fov.contains(identity, direction(7 * DEG, 0))
    assert not fov.contains(identity, direction(0, 7 * DEG))
    # Directions behind the camera are never inside.
    assert not fov.contains(identity, [0.0, 0.0, -1.0])


def test_from_detector() -> None:
    # ESA frames: 1024 x 768 binned pixels of 6.9 um behind a 35 mm lens; reference.json gives
    # a horizontal field of about 11.42 deg (the lens' real focal length differs slightly).
    fov = RectangularFov.from_detector(1024, 768, pixel_pitch_m=6.9e-6, focal_length_m=35e-3)
    assert fov.half_width_rad == pytest.approx(math.atan(1024 * 6.9e-6 / 2 / 35e-3), rel=1e-15)
    assert fov.half_height_rad == pytest.approx(math.atan(768 * 6.9e-6 / 2 / 35e-3), rel=1e-15)
    assert 2 * fov.half_width_rad / DEG == pytest.approx(11.42, abs=0.2)


def test_contains_shapes() -> None:
    fov = CircularFov(20 * DEG)
    vectors = random_unit_vectors(50, 1)
    single = attitude_from_radec_roll(0.0, 0.0, 0.0)
    batch = random_attitudes(7, rng=2)
    assert fov.contains(single, vectors).shape == (50,)
    assert fov.contains(batch, vectors).shape == (7, 50)
    assert fov.contains(batch, vectors[0]).shape == (7,)
    assert fov.contains(single, radec_to_vectors(0.1, 0.0)).shape == ()
    np.testing.assert_array_equal(fov.contains(batch, vectors)[3], fov.contains(batch[3], vectors))


@pytest.mark.parametrize(
    "fov",
    [
        RectangularFov(5 * DEG, 5 * DEG),
        RectangularFov.from_detector(1024, 768, pixel_pitch_m=6.9e-6, focal_length_m=35e-3),
        RectangularFov(60 * DEG, 30 * DEG),
        CircularFov(8 * DEG),
        CircularFov(math.pi),
    ],
    ids=str,
)
def test_count_in_fov_equals_brute_force(fov) -> None:
    vectors = random_unit_vectors(3_000, 11)
    attitudes = random_attitudes(400, rng=12)
    expected = fov.contains(attitudes, vectors).sum(axis=1)
    counts = count_in_fov(fov, attitudes, vectors)
    assert counts.shape == (400,)
    np.testing.assert_array_equal(counts, expected)
    np.testing.assert_array_equal(
        count_in_fov(fov, attitudes, vectors, tree=cKDTree(vectors)), expected
    )
    assert count_in_fov(fov, attitudes[5], vectors) == expected[5]


def test_count_in_fov_with_stars_on_the_edge() -> None:
    # Stars on the corners (the enclosing cone) must not be lost by the tree prefilter: one
    # star just inside each field's corner (counted) and one exactly on it (rounding decides;
    # the count must agree with the exact test either way).
    fov = RectangularFov(5 * DEG, 3 * DEG)
    corner = np.array([math.tan(5 * DEG), math.tan(3 * DEG), 1.0])
    attitudes = random_attitudes(50, rng=3)
    just_inside = corner * [1 - 1e-10, 1 - 1e-10, 1]
    vectors = np.concatenate(
        [attitudes.inv().apply(v / np.linalg.norm(v)) for v in (just_inside, corner)]
    )
    expected = fov.contains(attitudes, vectors).sum(axis=1)
    assert expected.min() >= 1
    np.testing.assert_array_equal(count_in_fov(fov, attitudes, vectors), expected)
    cone = CircularFov(fov.enclosing_radius_rad)
    np.testing.assert_array_equal(
        count_in_fov(cone, attitudes, vectors), cone.contains(attitudes, vectors).sum(axis=1)
    )


def test_count_in_fov_blocks_large_candidate_sets(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(fov_module, "_CANDIDATE_BUDGET", 500)
    fov = CircularFov(30 * DEG)
    vectors = random_unit_vectors(2_000, 5)
    attitudes = random_attitudes(300, rng=6)
    np.testing.assert_array_equal(
        count_in_fov(fov, attitudes, vectors), fov.contains(attitudes, vectors).sum(axis=1)
    )


def test_fov_is_frozen() -> None:
    fov = CircularFov(0.1)
    with pytest.raises(dataclasses.FrozenInstanceError):
        fov.half_angle_rad = 0.2  # type: ignore[misc]


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: CircularFov(0.0), r"CircularFov\.half_angle_rad = 0\.0 rad is out of range"),
        (lambda: CircularFov(-0.1), r"half_angle_rad = -0\.1 .*0 < .*<= 3\.14159"),
        (lambda: CircularFov(4.0), r"half_angle_rad = 4\.0 rad is out of range"),
        (lambda: CircularFov(float("nan")), r"half_angle_rad = nan rad is out of range"),
        (lambda: RectangularFov(0.1, 0.0), r"RectangularFov\.half_height_rad = 0\.0 rad"),
        (lambda: RectangularFov(math.pi / 2, 0.1), r"half_width_rad = 1\.57.* < 1\.57"),
        (lambda: RectangularFov(float("nan"), 0.1), r"half_width_rad = nan"),
        (lambda: RectangularFov("wide", 0.1), r"half_width_rad must be a real number"),
        (
            lambda: RectangularFov.from_detector(
                0, 768, pixel_pitch_m=6.9e-6, focal_length_m=0.035
            ),
            r"columns = 0 .*>= 1",
        ),
        (
            lambda: RectangularFov.from_detector(
                1024, 768, pixel_pitch_m=-1.0, focal_length_m=0.035
            ),
            r"pixel_pitch_m = -1\.0",
        ),
        (
            lambda: RectangularFov.from_detector(
                1024, 768, pixel_pitch_m=6.9e-6, focal_length_m=float("nan")
            ),
            r"focal_length_m must be finite, got nan",
        ),
        (
            lambda: CircularFov(0.1).contains(Rotation.identity(), [[1.0, 0.0]]),
            r"vectors must have shape \(N, 3\)",
        ),
        (
            lambda: CircularFov(0.1).contains(Rotation.identity(), [[np.nan, 0.0, 1.0]]),
            r"non-finite",
        ),
        (
            lambda: count_in_fov(
                CircularFov(0.1), Rotation.identity(), np.eye(3), tree=cKDTree(np.eye(3)[:2])
            ),
            r"tree must be a cKDTree built on vectors \(3 points.*2 points",
        ),
        (lambda: count_in_fov(0.1, Rotation.identity(), np.eye(3)), r"fov must be"),
        (
            lambda: count_in_fov(CircularFov(0.1), np.eye(3), np.eye(3)),
            r"attitudes must be a scipy Rotation",
        ),
    ],
)
def test_bad_input_raises_input_error(call, match: str) -> None:
    with pytest.raises(InputError, match=match):
        call()
