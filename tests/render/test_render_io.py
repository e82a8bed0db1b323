"""Writing frames: TIFF / PNG / FITS round trips, JSON truth, atomic writes."""

from __future__ import annotations

import dataclasses
import json
import math
import os

import numpy as np
import pytest
from astropy.io import fits
from PIL import Image

from starsense.errors import InputError
from starsense.render import render_frame, write_frame
from starsense.units import DEG


@pytest.fixture(scope="module")
def frame(st16, attitude, catalog):
    return render_frame(st16, attitude, catalog, rate_rad_s=(0.5 * DEG, 0.0, 0.0), rng=3)


@pytest.mark.parametrize("name", ["frame.tif", "frame.TIFF", "frame.png"])
def test_pillow_round_trip(tmp_path, frame, name) -> None:
    path = write_frame(tmp_path / name, frame)
    with Image.open(path) as im:
        assert im.mode == "I;16"
        back = np.array(im)
    assert back.dtype == np.uint16
    assert np.array_equal(back, frame.image)
    truth = json.loads((tmp_path / (name + ".json")).read_text())
    assert truth == json.loads(json.dumps(frame.truth_dict()))
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([name, name + ".json"])


def test_fits_round_trip(tmp_path, frame) -> None:
    path = write_frame(tmp_path / "frame.fits", frame)
    with fits.open(path) as hdul:
        data = hdul[0].data
        header = hdul[0].header
        assert np.array_equal(data, frame.image)
        assert data.dtype.kind == "u"  # astropy restores uint16 from BZERO = 32768
        assert header["EXPTIME"] == pytest.approx(0.1)
        assert header["SENSOR"] == "st16"
        assert header["RA"] == pytest.approx(math.degrees(frame.truth.ra_rad))
    assert (tmp_path / "frame.fits.json").is_file()


def test_uint32_frames_go_to_tiff_and_fits_not_png(tmp_path, st16, attitude, catalog) -> None:
    sensor = st16.with_(detector=dataclasses.replace(st16.detector, bit_depth=20))
    f = render_frame(sensor, attitude, catalog, max_mag=4.0, rng=1)
    assert f.image.dtype == np.uint32
    with Image.open(write_frame(tmp_path / "f20.tif", f)) as im:
        assert np.array_equal(np.array(im), f.image)  # 32-bit signed TIFF, exact below 2^31
    with fits.open(write_frame(tmp_path / "f20.fits", f)) as hdul:
        assert np.array_equal(hdul[0].data, f.image)
    with pytest.raises(InputError, match="PNG holds 16-bit"):
        write_frame(tmp_path / "f20.png", f)
    assert not (tmp_path / "f20.png").exists()
    assert not (tmp_path / "f20.png.json").exists()


def test_bad_extension_raises_and_writes_nothing(tmp_path, frame) -> None:
    for name in ("frame.jpg", "frame", "frame.tif.bak"):
        with pytest.raises(InputError, match="unknown image extension"):
            write_frame(tmp_path / name, frame)
    with pytest.raises(InputError, match="directory"):
        write_frame(tmp_path / "missing" / "frame.tif", frame)
    assert list(tmp_path.iterdir()) == []


def test_failed_write_leaves_no_partial_files(tmp_path, frame, monkeypatch) -> None:
    # An error in the middle of writing (here: the image encoder) leaves neither the image,
    # the JSON nor the temporary files; an existing file is left as it was.
    target = tmp_path / "frame.tif"
    target.write_bytes(b"old")

    def boom(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr("starsense.render.io._write_pillow", boom)
    with pytest.raises(OSError, match="disk full"):
        write_frame(target, frame)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frame.tif"]
    assert target.read_bytes() == b"old"


def test_written_files_are_readable_by_others(tmp_path, frame) -> None:
    # temporary files are created 0600; the written ones follow the umask like any file
    mask = os.umask(0o022)
    try:
        path = write_frame(tmp_path / "frame.tif", frame)
    finally:
        os.umask(mask)
    assert path.stat().st_mode & 0o777 == 0o644
