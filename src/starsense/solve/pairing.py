"""Pairing detections with projected catalogue stars, and the checks on each pair.

The pieces of the one-frame lens fit (:mod:`starsense.solve.radial`) that decide which
detection is which star: one-to-one nearest pairs within a radius, a smooth map of what the
radial model leaves at the corners, the residual sigma after a fit, the deleted residual of each
pair (Cook 1977) and the test for another catalogue star near a detection.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

__all__ = [
    "FIELD_MIN_PAIRS",
    "FIELD_TERMS",
    "ambiguous_pairs",
    "deleted_residuals",
    "nearest_pairs",
    "residual_field",
    "residual_sigma",
]


def nearest_pairs(pred: np.ndarray, xy: np.ndarray, radius_px: float):
    """Return one-to-one nearest (detection, star) pairs within ``radius_px``, nearest first.

    Parameters
    ----------
    pred : ndarray, shape (S, 2)
        Predicted pixels of the stars (NaN rows are ignored), px.
    xy : ndarray, shape (N, 2)
        Detections, px.
    radius_px : float
        Largest distance of a pair, px.

    Returns
    -------
    det, star : ndarray of int64, shape (M,)
        Paired detection and star rows, sorted by detection.
    """
    ok = np.flatnonzero(np.isfinite(pred).all(axis=1))
    if len(ok) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    dist, near = cKDTree(pred[ok]).query(xy, distance_upper_bound=radius_px)
    hit = np.flatnonzero(np.isfinite(dist))
    order = hit[np.argsort(dist[hit], kind="stable")]
    # nearest first, each star to the first detection that reaches it (a later one goes unpaired)
    _, first = np.unique(near[order], return_index=True)
    det = np.sort(order[first]).astype(np.int64)
    return det, ok[near[det]].astype(np.int64)


#: (p, q) of the monomials x^p y^q of the residual field: a cubic in the image coordinates
FIELD_TERMS = [(p, q) for p in range(4) for q in range(4 - p)]
#: pairs needed before the residual field is fitted (5 per coefficient of each axis)
FIELD_MIN_PAIRS = 5 * len(FIELD_TERMS)


def residual_field(resid: np.ndarray, at: np.ndarray):
    """Return a smooth cubic map of the residuals, or None with too few pairs.

    Fitted by least squares with pairs beyond 3 sigma dropped (twice): a wrong pair does not
    bend it. It carries what a one-frame radial model leaves at the corners (decentring, a
    principal point off the image centre: a few pixels), only to pair the stars there.

    Parameters
    ----------
    resid : ndarray, shape (M, 2)
        Residuals (measured minus model), px.
    at : ndarray, shape (M, 2)
        Where they were measured, px.

    Returns
    -------
    callable or None
        Maps pixels (K, 2) to the residual expected there (K, 2), px; its ``design`` attribute
        gives the cubic's design matrix at pixels. None below :data:`FIELD_MIN_PAIRS` pairs.
    """
    if len(at) < FIELD_MIN_PAIRS:
        return None
    centre = at.mean(axis=0)
    scale = float(np.abs(at - centre).max()) or 1.0

    def design(p):
        u, v = ((np.asarray(p) - centre) / scale).T
        return np.column_stack([u**a * v**b for a, b in FIELD_TERMS])

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


def ambiguous_pairs(catalog, project, at, *, field, ids, where) -> np.ndarray:
    """Return which pairs have another catalogue star near their detection.

    Parameters
    ----------
    catalog : Catalog
        The full catalogue.
    project : callable
        Maps ICRS unit vectors (K, 3) to pixels (K, 2) through the fitted camera.
    field : callable or None
        The residual field (:func:`residual_field`) added to the projected pixels.
    at : ndarray, shape (M, 2)
        The paired detections, px.
    ids : ndarray of int64, shape (M,)
        Catalogue ids of the paired stars.
    where : (ndarray, float, float)
        Boresight (ICRS unit vector), cone half-angle (rad) and match radius (px).

    Returns
    -------
    ndarray of bool, shape (M,)
        True where a star other than the paired one, at most 1 mag fainter, lands within twice
        the match radius; all False when the ids are not the catalogue's (a database of
        another catalogue).
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
    limit = np.nan_to_num(mags[mine]) + 1.0  # a star fainter than this cannot confuse a pair
    bright = np.flatnonzero(mags <= limit.max())
    pred = project(catalog.vectors[idx[bright]])
    if field is not None:
        pred = pred + field(pred)
    finite = bright[np.isfinite(pred).all(axis=1)]
    pred = pred[np.isfinite(pred).all(axis=1)]
    out = np.zeros(len(ids), dtype=bool)
    if len(finite) == 0:
        return out
    near = cKDTree(pred).query_ball_point(np.asarray(at, dtype=float), 2.0 * radius)
    for i, js in enumerate(near):
        others = finite[js]
        others = others[others != mine[i]]
        out[i] = bool(np.any(mags[others] <= limit[i]))
    return out


def residual_sigma(e: np.ndarray, n_free: int) -> float:
    """Return the per-axis sigma of residuals after a fit.

    From their median length (Rayleigh: median = sigma sqrt(2 ln 2), robust to a wrong pair),
    scaled up by ``sqrt(2M / (2M - n_free))`` for the degrees of freedom the fit took.

    Parameters
    ----------
    e : ndarray, shape (M, 2)
        Residuals, px.
    n_free : int
        Parameters fitted.

    Returns
    -------
    float
        Sigma per axis, px.
    """
    m2 = 2 * len(e)
    med = float(np.median(np.hypot(*e.T))) / math.sqrt(2.0 * math.log(2.0))
    return med * math.sqrt(m2 / max(m2 - n_free, 1))


def deleted_residuals(res, at: np.ndarray, field) -> np.ndarray:
    """Return each pair's residual as predicted without it.

    ``e_(i) = (I - H_ii)^-1 e_i`` with ``H`` the hat matrix of the radial fit and the residual
    field together and ``e_i`` the residual after both (Cook 1977, the deleted residual). A pair
    at an unsupported corner that holds the fit to itself has ``H_ii`` near I: its deleted
    residual is large, and it is no evidence.

    Parameters
    ----------
    res : scipy.optimize.OptimizeResult
        The radial fit (``fun``, residuals (2M,); ``jac``, (2M, P)).
    at : ndarray, shape (M, 2)
        The paired detections, px.
    field : callable or None
        The residual field fitted to the same residuals (:func:`residual_field`).

    Returns
    -------
    ndarray, shape (M,)
        Length of each deleted residual, px (inf where the pair alone fixes the fit).
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
