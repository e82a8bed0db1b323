"""Where each star's window lies, how windows group, and whether a fit can hold them.

A star's window is the box of its track's nodes padded by ``half_px``
(:func:`track_boxes`); free stars whose boxes overlap share a group where that stays compact
(:func:`merged_groups`). A fit holds the groups' grids padded to one shape, and evaluates
the model at every source's nodes in every group its box reaches: :func:`over_capacity`
says when that passes what a fit may hold (:data:`MAX_WINDOW_PIXELS`, :data:`MAX_WORK`).
:mod:`starsense.model.windows` lays the windows out; :func:`window_capacity` asks the same
question of a frame's geometry alone (a prediction's).
"""

from __future__ import annotations

import math

import numpy as np

from starsense.model.stamps import stamp_side

__all__ = [
    "MAX_WINDOW_PIXELS",
    "MAX_WORK",
    "merged_groups",
    "over_capacity",
    "track_boxes",
    "window_capacity",
    "window_layout",
]

#: most pixels the groups of one frame may hold (padded): the fit holds ~(slots + parameters)
#: arrays of this size, ~8 MB each at 1,000,000
MAX_WINDOW_PIXELS = 1_000_000
#: most PSF evaluations (pixels x time nodes over every source in every group it reaches) of
#: one evaluation of the model: ~0.5 s of NumPy a step
MAX_WORK = 2e7


def window_layout(x, y, *, half_px: float, free: np.ndarray):
    """Return the sources' boxes, their groups, the groups' boxes and which group each reaches.

    ``(boxes (S, 4), group (S,), group boxes (G, 4), hit (S, G))``: every source is drawn in
    every group its box reaches.
    """
    boxes = track_boxes(x, y, half_px)
    side = 2 * (2 * math.ceil(half_px) + 1)  # a compact blend: two stars' boxes a side
    group = merged_groups(boxes, free, side)
    n_groups = int(group.max()) + 1 if np.any(free) else 0
    big = np.iinfo(np.int64).max
    gb = np.column_stack([np.full(n_groups, big), np.full(n_groups, -big)] * 2)
    fr = np.flatnonzero(free)
    np.minimum.at(gb[:, 0], group[fr], boxes[fr, 0])
    np.maximum.at(gb[:, 1], group[fr], boxes[fr, 1])
    np.minimum.at(gb[:, 2], group[fr], boxes[fr, 2])
    np.maximum.at(gb[:, 3], group[fr], boxes[fr, 3])
    hit = (
        (boxes[:, None, 0] < gb[None, :, 1])
        & (gb[None, :, 0] < boxes[:, None, 1])
        & (boxes[:, None, 2] < gb[None, :, 3])
        & (gb[None, :, 2] < boxes[:, None, 3])
    )
    return boxes, group, gb, hit


def over_capacity(boxes, gb, hit, *, n_nodes: int, half_px: float) -> str:
    """Say why a fit cannot hold these windows (its pixels or its work), or ``""``."""
    n_groups = len(gb)
    h = int((gb[:, 1] - gb[:, 0]).max()) if n_groups else 0
    w = int((gb[:, 3] - gb[:, 2]).max()) if n_groups else 0
    if n_groups * h * w > MAX_WINDOW_PIXELS:
        return (
            f"the stars' windows span {n_groups} x {h} x {w} pixels, more than the "
            f"{MAX_WINDOW_PIXELS:,} a fit may hold"
        )
    area = (boxes[:, 1] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 2])
    if n_nodes > 1:  # tracks: each node's stamp, then the box it is added into
        area = np.minimum(area, stamp_side(half_px) ** 2 + area // n_nodes)
    work = n_nodes * float((hit * area[:, None]).sum())
    if work > MAX_WORK:
        return (
            f"the stars' tracks and their neighbours' cover {work:.3g} pixel-nodes, more than "
            f"the {MAX_WORK:.3g} a fit may evaluate (long streaks crossing a crowded field)"
        )
    return ""


def window_capacity(x, y, *, half_px: float, free) -> str:
    """Say why a fit cannot hold the windows of these tracks, or ``""`` where it can.

    The rule :func:`make_windows` refuses by (the groups' padded pixels, the pixel-nodes the
    model evaluates), without laying the windows out: what a prediction asks of a frame's
    geometry before any frame exists. Parameters as :func:`make_windows`'s.
    """
    free = np.asarray(free, bool)
    boxes, _, gb, hit = window_layout(x, y, half_px=half_px, free=free)
    return over_capacity(boxes, gb, hit, n_nodes=np.asarray(x).shape[1], half_px=half_px)


def track_boxes(x, y, half_px: float) -> np.ndarray:
    """Detector boxes (row0, row1, col0, col1) of the tracks' nodes padded by ``half_px``."""
    r0 = np.floor(np.nanmin(y, axis=1) - half_px + 0.5).astype(np.int64)
    r1 = np.floor(np.nanmax(y, axis=1) + half_px + 0.5).astype(np.int64) + 1
    c0 = np.floor(np.nanmin(x, axis=1) - half_px + 0.5).astype(np.int64)
    c1 = np.floor(np.nanmax(x, axis=1) + half_px + 0.5).astype(np.int64) + 1
    return np.column_stack([r0, r1, c0, c1])


def _area(box) -> float:
    """Pixels of a box (row0, row1, col0, col1)."""
    return float((box[1] - box[0]) * (box[3] - box[2]))


def merged_groups(boxes: np.ndarray, free: np.ndarray, max_side: int) -> np.ndarray:
    """Return each free box's group (-1 for fixed ones).

    Overlapping free boxes share a group while the union of the group's boxes stays within
    ``max_side`` px a side, or holds no more pixels than the two grids it replaces: parallel
    tracks that share their pixels (a close pair at a body rate moves along one line) are one
    group whatever their length, crossing streaks (whose union is a square) keep their own.
    """
    n = len(boxes)
    parent = np.arange(n)
    # in floating point: a track that leaves the camera's view during the exposure (a wrong
    # rate) reaches coordinates whose differences and products overflow int64
    boxes = np.asarray(boxes, dtype=float)
    ext = boxes.copy()  # each root's union box

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    idx = np.flatnonzero(free)
    order = idx[np.argsort(boxes[idx, 2])]  # sweep along the columns
    for i_pos, i in enumerate(order):
        for j in order[i_pos + 1 :]:
            if boxes[j, 2] >= boxes[i, 3]:
                break
            a, b = boxes[i], boxes[j]
            if not (a[0] < b[1] and b[0] < a[1]):
                continue
            ri, rj = root(i), root(j)
            if ri == rj:
                continue
            u = np.r_[
                min(ext[ri, 0], ext[rj, 0]),
                max(ext[ri, 1], ext[rj, 1]),
                min(ext[ri, 2], ext[rj, 2]),
                max(ext[ri, 3], ext[rj, 3]),
            ]
            if (u[1] - u[0] <= max_side and u[3] - u[2] <= max_side) or _area(u) <= _area(
                ext[ri]
            ) + _area(ext[rj]):
                parent[rj] = ri
                ext[ri] = u
    group = np.full(n, -1)
    roots = {r: g for g, r in enumerate(sorted({root(i) for i in idx}))}
    for i in idx:
        group[i] = roots[root(i)]
    return group
