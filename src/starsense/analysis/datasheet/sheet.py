"""The datasheet of one sensor: predicted, and verified on rendered frames in the same run.

:func:`build_datasheet` composes the analyses (slew tolerance, availability, the Fisher bound,
the centroid noise model, the Monte Carlo) into the numbers vendors quote (ECSS-E-ST-60-20C
terms). The JSON form (:meth:`Datasheet.to_dict`) is documented in ``docs/datasheet.md`` and
versioned by its ``schema`` field.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from starsense.analysis.datasheet.predict import (
    DEFAULT_RATES_RAD_S,
    StarModel,
    fastest_rate,
    limiting_magnitude,
    nea_at,
    slew_grids,
)
from starsense.units import DEG, RAD_TO_ARCSEC, RAD_TO_DEG

__all__ = ["SCHEMA", "Datasheet", "DatasheetSettings", "build_datasheet"]

#: the JSON schema's name and version; bumped on any incompatible change
SCHEMA = "starsense.datasheet/1"
_N_MIN_LIS, _N_MIN_TRACK = 3, 2


@dataclass(frozen=True)
class DatasheetSettings:
    """How the datasheet is computed (all reported in its JSON).

    Attributes
    ----------
    trials : int
        Monte Carlo frames at rest, and again at ``rate_rad_s``.
    rate_rad_s : float
        Cross-axis rate of the second Monte Carlo, rad/s.
    seed : int
        Root seed of every random step.
    n_orientations : int
        Quasi-uniform boresights of the sky statistics.
    slew_trials : int
        Renders per (magnitude, rate) of the slew-tolerance Monte Carlo.
    model : str
        Sensitivity model (magnitude -> photo-electrons).
    rate_trials : int or None
        Frames of the run at ``rate_rad_s`` (None: ``trials``).
    """

    trials: int = 100
    rate_rad_s: float = 1.0 * DEG
    seed: int = 0
    n_orientations: int = 2000
    slew_trials: int = 20
    model: str = "reed"
    rate_trials: int | None = None


@dataclass
class Datasheet:
    """A sensor's datasheet: ``data`` is the JSON form; the arrays feed the figures."""

    data: dict
    boresights: np.ndarray | None = None
    nea_cross_rad: np.ndarray | None = None
    slew: object = None
    dynamic: object = None
    warnings: list = field(default_factory=list)

    def to_dict(self) -> dict:
        """Return the JSON form (units in the field names; None where a number does not exist)."""
        return _clean(self.data)


def _clean(value):
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    return value


def _stat(values: np.ndarray, q: float) -> float | None:
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(np.percentile(v, q)) if v.size else None


def _arcsec_stats(cross: np.ndarray, roll: np.ndarray) -> dict:
    c, r = cross * RAD_TO_ARCSEC, roll * RAD_TO_ARCSEC
    return {
        "cross": {"median": _stat(c, 50), "p95": _stat(c, 95)},
        "roll": {"median": _stat(r, 50), "p95": _stat(r, 95)},
    }


def _detection(sensor, settings: DatasheetSettings, tick):
    """Return the static limit, slew tolerance and threshold curve (all None: nothing detected)."""
    from starsense.analysis.availability import ThresholdCurve
    from starsense.analysis.slew import simulate_slew

    wide = np.arange(-2.0, 16.0001, 0.25)
    rest = simulate_slew(
        sensor, settings.model, wide, [0.0], n_trials=settings.slew_trials, seed=settings.seed
    )
    rough = limiting_magnitude(wide, rest.detected_fraction[:, 0])
    tick("static limit")
    if rough is None:
        return None, None, None
    mags, rates = slew_grids(sensor, rough)
    slew = simulate_slew(
        sensor, settings.model, mags, rates, n_trials=settings.slew_trials, seed=settings.seed
    )
    limit = limiting_magnitude(mags, slew.detected_fraction[:, 0])
    tick("slew tolerance")
    return (rough if limit is None else limit), slew, ThresholdCurve.from_slew(slew)


def _availability(analysis, curve, rate_rad_s: float) -> tuple[dict, object]:
    """Availability at rest and at the datasheet's rates, and the fastest rates that keep it."""
    rates = np.unique(np.append(DEFAULT_RATES_RAD_S, rate_rad_s))
    coarse = analysis.dynamic(curve, rates, _N_MIN_LIS)
    fine_rates = np.linspace(0.0, float(curve.rates_rad_s[-1]), 121)
    fine = analysis.dynamic(curve, fine_rates, _N_MIN_LIS)
    fastest = {
        name: {
            f"{int(p * 100)}": fastest_rate(fine_rates * RAD_TO_DEG, fine.by_n_min[n], p)
            for p in (0.5, 0.9, 0.99)
        }
        for name, n in (("lost_in_space", _N_MIN_LIS), ("tracking", _N_MIN_TRACK))
    }
    lis = np.asarray(coarse.by_n_min[_N_MIN_LIS], dtype=float)
    trk = np.asarray(coarse.by_n_min[_N_MIN_TRACK], dtype=float)
    out = {
        "lost_in_space": float(lis[0]),
        "tracking": float(trk[0]),
        "rates_deg_s": [float(r) for r in rates * RAD_TO_DEG],
        "lost_in_space_at_rate": [float(x) for x in lis],
        "tracking_at_rate": [float(x) for x in trk],
        "threshold_mag_at_rate": [float(x) for x in coarse.threshold_mag],
        "fastest_rate_deg_s": fastest,
        "n_orientations": analysis.n_orientations,
    }
    return out, fine


def _limit(catalog, sensor, fov, matrices) -> tuple[np.ndarray, np.ndarray]:
    """Fialho & Mortari's bound per attitude for the sensor's D, t and field (rad)."""
    from starsense.analysis.datasheet.field import axis_sigmas, field_stars_cam, fisher_per_pointing
    from starsense.analysis.limits.sky import star_weights
    from starsense.photometry.stars import BlackBodyStars

    stars = BlackBodyStars.from_catalog(catalog)
    w = star_weights(stars, sensor.optics.aperture_m, sensor.exposure_s)
    pairs = field_stars_cam(fov, matrices, stars.vectors)
    return axis_sigmas(fisher_per_pointing(pairs, w[pairs.star]))


def _geometry(sensor, limit_mag, model) -> dict:
    det = sensor.detector
    e0, elim = (float(x) for x in model.sensitivity.electrons(np.array([0.0, limit_mag])))
    return {
        "fov_deg": [2.0 * h * RAD_TO_DEG for h in sensor.half_fov_rad],
        "pixel_scale_arcsec": det.pixel_pitch_m / sensor.optics.focal_length_m * RAD_TO_ARCSEC,
        "limiting_magnitude": limit_mag,
        "electrons": {"magnitude_0": e0, "limiting_magnitude": elim},
        "centroid_sigma_px": {
            "magnitude_0": float(model.noise.sigma(e0)),
            "limiting_magnitude": float(model.noise.sigma(elim)),
            "crb_magnitude_0": float(model.noise.crb(e0)),
            "crb_limiting_magnitude": float(model.noise.crb(elim)),
        },
    }


def _budget(sensor, nea: dict, pixel: tuple, pse_px: float | None) -> list[dict]:
    """Return the error budget: term, cross, roll (arcsec), source."""
    from starsense.analysis.datasheet.terms import EARTH_ORBITAL_SPEED_M_S, aberration_error

    given = dict(sensor.budget)
    rows = [
        {
            "term": "noise-equivalent angle (temporal, 1 sigma, sky median)",
            "cross_arcsec": nea["cross"]["median"],
            "roll_arcsec": nea["roll"]["median"],
            "source": "modelled (centroid noise through eq. 21)",
        },
        {
            "term": f"pixel spatial error (centroid bias, rms {pse_px:.4f} px)"
            if pse_px
            else "pixel spatial error",
            "cross_arcsec": _stat(pixel[0] * RAD_TO_ARCSEC, 50),
            "roll_arcsec": _stat(pixel[1] * RAD_TO_ARCSEC, 50),
            "source": "measured in this run (noiseless renders)",
        },
        _fov_spatial(sensor, given),
    ]
    if not given.get("aberration_corrected", False):
        speeds = [("annual", EARTH_ORBITAL_SPEED_M_S)]
        if "orbital_speed_m_s" in given:
            speeds.append(("orbital", given["orbital_speed_m_s"]))
        for name, v in speeds:
            c, r = aberration_error(sensor, v)
            rows.append(
                {
                    "term": f"stellar aberration, {name}, if uncorrected (worst case)",
                    "cross_arcsec": c * RAD_TO_ARCSEC,
                    "roll_arcsec": r * RAD_TO_ARCSEC,
                    "source": f"modelled (v = {v / 1e3:.2f} km/s)",
                }
            )
    for key in ("bias", "thermoelastic"):
        c, r = given.get(f"{key}_cross_arcsec"), given.get(f"{key}_roll_arcsec")
        if c is not None or r is not None:
            rows.append(
                {
                    "term": key.replace("thermoelastic", "thermo-elastic"),
                    "cross_arcsec": c or 0.0,
                    "roll_arcsec": r or 0.0,
                    "source": "given (sensor TOML [budget])",
                }
            )
    ok = [r for r in rows if r["cross_arcsec"] is not None and r["roll_arcsec"] is not None]
    rows.append(
        {
            "term": "total (root sum square)",
            "cross_arcsec": math.sqrt(sum(r["cross_arcsec"] ** 2 for r in ok)),
            "roll_arcsec": math.sqrt(sum(r["roll_arcsec"] ** 2 for r in ok)),
            "source": "combined",
        }
    )
    return rows


def _fov_spatial(sensor, given: dict) -> dict:
    """Return the field-of-view spatial error row: given, zero for a pinhole, or unknown."""
    term = "field-of-view spatial error (distortion residual)"
    if "fov_spatial_cross_arcsec" in given or "fov_spatial_roll_arcsec" in given:
        return {
            "term": term,
            "cross_arcsec": given.get("fov_spatial_cross_arcsec", 0.0),
            "roll_arcsec": given.get("fov_spatial_roll_arcsec", 0.0),
            "source": "given (sensor TOML [budget], the calibration residual)",
        }
    if not any(sensor.optics.distortion):
        return {
            "term": term,
            "cross_arcsec": 0.0,
            "roll_arcsec": 0.0,
            "source": "modelled: pinhole camera, no distortion to leave",
        }
    why = (
        "not known: the sensor has distortion; give fov_spatial_cross_arcsec and "
        "fov_spatial_roll_arcsec in [budget] (the residual of `starsense calibrate`)"
    )
    return {"term": term, "cross_arcsec": None, "roll_arcsec": None, "source": why}


def _quoted(sensor, data: dict) -> list[dict]:
    """Predicted / quoted for each ``[quoted]`` value of the sensor TOML."""
    mc = data.get("monte_carlo") or {}
    avail = data.get("availability") or {}
    nea = data.get("nea_arcsec") or {}
    predicted = {
        "nea_cross_arcsec": (nea.get("cross") or {}).get("median"),
        "nea_roll_arcsec": (nea.get("roll") or {}).get("median"),
        "limiting_magnitude": data.get("limiting_magnitude"),
        "lost_in_space_success": (mc["solved"] / mc["frames"]) if mc.get("frames") else None,
        "lost_in_space_time_ms": mc.get("median_ms"),
        "availability": avail.get("lost_in_space"),
        "max_rate_deg_s": ((avail.get("fastest_rate_deg_s") or {}).get("tracking") or {}).get("90"),
    }
    out = []
    for key, value in sensor.quoted:
        if key == "source":
            continue
        p = predicted.get(key)
        ratio = p / value if p is not None and value else None
        out.append({"key": key, "predicted": p, "quoted": value, "ratio": ratio})
    return out


def _no_stars(sensor, settings, catalog_name: str) -> Datasheet:
    """Return the datasheet of a sensor that detects no star at rest: every number null, and why."""
    why = (
        f"{sensor.name} detects no star at rest, not even of magnitude -2 (the detection logic "
        f"needs {sensor.detection.min_pixels} pixels above {sensor.detection.lit_pixel_counts:g} "
        f"counts and {sensor.detection.min_integrated_counts:g} counts in all)"
    )
    data = {
        "schema": SCHEMA,
        "sensor": sensor.name,
        "limiting_magnitude": None,
        "warnings": [why],
        "settings": _settings(settings, catalog_name, None),
    }
    return Datasheet(data, warnings=[why])


def _settings(settings: DatasheetSettings, catalog_name: str, cut: float | None) -> dict:
    return {
        "catalog": catalog_name,
        "model": settings.model,
        "trials": settings.trials,
        "rate_deg_s": settings.rate_rad_s * RAD_TO_DEG,
        "seed": settings.seed,
        "n_orientations": settings.n_orientations,
        "slew_trials": settings.slew_trials,
        "catalog_cut_mag": cut,
        "fov": "rectangular (the detector)",
    }


def _warnings(data: dict) -> list[str]:
    """Say in words what the numbers cannot: too few stars, no attitude, wrong solutions."""
    out = []
    stars = data.get("stars_in_fov") or {}
    if (stars.get("median") or 0) < _N_MIN_LIS:
        out.append(
            f"the median field holds {stars.get('median')} detectable stars, fewer than the "
            f"{_N_MIN_LIS} lost in space needs"
        )
    if data["availability"]["tracking"] == 0.0:
        out.append("no boresight of the sky holds the 2 stars an attitude needs")
    mc, avail = data.get("monte_carlo") or {}, data["availability"]["lost_in_space"]
    if mc.get("frames"):
        solved = mc["solved"] / mc["frames"]
        margin = 2.0 * math.sqrt(max(solved * (1 - solved), 1e-4) / mc["frames"])  # ~95 %
        if solved < avail - margin:
            out.append(
                f"lost in space solved {solved:.1%} of the rendered frames at rest, below the "
                f"{avail:.1%} of the sky with >= {_N_MIN_LIS} detectable stars: identification "
                f"needs more than that (statuses {mc['statuses']})"
            )
    for key in ("monte_carlo", "monte_carlo_at_rate"):
        mc = data.get(key) or {}
        if mc.get("wrong"):
            out.append(f"{key}: {mc['wrong']} wrong identifications in {mc['frames']} frames")
    return out


def build_datasheet(
    sensor,
    catalog=None,
    settings: DatasheetSettings | None = None,
    *,
    client=None,
    progress: Callable[[str, int, int], None] | None = None,
) -> Datasheet:
    """Predict and verify what ``sensor`` does (see the module docstring).

    Parameters
    ----------
    sensor : Sensor
    catalog : Catalog, optional
        Default: the bundled Hipparcos (V magnitudes).
    settings : DatasheetSettings, optional
    client : dask.distributed.Client, optional
        Run the Monte Carlo frames on this cluster (same results for the same seed).
    progress : callable(label, done, total), optional

    Returns
    -------
    Datasheet
    """
    from starsense.analysis.availability import AvailabilityAnalysis
    from starsense.analysis.availability.field import catalog_stars
    from starsense.analysis.availability.pointings import sky_attitudes
    from starsense.analysis.datasheet.verify import score_montecarlo
    from starsense.analysis.montecarlo import run_montecarlo
    from starsense.catalog import load_catalog

    st = settings or DatasheetSettings()
    cat = load_catalog("hipparcos") if catalog is None else catalog
    steps = [
        "static limit",
        "slew tolerance",
        "availability",
        "noise",
        "monte carlo",
        "monte carlo at rate",
    ]

    def tick(label: str) -> None:
        if progress is not None:
            progress(f"datasheet: {label}", steps.index(label) + 1, len(steps))

    limit_mag, slew, curve = _detection(sensor, st, tick)
    if limit_mag is None:
        return _no_stars(sensor, st, getattr(cat, "name", ""))
    fov = sensor.fov()
    analysis = AvailabilityAnalysis.from_catalog(
        cat, fov, limit_mag, "V", n_orientations=st.n_orientations, roll=None, seed=st.seed
    )
    avail, fine = _availability(analysis, curve, st.rate_rad_s)
    tick("availability")
    vectors, mags = catalog_stars(cat, limit_mag, "V")
    model = StarModel.build(sensor, st.model, float(np.min(mags)), limit_mag)
    boresights, att = sky_attitudes(st.n_orientations, None, st.seed)
    mats = att.as_matrix()
    sig, counts = nea_at(model, fov, mats, vectors, mags, ("nea", "crb", "pixel"))
    lim = _limit(cat, sensor, fov, mats)
    tick("noise")
    nea = _arcsec_stats(*sig["nea"])
    data = {"schema": SCHEMA, "sensor": sensor.name, **_geometry(sensor, limit_mag, model)}
    data["stars_in_fov"] = {
        "median": float(np.median(counts)),
        "p05": float(np.percentile(counts, 5)),
    }
    data["nea_arcsec"] = nea
    data["crb_arcsec"] = _arcsec_stats(*sig["crb"])
    data["limit_arcsec"] = {
        "cross": _stat(lim[0] * RAD_TO_ARCSEC, 50),
        "roll": _stat(lim[1] * RAD_TO_ARCSEC, 50),
    }
    data["nea_over_limit"] = {
        k: (nea[k]["median"] / data["limit_arcsec"][k])
        if nea[k]["median"] is not None and data["limit_arcsec"][k]
        else None
        for k in ("cross", "roll")
    }
    data["roll_over_cross"] = _roll_factor(nea, vectors, mats, fov)
    runs = []
    rate_trials = st.trials if st.rate_trials is None else st.rate_trials
    for key, rate, n in (
        ("monte_carlo", 0.0, st.trials),
        ("monte_carlo_at_rate", st.rate_rad_s, rate_trials),
    ):
        res = run_montecarlo(
            sensor, n, rate_rad_s=rate, catalog=cat, seed=st.seed, model=st.model, client=client
        )
        data[key] = score_montecarlo(res, model, fov, vectors, mags, predict=rate == 0.0)
        runs.append(res)
        tick(key.replace("_", " "))
    data["availability"] = avail
    data["slew"] = slew.tolerance_dict()  # the JSON of `starsense slew tolerance`
    pse = np.nanmax(model.pixel_bias.rms_px) if np.isfinite(model.pixel_bias.rms_px).any() else None
    data["budget"] = _budget(sensor, nea, sig["pixel"], pse)
    data["quoted"] = _quoted(sensor, data)
    data["quoted_source"] = dict(sensor.quoted).get("source")
    data["settings"] = _settings(st, getattr(cat, "name", ""), limit_mag)
    data["warnings"] = _warnings(data)
    return Datasheet(data, boresights, sig["nea"][0], slew, fine, data["warnings"])


def _roll_factor(nea: dict, vectors, mats, fov) -> dict:
    """Roll over cross-boresight NEA, and the ratio the geometry implies.

    For N equally weighted stars at field angles r_i (rad), F_xx ~ sum w and F_zz = sum w r_i^2,
    so roll / cross ~ 1 / rms(r): the rms field angle of the stars used, here over the sky.
    """
    from starsense.analysis.datasheet.field import field_stars_cam

    pairs = field_stars_cam(fov, mats[:200], vectors)
    v = pairs.v_cam
    r2 = (v[:, 0] ** 2 + v[:, 1] ** 2) / v[:, 2] ** 2
    geometry = 1.0 / math.sqrt(float(np.mean(r2))) if len(r2) else None
    c, r = nea["cross"]["median"], nea["roll"]["median"]
    return {"nea": r / c if c and r else None, "geometry": geometry}
