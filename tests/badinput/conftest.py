"""The folder of bad input files the bad-input suite runs on, built once per session, and the
memory guard every test here runs under.

Each file is the smallest one showing one problem (builders in tests/_support/bad_files.py).
The guard caps the test process's address space (``RLIMIT_AS``) at 4 GB while a test runs, so
that an input which makes a command ask for tens of GiB fails that test with a MemoryError
instead of taking the machine's memory.
"""

from __future__ import annotations

import resource
from pathlib import Path

import numpy as np
import pytest
from bad_files import (
    GAIA_CSV,
    SENSOR_TOML,
    TLE_LINE1,
    TLE_LINE2,
    bsc5_bytes,
    fits_bytes,
    fits_card,
    gaia_parquet,
    png_bytes,
    png_claiming,
    tle_text,
)

#: the address-space cap of a bad-input test, bytes
MEMORY_LIMIT_BYTES = 4_000_000_000


def _address_space_bytes() -> int:
    with open("/proc/self/status", encoding="ascii") as fh:
        for line in fh:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    return 0  # pragma: no cover - not Linux


@pytest.fixture(autouse=True)
def memory_guard():
    """Cap the address space at 4 GB for the test (above what the process already holds).

    The soft limit only, restored afterwards; a session that already holds more (other suites
    run first, with their caches) gets 1 GB above what it holds.
    """
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    cap = max(MEMORY_LIMIT_BYTES, _address_space_bytes() + 1_000_000_000)
    if hard != resource.RLIM_INFINITY:
        cap = min(cap, hard)
    if soft == resource.RLIM_INFINITY or soft > cap:
        resource.setrlimit(resource.RLIMIT_AS, (cap, hard))
    try:
        yield cap
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def _sensor(**changes: str) -> str:
    """The valid sensor TOML with lines replaced: ``key="new line"`` replaces the line of key."""
    lines = SENSOR_TOML.splitlines()
    for key, new in changes.items():
        lines = [new if ln.split("=")[0].strip() == key else ln for ln in lines]
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="session")
def bad_dir(tmp_path_factory) -> Path:
    """A folder of bad (and a few valid) inputs; see the names."""
    d = tmp_path_factory.mktemp("bad")
    (d / "adir.toml").mkdir()
    (d / "adir.png").mkdir()
    (d / "adir.csv").mkdir()
    (d / "file.txt").write_text("not a folder\n")
    (d / "latin1.toml").write_bytes(SENSOR_TOML.replace("tiny", "caf\xe9").encode("latin-1"))
    (d / "gain.toml").write_text(
        SENSOR_TOML.replace("gain_counts_per_e = 1.0", "gain_counts_per_e = 1e-30")
    )
    ok = fits_bytes(np.arange(100, dtype=np.uint16).reshape(10, 10))
    (d / "ok.fits").write_bytes(ok)
    (d / "nobitpix.fits").write_bytes(fits_card(ok, "BITPIX", None))
    (d / "blankbitpix.fits").write_bytes(fits_card(ok, "BITPIX", ""))
    (d / "short.fits").write_bytes(fits_card(ok, "NAXIS1", "1000"))
    (d / "huge.fits").write_bytes(fits_card(fits_card(ok, "NAXIS1", "65535"), "NAXIS2", "65535"))
    (d / "nan.fits").write_bytes(fits_bytes(np.full((8, 8), np.nan, np.float32)))
    (d / "onebit.png").write_bytes(png_bytes(np.zeros((8, 8), bool)))
    (d / "huge.png").write_bytes(png_claiming(200_000, 200_000))
    (d / "huge2.png").write_bytes(png_claiming(65_535, 65_535))
    raw = gaia_parquet(d / "tmp.parquet").read_bytes()
    (d / "tmp.parquet").unlink()
    (d / "badschema.parquet").write_bytes(raw.replace(b"zzzzzz", b"\xff\xfezzzz"))
    rows = GAIA_CSV.splitlines()
    (d / "dup.csv").write_text("\n".join([rows[0], *rows[1:], *rows[1:]]) + "\n")
    (d / "g1e300.csv").write_text(GAIA_CSV.replace("17.5", "1e300"))
    (d / "baddec.csv").write_text("ra,dec,V\n1.0,2.0,3.0\n2.0,abc,4.0\n")
    (d / "sentinel.bsc5").write_bytes(bsc5_bytes([150, 32767]))
    _sensor_files(d)
    _mission_files(d)
    return d


def _sensor_files(d: Path) -> None:
    """Sensor TOMLs each with one fault of the schema (types, geometry, size)."""
    (d / "name.toml").write_text(_sensor(name='name = ["a"]'))
    (d / "budget.toml").write_text(SENSOR_TOML + "\n[budget]\nsource = 5\n")
    (d / "quoted.toml").write_text(
        SENSOR_TOML + '\n[quoted]\nsource = "vendor"\nnea_cross_arcsec = -1.0\n'
    )
    # a 1024 px detector of 5 um behind 10 mm: r = 0.36 focal lengths at the corner, past the
    # fold of k1 = -10 at r = 1 / sqrt(30) = 0.18 (d r_d / d r = 1 + 3 k1 r^2 = 0)
    (d / "k1.toml").write_text(
        _sensor(
            focal_length_m="focal_length_m = 0.01", columns="columns = 1024", rows="rows = 1024"
        ).replace("[detector]", "distortion_k1 = -10\n\n[detector]")
    )
    # 8000 columns of 5 um behind 0.5 mm (at f/1): 2 atan(20 mm / 0.5 mm) = 177.1 deg across
    # the columns; the 48 rows span 27 deg
    (d / "wide.toml").write_text(
        _sensor(
            focal_length_m="focal_length_m = 0.0005",
            aperture_m="aperture_m = 0.0005",
            columns="columns = 8000",
        )
    )
    (d / "big.toml").write_text(
        _sensor(
            focal_length_m="focal_length_m = 5.0", columns="columns = 100000", rows="rows = 100000"
        )
    )
    (d / "onepx.toml").write_text(_sensor(columns="columns = 1", rows="rows = 1"))
    (d / "lit.toml").write_text(SENSOR_TOML + "\n[detection]\nlit_pixel_counts = 1e300\n")


def _mission_files(d: Path) -> None:
    """TLEs with values out of range and attitude files a user might give by mistake."""
    (d / "ok.tle").write_text(tle_text(TLE_LINE1, TLE_LINE2))
    (d / "day0.tle").write_text(tle_text(TLE_LINE1[:20] + "000.5" + TLE_LINE1[25:], TLE_LINE2))
    (d / "day400.tle").write_text(tle_text(TLE_LINE1[:20] + "400.5" + TLE_LINE1[25:], TLE_LINE2))
    (d / "day366.tle").write_text(  # 2023 has 365 days: day 366.5 is past its end
        tle_text(TLE_LINE1[:18] + "23366.5" + TLE_LINE1[25:], TLE_LINE2)
    )
    (d / "inc200.tle").write_text(tle_text(TLE_LINE1, TLE_LINE2[:8] + "200.0000" + TLE_LINE2[16:]))
    (d / "latin1.csv").write_bytes(b"t_s,qx,qy,qz,qw\n0,0,0,0,1\n\xe9\n")
    (d / "qnan.csv").write_text("t_s,qx,qy,qz,qw\n0,0,0,0,1\n\n60,nan,0,0,1\n")
