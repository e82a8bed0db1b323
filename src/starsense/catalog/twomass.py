r"""Reader for the 2MASS All-Sky Point Source Catalog (Skrutskie et al. 2006; Cutri 2003).

Two forms are accepted:

* the distributed ``psc_aaa.gz`` ... ``psc_bcp.gz`` files: one source per line, 60 fields
  separated by ``|``, no header, null written ``\N`` (column list below, from the 2MASS
  All-Sky Data Release Explanatory Supplement, "format_psc");
* a CSV with a header naming at least ``ra``, ``dec`` (or ``decl``), ``j_m``, ``h_m``, ``k_m``,
  as exported from IRSA; a ``pts_key`` or ``cntr`` column is used as the identifier if present.

Positions are ICRS (J2000 equinox) at each source's observation epoch, 1997-2001 (``jdate``);
2MASS gives no proper motions, so the catalogue epoch is set to the nominal 2000.0 and the
positions of moving stars are off by up to ~3 yr of proper motion.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from starsense.catalog._columns import check_unique_ids
from starsense.catalog._parse import check_range, existing_file, head_lines, read_delimited
from starsense.catalog.table import Catalog
from starsense.errors import CatalogFormatError

READER_VERSION = 1
"""Bump when the output of this reader changes (invalidates cached catalogues)."""

TWOMASS_EPOCH_YR = 2000.0

PSC_COLUMNS: tuple[str, ...] = (
    "ra", "decl", "err_maj", "err_min", "err_ang", "designation",
    "j_m", "j_cmsig", "j_msigcom", "j_snr",
    "h_m", "h_cmsig", "h_msigcom", "h_snr",
    "k_m", "k_cmsig", "k_msigcom", "k_snr",
    "ph_qual", "rd_flg", "bl_flg", "cc_flg", "ndet", "prox", "pxpa", "pxcntr",
    "gal_contam", "mp_flg", "pts_key", "hemis", "date", "scan", "glon", "glat", "x_scan",
    "jdate", "j_psfchi", "h_psfchi", "k_psfchi",
    "j_m_stdap", "j_msig_stdap", "h_m_stdap", "h_msig_stdap", "k_m_stdap", "k_msig_stdap",
    "dist_edge_ns", "dist_edge_ew", "dist_edge_flg", "dup_src", "use_src",
    "a", "dist_opt", "phi_opt", "b_m_opt", "vr_m_opt", "nopt_mchs",
    "ext_key", "scan_key", "coadd_key", "coadd",
)  # fmt: skip
"""The 60 fields of a ``psc_*`` record, in order."""

PSC_NULL = "\\N"


def load_twomass(path: str | Path) -> Catalog:
    """Read 2MASS point sources from a ``psc_*`` file or an IRSA CSV export.

    Parameters
    ----------
    path : str or Path
        The file (``.gz`` accepted).

    Returns
    -------
    Catalog
        ``name="twomass"``, epoch 2000.0 (see the module notes). ``ids`` = ``pts_key`` (the
        PSC's unique source key; for a CSV the ``pts_key`` or ``cntr`` column, else the
        0-based row index). Mags ``J``, ``H``, ``Ks`` (NaN where null); colours ``J-H``,
        ``J-Ks``, ``H-Ks``; no proper motion.

    Raises
    ------
    InputError
        If the file does not exist.
    CatalogFormatError
        If it is empty, in neither form, lacks a required column, or has a malformed line
        (message names the file, line and field).
    """
    source = existing_file(path)
    lines = [line for line in head_lines(source) if line.strip()]
    if not lines:
        raise CatalogFormatError(str(source), detail="file is empty")
    first = lines[0]
    if first.count("|") == len(PSC_COLUMNS) - 1:
        return _load_psc(source)
    if "," in first:
        return _load_csv(source, [c.strip().strip('"') for c in first.split(",")])
    raise CatalogFormatError(
        str(source),
        detail=f"not a 2MASS psc file ({len(PSC_COLUMNS)} '|'-separated fields; this line has "
        f"{first.count('|') + 1}) nor a CSV with a header line",
        line=1,
    )


def _load_psc(source: Path) -> Catalog:
    import pyarrow as pa

    cols = read_delimited(
        source,
        delimiter="|",
        names=PSC_COLUMNS,
        skip_lines=0,
        types={
            "ra": pa.float64(),
            "decl": pa.float64(),
            "j_m": pa.float64(),
            "h_m": pa.float64(),
            "k_m": pa.float64(),
            "pts_key": pa.int64(),
        },
        required=("ra", "decl", "pts_key"),
        null_values=(PSC_NULL,),
        quoting=False,
    )
    return _catalog(source, cols["pts_key"], cols["ra"], cols["decl"], cols, 1, "ra", "decl")


def _load_csv(source: Path, header: list[str]) -> Catalog:
    import pyarrow as pa

    actual = {name.lower(): name for name in header}  # IRSA writes lower case; accept any
    dec_name = "dec" if "dec" in actual else "decl"
    for needed in ("ra", dec_name, "j_m", "h_m", "k_m"):
        if needed not in actual:
            raise CatalogFormatError(
                str(source),
                detail=f"required column {needed!r} missing from the header",
                line=1,
                field=needed,
            )
    id_name = next((c for c in ("pts_key", "cntr") if c in actual), None)
    wanted = ["ra", dec_name, "j_m", "h_m", "k_m"] + ([id_name] if id_name else [])
    types = {actual[c]: (pa.int64() if c == id_name else pa.float64()) for c in wanted}
    required = [actual[c] for c in ("ra", dec_name, id_name) if c]
    raw = read_delimited(
        source,
        delimiter=",",
        names=None,
        skip_lines=0,
        types=types,
        required=required,
        null_values=("", PSC_NULL, "null", "NULL", "nan", "NaN"),
        quoting=True,
    )
    cols = {c: raw[actual[c]] for c in wanted}
    ids = cols[id_name] if id_name else np.arange(len(cols["ra"]), dtype=np.int64)
    return _catalog(source, ids, cols["ra"], cols[dec_name], cols, 2, "ra", dec_name)


def _catalog(
    source: Path,
    ids: np.ndarray,
    ra: np.ndarray,
    dec: np.ndarray,
    cols: dict[str, np.ndarray],
    first_line: int,
    ra_name: str,
    dec_name: str,
) -> Catalog:
    line_no = np.arange(first_line, first_line + len(ra), dtype=np.int64)
    if len(ra) == 0:
        raise CatalogFormatError(str(source), detail="file has no data lines")
    check_range(source, ra, 0.0, 360.0, ra_name, line_no, hi_inclusive=False)
    check_range(source, dec, -90.0, 90.0, dec_name, line_no)
    j, h, k = cols["j_m"], cols["h_m"], cols["k_m"]
    catalog = Catalog.from_columns(
        name="twomass",
        source=str(source),
        epoch_yr=TWOMASS_EPOCH_YR,
        ids=ids,
        ra_deg=ra,
        dec_deg=dec,
        mags={"J": j, "H": h, "Ks": k},
        colours={"J-H": j - h, "J-Ks": j - k, "H-Ks": h - k},
    )
    return check_unique_ids(catalog, "id")
