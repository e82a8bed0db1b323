"""The Tycho-2 reader, on records in the I/259 tyc2.dat format."""

from __future__ import annotations

import gzip
import re
from pathlib import Path

import numpy as np
import pytest

from starsense.catalog import load_tycho2
from starsense.catalog.tycho2 import pack_tyc, unpack_tyc
from starsense.errors import CatalogFormatError

MAS = np.pi / (180 * 3600 * 1000)

# The first records of tyc2.dat (TYC 1-8-1, 1-13-1, 1-33-1), as distributed by CDS.
TYC_1_8_1 = (
    "0001 00008 1| |  2.31750494|  2.23184345|  -16.3|   -9.0| 68| 73| 1.7| 1.8|1958.89|"
    "1951.94| 4|1.0|1.0|0.9|1.0|12.146|0.158|12.146|0.223|999| |         |  2.31754222|"
    "  2.23186444|1.67|1.54| 88.0|100.8| |-0.2"
)
TYC_1_13_1 = (
    "0001 00013 1| |  1.12558209|  2.26739400|   27.7|   -0.5|  9| 12| 1.2| 1.2|1990.76|"
    "1989.25| 8|1.0|0.8|1.0|0.7|10.488|0.038| 8.670|0.015|999|T|         |  1.12551889|"
    "  2.26739556|1.81|1.52|  9.3| 12.7| |-0.2"
)
TYC_1_33_1 = (  # pflag X: no mean position, no proper motion, BT only
    "0001 00033 1|X|            |            |       |       |   |   |    |    |       |"
    "       |  |   |   |   |   |12.512|0.228|      |     |  5|T|         |  1.58432611|"
    "  0.94286667|1.69|1.58|115.5|125.1| | 0.0"
)
# A Hipparcos star (HIP field filled), built from TYC 1-13-1 in the same layout.
# a second component (TYC3 = 2) of TYC 1-13 with a HIP number: ids are unique in Tycho-2
WITH_HIP = "0001 00013 2" + TYC_1_13_1[12:142] + "    12  " + TYC_1_13_1[150:]


def write(tmp_path: Path, lines: list[str], name: str = "tyc2.dat") -> Path:
    path = tmp_path / name
    data = ("\n".join(lines) + "\n").encode("ascii")
    if name.endswith(".gz"):
        data = gzip.compress(data)
    path.write_bytes(data)
    return path


def test_reads_the_i259_records(tmp_path: Path) -> None:
    assert all(len(x) == 206 for x in (TYC_1_8_1, TYC_1_13_1, TYC_1_33_1, WITH_HIP))
    cat = load_tycho2(write(tmp_path, [TYC_1_8_1, TYC_1_13_1, TYC_1_33_1, WITH_HIP]))
    assert cat.name == "tycho2" and cat.epoch_yr == 2000.0 and len(cat) == 4
    assert cat.ids.tolist()[:3] == [1000081, 1000131, 1000331]
    np.testing.assert_array_equal(unpack_tyc(cat.ids[:2]), [[1, 1], [8, 13], [1, 1]])
    # mean J2000 position, and for pflag X the observed one
    np.testing.assert_allclose(
        np.degrees(cat.ra_rad[:3]), [2.31750494, 1.12558209, 1.58432611], rtol=0, atol=1e-12
    )
    np.testing.assert_allclose(
        np.degrees(cat.dec_rad[:3]), [2.23184345, 2.26739400, 0.94286667], rtol=0, atol=1e-12
    )
    assert cat.pm_ra_rad_yr[0] == pytest.approx(-16.3 * MAS, rel=1e-12)
    assert cat.pm_dec_rad_yr[1] == pytest.approx(-0.5 * MAS, rel=1e-12)
    assert np.isnan(cat.pm_ra_rad_yr[2]) and not cat.extra["has_mean_position"][2]
    assert cat.mags["BT"][:3].tolist() == [12.146, 10.488, 12.512]
    assert cat.mags["VT"][1] == 8.670 and np.isnan(cat.mags["VT"][2])
    # ESA 1997 Vol. 1 Sect. 1.3 Eq. 1.3.20: V = VT - 0.090 (BT-VT), B-V = 0.850 (BT-VT)
    assert cat.mags["V"][1] == pytest.approx(8.670 - 0.090 * (10.488 - 8.670), abs=1e-12)
    assert cat.colours["B-V"][1] == pytest.approx(0.850 * (10.488 - 8.670), abs=1e-12)
    assert cat.colours["BT-VT"][0] == pytest.approx(0.0, abs=1e-12)
    assert np.isnan(cat.mags["V"][2]) and np.isnan(cat.colours["B-V"][2])
    assert cat.extra["HIP"].tolist() == [0, 0, 0, 12]
    # the X star does not move; the others do
    moved = cat.propagate(2010.0)
    assert moved.ra_rad[2] == cat.ra_rad[2]
    assert moved.dec_rad[0] != cat.dec_rad[0]


def test_gzip_and_crlf(tmp_path: Path) -> None:
    cat = load_tycho2(write(tmp_path, [TYC_1_8_1, TYC_1_13_1], "tyc2.dat.00.gz"))
    assert len(cat) == 2
    crlf = tmp_path / "crlf.dat"
    crlf.write_bytes(f"{TYC_1_8_1}\r\n{TYC_1_13_1}\r\n".encode())
    assert len(load_tycho2(crlf)) == 2


def test_pack_tyc() -> None:
    assert pack_tyc(9537, 12121, 3) == 9537_12121_3
    assert [int(x) for x in unpack_tyc(pack_tyc(9537, 12121, 3))] == [9537, 12121, 3]


def replace(line: str, start: int, text: str) -> str:
    return line[: start - 1] + text + line[start - 1 + len(text) :]


@pytest.mark.parametrize(
    ("line", "field", "detail"),
    [
        (replace(TYC_1_13_1, 124, " 8.6a0"), "VTmag", "'8.6a0' is not a number"),
        (replace(TYC_1_13_1, 16, "  1.125582O9"), "RAmdeg", "is not a number"),
        (replace(TYC_1_13_1, 1, "000a"), "TYC1", "is not an integer"),
        (replace(TYC_1_13_1, 29, " 92.26739400"), "DEmdeg", "outside [-90.0, 90.0]"),
        (replace(TYC_1_13_1, 16, "            "), "RAmdeg", "pflag is not 'X'"),
        (TYC_1_13_1[:120], "e_BTmag", "truncated"),
        (replace(TYC_1_13_1, 40, "|0"), "DEmdeg", "expected '|' at byte 41"),
        (replace(TYC_1_13_1, 41, " "), None, "found 30 '|' field separators, expected 31"),
    ],
)
def test_malformed(tmp_path: Path, line: str, field: str | None, detail: str) -> None:
    path = write(tmp_path, [TYC_1_8_1, line])
    where = "tyc2.dat, line 2" + (f", field {field}" if field else "") + ": "
    with pytest.raises(CatalogFormatError, match=re.escape(where)) as info:
        load_tycho2(path)
    assert detail in str(info.value)


def test_wrong_length_and_empty(tmp_path: Path) -> None:
    with pytest.raises(CatalogFormatError, match="line 2: record is 210 bytes long"):
        load_tycho2(write(tmp_path, [TYC_1_8_1, TYC_1_8_1 + "|1.0"]))
    with pytest.raises(CatalogFormatError, match=r"tyc2\.dat: file is empty"):
        load_tycho2(write(tmp_path, [""]))
