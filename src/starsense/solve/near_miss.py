"""Near misses: fainter evidence for the best hypothesis of a frame that fell short of acceptance.

A frame with few bright detections (a short exposure, a faint 8-bit camera) can hold the right
hypothesis and still fail the verification's test (:mod:`starsense.identify.verify`): with ten
detections, eight matched give a false-match probability of ~1e-8 against the 1e-9 accepted.
The frame itself holds more evidence than its detections: the catalogue's fainter stars, which
the detector's threshold left out, are where the hypothesis puts them or they are not. The
threshold is never loosened; the evidence is gathered and weighed:

1. The best hypothesis of the failed search is found again (the same deterministic search, told
   to stop at the least false-match probability it saw), when that probability is at most
   :data:`NEAR_MISS_CEILING`.
2. Its attitude predicts where the catalogue's stars fall on the frame: the matched pairs give
   the pixel scale and centre (a pinhole), the matched fluxes the zero point; the stars predicted
   down to a sixth of the faintest detection's flux (about two magnitudes below it) are kept,
   the brightest :data:`MAX_PREDICTED`, except those within reach of a detection (whose light the
   verification has weighed already) and those closer to a brighter predicted star than twice
   the reach.
3. At each predicted place a statistic is read off the frame: the brightest 3 x 3 box mean
   within the reach, above the median of the window around it, over that window's spread (16-84
   % quantiles, robust to stars and quantisation). The same statistic is read at
   :data:`N_CONTROLS` control places drawn uniformly over the same admissible pixels (a fixed
   seed). A place "holds a star" when the statistic passes :data:`HIT_SIGMA`.
4. Under a wrong hypothesis the predicted places are unrelated to the frame's content, so they
   are exchangeable with the controls: the number of predicted places that hold a star is then
   hypergeometric over the pooled places (Fisher's exact test; no noise model is assumed, the
   controls measure the frame's own rate of chance peaks: clutter, hot pixels, clipped noise).
   Its tail ``p2`` is multiplied by the number of such tests made in the solve (Bonferroni).
5. The verification's probability ``p1`` and ``p2`` are independent evidence (different pixels):
   Fisher's combination ``P = t (1 - ln t)``, ``t = p1 p2``, is the probability under the null
   that two independent uniform p-values have a product as small. The hypothesis is accepted
   when ``P`` is at most the verifier's unchanged threshold, and ``P`` is its false-match
   probability.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.ndimage import uniform_filter

from starsense.identify import Identification, identify_ranked

__all__ = [
    "HIT_SIGMA",
    "MAX_CHANCE_FRACTION",
    "MAX_PREDICTED",
    "NEAR_MISS_CEILING",
    "N_CONTROLS",
    "FrameEvidence",
    "fisher_combined",
    "is_near_miss",
    "near_miss",
]

#: the least false-match probability of a failed search that is worth more evidence (above it no
#: plausible faint evidence brings the combination under 1e-9: it would need p2 < 5e-8)
NEAR_MISS_CEILING = 1e-3
#: the most control places that may read as a star for the reading to confirm a hypothesis: past
#: it the frame's light is nearly everywhere (streaks, clutter), and the predicted places being
#: lit says that the stars are about there, not that the attitude is right (a smeared frame's
#: near miss 160 arcsec off was "confirmed" with 37 % of the controls lit)
MAX_CHANCE_FRACTION = 0.1
#: control places drawn over the frame (the hypergeometric's resolution: with 20 chance peaks
#: among 2,000 controls, 6 hits of 30 predicted places give p2 ~ 2e-7)
N_CONTROLS = 2000
#: the most predicted stars read (the brightest): a frame's faint stars beyond are not needed
MAX_PREDICTED = 150
#: a place holds a star when its statistic passes this (in the window's spreads; its rate of
#: chance passes is measured on the controls, not assumed)
HIT_SIGMA = 3.0
#: the reach of a predicted place, px: at least this, else 3 x the pinhole fit's rms, at most 6
MIN_REACH_PX, MAX_REACH_PX = 1.5, 6.0


def fisher_combined(p1: float, p2: float) -> float:
    """Return Fisher's combination of two independent p-values.

    ``P[U1 U2 <= t] = t (1 - ln t)`` for independent uniform ``U1, U2`` (Fisher 1932, the
    chi-squared with 4 degrees of freedom of ``-2 ln t``).

    Parameters
    ----------
    p1, p2 : float
        The two p-values, in [0, 1].

    Returns
    -------
    float
    """
    t = min(max(p1, 0.0), 1.0) * min(max(p2, 0.0), 1.0)
    if t <= 0.0:
        return 0.0
    return min(t * (1.0 - math.log(t)), 1.0)


@dataclasses.dataclass
class FrameEvidence:
    """The frame a failed hypothesis is checked against (module docstring, steps 2-4).

    Parameters
    ----------
    image : ndarray (rows, columns)
        The frame, counts.
    x, y, flux : ndarray (N,)
        The detections (the points the identifier was given, in the same order).
    sky : callable
        ``sky(band) -> SkyStars``: the catalogue's stars in a band
        (:meth:`starsense.solve.identifiers.FieldIdentifiers.sky`).
    """

    image: np.ndarray
    x: np.ndarray
    y: np.ndarray
    flux: np.ndarray
    sky: object
    _smooth: np.ndarray | None = None

    @classmethod
    def of(cls, image, points, sky) -> FrameEvidence | None:
        """Return the evidence of a frame's detections (``CentroidPoints``), None without image."""
        if image is None or np.ndim(image) != 2:
            return None
        flux = np.asarray(points.flux, dtype=float)
        return cls(np.asarray(image), np.asarray(points.x, float), np.asarray(points.y, float),
                   flux, sky)  # fmt: skip

    def _pinhole(self, ident: Identification, database):
        """Pixel centre and scale fitted to the matched pairs: ``(cx, cy, f_px, rms_px)``."""
        det, cat = ident.detection_index, ident.catalog_index
        u = database.vectors[cat] @ ident.rotation.as_matrix().T
        t = u[:, :2] / u[:, 2:3]
        n = len(det)
        a = np.zeros((2 * n, 3))
        a[:n, 0], a[n:, 1] = 1.0, 1.0
        a[:n, 2], a[n:, 2] = t[:, 0], t[:, 1]
        b = np.concatenate([self.x[det], self.y[det]])
        sol, *_ = np.linalg.lstsq(a, b, rcond=None)
        rms = float(np.sqrt(np.mean((a @ sol - b) ** 2)) * math.sqrt(2.0))
        return float(sol[0]), float(sol[1]), float(sol[2]), rms

    def _mag_limit(self, ident: Identification, database) -> float | None:
        """Return the faintest magnitude predicted: ~2 mag below the faintest detection."""
        det, cat = ident.detection_index, ident.catalog_index
        good = self.flux[det] > 0
        if not good.any():
            return None
        zp = float(np.median(database.mags[cat][good] + 2.5 * np.log10(self.flux[det][good])))
        faintest = float(np.min(self.flux[self.flux > 0]))
        return zp - 2.5 * math.log10(faintest / 6.0)

    def predicted(self, rotation, pinhole, *, reach: float, stars, mag_limit: float) -> np.ndarray:
        """Return the predicted places (M, 2) of the catalogue's stars to ``mag_limit`` (step 2).

        Parameters
        ----------
        rotation : ndarray (3, 3)
            The hypothesis's attitude matrix (ICRS -> camera).
        pinhole : (cx, cy, f_px)
            The pixel centre and focal length, px.
        reach : float
            The reach of a place, px.
        stars : SkyStars
            The catalogue's stars.
        mag_limit : float
            The faintest magnitude predicted.
        """
        cx, cy, f_px = pinhole[:3]
        rows, cols = self.image.shape
        if not f_px > 0:
            return np.zeros((0, 2))
        half_diag = math.atan(math.hypot(rows, cols) / 2.0 / f_px)
        near = stars.tree.query_ball_point(rotation[2], 2.0 * math.sin(min(half_diag, 1.5) / 2))
        near = np.asarray(near, dtype=np.int64)
        near = near[stars.mags[near] <= mag_limit]
        near = near[np.argsort(stars.mags[near], kind="stable")]
        u = stars.vectors[near] @ rotation.T
        u = u[u[:, 2] > 0]
        xy = np.column_stack([cx + f_px * u[:, 0] / u[:, 2], cy + f_px * u[:, 1] / u[:, 2]])
        xy = xy[self._admissible(xy, reach)]
        kept: list[int] = []  # brightest first: none within 2 reaches of a brighter one
        for i in range(len(xy)):
            if len(kept) >= MAX_PREDICTED:
                break
            if kept and np.min(np.hypot(*(xy[kept] - xy[i]).T)) < 2.0 * reach:
                continue
            kept.append(i)
        return xy[kept]

    def _half(self, reach: float) -> int:
        return math.ceil(reach) + 6

    def _admissible(self, xy: np.ndarray, reach: float) -> np.ndarray:
        """Places whose window lies inside the frame and which no detection reaches."""
        rows, cols = self.image.shape
        h = self._half(reach)
        ok = (xy[:, 0] >= h) & (xy[:, 0] <= cols - 1 - h)
        ok &= (xy[:, 1] >= h) & (xy[:, 1] <= rows - 1 - h)
        if len(self.x) and ok.any():
            d2 = (xy[:, None, 0] - self.x[None, :]) ** 2 + (xy[:, None, 1] - self.y[None, :]) ** 2
            ok &= d2.min(axis=1) > (reach + 4.0) ** 2
        return ok

    def statistic(self, xy: np.ndarray, reach: float) -> np.ndarray:
        """Return the statistic at places ``xy`` (M, 2): the brightest box mean within reach."""
        if self._smooth is None:
            self._smooth = uniform_filter(np.asarray(self.image, dtype=np.float32), 3)
        if len(xy) == 0:
            return np.zeros(0)
        h = self._half(reach)
        win = np.lib.stride_tricks.sliding_window_view(self._smooth, (2 * h + 1, 2 * h + 1))
        r0 = np.rint(xy[:, 1]).astype(int) - h
        c0 = np.rint(xy[:, 0]).astype(int) - h
        w = win[r0, c0].reshape(len(xy), -1)
        dy, dx = np.mgrid[-h : h + 1, -h : h + 1]
        off = np.column_stack([(dx + 0.0).ravel(), (dy + 0.0).ravel()])
        frac = xy - np.rint(xy)  # the place's offset from its window's centre pixel
        d2 = np.add.reduce((off[None, :, :] - frac[:, None, :]) ** 2, axis=2)
        inner = d2 <= reach**2
        outer = d2 > (reach + 2.0) ** 2
        peak = np.where(inner, w, -np.inf).max(axis=1)
        ring = np.where(outer, w, np.nan)
        q16, q50, q84 = np.nanpercentile(ring, [16, 50, 84], axis=1)
        spread = np.maximum((q84 - q16) / 2.0, 1e-6)
        return (peak - q50) / spread

    def read(self, rotation, pinhole, *, reach: float, stars, mag_limit: float):
        """Return ``(p2, what was read)`` for an attitude and pinhole (steps 2-4).

        Parameters as :meth:`predicted`; ``p2`` is the hypergeometric tail of the hits among
        the predicted places against the controls (1 when nothing could be read).
        """
        xy = self.predicted(rotation, pinhole, reach=reach, stars=stars, mag_limit=mag_limit)
        rows, cols = self.image.shape
        rng = np.random.default_rng(49)
        ctrl = rng.uniform((0.0, 0.0), (cols - 1.0, rows - 1.0), (4 * N_CONTROLS, 2))
        ctrl = ctrl[self._admissible(ctrl, reach)][:N_CONTROLS]
        info = {"predicted": len(xy), "controls": len(ctrl), "reach_px": reach}
        if len(xy) == 0 or len(ctrl) < N_CONTROLS // 4:
            return 1.0, {**info, "hits": 0, "control_hits": 0}
        hits = int(np.count_nonzero(self.statistic(xy, reach) >= HIT_SIGMA))
        chance = int(np.count_nonzero(self.statistic(ctrl, reach) >= HIT_SIGMA))
        p2 = 1.0
        if hits:
            # only for a near miss: importing scipy.stats costs every solve ~0.1 s
            from scipy.stats import hypergeom  # noqa: PLC0415

            p2 = float(hypergeom.sf(hits - 1, len(xy) + len(ctrl), hits + chance, len(xy)))
        info.update(hits=hits, control_hits=chance)
        return p2, info

    def __call__(self, ident: Identification, database) -> tuple[float, dict]:
        """Return ``(p2, what was read)`` for a hypothesis (module docstring, steps 2-4)."""
        pinhole = self._pinhole(ident, database)
        reach = min(max(3.0 * pinhole[3], MIN_REACH_PX), MAX_REACH_PX)
        mag_limit = self._mag_limit(ident, database)
        try:
            stars = self.sky(database.params.band)
        except KeyError:  # a database in a band the solver's catalogue lacks (no prediction)
            stars = None
        if mag_limit is None or stars is None:
            return 1.0, {"predicted": 0, "controls": 0, "hits": 0, "control_hits": 0}
        return self.read(
            ident.rotation.as_matrix(), pinhole, reach=reach, stars=stars, mag_limit=mag_limit
        )


def is_near_miss(ident: Identification) -> bool:
    """Whether a failed identification came within :data:`NEAR_MISS_CEILING` of acceptance."""
    return ident.status == "no_match" and ident.best_false_match_probability <= NEAR_MISS_CEILING


def near_miss(identifier, vectors, flux, *, ident, args, kwargs, evidence, tests: list[int]):
    """Return the failed ``ident``, or its best hypothesis accepted on more evidence.

    Parameters
    ----------
    identifier : HashIdentifier or TriangleIdentifier
        The identifier that failed (its ``verifier`` and ``database``).
    vectors, flux : ndarray
        What it was given.
    ident : Identification
        Its failed answer.
    args, kwargs
        The rest of the identifier's call.
    evidence : FrameEvidence
        The frame's pixels and detections.
    tests : list of one int
        The near-miss tests made so far in the solve; counted up here when one is made (the
        Bonferroni factor of this one).

    Returns
    -------
    Identification
        ``ident`` unchanged, or the best hypothesis, solved, with the combined probability.
    """
    best = ident.best_false_match_probability
    verifier = getattr(identifier, "verifier", None)
    if verifier is None or ident.status != "no_match":
        return ident
    threshold = verifier.false_match_threshold
    if not threshold < best <= NEAR_MISS_CEILING:
        return ident
    kwargs = {**kwargs, "max_patterns": ident.n_patterns_tried}
    verifier.false_match_threshold = best  # the same search, stopped at its best hypothesis
    try:
        again = identify_ranked(identifier, vectors, flux, *args, **kwargs)
    finally:
        verifier.false_match_threshold = threshold
    if not again.solved:
        return ident
    p2, info = evidence(again, identifier.database)
    if info["control_hits"] > MAX_CHANCE_FRACTION * max(info["controls"], 1):
        return ident  # light nearly everywhere: being near it says nothing of the attitude
    tests[0] += 1
    p2 = min(p2 * tests[0], 1.0)
    combined = fisher_combined(again.false_match_probability, p2)
    if combined > threshold:
        return ident
    said = (
        f"{again.message}; near miss (P_false {again.false_match_probability:.1e}) confirmed by "
        f"{info['hits']} of {info['predicted']} fainter catalogue stars seen where predicted "
        f"({info['control_hits']} of {info['controls']} control places): P_false {combined:.1e}"
    )
    return dataclasses.replace(
        again,
        false_match_probability=combined,
        best_false_match_probability=combined,
        n_patterns_tried=ident.n_patterns_tried + again.n_patterns_tried,
        message=said,
    )
