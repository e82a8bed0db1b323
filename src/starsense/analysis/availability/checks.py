"""Checks of the availability analysis that carry its own rules (rates, magnitude limits).

Plain scalar checks are :mod:`starsense._validate`'s; messages name the parameter.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from starsense._validate import finite_array, show
from starsense.errors import InputError
from starsense.geometry.fov import CircularFov, RectangularFov

__all__ = ["Fov", "check_fov", "check_mag", "check_rates"]

Fov = CircularFov | RectangularFov


def check_rates(rates_rad_s: ArrayLike, name: str = "rates_rad_s") -> NDArray[np.float64]:
    """Return slew rates as a non-empty 1-D float array, finite and >= 0.

    Parameters
    ----------
    rates_rad_s : float or array_like, shape (R,)
        Slew rate magnitudes ``|w|``, rad/s.
    name : str
        The parameter's name, for the message.

    Returns
    -------
    ndarray, shape (R,)

    Raises
    ------
    InputError
        If a rate is not a number, not finite or negative, or none is given.
    """
    rates = np.atleast_1d(finite_array(rates_rad_s, name))
    if rates.ndim != 1 or rates.size == 0:
        raise InputError(f"{name} must be a non-empty list of rates, got {rates_rad_s!r}")
    if np.any(rates < 0):
        bad = float(rates[rates < 0][0])
        raise InputError(f"{name} = {show(bad)} is negative; rates are magnitudes |w| >= 0")
    return rates


def check_mag(value: object, name: str, allow_inf: bool = False) -> float:
    """Return a magnitude limit as a float: finite, or also ``+inf`` when `allow_inf`.

    Parameters
    ----------
    value : object
        The magnitude given.
    name : str
        The parameter's name, for the message.
    allow_inf : bool
        Accept ``+inf`` (no limit).

    Returns
    -------
    float

    Raises
    ------
    InputError
        If `value` is not a number, is NaN, ``-inf``, or ``+inf`` when not allowed.
    """
    if isinstance(value, bool):
        raise InputError(f"{name} must be a real number, got {show(value)}")
    try:
        out = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a real number, got {show(value)}") from None
    if math.isnan(out) or out == -math.inf or (out == math.inf and not allow_inf):
        allowed = "finite or +inf" if allow_inf else "finite"
        raise InputError(f"{name} must be {allowed}, got {show(value)}")
    return out


def check_fov(fov: object) -> Fov:
    """Return `fov` if it is a :class:`CircularFov` or :class:`RectangularFov`.

    Raises
    ------
    InputError
        For anything else.
    """
    if not isinstance(fov, CircularFov | RectangularFov):
        raise InputError(f"fov must be a CircularFov or RectangularFov, got {type(fov).__name__}")
    return fov
