"""The availability analysis: one star set seen through one field, configured once, then asked.

Dzamba & Enright 2014, sec. 1.2 (spatial static), 3.1 (spatial dynamic) and 4 (along-track).
Angles are radians and rates rad/s.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from starsense._validate import check_count, check_int, finite_array, finite_float
from starsense.analysis.availability.checks import Fov, check_fov, check_mag, check_rates
from starsense.analysis.availability.field import FieldStars, catalog_stars
from starsense.analysis.availability.pointings import (
    MAX_ORIENTATIONS,
    ORIENTATION_COST,
    describe_fov,
    sky_attitudes,
    track_family_attitudes,
)
from starsense.analysis.availability.results import (
    N_MIN_LOST_IN_SPACE,
    N_MIN_TRACKING,
    DynamicAvailability,
    StaticAvailability,
    TrackAvailability,
    static_result,
)
from starsense.analysis.availability.threshold import ThresholdCurve
from starsense.analysis.inputs import root_seed
from starsense.errors import InputError
from starsense.geometry.fov import RectangularFov
from starsense.units import DEG

__all__ = [
    "DEFAULT_INCLINATIONS",
    "DEFAULT_N_ORIENTATIONS",
    "DEFAULT_TRACK_SAMPLES",
    "AvailabilityAnalysis",
    "implied_threshold",
]

#: the paper's number of spatial orientations (sec. 1.2)
DEFAULT_N_ORIENTATIONS = 10_000
#: the paper's samples per orientation track, N_track (sec. 4)
DEFAULT_TRACK_SAMPLES = 1_000
#: track inclinations, -90 ... 90 deg in 1 deg steps (sec. 4: "-90 <= i <= 90"), rad
DEFAULT_INCLINATIONS = np.arange(-90.0, 90.5, 1.0) * DEG


def _check_curve(curve: object) -> ThresholdCurve:
    if not isinstance(curve, ThresholdCurve):
        raise InputError(f"curve must be a ThresholdCurve, got {type(curve).__name__}")
    return curve


class AvailabilityAnalysis:
    """Availability of one star set seen through one field: configure, then ask.

    The stars in the field are found once per set of pointings (the sky grid, the track
    family) and kept; :meth:`static`, :meth:`dynamic` and :meth:`track` are then lookups.

    Parameters
    ----------
    vectors : array_like, shape (N, 3)
        Star unit vectors, ICRS.
    magnitudes : array_like, shape (N,)
        Their magnitudes; stars fainter than `max_mag` are dropped.
    fov : CircularFov or RectangularFov
        The field.
    max_mag : float
        Catalogue cut: no star fainter than this is ever counted (the on-board catalogue).
    n_orientations : int
        Spatial boresights (spherical Fibonacci lattice).
    roll_rad : float or None
        Roll of the spatial attitudes, rad (None: uniform random from `rng`); matters only
        for a rectangular field.
    rng : None, int or numpy.random.Generator
        Seed of the random rolls.
    catalog, band : str
        Names for reports.
    progress : callable(str, done, total) or None
        Progress of the slow steps.
    """

    def __init__(
        self,
        vectors: ArrayLike,
        magnitudes: ArrayLike,
        fov: Fov,
        *,
        max_mag: float = math.inf,
        n_orientations: int = DEFAULT_N_ORIENTATIONS,
        roll_rad: float | None = None,
        rng: int | np.random.Generator | None = 0,
        catalog: str = "",
        band: str = "V",
        progress: Callable[[str, int, int], None] | None = None,
    ) -> None:
        check_fov(fov)
        self.max_mag = check_mag(max_mag, "max_mag", allow_inf=True)
        v = np.asarray(vectors, dtype=np.float64)
        m = np.asarray(magnitudes, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 3 or m.shape != (v.shape[0],):
            raise InputError(
                f"vectors must be (N, 3) and magnitudes (N,); got {v.shape} and {m.shape}"
            )
        keep = m <= self.max_mag
        if not keep.any():
            raise InputError(
                f"magnitude limit max_mag {self.max_mag:g} leaves no stars of "
                f"{catalog or 'the star set'} ({len(m)} stars); raise max_mag"
            )
        self.vectors = v[keep]
        self.magnitudes = m[keep]
        self.fov = fov
        self.n_orientations = check_count(
            n_orientations, "n_orientations", MAX_ORIENTATIONS, ORIENTATION_COST
        )
        self.roll_rad = None if roll_rad is None else finite_float(roll_rad, "roll_rad")
        self.seed = root_seed(rng)  # recorded: the rolls are drawn from it
        self.catalog = catalog
        self.band = band
        self.progress = progress
        self._tracks: dict[tuple, FieldStars] = {}

    @classmethod
    def from_catalog(
        cls, catalog: Any, fov: Fov, max_mag: float, *, band: str = "V", **kwargs: Any
    ) -> AvailabilityAnalysis:
        """Build the analysis of a catalogue's stars with ``mag <= max_mag`` in `band`.

        `catalog` is a :class:`~starsense.catalog.Catalog` or anything with ``vectors`` and
        ``mags[band]``; `kwargs` go to the constructor.
        """
        vectors, mags = catalog_stars(catalog, max_mag, band=band)
        name = getattr(catalog, "name", "")
        return cls(vectors, mags, fov, max_mag=max_mag, catalog=name, band=band, **kwargs)

    @property
    def n_stars(self) -> int:
        """Stars used, after the magnitude cut."""
        return len(self.magnitudes)

    @cached_property
    def tree(self) -> cKDTree:
        """A k-d tree over the star vectors."""
        return cKDTree(self.vectors)

    def _reporter(self, label: str) -> Callable[[int, int], None] | None:
        if self.progress is None:
            return None
        report = self.progress
        return lambda done, total: report(label, done, total)

    @cached_property
    def _sky(self) -> tuple[NDArray[np.float64], FieldStars]:
        roll = self.roll_rad if isinstance(self.fov, RectangularFov) else 0.0
        boresights, attitudes = sky_attitudes(self.n_orientations, roll, self.seed)
        stars = FieldStars.build(
            self.fov,
            attitudes,
            self.vectors,
            self.magnitudes,
            tree=self.tree,
            progress=self._reporter("stars in the field, sky grid"),
        )
        return boresights, stars

    @property
    def boresights(self) -> NDArray[np.float64]:
        """The spatial boresights, (n_orientations, 3)."""
        return self._sky[0]

    @property
    def sky(self) -> FieldStars:
        """Stars in the field at the spatial orientations."""
        return self._sky[1]

    def effective_threshold(self, m_t: ArrayLike) -> NDArray[np.float64]:
        """Return the threshold capped at the catalogue cut, ``min(m_t, max_mag)``."""
        return np.minimum(np.asarray(m_t, dtype=np.float64), self.max_mag)

    # -- spatial static ----------------------------------------------------------------------
    def static(
        self,
        n_min: int = N_MIN_LOST_IN_SPACE,
        *,
        max_mag: float | None = None,
        curve_span_mag: float = 3.0,
        curve_step_mag: float = 0.05,
    ) -> StaticAvailability:
        """Return the spatial static availability at `max_mag` (default: the catalogue cut).

        Also computes availability against m_t from ``max_mag - curve_span_mag`` to
        ``max_mag`` (Fig. 6) for N_min = 1 ... 4.
        """
        n_min = check_int(n_min, "n_min", 1)
        m_t = self.max_mag if max_mag is None else check_mag(max_mag, "max_mag")
        m_t = float(min(m_t, self.max_mag))
        if not math.isfinite(m_t):
            m_t = float(self.magnitudes.max())
        return static_result(
            self.sky,
            self.sky.counts(m_t),
            boresights=self.boresights,
            n_min=n_min,
            m_t=m_t,
            n_stars=self.n_stars,
            fov=describe_fov(self.fov),
            catalog=self.catalog,
            band=self.band,
            curve_span_mag=curve_span_mag,
            curve_step_mag=curve_step_mag,
        )

    # -- spatial dynamic ---------------------------------------------------------------------
    def dynamic(
        self, curve: ThresholdCurve, rates_rad_s: ArrayLike, n_min: int = N_MIN_LOST_IN_SPACE
    ) -> DynamicAvailability:
        """Return the spatial dynamic availability at each rate (rad/s).

        The threshold is ``m_t = min(curve(w), catalogue cut)``.
        """
        n_min = check_int(n_min, "n_min", 1)
        rates = check_rates(rates_rad_s, "rates_rad_s")
        _check_curve(curve)
        m_t = self.effective_threshold(curve(rates))
        keys = sorted({N_MIN_TRACKING, N_MIN_LOST_IN_SPACE, n_min})
        by = {k: np.asarray(self.sky.availability(m_t, k), dtype=np.float64) for k in keys}
        return DynamicAvailability(
            rates_rad_s=rates,
            threshold_mag=m_t,
            availability=by[n_min],
            by_n_min=by,
            n_min=n_min,
            n_orientations=self.n_orientations,
            n_stars=self.n_stars,
            max_mag=self.max_mag,
            curve=curve,
            fov=describe_fov(self.fov),
            catalog=self.catalog,
            band=self.band,
        )

    def sky_counts(self, m_t: float) -> NDArray[np.intp]:
        """Return the stars ``<= min(m_t, cut)`` in the field per spatial orientation."""
        return self.sky.counts(float(self.effective_threshold(m_t)))

    # -- along-track -------------------------------------------------------------------------
    def track_field(
        self,
        inclinations: ArrayLike = DEFAULT_INCLINATIONS,
        n_samples: int = DEFAULT_TRACK_SAMPLES,
        node_rad: float = 0.0,
    ) -> FieldStars:
        """Return the stars in the field along every track (track-major, `n_samples` each).

        Inclinations and node in rad, as :func:`track_family_attitudes`.
        """
        incl = np.atleast_1d(finite_array(inclinations, "inclinations"))
        key = (tuple(incl.tolist()), int(n_samples), float(node_rad))
        if key not in self._tracks:
            attitudes = track_family_attitudes(incl, n_samples, node_rad)
            self._tracks[key] = FieldStars.build(
                self.fov,
                attitudes,
                self.vectors,
                self.magnitudes,
                tree=self.tree,
                progress=self._reporter("stars in the field, tracks"),
            )
        return self._tracks[key]

    def track(
        self,
        curve: ThresholdCurve,
        rate_rad_s: float,
        *,
        n_min: int = N_MIN_LOST_IN_SPACE,
        inclinations: ArrayLike = DEFAULT_INCLINATIONS,
        n_samples: int = DEFAULT_TRACK_SAMPLES,
        node_rad: float = 0.0,
    ) -> TrackAvailability:
        """Return the along-track availability of each track at one constant slew rate.

        Parameters
        ----------
        curve : ThresholdCurve
            The detection threshold against rate.
        rate_rad_s : float
            Slew rate along the tracks, rad/s.
        n_min : int
            Stars needed.
        inclinations : array_like, shape (I,)
            Track inclinations, rad.
        n_samples : int
            Orientations per track.
        node_rad : float
            RA of the tracks' common node, rad.

        Returns
        -------
        TrackAvailability
        """
        n_min = check_int(n_min, "n_min", 1)
        rate = float(check_rates(rate_rad_s, "rate_rad_s")[0])
        n_samples = check_int(n_samples, "n_samples", 1)
        _check_curve(curve)
        incl = np.atleast_1d(finite_array(inclinations, "inclinations"))
        tracks = self.track_field(incl, n_samples, node_rad)
        m_t = float(self.effective_threshold(curve([rate]))[0])
        keys = sorted({N_MIN_TRACKING, N_MIN_LOST_IN_SPACE, n_min})
        by = {
            k: (tracks.kth_magnitude(k).reshape(incl.size, n_samples) <= m_t).mean(axis=1)
            for k in keys
        }
        return TrackAvailability(
            rate_rad_s=rate,
            threshold_mag=m_t,
            inclinations=incl,
            availability=by[n_min],
            by_n_min=by,
            spatial={k: self.sky.availability(m_t, k) for k in keys},
            n_min=n_min,
            n_samples=n_samples,
            n_stars=self.n_stars,
            n_orientations=self.n_orientations,
            node=float(node_rad),
            fov=describe_fov(self.fov),
            catalog=self.catalog,
            band=self.band,
            curve_label=curve.label,
        )


def implied_threshold(analysis: AvailabilityAnalysis, availability: float, n_min: int) -> float:
    """Return the m_t at which the spatial availability equals `availability`.

    Bisection on the monotone availability curve of the analysis's sky grid: what a quoted
    availability (e.g. Table 2's spatial column) implies for the threshold on our sky. NaN if
    even the catalogue cut does not reach it.
    """
    lo, hi = float(analysis.magnitudes.min()) - 1.0, float(analysis.max_mag)
    if analysis.sky.availability(hi, n_min) < availability:
        return math.nan
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if analysis.sky.availability(mid, n_min) >= availability:
            hi = mid
        else:
            lo = mid
    return hi
