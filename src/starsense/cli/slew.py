"""`starsense slew`: slew tolerance of smeared stars (Dzamba & Enright 2014)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from starsense._validate import finite_float
from starsense.cli.common import (
    JsonOpt,
    ModelOpt,
    SeedOpt,
    SensorOpt,
    emit,
    output_file,
    parse_floats,
    progress_bar,
)
from starsense.errors import InputError
from starsense.units import DEG

slew_app = typer.Typer(
    help="Slew tolerance: detection of smeared stars (Dzamba & Enright 2014).",
    no_args_is_help=True,
)


def _rates_rad_s(text: str | None) -> np.ndarray | None:
    """Return the --rates-deg-s grid in rad/s: >= 0 and increasing, or None for the default."""
    values = parse_floats(text, "--rates-deg-s")
    if values is None:
        return None
    rates = np.asarray(values, dtype=float)
    if np.any(rates < 0):
        raise InputError(f"rates must be >= 0 deg/s, got {rates[rates < 0][0]:g}")
    if np.any(np.diff(rates) <= 0):
        raise InputError("rates must be strictly increasing")
    return rates * DEG


def _run_slew(sensor_name, model, magnitudes, rates, trials, criterion, seed, colour_index=0.0):
    from starsense.analysis.slew import simulate_slew
    from starsense.sensor import load_sensor

    finite_float(colour_index, "--b-v")
    sensor = load_sensor(sensor_name)
    mags = parse_floats(magnitudes, "--magnitudes")
    rate_values = _rates_rad_s(rates)
    with progress_bar() as bar:
        result = simulate_slew(
            sensor, model, mags, rate_values, trials, criterion, seed,
            progress=bar.task("slew Monte Carlo"),
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
PlotOpt = Annotated[
    Path | None, typer.Option("--plot", help="Write a PNG figure here.", callback=output_file)
]
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
        from starsense.plotting.figure import save_png
        from starsense.plotting.slew import tolerance_figure

        save_png(tolerance_figure([res]), plot)
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
        from starsense.plotting.figure import save_png
        from starsense.plotting.slew import intensity_figure

        save_png(intensity_figure(res), plot)
        payload["plot"] = str(plot)
        lines.append(f"figure: {plot}")
    emit(payload, as_json, lines)
