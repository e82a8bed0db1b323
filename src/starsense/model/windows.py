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

from dataclasses import dataclass

import numpy as np

from starsense.errors import InputError
from starsense.model.psf import PixelPSF, gaussian_pixel_1d
from starsense.model.tracks import NodePositions

__all__ = ["MAX_WINDOW_PIXELS", "Evaluation", "Windows", "evaluate", "make_windows"]

#: most pixels the groups of one frame may hold (padded), to bound memory
MAX_WINDOW_PIXELS = 2_000_000


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
    g_r0 = np.array([boxes[group == g, 0].min() for g in range(n_groups)], dtype=np.int64)
    g_r1 = np.array([boxes[group == g, 1].max() for g in range(n_groups)], dtype=np.int64)
    g_c0 = np.array([boxes[group == g, 2].min() for g in range(n_groups)], dtype=np.int64)
    g_c1 = np.array([boxes[group == g, 3].max() for g in range(n_groups)], dtype=np.int64)
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
    for g in range(n_groups):
        members = np.flatnonzero((group == g) & free)
        slot[members] = np.arange(len(members))
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


def source_stamps(psf: PixelPSF, nodes: NodePositions, idx, rows, cols, gradient):
    """Return templates (S, h, w) of sources ``idx`` and their derivatives (S, P, h, w).

    Over pixel rows (S, h) and columns (S, w) of the detector.
    """
    wk = nodes.weights
    xk, yk = nodes.x[idx], nodes.y[idx]  # (S, K)
    if psf.spec.is_gaussian:  # separable: sums over nodes are matrix products
        px, dpx = gaussian_pixel_1d(cols[:, None, :] - xk[:, :, None], psf.sigma_px)
        py, dpy = gaussian_pixel_1d(rows[:, None, :] - yk[:, :, None], psf.sigma_px)
        t = np.einsum("skr,k,skc->src", py, wk, px)
        if not gradient:
            return t, None
        ax = wk[None, :, None] * nodes.dx[idx]  # (S, K, P)
        ay = wk[None, :, None] * nodes.dy[idx]
        d = -(
            np.einsum("skr,skp,skc->sprc", py, ax, dpx)
            + np.einsum("skr,skp,skc->sprc", dpy, ay, px)
        )
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


def evaluate(windows: Windows, psf: PixelPSF, nodes: NodePositions, fluxes, *, free,
             gradient: bool = True) -> Evaluation:  # fmt: skip
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
    """
    g_n, (h, w), m = windows.n_groups, windows.shape, windows.n_slots
    n_par = nodes.dx.shape[-1]
    templates = np.zeros((g_n, m, h, w))
    fixed = np.zeros((g_n, h, w))
    jac = np.zeros((g_n, n_par, h, w)) if gradient else None
    box = windows.box
    sizes = np.column_stack([box[:, 1] - box[:, 0], box[:, 3] - box[:, 2]])
    for size in np.unique(sizes, axis=0):  # sources of one box size at a time, batched
        idx = np.flatnonzero((sizes == size).all(axis=1))
        g = windows.group[idx]
        rows = (windows.row0[g] + box[idx, 0])[:, None] + np.arange(size[0])[None, :]
        cols = (windows.col0[g] + box[idx, 2])[:, None] + np.arange(size[1])[None, :]
        t, d = source_stamps(psf, nodes, idx, rows, cols, gradient)
        for n, s in enumerate(idx):
            sl = (slice(box[s, 0], box[s, 1]), slice(box[s, 2], box[s, 3]))
            if free[s]:
                templates[(windows.group[s], windows.slot[s], *sl)] = t[n]
            else:
                fixed[(windows.group[s], *sl)] += fluxes[s] * t[n]
            if gradient:
                jac[(windows.group[s], slice(None), *sl)] += fluxes[s] * d[n]
    return Evaluation(templates, fixed, jac)
