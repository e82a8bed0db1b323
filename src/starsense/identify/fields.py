"""Which databases to search, in which order, when the field of view is not known.

The 4-star edge ratios are scale-invariant, so one multi-scale database
(:func:`~starsense.identify.database.build_database` with ``min_fov_rad < max_fov_rad``) finds
the field within its range. One database for 3-60 deg would be large and slow to search, and
the right catalogue depends on the field: a 60 deg frame shows the brightest few hundred stars
of the sky, a 3 deg frame (3 x 2.25 deg, 7 square degrees) holds on average 20 Hipparcos stars
but only ~7 near the galactic poles, and many of the stars a camera sees there are fainter
than Hipparcos is complete (V ~ 8). So the search goes through field ranges, the common one
first, and uses the deeper Gaia catalogue (G <= 10, 482,176 stars, the ``gaia`` extra: 16 MB)
for the narrow range when it is installed.

:func:`unknown_field_plan` returns the ranges; the solver tries them in turn until one solves.
"""

from __future__ import annotations

from dataclasses import dataclass

from starsense.catalog import bundled_gaia_path, load_catalog
from starsense.catalog.table import Catalog
from starsense.errors import InputError
from starsense.identify.database import build_database
from starsense.identify.hashing import HashIdentifier
from starsense.identify.triangle import TriangleIdentifier
from starsense.units import DEG

__all__ = [
    "FieldRange",
    "deep_catalog_available",
    "identifier_for",
    "known_field_catalog",
    "plan_band",
    "unknown_field_plan",
]


@dataclass(frozen=True)
class FieldRange:
    """One database of the unknown-field search.

    Attributes
    ----------
    min_fov_rad, max_fov_rad : float
        Field range (full width of the widest image axis), rad.
    nominal_fov_rad : float
        The field the centroids are unprojected with before the scale is fitted, rad. The edge
        ratios are ratios of angles, which a wrong focal length distorts more the wider the
        field: unprojected at 15 deg, a quarter of 60 deg frames found no pattern within the
        ratio tolerance; at the wide range's own nominal field all solve.
    catalog : Catalog or str
        The catalogue, or a spec loaded when the range is searched
        (:func:`starsense.catalog.load_catalog`; the deep Gaia of the narrow range).
    band : str
        Magnitude band of that catalogue used for brightness order.
    field_oversampling : float
        Lattice density of the pattern fields (:class:`~starsense.identify.DatabaseParams`).
    patterns_per_field : int
        Patterns kept per lattice field, brightest stars first.
    """

    min_fov_rad: float
    max_fov_rad: float
    nominal_fov_rad: float
    catalog: Catalog | str
    band: str = "V"
    field_oversampling: float = 4.0
    patterns_per_field: int = 50


#: the common range (issue 5), then wide fields, then narrow ones, rad
#: (min, max, nominal) field of each range
COMMON_RANGE_RAD = (5.0 * DEG, 30.0 * DEG, 15.0 * DEG)
WIDE_RANGE_RAD = (25.0 * DEG, 70.0 * DEG, 50.0 * DEG)
NARROW_RANGE_RAD = (2.8 * DEG, 6.0 * DEG, 4.0 * DEG)
#: a known field narrower than this is identified on the bundled Gaia (with the default spec)
DEEP_KNOWN_FIELD_RAD = 4.0 * DEG
#: the narrow database's lattice: at the common range's density (16 fields per field area, 50
#: patterns each) Gaia at 2.5-6 deg made 8.3 M patterns (400 MB, 4 min to build); 4 fields per
#: field area and 35 patterns (the 4-subsets of the 7 brightest stars) make ~20x fewer
_NARROW_LATTICE = {"field_oversampling": 2.0, "patterns_per_field": 35}


def deep_catalog_available() -> bool:
    """Whether the bundled Gaia catalogue (``pip install 'starsense[gaia]'``) is installed."""
    try:
        return bundled_gaia_path().is_file()
    except InputError:
        return False


def plan_band(catalog: Catalog | str) -> str:
    """Return the band that orders a catalogue's stars by brightness for the databases.

    V, or G for a catalogue without V (Gaia); for a spec, G for ``gaia...`` and V otherwise.

    Parameters
    ----------
    catalog : Catalog or str
        The catalogue or its spec.

    Returns
    -------
    str
    """
    if isinstance(catalog, str):
        return "G" if catalog.strip().lower().startswith("gaia") else "V"
    return "G" if "V" not in catalog.bands and "G" in catalog.bands else "V"


def unknown_field_plan(
    catalog: Catalog | str = "hipparcos", *, deep_narrow: bool | None = None
) -> list[FieldRange]:
    """Return the databases to try, in order, for a frame whose field is not known.

    Parameters
    ----------
    catalog : Catalog or str
        The catalogue the user chose: an object, or a spec (kept as a spec in the ranges,
        loaded when a range is searched).
    deep_narrow : bool, optional
        Search the narrow range in the bundled Gaia to G = 10 when it is installed. Default:
        only for the spec ``"hipparcos"`` (the default catalogue); any other choice, and any
        Catalog object, is used for every range.

    Returns
    -------
    list of FieldRange
        5-30 deg, 25-70 deg, 2.8-6 deg.
    """
    if deep_narrow is None:
        deep_narrow = isinstance(catalog, str) and catalog.strip().lower() == "hipparcos"
    band = plan_band(catalog)
    plan = [
        FieldRange(*COMMON_RANGE_RAD, catalog, band),
        FieldRange(*WIDE_RANGE_RAD, catalog, band),
    ]
    if deep_narrow and deep_catalog_available():
        plan.append(FieldRange(*NARROW_RANGE_RAD, "gaia", "G", **_NARROW_LATTICE))
    else:
        plan.append(FieldRange(*NARROW_RANGE_RAD, catalog, band, **_NARROW_LATTICE))
    return plan


def known_field_catalog(catalog: Catalog | str, fov_rad: float | None) -> Catalog | str:
    """Return the catalogue to identify a known field with.

    The default spec ``"hipparcos"`` becomes the bundled Gaia (G <= 10) when the field is
    narrower than :data:`DEEP_KNOWN_FIELD_RAD` (4 deg) and Gaia is installed, as in the narrow
    range of the unknown-field search: Hipparcos alone serves fields of about 4-70 deg, and a
    1-3 deg field holds too few of its stars. Any other choice is kept.

    Parameters
    ----------
    catalog : Catalog or str
        The catalogue the user chose (an object or a spec).
    fov_rad : float or None
        The known field (full width of the widest axis), rad; None when it is not known.

    Returns
    -------
    Catalog or str
        `catalog`, or ``"gaia"``.
    """
    default = isinstance(catalog, str) and catalog.strip().lower() == "hipparcos"
    if default and fov_rad is not None and fov_rad < DEEP_KNOWN_FIELD_RAD:
        return "gaia" if deep_catalog_available() else catalog
    return catalog


def identifier_for(
    catalog: Catalog | str,
    *,
    algorithm: str = "hashing",
    fov_rad: float | None = None,
    field_range: FieldRange | None = None,
):
    """Build (or load from the disk cache) the identifier of a known field or of a field range.

    Parameters
    ----------
    catalog : Catalog or str
        The catalogue (or its spec) for a known field (a range carries its own).
    algorithm : {"hashing", "triangle"}
        Identification algorithm (triangle needs a known field).
    fov_rad : float or None
        The known field (full width), rad; None to use `field_range`.
    field_range : FieldRange or None
        The range of the unknown-field search, when `fov_rad` is None.

    Returns
    -------
    HashIdentifier or TriangleIdentifier
    """
    if fov_rad is not None:
        loaded = _loaded(catalog)
        db = build_database(loaded, fov_rad, band=plan_band(loaded))
    elif field_range is not None:
        fr = field_range
        db = build_database(
            _loaded(fr.catalog),
            fr.max_fov_rad,
            fr.min_fov_rad,
            band=fr.band,
            field_oversampling=fr.field_oversampling,
            patterns_per_field=fr.patterns_per_field,
        )
    else:
        raise InputError("give fov_rad or field_range")
    return (HashIdentifier if algorithm == "hashing" else TriangleIdentifier)(db)


def _loaded(catalog: Catalog | str) -> Catalog:
    return catalog if isinstance(catalog, Catalog) else load_catalog(catalog)
