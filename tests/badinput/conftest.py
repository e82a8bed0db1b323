"""The folder of bad input files the bad-input suite runs on, built once per session.

Each file is the smallest one showing one problem (builders in tests/_support/bad_files.py).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from bad_files import (
    GAIA_CSV,
    SENSOR_TOML,
    bsc5_bytes,
    fits_bytes,
    fits_card,
    gaia_parquet,
    png_bytes,
    png_claiming,
)


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
    return d
