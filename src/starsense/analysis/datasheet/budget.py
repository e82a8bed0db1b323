"""The datasheet's error budget and its predicted / quoted table.

The budget lists the error terms that can be modelled or measured in the run (noise-equivalent
angle, pixel spatial error, field-of-view spatial error, aberration) and those the sensor TOML
gives (``[budget]``: bias, thermo-elastic), with their root sum square (ECSS-E-ST-60-20C terms).
Per-star errors (centroid bias, PRNU, calibration residual) are propagated as errors through
the estimator's weights (:func:`starsense.analysis.datasheet.field.propagated_sigmas`);
aberration is shown "if uncorrected" and left out of the total unless ``[budget]
aberration_corrected = false``.
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
from starsense.analysis.datasheet.terms import (
    EARTH_ORBITAL_SPEED_M_S,
    aberration_error,
    prnu_centroid_px,
)
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


def _sky_row(term: str, pair, source: str) -> BudgetRow:
    """Return a row from per-attitude (cross, roll) errors in rad: their sky medians, arcsec."""
    return BudgetRow(
        term,
        sky_median(pair[0] * RAD_TO_ARCSEC, 50),
        sky_median(pair[1] * RAD_TO_ARCSEC, 50),
        source,
    )


def _aberration_rows(sensor, given: dict) -> tuple[list[BudgetRow], bool]:
    """Return the aberration rows (annual; orbital given a speed) and whether they count.

    Flight software corrects stellar aberration (the velocity is known): by default the rows
    are shown apart, "if uncorrected", and left out of the total; ``[budget]
    aberration_corrected = false`` puts them in.
    """
    corrected = bool(given.get("aberration_corrected", True))
    speeds = [("annual", EARTH_ORBITAL_SPEED_M_S)]
    if "orbital_speed_m_s" in given:
        speeds.append(("orbital", given["orbital_speed_m_s"]))
    rows = []
    for name, v in speeds:
        c, r = aberration_error(sensor, v)
        where = (
            "not in the total: corrected by the flight software ([budget] "
            "aberration_corrected = false adds it)"
            if corrected
            else "in the total ([budget] aberration_corrected = false)"
        )
        rows.append(
            BudgetRow(
                f"stellar aberration, {name}, if uncorrected (worst case)",
                c * RAD_TO_ARCSEC,
                r * RAD_TO_ARCSEC,
                f"modelled (v = {v / 1e3:.2f} km/s); {where}",
            )
        )
    return rows, not corrected


def _noise_rows(sensor, nea: AxisSpread, *, errors: dict, pse_px, refine: str) -> list[BudgetRow]:
    """Return the budget's noise-equivalent angle and pixel spatial error rows."""
    det = sensor.detector
    sc = sensor.optics.psf_sigma_corner_px
    optics = (
        f"; its PSF widens from {det.psf_sigma_px:g} px at the centre to {sc:g} px in the "
        "corners (optics, rendered)"
        if sc > 0 and sc != det.psf_sigma_px
        else ""
    )
    if refine == "model":
        how = (
            f"modelled (the forward model's Fisher information, {sensor.psf.describe()} PSF: "
            f"the bound the solver's fit attains){optics}"
        )
        pixel = "none: the fit's model integrates the PSF over the pixels"
    else:
        how = f"modelled (centroid noise through the solver's weighted fit, eq. 21){optics}"
        pixel = (
            "measured in this run (noisy renders over pixel phases), propagated as an error "
            "through the solver's weights"
        )
    return [
        BudgetRow(
            "noise-equivalent angle (temporal, 1 sigma, sky median)",
            nea.cross.median,
            nea.roll.median,
            how,
        ),
        _sky_row(
            "pixel spatial error (centroid bias"
            + (f", rms {pse_px:.4f} px over the stars used)" if pse_px else ")"),
            errors["pixel"],
            pixel,
        ),
    ]


#: a confusion below this (arcsec) is no number but the round-off of a catalogue without the
#: stars fainter than the limit (Hipparcos is complete to V 7.3): 1 micro-arcsecond, six
#: orders below the arcsecond scale of a star tracker's errors
_CONFUSION_FLOOR_ARCSEC = 1e-6


def _confusion_row(pair, refine: str) -> BudgetRow:
    """Return the confusion row; "not modelled" (None) where the catalogue lacks faint stars."""
    term = "confusion (fainter catalogue stars inside the centroid window)"
    if refine == "model":
        return _sky_row(
            term, pair, "none left: the fit draws the frames' catalogue stars in its windows"
        )
    row = _sky_row(term, pair, "modelled (the catalogue's star counts), rendered in the frames")
    if max(row.cross_arcsec or 0.0, row.roll_arcsec or 0.0) < (_CONFUSION_FLOOR_ARCSEC):
        why = (
            "not modelled: the catalogue holds (almost) no stars fainter than the limiting "
            "magnitude to pull the centroids (a deeper catalogue, --catalog gaia, models them)"
        )
        return BudgetRow(term, None, None, why)
    return row


def error_budget(
    sensor, nea: AxisSpread, *, errors: dict, pse_px: float | None, dsnu=None, refine="model"
) -> list[BudgetRow]:
    """Return the error budget rows: term, cross, roll (arcsec, 1 sigma), source; then the total.

    Parameters
    ----------
    sensor : Sensor
        The sensor (its optics, detector non-uniformity and its TOML ``[budget]``).
    nea : AxisSpread
        The noise-equivalent angle over the sky, arcsec.
    errors : dict of str -> tuple of ndarray (M,)
        Per-attitude (cross, roll) errors, rad, propagated through the estimator's weights:
        ``"pixel"`` (centroid bias), ``"prnu"`` and ``"residual"`` (when the sensor has them),
        ``"catalogue"`` (star positions, when the frames and the database differ).
    pse_px : float or None
        Rms sub-pixel centroid bias over the stars used, px (the value propagated).
    dsnu : AxisPair or None
        The NEA's growth from the dark-signal non-uniformity (quadrature difference), arcsec.
    refine : {"model", "cog"}
        The solver the NEA is of: the forward model's fit, or the centroids' attitude.

    Returns
    -------
    list of BudgetRow
        The terms, then "total": the root sum square of the terms it names, 1 sigma per axis.
    """
    given = dict(sensor.budget)
    det = sensor.detector
    rows = _noise_rows(sensor, nea, errors=errors, pse_px=pse_px, refine=refine)
    if "confusion" in errors:
        rows.append(_confusion_row(errors["confusion"], refine))
    if "catalogue" in errors:
        rows.append(
            _sky_row(
                "catalogue positions (the frames' catalogue against the solver's database)",
                errors["catalogue"],
                "modelled per star (both catalogues' stated errors at the database's epoch, "
                "proper motions' over the years between), through the solver's weights",
            )
        )
    if "prnu" in errors:
        rows.append(
            _sky_row(
                f"detector non-uniformity: PRNU {100 * det.prnu_fraction:g} % "
                f"({prnu_centroid_px(sensor):.4f} px per star)",
                errors["prnu"],
                "modelled (gain spread x the PSF's lever arm), rendered in the frames",
            )
        )
    if dsnu is not None:
        rows.append(
            BudgetRow(
                f"detector non-uniformity: DSNU {det.dsnu_e:g} e- rms",
                dsnu.cross,
                dsnu.roll,
                "modelled (NEA with DSNU added to the read noise, in quadrature), rendered",
            )
        )
    if det.hot_pixel_fraction > 0:
        n_hot = det.hot_pixel_fraction * det.columns * det.rows
        rows.append(
            BudgetRow(
                f"hot pixels: {n_hot:.3g} per frame ({det.hot_pixel_e_s:g} e-/s each)",
                None,
                None,
                "not an angle: each one above the lit threshold is a false star for "
                "identification (rendered; see lost in space)",
            )
        )
    rows.append(fov_spatial_row(sensor, given, errors.get("residual")))
    total_rows = [r for r in rows if r.cross_arcsec is not None and r.roll_arcsec is not None]
    aberration, counted = _aberration_rows(sensor, given)
    rows += aberration
    if counted:
        total_rows += aberration
    for key in ("bias", "thermoelastic"):
        c, r = given.get(f"{key}_cross_arcsec"), given.get(f"{key}_roll_arcsec")
        if c is not None or r is not None:
            row = BudgetRow(
                key.replace("thermoelastic", "thermo-elastic"),
                c or 0.0,
                r or 0.0,
                "given (sensor TOML [budget])",
            )
            rows.append(row)
            total_rows.append(row)
    names = ", ".join(r.term.split(" (")[0].split(":")[0] for r in total_rows)
    rows.append(
        BudgetRow(
            "total, 1 sigma per axis (root sum square)",
            math.sqrt(sum(r.cross_arcsec**2 for r in total_rows)),
            math.sqrt(sum(r.roll_arcsec**2 for r in total_rows)),
            f"includes: {names}",
        )
    )
    return rows


def fov_spatial_row(sensor, given: dict, residual=None) -> BudgetRow:
    """Return the field-of-view spatial error row: modelled, given, zero for a pinhole, or unknown.

    Parameters
    ----------
    sensor : Sensor
        The sensor (its distortion and ``optics.distortion_residual_px``).
    given : dict
        The sensor TOML's ``[budget]`` values.
    residual : tuple of ndarray (M,), optional
        Per-attitude (cross, roll) error of the calibration residual, rad.

    Returns
    -------
    BudgetRow
    """
    term = "field-of-view spatial error (distortion residual)"
    r_px = sensor.optics.distortion_residual_px
    if residual is not None and r_px > 0:
        return _sky_row(
            f"field-of-view spatial error (calibration residual {r_px:g} px per star)",
            residual,
            "given (optics.distortion_residual_px), propagated through eq. 21, rendered",
        )
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
        "not known: the sensor has distortion; give optics.distortion_residual_px (the "
        "residual of `starsense calibrate`) or fov_spatial_cross_arcsec and "
        "fov_spatial_roll_arcsec in [budget]"
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
