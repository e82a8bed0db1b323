"""The time a frame was taken, from its header."""

from __future__ import annotations

import numpy as np

from starsense.solve.frames import frame_time


def test_exif_datetime_original_wins_over_datetime(tmp_path):
    from PIL import Image

    exif = Image.Exif()
    exif[306] = "2020:01:01 00:00:00"  # DateTime (IFD0): when the file was last changed
    exif.get_ifd(0x8769)[36867] = "2019:07:29 20:47:26"  # DateTimeOriginal: the exposure
    path = tmp_path / "f.jpg"  # Pillow writes the Exif sub-IFD in JPEG (not in TIFF)
    Image.fromarray(np.zeros((8, 8), np.uint8)).save(path, exif=exif)
    assert frame_time(path) == ("2019:07:29 20:47:26", "EXIF DateTimeOriginal")


def test_no_time_in_headers(tmp_path):
    from astropy.io import fits
    from PIL import Image

    fits.PrimaryHDU(np.zeros((8, 8), np.uint16)).writeto(tmp_path / "f.fits")
    Image.fromarray(np.zeros((8, 8), np.uint8)).save(tmp_path / "f.png")
    assert frame_time(tmp_path / "f.fits") == (None, None)
    assert frame_time(tmp_path / "f.png") == (None, None)
    (tmp_path / "bad.fits").write_bytes(b"not a fits file")
    assert frame_time(tmp_path / "bad.fits") == (None, None)
