"""A parse-once cache of catalogues as ``.npz`` files.

Parsing a text catalogue (hip2.dat is ~33 MB) takes about a second; loading the same columns
from an uncompressed ``.npz`` takes milliseconds. :func:`cached_load` keys each cache file by
the source's absolute path, size and modification time (ns), the reader's name and its
``READER_VERSION`` and the cache layout version, so editing or replacing the source, or
changing a reader, invalidates the entry. Files are written atomically
(:func:`starsense._io.atomic_write`: a temporary name, then a rename). If the cache directory
cannot be created or written the catalogue is still returned, just without being cached.

The directory is ``platformdirs.user_cache_dir("starsense")/catalogs`` unless the environment
variable ``STARSENSE_CACHE_DIR`` names another one.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import sys
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import platformdirs

from starsense._io import atomic_write
from starsense.catalog._parse import existing_file
from starsense.catalog.table import Catalog

CACHE_FORMAT_VERSION = 1
"""Version of the ``.npz`` layout written here; bump it when that layout changes."""

CACHE_DIR_ENV = "STARSENSE_CACHE_DIR"
"""Environment variable overriding the cache directory."""

_log = logging.getLogger(__name__)

_OPTIONAL = ("pm_ra_rad_yr", "pm_dec_rad_yr", "parallax_rad", "radial_motion_per_yr")


def default_cache_dir() -> Path:
    """Return the catalogue cache directory (``$STARSENSE_CACHE_DIR`` if set)."""
    env = os.environ.get(CACHE_DIR_ENV)
    if env:
        return Path(env).expanduser()
    return Path(platformdirs.user_cache_dir("starsense")) / "catalogs"


def cache_key(reader: Callable[[Path], Catalog], path: str | Path) -> str:
    """Return the string identifying one (reader, source file state) pair."""
    p = Path(path).expanduser().resolve()
    st = p.stat()
    module = sys.modules.get(reader.__module__)
    return json.dumps(
        {
            "path": str(p),
            "size": st.st_size,
            "mtime_ns": st.st_mtime_ns,
            "reader": f"{reader.__module__}.{reader.__qualname__}",
            "reader_version": getattr(module, "READER_VERSION", 0),
            "cache_format": CACHE_FORMAT_VERSION,
        },
        sort_keys=True,
    )


def _digest(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def cache_file(
    reader: Callable[[Path], Catalog], path: str | Path, cache_dir: str | Path | None = None
) -> Path:
    """Where :func:`cached_load` keeps ``reader(path)`` for the file's current state."""
    key = cache_key(reader, path)
    return Path(cache_dir or default_cache_dir()) / f"{_stem(reader, path)}-{_digest(key)}.npz"


def _stem(reader: Callable[[Path], Catalog], path: str | Path) -> str:
    p = Path(path).expanduser().resolve()
    return f"{reader.__name__}-{_digest(f'{reader.__module__}.{reader.__qualname__}|{p}')}"


def cached_load(
    reader: Callable[[Path], Catalog],
    path: str | Path,
    *,
    cache_dir: str | Path | None = None,
) -> Catalog:
    """``reader(path)``, parsed once and then loaded from an ``.npz`` cache.

    Parameters
    ----------
    reader : callable
        A catalogue reader taking a path, e.g. :func:`~starsense.catalog.load_hip2`.
    path : str or Path
        The catalogue file.
    cache_dir : str or Path, optional
        Cache directory; default :func:`default_cache_dir`.

    Returns
    -------
    Catalog
        Equal column by column to ``reader(path)``.

    Raises
    ------
    InputError
        If ``path`` is not an existing file.
    CatalogFormatError
        If the file is malformed (nothing is cached then).
    """
    source = existing_file(path)
    directory = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    key = cache_key(reader, source)
    target = directory / f"{_stem(reader, source)}-{_digest(key)}.npz"
    catalog = _read(target, key)
    if catalog is not None:
        return catalog
    catalog = reader(source)
    if cache_key(reader, source) == key:  # the file did not change while we parsed it
        _write(target, key, catalog, stale_prefix=_stem(reader, source))
    return catalog


def _to_arrays(catalog: Catalog, key: str) -> dict[str, np.ndarray]:
    arrays: dict[str, np.ndarray] = {
        "ids": catalog.ids,
        "ra_rad": catalog.ra_rad,
        "dec_rad": catalog.dec_rad,
    }
    for attr in _OPTIONAL:
        value = getattr(catalog, attr)
        if value is not None:
            arrays[attr] = value
    for i, values in enumerate(catalog.mags.values()):
        arrays[f"mag{i}"] = values
    for i, values in enumerate(catalog.colours.values()):
        arrays[f"colour{i}"] = values
    for i, values in enumerate(catalog.extra.values()):
        arrays[f"extra{i}"] = values
    meta = {
        "key": key,
        "name": catalog.name,
        "source": catalog.source,
        "epoch_yr": catalog.epoch_yr,
        "mags": list(catalog.mags),
        "colours": list(catalog.colours),
        "extra": list(catalog.extra),
    }
    arrays["meta"] = np.array(json.dumps(meta))
    return arrays


def _read(target: Path, key: str) -> Catalog | None:
    if not target.is_file():
        return None
    try:
        with np.load(target, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            if meta.get("key") != key:
                return None
            return Catalog(
                name=meta["name"],
                source=meta["source"],
                epoch_yr=meta["epoch_yr"],
                ids=z["ids"],
                ra_rad=z["ra_rad"],
                dec_rad=z["dec_rad"],
                mags={b: z[f"mag{i}"] for i, b in enumerate(meta["mags"])},
                colours={c: z[f"colour{i}"] for i, c in enumerate(meta["colours"])},
                extra={e: z[f"extra{i}"] for i, e in enumerate(meta["extra"])},
                **{attr: z[attr] if attr in z.files else None for attr in _OPTIONAL},
            )
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        _log.info("ignoring unreadable catalogue cache %s: %s", target, exc)
        return None


def _write(target: Path, key: str, catalog: Catalog, *, stale_prefix: str) -> None:
    """Write ``catalog`` to ``target`` atomically, then remove stale entries of its source."""
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        with atomic_write(target, "wb", output=False) as f:
            np.savez(f, **_to_arrays(catalog, key))
        for old in target.parent.glob(f"{stale_prefix}-*.npz"):
            if old != target:
                with contextlib.suppress(OSError):
                    old.unlink()
    except OSError as exc:
        _log.info("catalogue cache not written to %s: %s", target, exc)
