"""Radial lens distortion estimated during a solve, for a frame whose camera is unknown.

A wide lens (30-70 deg) bends star positions by several per cent towards the edge: a cheap
3 mm lens as much as 10-15 % in the corners, tens of pixels. The identification tolerates that
(its match radius is 1 % of the field), but a pinhole attitude fitted through such residuals is
off by pixels and, in a dense field, the wide radius pairs some detections with the wrong
neighbour. So after a first, tentative match the camera is fitted as

``(x, y) = c + f D(g(A v))``

with ``g`` the gnomonic projection of a catalogue direction ``v`` seen at attitude ``A``,
``D`` the radial part of the Brown-Conrady model (:mod:`starsense.geometry.distortion`,
``r_d = r (1 + k1 r^2 + k2 r^4)``, r in units of the focal length), ``f`` the focal length in
pixels and ``c`` the image centre (the principal point of an unknown camera: one frame does not
separate it from the attitude). The attitude, ``f``, ``k1`` and (for a wide field with enough
stars) ``k2`` are fitted by ``scipy.optimize.least_squares``; with the fitted camera every
catalogue star of the field is projected into the image and paired one-to-one with the nearest
detection within a radius set by the residuals (4 sigma of the fit, as
:class:`~starsense.identify.verify.Verifier`), and the fit and pairing are repeated until the
pairs stop changing. The radial terms enter one per round (k1 first), with a robust loss while
the pairs may still be wrong; with enough pairs a smooth cubic map of what the radial model
leaves (decentring, a principal point off the centre) is added to the predicted places for the
pairing only (:mod:`starsense.solve.pairing`). Before the test below, pairs whose deleted
residual (the residual predicted without them) exceeds the radius are dropped, and so are pairs
with another catalogue star near their detection. A term less than :data:`SIGNIFICANT` sigma
from zero is then left out. Fields narrower than :data:`MIN_FIELD_RAD` are not refined.

The result is accepted only when it passes the same false-match test as the identification
(:func:`~starsense.identify.verify.false_match_probability`): the chance that as many
detections fall within the final radius of a catalogue star at random, with the hypothesis
stars and the fitted distortion terms not counted as evidence.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from starsense.geometry.distortion import undistort
from starsense.geometry.projection import tangent_to_vectors
from starsense.identify.verify import false_match_probability
from starsense.solve.pairing import (
    FIELD_TERMS,
    ambiguous_pairs,
    deleted_residuals,
    nearest_pairs,
    residual_field,
    residual_sigma,
)
from starsense.solve.radial_lsq import RadialModel

__all__ = ["MIN_FIELD_RAD", "RadialFit", "fit_radial", "radial_vectors"]

#: stars of the tentative match counted as hypothesis (the 4-star pattern), not as evidence
HYPOTHESIS_STARS = 4
#: tangent of the corner's off-axis angle above which k2 is fitted too (about 33 deg across
#: the diagonal): below it r^4 is under 1 % and k2 is degenerate with k1 and the focal length
K2_MIN_CORNER_TAN = 0.3
#: narrowest horizontal field refined, rad (20 deg). Below it the lenses are long and well
#: corrected: on the eight 11.4 deg ESA frames the fitted k1 (0.07-0.15) lowers the residual by
#: 0.01-0.06 px rms and moves the boresight by 1-3 arcsec either way, as much as the image
#: centre standing in for the unknown principal point does; the identification's pinhole stays.
MIN_FIELD_RAD = math.radians(20.0)
#: a distortion term is kept when it is at least this many of its sigmas from zero
SIGNIFICANT = 3.0
#: matched stars needed per fitted distortion term beyond the attitude and focal length
STARS_PER_TERM = 8


@dataclass(frozen=True)
class RadialFit:
    """A camera fitted to one frame's stars: focal length, radial distortion, attitude.

    Attributes
    ----------
    rotation : Rotation
        The attitude, ICRS -> camera.
    focal_px : float
        Focal length, pixels.
    k1, k2 : float
        Radial distortion coefficients (tangent-plane units of the focal length); k2 is 0 when
        not fitted.
    k1_sigma, k2_sigma : float
        Their 1-sigma uncertainties (0 when not fitted).
    n_terms : int
        Radial terms fitted (0, 1 or 2).
    detection_index, catalog_index : ndarray of int, shape (M,)
        The matched detections and database stars.
    residual_rms_px : float
        Rms residual per axis of the matched stars, pixels.
    pinhole_rms_px : float
        The same with the distortion terms held at zero (attitude and focal length re-fitted).
    false_match_probability : float
        The chance that the matches are random (module docstring).
    edge_distortion : float
        The fitted radial displacement at the image corner as a fraction of the radius
        (negative: barrel).
    """

    rotation: Rotation
    focal_px: float
    k1: float
    k2: float
    k1_sigma: float
    k2_sigma: float
    n_terms: int
    detection_index: np.ndarray
    catalog_index: np.ndarray
    residual_rms_px: float
    pinhole_rms_px: float
    false_match_probability: float
    edge_distortion: float

    def to_dict(self) -> dict:
        """JSON-ready summary (the ``distortion`` of a solution)."""
        return {
            "model": "radial",
            "terms": self.n_terms,
            "k1": self.k1,
            "k2": self.k2,
            "k1_sigma": self.k1_sigma,
            "k2_sigma": self.k2_sigma,
            "focal_length_px": self.focal_px,
            "edge_distortion_percent": 100.0 * self.edge_distortion,
            "residual_rms_px": self.residual_rms_px,
            "pinhole_residual_rms_px": self.pinhole_rms_px,
        }


def radial_vectors(x, y, *, shape, focal_px: float, k1: float, k2: float = 0.0) -> np.ndarray:
    """Return camera-frame unit vectors of pixels seen through a radially distorted lens.

    Parameters
    ----------
    x, y : array_like, shape (N,)
        Column and row of each position, pixels.
    shape : (int, int)
        Rows, columns of the image (the principal point is its centre).
    focal_px : float
        Focal length, pixels.
    k1, k2 : float
        Radial distortion coefficients (:mod:`starsense.geometry.distortion`).

    Returns
    -------
    ndarray, shape (N, 3)
        NaN rows where the model cannot be inverted.
    """
    rows, cols = shape
    u = (np.asarray(x, dtype=float) - (cols - 1) / 2.0) / focal_px
    w = (np.asarray(y, dtype=float) - (rows - 1) / 2.0) / focal_px
    u, w = undistort(u, w, (k1, k2, 0.0, 0.0))
    return tangent_to_vectors(np.column_stack([u, w]))


def _terms(n_matched: int, corner_tan: float, max_terms: int) -> int:
    """How many radial terms ``n_matched`` stars of a field reaching ``corner_tan`` support."""
    n = min(max_terms, max(0, (n_matched - 4) // STARS_PER_TERM))
    return min(n, 1) if corner_tan < K2_MIN_CORNER_TAN else n


def fit_radial(
    xy,
    shape,
    database,
    *,
    tentative,
    focal_px: float,
    k1: float = 0.0,
    catalog=None,
    max_detections: int = 100,
    max_terms: int = 2,
    false_match_threshold: float = 1e-9,
) -> RadialFit | None:
    """Fit focal length, radial distortion and attitude to a tentatively identified frame.

    Parameters
    ----------
    xy : array_like, shape (N, 2)
        Centroids (x = column, y = row), pixels, brightest first.
    shape : (int, int)
        Rows, columns of the image.
    database : IdentificationDatabase
        The database of the identification (its ``vectors`` and ``tree``).
    tentative : (Rotation, ndarray, ndarray)
        The identification's attitude (ICRS -> camera), matched detection indices and database
        star indices.
    focal_px : float
        The identification's focal length, pixels.
    k1 : float
        The radial distortion the identification assumed (tangent-plane units of
        ``focal_px``): the start of the fit.
    catalog : Catalog, optional
        The full catalogue the database was built from: a pair is dropped when another of its
        stars, at most 1 mag fainter, lands within twice the match radius of the detection
        (the database keeps only the brightest stars of each region, so a detection of a star
        it left out can land near one it kept; at the corners, where the one-frame model is
        least sure, that pair would pass).
    max_detections : int
        The brightest this many detections take part.
    max_terms : int
        Most radial terms fitted (0-2; fewer when the stars cannot support them).
    false_match_threshold : float
        Largest accepted probability of a false match.

    Returns
    -------
    RadialFit or None
        None when the refined match does not pass the false-match test.
    """
    rows, cols = shape
    xy = np.asarray(xy, dtype=float)[:max_detections]
    rotation, det, cat = tentative
    det, cat = np.asarray(det, np.int64), np.asarray(cat, np.int64)
    keep = det < len(xy)
    fit = _Fit(xy, shape, rotation, focal_px, k1)
    star = fit.sky_from(database, cat[keep])
    if star is None or keep.sum() < HYPOTHESIS_STARS + 1:
        return None
    pairs = fit.iterate(det[keep], star, max_terms)
    if pairs is None:
        return None
    pairs = fit.screen(*pairs, database, catalog)
    if pairs is None:
        return None
    det, star = pairs
    n_in = int(fit.inside.sum())
    p_single = n_in * math.pi * fit.radius**2 / (rows * cols)
    # the hypothesis stars and every fitted term beyond the attitude and scale are no evidence
    n_free = HYPOTHESIS_STARS + fit.n_terms + (2 * len(FIELD_TERMS) if fit.field else 0)
    p_false = false_match_probability(len(xy), len(det), n_hypothesis=n_free, p_single=p_single)
    if p_false > false_match_threshold:
        return None
    res, sigmas = fit.prune(det, star)
    theta, n_terms = fit.theta, fit.n_terms
    pin = RadialModel(xy, fit.centre, rotation, n_terms=0).fit(theta[:4], det, fit.sky[star])
    k1, k2 = (*theta[4 : 4 + n_terms], 0.0, 0.0)[:2]
    return RadialFit(
        rotation=Rotation.from_rotvec(theta[:3]) * rotation,
        focal_px=float(theta[3]),
        k1=float(k1),
        k2=float(k2),
        k1_sigma=sigmas[0],
        k2_sigma=sigmas[1],
        n_terms=n_terms,
        detection_index=det,
        catalog_index=fit.near[star],
        residual_rms_px=float(np.sqrt(np.mean(res.fun**2))),
        pinhole_rms_px=float(np.sqrt(np.mean(pin.fun**2))),
        false_match_probability=p_false,
        edge_distortion=float(k1 * fit.corner_tan**2 + k2 * fit.corner_tan**4),
    )


class _Fit:
    """The state of one frame's lens fit: parameters, pairs, match radius, residual field."""

    def __init__(self, xy, shape, rotation, focal_px, k1):
        rows, cols = shape
        self.xy, self.rotation, self.k1_start = xy, rotation, k1
        self.centre = np.array([(cols - 1) / 2.0, (rows - 1) / 2.0])
        self.corner_tan = math.hypot(cols / 2.0, rows / 2.0) / focal_px
        self.reach = math.atan(self.corner_tan) * 1.3 + 0.02  # barrel widens the sky seen
        self.boresight = rotation.inv().apply([0.0, 0.0, 1.0])
        self.theta = np.array([0.0, 0.0, 0.0, focal_px, k1, 0.0])
        self.radius = 0.01 * cols  # the identification's match radius, 1 % of the field
        self.n_terms = 0
        self.field = None
        self.inside = np.zeros(0, dtype=bool)

    def sky_from(self, database, cat):
        """Fetch the database stars of the field; return the tentative stars' rows in it."""
        chord = 2 * math.sin(self.reach / 2)
        self.near = np.asarray(database.tree.query_ball_point(self.boresight, chord), np.int64)
        self.sky = database.vectors[self.near]
        where = {int(s): i for i, s in enumerate(self.near.tolist())}
        star = np.array([where.get(int(c), -1) for c in cat], np.int64)
        return None if np.any(star < 0) else star

    def model(self):
        return RadialModel(
            self.xy, self.centre, self.rotation, n_terms=self.n_terms, fixed=(self.theta[4], 0.0)
        )

    def refit(self, det, star, scale_px=None):
        model = self.model()
        res = model.fit(self.theta[: 4 + self.n_terms], det, self.sky[star], scale_px=scale_px)
        self.theta[: 4 + self.n_terms] = res.x
        return model, res

    def iterate(self, det, star, max_terms):
        """Fit and re-pair until the pairs stop changing; None when too few stay."""
        xy = self.xy
        for it in range(10):
            # one more term per round (k1 first): a two-term fit to a tentative match's few
            # wrong pairs can bend into a false minimum
            cap = _terms(len(det), self.corner_tan, max_terms)
            if self.k1_start and len(det) >= HYPOTHESIS_STARS + 2:  # a guess is fitted
                cap = max(cap, 1)
            self.n_terms = min(self.n_terms + 1 if it or self.k1_start else 0, cap)
            model, res = self.refit(det, star, scale_px=self.radius / 4.0)
            e = xy[det] - model.project(res.x, self.sky[star])
            pred = model.project(res.x, self.sky)
            self.field = residual_field(e, xy[det])
            if self.field is not None:  # what the radial model leaves (decentring, centre)
                pred = pred + self.field(pred)
                e = e - self.field(xy[det])
            n_free = 4 + self.n_terms + (2 * len(FIELD_TERMS) if self.field else 0)
            self.radius = min(self.radius, max(4.0 * residual_sigma(e, n_free), 1.0))
            c = self.centre
            self.inside = np.isfinite(pred).all(axis=1) & (np.abs(pred - c) <= c + 0.5).all(1)
            shown = np.where(self.inside[:, None], pred, np.nan)
            new_det, new_star = nearest_pairs(shown, xy, self.radius)
            if len(new_det) < HYPOTHESIS_STARS + 1:
                return None
            same = np.array_equal(new_det, det) and np.array_equal(new_star, star)
            det, star = new_det, new_star
            if same and it >= 2 and cap <= self.n_terms:
                break
        return det, star

    def screen(self, det, star, database, catalog):
        """Drop the pairs a lone star holds the fit to, and the ambiguous ones (catalogue)."""
        model, res = self.refit(det, star)
        self.field = residual_field(res.fun.reshape(-1, 2), self.xy[det])
        ok = deleted_residuals(res, self.xy[det], self.field) <= self.radius
        if catalog is not None:
            theta = self.theta[: 4 + self.n_terms].copy()
            where = (self.boresight, self.reach, self.radius)
            ids = database.ids[self.near[star]]
            ok &= ~ambiguous_pairs(
                catalog,
                lambda v: model.project(theta, v),
                self.xy[det],
                field=self.field,
                ids=ids,
                where=where,
            )
        if not ok.all():
            det, star = det[ok], star[ok]
            if len(det) < HYPOTHESIS_STARS + 1:
                return None
            self.refit(det, star)
        return det, star

    def prune(self, det, star):
        """Leave out the highest radial term while it is not measured; the last fit, sigmas."""
        _, res = self.refit(det, star)
        sigmas = _sigmas(res, self.n_terms)
        while (
            self.n_terms
            and abs(self.theta[3 + self.n_terms]) < SIGNIFICANT * sigmas[self.n_terms - 1]
        ):
            # a noise-fitted k2 of a narrow field would bend the corners, where no star holds it
            self.theta[3 + self.n_terms] = 0.0
            self.n_terms -= 1
            _, res = self.refit(det, star)
            sigmas = _sigmas(res, self.n_terms)
        return res, sigmas


def _sigmas(res, n_terms: int) -> tuple[float, float]:
    """1-sigma of k1, k2 from the fit's Jacobian (``s^2 (J^T J)^-1``); 0 when not fitted."""
    if n_terms == 0:
        return 0.0, 0.0
    j = res.jac
    dof = max(len(res.fun) - j.shape[1], 1)
    s2 = float(np.sum(res.fun**2)) / dof
    try:
        cov = np.linalg.inv(j.T @ j) * s2
    except np.linalg.LinAlgError:
        return math.inf, math.inf
    sig = np.sqrt(np.clip(np.diag(cov)[4:], 0.0, None))
    return float(sig[0]), float(sig[1]) if n_terms > 1 else 0.0
