"""What a solved frame's matched stars are referenced to: their places on the sky at the frame.

The catalogue places of the matched stars, moved to their apparent places when the frame's time
is known (:mod:`starsense.catalog.apparent`: proper motion, parallax, aberration, the observer's
velocity), and, for the centroids' attitude, to a close double's photocentre where the PSF does
not split it (:func:`starsense.solve.blends.blended`). The forward model's fit draws each star
and its neighbours itself: it takes the unblended places.
"""

from __future__ import annotations

import numpy as np

from starsense.catalog.apparent import apparent_places_of
from starsense.solve.blends import blend_radius_px, blended

__all__ = ["matched_references", "reference_places"]


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


def matched_references(solver, db, ident, *, obs_time, pixel_rad: float):
    """Return the matched stars' references (apparent, blended), how, and their plain places.

    Parameters
    ----------
    solver : Solver
    db : identification database
        Its ``vectors`` hold the matched stars (``ident.catalog_index``).
    ident : identification result
    obs_time : str, astropy.time.Time or None
    pixel_rad : float
        The angle of a pixel, rad.

    Returns
    -------
    ref : ndarray (K, 3)
        For the centroids' attitude: apparent places, close doubles at their photocentres.
    apparent : dict
        How the apparent places were made.
    places : (ndarray, ndarray)
        The (catalogue, apparent) places, unblended: what the model fit draws.
    """
    plain = db.vectors[np.asarray(ident.catalog_index)]
    ref, apparent = reference_places(solver, plain, ident.catalog_id, obs_time=obs_time)
    places = (plain, ref)
    if solver.sensor is not None:  # blended close doubles: their photocentre, not one star
        radius = blend_radius_px(solver.sensor.detector.psf_sigma_px) * pixel_rad
        ref = blended(ref, plain, db, index=ident.catalog_index, radius_rad=radius)
    return ref, apparent, places
