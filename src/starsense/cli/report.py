"""`starsense report`: the HTML performance report."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from starsense._validate import check_count
from starsense.analysis.inputs import FRAME_COST, MAX_FRAMES
from starsense.analysis.slew import MAX_TRIALS_PER_POINT, SLEW_TRIAL_COST
from starsense.cli.common import (
    APERTURE_MAX_M,
    EXPOSURE_MAX_S,
    CatalogOpt,
    SensorOpt,
    option_float,
    output_dir,
    seed_option,
)
from starsense.report import build_report
from starsense.sensor import load_sensor


def report(
    out: Annotated[
        Path, typer.Option("--out", help="Output directory.", callback=output_dir)
    ] = Path("report"),
    catalog: CatalogOpt = "hipparcos",
    diameter_m: Annotated[
        float | None,
        typer.Option("--diameter-m", help="Aperture D of the limit, m (default: the sensor's)."),
    ] = None,
    exposure_s: Annotated[
        float | None,
        typer.Option("--exposure-s", help="Exposure t of the limit, s (default: the sensor's)."),
    ] = None,
    sensors: Annotated[
        Path | None,
        typer.Option("--sensors", help="CSV of real sensors to plot against the limit (Fig. 8)."),
    ] = None,
    seed: Annotated[
        int,
        typer.Option("--seed", help="Root seed of the Monte Carlo parts.", callback=seed_option),
    ] = 0,
    sensor: SensorOpt = "st16",
    slew_trials: Annotated[
        int, typer.Option("--slew-trials", help="Monte Carlo trials per slew point.")
    ] = 20,
    trials: Annotated[
        int, typer.Option("--trials", help="Datasheet check: rendered frames per rate.")
    ] = 40,
    mass_kg: Annotated[
        float | None, typer.Option("--mass-kg", help="The unit's mass, kg, for the summary.")
    ] = None,
    power_w: Annotated[
        float | None, typer.Option("--power-w", help="The unit's power, W, for the summary.")
    ] = None,
) -> None:
    """Write the performance report (HTML + PNG figures) to --out: the sensor's datasheet first."""
    if diameter_m is not None:
        option_float(diameter_m, "--diameter-m", 0.0, APERTURE_MAX_M, lo_open=True)
    if exposure_s is not None:
        option_float(exposure_s, "--exposure-s", 0.0, EXPOSURE_MAX_S, lo_open=True)
    check_count(slew_trials, "--slew-trials", MAX_TRIALS_PER_POINT, SLEW_TRIAL_COST)
    check_count(trials, "--trials", MAX_FRAMES, FRAME_COST)
    for name, value in (("--mass-kg", mass_kg), ("--power-w", power_w)):
        if value is not None:
            option_float(value, name, 0.0, 1e6, lo_open=True)
    sens = load_sensor(sensor)
    # the limit of the sensor given (its aperture and exposure) unless told otherwise
    diameter_m = sens.optics.aperture_m if diameter_m is None else diameter_m
    exposure_s = sens.exposure_s if exposure_s is None else exposure_s

    from rich.console import Console

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
            datasheet_trials=trials,
            mass_kg=mass_kg,
            power_w=power_w,
        )
    typer.echo(f"report written: {index}")
