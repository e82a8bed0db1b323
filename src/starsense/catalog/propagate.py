"""Epoch propagation of catalogue positions: uniform straight-line motion in space.

Each star moves uniformly on a straight line in space (ESA 1997, *The Hipparcos and Tycho
Catalogues*, Vol. 1, Sect. 1.5.5, "rigorous" propagation), written in units of the star's
distance at the catalogue epoch so that no parallax is needed:

``r(t) = u0 + (mu_a* p0 + mu_d q0 + mu_r u0) t``,  ``u = r / |r|``

with ``p0 = (-sin a, cos a, 0)``, ``q0 = (-sin d cos a, -sin d sin a, cos d)`` and ``t`` the
time since the catalogue epoch. The proper motions, the radial motion ``mu_r`` and the
parallax are carried to the new epoch (velocity / |r| split into tangential and radial parts;
parallax / |r|), which makes the operation exactly reversible.

:meth:`starsense.catalog.table.Catalog.propagate` applies this kernel to a catalogue.
"""

from __future__ import annotations

import numpy as np

from starsense.geometry.projection import radec_to_vectors, vectors_to_radec

__all__ = ["local_axes", "propagate_columns"]


def local_axes(ra_rad: np.ndarray, dec_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return the unit vectors towards increasing RA (p) and increasing Dec (q).

    Parameters
    ----------
    ra_rad, dec_rad : ndarray, shape (N,)
        ICRS right ascension and declination, rad.

    Returns
    -------
    p, q : ndarray, shape (N, 3)
        The local east and north axes.
    """
    sa, ca = np.sin(ra_rad), np.cos(ra_rad)
    sd, cd = np.sin(dec_rad), np.cos(dec_rad)
    p = np.stack([-sa, ca, np.zeros_like(ra_rad)], axis=1)
    q = np.stack([-sd * ca, -sd * sa, cd], axis=1)
    return p, q


def propagate_columns(
    ra_rad: np.ndarray,
    dec_rad: np.ndarray,
    *,
    pm_ra_rad_yr: np.ndarray,
    pm_dec_rad_yr: np.ndarray,
    radial_motion_per_yr: np.ndarray | None,
    parallax_rad: np.ndarray | None,
    dt_yr: float,
    vectors: np.ndarray | None = None,
) -> dict[str, np.ndarray | None]:
    """Move positions and motions by ``dt_yr`` Julian years (module docstring).

    Parameters
    ----------
    ra_rad, dec_rad : ndarray, shape (N,)
        ICRS right ascension and declination at the start, rad.
    pm_ra_rad_yr, pm_dec_rad_yr : ndarray, shape (N,)
        Proper motions ``mu_alpha*`` (including cos Dec) and ``mu_delta``, rad per Julian
        year. Stars where either is NaN keep their position and motions.
    radial_motion_per_yr : ndarray, shape (N,), or None
        Radial proper motion ``mu_r = v_r / d``, per Julian year; None or NaN means zero.
    parallax_rad : ndarray, shape (N,), or None
        Parallax, rad (only rescaled by the change of distance).
    dt_yr : float
        Time to move by, Julian years.
    vectors : ndarray, shape (N, 3), optional
        The unit vectors of (ra_rad, dec_rad), when already computed.

    Returns
    -------
    dict
        ``ra_rad``, ``dec_rad``, ``pm_ra_rad_yr``, ``pm_dec_rad_yr``, ``parallax_rad`` (None
        if `parallax_rad` is None) and ``radial_motion_per_yr``, each shape (N,).
    """
    has_pm = np.isfinite(pm_ra_rad_yr) & np.isfinite(pm_dec_rad_yr)
    pm_a = np.where(has_pm, pm_ra_rad_yr, 0.0)
    pm_d = np.where(has_pm, pm_dec_rad_yr, 0.0)
    mu_r = (
        np.zeros(len(ra_rad))
        if radial_motion_per_yr is None
        else np.where(np.isfinite(radial_motion_per_yr), radial_motion_per_yr, 0.0)
    )
    u0 = radec_to_vectors(ra_rad, dec_rad) if vectors is None else vectors
    p0, q0 = local_axes(ra_rad, dec_rad)
    velocity = pm_a[:, None] * p0 + pm_d[:, None] * q0 + mu_r[:, None] * u0
    r = u0 + velocity * dt_yr
    norm = np.linalg.norm(r, axis=1)
    u = r / norm[:, None]
    new_ra, new_dec = vectors_to_radec(u)
    p1, q1 = local_axes(new_ra, new_dec)
    w = velocity / norm[:, None]
    radial = np.einsum("ij,ij->i", u, w)
    tangential = w - u * radial[:, None]
    new_pm_a = np.einsum("ij,ij->i", tangential, p1)
    new_pm_d = np.einsum("ij,ij->i", tangential, q1)

    keep = ~has_pm  # stars without proper motion stay exactly where they were
    return {
        "ra_rad": np.where(keep, ra_rad, new_ra),
        "dec_rad": np.where(keep, dec_rad, new_dec),
        "pm_ra_rad_yr": np.where(keep, pm_ra_rad_yr, new_pm_a),
        "pm_dec_rad_yr": np.where(keep, pm_dec_rad_yr, new_pm_d),
        "parallax_rad": None if parallax_rad is None else parallax_rad / np.where(keep, 1.0, norm),
        "radial_motion_per_yr": np.where(keep, mu_r, radial),
    }
