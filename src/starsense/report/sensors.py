"""A user's table of real star sensors, to place beside the physical limit (Fig. 8).

The table is a CSV file with a header line, in one of two forms::

    name,diameter_m,exposure_s,theta_rms_arcsec
    name,diameter_m,exposure_s,sigma_cross_arcsec,sigma_roll_arcsec

``diameter_m`` is the sensor's effective diameter D (Fialho & Mortari 2019, sec. 3.5: the smallest
sphere enclosing the optical head, baffle excluded), ``exposure_s`` its exposure t. In the second
form the rms attitude error follows from the 1-sigma cross-boresight (pitch = yaw) and roll
errors as theta_rms^2 = 2 sigma_cross^2 + sigma_roll^2 (sec. 3.5). Blank lines and lines starting
with ``#`` are ignored. No table ships with starsense: datasheet numbers are the user's to give.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

from starsense._io import read_text
from starsense.errors import InputError
from starsense.units import ARCSEC

#: the two accepted headers (column order is free; extra columns are ignored)
THETA_COLUMNS = ("name", "diameter_m", "exposure_s", "theta_rms_arcsec")
SIGMA_COLUMNS = ("name", "diameter_m", "exposure_s", "sigma_cross_arcsec", "sigma_roll_arcsec")


@dataclass(frozen=True)
class SensorSpec:
    """One real sensor of the user's table.

    Attributes
    ----------
    name : str
    diameter_m : float
        Effective diameter D, m.
    exposure_s : float
        Exposure t, s.
    theta_rms_arcsec : float
        rms attitude error sqrt(tr P), arcsec.
    sigma_cross_arcsec, sigma_roll_arcsec : float or None
        The per-axis 1-sigma errors the table gave, if it gave them.
    line : int
        Line of the table the sensor came from (0 when built in code).
    """

    name: str
    diameter_m: float
    exposure_s: float
    theta_rms_arcsec: float
    sigma_cross_arcsec: float | None = None
    sigma_roll_arcsec: float | None = None
    line: int = 0

    @property
    def figure_of_merit(self) -> float:
        """D^2 t^1/2, m^2 s^1/2 (Fialho & Mortari 2019, eq. 23)."""
        return self.diameter_m**2 * math.sqrt(self.exposure_s)

    @property
    def theta_rms_rad(self) -> float:
        """Rms attitude error sqrt(tr P), rad."""
        return self.theta_rms_arcsec * ARCSEC

    def to_dict(self) -> dict:
        """Return the JSON form (arcsec, as the table gave it)."""
        return {
            "name": self.name,
            "diameter_m": self.diameter_m,
            "exposure_s": self.exposure_s,
            "theta_rms_arcsec": self.theta_rms_arcsec,
            "sigma_cross_arcsec": self.sigma_cross_arcsec,
            "sigma_roll_arcsec": self.sigma_roll_arcsec,
        }


def theta_from_sigmas(sigma_cross: float, sigma_roll: float) -> float:
    """theta_rms = sqrt(2 sigma_cross^2 + sigma_roll^2) (sec. 3.5), any angular unit."""
    return math.sqrt(2.0 * sigma_cross**2 + sigma_roll**2)


def load_sensor_table(path) -> list[SensorSpec]:
    """Read a CSV table of real sensors (see the module docstring for the format).

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    list of SensorSpec, in file order.

    Raises
    ------
    InputError
        Missing file or column, a cell that is not a number, D <= 0, t <= 0 or an error <= 0,
        with the file, line and column in the message.
    """
    path = Path(path)
    # a missing file, a folder, a FIFO (reading one waited for a writer for ever), not UTF-8
    text = read_text(path, "sensors table").removeprefix("\ufeff")

    reader = csv.reader(text.splitlines())
    header: list[str] | None = None
    columns: dict[str, int] = {}
    use_sigmas = False
    sensors: list[SensorSpec] = []
    for row in reader:
        line = reader.line_num
        if not row or all(not cell.strip() for cell in row) or row[0].lstrip().startswith("#"):
            continue
        if header is None:
            header = [cell.strip() for cell in row]
            columns, use_sigmas = _parse_header(path, line, header)
            continue
        if len(row) != len(header):
            raise InputError(
                f"{path}, line {line}: {len(row)} fields, but the header has {len(header)} "
                f"({','.join(header)})"
            )
        name = row[columns["name"]].strip()
        if not name:
            raise InputError(f"{path}, line {line}, column {columns['name'] + 1} (name): empty")
        values = {
            col: _positive(path, line, i, col, row[i])
            for col, i in columns.items()
            if col != "name"
        }
        d, t = values["diameter_m"], values["exposure_s"]
        if use_sigmas:
            sx, sz = values["sigma_cross_arcsec"], values["sigma_roll_arcsec"]
            theta = theta_from_sigmas(sx, sz)
        else:
            sx = sz = None
            theta = values["theta_rms_arcsec"]
        sensors.append(SensorSpec(name, d, t, theta, sx, sz, line))
    if header is None:
        raise InputError(f"{path}: sensors table is empty (expected a header line)")
    if not sensors:
        raise InputError(f"{path}: sensors table has a header but no sensors")
    return sensors


def _parse_header(path: Path, line: int, header: list[str]) -> tuple[dict[str, int], bool]:
    expected = f"expected '{','.join(THETA_COLUMNS)}' or '{','.join(SIGMA_COLUMNS)}'"
    dupes = sorted({h for h in header if header.count(h) > 1})
    if dupes:
        raise InputError(f"{path}, line {line}: column {dupes[0]!r} appears twice")
    has_theta = "theta_rms_arcsec" in header
    has_sigma = "sigma_cross_arcsec" in header or "sigma_roll_arcsec" in header
    if has_theta and has_sigma:
        raise InputError(
            f"{path}, line {line}: give either theta_rms_arcsec or "
            f"sigma_cross_arcsec,sigma_roll_arcsec, not both; {expected}"
        )
    wanted = SIGMA_COLUMNS if has_sigma else THETA_COLUMNS
    for col in wanted:
        if col not in header:
            raise InputError(
                f"{path}, line {line}: missing column {col!r} (header is {','.join(header)!r}; "
                f"{expected})"
            )
    return {col: header.index(col) for col in wanted}, has_sigma


def _positive(path: Path, line: int, index: int, col: str, cell: str) -> float:
    where = f"{path}, line {line}, column {index + 1} ({col})"
    try:
        value = float(cell)
    except ValueError:
        raise InputError(f"{where}: {cell.strip()!r} is not a number") from None
    if not math.isfinite(value) or value <= 0:
        raise InputError(f"{where}: must be a finite number > 0, got {cell.strip()!r}")
    return value
