"""Streaks that run into each other: one detection for two stars, matched to neither.

Under slew every star of a frame is a streak, all parallel and as long. Where two streaks
lie side by side or end to end closer than their lit footprints reach, the detector's
connected-component labelling makes one region of them, and its centre of gravity is the
flux-weighted mean of the stars' positions, not either star's. The solver identifies a
detection by its centroid, within a few of its own sigma of a database star
(:mod:`starsense.solve.rematch`, ``MATCH_SIGMAS``): a star whose region is pulled further than
that by the streaks it has run into is not matched, and its light is not in the attitude fit.
At rest the same happens only to doubles closer than the PSF, which the solver references at
their photocentre; at a rate a star's reach is the streak's length, and in the frames of a
long exposure one star in five or more is lost that way.

:func:`match_chances` says which stars of the datasheet's prediction under slew are lost, from
the stars the frames hold down to the faintest detected at that rate:

* a streak's lit footprint: its ridge, ``N / ((l + sqrt(2 pi) s) sqrt(2 pi) s)`` electrons per
  pixel (``N`` the star's electrons, ``l`` its streak, ``s`` the PSF sigma; ``N / 2 pi s^2`` at
  rest), times the gain, against the lit-pixel threshold: lit to ``w = s sqrt(2 ln(ridge /
  threshold))`` px either side of the streak's line (where two streaks overlap only near
  their ends, at the ridge the PSF's edge leaves there);
* two footprints are one region where they overlap or touch diagonally (8-connectivity: the
  gap between the lines within ``w_1 + w_2 + sqrt 2``), or where the noise lights a chain of
  pixels across the gap at one place at least along the streaks with a chance of
  ``BRIDGED_CHANCE`` (each dark pixel lit with the chance of the gap's darkest point); that
  region's centroid window is its box grown by the detector's margin, and a
  streak that does not touch but crosses the window adds the part inside;
* the window's centre of gravity moves a star by ``|sum_k f_k d_k| / (N + sum_k f_k)`` (``f_k``
  the electrons of each star's light in the window, ``d_k`` its offset, :func:`pulled_px`):
  past the match radius (:func:`match_radius_px`: four of the star's own centroid sigma, or
  the verification's four sigma of its frame's median residual), it is not matched;
* a streak cut by the frame's edge is detected by the part left on it, whose middle is off the
  star's (:func:`edge_pull_px`), added to the pull;
* a streak whose ridge is near the threshold is lit in pieces where the noise lifts it, or not
  at all: matched in the fraction of draws where its nearest detected piece lands within the
  match radius (:mod:`~starsense.analysis.datasheet.pieces`), the pieces' offsets counted in
  the frame's median residual, and among the frame's brightest detections the verification
  takes (``max_detections``), or within four of the piece's own sigma where no other piece of
  its streak is (the solver's rematch).

The prediction counts each star's information times its chance of being matched.
"""

from __future__ import annotations

import inspect
import math

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation
from scipy.special import ndtr

from starsense.analysis.datasheet.field import field_stars_cam
from starsense.analysis.datasheet.noise import empty_pixel_sigma_counts
from starsense.analysis.datasheet.pieces import (
    FLUX_BINS,
    footprint_half_width_px,
    piece_offsets_px,
    ridge_counts,
)
from starsense.identify.verify import Verifier
from starsense.solve.rematch import MATCH_SIGMAS

__all__ = [
    "edge_pull_px",
    "footprint_half_width_px",
    "match_chances",
    "match_radius_px",
    "pulled_px",
    "ridge_counts",
    "streaks_px_of",
]


#: the verification's initial match radius, a fraction of the field's width (its default)
_VERIFY_RADIUS = float(inspect.signature(Verifier).parameters["match_radius"].default)
#: the verification pairs a frame's brightest this many detections (its default)
_VERIFIED = int(inspect.signature(Verifier).parameters["max_detections"].default)
#: the median of a 2-d residual of per-axis sigma 1 (Rayleigh): sqrt(2 ln 2)
_RAYLEIGH_MEDIAN = math.sqrt(2.0 * math.log(2.0))
#: a gap is bridged where the noise lights a chain of pixels across it at one place at least
#: along the streaks with this chance
BRIDGED_CHANCE = 0.5
#: the seed of the pieces' draws (:func:`~starsense.analysis.datasheet.pieces.piece_offsets_px`):
#: a datasheet predicts the same for the same sensor
PIECES_SEED = 20140101


def streaks_px_of(sensor, v_cam, rates_rad_s) -> tuple[np.ndarray, np.ndarray]:
    """Mid-exposure pixel positions (P, 2) and streaks, start to end (P, 2), of stars v_cam."""
    v_cam = np.array(v_cam, dtype=float)  # a writable copy (Rotation.apply needs one)
    half = Rotation.from_rotvec(np.asarray(rates_rad_s) * 0.5 * sensor.exposure_s)
    x, y = sensor.project(v_cam)
    xs, ys = sensor.project(half.apply(v_cam))
    xe, ye = sensor.project(half.inv().apply(v_cam))
    return np.column_stack([x, y]), np.column_stack([xe - xs, ye - ys])


def _joined(sensor, ridges, along, across, length: float) -> np.ndarray:
    """Return whether a streak's lit region joins each neighbour's (module docstring).

    ``ridges``: the streak's ridge and the neighbours' (K,), counts; ``along``, ``across``:
    the neighbours' offsets, px. Where the two streaks overlap along their length by ``o``
    px, each is ``o / 2`` from its end there, where its ridge is ``Phi(o / 2 s)`` of the
    whole (the PSF's edge; a half at the very end, beyond it the gap between the ends).
    """
    s = sensor.detector.psf_sigma_px
    lit = float(sensor.detection.lit_pixel_counts)
    overlap = length - np.abs(along)
    end = ndtr(np.maximum(overlap, 0.0) / (2.0 * s))
    r_i, r_k = ridges[0] * end, ridges[1] * end
    w_i, w_k = (s * np.sqrt(2.0 * np.log(np.maximum(r / lit, 1.0))) for r in (r_i, r_k))
    gap = np.hypot(np.maximum(-overlap, 0.0), np.abs(across))
    joined = (gap <= w_i + w_k + math.sqrt(2.0)) & (np.minimum(r_i, r_k) >= lit)
    # beyond: the dark pixels between the footprints, each lit by the noise with the chance
    # of the gap's darkest point (the two profiles' sum), as a chain at one place at least
    # along the streaks
    v = np.linspace(0.0, 1.0, 17)[None, :] * gap[:, None]
    prof = r_i[:, None] * np.exp(-0.5 * (v / s) ** 2)
    prof = prof + r_k[:, None] * np.exp(-0.5 * ((gap[:, None] - v) / s) ** 2)
    chance = ndtr((prof.min(axis=1) - lit) / empty_pixel_sigma_counts(sensor))
    chain = np.maximum(np.ceil((gap - w_i - w_k) / math.sqrt(2.0)) - 1.0, 1.0)
    places = np.maximum(overlap, 0.0) + np.minimum(w_i, w_k) + 1.0
    bridged = 1.0 - (1.0 - chance**chain) ** places
    return joined | (bridged >= BRIDGED_CHANCE)


def match_radius_px(sensor, frames, *, sigma_px, pull_px, counted=None) -> np.ndarray:
    """Return how far from its star each detection can be and be matched, px.

    The identification's verification pairs a frame's detections within four times the sigma
    its median residual implies (:class:`starsense.identify.verify.Verifier`: twice
    ``min(r, max(4 sigma, r / 20))`` from its initial radius ``r``, a fraction of the field's
    width), and the solver then each one within ``MATCH_SIGMAS`` of its own sigma
    (:mod:`starsense.solve.rematch`): the wider of the two. A residual is a detection's pull
    and its noise, whose median is ``1.1774 sigma`` (Rayleigh).

    Parameters
    ----------
    sensor : Sensor
        The camera (its detector's width).
    frames : ndarray (N,) of int
        The frame of each star.
    sigma_px : ndarray (N,)
        Its centroid's sigma per axis, px.
    pull_px : ndarray (N,)
        Its detection's offset from the star besides its noise: the pull (:func:`pulled_px`)
        and where a streak lit in pieces puts its detection, px.
    counted : ndarray (N,) of bool, optional
        The stars detected, whose residuals the verification sees (default: all).
    """
    frames, sigma = np.asarray(frames), np.asarray(sigma_px, dtype=float)
    residual = np.hypot(np.asarray(pull_px, dtype=float), _RAYLEIGH_MEDIAN * sigma)
    counted = np.ones(len(sigma), bool) if counted is None else np.asarray(counted, bool)
    first = _VERIFY_RADIUS * max(sensor.detector.columns, sensor.detector.rows)  # the field
    out = np.zeros(len(sigma))
    for f in np.unique(frames):
        at = frames == f
        seen = residual[at & counted] if (at & counted).any() else residual[at]
        r = first
        for _ in range(2):
            r = min(r, max(MATCH_SIGMAS * float(np.median(seen)) / _RAYLEIGH_MEDIAN, r / 20))
        out[at] = np.maximum(r, MATCH_SIGMAS * sigma[at])
    return out


def _inside_fraction(p0, p1, box) -> tuple[np.ndarray, np.ndarray]:
    """Return the fraction of segments p0 -> p1 (K, 2) inside ``box`` and that part's middle.

    ``box`` = (x0, x1, y0, y1); Liang-Barsky clipping.
    """
    d = p1 - p0
    t0, t1 = np.zeros(len(p0)), np.ones(len(p0))
    x0, x1, y0, y1 = box
    for q, lo, hi in ((0, x0, x1), (1, y0, y1)):
        dq = d[:, q]
        flat = np.abs(dq) < 1e-12
        outside = flat & ((p0[:, q] < lo) | (p0[:, q] > hi))
        t1 = np.where(outside, -1.0, t1)
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (lo - p0[:, q]) / dq, (hi - p0[:, q]) / dq
        enter, leave = np.minimum(ta, tb), np.maximum(ta, tb)
        t0 = np.where(flat, t0, np.maximum(t0, enter))
        t1 = np.where(flat, t1, np.minimum(t1, leave))
    frac = np.clip(t1 - t0, 0.0, 1.0)
    mid = p0 + 0.5 * (t0 + t1)[:, None] * d
    return frac, mid


def edge_pull_px(sensor, centres_px, streaks_px) -> np.ndarray:
    """Return how far the frame's edge moves each streak's detection from its middle, px.

    The detection holds the part of the streak on the frame: its middle is that part's
    (inf where none of it is on the frame).
    """
    xy = np.asarray(centres_px, dtype=float).reshape(-1, 2)
    half = 0.5 * np.asarray(streaks_px, dtype=float).reshape(-1, 2)
    det = sensor.detector
    box = (-0.5, det.columns - 0.5, -0.5, det.rows - 0.5)
    frac, mid = _inside_fraction(xy - half, xy + half, box)
    return np.where(frac > 0.0, np.hypot(*(mid - xy).T), np.inf)


def pulled_px(sensor, frames, *, centres_px, streaks_px, electrons, others,
              margin_px: int = 2) -> np.ndarray:  # fmt: skip
    """Return how far the other stars' streaks pull each star's detection centroid, px.

    The module docstring: a star run into joins the region with its whole streak, another's
    streak through the region's window (its box, the streak and its lit half-width, grown by
    ``margin_px``) adds the part inside.

    Parameters
    ----------
    sensor : Sensor
        The camera (PSF, gain, noise, lit-pixel threshold).
    frames : ndarray (N,) of int
        The frame of each star.
    centres_px, streaks_px : ndarray (N, 2)
        Each star's mid-exposure position and streak, px.
    electrons : ndarray (N,)
        Its electrons over the exposure.
    others : (ndarray (M,) of int, ndarray (M, 2), ndarray (M,))
        Every detectable star of the frames (the stars themselves among them): frame, position
        (px) and electrons.
    margin_px : int
        The detector's centroid window margin around a region's box, px.

    Returns
    -------
    ndarray (N,)
        px; 0 where nothing is in reach.
    """
    frames = np.asarray(frames)
    xy = np.asarray(centres_px, dtype=float).reshape(-1, 2)
    streak = np.asarray(streaks_px, dtype=float).reshape(-1, 2)
    n_e = np.asarray(electrons, dtype=float)
    o_frame, o_xy, o_e = (np.asarray(a) for a in others)
    o_xy, o_e = o_xy.astype(float).reshape(-1, 2), o_e.astype(float)
    length = np.hypot(streak[:, 0], streak[:, 1])
    w = footprint_half_width_px(sensor, n_e, length)
    ridge = ridge_counts(sensor, n_e, length)
    out = np.zeros(len(n_e))
    order = np.argsort(o_frame, kind="stable")
    starts = np.searchsorted(o_frame[order], np.unique(frames))
    ends = np.searchsorted(o_frame[order], np.unique(frames), side="right")
    for f, a, b in zip(np.unique(frames), starts, ends, strict=True):
        mine = np.flatnonzero((frames == f) & (length > 0) & (n_e > 0))
        theirs = order[a:b]
        if len(theirs) < 2 or len(mine) == 0:
            continue
        pos, e_k = o_xy[theirs], o_e[theirs]
        ridge_k = ridge_counts(sensor, e_k, float(np.median(length[mine])))
        w_k = footprint_half_width_px(sensor, e_k, float(np.median(length[mine])))
        reach = 1.5 * length[mine] + w[mine] + float(w_k.max()) + margin_px + 2.0
        near_all = cKDTree(pos).query_ball_point(xy[mine], reach)
        for i, near in zip(mine, near_all, strict=True):
            d = pos[near] - xy[i]
            far = np.hypot(d[:, 0], d[:, 1]) > 1e-6  # not the star itself
            k, d = np.asarray(near, dtype=int)[far], d[far]
            if len(k) == 0:
                continue
            u = streak[i] / length[i]
            across = d[:, 0] * u[1] - d[:, 1] * u[0]
            touch = _joined(sensor, (ridge[i], ridge_k[k]), d @ u, across, float(length[i]))
            half = 0.5 * np.abs(streak[i]) + w[i] + margin_px
            box = (-half[0], half[0], -half[1], half[1])
            frac, mid = _inside_fraction(d - 0.5 * streak[i], d + 0.5 * streak[i], box)
            frac, mid = np.where(touch, 1.0, frac), np.where(touch[:, None], d, mid)
            pull = e_k[k] * frac
            out[i] = np.hypot(*(pull @ mid)) / (n_e[i] + pull.sum())
    return out


def match_chances(model, fov, *, matrices, rates_rad_s, detectable, frames, centres_px,
                  streaks_px, electrons, cov_px2):  # fmt: skip
    """Return each predicted star's chance of being matched under slew (module docstring).

    0 where other streaks pull its detection further than the match radius
    (:func:`pulled_px`, :func:`match_radius_px`), else the chance that its nearest detection,
    a piece where the streak is lit in pieces
    (:func:`~starsense.analysis.datasheet.pieces.piece_offsets_px`), lands within it.

    Parameters
    ----------
    model : StarModel
        The datasheet's star model (sensor, sensitivity).
    fov : RectangularFov
    matrices : ndarray (M, 3, 3)
        The frames' attitudes, ICRS -> camera.
    rates_rad_s : ndarray (M, 3)
        Their body rates, camera frame.
    detectable : (ndarray (K, 3), ndarray (K,))
        Every star the frames hold down to the faintest detected at the rate: ICRS vectors
        and V magnitudes.
    frames, centres_px, streaks_px, electrons : ndarray (P,), (P, 2), (P, 2), (P,)
        The predicted stars: frame, mid-exposure position and streak (px), electrons.
    cov_px2 : ndarray (P, 2, 2)
        Their centroid covariance (own noise), px^2.
    """
    vectors, mags = (np.asarray(a, dtype=float) for a in detectable)
    everyone = field_stars_cam(fov, np.asarray(matrices), vectors)
    rates = np.asarray(rates_rad_s, dtype=float).reshape(-1, 3)
    centres_o, _ = streaks_px_of(model.sensor, everyone.v_cam, rates[everyone.point])
    sigma = np.sqrt(0.5 * np.trace(np.nan_to_num(cov_px2), axis1=1, axis2=2))
    others = (everyone.point, centres_o, model.sensitivity.electrons(mags[everyone.star]))
    frames = np.asarray(frames)
    pull = pulled_px(model.sensor, frames, centres_px=centres_px, streaks_px=streaks_px,
                     electrons=electrons, others=others)  # fmt: skip
    # a streak cut by the frame's edge is detected by the part left on it
    pull = np.hypot(pull, edge_pull_px(model.sensor, centres_px, streaks_px))
    # where each one's nearest detection lands (0 lit whole, inf not detected), its own sigma
    # and its counts: the solver pairs it within the verification's radius if it is among the
    # frame's brightest detections the verification takes, or within four of its own sigma
    got = piece_offsets_px(model.sensor, electrons, streaks_px,
                           rng=np.random.default_rng(PIECES_SEED))  # fmt: skip
    draws = got.offsets_px
    detected = np.isfinite(draws)
    counted = (detected.mean(axis=1) >= 0.5) & np.isfinite(pull)
    typical = np.nanmedian(np.where(detected, draws, np.nan)[counted], axis=1)
    piece = np.zeros(len(draws))
    piece[counted] = typical
    radius = match_radius_px(model.sensor, frames, sigma_px=sigma,
                             pull_px=np.hypot(pull, piece), counted=counted)  # fmt: skip
    off = np.hypot(draws, pull[:, None])
    verified = (off <= radius[:, None]) & _among_brightest(frames, got)
    chance = np.mean(verified | (off <= MATCH_SIGMAS * got.sigmas_px), axis=1)
    return np.where(pull > radius, 0.0, chance)


def _among_brightest(frames, got) -> np.ndarray:
    """Return whether each draw's detection is among its frame's ``_VERIFIED`` brightest.

    The frame's detections are those of its predicted stars (whole streaks and pieces, counted
    by :func:`~starsense.analysis.datasheet.pieces.piece_offsets_px` per bin of summed counts);
    a detection is among the brightest where fewer than ``_VERIFIED`` are in brighter bins,
    with half of those of its own bin.
    """
    frames = np.asarray(frames)
    _, f = np.unique(frames, return_inverse=True)
    per_frame = np.zeros((f.max() + 1 if len(f) else 0, got.per_bin.shape[1]))
    np.add.at(per_frame, f, got.per_bin)
    above = np.cumsum(per_frame[:, ::-1], axis=1)[:, ::-1]  # detections in bin b or brighter
    bins = len(FLUX_BINS) - 1
    b = np.clip(
        np.searchsorted(FLUX_BINS, np.log10(np.maximum(got.counts, 1.0)), side="right") - 1,
        0,
        bins - 1,
    )
    brighter = np.where(b + 1 < bins, above[f[:, None], np.minimum(b + 1, bins - 1)], 0.0)
    own = per_frame[f[:, None], b]
    return brighter + 0.5 * own < _VERIFIED
