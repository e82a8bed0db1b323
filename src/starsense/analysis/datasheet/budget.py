"""The datasheet's error budget and its predicted / quoted table.

The budget lists the error terms that can be modelled or measured in the run (noise-equivalent
angle, pixel spatial error, field-of-view spatial error, aberration) and those the sensor TOML
gives (``[budget]``: bias, thermo-elastic), with their root sum square (ECSS-E-ST-60-20C terms).
"""

from __future__ import annotations

import math

import numpy as np

from starsense.analysis.datasheet.sections import (
    AvailabilitySummary,
    AxisSpread,
    BudgetRow,
    MonteCarloCheck,
    QuotedValue,
)
from starsense.analysis.datasheet.terms import EARTH_ORBITAL_SPEED_M_S, aberration_error
from starsense.units import RAD_TO_ARCSEC

__all__ = ["error_budget", "fov_spatial_row", "quoted_values", "sky_median"]


def sky_median(values: np.ndarray, q: float = 50) -> float | None:
    """Return the ``q``-th percentile of the finite ``values`` (None when there are none).

    Parameters
    ----------
    values : array_like (M,)
        Values over the sky (NaN where they do not exist).
    q : float
        Percentile, 0-100.

    Returns
    -------
    float or None
    """
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(np.percentile(v, q)) if v.size else None


def error_budget(sensor, nea: AxisSpread, *, pixel: tuple, pse_px: float | None) -> list[BudgetRow]:
    """Return the error budget rows: term, cross, roll (arcsec), source.

    Parameters
    ----------
    sensor : Sensor
        The sensor (its optics and its TOML ``[budget]``).
    nea : AxisSpread
        The noise-equivalent angle over the sky, arcsec.
    pixel : tuple of ndarray (M,)
        Pixel spatial error per attitude, cross and roll, rad.
    pse_px : float or None
        Rms sub-pixel centroid bias, px.

    Returns
    -------
    list of BudgetRow
        The terms, then their root sum square (of the known ones).
    """
    given = dict(sensor.budget)
    rows = [
        BudgetRow(
            "noise-equivalent angle (temporal, 1 sigma, sky median)",
            nea.cross.median,
            nea.roll.median,
            "modelled (centroid noise through eq. 21)",
        ),
        BudgetRow(
            f"pixel spatial error (centroid bias, rms {pse_px:.4f} px)"
            if pse_px
            else "pixel spatial error",
            sky_median(pixel[0] * RAD_TO_ARCSEC, 50),
            sky_median(pixel[1] * RAD_TO_ARCSEC, 50),
            "measured in this run (noiseless renders)",
        ),
        fov_spatial_row(sensor, given),
    ]
    if not given.get("aberration_corrected", False):
        speeds = [("annual", EARTH_ORBITAL_SPEED_M_S)]
        if "orbital_speed_m_s" in given:
            speeds.append(("orbital", given["orbital_speed_m_s"]))
        for name, v in speeds:
            c, r = aberration_error(sensor, v)
            rows.append(
                BudgetRow(
                    f"stellar aberration, {name}, if uncorrected (worst case)",
                    c * RAD_TO_ARCSEC,
                    r * RAD_TO_ARCSEC,
                    f"modelled (v = {v / 1e3:.2f} km/s)",
                )
            )
    for key in ("bias", "thermoelastic"):
        c, r = given.get(f"{key}_cross_arcsec"), given.get(f"{key}_roll_arcsec")
        if c is not None or r is not None:
            rows.append(
                BudgetRow(
                    key.replace("thermoelastic", "thermo-elastic"),
                    c or 0.0,
                    r or 0.0,
                    "given (sensor TOML [budget])",
                )
            )
    ok = [r for r in rows if r.cross_arcsec is not None and r.roll_arcsec is not None]
    rows.append(
        BudgetRow(
            "total (root sum square)",
            math.sqrt(sum(r.cross_arcsec**2 for r in ok)),
            math.sqrt(sum(r.roll_arcsec**2 for r in ok)),
            "combined",
        )
    )
    return rows


def fov_spatial_row(sensor, given: dict) -> BudgetRow:
    """Return the field-of-view spatial error row: given, zero for a pinhole, or unknown.

    Parameters
    ----------
    sensor : Sensor
        The sensor (its distortion).
    given : dict
        The sensor TOML's ``[budget]`` values.

    Returns
    -------
    BudgetRow
    """
    term = "field-of-view spatial error (distortion residual)"
    if "fov_spatial_cross_arcsec" in given or "fov_spatial_roll_arcsec" in given:
        return BudgetRow(
            term,
            given.get("fov_spatial_cross_arcsec", 0.0),
            given.get("fov_spatial_roll_arcsec", 0.0),
            "given (sensor TOML [budget], the calibration residual)",
        )
    if not any(sensor.optics.distortion):
        return BudgetRow(term, 0.0, 0.0, "modelled: pinhole camera, no distortion to leave")
    why = (
        "not known: the sensor has distortion; give fov_spatial_cross_arcsec and "
        "fov_spatial_roll_arcsec in [budget] (the residual of `starsense calibrate`)"
    )
    return BudgetRow(term, None, None, why)


def quoted_values(
    sensor,
    *,
    limit_mag: float,
    nea: AxisSpread,
    monte_carlo: MonteCarloCheck,
    availability: AvailabilitySummary,
) -> list[QuotedValue]:
    """Return predicted / quoted for each ``[quoted]`` value of the sensor TOML.

    Parameters
    ----------
    sensor : Sensor
        The sensor (its TOML ``[quoted]`` values).
    limit_mag : float
        The predicted limiting magnitude.
    nea : AxisSpread
        The noise-equivalent angle over the sky, arcsec.
    monte_carlo : MonteCarloCheck
        The run at rest.
    availability : AvailabilitySummary
        The availability section.

    Returns
    -------
    list of QuotedValue
    """
    mc = monte_carlo
    predicted = {
        "nea_cross_arcsec": nea.cross.median,
        "nea_roll_arcsec": nea.roll.median,
        "limiting_magnitude": limit_mag,
        "lost_in_space_success": (mc.solved / mc.frames) if mc.frames else None,
        "lost_in_space_time_ms": mc.median_ms,
        "availability": availability.lost_in_space,
        "max_rate_deg_s": availability.fastest_rate_deg_s.tracking.p90,
    }
    out = []
    for key, value in sensor.quoted:
        if key == "source":
            continue
        p = predicted.get(key)
        ratio = p / value if p is not None and value else None
        out.append(QuotedValue(key, p, value, ratio))
    return out
