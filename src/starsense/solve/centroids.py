"""Centroid lists from other centroiders: CSV (x, y[, flux]) and astrometry.net xylists (FITS).

Pixel convention of starsense (:mod:`starsense.detect`): (0, 0) is the centre of the top-left
pixel, x runs along the columns and y along the rows. astrometry.net's xylists follow FITS,
where the centre of the first pixel is (1, 1): their X and Y are converted by subtracting 1.
CSV files are taken in starsense's convention as they are.

CSV: one centroid per line, "x, y" or "x, y, flux" (commas, or blanks), an optional header
line (names x, y and flux, in any case, in any column order; without a header the columns are
x, y[, flux] in that order), lines starting with "#" ignored. Without a flux column the
centroids are taken as listed, brightest first.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from starsense._validate import check_int, check_scalar, show
from starsense.errors import InputError
from starsense.solve.settings import FOV_RANGE_RAD

__all__ = [
    "CentroidList",
    "CentroidPoints",
    "check_centroid_input",
    "check_centroids",
    "check_frame_shape",
    "check_image_size",
    "read_centroids",
]

FITS_SUFFIXES = {".fits", ".fit", ".fts", ".xyls", ".axy"}

#: how far outside the image's edge a centroid may lie and still be a star, px: an extractor
#: puts a star cut by the edge at the centre of gravity of its visible part, or where its fitted
#: profile peaks, a fraction of a PSF width beyond the last pixel (x = -0.77 on a real set); two
#: pixels hold a star whose core (FWHM up to ~4 px) still lights the edge column. Farther out, a
#: centroid is not of this image: the image size is wrong.
EDGE_MARGIN_PX = 2.0


@dataclass(frozen=True)
class CentroidList:
    """Centroids read from a file.

    Attributes
    ----------
    xy : ndarray, shape (N, 2)
        Centroids (x = column, y = row), pixels, starsense convention (0-based centres).
    flux : ndarray, shape (N,), or None
        Brightness per centroid when the file gives one.
    image_size : (int, int) or None
        Width and height of the image, pixels, when the file records them (xylist IMAGEW,
        IMAGEH).
    """

    xy: np.ndarray
    flux: np.ndarray | None = None
    image_size: tuple[int, int] | None = None


def read_centroids(path: str | Path) -> CentroidList:
    """Read a centroid list: CSV or astrometry.net xylist (FITS BINTABLE with X, Y[, FLUX]).

    Parameters
    ----------
    path : path-like
        ``.csv``/``.txt`` (or any other suffix): CSV; ``.fits``, ``.fit``, ``.fts``,
        ``.xyls``, ``.axy``: xylist.

    Returns
    -------
    CentroidList

    Raises
    ------
    InputError
        Missing or empty file, a non-number (named by line and column), missing columns.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"centroid file not found: {p}")
    if p.suffix.lower() in FITS_SUFFIXES:
        return _read_xylist(p)
    return _read_csv(p)


def _split(line: str) -> list[str]:
    return [f.strip() for f in line.split(",")] if "," in line else line.split()


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _columns(header: list[str], p: Path) -> tuple[int, int, int | None]:
    names = [h.strip().strip('"').lower() for h in header]
    for need in ("x", "y"):
        if need not in names:
            raise InputError(f"{p}: line 1: header {show(header)} has no {need!r} column")
    flux = names.index("flux") if "flux" in names else None
    return names.index("x"), names.index("y"), flux


def _read_csv(p: Path) -> CentroidList:
    try:
        text = p.read_text(encoding="utf-8-sig")  # a spreadsheet's byte-order mark is not data
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{p}: not a readable text file ({exc})") from None
    rows = [
        (number, _split(line))
        for number, line in enumerate(text.splitlines(), start=1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not rows:
        raise InputError(f"{p}: no centroids (the file is empty)")
    cols: tuple[int, int, int | None] | None = None
    if not all(_is_number(f) for f in rows[0][1]):
        cols = _columns(rows[0][1], p)
        rows = rows[1:]
        if not rows:
            raise InputError(f"{p}: no centroids (a header only)")
    if cols is None:
        width = len(rows[0][1])
        if width not in (2, 3):
            raise InputError(
                f"{p}: line {rows[0][0]}: expected 2 or 3 columns (x, y[, flux]), got {width}"
            )
        cols = (0, 1, 2 if width == 3 else None)
    used = [c for c in cols if c is not None]
    values = np.empty((len(rows), len(used)))
    for i, (number, fields) in enumerate(rows):
        if len(fields) <= max(used):
            raise InputError(
                f"{p}: line {number}: expected {max(used) + 1} columns, got {show(fields)}"
            )
        for j, c in enumerate(used):
            try:
                values[i, j] = float(fields[c])
            except ValueError:
                raise InputError(
                    f"{p}: line {number}, column {c + 1}: not a number: {show(fields[c])}"
                ) from None
            if not np.isfinite(values[i, j]):
                raise InputError(
                    f"{p}: line {number}, column {c + 1}: not finite: {show(fields[c])}"
                )
    flux = values[:, 2] if cols[2] is not None else None
    return CentroidList(values[:, :2].copy(), flux)


def _read_xylist(p: Path) -> CentroidList:
    from astropy.io import fits

    try:
        with fits.open(p) as hdul:
            table = next((h for h in hdul if isinstance(h, fits.BinTableHDU)), None)
            if table is None:
                raise InputError(f"{p}: no BINTABLE extension (an xylist has X, Y[, FLUX])")
            names = {n.upper(): n for n in table.columns.names}
            for need in ("X", "Y"):
                if need not in names:
                    raise InputError(f"{p}: the table has no {need} column ({table.columns.names})")
            data = table.data
            x = np.array(data[names["X"]], dtype=float)
            y = np.array(data[names["Y"]], dtype=float)
            flux = np.array(data[names["FLUX"]], dtype=float) if "FLUX" in names else None
            size = None
            header = table.header
            if "IMAGEW" in header and "IMAGEH" in header:
                size = tuple(_size_card(header, key, p) for key in ("IMAGEW", "IMAGEH"))
    except (OSError, ValueError, TypeError) as exc:
        raise InputError(f"{p}: not a readable FITS xylist ({exc})") from None
    if x.size == 0:
        raise InputError(f"{p}: no centroids (the table is empty)")
    xy = np.column_stack([x, y]) - 1.0  # FITS: first pixel centre at (1, 1)
    bad = np.flatnonzero(~np.isfinite(xy).all(axis=1))
    if bad.size:
        raise InputError(f"{p}: row {bad[0] + 1}: X, Y not finite")
    return CentroidList(xy, flux, size)


def check_centroids(xy) -> np.ndarray:
    """Return centroids as a (N, 2) float array of finite (x, y), pixels; InputError if not."""
    try:
        pts = np.asarray(xy, dtype=float)
    except (TypeError, ValueError):
        raise InputError("centroids must be numbers, shape (N, 2)") from None
    if pts.size == 0:
        return np.zeros((0, 2))
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise InputError(f"centroids must have shape (N, 2) (x, y), got {pts.shape}")
    if not np.isfinite(pts).all():
        bad = np.flatnonzero(~np.isfinite(pts).all(axis=1))
        if bad.size:
            raise InputError(f"centroid {bad[0]} is not finite: {pts[bad[0]].tolist()}")
    return pts


def check_image_size(image_size) -> tuple[int, int]:
    """Return (rows, columns) of an image size given as (width, height), integers >= 1."""
    try:
        width, height = image_size
    except (TypeError, ValueError):
        raise InputError(f"image_size must be (width, height), got {image_size!r}") from None
    if type(width) is int and type(height) is int and width >= 1 and height >= 1:
        return height, width  # plain ints, checked: what check_int returns for them
    return check_int(height, "image height", 1), check_int(width, "image width", 1)


def check_centroid_input(xy, image_size, *, brightness=None, fov_rad=None, sensor=None):
    """Check the input of ``Solver.solve_centroids``; return it in the form the solver uses.

    Parameters
    ----------
    xy : array_like, shape (N, 2)
        Centroids (x = column, y = row), pixels.
    image_size : (int, int)
        Width and height of the image, pixels.
    brightness : array_like, shape (N,), optional
        Anything that grows with brightness; default: as listed, brightest first.
    fov_rad : float, optional
        Horizontal field, rad, in [0.5, 120] deg (not with a sensor).
    sensor : Sensor, optional
        The solver's sensor: the image size must be its detector's.

    Returns
    -------
    pts : ndarray, shape (N, 2)
    shape : (int, int)
        Rows, columns.
    flux : ndarray, shape (N,)
    fov_rad : float or None

    Raises
    ------
    InputError
        Centroids not (N, 2) finite numbers, a bad image size or field, brightness not one
        finite value per centroid, an image size that is not the sensor's, a centroid
        more than ``EDGE_MARGIN_PX`` (2 px) outside the image (closer: an edge star, kept).
    """
    pts = _as_points(xy)
    shape = check_image_size(image_size)
    if fov_rad is not None:
        if sensor is not None:
            raise InputError("give fov_rad only to a Solver without a sensor")
        fov_rad = check_scalar(fov_rad, "fov_rad", *FOV_RANGE_RAD)
    if sensor is not None:
        det = sensor.detector
        if shape != (det.rows, det.columns):
            raise InputError(
                f"image_size {shape[1]} x {shape[0]} is not the sensor's {det.columns} x {det.rows}"
            )
    _check_inside(pts, shape)
    if brightness is None:
        flux = np.arange(len(pts), 0, -1, dtype=float)  # as listed: brightest first
    else:
        flux = np.asarray(brightness, dtype=float)
        if flux.shape != (len(pts),) or not np.all(np.isfinite(flux)):
            raise InputError(
                f"brightness must be {len(pts)} finite numbers (one per centroid), "
                f"got shape {flux.shape}"
            )
    return pts, shape, flux, fov_rad


def _as_points(xy) -> np.ndarray:
    """:func:`check_centroids` of an (N, 2) float array, its finite test left to the bounds.

    The bounds test of :func:`_check_inside` takes the columns' least and largest values,
    which a NaN or an infinity fails: a list inside the image is finite, and any other goes
    through :func:`check_centroids`, which names what is wrong.
    """
    if isinstance(xy, np.ndarray) and xy.dtype == np.float64 and xy.ndim == 2 and xy.shape[1] == 2:
        return xy
    return check_centroids(xy)


def _check_inside(pts: np.ndarray, shape: tuple[int, int]) -> None:
    """Refuse centroids more than ``EDGE_MARGIN_PX`` outside the image of ``shape`` (rows, cols).

    The image spans x in [-0.5, cols - 0.5) and y in [-0.5, rows - 0.5); an edge star's centroid
    may lie up to ``EDGE_MARGIN_PX`` beyond (see there).
    """
    rows, cols = shape
    lo, m = -0.5 - EDGE_MARGIN_PX, EDGE_MARGIN_PX
    if not len(pts):
        return
    (x_min, y_min), (x_max, y_max) = pts.min(axis=0).tolist(), pts.max(axis=0).tolist()
    if x_min >= lo and y_min >= lo and x_max <= cols - 0.5 + m and y_max <= rows - 0.5 + m:
        return
    check_centroids(pts)  # a value not finite is named first
    outside = (pts[:, 0] < lo) | (pts[:, 0] > cols - 0.5 + m)
    outside |= (pts[:, 1] < lo) | (pts[:, 1] > rows - 0.5 + m)
    if outside.any():
        i = int(np.flatnonzero(outside)[0])
        raise InputError(
            f"{int(outside.sum())} centroid(s) lie outside the {cols} x {rows} image by more "
            f"than {m:g} px (x in [{lo:g}, {cols - 0.5 + m:g}], y in [{lo:g}, "
            f"{rows - 0.5 + m:g}]), the first: number {i + 1} at x = {pts[i, 0]:g}, "
            f"y = {pts[i, 1]:g}; is the image size right?"
        )


def check_frame_shape(shape, sensor) -> None:
    """Refuse a frame whose size is not the sensor's detector (cropped, binned or rotated).

    The sensor's optics map its own detector's pixels to directions; a frame of another size
    would be unprojected through the wrong principal point and scale and could "solve" degrees
    off. Such a frame is solved as what it is, without the sensor (its own field, or none).

    Parameters
    ----------
    shape : (int, int)
        Rows, columns of the frame.
    sensor : Sensor or None
        The solver's sensor (nothing is checked without one).

    Raises
    ------
    InputError
        Naming both sizes and what to do.
    """
    if sensor is None or len(shape) != 2:
        return  # not a 2-D frame: the detector says so
    det = sensor.detector
    if tuple(shape) == (det.rows, det.columns):
        return
    turned = tuple(shape) == (det.columns, det.rows)
    what = "rotated by 90 deg" if turned else "cropped, binned or from another camera"
    raise InputError(
        f"the frame is {shape[1]} x {shape[0]} pixels but the sensor {sensor.name!r} has a "
        f"{det.columns} x {det.rows} detector (a frame {what}): its optics do not apply; solve "
        "it without --sensor (give --fov-deg for the frame's own field, or nothing)"
    )


class CentroidPoints(NamedTuple):
    """Centroids to solve, as the Solver carries them from detection to the attitude.

    A named tuple (immutable; made once per solve, and per mirror image tried).

    Parameters
    ----------
    x, y : ndarray (N,)
        Centroids, px (x along the columns, y down the rows).
    flux : ndarray (N,)
        Brightness: the lit sums, counts, of "detections"; any unit for "centroids" (only the
        order matters).
    shape : tuple of int
        The image's (rows, columns).
    what : str
        What the points are ("detections" or "centroids"), for messages.
    rank : ndarray (N,), optional
        The order the identification takes them in, largest first, when it is not ``flux``'s
        (detections ranked by their evidence of being stars: :mod:`starsense.solve.sharp`).
    """

    x: np.ndarray
    y: np.ndarray
    flux: np.ndarray
    shape: tuple
    what: str
    rank: np.ndarray | None = None

    @property
    def ranking(self) -> np.ndarray:
        """The identification's order key: ``rank`` when given, else ``flux``."""
        return self.flux if self.rank is None else self.rank


def _size_card(header, key: str, path: Path) -> int:
    """Return an xylist's IMAGEW / IMAGEH card as a positive whole number of pixels."""
    value = header[key]
    if isinstance(value, bool) or not isinstance(value, int | float) or value != int(value):
        raise InputError(f"{path}: card {key} = {value!r} is not a whole number of pixels")
    if value < 1:
        raise InputError(f"{path}: card {key} = {value!r} must be at least 1 pixel")
    return int(value)
