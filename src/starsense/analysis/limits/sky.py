"""Whole-sky and FOV-limited limits (Fialho & Mortari 2019, eqs. 19-24, sec. 3.4, Table 2).

Per-chunk kernels (:func:`sky_fisher`, :func:`fov_fishers`) take any subset of the stars and
return quantities that add exactly over disjoint subsets (sums of eq. 21's terms), so the
whole-catalogue result is the sum over chunks. The in-memory functions call them once on all
stars; :mod:`starsense.scale` calls them on every partition of a HATS catalogue and adds the
results.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from starsense._validate import check_scalar
from starsense.analysis.inputs import as_catalog, as_sensor
from starsense.analysis.limits.centroid import check_aperture
from starsense.analysis.limits.result import LimitResult, boresight_frame, limit_from_fisher
from starsense.attitude.covariance import fisher_matrix
from starsense.catalog import Catalog
from starsense.photometry.stars import BlackBodyStars
from starsense.sensor import Sensor

__all__ = [
    "fov_fishers",
    "fov_limit",
    "fov_results",
    "in_cone",
    "sky_fisher",
    "sky_limit",
    "star_weights",
]


def in_cone(vectors, target, fov_diameter_rad: float) -> np.ndarray:
    """Return the mask of stars inside a cone of full angle ``fov_diameter_rad``.

    Parameters
    ----------
    vectors : array (N, 3)
        Stars, ICRS unit vectors.
    target : array (3,)
        Cone axis (need not be normalised).
    fov_diameter_rad : float
        Full cone angle, rad, in (0, 2 pi].

    Returns
    -------
    array (N,) of bool
    """
    check_scalar(fov_diameter_rad, "fov_diameter_rad", 0, 2 * np.pi, lo_open=True)
    t = np.asarray(target, dtype=float)
    t = t / np.linalg.norm(t)
    return np.asarray(vectors) @ t >= np.cos(fov_diameter_rad / 2.0) - 1e-15


def star_weights(stars: BlackBodyStars, diameter_m: float, exposure_s: float) -> np.ndarray:
    """Return F_i = F_i(1 m, 1 s) D^4 t (eq. 19) per star, rad^-2, (N,)."""
    return stars.fisher_unit * diameter_m**4 * exposure_s


def sky_fisher(stars: BlackBodyStars, diameter_m: float, exposure_s: float) -> np.ndarray:
    """Return eq. 21 over these stars, (3, 3) rad^-2: the per-chunk kernel of :func:`sky_limit`."""
    return fisher_matrix(stars.vectors, star_weights(stars, diameter_m, exposure_s))


def sky_limit(
    stars: BlackBodyStars | Catalog | str | None = None,
    *,
    sensor: Sensor | str | Path | None = None,
    diameter_m: float | None = None,
    exposure_s: float | None = None,
) -> LimitResult:
    """Compute the limit of the ideal spherical sensor that sees the whole sky (eqs. 19-24).

    The aperture and exposure are a sensor's (``sensor``), or given (``diameter_m``,
    ``exposure_s``; either overrides the sensor's), or the unit aperture (1 m, 1 s) the paper
    scales from (the limit goes as ``D^-2 t^-1/2``).

    Parameters
    ----------
    stars : BlackBodyStars, Catalog, str or None
        The catalogue's stars as black bodies, a catalogue, a catalogue specification
        (``"hipparcos"``) or None for the bundled Hipparcos.
    sensor : Sensor, str or Path, optional
        A sensor (object, preset name or TOML file): its aperture and exposure.
    diameter_m : float, optional
        Aperture D, m (default: the sensor's, else 1).
    exposure_s : float, optional
        Exposure t, s (default: the sensor's, else 1).

    Returns
    -------
    LimitResult
        Axes in ICRS.
    """
    sens = None if sensor is None else as_sensor(sensor)
    if diameter_m is None:
        diameter_m = 1.0 if sens is None else sens.optics.aperture_m
    if exposure_s is None:
        exposure_s = 1.0 if sens is None else sens.exposure_s
    if not isinstance(stars, BlackBodyStars):
        stars = BlackBodyStars.from_catalog(as_catalog(stars))
    check_aperture(diameter_m, exposure_s)
    return limit_from_fisher(
        sky_fisher(stars, diameter_m, exposure_s),
        len(stars),
        diameter_m=diameter_m,
        exposure_s=exposure_s,
    )


def fov_fishers(
    stars: BlackBodyStars,
    targets,
    *,
    fov_diameter_rad: float,
    diameter_m: float,
    exposure_s: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Return each head's Fisher matrix and star count: the per-chunk kernel of :func:`fov_limit`.

    Parameters
    ----------
    stars : BlackBodyStars
        Any subset of the catalogue's stars.
    targets : array (T, 3)
        Head boresights, ICRS unit vectors.
    fov_diameter_rad : float
        Full cone angle of each head, rad.
    diameter_m, exposure_s : float
        Aperture D (m) and exposure t (s).

    Returns
    -------
    fishers : array (T, 3, 3)
        rad^-2.
    counts : array (T,) of int
        Stars in each head's cone.
    """
    targets = np.atleast_2d(np.asarray(targets, dtype=float))
    w = star_weights(stars, diameter_m, exposure_s)
    fishers = np.zeros((len(targets), 3, 3))
    counts = np.zeros(len(targets), dtype=np.int64)
    for k, t in enumerate(targets):
        m = in_cone(stars.vectors, t, fov_diameter_rad)
        fishers[k] = fisher_matrix(stars.vectors[m], w[m])
        counts[k] = int(m.sum())
    return fishers, counts


def fov_results(
    fishers, counts, targets, *, diameter_m: float, exposure_s: float
) -> tuple[list[LimitResult], LimitResult | None]:
    """Return the heads and merged heads from the summed output of :func:`fov_fishers`.

    Parameters
    ----------
    fishers : array (T, 3, 3)
        Each head's Fisher matrix, rad^-2.
    counts : array (T,) of int
        Stars per head.
    targets : array (T, 3)
        Head boresights, ICRS unit vectors.
    diameter_m, exposure_s : float
        Aperture D (m) and exposure t (s).

    Returns
    -------
    heads : list of LimitResult
        Axes in each head's boresight frame.
    merged : LimitResult or None
        All heads merged (sec. 3.4), ICRS axes; None for a single target.
    """
    targets = np.atleast_2d(np.asarray(targets, dtype=float))
    heads = [
        limit_from_fisher(
            f, int(n), diameter_m=diameter_m, exposure_s=exposure_s, frame_rows=boresight_frame(t)
        )
        for f, n, t in zip(fishers, counts, targets, strict=True)
    ]
    merged = None
    if len(targets) > 1:
        merged = limit_from_fisher(
            np.sum(fishers, axis=0),
            int(np.sum(counts)),
            diameter_m=diameter_m,
            exposure_s=exposure_s,
        )
    return heads, merged


def fov_limit(
    stars: BlackBodyStars,
    targets,
    *,
    fov_diameter_rad: float,
    diameter_m: float = 1.0,
    exposure_s: float = 1.0,
) -> tuple[list[LimitResult], LimitResult | None]:
    """Compute the FOV-limited limit (sec. 3.4, Table 2): one head per target, and all merged.

    Each head sees the stars in a cone of full angle ``fov_diameter_rad`` around its target
    (unit vector). The merged estimate adds the heads' Fisher matrices: measurements of separate
    heads are independent, so a merged pair is never worse than either head.

    Parameters
    ----------
    stars : BlackBodyStars
        The catalogue's stars.
    targets : array (3,) or (T, 3)
        Head boresights, ICRS unit vectors.
    fov_diameter_rad : float
        Full cone angle of each head, rad.
    diameter_m, exposure_s : float
        Aperture D (m) and exposure t (s).

    Returns
    -------
    heads : list of LimitResult
        Axes in each head's boresight frame.
    merged : LimitResult or None
        ICRS axes; None for a single target.
    """
    check_aperture(diameter_m, exposure_s)
    fishers, counts = fov_fishers(
        stars,
        targets,
        fov_diameter_rad=fov_diameter_rad,
        diameter_m=diameter_m,
        exposure_s=exposure_s,
    )
    return fov_results(fishers, counts, targets, diameter_m=diameter_m, exposure_s=exposure_s)
