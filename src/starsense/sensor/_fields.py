"""The one check of a numeric sensor field: a TOML number, finite, within its allowed range.

Messages name the field as it is written in the TOML file (``detector.bit_depth``), its value
and the allowed range; the range check itself is :func:`starsense._validate.check_scalar`.
"""

from __future__ import annotations

import numbers

from starsense._validate import check_int, check_scalar, show
from starsense.errors import InputError


def check_field(
    section: str,
    key: str,
    value: object,
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
    hi_open: bool = False,
    integer: bool = False,
) -> None:
    """Raise :class:`InputError` unless ``value`` is a number (an integer if asked) in range.

    Parameters
    ----------
    section, key : str
        TOML table and key, e.g. ``"detector"``, ``"bit_depth"``: the message names
        ``section.key``.
    value : object
        The field's value. Strings and booleans are refused: a TOML value in quotes is not a
        number, even when it reads like one.
    lo, hi : float or None
        Allowed range; None for no bound.
    lo_open, hi_open : bool
        Exclude the bound itself.
    integer : bool
        The value must be integral.
    """
    name = f"{section}.{key}"
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputError(f"{name} must be a number, got {show(value)}")
    if integer:
        check_int(value, name)
    check_scalar(value, name, lo, hi, lo_open=lo_open, hi_open=hi_open)
