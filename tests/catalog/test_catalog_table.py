"""The Catalog type: validation, selection, cone queries and epoch propagation."""

from __future__ import annotations

import numpy as np
import pytest

from starsense.catalog import KNOWN_BANDS, Catalog, concat
from starsense.errors import InputError

ARCSEC = np.pi / (180 * 3600)
MAS = ARCSEC / 1000


def random_catalog(n: int = 2000, seed: int = 1, *, pm: bool = True) -> Catalog:
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    ra = np.mod(np.arctan2(v[:, 1], v[:, 0]), 2 * np.pi)
    dec = np.arcsin(v[:, 2])
    mag_v = rng.uniform(-1, 12, n)
    mag_v[::17] = np.nan
    return Catalog(
        name="random",
        source="synthetic",
        epoch_yr=2000.0,
        ids=np.arange(10, 10 + n),
        ra_rad=ra,
        dec_rad=dec,
        mags={"V": mag_v, "Hp": mag_v + 0.1},
        colours={"B-V": rng.uniform(-0.3, 2, n)},
        pm_ra_rad_yr=rng.normal(0, 200, n) * MAS if pm else None,
        pm_dec_rad_yr=rng.normal(0, 200, n) * MAS if pm else None,
        parallax_rad=rng.uniform(0, 100, n) * MAS if pm else None,
        extra={"label": np.array([f"s{i}" for i in range(n)])},
    )


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between unit vectors, robust near 0 (atan2 of |a x b| and a.b)."""
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


# -- construction -------------------------------------------------------------------------
def test_columns_and_vectors() -> None:
    cat = random_catalog(50)
    assert len(cat) == 50
    assert cat.ids.dtype == np.int64
    assert cat.vectors.shape == (50, 3)
    np.testing.assert_allclose(np.linalg.norm(cat.vectors, axis=1), 1.0, rtol=0, atol=1e-15)
    assert cat.bands == ("V", "Hp")
    assert "n_stars=50" in repr(cat)
    with pytest.raises(ValueError, match="read-only"):
        cat.ra_rad[0] = 1.0
    with pytest.raises(TypeError):
        cat.mags["V"] = np.zeros(50)  # type: ignore[index]


def test_ra_is_wrapped_into_0_2pi() -> None:
    cat = Catalog(
        name="w",
        source="t",
        epoch_yr=2000.0,
        ids=[1, 2],
        ra_rad=[-0.5, 2 * np.pi + 0.25],
        dec_rad=[0.0, 0.1],
    )
    np.testing.assert_allclose(cat.ra_rad, [2 * np.pi - 0.5, 0.25], rtol=0, atol=1e-15)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"ra_rad": [0.0, np.nan]}, "must be finite"),
        ({"dec_rad": [0.0, 2.0]}, r"dec_rad must lie in \[-pi/2, pi/2\]"),
        ({"dec_rad": [0.0]}, "has 1 rows, expected 2"),
        ({"ids": [1.5, 2.5]}, "ids must be integers"),
        ({"mags": {"Vmag": [1.0, 2.0]}}, "unknown mag name 'Vmag'"),
        ({"colours": {"B_V": [1.0, 2.0]}}, "unknown colour name 'B_V'"),
        ({"mags": {"V": [1.0]}}, r"mags\['V'\] has 1 rows"),
        ({"pm_ra_rad_yr": [0.0, 0.0]}, "give both pm_ra_rad_yr and pm_dec_rad_yr"),
        ({"extra": {"x": np.array([None, None], dtype=object)}}, "object array"),
        ({"epoch_yr": float("nan")}, "epoch_yr must be finite"),
        ({"name": ""}, "name must be a non-empty string"),
    ],
)
def test_validation_errors(kwargs: dict, message: str) -> None:
    args = {
        "name": "t",
        "source": "s",
        "epoch_yr": 2000.0,
        "ids": [1, 2],
        "ra_rad": [0.0, 1.0],
        "dec_rad": [0.0, 0.5],
    }
    args.update(kwargs)
    with pytest.raises(InputError, match=message):
        Catalog(**args)


def test_from_columns_converts_units() -> None:
    cat = Catalog.from_columns(
        name="t",
        source="s",
        epoch_yr=2016.0,
        ids=[7],
        ra_deg=[180.0],
        dec_deg=[-45.0],
        pm_ra_mas_yr=[1000.0],
        pm_dec_mas_yr=[-500.0],
        parallax_mas=[100.0],
        mags={"G": [5.0]},
    )
    assert cat.ra_rad[0] == pytest.approx(np.pi, abs=1e-15)
    assert cat.dec_rad[0] == pytest.approx(-np.pi / 4, abs=1e-15)
    assert cat.pm_ra_rad_yr[0] == pytest.approx(ARCSEC, rel=1e-15)
    assert cat.pm_dec_rad_yr[0] == pytest.approx(-0.5 * ARCSEC, rel=1e-15)
    assert cat.parallax_rad[0] == pytest.approx(0.1 * ARCSEC, rel=1e-15)


# -- selection ----------------------------------------------------------------------------
def test_subset_slices_every_column_consistently() -> None:
    cat = random_catalog(100)
    _ = cat.vectors
    idx = np.array([5, 3, 99])
    sub = cat.subset(idx)
    assert sub.ids.tolist() == [15, 13, 109]
    for attr in ("ra_rad", "dec_rad", "pm_ra_rad_yr", "pm_dec_rad_yr", "parallax_rad"):
        np.testing.assert_array_equal(getattr(sub, attr), getattr(cat, attr)[idx])
    np.testing.assert_array_equal(sub.mags["Hp"], cat.mags["Hp"][idx])
    np.testing.assert_array_equal(sub.colours["B-V"], cat.colours["B-V"][idx])
    assert sub.extra["label"].tolist() == ["s5", "s3", "s99"]
    np.testing.assert_array_equal(sub.vectors, cat.vectors[idx])
    mask = cat.ids % 2 == 0
    assert len(cat.subset(mask)) == int(mask.sum())
    assert len(cat.subset(slice(10, 20))) == 10
    assert len(cat.subset([])) == 0
    with pytest.raises(InputError, match="out of range"):
        cat.subset([100])
    with pytest.raises(InputError, match="mask must have shape"):
        cat.subset(np.ones(3, dtype=bool))


def test_brighter_than_and_brightest() -> None:
    cat = random_catalog(500)
    v = cat.mags["V"]
    sel = cat.brighter_than("V", 5.0)
    assert len(sel) == int(np.sum(v <= 5.0))  # NaN excluded
    assert np.all(sel.mags["V"] <= 5.0)
    top = cat.brightest(10, "V")
    np.testing.assert_array_equal(top.mags["V"], np.sort(v[np.isfinite(v)])[:10])
    assert len(cat.brightest(10_000, "V")) == int(np.isfinite(v).sum())
    assert len(cat.brightest(0, "V")) == 0
    ordered = cat.sorted_by("V")
    assert len(ordered) == len(cat)
    finite = ordered.mags["V"][np.isfinite(ordered.mags["V"])]
    assert np.all(np.diff(finite) >= 0)
    assert np.isnan(ordered.mags["V"][-1])


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (
            lambda c: c.brighter_than("G", 5.0),
            r"band 'G' not in catalogue 'random'; "
            r"available bands: V, Hp",
        ),
        (lambda c: c.brighter_than("V", float("nan")), "max_mag must not be NaN"),
        (lambda c: c.brighter_than("V", "5"), "max_mag must be a number"),
        (lambda c: c.brightest(-1, "V"), "n must be a non-negative integer"),
        (lambda c: c.brightest(2.5, "V"), "n must be an integer"),
        (lambda c: c.sorted_by("Ks"), "band 'Ks' not in catalogue"),
        (lambda c: c.cone([0, 0, 1], -0.1), "radius_rad must be >= 0"),
        (lambda c: c.cone([0, 0, 0], 0.1), "zero vector"),
        (lambda c: c.cone([0, 0, 1, 0], 0.1), "must have shape"),
        (lambda c: c.cones(np.zeros((3, 3)) + 1, np.ones(2)), "radius_rad must be a scalar"),
        (lambda c: c.index_of([10, 3]), r"ids not in catalogue 'random': \[3\]"),
    ],
)
def test_argument_errors(call, message: str) -> None:
    with pytest.raises(InputError, match=message):
        call(random_catalog(50))


def test_index_of() -> None:
    cat = random_catalog(50)
    assert cat.index_of(10) == 0
    np.testing.assert_array_equal(cat.index_of([59, 12]), [49, 2])


def test_known_bands_are_the_documented_ones() -> None:
    assert KNOWN_BANDS == ("V", "B", "I", "Hp", "BT", "VT", "J", "H", "Ks", "G", "BP", "RP")


# -- cone queries -------------------------------------------------------------------------
def test_cone_matches_brute_force() -> None:
    cat = random_catalog(5000, seed=7)
    rng = np.random.default_rng(11)
    centers = rng.normal(size=(40, 3))
    centers /= np.linalg.norm(centers, axis=1, keepdims=True)
    for center, radius in zip(centers, rng.uniform(0.0, 0.6, 40), strict=True):
        expected = np.flatnonzero(angle_between(cat.vectors, center) <= radius)
        np.testing.assert_array_equal(cat.cone(center, radius), expected)
    # (RA, Dec) centres and the degenerate radii
    ra, dec = 1.0, -0.3
    center = np.array([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)])
    np.testing.assert_array_equal(cat.cone((ra, dec), 0.2), cat.cone(center, 0.2))
    assert len(cat.cone(center, 4.0)) == len(cat)  # beyond pi: the whole sphere
    assert cat.cone(cat.vectors[3], 0.0).tolist() == [3]


def test_cones_and_counts_match_single_queries() -> None:
    cat = random_catalog(3000, seed=3)
    rng = np.random.default_rng(5)
    centers = rng.normal(size=(25, 3))
    centers /= np.linalg.norm(centers, axis=1, keepdims=True)
    radii = rng.uniform(0.05, 0.4, 25)
    many = cat.cones(centers, radii)
    counts = cat.count_in_cones(centers, radii)
    assert counts.dtype == np.int64 and counts.shape == (25,)
    for c, r, hits, count in zip(centers, radii, many, counts, strict=True):
        np.testing.assert_array_equal(hits, cat.cone(c, r))
        assert count == len(hits)
    np.testing.assert_array_equal(
        cat.count_in_cones(centers, 0.2), [len(cat.cone(c, 0.2)) for c in centers]
    )


# -- propagation --------------------------------------------------------------------------
def test_propagate_round_trip_returns_the_original() -> None:
    cat = random_catalog(2000, seed=2)
    there = cat.propagate(2100.0)
    back = there.propagate(2000.0)
    assert back.epoch_yr == 2000.0
    # 1e-12 rad (0.2 uas) is ~1000 ulp of the unit vectors after two propagations.
    assert np.max(angle_between(back.vectors, cat.vectors)) < 1e-12
    np.testing.assert_allclose(back.pm_ra_rad_yr, cat.pm_ra_rad_yr, rtol=0, atol=1e-12 * MAS)
    np.testing.assert_allclose(back.pm_dec_rad_yr, cat.pm_dec_rad_yr, rtol=0, atol=1e-12 * MAS)
    np.testing.assert_allclose(back.parallax_rad, cat.parallax_rad, rtol=1e-12)
    np.testing.assert_allclose(back.radial_motion_per_yr, 0.0, atol=1e-20)


def test_propagate_moves_by_proper_motion_times_time() -> None:
    cat = random_catalog(1000, seed=4)
    moved = cat.propagate(2010.0)
    total_pm = np.hypot(cat.pm_ra_rad_yr, cat.pm_dec_rad_yr)
    # straight-line motion on the tangent plane: the angle is atan(mu t)
    np.testing.assert_allclose(
        angle_between(moved.vectors, cat.vectors), np.arctan(total_pm * 10.0), rtol=1e-9, atol=1e-15
    )
    assert moved.propagate(2010.0) is moved


def test_propagate_needs_proper_motions() -> None:
    cat = random_catalog(10, pm=False)
    assert cat.propagate(2000.0) is cat
    with pytest.raises(InputError, match="has no proper motions"):
        cat.propagate(2001.0)


def test_stars_without_proper_motion_stay_put() -> None:
    cat = random_catalog(10)
    pm = np.array(cat.pm_ra_rad_yr)
    pm[3] = np.nan
    cat2 = Catalog(**{**{f: getattr(cat, f) for f in cat.__dataclass_fields__}, "pm_ra_rad_yr": pm})
    moved = cat2.propagate(2050.0)
    assert moved.ra_rad[3] == cat.ra_rad[3] and moved.dec_rad[3] == cat.dec_rad[3]
    assert np.isnan(moved.pm_ra_rad_yr[3])


def test_concat() -> None:
    a = random_catalog(20, seed=1)
    b = Catalog(
        name="b",
        source="s",
        epoch_yr=2000.0,
        ids=[1, 2],
        ra_rad=[0.1, 0.2],
        dec_rad=[0.0, 0.1],
        mags={"G": [3.0, 4.0]},
    )
    c = concat([a, b], name="ab")
    assert len(c) == 22 and c.name == "ab"
    assert set(c.mags) == {"V", "Hp", "G"}
    assert np.isnan(c.mags["G"][:20]).all() and c.mags["G"][20:].tolist() == [3.0, 4.0]
    assert np.isnan(c.pm_ra_rad_yr[20:]).all()
    assert "label" not in c.extra
    with pytest.raises(InputError, match="different epochs"):
        concat([a, a.propagate(2001.0)])
