"""JSON output that is always valid JSON: NaN and infinity become ``null``."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from typing import Any

__all__ = ["json_text", "jsonable"]


def jsonable(x: Any) -> Any:
    """Return ``x`` with NumPy scalars and arrays as Python values and NaN/inf as None.

    JSON has no NaN or infinity: a missing or unbounded number is written ``null``.
    """
    if isinstance(x, Mapping):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple | set | frozenset):
        return [jsonable(v) for v in x]
    if hasattr(x, "tolist") and hasattr(x, "dtype"):  # numpy arrays and scalars
        return jsonable(x.tolist())
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, os.PathLike):
        return os.fspath(x)
    return x


def json_text(x: Any, indent: int | None = 2) -> str:
    """Return ``x`` as valid JSON text (:func:`jsonable` first; ``allow_nan=False`` then holds).

    Parameters
    ----------
    x : object
        Dicts, lists, numbers, strings, NumPy values, paths.
    indent : int or None
        As for :func:`json.dumps`.

    Returns
    -------
    str
    """
    return json.dumps(jsonable(x), indent=indent, allow_nan=False)
