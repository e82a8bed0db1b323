"""The identification database: thinned catalogue stars plus the pattern indices of the solvers.

A database is built once from a catalogue for a range of field sizes and a magnitude limit,
then cached on disk (:mod:`starsense.identify.cache`). It holds

* the *verification stars*: in every region of the sky (a cone of radius ``fov / 2`` around
  quasi-uniform lattice centres, :func:`~starsense.geometry.sampling.fibonacci_sphere`) the
  ``verification_stars_per_fov`` brightest stars, so that the faint end of the catalogue does
  not blow the database up where stars are dense (the thinning of tetra3's
  ``pattern_stars_per_fov`` / ``verification_stars_per_fov``);
* the *pattern stars*: the ``pattern_stars_per_fov`` brightest of each region;
* the 4-star *patterns* of :mod:`starsense.identify.hashing`: for each lattice centre, the
  4-combinations of its brightest pattern stars, with their five scale-invariant edge ratios,
  quantised into a sorted hash index (tetra3, Brown et al. 2023 / cedar-solve);
* the star *pairs* of :mod:`starsense.identify.triangle`: every pair of pattern stars closer than
  the field diagonal, sorted by angle.

The pattern machinery is in :mod:`starsense.identify.patterns`. When the field size is not
known, give ``min_fov_rad < max_fov_rad``: patterns are then built at a geometric series of
field sizes from the largest to the smallest (a multi-scale database, as tetra3 does), and a
solver recovers the scale from the match.
"""

from __future__ import annotations

import json
import logging
import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from starsense._validate import check_int, check_scalar
from starsense.catalog.table import Catalog
from starsense.errors import InputError
from starsense.identify.cache import (
    DATABASE_FORMAT_VERSION,
    database_cache_file,
    page_in,
    read_arrays,
    write_arrays,
)
from starsense.identify.lattice import (
    MAX_PAIRS,
    NOTICE_BUILD_S,
    PATTERN_BUDGET,
    estimated_build_s,
    expected_pairs,
    fov_text,
    lattice_pattern_count,
    pattern_lattice,
)
from starsense.identify.patterns import (
    field_sizes,
    hash_patterns,
    lattice_patterns,
    star_pairs,
    thin_by_region,
)
from starsense.identify.progress import BuildProgress
from starsense.units import DEG, RAD_TO_DEG

__all__ = [
    "DATABASE_FORMAT_VERSION",
    "PATTERN_BUDGET",
    "DatabaseParams",
    "IdentificationDatabase",
    "build_database",
    "database_cache_file",
    "estimated_build_s",
    "lattice_pattern_count",
    "pattern_lattice",
]

_log = logging.getLogger(__name__)


@dataclass(frozen=True)
class DatabaseParams:
    """Build parameters of an :class:`IdentificationDatabase` (all of them enter the cache key).

    Attributes
    ----------
    max_fov_rad : float
        Largest field of view (full width of the widest image axis), rad.
    min_fov_rad : float
        Smallest field of view, rad; equal to `max_fov_rad` when the field is known.
    mag_limit : float or None
        Faintest magnitude used, in `band`; None for the whole catalogue.
    band : str
        Magnitude band used for brightness order.
    pattern_stars_per_fov : int
        Pattern stars kept per field-sized region, and the stars per lattice field whose
        4-combinations become patterns. This depth, not the pattern tolerance, set the
        lost-in-space ceiling: when a detector misses 30 % of the stars and a third of the
        detections are false, the brightest 12 detections hold true stars down to rank ~15 of
        the field, and with 10 stars per field only ~98 % of such frames had one all-true
        4-subset in the database; 13 (1.6 M patterns at 15 deg, Hipparcos) solves all 2,001
        seeded frames of that benchmark (``bench/peers/compare.py``).
    verification_stars_per_fov : int
        Verification stars kept per field-sized region.
    lattice_oversampling : float
        Linear oversampling of the lattice of regions that thin the catalogue (pattern and
        verification stars): ``lattice_oversampling**2`` region centres per region area.
    field_oversampling : float
        Linear oversampling of the lattice of pattern fields: ``field_oversampling**2`` field
        centres per field area (a cone of radius ``fov / 2``). A 4-star subset of an image is in
        the database only if some field centre has all four among its brightest pattern stars,
        so a sparse lattice leaves holes: at 2 (4 centres per field area) about 1 in 700 random
        15 deg frames had no 4-subset of its 10 brightest stars in the database.
    n_bins : int
        Hash bins per edge ratio (ratios lie in (0, 1]).
    patterns_per_field : int or None
        Patterns kept per lattice field (breadth-first: those of the brightest stars first);
        None keeps all 4-combinations of the field's pattern stars. tetra3 keeps 50; a cap
        keeps a multi-scale database small.
    """

    max_fov_rad: float
    min_fov_rad: float
    mag_limit: float | None = None
    band: str = "V"
    pattern_stars_per_fov: int = 13
    verification_stars_per_fov: int = 40
    lattice_oversampling: float = 2.0
    field_oversampling: float = 4.0
    n_bins: int = 50
    patterns_per_field: int | None = None

    def __post_init__(self) -> None:
        for name in ("max_fov_rad", "min_fov_rad"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value)):
                raise InputError(f"{name} must be a finite number, got {value!r}")
            if not 0.1 * DEG <= value <= 100 * DEG:
                raise InputError(
                    f"{name} = {value} rad ({value * RAD_TO_DEG:.3g} deg) is out of range; "
                    "must be in [0.1, 100] deg"
                )
        if self.min_fov_rad > self.max_fov_rad:
            raise InputError(
                f"min_fov_rad ({self.min_fov_rad}) must not exceed max_fov_rad ({self.max_fov_rad})"
            )
        if self.mag_limit is not None and not math.isfinite(self.mag_limit):
            raise InputError(f"mag_limit must be finite or None, got {self.mag_limit!r}")
        check_int(self.pattern_stars_per_fov, "pattern_stars_per_fov", 4, 30)
        if self.verification_stars_per_fov < self.pattern_stars_per_fov:
            raise InputError(
                f"verification_stars_per_fov ({self.verification_stars_per_fov}) must be at "
                f"least pattern_stars_per_fov ({self.pattern_stars_per_fov})"
            )
        check_scalar(self.lattice_oversampling, "lattice_oversampling", 0.5, 8)
        check_scalar(self.field_oversampling, "field_oversampling", 0.5, 16)
        check_int(self.n_bins, "n_bins", 5, 1000)
        if self.patterns_per_field is not None:
            check_int(self.patterns_per_field, "patterns_per_field", 1)

    def to_json(self) -> str:
        """Return the parameters as JSON (sorted keys), as they enter the cache key."""
        return json.dumps(self.__dict__, sort_keys=True)


@dataclass(frozen=True, eq=False)
class IdentificationDatabase:
    """Stars and pattern indices for lost-in-space identification.

    Build it with :func:`build_database` (cached). Star indices used by the solvers index the
    arrays ``vectors``, ``ids`` and ``mags`` here (brightest first).

    Attributes
    ----------
    params : DatabaseParams
        How it was built.
    catalog_name : str
        Name of the source catalogue.
    vectors : ndarray, shape (M, 3)
        ICRS unit vectors of the kept (verification) stars, brightest first.
    ids : ndarray of int64, shape (M,)
        Their catalogue identifiers.
    mags : ndarray, shape (M,)
        Their magnitudes in ``params.band``.
    is_pattern_star : ndarray of bool, shape (M,)
        Whether a star is a pattern star (at any field size).
    patterns : ndarray of int32, shape (P, 4)
        Star indices of each 4-star pattern, in canonical order
        (:func:`order_by_centroid_distance`).
    pattern_ratios : ndarray of float32, shape (P, 5)
        Edge ratios of each pattern (:func:`edge_ratios`).
    pattern_largest_rad : ndarray of float32, shape (P,)
        Largest edge of each pattern, rad.
    pattern_keys : ndarray of int64, shape (P,)
        Hash key of each pattern; patterns are sorted by key.
    pairs : ndarray of int32, shape (Q, 2)
        Pattern-star pairs closer than the field diagonal, sorted by angle (empty for a
        multi-scale database: the triangle algorithm needs a known field).
    pair_angles_rad : ndarray, shape (Q,)
        Their separations, rad, ascending.
    """

    params: DatabaseParams
    catalog_name: str
    vectors: NDArray[np.float64]
    ids: NDArray[np.int64]
    mags: NDArray[np.float64]
    is_pattern_star: NDArray[np.bool_]
    patterns: NDArray[np.int32]
    pattern_ratios: NDArray[np.float32]
    pattern_largest_rad: NDArray[np.float32]
    pattern_keys: NDArray[np.int64]
    pairs: NDArray[np.int32]
    pair_angles_rad: NDArray[np.float64]
    build_time_s: float = 0.0
    _tree: cKDTree | None = field(default=None, repr=False)

    @property
    def tree(self) -> cKDTree:
        """k-d tree on :attr:`vectors` (chord distance), built on first use."""
        if self._tree is None:
            object.__setattr__(self, "_tree", cKDTree(self.vectors))
        return self._tree

    def page_in(self) -> None:
        """Read the tables mapped from the disk cache through (:func:`~.cache.page_in`)."""
        page_in([getattr(self, name) for name in self._ARRAYS])

    def __len__(self) -> int:
        return len(self.vectors)

    def __repr__(self) -> str:
        p = self.params
        return (
            f"IdentificationDatabase({self.catalog_name}, fov {p.min_fov_rad * RAD_TO_DEG:.3g}-"
            f"{p.max_fov_rad * RAD_TO_DEG:.3g} deg, {len(self)} stars, "
            f"{int(self.is_pattern_star.sum())} pattern stars, {len(self.patterns)} patterns, "
            f"{len(self.pairs)} pairs)"
        )

    # -- persistence ---------------------------------------------------------------------
    _ARRAYS = (
        "vectors",
        "ids",
        "mags",
        "is_pattern_star",
        "patterns",
        "pattern_ratios",
        "pattern_largest_rad",
        "pattern_keys",
        "pairs",
        "pair_angles_rad",
    )

    def save(self, path: str | Path, key: str = "") -> None:
        """Write to the directory ``path`` atomically (:func:`~.cache.write_arrays`).

        Parameters
        ----------
        path : str or Path
            The directory to write.
        key : str
            The cache key stored with it (:func:`database_cache_file`).
        """
        meta = {
            "key": key,
            "params": self.params.__dict__,
            "catalog_name": self.catalog_name,
            "build_time_s": self.build_time_s,
        }
        write_arrays(path, meta, {a: getattr(self, a) for a in self._ARRAYS})

    @classmethod
    def load(cls, path: str | Path, key: str | None = None) -> IdentificationDatabase | None:
        """Open a database written by :meth:`save` (memory-mapped); None if missing or stale.

        Parameters
        ----------
        path : str or Path
            The directory to open.
        key : str, optional
            The expected cache key; a file with another key is stale.

        Returns
        -------
        IdentificationDatabase or None
            The database, or None.
        """
        stored = read_arrays(path, cls._ARRAYS, key)
        if stored is None:
            return None
        meta, arrays = stored
        try:
            return cls(
                params=DatabaseParams(**meta["params"]),
                catalog_name=meta["catalog_name"],
                build_time_s=float(meta.get("build_time_s", 0.0)),
                **arrays,
            )
        except (ValueError, KeyError, TypeError) as exc:
            _log.info("ignoring unreadable identification database %s: %s", path, exc)
            return None


def build_database(
    catalog: Catalog,
    max_fov_rad: float,
    min_fov_rad: float | None = None,
    *,
    mag_limit: float | None = None,
    band: str = "V",
    pattern_stars_per_fov: int = 13,
    verification_stars_per_fov: int = 40,
    lattice_oversampling: float = 2.0,
    field_oversampling: float | None = None,
    n_bins: int = 50,
    patterns_per_field: int | Literal["all"] | None = None,
    cache: bool = True,
    cache_dir: str | Path | None = None,
) -> IdentificationDatabase:
    """Build (or load from the cache) the identification database of a catalogue.

    Parameters
    ----------
    catalog : Catalog
        Source catalogue, e.g. ``load_catalog("hipparcos")``.
    max_fov_rad : float
        Field of view (full width of the widest image axis), rad; the largest one when the
        field is not known.
    min_fov_rad : float, optional
        Smallest field of view, rad, when the field is not known (multi-scale database);
        default `max_fov_rad`.
    mag_limit : float, optional
        Faintest magnitude kept, in `band`.
    band : str
        Magnitude column used for brightness order (default ``"V"``).
    pattern_stars_per_fov, verification_stars_per_fov : int
        Brightest stars kept per field-sized region as pattern / verification stars.
    lattice_oversampling : float
        Linear oversampling of the lattice of thinning regions (``**2`` centres per area).
    field_oversampling : float, optional
        Linear oversampling of the lattice of pattern fields (``**2`` centres per field area).
        Default (with `patterns_per_field`): :func:`pattern_lattice`, 4 and every combination,
        or for fields whose database would exceed :data:`PATTERN_BUDGET` patterns (narrow
        fields, a few degrees), the sparse lattice of 2 and 35 patterns per field.
    n_bins : int
        Hash bins per edge ratio.
    patterns_per_field : int or "all", optional
        Patterns kept per lattice field, brightest stars first; "all" for every combination.
    cache : bool
        Reuse / write a memory-mapped copy (a directory of ``.npy`` files) under
        ``$STARSENSE_CACHE_DIR/identify`` (or the user cache directory).
    cache_dir : str or Path, optional
        Another cache directory.

    Returns
    -------
    IdentificationDatabase

    Raises
    ------
    InputError
        A parameter is out of range, or the catalogue lacks `band`.
    """
    params = DatabaseParams(  # validated here, then given its pattern lattice
        max_fov_rad=float(max_fov_rad),
        min_fov_rad=float(max_fov_rad if min_fov_rad is None else min_fov_rad),
        mag_limit=None if mag_limit is None else float(mag_limit),
        band=band,
        pattern_stars_per_fov=int(pattern_stars_per_fov),
        verification_stars_per_fov=int(verification_stars_per_fov),
        lattice_oversampling=float(lattice_oversampling),
        n_bins=int(n_bins),
    )
    lattice = pattern_lattice(
        params.max_fov_rad,
        params.min_fov_rad,
        params.pattern_stars_per_fov,
        field_oversampling=field_oversampling,
        patterns_per_field=patterns_per_field,
    )
    params = replace(params, field_oversampling=lattice[0], patterns_per_field=lattice[1])
    if band not in catalog.mags:
        raise InputError(
            f"catalogue {catalog.name!r} has no {band!r} magnitudes; "
            f"bands: {', '.join(catalog.mags)}"
        )
    if not cache:
        return _build(catalog, params)
    path, key = database_cache_file(catalog, params, cache_dir)
    db = IdentificationDatabase.load(path, key)
    if db is not None:
        return db
    expected_s = estimated_build_s(params, len(catalog))
    about = f"about {expected_s:.0f} s, " if expected_s >= NOTICE_BUILD_S else ""
    what = f"the {fov_text(params)} deg identification database ({about}once; cached in "
    with BuildProgress(f"{what}{path.parent})") as progress:  # on stderr after a second
        db = _build(catalog, params, step=progress.step)
        progress.step("writing it")
        try:
            db.save(path, key)
        except OSError as exc:
            _log.info("identification database not cached at %s: %s", path, exc)
    return db


def _build(catalog: Catalog, params: DatabaseParams, step=lambda _text: None):
    """Build the database of ``catalog`` (no cache); ``step(text)`` names each step."""
    t0 = time.perf_counter()
    step("choosing the stars")
    mags_all = np.asarray(catalog.mags[params.band], dtype=np.float64)
    usable = np.isfinite(mags_all)
    if params.mag_limit is not None:
        usable &= mags_all <= params.mag_limit
    idx = np.flatnonzero(usable)
    idx = idx[np.argsort(mags_all[idx], kind="stable")]  # brightest first
    vec_all = catalog.vectors[idx]
    mag_all = mags_all[idx]

    sizes = field_sizes(params.min_fov_rad, params.max_fov_rad)
    keep = thin_by_region(
        vec_all,
        mag_all,
        radius_rad=params.min_fov_rad / 2,
        n_per_region=params.verification_stars_per_fov,
        oversampling=params.lattice_oversampling,
    )
    pattern_masks = [
        thin_by_region(
            vec_all,
            mag_all,
            radius_rad=s / 2,
            n_per_region=params.pattern_stars_per_fov,
            oversampling=params.lattice_oversampling,
        )
        for s in sizes
    ]
    keep |= np.logical_or.reduce(pattern_masks)
    kept = np.flatnonzero(keep)  # still brightest first
    new_index = np.full(len(idx), -1, dtype=np.int64)
    new_index[kept] = np.arange(len(kept))
    vectors = vec_all[kept]
    is_pattern = np.logical_or.reduce(pattern_masks)[kept]

    # Patterns: per lattice field at each size, 4-combinations of its brightest pattern stars.
    step("the 4-star patterns")
    patterns = lattice_patterns(
        vectors,
        [new_index[np.flatnonzero(mask)] for mask in pattern_masks],
        sizes,
        stars_per_field=params.pattern_stars_per_fov,
        field_oversampling=params.field_oversampling,
        patterns_per_field=params.patterns_per_field,
    )
    step(f"hashing {len(patterns):,} patterns")
    patterns, ratios, largest, keys = hash_patterns(vectors, patterns, params.n_bins)

    # Pairs of pattern stars within the field diagonal (rectangular fields up to 4:3 -> 1.25).
    # Only for a known field: the triangle algorithm needs the absolute scale; and only when
    # they are few enough to keep (a 1.1 deg field on Gaia would make 16 M, 400 MB).
    pstars = np.flatnonzero(is_pattern)
    if len(sizes) > 1 or expected_pairs(len(pstars), params.max_fov_rad) > MAX_PAIRS:
        pstars = np.zeros(0, dtype=np.int64)
    pairs, angles = star_pairs(vectors, pstars, params.max_fov_rad)

    return IdentificationDatabase(
        params=params,
        catalog_name=catalog.name,
        vectors=vectors,
        ids=np.asarray(catalog.ids)[idx[kept]].astype(np.int64),
        mags=mag_all[kept],
        is_pattern_star=is_pattern,
        patterns=patterns.astype(np.int32),
        pattern_ratios=ratios.astype(np.float32),
        pattern_largest_rad=largest.astype(np.float32),
        pattern_keys=keys,
        pairs=pairs.astype(np.int32),
        pair_angles_rad=angles,
        build_time_s=time.perf_counter() - t0,
    )
