"""Fuzzed files: only the project's own exceptions escape the readers.

A valid file of each format (conftest.py) is mutated by hypothesis (bytes flipped, set,
inserted, deleted, the file cut short); the reader must either read it or raise a
:class:`~starsense.errors.StarsenseError` subclass. Any other exception, or a warning (warnings
are errors in the test run), fails. A few hundred examples per reader in the default run; many
more under ``slow``.
"""

from __future__ import annotations

import gzip
import io
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from bad_files import (
    GAIA_CSV,
    HIP_MAIN_LINE,
    PSC_LINE,
    SENSOR_TOML,
    TYC_LINE,
    bsc5_bytes,
    fits_bytes,
    gaia_binary,
    gaia_parquet,
    hip2_lines,
    png_bytes,
)
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from starsense.catalog import (
    load_bsc5,
    load_gaia,
    load_hip2,
    load_hip_main,
    load_twomass,
    load_tycho2,
)
from starsense.errors import StarsenseError
from starsense.sensor import load_sensor
from starsense.solve.frames import load_image

FAST = 150
SLOW = 600  # 3000 each (36,000 files) ran clean once: 5 min, too long for every CI run


@st.composite
def mutated(draw, seed: bytes) -> bytes:
    """``seed`` with 1-4 random edits, or (rarely) random bytes."""
    if draw(st.integers(0, 19)) == 0:
        return draw(st.binary(max_size=4 * len(seed)))
    data = bytearray(seed)
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["flip", "set", "insert", "delete", "cut"]))
        pos = draw(st.integers(0, max(len(data) - 1, 0)))
        if op == "flip" and data:
            data[pos] ^= 1 << draw(st.integers(0, 7))
        elif op == "set" and data:
            data[pos] = draw(st.sampled_from(b"\x00\xff-+.eE9 |,\n\r\t\x80NnaI"))
        elif op == "insert":
            data[pos:pos] = draw(st.binary(min_size=1, max_size=16))
        elif op == "delete":
            del data[pos : pos + draw(st.integers(1, 16))]
        elif op == "cut":
            del data[pos:]
    return bytes(data)


def _seed_files() -> dict[str, tuple[str, bytes, Callable[[Path], object]]]:
    """name -> (file name, valid bytes, reader)."""

    def image(path):  # a low pixel limit: a mutated header must not make the test allocate
        return load_image(path, max_pixels=1 << 20)

    with tempfile.TemporaryDirectory() as d:
        parquet = gaia_parquet(Path(d) / "g.parquet", "parallax").read_bytes()
    frame = (np.arange(64 * 48, dtype=np.uint16) % 4000).reshape(48, 64)
    return {
        "bsc5": ("bsc5", bsc5_bytes([150, 300, -46]), load_bsc5),
        "hip2": ("hip2.dat", hip2_lines(10), load_hip2),
        "hip_main": ("hip_main.dat", (HIP_MAIN_LINE + "\n").encode(), load_hip_main),
        "tycho2": ("tyc2.dat", (TYC_LINE + "\n").encode(), load_tycho2),
        "twomass_psc": ("psc_aaa.gz", gzip.compress((PSC_LINE + "\n").encode()), load_twomass),
        "gaia_csv": ("gaia.csv", GAIA_CSV.encode(), load_gaia),
        "gaia_parquet": ("gaia.parquet", parquet, load_gaia),
        "gaia_binary": ("gaia_merged.bin", gaia_binary(3), load_gaia),
        "png": ("frame.png", png_bytes(frame), image),
        "fits": ("frame.fits", fits_bytes(frame), image),
        "tiff": ("frame.tif", _tiff(frame), image),
        "sensor": ("sensor.toml", SENSOR_TOML.encode(), load_sensor),
    }


def _tiff(frame: np.ndarray) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(frame).save(buf, format="TIFF")
    return buf.getvalue()


SEEDS = _seed_files()


def _check(name: str, data: bytes, folder: Path) -> None:
    filename, _, reader = SEEDS[name]
    path = folder / filename
    path.write_bytes(data)
    try:
        reader(path)
    except StarsenseError:
        pass


@pytest.mark.parametrize("name", list(SEEDS))
def test_seed_files_are_valid(name, tmp_path):
    filename, data, reader = SEEDS[name]
    (tmp_path / filename).write_bytes(data)
    reader(tmp_path / filename)  # the mutations start from a file that reads


def _fuzz(name: str, n: int) -> None:
    folder = Path(tempfile.mkdtemp(prefix="starsense-fuzz-"))

    @settings(
        max_examples=n,
        deadline=None,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    )
    @given(data=mutated(SEEDS[name][1]))
    def run(data):
        _check(name, data, folder)

    try:
        run()
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@pytest.mark.parametrize("name", list(SEEDS))
def test_fuzz_only_project_errors(name):
    _fuzz(name, FAST)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(SEEDS))
def test_fuzz_only_project_errors_long(name):
    _fuzz(name, SLOW)
