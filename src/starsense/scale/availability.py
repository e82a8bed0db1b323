"""Star counts per boresight and static availability over HATS catalogues (Dzamba & Enright 2014).

Every partition runs the in-memory :class:`~starsense.analysis.availability.FieldStars` on its
own stars against all boresights; counts add, and the K brightest magnitudes in the field merge
exactly (:meth:`~starsense.analysis.availability.BrightestInField.merge`), which is all the
availability for N_min <= K needs. The result is the in-memory
:class:`~starsense.analysis.availability.StaticAvailability`, assembled by the same
:func:`~starsense.analysis.availability.static_result`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from starsense._validate import check_int
from starsense.analysis.availability import (
    DEFAULT_N_ORIENTATIONS,
    N_MIN_LOST_IN_SPACE,
    StaticAvailability,
    check_fov,
    check_mag,
    describe_fov,
    sky_attitudes,
    static_result,
)
from starsense.errors import InputError
from starsense.geometry.fov import RectangularFov
from starsense.scale import kernels
from starsense.scale.hats import ColumnPlan, HatsCatalog
from starsense.scale.run import Progress, client_or_local, run_partitions

#: bands tried, in order, when none is asked for
DEFAULT_BANDS = ("V", "Hp", "VT", "G", "J", "H", "Ks")


def band_plan(catalog: HatsCatalog, band: str | None) -> tuple[ColumnPlan, str]:
    """Return the columns for positions and one magnitude band (default: the first it has).

    The bands are tried in the order of :data:`DEFAULT_BANDS`.
    """
    plan = catalog.plan()
    have = dict(plan.mags)
    if band is None:
        band = next((b for b in DEFAULT_BANDS if b in have), None)
        if band is None:
            raise catalog.missing("a magnitude (V, Hp, VT, G, J, H or Ks)")
    elif band not in have:
        raise catalog.missing(f"the {band} magnitude (band {band!r})")
    return plan.restrict([band], []), band


def _field(
    catalog: HatsCatalog,
    fov,
    attitudes: Rotation,
    max_mag: float,
    band: str | None,
    k: int,
    client: Any | None,
    progress: Progress | None,
    label: str,
):
    check_fov(fov)
    m = check_mag(max_mag, "max_mag", allow_inf=True)
    plan, band = band_plan(catalog, band)
    with client_or_local(client) as c:
        counts, top, n, faintest = run_partitions(
            c,
            catalog,
            plan=plan,
            kernel=kernels.field_part,
            kernel_args={"band": band, "max_mag": m, "fov": fov, "attitudes": attitudes, "k": k},
            combine=kernels.combine_field,
            label=label,
            progress=progress,
        )
    if n == 0:
        raise InputError(
            f"magnitude limit max_mag {m:g} leaves no stars of HATS catalogue "
            f"{catalog.location} ({band}); raise max_mag"
        )
    return counts, top, n, faintest, band


def star_counts(
    catalog: HatsCatalog,
    fov,
    attitudes: Rotation,
    *,
    max_mag: float = math.inf,
    band: str | None = None,
    client: Any | None = None,
    progress: Progress | None = None,
) -> NDArray[np.intp]:
    """Return the stars ``<= max_mag`` in the field at each attitude, shape (M,).

    Equal to ``FieldStars.build(fov, attitudes, *catalog_stars(cat, max_mag, band)).counts()``
    on the whole catalogue in memory.
    """
    counts, *_ = _field(
        catalog, fov, attitudes, max_mag, band, 0, client, progress, "stars in the field"
    )
    return counts


def static_availability(
    catalog: HatsCatalog,
    fov,
    *,
    max_mag: float,
    n_min: int = N_MIN_LOST_IN_SPACE,
    band: str | None = None,
    n_orientations: int = DEFAULT_N_ORIENTATIONS,
    roll_rad: float | None = None,
    rng: int | np.random.Generator | None = 0,
    client: Any | None = None,
    progress: Progress | None = None,
) -> StaticAvailability:
    """Return the spatial static availability (sec. 1.2) of a HATS catalogue.

    As ``AvailabilityAnalysis.from_catalog(cat, fov, max_mag, band, ...).static(n_min)``;
    `roll_rad` (None: random from `rng`) matters only for a rectangular field.
    """
    n_min = check_int(n_min, "n_min", 1)
    roll = roll_rad if isinstance(fov, RectangularFov) else 0.0
    boresights, attitudes = sky_attitudes(n_orientations, roll, rng=rng)
    counts, top, n, faintest, band = _field(
        catalog,
        fov,
        attitudes,
        max_mag,
        band,
        max(4, n_min),
        client,
        progress,
        "availability: stars in the field",
    )
    m_t = float(max_mag) if math.isfinite(max_mag) else faintest
    return static_result(
        top,
        counts,
        boresights=boresights,
        n_min=n_min,
        m_t=m_t,
        n_stars=n,
        fov=describe_fov(fov),
        catalog=catalog.name,
        band=band,
    )
