"""The expected pixels of groups of stars, and their Jacobian.

Each modelled star is given a box around its track (its nodes' extent padded by ``half_px``);
stars whose boxes overlap share a *group*, whose pixel grid is the union of their boxes (padded
to one shape for all groups, so that the fit works on arrays). In a group's pixel ``j``::

    mu_j = b_g + sum_s F_s T_s(j),   T_s(j) = sum_k w_k P(x_j - x_sk, y_j - y_sk)

``P`` the pixel-integrated PSF (:mod:`starsense.model.psf`), ``(x_sk, y_sk)`` the star's
position at time node ``k`` (:mod:`starsense.model.tracks`), ``F_s`` its electrons, ``b_g`` the
group's background per pixel. The derivatives: ``d mu / d F_s = T_s``, ``d mu / d b_g = 1`` and
``d mu / d p = sum_s F_s sum_k w_k (-dP/ddx dx_sk/dp - dP/ddy dy_sk/dp)`` for the geometric
parameters ``p`` (attitude, rate).

Stars with a *free* flux are fitted; a *fixed* star (a faint catalogue neighbour) adds its
light at a given flux and moves with the attitude, but is not fitted.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from starsense.errors import InputError
from starsense.model.psf import PixelPSF, gaussian_pixel_1d
from starsense.model.tracks import NodePositions

__all__ = ["MAX_WINDOW_PIXELS", "Evaluation", "Windows", "evaluate", "make_windows"]

#: most pixels the groups of one frame may hold (padded): the fit holds ~(slots + parameters)
#: arrays of this size, ~100 MB at 400,000
MAX_WINDOW_PIXELS = 400_000


@dataclass(frozen=True)
class Windows:
    """Groups of stars and their pixel grids.

    Attributes
    ----------
    row0, col0 : ndarray of int, shape (G,)
        Detector index of each group grid's first pixel.
    shape : (int, int)
        The grids' (padded) rows and columns.
    on : ndarray of bool, shape (G, H, W)
        Pixels of the group that lie on the detector (padding and off-detector pixels are not).
    group : ndarray of int, shape (S,)
        Each source's group.
    slot : ndarray of int, shape (S,)
        Each free source's place among its group's fitted fluxes (-1 for a fixed one).
    n_slots : int
        Most free sources in a group.
    box : ndarray of int, shape (S, 4)
        Each source's box in its group's grid: row0, row1, col0, col1.
    """

    row0: np.ndarray
    col0: np.ndarray
    shape: tuple[int, int]
    on: np.ndarray
    group: np.ndarray
    slot: np.ndarray
    n_slots: int
    box: np.ndarray

    @property
    def n_groups(self) -> int:
        """G, the number of groups."""
        return len(self.row0)

    @functools.cached_property
    def size_classes(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """The sources' box sizes (rows, columns) and, for each, the sources of that size."""
        b = self.box
        sizes = np.column_stack([b[:, 1] - b[:, 0], b[:, 3] - b[:, 2]])
        return [(z, np.flatnonzero((sizes == z).all(axis=1))) for z in np.unique(sizes, axis=0)]


def _boxes(x, y, half_px: float) -> np.ndarray:
    """Detector boxes (row0, row1, col0, col1) of the tracks' nodes padded by ``half_px``."""
    r0 = np.floor(np.nanmin(y, axis=1) - half_px + 0.5).astype(np.int64)
    r1 = np.floor(np.nanmax(y, axis=1) + half_px + 0.5).astype(np.int64) + 1
    c0 = np.floor(np.nanmin(x, axis=1) - half_px + 0.5).astype(np.int64)
    c1 = np.floor(np.nanmax(x, axis=1) + half_px + 0.5).astype(np.int64) + 1
    return np.column_stack([r0, r1, c0, c1])


def _merge(boxes: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Group index of each box: free boxes that overlap (transitively) share one.

    A fixed source joins the group of the first free box it overlaps (-1: none).
    """
    n = len(boxes)
    parent = np.arange(n)

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    def overlap(a, b):
        return a[0] < b[1] and b[0] < a[1] and a[2] < b[3] and b[2] < a[3]

    idx = np.flatnonzero(free)
    order = idx[np.argsort(boxes[idx, 2])]  # sweep along the columns
    for i_pos, i in enumerate(order):
        for j in order[i_pos + 1 :]:
            if boxes[j, 2] >= boxes[i, 3]:
                break
            if overlap(boxes[i], boxes[j]):
                parent[root(j)] = root(i)
    group = np.full(n, -1)
    roots = {r: g for g, r in enumerate(sorted({root(i) for i in idx}))}
    for i in idx:
        group[i] = roots[root(i)]
    for i in np.flatnonzero(~free):
        for j in idx:
            if overlap(boxes[i], boxes[j]):
                group[i] = group[j]
                break
    return group


def make_windows(
    x, y, *, half_px: float, shape: tuple[int, int], free
) -> tuple[Windows, np.ndarray]:
    """Group sources by their boxes and lay out the grids.

    Parameters
    ----------
    x, y : ndarray, shape (S, K)
        Node positions of the sources, px.
    half_px : float
        Box half-size around each track, px.
    shape : (int, int)
        The detector's (rows, columns).
    free : ndarray of bool, shape (S,)
        Sources whose flux is fitted.

    Returns
    -------
    windows : Windows
    kept : ndarray of int
        The sources modelled (fixed sources outside every free box are dropped), indices into
        the input; ``windows`` describes them in that order.
    """
    free = np.asarray(free, bool)
    boxes = _boxes(x, y, half_px)
    group = _merge(boxes, free)
    kept = np.flatnonzero(group >= 0)
    boxes, group, free = boxes[kept], group[kept], free[kept]
    n_groups = int(group.max()) + 1 if len(group) else 0
    big = np.iinfo(np.int64).max
    g_r0, g_c0 = np.full(n_groups, big), np.full(n_groups, big)
    g_r1, g_c1 = np.full(n_groups, -big), np.full(n_groups, -big)
    np.minimum.at(g_r0, group, boxes[:, 0])
    np.maximum.at(g_r1, group, boxes[:, 1])
    np.minimum.at(g_c0, group, boxes[:, 2])
    np.maximum.at(g_c1, group, boxes[:, 3])
    h = int((g_r1 - g_r0).max()) if n_groups else 0
    w = int((g_c1 - g_c0).max()) if n_groups else 0
    if n_groups * h * w > MAX_WINDOW_PIXELS:
        raise InputError(
            f"the stars' windows span {n_groups} x {h} x {w} pixels, more than the "
            f"{MAX_WINDOW_PIXELS:,} a fit may hold"
        )
    rows = g_r0[:, None] + np.arange(h)[None, :]
    cols = g_c0[:, None] + np.arange(w)[None, :]
    inside = (rows < g_r1[:, None])[:, :, None] & (cols < g_c1[:, None])[:, None, :]
    on_det = ((rows >= 0) & (rows < shape[0]))[:, :, None] & ((cols >= 0) & (cols < shape[1]))[
        :, None, :
    ]
    slot = np.full(len(kept), -1)
    members = np.flatnonzero(free)
    order = members[np.argsort(group[members], kind="stable")]  # by group, in source order
    first = np.searchsorted(group[order], group[order], side="left")
    slot[order] = np.arange(len(order)) - first
    local = boxes - np.column_stack([g_r0[group], g_r0[group], g_c0[group], g_c0[group]])
    windows = Windows(g_r0, g_c0, (h, w), inside & on_det, group, slot, int(slot.max()) + 1, local)
    return windows, kept


@dataclass(frozen=True)
class Evaluation:
    """The model on the windows at one set of parameters.

    Attributes
    ----------
    templates : ndarray, shape (G, M, H, W)
        Each free source's light per electron (``T_s``), at its group and slot.
    fixed : ndarray, shape (G, H, W)
        The fixed sources' light, electrons.
    jacobian : ndarray, shape (G, P, H, W) or None
        ``d mu / d p`` of the geometric parameters at the given fluxes, electrons per unit.
    """

    templates: np.ndarray
    fixed: np.ndarray
    jacobian: np.ndarray | None


def _gaussian_width_1d(d, sigma):
    """Return d/dsigma of a 1-D Gaussian's pixel fractions at offsets ``d``.

    ``-(a phi(a) - b phi(b)) / sigma`` with ``a, b = (d +- 1/2) / sigma``.
    """
    a, b = (d + 0.5) / sigma, (d - 0.5) / sigma
    return -(a * np.exp(-0.5 * a * a) - b * np.exp(-0.5 * b * b)) * _INV_SQRT2PI / sigma


_INV_SQRT2PI = 1.0 / math.sqrt(2.0 * math.pi)


def _static_gaussian(sigma, nodes: NodePositions, idx, rows, cols, gradient, width):
    """:func:`source_stamps` of Gaussian stars at rest (one time node)."""
    px, dpx = gaussian_pixel_1d(cols - nodes.x[idx, :1], sigma)  # (S, w)
    py, dpy = gaussian_pixel_1d(rows - nodes.y[idx, :1], sigma)  # (S, h)
    t = py[:, :, None] * px[:, None, :]
    if not gradient:
        return t, None
    ax, ay = nodes.dx[idx, 0], nodes.dy[idx, 0]  # (S, P)
    gx = py[:, :, None] * dpx[:, None, :]  # d t / d(dx)
    gy = dpy[:, :, None] * px[:, None, :]
    d = -(ax[:, :, None, None] * gx[:, None] + ay[:, :, None, None] * gy[:, None])
    if width:
        dw = _gaussian_width_1d(rows - nodes.y[idx, :1], sigma)[:, :, None] * px[:, None, :]
        dw += py[:, :, None] * _gaussian_width_1d(cols - nodes.x[idx, :1], sigma)[:, None, :]
        d = np.concatenate([d, dw[:, None]], axis=1)
    return t, d


def source_stamps(psf: PixelPSF, nodes: NodePositions, idx, *, rows, cols, gradient=True,
                  width=False):  # fmt: skip
    """Return templates (S, h, w) of sources ``idx`` and their derivatives (S, P, h, w).

    Over pixel rows (S, h) and columns (S, w) of the detector. With ``width`` (a Gaussian), the
    derivative with respect to the PSF's sigma is appended (P + 1 columns).
    """
    wk = nodes.weights
    xk, yk = nodes.x[idx], nodes.y[idx]  # (S, K)
    if psf.spec.is_gaussian and len(wk) == 1:  # at rest: outer products, no sums over time
        return _static_gaussian(psf.sigma_px, nodes, idx, rows, cols, gradient, width)
    if psf.spec.is_gaussian:  # separable: sums over nodes are matrix products
        sigma = psf.sigma_px
        dxp, dyp = cols[:, None, :] - xk[:, :, None], rows[:, None, :] - yk[:, :, None]
        px, dpx = gaussian_pixel_1d(dxp, sigma)
        py, dpy = gaussian_pixel_1d(dyp, sigma)
        t = np.einsum("skr,k,skc->src", py, wk, px)
        if not gradient:
            return t, None
        ax = wk[None, :, None] * nodes.dx[idx]  # (S, K, P)
        ay = wk[None, :, None] * nodes.dy[idx]
        d = -(
            np.einsum("skr,skp,skc->sprc", py, ax, dpx)
            + np.einsum("skr,skp,skc->sprc", dpy, ay, px)
        )
        if width:
            sx, sy = _gaussian_width_1d(dxp, sigma), _gaussian_width_1d(dyp, sigma)
            dw = np.einsum("skr,k,skc->src", sy, wk, px) + np.einsum("skr,k,skc->src", py, wk, sx)
            d = np.concatenate([d, dw[:, None]], axis=1)
        return t, d
    dxg = cols[:, None, None, :] - xk[:, :, None, None]  # (S, K, h, w)
    dyg = rows[:, None, :, None] - yk[:, :, None, None]
    if not gradient:
        return np.einsum("k,skrc->src", wk, psf.evaluate(dxg, dyg, gradient=False)), None
    v, gx, gy = psf.evaluate(dxg, dyg)
    t = np.einsum("k,skrc->src", wk, v)
    d = -(
        np.einsum("skrc,skp->sprc", gx, wk[None, :, None] * nodes.dx[idx])
        + np.einsum("skrc,skp->sprc", gy, wk[None, :, None] * nodes.dy[idx])
    )
    return t, d


def evaluate(windows: Windows, psf: PixelPSF, nodes: NodePositions, *, fluxes, free,
             gradient: bool = True, width: bool = False) -> Evaluation:  # fmt: skip
    """Return the templates, the fixed light and the geometric Jacobian on the windows.

    Parameters
    ----------
    windows : Windows
    psf : PixelPSF
    nodes : NodePositions
        Node positions of the sources, in the windows' order.
    fluxes : ndarray, shape (S,)
        Electrons of each source (those of free sources weight the Jacobian).
    free : ndarray of bool, shape (S,)
    gradient : bool
        Compute the Jacobian.
    width : bool
        Append the derivative with respect to a Gaussian PSF's sigma to the Jacobian.
    """
    g_n, (h, w), m = windows.n_groups, windows.shape, windows.n_slots
    width = width and psf.spec.is_gaussian
    n_par = nodes.dx.shape[-1] + int(width)
    templates = np.zeros(g_n * m * h * w)
    fixed = np.zeros(g_n * h * w)
    jac = np.zeros(g_n * n_par * h * w) if gradient else None
    box = windows.box
    fluxes = np.asarray(fluxes, dtype=float)
    for size, idx in windows.size_classes:  # sources of one box size at a time, batched
        g = windows.group[idx]
        rows = (windows.row0[g] + box[idx, 0])[:, None] + np.arange(size[0])[None, :]
        cols = (windows.col0[g] + box[idx, 2])[:, None] + np.arange(size[1])[None, :]
        t, d = source_stamps(psf, nodes, idx, rows=rows, cols=cols, gradient=gradient, width=width)
        # each stamp's pixels as flat indices of its group's (H, W) grid
        local = (box[idx, 0][:, None, None] + np.arange(size[0])[None, :, None]) * w + (
            box[idx, 2][:, None, None] + np.arange(size[1])[None, None, :]
        )
        fr = free[idx]
        slot_of = (g[fr] * m + windows.slot[idx][fr])[:, None, None] * (h * w)
        templates[(slot_of + local[fr]).ravel()] = t[fr].ravel()
        if (~fr).any():
            at = (g[~fr][:, None, None] * (h * w) + local[~fr]).ravel()
            fixed += np.bincount(at, (fluxes[idx][~fr, None, None] * t[~fr]).ravel(), fixed.size)
        if gradient:
            par = (g[:, None] * n_par + np.arange(n_par)[None, :])[:, :, None, None] * (h * w)
            at = (par + local[:, None]).ravel()
            jac += np.bincount(at, (fluxes[idx][:, None, None, None] * d).ravel(), jac.size)
    return Evaluation(
        templates.reshape(g_n, m, h, w),
        fixed.reshape(g_n, h, w),
        None if jac is None else jac.reshape(g_n, n_par, h, w),
    )
