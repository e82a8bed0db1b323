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


def _tiff_with_times(path, changed: str | None, original: str | None) -> None:
    """An 8 x 8 8-bit TIFF whose IFD0 holds DateTime and whose Exif IFD DateTimeOriginal.

    Written byte by byte: Pillow writes no Exif IFD in a TIFF, and cameras do.
    """
    import struct

    ascii_ = {k: v.encode() + b"\x00" for k, v in (("dt", changed), ("orig", original)) if v}
    entries = [(256, 3, 1, 8), (257, 3, 1, 8), (258, 3, 1, 8), (259, 3, 1, 1), (262, 3, 1, 1)]
    entries += [(273, 4, 1, None), (277, 3, 1, 1), (278, 3, 1, 8), (279, 4, 1, 64)]
    if "dt" in ascii_:
        entries.append((306, 2, len(ascii_["dt"]), "dt"))
    if "orig" in ascii_:
        entries.append((34665, 4, 1, "exif"))
    ifd0 = 8
    exif = ifd0 + 2 + 12 * len(entries) + 4
    extra = exif + (2 + 12 + 4 if "orig" in ascii_ else 0)
    where = {}
    for k, v in ascii_.items():
        where[k] = extra
        extra += len(v)
    pixels = extra

    def entry(tag, kind, count, value):
        value = {None: pixels, "exif": exif}.get(value, where.get(value, value))
        packed = struct.pack("<H", value) + b"\x00\x00" if kind == 3 else struct.pack("<I", value)
        return struct.pack("<HHI", tag, kind, count) + packed

    out = b"II*\x00" + struct.pack("<I", ifd0) + struct.pack("<H", len(entries))
    out += b"".join(entry(*e) for e in entries) + struct.pack("<I", 0)
    if "orig" in ascii_:
        out += struct.pack("<H", 1) + entry(36867, 2, len(ascii_["orig"]), "orig")
        out += struct.pack("<I", 0)
    out += b"".join(ascii_.values()) + bytes(range(64))
    path.write_bytes(out)


def test_tiff_times_read_as_pillow_reads_them(tmp_path):
    # TIFF headers are read with tifffile (the frame's reader), not Pillow: Pillow's reading of
    # the same files is the reference
    from PIL import Image

    cases = [
        ("2020:01:01 00:00:00", "2019:07:29 20:47:26"),
        ("2020:01:01 00:00:00", None),
        (None, "2019:07:29 20:47:26"),
        (None, None),
        ("0000:00:00 00:00:00", None),  # a camera's blank date
    ]
    for i, (changed, original) in enumerate(cases):
        path = tmp_path / f"f{i}.tiff"
        _tiff_with_times(path, changed, original)
        with Image.open(path) as im:
            assert np.array_equal(np.array(im), np.arange(64, dtype=np.uint8).reshape(8, 8))
            exif = im.getexif()
            pil_original = exif.get_ifd(0x8769).get(36867)
            pil_changed = exif.get(306)
        assert (pil_changed, pil_original) == (changed, original)  # the file is as meant
        expected = (None, None)
        if original:
            expected = (original, "EXIF DateTimeOriginal")
        elif changed and changed.strip(" :0"):
            expected = (changed, "EXIF DateTime")
        assert frame_time(path) == expected
