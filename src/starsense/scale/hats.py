"""HATS catalogues: where they are, which columns they have, a partition as a Catalog.

A partition is read as a :class:`~starsense.catalog.Catalog`.

A HATS catalogue (Hierarchical Adaptive Tiling Scheme) is a directory of Parquet files, one per
HEALPix tile, with ``hats.properties`` (or, for a collection of a catalogue with its margins and
indexes, ``collection.properties``) at its root. It is opened with ``lsdb`` from a local path or
a URL. Published catalogues (verified at the time of writing; the ``data.lsdb.io`` addresses
are those of the LSDB documentation, with a mirror at ``linea.data.lsdb.io``):

====================================  ===============================================
``https://data.lsdb.io/hats/gaia_dr3``  Gaia DR3 ``gaia_source`` (collection; the main
                                        catalogue is ``.../gaia_dr3/gaia``),
                                        1,812,731,847 rows, HEALPix order <= 6
``https://data.lsdb.io/hats/two_mass``  2MASS All-Sky Point Source Catalog (collection),
                                        470,992,970 rows, 1,107 partitions, 43 GB
====================================  ===============================================

Columns are found by name (:data:`MAG_ALIASES`, :data:`COLOUR_ALIASES`): the Gaia archive's
``phot_g_mean_mag``, ``bp_rp`` ..., IRSA's 2MASS ``j_m``, ``h_m``, ``k_m``, or plain band names
(``V``, ``B-V``, ``G``, ``J`` ...) as written by ``starsense catalog import``. A colour that is not
a column is the difference of its two bands, as the in-memory readers compute it.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from starsense.catalog.table import Catalog
from starsense.errors import InputError
from starsense.photometry.colour import COLOUR_SYSTEMS
from starsense.scale._deps import quiet_third_party_warnings, require
from starsense.scale.errors import CatalogUnavailableError, MissingColumnsError
from starsense.scale.location import (  # noqa: F401 - PUBLISHED_HATS, is_hats_spec: public here too
    PUBLISHED_HATS,
    URL_SCHEMES,
    URL_TIMEOUT_S,
    hats_location,
    is_hats_spec,
)
from starsense.scale.location import probe_url as _probe_url

#: band -> accepted column names, in order of preference
MAG_ALIASES: dict[str, tuple[str, ...]] = {
    "V": ("V", "Vmag", "vmag", "mag_v", "v_mag"),
    "B": ("B", "Bmag", "bmag", "mag_b", "b_mag"),
    "I": ("I", "Imag", "imag"),
    "Hp": ("Hp", "Hpmag", "hpmag"),
    "BT": ("BT", "BTmag", "btmag"),
    "VT": ("VT", "VTmag", "vtmag"),
    "J": ("J", "j_m", "Jmag", "jmag"),
    "H": ("H", "h_m", "Hmag", "hmag"),
    "Ks": ("Ks", "k_m", "ks_m", "Kmag", "Ksmag", "kmag"),
    "G": ("G", "phot_g_mean_mag", "Gmag", "gmag"),
    "BP": ("BP", "phot_bp_mean_mag", "BPmag", "bpmag"),
    "RP": ("RP", "phot_rp_mean_mag", "RPmag", "rpmag"),
}

#: colour -> accepted column names (else the difference of its two bands)
COLOUR_ALIASES: dict[str, tuple[str, ...]] = {
    "B-V": ("B-V", "b_v", "BV", "B_V"),
    "V-I": ("V-I", "v_i", "V_I"),
    "BT-VT": ("BT-VT", "bt_vt", "BT_VT"),
    "J-H": ("J-H", "j_h", "J_H"),
    "J-Ks": ("J-Ks", "j_ks", "j_k", "J_Ks"),
    "H-Ks": ("H-Ks", "h_ks", "h_k", "H_Ks"),
    "BP-RP": ("BP-RP", "bp_rp", "BP_RP"),
}


@dataclass(frozen=True)
class ColumnPlan:
    """Which columns of a HATS catalogue make a :class:`Catalog`, and how.

    Picklable and small: it travels with every partition task.

    Attributes
    ----------
    ra, dec : str
        Position columns, degrees (ICRS).
    mags : tuple of (band, column)
    colours : tuple of (colour, column or None)
        None: the difference of the colour's two bands (which are then in ``mags``).
    name, source : str
    epoch_yr : float
    """

    ra: str
    dec: str
    mags: tuple[tuple[str, str], ...]
    colours: tuple[tuple[str, str | None], ...]
    name: str
    source: str
    epoch_yr: float = 2000.0

    @property
    def columns(self) -> list[str]:
        """Columns to read."""
        cols = [self.ra, self.dec, *(c for _, c in self.mags)]
        cols += [c for _, c in self.colours if c is not None]
        return list(dict.fromkeys(cols))

    def catalog(self, frame: Any) -> Catalog:
        """One partition (a pandas-like frame) as a :class:`Catalog` (ids: row numbers)."""

        def col(name: str) -> np.ndarray:
            series = frame[name]
            try:
                return np.asarray(series.to_numpy(dtype=np.float64, na_value=np.nan))
            except (TypeError, ValueError):
                raise InputError(
                    f"{self.source}: column {name!r} is not numeric ({series.dtype})"
                ) from None

        mags = {band: col(c) for band, c in self.mags}
        colours = {}
        for colour, c in self.colours:
            if c is not None:
                colours[colour] = col(c)
            else:
                blue, red, _ = COLOUR_SYSTEMS[colour]
                colours[colour] = mags[blue] - mags[red]
        ra = col(self.ra)
        return Catalog.from_columns(
            name=self.name,
            source=self.source,
            epoch_yr=self.epoch_yr,
            ids=np.arange(len(ra), dtype=np.int64),
            ra_deg=ra,
            dec_deg=col(self.dec),
            mags=mags,
            colours=colours,
        )

    def empty_catalog(self) -> Catalog:
        """Return a catalogue with this plan's columns and no rows (to validate choices early)."""
        z = np.zeros(0)
        return Catalog.from_columns(
            name=self.name,
            source=self.source,
            epoch_yr=self.epoch_yr,
            ids=np.zeros(0, dtype=np.int64),
            ra_deg=z,
            dec_deg=z,
            mags={b: z for b, _ in self.mags},
            colours={c: z for c, _ in self.colours},
        )

    def restrict(self, bands=(), colours=()) -> ColumnPlan:
        """Return the plan reduced to these bands and colours (and the bands those colours need)."""
        keep_c = tuple((c, col) for c, col in self.colours if c in colours)
        need = set(bands) | {b for c, col in keep_c if col is None for b in COLOUR_SYSTEMS[c][:2]}
        keep_m = tuple((b, col) for b, col in self.mags if b in need)
        return dataclasses.replace(self, mags=keep_m, colours=keep_c)


def _find(names: list[str], aliases: tuple[str, ...]) -> str | None:
    for a in aliases:
        if a in names:
            return a
    lower = {n.lower(): n for n in names}
    for a in aliases:
        if a.lower() in lower:
            return lower[a.lower()]
    return None


@dataclass(frozen=True, eq=False)
class HatsCatalog:
    """An opened HATS catalogue (metadata only; partitions are read by the workers).

    Attributes
    ----------
    location : str
        Path or URL.
    name : str
    columns : tuple of str
        All columns of the catalogue.
    ra_column, dec_column : str
    n_rows : int or None
        Rows according to the catalogue's properties.
    n_partitions : int
    """

    location: str
    name: str
    columns: tuple[str, ...]
    ra_column: str
    dec_column: str
    n_rows: int | None
    n_partitions: int
    dataset: Any = dataclasses.field(default=None, repr=False)
    """The ``hats`` catalogue object (metadata, read once; None: read again when needed)."""

    def plan(self) -> ColumnPlan:
        """Every magnitude and colour this catalogue can give (see the module notes)."""
        names = list(self.columns)
        mags = tuple((band, col) for band, al in MAG_ALIASES.items() if (col := _find(names, al)))
        have = dict(mags)
        colours: list[tuple[str, str | None]] = []
        for colour, al in COLOUR_ALIASES.items():
            col = _find(names, al)
            blue, red, _ = COLOUR_SYSTEMS[colour]
            if col is not None:
                colours.append((colour, col))
            elif blue in have and red in have:
                colours.append((colour, None))
        epoch = 2016.0 if "G" in have and have["G"] == "phot_g_mean_mag" else 2000.0
        return ColumnPlan(
            self.ra_column,
            self.dec_column,
            mags,
            tuple(colours),
            self.name,
            self.location,
            epoch,
        )

    def missing(self, what: str) -> MissingColumnsError:
        """Return the error for a catalogue without a column for ``what``."""
        return MissingColumnsError(
            f"HATS catalogue {self.location}: no column for {what} (columns: "
            f"{', '.join(self.columns)}); magnitude columns are recognised by the names "
            f"{', '.join(a for al in MAG_ALIASES.values() for a in al[:2])}, colours by "
            f"{', '.join(a for al in COLOUR_ALIASES.values() for a in al[:2])} "
            "or as the difference of two bands"
        )

    def partitions(self, columns: list[str]) -> list[Any]:
        """One dask Delayed per partition, reading ``columns`` (lsdb)."""
        (lsdb,) = require("lsdb")
        try:
            with warnings.catch_warnings():
                quiet_third_party_warnings()
                cat = _lsdb_catalog(lsdb, self.location, self.dataset, columns)
        except (OSError, ValueError) as exc:
            raise CatalogUnavailableError(
                f"cannot read HATS catalogue {self.location}: {exc}"
            ) from None
        return cat.to_delayed()


def _lsdb_catalog(lsdb: Any, location: str, dataset: Any, columns: list[str]) -> Any:
    """``lsdb.open_catalog(location, columns=columns)`` reusing metadata read by :func:`open_hats`.

    ``lsdb.open_catalog`` reads the catalogue's coverage map (``point_map.fits``: 66 MB for a
    catalogue mapped at HEALPix order 10, more for Gaia) on every call, ~1 s locally, longer
    over HTTP; the analyses never need it. lsdb reads the columns given when opening (a column
    selection afterwards still reads all of them), so each analysis opens with its own columns,
    from the metadata already in hand, through lsdb's loader; if that internal function ever
    changes, the public call is the fallback.
    """
    try:
        from lsdb.loaders.hats.read_hats import _read_dataset
    except ImportError:  # pragma: no cover - a future lsdb
        _read_dataset = None
    if dataset is not None and _read_dataset is not None:
        try:
            return _read_dataset(dataset, columns=columns)
        except TypeError:  # pragma: no cover - signature changed
            pass
    return lsdb.open_catalog(location, columns=columns)  # pragma: no cover


def open_hats(spec: str, timeout_s: float = URL_TIMEOUT_S) -> HatsCatalog:
    """Open a HATS catalogue (or collection) from ``hats:PATH_OR_URL`` or a bare path / URL.

    Raises
    ------
    CatalogUnavailableError
        The path does not exist or is not HATS, or the URL does not answer within
        ``timeout_s`` (no hang on an unreachable host).
    ScaleNotInstalledError
        ``starsense[scale]`` is not installed.
    """
    location = hats_location(spec) if is_hats_spec(spec) else str(spec).strip()
    if not math.isfinite(timeout_s) or timeout_s <= 0:
        raise InputError(f"timeout must be > 0 s, got {timeout_s!r}")
    lower = location.lower()
    is_http = lower.startswith(("http://", "https://"))
    if is_http:
        _probe_url(location, timeout_s)  # before importing lsdb: a refusal is known at once
    hats, _lsdb = require("hats", "lsdb")
    if not is_http and not lower.startswith(URL_SCHEMES):
        path = Path(location).expanduser()
        if not path.exists():
            raise CatalogUnavailableError(f"HATS catalogue not found: {path}")
        if not path.is_dir():
            raise CatalogUnavailableError(
                f"{path} is a file; a HATS catalogue is a directory (make one with "
                "`starsense catalog import`)"
            )
        location = str(path)
    try:
        with warnings.catch_warnings():
            quiet_third_party_warnings()
            dataset = hats.read_hats(location, read_moc=False)  # coverage map: not needed
    except (OSError, ValueError, KeyError) as exc:
        raise CatalogUnavailableError(
            f"{location} is not a readable HATS catalogue ({type(exc).__name__}: {exc})"
        ) from None
    main = getattr(dataset, "main_catalog", dataset)  # a collection -> its main catalogue
    info = main.catalog_info
    if getattr(main, "schema", None) is None:
        raise CatalogUnavailableError(f"{location}: HATS catalogue without a schema (_metadata)")
    hidden = {"Norder", "Dir", "Npix", "_healpix_29"}
    columns = tuple(n for n in main.schema.names if n not in hidden)
    ra, dec = info.ra_column or "ra", info.dec_column or "dec"
    for c in (ra, dec):
        if c not in columns:
            raise MissingColumnsError(f"HATS catalogue {location}: position column {c!r} missing")
    return HatsCatalog(
        location=location,
        name=str(info.catalog_name),
        columns=columns,
        ra_column=ra,
        dec_column=dec,
        n_rows=int(info.total_rows) if info.total_rows is not None else None,
        n_partitions=len(main.get_healpix_pixels()),
        dataset=main,
    )
