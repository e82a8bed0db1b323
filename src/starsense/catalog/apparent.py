"""Apparent places: catalogue stars as an observer sees them at one time.

Three steps, each the one copy of its model:

1. proper motion (and the radial motion it implies) from the catalogue epoch to the time's
   Julian epoch (:meth:`Catalog.propagate`, uniform straight-line motion, ESA 1997 Vol. 1,
   Sect. 1.5.5);
2. annual parallax: the star sits at ``u / parallax`` (AU) from the barycentre, so from the
   observer at ``X`` it is seen along ``u - parallax X / AU`` (ESA 1997 Vol. 1, eq. 1.2.16;
   stars without a parallax are at infinity);
3. stellar aberration for the observer's barycentric velocity
   (:func:`starsense.geometry.apparent.aberrate`, relativistic).

The result is the direction of each star in the ICRS axes as the observer sees it: an attitude
fitted to these directions is the observer's true ICRS attitude.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from starsense.catalog import load_catalog
from starsense.catalog.table import Catalog
from starsense.errors import InputError
from starsense.geometry.apparent import AU_M, aberrate, observer_state, parse_time

__all__ = ["ApparentPlaces", "apparent_places", "apparent_places_of"]


@dataclass(frozen=True, eq=False)
class ApparentPlaces:
    """Apparent directions of some catalogue stars, and what was applied.

    Attributes
    ----------
    vectors : ndarray, shape (N, 3)
        Apparent unit vectors (ICRS axes).
    time_utc : str
        The observation time, ISO 8601 UTC.
    epoch_yr : float
        Its Julian epoch, years.
    velocity_m_s : ndarray, shape (3,)
        The observer's barycentric velocity used for the aberration, m/s.
    proper_motion : bool
        Whether proper motions were applied (False for a catalogue without them).
    parallax : bool
        Whether parallaxes were applied.
    """

    vectors: np.ndarray
    time_utc: str
    epoch_yr: float
    velocity_m_s: np.ndarray
    proper_motion: bool
    parallax: bool

    def to_dict(self) -> dict:
        """JSON-ready summary (speed in km/s)."""
        return {
            "applied": True,
            "time_utc": self.time_utc,
            "epoch_yr": self.epoch_yr,
            "observer_speed_km_s": float(np.linalg.norm(self.velocity_m_s) / 1e3),
            "proper_motion": self.proper_motion,
            "parallax": self.parallax,
            "aberration": True,
        }


def apparent_places(catalog, index, time, *, observer_velocity_m_s=None) -> ApparentPlaces:
    """Return the apparent directions of catalogue stars ``index`` at ``time`` (module steps).

    Parameters
    ----------
    catalog : Catalog
        The catalogue (positions at its epoch).
    index : array_like of int, shape (N,)
        Rows of the stars.
    time : str or astropy.time.Time
        Observation time (ISO 8601 UTC or Time).
    observer_velocity_m_s : array_like, shape (3,), optional
        The observer's velocity relative to the geocentre (orbit, ground site rotation), ICRS
        axes, m/s; added to the Earth's barycentric velocity.

    Returns
    -------
    ApparentPlaces
    """
    t = parse_time(time)
    epoch = float(t.tdb.jyear)
    stars = catalog.subset(np.asarray(index, dtype=np.intp))
    moved = stars.pm_ra_rad_yr is not None and stars.pm_dec_rad_yr is not None
    if moved:
        stars = stars.propagate(epoch)
    position_m, velocity = observer_state(t, observer_velocity_m_s)
    u = np.asarray(stars.vectors, dtype=float).reshape(-1, 3)
    has_plx = stars.parallax_rad is not None
    if has_plx:
        plx = np.nan_to_num(np.asarray(stars.parallax_rad, dtype=float), nan=0.0)
        if np.any(plx < 0):
            plx = np.maximum(plx, 0.0)  # a negative parallax is noise around zero: at infinity
        u = u - plx[:, None] * (position_m / AU_M)[None, :]
        u = u / np.linalg.norm(u, axis=1, keepdims=True)
    if len(u) == 0:
        raise InputError("apparent_places needs at least one star")
    return ApparentPlaces(
        vectors=aberrate(u, velocity),
        time_utc=t.utc.isot,
        epoch_yr=epoch,
        velocity_m_s=velocity,
        proper_motion=moved,
        parallax=has_plx,
    )


@functools.lru_cache(maxsize=4)
def _loaded(spec: str) -> Catalog:
    return load_catalog(spec)


def apparent_places_of(
    catalog: Catalog | str, ids, time, *, observer_velocity_m_s=None
) -> ApparentPlaces:
    """Return the apparent places of the stars ``ids`` of a catalogue, by identifier.

    Parameters
    ----------
    catalog : Catalog or str
        The catalogue, or its specification (:func:`starsense.catalog.load_catalog`; a spec
        is loaded once and kept for later calls).
    ids : array_like of int, shape (N,)
        Catalogue identifiers.
    time : str or astropy.time.Time
        Observation time.
    observer_velocity_m_s : array_like, shape (3,), optional
        As for :func:`apparent_places`.

    Returns
    -------
    ApparentPlaces
    """
    cat = catalog if isinstance(catalog, Catalog) else _loaded(catalog)
    index = cat.index_of(np.asarray(ids, dtype=np.int64))
    return apparent_places(cat, index, time, observer_velocity_m_s=observer_velocity_m_s)
