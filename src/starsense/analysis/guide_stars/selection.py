"""Guide-star selection among the stars in some attitude-determination areas (Lin et al. 2024)."""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from starsense._validate import check_int, positive_float
from starsense.analysis.guide_stars._common import check_metric
from starsense.analysis.guide_stars.focal_plane import attitude_area, triangle_fov_ratio
from starsense.analysis.guide_stars.metrics import batch_covariance, metric_block
from starsense.errors import InputError
from starsense.geometry.projection import tangent_to_vectors, xy_points
from starsense.units import ARCSEC

__all__ = [
    "CRITERIA",
    "SELECTION_SIGMA",
    "GuideStarSelection",
    "SelectionStatus",
    "select_guide_stars",
]

CRITERIA = ("trace", "rules", "brightest")
"""Selection criteria of :func:`select_guide_stars`."""
SELECTION_SIGMA = 0.1 * ARCSEC
"""Default per-axis measurement error of the trace criterion, rad (0.1 arcsec)."""
SelectionStatus = Literal["ok", "no_stars", "too_few_stars"]
"""What a guide-star selection found (:attr:`GuideStarSelection.status`)."""


@dataclass(frozen=True, eq=False)
class GuideStarSelection:
    """Guide stars chosen from the stars in some attitude-determination areas.

    Attributes
    ----------
    status : SelectionStatus
        ``"ok"``, ``"no_stars"`` (no catalogue star in the areas) or ``"too_few_stars"`` (1-2:
        no triangle, no attitude).
    indices : ndarray of int
        Chosen stars, indices into the arrays given to :func:`select_guide_stars`.
    n_candidates : int
        Stars in the areas (before the brightness cut to ``max_candidates``).
    areas_covered : int
        Areas holding at least one chosen star.
    triangle_ratio : float
        Average FOV ratio of the chosen stars' triangles (NaN below 3 stars).
    predicted_rad : float
        ``sqrt(trace P)`` of the metric's block at ``sigma_rad``, rad (NaN below 3 stars).
    criterion : str
        The criterion used.
    """

    status: SelectionStatus
    indices: NDArray[np.int_]
    n_candidates: int
    areas_covered: int
    triangle_ratio: float
    predicted_rad: float
    criterion: str

    @property
    def ok(self) -> bool:
        """Whether guide stars were chosen (``status == "ok"``)."""
        return self.status == "ok"


def _check_selection(xy, magnitude, layout, areas, n_stars, criterion, metric, max_candidates):
    """Return the validated (xy, magnitude, area numbers, n_stars) of a selection."""
    p = xy_points(xy)
    if p.ndim != 2:
        raise InputError(f"xy must have shape (N, 2), got {p.shape}")
    mag = np.asarray(magnitude, dtype=np.float64)
    if mag.shape != (len(p),):
        raise InputError(f"magnitude must have shape ({len(p)},), got {mag.shape}")
    if criterion not in CRITERIA:
        raise InputError(f"criterion = {criterion!r} is not known; choose one of {CRITERIA}")
    check_metric(metric)
    n_stars = check_int(n_stars, "n_stars")
    if n_stars < 3:
        raise InputError(f"n_stars = {n_stars} must be >= 3 (triangles need three stars)")
    if check_int(max_candidates, "max_candidates") < n_stars:
        raise InputError(f"max_candidates = {max_candidates!r} must be an integer >= n_stars")
    chosen_areas = tuple(range(1, len(layout.areas) + 1)) if areas is None else tuple(areas)
    for k in chosen_areas:
        if not 1 <= k <= len(layout.areas):
            raise InputError(f"area number {k} is not in the layout (1-{len(layout.areas)})")
    return p, mag, chosen_areas, n_stars


def _best_combination(p, which, idx, chosen_areas, criterion, sigma, metric, denom) -> int:
    """Return the index of the best of the candidate combinations ``idx`` (C, n)."""
    if len(idx) <= 1:
        return 0
    if criterion == "trace":
        vec = tangent_to_vectors(p[idx])
        tr = np.trace(metric_block(batch_covariance(vec, sigma), metric), axis1=-2, axis2=-1)
        return int(np.argmin(tr))
    # rules: coverage first, then the triangle ratio
    covered = np.zeros(len(idx), dtype=int)
    for k in chosen_areas:
        covered += (which[idx] == k).any(axis=1)
    ratio = triangle_fov_ratio(p[idx]) * attitude_area("four") / denom
    return int(np.lexsort((-ratio, -covered))[0])


def select_guide_stars(
    xy: ArrayLike,
    magnitude: ArrayLike,
    *,
    layout,
    areas: tuple[int, ...] | None = None,
    n_stars: int = 5,
    criterion: str = "trace",
    sigma_rad: float = SELECTION_SIGMA,
    metric: str = "pointing",
    max_candidates: int = 20,
) -> GuideStarSelection:
    """Choose ``n_stars`` guide stars among the stars in some areas of a layout.

    Criteria
        ``"trace"`` (the direct one): the combination with the smallest trace of the attitude
        covariance (eqs. 1-3; the x-y block for ``metric="pointing"``). ``"rules"`` (the paper's
        sec. 4 rules): cover as many areas as possible, then the largest average FOV ratio of
        the triangles. ``"brightest"``: the ``n_stars`` brightest, the baseline. Combinations
        are enumerated exhaustively among the ``max_candidates`` brightest stars in the areas
        (C(20, 5) = 15,504 at the defaults, vectorised).

    Parameters
    ----------
    xy : array_like, shape (N, 2)
        Stars' tangent-plane coordinates (:mod:`starsense.geometry.areas`).
    magnitude : array_like, shape (N,)
        Brightness order (smaller is brighter); NaN sorts last.
    layout : AreaLayout
        The attitude-determination areas (:class:`starsense.geometry.areas.AreaLayout`).
    areas : tuple of int or None
        1-based area numbers to use (default: all).
    n_stars : int
        Guide stars wanted, >= 3; fewer are used when the areas hold fewer.
    criterion : {"trace", "rules", "brightest"}
        How to choose, see above.
    sigma_rad : float
        Per-axis measurement error of every star, rad, > 0 (the trace and the prediction).
    metric : {"total", "pointing"}
        The covariance block the trace and the prediction use.
    max_candidates : int
        Brightest stars in the areas among which combinations are enumerated, >= n_stars.

    Returns
    -------
    GuideStarSelection
    """
    p, mag, chosen_areas, n_stars = _check_selection(
        xy, magnitude, layout, areas, n_stars, criterion, metric, max_candidates
    )
    s = positive_float(sigma_rad, "sigma_rad")
    which = layout.index(p) if len(p) else np.zeros(0, dtype=int)
    cand = np.flatnonzero(np.isin(which, chosen_areas))
    n_cand = len(cand)
    cand = cand[np.argsort(np.where(np.isnan(mag[cand]), np.inf, mag[cand]), kind="stable")]
    cand = cand[:max_candidates]
    nan = float("nan")
    if n_cand == 0:
        return GuideStarSelection("no_stars", cand, 0, 0, nan, nan, criterion)
    if n_cand < 3:
        covered = len(set(which[cand].tolist()))
        return GuideStarSelection("too_few_stars", cand, n_cand, covered, nan, nan, criterion)
    n = min(n_stars, len(cand))
    combos = (
        np.arange(n)[None, :]
        if criterion == "brightest"
        else np.array(list(combinations(range(len(cand)), n)))
    )
    idx = cand[combos]  # (C, n)
    denom = layout.subset_area(chosen_areas)
    sel = idx[_best_combination(p, which, idx, chosen_areas, criterion, s, metric, denom)]
    cov = batch_covariance(tangent_to_vectors(p[sel])[None], s)[0]
    return GuideStarSelection(
        status="ok",
        indices=sel,
        n_candidates=n_cand,
        areas_covered=len(set(which[sel].tolist())),
        triangle_ratio=float(triangle_fov_ratio(p[sel]) * attitude_area("four") / denom),
        predicted_rad=float(np.sqrt(np.trace(metric_block(cov, metric)))),
        criterion=criterion,
    )
