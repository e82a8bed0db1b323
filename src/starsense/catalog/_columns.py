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
            f"RA/Dec must be finite: star {i} (id {ids[i]}) has ra_rad={float(ra[i])!r}, "
            f"dec_rad={float(dec[i])!r}"
        )
    bad = np.abs(dec) > 0.5 * np.pi + 1e-12
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(
            f"dec_rad must lie in [-pi/2, pi/2]: star {i} (id {ids[i]}) has {float(dec[i])!r}"
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


#: magnitudes a catalogue may hold: the Sun is -26.7, the deepest surveys reach ~30; anything
#: outside (BSC5's 327.67, a G of 1e300) is a sentinel or a corrupt value, never a star
MAG_RANGE = (-30.0, 35.0)


def check_magnitudes(mags: Mapping[str, np.ndarray], ids: np.ndarray, source: str) -> None:
    """Raise :class:`InputError` at the first magnitude outside :data:`MAG_RANGE` (NaN: missing).

    The message names the source, the band, the star (row and identifier) and the value.
    """
    lo, hi = MAG_RANGE
    for band, values in mags.items():
        with np.errstate(invalid="ignore"):
            bad = (values < lo) | (values > hi)
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(
                f"{source}: magnitude {band} = {float(values[i]):g} of star {i + 1} (id "
                f"{int(ids[i])}) is outside [{lo:g}, {hi:g}] (a missing-value sentinel?)"
            )


def check_unique_ids(catalog, id_name: str = "id"):
    """Return ``catalog`` if no identifier appears twice; else raise naming the first repeat.

    Readers call it on what they read: a star listed twice would be counted twice by every
    analysis. (Catalogues stacked with ``concat`` may share identifiers and are not checked.)

    Raises
    ------
    InputError
        Naming the source, the identifier, how often it appears and the first two rows.
    """
    ids = catalog.ids
    order = np.argsort(ids, kind="stable")
    same = ids[order[1:]] == ids[order[:-1]]
    if same.any():
        k = int(np.argmax(same))
        first, second = int(order[k]), int(order[k + 1])
        value = ids[first]
        n_dup = int(same.sum())
        raise InputError(
            f"{catalog.source}: {id_name} {int(value)} appears more than once (stars {first + 1} "
            f"and {second + 1}; {n_dup:,} repeated rows in all): each star must be listed once"
        )
    return catalog
