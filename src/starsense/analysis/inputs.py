"""What the analyses' entry points accept: a sensor, a catalogue and a source of randomness.

Each entry point (:func:`starsense.analysis.datasheet.datasheet`,
:func:`starsense.analysis.montecarlo.montecarlo`, the availability functions, ...) takes a
sensor as an object, a preset name or a TOML path, a catalogue as an object, a specification
string or None (the bundled Hipparcos), and ``rng`` as None, an int seed or a Generator. These
functions read them the one way.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from starsense._validate import as_generator
from starsense.catalog import Catalog, load_catalog
from starsense.catalog.combine import concat
from starsense.photometry.colour import with_johnson_from_gaia
from starsense.sensor import Sensor, load_sensor
from starsense.units import ARCSEC

__all__ = [
    "DEFAULT_CATALOG_SPEC",
    "FRAME_COST",
    "MAX_FRAMES",
    "SAME_STAR_RAD",
    "as_catalog",
    "as_sensor",
    "at_epoch",
    "completed_sky",
    "root_seed",
    "same_star_index",
]

#: most frames one Monte Carlo renders and solves (montecarlo, the datasheet's checks, the
#: availability fidelity check): each takes ~0.01-0.1 s, so the cap bounds a run to hours, and
#: its per-frame records (~100 bytes) to ~0.1 GB; more trials are more seeds, run apart
MAX_FRAMES = 1_000_000
FRAME_COST = "each renders and solves a frame, ~0.01-0.1 s"

#: the catalogue an analysis uses when given none
DEFAULT_CATALOG_SPEC = "hipparcos"

#: a star of one catalogue within this of a star of another, at one epoch, is that star: the
#: catalogues' errors over decades stay under 0.1" (Hipparcos' ~1 mas/yr), and a frame does not
#: separate two stars 1" apart
SAME_STAR_RAD = 1.0 * ARCSEC


def as_sensor(sensor: Sensor | str | Path) -> Sensor:
    """Return ``sensor`` as a :class:`~starsense.sensor.Sensor`.

    Parameters
    ----------
    sensor : Sensor, str or Path
        The sensor, a preset name (``"st16"``) or the path of a sensor TOML file.

    Returns
    -------
    Sensor
    """
    return sensor if isinstance(sensor, Sensor) else load_sensor(sensor)


def as_catalog(catalog: Catalog | str | None) -> Catalog:
    """Return ``catalog`` as a :class:`~starsense.catalog.Catalog`.

    Parameters
    ----------
    catalog : Catalog, str or None
        The catalogue, a specification for :func:`starsense.catalog.load_catalog`
        (``"hipparcos"``, ``"bsc5:PATH"``, ...) or None for the bundled Hipparcos.

    Returns
    -------
    Catalog
    """
    if isinstance(catalog, Catalog):
        return catalog
    return load_catalog(DEFAULT_CATALOG_SPEC if catalog is None else catalog)


def at_epoch(catalog: Catalog, epoch_yr: float) -> Catalog:
    """Return ``catalog`` with its positions at ``epoch_yr`` (itself without proper motions).

    A simulated frame is rendered from one catalogue and identified against the solver's
    (Gaia, epoch 2016.0, for a narrow field; Hipparcos, epoch 1991.25, else): rendering the sky
    at the epoch of the solver's catalogue keeps 25 years of proper motion (up to arcseconds
    per star) out of the measured attitude error.

    Parameters
    ----------
    catalog : Catalog
        The stars to render.
    epoch_yr : float
        The Julian epoch of the solver's catalogue, years.

    Returns
    -------
    Catalog
        ``catalog`` propagated to ``epoch_yr`` (:meth:`Catalog.propagate`), or ``catalog``
        itself when it is already there or carries no proper motions.
    """
    if catalog.epoch_yr == epoch_yr or catalog.pm_ra_rad_yr is None:
        return catalog
    return catalog.propagate(epoch_yr)


def same_star_index(vectors: np.ndarray, others: np.ndarray) -> np.ndarray:
    """Return, for each of ``vectors``, the index of the same star among ``others`` (or -1).

    The nearest of ``others`` within :data:`SAME_STAR_RAD` (unit vectors at one epoch): that
    star in another catalogue.
    """
    chord = 2.0 * np.sin(0.5 * SAME_STAR_RAD)
    dist, idx = cKDTree(others).query(vectors, distance_upper_bound=chord)
    return np.where(np.isfinite(dist), idx, -1)


def _has_same_star(vectors: np.ndarray, others: np.ndarray) -> np.ndarray:
    """Return whether each of ``vectors`` has one of ``others`` within :data:`SAME_STAR_RAD`."""
    return same_star_index(vectors, others) >= 0


def _with_database_motion(catalog: Catalog, database: Catalog) -> Catalog:
    """Return ``catalog`` with its database counterparts' proper motions where it has none.

    A catalogue without proper motions (the bundled Gaia DR3 file holds positions at J2016.0
    only) cannot be moved to the database's epoch, 25 years away for Hipparcos: its stars
    would sit arcseconds (a median of 0.7" for stars of V < 8) from their database positions
    and be drawn twice in the frames' sky. Each of its stars with a database star within
    :data:`SAME_STAR_RAD` at the catalogue's own epoch takes that star's proper motion (moved
    there with it); the others keep none (they stay where the catalogue puts them).
    """
    pm_a, pm_d = catalog.pm_ra_rad_yr, catalog.pm_dec_rad_yr
    n = len(catalog.ids)
    if pm_a is not None and pm_d is not None and np.isfinite(pm_a).all():
        return catalog
    if database.pm_ra_rad_yr is None or n == 0:
        return catalog
    db = database.propagate(catalog.epoch_yr)
    idx = same_star_index(catalog.vectors, db.vectors)
    pm_a = np.full(n, np.nan) if pm_a is None else np.array(pm_a, float)
    pm_d = np.full(n, np.nan) if pm_d is None else np.array(pm_d, float)
    take = (idx >= 0) & ~(np.isfinite(pm_a) & np.isfinite(pm_d))
    pm_a[take] = db.pm_ra_rad_yr[idx[take]]
    pm_d[take] = db.pm_dec_rad_yr[idx[take]]
    return replace(catalog, pm_ra_rad_yr=pm_a, pm_dec_rad_yr=pm_d)


def _measured_photometry(catalog: Catalog, database: Catalog, sky: np.ndarray) -> Catalog:
    """Return ``catalog`` with its database counterpart's V and B - V where its colour is a guess.

    A Gaia star without BP - RP has a V from G at an assumed colour, off by ~0.3 mag for a red
    or a blue star (:func:`starsense.photometry.colour.with_johnson_from_gaia`); the database
    (Hipparcos) measured that star's V and B - V. One star takes one photometry in the frames'
    sky, the measured one: otherwise the frames draw it at one brightness while the solver
    draws it, as a neighbour, at another. ``sky``: the catalogue's unit vectors at the
    database's epoch.
    """
    if "G" not in catalog.mags or "V" not in database.mags or "B-V" not in database.colours:
        return catalog
    guessed = ~np.isfinite(catalog.colours.get("BP-RP", np.full(len(catalog.ids), np.nan)))
    if not guessed.any():
        return catalog
    idx = same_star_index(sky[guessed], database.vectors)
    rows, src = np.flatnonzero(guessed)[idx >= 0], idx[idx >= 0]
    v_db = np.asarray(database.mags["V"], float)[src]
    bv_db = np.asarray(database.colours["B-V"], float)[src]
    ok = np.isfinite(v_db) & np.isfinite(bv_db)
    v = np.array(catalog.mags["V"], float)
    b_v = np.array(catalog.colours["B-V"], float)
    v[rows[ok]], b_v[rows[ok]] = v_db[ok], bv_db[ok]
    return replace(catalog, mags={**catalog.mags, "V": v}, colours={**catalog.colours, "B-V": b_v})


def completed_sky(catalog: Catalog, database: Catalog) -> Catalog:
    """Return ``catalog`` and the stars of the solver's ``database`` it lacks: a frame's sky.

    A simulated frame rendered from one catalogue and solved against another (Hipparcos and the
    narrow field's Gaia DR3) would lack the database's stars the rendering catalogue does not
    hold (Hipparcos is complete to V = 7.3 only), while the solver models its matched stars'
    neighbours from the database, as it must on the real sky. The rendered sky is therefore
    ``catalog`` (its positions: the catalogue term of the datasheet is their difference), plus
    every database star with no ``catalog`` star within :data:`SAME_STAR_RAD` (V and B - V from
    G and BP - RP when the database has only those,
    :func:`starsense.photometry.colour.with_johnson_from_gaia`). A ``catalog`` that already
    holds them all is returned as is.

    Parameters
    ----------
    catalog : Catalog
        The catalogue the frames are rendered from.
    database : Catalog
        The catalogue the solver identifies against.

    Returns
    -------
    Catalog
        At the epoch of ``catalog``; named ``"<catalog>+<database>"`` when stars were added.
    """
    same = database.name == catalog.name and len(database) == len(catalog)
    if database is catalog or same or len(database) == 0:
        return catalog
    missing = np.ones(len(database), dtype=bool)
    catalog = _with_database_motion(catalog, database)
    if len(catalog):  # matched where the frames are rendered: at the database's epoch
        sky = at_epoch(catalog, database.epoch_yr).vectors
        missing = ~_has_same_star(database.vectors, sky)
        catalog = _measured_photometry(catalog, database, sky)
    extra, _ = with_johnson_from_gaia(database.subset(missing))
    if not missing.any() or "V" not in extra.mags:
        return catalog
    extra = at_epoch(extra, catalog.epoch_yr)
    if extra.epoch_yr != catalog.epoch_yr:  # no proper motions: the same positions at any epoch
        extra = replace(extra, epoch_yr=catalog.epoch_yr)
    return concat([catalog, extra], name=f"{catalog.name}+{database.name}")


def root_seed(rng: int | np.random.Generator | None) -> int:
    """Return the root seed of a run from ``rng``, so that its JSON records it.

    Parameters
    ----------
    rng : None, int or numpy.random.Generator
        An int is the seed itself; None draws a fresh seed from the OS entropy; a Generator
        gives one seed drawn from it (the run is then as reproducible as the Generator).

    Returns
    -------
    int
        A non-negative seed (< 2**63).
    """
    gen, seed = as_generator(rng)
    return int(gen.integers(2**63)) if seed is None else seed
