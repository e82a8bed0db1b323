"""What a solved frame's matched stars are referenced to: their places on the sky at the frame.

The catalogue places of the matched stars, moved to their apparent places when the frame's time
is known (:mod:`starsense.catalog.apparent`: proper motion, parallax, aberration, the observer's
velocity). A close double the PSF does not split is drawn by the forward model's fit, star and
neighbour (:mod:`starsense.solve.refine`).
"""

from __future__ import annotations

import numpy as np

from starsense.catalog.apparent import apparent_places, apparent_places_of

__all__ = ["matched_references", "reference_places", "sky_places"]


def reference_places(solver, vectors, catalog_ids, *, obs_time) -> tuple[np.ndarray, dict]:
    """Return the matched stars' reference vectors: apparent places when a time is known.

    Parameters
    ----------
    solver : Solver
        Its catalogue and settings (``apparent``, ``observer_velocity_m_s``).
    vectors : ndarray (K, 3)
        The stars' catalogue places, ICRS.
    catalog_ids : sequence of int
        Their catalogue identifiers.
    obs_time : str, astropy.time.Time or None
        When the frame was taken.

    Returns
    -------
    ndarray (K, 3), dict
        The places and how they were made (:meth:`ApparentPlaces.to_dict`).
    """
    if obs_time is None or not solver.settings.apparent:
        why = "no frame time" if obs_time is None else "off"
        return vectors, {"applied": False, "reason": why}
    p = apparent_places_of(
        solver.catalog,
        catalog_ids,
        obs_time,
        observer_velocity_m_s=solver.settings.observer_velocity_m_s,
    )
    return p.vectors, p.to_dict()


def matched_references(solver, db, ident, *, obs_time):
    """Return the matched stars' references (apparent places), how, and their places.

    Parameters
    ----------
    solver : Solver
    db : identification database
        Its ``vectors`` hold the matched stars (``ident.catalog_index``).
    ident : identification result
    obs_time : str, astropy.time.Time or None

    Returns
    -------
    ref : ndarray (K, 3)
        Apparent places (catalogue places when no time is known).
    apparent : dict
        How the apparent places were made.
    places : (ndarray, ndarray)
        The (catalogue, apparent) places.
    """
    plain = db.vectors[np.asarray(ident.catalog_index)]
    ref, apparent = reference_places(solver, plain, ident.catalog_id, obs_time=obs_time)
    return ref, apparent, (plain, ref)


def sky_places(solver, sky, *, obs_time):
    """Return the function placing stars of ``sky`` (rows of it) where the frame sees them.

    Parameters
    ----------
    solver : Solver
        Its settings (``apparent``, ``observer_velocity_m_s``).
    sky : SkyStars
        The catalogue's stars the model fit may draw.
    obs_time : str, astropy.time.Time or None
        When the frame was taken.

    Returns
    -------
    callable
        ``place(rows) -> ndarray (len(rows), 3)``: apparent places when a time is known (each
        star's own proper motion, parallax and aberration), else the catalogue places.
    """
    if obs_time is None or not solver.settings.apparent:
        return lambda rows: sky.vectors[np.asarray(rows, dtype=int)]
    velocity = solver.settings.observer_velocity_m_s

    def place(rows):
        rows = np.asarray(rows, dtype=int)
        if rows.size == 0:
            return np.zeros((0, 3))
        got = apparent_places(sky.catalog, sky.rows[rows], obs_time, observer_velocity_m_s=velocity)
        return got.vectors

    return place
