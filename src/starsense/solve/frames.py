"""Reading camera frames: BMP, PNG, JPEG, TIFF (Pillow, else tifffile) and FITS (astropy).

8 to 32-bit integers and floats; grey, RGB, RGBA, palette (PNG), 16-bit and float TIFF (any
compression Pillow or tifffile decodes), FITS in the primary or the first image HDU,
tile-compressed HDUs and 1 x H x W cubes. Colour frames are converted to luminance with the
ITU-R BT.601 weights (0.299 R + 0.587 G + 0.114 B), as Pillow's "L" mode does, but in floating
point so 16-bit colour keeps its depth; a grey frame stored as colour (R = G = B, an RGBA PNG of
grey) keeps its integer counts, so that its quantisation is seen. A raw Bayer mosaic is binned
2 x 2 when its pattern is given (:mod:`starsense.solve.bayer`).

Every problem with the file is an :class:`~starsense.errors.InputError` naming it: missing or
unreadable, a size past the pixel limit (:data:`DEFAULT_MAX_PIXELS`, raised with the
environment variable ``STARSENSE_MAX_PIXELS`` or ``max_pixels=``) checked from the header before
any pixel is decoded, a FITS header with no or a blank ``BITPIX`` or promising more data than
the file holds, 1-bit frames, and NaN or infinite pixels.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import math
import os
import threading
import warnings
from pathlib import Path

import numpy as np

from starsense._io import readable_file
from starsense.errors import InputError
from starsense.geometry.apparent import parse_time
from starsense.solve.bayer import bayer_hint, bin_bayer, check_bayer

LUMA_WEIGHTS = np.array([0.299, 0.587, 0.114])
FITS_SUFFIXES = {".fits", ".fit", ".fts"}
PILLOW_SUFFIXES = {".tif", ".tiff", ".png", ".jpg", ".jpeg", ".bmp"}
TIFF_SUFFIXES = {".tif", ".tiff"}
#: held while Pillow's pixel limit is lifted (:func:`_pillow_open`)
_PILLOW_LOCK = threading.Lock()

#: frames larger than this many pixels are refused before decoding (2^28: 16384 x 16384, 512 MB
#: as 16-bit counts and 2 GB once converted to float for detection); the environment variable
#: ``STARSENSE_MAX_PIXELS`` or the ``max_pixels`` argument raises it
DEFAULT_MAX_PIXELS = 1 << 28
MAX_PIXELS_ENV = "STARSENSE_MAX_PIXELS"
_FITS_BITPIX = (8, 16, 32, 64, -32, -64)


def max_pixels(value: int | None = None) -> int:
    """Return the pixel limit: ``value`` if given, else ``$STARSENSE_MAX_PIXELS``, else default.

    Raises
    ------
    InputError
        The limit given (or the environment variable) is not a positive integer.
    """
    if value is None:
        text = os.environ.get(MAX_PIXELS_ENV, "").strip()
        if not text:
            return DEFAULT_MAX_PIXELS
        try:
            value = int(text)
        except ValueError:
            raise InputError(f"{MAX_PIXELS_ENV} must be a positive integer, got {text!r}") from None
        name = MAX_PIXELS_ENV
    else:
        name = "max_pixels"
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise InputError(f"{name} must be a positive integer, got {value!r}")
    return value


def _check_size(p: Path, shape: tuple[int, ...], limit: int) -> None:
    n = math.prod(shape[-2:]) if len(shape) >= 2 else math.prod(shape)
    if n > limit:
        dims = " x ".join(str(s) for s in shape)
        raise InputError(
            f"{p}: image of {dims} pixels ({n:,}) is larger than the limit of {limit:,} pixels; "
            f"set {MAX_PIXELS_ENV} to raise it"
        )


def load_image(
    path: str | Path, max_pixels: int | None = None, *, bayer: str | None = None
) -> np.ndarray:
    """Load a frame as a 2-D array (rows, columns).

    Monochrome frames (and grey ones stored as colour) keep their integer type; colour frames
    are converted to luminance (float); a raw Bayer mosaic is binned 2 x 2 (float).

    Parameters
    ----------
    path : path-like
        BMP, PNG, JPEG, TIFF or FITS file.
    max_pixels : int, optional
        Refuse frames with more pixels (rows x columns) than this; default
        ``$STARSENSE_MAX_PIXELS`` or :data:`DEFAULT_MAX_PIXELS`.
    bayer : {"RGGB", "BGGR", "GRBG", "GBRG"}, optional
        The frame is a raw Bayer mosaic of this pattern: its luminance is the sum of every
        2 x 2 cell (:func:`starsense.solve.bayer.bin_bayer`), half the size each way.

    Returns
    -------
    ndarray, shape (rows, columns)

    Raises
    ------
    InputError
        The file is missing, of an unknown type, unreadable, past the pixel limit, 1-bit, holds
        NaN or infinite pixels, or is not a 2-D image. The message names the file.
    """
    limit = _limit(max_pixels)
    bayer = check_bayer(bayer)
    p = readable_file(path, "image")
    suffix = p.suffix.lower()
    if suffix in FITS_SUFFIXES:
        a = _load_fits(p, limit)
    elif suffix in TIFF_SUFFIXES:
        a = _load_tiff(p, limit)
    elif suffix in PILLOW_SUFFIXES:
        a = _load_pillow(p, limit)
    else:
        known = ", ".join(sorted(FITS_SUFFIXES | PILLOW_SUFFIXES))
        raise InputError(f"{p}: unknown image type {suffix!r}; known: {known}")
    if a.dtype == bool:
        raise InputError(f"{p}: 1-bit image; a star frame needs 8 bits or more per pixel")
    if a.dtype.kind not in "uif":
        raise InputError(f"{p}: pixels of type {a.dtype} are not numbers")
    while a.ndim > 2 and a.shape[0] == 1:  # a 1 x H x W cube
        a = a[0]
    if a.ndim == 3 and a.shape[0] in (3, 4) and a.shape[-1] not in (3, 4):
        a = np.moveaxis(a, 0, -1)  # FITS planes first
    if a.ndim == 3 and a.shape[-1] in (3, 4):  # RGB(A): luminance, alpha dropped
        rgb = a[..., :3]
        if (rgb[..., 0] == rgb[..., 1]).all() and (rgb[..., 0] == rgb[..., 2]).all():
            a = np.ascontiguousarray(rgb[..., 0])  # grey stored as colour: its own counts
        else:
            a = rgb.astype(float) @ LUMA_WEIGHTS
    elif a.ndim == 3 and a.shape[-1] == 2:  # grey + alpha
        a = np.ascontiguousarray(a[..., 0])
    if a.ndim != 2:
        raise InputError(f"{p}: expected a 2-D (monochrome or colour) image, got shape {a.shape}")
    if a.size == 0:
        raise InputError(f"{p}: image is empty")
    if a.dtype.kind == "f":
        bad = ~np.isfinite(a)
        if bad.any():
            row, col = np.argwhere(bad)[0]
            raise InputError(
                f"{p}: {int(bad.sum()):,} pixels are NaN or infinite (the first at row {row}, "
                f"column {col}); a frame needs finite values"
            )
    if bayer is not None:
        a = bin_bayer(a, bayer, name=str(p))
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
        ``"EXIF DateTimeOriginal"`` or ``"EXIF DateTime"``; (None, None) when there is none
        (or a blank EXIF date).

    Raises
    ------
    InputError
        A FITS DATE-OBS card that cannot be read, or a time that is not a time, naming the
        file and the card or tag.
    """
    p = Path(path)
    value, source = _header_time(p)
    if value is None:
        return None, None
    if not value.strip(" :0-T"):  # a camera's blank EXIF date ("0000:00:00 00:00:00", spaces)
        return None, None
    parse_time(value, f"{p}: {source}")  # a bad time names the file and the card or tag
    return value, source


def _header_time(p: Path) -> tuple[str | None, str | None]:
    suffix = p.suffix.lower()
    try:
        if suffix in FITS_SUFFIXES:
            from astropy.io import fits

            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                with fits.open(p) as hdul:
                    for i, hdu in enumerate(hdul):
                        try:
                            value = hdu.header.get("DATE-OBS")
                        except Exception as exc:  # astropy's VerifyError: an unparsable card
                            raise InputError(
                                f"{p}: FITS card DATE-OBS of HDU {i} cannot be read "
                                f"({_one_line(exc)})"
                            ) from None
                        if value:
                            return str(value), "FITS DATE-OBS"
        elif suffix in TIFF_SUFFIXES:  # tifffile, which load_image has imported: not Pillow
            return _tiff_time(p)
        elif suffix in PILLOW_SUFFIXES:
            with _pillow_open(p) as im:
                exif = im.getexif()
                original = exif.get_ifd(_EXIF_IFD).get(_EXIF_DATETIME_ORIGINAL)
                if original:
                    return str(original).strip("\x00 "), "EXIF DateTimeOriginal"
                if exif.get(_EXIF_DATETIME):
                    return str(exif[_EXIF_DATETIME]).strip("\x00 "), "EXIF DateTime"
    except InputError:
        raise
    except Exception:  # unreadable headers: load_image reports the frame
        return None, None
    return None, None


def _tiff_time(p: Path) -> tuple[str | None, str | None]:
    """Return the EXIF time of a TIFF's first page, as Pillow's ``getexif`` reads it."""
    import tifffile

    log = logging.getLogger("tifffile")
    log.addFilter(_quiet)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with tifffile.TiffFile(p) as tif:
                tags = tif.pages[0].tags
                exif = tags.get(_EXIF_IFD)  # the Exif IFD, which tifffile reads as a dict
                exif = exif.value if exif is not None and isinstance(exif.value, dict) else {}
                original = exif.get("DateTimeOriginal")
                if original:
                    return str(original).strip("\x00 "), "EXIF DateTimeOriginal"
                changed = tags.get(_EXIF_DATETIME)
                if changed is not None and changed.value:
                    return str(changed.value).strip("\x00 "), "EXIF DateTime"
    finally:
        log.removeFilter(_quiet)
    return None, None


_limit = max_pixels  # the argument of load_image shadows the function's name


def _pillow_array(im) -> np.ndarray:
    """Return the pixels of an open Pillow image: palettes expanded, colour models to RGB."""
    if im.mode in ("P", "PA"):
        im = im.convert("RGBA")
    elif im.mode in ("CMYK", "YCbCr", "LAB", "HSV"):
        im = im.convert("RGB")
    return np.array(im)


@contextlib.contextmanager
def _pillow_open(p: Path):
    """Open ``p`` with Pillow, its "decompression bomb" check lifted (ours is the pixel limit).

    Pillow's limit is one setting for the process: frames are opened one at a time while it is
    lifted (threads of a batch would otherwise restore it under each other's feet). A corrupt
    file makes Pillow warn ("Corrupt EXIF data") before it fails: the warnings are kept out of
    the user's way; the failure is reported, with its reason.
    """
    from PIL import Image

    with _PILLOW_LOCK:
        old = Image.MAX_IMAGE_PIXELS
        Image.MAX_IMAGE_PIXELS = None
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                with Image.open(p) as im:  # opening reads the header only
                    yield im
        finally:
            Image.MAX_IMAGE_PIXELS = old


def _load_pillow(p: Path, limit: int) -> np.ndarray:
    try:
        with _pillow_open(p) as im:
            _check_size(p, (im.height, im.width), limit)
            return _pillow_array(im)
    except InputError:
        raise
    except Exception as exc:  # a decoder's view of a damaged file: OSError, SyntaxError, ...
        raise InputError(f"{p}: not a readable image ({_one_line(exc)})") from None


def _load_tiff(p: Path, limit: int) -> np.ndarray:
    """Read a TIFF: tifffile's first page (16-bit colour keeps its depth), else Pillow's.

    tifffile decodes uncompressed, deflate and packbits strips itself and the other codecs
    (LZW, JPEG, ...) with the optional imagecodecs; Pillow (libtiff) reads those, but reads
    16-bit colour as 8-bit.
    """
    import tifffile

    log = logging.getLogger("tifffile")  # its complaints about a damaged file: reported below
    log.addFilter(_quiet)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with tifffile.TiffFile(p) as tif:
                page = tif.pages[0]
                shape = page.shape
                _check_size(p, tuple(shape[:2]) if page.samplesperpixel > 1 else shape, limit)
                return np.asarray(page.asarray())
    except InputError:
        raise
    except Exception as exc:
        try:
            return _load_pillow(p, limit)
        except InputError as pillow_error:
            raise InputError(f"{pillow_error}; tifffile: {_one_line(exc)}") from None
    finally:
        log.removeFilter(_quiet)


def _quiet(record: logging.LogRecord) -> bool:
    return False


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 200 else text[:197] + "..."


def _check_fits_header(p: Path, header, limit: int) -> tuple[int, tuple[int, ...]]:
    """Return (BITPIX, shape) of an image header, or raise InputError naming what is wrong."""
    bitpix = header.get("BITPIX")
    if "BITPIX" not in header:
        raise InputError(f"{p}: FITS header has no BITPIX")
    if isinstance(bitpix, bool) or not isinstance(bitpix, int) or bitpix not in _FITS_BITPIX:
        shown = "blank" if bitpix is None or not str(bitpix).strip() else repr(bitpix)
        raise InputError(
            f"{p}: FITS BITPIX is {shown}; must be one of {', '.join(map(str, _FITS_BITPIX))}"
        )
    naxis = header.get("NAXIS")
    if isinstance(naxis, bool) or not isinstance(naxis, int) or not 0 <= naxis <= 999:
        raise InputError(f"{p}: FITS NAXIS is {naxis!r}; must be an integer 0-999")
    dims = []
    for i in range(1, naxis + 1):
        n = header.get(f"NAXIS{i}")
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise InputError(f"{p}: FITS NAXIS{i} is {n!r}; must be an integer >= 0")
        dims.append(n)
    shape = tuple(reversed(dims))  # FITS lists the fastest axis first
    if naxis:
        _check_size(p, shape, limit)
    return bitpix, shape


def _load_fits(p: Path, limit: int) -> np.ndarray:
    from astropy.io import fits

    size = p.stat().st_size
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # astropy's truncation warnings: checked below, named
        try:
            _check_fits_header(p, fits.Header.fromfile(p), limit)
            with fits.open(p, memmap=False, lazy_load_hdus=True) as hdul:
                for hdu in hdul:
                    image_hdu = isinstance(hdu, (fits.PrimaryHDU, fits.ImageHDU))
                    compressed = isinstance(hdu, fits.CompImageHDU)
                    if not (image_hdu or compressed) or not hdu.header.get("NAXIS"):
                        continue  # tables, empty primaries: the image is further on
                    bitpix, shape = _check_fits_header(p, hdu.header, limit)
                    need = abs(bitpix) // 8 * math.prod(shape)
                    start = hdu.fileinfo()["datLoc"]
                    if not compressed and start + need > size:
                        raise InputError(
                            f"{p}: FITS header promises {need:,} bytes of data "
                            f"({' x '.join(map(str, shape))}, BITPIX {bitpix}) but the file "
                            f"holds {max(size - start, 0):,} after the header (truncated?)"
                        )
                    data = hdu.data
                    if data is not None:
                        return np.array(data)
        except InputError:
            raise
        except Exception as exc:  # astropy's view of a damaged file
            raise InputError(f"{p}: not a readable FITS file ({_one_line(exc)})") from None
    raise InputError(f"{p}: FITS file holds no image data")


def solve_frame_file(solver, path, obs_time=None, *, bayer=None):
    """Load a frame and solve it with ``solver`` (:meth:`starsense.solve.solver.Solver.solve_file`).

    The frame's time is ``obs_time`` if given, else its FITS DATE-OBS or EXIF
    DateTimeOriginal / DateTime (:func:`frame_time`), else unknown. A frame that looks like a raw
    Bayer mosaic (none given) gets a note saying so.
    """
    image = load_image(path, bayer=bayer)  # first: its checks come before any other read
    source = "obs_time"
    if obs_time is None:
        obs_time, source = frame_time(path)
    sol = solver(image, obs_time)
    if sol.apparent is not None and sol.apparent.get("applied"):
        sol = dataclasses.replace(sol, apparent={**sol.apparent, "time_source": source})
    hint = bayer_hint(image) if bayer is None else None
    return sol if hint is None else dataclasses.replace(sol, notes=(*sol.notes, hint))
