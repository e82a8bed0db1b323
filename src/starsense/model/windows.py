"""The expected pixels of groups of stars, and their Jacobian.

Each modelled star is given a box around its track (its nodes' extent padded by ``half_px``).
Free stars (their fluxes fitted) whose boxes overlap share a *group* when the union of their
boxes stays compact (a blend at rest: its stars' fluxes are fitted together) or holds no more
pixels than their own boxes (a close pair at a body rate: two streaks along one line); stars
whose overlapping boxes would make a large group (long crossing streaks) keep groups of their
own.
Every pixel belongs to one group at most: the group of the free star whose track is nearest
(so that no pixel counts twice), within the group's box. Each group's grid is padded to one
shape for all groups, so that the fit works on arrays (the fit lays groups of like sizes out on
grids of their own: :mod:`starsense.model.problem`). In a group's pixel ``j``::

    mu_j = b_g + sum_s F_s T_s(j),   T_s(j) = sum_k w_k P(x_j - x_sk, y_j - y_sk)

summed over every source whose box reaches the group's: ``P`` the pixel-integrated PSF
(:mod:`starsense.model.psf`), ``(x_sk, y_sk)`` the star's position at time node ``k``
(:mod:`starsense.model.tracks`), ``F_s`` its electrons, ``b_g`` the group's background per
pixel. The derivatives: ``d mu / d F_s = T_s``, ``d mu / d b_g = 1`` and
``d mu / d p = sum_s F_s sum_k w_k (-dP/ddx dx_sk/dp - dP/ddy dy_sk/dp)`` for the geometric
parameters ``p`` (attitude, rate).

A group fits the fluxes of its own free stars; another group's star whose light reaches it, and
a *fixed* star (a faint catalogue neighbour), add their light at a given flux (the other
group's current fit) and move with the attitude.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from starsense.errors import InputError
from starsense.model.boxes import over_capacity, window_layout
from starsense.model.psf import PixelPSF
from starsense.model.stamps import source_stamps
from starsense.model.tracks import NodePositions

try:  # the compiled form of evaluate() for Gaussian stars at rest (setup.py)
    import starsense.model._modelc as _modelc
except ImportError:  # pragma: no cover - built without a C compiler: the NumPy form
    _modelc = None

__all__ = [
    "MAX_NODES",
    "WINDOW_HALF_SIGMAS",
    "Evaluation",
    "Windows",
    "evaluate",
    "make_windows",
    "window_half_px",
]

#: most time nodes over every source (free and fixed) of one fit: each holds its position and
#: its derivatives (14 floats) and laying them out 21 more, ~0.3 GB at 1,000,000
MAX_NODES = 1_000_000
#: a star's box reaches this many PSF sigmas (+1 px) beyond its track
WINDOW_HALF_SIGMAS = 3.5


def window_half_px(psf: PixelPSF) -> float:
    """Half-size of a star's box beyond its track, px."""
    return WINDOW_HALF_SIGMAS * psf.sigma_px + 1.0


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
        The group's pixels: on the detector, in its box, nearer its own free stars' tracks
        than any other group's (padding and other pixels are not).
    group : ndarray of int, shape (S,)
        Each free source's own group (-1 for a fixed one).
    slot : ndarray of int, shape (S,)
        Each free source's place among its group's fitted fluxes (-1 for a fixed one).
    n_slots : int
        Most free sources in a group.
    pair_source, pair_group, pair_slot : ndarray of int, shape (Q,)
        Every source drawn in every group its box reaches: the source, the group, and its slot
        there (-1 where its flux is given, not fitted there).
    pair_box : ndarray of int, shape (Q, 4)
        The part of the source's box inside the group's grid: row0, row1, col0, col1 (local).
    half_px : float
        The reach of a star's light from each point of its track, px (its box's padding).
    node_origin : ndarray of int, shape (S, K, 2)
        The first row and column of each time node's stamp (:func:`source_stamps`), laid
        where the windows were made (as the boxes are: the model stays smooth in its
        parameters while the fit moves the nodes).
    extent : ndarray of int, shape (G, 2)
        Each group's box: its rows and columns (at most ``shape``).
    """

    row0: np.ndarray
    col0: np.ndarray
    shape: tuple[int, int]
    on: np.ndarray
    group: np.ndarray
    slot: np.ndarray
    n_slots: int
    pair_source: np.ndarray
    pair_group: np.ndarray
    pair_slot: np.ndarray
    pair_box: np.ndarray
    half_px: float
    node_origin: np.ndarray
    extent: np.ndarray

    @property
    def n_groups(self) -> int:
        """G, the number of groups."""
        return len(self.row0)

    @functools.cached_property
    def size_classes(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """The pairs' box sizes (rows, columns) and, for each, the pairs of that size."""
        b = self.pair_box
        sizes = np.column_stack([b[:, 1] - b[:, 0], b[:, 3] - b[:, 2]])
        return [(z, np.flatnonzero((sizes == z).all(axis=1))) for z in np.unique(sizes, axis=0)]


def _nearest_mask(windows_shape, g_r0, g_c0, group, x, y, hit, on):
    """Keep in each group the pixels nearer its own free tracks than another group's.

    ``hit`` (S, G): which groups each source's box reaches (only there it competes). A
    pixel's distance to a track is to its nearest time node; a group's pixels are queried
    against a k-d tree of its own tracks' nodes and one of the other free tracks' reaching it
    (a streak's box holds ~1e4 pixels and its track ~1e3 nodes: a tree, not every pair).
    """
    (h, w), out = windows_shape, on.copy()
    free = group >= 0
    for g in np.flatnonzero(hit[free].sum(axis=0) > 1):  # a group no other track reaches: all
        others = free & hit[:, g] & (group != g)
        if not others.any():
            continue
        mine = free & (group == g)
        pix = np.column_stack(
            [np.repeat(g_r0[g] + np.arange(h), w), np.tile(g_c0[g] + np.arange(w), h)]
        ).astype(float)
        d_own = _nearest_node(pix, x[mine], y[mine])
        d_other = _nearest_node(pix, x[others], y[others])
        out[g] &= (d_own <= d_other).reshape(h, w)
    return out


def _nearest_node(pix, x, y) -> np.ndarray:
    """Return each pixel's (row, column) distance to the nearest of the nodes (x, y), px."""
    tree = cKDTree(np.column_stack([np.ravel(y), np.ravel(x)]))
    return tree.query(pix)[0]


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
    boxes, group, gb, hit = window_layout(x, y, half_px=half_px, free=free)
    why = over_capacity(boxes, gb, hit, n_nodes=np.asarray(x).shape[1], half_px=half_px)
    if why:
        raise InputError(why)
    n_groups = len(gb)
    kept = np.flatnonzero(hit.any(axis=1) | free)
    boxes, group, free, hit = boxes[kept], group[kept], free[kept], hit[kept]
    x, y = np.asarray(x)[kept], np.asarray(y)[kept]
    h = int((gb[:, 1] - gb[:, 0]).max()) if n_groups else 0
    w = int((gb[:, 3] - gb[:, 2]).max()) if n_groups else 0
    slot = np.full(len(kept), -1)
    members = np.flatnonzero(free)
    order = members[np.argsort(group[members], kind="stable")]  # by group, in source order
    first = np.searchsorted(group[order], group[order], side="left")
    slot[order] = np.arange(len(order)) - first
    p_src, p_grp = np.nonzero(hit)
    p_slot = np.where(group[p_src] == p_grp, slot[p_src], -1)
    lo = np.column_stack([gb[p_grp, 0], gb[p_grp, 0], gb[p_grp, 2], gb[p_grp, 2]])
    p_box = (
        np.column_stack(
            [
                np.maximum(boxes[p_src, 0], gb[p_grp, 0]),
                np.minimum(boxes[p_src, 1], gb[p_grp, 1]),
                np.maximum(boxes[p_src, 2], gb[p_grp, 2]),
                np.minimum(boxes[p_src, 3], gb[p_grp, 3]),
            ]
        )
        - lo
    )
    g_r0, g_c0 = gb[:, 0], gb[:, 2]
    rows = g_r0[:, None] + np.arange(h)[None, :]
    cols = g_c0[:, None] + np.arange(w)[None, :]
    inside = (rows < gb[:, 1, None])[:, :, None] & (cols < gb[:, 3, None])[:, None, :]
    on_det = ((rows >= 0) & (rows < shape[0]))[:, :, None] & ((cols >= 0) & (cols < shape[1]))[
        :, None, :
    ]
    on = _nearest_mask((h, w), g_r0, g_c0, group, x, y, hit, inside & on_det)
    n_slots = int(slot.max()) + 1 if len(slot) else 0
    origin = np.stack([np.floor(y - half_px + 0.5), np.floor(x - half_px + 0.5)], axis=-1)
    windows = Windows(
        g_r0, g_c0, (h, w), on, group, slot, n_slots, p_src, p_grp, p_slot, p_box, half_px,
        origin.astype(np.int64), np.column_stack([gb[:, 1] - gb[:, 0], gb[:, 3] - gb[:, 2]]),
    )  # fmt: skip
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


def evaluate(
    windows: Windows,
    psf: PixelPSF,
    nodes: NodePositions,
    *,
    fluxes,
    gradient: bool = True,
    width: bool = False,
    out: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> Evaluation:
    """Return the templates, the fixed light and the geometric Jacobian on the windows.

    Parameters
    ----------
    windows : Windows
    psf : PixelPSF
    nodes : NodePositions
        Node positions of the sources, in the windows' order.
    fluxes : ndarray, shape (S,)
        Electrons of each source (those of free sources weight the Jacobian).
    gradient : bool
        Compute the Jacobian.
    width : bool
        Append the derivative with respect to a Gaussian PSF's sigma to the Jacobian.
    out : (ndarray, ndarray, ndarray), optional
        Arrays to write into, reused over the steps of a fit (no new pages each step): the
        templates' (G, M + 1, H, W), of which the first M slots are written, the fixed light's
        (G, H, W) and the Jacobian's (G, P, H, W). The Evaluation's arrays are then views of
        them.
    """
    g_n, (h, w), m = windows.n_groups, windows.shape, windows.n_slots
    width = width and psf.spec.is_gaussian
    n_par = nodes.dx.shape[-1] + int(width)
    templates = np.zeros(g_n * m * h * w)
    fixed = np.zeros(g_n * h * w)
    fluxes = np.asarray(fluxes, dtype=float)
    if _modelc is not None and psf.spec.is_gaussian and len(nodes.weights) == 1:
        return _compiled(windows, psf, nodes, fluxes, (gradient, width), out)
    if out is not None:  # the NumPy form's arrays copied into the given ones
        ev = evaluate(windows, psf, nodes, fluxes=fluxes, gradient=gradient, width=width)
        out[0][:, :m] = ev.templates
        out[1][...] = ev.fixed
        if gradient:
            out[2][...] = ev.jacobian
        return Evaluation(out[0][:, :m], out[1], out[2] if gradient else None)
    # the fixed light and the Jacobian summed once over every class (a sum per class over the
    # whole grids cost the classes times the grids: hundreds of box sizes under long streaks)
    fixed_at, fixed_light, jac_at, jac_values = [], [], [], []
    for size, q in windows.size_classes:  # pairs of one box size at a time, batched
        g, src, box = windows.pair_group[q], windows.pair_source[q], windows.pair_box[q]
        rows = (windows.row0[g] + box[:, 0])[:, None] + np.arange(size[0])[None, :]
        cols = (windows.col0[g] + box[:, 2])[:, None] + np.arange(size[1])[None, :]
        t, d = source_stamps(
            psf,
            nodes,
            src,
            rows=rows,
            cols=cols,
            half_px=windows.half_px,
            origin=windows.node_origin[src],
            gradient=gradient,
            width=width,
        )
        # each stamp's pixels as flat indices of its group's (H, W) grid
        local = (box[:, 0][:, None, None] + np.arange(size[0])[None, :, None]) * w + (
            box[:, 2][:, None, None] + np.arange(size[1])[None, None, :]
        )
        fit_here = windows.pair_slot[q] >= 0
        slot_of = (g[fit_here] * m + windows.pair_slot[q][fit_here])[:, None, None] * (h * w)
        templates[(slot_of + local[fit_here]).ravel()] = t[fit_here].ravel()
        given = ~fit_here
        if given.any():
            fixed_at.append((g[given][:, None, None] * (h * w) + local[given]).ravel())
            fixed_light.append((fluxes[src][given, None, None] * t[given]).ravel())
        if gradient:
            par = (g[:, None] * n_par + np.arange(n_par)[None, :])[:, :, None, None] * (h * w)
            jac_at.append((par + local[:, None]).ravel())
            jac_values.append((fluxes[src][:, None, None, None] * d).ravel())
    if fixed_at:
        fixed = np.bincount(np.concatenate(fixed_at), np.concatenate(fixed_light), fixed.size)
    jac = None
    if gradient:
        size = g_n * n_par * h * w
        jac = np.zeros(size)
        if jac_at:
            jac = np.bincount(np.concatenate(jac_at), np.concatenate(jac_values), size)
    return Evaluation(
        templates.reshape(g_n, m, h, w),
        fixed.reshape(g_n, h, w),
        None if jac is None else jac.reshape(g_n, n_par, h, w),
    )


def _compiled(windows: Windows, psf: PixelPSF, nodes: NodePositions, fluxes, flags, out):
    """:func:`evaluate` of Gaussian stars at rest by the compiled kernel (the same sums).

    ``flags``: (gradient, width); ``out``: as :func:`evaluate`'s (zeroed here where summed).
    """
    gradient, width = flags
    g_n, (h, w), m = windows.n_groups, windows.shape, windows.n_slots
    n_geo = nodes.dx.shape[-1]
    n_par = n_geo + int(width)
    if out is None:
        lin, fixed = np.zeros((g_n, m + 1, h, w)), np.zeros((g_n, h, w))
        jac = np.zeros((g_n, n_par, h, w)) if gradient else np.zeros(0)
    else:  # a template is set over its box (the same pixels every step), the sums zeroed
        lin, fixed, jac = out
        fixed.fill(0.0)
        if gradient:
            jac.fill(0.0)

    def c(a, kind):
        return np.ascontiguousarray(a, dtype=kind)

    _modelc.static_gaussian(
        c(windows.pair_group, np.int64), c(windows.pair_source, np.int64),
        c(windows.pair_slot, np.int64), c(windows.pair_box, np.int64),
        c(windows.row0, np.int64), c(windows.col0, np.int64),
        c(nodes.x[:, 0], float), c(nodes.y[:, 0], float),
        c(nodes.dx[:, 0, :], float), c(nodes.dy[:, 0, :], float), c(fluxes, float),
        len(windows.pair_source), g_n, h, w, m, n_geo, float(psf.sigma_px),
        bool(gradient), bool(width), lin, fixed, jac,
    )  # fmt: skip
    return Evaluation(lin[:, :m], fixed, jac if gradient else None)
