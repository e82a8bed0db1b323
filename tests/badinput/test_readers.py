"""The reading helpers and the image loader's limits, directly (the CLI suite runs them whole)."""

from __future__ import annotations

import numpy as np
import pytest
from bad_files import fits_bytes, png_bytes

from starsense._io import read_text, readable_file
from starsense.errors import InputError
from starsense.solve.frames import DEFAULT_MAX_PIXELS, MAX_PIXELS_ENV, load_image


def test_read_text_names_the_file_and_the_byte(tmp_path):
    path = tmp_path / "s.toml"
    path.write_bytes(b'name = "ok"\nnote = "caf\xe9"\n')
    with pytest.raises(InputError, match=r"s\.toml is not UTF-8 text: byte 0xe9 at line 2"):
        read_text(path, "sensor file")


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda d: "", r"^thing path is empty"),
        (lambda d: "   ", r"^thing path is empty"),
        (lambda d: d / "missing", r"^thing not found: .*missing$"),
        (lambda d: d, r"is a directory, not a file$"),
        (lambda d: "/dev/null", r"/dev/null is not a regular file$"),
    ],
)
def test_readable_file_refusals(tmp_path, make, message):
    with pytest.raises(InputError, match=message):
        readable_file(make(tmp_path), "thing")


def test_pixel_limit_is_stated_and_can_be_raised(tmp_path, monkeypatch):
    path = tmp_path / "f.png"
    path.write_bytes(png_bytes(np.ones((4, 5), np.uint8)))
    with pytest.raises(InputError, match=r"4 x 5 pixels \(20\) is larger than the limit of 19"):
        load_image(path, max_pixels=19)
    assert load_image(path, max_pixels=20).shape == (4, 5)
    monkeypatch.setenv(MAX_PIXELS_ENV, "19")
    with pytest.raises(InputError, match="STARSENSE_MAX_PIXELS to raise it"):
        load_image(path)
    monkeypatch.setenv(MAX_PIXELS_ENV, "many")
    with pytest.raises(InputError, match=r"STARSENSE_MAX_PIXELS must be a positive integer"):
        load_image(path)
    monkeypatch.delenv(MAX_PIXELS_ENV)
    assert DEFAULT_MAX_PIXELS == 16384 * 16384
    assert load_image(path).shape == (4, 5)


def test_fits_limit_is_checked_from_the_header(tmp_path):
    path = tmp_path / "f.fits"
    path.write_bytes(fits_bytes(np.zeros((6, 7), np.int16)))
    with pytest.raises(InputError, match=r"6 x 7 pixels \(42\)"):
        load_image(path, max_pixels=41)
    assert load_image(path, max_pixels=42).shape == (6, 7)
