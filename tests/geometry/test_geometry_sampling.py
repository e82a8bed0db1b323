"""Points on the sphere, random attitudes and great-circle tracks."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from starsense.errors import InputError
from starsense.geometry.attitude import boresight, vectors_to_radec
from starsense.geometry.sampling import (
    fibonacci_sphere,
    great_circle_track,
    random_attitudes,
    track_attitudes,
)


@pytest.mark.parametrize("n", [1, 2, 3, 10, 1001])
def test_fibonacci_points_are_unit_vectors(n: int) -> None:
    points = fibonacci_sphere(n)
    assert points.shape == (n, 3)
    np.testing.assert_allclose(np.linalg.norm(points, axis=1), 1.0, atol=1e-15)


def test_fibonacci_is_balanced() -> None:
    points = fibonacci_sphere(10_000)
    # Equal-area bands in z make the mean z exactly 0; the spiral balances x and y too.
    np.testing.assert_allclose(points.mean(axis=0), 0.0, atol=1e-3)


def test_fibonacci_counts_in_random_caps_match_area() -> None:
    """Count in a cap of radius a = n (1 - cos a) / 2 (area fraction), to within 1 binomial sd.

    One binomial standard deviation sqrt(n p (1 - p)) is the typical error of n independent
    uniform points, which would exceed it in about a third of the caps; a quasi-uniform lattice
    must do better in every cap. (Measured worst case over these caps: about 0.4 sd at
    n = 10,000.) One extra point allows for the discreteness of the count.
    """
    n = 10_000
    points = fibonacci_sphere(n)
    rng = np.random.default_rng(20240601)
    centres = rng.normal(size=(200, 3))
    centres /= np.linalg.norm(centres, axis=1, keepdims=True)
    radii = rng.uniform(0.05, np.pi - 0.05, size=200)
    counts = (points @ centres.T >= np.cos(radii)).sum(axis=0)
    p = 0.5 * (1.0 - np.cos(radii))
    sd = np.sqrt(n * p * (1.0 - p))
    assert np.all(np.abs(counts - n * p) <= sd + 1.0)


def test_random_attitudes_reproducible_and_uniform() -> None:
    a = random_attitudes(50_000, rng=42)
    b = random_attitudes(50_000, rng=np.random.default_rng(42))
    assert isinstance(a, Rotation) and len(a) == 50_000
    np.testing.assert_array_equal(a.as_quat(), b.as_quat())
    # Haar measure: boresights uniform on the sphere, so sin(dec) is uniform on [-1, 1]
    # (mean 0, variance 1/3; the sd of the mean is sqrt(1/3 / n) = 0.0026, test at 4 sd).
    z = boresight(a)[:, 2]
    assert abs(z.mean()) < 4 * np.sqrt(1 / 3 / z.size)
    assert abs(np.var(z) - 1 / 3) < 0.01
    # The rotation angle has density (1 - cos t) / pi on [0, pi], mean pi/2 + 2/pi.
    assert abs(a.magnitude().mean() - (np.pi / 2 + 2 / np.pi)) < 0.01


@pytest.mark.parametrize("inclination_deg", [-90.0, -60.0, -10.0, 0.0, 23.4, 51.6, 90.0])
@pytest.mark.parametrize("node_rad", [0.0, 1.0, -2.5])
def test_great_circle_track_geometry(inclination_deg: float, node_rad: float) -> None:
    inc = np.radians(inclination_deg)
    n = 360  # a multiple of 4, so the point of largest declination (t = pi/2) is sampled
    pos, direction = great_circle_track(inc, n, ascending_node_rad=node_rad)
    assert pos.shape == direction.shape == (n, 3)
    np.testing.assert_allclose(np.linalg.norm(pos, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(direction, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(np.einsum("ij,ij->i", pos, direction), 0.0, atol=1e-15)
    # All points lie on the plane whose normal makes the angle |i| with the celestial pole.
    normal = np.cross(pos[0], direction[0])
    np.testing.assert_allclose(pos @ normal, 0.0, atol=1e-14)
    np.testing.assert_allclose(np.cross(pos, direction), np.tile(normal, (n, 1)), atol=1e-14)
    assert np.arccos(np.clip(normal[2], -1, 1)) == pytest.approx(abs(inc), abs=1e-12)
    _, dec = vectors_to_radec(pos)
    assert dec.max() == pytest.approx(abs(inc), abs=1e-12)
    # Equally spaced over the full circle: consecutive separations are all 2 pi / n.
    steps = np.arccos(np.clip(np.einsum("ij,ij->i", pos, np.roll(pos, -1, axis=0)), -1, 1))
    np.testing.assert_allclose(steps, 2 * np.pi / n, atol=1e-7)
    # The tangent points along the motion, towards the next point.
    assert np.all(np.einsum("ij,ij->i", direction, np.roll(pos, -1, axis=0) - pos) > 0)
    # The first point is the node, on the equator at RA = node; heading north for i > 0.
    np.testing.assert_allclose(pos[0], [np.cos(node_rad), np.sin(node_rad), 0.0], atol=1e-15)
    assert np.sign(direction[0, 2]) == np.sign(np.round(inc, 15))


@pytest.mark.parametrize("along", ["x", "y"])
def test_track_attitudes_follow_the_track(along: str) -> None:
    inc, node = np.radians(51.6), 0.7
    pos, direction = great_circle_track(inc, 100, ascending_node_rad=node)
    att = track_attitudes(inc, 100, ascending_node_rad=node, along=along)
    assert len(att) == 100
    np.testing.assert_allclose(boresight(att), pos, atol=1e-14)
    axis = [1.0, 0.0, 0.0] if along == "x" else [0.0, 1.0, 0.0]
    np.testing.assert_allclose(att.inv().apply(axis), direction, atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(att.as_matrix()), 1.0, atol=1e-12)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: fibonacci_sphere(0), r"n = 0 is out of range.*>= 1"),
        (lambda: fibonacci_sphere(-3), r"n = -3 is out of range"),
        (lambda: fibonacci_sphere(2.5), r"n must be an integer >= 1, got 2\.5"),
        (lambda: fibonacci_sphere(True), r"n must be an integer"),
        (lambda: random_attitudes(0, rng=1), r"n = 0 is out of range"),
        (lambda: great_circle_track(2.0, 10), r"inclination_rad = 2\.0 is out of range"),
        (lambda: great_circle_track(np.nan, 10), r"inclination_rad = nan .*finite"),
        (lambda: great_circle_track(0.1, 0), r"n = 0 is out of range"),
        (lambda: great_circle_track(0.1, 10, np.inf), r"ascending_node_rad = inf"),
        (lambda: track_attitudes(0.1, 10, along="z"), r"along = 'z' .*'x' or 'y'"),
    ],
)
def test_bad_input_raises_input_error(call, match: str) -> None:
    with pytest.raises(InputError, match=match):
        call()
