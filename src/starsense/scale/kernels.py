"""Per-partition tasks: a HATS tile in, small summable results out.

Each task turns its tile into a :class:`~starsense.catalog.Catalog` (:meth:`ColumnPlan.catalog`)
and calls the in-memory path's own kernels on it —
:func:`~starsense.analysis.limits.sky.sky_fisher`,
:func:`~starsense.analysis.limits.sky.fov_fishers`,
:class:`~starsense.analysis.availability.FieldStars` ... — so there is one copy of the
physics. What they return adds (or merges) exactly over disjoint tiles; the ``combine_*``
functions do that, on the workers, in a tree.

Top-level functions only: they are pickled to worker processes.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from starsense.analysis.availability import BrightestInField, FieldStars, catalog_stars
from starsense.analysis.limits.sky import fov_fishers, sky_fisher, star_weights
from starsense.attitude.covariance import fisher_components
from starsense.geometry.fov import count_in_fov
from starsense.photometry.stars import BlackBodyStars
from starsense.scale._deps import quiet_third_party_warnings
from starsense.scale.hats import ColumnPlan


def limit_stars(frame: Any, plan: ColumnPlan, *, colour: str, max_mag: float | None):
    """Return the tile's black-body stars, as ``starsense limit`` makes them in memory."""
    quiet_third_party_warnings()
    stars = BlackBodyStars.from_catalog(plan.catalog(frame), colour)
    if max_mag is not None:
        stars = stars.subset(stars.magnitude <= max_mag)
    return stars


def sky_part(frame, plan, *, colour, max_mag, diameter_m, exposure_s):
    """(F (3, 3), stars used, stars skipped) of one tile."""
    stars = limit_stars(frame, plan, colour=colour, max_mag=max_mag)
    return sky_fisher(stars, diameter_m, exposure_s), len(stars), stars.n_skipped


def fov_part(frame, plan, *, colour, max_mag, targets, fov_diameter_rad, diameter_m, exposure_s):
    """(F per head (T, 3, 3), stars per head (T,), stars used, stars skipped) of one tile."""
    stars = limit_stars(frame, plan, colour=colour, max_mag=max_mag)
    fishers, counts = fov_fishers(
        stars,
        targets,
        fov_diameter_rad=fov_diameter_rad,
        diameter_m=diameter_m,
        exposure_s=exposure_s,
    )
    return fishers, counts, len(stars), stars.n_skipped


def combine_sum(*parts):
    """Element-wise sum of tuples of arrays / numbers."""
    return tuple(
        np.sum([p[i] for p in parts], axis=0)
        if isinstance(parts[0][i], np.ndarray)
        else sum(p[i] for p in parts)
        for i in range(len(parts[0]))
    )


# -- N brightest --------------------------------------------------------------------------------


def magnitude_bins(magnitude: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Bin of each magnitude: 0 below edges[0], i in [edges[i-1], edges[i]), len(edges) above."""
    return np.searchsorted(edges, magnitude, side="right")


def histogram_part(frame, plan, *, colour, max_mag, edges):
    """(stars per magnitude bin (len(edges) + 1,), stars skipped) of one tile."""
    stars = limit_stars(frame, plan, colour=colour, max_mag=max_mag)
    counts = np.bincount(magnitude_bins(stars.magnitude, edges), minlength=len(edges) + 1)
    return counts.astype(np.int64), stars.n_skipped


def brightest_part(frame, plan, *, colour, max_mag, diameter_m, exposure_s, edges, bins, partial):
    """Return summed eq. 21 components per checkpoint bin, and the stars of the cut bins.

    Components are summed between and in the checkpoint bins; the stars of the bins a
    checkpoint cuts through are returned one by one.

    Parameters
    ----------
    edges : array (E,)
        Magnitude bin edges (:func:`magnitude_bins`).
    bins : array (C,) of int
        Sorted bins that hold a checkpoint of the curve.
    partial : array (C,) of bool
        The checkpoint cuts through the bin (its stars are returned one by one).

    Returns
    -------
    rows : array (2 C + 1, 7)
        Row 2j: :func:`~starsense.attitude.covariance.fisher_components` summed over the stars
        between bins[j-1] and bins[j]; row 2j + 1: over the stars in bins[j] unless partial;
        row 2C: after the last checkpoint bin.
    explicit : (magnitude (P,), vectors (P, 3), weights (P,))
        The stars in partial bins.
    """
    stars = limit_stars(frame, plan, colour=colour, max_mag=max_mag)
    w = star_weights(stars, diameter_m, exposure_s)
    idx = magnitude_bins(stars.magnitude, edges)
    j = np.searchsorted(bins, idx, side="left")
    in_bin = (j < len(bins)) & (bins[np.minimum(j, len(bins) - 1)] == idx)
    explicit = in_bin & partial[np.minimum(j, len(bins) - 1)]
    row = np.where(in_bin, 2 * j + 1, 2 * j)
    rest = ~explicit
    comps = fisher_components(stars.vectors[rest], w[rest])
    rows = np.zeros((2 * len(bins) + 1, 7))
    np.add.at(rows, row[rest], comps)
    return rows, (stars.magnitude[explicit], stars.vectors[explicit], w[explicit])


def combine_brightest(*parts):
    """Add the rows and concatenate the explicit stars of :func:`brightest_part` results."""
    rows = np.sum([p[0] for p in parts], axis=0)
    explicit = tuple(np.concatenate([p[1][i] for p in parts]) for i in range(3))
    return rows, explicit


# -- availability -------------------------------------------------------------------------------


def field_part(frame, plan, *, band, max_mag, fov, attitudes, k):
    """Run one tile through the in-memory :class:`FieldStars`.

    Returns
    -------
    tuple
        (stars in the field per pointing (M,), the k brightest there (:class:`BrightestInField`,
        None for k = 0), stars used, faintest magnitude used).
    """
    quiet_third_party_warnings()
    vectors, mags = catalog_stars(plan.catalog(frame), max_mag, band=band, allow_empty=True)
    faintest = float(mags.max()) if len(mags) else -math.inf
    if not k:  # counts only: the in-memory count_in_fov, no per-pointing magnitude lists
        return count_in_fov(fov, attitudes, vectors), None, len(mags), faintest
    field = FieldStars.build(fov, attitudes, vectors, mags)
    return field.counts(), field.brightest(k), len(mags), faintest


def combine_field(*parts):
    """Add the counts and merge the brightest stars of :func:`field_part` results."""
    counts = np.sum([p[0] for p in parts], axis=0)
    top = None if parts[0][1] is None else BrightestInField.merge([p[1] for p in parts])
    return counts, top, sum(p[2] for p in parts), max(p[3] for p in parts)
