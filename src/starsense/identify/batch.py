"""Triangle identification of many small star sets at once (Liebe 1992), vectorised over trials.

A Monte Carlo of star identification solves the same tiny problem many times: a handful of
measured stars against a catalogue that is the same handful of true stars.
:func:`identify_triangles` runs the triangle algorithm with verification by the remaining stars
on a whole batch of such trials in one set of array operations (Lin et al. 2024, sec. 4).
"""

from __future__ import annotations

from itertools import combinations, permutations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from starsense._validate import positive_float
from starsense.errors import InputError

__all__ = ["ID_CORRECT", "ID_FAILED", "ID_WRONG", "identify_triangles"]

ID_FAILED, ID_CORRECT, ID_WRONG = 0, 1, 2
"""Outcome codes of :func:`identify_triangles`: no unique triangle, the true stars, others."""


def _pair_angles(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return the inter-star angles (..., N, N) of unit vectors (..., N, 3), rad (chord form)."""
    chord = np.linalg.norm(v[..., :, None, :] - v[..., None, :, :], axis=-1)
    return 2.0 * np.arcsin(np.clip(chord / 2.0, 0.0, 1.0))


def _handedness(v: NDArray[np.float64], tri: NDArray[np.int_]) -> NDArray[np.float64]:
    """Return the sign of the triple product of triangles ``tri`` (T, 3) of sets (..., N, 3)."""
    a, b, c = v[..., tri[:, 0], :], v[..., tri[:, 1], :], v[..., tri[:, 2], :]
    return np.sign(np.einsum("...i,...i->...", a, np.cross(b, c)))


def _sides(d: NDArray[np.float64], tri: NDArray[np.int_]) -> NDArray[np.float64]:
    """Return the three sides (M, T, 3) of triangles ``tri`` (T, 3) from angles ``d`` (M, N, N)."""
    return np.stack(
        [d[:, tri[:, 0], tri[:, 1]], d[:, tri[:, 0], tri[:, 2]], d[:, tri[:, 1], tri[:, 2]]],
        axis=-1,
    )


def _verify(dm, dc, combos, perms, k, t, p, n, tol) -> NDArray[np.bool_]:
    """Return which candidates (k, t, p) the remaining stars confirm, shape (K,).

    A candidate is confirmed when every remaining measured star has a remaining catalogue star
    whose angles to the triangle's three vertices match within ``tol``.
    """
    others = np.array([[j for j in range(n) if j not in c] for c in combos])  # (T, N-3)
    rest_m = others[t]  # (K, N-3) remaining measured stars
    in_p = np.zeros((len(k), n), dtype=bool)
    in_p[np.arange(len(k))[:, None], perms[p]] = True
    # angles from each remaining measured star to the measured triangle's vertices
    am = dm[k[:, None, None], rest_m[:, :, None], combos[t][:, None, :]]  # (K, N-3, 3)
    # angles from every catalogue star to the catalogue triangle's vertices
    ac = dc[k[:, None, None], np.arange(n)[None, :, None], perms[p][:, None, :]]  # (K, N, 3)
    ok = np.all(np.abs(am[:, :, None, :] - ac[:, None, :, :]) <= tol, axis=-1)
    ok &= ~in_p[:, None, :]  # (K, N-3, N)
    return np.all(ok.any(axis=-1), axis=-1)


def identify_triangles(
    measured: ArrayLike, catalogue: ArrayLike, tolerance_rad: float
) -> NDArray[np.int_]:
    """Identify many small star sets at once by triangles, verified by the remaining stars.

    Liebe 1992's triangle algorithm. The catalogue of each trial is its own guide stars (Lin et
    al. 2024, sec. 4: "the reference star catalog does not include interfering stars"). The
    measured triangles are tried in turn; a catalogue triangle (an ordered vertex triple) is a
    candidate when its three sides match the measured ones within ``tolerance_rad`` and it has
    the same handedness (the sign of the triple product, which a rotation keeps). A candidate
    is verified when every remaining measured star has a remaining catalogue star whose angles
    to the triangle's three vertices match within the tolerance. The first measured triangle
    with exactly one verified candidate decides; a trial where no triangle does is a failure.
    The algorithm sees only inter-star angles, never the star indices, so the outcome is
    compared to the truth (star ``i`` measured is catalogue star ``i``) only at the end.

    Parameters
    ----------
    measured : array_like, shape (M, N, 3)
        Measured (noisy) camera-frame unit vectors, N >= 3.
    catalogue : array_like, shape (M, N, 3)
        The guide stars' true directions in any one frame per trial (angles are all that
        matter).
    tolerance_rad : float
        Largest accepted difference between a measured and a catalogue angle, rad, > 0.

    Returns
    -------
    ndarray of int, shape (M,)
        :data:`ID_CORRECT`, :data:`ID_WRONG` or :data:`ID_FAILED` per trial.
    """
    tol = positive_float(tolerance_rad, "tolerance_rad")
    bm = np.asarray(measured, dtype=np.float64)
    bc = np.asarray(catalogue, dtype=np.float64)
    if bm.ndim != 3 or bm.shape[-1] != 3 or bm.shape != bc.shape:
        raise InputError(
            f"measured and catalogue must both have shape (M, N, 3), got {bm.shape} and {bc.shape}"
        )
    m, n = bm.shape[:2]
    if n < 3:
        raise InputError(f"triangle identification needs at least 3 guide stars, got {n}")
    combos = np.array(list(combinations(range(n), 3)))  # measured triangles, tried in order
    perms = np.array(list(permutations(range(n), 3)))  # catalogue ordered triangles
    dm, dc = _pair_angles(bm), _pair_angles(bc)
    hm, hc = _handedness(bm, combos), _handedness(bc, perms)
    side_m, side_c = _sides(dm, combos), _sides(dc, perms)  # (M, T, 3), (M, P, 3)
    match = np.all(np.abs(side_m[:, :, None, :] - side_c[:, None, :, :]) <= tol, axis=-1)
    match &= hm[:, :, None] == hc[:, None, :]
    # verification of the (sparse) candidates by the remaining stars
    k, t, p = np.nonzero(match)
    verified = np.ones(len(k), dtype=bool)
    if n > 3 and len(k):
        verified = _verify(dm, dc, combos, perms, k, t, p, n, tol)
    n_verified = np.zeros((m, len(combos)), dtype=int)
    np.add.at(n_verified, (k[verified], t[verified]), 1)
    decided = n_verified == 1
    has = decided.any(axis=1)
    first = np.argmax(decided, axis=1)
    out = np.full(m, ID_FAILED, dtype=int)
    if has.any():
        sel = verified & (t == first[k]) & has[k]
        kk, pp = k[sel], p[sel]
        correct = np.all(perms[pp] == combos[first[kk]], axis=-1)
        out[kk] = np.where(correct, ID_CORRECT, ID_WRONG)
    return out
