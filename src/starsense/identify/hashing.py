"""Lost-in-space identification by geometric hashing of 4-star patterns (tetra3 / cedar-solve).

For every 4-star pattern the six inter-star angles, sorted and divided by the largest, give
five ratios that do not depend on the plate scale (Brown, Stubis et al. 2023, "tetra3";
Arnas, Fialho & Mortari 2017 for the general idea). The database
(:mod:`starsense.identify.database`) quantises the ratios of catalogue patterns into integer
hash keys; at solve time the patterns of the brightest detections are looked up in breadth-first
order (patterns of the brightest stars first), each candidate is checked against the ratios
within ``pattern_max_error``, and the survivors are verified
(:class:`~starsense.identify.verify.Verifier`) until one passes the false-match test.

Because the ratios are scale-invariant, the field of view need not be known: with
``fov_rad=None`` the scale comes out of the match (the database must then cover a range of
field sizes, ``build_database(cat, max_fov_rad, min_fov_rad)``).
"""

from __future__ import annotations

import itertools
import math
import time
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from starsense._validate import check_int, check_scalar
from starsense.errors import InputError
from starsense.geometry.projection import vectors_to_tangent
from starsense.identify.database import IdentificationDatabase
from starsense.identify.hash_kernels import (
    KERNEL_BUILT,
    HashKernel,
    descriptors_numpy,
    unit_vectors_compiled,
)
from starsense.identify.patterns import breadth_first_combinations, hash_keys
from starsense.identify.result import Identification, result_builder, validate_vectors
from starsense.identify.verify import Verifier
from starsense.units import RAD_TO_DEG

__all__ = ["MIN_SOLVING_STARS", "PATTERN_STARS", "HashIdentifier"]

_NO_CANDIDATES = np.zeros(0, dtype=np.int64)
#: the stars of a pattern: a hypothesis pairs this many detections with catalogue stars, and
#: only matches beyond them are evidence (:func:`starsense.identify.verify.
#: false_match_probability` is 1 without one), so lost in space needs at least one more
PATTERN_STARS = 4
#: the fewest detections an identification can be accepted from (the availability's N_min)
MIN_SOLVING_STARS = PATTERN_STARS + 1


class _Search(NamedTuple):
    """What the search of one frame found (either form)."""

    status: str  # "solved", "no_match" or "timeout"
    tried: int
    verified: int
    best: float
    found: object = None  # the accepted verification (rotation, scale, indices, rms, p_false)


class _Found(NamedTuple):
    rotation: object  # a Rotation or its matrix
    scale: float
    detection_index: NDArray[np.int64]
    catalog_index: NDArray[np.int64]
    residual_rms_rad: float
    false_match_probability: float


class HashIdentifier:
    """Identify stars by 4-star geometric hashing.

    Parameters
    ----------
    database : IdentificationDatabase
        From :func:`~starsense.identify.database.build_database`.
    pattern_max_error : float
        Largest difference between a detected and a catalogue edge ratio (dimensionless).
    match_radius : float
        Verification match radius as a fraction of the field width (0.01 as tetra3).
    false_match_threshold : float
        Largest accepted probability of a false match.
    n_pattern_detections : int
        Patterns are made from the brightest this many detections (12: with a third of them
        false, 10 left some frames with fewer than 4 true stars to make a pattern of).
    max_detections : int
        Detections used in verification.
    scale_tolerance : float
        With a known field: largest relative difference between the detected and catalogue
        size of a pattern.
    max_candidates_per_pattern : int
        Catalogue patterns verified per detection pattern (nearest ratios first).
    timeout_s : float or None
        Give up (status ``"timeout"``) after this wall time.
    compiled : bool
        Search and verify in the compiled kernel
        (:class:`~starsense.identify.hash_kernels.HashKernel`) where it is built: the same
        answers ~10x faster. False: always the NumPy form.
    """

    algorithm = "hashing"

    def __init__(
        self,
        database: IdentificationDatabase,
        *,
        pattern_max_error: float = 0.005,
        match_radius: float = 0.01,
        false_match_threshold: float = 1e-9,
        n_pattern_detections: int = 12,
        max_detections: int = 60,
        scale_tolerance: float = 0.02,
        max_candidates_per_pattern: int = 50,
        timeout_s: float | None = None,
        compiled: bool = True,
    ) -> None:
        if not isinstance(database, IdentificationDatabase):
            raise InputError(f"database must be an IdentificationDatabase, got {database!r}")
        if len(database.patterns) == 0:
            raise InputError("the database holds no 4-star patterns")
        check_scalar(pattern_max_error, "pattern_max_error", 0, 0.1, lo_open=True, hi_open=True)
        check_int(n_pattern_detections, "n_pattern_detections", 4, 30)
        check_scalar(scale_tolerance, "scale_tolerance", 0, 0.5, lo_open=True, hi_open=True)
        if timeout_s is not None:
            check_scalar(timeout_s, "timeout_s", 0, None, lo_open=True, allow_inf=True)
        self.database = database
        self.pattern_max_error = float(pattern_max_error)
        self.n_pattern_detections = int(n_pattern_detections)
        self.scale_tolerance = float(scale_tolerance)
        self.max_candidates_per_pattern = int(max_candidates_per_pattern)
        self.timeout_s = timeout_s
        self.verifier = Verifier(
            database,
            match_radius=match_radius,
            false_match_threshold=false_match_threshold,
            max_detections=max_detections,
        )
        self._combos = breadth_first_combinations(self.n_pattern_detections, 4)
        nb = database.params.n_bins
        self._key_weights = nb ** np.arange(5, dtype=np.int64)
        # The 32 corners of a box of bins one bin wide in each ratio: when 2 x the pattern
        # error is below a bin (the default), a detected pattern's box has at most 2 bins per
        # ratio and these offsets enumerate its keys without itertools.
        self._corners = np.array(list(itertools.product((0, 1), repeat=5)), dtype=np.int64)
        self._corner_keys = self._corners @ self._key_weights
        self._kernel = None
        if compiled and KERNEL_BUILT and self.verifier.max_detections >= self.n_pattern_detections:
            self._kernel = HashKernel(
                database,
                pattern_max_error=self.pattern_max_error,
                scale_tolerance=self.scale_tolerance,
                match_radius=self.verifier.match_radius,
                max_candidates=self.max_candidates_per_pattern,
                max_detections=self.verifier.max_detections,
            )

    @property
    def compiled(self) -> bool:
        """Whether frames are searched by the compiled kernel."""
        return self._kernel is not None

    def _lookup(self, ratios: NDArray[np.float64]) -> NDArray[np.int64]:
        """Return the database patterns whose hash bins overlap ``ratios +- pattern_max_error``.

        Nearest ratios first; those farther than the error are dropped.
        """
        db = self.database
        nb = db.params.n_bins
        err = self.pattern_max_error
        lo = np.minimum(np.maximum((ratios - err) * nb, 0.0), nb - 1).astype(np.int64)
        hi = np.minimum(np.maximum((ratios + err) * nb, 0.0), nb - 1).astype(np.int64)
        span = hi - lo
        if span.max() <= 1:
            # the corners that step only along ratios spanning two bins: distinct keys
            corners = self._corners @ (span == 0) == 0
            keys = int(lo @ self._key_weights) + self._corner_keys[corners]
        else:
            ranges = [range(a, b + 1) for a, b in zip(lo.tolist(), hi.tolist(), strict=True)]
            bins = np.array(list(itertools.product(*ranges)), dtype=np.int64)
            keys = hash_keys(bins, nb)
        left = np.searchsorted(db.pattern_keys, keys, side="left")
        right = np.searchsorted(db.pattern_keys, keys, side="right")
        hit = right > left
        if not hit.any():
            return _NO_CANDIDATES
        left, right = left[hit], right[hit]
        if len(left) == 1:
            cand = np.arange(left[0], right[0])
        else:
            cand = np.concatenate(
                [np.arange(a, b) for a, b in zip(left.tolist(), right.tolist(), strict=True)]
            )
        diff = np.abs(db.pattern_ratios[cand] - ratios).max(axis=1)
        ok = diff <= err
        if not ok.any():
            return _NO_CANDIDATES
        cand, diff = cand[ok], diff[ok]
        return cand if len(cand) == 1 else cand[np.argsort(diff, kind="stable")]

    def _check_fov(self, fov_rad: float) -> float:
        """Return `fov_rad` as a float if the database covers it, else raise InputError."""
        p = self.database.params
        fov_rad = float(fov_rad)
        if not (math.isfinite(fov_rad) and 0.75 * p.min_fov_rad <= fov_rad <= 1.25 * p.max_fov_rad):
            raise InputError(
                f"fov_rad = {fov_rad} ({fov_rad * RAD_TO_DEG:.3g} deg) is outside the "
                f"database's range {p.min_fov_rad * RAD_TO_DEG:.3g}-"
                f"{p.max_fov_rad * RAD_TO_DEG:.3g} deg"
            )
        return fov_rad

    def __call__(
        self,
        vectors_cam: object,
        fov_rad: float | None = None,
        *,
        assumed_fov_rad: float | None = None,
        max_patterns: int | None = None,
    ) -> Identification:
        """Identify the stars of one frame.

        Parameters
        ----------
        vectors_cam : array_like, shape (N, 3)
            Directions of the detections in the camera frame (+z boresight), brightest first,
            e.g. ``sensor.unproject(det.x, det.y)``.
        fov_rad : float, optional
            Field of view (full width of the widest image axis), rad, when it is known; the
            vectors are then taken as exact. None: the field is unknown and the scale of the
            vectors is fitted (the vectors may have been computed with any roughly right focal
            length).
        assumed_fov_rad : float, optional
            With ``fov_rad=None``: the field width at which `vectors_cam` were computed, so that
            the result can report the field found (``fov_rad``).
        max_patterns : int, optional
            A work budget: give up (status ``"timeout"``) once this many detection patterns
            have been looked up, in the breadth-first order (brightest first), so that the
            answer does not depend on the machine (as tetra3's ``max_patterns_checked``).
            None: every pattern of the brightest ``n_pattern_detections``.

        Returns
        -------
        Identification

        Raises
        ------
        InputError
            `vectors_cam` is not an (N, 3) array of finite, non-zero vectors in front of the
            camera, or `fov_rad` is outside what the database was built for.
        """
        t0 = time.perf_counter()
        v = None if self._kernel is None else unit_vectors_compiled(vectors_cam)
        if v is None:
            v = validate_vectors(vectors_cam)
        db = self.database
        known = fov_rad is not None
        if known:
            fov_rad = self._check_fov(fov_rad)
        if assumed_fov_rad is not None and not (
            math.isfinite(assumed_fov_rad) and 0 < assumed_fov_rad < math.pi
        ):
            raise InputError(f"assumed_fov_rad = {assumed_fov_rad} must be in (0, pi)")
        n = len(v)

        result = result_builder(self.algorithm, n, t0)

        if n < PATTERN_STARS:
            return result(
                "too_few_stars",
                f"{n} detections; the {PATTERN_STARS}-star hashing needs at least {PATTERN_STARS}",
            )

        n_pat = min(n, self.n_pattern_detections)
        if max_patterns is not None and not (type(max_patterns) is int and max_patterns >= 0):
            max_patterns = check_int(max_patterns, "max_patterns", 0)
        if self._kernel is not None:
            search = self._search_compiled(v, n_pat, fov_rad, t0, max_patterns)
        else:
            search = self._search_numpy(v, n_pat, fov_rad, t0, max_patterns)
        if search.status == "timeout":
            spent = max_patterns is not None and search.tried >= max_patterns
            within = f"{max_patterns} patterns (the budget)" if spent else f"{self.timeout_s} s"
            return result(
                "timeout",
                f"no match within {within} ({search.tried} patterns tried)",
                n_patterns_tried=search.tried,
                n_candidates=search.verified,
                best_false_match_probability=search.best,
            )
        if search.status == "no_match":
            return result(
                "no_match",
                f"none of {search.tried} patterns of the brightest {n_pat} detections matched "
                f"the catalogue with a false-match probability below "
                f"{self.verifier.false_match_threshold:g} ({search.verified} hypotheses "
                f"verified)",
                n_patterns_tried=search.tried,
                n_candidates=search.verified,
                best_false_match_probability=search.best,
            )
        out = search.found
        fov_out = fov_rad
        if not known and assumed_fov_rad is not None:
            fov_out = 2.0 * math.atan(out.scale * math.tan(assumed_fov_rad / 2.0))
        return result(
            "solved",
            f"matched {len(out.detection_index)} of {n} detections",
            rotation=out.rotation,
            fov_rad=fov_out,
            scale=out.scale,
            detection_index=out.detection_index,
            catalog_index=out.catalog_index,
            catalog_id=db.ids[out.catalog_index],
            residual_rms_rad=out.residual_rms_rad,
            false_match_probability=out.false_match_probability,
            n_patterns_tried=search.tried,
            n_candidates=search.verified,
            best_false_match_probability=out.false_match_probability,
        )

    def _scale_range(self, v: NDArray[np.float64]) -> tuple[float, float]:
        """With an unknown field: the scales the largest pattern in the image allows."""
        p = self.database.params
        max_off = float(np.arccos(v[:, 2].min()))
        return (
            0.5 * p.min_fov_rad / (2 * max_off + 1e-12),
            4.0 * p.max_fov_rad / (2 * max_off + 1e-12),
        )

    def _search_compiled(
        self,
        v: NDArray[np.float64],
        n_pat: int,
        fov_rad: float | None,
        t0: float,
        max_patterns: int | None = None,
    ) -> _Search:
        """Search and verify in the compiled kernel."""
        budget = math.inf
        if self.timeout_s is not None:
            budget = self.timeout_s - (time.perf_counter() - t0)
        status, tried, verified, best, r, det, cat, rms, p_false, scale = self._kernel.identify(
            v,
            n_pattern=n_pat,
            fov_rad=fov_rad,
            accept=self.verifier.accept,
            budget_s=budget,
            scale_range=(0.0, math.inf) if fov_rad is not None else self._scale_range(v),
            max_patterns=max_patterns,
        )
        if status != 1:
            return _Search("timeout" if status == 2 else "no_match", tried, verified, best)
        # the matrix: Identification builds the Rotation when it is first read
        found = _Found(r, scale, det, cat, rms, p_false)
        return _Search("solved", tried, verified, best, found)

    def _search_numpy(
        self,
        v: NDArray[np.float64],
        n_pat: int,
        fov_rad: float | None,
        t0: float,
        max_patterns: int | None = None,
    ) -> _Search:
        """Search and verify pattern by pattern in NumPy (the reference form)."""
        db = self.database
        known = fov_rad is not None
        combos = self._combos[(self._combos < n_pat).all(axis=1)]
        tried = 0
        verified = 0
        best = [1.0]  # the least false-match probability seen
        # The largest pattern in the image tells the scale; its bounds for an unknown field.
        scale_range = (0.0, math.inf) if known else self._scale_range(v)
        tangent = vectors_to_tangent(v[: self.verifier.max_detections])
        keep = self.max_candidates_per_pattern
        for det, ratios, largest in descriptors_numpy(v, combos):
            if self.timeout_s is not None and time.perf_counter() - t0 > self.timeout_s:
                return _Search("timeout", tried, verified, best[0])
            if max_patterns is not None and tried >= max_patterns:
                return _Search("timeout", tried, verified, best[0])
            tried += 1
            cand = self._lookup(ratios)
            if len(cand) == 0:
                continue
            scales = db.pattern_largest_rad[cand].astype(np.float64) / largest
            if known:
                cand = cand[np.abs(scales - 1.0) <= self.scale_tolerance]
                scales = np.ones(len(cand))
            for c, s in zip(cand[:keep].tolist(), scales[:keep].tolist(), strict=True):
                verified += 1
                out = self.verifier(
                    v,
                    det,
                    db.patterns[c].astype(np.int64),
                    scale=s,
                    fit_scale=not known,
                    field_width_rad=fov_rad,
                    scale_range=scale_range,
                    tangent=tangent,
                    seen=best,
                )
                if out is not None:
                    return _Search("solved", tried, verified, best[0], out)
        return _Search("no_match", tried, verified, best[0])
