"""Datasheets side by side: the numbers ``starsense datasheet --compare`` tabulates."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from starsense.analysis.datasheet.sections import Datasheet
from starsense.analysis.datasheet.sheet import datasheet
from starsense.analysis.inputs import as_catalog, as_sensor, root_seed
from starsense.units import DEG

__all__ = ["Comparison", "ComparisonRow", "compare", "comparison_rows"]

#: label, the value of one datasheet's JSON form, and its text format
_ROWS: tuple[tuple[str, Callable[[dict], float | None], str], ...] = (
    ("limiting magnitude", lambda d: d.get("limiting_magnitude"), ".2f"),
    ("stars in field, median", lambda d: (d.get("stars_in_fov") or {}).get("median"), ".0f"),
    ("NEA cross, arcsec", lambda d: d["nea_arcsec"]["cross"]["median"], ".3f"),
    ("NEA roll, arcsec", lambda d: d["nea_arcsec"]["roll"]["median"], ".3f"),
    ("limit cross, arcsec", lambda d: d["limit_arcsec"]["cross"], ".4f"),
    (
        "LIS solved at rest",
        lambda d: d["monte_carlo"]["solved"] / d["monte_carlo"]["frames"],
        ".3f",
    ),
    ("measured/predicted cross", lambda d: d["monte_carlo"]["cross_ratio"], ".2f"),
    ("availability LIS at rest", lambda d: d["availability"]["lost_in_space"], ".3f"),
)


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
    """

    label: str
    values: tuple[float | None, ...]
    fmt: str


def comparison_rows(payloads: Sequence[dict]) -> tuple[ComparisonRow, ...]:
    """Return the comparison rows of datasheets in their JSON form.

    Parameters
    ----------
    payloads : sequence of dict
        :meth:`Datasheet.to_dict` of each sensor.

    Returns
    -------
    tuple of ComparisonRow
        Limiting magnitude, stars in the field, NEA cross and roll, the limit, lost in space
        solved at rest, measured / predicted, availability.
    """
    rows = []
    for label, get, fmt in _ROWS:
        values = []
        for d in payloads:
            try:
                values.append(get(d))
            except (KeyError, TypeError, ZeroDivisionError):
                values.append(None)
        rows.append(ComparisonRow(label, tuple(values), fmt))
    return tuple(rows)


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
        """Return the JSON form: ``{"sensors": [datasheet, ...]}`` (``--compare --json``)."""
        return {"sensors": [s.to_dict() for s in self.sheets]}


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
    sens = [as_sensor(s) for s in sensors]
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
