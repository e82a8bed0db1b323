"""The pattern lattice of a database: dense where it fits, sparse for narrow fields, built in
bounded blocks with the same result as in one piece."""

from __future__ import annotations

import math

import numpy as np
import pytest

from starsense.catalog import load_catalog
from starsense.geometry.attitude import angular_separation, attitude_from_radec_roll
from starsense.identify import build_database
from starsense.identify import patterns as patterns_module
from starsense.identify.fields import deep_catalog_available, known_field_catalog
from starsense.identify.lattice import (
    DENSE_LATTICE,
    PATTERN_BUDGET,
    SPARSE_LATTICE,
    expected_pairs,
    lattice_pattern_count,
    pattern_lattice,
)
from starsense.render.scene import render_frame
from starsense.sensor import load_sensor
from starsense.solve.solver import Solver

DEG = math.radians(1.0)


def _lattice(lattice):
    return {"field_oversampling": lattice[0], "patterns_per_field": lattice[1]}


@pytest.mark.parametrize("fov_deg", [8.0, 11.42, 15.0, 20.0, 30.0])
def test_common_fields_keep_the_dense_lattice(fov_deg):
    # the lattice every lost-in-space result of these fields was measured with
    fov = fov_deg * DEG
    assert pattern_lattice(fov, fov, 13) == DENSE_LATTICE


@pytest.mark.parametrize("fov_deg", [1.0, 1.14, 2.3, 4.0])
def test_narrow_fields_get_the_sparse_lattice_within_budget(fov_deg):
    fov = fov_deg * DEG
    dense = lattice_pattern_count(fov, fov, 13, **_lattice(DENSE_LATTICE))
    assert dense > PATTERN_BUDGET  # what made the 1-5 deg databases run out of memory
    assert pattern_lattice(fov, fov, 13) == SPARSE_LATTICE
    # at most ~6 M lattice patterns at 1 deg: 48 bytes each in the database, < 0.4 GB
    assert lattice_pattern_count(fov, fov, 13, **_lattice(SPARSE_LATTICE)) * 48 < 0.4e9


def test_what_the_caller_gives_is_kept():
    fov = 1.14 * DEG
    assert pattern_lattice(fov, fov, 13, field_oversampling=4.0, patterns_per_field="all") == (
        4.0,
        None,
    )
    # one given, the other from the sparse lattice when the dense one is over budget
    assert pattern_lattice(fov, fov, 13, field_oversampling=3.0) == (3.0, SPARSE_LATTICE[1])
    assert pattern_lattice(15 * DEG, 15 * DEG, 13, patterns_per_field=50) == (4.0, 50)


def test_expected_pairs_counts_uniform_stars():
    # Independent count: uniform random stars on the sphere, pairs by brute force.
    rng = np.random.default_rng(5)
    v = rng.normal(size=(1500, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    fov = 10 * DEG
    cos = v @ v.T
    n = (np.triu(cos, 1) > math.cos(1.3 * fov)).sum()
    expected = expected_pairs(1500, fov)
    # Poisson scatter of ~5,700 pairs is ~1.3 %; 5 % leaves room for the clustering of pairs
    assert n == pytest.approx(expected, rel=0.05)


@pytest.mark.slow
def test_blocks_give_the_same_database(hipparcos, monkeypatch):
    # Built in blocks of 1,000 patterns (instead of 1 M), the database is identical.
    fov = 20 * DEG
    whole = build_database(hipparcos, fov, cache=False)
    monkeypatch.setattr(patterns_module, "CHUNK_PATTERNS", 1000)
    blocks = build_database(hipparcos, fov, cache=False)
    for name in whole._ARRAYS:
        np.testing.assert_array_equal(getattr(blocks, name), getattr(whole, name))


def test_narrow_known_fields_use_gaia_with_the_default_catalogue():
    deep = "gaia" if deep_catalog_available() else "hipparcos"
    assert known_field_catalog("hipparcos", 1.14 * DEG) == deep
    assert known_field_catalog("hipparcos", 3.9 * DEG) == deep
    # Hipparcos alone serves 4-70 deg; a catalogue the user chose is always kept
    assert known_field_catalog("hipparcos", 6.0 * DEG) == "hipparcos"
    assert known_field_catalog("hipparcos", None) == "hipparcos"
    assert known_field_catalog("bsc5:/x/catalog", 1.0 * DEG) == "bsc5:/x/catalog"


@pytest.mark.slow  # builds the 1.14 deg Gaia database once (~25 s, ~1.2 GB peak)
def test_lin2024_frame_solves_on_gaia():
    """A rendered lin2024 frame (1.14 deg, 2 arcsec pixels, Gaia to G = 10) solves, right.

    The boresight must lie within one pixel (2 arcsec) of the truth: dozens of matched stars
    centroided to a fraction of a pixel; a wrong identification is off by degrees.
    """
    if not deep_catalog_available():
        pytest.skip("narrow fields need the gaia extra (pip install 'starsense[gaia]')")
    sensor = load_sensor("lin2024")
    gaia = load_catalog("gaia")
    solver = Solver(sensor="lin2024")
    for i, (ra, dec) in enumerate([(83.8, -5.4), (192.9, 27.1), (280.0, -30.0)]):
        truth = attitude_from_radec_roll(math.radians(ra), math.radians(dec), 0.3 * i)
        frame = render_frame(sensor, truth, gaia, band="G", max_mag=10.0, rng=i)
        sol = solver(frame.image)
        assert sol.solved, (ra, dec, sol.status, sol.message)
        err = angular_separation(sol.rotation.inv().apply([0, 0, 1]), truth.inv().apply([0, 0, 1]))
        assert err < math.radians(2.0 / 3600.0), (ra, dec, math.degrees(err) * 3600)
