"""`starsense render`, `solve` and `montecarlo`: frames rendered, frames solved."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from starsense.cli.common import (
    CatalogOpt,
    JsonOpt,
    ModelOpt,
    SeedOpt,
    SensorOpt,
    emit,
    option_float,
    option_int,
    parse_floats,
    progress_bar,
)
from starsense.errors import InputError
from starsense.units import DEG


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

    option_float(ra_deg, "--ra-deg")
    option_float(dec_deg, "--dec-deg", -90.0, 90.0)
    option_float(roll_deg, "--roll-deg")
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

    Without --sensor or --fov-deg the field is searched over 2.8-70 deg. Exit status 0 when solved,
    1 when the frame does not solve, 2 for bad input (including a frame with no stars).
    """
    from starsense.solve.solver import Solver

    if sensor is not None and fov_deg is not None:
        raise InputError("give --sensor or --fov-deg, not both")
    if fov_deg is not None and not (0.5 <= fov_deg <= 120.0):
        raise InputError(f"--fov-deg must be within [0.5, 120] deg, got {fov_deg}")
    if sensor is None and fov_deg is None and algorithm == "triangle":
        raise InputError("the triangle algorithm needs a known field: give --sensor or --fov-deg")
    fov_rad = None if fov_deg is None else fov_deg * DEG
    sol = Solver(sensor, fov_rad, catalog, algorithm).solve_file(image)
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
    from starsense.analysis.montecarlo import run_montecarlo
    from starsense.catalog import load_catalog

    option_int(trials, "--trials", 1)
    option_float(rate_deg_s, "--rate-deg-s", 0.0)
    cat = load_catalog("hipparcos")
    with progress_bar(not as_json) as bar:
        res = run_montecarlo(
            sensor, trials, rate_rad_s=rate_deg_s * DEG, model=model, catalog=cat,
            max_mag=max_mag, seed=seed, progress=bar.task("Monte Carlo", total=trials),
        )  # fmt: skip
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
