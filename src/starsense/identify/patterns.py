"""Star patterns of the identification database: thinning, 4-star patterns, hashing, pairs.

Plain functions on NumPy arrays, used by :func:`starsense.identify.database.build_database`
and, at solve time, by the identifiers (the same descriptors computed on detections):

* :func:`thin_by_region`: the brightest stars of every field-sized region of the sky (the
  thinning of tetra3's ``pattern_stars_per_fov`` / ``verification_stars_per_fov``);
* :func:`lattice_patterns`: for each centre of a quasi-uniform lattice of fields
  (:func:`~starsense.geometry.sampling.fibonacci_sphere`), the 4-combinations of its brightest
  pattern stars;
* :func:`pattern_edges`, :func:`edge_ratios`, :func:`order_by_centroid_distance`,
  :func:`hash_keys`, :func:`hash_patterns`: the scale-invariant descriptor of a 4-star pattern
  (five edge ratios) quantised into a sorted hash index (tetra3, Brown et al. 2023 /
  cedar-solve);
* :func:`star_pairs`: every pair of pattern stars closer than the field diagonal, sorted by
  angle (for :mod:`starsense.identify.triangle`).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from starsense.geometry.sampling import fibonacci_sphere

__all__ = [
    "CHUNK_PATTERNS",
    "breadth_first_combinations",
    "chord_angles",
    "edge_ratios",
    "field_sizes",
    "hash_keys",
    "hash_patterns",
    "lattice_patterns",
    "order_by_centroid_distance",
    "pattern_edges",
    "star_pairs",
    "thin_by_region",
]

#: patterns described per block when building (temporaries of ~0.3 KB per pattern)
CHUNK_PATTERNS = 1 << 20

# The 6 edges of a 4-star pattern, as index pairs into the pattern.
_EDGE_PAIRS = np.array([(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)], dtype=np.intp)


def breadth_first_combinations(n: int, k: int) -> NDArray[np.intp]:
    """Return all k-combinations of range(n), those of the brightest stars first.

    Ordered by the largest index in the combination (so all combinations of the first ``m``
    stars come before any that uses star ``m``), then lexicographically.

    Parameters
    ----------
    n : int
        Number of stars (indices 0..n-1, brightest first).
    k : int
        Stars per combination.

    Returns
    -------
    ndarray of int, shape (C(n, k), k)
    """
    combos = np.array(list(itertools.combinations(range(n), k)), dtype=np.intp).reshape(-1, k)
    order = np.lexsort((*combos.T[::-1], combos.max(axis=1)))
    return combos[order]


def chord_angles(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return the angles between unit vectors ``a`` and ``b`` (..., 3), rad (chord formula)."""
    d = a - b
    chord = np.sqrt(np.einsum("...i,...i->...", d, d))
    return 2.0 * np.arcsin(np.clip(chord / 2.0, 0.0, 1.0))


def pattern_edges(vectors: NDArray[np.float64]) -> NDArray[np.float64]:
    """Compute the six edge angles of 4-star patterns.

    Parameters
    ----------
    vectors : ndarray, shape (P, 4, 3)
        Unit vectors of the four stars of each pattern.

    Returns
    -------
    ndarray, shape (P, 6)
        Angles between the stars, rad, in the order (01, 02, 03, 12, 13, 23).
    """
    return chord_angles(vectors[:, _EDGE_PAIRS[:, 0], :], vectors[:, _EDGE_PAIRS[:, 1], :])


def edge_ratios(edges: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Compute the scale-invariant pattern descriptor: the five smallest edges over the largest.

    Parameters
    ----------
    edges : ndarray, shape (P, 6)
        Edge angles, rad (:func:`pattern_edges`).

    Returns
    -------
    ratios : ndarray, shape (P, 5)
        Sorted edges divided by the largest, in (0, 1], ascending.
    largest : ndarray, shape (P,)
        The largest edge, rad.
    """
    s = np.sort(edges, axis=-1)
    largest = s[:, -1]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratios = s[:, :-1] / largest[:, None]
    return ratios, largest


def order_by_centroid_distance(vectors: NDArray[np.float64]) -> NDArray[np.intp]:
    """Order pattern stars canonically: increasing angular distance from the pattern centroid.

    Parameters
    ----------
    vectors : ndarray, shape (P, K, 3)
        Unit vectors of the K stars of each pattern.

    Returns
    -------
    ndarray of int, shape (P, K)
        Per pattern, the permutation putting its stars in canonical order.
    """
    centroid = vectors.sum(axis=1, keepdims=True)
    centroid /= np.sqrt(np.einsum("pki,pki->pk", centroid, centroid))[..., None]
    d = vectors - centroid
    dist2 = np.einsum("pki,pki->pk", d, d)  # squared chords: the same order as the angles
    return np.argsort(dist2, axis=1, kind="stable")


def hash_keys(bins: NDArray[np.integer], n_bins: int) -> NDArray[np.int64]:
    """Return the integer hash key of quantised ratios ``(P, 5)`` (mixed radix, base ``n_bins``)."""
    weights = n_bins ** np.arange(bins.shape[-1], dtype=np.int64)
    return (bins.astype(np.int64) * weights).sum(axis=-1)


def thin_by_region(
    vectors: NDArray[np.float64],
    mags: NDArray[np.float64],
    *,
    radius_rad: float,
    n_per_region: int,
    oversampling: float = 2.0,
) -> NDArray[np.bool_]:
    """Keep, in every region of the sky, its ``n_per_region`` brightest stars.

    Regions are cones of radius `radius_rad` around ``oversampling**2 * 4 / radius_rad**2``
    quasi-uniform centres (Fibonacci lattice); a star is kept if it is among the brightest of
    at least one region.

    Parameters
    ----------
    vectors : ndarray, shape (N, 3)
        ICRS unit vectors.
    mags : ndarray, shape (N,)
        Magnitudes (smaller is brighter); NaN stars are never kept.
    radius_rad : float
        Region radius, rad (half the field of view).
    n_per_region : int
        Stars kept per region.
    oversampling : float
        Lattice density relative to one centre per cone area.

    Returns
    -------
    ndarray of bool, shape (N,)
        Whether each star is kept.
    """
    finite = np.flatnonzero(np.isfinite(mags))
    keep = np.zeros(len(mags), dtype=bool)
    if len(finite) == 0:
        return keep
    order = finite[np.argsort(mags[finite], kind="stable")]  # brightest first
    tree = cKDTree(vectors[order])
    n_centres = max(12, math.ceil(oversampling**2 * 4.0 / radius_rad**2))
    centres = fibonacci_sphere(n_centres)
    chord = 2.0 * math.sin(radius_rad / 2.0)
    for members in tree.query_ball_point(centres, chord):
        if members:
            members = np.sort(np.asarray(members))[:n_per_region]
            keep[order[members]] = True
    return keep


def field_sizes(min_fov_rad: float, max_fov_rad: float, step: float = 1.4) -> list[float]:
    """Return a geometric series of field sizes (rad) from the largest down to the smallest."""
    if min_fov_rad >= max_fov_rad:
        return [max_fov_rad]
    n = math.ceil(math.log(max_fov_rad / min_fov_rad) / math.log(step)) + 1
    return list(np.geomspace(max_fov_rad, min_fov_rad, n))


def lattice_patterns(
    vectors: NDArray[np.float64],
    pattern_stars: list[NDArray[np.int64]],
    sizes: list[float],
    *,
    stars_per_field: int,
    field_oversampling: float,
    patterns_per_field: int | None,
) -> NDArray[np.int64]:
    """Collect the 4-star patterns of a lattice of fields at each field size.

    Parameters
    ----------
    vectors : ndarray, shape (M, 3)
        ICRS unit vectors of the database stars, brightest first.
    pattern_stars : list of ndarray of int
        Per field size, the indices (into `vectors`, ascending = brightest first) of its
        pattern stars.
    sizes : list of float
        Field sizes, rad, one per entry of `pattern_stars`.
    stars_per_field : int
        The brightest stars of each lattice field whose 4-combinations become patterns.
    field_oversampling : float
        Linear oversampling of the lattice: ``field_oversampling**2`` field centres per field
        area (a cone of radius ``size / 2``).
    patterns_per_field : int or None
        Patterns kept per field, breadth-first (those of the brightest stars first); None for
        all of them.

    Returns
    -------
    ndarray of int64, shape (P, 4)
        Distinct patterns (star indices), each in canonical order
        (:func:`order_by_centroid_distance`).
    """
    combos = breadth_first_combinations(stars_per_field, 4)[:patterns_per_field]
    chunks = []
    for size, stars in zip(sizes, pattern_stars, strict=True):
        tree = cKDTree(vectors[stars])
        n_centres = max(12, math.ceil(field_oversampling**2 * 16.0 / size**2))
        centres = fibonacci_sphere(n_centres)
        chord = 2.0 * math.sin(size / 4.0)
        table = np.full((n_centres, stars_per_field), -1, dtype=np.int64)
        for i, members in enumerate(tree.query_ball_point(centres, chord)):
            m = np.sort(np.asarray(members, dtype=np.int64))[:stars_per_field]
            table[i, : len(m)] = stars[m]
        block = max(1, CHUNK_PATTERNS // len(combos))  # fields per block: bounded temporaries
        for start in range(0, n_centres, block):
            pats = table[start : start + block][:, combos].reshape(-1, 4)
            chunks.append(pats[(pats >= 0).all(axis=1)])
    patterns = np.sort(np.concatenate(chunks), axis=1)
    if len(vectors) < 2**16:
        packed = (patterns[:, 0] << 48) | (patterns[:, 1] << 32) | (patterns[:, 2] << 16)
        _, first = np.unique(packed | patterns[:, 3], return_index=True)
        patterns = patterns[first]
    elif len(vectors) < 2**21:  # two 42-bit keys: np.unique(axis=0)'s result, 5x faster
        hi = (patterns[:, 0] << 21) | patterns[:, 1]
        lo = (patterns[:, 2] << 21) | patterns[:, 3]
        order = np.lexsort((lo, hi))
        hi, lo = hi[order], lo[order]
        first = np.ones(len(order), dtype=bool)
        first[1:] = (hi[1:] != hi[:-1]) | (lo[1:] != lo[:-1])
        patterns = patterns[order[first]]
    else:
        patterns = np.unique(patterns, axis=0)
    for start in range(0, len(patterns), CHUNK_PATTERNS):  # bounded temporaries
        part = patterns[start : start + CHUNK_PATTERNS]
        part[:] = np.take_along_axis(part, order_by_centroid_distance(vectors[part]), axis=1)
    return patterns


def hash_patterns(
    vectors: NDArray[np.float64], patterns: NDArray[np.int64], n_bins: int
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """Describe 4-star patterns by their edge ratios and sort them by hash key.

    Parameters
    ----------
    vectors : ndarray, shape (M, 3)
        ICRS unit vectors of the database stars.
    patterns : ndarray of int, shape (P, 4)
        Star indices of each pattern (:func:`lattice_patterns`).
    n_bins : int
        Hash bins per edge ratio (ratios lie in (0, 1]).

    Returns
    -------
    patterns : ndarray of int64, shape (P, 4)
        The patterns, sorted by key.
    ratios : ndarray, shape (P, 5)
        Their edge ratios (:func:`edge_ratios`).
    largest : ndarray, shape (P,)
        Their largest edge, rad.
    keys : ndarray of int64, shape (P,)
        Their hash keys, ascending.
    """
    ratios = np.empty((len(patterns), 5))
    largest = np.empty(len(patterns))
    for start in range(0, len(patterns), CHUNK_PATTERNS):  # bounded temporaries
        part = slice(start, start + CHUNK_PATTERNS)
        ratios[part], largest[part] = edge_ratios(pattern_edges(vectors[patterns[part]]))
    bins = np.clip((ratios * n_bins).astype(np.int64), 0, n_bins - 1)
    keys = hash_keys(bins, n_bins)
    del bins
    sort = np.argsort(keys, kind="stable")
    return patterns[sort], ratios[sort], largest[sort], keys[sort]


def star_pairs(
    vectors: NDArray[np.float64], stars: NDArray[np.int64], max_fov_rad: float
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Find the pairs of `stars` closer than the diagonal of a field, sorted by angle.

    Parameters
    ----------
    vectors : ndarray, shape (M, 3)
        ICRS unit vectors of the database stars.
    stars : ndarray of int, shape (S,)
        Indices into `vectors` of the stars to pair (the pattern stars).
    max_fov_rad : float
        Field of view, rad; pairs up to 1.3 times it (the diagonal of fields up to 4:3, with
        a margin) are kept.

    Returns
    -------
    pairs : ndarray of int64, shape (Q, 2)
        Indices into `vectors`.
    angles : ndarray, shape (Q,)
        Their separations, rad, ascending.
    """
    diag = min(math.pi / 2, 1.3 * max_fov_rad)
    tree = cKDTree(vectors[stars])
    pairs_local = tree.query_pairs(2.0 * math.sin(diag / 2.0), output_type="ndarray")
    pairs = stars[pairs_local.reshape(-1, 2)]
    angles = chord_angles(vectors[pairs[:, 0]], vectors[pairs[:, 1]])
    order = np.argsort(angles, kind="stable")
    return pairs[order], angles[order]
