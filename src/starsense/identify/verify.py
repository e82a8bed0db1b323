"""Verification of a candidate star match, shared by every identification algorithm.

From a hypothesis (a few detections paired with catalogue stars, and for an unknown field a
first guess of the scale) :class:`Verifier` computes the attitude, projects the catalogue
stars of the field into the camera, pairs every detection with the nearest one within the
match radius, refines the attitude (and scale) with all pairs, and computes the probability
that that many detections would land on catalogue stars by chance (tetra3's test, Brown et
al. 2023; Mortari et al. 2004 use the same reasoning for the pyramid algorithm):

    p = (catalogue stars in the field) x (pi r_match^2) / (solid angle of the field)
    P_false = P[X >= n - k],  X ~ Binomial(N - k, p)

with ``N`` detections, ``n`` of them matched and ``k`` the stars of the hypothesis itself
(which match by construction). A solution is accepted only when ``P_false`` is below a
threshold (default 1e-9).

Also here: the :class:`Identification` result shared by all algorithms and the input
validation they share.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation
from scipy.special import bdtrc

from starsense.errors import InputError
from starsense.identify.database import IdentificationDatabase

__all__ = [
    "STATUSES",
    "Identification",
    "Verifier",
    "apply_scale",
    "false_match_probability",
]

STATUSES = ("solved", "no_match", "ambiguous", "too_few_stars", "timeout")
"""Possible values of :attr:`Identification.status`."""

_EMPTY_INT = np.zeros(0, dtype=np.int64)

# The SVD fit returns an exact rotation matrix: skip scipy's re-orthogonalisation where it can.
try:
    Rotation.from_matrix(np.eye(3), assume_valid=True)
    _VALID_MATRIX: dict = {"assume_valid": True}
except TypeError:  # scipy < 1.15
    _VALID_MATRIX = {}


@dataclass(frozen=True, eq=False)
class Identification:
    """The answer of a lost-in-space identifier.

    Attributes
    ----------
    status : str
        ``"solved"``, ``"no_match"`` (no hypothesis passed verification),
        ``"too_few_stars"`` or ``"timeout"``. (``"ambiguous"``, two different attitudes
        passing, is reserved: the solvers accept the first hypothesis that passes.)
    algorithm : str
        ``"hashing"`` or ``"triangle"``.
    rotation : Rotation or None
        Attitude, ICRS -> camera (:mod:`starsense.geometry.attitude`), when solved.
    fov_rad : float or None
        Field of view (full width of the widest image axis), rad: the one given, or, when the
        field was unknown and the caller said at which field the vectors were computed, the
        one found.
    scale : float
        Factor applied to the tangent-plane coordinates ``(x/z, y/z)`` of the input vectors
        to get true camera directions: 1 for a known field, the estimate otherwise (the true
        focal length is the assumed one divided by `scale`).
    detection_index : ndarray of int, shape (M,)
        Matched detections (indices into the input vectors).
    catalog_index : ndarray of int, shape (M,)
        The database stars they match (indices into ``database.vectors``).
    catalog_id : ndarray of int64, shape (M,)
        Catalogue identifiers of those stars (HIP numbers for Hipparcos).
    residual_rms_rad : float
        RMS angle between matched detections and their catalogue stars after the fit, rad.
    false_match_probability : float
        Probability that a wrong attitude would match as many detections by chance.
    n_detections : int
        Detections given.
    n_patterns_tried : int
        Detection patterns (4-star or triangles) looked up.
    n_candidates : int
        Hypotheses verified.
    time_ms : float
        Wall time of the call, ms.
    message : str
        Why it failed, or a summary when solved.
    """

    status: str
    algorithm: str
    rotation: Rotation | None = None
    fov_rad: float | None = None
    scale: float = 1.0
    detection_index: NDArray[np.int64] = field(default_factory=lambda: _EMPTY_INT)
    catalog_index: NDArray[np.int64] = field(default_factory=lambda: _EMPTY_INT)
    catalog_id: NDArray[np.int64] = field(default_factory=lambda: _EMPTY_INT)
    residual_rms_rad: float = math.nan
    false_match_probability: float = 1.0
    n_detections: int = 0
    n_patterns_tried: int = 0
    n_candidates: int = 0
    time_ms: float = 0.0
    message: str = ""

    @property
    def solved(self) -> bool:
        """True when :attr:`status` is ``"solved"``."""
        return self.status == "solved"

    @property
    def n_matches(self) -> int:
        """Number of matched detections."""
        return len(self.detection_index)

    def __repr__(self) -> str:
        if not self.solved:
            return f"Identification({self.status}: {self.message})"
        from starsense.geometry.attitude import radec_roll_from_attitude

        ra, dec, roll = (math.degrees(a) for a in radec_roll_from_attitude(self.rotation))
        return (
            f"Identification(solved, RA {ra:.4f} Dec {dec:.4f} roll {roll:.3f} deg, "
            f"{self.n_matches}/{self.n_detections} matched, rms "
            f"{math.degrees(self.residual_rms_rad) * 3600:.1f} arcsec, P_false "
            f"{self.false_match_probability:.1e}, {self.time_ms:.1f} ms)"
        )


def validate_vectors(vectors_cam: object) -> NDArray[np.float64]:
    """Check and normalise detection directions ``(N, 3)``; raise :class:`InputError`."""
    try:
        v = np.asarray(vectors_cam, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"vectors_cam must be an (N, 3) array of numbers: {exc}") from None
    if v.ndim != 2 or v.shape[1] != 3:
        raise InputError(f"vectors_cam must have shape (N, 3), got {v.shape}")
    if not np.all(np.isfinite(v)):
        row = int(np.flatnonzero(~np.isfinite(v).all(axis=1))[0])
        raise InputError(f"vectors_cam[{row}] = {v[row].tolist()} is not finite")
    norm = np.linalg.norm(v, axis=1)
    if np.any(norm == 0):
        raise InputError(f"vectors_cam[{int(np.flatnonzero(norm == 0)[0])}] is a zero vector")
    v = v / norm[:, None]
    if np.any(v[:, 2] <= 0):
        row = int(np.flatnonzero(v[:, 2] <= 0)[0])
        raise InputError(
            f"vectors_cam[{row}] = {v[row].tolist()} points behind the camera (z <= 0)"
        )
    return v


def apply_scale(vectors_cam: NDArray[np.float64], scale: float) -> NDArray[np.float64]:
    """Scale the tangent-plane coordinates ``(x/z, y/z)`` of unit vectors by `scale`.

    This is what changing the focal length of a pinhole camera does to the directions
    computed from fixed pixel positions: ``f_true = f_assumed / scale``.
    """
    if scale == 1.0:
        return vectors_cam
    t = vectors_cam[:, :2] / vectors_cam[:, 2:3] * scale
    v = np.concatenate([t, np.ones((len(t), 1))], axis=1)
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _estimate_matrix(
    body: NDArray[np.float64], ref: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Attitude matrix ``R`` (``body ~ R @ ref``) from paired unit vectors, and the residual
    angles (rad): the SVD solution of Wahba's problem with equal weights (Kabsch).
    """
    if len(body) == 2:  # align_vectors needs a weight on the primary for two pairs
        rot, _ = Rotation.align_vectors(body, ref, weights=[np.inf, 1.0])
        r = rot.as_matrix()
    else:
        u, _, vt = np.linalg.svd(body.T @ ref)
        r = u @ vt
        if np.linalg.det(r) < 0:  # reflection -> the nearest proper rotation
            u[:, 2] = -u[:, 2]
            r = u @ vt
    chord = np.sqrt(np.sum((ref @ r.T - body) ** 2, axis=1))
    return r, 2.0 * np.arcsin(np.minimum(chord / 2.0, 1.0))


def _estimate_attitude(
    body: NDArray[np.float64], ref: NDArray[np.float64]
) -> tuple[Rotation, NDArray[np.float64]]:
    """Attitude (ICRS -> camera) from paired directions, and the residual angles (rad).

    The one place to point at :func:`starsense.attitude.estimate_attitude` when it lands.
    """
    r, resid = _estimate_matrix(body, ref)
    return Rotation.from_matrix(r), resid


def false_match_probability(
    n_detections: int, n_matched: int, n_hypothesis: int, p_single: float
) -> float:
    """Probability that at least ``n_matched - n_hypothesis`` of the other
    ``n_detections - n_hypothesis`` detections fall within the match radius of a catalogue
    star by chance (binomial tail; tetra3's test).

    Parameters
    ----------
    n_detections : int
        Detections considered.
    n_matched : int
        Detections matched.
    n_hypothesis : int
        Stars of the hypothesis (matched by construction, not counted as evidence).
    p_single : float
        Probability that one random detection lands within the match radius of a catalogue
        star: (catalogue stars in the field) x (match area) / (field area).

    Returns
    -------
    float
    """
    extra = n_matched - n_hypothesis
    trials = n_detections - n_hypothesis
    if extra <= 0 or trials <= 0:
        return 1.0
    p = min(max(p_single, 0.0), 1.0)
    # P[X >= extra] = P[X > extra - 1]: bdtrc is binom.sf without the distribution overhead
    return float(bdtrc(extra - 1, trials, p))


@dataclass(frozen=True)
class _Verified:
    rotation: Rotation
    scale: float
    detection_index: NDArray[np.int64]
    catalog_index: NDArray[np.int64]
    residual_rms_rad: float
    false_match_probability: float


class _Field:
    """Catalogue stars around a first attitude, fetched once per hypothesis and filtered to
    the cone of each later attitude (which moves by much less than the margin).
    """

    __slots__ = ("centre", "cos_reach", "index", "vectors")

    def __init__(self, db: IdentificationDatabase, centre: NDArray[np.float64], reach: float):
        reach = min(reach, math.pi)
        self.centre = centre
        self.cos_reach = math.cos(reach)
        idx = db.tree.query_ball_point(centre, 2.0 * math.sin(reach / 2.0))
        self.index = np.asarray(idx, dtype=np.int64)
        self.vectors = db.vectors[self.index]


class Verifier:
    """Verify star-match hypotheses against a database (see the module docstring).

    Parameters
    ----------
    database : IdentificationDatabase
    match_radius : float
        Match radius as a fraction of the field width (default 0.01, as tetra3).
    false_match_threshold : float
        Largest accepted probability of a false match.
    max_detections : int
        Only the brightest this many detections take part in the verification.
    """

    def __init__(
        self,
        database: IdentificationDatabase,
        *,
        match_radius: float = 0.01,
        false_match_threshold: float = 1e-9,
        max_detections: int = 60,
    ) -> None:
        if not 0 < match_radius < 0.2:
            raise InputError(f"match_radius = {match_radius} is out of range (0, 0.2)")
        if not 0 < false_match_threshold < 1:
            raise InputError(
                f"false_match_threshold = {false_match_threshold} is out of range (0, 1)"
            )
        if max_detections < 4:
            raise InputError(f"max_detections = {max_detections} must be at least 4")
        self.database = database
        self.match_radius = float(match_radius)
        self.false_match_threshold = float(false_match_threshold)
        self.max_detections = int(max_detections)

    def _fit(
        self,
        tangent: NDArray[np.float64],
        det: NDArray[np.int64],
        cat: NDArray[np.int64],
        scale: float,
        fit_scale: bool,
        vs: NDArray[np.float64] | None = None,
    ) -> tuple[NDArray[np.float64], float, NDArray[np.float64]]:
        """Attitude matrix (and scale) from pairs; tangent = (x/z, y/z) of the input vectors;
        `vs`, the unit vectors at `scale`, when already computed.
        """
        ref = self.database.vectors[cat]
        if not fit_scale:
            body = vs[det] if vs is not None else _unit_from_tangent(tangent[det] * scale)
            r, resid = _estimate_matrix(body, ref)
            return r, scale, resid
        t_det = tangent[det]
        denom = float(np.sum(t_det * t_det))
        for _ in range(4):
            r, resid = _estimate_matrix(_unit_from_tangent(t_det * scale), ref)
            c = ref @ r.T
            t_cat = c[:, :2] / c[:, 2:3]
            if denom <= 0:
                break
            scale = float(np.sum(t_det * t_cat)) / denom
        r, resid = _estimate_matrix(_unit_from_tangent(t_det * scale), ref)
        return r, scale, resid

    def __call__(
        self,
        vectors_cam: NDArray[np.float64],
        det: NDArray[np.int64],
        cat: NDArray[np.int64],
        *,
        scale: float = 1.0,
        fit_scale: bool = False,
        field_width_rad: float | None = None,
        scale_range: tuple[float, float] = (0.0, math.inf),
        tangent: NDArray[np.float64] | None = None,
    ) -> _Verified | None:
        """Verify one hypothesis; None if it fails.

        Parameters
        ----------
        vectors_cam : ndarray, shape (N, 3)
            Detection directions (unit, z > 0), brightest first.
        det, cat : ndarray of int, shape (K,)
            The hypothesis: detection ``det[i]`` is database star ``cat[i]``.
        scale : float
            Tangent-plane scale of the input (first guess when `fit_scale`).
        fit_scale : bool
            Estimate the scale too (unknown field).
        field_width_rad : float, optional
            Field width for the match radius; default twice the largest angle of a
            detection from the boresight.
        scale_range : (float, float)
            Accepted range of the fitted scale.
        tangent : ndarray, shape (N, 2), optional
            ``(x/z, y/z)`` of the first `max_detections` vectors, when the caller verifies many
            hypotheses on the same vectors (computed here otherwise).
        """
        v = vectors_cam[: self.max_detections]
        n = len(v)
        k = len(det)
        if tangent is None:
            tangent = v[:, :2] / v[:, 2:3]
        vs = v if scale == 1.0 and not fit_scale else _unit_from_tangent(tangent * scale)
        r, scale, resid = self._fit(tangent, det, cat, scale, fit_scale, vs)
        if not scale_range[0] <= scale <= scale_range[1]:
            return None
        if fit_scale:
            vs = _unit_from_tangent(tangent * scale)
        max_off = float(np.arccos(min(max(float(vs[:, 2].min()), -1.0), 1.0)))
        width = field_width_rad if field_width_rad is not None else 2.0 * max_off
        radius = self.match_radius * width
        if resid.max() > radius:
            return None
        # The catalogue stars of the field, once: later attitudes differ from this one by less
        # than the match radius (every hypothesis star lies within it).
        sky = _Field(self.database, r[2].copy(), max_off + 4.0 * radius)
        pairs = (det, cat)
        for _ in range(2):
            det_m, cat_m, _p = self._match(sky, vs, r, max_off + radius, radius)
            if len(det_m) < k:
                return None
            if fit_scale or not _same_pairs(pairs, det_m, cat_m):
                r, scale, resid = self._fit(tangent, det_m, cat_m, scale, fit_scale, vs)
                pairs = (det_m, cat_m)
            if not scale_range[0] <= scale <= scale_range[1]:
                return None
            if fit_scale:
                vs = _unit_from_tangent(tangent * scale)
        # Final pairing with a radius matched to the residuals (5 robust sigma, at least 1/20
        # of the search radius): a false or unlisted star that fell near another catalogue
        # star inside the wide search radius would otherwise bias the attitude.
        sigma = 1.4826 * float(np.median(resid)) / math.sqrt(2 * math.log(2))
        radius = min(radius, max(5.0 * sigma, radius / 20.0))
        det_m, cat_m, p_single = self._match(sky, vs, r, max_off + radius, radius)
        if len(det_m) < k:
            return None
        if fit_scale or not _same_pairs(pairs, det_m, cat_m):
            r, scale, resid = self._fit(tangent, det_m, cat_m, scale, fit_scale, vs)
        p_false = false_match_probability(n, len(det_m), k, p_single)
        if p_false > self.false_match_threshold:
            return None
        return _Verified(
            rotation=Rotation.from_matrix(r, **_VALID_MATRIX),
            scale=scale,
            detection_index=det_m,
            catalog_index=cat_m,
            residual_rms_rad=float(np.sqrt(np.mean(resid**2))),
            false_match_probability=p_false,
        )

    def _match(
        self,
        sky: _Field,
        vs: NDArray[np.float64],
        r: NDArray[np.float64],
        cone_rad: float,
        radius: float,
    ) -> tuple[NDArray[np.int64], NDArray[np.int64], float]:
        """One-to-one nearest pairs (detection, star) within `radius`, and p_single."""
        centre = r[2]  # the boresight in ICRS: R.T @ (0, 0, 1)
        cone = min(cone_rad, math.pi / 2)
        if float(centre @ sky.centre) < math.cos(max(math.acos(sky.cos_reach) - cone, 0.0)):
            # moved too far for the fetched stars (never seen in practice): fetch again
            sky = _Field(self.database, centre.copy(), cone + 0.05)
        inside = sky.vectors @ centre >= math.cos(cone)
        near = sky.index[inside]
        solid_angle = 2.0 * math.pi * (1.0 - math.cos(cone_rad))
        p_single = len(near) * math.pi * radius**2 / solid_angle
        if len(near) == 0:
            return _EMPTY_INT, _EMPTY_INT, p_single
        cam = sky.vectors[inside] @ r.T
        # squared chords between unit vectors: 2 - 2 cos
        chord2 = 2.0 - 2.0 * (vs @ cam.T)
        limit = 2.0 * math.sin(radius / 2.0)
        di, ci = np.nonzero(chord2 <= limit * limit)
        if len(di) == 0:
            return _EMPTY_INT, _EMPTY_INT, p_single
        if np.any(di[1:] == di[:-1]) or np.bincount(ci).max() > 1:  # di is sorted
            # contested: nearest pairs first, each detection and star used once
            order = np.argsort(chord2[di, ci], kind="stable")
            used_d: set[int] = set()
            used_c: set[int] = set()
            pairs = []
            for d, c in zip(di[order].tolist(), ci[order].tolist(), strict=True):
                if d in used_d or c in used_c:
                    continue
                used_d.add(d)
                used_c.add(c)
                pairs.append((d, c))
            pairs.sort()
            arr = np.asarray(pairs, dtype=np.int64)
            di, ci = arr[:, 0], arr[:, 1]
        return di.astype(np.int64), near[ci], p_single


def _same_pairs(
    pairs: tuple[NDArray[np.int64], NDArray[np.int64]],
    det: NDArray[np.int64],
    cat: NDArray[np.int64],
) -> bool:
    """Whether (det, cat) are the pairs of the last fit (then the fit would not change)."""
    d0, c0 = pairs
    return len(d0) == len(det) and bool(np.array_equal(d0, det) and np.array_equal(c0, cat))


def _unit_from_tangent(t: NDArray[np.float64]) -> NDArray[np.float64]:
    v = np.empty((len(t), 3))
    v[:, :2] = t
    v[:, 2] = 1.0
    return v / np.sqrt(np.sum(v * v, axis=1))[:, None]


def result_builder(algorithm: str, n_detections: int, t0: float):
    """``result(status, message, **fields) -> Identification`` for one identifier call, stamping
    the algorithm, the number of detections and the time since ``t0`` (perf_counter).
    """
    import time

    def result(status: str, message: str, **kw) -> Identification:
        return Identification(
            status=status,
            algorithm=algorithm,
            n_detections=n_detections,
            time_ms=(time.perf_counter() - t0) * 1e3,
            message=message,
            **kw,
        )

    return result


def identify_ranked(identifier, vectors_cam, brightness, *args, **kwargs) -> Identification:
    """Run ``identifier`` on detections given in any order, ranked here by ``brightness``.

    The identifiers build their patterns from the first (brightest) detections; this makes the
    result independent of the order the caller lists them in. ``detection_index`` of the result
    refers to the caller's order.

    Parameters
    ----------
    identifier : HashIdentifier or TriangleIdentifier
    vectors_cam : array (N, 3)
    brightness : array (N,)
        Any measure that grows with brightness (integrated counts, electrons, flux).
    *args, **kwargs
        Passed on to the identifier (``fov_rad``, ``assumed_fov_rad``).
    """
    v = np.asarray(vectors_cam, dtype=float)
    b = np.asarray(brightness, dtype=float)
    if b.shape != (len(v),):
        raise InputError(f"brightness must have one value per detection ({len(v)}), got {b.shape}")
    order = np.argsort(-b, kind="stable")
    result = identifier(v[order], *args, **kwargs)
    if len(result.detection_index) == 0:
        return result
    return dataclasses.replace(result, detection_index=order[result.detection_index])
