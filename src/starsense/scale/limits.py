"""The attitude-accuracy limit over HATS catalogues on a Dask cluster (Fialho & Mortari 2019).

Same results as :mod:`starsense.analysis.limits` on the same stars (to rounding of the sums,
~1e-15 relative): each partition computes the in-memory kernels' partial sums, which add
exactly; the last step (:func:`~starsense.analysis.limits.result.limit_from_fisher`,
:func:`~starsense.analysis.limits.sky.fov_results`,
:func:`~starsense.analysis.limits.brightest.brightest_from_sums`) is the in-memory one. Angles
are radians (FOV diameters, targets as unit vectors).

>>> from starsense.scale import open_hats, sky_limit
>>> gaia = open_hats("hats:https://data.lsdb.io/hats/gaia_dr3")   # doctest: +SKIP
>>> sky_limit(gaia, diameter_m=0.1, exposure_s=0.1)                  # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from starsense.analysis.limits.brightest import (
    BrightestCurve,
    brightest_checkpoints,
    brightest_from_sums,
    brightest_order,
)
from starsense.analysis.limits.centroid import check_aperture
from starsense.analysis.limits.result import LimitResult, limit_from_fisher
from starsense.analysis.limits.sky import fov_results, in_cone
from starsense.attitude.covariance import fisher_components
from starsense.errors import InputError, SingularGeometryError
from starsense.photometry.colour import COLOUR_SYSTEMS
from starsense.photometry.stars import BlackBodyStars
from starsense.references.fialho2019 import N_GALAXY
from starsense.scale import kernels
from starsense.scale.hats import ColumnPlan, HatsCatalog
from starsense.scale.run import Progress, client_or_local, run_partitions

#: first histogram of the N-brightest ranking: bins of 40 mag / 16384 = 0.0024 mag
_MAG_RANGE = (-5.0, 35.0)
_N_BINS = 2**14
#: a bin a checkpoint falls into is split into this many when it holds too many stars
_REFINE = 1024
#: stars returned one by one (those in bins a checkpoint cuts through) before refining the bins
MAX_EXPLICIT_STARS = 200_000


@dataclass(frozen=True)
class StarSummary:
    """What a distributed limit used: the colour system and the star counts."""

    colour: str
    n_stars: int
    n_skipped: int


def limit_plan(catalog: HatsCatalog, colour: str | None) -> tuple[ColumnPlan, str]:
    """Return the columns the black-body model needs, and the colour system (chosen as in memory).

    Parameters
    ----------
    catalog : HatsCatalog
        From :func:`~starsense.scale.open_hats`.
    colour : str or None
        Colour system; None for the first the catalogue has (as in memory).

    Returns
    -------
    plan : ColumnPlan
        The columns to read.
    colour : str
        The colour system chosen.
    """
    plan = catalog.plan()
    try:
        chosen = BlackBodyStars.from_catalog(plan.empty_catalog(), colour).colour
    except InputError:
        what = (
            "a magnitude and colour of one colour system"
            if colour is None
            else f"the {colour} colour index with its magnitude (colour {colour!r})"
        )
        raise catalog.missing(what) from None
    return plan.restrict([COLOUR_SYSTEMS[chosen][2]], [chosen]), chosen


def _check_max_mag(max_mag: float | None) -> None:
    if max_mag is not None and not np.isfinite(max_mag):
        raise InputError(f"max_mag must be a finite magnitude, got {max_mag!r}")


def _enough(n: int, catalog: HatsCatalog, max_mag: float | None) -> None:
    if n < 2:
        cut = f" with max_mag {max_mag}" if max_mag is not None else ""
        raise InputError(
            f"{n} star(s) of HATS catalogue {catalog.location}{cut} have a magnitude and "
            "colour; at least 2 are needed"
        )


def sky_limit(
    catalog: HatsCatalog,
    *,
    diameter_m: float = 1.0,
    exposure_s: float = 1.0,
    colour: str | None = None,
    max_mag: float | None = None,
    client: Any | None = None,
    progress: Progress | None = None,
) -> tuple[LimitResult, StarSummary]:
    """Compute the whole-sky limit (eqs. 19-24) over a HATS catalogue.

    The distributed :func:`starsense.analysis.limits.sky_limit`.

    Parameters
    ----------
    catalog : HatsCatalog
        From :func:`~starsense.scale.open_hats`.
    diameter_m, exposure_s : float
        D (m), t (s).
    colour : str or None
        Colour system (default: as :meth:`BlackBodyStars.from_catalog` chooses).
    max_mag : float or None
        Use only stars with magnitude <= this (in the colour system's magnitude band).
    client : distributed.Client or None
        Default: an in-process local cluster for this call.
    progress : callable(label, done, total) or None
        Called as partitions complete.

    Returns
    -------
    LimitResult
        Axes in ICRS.
    StarSummary
        Colour system and star counts.
    """
    check_aperture(diameter_m, exposure_s)
    _check_max_mag(max_mag)
    plan, chosen = limit_plan(catalog, colour)
    with client_or_local(client) as c:
        fisher, n, skipped = run_partitions(
            c,
            catalog,
            plan=plan,
            kernel=kernels.sky_part,
            kernel_args={
                "colour": chosen,
                "max_mag": max_mag,
                "diameter_m": diameter_m,
                "exposure_s": exposure_s,
            },
            combine=kernels.combine_sum,
            label="whole-sky limit",
            progress=progress,
        )
    _enough(n, catalog, max_mag)
    return limit_from_fisher(fisher, n, diameter_m=diameter_m, exposure_s=exposure_s), StarSummary(
        chosen, n, skipped
    )


def fov_limit(
    catalog: HatsCatalog,
    targets,
    *,
    fov_diameter_rad: float,
    diameter_m: float = 1.0,
    exposure_s: float = 1.0,
    colour: str | None = None,
    max_mag: float | None = None,
    client: Any | None = None,
    progress: Progress | None = None,
) -> tuple[list[LimitResult], LimitResult | None, StarSummary]:
    """Compute the FOV-limited limit for many targets (sec. 3.4) over a HATS catalogue.

    The distributed :func:`starsense.analysis.limits.fov_limit`.

    Parameters
    ----------
    catalog : HatsCatalog
        From :func:`~starsense.scale.open_hats`.
    targets : array (3,) or (T, 3)
        Head boresights, ICRS unit vectors.
    fov_diameter_rad : float
        Full cone angle of each head, rad.
    diameter_m, exposure_s : float
        D (m), t (s).
    colour, max_mag, client, progress
        As for :func:`sky_limit`.

    Returns
    -------
    heads : list of LimitResult
        Axes in each head's boresight frame.
    merged : LimitResult or None
        All heads merged; None for one target.
    summary : StarSummary
        Colour system and star counts.
    """
    check_aperture(diameter_m, exposure_s)
    _check_max_mag(max_mag)
    targets = np.atleast_2d(np.asarray(targets, dtype=float))
    in_cone(np.zeros((0, 3)), np.array([0.0, 0.0, 1.0]), fov_diameter_rad)  # validates the FOV
    plan, chosen = limit_plan(catalog, colour)
    with client_or_local(client) as c:
        fishers, counts, n, skipped = run_partitions(
            c,
            catalog,
            plan=plan,
            kernel=kernels.fov_part,
            kernel_args={
                "colour": chosen,
                "max_mag": max_mag,
                "targets": targets,
                "fov_diameter_rad": fov_diameter_rad,
                "diameter_m": diameter_m,
                "exposure_s": exposure_s,
            },
            combine=kernels.combine_sum,
            label="FOV-limited limits",
            progress=progress,
        )
    heads, merged = fov_results(
        fishers, counts, targets, diameter_m=diameter_m, exposure_s=exposure_s
    )
    return heads, merged, StarSummary(chosen, n, skipped)


def _checkpoint_bins(counts: np.ndarray, ns: np.ndarray):
    """Bin holding each checkpoint, whether it cuts through it, and the stars before it."""
    cum = np.cumsum(counts)
    b = np.searchsorted(cum, ns, side="left")
    before = cum[b] - counts[b]
    bins = np.unique(b)
    partial = np.zeros(len(bins), dtype=bool)
    j = np.searchsorted(bins, b)
    partial[j[ns < cum[b]]] = True
    return b, before, bins, partial


def _refine(edges: np.ndarray, bins: np.ndarray) -> np.ndarray:
    """Edges with each (finite, not already tiny) bin of ``bins`` split into _REFINE."""
    extra = [
        np.linspace(edges[i - 1], edges[i], _REFINE + 1)[1:-1]
        for i in bins
        if 0 < i < len(edges) and edges[i] - edges[i - 1] > 1e-9 * max(1.0, abs(edges[i]))
    ]
    return np.unique(np.concatenate([edges, *extra])) if extra else edges


def brightest_curve(
    catalog: HatsCatalog,
    *,
    diameter_m: float = 1.0,
    exposure_s: float = 1.0,
    points_per_decade: int = 20,
    n_extrapolated: float = N_GALAXY,
    colour: str | None = None,
    max_mag: float | None = None,
    client: Any | None = None,
    progress: Progress | None = None,
    max_explicit: int = MAX_EXPLICIT_STARS,
) -> BrightestCurve:
    """Compute theta_rms of the N brightest stars (Fig. 7) over a HATS catalogue, unsorted.

    :func:`starsense.analysis.limits.brightest_curve` ranks all stars; here a histogram of
    magnitudes (summed over the partitions) locates the magnitude bin of each checkpoint N, bins
    that hold too many stars are split and counted again, and a last pass returns the eq. 21
    components summed between the checkpoints plus, one by one, only the stars of the bins a
    checkpoint cuts through, which are ranked with the in-memory :func:`brightest_order`. Three
    or four passes over the catalogue; memory on the client ~ ``max_explicit`` stars.

    Parameters
    ----------
    catalog : HatsCatalog
        From :func:`~starsense.scale.open_hats`.
    diameter_m, exposure_s : float
        D (m), t (s).
    points_per_decade : int
        Checkpoints per decade of N.
    n_extrapolated : float
        N to extrapolate the power law to.
    colour, max_mag, client, progress
        As for :func:`sky_limit`.
    max_explicit : int
        Stars returned one by one before the magnitude bins are refined.

    Returns
    -------
    BrightestCurve
    """
    check_aperture(diameter_m, exposure_s)
    _check_max_mag(max_mag)
    plan, chosen = limit_plan(catalog, colour)
    edges = np.linspace(*_MAG_RANGE, _N_BINS + 1)
    with client_or_local(client) as c:

        def histogram(e: np.ndarray, label: str) -> np.ndarray:
            counts, _ = run_partitions(
                c,
                catalog,
                plan=plan,
                kernel=kernels.histogram_part,
                kernel_args={"colour": chosen, "max_mag": max_mag, "edges": e},
                combine=kernels.combine_sum,
                label=label,
                progress=progress,
            )
            return counts

        counts = histogram(edges, "N brightest: magnitude histogram")
        n_total = int(counts.sum())
        if n_total < 2:
            raise SingularGeometryError(
                f"singular geometry ({n_total} star): need at least 2 stars"
            )
        ns = brightest_checkpoints(n_total, points_per_decade)
        for _ in range(2):
            b, before, bins, partial = _checkpoint_bins(counts, ns)
            if counts[bins[partial]].sum() <= max_explicit:
                break
            finer = _refine(edges, bins[partial])
            if len(finer) == len(edges):
                break
            edges = finer
            counts = histogram(edges, "N brightest: finer histogram")
        b, before, bins, partial = _checkpoint_bins(counts, ns)
        rows, (mag, vec, w) = run_partitions(
            c,
            catalog,
            plan=plan,
            kernel=kernels.brightest_part,
            kernel_args={
                "colour": chosen,
                "max_mag": max_mag,
                "diameter_m": diameter_m,
                "exposure_s": exposure_s,
                "edges": edges,
                "bins": bins,
                "partial": partial,
            },
            combine=kernels.combine_brightest,
            label="N brightest: sums",
            progress=progress,
        )
    order = brightest_order(mag, vec, w)
    cum_explicit = np.cumsum(fisher_components(vec[order], w[order]), axis=0)
    cum_rows = np.cumsum(rows, axis=0)
    # explicit stars before each checkpoint bin: all of the partial bins below it
    per_bin = np.where(partial, counts[bins], 0)
    explicit_before = np.concatenate([[0], np.cumsum(per_bin)[:-1]])
    sums = np.empty((len(ns), 7))
    for k, (n, bk) in enumerate(zip(ns, b, strict=True)):
        j = int(np.searchsorted(bins, bk))
        take = explicit_before[j] + (n - before[k] if partial[j] else 0)
        sums[k] = cum_rows[2 * j + 1] + (cum_explicit[take - 1] if take > 0 else 0.0)
    return brightest_from_sums(ns, sums, n_extrapolated=n_extrapolated, colour=chosen)
