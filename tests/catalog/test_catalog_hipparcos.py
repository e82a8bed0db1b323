"""Hipparcos readers: the bundled new reduction (hip2.dat) and the original hip_main.dat."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from starsense.catalog import Catalog, load_bsc5, load_hip2, load_hip_main, v_from_hp
from starsense.catalog.hipparcos import B_MINUS_V_RANGE, BRIGHT_STAR_V
from starsense.errors import CatalogFormatError, InputError

ARCSEC = np.pi / (180 * 3600)


def hms(ra_rad: float) -> tuple[int, int, float]:
    s = np.degrees(ra_rad) / 15 * 3600
    return int(s // 3600), int(s % 3600 // 60), s % 60


def dms(dec_rad: float) -> tuple[int, int, float]:
    s = np.degrees(abs(dec_rad)) * 3600
    return int(np.sign(dec_rad) * (s // 3600)), int(s % 3600 // 60), s % 60


# -- hip2: the bundled catalogue ----------------------------------------------------------
def test_vizier_i311_hip2_has_117955_stars(hip2: Catalog) -> None:
    # VizieR I/311 ReadMe, File Summary: hip2.dat, 117955 records.
    assert len(hip2) == 117_955
    assert hip2.name == "hip2" and hip2.epoch_yr == 1991.25
    assert len(np.unique(hip2.ids)) == len(hip2)
    assert set(hip2.mags) == {"Hp", "V"} and set(hip2.colours) == {"B-V", "V-I"}
    assert np.isfinite(hip2.mags["V"]).all()


def test_van_leeuwen2007_vega(hip2: Catalog) -> None:
    i = hip2.index_of(91262)
    # I/311 record of HIP 91262: Hpmag 0.0868, B-V -0.001 (exact file values).
    assert hip2.mags["Hp"][i] == pytest.approx(0.0868, abs=5e-5)
    assert hip2.colours["B-V"][i] == pytest.approx(0.00, abs=0.005)
    # Vega's V is the literature value V = 0.03 (BSC5); its Hp is 0.06 mag fainter than V,
    # so the Hp -> V transformation alone gives 0.074 (within 0.05 of 0.03).
    assert hip2.mags["V"][i] == pytest.approx(0.03, abs=1e-9)
    assert hip2.extra["V_from_literature"][i]
    assert v_from_hp(0.0868, -0.001) == pytest.approx(0.03, abs=0.05)


@pytest.mark.parametrize(
    ("hip", "ra_hms", "dec_dms"),
    [
        # SIMBAD ICRS J2000 coordinates, which are the van Leeuwen (2007) solution
        # propagated to J2000 and quoted to 1e-5 s / 1e-4 arcsec.
        (11767, (2, 31, 49.09456), (89, 15, 50.7923)),  # Polaris
        (91262, (18, 36, 56.33635), (38, 47, 1.2802)),  # Vega
        (32349, (6, 45, 8.91728), (-16, 42, 58.0171)),  # Sirius
    ],
)
def test_simbad_j2000_positions(hip2: Catalog, hip: int, ra_hms: tuple, dec_dms: tuple) -> None:
    star = hip2.subset([hip2.index_of(hip)]).propagate(2000.0)
    h, m, s = hms(star.ra_rad[0])
    d, dm, ds = dms(star.dec_rad[0])
    assert (h, m, d, dm) == (ra_hms[0], ra_hms[1], dec_dms[0], dec_dms[1])
    # 1 mas: the rounding of the quoted values is <= 0.15 mas; the remaining 0.2 mas for
    # Sirius is the propagation model (radial velocity) used by SIMBAD.
    cos_dec = np.cos(star.dec_rad[0])
    assert abs(s - ra_hms[2]) * 15 * cos_dec < 1e-3
    assert abs(ds - dec_dms[2]) < 1e-3


def test_barnards_star_moves_10_3_arcsec_per_year(hip2: Catalog) -> None:
    star = hip2.subset([hip2.index_of(87937)])
    total_pm = np.hypot(star.pm_ra_rad_yr[0], star.pm_dec_rad_yr[0]) / ARCSEC
    # Barnard's star, the largest proper motion known: 10.36"/yr (van Leeuwen 2007).
    assert total_pm == pytest.approx(10.358, abs=0.002)
    later = star.propagate(2001.25)
    moved = np.arccos(np.clip(star.vectors[0] @ later.vectors[0], -1, 1)) / ARCSEC
    # Uniform motion on the tangent plane: atan(mu t) = mu t to 1e-12 relative.
    assert moved == pytest.approx(10 * total_pm, abs=1e-3)
    assert moved == pytest.approx(103.6, abs=0.05)


# -- V from Hp ----------------------------------------------------------------------------
def test_bessell2000_table2_nodes() -> None:
    # Bessell (2000) Table 2 rows: BT-VT=0.000 -> B-V=-0.005, V-Hp=-0.011;
    # BT-VT=1.000 -> B-V=0.878, V-Hp=-0.155; BT-VT=2.000 -> B-V=1.658, V-Hp=-0.106.
    np.testing.assert_allclose(
        v_from_hp(np.zeros(3), np.array([-0.005, 0.878, 1.658])),
        [-0.011, -0.155, -0.106],
        atol=1e-12,
    )
    assert B_MINUS_V_RANGE == pytest.approx((-0.219, 1.658))
    # clamped outside the table, NaN colour -> NaN
    assert v_from_hp(1.0, 3.0) == pytest.approx(1.0 - 0.106)
    assert np.isnan(v_from_hp(1.0, np.nan))


def test_derived_v_agrees_with_bsc5_v(hip2: Catalog, bsc5_path: Path) -> None:
    bsc = load_bsc5(bsc5_path)
    hip = hip2.propagate(2000.0)
    hits = hip.cones(bsc.vectors, 5 * ARCSEC)
    one = np.array([len(h) == 1 for h in hits])
    bi = np.flatnonzero(one)
    hi = np.array([hits[k][0] for k in bi])
    assert len(bi) > 8500  # most BSC5 stars are in Hipparcos
    bv = hip.colours["B-V"][hi]
    derived = v_from_hp(hip.mags["Hp"][hi], bv)
    diff = derived - bsc.mags["V"][bi]
    inside = (bv > -0.25) & (bv < 1.6)
    median = np.median(diff[inside])
    robust_sigma = 1.4826 * np.median(np.abs(diff[inside] - median))
    # BSC5 V is quoted to 0.01 mag from heterogeneous photoelectric sources; Bessell's
    # table reproduces standard V to ~0.01-0.02 mag. Measured: -0.006 and 0.017 mag.
    assert abs(median) < 0.015
    assert robust_sigma < 0.025
    # Hp alone is 0.09 mag too faint on average: the transformation is doing the work.
    assert np.median((hip.mags["Hp"][hi] - bsc.mags["V"][bi])[inside]) > 0.05


def test_literature_v_table_is_bsc5(bsc5_path: Path) -> None:
    bsc = load_bsc5(bsc5_path)
    v = dict(zip(bsc.ids.tolist(), bsc.mags["V"].tolist(), strict=True))
    for hip, (name, hr, value) in BRIGHT_STAR_V.items():
        expected = v[hr]
        if hip == 60718:  # Acrux: alpha1 (HR 4730) + alpha2 (HR 4731) Cru combined
            expected = -2.5 * np.log10(10 ** (-0.4 * v[4730]) + 10 ** (-0.4 * v[4731]))
        assert value == pytest.approx(expected, abs=0.005), name


def test_literature_v_is_applied(hip2: Catalog) -> None:
    rows = hip2.index_of(list(BRIGHT_STAR_V))
    np.testing.assert_array_equal(hip2.mags["V"][rows], [e[2] for e in BRIGHT_STAR_V.values()])
    assert hip2.extra["V_from_literature"].sum() == len(BRIGHT_STAR_V)
    brightest = hip2.brightest(3, "V")
    assert brightest.ids.tolist() == [32349, 30438, 69673]  # Sirius, Canopus, Arcturus


# -- hip2: malformed files ----------------------------------------------------------------
def write(tmp_path: Path, name: str, lines: list[bytes]) -> Path:
    path = tmp_path / name
    path.write_bytes(b"".join(lines))
    return path


def test_hip2_subset_file_round_trips(tmp_path: Path, hip2: Catalog, hip2_lines) -> None:
    path = write(tmp_path, "hip2_head.dat", hip2_lines[:50])
    cat = load_hip2(path)
    assert len(cat) == 50
    np.testing.assert_array_equal(cat.ra_rad, hip2.ra_rad[:50])
    np.testing.assert_array_equal(cat.mags["V"], hip2.mags["V"][:50])
    # CR LF line ends and a missing final newline are accepted
    crlf = write(tmp_path, "crlf.dat", [ln.replace(b"\n", b"\r\n") for ln in hip2_lines[:5]])
    assert len(load_hip2(crlf)) == 5
    no_nl = write(tmp_path, "nonl.dat", [*hip2_lines[:2], hip2_lines[2].rstrip(b"\n")])
    assert len(load_hip2(no_nl)) == 3


def corrupt(line: bytes, start: int, text: bytes) -> bytes:
    """Overwrite bytes start.. (1-based) of a record."""
    return line[: start - 1] + text + line[start - 1 + len(text) :]


@pytest.mark.parametrize(
    ("mutate", "line", "field", "detail"),
    [
        (lambda ln: corrupt(ln, 130, b" 9.2x43"), 3, "Hpmag", "'9.2x43' is not a number"),
        (lambda ln: corrupt(ln, 16, b" 0.000O159148"), 3, "RArad", "is not a number"),
        (lambda ln: corrupt(ln, 1, b"    1a"), 3, "HIP", "is not an integer"),
        (lambda ln: corrupt(ln, 153, b" 0.4.2"), 3, "B-V", "is not a number"),
        (lambda ln: corrupt(ln, 130, b"    nan"), 3, "Hpmag", "'nan' is not a number"),
        (lambda ln: corrupt(ln, 16, b"             "), 3, "RArad", "blank"),
        (lambda ln: corrupt(ln, 30, b"  2.000000000"), 3, "DErad", "outside"),
        (lambda ln: ln[:160] + b"\n", 3, "e_B-V", "truncated"),
        (lambda ln: ln[:-1] + b"  99\n", 3, None, "wrong record length"),
    ],
)
def test_hip2_malformed(tmp_path: Path, hip2_lines, mutate, line, field, detail) -> None:
    lines = list(hip2_lines[:5])
    lines[line - 1] = mutate(lines[line - 1])
    path = write(tmp_path, "bad_hip2.dat", lines)
    where = f"bad_hip2.dat, line {line}" + (f", field {field}" if field else "")
    with pytest.raises(CatalogFormatError, match=where) as info:
        load_hip2(path)
    assert detail in str(info.value)
    assert info.value.line == line and info.value.field == field


def test_hip2_empty_and_missing(tmp_path: Path) -> None:
    empty = tmp_path / "empty.dat"
    empty.write_bytes(b"")
    with pytest.raises(CatalogFormatError, match=r"empty\.dat: file is empty"):
        load_hip2(empty)
    with pytest.raises(InputError, match=r"not found: .*nope\.dat"):
        load_hip2(tmp_path / "nope.dat")


# -- hip_main.dat (I/239) -----------------------------------------------------------------
# The first record of hip_main.dat (HIP 1), verbatim from the CDS distribution.
HIP_MAIN_1 = (
    "H|           1| |00 00 00.22|+01 05 20.4| 9.10| |H|000.00091185|+01.08901332| |   3.54|"
    "   -5.20|   -1.88|  1.32|  0.74|  1.39|  1.36|  0.81| 0.32|-0.07|-0.11|-0.24| 0.09|"
    "-0.01| 0.10|-0.01| 0.01| 0.34|  0| 0.74|     1| 9.643|0.020| 9.130|0.019| | 0.482|"
    "0.025|T|0.55|0.03|L| | 9.2043|0.0020|0.017| 87| | 9.17| 9.24|       | | | |          |"
    " |  | 1| | | |  |   |       |     |     |    |S| | |224700|B+00 5077 |          |"
    "          |0.66|F5          |S "
)
# (start, end) bytes from the I/239 ReadMe
SPANS = {
    "HIP": (9, 14),
    "RAhms": (18, 28),
    "DEdms": (30, 40),
    "Vmag": (42, 46),
    "RAdeg": (52, 63),
    "DEdeg": (65, 76),
    "Plx": (80, 86),
    "pmRA": (88, 95),
    "pmDE": (97, 104),
    "HIP2": (211, 216),
    "BTmag": (218, 223),
    "VTmag": (231, 236),
    "B-V": (246, 251),
    "V-I": (261, 264),
    "Hpmag": (275, 281),
    "SpType": (436, 447),
}


def hip_main_line(**fields: str) -> str:
    """The HIP 1 record with some fields replaced (right-aligned, as in the catalogue)."""
    line = HIP_MAIN_1
    for name, value in fields.items():
        start, end = SPANS[name]
        width = end - start + 1
        text = value.ljust(width) if name == "SpType" else value.rjust(width)
        assert len(text) == width, name
        line = line[: start - 1] + text + line[end:]
    return line


def hip_main_file(tmp_path: Path, lines: list[str], name: str = "hip_main.dat") -> Path:
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n", encoding="ascii")
    return path


SIRIUS = {
    "HIP": "32349",
    "Vmag": "-1.44",
    "RAdeg": "101.28715533",
    "DEdeg": "-16.71611586",
    "Plx": "379.21",
    "pmRA": "-546.01",
    "pmDE": "-1223.08",
    "HIP2": "32349",
    "BTmag": "",
    "VTmag": "",
    "B-V": "0.009",
    "V-I": "0.00",
    "Hpmag": "-1.0876",
    "SpType": "A0m...",
}


def test_hip_main_reads_fields(tmp_path: Path) -> None:
    assert len(HIP_MAIN_1) == 450 and HIP_MAIN_1.count("|") == 77
    no_astrometry = hip_main_line(HIP="3", RAdeg="", DEdeg="", Plx="", pmRA="", pmDE="")
    path = hip_main_file(tmp_path, [HIP_MAIN_1, hip_main_line(**SIRIUS), no_astrometry])
    cat = load_hip_main(path)
    assert cat.name == "hip_main" and cat.epoch_yr == 1991.25
    assert cat.ids.tolist() == [1, 32349]  # the entry without astrometry is skipped
    assert np.degrees(cat.ra_rad[0]) == pytest.approx(0.00091185, abs=1e-12)
    assert np.degrees(cat.dec_rad[1]) == pytest.approx(-16.71611586, abs=1e-12)
    assert cat.mags["V"].tolist() == [9.10, -1.44]
    assert cat.mags["BT"][0] == 9.643 and cat.mags["VT"][0] == 9.130
    assert np.isnan(cat.mags["BT"][1]) and np.isnan(cat.colours["BT-VT"][1])
    assert cat.colours["BT-VT"][0] == pytest.approx(0.513)
    assert cat.colours["B-V"].tolist() == [0.482, 0.009]
    assert cat.colours["V-I"][0] == 0.55
    assert cat.mags["Hp"][1] == -1.0876
    assert cat.pm_dec_rad_yr[1] == pytest.approx(-1223.08e-3 * ARCSEC, rel=1e-12)
    assert cat.parallax_rad[0] == pytest.approx(3.54e-3 * ARCSEC, rel=1e-12)
    assert cat.extra["spectral_type"].tolist() == ["F5", "A0m..."]
    # trailing blanks stripped by an editor: still accepted
    stripped = hip_main_file(tmp_path, [HIP_MAIN_1.rstrip()], "stripped.dat")
    assert len(load_hip_main(stripped)) == 1


@pytest.mark.parametrize(
    ("line", "field", "detail"),
    [
        (hip_main_line(Vmag="9.1O"), "Vmag (H5)", "'9.1O' is not a number"),
        (hip_main_line(pmDE="-1.8.8"), "pmDE (H13)", "is not a number"),
        (hip_main_line(RAdeg="400.00000000"), "RAdeg (H8)", "outside"),
        (HIP_MAIN_1[:100], "pmDE (H13)", "truncated"),
        (HIP_MAIN_1.replace("| 9.10|", "|9.10| "), "Vmag (H5)", "expected '|' at byte 47"),
        (HIP_MAIN_1[:-2] + "|S", None, "found 78 '|' field separators, expected 77"),
    ],
)
def test_hip_main_malformed(tmp_path: Path, line: str, field: str | None, detail: str) -> None:
    path = hip_main_file(tmp_path, [HIP_MAIN_1, line])
    where = "hip_main.dat, line 2" + (f", field {field}" if field else "")
    with pytest.raises(CatalogFormatError, match=re.escape(where)) as info:
        load_hip_main(path)
    assert detail in str(info.value)
