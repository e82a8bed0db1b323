"""Degrees for the edges: the conversion results use when they print or write an angle."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from starsense.units import DEG

__all__ = ["edge_degrees"]

#: decimals of a degree value that an input given in degrees can have and still round-trip
_DECIMALS = 9


def edge_degrees(angle_rad: ArrayLike) -> NDArray[np.float64]:
    """Return an angle in degrees, restoring the decimal value it was given in.

    ``x_deg * DEG / DEG`` need not be ``x_deg`` to the last bit (``0.3`` comes back as
    ``0.30000000000000004``). A value within a few ulp of a number with at most 9 decimals is
    returned as that number, so degrees given at the command line come back exactly in JSON and
    text; any other value is returned as computed.

    Parameters
    ----------
    angle_rad : float or array_like
        Angle(s) or angular rate(s), rad or rad/s.

    Returns
    -------
    ndarray
        The same in deg or deg/s, same shape.
    """
    deg = np.asarray(angle_rad, dtype=np.float64) / DEG
    snapped = np.round(deg, _DECIMALS)
    close = np.abs(snapped - deg) <= 4.0 * np.spacing(np.maximum(np.abs(deg), 1e-300))
    return np.where(close, snapped, deg)
