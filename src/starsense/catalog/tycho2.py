"""Reader for the Tycho-2 Catalogue (Høg et al. 2000; VizieR I/259, ``tyc2.dat``).

The byte layout is the VizieR I/259 ReadMe ("Byte-by-byte Description of file: tyc2.dat",
C. Fabricius 2000): 206-byte records, 32 fields separated by ``|`` (the TYC identifier
``TYC1 TYC2 TYC3`` counting as one field, and HIP + CCDM as another). The distributed file is
split in 20 parts ``tyc2.dat.00`` ... ``tyc2.dat.19`` (gzipped); concatenate them or load
each and :func:`~starsense.catalog.combine.concat` the results.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from starsense.catalog._columns import check_unique_ids
from starsense.catalog._parse import (
    Field,
    FixedWidthRecords,
    check_range,
    existing_file,
    read_bytes,
)
from starsense.catalog.table import Catalog

READER_VERSION = 1
"""Bump when the output of this reader changes (invalidates cached catalogues)."""

TYCHO2_EPOCH_YR = 2000.0
RECORD_LENGTH = 206
SEPARATORS = 31

_TYC2 = {
    f.name: f
    for f in (
        Field("TYC1", 1, 4),
        Field("TYC2", 6, 10),
        Field("TYC3", 12, 12),
        Field("pflag", 14, 14),
        Field("RAmdeg", 16, 27),
        Field("DEmdeg", 29, 40),
        Field("pmRA", 42, 48),
        Field("pmDE", 50, 56),
        Field("e_RAmdeg", 58, 60),
        Field("e_DEmdeg", 62, 64),
        Field("e_pmRA", 66, 69),
        Field("e_pmDE", 71, 74),
        Field("EpRAm", 76, 82),
        Field("EpDEm", 84, 90),
        Field("Num", 92, 93),
        Field("q_RAmdeg", 95, 97),
        Field("q_DEmdeg", 99, 101),
        Field("q_pmRA", 103, 105),
        Field("q_pmDE", 107, 109),
        Field("BTmag", 111, 116),
        Field("e_BTmag", 118, 122),
        Field("VTmag", 124, 129),
        Field("e_VTmag", 131, 135),
        Field("prox", 137, 139),
        Field("TYC", 141, 141),
        Field("HIP", 143, 148),
        Field("CCDM", 149, 151),
        Field("RAdeg", 153, 164),
        Field("DEdeg", 166, 177),
        Field("EpRA-1990", 179, 182),
        Field("EpDE-1990", 184, 187),
        Field("e_RAdeg", 189, 193),
        Field("e_DEdeg", 195, 199),
        Field("posflg", 201, 201),
        Field("corr", 203, 206),
    )
}

# ESA 1997, The Hipparcos and Tycho Catalogues, Vol. 1, Sect. 1.3, Eq. 1.3.20 (quoted in
# note 7 of the I/259 ReadMe): approximate Johnson photometry from Tycho BT, VT.
V_MINUS_VT_PER_BT_MINUS_VT = -0.090
B_MINUS_V_PER_BT_MINUS_VT = 0.850


def pack_tyc(tyc1: np.ndarray, tyc2: np.ndarray, tyc3: np.ndarray) -> np.ndarray:
    """Pack Tycho identifiers ``TYC1-TYC2-TYC3`` into one int64.

    The packed id is ``TYC1 * 1_000_000 + TYC2 * 10 + TYC3`` (TYC1 <= 9537, TYC2 <= 12121 < 10**5,
    TYC3 <= 4 < 10), e.g. TYC 1-13-1 -> 1000131.
    """
    return (
        np.asarray(tyc1, dtype=np.int64) * 1_000_000
        + np.asarray(tyc2, dtype=np.int64) * 10
        + np.asarray(tyc3, dtype=np.int64)
    )


def unpack_tyc(ids: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inverse of :func:`pack_tyc`: ``(TYC1, TYC2, TYC3)``."""
    ids = np.asarray(ids, dtype=np.int64)
    return ids // 1_000_000, (ids // 10) % 100_000, ids % 10


def load_tycho2(path: str | Path) -> Catalog:
    """Read the Tycho-2 main catalogue (VizieR I/259 ``tyc2.dat``, or a part of it).

    Parameters
    ----------
    path : str or Path
        The file (``.gz`` accepted).

    Returns
    -------
    Catalog
        ``name="tycho2"``, epoch 2000.0. ``ids`` = packed TYC numbers (:func:`pack_tyc`).
        Positions are the mean positions RAmdeg/DEmdeg at J2000; for stars with
        ``pflag == 'X'`` (no mean position or proper motion, ~0.4 % of entries) the observed
        Tycho-2 position RAdeg/DEdeg is used instead, which refers to epoch ~1991.5 (the
        catalogue gives no proper motion to bring it to J2000) and whose proper motion is
        NaN. Mags ``BT``, ``VT`` and the approximate Johnson ``V = VT - 0.090 (BT - VT)``;
        colours ``BT-VT`` and ``B-V = 0.850 (BT - VT)`` (ESA 1997, Vol. 1, Sect. 1.3,
        Eq. 1.3.20); V and B-V are NaN where BT or VT is missing. ``extra``: ``HIP`` (0 if
        none) and ``has_mean_position`` (bool).

    Raises
    ------
    InputError
        If the file does not exist.
    CatalogFormatError
        If it is empty or malformed (message names the file, line and field).
    """
    source = existing_file(path)
    rec = FixedWidthRecords(
        source,
        read_bytes(source),
        tuple(_TYC2.values()),
        min_length=RECORD_LENGTH,
        max_length=RECORD_LENGTH,
    )
    f = _TYC2
    rec.expect_separators(b"|", SEPARATORS)
    for name in (
        "TYC3",
        "pflag",
        "RAmdeg",
        "DEmdeg",
        "pmRA",
        "pmDE",
        "BTmag",
        "VTmag",
        "CCDM",
        "RAdeg",
        "DEdeg",
    ):
        rec.expect_byte(f[name].end + 1, b"|", f[name])

    ids = pack_tyc(rec.ints(f["TYC1"]), rec.ints(f["TYC2"]), rec.ints(f["TYC3"]))
    no_mean = rec.chars(f["pflag"]) == ord("X")
    ra_mean = rec.floats(f["RAmdeg"])
    dec_mean = rec.floats(f["DEmdeg"])
    missing = ~no_mean & (np.isnan(ra_mean) | np.isnan(dec_mean))
    if missing.any():
        i = int(np.argmax(missing))
        field = "RAmdeg" if np.isnan(ra_mean[i]) else "DEmdeg"
        raise rec.fail(i, field, "mean position is blank but pflag is not 'X'")
    ra_obs = rec.floats(f["RAdeg"], required=True)
    dec_obs = rec.floats(f["DEdeg"], required=True)
    ra = np.where(no_mean, ra_obs, ra_mean)
    dec = np.where(no_mean, dec_obs, dec_mean)
    ra_field = np.where(no_mean, "RAdeg", "RAmdeg")
    for values, lo, hi, names, incl in (
        (ra, 0.0, 360.0, ra_field, False),
        (dec, -90.0, 90.0, np.where(no_mean, "DEdeg", "DEmdeg"), True),
    ):
        with np.errstate(invalid="ignore"):
            ok = (values >= lo) & ((values <= hi) if incl else (values < hi))
        if not ok.all():
            i = int(np.argmax(~ok))
            check_range(
                source,
                values[i : i + 1],
                lo,
                hi,
                str(names[i]),
                rec.line_no[i : i + 1],
                hi_inclusive=incl,
            )

    bt = rec.floats(f["BTmag"])
    vt = rec.floats(f["VTmag"])
    bt_vt = bt - vt
    pm_ra = rec.floats(f["pmRA"])
    pm_dec = rec.floats(f["pmDE"])
    catalog = Catalog.from_columns(
        name="tycho2",
        source=str(source),
        epoch_yr=TYCHO2_EPOCH_YR,
        ids=ids,
        ra_deg=ra,
        dec_deg=dec,
        mags={"BT": bt, "VT": vt, "V": vt + V_MINUS_VT_PER_BT_MINUS_VT * bt_vt},
        colours={"BT-VT": bt_vt, "B-V": B_MINUS_V_PER_BT_MINUS_VT * bt_vt},
        pm_ra_mas_yr=np.where(no_mean, np.nan, pm_ra),
        pm_dec_mas_yr=np.where(no_mean, np.nan, pm_dec),
        extra={"HIP": rec.ints(f["HIP"], required=False), "has_mean_position": ~no_mean},
    )
    return check_unique_ids(catalog, "TYC number")
