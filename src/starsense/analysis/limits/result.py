"""The attitude-accuracy limit of one sensor, from its Fisher matrix (eqs. 20-23)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from starsense.attitude.covariance import covariance, theta_rms
from starsense.geometry.attitude import east_north, vectors_to_radec

__all__ = ["LimitResult", "boresight_frame", "limit_from_fisher", "limit_line"]


def boresight_frame(target) -> np.ndarray:
    """Return the rows east, north and boresight of a sensor pointed at ``target``.

    Used to express a pointed sensor's covariance as two cross-boresight axes and roll; the
    east/north convention is :func:`starsense.geometry.attitude.east_north`'s.

    Parameters
    ----------
    target : array (3,)
        Boresight, ICRS unit vector.

    Returns
    -------
    array (3, 3)
        Unit east, north and boresight as rows.
    """
    z = np.asarray(target, dtype=float)
    z = z / np.linalg.norm(z)
    ra, dec = vectors_to_radec(z)
    east, north = east_north(ra, dec)
    return np.stack([east, north, z])


@dataclass(frozen=True)
class LimitResult:
    """The attitude-accuracy limit of one sensor (or of merged heads).

    Attributes
    ----------
    theta_rms_rad : float
        sqrt(tr P), eq. 22.
    axis_sigma_rad : array (3,)
        sqrt(diag P) in ``frame``: ICRS x, y, z for the whole sky; for a pointed sensor the two
        cross-boresight axes (east, north) and the roll about the boresight.
    covariance : array (3, 3)
        P in ICRS, rad^2.
    n_stars : int
        Stars contributing.
    g_rad_m2_s05 : float
        G = theta_rms D^2 t^1/2 (eq. 23).
    frame : str
        "icrs" or "boresight".
    """

    theta_rms_rad: float
    axis_sigma_rad: np.ndarray
    covariance: np.ndarray
    n_stars: int
    g_rad_m2_s05: float
    frame: str = "icrs"

    def to_dict(self) -> dict:
        """Return the JSON form (radians)."""
        return {
            "theta_rms_rad": self.theta_rms_rad,
            "axis_sigma_rad": [float(x) for x in self.axis_sigma_rad],
            "n_stars": self.n_stars,
            "g_rad_m2_s05": self.g_rad_m2_s05,
            "frame": self.frame,
        }


def limit_from_fisher(fisher, n_stars, *, diameter_m, exposure_s, frame_rows=None) -> LimitResult:
    """Return the :class:`LimitResult` of an attitude Fisher matrix (eqs. 20-23).

    The last step of every limit, shared by the in-memory and the distributed paths
    (:mod:`starsense.scale`): ``fisher`` may be a sum of per-chunk matrices.

    Parameters
    ----------
    fisher : array (3, 3)
        Attitude Fisher matrix, rad^-2.
    n_stars : int
        Stars that contributed.
    diameter_m, exposure_s : float
        D (m) and t (s), for G = theta_rms D^2 t^1/2.
    frame_rows : array (3, 3) or None
        Rows of a pointed sensor's frame (:func:`boresight_frame`); None for ICRS axes.

    Returns
    -------
    LimitResult
    """
    p = covariance(fisher, n_stars)
    th = theta_rms(p)
    if frame_rows is None:
        axes, frame = np.sqrt(np.diag(p)), "icrs"
    else:
        axes, frame = np.sqrt(np.diag(frame_rows @ p @ frame_rows.T)), "boresight"
    return LimitResult(th, axes, p, n_stars, th * diameter_m**2 * np.sqrt(exposure_s), frame)


def limit_line(g_rad_m2_s05, d2_sqrt_t):
    """Return theta = G / (D^2 t^1/2) (eq. 23) against the figure of merit D^2 t^1/2.

    Parameters
    ----------
    g_rad_m2_s05 : float or array
        G, rad m^2 s^1/2.
    d2_sqrt_t : float or array
        D^2 t^1/2, m^2 s^1/2.

    Returns
    -------
    float or array
        theta_rms, rad.
    """
    return np.asarray(g_rad_m2_s05) / np.asarray(d2_sqrt_t)
