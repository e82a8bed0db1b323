"""Catalogues combined: :func:`concat` stacks catalogues of one epoch into one."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from starsense.catalog.table import KNOWN_BANDS, KNOWN_COLOURS, Catalog
from starsense.errors import InputError

__all__ = ["concat"]


def concat(catalogs: Sequence[Catalog], *, name: str | None = None) -> Catalog:
    """Stack catalogues at the same epoch into one.

    Magnitude and colour columns are the union of the inputs (NaN where a catalogue lacks
    one); proper motions, parallax and radial motion are kept if any input has them (NaN
    elsewhere); ``extra`` keeps only the keys every input has.

    Parameters
    ----------
    catalogs : sequence of Catalog
        At least one; all with the same ``epoch_yr`` (propagate first otherwise).
    name : str, optional
        Name of the result (default: the input names joined with ``+``).
    """
    cats = list(catalogs)
    if not cats or not all(isinstance(c, Catalog) for c in cats):
        raise InputError("concat needs a non-empty sequence of Catalog objects")
    epoch = cats[0].epoch_yr
    for c in cats[1:]:
        if c.epoch_yr != epoch:
            raise InputError(
                f"cannot concatenate catalogues at different epochs ({cats[0].name!r} at "
                f"{epoch}, {c.name!r} at {c.epoch_yr}); propagate them to one epoch first"
            )

    def stack(get: Any) -> np.ndarray:
        return np.concatenate(
            [get(c) if get(c) is not None else np.full(len(c), np.nan) for c in cats]
        )

    def optional(attr: str) -> np.ndarray | None:
        if all(getattr(c, attr) is None for c in cats):
            return None
        return stack(lambda c: getattr(c, attr))

    bands = [b for b in KNOWN_BANDS if any(b in c.mags for c in cats)]
    colours = [k for k in KNOWN_COLOURS if any(k in c.colours for c in cats)]
    extra_keys = [k for k in cats[0].extra if all(k in c.extra for c in cats[1:])]
    return Catalog(
        name=name or "+".join(c.name for c in cats),
        source="; ".join(c.source for c in cats),
        epoch_yr=epoch,
        ids=np.concatenate([c.ids for c in cats]),
        ra_rad=np.concatenate([c.ra_rad for c in cats]),
        dec_rad=np.concatenate([c.dec_rad for c in cats]),
        mags={b: stack(lambda c, b=b: c.mags.get(b)) for b in bands},
        colours={k: stack(lambda c, k=k: c.colours.get(k)) for k in colours},
        pm_ra_rad_yr=optional("pm_ra_rad_yr"),
        pm_dec_rad_yr=optional("pm_dec_rad_yr"),
        parallax_rad=optional("parallax_rad"),
        extra={k: np.concatenate([c.extra[k] for c in cats]) for k in extra_keys},
        radial_motion_per_yr=optional("radial_motion_per_yr"),
    )
