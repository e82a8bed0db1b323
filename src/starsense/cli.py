"""Command line: parse, load, call the API, print or write results. No physics here.

User errors (:class:`~starsense.errors.StarsenseError`) are printed as one line on stderr with exit
status 2; no traceback.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from starsense.cli_catalog import DaskOpt, ScaleCatalogOpt, check_dask_option
from starsense.cli_common import CatalogOpt, JsonOpt, SeedOpt, SensorOpt, emit, parse_floats
from starsense.errors import InputError, StarsenseError

ARCSEC_PER_RAD = 180.0 / np.pi * 3600.0

app = typer.Typer(
    name="starsense",
    help="Star-tracker engineering: how good a star sensor can be, and how good it is.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
limit_app = typer.Typer(
    help="The physical limit of attitude accuracy (Fialho & Mortari 2019).",
    no_args_is_help=True,
)
app.add_typer(limit_app, name="limit")
slew_app = typer.Typer(
    help="Slew tolerance: detection of smeared stars (Dzamba & Enright 2014).",
    no_args_is_help=True,
)
app.add_typer(slew_app, name="slew")


def _register_subapps() -> None:
    from starsense.cli_availability import availability_app
    from starsense.cli_catalog import catalog_app
    from starsense.cli_guide_stars import guide_stars_app

    app.add_typer(availability_app, name="availability")
    app.add_typer(guide_stars_app, name="guide-stars")
    app.add_typer(catalog_app, name="catalog")


_register_subapps()

DiameterOpt = Annotated[
    float, typer.Option("--diameter-m", help="Aperture (ideal sensor) diameter D, metres.")
]
ExposureOpt = Annotated[float, typer.Option("--exposure-s", help="Exposure time t, seconds.")]
ColourOpt = Annotated[
    str | None,
    typer.Option("--colour", help="Colour system: B-V, V-I, BT-VT, J-H, J-Ks, H-Ks, BP-RP."),
]


ModelOpt = Annotated[
    str, typer.Option("--model", help="Sensitivity model: reed, liebe (or blackbody to render).")
]


def _rad(x: float) -> str:
    return f"{x:.4g} rad ({x * ARCSEC_PER_RAD:.4g} arcsec)"


def _parse_target(text: str) -> tuple[float, float]:
    try:
        ra, dec = (float(p) for p in text.split(","))
    except ValueError:
        raise InputError(f"--target-deg expects RA,DEC in degrees, got {text!r}") from None
    if not (np.isfinite(ra) and np.isfinite(dec)) or not -90.0 <= dec <= 90.0:
        raise InputError(f"--target-deg {text!r}: RA must be finite and Dec within [-90, 90]")
    return ra, dec


def _load_stars(catalog: str, max_mag: float | None, colour: str | None):
    from starsense.analysis.limits import BlackBodyStars
    from starsense.catalog import load_catalog

    cat = load_catalog(catalog)
    stars = BlackBodyStars.from_catalog(cat, colour)
    if max_mag is not None:
        if not np.isfinite(max_mag):
            raise InputError(f"--max-mag must be a finite magnitude, got {max_mag!r}")
        keep = stars.magnitude <= max_mag
        if keep.sum() < 2:
            raise InputError(
                f"--max-mag {max_mag} leaves {int(keep.sum())} star(s) of {len(stars)} in "
                f"{cat.name}; at least 2 are needed"
            )
        stars = stars.subset(keep)
    return cat, stars


@limit_app.command("star")
def limit_star(
    mag_v: Annotated[float | None, typer.Option("--mag-v", help="Johnson V magnitude.")] = None,
    b_v: Annotated[float | None, typer.Option("--b-v", help="B-V colour index.")] = None,
    mag_h: Annotated[float | None, typer.Option("--mag-h", help="2MASS H magnitude.")] = None,
    h_ks: Annotated[float | None, typer.Option("--h-ks", help="2MASS H-Ks colour.")] = None,
    mag: Annotated[
        float | None, typer.Option("--mag", help="Magnitude in --colour's band.")
    ] = None,
    colour_index: Annotated[
        float | None, typer.Option("--colour-index", help="Colour index in --colour.")
    ] = None,
    colour: ColourOpt = None,
    diameter_m: DiameterOpt = 0.1,
    exposure_s: ExposureOpt = 0.1,
    as_json: JsonOpt = False,
) -> None:
    """One star's black body, photons and centroid bound (Table 1; eqs. 9, 12, 19)."""
    from starsense.analysis.limits import centroid_fisher
    from starsense.photometry import ColourModel, fit_star, total_photons

    if mag_v is not None or b_v is not None:
        if mag_v is None or b_v is None:
            raise InputError("--mag-v and --b-v must be given together")
        m, ci, system = mag_v, b_v, "B-V"
    elif mag_h is not None or h_ks is not None:
        if mag_h is None or h_ks is None:
            raise InputError("--mag-h and --h-ks must be given together")
        m, ci, system = mag_h, h_ks, "H-Ks"
    elif mag is not None and colour_index is not None and colour is not None:
        m, ci, system = mag, colour_index, colour
    else:
        raise InputError(
            "give --mag-v and --b-v, or --mag-h and --h-ks, or --mag, --colour-index and --colour"
        )
    t, c = fit_star(m, ci, system)
    f = float(centroid_fisher(c, t, diameter_m, exposure_s))
    photons = float(total_photons(c, t, diameter_m, exposure_s))
    sigma = 1.0 / np.sqrt(f)
    payload = {
        "temperature_k": t,
        "dilution": c,
        "photons": photons,
        "sigma_rad": float(sigma),
        "sigma_arcsec": float(sigma * ARCSEC_PER_RAD),
        "colour": system,
        "magnitude_band": ColourModel(system).magnitude_band,
        "diameter_m": diameter_m,
        "exposure_s": exposure_s,
    }
    emit(
        payload,
        as_json,
        [
            f"black body ({system}): T = {t:.0f} K, C = {c:.3e}",
            f"photons collected (D = {diameter_m} m, t = {exposure_s} s): {photons:.4g}",
            f"centroid bound sigma_min: {_rad(sigma)}",
        ],
    )


@limit_app.command("sky")
def limit_sky(
    diameter_m: DiameterOpt = 1.0,
    exposure_s: ExposureOpt = 1.0,
    catalog: ScaleCatalogOpt = "hipparcos",
    max_mag: Annotated[
        float | None, typer.Option("--max-mag", help="Use only stars brighter than this.")
    ] = None,
    colour: ColourOpt = None,
    fov_deg: Annotated[
        float | None, typer.Option("--fov-deg", help="FOV cone diameter, deg (with --target-deg).")
    ] = None,
    target_deg: Annotated[
        list[str] | None,
        typer.Option("--target-deg", help="RA,DEC of a head's boresight, deg; repeat for heads."),
    ] = None,
    dask: DaskOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Attitude limit over a catalogue: theta_rms, per-axis sigma, G (eqs. 21-24; Table 2).

    With --catalog hats:PATH_OR_URL the catalogue is processed partition by partition on Dask
    (--dask), with the same kernels and results as in memory.
    """
    from starsense.analysis.limits import fov_limit, sky_limit
    from starsense.geometry.attitude import radec_to_vectors

    if (fov_deg is None) != (not target_deg):
        raise InputError("--fov-deg and --target-deg go together (one or more targets)")
    if fov_deg is not None and (not np.isfinite(fov_deg) or not 0 < fov_deg <= 360):
        raise InputError(f"--fov-deg must be in (0, 360], got {fov_deg}")
    if check_dask_option(catalog, dask):
        _limit_sky_hats(catalog, dask, diameter_m, exposure_s, max_mag, colour, fov_deg,
                        target_deg, as_json)  # fmt: skip
        return
    cat, stars = _load_stars(catalog, max_mag, colour)
    common = {"catalog": cat.name, "colour": stars.colour, "n_skipped": stars.n_skipped}
    if fov_deg is None:
        res = sky_limit(stars, diameter_m, exposure_s)
        payload = {**res.to_dict(), **common}
        lines = [
            f"catalogue {cat.name}: {res.n_stars} stars ({stars.colour}; "
            f"{stars.n_skipped} skipped without magnitude or colour)",
            f"theta_rms (D = {diameter_m} m, t = {exposure_s} s): {_rad(res.theta_rms_rad)}",
            "per-axis sigma (ICRS x, y, z): "
            + ", ".join(f"{s:.3g}" for s in res.axis_sigma_rad)
            + " rad",
            f"G = {res.g_rad_m2_s05:.3e} rad m^2 s^1/2 (paper: 7e-15 < G < 1e-13)",
        ]
        emit(payload, as_json, lines)
        return
    radec = [_parse_target(t) for t in target_deg]
    vecs = np.array([radec_to_vectors(np.radians(ra), np.radians(dec)) for ra, dec in radec])
    heads, merged = fov_limit(stars, vecs, np.radians(fov_deg), diameter_m, exposure_s)
    _emit_fov(cat.name, stars.colour, common, fov_deg, radec, heads, merged, as_json)


def _emit_fov(name, colour, common, fov_deg, radec, heads, merged, as_json) -> None:
    best = merged if merged is not None else heads[0]
    payload = {
        **best.to_dict(),
        **common,
        "fov_deg": fov_deg,
        "heads": [
            {"target_deg": list(rd), **h.to_dict()} for rd, h in zip(radec, heads, strict=True)
        ],
    }
    if merged is not None:
        payload["merged"] = merged.to_dict()
    lines = [f"catalogue {name} ({colour}), FOV {fov_deg} deg:"]
    for rd, h in zip(radec, heads, strict=True):
        lines.append(
            f"  head at RA {rd[0]:g}, Dec {rd[1]:g}: {h.n_stars} stars, theta_rms "
            f"{_rad(h.theta_rms_rad)}; cross-boresight {h.axis_sigma_rad[0]:.3g}, "
            f"{h.axis_sigma_rad[1]:.3g} rad, roll {h.axis_sigma_rad[2]:.3g} rad"
        )
    if merged is not None:
        lines.append(f"  merged heads: theta_rms {_rad(merged.theta_rms_rad)}")
    emit(payload, as_json, lines)


def _limit_sky_hats(catalog, dask, diameter_m, exposure_s, max_mag, colour, fov_deg, target_deg,
                    as_json) -> None:  # fmt: skip
    """``limit sky`` over a HATS catalogue on Dask (starsense.scale)."""
    from starsense.cli_catalog import hats_session
    from starsense.geometry.attitude import radec_to_vectors
    from starsense.scale import fov_limit, sky_limit

    radec = [_parse_target(t) for t in target_deg or []]
    with hats_session(catalog, dask, not as_json) as (cat, client, progress):
        opts = {"colour": colour, "max_mag": max_mag, "client": client, "progress": progress}
        if fov_deg is None:
            res, used = sky_limit(cat, diameter_m, exposure_s, **opts)
        else:
            vecs = np.array(
                [radec_to_vectors(np.radians(ra), np.radians(dec)) for ra, dec in radec]
            )
            heads, merged, used = fov_limit(
                cat, vecs, np.radians(fov_deg), diameter_m, exposure_s, **opts
            )
    common = {"catalog": cat.name, "colour": used.colour, "n_skipped": used.n_skipped,
              "source": cat.location}  # fmt: skip
    if fov_deg is not None:
        _emit_fov(cat.name, used.colour, common, fov_deg, radec, heads, merged, as_json)
        return
    emit({**res.to_dict(), **common}, as_json, [
        f"HATS catalogue {cat.name} ({cat.location}, {cat.n_partitions} partitions): "
        f"{res.n_stars} stars ({used.colour}; {used.n_skipped} skipped without magnitude or "
        "colour)",
        f"theta_rms (D = {diameter_m} m, t = {exposure_s} s): {_rad(res.theta_rms_rad)}",
        "per-axis sigma (ICRS x, y, z): " + ", ".join(f"{s:.3g}" for s in res.axis_sigma_rad)
        + " rad",
        f"G = {res.g_rad_m2_s05:.3e} rad m^2 s^1/2 (paper: 7e-15 < G < 1e-13)",
    ])  # fmt: skip


@limit_app.command("curve")
def limit_curve(
    catalog: ScaleCatalogOpt = "hipparcos",
    colour: ColourOpt = None,
    diameter_m: DiameterOpt = 1.0,
    exposure_s: ExposureOpt = 1.0,
    extrapolate_to: Annotated[
        float, typer.Option("--extrapolate-to", help="N stars to extrapolate to (paper: 3e11).")
    ] = 3e11,
    plot: Annotated[Path | None, typer.Option("--plot", help="Write a PNG of the curve.")] = None,
    dask: DaskOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """theta_rms over the N brightest stars, N = 2 .. all, and its extrapolation (Fig. 7).

    With --catalog hats:PATH_OR_URL the curve is built partition by partition on Dask (--dask)
    from magnitude histograms, without sorting the catalogue.
    """
    from starsense.analysis.limits import brightest_curve

    if not np.isfinite(extrapolate_to) or extrapolate_to < 2:
        raise InputError(f"--extrapolate-to must be >= 2 stars, got {extrapolate_to}")
    if check_dask_option(catalog, dask):
        from starsense.cli_catalog import hats_session
        from starsense.scale import brightest_curve as hats_curve

        with hats_session(catalog, dask, not as_json) as (cat, client, progress):
            curve = hats_curve(
                cat, diameter_m, exposure_s, n_extrapolated=extrapolate_to, colour=colour,
                client=client, progress=progress,
            )  # fmt: skip
    else:
        cat, stars = _load_stars(catalog, None, colour)
        curve = brightest_curve(stars, diameter_m, exposure_s, n_extrapolated=extrapolate_to)
    payload = {"catalog": cat.name, "diameter_m": diameter_m, "exposure_s": exposure_s}
    payload.update(curve.to_dict())
    lines = [
        f"catalogue {cat.name} ({curve.colour}), D = {diameter_m} m, t = {exposure_s} s",
        *(
            f"  N = {n:>9d}  theta_rms = {th:.3e} rad"
            for n, th in zip(
                curve.n_stars[:: max(1, len(curve.n_stars) // 12)],
                curve.theta_rms_rad[:: max(1, len(curve.n_stars) // 12)],
                strict=True,
            )
        ),
        f"  all {curve.n_stars[-1]} stars: {curve.theta_rms_rad[-1]:.3e} rad",
        f"  tail slope d log theta / d log N = {curve.slope:.3f}; extrapolated to "
        f"N = {extrapolate_to:.3g}: {curve.theta_extrapolated_rad:.3e} rad",
    ]
    if plot is not None:
        from starsense.report.figures import plot_brightest_curves

        plot_brightest_curves(
            [curve], plot, catalog_name=cat.name, diameter_m=diameter_m, exposure_s=exposure_s
        )
        payload["plot"] = str(plot)
        lines.append(f"  figure: {plot}")
    emit(payload, as_json, lines)


@limit_app.command("photons")
def limit_photons(
    diameter_m: DiameterOpt = 0.1,
    exposure_s: ExposureOpt = 0.01,
    catalog: CatalogOpt = "hipparcos",
    colour: ColourOpt = None,
    trials: Annotated[int, typer.Option("--trials", help="Monte Carlo draws.")] = 200,
    seed: Annotated[int, typer.Option("--seed")] = 0,
    as_json: JsonOpt = False,
) -> None:
    """Low-photon degradation of the limit for small sensors and short exposures (sec. 3.3.2)."""
    from starsense.analysis.limits import low_photon_degradation

    cat, stars = _load_stars(catalog, None, colour)
    res = low_photon_degradation(stars, diameter_m, exposure_s, trials, seed)
    payload = {"catalog": cat.name, "diameter_m": diameter_m, "exposure_s": exposure_s}
    payload.update(res.to_dict())
    emit(
        payload,
        as_json,
        [
            f"catalogue {cat.name}: {len(stars)} stars, {res.n_below_one_photon} expected to "
            f"deliver < 1 photon; {res.expected_observed_stars:.4g} seen on average",
            f"theta_rms ideal {_rad(res.theta_ideal_rad)}; with Poisson photon counts "
            f"{_rad(res.theta_poisson_rad)} (x{res.degradation:.4f}, {trials} trials)",
            f"D^2 t = {diameter_m**2 * exposure_s:.3g} m^2 s (paper: >= 1e-4 comes close to "
            "the limit)",
        ],
    )


def _run_slew(sensor_name, model, magnitudes, rates, trials, criterion, seed, colour_index=0.0):
    from rich.progress import Progress

    from starsense.analysis.slew import simulate_slew
    from starsense.sensor import load_sensor

    sensor = load_sensor(sensor_name)
    mags = parse_floats(magnitudes, "--magnitudes")
    rate_values = parse_floats(rates, "--rates-deg-s")
    with Progress(transient=True, disable=not sys.stderr.isatty()) as bar:
        task = bar.add_task("slew Monte Carlo", total=None)
        result = simulate_slew(
            sensor, model, mags, rate_values, trials, criterion, seed,
            progress=lambda done, total: bar.update(task, completed=done, total=total),
            colour_index=colour_index,
        )  # fmt: skip
    return sensor, result


MagsOpt = Annotated[
    str | None,
    typer.Option("--magnitudes", help="Comma-separated magnitudes (default 1.25..6 by 0.25)."),
]
RatesOpt = Annotated[
    str | None,
    typer.Option("--rates-deg-s", help="Comma-separated increasing rates (default 0..10, 40)."),
]
TrialsOpt = Annotated[int, typer.Option("--trials", help="Monte Carlo trials per point.")]
CriterionOpt = Annotated[
    float, typer.Option("--criterion", help="Detection fraction that counts as detected.")
]
PlotOpt = Annotated[Path | None, typer.Option("--plot", help="Write a PNG figure here.")]
BvOpt = Annotated[
    float, typer.Option("--b-v", help="B-V of the simulated star (blackbody model; 0 = A0).")
]


@slew_app.command("tolerance")
def slew_tolerance(
    sensor: SensorOpt = "st16",
    model: ModelOpt = "reed",
    magnitudes: MagsOpt = None,
    rates_deg_s: RatesOpt = None,
    trials: TrialsOpt = 20,
    criterion: CriterionOpt = 0.5,
    seed: SeedOpt = 0,
    b_v: BvOpt = 0.0,
    plot: PlotOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Tolerable slew rate per magnitude (Fig. 10): the fastest rate still detected."""
    sens, res = _run_slew(sensor, model, magnitudes, rates_deg_s, trials, criterion, seed, b_v)
    payload = res.tolerance_dict()
    lines = [
        f"{sens.name}, {model} model: tolerable cross-axis slew rate (detected in >= "
        f"{criterion:.0%} of {trials} trials)"
    ]
    for m, r, c in zip(res.magnitudes, res.tolerable_rate_deg_s, res.capped, strict=True):
        text = "not detected at rest" if r is None else f"{'>= ' if c else ''}{r:.2f} deg/s"
        lines.append(f"  m = {m:5.2f}: {text}")
    if plot is not None:
        from starsense.report.slew import plot_tolerance

        plot_tolerance([res], plot)
        payload["plot"] = str(plot)
        lines.append(f"figure: {plot}")
    emit(payload, as_json, lines)


@slew_app.command("intensity")
def slew_intensity(
    sensor: SensorOpt = "st16",
    model: ModelOpt = "reed",
    magnitudes: MagsOpt = None,
    rates_deg_s: RatesOpt = None,
    trials: TrialsOpt = 20,
    seed: SeedOpt = 0,
    b_v: BvOpt = 0.0,
    plot: PlotOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Integrated intensity against slew rate per magnitude (Fig. 9)."""
    sens, res = _run_slew(sensor, model, magnitudes, rates_deg_s, trials, 0.5, seed, b_v)
    payload = res.intensity_dict()
    lines = [f"{sens.name}, {model} model: mean integrated intensity (counts) of detections"]
    header = "  rate deg/s " + " ".join(f"m={m:<6.2f}" for m in res.magnitudes)
    lines.append(header)
    for j, w in enumerate(res.rates_deg_s):
        row = " ".join(
            f"{v:8.0f}" if np.isfinite(v) else "       -" for v in res.mean_intensity_counts[:, j]
        )
        lines.append(f"  {w:10.2f} {row}")
    if plot is not None:
        from starsense.report.slew import plot_intensity

        plot_intensity(res, plot)
        payload["plot"] = str(plot)
        lines.append(f"figure: {plot}")
    emit(payload, as_json, lines)


@app.command("render")
def render(
    out: Annotated[Path, typer.Option("--out", help="Frame to write (.tiff, .png, .fits).")],
    sensor: SensorOpt = "st16",
    ra_deg: Annotated[float, typer.Option("--ra-deg", help="Boresight RA, deg.")] = 0.0,
    dec_deg: Annotated[float, typer.Option("--dec-deg", help="Boresight Dec, deg.")] = 0.0,
    roll_deg: Annotated[float, typer.Option("--roll-deg", help="Roll, deg.")] = 0.0,
    rate_deg_s: Annotated[
        str, typer.Option("--rate-deg-s", help="Body rate WX,WY,WZ in the camera frame, deg/s.")
    ] = "0,0,0",
    model: ModelOpt = "reed",
    catalog: CatalogOpt = "hipparcos",
    max_mag: Annotated[
        float | None, typer.Option("--max-mag", help="Render only stars brighter than this.")
    ] = None,
    seed: SeedOpt = 0,
    no_noise: Annotated[bool, typer.Option("--no-noise", help="Expected image only.")] = False,
    areas: Annotated[
        bool,
        typer.Option(
            "--areas",
            help="Render the sensor's attitude-determination areas (its focal plane, bias "
            "level outside the areas) instead of its detector.",
        ),
    ] = False,
) -> None:
    """Render a frame (with its truth as JSON beside it) for an attitude and body rate."""
    from starsense.catalog import load_catalog
    from starsense.geometry.attitude import attitude_from_radec_roll
    from starsense.render.io import write_frame
    from starsense.render.scene import render_frame
    from starsense.sensor import load_sensor

    if not -90.0 <= dec_deg <= 90.0 or not np.isfinite(ra_deg) or not np.isfinite(roll_deg):
        raise InputError("--ra-deg and --roll-deg must be finite and --dec-deg within [-90, 90]")
    rate = np.radians(parse_floats(rate_deg_s, "--rate-deg-s", 3))
    sens = load_sensor(sensor)
    att = attitude_from_radec_roll(np.radians(ra_deg), np.radians(dec_deg), np.radians(roll_deg))
    kwargs = {"rate_rad_s": rate, "model": model, "max_mag": max_mag, "rng": seed,
              "noise": not no_noise}  # fmt: skip
    if areas:
        from starsense.render.areas import render_areas

        area_frame = render_areas(sens, att, load_catalog(catalog), **kwargs)
        frame = area_frame.frame
        per_area = np.bincount(area_frame.star_area, minlength=len(sens.attitude_areas.areas) + 1)
        names = sens.attitude_areas.names
        where = ", ".join(f"{a}: {int(k)}" for a, k in zip(names, per_area[1:], strict=True))
        note = f"; in the areas {where}"
    else:
        frame = render_frame(sens, att, load_catalog(catalog), **kwargs)
        note = ""
    written = write_frame(out, frame)
    n = len(frame.truth.stars)
    typer.echo(f"frame written: {written} ({n} stars{note}; truth in {written}.json)")


@app.command("solve")
def solve(
    image: Annotated[Path, typer.Argument(help="Frame: TIFF, PNG, JPEG or FITS (8-32 bit).")],
    sensor: Annotated[
        str | None, typer.Option("--sensor", help="Sensor preset or TOML (known optics).")
    ] = None,
    fov_deg: Annotated[
        float | None, typer.Option("--fov-deg", help="Horizontal field, deg (pinhole).")
    ] = None,
    algorithm: Annotated[
        str, typer.Option("--algorithm", help="hashing (default, FOV-free) or triangle.")
    ] = "hashing",
    catalog: CatalogOpt = "hipparcos",
    wcs: Annotated[
        Path | None, typer.Option("--wcs", help="Write the solution's TAN WCS (FITS header).")
    ] = None,
    as_json: JsonOpt = False,
) -> None:
    """Solve a frame lost-in-space: RA, Dec, roll, FOV, matches, residuals, false-match odds.

    Without --sensor or --fov-deg the field is searched over 5-30 deg. Exit status 0 when solved,
    1 when the frame does not solve, 2 for bad input (including a frame with no stars).
    """
    from starsense.pipeline import Solver

    sol = Solver(sensor, fov_deg, catalog, algorithm).solve_file(image)
    payload = {"image": str(image), **sol.to_dict()}
    if sol.solved:
        lines = [
            f"{image}: solved in {sol.time_ms:.0f} ms - RA {sol.ra_deg:.4f} deg, "
            f"Dec {sol.dec_deg:.4f} deg, roll {sol.roll_deg:.3f} deg, FOV {sol.fov_deg:.3f} deg",
            f"  {sol.n_matched} of {sol.n_detections} stars matched, residual "
            f"{sol.rmse_arcsec:.1f} arcsec rms, false-match probability "
            f"{sol.false_match_probability:.1e}",
        ]
        if wcs is not None:
            payload["wcs"] = str(sol.write_wcs(wcs))
            lines.append(f"  WCS written: {wcs}")
        emit(payload, as_json, lines)
        return
    if sol.status == "no_stars":
        raise InputError(f"{image}: {sol.message}")
    emit(payload, as_json, [f"{image}: not solved ({sol.status}): {sol.message}"])
    raise typer.Exit(1)


@app.command("montecarlo")
def montecarlo(
    sensor: SensorOpt = "st16",
    trials: Annotated[int, typer.Option("--trials", help="Random attitudes to solve.")] = 100,
    rate_deg_s: Annotated[
        float, typer.Option("--rate-deg-s", help="Cross-axis body rate of every trial, deg/s.")
    ] = 0.0,
    model: ModelOpt = "reed",
    max_mag: Annotated[
        float | None, typer.Option("--max-mag", help="Render only stars brighter than this.")
    ] = None,
    seed: SeedOpt = 0,
    as_json: JsonOpt = False,
) -> None:
    """Random attitudes through render -> detect -> identify -> estimate: solve and wrong rates,
    attitude error per axis against the predicted covariance, time per frame."""
    from rich.progress import Progress

    from starsense.analysis.montecarlo import run_montecarlo
    from starsense.catalog import load_catalog

    cat = load_catalog("hipparcos")
    with Progress(transient=True, disable=not sys.stderr.isatty()) as bar:
        task = bar.add_task("Monte Carlo", total=trials)
        res = run_montecarlo(
            sensor, trials, rate_deg_s=rate_deg_s, model=model, catalog=cat, max_mag=max_mag,
            seed=seed, progress=lambda done, total: bar.update(task, completed=done),
        )  # fmt: skip
    err, pred = res.rms_error_arcsec, res.rms_predicted_arcsec
    emit(
        res.to_dict(),
        as_json,
        [
            f"{res.sensor}, {trials} random attitudes at {rate_deg_s:g} deg/s ({model} model): "
            f"solved {res.solve_rate:.1%}, wrong {res.wrong_rate:.1%} ({res.statuses})",
            f"  rms error x / y / roll: {err[0]:.2f} / {err[1]:.2f} / {err[2]:.2f} arcsec; "
            f"predicted {pred[0]:.2f} / {pred[1]:.2f} / {pred[2]:.2f}",
            f"  time per frame: render {res.time_ms['render']:.0f} ms, "
            f"solve {res.time_ms['solve']:.0f} ms",
        ],
    )


@app.command("report")
def report(
    out: Annotated[Path, typer.Option("--out", help="Output directory.")] = Path("report"),
    catalog: CatalogOpt = "hipparcos",
    diameter_m: DiameterOpt = 0.1,
    exposure_s: ExposureOpt = 0.01,
    sensors: Annotated[
        Path | None,
        typer.Option("--sensors", help="CSV of real sensors to plot against the limit (Fig. 8)."),
    ] = None,
    seed: Annotated[int, typer.Option("--seed", help="Root seed of the Monte Carlo parts.")] = 0,
    sensor: SensorOpt = "st16",
    slew_trials: Annotated[
        int, typer.Option("--slew-trials", help="Monte Carlo trials per slew point.")
    ] = 20,
) -> None:
    """Write the performance report (HTML + PNG figures) to --out."""
    from rich.console import Console

    from starsense.report import build_report
    from starsense.sensor import load_sensor

    sens = load_sensor(sensor)

    console = Console(stderr=True)
    with console.status("building report") as status:
        index = build_report(
            out,
            catalog_spec=catalog,
            diameter_m=diameter_m,
            exposure_s=exposure_s,
            sensors_table=sensors,
            progress=lambda msg: status.update(msg),
            seed=seed,
            sensor=sens,
            slew_trials=slew_trials,
        )
    typer.echo(f"report written: {index}")


def main(argv: list[str] | None = None) -> int:
    """Entry point: run the app, turning user errors into one line and exit status 2.

    Usage errors (unknown option, bad type) are reported by typer itself, also with status 2.
    """
    try:
        app(args=argv, prog_name="starsense")  # standalone mode: ends with SystemExit
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except StarsenseError as exc:
        typer.echo(f"error: {exc}", err=True)
        return 2
    except FileNotFoundError as exc:
        typer.echo(f"error: file not found: {exc.filename}", err=True)
        return 2
    return 0


def _console_main() -> None:  # pragma: no cover - thin wrapper for the console script
    sys.exit(main())


if __name__ == "__main__":  # pragma: no cover
    _console_main()
