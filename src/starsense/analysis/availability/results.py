"""Results of the availability analysis: static, dynamic and along-track (Dzamba & Enright 2014).

Angles are stored in radians; the ``*_deg`` properties, :meth:`to_dict` (JSON) and :meth:`lines`
(text) give degrees, as the command line and the report print them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from starsense.analysis.availability.field import BrightestInField, FieldStars
from starsense.analysis.availability.threshold import ThresholdCurve
from starsense.units import DEG, to_edge

__all__ = [
    "N_MIN_CONSERVATIVE",
    "N_MIN_LOST_IN_SPACE",
    "N_MIN_TRACKING",
    "DynamicAvailability",
    "StaticAvailability",
    "TrackAvailability",
    "percent",
    "static_result",
]

#: two stars give the incremental attitude in tracking mode (sec. 1.1)
N_MIN_TRACKING = 2
#: three stars identify a pattern lost-in-space: the paper's definition of availability
N_MIN_LOST_IN_SPACE = 3
#: four stars: the conservative allowance for pattern ambiguity
N_MIN_CONSERVATIVE = 4


def percent(x: float) -> str:
    """Return a fraction as a percentage with two decimals (``"99.50 %"``), for text output."""
    return f"{100.0 * x:.2f} %"


@dataclass(frozen=True)
class StaticAvailability:
    """Spatial static availability (sec. 1.2; Figs. 4-6).

    Attributes
    ----------
    availability : float
        Fraction of orientations with at least `n_min` stars ``<= max_mag`` in the field.
    n_min : int
        Stars needed.
    max_mag : float
        Detection threshold m_t (= the catalogue cut).
    n_orientations, n_stars : int
        Orientations tested; catalogue stars used (after the cut).
    by_n_min : dict of int -> float
        Availability for N_min = 1 ... 4 (and `n_min`).
    counts : ndarray, shape (n_orientations,)
        Stars in the field per orientation (for the sky maps).
    boresights : ndarray, shape (n_orientations, 3)
        ICRS unit vectors.
    mag_grid : ndarray, shape (K,)
        Thresholds of the availability-against-m_t curve (Fig. 6).
    curve : dict of int -> ndarray, shape (K,)
        Availability at each ``mag_grid`` threshold, per N_min.
    fov, catalog, band : str
        Descriptions for reports.
    """

    availability: float
    n_min: int
    max_mag: float
    n_orientations: int
    n_stars: int
    by_n_min: dict[int, float]
    counts: NDArray[np.intp] = field(repr=False)
    boresights: NDArray[np.float64] = field(repr=False)
    mag_grid: NDArray[np.float64] = field(repr=False)
    curve: dict[int, NDArray[np.float64]] = field(repr=False)
    fov: str = ""
    catalog: str = ""
    band: str = "V"

    def to_dict(self) -> dict:
        """Return the numbers as JSON-ready values."""
        return {
            "availability": self.availability,
            "n_orientations": self.n_orientations,
            "n_stars": self.n_stars,
            "n_min": self.n_min,
            "max_mag": self.max_mag,
            "availability_by_n_min": {str(k): v for k, v in sorted(self.by_n_min.items())},
            "stars_in_field": {
                "min": int(self.counts.min()),
                "mean": float(self.counts.mean()),
                "max": int(self.counts.max()),
            },
            "fov": self.fov,
            "catalog": self.catalog,
            "band": self.band,
        }

    def lines(self) -> list[str]:
        """Return a human-readable summary."""
        return [
            f"spatial static availability, N_min = {self.n_min}, m_t = {self.max_mag:g}: "
            f"{percent(self.availability)}",
            f"  {self.n_orientations} orientations, {self.n_stars} stars used "
            f"({self.catalog}, {self.band} <= {self.max_mag:g}), field {self.fov}",
            "  by N_min: "
            + ", ".join(f"{k}: {percent(v)}" for k, v in sorted(self.by_n_min.items())),
            f"  stars in field: min {self.counts.min()}, mean {self.counts.mean():.1f}, "
            f"max {self.counts.max()}",
        ]


@dataclass(frozen=True)
class DynamicAvailability:
    """Spatial dynamic availability against slew rate (sec. 3.1; Fig. 11).

    Attributes
    ----------
    rates_rad_s : ndarray, shape (R,)
        Slew rates, rad/s.
    threshold_mag : ndarray, shape (R,)
        Effective m_t at each rate: ``min(curve(w), max_mag)``.
    availability : ndarray, shape (R,)
        At `n_min`.
    by_n_min : dict of int -> ndarray, shape (R,)
        For N_min = 2, 3 (and `n_min`).
    n_min, n_orientations, n_stars : int
        Stars needed, orientations, stars used.
    max_mag : float
        Catalogue cut.
    curve : ThresholdCurve
        The threshold against rate.
    fov, catalog, band : str
        Descriptions for reports.
    """

    rates_rad_s: NDArray[np.float64]
    threshold_mag: NDArray[np.float64]
    availability: NDArray[np.float64]
    by_n_min: dict[int, NDArray[np.float64]]
    n_min: int
    n_orientations: int
    n_stars: int
    max_mag: float
    curve: ThresholdCurve
    fov: str = ""
    catalog: str = ""
    band: str = "V"

    @property
    def rates_deg_s(self) -> NDArray[np.float64]:
        """Slew rates, deg/s (for output)."""
        return to_edge(self.rates_rad_s, DEG)

    def to_dict(self) -> dict:
        """Return the numbers as JSON-ready values (rates in deg/s)."""
        return {
            "rates_deg_s": self.rates_deg_s.tolist(),
            "availability": self.availability.tolist(),
            "threshold_mag": [None if not np.isfinite(m) else float(m) for m in self.threshold_mag],
            "availability_by_n_min": {str(k): v.tolist() for k, v in sorted(self.by_n_min.items())},
            "n_min": self.n_min,
            "n_orientations": self.n_orientations,
            "n_stars": self.n_stars,
            "max_mag": self.max_mag,
            "threshold_curve": self.curve.to_dict(),
            "fov": self.fov,
            "catalog": self.catalog,
            "band": self.band,
        }

    def lines(self) -> list[str]:
        """Return a human-readable table, one row per rate."""
        keys = sorted(self.by_n_min)
        out = [
            f"spatial dynamic availability ({self.curve.label or 'given threshold curve'}), "
            f"{self.n_orientations} orientations, {self.n_stars} stars used "
            f"({self.catalog}, {self.band} <= {self.max_mag:g}), field {self.fov}",
            "  rate deg/s    m_t  " + "  ".join(f"N_min={k:<2d}" for k in keys),
        ]
        for j, w in enumerate(self.rates_deg_s):
            m = self.threshold_mag[j]
            mt = f"{m:6.2f}" if np.isfinite(m) else "  none"
            cells = "  ".join(f"{100 * self.by_n_min[k][j]:7.2f}%" for k in keys)
            out.append(f"  {w:10.2f} {mt}  {cells}")
        return out


@dataclass(frozen=True)
class TrackAvailability:
    """Along-track dynamic availability at one slew rate (sec. 4; Figs. 16-17, Table 2).

    Attributes
    ----------
    rate_rad_s : float
        Slew rate, rad/s.
    threshold_mag : float
        The effective m_t at that rate.
    inclinations : ndarray, shape (I,)
        Track inclinations, rad.
    availability : ndarray, shape (I,)
        Fraction of each track's samples with at least `n_min` stars, at `n_min`.
    by_n_min : dict of int -> ndarray, shape (I,)
        The same per N_min.
    spatial : dict of int -> float
        Spatial dynamic availability at the same rate, for comparison.
    n_min, n_samples, n_stars, n_orientations : int
        Stars needed, samples per track, stars used, spatial orientations.
    node : float
        RA of the tracks' common node, rad.
    fov, catalog, band, curve_label : str
        Descriptions for reports.
    """

    rate_rad_s: float
    threshold_mag: float
    inclinations: NDArray[np.float64]
    availability: NDArray[np.float64]
    by_n_min: dict[int, NDArray[np.float64]]
    spatial: dict[int, float]
    n_min: int
    n_samples: int
    n_stars: int
    n_orientations: int
    node: float = 0.0
    fov: str = ""
    catalog: str = ""
    band: str = "V"
    curve_label: str = ""

    @property
    def rate_deg_s(self) -> float:
        """Slew rate, deg/s (for output)."""
        return float(to_edge(self.rate_rad_s, DEG))

    @property
    def inclinations_deg(self) -> NDArray[np.float64]:
        """Track inclinations, deg (for output)."""
        return to_edge(self.inclinations, DEG)

    @property
    def node_deg(self) -> float:
        """RA of the tracks' common node, deg (for output)."""
        return float(to_edge(self.node, DEG))

    @property
    def mean(self) -> float:
        """Mean availability over the inclinations, at `n_min`."""
        return float(self.availability.mean())

    @property
    def max(self) -> float:
        """Largest availability over the inclinations, at `n_min`."""
        return float(self.availability.max())

    @property
    def min(self) -> float:
        """Smallest availability over the inclinations, at `n_min`."""
        return float(self.availability.min())

    def stats(self, n_min: int) -> dict[str, float]:
        """Return mean / max / min over the inclinations, and the spatial value, at `n_min`."""
        a = self.by_n_min[n_min]
        return {
            "spatial": self.spatial[n_min],
            "mean": float(a.mean()),
            "max": float(a.max()),
            "min": float(a.min()),
        }

    def to_dict(self) -> dict:
        """Return the numbers as JSON-ready values (angles in deg)."""
        return {
            "mean": self.mean,
            "max": self.max,
            "min": self.min,
            "inclinations_deg": self.inclinations_deg.tolist(),
            "availability": self.availability.tolist(),
            "rate_deg_s": self.rate_deg_s,
            "threshold_mag": float(self.threshold_mag) if np.isfinite(self.threshold_mag) else None,
            "n_min": self.n_min,
            "spatial": self.spatial[self.n_min],
            "by_n_min": {str(k): self.stats(k) for k in sorted(self.by_n_min)},
            "n_samples": self.n_samples,
            "node_deg": self.node_deg,
            "n_stars": self.n_stars,
            "n_orientations": self.n_orientations,
            "fov": self.fov,
            "catalog": self.catalog,
            "band": self.band,
        }

    def lines(self) -> list[str]:
        """Return a human-readable table, one row per N_min."""
        mt = f"{self.threshold_mag:.2f}" if np.isfinite(self.threshold_mag) else "none"
        out = [
            f"along-track dynamic availability at {self.rate_deg_s:g} deg/s (m_t = {mt}; "
            f"{self.curve_label or 'given threshold curve'}), {len(self.inclinations)} "
            f"tracks x {self.n_samples} samples, node RA {self.node_deg:g} deg, "
            f"{self.n_stars} stars used",
            "  N_min  spatial    mean     max     min",
        ]
        for k in sorted(self.by_n_min):
            s = self.stats(k)
            out.append(
                f"  {k:5d}  "
                + "  ".join(f"{100 * s[c]:6.2f}%" for c in ("spatial", "mean", "max", "min"))
            )
        return out


def static_result(
    field: FieldStars | BrightestInField,
    counts: NDArray[np.intp],
    *,
    boresights: NDArray[np.float64],
    n_min: int,
    m_t: float,
    n_stars: int,
    fov: str,
    catalog: str,
    band: str,
    curve_span_mag: float = 3.0,
    curve_step_mag: float = 0.05,
) -> StaticAvailability:
    """Assemble :class:`StaticAvailability` from the stars in the field at each boresight.

    Shared by :meth:`AvailabilityAnalysis.static` (a :class:`FieldStars`) and the distributed
    path (:mod:`starsense.scale`, a merged :class:`BrightestInField` with K >= max(4, n_min)).

    Parameters
    ----------
    field : FieldStars or BrightestInField
        The stars in the field at each boresight.
    counts : ndarray, shape (M,)
        Stars ``<= m_t`` in the field per boresight.
    boresights : ndarray, shape (M, 3)
        ICRS unit vectors.
    n_min : int
        Stars needed.
    m_t : float
        Detection threshold (finite).
    n_stars : int
        Stars used, after the catalogue cut.
    fov, catalog, band : str
        Descriptions for reports.
    curve_span_mag, curve_step_mag : float
        Availability against m_t from ``m_t - curve_span_mag`` to ``m_t`` (Fig. 6).

    Returns
    -------
    StaticAvailability
    """
    keys = sorted({1, 2, 3, 4, n_min})
    grid = np.round(np.arange(m_t - curve_span_mag, m_t + 1e-9, curve_step_mag), 6)
    return StaticAvailability(
        availability=field.availability(m_t, n_min),
        n_min=n_min,
        max_mag=m_t,
        n_orientations=len(boresights),
        n_stars=n_stars,
        by_n_min={k: field.availability(m_t, k) for k in keys},
        counts=counts,
        boresights=boresights,
        mag_grid=grid,
        curve={k: field.availability(grid, k) for k in keys},
        fov=fov,
        catalog=catalog,
        band=band,
    )
