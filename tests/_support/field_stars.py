"""A catalogue of given stars: the unit vectors and V magnitudes a test places in a frame."""

from __future__ import annotations

import numpy as np

from starsense.catalog.table import Catalog


def catalog_of(vectors, mags) -> Catalog:
    """Return a catalogue of the stars at ``vectors`` (ICRS unit vectors) with V ``mags``.

    Their colour is a Sun-like B-V of 0.6; ids are their rows.
    """
    v = np.asarray(vectors, dtype=float)
    n = len(v)
    return Catalog.from_columns(
        name="field", source="test", epoch_yr=2016.0, ids=np.arange(n),
        ra_deg=np.degrees(np.arctan2(v[:, 1], v[:, 0])) % 360.0,
        dec_deg=np.degrees(np.arcsin(v[:, 2])), mags={"V": np.asarray(mags, dtype=float)},
        colours={"B-V": np.full(n, 0.6)},
    )  # fmt: skip
