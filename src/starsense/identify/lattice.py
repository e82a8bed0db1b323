"""How dense the pattern lattice of a database is, and what a build will cost.

The 4-combinations of the brightest stars of every lattice field
(:func:`~starsense.identify.patterns.lattice_patterns`) grow as the inverse square of the
field: the dense lattice that serves a 15 deg field (1.6 M patterns) would make ~460 M for a
1.1 deg field on Gaia. :func:`pattern_lattice` keeps the dense lattice where it fits a budget
and makes narrow fields sparse, as the narrow range of the unknown-field search is
(:mod:`starsense.identify.fields`); :func:`estimated_build_s` is what the build announces.
"""

from __future__ import annotations

import math
from typing import Any, Literal

from starsense.identify.patterns import field_sizes
from starsense.units import RAD_TO_DEG

__all__ = [
    "DENSE_LATTICE",
    "MAX_PAIRS",
    "NOTICE_BUILD_S",
    "PATTERN_BUDGET",
    "SPARSE_LATTICE",
    "estimated_build_s",
    "expected_pairs",
    "fov_text",
    "lattice_pattern_count",
    "pattern_lattice",
]

#: a lattice whose database would hold more patterns than this is made sparse (2 fields per
#: field width, 35 patterns each, as the narrow range of the unknown-field search): at the dense
#: default a 1.1 deg field on Gaia wanted ~460 M patterns (13.8 GiB); the sparse one ~6 M
PATTERN_BUDGET = 12_000_000
#: the dense default lattice: (field_oversampling, patterns_per_field: every combination)
DENSE_LATTICE: tuple[float, int | None] = (4.0, None)
#: the sparse lattice of narrow fields: (field_oversampling, patterns_per_field)
SPARSE_LATTICE: tuple[float, int | None] = (2.0, 35)
#: star pairs (of the triangle algorithm) kept at most; a denser database has none
MAX_PAIRS = 4_000_000
#: builds expected to take longer than this many seconds are announced first
NOTICE_BUILD_S = 15.0
#: build time per lattice pattern and per catalogue star (the thinning), s, fitted to two
#: builds on a loaded 2-core machine: Hipparcos at 11.4 deg (4.6 M lattice patterns, ~10 s) and
#: Gaia to G = 10 at 1.14 deg (5.6 M lattice patterns, 482 k stars, ~25 s)
_BUILD_S_PER_PATTERN = 1.5e-6
_BUILD_S_PER_STAR = 3.0e-5


def lattice_pattern_count(
    max_fov_rad: float,
    min_fov_rad: float,
    pattern_stars_per_fov: int,
    *,
    field_oversampling: float,
    patterns_per_field: int | None,
) -> int:
    """Return the number of lattice patterns a build makes, before duplicates are removed.

    Parameters
    ----------
    max_fov_rad, min_fov_rad : float
        Field range, rad.
    pattern_stars_per_fov : int
        Stars per lattice field.
    field_oversampling : float
        Linear oversampling of the field lattice.
    patterns_per_field : int or None
        Patterns kept per field (None: every 4-combination).

    Returns
    -------
    int
        Fields (:func:`~starsense.identify.patterns.lattice_patterns`) times patterns each.
    """
    per_field = math.comb(pattern_stars_per_fov, 4)
    if patterns_per_field is not None:
        per_field = min(per_field, patterns_per_field)
    fields = sum(
        max(12, math.ceil(field_oversampling**2 * 16.0 / size**2))
        for size in field_sizes(min_fov_rad, max_fov_rad)
    )
    return fields * per_field


def pattern_lattice(
    max_fov_rad: float,
    min_fov_rad: float,
    pattern_stars_per_fov: int,
    *,
    field_oversampling: float | None = None,
    patterns_per_field: int | Literal["all"] | None = None,
) -> tuple[float, int | None]:
    """Return the pattern lattice of a build: (field_oversampling, patterns_per_field).

    What the caller gave is kept; what it left as None comes from the dense default (4, every
    combination), or from the sparse :data:`SPARSE_LATTICE` when the dense one would exceed
    :data:`PATTERN_BUDGET` patterns: this bounds a narrow field's database in memory and on
    disk.

    Parameters
    ----------
    max_fov_rad, min_fov_rad : float
        Field range, rad.
    pattern_stars_per_fov : int
        Stars per lattice field.
    field_oversampling : float, optional
        Linear oversampling of the field lattice.
    patterns_per_field : int or "all", optional
        Patterns per field; "all" for every combination.

    Returns
    -------
    (float, int or None)
        The lattice (None: every combination).
    """

    def resolve(default: tuple[float, int | None]) -> tuple[float, int | None]:
        fo = default[0] if field_oversampling is None else float(field_oversampling)
        if patterns_per_field is None:
            return fo, default[1]
        return fo, None if patterns_per_field == "all" else int(patterns_per_field)

    chosen = resolve(DENSE_LATTICE)
    if field_oversampling is None or patterns_per_field is None:
        count = lattice_pattern_count(
            max_fov_rad,
            min_fov_rad,
            pattern_stars_per_fov,
            field_oversampling=chosen[0],
            patterns_per_field=chosen[1],
        )
        if count > PATTERN_BUDGET:
            chosen = resolve(SPARSE_LATTICE)
    return chosen


def estimated_build_s(params: Any, n_stars: int) -> float:
    """Return the expected build time of a database, s (from its lattice pattern count).

    Parameters
    ----------
    params : DatabaseParams
        The build parameters (:class:`~starsense.identify.database.DatabaseParams`).
    n_stars : int
        Stars in the catalogue.

    Returns
    -------
    float
        Seconds, on a loaded 2-core machine (a rough guide: within a factor of 2).
    """
    return _BUILD_S_PER_STAR * n_stars + _BUILD_S_PER_PATTERN * lattice_pattern_count(
        params.max_fov_rad,
        params.min_fov_rad,
        params.pattern_stars_per_fov,
        field_oversampling=params.field_oversampling,
        patterns_per_field=params.patterns_per_field,
    )


def fov_text(params: Any) -> str:
    """Return a database's field (range) in degrees, as a message shows it.

    Parameters
    ----------
    params : DatabaseParams
        The build parameters.

    Returns
    -------
    str
        E.g. ``"2.3"`` or ``"2.8-6"``.
    """
    lo, hi = params.min_fov_rad * RAD_TO_DEG, params.max_fov_rad * RAD_TO_DEG
    return f"{hi:.3g}" if lo == hi else f"{lo:.3g}-{hi:.3g}"


def expected_pairs(n_stars: int, max_fov_rad: float) -> float:
    """Return the expected number of star pairs closer than 1.3 fields among `n_stars` stars.

    Stars spread evenly over the sphere: each has ``n_stars`` times the cap fraction
    ``(1 - cos(1.3 fov)) / 2`` neighbours within the pair limit of
    :func:`~starsense.identify.patterns.star_pairs`.

    Parameters
    ----------
    n_stars : int
        Pattern stars.
    max_fov_rad : float
        The field, rad.

    Returns
    -------
    float
        Expected pairs.
    """
    cap = (1.0 - math.cos(min(math.pi / 2, 1.3 * max_fov_rad))) / 2.0
    return 0.5 * n_stars * n_stars * cap
