"""Raw Bayer mosaics: luminance by 2 x 2 binning, and telling a frame that looks like one.

A colour sensor read out raw (not demosaiced) stores one colour per pixel in a repeating 2 x 2
cell: ``RGGB`` means R at (row 0, column 0), G at (0, 1) and (1, 0), B at (1, 1); ``BGGR``,
``GRBG`` and ``GBRG`` likewise. Summing each cell gives one luminance pixel (R + 2G + B) at half
the resolution with no colour interpolation: a star's centroid is unbiased (every cell holds
each colour in the same place), and its light is kept whatever its colour. The four patterns
bin to the same image; the pattern is asked for so that a user says what the frame is.

A mosaic read as a monochrome frame shows the 2 x 2 cell: the four sub-lattices (even/odd rows
x even/odd columns) have different levels (R, G and B see a sky and a dark frame differently),
the two green ones alike. :func:`bayer_hint` measures that from the sub-lattice means against
the frame's noise.
"""

from __future__ import annotations

import numpy as np

from starsense.errors import InputError

__all__ = ["BAYER_PATTERNS", "bayer_hint", "bin_bayer", "check_bayer"]

#: the 2 x 2 colour cells, read row by row
BAYER_PATTERNS = ("RGGB", "BGGR", "GRBG", "GBRG")
#: a sub-lattice level this many standard errors of the mean from the others marks a mosaic
_HINT_SIGMAS = 20.0
#: ... and at least this fraction of the background noise (a smooth glow's gradient moves the
#: four means by much less)
_HINT_NOISE_FRACTION = 0.25


def check_bayer(pattern: str | None, where: str = "--bayer") -> str | None:
    """Return the pattern in upper case, or raise InputError naming the allowed ones."""
    if pattern is None:
        return None
    p = str(pattern).strip().upper()
    if p not in BAYER_PATTERNS:
        raise InputError(f"{where} must be one of {', '.join(BAYER_PATTERNS)}, got {pattern!r}")
    return p


def bin_bayer(image, pattern: str, *, name: str = "image") -> np.ndarray:
    """Return the luminance of a raw Bayer mosaic: the sum of every 2 x 2 cell.

    Parameters
    ----------
    image : array_like, shape (rows, columns)
        The raw mosaic, counts (one colour per pixel).
    pattern : {"RGGB", "BGGR", "GRBG", "GBRG"}
        Its colour cell.
    name : str
        What to call the frame in an error (its file).

    Returns
    -------
    ndarray, shape (rows // 2, columns // 2)
        Counts summed over each cell (float64); an odd last row or column is dropped.

    Raises
    ------
    InputError
        Not a 2-D frame of at least 2 x 2 pixels, or an unknown pattern.
    """
    check_bayer(pattern)
    a = np.asarray(image)
    if a.ndim != 2:
        raise InputError(
            f"{name}: a raw Bayer mosaic is one 2-D plane, got shape {a.shape} "
            "(a colour image is already demosaiced: drop --bayer)"
        )
    rows, cols = (a.shape[0] // 2) * 2, (a.shape[1] // 2) * 2
    if rows == 0 or cols == 0:
        raise InputError(f"{name}: {a.shape[1]} x {a.shape[0]} pixels is too small to bin 2 x 2")
    a = a[:rows, :cols].astype(np.float64)
    return a[0::2, 0::2] + a[0::2, 1::2] + a[1::2, 0::2] + a[1::2, 1::2]


def bayer_hint(image) -> str | None:
    """Return a sentence when a monochrome frame looks like a raw Bayer mosaic, else None.

    The means of the four 2 x 2 sub-lattices (each pixel held below the frame's 99th
    percentile, so stars and hot pixels barely count) are compared: a mosaic has two (the
    greens, on one diagonal) alike and the others apart by many standard errors of a mean
    (sigma / sqrt(n)) and by a good fraction of the noise; a monochrome frame's four means
    agree to a fraction of the noise.

    Parameters
    ----------
    image : array_like, shape (rows, columns)
        The frame as read, counts.

    Returns
    -------
    str or None
    """
    a = np.asarray(image)
    if a.ndim != 2 or min(a.shape) < 16:
        return None
    a = a[: a.shape[0] // 2 * 2, : a.shape[1] // 2 * 2]
    # float32 values of the pixels, each sub-lattice converted as it is capped (no float32 copy
    # of the whole frame: the same values, in half the time)
    cap = np.float32(np.percentile(a[::3, ::3].astype(np.float32), 99.0))  # stars held down
    lattices = [np.minimum(a[r::2, c::2], cap, dtype=np.float32) for r in (0, 1) for c in (0, 1)]
    med = np.array([float(s.mean()) for s in lattices])  # trimmed means: not quantised
    noise = float(np.mean([s.std() for s in lattices]))
    if noise <= 0:
        return None
    err = noise / np.sqrt(lattices[0].size)
    spread = med.max() - med.min()
    if spread < max(_HINT_SIGMAS * err, _HINT_NOISE_FRACTION * noise):
        return None
    # the greens: one diagonal pair (0, 3) or (1, 2) alike compared with the spread
    diag = min(abs(med[0] - med[3]), abs(med[1] - med[2]))
    if diag > 0.5 * spread:
        return None
    levels = ", ".join(f"{m:.1f}" for m in med)
    return (
        f"the frame looks like a raw Bayer mosaic (the 2 x 2 sub-lattices sit at {levels} "
        f"counts, noise {noise:.1f}): give --bayer {'|'.join(BAYER_PATTERNS)} to bin it"
    )
