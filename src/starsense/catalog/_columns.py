"""Column checks of :class:`~starsense.catalog.table.Catalog`: shapes, types, ranges.

Each check returns the column as the catalogue stores it (a read-only float64 or int64 view)
or raises :class:`~starsense.errors.InputError` naming the column and, for a bad value, the
star (row and identifier).
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

import numpy as np

from starsense.errors import InputError

_TWO_PI = 2.0 * np.pi


def readonly(a: np.ndarray) -> np.ndarray:
    """Return a read-only view of ``a``."""
    view = a.view()
    view.flags.writeable = False
    return view


def float_column(name: str, values: object, n: int | None) -> np.ndarray:
    """Return ``values`` as a read-only float64 ``(n,)`` column (any length if n is None)."""
    try:
        a = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"column {name} must be numeric: {exc}") from exc
    if a.ndim != 1:
        raise InputError(f"column {name} must be one-dimensional (N,), got shape {a.shape}")
    if n is not None and a.shape[0] != n:
        raise InputError(f"column {name} has {a.shape[0]} rows, expected {n} (length of ra_rad)")
    return readonly(a)


def named_columns(
    kind: str, columns: Mapping[str, object] | None, allowed: tuple[str, ...], n: int
) -> Mapping[str, np.ndarray]:
    """Return a read-only mapping of checked float columns whose names are in ``allowed``."""
    if columns is None:
        columns = {}
    if not isinstance(columns, Mapping):
        raise InputError(f"{kind} must be a mapping of name -> (N,) array, got {type(columns)}")
    out: dict[str, np.ndarray] = {}
    for key, values in columns.items():
        if key not in allowed:
            raise InputError(f"unknown {kind[:-1]} name {key!r}; allowed: {', '.join(allowed)}")
        out[key] = float_column(f"{kind}[{key!r}]", values, n)
    return MappingProxyType(out)


def id_column(ids: object, n: int) -> np.ndarray:
    """Return the identifiers as a read-only int64 ``(n,)`` column."""
    ids = np.asarray(ids)
    if ids.ndim != 1 or ids.shape[0] != n:
        raise InputError(f"ids must have shape ({n},), got {ids.shape}")
    if ids.size and not np.issubdtype(ids.dtype, np.integer):
        raise InputError(f"ids must be integers, got dtype {ids.dtype}")
    return readonly(ids.astype(np.int64, copy=False))


def position_columns(
    ra: np.ndarray, dec: np.ndarray, ids: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Check RA/Dec (rad); return RA wrapped into [0, 2 pi) and Dec clipped to +-pi/2."""
    n = ra.shape[0]
    bad = ~(np.isfinite(ra) & np.isfinite(dec))
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(
            f"RA/Dec must be finite: star {i} (id {ids[i]}) has ra_rad={ra[i]!r}, "
            f"dec_rad={dec[i]!r}"
        )
    bad = np.abs(dec) > 0.5 * np.pi + 1e-12
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(
            f"dec_rad must lie in [-pi/2, pi/2]: star {i} (id {ids[i]}) has {dec[i]!r}"
        )
    if n and ((ra < 0).any() or (ra >= _TWO_PI).any()):
        wrapped = np.mod(ra, _TWO_PI)
        wrapped[wrapped >= _TWO_PI] = 0.0
        ra = readonly(wrapped)
    return ra, readonly(np.clip(dec, -0.5 * np.pi, 0.5 * np.pi))


def extra_columns(extra: object, n: int) -> Mapping[str, np.ndarray]:
    """Return a read-only mapping of the ``extra`` columns, each with ``n`` rows."""
    extra = extra if extra is not None else {}
    if not isinstance(extra, Mapping):
        raise InputError(f"extra must be a mapping of name -> array, got {type(extra)}")
    checked: dict[str, np.ndarray] = {}
    for key, values in extra.items():
        a = np.asarray(values)
        if a.ndim < 1 or a.shape[0] != n:
            raise InputError(f"extra[{key!r}] must have {n} rows, got shape {a.shape}")
        if a.dtype == object:
            raise InputError(f"extra[{key!r}] must not be an object array (use str/bytes)")
        checked[str(key)] = readonly(a)
    return MappingProxyType(checked)
