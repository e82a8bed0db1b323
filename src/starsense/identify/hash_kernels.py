"""The per-frame work of hashing identification, in two forms that give the same answers.

:func:`descriptors_numpy` (the patterns of a frame, a block at a time) with
:class:`~starsense.identify.hashing.HashIdentifier`'s look-up and
:class:`~starsense.identify.verify.Verifier` is the reference: NumPy, one pattern and one
hypothesis at a time. :class:`HashKernel` runs the same algorithm for a whole frame in the
compiled kernel ``_hashc`` (``_hashc.c``, built by setup.py as an optional extension): the
patterns of the brightest detections, their hash look-up and the verification of every
candidate, in one call. The acceptance decision stays in Python: the kernel calls back
:meth:`Verifier.accept <starsense.identify.verify.Verifier.accept>` with what it matched.

The canonical order of a pattern's stars and the look-up are equal bit for bit, the edge ratios
to a few ulp (NumPy may take ``arcsin`` from its own vectorised routine); the attitude of a
verification is Davenport's q method where the reference takes the SVD (the same rotation to
~1e-13 rad), so a solve, with the field known or its scale fitted, gives the same matches, the
same probability and the same attitude to rounding.
:class:`~starsense.identify.hashing.HashIdentifier` uses the kernel where it is built, else the
NumPy form (tests/identify/test_hash_kernel.py holds them equal).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator

import numpy as np
from numpy.typing import NDArray

from starsense.identify.database import IdentificationDatabase
from starsense.identify.patterns import edge_ratios, order_by_centroid_distance, pattern_edges

try:  # the compiled kernel (setup.py builds it where a C compiler exists)
    import starsense.identify._hashc as _hashc
except ImportError:  # pragma: no cover - exercised on machines without a compiler
    _hashc = None

__all__ = [
    "KERNEL_BUILT",
    "HashKernel",
    "descriptors_compiled",
    "descriptors_numpy",
    "key_directory",
    "pinhole_vectors_compiled",
    "star_grid",
    "unit_vectors_compiled",
]

#: whether the compiled kernel ``_hashc`` is importable
KERNEL_BUILT = _hashc is not None
#: cells per axis of :func:`star_grid` at most (its index holds ``grid**3 + 1`` int64)
_MAX_GRID = 64
#: buckets of :func:`key_directory` (512 KiB of int64)
_DIR_BUCKETS = 1 << 16


def descriptors_numpy(
    v: NDArray[np.float64], combos: NDArray[np.intp]
) -> Iterator[tuple[NDArray[np.intp], NDArray[np.float64], float]]:
    """Yield (stars in canonical order, edge ratios, largest edge) of the patterns `combos`.

    The patterns of `v` are computed a block at a time (most frames solve on one of the first
    few patterns); a pattern without a shape (a zero edge: a star listed twice) is skipped.

    Parameters
    ----------
    v : ndarray, shape (N, 3)
        Detection directions, unit vectors, brightest first.
    combos : ndarray of int, shape (C, 4)
        The patterns, rows of `v` (:func:`~starsense.identify.patterns.breadth_first_combinations`).

    Yields
    ------
    det : ndarray of int, shape (4,)
        The pattern's detections in canonical order
        (:func:`~starsense.identify.patterns.order_by_centroid_distance`).
    ratios : ndarray, shape (5,)
        Its edge ratios (:func:`~starsense.identify.patterns.edge_ratios`).
    largest : float
        Its largest edge, rad.
    """
    start = 0
    for stop in (1, 15, 70, len(combos)):
        block = combos[start:stop]
        start = max(start, stop)
        if len(block) == 0:
            continue
        pv = v[block]
        with np.errstate(divide="ignore", invalid="ignore"):
            dets = np.take_along_axis(block, order_by_centroid_distance(pv), axis=1)
            ratios, largest = edge_ratios(pattern_edges(pv))
        ok = (largest > 0) & np.isfinite(ratios).all(axis=1)
        yield from zip(dets[ok], ratios[ok], largest[ok].tolist(), strict=True)


def descriptors_compiled(
    v: NDArray[np.float64], n_pattern: int
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Describe every pattern of the first `n_pattern` detections in the compiled kernel.

    The kernel's form of :func:`descriptors_numpy`.

    Parameters
    ----------
    v : ndarray, shape (N, 3)
        Detection directions, unit vectors, brightest first.
    n_pattern : int
        Patterns are the 4-combinations of the first this many detections, breadth first.

    Returns
    -------
    det : ndarray of int64, shape (P, 4)
    ratios : ndarray, shape (P, 5)
    largest : ndarray, shape (P,)
        As :func:`descriptors_numpy` yields them, in the same order.
    """
    count, det, ratios, largest = _hashc.describe(np.ascontiguousarray(v, np.float64), n_pattern)
    return (
        np.frombuffer(det, np.int64).reshape(count, 4),
        np.frombuffer(ratios, np.float64).reshape(count, 5),
        np.frombuffer(largest, np.float64),
    )


def unit_vectors_compiled(vectors_cam: object) -> NDArray[np.float64] | None:
    """Return detection directions as unit vectors, or None if they need the full check.

    The kernel's form of :func:`~starsense.identify.result.validate_vectors` for the valid
    case (the same values bit for bit); None for anything else (not an (N, 3) array of
    numbers, a non-finite or zero vector, one behind the camera), for which the caller runs
    ``validate_vectors`` and raises its error.

    Parameters
    ----------
    vectors_cam : array_like, shape (N, 3)
        Directions in the camera frame.

    Returns
    -------
    ndarray, shape (N, 3), or None
    """
    if not isinstance(vectors_cam, np.ndarray) or vectors_cam.dtype != np.float64:
        return None
    if vectors_cam.ndim != 2 or vectors_cam.shape[1] != 3 or len(vectors_cam) == 0:
        return None
    v = np.ascontiguousarray(vectors_cam)
    out = np.empty_like(v)
    return out if _hashc.unit_vectors(v, out) else None


def pinhole_vectors_compiled(
    x: NDArray[np.float64], y: NDArray[np.float64], *, centre: tuple[float, float], f_px: float
) -> NDArray[np.float64] | None:
    """Return the unit vectors of pixel positions through a pinhole, or None if not computed.

    The kernel's form of :func:`~starsense.solve.pinhole.pinhole_vectors` (the same values bit
    for bit): the unit vectors of ``((x - cx) / f_px, (y - cy) / f_px, 1)``. None when the
    kernel is not built, the positions are not two 1-d float64 arrays of one length, or one is
    not finite: the caller then takes its NumPy form, which raises the error.

    Parameters
    ----------
    x, y : ndarray, shape (N,)
        Column and row of each position, pixels.
    centre : (float, float)
        Column and row of the principal point, pixels.
    f_px : float
        Focal length, pixels.

    Returns
    -------
    ndarray, shape (N, 3), or None
    """
    if _hashc is None or not (isinstance(x, np.ndarray) and isinstance(y, np.ndarray)):
        return None
    if x.dtype != np.float64 or y.dtype != np.float64 or x.ndim != 1 or x.shape != y.shape:
        return None
    out = np.empty((len(x), 3))
    ok = _hashc.pinhole(
        np.ascontiguousarray(x), np.ascontiguousarray(y), centre[0], centre[1], f_px, out
    )
    return out if ok else None


def key_directory(keys: NDArray[np.int64], n_keys: int) -> tuple[NDArray[np.int64], int]:
    """Index sorted hash keys by their leading part, so that a look-up reads a few cache lines.

    A binary search over millions of keys misses the cache at most of its ~20 steps; with the
    directory it searches only the keys of one bucket of :data:`_DIR_BUCKETS`.

    Parameters
    ----------
    keys : ndarray of int64, shape (P,)
        Hash keys, ascending, each in [0, `n_keys`).
    n_keys : int
        Number of possible keys (``n_bins**5``).

    Returns
    -------
    directory : ndarray of int64, shape (D + 1,)
        ``keys[directory[b]:directory[b + 1]]`` are the keys in ``[b, b + 1) * step``.
    step : int
        Keys per bucket.
    """
    step = max(1, -(-n_keys // _DIR_BUCKETS))
    n_dir = -(-n_keys // step)
    bounds = np.arange(n_dir + 1, dtype=np.int64) * step
    directory = np.searchsorted(keys, bounds, side="left").astype(np.int64)
    directory[-1] = len(keys)
    return directory, step


def star_grid(
    vectors: NDArray[np.float64], cell: float
) -> tuple[NDArray[np.int64], NDArray[np.int64], int, float]:
    """Index unit vectors by the cell of a cubic grid on [-1, 1]^3 (the kernel's cone search).

    Parameters
    ----------
    vectors : ndarray, shape (M, 3)
        Unit vectors.
    cell : float
        Wanted cell size (chord); at most :data:`_MAX_GRID` cells per axis.

    Returns
    -------
    cell_start : ndarray of int64, shape (grid**3 + 1,)
        Cell ``i`` holds ``cell_stars[cell_start[i]:cell_start[i + 1]]``.
    cell_stars : ndarray of int64, shape (M,)
        Indices into `vectors`, cell by cell.
    grid : int
        Cells per axis.
    cell : float
        The cell size used, ``2 / grid``.
    """
    grid = int(min(_MAX_GRID, max(1, math.ceil(2.0 / cell))))
    cell = 2.0 / grid
    ijk = np.clip(np.floor((vectors + 1.0) / cell).astype(np.int64), 0, grid - 1)
    flat = (ijk[:, 0] * grid + ijk[:, 1]) * grid + ijk[:, 2]
    order = np.argsort(flat, kind="stable").astype(np.int64)
    start = np.zeros(grid**3 + 1, dtype=np.int64)
    np.cumsum(np.bincount(flat, minlength=grid**3), out=start[1:])
    return start, order, grid, cell


class HashKernel:
    """A database's arrays held for the compiled kernel, and the kernel's calls.

    Parameters
    ----------
    database : IdentificationDatabase
    pattern_max_error : float
        Largest difference between a detected and a catalogue edge ratio.
    scale_tolerance : float
        Largest relative difference between the detected and catalogue size of a pattern.
    match_radius : float
        Verification match radius as a fraction of the field width.
    max_candidates : int
        Catalogue patterns verified per detection pattern (nearest ratios first).
    max_detections : int
        Detections used in verification.

    Raises
    ------
    RuntimeError
        The kernel is not built (:data:`KERNEL_BUILT` is False).
    """

    def __init__(
        self,
        database: IdentificationDatabase,
        *,
        pattern_max_error: float,
        scale_tolerance: float,
        match_radius: float,
        max_candidates: int,
        max_detections: int,
    ) -> None:
        if _hashc is None:
            raise RuntimeError("the compiled hashing kernel (_hashc) is not built")
        db = database
        # the cone of a verification reaches ~0.65 of the field from the boresight
        reach = min(math.pi / 2, 0.65 * db.params.max_fov_rad)
        start, stars, grid, cell = star_grid(db.vectors, 2.0 * math.sin(reach / 2.0))
        # the arrays stay referenced here while the kernel holds their buffers
        self._arrays = (
            np.ascontiguousarray(db.pattern_keys, np.int64),
            np.ascontiguousarray(db.pattern_ratios, np.float32),
            np.ascontiguousarray(db.pattern_largest_rad, np.float32),
            np.ascontiguousarray(db.patterns, np.int32),
            np.ascontiguousarray(db.vectors, np.float64),
            start,
            stars,
            np.ascontiguousarray(db.vectors[stars], np.float64),  # a cell's stars side by side
            *key_directory(db.pattern_keys, int(db.params.n_bins) ** 5),
        )
        self._tables = _hashc.tables(
            *self._arrays,
            grid,
            cell,
            int(db.params.n_bins),
            float(pattern_max_error),
            float(scale_tolerance),
            float(match_radius),
            int(max_candidates),
            int(max_detections),
        )

    def lookup(self, ratios: NDArray[np.float64]) -> NDArray[np.int64]:
        """Return the database patterns within the error of `ratios` (5,), nearest first."""
        return np.frombuffer(_hashc.lookup(self._tables, *map(float, ratios)), np.int64)

    def verify(
        self,
        v: NDArray[np.float64],
        det: NDArray[np.integer],
        cat: NDArray[np.integer],
        *,
        fov_rad: float | None,
        accept: Callable[..., tuple[float, bool]],
        scale: float = 1.0,
        scale_range: tuple[float, float] = (0.0, math.inf),
    ) -> tuple | None:
        """Verify one hypothesis (as :class:`~.verify.Verifier` does).

        Parameters
        ----------
        v : ndarray, shape (N, 3)
            Detection directions, unit vectors, brightest first.
        det, cat : array of int, shape (4,)
            The hypothesis: detection ``det[i]`` is database star ``cat[i]``.
        fov_rad : float or None
            Field width, rad; None: unknown, the scale is fitted.
        accept : callable
            The decision, ``accept(n, matched, n_hypothesis=, p_single=) -> (p_false, ok)``.
        scale : float
            With an unknown field: the first guess of the tangent-plane scale.
        scale_range : (float, float)
            With an unknown field: the accepted range of the fitted scale.

        Returns
        -------
        None or (rotation_matrix (3, 3), detection_index, catalog_index, rms_rad, p_false, scale)
        """
        out = _hashc.verify(
            self._tables,
            np.ascontiguousarray(v, np.float64),
            tuple(int(i) for i in det),
            tuple(int(i) for i in cat),
            0.0 if fov_rad is None else float(fov_rad),
            accept,
            float(scale),
            float(scale_range[0]),
            float(scale_range[1]),
        )
        if out is None:
            return None
        r, d, c, rms, p_false, scale = out
        return (
            np.asarray(r).reshape(3, 3),
            np.frombuffer(d, np.int64),
            np.frombuffer(c, np.int64),
            rms,
            p_false,
            scale,
        )

    def identify(
        self,
        v: NDArray[np.float64],
        *,
        n_pattern: int,
        fov_rad: float | None,
        accept: Callable[..., tuple[float, bool]],
        budget_s: float = math.inf,
        scale_range: tuple[float, float] = (0.0, math.inf),
        max_patterns: int | None = None,
    ) -> tuple:
        """Search and verify the patterns of one frame.

        Parameters
        ----------
        v : ndarray, shape (N, 3)
            Detection directions, unit vectors, brightest first (C-contiguous float64).
        n_pattern : int
            Patterns are made from the first this many detections.
        fov_rad : float or None
            Field width, rad; None: unknown, the scale of each hypothesis is fitted.
        accept : callable
            The decision (see :meth:`verify`).
        budget_s : float
            Give up (status 2) after this many seconds.
        scale_range : (float, float)
            With an unknown field: the accepted range of the fitted scale.
        max_patterns : int, optional
            Give up (status 2) once this many patterns have been looked up (None: no bound).

        Returns
        -------
        tuple
            ``(status, patterns tried, hypotheses verified, least P_false seen, rotation matrix
            (3, 3) or None, detection_index, catalog_index, rms_rad, p_false, scale)``; status
            0: no match, 1: solved, 2: out of time or of patterns.
        """
        status, tried, verified, best, r, d, c, rms, p_false, scale = _hashc.identify(
            self._tables,
            v,
            n_pattern,
            0.0 if fov_rad is None else fov_rad,
            accept,
            budget_s,
            *scale_range,
            -1 if max_patterns is None else int(max_patterns),
        )
        if status != 1:
            return status, tried, verified, best, None, None, None, rms, p_false, scale
        return (
            status,
            tried,
            verified,
            best,
            np.frombuffer(r, np.float64).reshape(3, 3),
            np.frombuffer(d, np.int64),
            np.frombuffer(c, np.int64),
            rms,
            p_false,
            scale,
        )
