"""Real star fields: Lin et al. 2024, sec. 5, Tables 3-4 (average accuracy per configuration)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from starsense._validate import as_generator, check_count, check_scalar, finite_float
from starsense.analysis.guide_stars._common import check_metric, check_sigmas
from starsense.analysis.guide_stars.focal_plane import CONFIGURATIONS, configuration_areas
from starsense.analysis.guide_stars.metrics import (
    batch_covariance,
    error_norm,
    metric_block,
    monte_carlo_errors,
)
from starsense.analysis.guide_stars.selection import SELECTION_SIGMA, select_guide_stars
from starsense.errors import InputError
from starsense.geometry.areas import AreaLayout
from starsense.geometry.attitude import attitude_from_radec_roll
from starsense.geometry.projection import tangent_to_vectors, vectors_to_tangent
from starsense.geometry.sampling import random_attitudes
from starsense.references import lin2024
from starsense.units import ARCSEC, DEG, to_edge

__all__ = [
    "FIELD_TRIAL_COST",
    "LAYOUT_COMBINATIONS",
    "MAX_FIELD_TRIALS",
    "PAPER_FIELD_SIGMAS",
    "FieldAccuracy",
    "field_accuracy",
    "field_stars",
    "lin_layout",
]

#: most noisy solves per area combination: each holds ~1 KB while its combination is solved
#: and takes ~0.7 ms (peak RSS and time of ``guide-stars field`` at 2,000 and 100,000 on a
#: 30 deg field), so the cap keeps a combination near 1 GB and ~12 minutes
MAX_FIELD_TRIALS = 1_000_000
FIELD_TRIAL_COST = "~1 KB of memory and ~0.7 ms per noisy solve"

LAYOUT_COMBINATIONS: dict[str, tuple[tuple[int, ...], ...]] = {
    "one": ((1,), (2,), (3,), (4,)),
    "two_adjacent": ((1, 2), (2, 3), (3, 4), (4, 1)),
    "two_symmetric": ((1, 3), (2, 4)),
    "three": ((1, 2, 3), (2, 3, 4), (3, 4, 1), (4, 1, 2)),
    "four": ((1, 2, 3, 4),),
}
"""Area combinations of each configuration on a four-area layout (sec. 5: "the average value of
all possible combinations")."""
PAPER_FIELD_SIGMAS = tuple(s * ARCSEC for s in lin2024.TABLE3_4_SIGMAS_ARCSEC)
"""Average measurement errors of Tables 3-4 (0.2 and 0.05 arcsec), rad."""


def _mean_rows(rows: NDArray[np.float64], scale: float) -> NDArray[np.float64]:
    """Return the mean over combinations of ``rows / scale`` (n_usable, n_sigma); NaN if none."""
    if not len(rows):
        return np.full(rows.shape[-1], np.nan)
    return np.mean(rows / scale, axis=0)


@dataclass(frozen=True, eq=False)
class FieldAccuracy:
    """Average attitude accuracy of a real star field per configuration (Tables 3-4).

    Angles are stored in radians; the ``*_deg`` and ``*_arcsec`` properties give them in the
    units of the paper and the command line.

    Attributes
    ----------
    center_rad : tuple of float
        Boresight (RA, Dec), rad.
    lens_fov_rad : float
        Lens-circle diameter, rad.
    catalog, band : str
        The catalogue and the magnitude band used.
    max_mag : float or None
        Faintest star used.
    stars_per_area : tuple of int
        Catalogue stars in areas 1-4.
    sigmas_rad : tuple of float
        Quoted measurement errors, rad.
    errors_rad : dict str -> ndarray (n_usable, n_sigma)
        Mean attitude error (Monte Carlo, the metric's norm) of each usable area combination
        of the configuration, rad.
    predicted_rad : dict str -> ndarray (n_usable, n_sigma)
        ``sqrt(trace P)`` (eqs. 1-3) of each usable combination, rad.
    usable : dict str -> tuple (usable, total)
        Area combinations with at least three stars, and all combinations.
    selections : dict str -> list of (areas, GuideStarSelection)
        The guide stars of every combination.
    criterion, n_trials, metric, sigma_kind
        Settings of :func:`field_accuracy`.
    """

    center_rad: tuple[float, float]
    lens_fov_rad: float
    catalog: str
    band: str
    max_mag: float | None
    stars_per_area: tuple[int, ...]
    sigmas_rad: tuple[float, ...]
    errors_rad: dict[str, NDArray[np.float64]]
    predicted_rad: dict[str, NDArray[np.float64]]
    usable: dict[str, tuple[int, int]]
    selections: dict[str, list] = field(repr=False)
    criterion: str = "trace"
    n_trials: int = 2000
    metric: str = "pointing"
    sigma_kind: str = "1sigma"

    @property
    def center_deg(self) -> tuple[float, float]:
        """Boresight (RA, Dec), deg."""
        return (to_edge(self.center_rad[0], DEG), to_edge(self.center_rad[1], DEG))

    @property
    def lens_fov_deg(self) -> float:
        """Lens-circle diameter, deg."""
        return to_edge(self.lens_fov_rad, DEG)

    @property
    def sigma_arcsec(self) -> tuple[float, ...]:
        """Quoted measurement errors, arcsec."""
        return tuple(to_edge(s, ARCSEC) for s in self.sigmas_rad)

    @property
    def accuracy_arcsec(self) -> dict[str, NDArray[np.float64]]:
        """Mean error averaged over the usable combinations, arcsec (NaN when none), per sigma."""
        return {k: _mean_rows(v, ARCSEC) for k, v in self.errors_rad.items()}

    @property
    def predicted_arcsec(self) -> dict[str, NDArray[np.float64]]:
        """The same average of ``sqrt(trace P)``, arcsec (NaN when none), per sigma."""
        return {k: _mean_rows(v, ARCSEC) for k, v in self.predicted_rad.items()}

    def as_dict(self) -> dict:
        """Return the JSON-ready summary (the CLI's ``--json`` payload; deg and arcsec)."""

        def num(x: float) -> float | None:
            return None if not np.isfinite(x) else float(x)

        return {
            "center_deg": list(self.center_deg),
            "lens_fov_deg": self.lens_fov_deg,
            "catalog": self.catalog,
            "band": self.band,
            "max_mag": self.max_mag,
            "stars_per_area": list(self.stars_per_area),
            "sigma_arcsec": list(self.sigma_arcsec),
            "accuracy_arcsec": {k: [num(x) for x in v] for k, v in self.accuracy_arcsec.items()},
            "predicted_arcsec": {k: [num(x) for x in v] for k, v in self.predicted_arcsec.items()},
            "usable_combinations": {k: list(v) for k, v in self.usable.items()},
            "guide_stars": {
                k: [
                    {
                        "areas": list(a),
                        "status": s.status,
                        "n_candidates": s.n_candidates,
                        "n_guide_stars": len(s.indices) if s.ok else 0,
                        "areas_covered": s.areas_covered,
                        "triangle_ratio": num(s.triangle_ratio),
                    }
                    for a, s in v
                ]
                for k, v in self.selections.items()
            },
            "criterion": self.criterion,
            "n_trials": self.n_trials,
            "metric": self.metric,
            "sigma_kind": self.sigma_kind,
        }


def lin_layout(lens_fov_rad: float) -> AreaLayout:
    """Return the four-segment layout of a lens circle of diameter ``lens_fov_rad``.

    Parameters
    ----------
    lens_fov_rad : float
        Lens-circle diameter (the pattern's field of Table 2), rad, in (0, 60 deg).

    Returns
    -------
    AreaLayout
        The segments around the inscribed square (:meth:`AreaLayout.lin2024`).
    """
    fov = check_scalar(lens_fov_rad, "lens_fov_rad", 0.0, 60 * DEG, lo_open=True, hi_open=True)
    return AreaLayout.lin2024(math.tan(fov / 2.0) / math.sqrt(2.0))


def field_stars(
    catalog,
    center_rad: tuple[float, float],
    *,
    layout: AreaLayout,
    roll_rad: float = 0.0,
    max_mag: float | None = None,
) -> tuple[NDArray[np.int_], NDArray[np.float64], NDArray[np.float64], str]:
    """Return the catalogue stars that can fall in a layout's areas at one pointing.

    Parameters
    ----------
    catalog : Catalog
        With a V, G or Hp band.
    center_rad : tuple of float
        Boresight (RA, Dec), rad.
    layout : AreaLayout
        The areas, tangent-plane coordinates.
    roll_rad : float
        Roll about the boresight, rad.
    max_mag : float or None
        Faintest magnitude kept.

    Returns
    -------
    rows : ndarray of int, shape (N,)
        Catalogue row indices of the stars within the layout's outermost vertex.
    xy : ndarray, shape (N, 2)
        Their tangent-plane positions.
    mag : ndarray, shape (N,)
        Their magnitudes.
    band : str
        The magnitude band used (V, else G, else Hp).
    """
    try:
        ra, dec = (float(c) for c in center_rad)
    except (TypeError, ValueError):
        raise InputError(f"center_rad {center_rad!r} must be (RA, Dec) in radians") from None
    if not (np.isfinite(ra) and np.isfinite(dec) and -math.pi / 2 <= dec <= math.pi / 2):
        raise InputError(
            f"center_rad {center_rad!r}: RA must be finite and Dec within [-pi/2, pi/2]"
        )
    roll = finite_float(roll_rad, "roll_rad")
    band = next((b for b in ("V", "G", "Hp") if b in catalog.bands), None)
    if band is None:
        raise InputError(f"catalogue {catalog.name} has none of the bands V, G, Hp")
    att = attitude_from_radec_roll(ra, dec, roll)
    reach = max(float(np.hypot(*a.vertices.T).max()) for a in layout.areas)
    radius = math.atan(reach) * 1.0001
    rows = np.asarray(catalog.cone(att.inv().apply([0.0, 0.0, 1.0]), radius), dtype=int)
    mag = np.asarray(catalog.mags[band], dtype=np.float64)[rows]
    if max_mag is not None:
        keep = mag <= max_mag
        rows, mag = rows[keep], mag[keep]
    xy = vectors_to_tangent(att.apply(catalog.vectors[rows]).reshape(-1, 3))
    return rows, xy, mag, band


def _combination_rows(xy, sel, sig, per_quoted, n_trials, metric, gen):
    """Return the Monte Carlo mean error and sqrt(trace P) of one selection, rad, per sigma."""
    vec = tangent_to_vectors(xy[sel.indices])
    vecs = np.broadcast_to(vec, (n_trials, *vec.shape))
    z = gen.standard_normal((n_trials, len(vec), 2))
    att = random_attitudes(n_trials, gen)
    cov1 = batch_covariance(vec[None], 1.0)[0]
    a_row, p_row = [], []
    for s in sig:
        s_rad = s * per_quoted
        err = monte_carlo_errors(vecs, s_rad, noise=z, attitudes=att)
        a_row.append(float(np.mean(error_norm(err, metric))))
        p_row.append(float(np.sqrt(np.trace(metric_block(cov1, metric)))) * s_rad)
    return a_row, p_row


def field_accuracy(
    catalog,
    center_rad: tuple[float, float],
    *,
    lens_fov_rad: float = lin2024.PATTERN_FOVS_DEG[0] * DEG,
    sigmas_rad: ArrayLike = PAPER_FIELD_SIGMAS,
    configurations: tuple[str, ...] | list[str] | None = None,
    n_stars: int = 5,
    criterion: str = "trace",
    max_mag: float | None = None,
    n_trials: int = 2000,
    metric: str = "pointing",
    sigma_kind: str = "1sigma",
    roll_rad: float = 0.0,
    rng: int | np.random.Generator | None = 0,
) -> FieldAccuracy:
    """Compute Lin et al. 2024, Tables 3-4: average accuracy of a real field per configuration.

    For every area combination of every configuration (:data:`LAYOUT_COMBINATIONS`), guide
    stars are chosen (:func:`select_guide_stars`) among the catalogue stars in those areas, and
    ``n_trials`` noisy solves (:func:`monte_carlo_errors`) give the mean error; combinations
    with fewer than three stars are not usable and are counted, not averaged. The layout is the
    four segments around the square inscribed in the lens circle (``lens_fov_rad`` is the
    pattern's field, Table 2: 1.6 or 0.4 deg).

    Parameters
    ----------
    catalog : Catalog
        The stars.
    center_rad : tuple of float
        Boresight (RA, Dec), rad.
    lens_fov_rad : float
        Lens-circle diameter, rad.
    sigmas_rad : array_like of float
        Quoted measurement errors, rad (default: the paper's 0.2 and 0.05 arcsec).
    configurations : sequence of str or None
        Default: all five.
    n_stars : int
        Guide stars per solve.
    criterion : str
        Selection criterion (:data:`CRITERIA`).
    max_mag : float or None
        Faintest catalogue star used.
    n_trials : int
        Noisy solves per combination, >= 1.
    metric : {"total", "pointing"}
        Which norm of the error.
    sigma_kind : {"1sigma", "3sigma"}
        What a quoted sigma is.
    roll_rad : float
        Roll about the boresight, rad.
    rng : None, int or numpy.random.Generator
        Randomness of the noise and the attitudes (an int: the root seed).

    Returns
    -------
    FieldAccuracy
    """
    sig, per_quoted = check_sigmas(sigmas_rad, sigma_kind)
    check_metric(metric)
    n_trials = check_count(n_trials, "n_trials", MAX_FIELD_TRIALS, FIELD_TRIAL_COST)
    configs = tuple(CONFIGURATIONS) if configurations is None else tuple(configurations)
    for c in configs:
        configuration_areas(c)
    layout = lin_layout(lens_fov_rad)
    _, xy, mag, band = field_stars(
        catalog, center_rad, layout=layout, roll_rad=roll_rad, max_mag=max_mag
    )
    which = layout.index(xy) if len(xy) else np.zeros(0, dtype=int)
    gen, _ = as_generator(rng)
    errors: dict[str, NDArray[np.float64]] = {}
    pred: dict[str, NDArray[np.float64]] = {}
    usable: dict[str, tuple[int, int]] = {}
    sels: dict[str, list] = {}
    for c in configs:
        rows_acc, rows_pred, chosen = [], [], []
        for areas in LAYOUT_COMBINATIONS[c]:
            sel = select_guide_stars(
                xy,
                mag,
                layout=layout,
                areas=areas,
                n_stars=n_stars,
                criterion=criterion,
                sigma_rad=SELECTION_SIGMA,
                metric=metric,
            )
            chosen.append((areas, sel))
            if sel.ok:
                a_row, p_row = _combination_rows(xy, sel, sig, per_quoted, n_trials, metric, gen)
                rows_acc.append(a_row)
                rows_pred.append(p_row)
        usable[c] = (len(rows_acc), len(LAYOUT_COMBINATIONS[c]))
        errors[c] = np.array(rows_acc, dtype=np.float64).reshape(-1, len(sig))
        pred[c] = np.array(rows_pred, dtype=np.float64).reshape(-1, len(sig))
        sels[c] = chosen
    return FieldAccuracy(
        center_rad=(float(center_rad[0]), float(center_rad[1])),
        lens_fov_rad=float(lens_fov_rad),
        catalog=str(catalog.name),
        band=band,
        max_mag=max_mag,
        stars_per_area=tuple(int(np.sum(which == k)) for k in (1, 2, 3, 4)),
        sigmas_rad=tuple(float(s) for s in sig),
        errors_rad=errors,
        predicted_rad=pred,
        usable=usable,
        selections=sels,
        criterion=criterion,
        n_trials=int(n_trials),
        metric=metric,
        sigma_kind=sigma_kind,
    )
