"""Tracking-mode identification: match detections to the stars a prior attitude predicts.

Given a prior attitude (from the last frame, propagated by the rate) and a search radius that
covers its uncertainty, :class:`TrackingIdentifier`

1. predicts the camera directions of the database stars in the field
   (``scipy.spatial.cKDTree`` cone query on the ICRS unit vectors, chord distance);
2. pairs every detection with its nearest predicted star within the search radius (the two
   nearest predicted directions by chord distance, compared directly: a few dozen stars), and
   drops a pair as **ambiguous** when a second predicted star is nearly as close
   (``d2 < ambiguity_ratio * d1``) or when two detections claim the same star;
3. fits the attitude to the pairs (SVD / Kabsch, as the lost-in-space verifier), checks that it
   moves no star by more than the search radius from the prior (an innovation test), and pairs
   again at a radius matched to the residuals (5 robust sigma, at least
   ``min_match_radius_rad``), up to three times;
4. computes the probability that the matches beyond the two that fix the attitude are chance,
   with the verifier's binomial test (:func:`~starsense.identify.verify.false_match_probability`,
   tetra3 / Mortari et al. 2004): ``p = (predicted stars in the searched region) x pi r^2 /
   (solid angle of the searched region)``, ``P_false = P[X >= n - 2], X ~ B(N - 2, p)``.

Two pairs determine the attitude (status ``"unverified"``: nothing is left to test it with);
three or more with ``P_false`` at most the threshold make it ``"verified"``. Fewer than two
pairs give ``"too_few_stars"`` (or ``"ambiguous"`` when pairs were dropped as ambiguous), a fit
outside the prior's reach ``"no_match"``: the caller then falls back to lost-in-space.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Literal, TypeAlias, get_args

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from starsense._validate import check_scalar
from starsense.attitude.svd import wahba_matrix
from starsense.detect.clip import MAD_TO_SIGMA
from starsense.identify.database import IdentificationDatabase
from starsense.identify.result import validate_vectors
from starsense.identify.track_kernels import (
    fit_compiled,
    match_compiled,
    pair_compiled,
    pair_numpy,
)
from starsense.identify.verify import false_match_probability

__all__ = ["TRACKING_STATUSES", "TrackingIdentifier", "TrackingMatch", "TrackingStatus"]

#: Possible values of :attr:`TrackingMatch.status`.
TrackingStatus: TypeAlias = Literal[
    "verified", "unverified", "too_few_stars", "ambiguous", "no_match"
]
TRACKING_STATUSES = get_args(TrackingStatus)

_EMPTY_INT = np.zeros(0, dtype=np.int64)
#: the residuals' sigma from their median: MAD_TO_SIGMA x median / sqrt(2 ln 2) (the median of
#: a 2-D Gaussian's radius is sigma sqrt(2 ln 2))
_MAD_SCALE = (MAD_TO_SIGMA, math.sqrt(2 * math.log(2)))


def _fit(body: np.ndarray, ref: np.ndarray):
    """Attitude matrix and residual angles of the pairs: equal weights, two pairs by TRIAD.

    :func:`~starsense.attitude.svd.wahba_matrix`, or the same fit in the compiled kernel
    (:func:`~starsense.identify.track_kernels.fit_compiled`, equal to rounding).
    """
    got = fit_compiled(body, ref, np.ones(len(body)), two_exact=True)
    return wahba_matrix(body, ref, two_exact=True)[:2] if got is None else got[:2]


def _chord(angle_rad: float) -> float:
    return 2.0 * math.sin(min(angle_rad, math.pi) / 2.0)


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    """``np.array_equal`` of two 1-D integer arrays, without its overheads."""
    return len(a) == len(b) and bool((a == b).all())


def _median(values: np.ndarray) -> float:
    """``np.median`` of a 1-D array (the middle value, or the mean of the middle two)."""
    s = np.sort(values)
    h = len(s) // 2
    return float(s[h]) if len(s) % 2 else float((s[h - 1] + s[h]) / 2)


def _rotvec(m: np.ndarray) -> np.ndarray:
    """Rotation vector of a rotation matrix of angle below pi, rad (shape (3,)).

    ``sin(angle) axis`` is the antisymmetric part of ``m``, ``cos(angle) = (tr m - 1) / 2``;
    the angle from both (atan2) is accurate from 0 to near pi.
    """
    s = 0.5 * np.array([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]])
    sin = math.sqrt(float(s @ s))
    angle = math.atan2(sin, 0.5 * (m[0, 0] + m[1, 1] + m[2, 2] - 1.0))
    return s * (angle / sin) if sin > 0 else np.zeros(3)


@dataclass(frozen=True, eq=False)
class TrackingMatch:
    """The answer of :class:`TrackingIdentifier`.

    Attributes
    ----------
    status : TrackingStatus
        One of :data:`TRACKING_STATUSES`.
    rotation : Rotation or None
        Fitted attitude (ICRS -> camera) for "verified" and "unverified" (built on access
        from ``rotation_matrix``).
    rotation_matrix : ndarray, shape (3, 3), or None
        The same attitude as a matrix.
    detection_index, catalog_index : ndarray of int, shape (M,)
        Matched detections and their database stars (indices into ``database.vectors``).
    catalog_id : ndarray of int64, shape (M,)
        Catalogue identifiers of the matched stars.
    residual_rms_rad : float
        Rms angle between matched detections and their stars after the fit, rad.
    false_match_probability : float
        Probability that the matches beyond the two that fix the attitude are chance.
    n_detections, n_predicted, n_ambiguous : int
        Detections given, database stars predicted in the field, pairs dropped as ambiguous.
    innovation_rad : float
        How far the fit moved a star at the field edge from where the prior put it, rad
        (cross-boresight angle plus roll angle x sin(field radius)).
    time_ms : float
    message : str
    """

    status: TrackingStatus
    rotation_matrix: NDArray[np.float64] | None = field(default=None, repr=False)
    detection_index: NDArray[np.int64] = field(default_factory=lambda: _EMPTY_INT)
    catalog_index: NDArray[np.int64] = field(default_factory=lambda: _EMPTY_INT)
    catalog_id: NDArray[np.int64] = field(default_factory=lambda: _EMPTY_INT)
    residual_rms_rad: float = math.nan
    false_match_probability: float = 1.0
    n_detections: int = 0
    n_predicted: int = 0
    n_ambiguous: int = 0
    innovation_rad: float = math.nan
    time_ms: float = 0.0
    message: str = ""

    @property
    def rotation(self) -> Rotation | None:
        """Fitted attitude (ICRS -> camera), or None."""
        if self.rotation_matrix is None:
            return None
        # orthogonal to rounding (an SVD's U V^T): scipy's re-normalisation is not needed
        return Rotation.from_matrix(self.rotation_matrix, assume_valid=True)

    @property
    def solved(self) -> bool:
        """Whether an attitude was found ("verified" or "unverified")."""
        return self.status in ("verified", "unverified")

    @property
    def n_matches(self) -> int:
        """Matched detections."""
        return len(self.detection_index)


class TrackingIdentifier:
    """Configure with a database, then call with detections and a prior (module docstring).

    Parameters
    ----------
    database : IdentificationDatabase
    ambiguity_ratio : float
        A pair is ambiguous when a second predicted star lies within ``ambiguity_ratio`` times
        the nearest one's distance (and within the search radius); > 1.
    false_match_threshold : float
        Largest ``P_false`` of a verified match. Default 1e-3: the prior already confines the
        answer to the search radius, which the lost-in-space default (1e-9) does not have.
    min_match_radius_rad : float
        Smallest radius of the final pairing, rad (e.g. a few centroid sigmas).
    """

    def __init__(
        self,
        database: IdentificationDatabase,
        *,
        ambiguity_ratio: float = 3.0,
        false_match_threshold: float = 1e-3,
        min_match_radius_rad: float = 1e-5,
    ) -> None:
        self.database = database
        self.ambiguity_ratio = check_scalar(ambiguity_ratio, "ambiguity_ratio", 1.0, lo_open=True)
        self.false_match_threshold = check_scalar(
            false_match_threshold, "false_match_threshold", 0.0, 1.0, lo_open=True
        )
        self.min_match_radius_rad = check_scalar(
            min_match_radius_rad, "min_match_radius_rad", 0.0, 0.1, lo_open=True
        )

    def _pair(self, vectors, cam, radius):
        """Nearest predicted star of each detection within ``radius``; ambiguous ones dropped.

        :func:`~starsense.identify.track_kernels.pair_numpy` (compiled where built). Returns
        (detection index, predicted index, number dropped as ambiguous).
        """
        bound2 = _chord(radius) ** 2
        got = pair_compiled(vectors, cam, bound2=bound2, ratio=self.ambiguity_ratio)
        return (
            pair_numpy(vectors, cam, bound2=bound2, ratio=self.ambiguity_ratio)
            if got is None
            else got
        )

    def _match(self, v, ref, prior_matrix, r_s):
        """Pair, fit, pair again at the residuals' radius (module docstring, step 3).

        Returns (det, star, n_ambiguous, attitude matrix, residuals, radius); the matrix and
        residuals None with fewer than two pairs. In the compiled kernel where it is built
        (:func:`~starsense.identify.track_kernels.match_compiled`), else step by step.
        """
        got = match_compiled(
            v,
            ref,
            prior_matrix,
            radius=r_s,
            min_radius=self.min_match_radius_rad,
            ratio=self.ambiguity_ratio,
            mad_scale=_MAD_SCALE,
        )
        if got is not None:
            return got
        det, star, n_amb = self._pair(v, ref @ prior_matrix.T, r_s)
        if len(det) < 2:
            return det, star, n_amb, None, None, r_s
        radius = r_s
        fitted = False  # whether r, resid are the fit to the pairs (det, star)
        for _ in range(3):
            r, resid = _fit(v[det], ref[star])
            fitted = True
            sigma = _MAD_SCALE[0] * _median(resid) / _MAD_SCALE[1]
            radius = min(radius, max(5.0 * sigma, self.min_match_radius_rad))
            det_new, star_new, n_amb = self._pair(v, ref @ r.T, radius)
            if len(det_new) < 2:
                break
            fitted = _same(det_new, det) and _same(star_new, star)
            det, star = det_new, star_new
            if fitted:
                break
        if not fitted:
            r, resid = _fit(v[det], ref[star])
        return det, star, n_amb, r, resid, radius

    def __call__(
        self,
        vectors_cam,
        prior: Rotation,
        *,
        search_radius_rad: float,
        field_radius_rad: float,
        region: tuple[float, int] | None = None,
        candidates=None,
    ) -> TrackingMatch:
        """Match detections to the stars predicted by ``prior``.

        Parameters
        ----------
        vectors_cam : array_like, shape (N, 3)
            Detection directions in the camera frame (unit, z > 0), brightest first.
        prior : Rotation
            Predicted attitude, ICRS -> camera.
        search_radius_rad : float
            How far a star may be from its predicted position, rad (the prior's uncertainty
            at the field edge, a few sigma).
        field_radius_rad : float
            Angle from the boresight to the farthest detection, rad (the cone of stars
            predicted is this plus the search radius).
        region : (float, int), optional
            Solid angle the detections were searched in, sr, and the predicted stars in it (the
            detection windows); default the cone of the field and every star predicted in it.
        candidates : array_like of int, optional
            The database stars to predict (e.g. the brightest on the detector: a frame that
            shows few stars shows the brightest, and fewer candidates leave fewer ambiguous
            pairs); default every database star in the cone.

        Returns
        -------
        TrackingMatch
        """
        t0 = time.perf_counter()
        v = validate_vectors(vectors_cam)
        r_s = check_scalar(search_radius_rad, "search_radius_rad", 0.0, 0.5, lo_open=True)
        field_r = check_scalar(field_radius_rad, "field_radius_rad", 0.0, math.pi / 2)
        if candidates is not None:
            candidates = np.asarray(candidates, dtype=np.int64).reshape(-1)
        return self.match_checked(
            v,
            prior.as_matrix(),
            search_radius_rad=r_s,
            field_radius_rad=field_r,
            region=region,
            candidates=candidates,
            t0=t0,
        )

    def match_checked(
        self,
        vectors_cam: np.ndarray,
        prior_matrix: np.ndarray,
        *,
        search_radius_rad: float,
        field_radius_rad: float,
        region: tuple[float, int] | None = None,
        candidates: np.ndarray | None = None,
        t0: float | None = None,
    ) -> TrackingMatch:
        """:meth:`__call__` on inputs already checked: a caller's per-frame loop (tracking).

        Parameters
        ----------
        vectors_cam : ndarray of float64, shape (N, 3)
            Unit detection directions in the camera frame (z > 0), brightest first (as
            :func:`~starsense.identify.result.validate_vectors` returns them).
        prior_matrix : ndarray, shape (3, 3)
            The predicted attitude's matrix (ICRS -> camera).
        search_radius_rad, field_radius_rad : float
            As :meth:`__call__`, in its ranges.
        region : (float, int), optional
            As :meth:`__call__`.
        candidates : ndarray of int64, shape (M,), optional
            As :meth:`__call__`.
        t0 : float, optional
            ``time.perf_counter()`` at the start of the call (default now).

        Returns
        -------
        TrackingMatch
        """
        t0 = time.perf_counter() if t0 is None else t0
        v, r_s, field_r = vectors_cam, search_radius_rad, field_radius_rad
        db = self.database
        cone = min(field_r + r_s, math.pi / 2)
        r = prior_matrix
        if candidates is None:
            centre = r[2]  # the boresight in ICRS: R^T z
            near = np.asarray(db.tree.query_ball_point(centre, _chord(cone)), dtype=np.int64)
            near.sort()
        else:
            near = candidates
        if region is None:
            region = (2 * math.pi * (1 - math.cos(cone)), len(near))

        def done(status, message, **kw):
            return TrackingMatch(
                status,
                n_detections=len(v),
                n_predicted=len(near),
                time_ms=(time.perf_counter() - t0) * 1e3,
                message=message,
                **kw,
            )

        ref = db.vectors[near]
        prior_matrix = r
        det, star, n_amb, r, resid, radius = self._match(v, ref, prior_matrix, r_s)
        if len(det) < 2:
            why = "ambiguous" if n_amb else "too_few_stars"
            return done(
                why,
                f"{len(det)} star(s) matched within {r_s:.2e} rad of the prior "
                f"({n_amb} ambiguous, {len(v)} detections, {len(near)} predicted)",
                n_ambiguous=n_amb,
            )
        # the fit's departure from the prior, as the displacement of a star at the field edge
        # (the measure of the search radius): cross-boresight plus roll x sin(field radius)
        d = _rotvec(r @ prior_matrix.T)
        innovation = float(math.hypot(d[0], d[1]) + abs(d[2]) * math.sin(field_r))
        cat = near[star]
        p_single = region[1] * math.pi * radius**2 / max(region[0], 1e-30)
        p_false = false_match_probability(len(v), len(det), n_hypothesis=2, p_single=p_single)
        rms = math.sqrt(float(resid @ resid) / len(resid))
        kw = {
            "detection_index": det,
            "catalog_index": cat,
            "catalog_id": db.ids[cat],
            "residual_rms_rad": rms,
            "n_ambiguous": n_amb,
            "false_match_probability": p_false,
            "innovation_rad": innovation,
        }
        if innovation > r_s:
            return done(
                "no_match",
                f"the fit is {innovation:.2e} rad from the prior, beyond "
                f"the search radius {r_s:.2e} rad",
                **kw,
            )
        if len(det) < 3:
            return done(
                "unverified", "2 stars matched (3 are needed to verify)", rotation_matrix=r, **kw
            )
        verified = p_false <= self.false_match_threshold
        status = "verified" if verified else "unverified"
        return done(
            status,
            f"{len(det)} of {len(v)} detections matched, P_false {p_false:.1e}",
            rotation_matrix=r,
            **kw,
        )
