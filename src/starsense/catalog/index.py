"""Cone queries on the celestial sphere with a k-d tree over ICRS unit vectors.

Two unit vectors separated by the angle ``theta`` are a Euclidean (chord) distance
``2 sin(theta / 2)`` apart, so an angular cone of radius ``r`` is a Euclidean ball of radius
``2 sin(r / 2)`` around its centre vector; :class:`scipy.spatial.cKDTree` answers that
directly. These are plain functions on arrays, shared by :class:`~starsense.catalog.Catalog`
and by anything else that holds unit vectors.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from starsense.errors import InputError
from starsense.geometry.projection import radec_to_vectors


def as_unit_vectors(centers: object, *, name: str = "center") -> np.ndarray:
    """Interpret ``centers`` as unit vector(s).

    Parameters
    ----------
    centers : array_like, shape (3,), (2,), (M, 3) or (M, 2)
        Unit vectors (any non-zero length; they are normalised) or ``(RA, Dec)`` pairs in
        radians. The last axis decides: 3 means vectors, 2 means RA/Dec.
    name : str
        Argument name for error messages.

    Returns
    -------
    numpy.ndarray, shape (3,) or (M, 3)
    """
    try:
        a = np.asarray(centers, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be numeric, got {centers!r}") from exc
    if a.ndim not in (1, 2) or a.shape[-1] not in (2, 3):
        raise InputError(
            f"{name} must have shape (3,) or (M, 3) (unit vectors) or (2,) or (M, 2) "
            f"(RA, Dec in radians); got shape {a.shape}"
        )
    if not np.isfinite(a).all():
        raise InputError(f"{name} must be finite, got {a!r}")
    if a.shape[-1] == 2:
        return radec_to_vectors(a[..., 0], a[..., 1])
    norm = np.linalg.norm(a, axis=-1, keepdims=True)
    if (norm == 0).any():
        raise InputError(f"{name} contains a zero vector; cannot define a direction")
    return a / norm


def chord_radius(radius_rad: object, *, name: str = "radius_rad") -> np.ndarray:
    """Return the chord length ``2 sin(r / 2)`` for an angular radius ``r`` (rad, >= 0).

    Radii above pi are clamped to pi (the whole sphere).
    """
    try:
        r = np.asarray(radius_rad, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a number, got {radius_rad!r}") from exc
    if np.isnan(r).any() or (r < 0).any():
        raise InputError(f"{name} must be >= 0 and not NaN, got {radius_rad!r}")
    return 2.0 * np.sin(0.5 * np.minimum(r, np.pi))


def build_tree(vectors: np.ndarray) -> cKDTree:
    """Build a k-d tree over unit vectors ``(N, 3)`` for chord-distance queries."""
    return cKDTree(np.asarray(vectors, dtype=np.float64))


def cone_query(tree: cKDTree, center: object, radius_rad: float) -> np.ndarray:
    """Return the indices (ascending, int64) of the points within ``radius_rad`` of ``center``."""
    c = as_unit_vectors(center)
    if c.ndim != 1:
        raise InputError(f"center must be a single direction; got shape {c.shape} (use cones)")
    chord = float(chord_radius(radius_rad))
    hits = tree.query_ball_point(c, chord, return_sorted=True)
    return np.asarray(hits, dtype=np.int64)


def cones_query(tree: cKDTree, centers: object, radius_rad: object) -> list[np.ndarray]:
    """Return the indices within each of ``M`` cones: a list of M ascending int64 arrays.

    ``radius_rad`` is a scalar or an ``(M,)`` array of radii.
    """
    c, chord = _batch(centers, radius_rad)
    hits = tree.query_ball_point(c, chord, return_sorted=True, workers=-1)
    return [np.asarray(h, dtype=np.int64) for h in hits]


def count_cones(tree: cKDTree, centers: object, radius_rad: object) -> np.ndarray:
    """Count the points within each of ``M`` cones, ``(M,)`` int64."""
    c, chord = _batch(centers, radius_rad)
    counts = tree.query_ball_point(c, chord, return_length=True, workers=-1)
    return np.asarray(counts, dtype=np.int64).reshape(len(c))


def _batch(centers: object, radius_rad: object) -> tuple[np.ndarray, np.ndarray]:
    c = as_unit_vectors(centers, name="centers")
    c = np.atleast_2d(c)
    chord = chord_radius(radius_rad)
    if chord.ndim not in (0, 1) or (chord.ndim == 1 and chord.shape != (len(c),)):
        raise InputError(
            f"radius_rad must be a scalar or have shape ({len(c)},), got shape {chord.shape}"
        )
    return c, chord
