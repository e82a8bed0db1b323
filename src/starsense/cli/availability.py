"""``starsense availability static|dynamic|track|fidelity``: star-tracker availability.

Dzamba & Enright 2014: spatial static (sec. 1.2, Figs. 4-6), spatial dynamic (sec. 3.1,
Fig. 11) and along-track dynamic availability (sec. 4, Table 2, Figs. 16-17), and a check of
the threshold model against rendered, detected frames. Thin: parse, build the analysis, print
or write. User errors are :class:`~starsense.errors.InputError`; the main app prints them as one
line and exits 2.
"""

from __future__ import annotations

import contextlib
import json
import math
import re
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from starsense._validate import finite_float
from starsense.cli.catalog import check_dask_option
from starsense.cli.common import (
    CatalogOpt,
    DaskOpt,
    JsonOpt,
    ScaleCatalogOpt,
    SeedOpt,
    SensorOpt,
    emit,
    output_dir,
    output_file,
    parse_floats,
    progress_bar,
    step_grid,
)
from starsense.errors import InputError
from starsense.units import DEG

availability_app = typer.Typer(
    help="Star-tracker availability: spatial static, spatial dynamic and along-track "
    "(Dzamba & Enright 2014).",
    no_args_is_help=True,
)

# -- the options every command shares ---------------------------------------------------------

FovOpt = Annotated[
    str,
    typer.Option(
        "--fov",
        help="circular: a cone of the detector's minor half-axis (or --half-fov-deg); "
        "rectangular: the detector's real field, with roll.",
    ),
]
HalfFovOpt = Annotated[
    float | None,
    typer.Option(
        "--half-fov-deg",
        help="Half-angle of the circular field, deg (the ST-16 paper: 7.5; default: the "
        "sensor's minor half-axis).",
    ),
]
MaxMagOpt = Annotated[
    float,
    typer.Option(
        "--max-mag", help="Catalogue cut and static detection threshold m_t, V magnitude."
    ),
]
NMinOpt = Annotated[
    int,
    typer.Option("--n-min", help="Stars needed: 2 tracking, 3 lost-in-space, 4 conservative."),
]
NOrientOpt = Annotated[
    int, typer.Option("--n-orientations", help="Quasi-uniform boresights over the sky.")
]
RollOpt = Annotated[
    float | None,
    typer.Option(
        "--roll-deg",
        help="Roll of every spatial attitude, deg (rectangular field; default: uniform "
        "random from --seed).",
    ),
]
PlotOpt = Annotated[
    Path | None, typer.Option("--plot", help="Write the curve (PNG) here.", callback=output_file)
]
MapsOpt = Annotated[
    Path | None, typer.Option("--maps", help="Mollweide sky maps (PNG) here.", callback=output_dir)
]
ModelOpt = Annotated[str, typer.Option("--model", help="Sensitivity model: reed or liebe.")]
TrialsOpt = Annotated[
    int, typer.Option("--trials", help="Slew Monte Carlo trials per (magnitude, rate).")
]
ToleranceOpt = Annotated[
    Path | None,
    typer.Option(
        "--tolerance-json",
        help="Use a tolerable-slew curve saved by `starsense slew tolerance --json` instead of "
        "running the slew Monte Carlo.",
    ),
]

DEFAULT_DYNAMIC_RATES = "0,0.25,0.5,0.75,1,1.25,1.5,1.75,2,2.25,2.5,2.75,3,3.5,4,4.5,5"


# -- the options, checked at the edge (messages name the option) -------------------------------


def _check_n_min(n_min: int) -> int:
    if n_min < 1:
        raise InputError(
            f"N_min (--n-min) = {n_min} is out of range; must be an integer >= 1 "
            "(2 tracking, 3 lost-in-space, 4 conservative)"
        )
    return n_min


def _check_count(n: int, label: str, option: str) -> int:
    if n < 1:
        raise InputError(f"{label} ({option}) = {n} is out of range; must be an integer >= 1")
    return n


def _check_rates_deg_s(values: list[float], option: str) -> np.ndarray:
    """Slew rates given in deg/s, finite and >= 0, converted to rad/s."""
    rates = np.asarray(values, dtype=np.float64)
    if not np.all(np.isfinite(rates)):
        raise InputError(f"slew rates ({option}) must be finite, got {rates.tolist()}")
    if np.any(rates < 0):
        bad = float(rates[rates < 0][0])
        raise InputError(
            f"slew rate ({option}) = {bad:g} deg/s is negative; rates are magnitudes |w| >= 0"
        )
    return rates * DEG


def _check_max_mag(max_mag: float) -> float:
    if math.isnan(max_mag) or max_mag == -math.inf:
        raise InputError(f"magnitude limit (--max-mag) must be finite, got {max_mag!r}")
    return max_mag


def _field_of_view(sens, fov: str, half_fov_deg: float | None):
    """Return the field of --fov / --half-fov-deg (deg, converted to rad)."""
    from starsense.analysis.availability import field_of_view

    if fov == "rectangular" and half_fov_deg is not None:
        raise InputError(
            "--half-fov-deg sets the circular field only; the rectangular field is the "
            "detector's (drop --half-fov-deg or use --fov circular)"
        )
    if fov not in ("circular", "rectangular"):
        raise InputError(f"field of view (--fov) must be 'circular' or 'rectangular', got {fov!r}")
    if half_fov_deg is None:
        return field_of_view(sens, fov)
    a = finite_float(half_fov_deg, "--half-fov-deg")
    if not 0.0 < a <= 90.0:
        raise InputError(
            f"half field (--half-fov-deg) = {a:g} deg is out of range; allowed (0, 90]"
        )
    return field_of_view(sens, fov, a * DEG)


def _roll(roll_deg: float | None) -> float | None:
    return None if roll_deg is None else finite_float(roll_deg, "--roll-deg") * DEG


#: parameter names of the library -> the options that set them, for messages that depend on the
#: data (a magnitude cut that leaves no star of the catalogue)
_OPTIONS = {"max_mag": "--max-mag"}


@contextlib.contextmanager
def _as_options() -> Iterator[None]:
    """Re-raise the library's user errors with its parameter names replaced by option names."""
    try:
        yield
    except InputError as exc:
        text = str(exc)
        for name, option in _OPTIONS.items():
            text = re.sub(rf"(?<![.\w]){name}\b", option, text)
        raise InputError(text) from None


def _setup(
    sensor: str,
    catalog: str,
    fov: str,
    half_fov_deg: float | None,
    max_mag: float,
    n_orientations: int,
    roll_deg: float | None,
    seed: int,
    progress: Callable[[str, int, int], None] | None = None,
    band: str = "V",
):
    """Return (sensor, catalogue, analysis) of the options every command shares."""
    from starsense.analysis.availability import AvailabilityAnalysis
    from starsense.catalog import load_catalog
    from starsense.sensor import load_sensor

    _check_max_mag(max_mag)
    _check_count(n_orientations, "number of orientations", "--n-orientations")
    roll = _roll(roll_deg)
    sens = load_sensor(sensor)
    field = _field_of_view(sens, fov, half_fov_deg)
    cat = load_catalog(catalog)
    with _as_options():
        analysis = AvailabilityAnalysis.from_catalog(
            cat,
            field,
            max_mag,
            band=band,
            n_orientations=n_orientations,
            roll_rad=roll,
            rng=seed,
            progress=progress,
        )
    return sens, cat, analysis


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
    from starsense.cli.catalog import hats_session
    from starsense.scale import static_availability
    from starsense.sensor import load_sensor

    _check_max_mag(max_mag)
    _check_count(n_orientations, "number of orientations", "--n-orientations")
    roll = _roll(roll_deg)
    sens = load_sensor(sensor)
    field = _field_of_view(sens, fov, half_fov_deg)
    with hats_session(catalog, dask, not as_json) as (cat, client, progress), _as_options():
        res = static_availability(
            cat,
            field,
            max_mag,
            n_min,
            band=band,
            n_orientations=n_orientations,
            roll=roll,
            seed=seed,
            client=client,
            progress=progress,
        )
    return res, sens


def _threshold_curve(
    sens,
    model: str,
    trials: int,
    seed: int,
    tolerance_json: Path | None,
    progress: Callable[[str, int, int], None] | None,
):
    """m_t(w) from a saved tolerance JSON, or from the slew Monte Carlo."""
    from starsense.analysis.availability import ThresholdCurve

    if tolerance_json is not None:
        try:
            data = json.loads(Path(tolerance_json).read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise InputError(f"--tolerance-json: file not found: {tolerance_json}") from None
        except (OSError, ValueError) as exc:
            raise InputError(f"--tolerance-json {tolerance_json}: not valid JSON ({exc})") from None
        if not isinstance(data, dict):
            raise InputError(f"--tolerance-json {tolerance_json}: expected a JSON object")
        return ThresholdCurve.from_tolerance_dict(data, f"--tolerance-json {tolerance_json}")
    if model not in ("reed", "liebe"):
        raise InputError(f"--model must be 'reed' or 'liebe', got {model!r}")
    if isinstance(trials, bool) or trials < 1:
        raise InputError(f"--trials = {trials} is out of range; must be an integer >= 1")
    from starsense.analysis.slew import simulate_slew

    result = simulate_slew(
        sens,
        model=model,
        n_trials=trials,
        rng=seed,
        progress=None
        if progress is None
        else (lambda done, total: progress(f"slew Monte Carlo ({model})", done, total)),
    )
    return ThresholdCurve.from_slew(result)


def _maps_dir(maps: Path) -> Path:
    maps = Path(maps)  # checked by its option's callback (output_dir)
    maps.mkdir(parents=True, exist_ok=True)
    return maps


# -- commands ---------------------------------------------------------------------------------


@availability_app.command("static")
def static(
    sensor: SensorOpt = "st16",
    catalog: ScaleCatalogOpt = "hipparcos",
    fov: FovOpt = "circular",
    half_fov_deg: HalfFovOpt = None,
    max_mag: MaxMagOpt = 5.75,
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
    _check_n_min(n_min)
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
            sens, _, analysis = _setup(
                sensor,
                catalog,
                fov,
                half_fov_deg,
                max_mag,
                n_orientations,
                roll_deg,
                seed,
                progress,
                band or "V",
            )
            res = analysis.static(n_min)
    payload = {**res.to_dict(), "sensor": sens.name}
    lines = [f"{sens.name}: " + res.lines()[0], *res.lines()[1:]]
    figures = []
    if plot is not None:
        from starsense.plotting.availability import save_figure, static_curve_figure

        figures.append(save_figure(static_curve_figure(res), plot))
    if maps is not None:
        from starsense.plotting.availability import save_figure, sky_map_figure

        folder = _maps_dir(maps)
        figures.append(
            save_figure(
                sky_map_figure(
                    res.boresights,
                    res.counts,
                    f"{sens.name}: stars in the field, m_t = {res.max_mag:g} ({res.fov})",
                ),
                folder / "static_stars_in_field.png",
            )
        )
        figures.append(
            save_figure(
                sky_map_figure(
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
    max_mag: MaxMagOpt = 5.75,
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
    rates = _check_rates_deg_s(parse_floats(rates_deg_s, "--rates-deg-s"), "--rates-deg-s")
    _check_n_min(n_min)
    with progress_bar() as progress:
        sens, _, analysis = _setup(
            sensor, catalog, fov, half_fov_deg, max_mag, n_orientations, roll_deg, seed, progress
        )
        curve = _threshold_curve(sens, model, trials, seed, tolerance_json, progress)
        res = analysis.dynamic(curve, rates, n_min)
    payload = {**res.to_dict(), "sensor": sens.name, "model": model}
    lines = res.lines()
    figures = []
    if plot is not None:
        from starsense.plotting.availability import dynamic_figure, save_figure

        figures.append(save_figure(dynamic_figure([res]), plot))
    if maps is not None:
        from starsense.plotting.availability import save_figure, sky_map_figure

        folder = _maps_dir(maps)
        for w, m in zip(res.rates_deg_s, res.threshold_mag, strict=True):
            mt = f"{m:.2f}" if np.isfinite(m) else "none"
            figures.append(
                save_figure(
                    sky_map_figure(
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
    max_mag: MaxMagOpt = 5.75,
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
    rate = float(_check_rates_deg_s([rate_deg_s], "--rate-deg-s")[0])
    _check_n_min(n_min)
    _check_count(track_samples, "samples per track", "--track-samples")
    node = finite_float(node_deg, "--node-deg") * DEG
    # from a count (0.01 deg: 18,001 tracks ending at 90); finer than 0.001 deg is refused
    inclinations = DEG * step_grid(-90, 90, inclination_step_deg, "--inclination-step-deg", 1e-3)
    with progress_bar() as progress:
        sens, _, analysis = _setup(
            sensor, catalog, fov, half_fov_deg, max_mag, n_orientations, roll_deg, seed, progress
        )
        curve = _threshold_curve(sens, model, trials, seed, tolerance_json, progress)
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
        from starsense.plotting.availability import save_figure, track_nmin_figure

        figures.append(save_figure(track_nmin_figure(res), plot))
    if maps is not None:
        from starsense.geometry.sampling import great_circle_track
        from starsense.plotting.availability import save_figure, sky_map_figure

        folder = _maps_dir(maps)
        shown = (-60.0, -30.0, 0.0, 30.0, 60.0, 90.0)
        paths = [great_circle_track(i * DEG, 721, node)[0] for i in shown]
        figures.append(
            save_figure(
                sky_map_figure(
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
    max_mag: MaxMagOpt = 5.75,
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
    from starsense.analysis.availability import fidelity_check
    from starsense.catalog import load_catalog
    from starsense.sensor import load_sensor

    rate = float(_check_rates_deg_s([rate_deg_s], "--rate-deg-s")[0])
    _check_n_min(n_min)
    _check_count(frames, "number of frames", "--frames")
    _check_max_mag(max_mag)
    sens = load_sensor(sensor)
    cat = load_catalog(catalog)
    with progress_bar() as progress:
        curve = _threshold_curve(sens, model, trials, seed, tolerance_json, progress)
        with _as_options():
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
