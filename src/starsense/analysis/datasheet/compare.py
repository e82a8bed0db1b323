"""Datasheets side by side: the numbers ``starsense datasheet --compare`` tabulates."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from starsense._validate import show
from starsense.analysis.datasheet.sections import Datasheet
from starsense.analysis.datasheet.sheet import datasheet
from starsense.analysis.inputs import as_catalog, as_sensor, root_seed
from starsense.errors import InputError
from starsense.sensor import Sensor
from starsense.units import DEG

__all__ = [
    "ROW_KEYS",
    "Comparison",
    "ComparisonRow",
    "compare",
    "comparison_rows",
    "format_value",
    "row_values",
]


def _get(d: dict, *path):
    for k in path:
        d = d[k]
    return d


def _solved(d: dict, run: str) -> float | None:
    mc = d[run]
    return mc["solved"] / mc["frames"] if mc["frames"] else None


def _wrong(d: dict, run: str) -> int | None:
    return d[run]["wrong"] if d[run]["frames"] else None


def _fastest(d: dict, p: str) -> tuple[float | None, bool]:
    """Fastest rate keeping ``p`` % (deg/s) and whether it is the top of the rate grid."""
    value = d["availability"]["fastest_rate_deg_s"]["lost_in_space"][p]
    top = max(d["slew"]["rates_deg_s"]) if d.get("slew") else None
    return value, value is not None and top is not None and value >= top * (1 - 1e-9)


def _budget_total(d: dict, axis: str) -> float | None:
    for term in d.get("budget") or ():
        if term["term"].startswith("total"):
            return term[f"{axis}_arcsec"]
    return None


def _ecss_total(d: dict, axis: str, rate_deg_s: float | None) -> float | None:
    """Return the ECSS statement's total on ``axis`` at a rate, arcsec (None: the sheet's rate)."""
    rate = d["settings"]["rate_deg_s"] if rate_deg_s is None else rate_deg_s
    for row in (d.get("statement") or {}).get("rows") or ():
        if row["class"] == "total" and row["axis"] == axis and abs(row["rate_deg_s"] - rate) < 1e-9:
            return row["value_arcsec"]
    return None


#: the statement's totals: inertial pointing (at rest) and slewing (at the datasheet's rate)
_ECSS_ROWS = tuple(
    (
        f"ecss_total_{a.lower()}_{where}",
        f"ECSS total {a} {'at rest' if rate == 0.0 else 'at rate'}, arcsec",
        lambda d, a=a, rate=rate: _ecss_total(d, a, rate),
        ".3f",
    )
    for where, rate in (("rest", 0.0), ("rate", None))
    for a in ("X", "Y", "Z")
)

#: key, label, the value of one datasheet's JSON form (or (value, capped)), its text format
_ROWS: tuple[tuple[str, str, Callable[[dict], object], str], ...] = (
    ("fov_width_deg", "field width, deg", lambda d: d["fov_deg"][0], ".2f"),
    ("fov_height_deg", "field height, deg", lambda d: d["fov_deg"][1], ".2f"),
    ("pixel_scale_arcsec", "pixel scale, arcsec", lambda d: d["pixel_scale_arcsec"], ".2f"),
    ("limiting_magnitude", "limiting magnitude", lambda d: d.get("limiting_magnitude"), ".2f"),
    ("stars_median", "stars in field, median", lambda d: _get(d, "stars_in_fov", "median"), ".0f"),
    ("nea_cross", "NEA cross, arcsec", lambda d: _get(d, "nea_arcsec", "cross", "median"), ".3f"),
    ("nea_roll", "NEA roll, arcsec", lambda d: _get(d, "nea_arcsec", "roll", "median"), ".3f"),
    (
        "nea_cross_measured",
        "NEA cross measured, arcsec",
        lambda d: d["monte_carlo"]["cross_rms_arcsec"],
        ".3f",
    ),
    (
        "nea_roll_measured",
        "NEA roll measured, arcsec",
        lambda d: d["monte_carlo"]["roll_rms_arcsec"],
        ".3f",
    ),
    ("limit_cross", "limit cross, arcsec", lambda d: d["limit_arcsec"]["cross"], ".4f"),
    ("limit_roll", "limit roll, arcsec", lambda d: d["limit_arcsec"]["roll"], ".4f"),
    ("nea_over_limit_cross", "NEA / limit cross", lambda d: d["nea_over_limit"]["cross"], ".1f"),
    ("nea_over_limit_roll", "NEA / limit roll", lambda d: d["nea_over_limit"]["roll"], ".1f"),
    ("lis_solved_rest", "LIS solved at rest", lambda d: _solved(d, "monte_carlo"), ".3f"),
    ("lis_wrong_rest", "LIS wrong at rest", lambda d: _wrong(d, "monte_carlo"), "d"),
    ("lis_ms_rest", "LIS median time at rest, ms", lambda d: d["monte_carlo"]["median_ms"], ".1f"),
    ("lis_solved_rate", "LIS solved at rate", lambda d: _solved(d, "monte_carlo_at_rate"), ".3f"),
    ("lis_wrong_rate", "LIS wrong at rate", lambda d: _wrong(d, "monte_carlo_at_rate"), "d"),
    (
        "lis_ms_rate",
        "LIS median time at rate, ms",
        lambda d: d["monte_carlo_at_rate"]["median_ms"],
        ".1f",
    ),
    ("ratio_cross", "measured/predicted cross", lambda d: d["monte_carlo"]["cross_ratio"], ".2f"),
    ("ratio_roll", "measured/predicted roll", lambda d: d["monte_carlo"]["roll_ratio"], ".2f"),
    ("fastest_50", "fastest rate keeping 50 %, deg/s", lambda d: _fastest(d, "50"), ".2f"),
    ("fastest_90", "fastest rate keeping 90 %, deg/s", lambda d: _fastest(d, "90"), ".2f"),
    ("fastest_99", "fastest rate keeping 99 %, deg/s", lambda d: _fastest(d, "99"), ".2f"),
    ("availability_lis_rest", "availability LIS at rest", lambda d: _at(d, 0.0), ".3f"),
    ("availability_lis_0.5", "availability LIS at 0.5 deg/s", lambda d: _at(d, 0.5), ".3f"),
    ("availability_lis_1", "availability LIS at 1 deg/s", lambda d: _at(d, 1.0), ".3f"),
    ("availability_lis_2", "availability LIS at 2 deg/s", lambda d: _at(d, 2.0), ".3f"),
    ("availability_lis_rate", "availability LIS at the rate", lambda d: _at(d, None), ".3f"),
    (
        "budget_total_cross",
        "budget total cross, arcsec",
        lambda d: _budget_total(d, "cross"),
        ".3f",
    ),
    ("budget_total_roll", "budget total roll, arcsec", lambda d: _budget_total(d, "roll"), ".3f"),
    *_ECSS_ROWS,
)


def _at(d: dict, rate_deg_s: float | None) -> float | None:
    """Lost-in-space availability at a rate, deg/s (None: the datasheet's own rate)."""
    a = d["availability"]
    rate = d["settings"]["rate_deg_s"] if rate_deg_s is None else rate_deg_s
    for r, v in zip(a["rates_deg_s"], a["lost_in_space_at_rate"], strict=True):
        if abs(r - rate) < 1e-9:
            return v
    return None


#: the keys of the trade rows, in order
ROW_KEYS = tuple(key for key, *_ in _ROWS)


def row_values(payload: dict) -> dict[str, dict]:
    """Return the trade rows of one datasheet: ``{key: {"value": v, "capped": bool}}``.

    Parameters
    ----------
    payload : dict
        :meth:`Datasheet.to_dict` of one sensor.

    Returns
    -------
    dict
        In :data:`ROW_KEYS` order; ``value`` None where the datasheet has no such number (no
        frames, nothing detected); ``capped`` True where the value is the end of its grid (the
        fastest rate when every rate of the slew grid keeps the availability: read ">= v").
    """
    out = {}
    for key, _, get, _ in _ROWS:
        try:
            got = get(payload)
        except (KeyError, TypeError, IndexError, ZeroDivisionError):
            got = None
        value, capped = got if isinstance(got, tuple) else (got, False)
        out[key] = {"value": value, "capped": bool(capped)}
    return out


def format_value(value, fmt: str, *, capped: bool = False) -> str:
    """Return a row value as text: "n/a" for None, ">= v" for a value at its grid's end."""
    if value is None:
        return "n/a"
    text = format(value, fmt)
    return f">= {text}" if capped else text


@dataclass(frozen=True)
class ComparisonRow:
    """One quantity across the sensors.

    Attributes
    ----------
    label : str
        What it is, with its unit.
    values : tuple of float or None
        One per sensor, in the comparison's order (None: does not exist for that sensor).
    fmt : str
        Format of the values for text (``".3f"``).
    key : str
        Its name in JSON (:data:`ROW_KEYS`).
    capped : tuple of bool
        Per sensor: the value is the end of its grid (a lower bound).
    """

    label: str
    values: tuple[float | None, ...]
    fmt: str
    key: str = ""
    capped: tuple[bool, ...] = ()

    def cells(self) -> list[str]:
        """Return the values as text (:func:`format_value`)."""
        caps = self.capped or (False,) * len(self.values)
        return [format_value(v, self.fmt, capped=c) for v, c in zip(self.values, caps, strict=True)]

    def to_dict(self) -> dict:
        """Return ``{"key", "label", "values", "capped"}`` (JSON)."""
        return {
            "key": self.key,
            "label": self.label,
            "values": list(self.values),
            "capped": list(self.capped),
        }


def comparison_rows(payloads: Sequence[dict]) -> tuple[ComparisonRow, ...]:
    """Return the comparison rows of datasheets in their JSON form.

    Parameters
    ----------
    payloads : sequence of dict
        :meth:`Datasheet.to_dict` of each sensor.

    Returns
    -------
    tuple of ComparisonRow
        The trade rows (:data:`ROW_KEYS`): field, pixel scale, limiting magnitude, stars, NEA
        predicted and measured and NEA / limit per axis, lost in space at rest and at the rate
        (solved, wrong, median time), the fastest rates keeping 50/90/99 %, availability at
        rest and at the rate, the budget's total, and the ECSS statement's totals per axis at
        rest and at the rate where the payload holds a ``statement`` (its confidence).
    """
    per = [row_values(d) for d in payloads]
    return tuple(
        ComparisonRow(
            label,
            tuple(p[key]["value"] for p in per),
            fmt,
            key,
            tuple(p[key]["capped"] for p in per),
        )
        for key, label, _, fmt in _ROWS
    )


@dataclass(frozen=True)
class Comparison:
    """Several sensors' datasheets and the rows that compare them.

    Attributes
    ----------
    sheets : tuple of Datasheet
        One per sensor, in the order given.
    rows : tuple of ComparisonRow
        The quantities side by side (what ``starsense datasheet --compare`` prints).
    """

    sheets: tuple[Datasheet, ...]
    rows: tuple[ComparisonRow, ...]

    @classmethod
    def from_sheets(cls, sheets: Sequence[Datasheet]) -> Comparison:
        """Return the comparison of datasheets already built.

        Parameters
        ----------
        sheets : sequence of Datasheet
            One per sensor, in the order of the columns.

        Returns
        -------
        Comparison
        """
        sheets = tuple(sheets)
        return cls(sheets, comparison_rows([s.to_dict() for s in sheets]))

    @property
    def sensors(self) -> tuple[str, ...]:
        """The sensors' names, in order."""
        return tuple(s.sensor for s in self.sheets)

    def to_dict(self) -> dict:
        """Return the JSON form: ``{"sensors": [datasheet, ...], "rows": [row, ...]}``."""
        return {
            "sensors": [s.to_dict() for s in self.sheets],
            "rows": [r.to_dict() for r in self.rows],
        }


def compare(
    sensors: Sequence,
    catalog=None,
    *,
    n_trials: int = 100,
    rate_rad_s: float = 1.0 * DEG,
    rng: int | np.random.Generator | None = 0,
    n_orientations: int = 2000,
    model: str = "reed",
    n_slew_trials: int = 20,
    n_rate_trials: int | None = None,
    client=None,
    progress: Callable[[str, int, int], None] | None = None,
) -> Comparison:
    """Return the datasheets of several sensors, computed alike, and their comparison.

    Parameters
    ----------
    sensors : sequence of Sensor, str or Path
        The sensors (objects, preset names or sensor TOML files).
    catalog : Catalog, str or None
        The catalogue (object or specification; None: the bundled Hipparcos), loaded once.
    n_trials, n_orientations, n_slew_trials : int
        Rendered frames per check, boresights of the sky statistics, and trials per point of
        the slew curve, as for :func:`~starsense.analysis.datasheet.datasheet`.
    rate_rad_s : float
        The rate of the check under slew, rad/s.
    model : str
        Sensitivity model ("reed", "liebe" or "blackbody").
    n_rate_trials : int or None
        Frames of the check under slew (None: ``n_trials``).
    rng : None, int or numpy.random.Generator
        Root seed, the same for every sensor.
    client : dask.distributed.Client, optional
        Run the Monte Carlo frames on this cluster.
    progress : callable(label, done, total), optional
        Called after each step of each datasheet.

    Returns
    -------
    Comparison
    """
    if isinstance(sensors, str | Path | Sensor) or not isinstance(sensors, Iterable):
        raise InputError(
            "sensors must be a list of sensors (Sensor objects, preset names or TOML paths), "
            f"e.g. ['st16', 'esa_blackfly']; got {type(sensors).__name__} {show(sensors)}"
        )
    sens = [as_sensor(s) for s in sensors]
    if not sens:
        raise InputError("sensors is empty: give at least one sensor to compare")
    cat, seed = as_catalog(catalog), root_seed(rng)  # one catalogue and one seed for all
    sheets = [
        datasheet(
            s,
            cat,
            n_trials=n_trials,
            rate_rad_s=rate_rad_s,
            rng=seed,
            n_orientations=n_orientations,
            model=model,
            n_slew_trials=n_slew_trials,
            n_rate_trials=n_rate_trials,
            client=client,
            progress=progress,
        )
        for s in sens
    ]
    return Comparison.from_sheets(sheets)
