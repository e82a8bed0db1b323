"""Stars of one or two pixels: held aside as hot pixels first, tried as stars when that fails.

A single frame cannot tell a star whose PSF fits in one pixel (a wide imager summed on board to
0.3 deg a pixel, PSF sigma 0.3-0.5 px: the brightest neighbour holds 5-25 % of the peak) from
a hot pixel by its shape alone. The robust extraction holds such spikes aside
(:func:`starsense.detect.background.hot_pixel_mask`): a frame of a sharp camera with hundreds
of hot pixels (a CMOS sensor at high gain) solves on its stars. When the frame does not solve
that way and spikes were held aside, they are not hot pixels by default: the frame is detected
again with them kept as candidates (ranked by brightness with the rest) and solved. A spike is
then told apart by what a star never does: it is **absent from the catalogue** at the solved
attitude (no catalogue star, to a magnitude beyond the faintest matched, within
:data:`HOT_REACH_PX` of it). The solution counts the spikes, the stars among them and the hot
pixels, and its notes list the hot pixels and why they are hot.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import time

import numpy as np

from starsense.detect import hot_pixel_mask

__all__ = ["HOT_REACH_PX", "MIN_HELD", "classify_spikes", "retry_with_spikes", "spike_detector"]

#: spikes held aside before the frame is tried with them (fewer: a couple of defects, not stars)
MIN_HELD = 3
#: a spike with a catalogue star within this many pixels at the solved attitude is a star
HOT_REACH_PX = 2.0
#: hot pixels listed by place in the solution's notes (the rest counted)
LISTED = 10


def spike_detector(detector):
    """Return a copy of the robust ``detector`` that keeps one- and two-pixel spikes."""
    kept = copy.copy(detector)
    kept.remove_hot_pixels = False
    return kept


def retry_with_spikes(solver, a, sol, *, t0: float, stages: dict, obs_time, solve):
    """Return ``sol``, or the frame solved with its held-aside spikes kept as candidates.

    Parameters
    ----------
    solver : Solver
    a : ndarray (rows, columns)
        The frame.
    sol : Solution
        The robust extraction's answer.
    t0 : float
        The solve's start (perf_counter).
    stages : dict
        Stage times so far.
    obs_time : str or Time or None
    solve : callable
        ``solve(a, detector, t0, stages, obs_time)``: the solver's solve of a frame with the
        detector given.

    Returns
    -------
    Solution
        ``sol`` when it solved, held fewer than :data:`MIN_HELD` spikes aside, or the retry did
        not solve either; else the retry's solution (``stage_ms["robust_ms"]`` says so), with
        its spikes classified (:func:`classify_spikes`).
    """
    if sol.solved or sol.counts.get("hot_pixels", 0) < MIN_HELD:
        return sol
    stages = {**stages, "robust_ms": (time.perf_counter() - t0) * 1e3}
    again = solve(a, solver.spike_detector, t0, stages, obs_time)
    if not again.solved:
        return sol
    counts, notes = classify_spikes(solver, a, again)
    return dataclasses.replace(
        again, counts={**again.counts, **counts}, notes=(*again.notes, *notes)
    )


def classify_spikes(solver, a, sol) -> tuple[dict, tuple[str, ...]]:
    """Tell the solved frame's spikes apart: stars (on the catalogue) and hot pixels (absent).

    Parameters
    ----------
    solver : Solver
    a : ndarray (rows, columns)
        The frame.
    sol : Solution
        Its solution from the spike-keeping extraction.

    Returns
    -------
    counts : dict
        ``spikes`` (detections on a pixel the robust extraction held aside), ``spike_stars``
        (of those, matched or on a catalogue star), ``hot_pixels_absent_from_catalogue``.
    notes : tuple of str
        The hot pixels' places and why.
    """
    held = hot_pixel_mask(a, solver.detector.frame_background(a))
    xy = np.asarray(sol.centroids_px, dtype=float)
    rows, cols = held.shape
    r = np.clip(np.rint(xy[:, 1]).astype(int), 0, rows - 1)
    c = np.clip(np.rint(xy[:, 0]).astype(int), 0, cols - 1)
    spike = np.zeros(len(xy), dtype=bool)
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            spike |= held[np.clip(r + dr, 0, rows - 1), np.clip(c + dc, 0, cols - 1)]
    matched = np.zeros(len(xy), dtype=bool)
    matched[[d for d, _ in sol.matches]] = True
    on_sky = matched | _near_catalogue(solver, sol, xy)
    hot = np.flatnonzero(spike & ~on_sky)
    counts = {
        "spikes": int(spike.sum()),
        "spike_stars": int((spike & on_sky).sum()),
        "hot_pixels_absent_from_catalogue": len(hot),
    }
    if not len(hot):
        return counts, ()
    places = ", ".join(f"({xy[i, 0]:.0f}, {xy[i, 1]:.0f})" for i in hot[:LISTED])
    more = f" and {len(hot) - LISTED} more" if len(hot) > LISTED else ""
    note = (
        f"{int(spike.sum())} one- or two-pixel spikes kept as candidates (the frame did not "
        f"solve without them): {int((spike & on_sky).sum())} are catalogue stars; hot pixels "
        f"(absent from the catalogue at the solved attitude): {places}{more}"
    )
    return counts, (note,)


def _near_catalogue(solver, sol, xy) -> np.ndarray:
    """Whether a catalogue star lies within :data:`HOT_REACH_PX` of each place (pinhole)."""
    near = np.zeros(len(xy), dtype=bool)
    if sol.focal_px is None or sol.rotation is None or not len(sol.matches):
        return near
    catalog = solver.catalog
    if "V" not in catalog.mags:
        return near
    stars = solver.sky_stars("V")
    # to a magnitude beyond the faintest matched star (a fainter one could not have lit it)
    matched = np.isin(np.asarray(catalog.ids)[stars.rows], [i for _, i in sol.matches])
    if not matched.any():
        return near
    limit = float(stars.mags[matched].max()) + 1.0
    rows, cols = sol.image_shape
    m = sol.rotation.as_matrix()
    half = math.atan(math.hypot(rows, cols) / 2.0 / sol.focal_px)
    idx = np.asarray(stars.tree.query_ball_point(m[2], 2 * math.sin(min(half, 1.5) / 2)), int)
    idx = idx[stars.mags[idx] <= limit]
    u = stars.vectors[idx] @ m.T
    u = u[u[:, 2] > 0]
    if not len(u):
        return near
    px = np.column_stack(
        [(cols - 1) / 2 + sol.focal_px * u[:, 0] / u[:, 2],
         (rows - 1) / 2 + sol.focal_px * u[:, 1] / u[:, 2]]
    )  # fmt: skip
    d2 = ((xy[:, None, :] - px[None, :, :]) ** 2).sum(axis=2)
    return d2.min(axis=1) <= HOT_REACH_PX**2
