"""What the analyses' entry points accept: a sensor, a catalogue and a source of randomness.

Each entry point (:func:`starsense.analysis.datasheet.datasheet`,
:func:`starsense.analysis.montecarlo.montecarlo`, the availability functions, ...) takes a
sensor as an object, a preset name or a TOML path, a catalogue as an object, a specification
string or None (the bundled Hipparcos), and ``rng`` as None, an int seed or a Generator. These
functions read them the one way.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from starsense._validate import as_generator
from starsense.catalog import Catalog, load_catalog
from starsense.sensor import Sensor, load_sensor

__all__ = ["DEFAULT_CATALOG_SPEC", "as_catalog", "as_sensor", "root_seed"]

#: the catalogue an analysis uses when given none
DEFAULT_CATALOG_SPEC = "hipparcos"


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
