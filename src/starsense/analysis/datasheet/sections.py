"""The typed datasheet: one frozen dataclass per section of its JSON.

``sheet.nea_arcsec.cross.median`` reads what the JSON (``starsense datasheet --json``, schema
``src/starsense/data/datasheet.schema.json``) calls ``nea_arcsec.cross.median``. Field names are
the JSON keys, except where the JSON key is not a Python name or not the package's vocabulary
(``"50"`` -> ``p50``, ``"trials"`` -> ``n_trials``); :meth:`Datasheet.to_dict` gives the JSON
form back, key for key and in the same order.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, is_dataclass

import numpy as np

from starsense.analysis.availability.results import DynamicAvailability
from starsense.analysis.slew import SlewResult

__all__ = [
    "AvailabilitySummary",
    "AxisPair",
    "AxisSpread",
    "BudgetRow",
    "CentroidSigma",
    "Datasheet",
    "Electrons",
    "FastestRates",
    "MonteCarloCheck",
    "QuotedValue",
    "RatesKept",
    "RollOverCross",
    "SheetSettings",
    "Spread",
    "StarsInFov",
    "json_clean",
]


def json_clean(value):
    """Return ``value`` with NumPy scalars as Python numbers, non-finite floats as None.

    Parameters
    ----------
    value : dict, list, tuple, number or str
        A JSON-like value (nested).

    Returns
    -------
    dict, list, number, str or None
        The same value, JSON-ready (tuples become lists).
    """
    if isinstance(value, dict):
        return {k: json_clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_clean(v) for v in value]
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    return value


def _json(value):
    """Return the JSON form of a section value (sections through their ``to_dict``)."""
    if is_dataclass(value) and not isinstance(value, type):
        return value.to_dict()
    if isinstance(value, list | tuple):
        return [_json(v) for v in value]
    if isinstance(value, Mapping):
        return {k: _json(v) for k, v in value.items()}
    return value


def _key(name: str, **meta):
    """Return a dataclass field whose JSON key is ``name``."""
    return field(metadata={"key": name, **meta})


class _Section:
    """The JSON form of a section: its fields in order, under their keys."""

    def to_dict(self) -> dict:
        """Return the section as a dict (JSON keys, sections nested as dicts)."""
        out = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None and f.metadata.get("omit_none"):
                continue
            out[f.metadata.get("key", f.name)] = _json(value)
        return out


@dataclass(frozen=True)
class Electrons(_Section):
    """Photo-electrons per exposure of a V = 0 star and of a limiting-magnitude star."""

    magnitude_0: float
    limiting_magnitude: float


@dataclass(frozen=True)
class CentroidSigma(_Section):
    """Centroid noise per axis (px), modelled and its Cramer-Rao bound, at V = 0 and the limit."""

    magnitude_0: float
    limiting_magnitude: float
    crb_magnitude_0: float
    crb_limiting_magnitude: float


@dataclass(frozen=True)
class StarsInFov(_Section):
    """Detectable stars in the field over the sky: median and 5th percentile."""

    median: float
    p05: float


@dataclass(frozen=True)
class Spread(_Section):
    """Median and 95th percentile over the sky (None: no attitude anywhere)."""

    median: float | None
    p95: float | None


@dataclass(frozen=True)
class AxisSpread(_Section):
    """A :class:`Spread` cross-boresight (rms of the two axes) and about the boresight."""

    cross: Spread
    roll: Spread


@dataclass(frozen=True)
class AxisPair(_Section):
    """One number cross-boresight and one about the boresight (None: does not exist)."""

    cross: float | None
    roll: float | None


@dataclass(frozen=True)
class RollOverCross(_Section):
    """Roll NEA over cross NEA, and the ratio the stars' field angles imply."""

    nea: float | None
    geometry: float | None


@dataclass(frozen=True)
class MonteCarloCheck(_Section):
    """A Monte Carlo run scored against the prediction (keys of ``monte_carlo`` in the JSON).

    ``frames`` rendered, ``solved`` right, ``wrong``; rms errors measured and predicted
    (arcsec; at a rate, the prediction of the smeared stars' streak centroids) and their
    ratios, None where nothing solved, with each ratio's 95 % interval over the frames
    (``[low, high]``, :func:`starsense.analysis.datasheet.verify.ratio_interval`);
    ``stars_matched_median`` only where predicted (absent from the JSON otherwise);
    ``frames_beyond_fit`` at a rate: the right solutions whose streaks' windows pass what the
    model fit may hold (their centroids' attitude, left out of the comparison).
    """

    frames: int
    solved: int
    wrong: int
    wrong_rate_upper95: float
    rate_deg_s: float
    median_ms: float | None
    p95_ms: float | None
    statuses: Mapping[str, int]
    cross_rms_arcsec: float | None
    roll_rms_arcsec: float | None
    cross_predicted_arcsec: float | None
    roll_predicted_arcsec: float | None
    cross_ratio: float | None
    roll_ratio: float | None
    cross_ratio_robust: float | None
    roll_ratio_robust: float | None
    outliers_5sigma: int | None
    cross_ratio_ci95: list[float] | None = None
    roll_ratio_ci95: list[float] | None = None
    stars_matched_median: float | None = field(default=None, metadata={"omit_none": True})
    frames_beyond_fit: int | None = field(default=None, metadata={"omit_none": True})

    @property
    def solved_fraction(self) -> float | None:
        """Fraction of the frames solved right (None without frames)."""
        return self.solved / self.frames if self.frames else None


@dataclass(frozen=True)
class FastestRates(_Section):
    """Fastest rate (deg/s) that keeps 50, 90 and 99 % of the sky available (JSON "50" ...)."""

    p50: float | None = _key("50")
    p90: float | None = _key("90")
    p99: float | None = _key("99")


@dataclass(frozen=True)
class RatesKept(_Section):
    """:class:`FastestRates` for lost in space (N >= 5: the solver's) and tracking (N >= 2)."""

    lost_in_space: FastestRates
    tracking: FastestRates


@dataclass(frozen=True)
class AvailabilitySummary(_Section):
    """Availability at rest and at the datasheet's rates (fractions of the sky), rates in deg/s."""

    lost_in_space: float
    tracking: float
    rates_deg_s: tuple[float, ...]
    lost_in_space_at_rate: tuple[float, ...]
    tracking_at_rate: tuple[float, ...]
    threshold_mag_at_rate: tuple[float, ...]
    fastest_rate_deg_s: RatesKept
    n_orientations: int


@dataclass(frozen=True)
class BudgetRow(_Section):
    """One term of the error budget, arcsec (None: not known), and where it comes from."""

    term: str
    cross_arcsec: float | None
    roll_arcsec: float | None
    source: str


@dataclass(frozen=True)
class QuotedValue(_Section):
    """A vendor-quoted value of the sensor TOML against the prediction."""

    key: str
    predicted: float | None
    quoted: float
    ratio: float | None


@dataclass(frozen=True)
class SheetSettings(_Section):
    """How the datasheet was computed, as its JSON records it (keys ``trials``, ...)."""

    catalog: str
    model: str
    n_trials: int = _key("trials")
    rate_deg_s: float = _key("rate_deg_s")
    seed: int = _key("seed")
    n_orientations: int = _key("n_orientations")
    n_slew_trials: int = _key("slew_trials")
    catalog_cut_mag: float | None = _key("catalog_cut_mag")
    fov: str = _key("fov")


#: the keys of a datasheet without any detected star, in their JSON order
_NO_STAR_KEYS = ("schema", "sensor", "limiting_magnitude", "warnings", "settings")
#: the fields that are not in the JSON (arrays for the figures)
_ARRAYS = {"boresights", "nea_cross_rad", "dynamic", "frame_errors_rad"}


@dataclass(frozen=True, kw_only=True)
class Datasheet:
    """A sensor's datasheet: every JSON section typed, and the arrays the figures need.

    A sensor that detects no star at rest has ``limiting_magnitude`` None, its ``warnings``
    say why, and every section but ``settings`` is None.

    Parameters
    ----------
    schema, sensor : str
        The JSON schema's name and version; the sensor's name.
    fov_deg : tuple of float
        Full field, columns x rows, deg.
    pixel_scale_arcsec : float
        Angle of one pixel at the boresight, arcsec.
    limiting_magnitude : float or None
        Faintest V detected in >= 50 % of noisy renders at rest.
    electrons, centroid_sigma_px, stars_in_fov : sections
        Photo-electrons, centroid noise (px) and stars in the field.
    nea_arcsec, crb_arcsec : AxisSpread
        Noise-equivalent angle and its Cramer-Rao version over the sky, arcsec, 1 sigma.
    limit_arcsec, nea_over_limit : AxisPair
        Fialho & Mortari's bound for this D, t and field (arcsec), and NEA over it.
    roll_over_cross : RollOverCross
        Roll over cross-boresight NEA, and what the field's geometry gives.
    monte_carlo, monte_carlo_at_rate : MonteCarloCheck
        The rendered-frame checks at rest and at the settings' rate.
    availability : AvailabilitySummary
        Availability at the datasheet's rates for lost in space and tracking.
    slew : SlewResult
        The slew-tolerance run; its JSON section is :meth:`SlewResult.tolerance_dict`.
    budget : tuple of BudgetRow
        The error budget, one row per term.
    quoted : tuple of QuotedValue
        The TOML's ``[quoted]`` values beside the predictions.
    quoted_source : str or None
        Where the quoted values come from.
    settings : SheetSettings
        Trials, rate, seed and catalogue of the run.
    warnings : tuple of str
        What the reader should know, in words.
    boresights : ndarray (M, 3) or None
        Boresights of the sky statistics (not in the JSON).
    nea_cross_rad : ndarray (M,) or None
        Cross-boresight NEA at each boresight, rad (not in the JSON).
    dynamic : DynamicAvailability or None
        Availability on a fine grid of rates (not in the JSON).
    frame_errors_rad : dict or None
        Per Monte Carlo rate (deg/s): the camera-frame X, Y, Z error (N, 3) of each right
        solution, rad (not in the JSON).
    """

    schema: str
    sensor: str
    fov_deg: tuple[float, float] | None = None
    pixel_scale_arcsec: float | None = None
    limiting_magnitude: float | None = None
    electrons: Electrons | None = None
    centroid_sigma_px: CentroidSigma | None = None
    stars_in_fov: StarsInFov | None = None
    nea_arcsec: AxisSpread | None = None
    crb_arcsec: AxisSpread | None = None
    limit_arcsec: AxisPair | None = None
    nea_over_limit: AxisPair | None = None
    roll_over_cross: RollOverCross | None = None
    monte_carlo: MonteCarloCheck | None = None
    monte_carlo_at_rate: MonteCarloCheck | None = None
    availability: AvailabilitySummary | None = None
    slew: SlewResult | None = None
    budget: tuple[BudgetRow, ...] = ()
    quoted: tuple[QuotedValue, ...] = ()
    quoted_source: str | None = None
    settings: SheetSettings
    warnings: tuple[str, ...] = ()
    boresights: np.ndarray | None = field(default=None, repr=False, compare=False)
    nea_cross_rad: np.ndarray | None = field(default=None, repr=False, compare=False)
    dynamic: DynamicAvailability | None = field(default=None, repr=False, compare=False)
    frame_errors_rad: dict | None = field(default=None, repr=False, compare=False)

    def to_dict(self) -> dict:
        """Return the JSON form (units in the field names; None where a number does not exist).

        Returns
        -------
        dict
            The keys and order of ``datasheet.schema.json``; ``json.dumps`` of it is what
            ``starsense datasheet --json`` prints.
        """
        out = {}
        for f in fields(self):
            if f.name in _ARRAYS:
                continue
            value = getattr(self, f.name)
            slew = f.name == "slew" and value is not None
            out[f.name] = value.tolerance_dict() if slew else _json(value)
        if self.limiting_magnitude is None:
            out = {k: out[k] for k in _NO_STAR_KEYS}
        return json_clean(out)
