"""Frames that once failed, kept solving.

Cases 336, 517 and 1823 of the peer comparison's synthetic set (bench/peers/compare.py: 2,001
Fibonacci boresights, seed 20240605, 15 x 11.25 deg, 20 brightest V <= 9 stars, 0.3 px noise,
2 false stars) ended ``no_match``: none of the 4-subsets of their 10 brightest detections was
in the database, whose lattice of pattern fields (cones of radius fov/2, each contributing the
4-combinations of its 10 brightest pattern stars) was too sparse, 4 centres per field area.
The frames are regenerated here exactly as compare.py makes them.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from starsense.geometry.attitude import (
    angular_separation,
    attitude_from_radec_roll,
    radec_roll_from_attitude,
    radec_to_vectors,
    vectors_to_radec,
)
from starsense.geometry.sampling import fibonacci_sphere
from starsense.identify import HashIdentifier, build_database
from starsense.solve.pinhole import pinhole_vectors

ARCMIN = math.radians(1.0 / 60.0)
FOV_RAD = math.radians(15.0)
SIZE = (960, 1280)  # rows, columns
FORMERLY_FAILING = (336, 517, 1823)


def _peer_frames(catalog, wanted, n=2001, seed=20240605):
    """{case: (vectors_cam, true boresight)} of compare.py's synthetic_inputs(n, seed)."""
    mags = catalog.mags["V"]
    ok = np.flatnonzero(np.isfinite(mags) & (mags <= 9.0))
    ok = ok[np.argsort(mags[ok], kind="stable")]
    stars = catalog.vectors[ok]
    rows, cols = SIZE
    f_px = cols / 2.0 / math.tan(FOV_RAD / 2.0)
    cx, cy = (cols - 1) / 2.0, (rows - 1) / 2.0
    rng = np.random.default_rng(seed)
    bores = fibonacci_sphere(n)
    ra, dec = vectors_to_radec(bores)
    truth = attitude_from_radec_roll(ra, dec, rng.uniform(0.0, 2.0 * math.pi, n))
    cos_lim = math.cos(math.radians(12.0))
    frames = {}
    for i in range(max(wanted) + 1):  # every case draws from the generator
        cam = truth[i].apply(stars[stars @ bores[i] > cos_lim])
        x = cx + f_px * cam[:, 0] / cam[:, 2]
        y = cy + f_px * cam[:, 1] / cam[:, 2]
        inside = np.flatnonzero((x >= 0) & (x <= cols - 1) & (y >= 0) & (y <= rows - 1))[:20]
        xs = x[inside] + rng.normal(0.0, 0.3, len(inside))
        ys = y[inside] + rng.normal(0.0, 0.3, len(inside))
        for _ in range(2):
            pos = int(rng.integers(0, len(xs) + 1))
            xs = np.insert(xs, pos, rng.uniform(0, cols - 1))
            ys = np.insert(ys, pos, rng.uniform(0, rows - 1))
        if i in wanted:
            frames[i] = (pinhole_vectors(xs, ys, shape=SIZE, fov_rad=FOV_RAD), bores[i])
    return frames


@pytest.fixture(scope="module")
def peer_frames(hipparcos):
    return _peer_frames(hipparcos, FORMERLY_FAILING)


@pytest.mark.parametrize("case", FORMERLY_FAILING)
def test_formerly_unmatched_peer_frames_solve(case, peer_frames, hipparcos):
    identify = HashIdentifier(build_database(hipparcos, FOV_RAD))
    vectors, bore = peer_frames[case]
    result = identify(vectors, FOV_RAD)
    assert result.solved, f"case {case}: {result}"
    ra, dec, _ = radec_roll_from_attitude(result.rotation)
    assert float(angular_separation(radec_to_vectors(ra, dec), bore)) < ARCMIN
    assert result.false_match_probability < 1e-9


def test_sparse_pattern_field_lattice_has_holes(peer_frames, hipparcos):
    """The cause: with the old lattice (2**2 pattern fields per field area) these frames have
    no 4-subset of their brightest detections in the database (at the then depth: 10 pattern
    stars per field, patterns of the 10 brightest detections)."""
    sparse = HashIdentifier(
        build_database(hipparcos, FOV_RAD, field_oversampling=2.0, pattern_stars_per_fov=10),
        n_pattern_detections=10,
    )
    statuses = [sparse(vectors, FOV_RAD).status for vectors, _ in peer_frames.values()]
    assert statuses == ["no_match"] * len(FORMERLY_FAILING), statuses
