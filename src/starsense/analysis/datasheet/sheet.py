"""The datasheet of one sensor: predicted, and verified on rendered frames in the same run.

:func:`build_datasheet` composes the analyses (slew tolerance, availability, the Fisher bound,
the centroid noise model, the Monte Carlo) into the numbers vendors quote (ECSS-E-ST-60-20C
terms), a typed :class:`~starsense.analysis.datasheet.sections.Datasheet`. Its JSON form
(:meth:`Datasheet.to_dict`) is documented in ``docs/datasheet.md`` and versioned by its
``schema`` field.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from starsense.analysis.availability.analysis import AvailabilityAnalysis
from starsense.analysis.availability.field import catalog_stars
from starsense.analysis.availability.pointings import sky_attitudes
from starsense.analysis.datasheet.budget import error_budget, quoted_values, sky_median
from starsense.analysis.datasheet.checks import no_star_reason, sanity_warnings, solving_warnings
from starsense.analysis.datasheet.field import field_stars_cam
from starsense.analysis.datasheet.predict import (
    DEFAULT_RATES_RAD_S,
    StarModel,
    error_kinds,
    fastest_rate,
    nea_at,
)
from starsense.analysis.datasheet.sections import (
    AvailabilitySummary,
    AxisPair,
    AxisSpread,
    CentroidSigma,
    Datasheet,
    Electrons,
    FastestRates,
    RatesKept,
    RollOverCross,
    Spread,
    StarsInFov,
)
from starsense.analysis.datasheet.settings import DatasheetSettings, sheet_settings
from starsense.analysis.datasheet.skycache import limit_sigmas
from starsense.analysis.datasheet.stars import fitted_stars
from starsense.analysis.datasheet.verify import run_checks
from starsense.analysis.inputs import (
    as_catalog,
    as_sensor,
    completed_sky,
    root_seed,
)
from starsense.analysis.sensor_detection import sensor_detection
from starsense.identify.hashing import MIN_SOLVING_STARS
from starsense.photometry.colour import with_johnson_from_gaia
from starsense.render.scene import check_frame_size
from starsense.solve.solver import Solver
from starsense.units import DEG, RAD_TO_ARCSEC, RAD_TO_DEG

__all__ = ["SCHEMA", "Datasheet", "DatasheetSettings", "build_datasheet", "datasheet"]

#: the JSON schema's name and version; bumped on any incompatible change
SCHEMA = "starsense.datasheet/1"
#: the stars lost in space needs: the identifier's pattern and one more detection that
#: matches (the pattern's own stars are no evidence of a match), and tracking's two
_N_MIN_LIS, _N_MIN_TRACK = MIN_SOLVING_STARS, 2
#: the steps a datasheet reports its progress through
_STEPS = (
    "static limit",
    "slew tolerance",
    "availability",
    "noise",
    "monte carlo",
    "monte carlo at rate",
)


def _arcsec_stats(cross: np.ndarray, roll: np.ndarray) -> AxisSpread:
    c, r = cross * RAD_TO_ARCSEC, roll * RAD_TO_ARCSEC
    return AxisSpread(
        Spread(sky_median(c, 50), sky_median(c, 95)), Spread(sky_median(r, 50), sky_median(r, 95))
    )


def _detection(sensor, settings: DatasheetSettings, tick):
    """Return the static limit, slew tolerance and threshold curve (all None: nothing detected)."""
    det = sensor_detection(
        sensor,
        model=settings.model,
        n_trials=settings.n_slew_trials,
        rng=settings.seed,
        progress=tick,
        full_grid=settings.slew_full_grid,
    )
    return det.limit_mag, det.slew, det.curve


def _availability(analysis, curve, rate_rad_s: float) -> tuple[AvailabilitySummary, object]:
    """Availability at rest and at the datasheet's rates, and the fastest rates that keep it."""
    rates = np.unique(np.append(DEFAULT_RATES_RAD_S, rate_rad_s))
    coarse = analysis.dynamic(curve, rates, _N_MIN_LIS)
    fine_rates = np.linspace(0.0, float(curve.rates_rad_s[-1]), 121)
    fine = analysis.dynamic(curve, fine_rates, _N_MIN_LIS)
    fastest = {
        name: FastestRates(
            *(fastest_rate(fine_rates * RAD_TO_DEG, fine.by_n_min[n], p) for p in (0.5, 0.9, 0.99))
        )
        for name, n in (("lost_in_space", _N_MIN_LIS), ("tracking", _N_MIN_TRACK))
    }
    lis = np.asarray(coarse.by_n_min[_N_MIN_LIS], dtype=float)
    trk = np.asarray(coarse.by_n_min[_N_MIN_TRACK], dtype=float)
    out = AvailabilitySummary(
        lost_in_space=float(lis[0]),
        tracking=float(trk[0]),
        rates_deg_s=tuple(float(r) for r in rates * RAD_TO_DEG),
        lost_in_space_at_rate=tuple(float(x) for x in lis),
        tracking_at_rate=tuple(float(x) for x in trk),
        threshold_mag_at_rate=tuple(float(x) for x in coarse.threshold_mag),
        fastest_rate_deg_s=RatesKept(**fastest),
        n_orientations=analysis.n_orientations,
    )
    return out, fine


def _limit(catalog, sensor, fov, matrices) -> tuple[np.ndarray, np.ndarray]:
    """Fialho & Mortari's bound per attitude for the sensor's D, t and field (rad)."""
    return limit_sigmas(catalog, sensor, fov, matrices=matrices)


def _geometry(sensor, limit_mag, model) -> dict:
    """Return the fields of the sensor's geometry and signal (keyword arguments of Datasheet)."""
    det = sensor.detector
    e0, elim = (float(x) for x in model.sensitivity.electrons(np.array([0.0, limit_mag])))
    return {
        "fov_deg": tuple(2.0 * h * RAD_TO_DEG for h in sensor.half_fov_rad),
        "pixel_scale_arcsec": det.pixel_pitch_m / sensor.optics.focal_length_m * RAD_TO_ARCSEC,
        "limiting_magnitude": limit_mag,
        "electrons": Electrons(e0, elim),
        "centroid_sigma_px": CentroidSigma(
            magnitude_0=float(model.noise.sigma(e0)),
            limiting_magnitude=float(model.noise.sigma(elim)),
            crb_magnitude_0=float(model.noise.crb(e0)),
            crb_limiting_magnitude=float(model.noise.crb(elim)),
        ),
    }


def _no_stars(sensor, settings, catalog_name: str, sky=None) -> Datasheet:
    """Return the datasheet of a sensor that detects no star at rest: every number null, and why.

    ``sky``: (its limiting magnitude, the catalogue's brightest star), V, where the limit lies
    above every star of the sky; None where it detects none of magnitude -2.
    """
    why = no_star_reason(sensor, sky)
    return Datasheet(
        schema=SCHEMA,
        sensor=sensor.name,
        limiting_magnitude=None,
        warnings=(why, *sanity_warnings(sensor, catalog_name="", limit_mag=None, runs={})),
        settings=sheet_settings(settings, catalog_name, None),
    )


def _sky_noise(cat, sensor, st: DatasheetSettings, detection, fov, database):
    """Return the sky statistics: star model, fitted stars, boresights, per-attitude sigmas, bound.

    ``detection``: the limiting magnitude at rest and the slew tolerance run; ``database``:
    the solver's catalogue.
    """
    limit_mag, slew = detection
    vectors, mags = catalog_stars(cat, limit_mag, band="V")
    every = np.asarray(cat.mags["V"], dtype=float)  # the frames hold all of them
    if st.refine == "model":  # the fit draws the frames' own sky (montecarlo: Solver(sky=))
        held = np.ones(len(every), dtype=bool)
    else:  # the centroids' attitude models no neighbour: every one pulls unmodelled
        held = np.zeros(len(every), dtype=bool)
    # the stars in the fit: the model's (to its floor), or the detector's by their chance
    fitted = fitted_stars(
        cat, sensor, slew=slew, limit_mag=limit_mag, refine=st.refine, model=st.model
    )
    faint = limit_mag
    if fitted.electrons is not None:  # the model fit's stars reach its floor
        faint = max(limit_mag, float(np.max(fitted.magnitudes, initial=limit_mag)))
    model = StarModel.build(
        sensor,
        model=st.model,
        bright_mag=float(np.min(mags)),
        faint_mag=faint,
        star_counts=every,
        unmodelled=every[~held],
        modelled=every[held],
        refine=st.refine,
    )
    boresights, att = sky_attitudes(st.n_orientations, None, st.seed)
    mats = att.as_matrix()
    counts = field_stars_cam(fov, mats, vectors).counts()  # every detectable star
    v, m, p, catalogue = fitted.at(0.0)
    kinds = error_kinds(sensor) + (() if catalogue is None else ("catalogue",))
    sig, _ = nea_at(
        model, fov, mats, vectors=v, magnitudes=m, kinds=kinds, catalogue=catalogue, presence=p
    )
    lim = _limit(cat, sensor, fov, mats)
    return model, fitted, boresights, mats, sig, counts, lim


def build_datasheet(
    sensor,
    catalog=None,
    *,
    settings: DatasheetSettings | None = None,
    client=None,
    progress: Callable[[str, int, int], None] | None = None,
) -> Datasheet:
    """Predict and verify what ``sensor`` does (see the module docstring).

    Parameters
    ----------
    sensor : Sensor
        The sensor.
    catalog : Catalog, optional
        Default: the bundled Hipparcos (V magnitudes).
    settings : DatasheetSettings, optional
        How to compute it (default :class:`DatasheetSettings`).
    client : dask.distributed.Client, optional
        Run the Monte Carlo frames on this cluster (same results for the same seed).
    progress : callable(label, done, total), optional
        Called after each step.

    Returns
    -------
    Datasheet
    """
    st = settings or DatasheetSettings()
    check_frame_size(sensor)  # the verification renders whole frames: refuse before any work
    cat, colour_note = with_johnson_from_gaia(as_catalog(catalog))

    def tick(label: str) -> None:
        if progress is not None:
            progress(f"datasheet: {label}", _STEPS.index(label) + 1, len(_STEPS))

    limit_mag, slew, curve = _detection(sensor, st, tick)
    if limit_mag is None:
        return _no_stars(sensor, st, getattr(cat, "name", ""))
    brightest = float(np.nanmin(cat.mags["V"], initial=np.inf))
    if limit_mag < brightest:
        return _no_stars(sensor, st, getattr(cat, "name", ""), (limit_mag, brightest))
    fov = sensor.fov()
    analysis = AvailabilityAnalysis.from_catalog(
        cat, fov, limit_mag, band="V", n_orientations=st.n_orientations, roll_rad=None, rng=st.seed
    )
    avail, fine = _availability(analysis, curve, st.rate_rad_s)
    tick("availability")
    # the frames' sky: the catalogue and the database stars it lacks (the prediction and the
    # frames see one sky, the one the solver models)
    database = Solver(sensor=sensor).catalog
    sky_cat = completed_sky(cat, database)
    model, fitted, boresights, mats, sig, counts, lim = _sky_noise(
        sky_cat, sensor, st, (limit_mag, slew), fov, database
    )
    vectors, mags, presence, _ = fitted.at(0.0)
    tick("noise")
    nea = _arcsec_stats(*sig["nea"])
    stars = StarsInFov(float(np.median(counts)), float(np.percentile(counts, 5)))
    limit = AxisPair(sky_median(lim[0] * RAD_TO_ARCSEC, 50), sky_median(lim[1] * RAD_TO_ARCSEC, 50))
    over = {
        k: (getattr(nea, k).median / getattr(limit, k))
        if getattr(nea, k).median is not None and getattr(limit, k)
        else None
        for k in ("cross", "roll")
    }
    frames: dict = {}
    runs = run_checks(
        sensor, sky_cat, st, sky=(model, fov, fitted), client=client, tick=tick, keep=frames
    )
    bias = model.pixel_bias.rms(model.sensitivity.electrons(mags))
    pse = float(np.sqrt(np.nanmean(bias**2))) if np.isfinite(bias).any() else None
    errors = {k: v for k, v in sig.items() if k not in ("nea", "crb")}
    return Datasheet(
        schema=SCHEMA,
        sensor=sensor.name,
        **_geometry(sensor, limit_mag, model),
        stars_in_fov=stars,
        nea_arcsec=nea,
        crb_arcsec=_arcsec_stats(*sig["crb"]),
        limit_arcsec=limit,
        nea_over_limit=AxisPair(**over),
        roll_over_cross=_roll_factor(nea, vectors, mats, fov),
        **runs,
        availability=avail,
        slew=slew,  # its JSON is that of `starsense slew tolerance`
        budget=tuple(
            error_budget(
                sensor,
                nea,
                errors=errors,
                pse_px=pse,
                dsnu=_dsnu_growth(sensor, st, fov, (vectors, mags, presence, mats), nea),
                refine=st.refine,
            )
        ),
        quoted=tuple(
            quoted_values(
                sensor,
                limit_mag=limit_mag,
                nea=nea,
                monte_carlo=runs["monte_carlo"],
                availability=avail,
            )
        ),
        quoted_source=dict(sensor.quoted).get("source"),
        settings=sheet_settings(st, getattr(cat, "name", ""), limit_mag),
        warnings=(
            *([colour_note] if colour_note else []),
            *solving_warnings(stars, avail, runs, n_min=_N_MIN_LIS),
            *sanity_warnings(
                sensor, catalog_name=getattr(cat, "name", ""), limit_mag=limit_mag, runs=runs
            ),
        ),
        boresights=boresights,
        nea_cross_rad=sig["nea"][0],
        dynamic=fine,
        frame_errors_rad=frames,
    )


def _dsnu_growth(sensor, st, fov, sky, nea: AxisSpread) -> AxisPair | None:
    """Return how much the DSNU grows the NEA (quadrature difference of sky medians), arcsec.

    The dark-signal non-uniformity left after the dark frame acts, for one frame, as a second
    read noise: the NEA is recomputed with ``hypot(read_noise, dsnu)``.
    """
    det = sensor.detector
    if det.dsnu_e <= 0 or nea.cross.median is None:
        return None
    vectors, mags, presence, mats = sky
    noisier = sensor.with_(
        detector=dataclasses.replace(det, read_noise_e=math.hypot(det.read_noise_e, det.dsnu_e))
    )
    limit_mag = float(np.max(mags))
    model = StarModel.build(
        noisier, model=st.model, bright_mag=float(np.min(mags)), faint_mag=limit_mag
    )
    sig, _ = nea_at(model, fov, mats, vectors=vectors, magnitudes=mags, presence=presence)
    grown = _arcsec_stats(*sig["nea"])
    return AxisPair(
        *(
            math.sqrt(max(getattr(grown, k).median ** 2 - getattr(nea, k).median ** 2, 0.0))
            for k in ("cross", "roll")
        )
    )


def _roll_factor(nea: AxisSpread, vectors, mats, fov) -> RollOverCross:
    """Roll over cross-boresight NEA, and the ratio the geometry implies.

    For N equally weighted stars at field angles r_i (rad), F_xx ~ sum w and F_zz = sum w r_i^2,
    so roll / cross ~ 1 / rms(r): the rms field angle of the stars used, here over the sky.
    """
    pairs = field_stars_cam(fov, mats[:200], vectors)
    v = pairs.v_cam
    r2 = (v[:, 0] ** 2 + v[:, 1] ** 2) / v[:, 2] ** 2
    geometry = 1.0 / math.sqrt(float(np.mean(r2))) if len(r2) else None
    c, r = nea.cross.median, nea.roll.median
    return RollOverCross(r / c if c and r else None, geometry)


def datasheet(
    sensor,
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
) -> Datasheet:
    """Return the datasheet of a sensor: what it will do, predicted and checked in one run.

    Field of view, limiting magnitude, stars in the field, noise-equivalent angle over the sky
    (median and 95th percentile), the error budget, lost-in-space success on rendered frames at
    rest and at ``rate_rad_s``, availability static and under slew, and the distance from the
    physical limit (ECSS-E-ST-60-20C terms). The same as ``starsense datasheet``.

    Parameters
    ----------
    sensor : Sensor, str or Path
        The sensor, a preset name (``"st16"``) or a sensor TOML file.
    catalog : Catalog, str or None
        The catalogue, a specification (``"hipparcos"``, ``"bsc5:PATH"``) or None for the
        bundled Hipparcos (V magnitudes).
    n_trials : int
        Rendered frames of the Monte Carlo at rest (and at ``rate_rad_s``), >= 1.
    rate_rad_s : float
        Cross-axis body rate of the second Monte Carlo, rad/s (default 1 deg/s).
    rng : None, int or numpy.random.Generator
        Root seed of every random step (a Generator gives one seed drawn from it; the seed is
        recorded in ``settings.seed``).
    n_orientations : int
        Quasi-uniform boresights of the sky statistics.
    model : {"reed", "liebe", "blackbody"}
        Sensitivity model (magnitude -> photo-electrons).
    n_slew_trials : int
        Renders per (magnitude, rate) of the slew-tolerance Monte Carlo.
    n_rate_trials : int, optional
        Frames of the run at ``rate_rad_s`` (default ``n_trials``).
    client : dask.distributed.Client, optional
        Run the Monte Carlo frames on this cluster (the same results).
    progress : callable(label, done, total), optional
        Called after each step.

    Returns
    -------
    Datasheet
        Typed sections (``sheet.nea_arcsec.cross.median``, arcsec); ``sheet.to_dict()`` is the
        JSON of ``starsense datasheet --json``.
    """
    settings = DatasheetSettings(
        n_trials=n_trials,
        rate_rad_s=rate_rad_s,
        seed=root_seed(rng),
        n_orientations=n_orientations,
        n_slew_trials=n_slew_trials,
        model=model,
        n_rate_trials=n_rate_trials,
    )
    return build_datasheet(
        as_sensor(sensor), catalog, settings=settings, client=client, progress=progress
    )
