"""The error terms of the statement: each one's 1-sigma per attitude and axis, at each rate.

Each term is one source in one ECSS class (:mod:`starsense.analysis.ecss.classes`), with a
stable key. Its values are 1-sigma errors in rad, per axis X, Y, Z: an array (M, 3) over the
datasheet's attitudes where the error depends on the stars in the field (propagated through
the solver's weights, :mod:`starsense.analysis.ecss.axes`), a triple (3,) where it does not
(given, worst case), or None where it is not known. The spatial and given terms have the same
amplitude at every rate (how they act changes, not their size: :func:`starsense.analysis.ecss.
classes.acting`); the temporal noise is the forward model's Fisher information of the smeared
stars at each rate.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from starsense.analysis.datasheet.terms import EARTH_ORBITAL_SPEED_M_S, aberration_error
from starsense.analysis.ecss.sky import SkyStars, sky_stars
from starsense.units import ARCSEC

__all__ = ["Term", "error_terms"]


@dataclass(frozen=True)
class Term:
    """One error term of the statement.

    Attributes
    ----------
    key : str
        Stable snake_case key (``temporal_noise``, ``pixel_spatial_prnu``, ...).
    ecss_class : str
        Its ECSS class (a key of :data:`starsense.analysis.ecss.classes.CLASSES`).
    values_rad : tuple
        Per rate: ndarray (M, 3) over the attitudes, ndarray (3,), or None (not known); 1-sigma
        X, Y, Z, rad (a worst case where ``gaussian`` is False).
    gaussian : bool
        Zero-mean Gaussian per axis (scaled by the confidence's factor); False: a worst-case
        bound, quoted as it is at every confidence.
    counted : bool
        In the statement's totals.
    distribution : str
        Its distribution, in words.
    source : str
        How it was obtained, in words.
    """

    key: str
    ecss_class: str
    values_rad: tuple
    gaussian: bool
    counted: bool
    distribution: str
    source: str


_GAUSS_SKY = (
    "Gaussian per axis at each attitude; over the sky a mixture of Gaussians of different "
    "widths (heavier tails: the sky ensemble bound is given beside the median's)"
)
_PER_STAR = (
    "Gaussian over the stars (a fixed draw per star); per attitude a constant, over the sky "
    "a mixture of Gaussians"
)


def _same(value, n_rates: int) -> tuple:
    return (value,) * n_rates


def _given(sensor, key: str, n_rates: int) -> Term:
    """Return a term the sensor TOML's ``[budget]`` gives (None when it does not)."""
    name = key.replace("_", "")  # the TOML's keys: bias_*, thermoelastic_*
    given = dict(sensor.budget)
    c, r = given.get(f"{name}_cross_arcsec"), given.get(f"{name}_roll_arcsec")
    if c is None and r is None:
        return Term(
            key,
            key,
            _same(None, n_rates),
            True,
            True,
            "not known",
            f"not given: put {name}_cross_arcsec and {name}_roll_arcsec in the sensor "
            "TOML's [budget]",
        )
    value = np.array([c or 0.0, c or 0.0, r or 0.0]) * ARCSEC
    return Term(
        key,
        key,
        _same(value, n_rates),
        True,
        True,
        "as given, taken as the 1-sigma of a zero-mean Gaussian per axis",
        f"given (sensor TOML [budget] {name}_cross_arcsec for X and Y, {name}_roll_arcsec for Z)",
    )


def _fov_spatial(sensor, sky: SkyStars, n_rates: int) -> Term:
    given = dict(sensor.budget)
    r_px = sensor.optics.distortion_residual_px
    if r_px > 0:
        value, src = (
            sky.propagated("residual"),
            f"modelled: the distortion calibration's residual {r_px:g} px per star "
            "(optics.distortion_residual_px), through the solver's weights",
        )
    elif "fov_spatial_cross_arcsec" in given or "fov_spatial_roll_arcsec" in given:
        c = given.get("fov_spatial_cross_arcsec", 0.0)
        value = np.array([c, c, given.get("fov_spatial_roll_arcsec", 0.0)]) * ARCSEC
        src = "given (sensor TOML [budget] fov_spatial_cross_arcsec, fov_spatial_roll_arcsec)"
    elif not any(sensor.optics.distortion):
        value, src = np.zeros(3), "modelled: a pinhole camera, no distortion to leave"
    else:
        value, src = (
            None,
            (
                "not known: the sensor has distortion; give optics.distortion_residual_px (the "
                "residual of `starsense calibrate`) or [budget] fov_spatial_cross_arcsec"
            ),
        )
    dist = _PER_STAR if value is not None else "not known"
    return Term("fov_spatial", "fov_spatial", _same(value, n_rates), True, True, dist, src)


def _pixel_terms(sensor, sky: SkyStars, settings, limit_mag, n_rates) -> list[Term]:
    det = sensor.detector
    if sky.model.refine == "model":
        interp = Term(
            "pixel_spatial_interpolation",
            "pixel_spatial",
            _same(np.zeros(3), n_rates),
            True,
            True,
            "none",
            "modelled: none, the fit's model integrates the PSF over the pixels",
        )
    else:
        interp = Term(
            "pixel_spatial_interpolation",
            "pixel_spatial",
            _same(sky.propagated("pixel"), n_rates),
            True,
            True,
            "periodic in each star's sub-pixel phase (bounded, not Gaussian): its rms is "
            "quoted as a 1-sigma",
            "measured on noisy single-star renders over sub-pixel phases (the datasheet's "
            "pixel spatial error), through the solver's weights",
        )
    prnu = Term(
        "pixel_spatial_prnu",
        "pixel_spatial",
        _same(sky.propagated("prnu") if det.prnu_fraction > 0 else np.zeros(3), n_rates),
        True,
        True,
        _PER_STAR,
        f"modelled: PRNU {100 * det.prnu_fraction:g} % x the PSF's lever arm, through the "
        "solver's weights"
        if det.prnu_fraction > 0
        else "modelled: no PRNU in the sensor TOML",
    )
    dsnu = np.zeros(3)
    if det.dsnu_e > 0:  # the NEA with the DSNU added to the read noise, less the NEA
        noisier = sensor.with_(
            detector=dataclasses.replace(
                det, read_noise_e=float(np.hypot(det.read_noise_e, det.dsnu_e))
            )
        )
        grown = sky_stars(
            noisier, sky.catalog, settings, limit_mag=limit_mag, slew=sky.stars.slew
        ).propagated("nea")
        dsnu = np.sqrt(np.maximum(grown**2 - sky.propagated("nea") ** 2, 0.0))
    dsnu_term = Term(
        "pixel_spatial_dsnu",
        "pixel_spatial",
        _same(dsnu, n_rates),
        True,
        True,
        _PER_STAR,
        f"modelled: DSNU {det.dsnu_e:g} e- rms as a second read noise (the NEA's quadrature growth)"
        if det.dsnu_e > 0
        else "modelled: no DSNU in the sensor TOML",
    )
    return [interp, prnu, dsnu_term]


def _temporal(sky: SkyStars, rates_rad_s) -> Term:
    values = []
    for rate in rates_rad_s:
        if rate <= 0.0:
            values.append(sky.propagated("nea"))
        elif sky.model.refine == "model":
            values.append(sky.temporal_at_rate(rate))
        else:
            values.append(None)
    kept = len(sky.matrices[:: sky.rate_stride])
    how = (
        "modelled: the forward model's Fisher information (the bound its fit attains); at a "
        f"rate, of the smeared stars detected at that rate, over {kept} of the "
        f"{len(sky.matrices)} attitudes"
        if sky.model.refine == "model"
        else "modelled at rest (windowed centre-of-gravity noise); under slew not predicted "
        "(the datasheet's Monte Carlo measures it)"
    )
    return Term("temporal_noise", "temporal_noise", tuple(values), True, True, _GAUSS_SKY, how)


def _aberration(sensor, n_rates: int) -> list[Term]:
    given = dict(sensor.budget)
    counted = not bool(given.get("aberration_corrected", True))
    speeds = [("annual", EARTH_ORBITAL_SPEED_M_S)]
    if "orbital_speed_m_s" in given:
        speeds.append(("orbital", float(given["orbital_speed_m_s"])))
    out = []
    for name, v in speeds:
        c, r = aberration_error(sensor, v)
        where = "in the totals" if counted else "left out of the totals (corrected on board)"
        out.append(
            Term(
                f"aberration_{name}",
                "aberration",
                _same(np.array([c, c, r]), n_rates),
                False,
                counted,
                "deterministic (the velocity is known): the worst case over apex "
                "directions, the same at every confidence",
                f"modelled (v = {v / 1e3:.2f} km/s, if uncorrected); {where}",
            )
        )
    return out


def error_terms(sensor, sky: SkyStars, settings, *, limit_mag, rates_rad_s) -> list[Term]:
    """Return the statement's terms of ``sensor`` at ``rates_rad_s`` (module docstring).

    Parameters
    ----------
    sensor : Sensor
    sky : SkyStars
        The datasheet's sky (:func:`starsense.analysis.ecss.sky.sky_stars`).
    settings : DatasheetSettings
    limit_mag : float
        The limiting magnitude at rest, V.
    rates_rad_s : sequence of float
        Body rates, rad/s.

    Returns
    -------
    list of Term
    """
    n = len(rates_rad_s)
    return [
        _given(sensor, "bias", n),
        _given(sensor, "thermo_elastic", n),
        _fov_spatial(sensor, sky, n),
        *_pixel_terms(sensor, sky, settings, limit_mag, n),
        _temporal(sky, rates_rad_s),
        *_aberration(sensor, n),
    ]
