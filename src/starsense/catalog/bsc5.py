"""Reader for the Yale Bright Star Catalogue, 5th revised edition (Hoffleit & Warren 1991).

The catalogue is read in the binary form distributed by the Harvard-Smithsonian CfA.

Layout (little-endian): a 28-byte header of seven int32 ``STAR0, STAR1, STARN, STNUM, MPROP,
NMAG, NBENT`` (``STARN < 0`` means J2000 coordinates, ``|STARN|`` records follow; ``NBENT`` is
the record length, 32 here), then records of

=====  =======  ===============================================
XNO    float32  catalogue number (HR)
SRA0   float64  right ascension, J2000, radians
SDEC0  float64  declination, J2000, radians
IS     2 chars  spectral type (two characters)
MAG    int16    V magnitude x 100
XRPM   float32  proper motion in RA, radians per year
XDPM   float32  proper motion in Dec, radians per year
=====  =======  ===============================================

Proper motion in RA: XRPM is ``mu_alpha* = d(alpha)/dt cos(delta)`` (motion on a great
circle), not ``d(alpha)/dt``. The check is Polaris (HR 424, Dec +89.26 deg): XRPM is
38 mas/yr, as is the BSC5 text catalogue's pmRA (+0.038"/yr, V/50), and Hipparcos gives
mu_alpha* = 44.5 mas/yr (I/311); read as d(alpha)/dt it would be 0.5 mas/yr of great circle,
and across the bright stars the ratio to Hipparcos mu_alpha* shows no 1/cos(Dec) trend.
It is therefore stored as is in ``pm_ra_rad_yr``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from starsense.catalog._columns import check_unique_ids
from starsense.catalog._parse import check_range, existing_file, read_bytes
from starsense.catalog.table import Catalog
from starsense.errors import CatalogFormatError

READER_VERSION = 1
"""Bump when the output of this reader changes (invalidates cached catalogues)."""

BSC5_EPOCH_YR = 2000.0
HEADER_DTYPE = np.dtype(
    [(name, "<i4") for name in ("STAR0", "STAR1", "STARN", "STNUM", "MPROP", "NMAG", "NBENT")]
)
RECORD_DTYPE = np.dtype(
    [
        ("XNO", "<f4"),
        ("SRA0", "<f8"),
        ("SDEC0", "<f8"),
        ("IS", "S2"),
        ("MAG", "<i2"),
        ("XRPM", "<f4"),
        ("XDPM", "<f4"),
    ]
)
assert HEADER_DTYPE.itemsize == 28 and RECORD_DTYPE.itemsize == 32


def load_bsc5(path: str | Path) -> Catalog:
    """Read the binary Yale Bright Star Catalogue (BSC5).

    Parameters
    ----------
    path : str or Path
        The ``bsc5`` binary file (``.gz`` accepted).

    Returns
    -------
    Catalog
        ``name="bsc5"``, epoch 2000.0 (positions J2000, FK5 ~ ICRS to ~0.05"), ``ids`` = HR
        numbers; mags ``{"V"}``; no colour; proper motions (``XRPM`` taken as mu_alpha*, see
        the module notes); ``extra["spectral_type"]`` (two characters, e.g. ``"A0"``).
        The 14 records with RA = Dec = 0 (entries removed from the catalogue) are skipped.

    Raises
    ------
    InputError
        If the file does not exist.
    CatalogFormatError
        If the header is inconsistent (names the header field) or a record holds an
        impossible value (names the 1-based record number and field).
    """
    source = existing_file(path)
    data = read_bytes(source)
    name = str(source)

    def header_error(field: str, detail: str) -> CatalogFormatError:
        return CatalogFormatError(name, detail=f"bad BSC5 header: {detail}", field=field)

    if len(data) == 0:
        raise CatalogFormatError(name, detail="file is empty")
    if len(data) < HEADER_DTYPE.itemsize:
        raise CatalogFormatError(
            name, detail=f"file is {len(data)} bytes, shorter than the 28-byte header"
        )
    header = np.frombuffer(data, dtype=HEADER_DTYPE, count=1)[0]
    nbent = int(header["NBENT"])
    if nbent != RECORD_DTYPE.itemsize:
        raise header_error("NBENT", f"record length {nbent}, expected {RECORD_DTYPE.itemsize}")
    starn = int(header["STARN"])
    if starn >= 0:
        raise header_error(
            "STARN",
            f"STARN = {starn}; only J2000 catalogues (negative STARN) are supported",
        )
    if int(header["NMAG"]) != 1:
        raise header_error("NMAG", f"NMAG = {int(header['NMAG'])}, expected 1 magnitude")
    if int(header["MPROP"]) != 1:
        raise header_error("MPROP", f"MPROP = {int(header['MPROP'])}, expected 1 (proper motion)")
    n_records = -starn
    expected = HEADER_DTYPE.itemsize + n_records * RECORD_DTYPE.itemsize
    if len(data) != expected:
        raise header_error(
            "STARN",
            f"|STARN| = {n_records} records of {nbent} bytes need {expected} bytes, "
            f"the file has {len(data)}",
        )
    rec = np.frombuffer(data, dtype=RECORD_DTYPE, count=n_records, offset=HEADER_DTYPE.itemsize)

    record_no = np.arange(1, n_records + 1, dtype=np.int64)
    for field in ("XNO", "SRA0", "SDEC0", "XRPM", "XDPM"):
        bad = ~np.isfinite(rec[field])
        if bad.any():
            i = int(np.argmax(bad))
            raise CatalogFormatError(
                name,
                detail=f"value {float(rec[field][i])!r} is not finite",
                line=i + 1,
                field=field,
            )
    xno = rec["XNO"].astype(np.float64)
    bad = (xno != np.round(xno)) | (xno < 1) | (xno > 2**31 - 1)  # an int32 catalogue number
    if bad.any():
        i = int(np.argmax(bad))
        raise CatalogFormatError(
            name, detail=f"{float(xno[i])!r} is not a catalogue number", line=i + 1, field="XNO"
        )

    keep = ~((rec["SRA0"] == 0.0) & (rec["SDEC0"] == 0.0))
    rec, record_no = rec[keep], record_no[keep]
    check_range(
        name, rec["SRA0"], 0.0, 2.0 * np.pi, "SRA0", record_no, hi_inclusive=False, unit="rad"
    )
    check_range(name, rec["SDEC0"], -0.5 * np.pi, 0.5 * np.pi, "SDEC0", record_no, unit="rad")

    spectral = np.char.strip(np.char.decode(rec["IS"], "ascii", errors="replace"))
    catalog = Catalog(
        name="bsc5",
        source=name,
        epoch_yr=BSC5_EPOCH_YR,
        ids=rec["XNO"].astype(np.int64),
        ra_rad=rec["SRA0"].astype(np.float64),
        dec_rad=rec["SDEC0"].astype(np.float64),
        mags={"V": rec["MAG"].astype(np.float64) / 100.0},
        pm_ra_rad_yr=rec["XRPM"].astype(np.float64),
        pm_dec_rad_yr=rec["XDPM"].astype(np.float64),
        extra={"spectral_type": spectral},
    )
    return check_unique_ids(catalog, "HR number")
