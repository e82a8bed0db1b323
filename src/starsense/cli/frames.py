"""`starsense render` and `montecarlo`: frames rendered (`solve` is in cli/solve.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from starsense._io import check_output
from starsense._validate import check_count
from starsense.analysis.inputs import FRAME_COST, MAX_FRAMES
from starsense.analysis.montecarlo import run_montecarlo
from starsense.catalog import load_catalog
from starsense.cli.common import (
    BRIGHTEST_MAG,
    CatalogOpt,
    JsonOpt,
    ModelOpt,
    SeedOpt,
    SensorOpt,
    emit,
    option_float,
    option_int,
    output_file,
    parse_floats,
    progress_bar,
)
from starsense.errors import InputError
from starsense.geometry.apparent import parse_time
from starsense.geometry.attitude import attitude_from_radec_roll
from starsense.render import scene
from starsense.render.areas import render_areas
from starsense.render.io import FORMATS, write_frame, write_frames
from starsense.render.sequence import render_sequence, sequence_paths
from starsense.sensor import load_sensor
from starsense.units import DEG


def render(
    out: Annotated[
        Path,
        typer.Option("--out", help="Frame to write (.tiff, .png, .fits).", callback=output_file),
    ],
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
    time: Annotated[
        str | None,
        typer.Option("--time", help="UTC time (ISO 8601): stars at their apparent places."),
    ] = None,
    areas: Annotated[
        bool,
        typer.Option(
            "--areas",
            help="Render the sensor's attitude-determination areas (its focal plane, bias "
            "level outside the areas) instead of its detector.",
        ),
    ] = False,
    sequence: Annotated[
        int | None,
        typer.Option(
            "--sequence",
            help="Render N frames, the attitude carried on by the rate: --out DIR/frame.tiff "
            "writes DIR/frame_000.tiff ... (each with its truth JSON).",
        ),
    ] = None,
    interval_s: Annotated[
        float | None,
        typer.Option("--interval-s", help="Time between frames of a --sequence, s."),
    ] = None,
) -> None:
    """Render a frame (with its truth as JSON beside it) for an attitude and body rate."""
    if sequence is None:  # the truth beside the frame, before the work (a sequence: its paths)
        check_output(out.with_name(out.name + ".json"), "--out")
    option_float(ra_deg, "--ra-deg", -360.0, 360.0)
    option_float(dec_deg, "--dec-deg", -90.0, 90.0)
    option_float(roll_deg, "--roll-deg", -360.0, 360.0)
    # each component within one turn a second (render.tracks.MAX_RATE_RAD_S bounds the norm)
    rate = np.radians(parse_floats(rate_deg_s, "--rate-deg-s", 3, -360.0, 360.0))
    if max_mag is not None:
        option_float(max_mag, "--max-mag", BRIGHTEST_MAG)
    sens = load_sensor(sensor)
    obs_time = None if time is None else parse_time(time, "--time")
    if obs_time is not None and areas:
        raise InputError("--time is not available with --areas")
    att = attitude_from_radec_roll(np.radians(ra_deg), np.radians(dec_deg), np.radians(roll_deg))
    if sequence is not None or interval_s is not None:
        if areas:
            raise InputError("--sequence renders detector frames: it does not take --areas")
        _render_sequence(
            out,
            sens,
            att,
            rate,
            sequence,
            interval_s,
            seed,
            model=model,
            catalog=load_catalog(catalog),
            max_mag=max_mag,
            noise=not no_noise,
            obs_time=obs_time,
        )
        return
    kwargs = {
        "rate_rad_s": rate,
        "model": model,
        "max_mag": max_mag,
        "rng": seed,
        "noise": not no_noise,
    }
    if obs_time is not None:
        kwargs["obs_time"] = obs_time
    if areas:
        frame, note = _render_areas(sens, att, load_catalog(catalog), kwargs)
    else:
        frame = scene.render_frame(sens, att, load_catalog(catalog), **kwargs)
        note = ""
    written = write_frame(out, frame)
    n = len(frame.truth.stars)
    typer.echo(f"frame written: {written} ({n} stars{note}; truth in {written}.json)")


def _render_areas(sens, att, catalog, kwargs: dict) -> tuple:
    """``render --areas``: return the focal-plane frame and a note of the stars in each area."""
    area_frame = render_areas(sens, att, catalog, **kwargs)
    per_area = np.bincount(area_frame.star_area, minlength=len(sens.attitude_areas.areas) + 1)
    names = sens.attitude_areas.names
    where = ", ".join(f"{a}: {int(k)}" for a, k in zip(names, per_area[1:], strict=True))
    return area_frame.frame, f"; in the areas {where}"


def _render_sequence(out, sens, att, rate, n, interval_s, seed, *, catalog, **kwargs) -> None:
    """``render --sequence N --interval-s DT``: frames DIR/stem_000.ext ..., checked first."""
    if n is None or interval_s is None:
        raise InputError("--sequence and --interval-s go together: give both")
    option_int(n, "--sequence", 1, 10000)
    option_float(interval_s, "--interval-s", 0.0)
    if interval_s <= 0 or interval_s < sens.exposure_s:
        raise InputError(
            f"--interval-s must be at least the exposure ({sens.exposure_s:g} s), got {interval_s}"
        )
    if out.suffix.lower() not in FORMATS:
        raise InputError(f"--out {out}: unknown image extension; use one of {', '.join(FORMATS)}")
    if not (out.parent if str(out.parent) else Path(".")).is_dir():
        raise InputError(f"--out {out}: directory {str(out.parent)!r} not found")
    paths = sequence_paths(out, n)
    frames = render_sequence(
        sens, att, catalog, n_frames=n, interval_s=interval_s, rate_rad_s=rate, seed=seed, **kwargs
    )
    done = []

    def noted(frames):  # what each frame held, for the lines printed once all are in place
        for frame in frames:
            done.append((frame.truth.time_s, len(frame.truth.stars)))
            yield frame

    write_frames(paths, noted(frames))  # the whole sequence, or nothing of it
    for path, (t, n_stars) in zip(paths, done, strict=True):
        typer.echo(f"frame written: {path} (t = {t:g} s, {n_stars} stars; truth in {path}.json)")


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
    """Run random attitudes through render -> detect -> identify -> estimate.

    Prints the solve and wrong rates, the attitude error per axis against the predicted
    covariance, and the time per frame.
    """
    check_count(trials, "--trials", MAX_FRAMES, FRAME_COST)
    option_float(rate_deg_s, "--rate-deg-s", 0.0)
    if max_mag is not None:
        option_float(max_mag, "--max-mag", BRIGHTEST_MAG)
    cat = load_catalog("hipparcos")
    with progress_bar(not as_json) as bar:
        res = run_montecarlo(
            sensor,
            cat,
            n_trials=trials,
            rate_rad_s=rate_deg_s * DEG,
            model=model,
            max_mag=max_mag,
            rng=seed,
            progress=bar.task("Monte Carlo", total=trials),
        )
    err, pred = res.rms_error_arcsec, res.rms_predicted_arcsec
    payload = {**res.to_dict(), "rate_deg_s": float(rate_deg_s)}  # the option as given
    emit(
        payload,
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
