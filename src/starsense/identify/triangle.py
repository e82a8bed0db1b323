"""Lost-in-space identification by star triangles (Liebe 1992; Cole & Crassidis 2006).

The three inter-star angles of a triangle of bright detections are matched against the
catalogue's star pairs (:attr:`IdentificationDatabase.pairs`, sorted by angle) within an
angular tolerance: pairs matching the first side and pairs matching the second side are joined
on their common star, the third side is checked directly, and the handedness of the triangle
(the sign of the triple product, which a rotation preserves) removes mirror images. Each
surviving catalogue triangle is verified (:class:`~starsense.identify.verify.Verifier`).

Unlike 4-star hashing this needs the absolute scale, i.e. a known field of view, and a
single-scale database; it works with as few as three stars, which is what a small field
(guide-star use) often gives.
"""

from __future__ import annotations

import math
import time

import numpy as np
from numpy.typing import NDArray

from starsense._validate import check_int, check_scalar
from starsense.errors import InputError
from starsense.identify.database import IdentificationDatabase
from starsense.identify.lattice import MAX_PAIRS
from starsense.identify.patterns import breadth_first_combinations, chord_angles
from starsense.identify.result import Identification, result_builder, validate_vectors
from starsense.identify.verify import Verifier

__all__ = ["TriangleIdentifier"]


class TriangleIdentifier:
    """Identify stars by matching triangles of inter-star angles.

    Parameters
    ----------
    database : IdentificationDatabase
        A single-scale database (``min_fov_rad == max_fov_rad``) with star pairs.
    tolerance_rad : float, optional
        Largest difference between a detected and a catalogue inter-star angle, rad; default
        0.2 % of the field width (about 2 pixels on a 1000-pixel detector).
    match_radius : float
        Verification match radius as a fraction of the field width.
    false_match_threshold : float
        Largest accepted probability of a false match.
    n_pattern_detections : int
        Triangles are made from the brightest this many detections.
    max_detections : int
        Detections used in verification.
    max_candidates_per_triangle : int
        Catalogue triangles verified per detected triangle (closest first).
    timeout_s : float or None
        Give up (status ``"timeout"``) after this wall time.
    """

    algorithm = "triangle"

    def __init__(
        self,
        database: IdentificationDatabase,
        *,
        tolerance_rad: float | None = None,
        match_radius: float = 0.01,
        false_match_threshold: float = 1e-9,
        n_pattern_detections: int = 8,
        max_detections: int = 60,
        max_candidates_per_triangle: int = 100,
        timeout_s: float | None = None,
    ) -> None:
        if not isinstance(database, IdentificationDatabase):
            raise InputError(f"database must be an IdentificationDatabase, got {database!r}")
        if len(database.pairs) == 0:
            raise InputError(
                "the database has no star pairs: the triangle algorithm needs a database built "
                "for one known field (min_fov_rad equal to max_fov_rad) with at most "
                f"{MAX_PAIRS:,} pairs (a narrow field on a deep catalogue has more: use hashing)"
            )
        if tolerance_rad is not None:
            check_scalar(tolerance_rad, "tolerance_rad", 0, 0.05, lo_open=True, hi_open=True)
        check_int(n_pattern_detections, "n_pattern_detections", 3, 30)
        if timeout_s is not None:
            check_scalar(timeout_s, "timeout_s", 0, None, lo_open=True, allow_inf=True)
        self.database = database
        self.tolerance_rad = tolerance_rad
        self.n_pattern_detections = int(n_pattern_detections)
        self.max_candidates_per_triangle = int(max_candidates_per_triangle)
        self.timeout_s = timeout_s
        self.verifier = Verifier(
            database,
            match_radius=match_radius,
            false_match_threshold=false_match_threshold,
            max_detections=max_detections,
        )
        self._combos = breadth_first_combinations(self.n_pattern_detections, 3)

    def _directed_pairs(self, angle: float, tol: float) -> NDArray[np.int64]:
        """Catalogue pairs (both orientations) whose angle is within `tol` of `angle`."""
        db = self.database
        lo = np.searchsorted(db.pair_angles_rad, angle - tol, side="left")
        hi = np.searchsorted(db.pair_angles_rad, angle + tol, side="right")
        p = db.pairs[lo:hi].astype(np.int64)
        return np.concatenate([p, p[:, ::-1]])

    def _candidates(
        self, tri: NDArray[np.float64], tol: float
    ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """Catalogue triangles (K, 3) matching the detected triangle ``tri`` (3, 3)."""
        db = self.database
        a01 = float(chord_angles(tri[0], tri[1]))
        a02 = float(chord_angles(tri[0], tri[2]))
        a12 = float(chord_angles(tri[1], tri[2]))
        p01 = self._directed_pairs(a01, tol)
        p02 = self._directed_pairs(a02, tol)
        if len(p01) == 0 or len(p02) == 0:
            return np.zeros((0, 3), dtype=np.int64), np.zeros(0)
        # join on the common first star
        p02 = p02[np.argsort(p02[:, 0], kind="stable")]
        left = np.searchsorted(p02[:, 0], p01[:, 0], side="left")
        right = np.searchsorted(p02[:, 0], p01[:, 0], side="right")
        counts = right - left
        if counts.sum() == 0:
            return np.zeros((0, 3), dtype=np.int64), np.zeros(0)
        rows = np.repeat(np.arange(len(p01)), counts)
        offsets = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
        third = p02[np.repeat(left, counts) + offsets, 1]
        cand = np.column_stack([p01[rows, 0], p01[rows, 1], third])
        cand = cand[cand[:, 1] != cand[:, 2]]
        vec = db.vectors
        d12 = np.abs(chord_angles(vec[cand[:, 1]], vec[cand[:, 2]]) - a12)
        cand, d12 = cand[d12 <= tol], d12[d12 <= tol]
        handed = np.sign(np.linalg.det(tri))
        dets = np.linalg.det(vec[cand])
        keep = np.sign(dets) == handed
        cand = cand[keep]
        err = (
            np.abs(chord_angles(vec[cand[:, 0]], vec[cand[:, 1]]) - a01)
            + np.abs(chord_angles(vec[cand[:, 0]], vec[cand[:, 2]]) - a02)
            + d12[keep]
        )
        order = np.argsort(err, kind="stable")
        return cand[order], err[order]

    def __call__(self, vectors_cam: object, fov_rad: float | None = None) -> Identification:
        """Identify the stars of one frame.

        Parameters
        ----------
        vectors_cam : array_like, shape (N, 3)
            Directions of the detections in the camera frame (+z boresight), brightest first.
        fov_rad : float, optional
            Field of view (full width of the widest image axis), rad; default the database's.
            The triangle algorithm needs it known: the vectors are taken as exact.

        Returns
        -------
        Identification

        Raises
        ------
        InputError
            Bad `vectors_cam` (shape, NaN, behind the camera) or `fov_rad`.
        """
        t0 = time.perf_counter()
        v = validate_vectors(vectors_cam)
        db = self.database
        if fov_rad is None:
            fov_rad = db.params.max_fov_rad
        fov_rad = float(fov_rad)
        if not (math.isfinite(fov_rad) and 0 < fov_rad <= 1.25 * db.params.max_fov_rad):
            raise InputError(
                f"fov_rad = {fov_rad} is outside (0, 1.25 x the database's "
                f"{db.params.max_fov_rad:.4g}] rad"
            )
        tol = self.tolerance_rad if self.tolerance_rad is not None else 0.002 * fov_rad
        n = len(v)

        result = result_builder(self.algorithm, n, t0)

        if n < 3:
            return result("too_few_stars", f"{n} detections; the triangle algorithm needs 3")
        n_pat = min(n, self.n_pattern_detections)
        combos = self._combos[(self._combos < n_pat).all(axis=1)]
        tried = verified = 0
        best = [1.0]  # the least false-match probability seen
        for combo in combos:
            if self.timeout_s is not None and time.perf_counter() - t0 > self.timeout_s:
                return result(
                    "timeout",
                    f"no match within {self.timeout_s} s ({tried} triangles tried)",
                    n_patterns_tried=tried,
                    n_candidates=verified,
                    best_false_match_probability=best[0],
                )
            tried += 1
            cand, _ = self._candidates(v[combo], tol)
            for cat in cand[: self.max_candidates_per_triangle]:
                verified += 1
                out = self.verifier(
                    v, combo.astype(np.int64), cat, field_width_rad=fov_rad, seen=best
                )
                if out is None:
                    continue
                return result(
                    "solved",
                    f"matched {len(out.detection_index)} of {n} detections",
                    rotation=out.rotation,
                    fov_rad=fov_rad,
                    detection_index=out.detection_index,
                    catalog_index=out.catalog_index,
                    catalog_id=db.ids[out.catalog_index],
                    residual_rms_rad=out.residual_rms_rad,
                    false_match_probability=out.false_match_probability,
                    n_patterns_tried=tried,
                    n_candidates=verified,
                    best_false_match_probability=out.false_match_probability,
                )
        return result(
            "no_match",
            f"none of {tried} triangles of the brightest {n_pat} detections matched the "
            f"catalogue with a false-match probability below "
            f"{self.verifier.false_match_threshold:g} ({verified} hypotheses verified)",
            n_patterns_tried=tried,
            n_candidates=verified,
            best_false_match_probability=best[0],
        )
