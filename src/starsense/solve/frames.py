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
        import struct
        import warnings

        from PIL import Image, UnidentifiedImageError

        # a corrupt file makes Pillow warn ("Corrupt EXIF data") before it fails: the warnings
        # are kept out of the user's way; the failure is reported, with its reason
        # (the warning filters are process-wide: a warning turned into an error elsewhere, as
        # in the test run, is a failure to read like the others)
        failures = (OSError, UnidentifiedImageError, ValueError, SyntaxError, struct.error,
                    UserWarning)  # fmt: skip
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                with Image.open(p) as im:
                    a = np.array(im)
        except failures as exc:
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
