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
(which match by construction); ``p`` is at least the mean, over the other detections, of the
same chance at the catalogue density around each (a cluster's matches are not evidence at the
field's mean density, ``Verifier._local_p``). A solution is accepted only when
``P_false`` is below a threshold (default 1e-9) and, with the optics known, when its pairs are a
rigid rotation of the sky: their residuals' Rayleigh spread (4 sigma) lies inside the match
radius.

The :class:`~starsense.identify.result.Identification` result that the algorithms return is in
:mod:`starsense.identify.result`.

The compiled kernel of hashing identification (``_hashc.c``, see
:mod:`starsense.identify.hash_kernels`) repeats :meth:`Verifier.__call__` step by step and
calls :meth:`Verifier.accept` for the decision: a change to the matching or fitting
here must be made there too (tests/identify/test_hash_kernel.py holds the two equal).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation
from scipy.special import bdtrc

from starsense._validate import check_int, check_scalar
from starsense.attitude.svd import wahba_matrix
from starsense.geometry.projection import tangent_to_vectors, vectors_to_tangent
from starsense.identify.database import IdentificationDatabase

__all__ = [
    "Verifier",
    "apply_scale",
    "exact_rotation",
    "false_match_probability",
]

_EMPTY_INT = np.zeros(0, dtype=np.int64)

#: the neighbourhood of a detection whose catalogue stars give its chance of a false match, in
#: initial match radii (5: a cone of radius 5 % of the field's width, 1 deg in a 20 deg field,
#: the scale of an open cluster such as the Pleiades; wide against the match radius, so that a
#: count of a few stars measures a density)
LOCAL_RADII = 5.0

# The SVD fit returns an exact rotation matrix: skip scipy's re-orthogonalisation where it can.
try:
    Rotation.from_matrix(np.eye(3), assume_valid=True)
    _VALID_MATRIX: dict = {"assume_valid": True}
except TypeError:  # scipy < 1.15
    _VALID_MATRIX = {}


def exact_rotation(matrix: NDArray[np.float64]) -> Rotation:
    """Return the Rotation of a rotation matrix that is orthonormal to rounding (a fit's).

    Parameters
    ----------
    matrix : ndarray, shape (3, 3)
        Rotation matrix (from :func:`starsense.attitude.svd.wahba_matrix` or the compiled kernel).

    Returns
    -------
    Rotation
        Without scipy's re-orthogonalisation where scipy allows it (>= 1.15).
    """
    return Rotation.from_matrix(matrix, **_VALID_MATRIX)


def apply_scale(vectors_cam: NDArray[np.float64], scale: float) -> NDArray[np.float64]:
    """Scale the tangent-plane coordinates ``(x/z, y/z)`` of unit vectors by `scale`.

    This is what changing the focal length of a pinhole camera does to the directions
    computed from fixed pixel positions: ``f_true = f_assumed / scale``.

    Parameters
    ----------
    vectors_cam : ndarray, shape (N, 3)
        Camera-frame unit vectors with z > 0.
    scale : float
        Factor on the tangent-plane coordinates.

    Returns
    -------
    ndarray, shape (N, 3)
        The scaled directions, unit vectors.
    """
    if scale == 1.0:
        return vectors_cam
    return tangent_to_vectors(vectors_to_tangent(vectors_cam) * scale)


def false_match_probability(
    n_detections: int, n_matched: int, *, n_hypothesis: int, p_single: float
) -> float:
    """Return the probability that the extra matches of a hypothesis are chance.

    The probability that at least ``n_matched - n_hypothesis`` of the other
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
    """Catalogue stars around a first attitude, fetched once per hypothesis.

    They are filtered to the cone of each later attitude (which moves by much less than the
    margin).
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
        check_scalar(match_radius, "match_radius", 0, 0.2, lo_open=True, hi_open=True)
        check_scalar(
            false_match_threshold, "false_match_threshold", 0, 1, lo_open=True, hi_open=True
        )
        check_int(max_detections, "max_detections", 4)
        self.database = database
        self.match_radius = float(match_radius)
        self.false_match_threshold = float(false_match_threshold)
        self.max_detections = int(max_detections)

    def accept(
        self, n_detections: int, n_matched: int, *, n_hypothesis: int, p_single: float
    ) -> tuple[float, bool]:
        """Decide whether a verified hypothesis is accepted (the compiled kernel calls this too).

        Parameters
        ----------
        n_detections : int
            Detections that took part in the verification.
        n_matched : int
            Detections matched to a catalogue star.
        n_hypothesis : int
            Stars of the hypothesis itself.
        p_single : float
            Probability that one random detection lands on a catalogue star
            (:func:`false_match_probability`).

        Returns
        -------
        p_false : float
            The probability of a false match.
        accepted : bool
            Whether it is at most :attr:`false_match_threshold`.
        """
        p = false_match_probability(
            n_detections, n_matched, n_hypothesis=n_hypothesis, p_single=p_single
        )
        return p, p <= self.false_match_threshold

    def _fit(
        self,
        tangent: NDArray[np.float64],
        det: NDArray[np.int64],
        cat: NDArray[np.int64],
        scale: float,
        fit_scale: bool,
        vs: NDArray[np.float64] | None = None,
    ) -> tuple[NDArray[np.float64], float, NDArray[np.float64]]:
        """Fit the attitude matrix (and scale) to pairs.

        `tangent` holds (x/z, y/z) of the input vectors; `vs` the unit vectors at `scale`, when
        already computed.
        """
        ref = self.database.vectors[cat]
        if not fit_scale:
            body = vs[det] if vs is not None else tangent_to_vectors(tangent[det] * scale)
            r, resid, _ = wahba_matrix(body, ref, two_exact=True)
            return r, scale, resid
        t_det = tangent[det]
        denom = float(np.sum(t_det * t_det))
        for _ in range(4):
            r, resid, _ = wahba_matrix(tangent_to_vectors(t_det * scale), ref, two_exact=True)
            c = ref @ r.T
            # inline, not vectors_to_tangent: a wrong hypothesis may not raise on z <= 0
            t_cat = c[:, :2] / c[:, 2:3]
            if denom <= 0:
                break
            scale = float(np.sum(t_det * t_cat)) / denom
        r, resid, _ = wahba_matrix(tangent_to_vectors(t_det * scale), ref, two_exact=True)
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
        seen: list[float] | None = None,
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
        seen : list of one float, optional
            The least false-match probability of the hypotheses verified so far: lowered here
            when this one gets as far as a probability (the "best seen" of a failed solve).
        """
        v = vectors_cam[: self.max_detections]
        n = len(v)
        k = len(det)
        if tangent is None:
            tangent = vectors_to_tangent(v)
        vs = v if scale == 1.0 and not fit_scale else tangent_to_vectors(tangent * scale)
        r, scale, resid = self._fit(tangent, det, cat, scale, fit_scale, vs)
        if not scale_range[0] <= scale <= scale_range[1]:
            return None
        if fit_scale:
            vs = tangent_to_vectors(tangent * scale)
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
                vs = tangent_to_vectors(tangent * scale)
        # Final pairing with a radius matched to the residuals: a false or unlisted star that
        # fell near another catalogue star inside the wide search radius would otherwise bias
        # the attitude (in a dense field with 1 px noise, one such pair moved the boresight by
        # 70 arcsec). The residual of a true pair is Rayleigh-distributed: its median is
        # sigma sqrt(2 ln 2) for a per-axis sigma, and 4 sigma leaves out 1 true pair in 3,000
        # (exp(-8)). Twice: the second radius comes from a fit free of the outliers.
        # With the optics known, the first 4 sigma must lie inside the search radius, else the
        # pairs are not a rigid rotation of the sky: the radius would have cut off part of a
        # Rayleigh spread that wide. Residuals that fill the radius are what chance pairs leave,
        # or an attitude pulled between right pairs and the wrong ones of a hypothesis matched
        # to a self-similar group of stars (the Pleiades onto themselves): the right pairs make
        # P_false tiny however far off that attitude is (0.03-0.4 deg in a 20 deg field), so
        # the hypothesis is refused and the search goes on. With the scale fitted, a distorted
        # lens seen as a pinhole fills the radius with true pairs (its distortion is fitted
        # afterwards), so there the test is not made.
        for i in range(2):
            sigma = float(np.median(resid)) / math.sqrt(2.0 * math.log(2.0))
            if i == 0 and not fit_scale and 4.0 * sigma >= radius:
                return None
            radius = min(radius, max(4.0 * sigma, radius / 20.0))
            det_m, cat_m, p_single = self._match(sky, vs, r, max_off + radius, radius)
            if len(det_m) < k:
                return None
            if fit_scale or not _same_pairs(pairs, det_m, cat_m):
                r, scale, resid = self._fit(tangent, det_m, cat_m, scale, fit_scale, vs)
                pairs = (det_m, cat_m)
                if fit_scale:
                    vs = tangent_to_vectors(tangent * scale)
        local = LOCAL_RADII * self.match_radius * width
        p_local = self._local_p(sky, vs, r, (max_off + radius, radius, local), det, (det_m, cat_m))
        p_single = max(p_single, p_local)
        p_false, accepted = self.accept(n, len(det_m), n_hypothesis=k, p_single=p_single)
        if seen is not None:
            seen[0] = min(seen[0], p_false)
        if not accepted:
            return None
        return _Verified(
            rotation=exact_rotation(r),
            scale=scale,
            detection_index=det_m,
            catalog_index=cat_m,
            residual_rms_rad=float(np.sqrt(np.mean(resid**2))),
            false_match_probability=p_false,
        )

    def _local_p(
        self,
        sky: _Field,
        vs: NDArray[np.float64],
        r: NDArray[np.float64],
        radii: tuple[float, float, float],
        hypothesis: NDArray[np.int64],
        pairs: tuple[NDArray[np.int64], NDArray[np.int64]],
    ) -> float:
        """Mean chance of a match of the detections outside the hypothesis, at their own density.

        A cluster (the Pleiades) holds many catalogue stars where the field's mean density
        holds one: a detection there lands on a star by chance far more often than the mean
        ``p_single`` says, and a hypothesis inside the cluster collects matches there that
        are not evidence for the attitude. Each detection's chance is counted from the
        catalogue stars within ``LOCAL_RADII`` initial match radii of it (its own pair left
        out): ``p_i = n_i pi r^2 / (solid angle of that cone)``. Their mean bounds the false
        match probability from above through the binomial (Hoeffding 1956: the tail of a sum
        of Bernoulli(p_i) past its mean is at most that of the binomial of the mean p).
        """
        cone_rad, radius, wide = radii  # the field's cone, the match radius, the local one
        inside = sky.vectors @ r[2] >= math.cos(min(cone_rad, math.pi / 2))
        if not inside.any():
            return 0.0
        cam = sky.vectors[inside] @ r.T
        limit = 2.0 * math.sin(wide / 2.0)
        count = np.count_nonzero(2.0 - 2.0 * (vs @ cam.T) <= limit * limit, axis=1)
        det_m, cat_m = pairs
        own = np.sqrt(np.add.reduce((self.database.vectors[cat_m] @ r.T - vs[det_m]) ** 2, axis=1))
        count[det_m] -= own <= limit  # the detection's own pair is not its neighbourhood
        others = np.ones(len(vs), dtype=bool)
        others[hypothesis] = False
        if not others.any():
            return 0.0
        cap = 2.0 * math.pi * (1.0 - math.cos(wide))
        p = np.minimum(count[others] * (math.pi * radius**2 / cap), 1.0)
        return float(p.mean())

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
