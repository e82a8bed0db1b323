"""``starsense availability static|dynamic|track|fidelity``: star-tracker availability.

Dzamba & Enright 2014: spatial static (sec. 1.2, Figs. 4-6), spatial dynamic (sec. 3.1,
Fig. 11) and along-track dynamic availability (sec. 4, Table 2, Figs. 16-17), and a check of
the threshold model against rendered, detected frames. Thin: parse, build the analysis, print
or write. User errors are :class:`~starsense.errors.InputError`; the main app prints them as one
line and exits 2.
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
import typer

from starsense import plotting
from starsense._validate import finite_float
from starsense.analysis.availability import (
    fidelity_check,
)
from starsense.analysis.availability.pointings import MAX_ORIENTATIONS, ORIENTATION_COST
from starsense.analysis.inputs import FRAME_COST, MAX_FRAMES
from starsense.catalog import load_catalog
from starsense.cli.availability_options import (
    DEFAULT_DYNAMIC_RATES,
    FovOpt,
    HalfFovOpt,
    MapsOpt,
    MaxMagOpt,
    ModelOpt,
    NMinOpt,
    NOrientOpt,
    PlotOpt,
    RollOpt,
    ToleranceOpt,
    TrialsOpt,
    as_options,
    check_count,
    check_maps,
    check_max_mag,
    check_n_min,
    check_rates_deg_s,
    check_slew_trials,
    field_of_view_option,
    maps_dir,
    roll_option,
    sensor_threshold,
    setup_analysis,
)
from starsense.cli.catalog import check_dask_option, hats_session
from starsense.cli.common import (
    CatalogOpt,
    DaskOpt,
    JsonOpt,
    ScaleCatalogOpt,
    SeedOpt,
    SensorOpt,
    emit,
    parse_floats,
    progress_bar,
    step_grid,
)
from starsense.errors import InputError
from starsense.geometry.sampling import great_circle_track
from starsense.scale import static_availability
from starsense.sensor import load_sensor
from starsense.units import DEG

availability_app = typer.Typer(
    help="Star-tracker availability: spatial static, spatial dynamic and along-track "
    "(Dzamba & Enright 2014).",
    no_args_is_help=True,
)


def _static_hats(
    sensor,
    catalog,
    dask,
    fov,
    half_fov_deg,
    max_mag,
    n_min,
    n_orientations,
    roll_deg,
    seed,
    band,
    as_json,
):
    """``availability static`` over a HATS catalogue on Dask (starsense.scale)."""
    check_max_mag(max_mag)
    check_count(
        n_orientations,
        "number of orientations",
        "--n-orientations",
        MAX_ORIENTATIONS,
        ORIENTATION_COST,
    )
    roll = roll_option(roll_deg)
    sens = load_sensor(sensor)
    field = field_of_view_option(sens, fov, half_fov_deg)
    if max_mag is None:  # the sensor's own threshold at rest (V; a hats: catalogue's --band)
        max_mag = sensor_threshold(sens, seed=seed)[1]
    with hats_session(catalog, dask, not as_json) as (cat, client, progress), as_options():
        res = static_availability(
            cat,
            field,
            max_mag=max_mag,
            n_min=n_min,
            band=band,
            n_orientations=n_orientations,
            roll_rad=roll,
            rng=seed,
            client=client,
            progress=progress,
        )
    return res, sens


# -- commands ---------------------------------------------------------------------------------


def _curve_and_analysis(sensor, catalog, *, threshold, grid, max_mag, roll_deg, seed, progress):
    """Return the sensor's m_t(w), the sensor and the analysis of the shared options.

    ``threshold`` holds :func:`sensor_threshold`'s options, ``grid`` the field options of
    :func:`setup_analysis`; ``max_mag`` None is the sensor's own static threshold.
    """
    check_slew_trials(threshold["n_trials"])
    curve, rest_mag = sensor_threshold(
        load_sensor(sensor), seed=seed, progress=progress, **threshold
    )
    sens, _, analysis = setup_analysis(
        sensor,
        catalog,
        max_mag=rest_mag if max_mag is None else max_mag,
        roll_deg=roll_deg,
        seed=seed,
        progress=progress,
        **grid,
    )
    return curve, sens, analysis


@availability_app.command("static")
def static(
    sensor: SensorOpt = "st16",
    catalog: ScaleCatalogOpt = "hipparcos",
    fov: FovOpt = "circular",
    half_fov_deg: HalfFovOpt = None,
    max_mag: MaxMagOpt = None,
    n_min: NMinOpt = 3,
    n_orientations: NOrientOpt = 10_000,
    roll_deg: RollOpt = None,
    seed: SeedOpt = 0,
    band: Annotated[
        str | None,
        typer.Option(
            "--band",
            help="Magnitude band of --max-mag (default V; for a hats: catalogue the first of "
            "V, Hp, VT, G, J, H, Ks it has).",
        ),
    ] = None,
    dask: DaskOpt = None,
    plot: PlotOpt = None,
    maps: MapsOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Spatial static availability: fraction of boresights with >= N_min stars <= m_t.

    With --catalog hats:PATH_OR_URL the stars in the field are counted partition by partition on
    Dask (--dask), with the same kernels and results as in memory.
    """
    check_n_min(n_min)
    check_maps(maps, ["static_stars_in_field.png", "static_sparse.png"])
    if check_dask_option(catalog, dask):
        res, sens = _static_hats(
            sensor,
            catalog,
            dask,
            fov,
            half_fov_deg,
            max_mag,
            n_min,
            n_orientations,
            roll_deg,
            seed,
            band,
            as_json,
        )
    else:
        with progress_bar() as progress:
            sens, _, analysis = setup_analysis(
                sensor,
                catalog,
                fov=fov,
                half_fov_deg=half_fov_deg,
                max_mag=max_mag,
                n_orientations=n_orientations,
                roll_deg=roll_deg,
                seed=seed,
                progress=progress,
                band=band or "V",
            )
            res = analysis.static(n_min)
    payload = {**res.to_dict(), "sensor": sens.name}
    lines = [f"{sens.name}: " + res.lines()[0], *res.lines()[1:]]
    figures = []
    if plot is not None:
        figures.append(
            plotting.availability.save_figure(plotting.availability.static_curve_figure(res), plot)
        )
    if maps is not None:
        folder = maps_dir(maps)
        figures.append(
            plotting.availability.save_figure(
                plotting.availability.sky_map_figure(
                    res.boresights,
                    res.counts,
                    f"{sens.name}: stars in the field, m_t = {res.max_mag:g} ({res.fov})",
                ),
                folder / "static_stars_in_field.png",
            )
        )
        figures.append(
            plotting.availability.save_figure(
                plotting.availability.sky_map_figure(
                    res.boresights,
                    res.counts,
                    f"{sens.name}: star-sparse regions, m_t = {res.max_mag:g}",
                    sparse=True,
                    n_min=res.n_min,
                ),
                folder / "static_sparse.png",
            )
        )
    if figures:
        payload["figures"] = [str(f) for f in figures]
        lines += [f"figure: {f}" for f in figures]
    emit(payload, as_json, lines)


@availability_app.command("dynamic")
def dynamic(
    sensor: SensorOpt = "st16",
    catalog: CatalogOpt = "hipparcos",
    fov: FovOpt = "circular",
    half_fov_deg: HalfFovOpt = None,
    max_mag: MaxMagOpt = None,
    n_min: NMinOpt = 3,
    n_orientations: NOrientOpt = 10_000,
    roll_deg: RollOpt = None,
    seed: SeedOpt = 0,
    model: ModelOpt = "reed",
    rates_deg_s: Annotated[
        str, typer.Option("--rates-deg-s", help="Comma-separated slew rates, deg/s.")
    ] = DEFAULT_DYNAMIC_RATES,
    trials: TrialsOpt = 20,
    tolerance_json: ToleranceOpt = None,
    plot: PlotOpt = None,
    maps: MapsOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Spatial dynamic availability against slew rate, m_t = m_t(w) (Fig. 11)."""
    rates = check_rates_deg_s(parse_floats(rates_deg_s, "--rates-deg-s"), "--rates-deg-s")
    check_n_min(n_min)
    check_max_mag(max_mag)
    check_maps(maps, [f"dynamic_{w:g}degs.png" for w in rates / DEG])
    with progress_bar() as progress:
        curve, sens, analysis = _curve_and_analysis(
            sensor,
            catalog,
            threshold={"model": model, "n_trials": trials, "tolerance_json": tolerance_json},
            grid={"fov": fov, "half_fov_deg": half_fov_deg, "n_orientations": n_orientations},
            max_mag=max_mag,
            roll_deg=roll_deg,
            seed=seed,
            progress=progress,
        )
        res = analysis.dynamic(curve, rates, n_min)
    payload = {**res.to_dict(), "sensor": sens.name, "model": model}
    lines = res.lines()
    figures = []
    if plot is not None:
        figures.append(
            plotting.availability.save_figure(plotting.availability.dynamic_figure([res]), plot)
        )
    if maps is not None:
        folder = maps_dir(maps)
        for w, m in zip(res.rates_deg_s, res.threshold_mag, strict=True):
            mt = f"{m:.2f}" if np.isfinite(m) else "none"
            figures.append(
                plotting.availability.save_figure(
                    plotting.availability.sky_map_figure(
                        analysis.boresights,
                        analysis.sky_counts(m),
                        f"{sens.name}: stars detectable at {w:g} deg/s ({curve.label}, m_t = {mt})",
                        sparse=True,
                        n_min=n_min,
                    ),
                    folder / f"dynamic_{w:g}degs.png",
                )
            )
    if figures:
        payload["figures"] = [str(f) for f in figures]
        lines += [f"figure: {f}" for f in figures]
    emit(payload, as_json, lines)


@availability_app.command("track")
def track(
    sensor: SensorOpt = "st16",
    catalog: CatalogOpt = "hipparcos",
    fov: FovOpt = "circular",
    half_fov_deg: HalfFovOpt = None,
    max_mag: MaxMagOpt = None,
    n_min: NMinOpt = 3,
    n_orientations: NOrientOpt = 10_000,
    roll_deg: RollOpt = None,
    seed: SeedOpt = 0,
    model: ModelOpt = "reed",
    rate_deg_s: Annotated[
        float, typer.Option("--rate-deg-s", help="Constant slew rate along the tracks, deg/s.")
    ] = 1.0,
    inclination_step_deg: Annotated[
        float,
        typer.Option("--inclination-step-deg", help="Step of the inclinations -90 ... 90 deg."),
    ] = 1.0,
    track_samples: Annotated[
        int, typer.Option("--track-samples", help="Orientations per track (paper: 1000).")
    ] = 1000,
    node_deg: Annotated[
        float, typer.Option("--node-deg", help="RA of the tracks' common node, deg.")
    ] = 0.0,
    trials: TrialsOpt = 20,
    tolerance_json: ToleranceOpt = None,
    plot: PlotOpt = None,
    maps: MapsOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Along-track dynamic availability of great circles inclined -90 ... 90 deg (Table 2)."""
    rate = float(check_rates_deg_s([rate_deg_s], "--rate-deg-s")[0])
    check_n_min(n_min)
    check_maps(maps, [f"track_{rate / DEG:g}degs.png"])
    check_count(
        track_samples, "samples per track", "--track-samples", MAX_ORIENTATIONS, ORIENTATION_COST
    )
    node = finite_float(node_deg, "--node-deg") * DEG
    # from a count (0.01 deg: 18,001 tracks ending at 90); finer than 0.001 deg is refused
    inclinations = DEG * step_grid(-90, 90, inclination_step_deg, "--inclination-step-deg", 1e-3)
    if track_samples * inclinations.size > MAX_ORIENTATIONS:
        raise InputError(
            f"--track-samples = {track_samples:,} on {inclinations.size:,} tracks is "
            f"{track_samples * inclinations.size:,} orientations, above the cap of "
            f"{MAX_ORIENTATIONS:,} ({ORIENTATION_COST}); lower --track-samples or raise "
            "--inclination-step-deg"
        )
    check_max_mag(max_mag)
    with progress_bar() as progress:
        curve, sens, analysis = _curve_and_analysis(
            sensor,
            catalog,
            threshold={"model": model, "n_trials": trials, "tolerance_json": tolerance_json},
            grid={"fov": fov, "half_fov_deg": half_fov_deg, "n_orientations": n_orientations},
            max_mag=max_mag,
            roll_deg=roll_deg,
            seed=seed,
            progress=progress,
        )
        res = analysis.track(
            curve,
            rate,
            n_min=n_min,
            inclinations=inclinations,
            n_samples=track_samples,
            node_rad=node,
        )
    payload = {**res.to_dict(), "sensor": sens.name, "model": model}
    lines = res.lines()
    figures = []
    if plot is not None:
        figures.append(
            plotting.availability.save_figure(plotting.availability.track_nmin_figure(res), plot)
        )
    if maps is not None:
        folder = maps_dir(maps)
        shown = (-60.0, -30.0, 0.0, 30.0, 60.0, 90.0)
        paths = [great_circle_track(i * DEG, 721, node)[0] for i in shown]
        figures.append(
            plotting.availability.save_figure(
                plotting.availability.sky_map_figure(
                    analysis.boresights,
                    analysis.sky_counts(res.threshold_mag),
                    f"{sens.name}: stars detectable at {res.rate_deg_s:g} deg/s; tracks i = "
                    + ", ".join(f"{i:g}" for i in shown)
                    + " deg",
                    sparse=True,
                    n_min=n_min,
                    tracks=paths,
                ),
                folder / f"track_{res.rate_deg_s:g}degs.png",
            )
        )
    if figures:
        payload["figures"] = [str(f) for f in figures]
        lines += [f"figure: {f}" for f in figures]
    emit(payload, as_json, lines)


@availability_app.command("fidelity")
def fidelity(
    sensor: SensorOpt = "st16",
    catalog: CatalogOpt = "hipparcos",
    max_mag: MaxMagOpt = None,
    n_min: NMinOpt = 3,
    seed: SeedOpt = 0,
    model: ModelOpt = "reed",
    rate_deg_s: Annotated[
        float, typer.Option("--rate-deg-s", help="Cross-axis slew rate of the frames, deg/s.")
    ] = 1.0,
    frames: Annotated[int, typer.Option("--frames", help="Frames to render.")] = 50,
    trials: TrialsOpt = 20,
    tolerance_json: ToleranceOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Rendered frames through the detector against the threshold model (real detector field)."""  # noqa: D401
    rate = float(check_rates_deg_s([rate_deg_s], "--rate-deg-s")[0])
    check_n_min(n_min)
    check_count(frames, "number of frames", "--frames", MAX_FRAMES, FRAME_COST)
    check_slew_trials(trials)
    check_max_mag(max_mag)
    sens = load_sensor(sensor)
    cat = load_catalog(catalog)
    with progress_bar() as progress:
        curve, rest_mag = sensor_threshold(
            sens,
            model=model,
            n_trials=trials,
            seed=seed,
            tolerance_json=tolerance_json,
            progress=progress,
        )
        max_mag = rest_mag if max_mag is None else max_mag
        with as_options():
            res = fidelity_check(
                sens,
                cat,
                curve,
                rate_rad_s=rate,
                n_trials=frames,
                n_min=n_min,
                max_mag=max_mag,
                model=model,
                rng=seed,
                progress=lambda done, total: progress("rendering frames", done, total),
            )
    emit({**res.to_dict(), "sensor": sens.name}, as_json, res.lines())
