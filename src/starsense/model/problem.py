"""What a forward-model fit holds while it iterates: its sources, its pixels in parts, its arrays.

The groups of a frame (:mod:`starsense.model.windows`) differ in size: most hold one star in a
box a few PSF sigmas across, a few hold a blend, a streak or a star whose track is long. On one
grid of the largest group's shape for all, the fit's arrays (templates, Jacobian, weights) would
be mostly padding: on an ST-16 frame of ~200 stars with one blend, 2.6 times the pixels. The
groups are therefore laid out in *parts*, each on a grid of its own groups' largest extent
(:func:`split_parts`). The likelihood is a sum over groups, so the parts' sums add: the fit does
not depend on the split, only its cost does.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from starsense._workspace import scratch
from starsense.model.psf import PixelPSF, pixel_psf
from starsense.model.tracks import node_positions, track_nodes
from starsense.model.windows import MAX_NODES, Windows, evaluate, make_windows, window_half_px

__all__ = ["MAX_PARTS", "PART_VALUES", "Part", "Problem", "linearised", "set_up", "split_parts"]

#: most parts a fit's groups are laid out in
MAX_PARTS = 8
#: what one more part costs beside its arrays, in array values: its calls each step (~0.2 ms
#: of NumPy and the compiled sums), about the time 20,000 values of its arrays take
PART_VALUES = 20_000
#: most float64 values of a fit's arrays kept in the thread's work buffer between fits (16 MB);
#: a larger fit allocates its own
MAX_KEPT_VALUES = 1 << 21
#: the width's central difference, a fraction of the width
WIDTH_STEP = 2e-3


def _zeros(n: int) -> np.ndarray:
    """Return ``n`` float64 zeros, in this thread's work buffer for the model when they fit.

    Reused by the next fit: freshly mapped pages cost more to fault in than the kernel takes
    to fill them (~1 ms a fit of 20,000 pixels). The buffer's length is a power of two, so
    that fits of other sizes share it; one fit at a time holds it (no fit runs inside another).
    """
    if n > MAX_KEPT_VALUES:
        return np.zeros(n)
    out = scratch("model.fit", (1 << max(int(n) - 1, 0).bit_length(),), np.float64)[:n]
    out.fill(0.0)
    return out


def _part_cost(extent: np.ndarray, slots: np.ndarray, values: int) -> np.ndarray:
    """Return the cost of the parts ``extent[:k]`` for every ``k`` (prefix maxima), values."""
    h = np.maximum.accumulate(extent[:, 0])
    w = np.maximum.accumulate(extent[:, 1])
    m = np.maximum.accumulate(slots)
    return np.arange(1, len(slots) + 1) * h * w * (m + values) + PART_VALUES


def split_parts(windows: Windows, values_per_pixel: int) -> list[np.ndarray]:
    """Return the groups of each part (ascending), parts of groups of like extents.

    Each part's arrays hold ``(slots + values_per_pixel)`` values a pixel of its grid (the
    templates, the background's, the fixed light and the geometric Jacobian). The groups,
    ordered by area, are cut where a cut saves the most (the two parts' padded values and
    :data:`PART_VALUES` each, against the whole), again while a cut saves anything, to at most
    :data:`MAX_PARTS`.
    """
    w = windows
    if w.n_groups == 0:
        return []
    slots = np.bincount(w.group[w.group >= 0], minlength=w.n_groups).astype(np.int64)
    ext = w.extent.astype(np.int64)
    parts = [np.lexsort((slots, ext[:, 1], ext[:, 0] * ext[:, 1]))]
    while len(parts) < MAX_PARTS:
        best = (0.0, -1, 0)
        for i, ix in enumerate(parts):
            if len(ix) < 2:
                continue
            head = _part_cost(ext[ix], slots[ix], values_per_pixel)
            tail = _part_cost(ext[ix][::-1], slots[ix][::-1], values_per_pixel)[::-1]
            cut = head[:-1] + tail[1:]  # cut k + 1: ix[: k + 1] and ix[k + 1 :]
            k = int(np.argmin(cut))
            gain = float(head[-1] - cut[k])
            if gain > best[0]:
                best = (gain, i, k + 1)
        if best[1] < 0:
            break
        _, i, k = best
        ix = parts.pop(i)
        parts[i:i] = [ix[:k], ix[k:]]
    return [np.sort(ix) for ix in parts]


def _subset(w: Windows, groups: np.ndarray) -> Windows:
    """Return the windows of ``groups`` alone, on a grid of their largest extent."""
    new = np.full(w.n_groups, -1)
    new[groups] = np.arange(len(groups))
    ext = w.extent[groups]
    h, wd = int(ext[:, 0].max()), int(ext[:, 1].max())
    mine = (w.group >= 0) & (new[np.maximum(w.group, 0)] >= 0)
    group = np.where(mine, new[np.maximum(w.group, 0)], -1)
    slot = np.where(mine, w.slot, -1)
    q = np.flatnonzero(new[w.pair_group] >= 0)
    return Windows(
        w.row0[groups], w.col0[groups], (h, wd), np.ascontiguousarray(w.on[groups, :h, :wd]),
        group, slot, int(slot.max()) + 1 if mine.any() else 0, w.pair_source[q],
        new[w.pair_group[q]], w.pair_slot[q], w.pair_box[q], w.half_px, w.node_origin, ext,
    )  # fmt: skip


def _data(image, windows: Windows, detector) -> tuple[np.ndarray, np.ndarray]:
    """Return the windows' pixels in electrons above the bias (G, N) and which are usable."""
    h, w = windows.shape
    rows = windows.row0[:, None, None] + np.arange(h)[None, :, None]
    cols = windows.col0[:, None, None] + np.arange(w)[None, None, :]
    on = windows.on
    r = np.clip(rows, 0, image.shape[0] - 1)
    c = np.clip(cols, 0, image.shape[1] - 1)
    counts = np.asarray(image)[r, c].astype(float)
    e = (counts - detector.bias_counts) / detector.gain_counts_per_e
    use = on & (counts < detector.saturation_counts - 0.5) & (e < 0.999 * detector.full_well_e)
    g = windows.n_groups
    return e.reshape(g, -1), use.reshape(g, -1)


@dataclass
class Part:
    """Groups of like extents on a grid of their own: their windows, pixels and arrays.

    ``data`` (G, N) the pixels' electrons above the bias, ``use`` which enter the sums;
    ``buffers`` the model's arrays (:meth:`Problem.lay_out`).
    """

    windows: Windows
    data: np.ndarray
    use: np.ndarray
    buffers: tuple | None = None

    @functools.cached_property
    def mine(self) -> np.ndarray:
        """The free sources whose fluxes this part fits (indices of the problem's sources)."""
        return np.flatnonzero(self.windows.group >= 0)

    def fluxes(self, lin_values: np.ndarray) -> np.ndarray:
        """Return the fitted fluxes of :attr:`mine` from the part's linear values."""
        s = self.mine
        return lin_values[self.windows.group[s], self.windows.slot[s]]


@dataclass
class Problem:
    """What stays fixed while the fit iterates: the sources, the parts' pixels, the quadrature."""

    sensor: object
    vectors: np.ndarray
    free: np.ndarray
    fluxes: np.ndarray
    parts: list[Part]
    fractions: np.ndarray
    weights: np.ndarray
    fit_rate: bool
    fit_width: bool
    kept: np.ndarray

    @property
    def n_pixels(self) -> int:
        """The pixels in the sums."""
        return sum(int(p.use.sum()) for p in self.parts)

    def lay_out(self, n_par: int) -> None:
        """Lay the parts' arrays out in one work buffer (:func:`evaluate`'s ``out``).

        Each part's: the linear design (its last row ones), the fixed light, the Jacobian of
        ``n_par`` parameters.
        """
        if all(p.buffers is not None and p.buffers[2].shape[1] == n_par for p in self.parts):
            return
        sizes = [
            p.windows.n_groups * int(np.prod(p.windows.shape)) * (p.windows.n_slots + 2 + n_par)
            for p in self.parts
        ]
        flat, at = _zeros(sum(sizes)), 0
        for p, size in zip(self.parts, sizes, strict=True):
            w = p.windows
            g, m, (h, wd) = w.n_groups, w.n_slots, w.shape
            mine = flat[at : at + size]
            at += size
            a, b = g * (m + 1) * h * wd, g * (m + 2) * h * wd
            lin = mine[:a].reshape(g, m + 1, h, wd)
            lin[:, -1] = 1.0  # the background's
            p.buffers = (lin, mine[a:b].reshape(g, h, wd), mine[b:].reshape(g, n_par, h, wd))


def set_up(image, sensor, rotation, *, rate, psf, sources, flags, window_rate=None) -> Problem:
    """Lay out the windows around the sources' tracks, in parts, and read their pixels.

    ``sources``: (free vectors, fixed vectors, fixed electrons); ``flags``: (fit_rate,
    fit_width). The tracks at ``window_rate`` where given (else at the rate's).
    """
    v_free, v_fix, f_fix = sources
    fit_rate, fit_width = flags
    allv = np.concatenate([v_free, v_fix])
    free = np.r_[np.ones(len(v_free), bool), np.zeros(len(v_fix), bool)]
    lay = {"sigma_px": psf.sigma_px, "max_nodes": MAX_NODES}  # nodes bounded by their memory
    moving = fit_rate or bool(np.any(rate))
    frac, wts, nodes = track_nodes(
        sensor, (v_free, allv), rotation, rate_rad_s=rate, moving=moving, **lay
    )
    if window_rate is not None:  # the windows laid around the tracks of another rate
        nodes = track_nodes(
            sensor, (v_free, allv), rotation, rate_rad_s=window_rate, moving=True, **lay
        )[2]
    windows, kept = make_windows(
        nodes.x, nodes.y, half_px=window_half_px(psf), shape=image.shape, free=free
    )
    n_par = (6 if fit_rate else 3) + int(fit_width)
    parts = []
    for groups in split_parts(windows, 2 + n_par):
        w = _subset(windows, groups)
        parts.append(Part(w, *_data(image, w, sensor.detector)))
    fluxes = np.r_[np.zeros(len(v_free)), f_fix][kept]
    return Problem(
        sensor, allv[kept], free[kept], fluxes, parts, frac, wts, fit_rate, fit_width, kept
    )


def linearised(pb: Problem, psf: PixelPSF, rotation, *, rate, lin_values: list[np.ndarray]):
    """Return each part's linear design (G, M+1, N), geometric Jacobian (G, P, N) and model."""
    nodes = node_positions(
        pb.sensor,
        pb.vectors,
        rotation,
        rate_rad_s=rate,
        exposure_s=pb.sensor.exposure_s,
        fractions=pb.fractions,
        weights=pb.weights,
        fit_rate=pb.fit_rate,
    )
    fl = pb.fluxes
    for p, lv in zip(pb.parts, lin_values, strict=True):
        fl[p.mine] = p.fluxes(lv)  # the Jacobian at these fluxes
    exact = pb.fit_width and psf.spec.is_gaussian  # the width's derivative in closed form
    pb.lay_out(nodes.dx.shape[-1] + int(exact))
    return [
        _part_terms(p, psf, nodes, fl, lv, (pb.fit_width, exact))
        for p, lv in zip(pb.parts, lin_values, strict=True)
    ]


def _part_terms(p: Part, psf: PixelPSF, nodes, fl, lin_values, width):
    """One part's linear design, geometric Jacobian and model (:func:`linearised`).

    ``width``: (the width is fitted, its derivative is in closed form).
    """
    w = p.windows
    fit_width, exact = width
    ev = evaluate(w, psf, nodes, fluxes=fl, width=exact, out=p.buffers)
    g_n, m = w.n_groups, w.n_slots
    lin = p.buffers[0].reshape(g_n, m + 1, -1)
    jac = ev.jacobian.reshape(g_n, ev.jacobian.shape[1], -1)
    if fit_width and not exact:  # d mu / d sigma by a central difference of the width
        h = WIDTH_STEP * psf.sigma_px
        sides = []
        for sign in (1.0, -1.0):
            other = pixel_psf(psf.spec, psf.sigma_px + sign * h)
            e = evaluate(w, other, nodes, fluxes=fl, gradient=False)
            sides.append(e.fixed + np.einsum("gm,gmhw->ghw", lin_values[:, :m], e.templates))
        dw = (sides[0] - sides[1]) / (2.0 * h)
        jac = np.concatenate([jac, dw.reshape(g_n, 1, -1)], axis=1)
    mu = ev.fixed.reshape(g_n, -1) + np.einsum("gm,gmn->gn", lin_values, lin)
    return lin, jac, mu
