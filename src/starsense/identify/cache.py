"""The on-disk cache of identification databases (``.npz`` files in the user cache directory).

The cache key is a hash of the catalogue's name, source, size, the modification time of its
source file (if it is one), a digest of its positions and magnitudes, and every build
parameter. Files are written atomically (:func:`starsense._io.atomic_write`); a missing,
unreadable or stale file reads as None, and the database is then rebuilt.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from starsense._io import atomic_write
from starsense.catalog.cache import default_cache_dir

if TYPE_CHECKING:
    from starsense.catalog.table import Catalog

__all__ = ["DATABASE_FORMAT_VERSION", "BuildParams", "database_cache_file", "read_npz", "write_npz"]


class BuildParams(Protocol):
    """What the cache key needs of a database's build parameters.

    :class:`starsense.identify.database.DatabaseParams` (which imports this module).
    """

    band: str

    def to_json(self) -> str:
        """Return the parameters as a JSON object (text)."""
        ...


DATABASE_FORMAT_VERSION = 1
"""Version of the ``.npz`` layout; bump it when the layout or the build algorithm changes."""

_log = logging.getLogger(__name__)


def _catalog_digest(catalog: Catalog, band: str) -> dict:
    """Return what identifies a catalogue's content for the cache key."""
    h = hashlib.sha256()
    for arr in (catalog.ids, catalog.ra_rad, catalog.dec_rad, catalog.mags[band]):
        h.update(np.ascontiguousarray(arr).tobytes())
    info: dict = {
        "name": catalog.name,
        "source": str(catalog.source),
        "n": len(catalog),
        "digest": h.hexdigest()[:32],
    }
    with contextlib.suppress(OSError, ValueError):
        st = Path(catalog.source).stat()
        info["size"] = st.st_size
        info["mtime_ns"] = st.st_mtime_ns
    return info


def database_cache_file(
    catalog: Catalog, params: BuildParams, cache_dir: str | Path | None = None
) -> tuple[Path, str]:
    """Return the path and key of the cache file of ``build_database(catalog, params)``.

    Parameters
    ----------
    catalog : Catalog
        The source catalogue.
    params : DatabaseParams
        The build parameters.
    cache_dir : str or Path, optional
        The cache directory; default ``identify/`` in the catalogue cache directory
        (:func:`starsense.catalog.cache.default_cache_dir`).

    Returns
    -------
    path : Path
        The ``.npz`` file.
    key : str
        The key stored in (and checked against) the file.
    """
    key = json.dumps(
        {
            "catalog": _catalog_digest(catalog, params.band),
            "params": json.loads(params.to_json()),
            "format": DATABASE_FORMAT_VERSION,
        },
        sort_keys=True,
    )
    digest = hashlib.sha256(key.encode()).hexdigest()[:16]
    directory = Path(cache_dir) if cache_dir is not None else default_cache_dir() / "identify"
    return directory / f"iddb-{catalog.name}-{digest}.npz", key


def write_npz(path: str | Path, meta: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
    """Write ``meta`` (as JSON, with the format version) and ``arrays`` to ``path`` atomically.

    Parameters
    ----------
    path : str or Path
        The ``.npz`` file; its directory is created if needed.
    meta : dict
        JSON-serialisable metadata (the cache key, build parameters, ...).
    arrays : dict of str to ndarray
        The arrays to store.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    meta = {**meta, "format": DATABASE_FORMAT_VERSION}
    with atomic_write(target, "wb") as f:
        np.savez(f, meta=np.array(json.dumps(meta)), **arrays)


def read_npz(
    path: str | Path, names: tuple[str, ...], key: str | None = None
) -> tuple[dict[str, Any], dict[str, np.ndarray]] | None:
    """Read a file written by :func:`write_npz`; None if missing, unreadable or stale.

    Parameters
    ----------
    path : str or Path
        The ``.npz`` file.
    names : tuple of str
        The arrays to read.
    key : str, optional
        The expected cache key; a file with another key is stale.

    Returns
    -------
    (dict, dict of str to ndarray) or None
        The metadata and the arrays.
    """
    path = Path(path)
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            if meta.get("format") != DATABASE_FORMAT_VERSION:
                return None
            if key is not None and meta.get("key") != key:
                return None
            return meta, {a: z[a] for a in names}
    except (OSError, ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile) as exc:
        _log.info("ignoring unreadable identification database %s: %s", path, exc)
        return None
