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
pairs stop changing.

The result is accepted only when it passes the same false-match test as the identification
(:func:`~starsense.identify.verify.false_match_probability`): the chance that as many
detections fall within the final radius of a catalogue star at random, with the hypothesis
stars and the fitted distortion terms not counted as evidence.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from starsense.geometry.distortion import distort, undistort
from starsense.geometry.projection import tangent_to_vectors
from starsense.identify.verify import false_match_probability
from starsense.solve.pinhole import pinhole_vectors

__all__ = ["RadialFit", "fit_radial", "radial_vectors", "refine_identification"]

#: stars of the tentative match counted as hypothesis (the 4-star pattern), not as evidence
HYPOTHESIS_STARS = 4
#: tangent of the corner's off-axis angle above which k2 is fitted too (about 33 deg across
#: the diagonal): below it r^4 is under 1 % and k2 is degenerate with k1 and the focal length
K2_MIN_CORNER_TAN = 0.3
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


class _Model:
    """Residuals of detections against projected catalogue stars for one set of pairs."""

    def __init__(self, xy, centre, rotation, n_terms, fixed=(0.0, 0.0)):
        self.xy, self.centre, self.r0, self.n_terms = xy, centre, rotation, n_terms
        self.fixed = fixed  # the radial terms held, where not fitted

    def project(self, theta, v):
        rot = Rotation.from_rotvec(theta[:3]) * self.r0
        c = rot.apply(v)
        with np.errstate(divide="ignore", invalid="ignore"):
            x, y = c[:, 0] / c[:, 2], c[:, 1] / c[:, 2]
        k = (*theta[4 : 4 + self.n_terms], *self.fixed[self.n_terms :])
        xd, yd = distort(x, y, (k[0], k[1], 0.0, 0.0))
        out = np.column_stack([xd, yd]) * theta[3] + self.centre
        out[c[:, 2] <= 0] = np.nan
        return out

    def fit(self, theta0, det, v, scale_px=None):
        """Least squares; robust (soft L1 beyond ``scale_px``) while pairs may be wrong."""

        def residuals(theta):
            return (self.xy[det] - self.project(theta, v)).ravel()

        if scale_px is None:
            return least_squares(residuals, theta0, x_scale="jac", method="lm")
        return least_squares(
            residuals, theta0, x_scale="jac", loss="soft_l1", f_scale=scale_px, method="trf"
        )


def _pairs(pred: np.ndarray, xy: np.ndarray, radius_px: float) -> tuple[np.ndarray, np.ndarray]:
    """One-to-one nearest (detection, star) pairs within ``radius_px``, nearest first."""
    ok = np.flatnonzero(np.isfinite(pred).all(axis=1))
    if len(ok) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    dist, near = cKDTree(pred[ok]).query(xy, distance_upper_bound=radius_px)
    hit = np.flatnonzero(np.isfinite(dist))
    order = hit[np.argsort(dist[hit], kind="stable")]
    used: set[int] = set()
    det, star = [], []
    for d in order.tolist():
        s = int(ok[near[d]])
        if s in used:
            continue
        used.add(s)
        det.append(d)
        star.append(s)
    idx = np.argsort(det)
    return np.asarray(det, np.int64)[idx], np.asarray(star, np.int64)[idx]


def _terms(n_matched: int, corner_tan: float, max_terms: int) -> int:
    """How many radial terms ``n_matched`` stars of a field reaching ``corner_tan`` support."""
    n = min(max_terms, max(0, (n_matched - 4) // STARS_PER_TERM))
    return min(n, 1) if corner_tan < K2_MIN_CORNER_TAN else n


def fit_radial(
    xy,
    shape,
    database,
    tentative,
    *,
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
    centre = np.array([(cols - 1) / 2.0, (rows - 1) / 2.0])
    rotation, det, cat = tentative
    det, cat = np.asarray(det, np.int64), np.asarray(cat, np.int64)
    keep = det < len(xy)
    det, cat = det[keep], cat[keep]
    if len(det) < HYPOTHESIS_STARS + 1:
        return None
    half_diag_px = math.hypot(cols / 2.0, rows / 2.0)
    corner_tan = half_diag_px / focal_px
    reach = math.atan(corner_tan) * 1.3 + 0.02  # barrel distortion widens the sky seen
    boresight = rotation.inv().apply([0.0, 0.0, 1.0])
    near = np.asarray(database.tree.query_ball_point(boresight, 2 * math.sin(reach / 2)), np.int64)
    sky = database.vectors[near]
    where = {int(s): i for i, s in enumerate(near.tolist())}
    star = np.array([where.get(int(c), -1) for c in cat], np.int64)
    if np.any(star < 0):
        return None
    theta = np.array([0.0, 0.0, 0.0, focal_px, k1, 0.0])
    radius = 0.01 * cols  # the identification's match radius, 1 % of the field
    n_terms = 0
    field = None
    for it in range(10):
        # one more term per round (k1 first): a two-term fit to a tentative match's few wrong
        # pairs can bend into a false minimum
        cap = _terms(len(det), corner_tan, max_terms)
        if k1 and len(det) >= HYPOTHESIS_STARS + 2:  # a guessed k1 is fitted, not kept
            cap = max(cap, 1)
        n_terms = min(n_terms + 1 if it or k1 else 0, cap)
        model = _Model(xy, centre, rotation, n_terms, (theta[4], 0.0))
        res = model.fit(theta[: 4 + n_terms], det, sky[star], scale_px=radius / 4.0)
        theta[: 4 + n_terms] = res.x
        e = xy[det] - model.project(res.x, sky[star])
        pred = model.project(theta[: 4 + n_terms], sky)
        field = _residual_field(e, xy[det])
        if field is not None:  # what the radial model leaves (decentring, principal point)
            pred = pred + field(pred)
            e = e - field(xy[det])
        n_free = 4 + n_terms + (2 * len(_FIELD_TERMS) if field is not None else 0)
        radius = min(radius, max(4.0 * _sigma(e, n_free), 1.0))
        inside = np.isfinite(pred).all(axis=1) & (np.abs(pred - centre) <= centre + 0.5).all(1)
        new_det, new_star = _pairs(np.where(inside[:, None], pred, np.nan), xy, radius)
        if len(new_det) < HYPOTHESIS_STARS + 1:
            return None
        same = np.array_equal(new_det, det) and np.array_equal(new_star, star)
        det, star = new_det, new_star
        if same and it >= 2 and cap <= n_terms:
            break
    model = _Model(xy, centre, rotation, n_terms, (theta[4], 0.0))
    res = model.fit(theta[: 4 + n_terms], det, sky[star])
    theta[: 4 + n_terms] = res.x
    field = _residual_field(res.fun.reshape(-1, 2), xy[det])
    # drop the pairs that only fit because they bent the model to themselves
    ok = _deleted_residuals(res, xy[det], field) <= radius
    if catalog is not None:
        ids = database.ids[near[star]]
        project = lambda v: model.project(theta[: 4 + n_terms], v)  # noqa: E731
        ok &= ~_ambiguous(catalog, project, field, xy[det], ids, (boresight, reach, radius))
    if not ok.all():
        det, star = det[ok], star[ok]
        if len(det) < HYPOTHESIS_STARS + 1:
            return None
        res = model.fit(theta[: 4 + n_terms], det, sky[star])
        theta[: 4 + n_terms] = res.x
    n_in = int(inside.sum())
    p_single = n_in * math.pi * radius**2 / (rows * cols)
    # the hypothesis stars and every fitted term beyond the attitude and scale are no evidence
    n_free = HYPOTHESIS_STARS + n_terms + (2 * len(_FIELD_TERMS) if field is not None else 0)
    p_false = false_match_probability(len(xy), len(det), n_hypothesis=n_free, p_single=p_single)
    if p_false > false_match_threshold:
        return None
    sigmas = _sigmas(res, n_terms)
    while n_terms and abs(theta[3 + n_terms]) < SIGNIFICANT * sigmas[n_terms - 1]:
        # the highest term is not measured: leave it out (a noise-fitted k2 of a narrow field
        # would bend the corners, where no star holds it)
        theta[3 + n_terms] = 0.0
        n_terms -= 1
        model = _Model(xy, centre, rotation, n_terms)
        res = model.fit(theta[: 4 + n_terms], det, sky[star])
        theta[: 4 + n_terms] = res.x
        sigmas = _sigmas(res, n_terms)
    pin = _Model(xy, centre, rotation, 0).fit(theta[:4], det, sky[star])
    k1, k2 = (*theta[4 : 4 + n_terms], 0.0, 0.0)[:2]
    edge = k1 * corner_tan**2 + k2 * corner_tan**4
    rot = Rotation.from_rotvec(theta[:3]) * rotation
    return RadialFit(
        rotation=rot,
        focal_px=float(theta[3]),
        k1=float(k1),
        k2=float(k2),
        k1_sigma=sigmas[0],
        k2_sigma=sigmas[1],
        n_terms=n_terms,
        detection_index=det,
        catalog_index=near[star],
        residual_rms_px=float(np.sqrt(np.mean(res.fun**2))),
        pinhole_rms_px=float(np.sqrt(np.mean(pin.fun**2))),
        false_match_probability=p_false,
        edge_distortion=float(edge),
    )


#: (p, q) of the monomials x^p y^q of the residual field: a cubic in the image coordinates
_FIELD_TERMS = [(p, q) for p in range(4) for q in range(4 - p)]
#: pairs needed before the residual field is fitted (5 per coefficient of each axis)
FIELD_MIN_PAIRS = 5 * len(_FIELD_TERMS)


def _residual_field(resid: np.ndarray, at: np.ndarray):
    """Return a smooth cubic map of the residuals (px -> px), or None with too few pairs.

    Fitted by least squares with pairs beyond 3 sigma dropped (twice): a wrong pair does not
    bend it. It carries what a one-frame radial model leaves at the corners (decentring, a
    principal point off the image centre: a few pixels), only to pair the stars there.
    """
    if len(at) < FIELD_MIN_PAIRS:
        return None
    centre = at.mean(axis=0)
    scale = float(np.abs(at - centre).max()) or 1.0

    def design(p):
        u, v = ((np.asarray(p) - centre) / scale).T
        return np.column_stack([u**a * v**b for a, b in _FIELD_TERMS])

    m = design(at)
    keep = np.ones(len(at), dtype=bool)
    for _ in range(3):
        coeff, *_ = np.linalg.lstsq(m[keep], resid[keep], rcond=None)
        err = np.hypot(*(resid - m @ coeff).T)
        sigma = float(np.median(err[keep])) / math.sqrt(2.0 * math.log(2.0))
        keep = err <= max(3.0 * sigma, 1e-6)
        if keep.sum() < FIELD_MIN_PAIRS:
            return None

    def field(p):
        out = design(np.nan_to_num(p)) @ coeff
        out[~np.isfinite(p).all(axis=1)] = np.nan
        return out

    field.design = design
    return field


def _ambiguous(catalog, project, field, at, ids, where) -> np.ndarray:
    """Return which pairs have another catalogue star near their detection (shape (M,)).

    ``where`` is (boresight, cone half-angle, match radius px); ``project`` maps unit vectors to
    pixels; the other star counts when it is at most 1 mag fainter than the paired one.
    """
    boresight, reach, radius = where
    idx = catalog.cone(boresight, reach)
    cone_ids = catalog.ids[idx]
    where_id = {int(i): k for k, i in enumerate(cone_ids.tolist())}
    mine = np.array([where_id.get(int(i), -1) for i in ids], dtype=np.int64)
    if np.any(mine < 0):  # a database of another catalogue (the deep narrow range)
        return np.zeros(len(ids), dtype=bool)
    band = "V" if "V" in catalog.bands else catalog.bands[0]
    mags = np.asarray(catalog.mags[band], dtype=float)[idx]
    pred = project(catalog.vectors[idx])
    if field is not None:
        pred = pred + field(pred)
    finite = np.flatnonzero(np.isfinite(pred).all(axis=1))
    tree = cKDTree(pred[finite])
    out = np.zeros(len(ids), dtype=bool)
    for i, (p, k) in enumerate(zip(at, mine.tolist(), strict=True)):
        others = [j for j in finite[tree.query_ball_point(p, 2.0 * radius)] if j != k]
        out[i] = bool(others) and bool(np.any(mags[others] <= np.nan_to_num(mags[k]) + 1.0))
    return out


def _sigma(e: np.ndarray, n_free: int) -> float:
    """Per-axis sigma of residuals ``e`` (M, 2) after fitting ``n_free`` parameters.

    From their median length (Rayleigh: median = sigma sqrt(2 ln 2), robust to a wrong pair),
    scaled up by ``sqrt(2M / (2M - n_free))`` for the degrees of freedom the fit took.
    """
    m2 = 2 * len(e)
    med = float(np.median(np.hypot(*e.T))) / math.sqrt(2.0 * math.log(2.0))
    return med * math.sqrt(m2 / max(m2 - n_free, 1))


def _deleted_residuals(res, at: np.ndarray, field) -> np.ndarray:
    """Return each pair's residual as predicted without it, px (shape (M,)).

    ``e_(i) = (I - H_ii)^-1 e_i`` with ``H`` the hat matrix of the radial fit and the residual
    field together and ``e_i`` the residual after both (Cook 1977, the deleted residual). A pair
    at an unsupported corner that holds the fit to itself has ``H_ii`` near I: its deleted
    residual is large, and it is no evidence.
    """
    e = res.fun.reshape(-1, 2)
    parts = [res.jac]
    if field is not None:
        e = e - field(at)
        m = field.design(at)
        fx = np.zeros((2 * len(at), m.shape[1]))
        fy = np.zeros_like(fx)
        fx[0::2], fy[1::2] = m, m
        parts += [fx, fy]
    q, _ = np.linalg.qr(np.hstack(parts))
    qb = q.reshape(len(at), 2, -1)
    h = np.einsum("nik,njk->nij", qb, qb)
    a = np.eye(2) - h
    det = a[:, 0, 0] * a[:, 1, 1] - a[:, 0, 1] * a[:, 1, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        dx = (a[:, 1, 1] * e[:, 0] - a[:, 0, 1] * e[:, 1]) / det
        dy = (-a[:, 1, 0] * e[:, 0] + a[:, 0, 0] * e[:, 1]) / det
    out = np.hypot(dx, dy)
    return np.where(det > 1e-9, out, np.inf)


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


def refine_identification(
    ident, database, x, y, flux, *, shape, fov_rad: float, k1=0.0, catalog=None
):
    """Refine a solved identification of an unknown camera with a radial-distortion fit.

    Parameters
    ----------
    ident : Identification
        A solved identification (pinhole, field ``fov_rad``).
    database : IdentificationDatabase
        Its database.
    x, y : ndarray, shape (N,)
        The centroids, pixels.
    flux : ndarray, shape (N,)
        Their brightness (larger is brighter).
    shape : (int, int)
        Rows, columns of the image.
    fov_rad : float
        The horizontal field the identification found (pinhole), rad.
    k1 : float
        The radial distortion the identification assumed, tangent-plane units of the focal
        length of ``fov_rad``.
    catalog : Catalog, optional
        The full catalogue behind the database (:func:`fit_radial`).

    Returns
    -------
    ident : Identification
        With the refined matches, attitude and false-match probability (unchanged when the fit
        does not pass the false-match test).
    fit : RadialFit or None
        The camera found, or None.
    vectors : ndarray, shape (N, 3)
        The centroids' camera-frame unit vectors through the camera found (or the pinhole).
    fov_rad : float
        The horizontal field across the image width, rad (through the distortion found).
    """
    rows, cols = shape
    focal = cols / 2.0 / math.tan(fov_rad / 2.0)
    order = np.argsort(-np.asarray(flux, dtype=float), kind="stable")  # brightest first
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    fit = fit_radial(
        np.column_stack([x, y])[order],
        shape,
        database,
        (ident.rotation, rank[np.asarray(ident.detection_index)], ident.catalog_index),
        focal_px=focal,
        k1=k1,
        catalog=catalog,
    )
    if fit is None:
        if k1:
            vectors = radial_vectors(x, y, shape=shape, focal_px=focal, k1=k1)
            return ident, None, vectors, fov_rad
        return ident, None, pinhole_vectors(x, y, shape=shape, fov_rad=fov_rad), fov_rad
    ident = dataclasses.replace(
        ident,
        rotation=fit.rotation,
        detection_index=order[fit.detection_index],
        catalog_index=fit.catalog_index,
        catalog_id=database.ids[fit.catalog_index],
        false_match_probability=fit.false_match_probability,
    )
    vectors = radial_vectors(x, y, shape=shape, focal_px=fit.focal_px, k1=fit.k1, k2=fit.k2)
    half, _ = undistort([cols / 2.0 / fit.focal_px], [0.0], (fit.k1, fit.k2, 0.0, 0.0))
    fov = 2.0 * math.atan(float(half[0])) if np.isfinite(half[0]) else fov_rad
    return ident, fit, vectors, fov
