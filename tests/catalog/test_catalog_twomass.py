"""The 2MASS reader: distributed psc_* files and IRSA CSV exports."""

from __future__ import annotations

import gzip
import re
from pathlib import Path

import numpy as np
import pytest

from starsense.catalog import load_twomass
from starsense.catalog.twomass import PSC_COLUMNS
from starsense.errors import CatalogFormatError

# The first line of psc_aaa.gz (2MASS All-Sky Release), 60 '|'-separated fields.
PSC_AAA_1 = (
    "1.119851|-89.91861|0.11|0.06|90|00042876-8955069 |"
    "12.467|0.018|0.021|359.4|12.131|0.025|0.026|224.7|11.963|0.023|0.025|133.7|"
    "AAA|222|111|000|666666|37.2|245|1329023254|0|0|1101364107|s|2000-09-22|64|"
    "302.951|-27.208|1.6|2451809.7124|1.07|1.18|0.81|"
    "12.481|0.014|12.112|0.028|11.98|0.012|332|251|sw|1|1|0|"
    "\\N|\\N|\\N|\\N|0|\\N|59038|1357874|267"
)


def psc_line(**fields: str) -> str:
    values = PSC_AAA_1.split("|")
    for name, value in fields.items():
        values[PSC_COLUMNS.index(name)] = value
    return "|".join(values)


# A faint source with null J and H (upper limits are '\N' in j_m only when undetected).
FAINT = psc_line(
    ra="359.999990",
    decl="45.5",
    designation="23595999+4530000 ",
    j_m="\\N",
    h_m="\\N",
    k_m="15.912",
    pts_key="42",
)


def write(tmp_path: Path, text: str, name: str) -> Path:
    path = tmp_path / name
    data = text.encode("ascii")
    path.write_bytes(gzip.compress(data) if name.endswith(".gz") else data)
    return path


def test_psc_line_layout() -> None:
    assert len(PSC_COLUMNS) == 60 and PSC_AAA_1.count("|") == 59
    assert psc_line() == PSC_AAA_1


@pytest.mark.parametrize("name", ["psc_aaa", "psc_aaa.gz"])
def test_reads_psc(tmp_path: Path, name: str) -> None:
    cat = load_twomass(write(tmp_path, f"{PSC_AAA_1}\n{FAINT}\n", name))
    assert cat.name == "twomass" and cat.epoch_yr == 2000.0 and len(cat) == 2
    assert cat.ids.tolist() == [1101364107, 42]  # pts_key
    np.testing.assert_allclose(np.degrees(cat.ra_rad), [1.119851, 359.99999], atol=1e-12)
    np.testing.assert_allclose(np.degrees(cat.dec_rad), [-89.91861, 45.5], atol=1e-12)
    assert cat.mags["J"][0] == 12.467 and cat.mags["H"][0] == 12.131
    assert cat.mags["Ks"].tolist() == [11.963, 15.912]
    assert np.isnan(cat.mags["J"][1]) and np.isnan(cat.colours["J-Ks"][1])
    assert cat.colours["J-H"][0] == pytest.approx(12.467 - 12.131, abs=1e-12)
    assert cat.colours["H-Ks"][0] == pytest.approx(12.131 - 11.963, abs=1e-12)
    assert cat.pm_ra_rad_yr is None


def test_reads_irsa_csv(tmp_path: Path) -> None:
    text = "ra,dec,j_m,h_m,k_m\n1.119851,-89.91861,12.467,12.131,11.963\n10.5,20.25,,9.1,8.9\n"
    cat = load_twomass(write(tmp_path, text, "irsa.csv"))
    assert cat.ids.tolist() == [0, 1]  # running index without pts_key / cntr
    assert cat.mags["J"][0] == 12.467 and np.isnan(cat.mags["J"][1])
    assert np.degrees(cat.dec_rad[1]) == pytest.approx(20.25, abs=1e-12)
    keyed = "cntr,RA,Dec,j_m,h_m,k_m\n7,1.0,2.0,3.0,4.0,5.0\n"
    assert load_twomass(write(tmp_path, keyed, "keyed.csv")).ids.tolist() == [7]


@pytest.mark.parametrize(
    ("line", "field", "detail"),
    [
        (psc_line(j_m="12.4x7"), "j_m", "'12.4x7' is not a number"),
        (psc_line(ra="\\N"), "ra", "value is missing"),
        (psc_line(decl="-91.0"), "decl", "outside [-90.0, 90.0]"),
        (psc_line(pts_key="1.5"), "pts_key", "'1.5' is not an integer"),
        ("|".join(PSC_AAA_1.split("|")[:20]), "bl_flg", "line has 20 fields, expected 60"),
    ],
)
def test_psc_malformed(tmp_path: Path, line: str, field: str, detail: str) -> None:
    path = write(tmp_path, f"{PSC_AAA_1}\n{PSC_AAA_1}\n{line}\n", "psc_bad")
    with pytest.raises(
        CatalogFormatError, match=re.escape(f"psc_bad, line 3, field {field}: ")
    ) as info:
        load_twomass(path)
    assert detail in str(info.value)


def test_csv_malformed(tmp_path: Path) -> None:
    with pytest.raises(CatalogFormatError, match=r"bad\.csv, line 1, field h_m: required column"):
        load_twomass(write(tmp_path, "ra,dec,j_m,k_m\n1,2,3,4\n", "bad.csv"))
    with pytest.raises(CatalogFormatError, match=r"bad\.csv, line 3, field k_m: 'abc' is not"):
        load_twomass(write(tmp_path, "ra,dec,j_m,h_m,k_m\n1,2,3,4,5\n1,2,3,4,abc\n", "bad.csv"))
    with pytest.raises(CatalogFormatError, match=r"bad\.csv, line 2, field ra: .*outside"):
        load_twomass(write(tmp_path, "ra,dec,j_m,h_m,k_m\n360.5,2,3,4,5\n", "bad.csv"))
    with pytest.raises(CatalogFormatError, match=r"empty\.csv: file is empty"):
        load_twomass(write(tmp_path, "\n", "empty.csv"))
    with pytest.raises(CatalogFormatError, match=r"odd\.txt, line 1: not a 2MASS psc file"):
        load_twomass(write(tmp_path, "1 2 3\n", "odd.txt"))
