"""The binary Yale Bright Star Catalogue reader."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from starsense.catalog import Catalog, load_bsc5
from starsense.catalog.bsc5 import HEADER_DTYPE, RECORD_DTYPE
from starsense.errors import CatalogFormatError

MAS = np.pi / (180 * 3600 * 1000)


@pytest.fixture(scope="module")
def bsc5(bsc5_path: Path) -> Catalog:
    return load_bsc5(bsc5_path)


def test_shared_readme_count_3852_with_v_le_5_75(bsc5: Catalog) -> None:
    # shared/data/catalogs/README.md (independent count): 9,110 records, 14 without a
    # position; 3,852 stars with V <= 5.75 (3,791 with V < 5.75).
    assert len(bsc5) == 9110 - 14
    assert len(bsc5.brighter_than("V", 5.75)) == 3852
    assert int(np.sum(bsc5.mags["V"] < 5.75)) == 3791
    assert bsc5.epoch_yr == 2000.0 and set(bsc5.mags) == {"V"} and not bsc5.colours


def test_hoffleit_warren1991_sirius_and_polaris(bsc5: Catalog) -> None:
    sirius = bsc5.index_of(2491)  # HR 2491 = alpha CMa
    assert bsc5.mags["V"][sirius] == -1.46
    assert bsc5.extra["spectral_type"][sirius] == "A1"
    assert bsc5.brightest(1, "V").ids.tolist() == [2491]
    # Polaris (HR 424): BSC5 J2000 position 02 31 48.7 +89 15 51 (V/50).
    polaris = bsc5.index_of(424)
    assert np.degrees(bsc5.ra_rad[polaris]) * 240 == pytest.approx(
        2 * 3600 + 31 * 60 + 48.7, abs=0.1
    )
    assert np.degrees(bsc5.dec_rad[polaris]) * 3600 == pytest.approx(
        89 * 3600 + 15 * 60 + 51, abs=1
    )


def test_xrpm_is_mu_alpha_star(bsc5: Catalog, hip2: Catalog) -> None:
    # Polaris: BSC5 pmRA +0.038"/yr; Hipparcos (I/311) mu_alpha* = 44.48 mas/yr. Were XRPM
    # d(alpha)/dt, mu_alpha* would be 38 cos(89.26 deg) = 0.5 mas/yr.
    polaris = bsc5.index_of(424)
    assert bsc5.pm_ra_rad_yr[polaris] / MAS == pytest.approx(38.0, abs=0.01)
    hip_polaris = hip2.index_of(11767)
    assert hip2.pm_ra_rad_yr[hip_polaris] / MAS == pytest.approx(44.48, abs=0.01)
    # Across stars above |Dec| = 60 deg the BSC5/Hipparcos ratio stays ~1, with no
    # 1/cos(Dec) trend (that would be a factor >= 2 here).
    hip = hip2.propagate(2000.0)
    hits = hip.cones(bsc5.vectors, 5 * np.pi / (180 * 3600))
    pairs = [(i, h[0]) for i, h in enumerate(hits) if len(h) == 1]
    bi, hi = np.array(pairs).T
    polar = (np.abs(bsc5.dec_rad[bi]) > np.radians(60)) & (np.abs(hip.pm_ra_rad_yr[hi]) > 20 * MAS)
    ratio = np.median(bsc5.pm_ra_rad_yr[bi][polar] / hip.pm_ra_rad_yr[hi][polar])
    assert polar.sum() > 300
    assert ratio == pytest.approx(1.0, abs=0.02)


# -- malformed files ----------------------------------------------------------------------
def tiny_bsc5(
    tmp_path: Path, header: dict | None = None, n: int = 3, name: str = "bsc5_bad", edit=None
) -> Path:
    h = np.zeros(1, HEADER_DTYPE)
    h[0] = (0, 1, -n, 1, 1, 1, 32)
    for key, value in (header or {}).items():
        h[0][key] = value
    rec = np.zeros(n, RECORD_DTYPE)
    rec["XNO"] = np.arange(1, n + 1)
    rec["SRA0"] = np.linspace(0.1, 6.0, n)
    rec["SDEC0"] = np.linspace(-1.0, 1.0, n)
    rec["IS"] = b"G2"
    rec["MAG"] = 500
    if edit:
        edit(rec)
    path = tmp_path / name
    path.write_bytes(h.tobytes() + rec.tobytes())
    return path


def test_tiny_file_reads(tmp_path: Path) -> None:
    def removed(rec: np.ndarray) -> None:
        rec["SRA0"][1] = rec["SDEC0"][1] = 0.0

    cat = load_bsc5(tiny_bsc5(tmp_path, edit=removed))
    assert cat.ids.tolist() == [1, 3]
    assert cat.mags["V"].tolist() == [5.0, 5.0]


@pytest.mark.parametrize(
    ("header", "field", "detail"),
    [
        ({"NBENT": 28}, "NBENT", "record length 28, expected 32"),
        ({"STARN": 3}, "STARN", "only J2000 catalogues"),
        (
            {"STARN": -4},
            "STARN",
            "|STARN| = 4 records of 32 bytes need 156 bytes, the file has 124",
        ),
        ({"STARN": -2}, "STARN", "need 92 bytes, the file has 124"),
        ({"NMAG": 2}, "NMAG", "expected 1 magnitude"),
        ({"MPROP": 0}, "MPROP", "expected 1 (proper motion)"),
    ],
)
def test_corrupted_header(tmp_path: Path, header: dict, field: str, detail: str) -> None:
    path = tiny_bsc5(tmp_path, header)
    with pytest.raises(CatalogFormatError, match=re.escape(f"bsc5_bad, field {field}: ")) as info:
        load_bsc5(path)
    assert detail in str(info.value)


def test_bad_records_name_record_and_field(tmp_path: Path) -> None:
    def nan_dec(rec: np.ndarray) -> None:
        rec["SDEC0"][2] = np.nan

    def big_ra(rec: np.ndarray) -> None:
        rec["SRA0"][1] = 7.0

    with pytest.raises(CatalogFormatError, match=r"bsc5_bad, line 3, field SDEC0: .*not finite"):
        load_bsc5(tiny_bsc5(tmp_path, edit=nan_dec))
    with pytest.raises(CatalogFormatError, match=r"bsc5_bad, line 2, field SRA0: .*outside"):
        load_bsc5(tiny_bsc5(tmp_path, edit=big_ra))


def test_empty_and_truncated(tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.write_bytes(b"")
    with pytest.raises(CatalogFormatError, match="empty: file is empty"):
        load_bsc5(empty)
    short = tmp_path / "short"
    short.write_bytes(b"\x00" * 10)
    with pytest.raises(CatalogFormatError, match="shorter than the 28-byte header"):
        load_bsc5(short)
