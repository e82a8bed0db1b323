"""The physical limit over the sky at unit aperture and exposure, computed once per field.

Fialho & Mortari's per-star information is ``F_i(1 m, 1 s) D^4 t`` (eq. 19,
:func:`starsense.analysis.limits.sky.star_weights`), so the attitude Fisher matrix of eq. 21
scales as ``D^4 t`` and the 1-sigma bound as ``D^-2 t^-1/2``. The bound of every attitude at
D = 1 m, t = 1 s therefore depends only on the catalogue, the field and the attitudes: it is
computed once (in blocks of attitudes, so the pairs of a wide field over the whole catalogue
never sit in memory together, with one k-d tree of the stars for every field) and kept for
the next design with the same field.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np
from scipy.spatial import cKDTree

from starsense.analysis.availability.field import field_pairs_cam
from starsense.analysis.datasheet.field import FieldStarsCam, axis_sigmas, fisher_per_pointing
from starsense.analysis.limits.sky import star_weights
from starsense.photometry.stars import BlackBodyStars

__all__ = ["black_bodies", "limit_sigmas", "unit_limit_sigmas"]

_BLOCK = 200  # attitudes per block
_KEEP = 8  # fields kept
_UNIT: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
_STARS: dict[int, tuple[object, BlackBodyStars]] = {}
_TREES: dict[int, tuple[BlackBodyStars, cKDTree]] = {}


def black_bodies(catalog) -> BlackBodyStars:
    """Return the catalogue's stars as black bodies (computed once per catalogue object).

    Parameters
    ----------
    catalog : Catalog

    Returns
    -------
    BlackBodyStars
    """
    key = id(catalog)
    if key not in _STARS or _STARS[key][0] is not catalog:
        _STARS.clear()
        _STARS[key] = (catalog, BlackBodyStars.from_catalog(catalog))
    return _STARS[key][1]


def _tree(stars: BlackBodyStars) -> cKDTree:
    """Return a k-d tree over the stars' vectors (built once per star set)."""
    key = id(stars)
    if key not in _TREES or _TREES[key][0] is not stars:
        _TREES.clear()
        _TREES[key] = (stars, cKDTree(stars.vectors))
    return _TREES[key][1]


def unit_limit_sigmas(catalog, fov, matrices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return the bound per attitude at D = 1 m, t = 1 s: cross, roll (rad), (M,) each.

    Parameters
    ----------
    catalog : Catalog
        The stars (all of them: the bound has no detection limit).
    fov : RectangularFov
        The field.
    matrices : ndarray (M, 3, 3)
        Attitudes, ICRS -> camera.

    Returns
    -------
    cross, roll : ndarray (M,)
        rad; NaN where fewer than two stars.
    """
    mats = np.ascontiguousarray(matrices, dtype=float)
    key = (
        id(catalog),
        len(catalog),
        repr(fov),
        hashlib.sha1(mats.tobytes()).hexdigest(),
    )
    if key not in _UNIT:
        stars = black_bodies(catalog)
        tree = _tree(stars)
        w = star_weights(stars, 1.0, 1.0)  # eq. 19 at D = 1 m, t = 1 s
        cross, roll = np.empty(len(mats)), np.empty(len(mats))
        for start in range(0, len(mats), _BLOCK):
            block = mats[start : start + _BLOCK]
            point, star, v_cam = field_pairs_cam(fov, block, stars.vectors, tree=tree, keep=False)
            pairs = FieldStarsCam(point, star, v_cam, n_pointings=len(block))
            c, r = axis_sigmas(fisher_per_pointing(pairs, w[pairs.star]))
            cross[start : start + _BLOCK], roll[start : start + _BLOCK] = c, r
        while len(_UNIT) >= _KEEP:
            _UNIT.pop(next(iter(_UNIT)))
        _UNIT[key] = (cross, roll)
    return _UNIT[key]


def limit_sigmas(catalog, sensor, fov, *, matrices) -> tuple[np.ndarray, np.ndarray]:
    """Return Fialho & Mortari's bound per attitude for the sensor's D and t (rad), (M,) each.

    The unit bound (:func:`unit_limit_sigmas`) divided by ``D^2 sqrt(t)``.

    Parameters
    ----------
    catalog : Catalog
        All the catalogue's stars.
    sensor : Sensor
        Its aperture D (m) and exposure t (s).
    fov : RectangularFov
        The field.
    matrices : ndarray (M, 3, 3)
        Attitudes, ICRS -> camera.

    Returns
    -------
    cross, roll : ndarray (M,)
        rad.
    """
    cross, roll = unit_limit_sigmas(catalog, fov, matrices)
    scale = sensor.optics.aperture_m**2 * math.sqrt(sensor.exposure_s)
    return cross / scale, roll / scale
