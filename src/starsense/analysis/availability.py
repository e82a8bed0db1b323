"""Star-tracker availability: spatial static, spatial dynamic and along-track dynamic.

Dzamba & Enright 2014 (Sensors 14, 3939), sec. 1.1-1.3 and 4. Availability is the fraction of
sensor orientations at which at least ``N_min`` stars brighter than the detection threshold
``m_t`` fall inside the field of view: ``N_min = 2`` to track, 3 to solve lost-in-space, 4 as a
conservative allowance for pattern ambiguity.

* **Spatial static** (sec. 1.2, Figs. 4-6): ``N`` quasi-uniform boresights (a spherical
  Fibonacci lattice standing in for the paper's Marantis distribution) and a fixed ``m_t``.
* **Spatial dynamic** (sec. 3.1, Fig. 11): the same boresights, with ``m_t = m_t(w)`` read from
  the tolerable-slew curve of the detection simulation (Fig. 10), :class:`ThresholdCurve`.
* **Along-track dynamic** (sec. 4, Figs. 16-17, Table 2): the boresight follows a great circle of
  inclination ``i`` to the celestial equator, sampled at ``N_track`` equally spaced orientations,
  while the sensor slews along it at a constant rate (the streaks run along the detector rows,
  camera +x, as in the slew simulation).

How it is computed
------------------
The stars inside the field at each pointing are found once (a :class:`scipy.spatial.cKDTree`
cone prefilter, then the exact field test), and their magnitudes are kept sorted per pointing
(:class:`FieldStars`, a CSR layout). The ``k``-th brightest magnitude in the field,
``m_(k)``, then answers every question: a pointing sees at least ``N_min`` stars brighter than
``m_t`` exactly when ``m_(N_min) <= m_t``, so the availability for any threshold is the empirical
distribution function of ``m_(N_min)`` over the pointings — one ``searchsorted`` per threshold.
Availability against ``m_t`` (Fig. 6), against slew rate (Fig. 11) and along every track
(Table 2) are lookups into the same sorted arrays; nothing is recounted per threshold.

The catalogue's positions are used at its own epoch (proper motion over a few decades moves the
bright stars by arcseconds, nothing at the scale of a 7.5 deg field).

Frame conventions are those of :mod:`starsense.geometry.attitude`.
"""

from __future__ import annotations

import itertools
import math
import operator
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from starsense.errors import InputError
from starsense.geometry.attitude import attitude_from_radec_roll, vectors_to_radec
from starsense.geometry.fov import CircularFov, RectangularFov
from starsense.geometry.sampling import fibonacci_sphere, track_attitudes

__all__ = [
    "DEFAULT_INCLINATIONS_DEG",
    "DEFAULT_N_ORIENTATIONS",
    "DEFAULT_TRACK_SAMPLES",
    "N_MIN_CONSERVATIVE",
    "N_MIN_LOST_IN_SPACE",
    "N_MIN_TRACKING",
    "PAPER_TABLE2",
    "AvailabilityAnalysis",
    "DynamicAvailability",
    "FidelityCheck",
    "FieldStars",
    "StaticAvailability",
    "ThresholdCurve",
    "TrackAvailability",
    "catalog_stars",
    "check_count",
    "check_n_min",
    "check_rates",
    "describe_fov",
    "fidelity_check",
    "field_of_view",
    "sky_attitudes",
    "track_family_attitudes",
]

#: two stars give the incremental attitude in tracking mode (sec. 1.1)
N_MIN_TRACKING = 2
#: three stars identify a pattern lost-in-space: the paper's definition of availability
N_MIN_LOST_IN_SPACE = 3
#: four stars: the conservative allowance for pattern ambiguity
N_MIN_CONSERVATIVE = 4

#: the paper's number of spatial orientations (sec. 1.2)
DEFAULT_N_ORIENTATIONS = 10_000
#: the paper's samples per orientation track, N_track (sec. 4)
DEFAULT_TRACK_SAMPLES = 1_000
#: track inclinations, -90 ... 90 deg in 1 deg steps (sec. 4: "-90 <= i <= 90")
DEFAULT_INCLINATIONS_DEG = np.arange(-90.0, 90.5, 1.0)

#: Dzamba & Enright 2014, Table 2: rate (deg/s) -> (N_min = 2, N_min = 3) pairs of
#: spatial dynamic, along-track mean, max and min availability, in percent.
PAPER_TABLE2: dict[float, dict[str, tuple[float, float]]] = {
    1.0: {"spatial": (93.3, 80.9), "mean": (95.5, 86.9), "max": (100.0, 100.0),
          "min": (86.2, 72.0)},
    1.5: {"spatial": (79.1, 58.6), "mean": (84.5, 66.6), "max": (98.0, 93.9),
          "min": (65.4, 45.6)},
    2.0: {"spatial": (50.8, 27.6), "mean": (67.7, 45.3), "max": (91.1, 78.0),
          "min": (45.9, 23.5)},
    3.0: {"spatial": (38.9, 14.2), "mean": (49.8, 26.6), "max": (80.1, 57.9),
          "min": (28.2, 8.0)},
}  # fmt: skip

# Margins on the prefilter chord so that rounding never drops a star the exact test accepts.
_CHORD_REL_MARGIN = 1e-9
_CHORD_ABS_MARGIN = 1e-12
# Upper bound on (pointing, star) candidate pairs held in memory at once.
_CANDIDATE_BUDGET = 2_000_000

Fov = CircularFov | RectangularFov


# ---------------------------------------------------------------------------------------------
# validation


def check_n_min(n_min: object) -> int:
    """N_min as an int >= 1, or an InputError naming --n-min."""
    if isinstance(n_min, bool | np.bool_):
        raise InputError(f"N_min (--n-min) must be an integer >= 1, got {n_min!r}")
    try:
        value = operator.index(n_min)
    except TypeError:
        raise InputError(f"N_min (--n-min) must be an integer >= 1, got {n_min!r}") from None
    if value < 1:
        raise InputError(
            f"N_min (--n-min) = {value} is out of range; must be an integer >= 1 "
            "(2 tracking, 3 lost-in-space, 4 conservative)"
        )
    return value


def check_count(n: object, name: str, option: str, minimum: int = 1) -> int:
    """A sample count as an int >= minimum, or an InputError naming the option."""
    label = f"{name} ({option})"
    if isinstance(n, bool | np.bool_):
        raise InputError(f"{label} must be an integer >= {minimum}, got {n!r}")
    try:
        value = operator.index(n)
    except TypeError:
        raise InputError(f"{label} must be an integer >= {minimum}, got {n!r}") from None
    if value < minimum:
        raise InputError(f"{label} = {value} is out of range; must be an integer >= {minimum}")
    return value


def check_rates(rates_deg_s: ArrayLike, option: str = "--rates-deg-s") -> NDArray[np.float64]:
    """Slew rates as a 1-D float array, finite and >= 0, or an InputError naming the option."""
    try:
        rates = np.atleast_1d(np.asarray(rates_deg_s, dtype=np.float64))
    except (TypeError, ValueError):
        raise InputError(f"slew rates ({option}) must be numbers, got {rates_deg_s!r}") from None
    if rates.ndim != 1 or rates.size == 0:
        raise InputError(f"slew rates ({option}) must be a non-empty list, got {rates_deg_s!r}")
    if not np.all(np.isfinite(rates)):
        raise InputError(f"slew rates ({option}) must be finite, got {rates.tolist()}")
    if np.any(rates < 0):
        bad = float(rates[rates < 0][0])
        raise InputError(
            f"slew rate ({option}) = {bad:g} deg/s is negative; rates are magnitudes |w| >= 0"
        )
    return rates


def _check_mag(value: object, name: str = "--max-mag", allow_inf: bool = False) -> float:
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InputError(f"magnitude limit ({name}) must be a number, got {value!r}") from None
    if math.isnan(x) or (math.isinf(x) and not (allow_inf and x > 0)):
        raise InputError(f"magnitude limit ({name}) must be finite, got {value!r}")
    return x


# ---------------------------------------------------------------------------------------------
# the detection threshold against slew rate


@dataclass(frozen=True)
class ThresholdCurve:
    """The stellar detection threshold against slew rate, ``m_t(w)`` (the paper's Fig. 10 read
    sideways): a star is detected at slew rate ``w`` when its magnitude is ``<= m_t(w)``.

    Between knots ``m_t`` is interpolated linearly; before the first knot and after the last it
    is held at the end value, except that above ``max_rate_deg_s`` nothing is detected
    (``m_t = -inf``).

    Parameters
    ----------
    rates_deg_s : array_like, shape (K,)
        Knot rates, deg/s: finite, >= 0, strictly increasing.
    max_mag : array_like, shape (K,)
        Threshold magnitude at each knot (finite).
    max_rate_deg_s : float
        Rate above which no star is detected, deg/s (``inf``: none; must be >= the last knot).
    label : str
        What the curve is (e.g. ``"st16, reed model"``), for reports.

    Raises
    ------
    InputError
        On an empty, unsorted, negative or non-finite knot, or mismatched lengths.
    """

    rates_deg_s: NDArray[np.float64]
    max_mag: NDArray[np.float64]
    max_rate_deg_s: float = math.inf
    label: str = ""

    def __post_init__(self) -> None:
        rates = check_rates(self.rates_deg_s, "ThresholdCurve.rates_deg_s")
        try:
            mags = np.atleast_1d(np.asarray(self.max_mag, dtype=np.float64))
        except (TypeError, ValueError):
            raise InputError(
                f"ThresholdCurve.max_mag must be numbers, got {self.max_mag!r}"
            ) from None
        if mags.shape != rates.shape:
            raise InputError(
                f"ThresholdCurve.max_mag has {mags.size} values for {rates.size} rates; "
                "give one magnitude per rate"
            )
        if not np.all(np.isfinite(mags)):
            raise InputError(f"ThresholdCurve.max_mag must be finite, got {mags.tolist()}")
        if np.any(np.diff(rates) <= 0):
            raise InputError(
                f"ThresholdCurve.rates_deg_s must be strictly increasing, got {rates.tolist()}"
            )
        top = float(self.max_rate_deg_s)
        if math.isnan(top) or top < rates[-1]:
            raise InputError(
                f"ThresholdCurve.max_rate_deg_s = {self.max_rate_deg_s!r} must be >= the last "
                f"knot rate {rates[-1]:g} deg/s"
            )
        for name, value in (("rates_deg_s", rates), ("max_mag", mags)):
            value.flags.writeable = False
            object.__setattr__(self, name, value)
        object.__setattr__(self, "max_rate_deg_s", top)

    @classmethod
    def constant(cls, max_mag: float, label: str = "") -> ThresholdCurve:
        """A threshold that does not depend on rate (static detection at every rate)."""
        mag = _check_mag(max_mag, "max_mag")
        return cls(np.array([0.0]), np.array([mag]), label=label or f"m_t = {mag:g}")

    @classmethod
    def from_tolerance(
        cls,
        magnitudes: ArrayLike,
        tolerable_rate_deg_s: Sequence[float | None],
        capped: ArrayLike | None = None,
        grid_max_rate_deg_s: float | None = None,
        label: str = "",
    ) -> ThresholdCurve:
        """Invert a tolerable-slew curve (magnitude -> fastest rate still detected, Fig. 10).

        The tolerable rate is first made monotonic (a brighter star tolerates at least the rate
        of a fainter one: a running minimum from bright to faint). Magnitudes never detected
        (``None``) are dropped. Each remaining magnitude ``m_k`` with tolerable rate ``r_k``
        becomes a knot ``(r_k, m_k)`` (of equal rates the faintest magnitude is kept), so that
        ``m_t`` interpolates the piecewise-linear inverse of Fig. 10. Magnitudes detected at every
        simulated rate (``capped``) are placed at the grid's top rate and ``m_t`` is held there
        beyond it; without capped magnitudes nothing is detected above the brightest
        magnitude's tolerable rate. At rates below the faintest detected magnitude's tolerable
        rate ``m_t`` is that magnitude: the faint limit of the simulated grid, so give a grid
        reaching past the catalogue's limit.

        Parameters
        ----------
        magnitudes : array_like, shape (M,)
        tolerable_rate_deg_s : sequence of float or None, length M
            Fastest rate at which each magnitude is still detected, deg/s; None if not even at
            rest.
        capped : array_like of bool, shape (M,), optional
            Detected at every rate of the grid.
        grid_max_rate_deg_s : float, optional
            Top rate of the simulated grid, deg/s (default: the largest tolerable rate).
        label : str

        Raises
        ------
        InputError
            If no magnitude is detected at rest, or the inputs disagree in length.
        """
        mags = np.atleast_1d(np.asarray(magnitudes, dtype=np.float64))
        tol_list = list(tolerable_rate_deg_s)
        if len(tol_list) != mags.size or mags.size == 0:
            raise InputError(
                f"tolerable-slew curve: {len(tol_list)} rates for {mags.size} magnitudes; "
                "give one rate (or None) per magnitude"
            )
        cap = np.zeros(mags.size, bool) if capped is None else np.asarray(capped, dtype=bool)
        if cap.shape != mags.shape:
            raise InputError("tolerable-slew curve: 'capped' needs one flag per magnitude")
        tol = np.array([-np.inf if r is None else float(r) for r in tol_list])
        if np.any(np.isnan(tol)) or np.any(np.isnan(mags)):
            raise InputError("tolerable-slew curve: magnitudes and rates must not be NaN")
        finite_tol = tol[np.isfinite(tol)]
        top = (
            float(grid_max_rate_deg_s)
            if grid_max_rate_deg_s is not None
            else float(finite_tol.max())
            if finite_tol.size
            else 0.0
        )
        tol = np.where(cap, np.inf, tol)
        order = np.argsort(mags, kind="stable")
        mags, tol = mags[order], tol[order]
        tol = np.minimum.accumulate(tol)  # non-increasing from bright to faint
        seen = tol > -np.inf
        if not seen.any():
            raise InputError(
                "tolerable-slew curve: no magnitude is detected even at rest "
                f"(magnitudes {mags.min():g} ... {mags.max():g}); nothing can be available"
            )
        mags, tol = mags[seen], tol[seen]
        is_capped = np.isinf(tol)
        knot_rate = np.where(is_capped, max(top, 0.0), np.maximum(tol, 0.0))
        # one knot per distinct rate, keeping the faintest magnitude
        knots: dict[float, float] = {}
        for r, m in zip(knot_rate.tolist(), mags.tolist(), strict=True):
            knots[r] = max(m, knots.get(r, -np.inf))
        rates = np.array(sorted(knots))
        max_mag = np.array([knots[r] for r in rates])
        # a fainter magnitude at a faster knot cannot happen after the running minimum; keep the
        # curve non-increasing anyway (ties of rate resolved above)
        max_mag = np.minimum.accumulate(max_mag)
        max_rate = math.inf if is_capped.any() else float(rates[-1])
        return cls(rates, max_mag, max_rate, label)

    @classmethod
    def from_slew(cls, result: Any, label: str | None = None) -> ThresholdCurve:
        """The threshold curve of a :class:`~starsense.analysis.slew.SlewResult` (its Fig. 10).

        See :meth:`from_tolerance`; the grid's top rate is the result's last simulated rate.
        """
        rates = np.asarray(result.rates_deg_s, dtype=np.float64)
        return cls.from_tolerance(
            result.magnitudes,
            result.tolerable_rate_deg_s,
            result.capped,
            float(rates[-1]) if rates.size else None,
            label if label is not None else f"{result.sensor_name}, {result.model} model",
        )

    @classmethod
    def from_tolerance_dict(cls, data: dict, source: str = "tolerance JSON") -> ThresholdCurve:
        """From the JSON of ``starsense slew tolerance --json`` (``magnitudes``,
        ``tolerable_rate_deg_s``, ``capped``, ``rates_deg_s``, ``sensor``, ``model``).
        """
        try:
            mags = data["magnitudes"]
            tol = data["tolerable_rate_deg_s"]
        except (KeyError, TypeError):
            raise InputError(
                f"{source}: expected the output of `starsense slew tolerance --json` with keys "
                "'magnitudes' and 'tolerable_rate_deg_s'"
            ) from None
        grid = data.get("rates_deg_s")
        label = ", ".join(str(data[k]) + (" model" if k == "model" else "")
                          for k in ("sensor", "model") if k in data)  # fmt: skip
        try:
            return cls.from_tolerance(
                mags, tol, data.get("capped"), float(max(grid)) if grid else None, label
            )
        except InputError as exc:
            raise InputError(f"{source}: {exc}") from None

    def __call__(self, rates_deg_s: ArrayLike) -> NDArray[np.float64]:
        """``m_t`` at the given rates (deg/s, >= 0); ``-inf`` above ``max_rate_deg_s``."""
        rates = check_rates(rates_deg_s, "rate")
        out = np.interp(rates, self.rates_deg_s, self.max_mag)
        out[rates > self.max_rate_deg_s] = -np.inf
        return out

    def to_dict(self) -> dict:
        return {
            "rates_deg_s": self.rates_deg_s.tolist(),
            "max_mag": self.max_mag.tolist(),
            "max_rate_deg_s": None if math.isinf(self.max_rate_deg_s) else self.max_rate_deg_s,
            "label": self.label,
        }


# ---------------------------------------------------------------------------------------------
# geometry helpers


def field_of_view(
    sensor: Any, kind: str = "circular", half_fov_deg: float | None = None
) -> CircularFov | RectangularFov:
    """The field used by the availability analysis.

    Parameters
    ----------
    sensor : starsense.sensor.Sensor
    kind : {"circular", "rectangular"}
        ``circular``: a cone with the detector's minor half-axis (or `half_fov_deg`), the
        paper's "7.5 deg half-axis field". ``rectangular``: the detector's real field
        (:meth:`Sensor.fov`), where roll matters.
    half_fov_deg : float, optional
        Half-angle of the circular field, deg (0 < a <= 90).

    Raises
    ------
    InputError
        Unknown `kind`, or `half_fov_deg` with a rectangular field or out of range.
    """
    if kind == "rectangular":
        if half_fov_deg is not None:
            raise InputError(
                "--half-fov-deg sets the circular field only; the rectangular field is the "
                "detector's (drop --half-fov-deg or use --fov circular)"
            )
        return sensor.fov()
    if kind != "circular":
        raise InputError(f"field of view (--fov) must be 'circular' or 'rectangular', got {kind!r}")
    if half_fov_deg is None:
        return CircularFov(min(sensor.half_fov_rad))
    a = _check_mag(half_fov_deg, "--half-fov-deg")  # finite number
    if not 0.0 < a <= 90.0:
        raise InputError(
            f"half field (--half-fov-deg) = {a:g} deg is out of range; allowed (0, 90]"
        )
    return CircularFov(math.radians(a))


def describe_fov(fov: Fov) -> str:
    """A short text: ``circular, half-angle 7.50 deg`` or ``rectangular 20.2 x 15.2 deg``."""
    if isinstance(fov, CircularFov):
        return f"circular, half-angle {math.degrees(fov.half_angle_rad):.2f} deg"
    return (
        f"rectangular {2 * math.degrees(fov.half_width_rad):.2f} x "
        f"{2 * math.degrees(fov.half_height_rad):.2f} deg"
    )


def sky_attitudes(
    n: int, roll_deg: float | None = None, seed: int | None = 0
) -> tuple[NDArray[np.float64], Rotation]:
    """Quasi-uniform boresights (spherical Fibonacci lattice) and attitudes with a roll.

    Parameters
    ----------
    n : int
        Number of orientations (>= 1).
    roll_deg : float or None
        Roll of every attitude, deg (convention of :mod:`starsense.geometry.attitude`); None
        draws each roll uniformly in [0, 360) from `seed`. Irrelevant for a circular field.
    seed : int or None
        Seed of the random rolls.

    Returns
    -------
    boresights : ndarray, shape (n, 3)
        ICRS unit vectors.
    attitudes : Rotation, batch of n
    """
    n = check_count(n, "number of orientations", "--n-orientations")
    boresights = fibonacci_sphere(n)
    ra, dec = vectors_to_radec(boresights)
    if roll_deg is None:
        roll = np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi, n)
    else:
        roll = np.full(n, math.radians(_check_mag(roll_deg, "--roll-deg")))
    return boresights, attitude_from_radec_roll(np.atleast_1d(ra), np.atleast_1d(dec), roll)


def track_family_attitudes(
    inclinations_deg: ArrayLike, n_samples: int, node_deg: float = 0.0
) -> Rotation:
    """Attitudes along great-circle tracks, one block of `n_samples` per inclination.

    Each track (:func:`starsense.geometry.sampling.track_attitudes`) starts at the node (on the
    equator at RA = `node_deg`), has the given inclination to the celestial equator, and the
    camera +x axis points along the motion, so the streaks run along the detector rows as in
    the slew simulation.

    Returns
    -------
    Rotation, batch of ``len(inclinations_deg) * n_samples``
        Track-major order: samples of the first inclination first.
    """
    incl = np.atleast_1d(np.asarray(inclinations_deg, dtype=np.float64))
    if incl.ndim != 1 or incl.size == 0 or not np.all(np.isfinite(incl)):
        raise InputError(f"inclinations (deg) must be a non-empty list of numbers, got {incl}")
    if np.any(np.abs(incl) > 90.0):
        raise InputError(f"inclinations must lie in [-90, 90] deg, got {incl.tolist()}")
    n = check_count(n_samples, "samples per track", "--track-samples")
    node = math.radians(_check_mag(node_deg, "--node-deg"))
    mats = [track_attitudes(math.radians(i), n, ascending_node_rad=node).as_matrix() for i in incl]
    return Rotation.from_matrix(np.concatenate(mats, axis=0))


# ---------------------------------------------------------------------------------------------
# the counting kernel


def _inside_camera(fov: Fov, v_cam: NDArray[np.float64]) -> NDArray[np.bool_]:
    """The exact field test on camera-frame vectors (..., 3) (same tests as geometry.fov)."""
    x, y, z = v_cam[..., 0], v_cam[..., 1], v_cam[..., 2]
    if isinstance(fov, CircularFov):
        return z >= math.cos(fov.half_angle_rad)
    return (
        (z > 0.0)
        & (np.abs(x) <= z * math.tan(fov.half_width_rad))
        & (np.abs(y) <= z * math.tan(fov.half_height_rad))
    )


def field_pairs(
    fov: Fov,
    matrices: NDArray[np.float64],
    vectors: NDArray[np.float64],
    tree: cKDTree | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """All (pointing, star) pairs with the star inside the field.

    A k-d tree over the stars gives the candidates within the chord of the field's enclosing
    radius around each boresight; the exact field test is applied to the candidates in NumPy,
    in blocks of at most a few million pairs.

    Parameters
    ----------
    fov : CircularFov or RectangularFov
    matrices : ndarray, shape (M, 3, 3)
        Attitude matrices (ICRS -> camera; row 2 is the boresight).
    vectors : ndarray, shape (N, 3)
        Star unit vectors, ICRS.
    tree : cKDTree, optional
        Built on exactly `vectors`.
    progress : callable(done, total), optional
        Called after each block with the pointings done.

    Returns
    -------
    point_idx, star_idx : ndarray of int, shape (P,)
        Pairs in ascending pointing order (star order within a pointing is arbitrary).
    """
    if not isinstance(fov, CircularFov | RectangularFov):
        raise InputError(f"fov must be a CircularFov or RectangularFov, got {type(fov).__name__}")
    n_att = matrices.shape[0]
    empty = np.zeros(0, dtype=np.intp)
    if n_att == 0 or vectors.shape[0] == 0:
        return empty, empty.copy()
    if tree is None:
        tree = cKDTree(vectors)
    radius = min(fov.enclosing_radius_rad, math.pi)
    chord = 2.0 * math.sin(0.5 * radius) * (1.0 + _CHORD_REL_MARGIN) + _CHORD_ABS_MARGIN
    expected = max(1.0, 1.5 * vectors.shape[0] * math.sin(0.5 * radius) ** 2)
    block = max(1, int(_CANDIDATE_BUDGET // expected))
    points, stars = [], []
    for start in range(0, n_att, block):
        mats = matrices[start : start + block]
        lists = tree.query_ball_point(mats[:, 2, :], chord, return_sorted=False)
        lengths = np.fromiter(map(len, lists), dtype=np.intp, count=len(lists))
        total = int(lengths.sum())
        if total:
            star_idx = np.fromiter(itertools.chain.from_iterable(lists), np.intp, count=total)
            point_idx = np.repeat(np.arange(len(mats)), lengths)
            if isinstance(fov, CircularFov):  # only the boresight matters
                v_cam = np.empty((total, 3))
                v_cam[:, :2] = 0.0
                v_cam[:, 2] = np.einsum("kj,kj->k", mats[point_idx, 2, :], vectors[star_idx])
            else:
                v_cam = np.einsum("kij,kj->ki", mats[point_idx], vectors[star_idx])
            inside = _inside_camera(fov, v_cam)
            points.append(point_idx[inside] + start)
            stars.append(star_idx[inside])
        if progress is not None:
            progress(min(start + block, n_att), n_att)
    if not points:
        return empty, empty.copy()
    return np.concatenate(points), np.concatenate(stars)


@dataclass(frozen=True, eq=False)
class FieldStars:
    """Magnitudes of the stars inside the field at each of M pointings, sorted per pointing.

    CSR layout: the stars of pointing ``j`` have magnitudes
    ``magnitudes[offsets[j]:offsets[j + 1]]``, brightest first.

    Attributes
    ----------
    offsets : ndarray of int, shape (M + 1,)
    magnitudes : ndarray, shape (P,)
    n_stars : int
        Stars of the star set the field was built from (after the magnitude cut).
    """

    offsets: NDArray[np.intp]
    magnitudes: NDArray[np.float64]
    n_stars: int
    _kth_sorted: dict = field(default_factory=dict, repr=False, init=False)

    @classmethod
    def build(
        cls,
        fov: Fov,
        attitudes: Rotation,
        vectors: ArrayLike,
        magnitudes: ArrayLike,
        tree: cKDTree | None = None,
        progress: Callable[[int, int], None] | None = None,
    ) -> FieldStars:
        """Find the stars in the field at every attitude and sort their magnitudes.

        Parameters
        ----------
        fov : CircularFov or RectangularFov
        attitudes : Rotation, batch of M
            ICRS -> camera.
        vectors : array_like, shape (N, 3)
            Star unit vectors, ICRS.
        magnitudes : array_like, shape (N,)
            Star magnitudes (finite).
        tree : cKDTree, optional
            Built on exactly `vectors`.
        progress : callable(done, total), optional
        """
        v = np.asarray(vectors, dtype=np.float64)
        mags = np.asarray(magnitudes, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 3 or mags.shape != (v.shape[0],):
            raise InputError(
                f"vectors must be (N, 3) and magnitudes (N,); got {v.shape} and {mags.shape}"
            )
        if not np.all(np.isfinite(mags)):
            raise InputError("star magnitudes must be finite (drop stars without one)")
        if not isinstance(attitudes, Rotation) or attitudes.single:
            raise InputError("attitudes must be a batch of scipy Rotations")
        matrices = attitudes.as_matrix().reshape(-1, 3, 3)
        n_att, n = matrices.shape[0], v.shape[0]
        if tree is not None and (tree.n != n or tree.m != 3):
            raise InputError("tree must be a cKDTree built on exactly the star vectors")
        points, stars = field_pairs(fov, matrices, v, tree, progress)
        # sort by (pointing, magnitude): rank the stars by magnitude once, then one integer sort
        rank = np.empty(n, dtype=np.int64)
        order = np.argsort(mags, kind="stable")
        rank[order] = np.arange(n)
        key = np.sort(points.astype(np.int64) * max(n, 1) + rank[stars])
        sorted_mags = mags[order][key % max(n, 1)] if key.size else np.zeros(0)
        counts = (
            np.bincount(key // max(n, 1), minlength=n_att)
            if key.size
            else np.zeros(n_att, dtype=np.intp)
        )
        offsets = np.zeros(n_att + 1, dtype=np.intp)
        np.cumsum(counts, out=offsets[1:])
        return cls(offsets, np.ascontiguousarray(sorted_mags, dtype=np.float64), int(n))

    @property
    def n_pointings(self) -> int:
        return len(self.offsets) - 1

    def counts(self, max_mag: float = math.inf) -> NDArray[np.intp]:
        """Stars with magnitude ``<= max_mag`` in the field at each pointing, shape (M,)."""
        m = float(max_mag)
        if math.isnan(m):
            raise InputError("detection threshold m_t must not be NaN")
        if m == math.inf:
            return np.diff(self.offsets)
        point = np.repeat(np.arange(self.n_pointings), np.diff(self.offsets))
        return np.bincount(point[self.magnitudes <= m], minlength=self.n_pointings)

    def kth_magnitude(self, k: int) -> NDArray[np.float64]:
        """Magnitude of the ``k``-th brightest star in the field at each pointing, shape (M,);
        ``inf`` where fewer than ``k`` stars are in the field.
        """
        k = check_n_min(k)
        start, stop = self.offsets[:-1], self.offsets[1:]
        has = (stop - start) >= k
        out = np.full(self.n_pointings, np.inf)
        out[has] = self.magnitudes[start[has] + k - 1]
        return out

    def _sorted_kth(self, n_min: int) -> NDArray[np.float64]:
        cached = self._kth_sorted.get(n_min)
        if cached is None:
            cached = np.sort(self.kth_magnitude(n_min))
            self._kth_sorted[n_min] = cached
        return cached

    def availability(self, max_mag: ArrayLike, n_min: int) -> float | NDArray[np.float64]:
        """Fraction of pointings with at least `n_min` stars of magnitude ``<= max_mag``.

        Vectorised over `max_mag` (any shape; ``-inf`` gives 0): the empirical distribution
        function of the ``n_min``-th brightest magnitude in the field.
        """
        n_min = check_n_min(n_min)
        return _availability(self._sorted_kth(n_min), max_mag, self.n_pointings)

    def available(self, max_mag: ArrayLike, n_min: int) -> NDArray[np.bool_]:
        """Per-pointing flag: at least `n_min` stars ``<= max_mag`` (shape (M,), or (..., M)
        for an array of thresholds).
        """
        kth = self.kth_magnitude(n_min)
        return kth <= np.asarray(max_mag, dtype=np.float64)[..., None]

    def brightest(self, k: int) -> BrightestInField:
        """The `k` brightest magnitudes in the field at each pointing (see
        :class:`BrightestInField`): all that availability for N_min <= k needs, in a form that
        merges exactly over disjoint star sets.
        """
        k = check_n_min(k)
        mags = np.column_stack([self.kth_magnitude(j) for j in range(1, k + 1)])
        return BrightestInField(mags.reshape(self.n_pointings, k), self.n_stars)


def _availability(
    sorted_kth: NDArray[np.float64], max_mag: ArrayLike, n_pointings: int
) -> float | NDArray[np.float64]:
    """Fraction of pointings whose sorted k-th brightest magnitude is ``<= max_mag``."""
    m = np.asarray(max_mag, dtype=np.float64)
    if np.any(np.isnan(m)):
        raise InputError("detection threshold m_t must not be NaN")
    if n_pointings == 0:
        raise InputError("no pointings: availability is undefined")
    frac = np.searchsorted(sorted_kth, m, side="right") / n_pointings
    return float(frac) if frac.ndim == 0 else frac


@dataclass(frozen=True, eq=False)
class BrightestInField:
    """The ``K`` brightest magnitudes in the field at each of M pointings.

    Availability for any N_min <= K needs nothing else, and two of these built from disjoint
    star sets (tiles of a HATS catalogue, :mod:`starsense.scale`) merge exactly into the one
    of their union (:meth:`merge`).

    Attributes
    ----------
    magnitudes : ndarray, shape (M, K)
        Ascending along each row; ``inf`` where fewer than K stars are in the field.
    n_stars : int
        Stars of the star set(s) the field was built from.
    """

    magnitudes: NDArray[np.float64]
    n_stars: int

    @property
    def n_pointings(self) -> int:
        return self.magnitudes.shape[0]

    def kth_magnitude(self, k: int) -> NDArray[np.float64]:
        """As :meth:`FieldStars.kth_magnitude`, for k <= K."""
        k = check_n_min(k)
        if k > self.magnitudes.shape[1]:
            raise InputError(f"only the {self.magnitudes.shape[1]} brightest stars are kept; k={k}")
        return self.magnitudes[:, k - 1]

    def availability(self, max_mag: ArrayLike, n_min: int) -> float | NDArray[np.float64]:
        """As :meth:`FieldStars.availability`, for N_min <= K."""
        return _availability(np.sort(self.kth_magnitude(n_min)), max_mag, self.n_pointings)

    @classmethod
    def merge(cls, parts: Sequence[BrightestInField]) -> BrightestInField:
        """The K brightest of the union of disjoint star sets, from each set's K brightest."""
        if not parts:
            raise InputError("nothing to merge")
        k = parts[0].magnitudes.shape[1]
        mags = np.sort(np.concatenate([p.magnitudes for p in parts], axis=1), axis=1)[:, :k]
        return cls(np.ascontiguousarray(mags), int(sum(p.n_stars for p in parts)))


# ---------------------------------------------------------------------------------------------
# star sets


def catalog_stars(
    catalog: Any, max_mag: float, band: str = "V", allow_empty: bool = False
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Unit vectors and magnitudes of the catalogue stars with ``mag <= max_mag`` in `band`.

    Works on a :class:`~starsense.catalog.Catalog` or anything with ``vectors`` (N, 3) and
    ``mags[band]`` (N,). Stars without a magnitude are dropped. ``allow_empty`` returns empty
    arrays instead of raising when no star passes the cut (one tile of a catalogue that is
    processed tile by tile, :mod:`starsense.scale`).

    Raises
    ------
    InputError
        If the band is missing or the cut leaves no star (the message gives the brightest
        magnitude present).
    """
    m = _check_mag(max_mag, allow_inf=True)  # +inf: every star with a magnitude
    mags_all = getattr(catalog, "mags", {})
    name = getattr(catalog, "name", "catalogue")
    if band not in mags_all:
        raise InputError(
            f"catalogue {name!r} has no {band} magnitudes; bands: {', '.join(mags_all) or 'none'}"
        )
    mags = np.asarray(mags_all[band], dtype=np.float64)
    keep = mags <= m
    if not keep.any() and allow_empty:
        return np.zeros((0, 3)), np.zeros(0)
    if not keep.any():
        finite = mags[np.isfinite(mags)]
        brightest = f"{finite.min():.2f}" if finite.size else "none"
        raise InputError(
            f"magnitude limit --max-mag {m:g} leaves no stars of catalogue {name!r} "
            f"(brightest {band} = {brightest}); raise --max-mag"
        )
    vectors = np.asarray(catalog.vectors, dtype=np.float64)[keep]
    return vectors, mags[keep]


# ---------------------------------------------------------------------------------------------
# results


def _pct(x: float) -> str:
    return f"{100.0 * x:.2f} %"


@dataclass(frozen=True)
class StaticAvailability:
    """Spatial static availability (sec. 1.2; Figs. 4-6).

    Attributes
    ----------
    availability : float
        Fraction of orientations with at least `n_min` stars ``<= max_mag`` in the field.
    n_min : int
    max_mag : float
        Detection threshold m_t (= the catalogue cut).
    n_orientations, n_stars : int
        Orientations tested; catalogue stars used (after the cut).
    by_n_min : dict of int -> float
        Availability for N_min = 1 ... 4 (and `n_min`).
    counts : ndarray (n_orientations,)
        Stars in the field per orientation (for the sky maps).
    boresights : ndarray (n_orientations, 3)
    mag_grid : ndarray (K,)
        Thresholds of the availability-against-m_t curve (Fig. 6).
    curve : dict of int -> ndarray (K,)
        Availability at each ``mag_grid`` threshold, per N_min.
    fov, catalog, band : str
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
        """Human-readable summary."""
        return [
            f"spatial static availability, N_min = {self.n_min}, m_t = {self.max_mag:g}: "
            f"{_pct(self.availability)}",
            f"  {self.n_orientations} orientations, {self.n_stars} stars used "
            f"({self.catalog}, {self.band} <= {self.max_mag:g}), field {self.fov}",
            "  by N_min: " + ", ".join(f"{k}: {_pct(v)}" for k, v in sorted(self.by_n_min.items())),
            f"  stars in field: min {self.counts.min()}, mean {self.counts.mean():.1f}, "
            f"max {self.counts.max()}",
        ]


@dataclass(frozen=True)
class DynamicAvailability:
    """Spatial dynamic availability against slew rate (sec. 3.1; Fig. 11).

    Attributes
    ----------
    rates_deg_s : ndarray (R,)
    threshold_mag : ndarray (R,)
        Effective m_t at each rate: ``min(curve(w), max_mag)``.
    availability : ndarray (R,)
        At `n_min`.
    by_n_min : dict of int -> ndarray (R,)
        For N_min = 2, 3 (and `n_min`).
    n_min, n_orientations, n_stars : int
    max_mag : float
        Catalogue cut.
    curve : ThresholdCurve
    fov, catalog, band : str
    """

    rates_deg_s: NDArray[np.float64]
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

    def to_dict(self) -> dict:
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
    rate_deg_s, threshold_mag : float
        Slew rate and the effective m_t at that rate.
    inclinations_deg : ndarray (I,)
    availability : ndarray (I,)
        Fraction of each track's samples with at least `n_min` stars, at `n_min`.
    by_n_min : dict of int -> ndarray (I,)
    spatial : dict of int -> float
        Spatial dynamic availability at the same rate, for comparison.
    n_min, n_samples, n_stars, n_orientations : int
    node_deg : float
        RA of the tracks' common node.
    """

    rate_deg_s: float
    threshold_mag: float
    inclinations_deg: NDArray[np.float64]
    availability: NDArray[np.float64]
    by_n_min: dict[int, NDArray[np.float64]]
    spatial: dict[int, float]
    n_min: int
    n_samples: int
    n_stars: int
    n_orientations: int
    node_deg: float = 0.0
    fov: str = ""
    catalog: str = ""
    band: str = "V"
    curve_label: str = ""

    @property
    def mean(self) -> float:
        return float(self.availability.mean())

    @property
    def max(self) -> float:
        return float(self.availability.max())

    @property
    def min(self) -> float:
        return float(self.availability.min())

    def stats(self, n_min: int) -> dict[str, float]:
        """Mean / max / min over the inclinations, and the spatial value, at `n_min`."""
        a = self.by_n_min[n_min]
        return {
            "spatial": self.spatial[n_min],
            "mean": float(a.mean()),
            "max": float(a.max()),
            "min": float(a.min()),
        }

    def to_dict(self) -> dict:
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
        mt = f"{self.threshold_mag:.2f}" if np.isfinite(self.threshold_mag) else "none"
        out = [
            f"along-track dynamic availability at {self.rate_deg_s:g} deg/s (m_t = {mt}; "
            f"{self.curve_label or 'given threshold curve'}), {len(self.inclinations_deg)} "
            f"tracks x {self.n_samples} samples, node RA {self.node_deg:g} deg, "
            f"{self.n_stars} stars used",
            "  N_min  spatial    mean     max     min",
        ]
        for k in sorted(self.by_n_min):
            s = self.stats(k)
            out.append(
                f"  {k:5d}  " + "  ".join(f"{100 * s[c]:6.2f}%" for c in ("spatial", "mean",
                                                                          "max", "min"))
            )  # fmt: skip
        return out


def static_result(
    field: FieldStars | BrightestInField,
    counts: NDArray[np.intp],
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
    counts : ndarray (M,)
        Stars ``<= m_t`` in the field per boresight.
    boresights : ndarray (M, 3)
    n_min : int
    m_t : float
        Detection threshold (finite).
    n_stars : int
        Stars used, after the catalogue cut.
    fov, catalog, band : str
        Descriptions for reports.
    curve_span_mag, curve_step_mag : float
        Availability against m_t from ``m_t - curve_span_mag`` to ``m_t`` (Fig. 6).
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


# ---------------------------------------------------------------------------------------------
# the analysis


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
    max_mag : float
        Catalogue cut: no star fainter than this is ever counted (the on-board catalogue).
    n_orientations : int
        Spatial boresights (spherical Fibonacci lattice).
    roll_deg : float or None
        Roll of the spatial attitudes (None: uniform random from `seed`); matters only for a
        rectangular field.
    seed : int or None
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
        roll_deg: float | None = None,
        seed: int | None = 0,
        catalog: str = "",
        band: str = "V",
        progress: Callable[[str, int, int], None] | None = None,
    ) -> None:
        if not isinstance(fov, CircularFov | RectangularFov):
            raise InputError(
                f"fov must be a CircularFov or RectangularFov, got {type(fov).__name__}"
            )
        self.max_mag = _check_mag(max_mag, allow_inf=True)
        v = np.asarray(vectors, dtype=np.float64)
        m = np.asarray(magnitudes, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 3 or m.shape != (v.shape[0],):
            raise InputError(
                f"vectors must be (N, 3) and magnitudes (N,); got {v.shape} and {m.shape}"
            )
        keep = m <= self.max_mag
        if not keep.any():
            raise InputError(
                f"magnitude limit --max-mag {self.max_mag:g} leaves no stars of "
                f"{catalog or 'the star set'} ({len(m)} stars); raise --max-mag"
            )
        self.vectors = v[keep]
        self.magnitudes = m[keep]
        self.fov = fov
        self.n_orientations = check_count(
            n_orientations, "number of orientations", "--n-orientations"
        )
        self.roll_deg = None if roll_deg is None else _check_mag(roll_deg, "--roll-deg")
        self.seed = seed
        self.catalog = catalog
        self.band = band
        self.progress = progress
        self._tracks: dict[tuple, FieldStars] = {}

    @classmethod
    def from_catalog(
        cls, catalog: Any, fov: Fov, max_mag: float, band: str = "V", **kwargs: Any
    ) -> AvailabilityAnalysis:
        """From a :class:`~starsense.catalog.Catalog` (or anything with ``vectors`` and
        ``mags[band]``), keeping the stars with ``mag <= max_mag``.
        """
        vectors, mags = catalog_stars(catalog, max_mag, band)
        name = getattr(catalog, "name", "")
        return cls(vectors, mags, fov, max_mag=max_mag, catalog=name, band=band, **kwargs)

    @property
    def n_stars(self) -> int:
        """Stars used, after the magnitude cut."""
        return len(self.magnitudes)

    @cached_property
    def tree(self) -> cKDTree:
        return cKDTree(self.vectors)

    def _reporter(self, label: str) -> Callable[[int, int], None] | None:
        if self.progress is None:
            return None
        report = self.progress
        return lambda done, total: report(label, done, total)

    @cached_property
    def _sky(self) -> tuple[NDArray[np.float64], FieldStars]:
        roll = self.roll_deg if isinstance(self.fov, RectangularFov) else 0.0
        boresights, attitudes = sky_attitudes(self.n_orientations, roll, self.seed)
        stars = FieldStars.build(
            self.fov, attitudes, self.vectors, self.magnitudes, self.tree,
            self._reporter("stars in the field, sky grid"),
        )  # fmt: skip
        return boresights, stars

    @property
    def boresights(self) -> NDArray[np.float64]:
        """The spatial boresights, (n_orientations, 3)."""
        return self._sky[0]

    @property
    def sky(self) -> FieldStars:
        """Stars in the field at the spatial orientations."""
        return self._sky[1]

    def _effective(self, m_t: ArrayLike) -> NDArray[np.float64]:
        return np.minimum(np.asarray(m_t, dtype=np.float64), self.max_mag)

    # -- spatial static ----------------------------------------------------------------------
    def static(
        self,
        n_min: int = N_MIN_LOST_IN_SPACE,
        max_mag: float | None = None,
        curve_span_mag: float = 3.0,
        curve_step_mag: float = 0.05,
    ) -> StaticAvailability:
        """Spatial static availability at threshold `max_mag` (default: the catalogue cut).

        Also computes availability against m_t from ``max_mag - curve_span_mag`` to
        ``max_mag`` (Fig. 6) for N_min = 1 ... 4.
        """
        n_min = check_n_min(n_min)
        m_t = self.max_mag if max_mag is None else _check_mag(max_mag)
        m_t = float(min(m_t, self.max_mag))
        if not math.isfinite(m_t):
            m_t = float(self.magnitudes.max())
        return static_result(
            self.sky, self.sky.counts(m_t), self.boresights, n_min, m_t, self.n_stars,
            describe_fov(self.fov), self.catalog, self.band, curve_span_mag, curve_step_mag,
        )  # fmt: skip

    # -- spatial dynamic ---------------------------------------------------------------------
    def dynamic(
        self, curve: ThresholdCurve, rates_deg_s: ArrayLike, n_min: int = N_MIN_LOST_IN_SPACE
    ) -> DynamicAvailability:
        """Spatial dynamic availability at each rate: m_t = min(curve(w), catalogue cut)."""
        n_min = check_n_min(n_min)
        rates = check_rates(rates_deg_s)
        if not isinstance(curve, ThresholdCurve):
            raise InputError(f"curve must be a ThresholdCurve, got {type(curve).__name__}")
        m_t = self._effective(curve(rates))
        keys = sorted({N_MIN_TRACKING, N_MIN_LOST_IN_SPACE, n_min})
        by = {k: np.asarray(self.sky.availability(m_t, k), dtype=np.float64) for k in keys}
        return DynamicAvailability(
            rates_deg_s=rates,
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
        """Stars ``<= min(m_t, cut)`` in the field per spatial orientation (sky maps)."""
        return self.sky.counts(float(self._effective(m_t)))

    # -- along-track -------------------------------------------------------------------------
    def track_field(
        self,
        inclinations_deg: ArrayLike = DEFAULT_INCLINATIONS_DEG,
        n_samples: int = DEFAULT_TRACK_SAMPLES,
        node_deg: float = 0.0,
    ) -> FieldStars:
        """Stars in the field along every track (track-major, `n_samples` per inclination)."""
        incl = np.atleast_1d(np.asarray(inclinations_deg, dtype=np.float64))
        key = (tuple(incl.tolist()), int(n_samples), float(node_deg))
        if key not in self._tracks:
            attitudes = track_family_attitudes(incl, n_samples, node_deg)
            self._tracks[key] = FieldStars.build(
                self.fov, attitudes, self.vectors, self.magnitudes, self.tree,
                self._reporter("stars in the field, tracks"),
            )  # fmt: skip
        return self._tracks[key]

    def track(
        self,
        curve: ThresholdCurve,
        rate_deg_s: float,
        n_min: int = N_MIN_LOST_IN_SPACE,
        inclinations_deg: ArrayLike = DEFAULT_INCLINATIONS_DEG,
        n_samples: int = DEFAULT_TRACK_SAMPLES,
        node_deg: float = 0.0,
    ) -> TrackAvailability:
        """Along-track dynamic availability of each track at one constant slew rate."""
        n_min = check_n_min(n_min)
        rate = float(check_rates(rate_deg_s, "--rate-deg-s")[0])
        n_samples = check_count(n_samples, "samples per track", "--track-samples")
        if not isinstance(curve, ThresholdCurve):
            raise InputError(f"curve must be a ThresholdCurve, got {type(curve).__name__}")
        incl = np.atleast_1d(np.asarray(inclinations_deg, dtype=np.float64))
        tracks = self.track_field(incl, n_samples, node_deg)
        m_t = float(self._effective(curve([rate]))[0])
        keys = sorted({N_MIN_TRACKING, N_MIN_LOST_IN_SPACE, n_min})
        by = {
            k: (tracks.kth_magnitude(k).reshape(incl.size, n_samples) <= m_t).mean(axis=1)
            for k in keys
        }
        return TrackAvailability(
            rate_deg_s=rate,
            threshold_mag=m_t,
            inclinations_deg=incl,
            availability=by[n_min],
            by_n_min=by,
            spatial={k: self.sky.availability(m_t, k) for k in keys},
            n_min=n_min,
            n_samples=n_samples,
            n_stars=self.n_stars,
            n_orientations=self.n_orientations,
            node_deg=float(node_deg),
            fov=describe_fov(self.fov),
            catalog=self.catalog,
            band=self.band,
            curve_label=curve.label,
        )


# ---------------------------------------------------------------------------------------------
# full-fidelity check: rendered frames through the detector


@dataclass(frozen=True)
class FidelityCheck:
    """Availability from rendered frames against the threshold model, at the same attitudes.

    Attributes
    ----------
    rate_deg_s : float
        Cross-axis slew rate of the frames (about camera y: streaks along the rows).
    threshold_mag : float
        m_t of the threshold model at that rate (capped at the catalogue cut).
    n_min : int
    model_counts, frame_counts : ndarray (S,)
        Stars the threshold model counts in the detector field; catalogue stars (within the
        cut) detected in the rendered frame (a detection matched to a true star image).
    n_spurious : ndarray (S,)
        Detections not matched to any catalogue star of the cut (fainter stars, noise).
    model_available, frame_available : ndarray of bool (S,)
    """

    rate_deg_s: float
    threshold_mag: float
    n_min: int
    model_counts: NDArray[np.intp]
    frame_counts: NDArray[np.intp]
    n_spurious: NDArray[np.intp]
    model_available: NDArray[np.bool_]
    frame_available: NDArray[np.bool_]
    model_name: str = ""

    @property
    def n_frames(self) -> int:
        return len(self.frame_counts)

    @property
    def model_availability(self) -> float:
        return float(self.model_available.mean())

    @property
    def frame_availability(self) -> float:
        return float(self.frame_available.mean())

    @property
    def optimistic(self) -> int:
        """Frames the threshold model calls available that the detector does not solve."""
        return int((self.model_available & ~self.frame_available).sum())

    @property
    def pessimistic(self) -> int:
        """Frames the detector solves that the threshold model calls unavailable."""
        return int((~self.model_available & self.frame_available).sum())

    def to_dict(self) -> dict:
        return {
            "rate_deg_s": self.rate_deg_s,
            "threshold_mag": self.threshold_mag,
            "n_min": self.n_min,
            "n_frames": self.n_frames,
            "model_availability": self.model_availability,
            "frame_availability": self.frame_availability,
            "optimistic_frames": self.optimistic,
            "pessimistic_frames": self.pessimistic,
            "mean_model_count": float(self.model_counts.mean()),
            "mean_frame_count": float(self.frame_counts.mean()),
            "mean_spurious": float(self.n_spurious.mean()),
            "model": self.model_name,
        }

    def lines(self) -> list[str]:
        return [
            f"full-fidelity check at {self.rate_deg_s:g} deg/s, N_min = {self.n_min}, "
            f"{self.n_frames} rendered frames ({self.model_name} model)",
            f"  threshold model (m_t = {self.threshold_mag:.2f}): "
            f"{_pct(self.model_availability)} available, "
            f"{self.model_counts.mean():.2f} stars per field",
            f"  rendered + detected: {_pct(self.frame_availability)} available, "
            f"{self.frame_counts.mean():.2f} stars detected per frame "
            f"(+{self.n_spurious.mean():.2f} unmatched)",
            f"  model optimistic in {self.optimistic} frames, pessimistic in {self.pessimistic}",
        ]


def _detect(frame: Any, sensor: Any) -> NDArray[np.float64]:
    """Centroids (K, 2) as (x, y) pixels of the stars the sensor's detector finds in a frame
    (:class:`starsense.detect.StarDetector` with the sensor's logic, bias as background).
    """
    from starsense.detect import StarDetector

    found = StarDetector.for_sensor(sensor)(frame.image)
    return np.stack([np.asarray(found.x, float), np.asarray(found.y, float)], axis=-1)


def _truth_xy_mag(frame: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mid-exposure image positions (K, 2) and magnitudes (K,) of a rendered frame's stars
    (:class:`starsense.render.scene.StarTruth`).
    """
    stars = frame.truth.stars
    xy = np.stack([np.asarray(stars.x_mid, float), np.asarray(stars.y_mid, float)], axis=-1)
    return xy.reshape(-1, 2), np.asarray(stars.mag, dtype=np.float64).reshape(-1)


def fidelity_check(
    sensor: Any,
    catalog: Any,
    curve: ThresholdCurve,
    rate_deg_s: float,
    *,
    n_frames: int = 50,
    n_min: int = N_MIN_LOST_IN_SPACE,
    max_mag: float = 5.75,
    model: str = "reed",
    band: str = "V",
    seed: int | None = 0,
    match_radius_px: float | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> FidelityCheck:
    """Render frames at random attitudes, detect, and compare with the threshold model.

    Each frame is rendered (:func:`starsense.render.scene.render_frame`) from the catalogue
    stars with ``mag <= max_mag`` (the on-board catalogue) while the sensor slews about its
    camera y axis at `rate_deg_s` (streaks along the rows, as in the slew simulation), then
    passed through the detector. A detection counts when its centroid lies within
    `match_radius_px` of a true star's mid-exposure position (default: half the streak length
    plus 3 PSF sigma). The threshold model counts the stars ``<= min(m_t(w), max_mag)`` in the
    rectangular detector field at the same attitude.

    Raises
    ------
    InputError
        On bad counts or rates.
    """
    from starsense.render.scene import render_frame

    n_frames = check_count(n_frames, "number of frames", "--frames")
    n_min = check_n_min(n_min)
    rate = float(check_rates(rate_deg_s, "--rate-deg-s")[0])
    vectors, mags = catalog_stars(catalog, max_mag, band)
    fov = sensor.fov()
    m_t = float(min(curve([rate])[0], max_mag))
    rng = np.random.default_rng(seed)
    attitudes = Rotation.random(n_frames, rng=rng)
    field_stars = FieldStars.build(fov, attitudes, vectors, mags)
    model_counts = field_stars.counts(m_t)
    w = math.radians(rate)
    streak = sensor.streak_length_px(w)
    radius = (
        float(match_radius_px)
        if match_radius_px is not None
        else 0.5 * streak + 3.0 * sensor.detector.psf_sigma_px + 1.0
    )
    children = np.random.SeedSequence(seed).spawn(n_frames)
    frame_counts = np.zeros(n_frames, dtype=np.intp)
    spurious = np.zeros(n_frames, dtype=np.intp)
    for i in range(n_frames):
        frame = render_frame(
            sensor, attitudes[i], catalog, rate_rad_s=np.array([0.0, w, 0.0]), model=model,
            band=band, max_mag=max_mag, rng=np.random.default_rng(children[i]),
            keep_expected=False,
        )  # fmt: skip
        centroids = _detect(frame, sensor)
        truth_xy, truth_mag = _truth_xy_mag(frame)
        keep = truth_mag <= max_mag
        truth_xy = truth_xy[keep]
        matched_truth = np.zeros(len(truth_xy), dtype=bool)
        n_unmatched = 0
        if len(centroids) and len(truth_xy):
            tree = cKDTree(truth_xy)
            dist, idx = tree.query(centroids, distance_upper_bound=radius)
            ok = np.isfinite(dist)
            matched_truth[idx[ok]] = True
            n_unmatched = int((~ok).sum())
        else:
            n_unmatched = len(centroids)
        frame_counts[i] = int(matched_truth.sum())
        spurious[i] = n_unmatched
        if progress is not None:
            progress(i + 1, n_frames)
    return FidelityCheck(
        rate_deg_s=rate,
        threshold_mag=m_t,
        n_min=n_min,
        model_counts=model_counts,
        frame_counts=frame_counts,
        n_spurious=spurious,
        model_available=model_counts >= n_min,
        frame_available=frame_counts >= n_min,
        model_name=model,
    )
