"""Writing rendered frames: TIFF / PNG (Pillow) or FITS (astropy), with the truth as JSON.

``write_frame("frame.tif", frame)`` writes ``frame.tif`` and ``frame.tif.json`` (the truth,
:meth:`Frame.truth_dict`). Both are written to temporary names in the target directory
(:func:`starsense._io.atomic_paths`, renamed together) and renamed into place only when both
are complete: an error leaves no partial file behind. They get the permissions of any file the
user creates (``0666`` less the umask).

Formats, chosen by the (case-insensitive) extension:

``.tif``, ``.tiff``
    Grayscale TIFF. ``uint16`` frames as 16-bit unsigned; ``uint32`` frames (ADCs of 17-31
    bits) as 32-bit *signed* integers, Pillow's only 32-bit integer TIFF (the values are
    exact, as every count is below 2^31; 32-bit ADC frames must go to FITS).
``.png``
    16-bit grayscale PNG (``uint16`` frames only).
``.fits``, ``.fit``, ``.fts``
    Primary HDU via astropy (unsigned integers stored with the standard BZERO offset), with
    the exposure, sensor and mid-exposure attitude in the header.

A frame rendered at a time (apparent places) carries it as FITS ``DATE-OBS`` or, in TIFF and
PNG, as EXIF ``DateTime`` (whole seconds), where :func:`starsense.solve.frames.frame_time`
finds it.

Rows are written in array order, row 0 first (the top of the image for TIFF / PNG; FITS
viewers conventionally display the first row at the bottom).
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from starsense._io import atomic_paths, json_text
from starsense.errors import InputError

__all__ = ["FORMATS", "write_frame", "write_frames"]

FORMATS = {
    ".tif": "TIFF",
    ".tiff": "TIFF",
    ".png": "PNG",
    ".fits": "FITS",
    ".fit": "FITS",
    ".fts": "FITS",
}


def _write_pillow(target: str, image: np.ndarray, fmt: str, time_utc: str | None) -> None:
    from PIL import Image

    if image.dtype == np.uint16:
        pil = Image.fromarray(image)  # mode I;16
    else:
        pil = Image.fromarray(image.astype(np.int32))  # mode I (checked < 2^31 by the caller)
    # PNG: zlib level 1, ~4x faster than the default 6 on noisy frames, a few % larger
    options = {"compress_level": 1} if fmt == "PNG" else {}
    if time_utc is not None:  # EXIF DateTime (tag 306), 'YYYY:MM:DD HH:MM:SS', as cameras write
        exif = Image.Exif()
        exif[306] = time_utc[:19].replace("-", ":").replace("T", " ")
        options["exif"] = exif
    pil.save(target, format=fmt, **options)


def _write_fits(target: str, frame) -> None:
    from astropy.io import fits

    t = frame.truth
    hdu = fits.PrimaryHDU(data=frame.image)
    h = hdu.header
    h["BUNIT"] = ("adu", "digital counts")
    h["EXPTIME"] = (t.exposure_s, "exposure, s")
    h["SENSOR"] = (t.sensor, "starsense sensor")
    h["RA"] = (math.degrees(t.ra_rad), "boresight RA, deg, mid-exposure")
    h["DEC"] = (math.degrees(t.dec_rad), "boresight Dec, deg, mid-exposure")
    h["ROLL"] = (math.degrees(t.roll_rad), "roll, deg, mid-exposure")
    for i, axis in enumerate("XYZ"):
        h[f"RATE{axis}"] = (t.rate_rad_s[i], f"body rate w{axis.lower()}, rad/s")
    if t.seed is not None and 0 <= t.seed < 2**63:
        h["SEED"] = (t.seed, "noise seed (numpy default_rng)")
    h["NSTARS"] = (len(t.stars), "stars rendered; truth in .json")
    if t.apparent is not None:
        h["DATE-OBS"] = (t.apparent["time_utc"], "mid-exposure, UTC")
    hdu.writeto(target, overwrite=True)


def _checked(target: Path, frame) -> tuple[str, np.ndarray]:
    """Return the format and image of ``frame`` for ``target``, or raise InputError."""
    ext = target.suffix.lower()
    if ext not in FORMATS:
        raise InputError(
            f"cannot write {str(target)!r}: unknown image extension {target.suffix!r}; "
            f"use one of {', '.join(sorted(FORMATS))}"
        )
    fmt = FORMATS[ext]
    directory = target.parent if str(target.parent) else Path(".")
    if not directory.is_dir():
        raise InputError(f"cannot write {str(target)!r}: directory {str(directory)!r} not found")
    if frame is None:
        return fmt, np.zeros((0, 0), np.uint16)
    image = np.asarray(frame.image)
    if image.ndim != 2 or image.dtype not in (np.uint16, np.uint32):
        raise InputError(f"frame.image must be a 2-D uint16 or uint32 array, got {image.dtype}")
    if fmt == "PNG" and image.dtype != np.uint16:
        raise InputError(
            f"cannot write {str(target)!r}: PNG holds 16-bit frames only, this frame is "
            f"{image.dtype}; use .tif or .fits"
        )
    if fmt == "TIFF" and image.dtype == np.uint32 and image.size and image.max() >= 2**31:
        raise InputError(
            f"cannot write {str(target)!r}: counts of 2^31 and above do not fit Pillow's "
            "32-bit TIFF; use .fits"
        )
    return fmt, image


def _write_pair(tmp_image: Path, tmp_json: Path, target: Path, frame) -> None:
    """Write ``frame``'s image and truth to the temporaries of ``target`` and its JSON."""
    fmt, image = _checked(target, frame)
    text = json_text(frame.truth_dict(), indent=1)
    if fmt == "FITS":
        _write_fits(str(tmp_image), frame)
    else:
        when = None if frame.truth.apparent is None else frame.truth.apparent["time_utc"]
        _write_pillow(str(tmp_image), image, fmt, when)
    with open(tmp_json, "w", encoding="utf-8") as fh:
        fh.write(text)
        fh.write("\n")


def write_frame(path: str | os.PathLike, frame) -> Path:
    """Write a frame's image and, beside it as ``<path>.json``, its truth; atomically.

    Parameters
    ----------
    path : str or PathLike
        Image file; the extension picks the format (``.tif``/``.tiff``, ``.png``,
        ``.fits``/``.fit``/``.fts``). An existing file is replaced.
    frame : Frame
        From :func:`starsense.render.render_frame`.

    Returns
    -------
    Path
        The image path.

    Raises
    ------
    InputError
        Unknown extension, a frame the format cannot hold (uint32 as PNG, 32-bit counts as
        TIFF), or a directory that does not exist. Nothing is written in these cases.
    """
    return write_frames([path], [frame])[0]


def write_frames(paths: Sequence[str | os.PathLike], frames: Iterable) -> list[Path]:
    """Write frames and their truths as one unit: all of them, or none.

    Each frame is written to temporaries as it comes (an iterator is rendered one frame at a
    time, never all held in memory); the images and truths are renamed into place together
    only when every one is complete, with SIGINT and SIGTERM held back meanwhile
    (:func:`starsense._io.atomic_paths`). An error or a signal before that leaves the previous
    files as they were and no temporary behind.

    Parameters
    ----------
    paths : sequence of str or PathLike
        Image files, one per frame (formats as in :func:`write_frame`).
    frames : iterable of Frame
        The frames, in the order of ``paths``.

    Returns
    -------
    list of Path
        The image paths.

    Raises
    ------
    InputError
        As :func:`write_frame`, or fewer or more frames than paths.
    """
    targets = [Path(p) for p in paths]
    for target in targets:
        _checked(target, None)  # extensions and folders, before any frame is rendered
    names = [t.with_name(t.name + ".json") for t in targets]
    suffixes = [t.suffix.lower() for t in targets]
    everything = [x for pair in zip(targets, names, strict=True) for x in pair]
    with atomic_paths(everything, [x for s in suffixes for x in (s, ".json")]) as tmps:
        frames = iter(frames)
        for k, target in enumerate(targets):
            frame = next(frames, None)
            if frame is None:
                raise InputError(f"{len(targets)} paths but only {k} frames to write")
            _write_pair(tmps[2 * k], tmps[2 * k + 1], target, frame)
        if next(frames, None) is not None:
            raise InputError(f"more frames than the {len(targets)} paths to write them to")
    return targets
