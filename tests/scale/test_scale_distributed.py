"""Deep catalogues on Dask (starsense.scale): the distributed results equal the in-memory ones.

One small catalogue (20,000 stars, Gaia and 2MASS column names) is written as Parquet and CSV,
read in memory by the real readers (``gaia:``, ``twomass:``), and turned into HATS by
``starsense catalog import`` (hats-import) with at most 2,000 rows per tile, so every result is
merged from ~20 partitions. Tolerance 1e-12 relative, with margin: the per-star quantities are
bit-identical (same kernels on the same float64 values); only the order of the Fisher sums
differs, ~1e-16 per addition x sqrt(20,000 terms) x the condition number of F (< 100 for the
20 deg fields here), i.e. ~1e-13 at worst. Integer results (counts, availability) are exact.

One in-process cluster (2 worker threads) serves the whole module; the CLI tests reach it by its
scheduler address, which also exercises ``--dask tcp://HOST:PORT``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from starsense.scale import ScaleNotInstalledError

try:
    from starsense.scale._deps import require

    require("lsdb", "hats", "hats_import", "distributed")
except ScaleNotInstalledError as exc:  # the optional extra is absent: nothing to test here
    pytest.skip(f"starsense[scale] not installed: {exc}", allow_module_level=True)

import pandas as pd  # after the skip: pandas comes with the extra

from starsense.analysis import limits as mem
from starsense.analysis.availability import (
    AvailabilityAnalysis,
    FieldStars,
    catalog_stars,
    sky_attitudes,
)
from starsense.catalog import load_catalog
from starsense.cli import main
from starsense.geometry.attitude import radec_to_vectors
from starsense.geometry.fov import CircularFov, RectangularFov
from starsense.scale import (
    brightest_curve,
    dask_client,
    fov_limit,
    import_catalog,
    open_hats,
    sky_limit,
    star_counts,
    static_availability,
)

REL = 1e-12  # relative; see the module notes for why it holds with margin
N_STARS = 20_000


def _stars_table(n: int, seed: int) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    ra = np.degrees(np.arctan2(v[:, 1], v[:, 0])) % 360.0
    dec = np.degrees(np.arcsin(np.clip(v[:, 2], -1.0, 1.0)))
    # magnitudes rounded to 0.01 mag, as many catalogues publish them: ~17 stars share each
    # value, so the N-brightest ranking must break ties the same way in both paths
    g = np.round(rng.uniform(2.0, 14.0, n), 2)
    bp_rp = rng.uniform(-0.6, 3.8, n)  # beyond both ends of the 2,000-30,000 K clamp
    bp_rp[rng.random(n) < 0.02] = np.nan  # 2 % without a colour: skipped by both paths
    j = g - rng.uniform(0.0, 2.0, n)
    h = j - rng.uniform(-0.1, 0.9, n)
    k = h - rng.uniform(-0.1, 0.4, n)
    return pd.DataFrame(
        {
            "source_id": np.arange(n, dtype=np.int64) * 7 + 3,
            "ra": ra,
            "dec": dec,
            "phot_g_mean_mag": g,
            "bp_rp": bp_rp,
            "j_m": j,
            "h_m": h,
            "k_m": k,
        }
    )


@pytest.fixture(scope="module")
def client():
    with dask_client("local:2", processes=False) as c:
        yield c


@pytest.fixture(scope="module")
def data(tmp_path_factory, client):
    """(folder, in-memory Gaia catalogue, in-memory 2MASS catalogue, opened HATS catalogue)."""
    folder = tmp_path_factory.mktemp("scale")
    table = _stars_table(N_STARS, seed=7)
    table.to_parquet(folder / "stars.parquet")
    table[["ra", "dec", "j_m", "h_m", "k_m"]].to_csv(
        folder / "twomass.csv",
        index=False,
        float_format="%.17g",  # round-trips float64
    )
    import_catalog(
        folder / "stars.parquet", folder / "stars_hats", pixel_threshold=2_000, client=client
    )
    gaia = load_catalog(f"gaia:{folder / 'stars.parquet'}", cache=False)
    twomass = load_catalog(f"twomass:{folder / 'twomass.csv'}", cache=False)
    return folder, gaia, twomass, open_hats(f"hats:{folder / 'stars_hats'}")


def _close(a, b, rel=REL):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    scale = np.max(np.abs(b))
    assert a.shape == b.shape
    assert np.max(np.abs(a - b)) <= rel * scale, (a, b)


def _same_limit(a: mem.LimitResult, b: mem.LimitResult) -> None:
    assert a.n_stars == b.n_stars
    assert a.frame == b.frame
    _close(a.theta_rms_rad, b.theta_rms_rad)
    _close(a.axis_sigma_rad, b.axis_sigma_rad)
    _close(a.covariance, b.covariance)  # relative to its largest entry
    _close(a.g_rad_m2_s05, b.g_rad_m2_s05)


def test_hats_catalogue_has_many_partitions(data):
    _, gaia, _, hats = data
    assert hats.n_rows == len(gaia) == N_STARS
    assert hats.n_partitions >= 10  # 20,000 rows / <= 2,000 per tile


def test_sky_limit_gaia_equals_in_memory(data, client):
    _, gaia, _, hats = data
    stars = mem.BlackBodyStars.from_catalog(gaia)
    assert stars.colour == "BP-RP"
    # the table also has 2MASS columns, and J-H comes first in the default order: ask for BP-RP
    res, used = sky_limit(hats, diameter_m=0.1, exposure_s=0.2, colour="BP-RP", client=client)
    _same_limit(res, mem.sky_limit(stars, diameter_m=0.1, exposure_s=0.2))
    assert (used.colour, used.n_stars, used.n_skipped) == ("BP-RP", len(stars), stars.n_skipped)
    assert used.n_skipped > 0  # the NaN colours


@pytest.mark.parametrize("colour", ["J-H", "H-Ks"])
def test_sky_limit_twomass_colours_with_cut_equal_in_memory(data, client, colour):
    _, _, twomass, hats = data
    stars = mem.BlackBodyStars.from_catalog(twomass, colour)
    band_cut = 9.0
    cut = stars.subset(stars.magnitude <= band_cut)  # what `limit sky --max-mag` does
    res, used = sky_limit(hats, colour=colour, max_mag=band_cut, client=client)
    _same_limit(res, mem.sky_limit(cut))
    assert used.colour == colour


def test_fov_limits_many_targets_equal_in_memory(data, client):
    _, gaia, _, hats = data
    stars = mem.BlackBodyStars.from_catalog(gaia)
    rng = np.random.default_rng(3)
    ra, dec = rng.uniform(0, 2 * np.pi, 12), np.arcsin(rng.uniform(-1, 1, 12))
    targets = np.array([radec_to_vectors(a, d) for a, d in zip(ra, dec, strict=True)])
    heads, merged, _ = fov_limit(
        hats,
        targets,
        fov_diameter_rad=np.radians(20.0),
        diameter_m=0.05,
        exposure_s=0.1,
        colour="BP-RP",
        client=client,
    )
    heads0, merged0 = mem.fov_limit(
        stars, targets, fov_diameter_rad=np.radians(20.0), diameter_m=0.05, exposure_s=0.1
    )
    for h, h0 in zip(heads, heads0, strict=True):
        _same_limit(h, h0)
        assert h.n_stars > 100  # each 20 deg cone holds ~600 stars: a real sum, not a few terms
    _same_limit(merged, merged0)


@pytest.mark.parametrize("max_explicit", [200_000, 50])
def test_brightest_curve_equals_in_memory(data, client, max_explicit):
    # max_explicit = 50 forces the finer second histogram (bins split 1024 times)
    _, gaia, _, hats = data
    stars = mem.BlackBodyStars.from_catalog(gaia)
    labels = set()
    curve = brightest_curve(
        hats,
        diameter_m=0.1,
        exposure_s=0.1,
        colour="BP-RP",
        client=client,
        max_explicit=max_explicit,
        progress=lambda label, done, total: labels.add(label),
    )
    assert ("N brightest: finer histogram" in labels) == (max_explicit == 50)
    curve0 = mem.brightest_curve(stars, diameter_m=0.1, exposure_s=0.1)
    np.testing.assert_array_equal(curve.n_stars, curve0.n_stars)
    assert np.all(np.abs(curve.theta_rms_rad / curve0.theta_rms_rad - 1) <= REL)
    assert curve.slope == pytest.approx(curve0.slope, rel=1e-9)  # a fit through those points
    assert curve.colour == curve0.colour


def test_brightest_order_is_independent_of_row_order(data):
    # the property the distributed ranking relies on: ties broken by content, not position
    _, gaia, _, _ = data
    stars = mem.BlackBodyStars.from_catalog(gaia)
    perm = np.random.default_rng(0).permutation(len(stars))
    shuffled = stars.subset(perm)
    a = mem.brightest_curve(stars)
    b = mem.brightest_curve(shuffled)
    assert np.all(np.abs(a.theta_rms_rad / b.theta_rms_rad - 1) <= REL)


@pytest.mark.parametrize(
    "fov", [CircularFov(np.radians(7.5)), RectangularFov(np.radians(10.0), np.radians(7.5))]
)
def test_star_counts_per_boresight_equal_in_memory(data, client, fov):
    _, gaia, _, hats = data
    _, attitudes = sky_attitudes(1_000, None, rng=2)
    counts = star_counts(hats, fov, attitudes, max_mag=11.0, band="G", client=client)
    counts0 = FieldStars.build(fov, attitudes, *catalog_stars(gaia, 11.0, band="G")).counts()
    np.testing.assert_array_equal(counts, counts0)
    assert counts.mean() > 5  # fields hold stars: the comparison is not of zeros


def test_static_availability_equals_in_memory(data, client):
    _, gaia, _, hats = data
    fov = CircularFov(np.radians(7.5))
    # G <= 2.5 keeps ~830 of the 20,000 stars (G uniform in 2-14): ~3.6 per 7.5 deg field on
    # average, so N_min = 3 is met at some boresights and not at others
    res = static_availability(
        hats, fov, max_mag=2.5, n_min=3, band="G", n_orientations=2_000, client=client
    )
    res0 = AvailabilityAnalysis.from_catalog(gaia, fov, 2.5, band="G", n_orientations=2_000).static(
        3
    )
    assert 0.2 < res.availability < 0.9
    assert res.availability == res0.availability
    assert res.by_n_min == res0.by_n_min
    assert res.n_stars == res0.n_stars
    np.testing.assert_array_equal(res.counts, res0.counts)
    for k in res0.curve:
        np.testing.assert_array_equal(res.curve[k], res0.curve[k])


# -- command line, against the module's cluster by address -------------------------------------


def run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_cli_limit_sky_hats_by_scheduler_address(data, client, capsys):
    folder, gaia, _, _ = data
    code, out, err = run(
        capsys,
        "limit",
        "sky",
        "--catalog",
        f"hats:{folder / 'stars_hats'}",
        "--dask",
        client.scheduler.address,
        "--diameter-m",
        "0.1",
        "--exposure-s",
        "0.1",
        "--colour",
        "BP-RP",
        "--json",
    )
    assert code == 0, err
    assert err == ""  # no progress bar or warnings: stderr is not a terminal
    payload = json.loads(out)  # --json output is pure JSON
    ref = mem.sky_limit(mem.BlackBodyStars.from_catalog(gaia), diameter_m=0.1, exposure_s=0.1)
    assert payload["n_stars"] == ref.n_stars
    assert payload["theta_rms_rad"] == pytest.approx(ref.theta_rms_rad, rel=REL)


def test_cli_limit_curve_hats(data, client, capsys):
    folder, gaia, _, _ = data
    code, out, err = run(
        capsys,
        "limit",
        "curve",
        "--catalog",
        f"hats:{folder / 'stars_hats'}",
        "--dask",
        client.scheduler.address,
        "--colour",
        "BP-RP",
        "--json",
    )
    assert code == 0, err
    payload = json.loads(out)
    ref = mem.brightest_curve(mem.BlackBodyStars.from_catalog(gaia, "BP-RP"))
    assert payload["n_stars"] == ref.n_stars.tolist()
    _close(payload["theta_rms_rad"], ref.theta_rms_rad)


def test_cli_limit_sky_hats_fov_heads(data, client, capsys):
    folder, gaia, _, _ = data
    code, out, err = run(
        capsys,
        "limit",
        "sky",
        "--catalog",
        f"hats:{folder / 'stars_hats'}",
        "--dask",
        client.scheduler.address,
        "--fov-deg",
        "20",
        "--target-deg",
        "10,20",
        "--target-deg",
        "200,-40",
        "--colour",
        "BP-RP",
        "--json",
    )
    assert code == 0, err
    payload = json.loads(out)
    targets = np.array(
        [radec_to_vectors(np.radians(a), np.radians(d)) for a, d in ((10, 20), (200, -40))]
    )
    heads, merged = mem.fov_limit(
        mem.BlackBodyStars.from_catalog(gaia), targets, fov_diameter_rad=np.radians(20.0)
    )
    assert [h["n_stars"] for h in payload["heads"]] == [h.n_stars for h in heads]
    assert payload["merged"]["theta_rms_rad"] == pytest.approx(merged.theta_rms_rad, rel=REL)


def test_cli_availability_static_hats(data, client, capsys):
    folder, gaia, _, _ = data
    code, out, err = run(
        capsys,
        "availability",
        "static",
        "--catalog",
        f"hats:{folder / 'stars_hats'}",
        "--dask",
        client.scheduler.address,
        "--band",
        "G",
        "--max-mag",
        "2.5",
        "--half-fov-deg",
        "7.5",
        "--n-orientations",
        "1000",
        "--json",
    )
    assert code == 0, err
    payload = json.loads(out)
    ref = AvailabilityAnalysis.from_catalog(
        gaia, CircularFov(np.radians(7.5)), 2.5, band="G", n_orientations=1_000
    ).static(3)
    assert payload["availability"] == ref.availability
    assert payload["stars_in_field"]["mean"] == pytest.approx(float(ref.counts.mean()), rel=REL)


@pytest.mark.slow
def test_cli_catalog_import_is_atomic(client, capsys, tmp_path):
    small = _stars_table(500, seed=11)
    small.to_csv(tmp_path / "mine.csv", index=False, float_format="%.17g")
    out_dir = tmp_path / "mine_hats"
    code, out, err = run(
        capsys,
        "catalog",
        "import",
        str(tmp_path / "mine.csv"),
        str(out_dir),
        "--dask",
        client.scheduler.address,
        "--json",
    )
    assert code == 0, err
    payload = json.loads(out)
    assert payload["n_rows"] == 500 and out_dir.is_dir()
    assert {"phot_g_mean_mag", "bp_rp"} <= set(payload["columns"])
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temp left
    # importing again onto an existing catalogue is refused, and leaves it alone
    code, _, err = run(
        capsys,
        "catalog",
        "import",
        str(tmp_path / "mine.csv"),
        str(out_dir),
        "--dask",
        client.scheduler.address,
    )
    assert code == 2 and "already exists" in err and out_dir.is_dir()
