"""theta_rms over the N brightest stars and its extrapolation (Fialho & Mortari 2019, Fig. 7).

The kernels (:func:`brightest_order`, :func:`brightest_checkpoints`,
:func:`brightest_from_sums`) are shared with the distributed path (:mod:`starsense.scale`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from starsense.analysis.limits.centroid import check_aperture
from starsense.analysis.limits.sky import star_weights
from starsense.attitude.covariance import (
    covariance,
    fisher_components,
    fisher_from_components,
    theta_rms,
)
from starsense.errors import SingularGeometryError
from starsense.photometry.stars import BlackBodyStars
from starsense.references.fialho2019 import N_GALAXY

__all__ = [
    "BrightestCurve",
    "brightest_checkpoints",
    "brightest_curve",
    "brightest_from_sums",
    "brightest_order",
]


@dataclass(frozen=True)
class BrightestCurve:
    """theta_rms over the N brightest stars (Fig. 7) and its power-law extrapolation.

    Attributes
    ----------
    n_stars : array (K,)
        N at each point of the curve.
    theta_rms_rad : array (K,)
        For the given D and t (G itself when D = 1 m, t = 1 s).
    slope : float
        d log theta / d log N fitted over the last decade of the catalogue.
    intercept : float
        log10 theta at N = 1 of the fitted power law.
    n_extrapolated : float
        N the curve is extrapolated to (paper: 3e11 stars in the Galaxy).
    theta_extrapolated_rad : float
        The power law at ``n_extrapolated``.
    colour : str
        Colour system of the black bodies.
    """

    n_stars: np.ndarray
    theta_rms_rad: np.ndarray
    slope: float
    intercept: float
    n_extrapolated: float
    theta_extrapolated_rad: float
    colour: str

    def extrapolate(self, n) -> np.ndarray:
        """Return the fitted power law at ``n`` stars, rad."""
        return 10 ** (self.intercept + self.slope * np.log10(n))

    def to_dict(self) -> dict:
        """Return the JSON form (radians)."""
        return {
            "colour": self.colour,
            "n_stars": [int(n) for n in self.n_stars],
            "theta_rms_rad": [float(x) for x in self.theta_rms_rad],
            "slope": self.slope,
            "n_extrapolated": self.n_extrapolated,
            "theta_extrapolated_rad": self.theta_extrapolated_rad,
        }


def brightest_curve(
    stars: BlackBodyStars,
    *,
    diameter_m: float = 1.0,
    exposure_s: float = 1.0,
    points_per_decade: int = 20,
    n_extrapolated: float = N_GALAXY,
) -> BrightestCurve:
    """Compute theta_rms of the N brightest stars, N = 2 ... all (Fig. 7), in one pass.

    Stars are ranked by catalogue magnitude (ties broken by position, :func:`brightest_order`);
    the seven independent components of eq. 21
    (:func:`~starsense.attitude.covariance.fisher_components`) are accumulated between
    checkpoints with ``np.add.reduceat``. N with a singular geometry (e.g. N = 2 antipodal stars)
    is dropped from the curve.

    Parameters
    ----------
    stars : BlackBodyStars
        The catalogue's stars.
    diameter_m, exposure_s : float
        Aperture D (m) and exposure t (s).
    points_per_decade : int
        Checkpoints per decade of N.
    n_extrapolated : float
        N to extrapolate the power law to.

    Returns
    -------
    BrightestCurve
    """
    check_aperture(diameter_m, exposure_s)
    n_total = len(stars)
    if n_total < 2:
        raise SingularGeometryError(f"singular geometry ({n_total} star): need at least 2 stars")
    w = star_weights(stars, diameter_m, exposure_s)
    order = brightest_order(stars.magnitude, stars.vectors, w)
    comps = fisher_components(stars.vectors[order], w[order])
    ns = brightest_checkpoints(n_total, points_per_decade)
    starts = np.concatenate([[0], ns[:-1]])
    sums = np.cumsum(np.add.reduceat(comps, starts, axis=0), axis=0)
    return brightest_from_sums(ns, sums, n_extrapolated=n_extrapolated, colour=stars.colour)


def brightest_order(magnitude, vectors, weights) -> np.ndarray:
    """Return indices that rank stars brightest first, whatever their order in the catalogue.

    Stars are sorted by magnitude; stars of equal magnitude (common in catalogues that round to
    0.01 mag) by x, y, z of the unit vector and then the weight, so that any partitioning of a
    catalogue (HATS tiles) ranks them the same way and the N-brightest sums agree exactly.

    Parameters
    ----------
    magnitude : array (N,)
        Catalogue magnitudes.
    vectors : array (N, 3)
        ICRS unit vectors.
    weights : array (N,)
        Per-star Fisher information, rad^-2.

    Returns
    -------
    array (N,) of int
    """
    mag = np.asarray(magnitude, dtype=float)
    order = np.argsort(mag, kind="stable")
    ms = mag[order]
    tie = ms[1:] == ms[:-1]
    if tie.any():
        in_group = np.zeros(len(ms), dtype=bool)
        in_group[1:] |= tie
        in_group[:-1] |= tie
        pos = np.flatnonzero(in_group)  # runs of equal magnitude, contiguous and ascending
        o = order[pos]
        r = np.asarray(vectors, dtype=float)[o]
        w = np.asarray(weights, dtype=float)[o]
        order[pos] = o[np.lexsort((w, r[:, 2], r[:, 1], r[:, 0], mag[o]))]
    return order


def brightest_checkpoints(n_total: int, points_per_decade: int = 20) -> np.ndarray:
    """Return the N at which the curve is evaluated: log-spaced from 2 to ``n_total`` included."""
    return np.unique(
        np.concatenate(
            [
                np.round(
                    np.logspace(
                        np.log10(2),
                        np.log10(n_total),
                        1 + int(points_per_decade * np.log10(n_total / 2)),
                    )
                ).astype(int),
                [n_total],
            ]
        )
    )


def brightest_from_sums(
    ns, sums, *, n_extrapolated: float = N_GALAXY, colour: str = ""
) -> BrightestCurve:
    """Build the curve from the summed components of the ``ns[k]`` brightest stars, ``sums[k]``.

    theta_rms at each N (eq. 22), dropping N with a singular geometry, and the power-law fit
    over the last decade extrapolated to ``n_extrapolated`` stars.

    Parameters
    ----------
    ns : array (K,) of int
        Checkpoints (:func:`brightest_checkpoints`).
    sums : array (K, 7)
        Summed :func:`~starsense.attitude.covariance.fisher_components` of the brightest ns[k].
    n_extrapolated : float
        N to extrapolate the power law to.
    colour : str
        Colour system, carried into the result.

    Returns
    -------
    BrightestCurve
    """
    keep_n, theta = [], []
    for n, s in zip(ns, sums, strict=True):
        try:
            theta.append(theta_rms(covariance(fisher_from_components(s), int(n))))
            keep_n.append(n)
        except SingularGeometryError:
            continue
    ns_arr, th_arr = np.array(keep_n), np.array(theta)
    tail = ns_arr >= max(ns_arr[-1] / 10.0, 2)
    if tail.sum() < 2:
        tail = np.ones_like(ns_arr, dtype=bool)
    slope, intercept = np.polyfit(np.log10(ns_arr[tail]), np.log10(th_arr[tail]), 1)
    extrap = float(10 ** (intercept + slope * np.log10(n_extrapolated)))
    return BrightestCurve(
        ns_arr,
        th_arr,
        float(slope),
        float(intercept),
        float(n_extrapolated),
        extrap,
        colour,
    )
