"""Scalar, array and rotation checks shared by every stage.

Messages name the *parameter* (``rate_rad_s``), never a command-line option: the CLI translates
parameter names to its option names (:func:`starsense.cli.common.option_float` checks an option
under its own name, before the command converts units). Each check returns
the validated value converted to the type the caller computes with.
"""

from __future__ import annotations

import math
import numbers
import secrets

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from starsense.errors import InputError

__all__ = [
    "as_generator",
    "check_count",
    "check_int",
    "check_rotation",
    "check_scalar",
    "finite_array",
    "finite_float",
    "name_keys",
    "positive_float",
    "show",
    "vectors3",
]


#: longest value a message quotes (an array or a long string is cut, never megabytes)
_SHOW_MAX = 200


def show(value: object) -> str:
    """Return plain text for a value in a message: no ``np.float64(...)``, at most 200 chars."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and value.is_integer() and abs(value) < 1e15:
        return repr(value)
    text = repr(value) if isinstance(value, str) else str(value)
    return text if len(text) <= _SHOW_MAX else text[: _SHOW_MAX - 3] + "..."


#: keys a message names before it counts the rest
_KEYS_SHOWN = 5
#: longest key a message quotes as it is
_KEY_MAX = 60


def _key_text(key: object) -> str:
    text = str(key)
    if text.isprintable() and 0 < len(text) <= _KEY_MAX:
        return text
    quoted = repr(text)  # control characters, escape sequences, bytes as \x.. escapes
    return quoted if len(quoted) <= _KEY_MAX else quoted[: _KEY_MAX - 3] + "..."


def name_keys(keys) -> str:
    """Return the first few of ``keys`` for a message, and how many more: never 40 KB.

    A printable key is shown as it is, any other (control characters, a terminal's escape
    sequences) escaped, and each cut at 60 characters: ``a, b, c, d, e and 4,995 more``.
    """
    keys = list(keys)
    shown = ", ".join(_key_text(k) for k in keys[:_KEYS_SHOWN])
    rest = len(keys) - _KEYS_SHOWN
    return shown if rest <= 0 else f"{shown} and {rest:,} more ({len(keys):,} in all)"


def finite_float(value: object, name: str) -> float:
    """Return ``value`` as a finite float, or raise :class:`InputError` naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (numbers.Real, np.generic, str)):
        if not (isinstance(value, np.ndarray) and value.ndim == 0):
            raise InputError(f"{name} must be a real number, got {show(value)}")
    try:
        out = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a real number, got {show(value)}") from None
    if not math.isfinite(out):
        raise InputError(f"{name} must be finite, got {show(value)}")
    return out


def check_scalar(
    value: object,
    name: str,
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
    hi_open: bool = False,
    allow_inf: bool = False,
) -> float:
    """Return a real number within ``[lo, hi]`` (ends open when asked), or raise InputError.

    Parameters
    ----------
    value : object
        What the caller was given.
    name : str
        The parameter's name, used in the message.
    lo, hi : float or None
        Bounds; None for none.
    lo_open, hi_open : bool
        Exclude the bound itself.
    allow_inf : bool
        Accept +-inf (still subject to the bounds); NaN is never accepted.

    Returns
    -------
    float
    """
    if allow_inf:
        try:
            out = float(value)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            raise InputError(f"{name} must be a real number, got {show(value)}") from None
        if math.isnan(out) or isinstance(value, bool):
            raise InputError(f"{name} must be a real number, got {show(value)}")
    else:
        out = finite_float(value, name)
    below = lo is not None and (out <= lo if lo_open else out < lo)
    above = hi is not None and (out >= hi if hi_open else out > hi)
    if below or above:
        left = "(" if lo_open else "["
        right = ")" if hi_open else "]"
        lo_s = "-inf" if lo is None else show(lo)
        hi_s = "inf" if hi is None else show(hi)
        raise InputError(
            f"{name} = {show(value)} is out of range; must be in {left}{lo_s}, {hi_s}{right}"
        )
    return out


def positive_float(value: object, name: str) -> float:
    """Return a finite number > 0, or raise :class:`InputError` naming ``name``."""
    out = finite_float(value, name)
    if out <= 0.0:
        raise InputError(f"{name} must be > 0, got {show(value)}")
    return out


def check_int(
    value: object, name: str, minimum: int | None = None, maximum: int | None = None
) -> int:
    """Return an integer (bools and non-integral floats refused) within the bounds given."""
    if isinstance(value, bool):
        raise InputError(f"{name} must be an integer, got {show(value)}")
    if isinstance(value, numbers.Integral | np.integer):
        out = int(value)
    elif isinstance(value, numbers.Real | np.floating) and float(value).is_integer():
        out = int(value)
    else:
        raise InputError(f"{name} must be an integer, got {show(value)}")
    if minimum is not None and out < minimum:
        raise InputError(f"{name} must be >= {minimum}, got {out}")
    if maximum is not None and out > maximum:
        raise InputError(f"{name} must be <= {maximum}, got {out}")
    return out


def check_count(value: object, name: str, cap: int, cost: str, minimum: int = 1) -> int:
    """Return a count (an integer >= ``minimum``) no larger than ``cap``, checked before any work.

    Parameters
    ----------
    value : object
        The count given.
    name : str
        The parameter (or option) it was given to, for the message.
    cap : int
        The largest count allowed, derived from the memory or time one unit costs.
    cost : str
        What one unit costs, for the message ("~1.3 KB of memory each").
    minimum : int
        The smallest count allowed.

    Raises
    ------
    InputError
        One line naming ``name``, the value, the cap and why.
    """
    n = check_int(value, name, minimum)
    if n > cap:
        raise InputError(f"{name} = {n:,} is above its cap of {cap:,} ({cost}); ask for fewer")
    return n


def finite_array(value: ArrayLike, name: str) -> NDArray[np.float64]:
    """Return a float64 array with no NaN or inf, or raise :class:`InputError` naming ``name``."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a real number or array of them, got {value!r}") from exc
    if not np.all(np.isfinite(arr)):
        bad = arr[~np.isfinite(arr)].flat[0]
        raise InputError(f"{name} = {show(bad)} is not allowed; must be finite")
    return arr


def vectors3(value: ArrayLike, name: str) -> NDArray[np.float64]:
    """Return a finite array of 3-vectors, shape ``(..., 3)``."""
    arr = finite_array(value, name)
    if arr.ndim == 0 or arr.shape[-1] != 3:
        raise InputError(f"{name} must have shape (N, 3) or (3,), got shape {arr.shape}")
    return arr


def check_rotation(rot: object, name: str):
    """Return a single :class:`~scipy.spatial.transform.Rotation` or a 1-D batch of them."""
    if not isinstance(rot, Rotation):
        raise InputError(f"{name} must be a scipy Rotation, got {type(rot).__name__}")
    if not rot.single and len(rot.shape) != 1:
        raise InputError(f"{name} must be a single Rotation or a 1-D batch, got shape {rot.shape}")
    return rot


def as_generator(rng=None) -> tuple[np.random.Generator, int | None]:
    """Return a Generator and the seed it came from: the one reading of every ``rng`` argument.

    ``None`` draws a fresh 63-bit seed from the OS entropy (recorded, so the run can be
    repeated; 63 bits fit a FITS integer keyword), an int seeds a new ``default_rng``, a
    Generator is used as is (seed ``None``: unknown).
    """
    if isinstance(rng, np.random.Generator):
        return rng, None
    if rng is None:
        seed = secrets.randbits(63)
        return np.random.default_rng(seed), seed
    if isinstance(rng, (bool, np.bool_)) or not isinstance(rng, (int, np.integer)) or rng < 0:
        raise InputError(f"rng must be None, a non-negative int seed or a Generator, got {rng!r}")
    return np.random.default_rng(int(rng)), int(rng)
