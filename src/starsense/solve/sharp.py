"""Stars of one or two pixels: held aside as hot pixels first, tried as stars when that fails.

A single frame cannot tell a star whose PSF fits in one pixel (a wide imager summed on board to
0.3 deg a pixel, PSF sigma 0.3-0.5 px: the brightest neighbour holds 5-25 % of the peak) from
a hot pixel by its shape alone. The robust extraction holds such spikes aside
(:func:`starsense.detect.hot_pixels.hot_pixel_mask`): a frame of a sharp camera with hundreds
of hot pixels (a CMOS sensor at high gain) solves on its stars. When the frame does not solve
that way and spikes were held aside, they are not hot pixels by default: the frame is detected
again with them kept as candidates and solved.

That retry takes the spikes for what they may be, the stars of an undersampled PSF:

- **Detected with a filter matched to a one-pixel star** when the PSF is not known (no sensor):
  the 1 px matched filter of a focused tracker keeps 56 % of a point source's ideal SNR (the
  weight of its centre over the root of its summed squared weights), so a star at 8 sigma in
  one pixel falls under a 5 sigma threshold; a filter of :data:`SPIKE_PSF_SIGMA_PX` keeps 96 %.
  A one-pixel star lights one pixel of that filtered frame, so one lit pixel is enough (the
  matched threshold and the significance test still apply).
- **Ranked by their evidence of being stars**: a star's light is the PSF integrated over the
  pixels, so its 8 neighbours hold some of it (at least 12 % of the peak pixel's for a
  Gaussian PSF of sigma >= 0.26 px, centred on a pixel, the least they can; 22 % at 0.3 px;
  a median of 56 % at 0.25 px for a star placed at random in its pixel). A detection whose
  neighbours hold less than :data:`MIN_NEIGHBOUR_SHARE` of its peak, significantly (3 sigma
  of the neighbours' noise), is sharper than such optics make: a defect's one pixel. It is
  not removed but ranked after every detection that shows a PSF, so the identification's
  patterns are built from those first (bright hot pixels, ranked by brightness, fill the
  brightest places otherwise).

A spike is finally told apart by what a star never does: it is **absent from the catalogue** at
the solved attitude (no catalogue star, to a magnitude beyond the faintest matched, within
:data:`HOT_REACH_PX` of it). The solution counts the spikes, the stars among them and the hot
pixels, and its notes list the hot pixels and why they are hot.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from starsense.detect import StarDetector, hot_pixel_mask

__all__ = [
    "HOT_REACH_PX",
    "MIN_HELD",
    "MIN_NEIGHBOUR_SHARE",
    "SPIKE_PSF_SIGMA_PX",
    "SpikeDetector",
    "classify_spikes",
    "neighbour_share",
    "retry_with_spikes",
    "spike_detector",
]

#: spikes held aside before the frame is tried with them (fewer: a couple of defects, not stars)
MIN_HELD = 3
#: a spike with a catalogue star within this many pixels at the solved attitude is a star
HOT_REACH_PX = 2.0
#: hot pixels listed by place in the solution's notes (the rest counted)
LISTED = 10
#: matched filter of the retry when the PSF is not known, px (module docstring)
SPIKE_PSF_SIGMA_PX = 0.5
#: least share of its peak pixel's light a star's 8 neighbours hold (module docstring)
MIN_NEIGHBOUR_SHARE = 0.1
#: significance, in sigmas of the neighbours' summed noise, of a share below that least one
SHARE_SIGMA = 3.0


class SpikeDetector(StarDetector):
    """The robust detector keeping one- and two-pixel spikes, ranking them by evidence.

    Its detections are those of the detector it was made from, with hot pixels kept (and, when
    the PSF is not known, the filter of a one-pixel star); their ``extra["rank"]`` orders them
    for the identification (module docstring): the brightness, every detection sharper than
    optics make ranked after all the others.
    """

    @classmethod
    def of(cls, detector: StarDetector, *, psf_known: bool) -> SpikeDetector:
        """Return the spike-keeping copy of the robust ``detector`` (module docstring)."""
        kept = cls.__new__(cls)
        kept.__dict__.update(detector.__dict__)
        kept.remove_hot_pixels = False
        if not psf_known:
            kept.psf_sigma_px = min(kept.psf_sigma_px, SPIKE_PSF_SIGMA_PX)
            kept.logic = dataclasses.replace(kept.logic, min_pixels=1)
        return kept

    def __call__(self, image):
        """Detect as the robust detector with spikes kept; ``extra["rank"]`` ranks them."""
        det = super().__call__(image)
        if not len(det):
            return det
        a = np.asarray(image)
        share, noise = neighbour_share(a, self.frame_background(a), x=det.x, y=det.y)
        sharp = share + SHARE_SIGMA * noise < MIN_NEIGHBOUR_SHARE
        rank = np.asarray(det.integrated_counts, dtype=float).copy()
        rank[sharp] -= float(rank.max()) + 1.0  # after every detection showing a PSF
        return dataclasses.replace(det, extra={**det.extra, "rank": rank})


def spike_detector(detector, *, psf_known: bool = True) -> SpikeDetector:
    """Return the spike-keeping copy of the robust ``detector`` (:class:`SpikeDetector`)."""
    return SpikeDetector.of(detector, psf_known=psf_known)


def retry_with_spikes(solver, a, sol, *, t0: float, stages: dict, obs_time, solve, restart):
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
    restart : callable
        ``restart()`` gives the retry's identifications a work budget of their own (the
        solver's ``max_patterns``): the robust extraction's unknown-field search, distortion
        guesses and mirror image spend the first one whole before a retry (a solve that
        retries looks up at most twice ``max_patterns``).

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
    restart()
    again = solve(a, solver.spike_detector, t0, stages, obs_time)
    if not again.solved:
        return sol
    counts, notes = classify_spikes(solver, a, again)
    return dataclasses.replace(
        again, counts={**again.counts, **counts}, notes=(*again.notes, *notes)
    )


def neighbour_share(a, background, *, x, y) -> tuple[np.ndarray, np.ndarray]:
    """Return the share of its peak pixel's light in each place's 8 neighbours, and its noise.

    Both over the local level: the median of the 16 pixels two away from the peak (a star of
    sigma <= 0.5 px puts under 0.2 % of its light in each), which follows a stray-light
    gradient or a glow the frame's background mesh smooths over.

    Parameters
    ----------
    a : ndarray (rows, columns)
        The frame, counts.
    background : Background
        Its background (its noise is used).
    x, y : ndarray (N,)
        Centroids, px; the peak pixel is the brightest of the 3 x 3 around each.

    Returns
    -------
    share : ndarray (N,)
        The 8 neighbours' counts above the local level over the peak pixel's (NaN where the
        peak is not above it, or the peak is too near the frame's edge to have the 16).
    noise : ndarray (N,)
        The share's noise: that of the 8 neighbours' sum less 8 times the median of 16
        (variance 8 + 64 (pi / 2) / 16 times a pixel's) over the peak pixel's counts.
    """
    rows, cols = a.shape
    pad = np.pad(a.astype(np.float64), 3, constant_values=np.nan)
    r = np.clip(np.rint(y).astype(int), 0, rows - 1) + 3
    c = np.clip(np.rint(x).astype(int), 0, cols - 1) + 3
    peak = np.full(len(r), -np.inf)
    pr, pc = r.copy(), c.copy()
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            v = np.nan_to_num(pad[r + dr, c + dc], nan=-np.inf)
            more = v > peak
            peak[more], pr[more], pc[more] = v[more], r[more] + dr, c[more] + dc
    two = [(dr, dc) for dr in range(-2, 3) for dc in range(-2, 3) if max(abs(dr), abs(dc)) == 2]
    level = np.median(np.stack([pad[pr + dr, pc + dc] for dr, dc in two]), axis=0)
    ring = sum(pad[pr + dr, pc + dc] for dr in (-1, 0, 1) for dc in (-1, 0, 1) if dr or dc)
    at = np.ravel_multi_index((np.clip(pr - 3, 0, rows - 1), np.clip(pc - 3, 0, cols - 1)), a.shape)
    sigma = np.broadcast_to(background.noise_at(at), peak.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        top = np.where(peak - level > 0, peak - level, np.nan)
        spread = math.sqrt(8.0 + 64.0 * (math.pi / 2.0) / 16.0)
        return (ring - 8.0 * level) / top, spread * sigma / top


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
