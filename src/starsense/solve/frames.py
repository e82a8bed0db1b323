"""Reading camera frames: TIFF, PNG, JPEG (Pillow) and FITS (astropy), 8 to 32 bits.

Colour frames are converted to luminance with the ITU-R BT.601 weights (0.299 R + 0.587 G +
0.114 B), as Pillow's "L" mode does, but in floating point so 16-bit colour keeps its depth.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from starsense.errors import InputError

LUMA_WEIGHTS = np.array([0.299, 0.587, 0.114])
FITS_SUFFIXES = {".fits", ".fit", ".fts"}
PILLOW_SUFFIXES = {".tif", ".tiff", ".png", ".jpg", ".jpeg"}


def load_image(path: str | Path) -> np.ndarray:
    """Load a frame as a 2-D array (rows, columns).

    Monochrome frames keep their integer type; colour frames are converted to luminance
    (float).

    Parameters
    ----------
    path : path-like
        TIFF, PNG, JPEG or FITS file.

    Returns
    -------
    ndarray, shape (rows, columns)

    Raises
    ------
    InputError
        The file is missing, of an unknown type, unreadable, or not a 2-D image.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"image not found: {p}")
    suffix = p.suffix.lower()
    if suffix in FITS_SUFFIXES:
        from astropy.io import fits

        try:
            with fits.open(p) as hdul:
                data = next((h.data for h in hdul if getattr(h, "data", None) is not None), None)
                a = None if data is None else np.array(data)
        except (OSError, ValueError) as exc:
            raise InputError(f"{p}: not a readable FITS file ({exc})") from None
        if a is None:
            raise InputError(f"{p}: FITS file holds no image data")
    elif suffix in PILLOW_SUFFIXES:
        from PIL import Image, UnidentifiedImageError

        try:
            with Image.open(p) as im:
                a = np.array(im)
        except (OSError, UnidentifiedImageError) as exc:
            raise InputError(f"{p}: not a readable image ({exc})") from None
    else:
        known = ", ".join(sorted(FITS_SUFFIXES | PILLOW_SUFFIXES))
        raise InputError(f"{p}: unknown image type {suffix!r}; known: {known}")
    if a.ndim == 3 and a.shape[-1] in (3, 4):  # RGB(A): luminance, alpha dropped
        a = a[..., :3].astype(float) @ LUMA_WEIGHTS
    elif a.ndim == 3 and a.shape[0] in (3, 4):  # FITS planes first
        a = np.tensordot(LUMA_WEIGHTS, a[:3].astype(float), axes=1)
    if a.ndim != 2:
        raise InputError(f"{p}: expected a 2-D (monochrome or colour) image, got shape {a.shape}")
    if a.size == 0:
        raise InputError(f"{p}: image is empty")
    return a


#: EXIF tags holding the time a frame was taken: DateTimeOriginal (Exif IFD), DateTime (IFD0)
_EXIF_IFD, _EXIF_DATETIME_ORIGINAL, _EXIF_DATETIME = 0x8769, 36867, 306


def frame_time(path: str | Path) -> tuple[str | None, str | None]:
    """Return the time a frame was taken, from its header, and where it was found.

    FITS: ``DATE-OBS`` (ISO 8601, UTC by the FITS standard), of the first HDU that has it.
    TIFF / JPEG / PNG: EXIF ``DateTimeOriginal``, else ``DateTime`` (``YYYY:MM:DD HH:MM:SS``;
    EXIF gives no time zone, so the camera clock is taken as UTC).

    Parameters
    ----------
    path : path-like
        The frame.

    Returns
    -------
    time, source : str or None
        The time as written (ISO 8601 or EXIF form) and ``"FITS DATE-OBS"``,
        ``"EXIF DateTimeOriginal"`` or ``"EXIF DateTime"``; (None, None) when there is none.
    """
    p = Path(path)
    suffix = p.suffix.lower()
    try:
        if suffix in FITS_SUFFIXES:
            from astropy.io import fits

            with fits.open(p) as hdul:
                for hdu in hdul:
                    value = hdu.header.get("DATE-OBS")
                    if value:
                        return str(value), "FITS DATE-OBS"
        elif suffix in PILLOW_SUFFIXES:
            from PIL import Image

            with Image.open(p) as im:
                exif = im.getexif()
                original = exif.get_ifd(_EXIF_IFD).get(_EXIF_DATETIME_ORIGINAL)
                if original:
                    return str(original).strip("\x00 "), "EXIF DateTimeOriginal"
                if exif.get(_EXIF_DATETIME):
                    return str(exif[_EXIF_DATETIME]).strip("\x00 "), "EXIF DateTime"
    except (OSError, ValueError):
        return None, None  # unreadable headers: load_image reports an unreadable frame
    return None, None
