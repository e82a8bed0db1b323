"""The stars inside the field at each pointing: the counting kernel of the availability analysis.

The stars inside the field at each pointing are found once (a :class:`scipy.spatial.cKDTree`
cone prefilter, then the exact field test), and their magnitudes are kept sorted per pointing
(:class:`FieldStars`, a CSR layout). The ``k``-th brightest magnitude in the field, ``m_(k)``,
then answers every question: a pointing sees at least ``N_min`` stars brighter than ``m_t``
exactly when ``m_(N_min) <= m_t``, so the availability for any threshold is the empirical
distribution function of ``m_(N_min)`` over the pointings: one ``searchsorted`` per threshold.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from starsense._validate import check_int
from starsense.analysis.availability.checks import Fov, check_fov, check_mag
from starsense.errors import InputError
from starsense.geometry.fov import CircularFov

__all__ = [
    "BrightestInField",
    "FieldStars",
    "catalog_stars",
    "field_pairs",
    "field_pairs_cam",
    "inside_camera",
]

# Margins on the prefilter chord so that rounding never drops a star the exact test accepts.
_CHORD_REL_MARGIN = 1e-9
_CHORD_ABS_MARGIN = 1e-12
# the last call of field_pairs_cam: {"last": (key, (point, star, v_cam))}
_LAST_PAIRS: dict = {}
# the largest result kept (pairs; 40 bytes each)
_MEMO_MAX_PAIRS = 2_000_000
# Upper bound on (pointing, star) candidate pairs held in memory at once.
_CANDIDATE_BUDGET = 1_000_000


def inside_camera(fov: Fov, v_cam: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Return which camera-frame vectors are inside the field (the tests of geometry.fov).

    Parameters
    ----------
    fov : CircularFov or RectangularFov
        The field.
    v_cam : ndarray (..., 3)
        Unit vectors in the camera frame (+z the boresight).

    Returns
    -------
    ndarray (...) of bool
    """
    x, y, z = v_cam[..., 0], v_cam[..., 1], v_cam[..., 2]
    if isinstance(fov, CircularFov):
        return z >= math.cos(fov.half_angle_rad)
    return (
        (z > 0.0)
        & (np.abs(x) <= z * math.tan(fov.half_width_rad))
        & (np.abs(y) <= z * math.tan(fov.half_height_rad))
    )


def field_pairs(
    fov: Fov,
    matrices: NDArray[np.float64],
    vectors: NDArray[np.float64],
    *,
    tree: cKDTree | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Return all (pointing, star) pairs with the star inside the field.

    :func:`field_pairs_cam` without the camera-frame vectors.

    Parameters
    ----------
    fov : CircularFov or RectangularFov
        The field.
    matrices : ndarray, shape (M, 3, 3)
        Attitude matrices (ICRS -> camera; row 2 is the boresight).
    vectors : ndarray, shape (N, 3)
        Star unit vectors, ICRS.
    tree : cKDTree, optional
        Built on exactly `vectors`.
    progress : callable(done, total), optional
        Called after each block with the pointings done.

    Returns
    -------
    point_idx, star_idx : ndarray of int, shape (P,)
        Pairs in ascending pointing order (star order within a pointing is arbitrary).
    """
    point, star, _ = field_pairs_cam(fov, matrices, vectors, tree=tree, progress=progress)
    return point, star


def field_pairs_cam(
    fov: Fov,
    matrices: NDArray[np.float64],
    vectors: NDArray[np.float64],
    *,
    tree: cKDTree | None = None,
    progress: Callable[[int, int], None] | None = None,
    keep: bool = True,
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]]:
    """Return all (pointing, star) pairs with the star inside the field, and its camera vector.

    The candidates are the stars within the chord of the field's enclosing radius around each
    boresight: one :meth:`cKDTree.sparse_distance_matrix` between a tree of the block's
    boresights and the stars' tree (NumPy arrays, no per-pair Python objects), grouped by
    pointing with a stable radix sort; each pointing's candidates are rotated into its camera
    frame by one matrix product and the exact field test keeps those inside. Blocks of
    pointings hold at most about a million candidate pairs. The last result is kept (read-only
    arrays): the datasheet asks for the same stars in the same field twice (the availability
    and the stars per field), and the second call is free.

    Parameters
    ----------
    fov : CircularFov or RectangularFov
        The field.
    matrices : ndarray, shape (M, 3, 3)
        Attitude matrices (ICRS -> camera; row 2 is the boresight).
    vectors : ndarray, shape (N, 3)
        Star unit vectors, ICRS.
    tree : cKDTree, optional
        Built on exactly `vectors`.
    progress : callable(done, total), optional
        Called after each block with the pointings done.
    keep : bool
        Keep the result for the next call with the same field, attitudes and stars (False:
        neither look it up nor keep it, for callers that walk blocks of attitudes once).

    Returns
    -------
    point_idx, star_idx : ndarray of int, shape (P,)
        Pairs in ascending pointing order (star order within a pointing is arbitrary).
    v_cam : ndarray, shape (P, 3)
        The star's unit vector in the pointing's camera frame.
    """
    check_fov(fov)
    n_att = matrices.shape[0]
    empty = np.zeros(0, dtype=np.intp)
    if n_att == 0 or vectors.shape[0] == 0:
        return empty, empty.copy(), np.zeros((0, 3))
    if not keep:
        return _pairs_cam(fov, matrices, vectors, tree=tree, progress=progress)
    key = _pairs_key(fov, matrices, vectors)
    last = _LAST_PAIRS.get("last")  # one read: safe with threads
    if last is not None and last[0] == key:
        if progress is not None:
            progress(n_att, n_att)
        return last[1]
    out = _pairs_cam(fov, matrices, vectors, tree=tree, progress=progress)
    if len(out[0]) <= _MEMO_MAX_PAIRS:
        for a in out:
            a.flags.writeable = False  # shared with the next caller of the same field
        _LAST_PAIRS["last"] = (key, out)
    return out


def _pairs_key(fov: Fov, matrices, vectors) -> bytes:
    """Return a digest of the field, the attitudes and the stars (the memo's key)."""
    h = hashlib.sha1(repr(fov).encode())
    h.update(np.ascontiguousarray(matrices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(vectors, dtype=np.float64).tobytes())
    return h.digest()


def _pairs_cam(fov: Fov, matrices, vectors, *, tree, progress):
    """Return what :func:`field_pairs_cam` returns, computed (non-empty inputs)."""
    n_att = matrices.shape[0]
    if tree is None:
        tree = cKDTree(vectors)
    radius = min(fov.enclosing_radius_rad, math.pi)
    chord = 2.0 * math.sin(0.5 * radius) * (1.0 + _CHORD_REL_MARGIN) + _CHORD_ABS_MARGIN
    expected = max(1.0, 1.5 * vectors.shape[0] * math.sin(0.5 * radius) ** 2)
    block = max(1, min(2**16 - 1, int(_CANDIDATE_BUDGET // expected)))
    vecs = np.asarray(vectors, dtype=np.float64)
    points, stars, cams = [], [], []
    for start in range(0, n_att, block):
        mats = np.asarray(matrices[start : start + block], dtype=np.float64)
        near = cKDTree(mats[:, 2, :]).sparse_distance_matrix(tree, chord, output_type="ndarray")
        group = near["i"].astype(np.uint16)
        order = np.argsort(group, kind="stable")  # a radix sort: grouped by pointing
        star_idx = near["j"][order].astype(np.intp, copy=False)
        counts = np.bincount(group, minlength=len(mats))
        del near, order, group
        v_cam = _rotate_grouped(mats, counts, vecs[star_idx])
        inside = inside_camera(fov, v_cam)
        points.append(np.repeat(np.arange(start, start + len(mats)), counts)[inside])
        stars.append(star_idx[inside])
        cams.append(v_cam[inside])
        if progress is not None:
            progress(min(start + block, n_att), n_att)
    return np.concatenate(points), np.concatenate(stars), np.concatenate(cams)


def _rotate_grouped(mats: NDArray[np.float64], counts, v: NDArray[np.float64]):
    """Rotate ``v`` (K, 3), grouped by pointing (``counts`` rows each), by each one's matrix."""
    offsets = np.zeros(len(mats) + 1, dtype=np.intp)
    np.cumsum(counts, out=offsets[1:])
    out = np.empty_like(v)
    for k in np.flatnonzero(counts):
        a, b = offsets[k], offsets[k + 1]
        np.matmul(v[a:b], mats[k].T, out=out[a:b])
    return out


def _availability(
    sorted_kth: NDArray[np.float64], max_mag: ArrayLike, n_pointings: int
) -> float | NDArray[np.float64]:
    """Return the fraction of pointings whose sorted k-th brightest magnitude is ``<= max_mag``."""
    m = np.asarray(max_mag, dtype=np.float64)
    if np.any(np.isnan(m)):
        raise InputError("detection threshold m_t must not be NaN")
    if n_pointings == 0:
        raise InputError("no pointings: availability is undefined")
    frac = np.searchsorted(sorted_kth, m, side="right") / n_pointings
    return float(frac) if frac.ndim == 0 else frac


@dataclass(frozen=True, eq=False)
class FieldStars:
    """Magnitudes of the stars inside the field at each of M pointings, sorted per pointing.

    CSR layout: the stars of pointing ``j`` have magnitudes
    ``magnitudes[offsets[j]:offsets[j + 1]]``, brightest first.

    Attributes
    ----------
    offsets : ndarray of int, shape (M + 1,)
        Start of each pointing's stars in `magnitudes`.
    magnitudes : ndarray, shape (P,)
        Magnitudes of the stars in the field, pointing by pointing.
    n_stars : int
        Stars of the star set the field was built from (after the magnitude cut).
    """

    offsets: NDArray[np.intp]
    magnitudes: NDArray[np.float64]
    n_stars: int
    _kth_sorted: dict = field(default_factory=dict, repr=False, init=False)

    @classmethod
    def build(
        cls,
        fov: Fov,
        attitudes: Rotation,
        vectors: ArrayLike,
        magnitudes: ArrayLike,
        *,
        tree: cKDTree | None = None,
        progress: Callable[[int, int], None] | None = None,
    ) -> FieldStars:
        """Find the stars in the field at every attitude and sort their magnitudes.

        Parameters
        ----------
        fov : CircularFov or RectangularFov
            The field.
        attitudes : Rotation, batch of M
            ICRS -> camera.
        vectors : array_like, shape (N, 3)
            Star unit vectors, ICRS.
        magnitudes : array_like, shape (N,)
            Star magnitudes (finite).
        tree : cKDTree, optional
            Built on exactly `vectors`.
        progress : callable(done, total), optional
            Called with the pointings done.

        Returns
        -------
        FieldStars
        """
        v = np.asarray(vectors, dtype=np.float64)
        mags = np.asarray(magnitudes, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 3 or mags.shape != (v.shape[0],):
            raise InputError(
                f"vectors must be (N, 3) and magnitudes (N,); got {v.shape} and {mags.shape}"
            )
        if not np.all(np.isfinite(mags)):
            raise InputError("star magnitudes must be finite (drop stars without one)")
        if not isinstance(attitudes, Rotation) or attitudes.single:
            raise InputError("attitudes must be a batch of scipy Rotations")
        matrices = attitudes.as_matrix().reshape(-1, 3, 3)
        n_att, n = matrices.shape[0], v.shape[0]
        if tree is not None and (tree.n != n or tree.m != 3):
            raise InputError("tree must be a cKDTree built on exactly the star vectors")
        points, stars = field_pairs(fov, matrices, v, tree=tree, progress=progress)
        # sort by (pointing, magnitude): rank the stars by magnitude once, then one integer sort
        rank = np.empty(n, dtype=np.int64)
        order = np.argsort(mags, kind="stable")
        rank[order] = np.arange(n)
        key = np.sort(points.astype(np.int64) * max(n, 1) + rank[stars])
        sorted_mags = mags[order][key % max(n, 1)] if key.size else np.zeros(0)
        counts = (
            np.bincount(key // max(n, 1), minlength=n_att)
            if key.size
            else np.zeros(n_att, dtype=np.intp)
        )
        offsets = np.zeros(n_att + 1, dtype=np.intp)
        np.cumsum(counts, out=offsets[1:])
        return cls(offsets, np.ascontiguousarray(sorted_mags, dtype=np.float64), int(n))

    @property
    def n_pointings(self) -> int:
        """Number of pointings M."""
        return len(self.offsets) - 1

    def counts(self, max_mag: float = math.inf) -> NDArray[np.intp]:
        """Return the stars with magnitude ``<= max_mag`` in the field at each pointing, (M,)."""
        m = float(max_mag)
        if math.isnan(m):
            raise InputError("detection threshold m_t must not be NaN")
        if m == math.inf:
            return np.diff(self.offsets)
        point = np.repeat(np.arange(self.n_pointings), np.diff(self.offsets))
        return np.bincount(point[self.magnitudes <= m], minlength=self.n_pointings)

    def kth_magnitude(self, k: int) -> NDArray[np.float64]:
        """Return the magnitude of the ``k``-th brightest star in the field per pointing, (M,).

        ``inf`` where fewer than ``k`` stars are in the field.
        """
        k = check_int(k, "n_min", 1)
        start, stop = self.offsets[:-1], self.offsets[1:]
        has = (stop - start) >= k
        out = np.full(self.n_pointings, np.inf)
        out[has] = self.magnitudes[start[has] + k - 1]
        return out

    def _sorted_kth(self, n_min: int) -> NDArray[np.float64]:
        cached = self._kth_sorted.get(n_min)
        if cached is None:
            cached = np.sort(self.kth_magnitude(n_min))
            self._kth_sorted[n_min] = cached
        return cached

    def availability(self, max_mag: ArrayLike, n_min: int) -> float | NDArray[np.float64]:
        """Return the fraction of pointings with at least `n_min` stars ``<= max_mag``.

        Vectorised over `max_mag` (any shape; ``-inf`` gives 0): the empirical distribution
        function of the ``n_min``-th brightest magnitude in the field.
        """
        n_min = check_int(n_min, "n_min", 1)
        return _availability(self._sorted_kth(n_min), max_mag, self.n_pointings)

    def available(self, max_mag: ArrayLike, n_min: int) -> NDArray[np.bool_]:
        """Return per pointing whether at least `n_min` stars are ``<= max_mag``.

        Shape (M,), or (..., M) for an array of thresholds.
        """
        kth = self.kth_magnitude(n_min)
        return kth <= np.asarray(max_mag, dtype=np.float64)[..., None]

    def brightest(self, k: int) -> BrightestInField:
        """Return the `k` brightest magnitudes in the field at each pointing.

        See :class:`BrightestInField`: all that availability for N_min <= k needs, in a form
        that merges exactly over disjoint star sets.
        """
        k = check_int(k, "k", 1)
        mags = np.column_stack([self.kth_magnitude(j) for j in range(1, k + 1)])
        return BrightestInField(mags.reshape(self.n_pointings, k), self.n_stars)


@dataclass(frozen=True, eq=False)
class BrightestInField:
    """The ``K`` brightest magnitudes in the field at each of M pointings.

    Availability for any N_min <= K needs nothing else, and two of these built from disjoint
    star sets (tiles of a HATS catalogue, :mod:`starsense.scale`) merge exactly into the one
    of their union (:meth:`merge`).

    Attributes
    ----------
    magnitudes : ndarray, shape (M, K)
        Ascending along each row; ``inf`` where fewer than K stars are in the field.
    n_stars : int
        Stars of the star set(s) the field was built from.
    """

    magnitudes: NDArray[np.float64]
    n_stars: int

    @property
    def n_pointings(self) -> int:
        """Number of pointings M."""
        return self.magnitudes.shape[0]

    def kth_magnitude(self, k: int) -> NDArray[np.float64]:
        """Return the k-th brightest magnitude as :meth:`FieldStars.kth_magnitude`, k <= K."""
        k = check_int(k, "n_min", 1)
        if k > self.magnitudes.shape[1]:
            raise InputError(f"only the {self.magnitudes.shape[1]} brightest stars are kept; k={k}")
        return self.magnitudes[:, k - 1]

    def availability(self, max_mag: ArrayLike, n_min: int) -> float | NDArray[np.float64]:
        """Return the availability as :meth:`FieldStars.availability`, for N_min <= K."""
        return _availability(np.sort(self.kth_magnitude(n_min)), max_mag, self.n_pointings)

    @classmethod
    def merge(cls, parts: Sequence[BrightestInField]) -> BrightestInField:
        """Return the K brightest of the union of disjoint star sets, from each set's K."""
        if not parts:
            raise InputError("nothing to merge")
        k = parts[0].magnitudes.shape[1]
        mags = np.sort(np.concatenate([p.magnitudes for p in parts], axis=1), axis=1)[:, :k]
        return cls(np.ascontiguousarray(mags), int(sum(p.n_stars for p in parts)))


def catalog_stars(
    catalog: Any, max_mag: float, *, band: str = "V", allow_empty: bool = False
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return unit vectors and magnitudes of the catalogue stars with ``mag <= max_mag``.

    Works on a :class:`~starsense.catalog.Catalog` or anything with ``vectors`` (N, 3) and
    ``mags[band]`` (N,). Stars without a magnitude are dropped.

    Parameters
    ----------
    catalog : Catalog-like
        The stars.
    max_mag : float
        Magnitude limit in `band` (``+inf``: every star with a magnitude).
    band : str
        Magnitude band.
    allow_empty : bool
        Return empty arrays instead of raising when no star passes the cut (one tile of a
        catalogue that is processed tile by tile, :mod:`starsense.scale`).

    Returns
    -------
    vectors : ndarray, shape (N, 3)
        ICRS unit vectors.
    magnitudes : ndarray, shape (N,)
        Their magnitudes in `band`.

    Raises
    ------
    InputError
        If the band is missing or the cut leaves no star (the message gives the brightest
        magnitude present).
    """
    m = check_mag(max_mag, "max_mag", allow_inf=True)
    mags_all = getattr(catalog, "mags", {})
    name = getattr(catalog, "name", "catalogue")
    if band not in mags_all:
        raise InputError(
            f"catalogue {name!r} has no {band} magnitudes; bands: {', '.join(mags_all) or 'none'}"
        )
    mags = np.asarray(mags_all[band], dtype=np.float64)
    keep = mags <= m
    if not keep.any() and allow_empty:
        return np.zeros((0, 3)), np.zeros(0)
    if not keep.any():
        finite = mags[np.isfinite(mags)]
        brightest = f"{finite.min():.2f}" if finite.size else "none"
        raise InputError(
            f"magnitude limit max_mag {m:g} leaves no stars of catalogue {name!r} "
            f"(brightest {band} = {brightest}); raise max_mag"
        )
    vectors = np.asarray(catalog.vectors, dtype=np.float64)[keep]
    return vectors, mags[keep]
