"""The on-disk cache of identification databases (directories in the user cache directory).

One database is one directory: ``meta.json`` (the cache key, the build parameters) and one
``.npy`` file per array, which :func:`read_arrays` memory-maps (``mmap_mode="r"``): opening a
database reads only its header, and a solve then touches the pages it probes, so start-up does
not pay for the whole database, nor a process for memory it does not use.

The cache key is a hash of the catalogue's name, size and a digest of its identifiers,
positions and magnitudes (the content, not the file's path or modification time: a fresh
clone or a moved installation reuses its databases), and every build parameter. A directory is
written under a temporary name (:func:`starsense._io.temp_prefix`, swept when its process is
gone) and renamed into place; a missing, unreadable or stale one reads as None, and the
database is then rebuilt.

``meta.json`` also holds each array file's size and SHA-256, checked when the database is
opened: a file of another size, or whose content no longer hashes to its checksum (a disk
error, a truncated copy, an edit), makes the database read as None, with a warning naming
the file, and it is rebuilt. Hashing a 300 MB database takes ~0.5 s, more than a solve, so a
file is hashed once per version of it on disk: ``verified.json`` records the size, times and
inode each file had when its checksum last matched, and a file unchanged since is not hashed
again (a file written or copied anew changes them).
"""

from __future__ import annotations

import hashlib
import json
import logging
import mmap
import os
import shutil
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from starsense._io import dir_mode, file_mode, sweep_stale, temp_prefix
from starsense.catalog.cache import default_cache_dir

if TYPE_CHECKING:
    from starsense.catalog.table import Catalog

__all__ = [
    "DATABASE_FORMAT_VERSION",
    "IN_MEMORY_MAX_BYTES",
    "BuildParams",
    "database_cache_file",
    "page_in",
    "read_arrays",
    "write_arrays",
]


class BuildParams(Protocol):
    """What the cache key needs of a database's build parameters.

    :class:`starsense.identify.database.DatabaseParams` (which imports this module).
    """

    band: str

    def to_json(self) -> str:
        """Return the parameters as a JSON object (text)."""
        ...


DATABASE_FORMAT_VERSION = 3
"""Version of the on-disk layout (2: a directory of ``.npy`` files, memory-mapped; the key
without the catalogue's path; 3: each file's size and SHA-256 in ``meta.json``); bump it when
the layout or the build algorithm changes."""

#: the file recording which array files were last found to match their checksums
_VERIFIED = "verified.json"

#: arrays up to this size are read into memory when a database is opened, bytes (16 MiB: the
#: star tables of any database; the pattern tables above it stay memory-mapped)
IN_MEMORY_MAX_BYTES = 16 * 2**20

_log = logging.getLogger(__name__)


def _catalog_digest(catalog: Catalog, band: str) -> dict:
    """Return what identifies a catalogue's content for the cache key."""
    h = hashlib.sha256()
    for arr in (catalog.ids, catalog.ra_rad, catalog.dec_rad, catalog.mags[band]):
        h.update(np.ascontiguousarray(arr).tobytes())
    return {"name": catalog.name, "n": len(catalog), "digest": h.hexdigest()[:32]}


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
        The database's directory.
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
    return directory / f"iddb-{catalog.name}-{digest}", key


def write_arrays(path: str | Path, meta: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
    """Write ``meta`` (JSON, with the format version) and ``arrays`` (``.npy``) as directory `path`.

    Written under a temporary name beside `path`, then renamed into place; a stale or
    unreadable directory already at `path` is replaced, one another process has just written
    is kept.

    Parameters
    ----------
    path : str or Path
        The database's directory; its parent is created if needed.
    meta : dict
        JSON-serialisable metadata (the cache key, build parameters, ...).
    arrays : dict of str to ndarray
        The arrays to store, one ``NAME.npy`` file each.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    sweep_stale(target)
    tmp = target.parent / f"{temp_prefix(target)}dir"
    try:
        tmp.mkdir(mode=dir_mode())
        files = {}
        for name, arr in arrays.items():
            np.save(tmp / f"{name}.npy", np.ascontiguousarray(arr), allow_pickle=False)
            files[name] = _file_checksum(tmp / f"{name}.npy")
        full = {**meta, "files": files, "format": DATABASE_FORMAT_VERSION}
        (tmp / "meta.json").write_text(json.dumps(full))
        for entry in tmp.iterdir():
            entry.chmod(file_mode())
        # the files were hashed as written: recorded as verified (after the chmod, which
        # changes their ctime), so the first open does not hash them again
        _write_verified(tmp, {name: _stamp(tmp / f"{name}.npy") for name in arrays})
        if (tmp / _VERIFIED).exists():
            (tmp / _VERIFIED).chmod(file_mode())
        if target.exists() and read_arrays(target, tuple(arrays), meta.get("key")) is None:
            shutil.rmtree(target) if target.is_dir() else target.unlink()
        try:
            tmp.rename(target)
        except OSError:
            if read_arrays(target, tuple(arrays), meta.get("key")) is None:
                raise  # not a concurrent writer's copy: say so
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def read_arrays(
    path: str | Path, names: tuple[str, ...], key: str | None = None
) -> tuple[dict[str, Any], dict[str, np.ndarray]] | None:
    """Open a directory written by :func:`write_arrays`; None if missing, unreadable or stale.

    The arrays larger than :data:`IN_MEMORY_MAX_BYTES` (the pattern tables) are memory-mapped
    read-only (``np.load(..., mmap_mode="r")``), as plain ndarrays; smaller ones (the star
    tables) are read into memory.

    Parameters
    ----------
    path : str or Path
        The database's directory.
    names : tuple of str
        The arrays to open.
    key : str, optional
        The expected cache key; a directory with another key is stale.

    Returns
    -------
    (dict, dict of str to ndarray) or None
        The metadata and the arrays.
    """
    path = Path(path)
    if not path.is_dir():
        return None
    try:
        meta = json.loads((path / "meta.json").read_text())
        if meta.get("format") != DATABASE_FORMAT_VERSION:
            _log.info("rebuilding identification database %s: an older format", path)
            return None
        if key is not None and meta.get("key") != key:
            return None
        bad = _unverified(path, names, meta.get("files"))
        if bad is not None:
            _log.warning("identification database %s: %s; rebuilding it", path, bad)
            return None
        arrays = {}
        for a in names:
            mapped = np.load(path / f"{a}.npy", mmap_mode="r", allow_pickle=False)
            # the pattern tables stay mapped (a plain read-only view, no copy); the small
            # star tables are read into memory, writable like any array a user gets (scipy's
            # Rotation.apply, for one, refuses a read-only buffer)
            small = mapped.nbytes <= IN_MEMORY_MAX_BYTES
            arrays[a] = np.array(mapped) if small else np.asarray(mapped)
        return meta, arrays
    except (OSError, ValueError, KeyError, TypeError, EOFError) as exc:
        _log.warning("identification database %s is unreadable (%s); rebuilding it", path, exc)
        return None


def page_in(arrays) -> None:
    """Read every page of the arrays :func:`read_arrays` left memory-mapped, once.

    A mapped table is read from its file a page at a time the first time a lookup reaches it:
    the first frames pay those reads (a search of an unknown scale reaches many). Reading one
    byte a page moves them to the start (a few ms for 100 MB already in the system's file
    cache); :meth:`starsense.solve.solver.Solver.prepare` does it. Arrays in memory are left.
    """
    for a in arrays:
        if isinstance(a.base, np.memmap):
            int(np.add.reduce(a.reshape(-1).view(np.uint8)[:: mmap.PAGESIZE], dtype=np.int64))


def _file_checksum(path: Path) -> dict:
    """Return a file's size and SHA-256 (hex)."""
    with open(path, "rb") as fh:
        digest = hashlib.file_digest(fh, "sha256").hexdigest()
    return {"bytes": path.stat().st_size, "sha256": digest}


def _stamp(path: Path) -> list[int]:
    """Return what changes when a file is written, copied or replaced: size, times, inode."""
    st = path.stat()
    return [st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_ino]


def _write_verified(path: Path, stamps: dict) -> None:
    """Record the files found to match their checksums (best effort: a read-only cache)."""
    target = path / _VERIFIED
    tmp = path / f"{temp_prefix(target)}json"
    try:
        tmp.write_text(json.dumps(stamps))
        os.replace(tmp, target)
    except OSError:
        tmp.unlink(missing_ok=True)


def _unverified(path: Path, names: tuple[str, ...], files: Any) -> str | None:
    """Return why the array files of ``path`` do not match ``files`` (meta.json), or None.

    A file's size is checked every time; its SHA-256 when the file changed since it last
    matched (``verified.json``).
    """
    if not isinstance(files, dict):
        return "meta.json holds no checksums"
    try:
        verified = json.loads((path / _VERIFIED).read_text())
    except (OSError, ValueError):
        verified = {}
    verified = verified if isinstance(verified, dict) else {}
    changed = False
    for name in names:
        expected = files.get(name)
        if not isinstance(expected, dict):
            return f"meta.json holds no checksum of {name}.npy"
        file = path / f"{name}.npy"
        stamp = _stamp(file)
        if stamp[0] != expected.get("bytes"):
            return f"{name}.npy has {stamp[0]:,} bytes, not the {expected.get('bytes')} written"
        if verified.get(name) == stamp:
            continue
        if _file_checksum(file)["sha256"] != expected.get("sha256"):
            return f"{name}.npy does not match its checksum (garbled)"
        verified[name], changed = stamp, True
    if changed:
        _write_verified(path, verified)
    return None
