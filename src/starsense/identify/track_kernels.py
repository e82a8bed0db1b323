"""Kernels of tracking's per-frame loop: pairing, the attitude fit, its covariance sandwich.

Each comes twice: the NumPy form (``*_numpy``, the reference and the fallback) and the same
arithmetic in the compiled kernel ``_trackc`` (``_trackc.c``, built by setup.py as an optional
extension; ``*_compiled`` return None where it is not built). Tracking spends its time in the
per-call overhead of a few hundred small NumPy operations on a few dozen stars, which the kernel
does not have.

* :func:`pair_compiled` equals :func:`pair_numpy` bit for bit (the same squared chords in the
  same order, the same comparisons).
* :func:`fit_compiled` solves Wahba's problem from Davenport's K matrix (its largest
  eigenvector by cyclic Jacobi rotations) where the NumPy form uses LAPACK's SVD: the attitude
  agrees to rounding (~1e-15 rad), the residuals to ~1e-15 rad absolute.
* :func:`match_compiled` runs TrackingIdentifier's whole pair-fit-pair loop in one call: the
  same steps, its predicted vectors summed without BLAS (equal to rounding: the same pairs but
  at a tie with the radius, the attitude to rounding).
* :func:`fisher_inverse_compiled`: the Fisher matrix and its inverse with the singularity test
  of :func:`~starsense.attitude.covariance.covariance` (to rounding).
* :func:`sandwich_compiled` sums the same products in another order: ~1e-13 relative.
* :func:`unblended_compiled` equals :func:`unblended_numpy` bit for bit (the same squared
  distances, minimum and square root).
"""

from __future__ import annotations

import numpy as np

try:  # the compiled kernel (setup.py builds it where a C compiler exists)
    import starsense.identify._trackc as _trackc
except ImportError:  # pragma: no cover - exercised on machines without a compiler
    _trackc = None

__all__ = [
    "COMPILED",
    "fisher_inverse_compiled",
    "fit_compiled",
    "match_compiled",
    "pair_compiled",
    "pair_numpy",
    "sandwich_compiled",
    "sandwich_numpy",
    "unblended_compiled",
    "unblended_numpy",
    "weighted_fit_compiled",
]

#: Whether the compiled kernel is built.
COMPILED = _trackc is not None

_ARANGE = np.arange(1024)
_EMPTY_INT = np.zeros(0, dtype=np.int64)


def pair_numpy(vectors: np.ndarray, cam: np.ndarray, *, bound2: float, ratio: float):
    """Nearest predicted star of each detection within a chord; ambiguous pairs dropped.

    The two nearest predicted stars of each detection by direct comparison (a few dozen of
    each: cheaper than a k-d tree built per call), within the squared chord ``bound2``
    (strictly, as ``cKDTree.query`` with ``distance_upper_bound``). A pair is ambiguous when
    a second predicted star lies within the bound and within ``ratio`` times the nearest one's
    chord, or when two detections claim the same star.

    Parameters
    ----------
    vectors : ndarray, shape (N, 3)
        Detection unit vectors, camera frame.
    cam : ndarray, shape (M, 3)
        Predicted star unit vectors, camera frame.
    bound2 : float
        Squared chord of the search radius.
    ratio : float
        Ambiguity ratio, > 1.

    Returns
    -------
    det, star : ndarray of int64, shape (K,)
        Paired detection and predicted-star indices, detections ascending.
    n_ambiguous : int
        Pairs dropped as ambiguous.
    """
    m = len(cam)
    if m == 0:
        return _EMPTY_INT, _EMPTY_INT, 0
    n = len(vectors)
    diff = vectors[:, None, :] - cam[None, :, :]
    d2 = np.add.reduce(diff * diff, axis=2)  # (N, M) squared chords
    rows = _ARANGE[:n] if n <= len(_ARANGE) else np.arange(n)
    first = d2.argmin(axis=1)
    d1 = d2[rows, first]
    found = d1 < bound2
    if m > 1:
        d2[rows, first] = np.inf
        second = d2[rows, d2.argmin(axis=1)]
        # clear: no second star within the search radius, or one much farther
        clear = (second >= bound2) | (np.sqrt(second) >= ratio * np.sqrt(d1))
    else:
        clear = np.ones(n, bool)
    det = (found & clear).nonzero()[0]
    star = first[det]
    n_amb = int(np.count_nonzero(found & ~clear))
    counts = np.bincount(star, minlength=m)
    unique = counts[star] == 1
    n_amb += len(unique) - int(np.count_nonzero(unique))
    return det[unique].astype(np.int64), star[unique].astype(np.int64), n_amb


def pair_compiled(vectors: np.ndarray, cam: np.ndarray, *, bound2: float, ratio: float):
    """:func:`pair_numpy` in the compiled kernel (equal bit for bit); None where not built."""
    if _trackc is None:
        return None
    n, m = len(vectors), len(cam)
    det = np.empty(n, np.int64)
    star = np.empty(n, np.int64)
    work = np.empty(n + m, np.int64)
    k, n_amb = _trackc.pair(
        np.ascontiguousarray(vectors, dtype=float),
        n,
        np.ascontiguousarray(cam, dtype=float),
        m,
        float(bound2),
        float(ratio),
        det,
        star,
        work,
    )
    return det[:k], star[:k], n_amb


def match_compiled(vectors, ref, prior, *, radius, min_radius, ratio, mad_scale):
    """TrackingIdentifier's pair-fit-pair loop in the compiled kernel; None where not built.

    Pair the detections with the stars ``ref`` (ICRS) predicted by ``prior`` (3, 3) within
    ``radius``; with two pairs or more, up to three times: fit the pairs (equal weights, two by
    TRIAD), shrink the radius to ``max(5 mad_scale median(residuals), min_radius)`` and pair
    again, until the pairs stand (fewer than two: the last fit is kept).

    Parameters
    ----------
    vectors : ndarray, shape (N, 3)
        Detections, camera frame.
    ref : ndarray, shape (M, 3)
        Predicted stars, ICRS.
    prior : ndarray, shape (3, 3)
        Attitude matrix, ICRS -> camera.
    radius, min_radius : float
        Search radius and the smallest pairing radius, rad.
    ratio : float
        Ambiguity ratio.
    mad_scale : tuple of float
        ``(a, b)``: the residuals' sigma is ``a x median / b``.

    Returns
    -------
    tuple or None
        (det, star, n_ambiguous, c, residuals, radius); ``c`` and ``residuals`` None with fewer
        than two pairs.
    """
    if _trackc is None:
        return None
    n = len(vectors)
    det = np.empty(n, np.int64)
    star = np.empty(n, np.int64)
    c = np.empty((3, 3))
    resid = np.empty(n)
    k, n_amb, radius = _trackc.match(
        np.ascontiguousarray(vectors, dtype=float),
        n,
        np.ascontiguousarray(ref, dtype=float),
        len(ref),
        np.ascontiguousarray(prior, dtype=float),
        float(radius),
        float(min_radius),
        float(ratio),
        float(mad_scale[0]),
        float(mad_scale[1]),
        det,
        star,
        c,
        resid,
    )
    if k < 2:
        return det[:k], star[:k], n_amb, None, None, radius
    return det[:k], star[:k], n_amb, c, resid[:k], radius


def fisher_inverse_compiled(body: np.ndarray, sigma: np.ndarray, *, rcond: float):
    """``F^-1`` of :func:`~starsense.attitude.covariance.fisher_covariance` in the kernel.

    Parameters
    ----------
    body : ndarray, shape (N, 3)
        Unit vectors.
    sigma : ndarray, shape (N,)
        Per-star sigma, rad (weights ``sigma^-2``).
    rcond : float
        Smallest eigenvalue ratio taken as non-singular.

    Returns
    -------
    ndarray, shape (3, 3), or False, or None
        The covariance, rad^2; False where F is not finite or singular (the NumPy form then
        raises its error); None where the kernel is not built.
    """
    if _trackc is None:
        return None
    out = np.empty((3, 3))
    ok = _trackc.fisher_inverse(
        np.ascontiguousarray(body, dtype=float),
        np.ascontiguousarray(sigma, dtype=float),
        len(body),
        float(rcond),
        out,
    )
    return out if ok else False


def fit_compiled(body: np.ndarray, ref: np.ndarray, weights: np.ndarray, *, two_exact: bool):
    """:func:`starsense.attitude.svd.wahba_matrix` in the compiled kernel (to rounding).

    None where the kernel is not built.
    """
    if _trackc is None:
        return None
    n = len(body)
    c = np.empty((3, 3))
    resid = np.empty(n)
    chord2 = np.empty(n)
    _trackc.wahba(
        np.ascontiguousarray(body, dtype=float),
        np.ascontiguousarray(ref, dtype=float),
        np.ascontiguousarray(weights, dtype=float),
        n,
        bool(two_exact),
        c,
        resid,
        chord2,
    )
    return c, resid, chord2


def weighted_fit_compiled(body: np.ndarray, ref: np.ndarray, sigma: np.ndarray, *, rcond: float):
    """:func:`fit_compiled` with weights ``sigma^-2`` and :func:`fisher_inverse_compiled`, at once.

    Parameters
    ----------
    body, ref : ndarray, shape (N, 3)
        Camera-frame and ICRS unit vectors of paired stars, N >= 2.
    sigma : ndarray, shape (N,)
        Each star's sigma, rad.
    rcond : float
        Smallest eigenvalue ratio of the Fisher matrix taken as non-singular.

    Returns
    -------
    tuple or None
        ``(c, resid, chord2, cov, loss)``: the matrix (3, 3), the residual angles and squared
        chords (N,), the covariance (3, 3) or False where the Fisher matrix is singular or not
        finite, the Wahba loss ``1/2 sum chord2 / sigma^2``; None where the kernel is not built.
    """
    if _trackc is None:
        return None
    n = len(body)
    c, cov = np.empty((3, 3)), np.empty((3, 3))
    resid, chord2 = np.empty(n), np.empty(n)
    ok, loss = _trackc.weighted_fit(
        np.ascontiguousarray(body, dtype=float),
        np.ascontiguousarray(ref, dtype=float),
        np.ascontiguousarray(sigma, dtype=float),
        n,
        float(rcond),
        c,
        resid,
        chord2,
        cov,
    )
    return c, resid, chord2, (cov if ok else False), loss


def sandwich_numpy(body, g, cov, *, w, inv) -> np.ndarray:
    """``inv (sum_i w_i^2 J_i^T G_i C_i G_i^T J_i) inv``, ``J_i = -[b_i]x`` (3, 3).

    Parameters
    ----------
    body : ndarray, shape (N, 3)
        Camera-frame unit vectors.
    g : ndarray, shape (N, 3, 2)
        Derivative of each unit vector by its pixel position, 1/px.
    cov : ndarray, shape (N, 2, 2)
        Centroid covariances, px^2.
    w : ndarray, shape (N,)
        Weights of the estimator, rad^-2.
    inv : ndarray, shape (3, 3)
        The inverse of the weighted Fisher matrix, rad^2.

    Returns
    -------
    ndarray, shape (3, 3)
        Covariance, rad^2.
    """
    n = len(body)
    noise = g @ cov @ g.transpose(0, 2, 1)  # (N, 3, 3)
    skew = np.zeros((n, 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -body[:, 2], body[:, 1], -body[:, 0]
    skew -= skew.transpose(0, 2, 1)
    middle = np.einsum("i,iaj,iab,ibk->jk", w**2, skew, noise, skew)
    return inv @ middle @ inv


def sandwich_compiled(body, g, cov, *, w, inv) -> np.ndarray | None:
    """:func:`sandwich_numpy` in the compiled kernel (to rounding); None where not built."""
    if _trackc is None:
        return None
    out = np.empty((3, 3))
    _trackc.sandwich(
        np.ascontiguousarray(body, dtype=float),
        np.ascontiguousarray(g, dtype=float),
        np.ascontiguousarray(cov, dtype=float),
        np.ascontiguousarray(w, dtype=float),
        np.ascontiguousarray(inv, dtype=float),
        len(body),
        out,
    )
    return out


def unblended_numpy(cat_index, near, *, x, y, blend_px: float) -> np.ndarray:
    """Return whether each matched star has no other predicted star within ``blend_px``.

    The nearest other predicted star of each, by direct comparison (a few dozen stars), among
    those with a finite position.

    Parameters
    ----------
    cat_index : ndarray of int, shape (M,)
        Database indices of the matched stars (all in ``near``).
    near : ndarray of int, shape (N,)
        Database indices of the predicted stars, ascending.
    x, y : ndarray, shape (N,)
        Their predicted positions, px (NaN: behind the camera).
    blend_px : float
        Distance below which two stars blend, px.

    Returns
    -------
    ndarray of bool, shape (M,)
    """
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.all():  # (every predicted star in front of the camera): no selection
        xo, yo, near_ok = x, y, near
    else:
        xo, yo, near_ok = x[ok], y[ok], near[ok]
    if len(xo) < 2:
        return np.ones(len(cat_index), bool)
    where = np.minimum(near_ok.searchsorted(cat_index), len(xo) - 1)
    dx = xo[where][:, None] - xo[None, :]
    dy = yo[where][:, None] - yo[None, :]
    d2 = dx * dx + dy * dy
    d2[np.arange(len(where)), where] = np.inf  # the star itself
    return np.sqrt(d2.min(axis=1)) > blend_px


def unblended_compiled(cat_index, near, *, x, y, blend_px: float) -> np.ndarray | None:
    """:func:`unblended_numpy` in the compiled kernel (bit for bit); None where not built."""
    if _trackc is None:
        return None
    cat_index = np.ascontiguousarray(cat_index, dtype=np.int64)
    x = np.ascontiguousarray(x, dtype=float)
    out = np.empty(len(cat_index), np.uint8)
    _trackc.unblended(
        x,
        np.ascontiguousarray(y, dtype=float),
        np.ascontiguousarray(near, dtype=np.int64),
        len(x),
        cat_index,
        len(cat_index),
        float(blend_px),
        out,
    )
    return out.view(bool)
