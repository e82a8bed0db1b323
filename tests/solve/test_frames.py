"""Frame loading: formats, bit depths, colour to luminance, bad files."""

from __future__ import annotations

import numpy as np
import pytest

from starsense.errors import InputError
from starsense.solve.frames import load_image


def test_16bit_tiff_and_8bit_png_round_trip(tmp_path):
    from PIL import Image

    a16 = (np.arange(12 * 10).reshape(12, 10) * 500).astype(np.uint16)
    Image.fromarray(a16).save(tmp_path / "f.tiff")
    assert np.array_equal(load_image(tmp_path / "f.tiff"), a16)
    a8 = (np.arange(12 * 10).reshape(12, 10) % 256).astype(np.uint8)
    Image.fromarray(a8).save(tmp_path / "f.png")
    assert np.array_equal(load_image(tmp_path / "f.png"), a8)


def test_colour_to_luminance(tmp_path):
    from PIL import Image

    rgb = np.zeros((4, 5, 3), dtype=np.uint8)
    rgb[..., 0], rgb[..., 1], rgb[..., 2] = 100, 200, 50
    Image.fromarray(rgb).save(tmp_path / "c.png")
    # BT.601: 0.299 * 100 + 0.587 * 200 + 0.114 * 50 = 153.0
    assert np.allclose(load_image(tmp_path / "c.png"), 153.0)


def test_fits(tmp_path):
    from astropy.io import fits

    a = np.arange(20, dtype=np.int16).reshape(4, 5)
    fits.PrimaryHDU(a).writeto(tmp_path / "f.fits")
    assert np.array_equal(load_image(tmp_path / "f.fits"), a)


def test_esa_frames_load(shared_dir):
    for path in sorted((shared_dir / "data/images/esa").glob("*.tiff")):
        a = load_image(path)
        assert a.shape == (768, 1024) and a.dtype == np.uint16


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("x.xcf", b"gimp xcf", "unknown image type '.xcf'"),
        ("x.bmp", b"BM", "not a readable image"),
        ("x.tiff", b"not a tiff", "not a readable image"),
        ("x.fits", b"SIMPLE  = garbage", "not a readable FITS file"),
    ],
)
def test_bad_files(tmp_path, name, content, message):
    (tmp_path / name).write_bytes(content)
    with pytest.raises(InputError, match=message):
        load_image(tmp_path / name)
    with pytest.raises(InputError, match="image not found"):
        load_image(tmp_path / "absent.tiff")
