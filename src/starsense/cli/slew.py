"""`starsense slew`: slew tolerance of smeared stars (Dzamba & Enright 2014)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from starsense import plotting
from starsense._validate import check_count, finite_float
from starsense.analysis.sensor_detection import sensor_grids
from starsense.analysis.slew import (
    MAX_TRIALS_PER_POINT,
    SLEW_TRIAL_COST,
    simulate_slew,
)
from starsense.analysis.slew_study import (
    DEFAULT_QE_MEANS,
    DEFAULT_SIGMAS_PX,
    study_magnitudes,
    study_slew,
)
from starsense.cli.common import (
    JsonOpt,
    ModelOpt,
    SeedOpt,
    SensorOpt,
    colour_clamp_note,
    emit,
    output_file,
    parse_floats,
    progress_bar,
)
from starsense.errors import InputError
from starsense.references.dzamba2014 import MAX_MAG
from starsense.sensor import load_sensor
from starsense.units import DEG, to_edge

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
    finite_float(colour_index, "--b-v")
    clamped = colour_clamp_note("B-V", colour_index, "--b-v")
    if clamped is not None:  # said in words, as `limit star` says it
        typer.echo(f"warning: {clamped}", err=True)
    check_count(trials, "--trials", MAX_TRIALS_PER_POINT, SLEW_TRIAL_COST)
    sensor = load_sensor(sensor_name)
    # the Sun (-26.7) to far beyond any tracker's limit: 1e308 ran and said nothing was seen
    mags = parse_floats(magnitudes, "--magnitudes", lo=-30.0, hi=40.0)
    rate_values = _rates_rad_s(rates)
    if mags is None or rate_values is None:  # the sensor's own grids, as its datasheet uses
        own_mags, own_rates = sensor_grids(
            sensor, model=model, n_trials=trials, rng=seed, colour_index=colour_index
        )
        mags = own_mags if mags is None else mags
        rate_values = own_rates if rate_values is None else rate_values
    with progress_bar() as bar:
        result = simulate_slew(
            sensor,
            model=model,
            magnitudes=mags,
            rates_rad_s=rate_values,
            n_trials=trials,
            criterion=criterion,
            rng=seed,
            progress=bar.task("slew Monte Carlo"),
            colour_index=colour_index,
        )
    return sensor, result


MagsOpt = Annotated[
    str | None,
    typer.Option(
        "--magnitudes",
        help="Comma-separated magnitudes (default: 20 steps of 0.25 ending just past the "
        "sensor's limit).",
    ),
]
RatesOpt = Annotated[
    str | None,
    typer.Option(
        "--rates-deg-s",
        help="Comma-separated increasing rates (default 0..10 in 40, or less when the "
        "detector cannot hold the streak).",
    ),
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
        plotting.figure.save_png(plotting.slew.tolerance_figure([res]), plot)
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
        plotting.figure.save_png(plotting.slew.intensity_figure(res), plot)
        payload["plot"] = str(plot)
        lines.append(f"figure: {plot}")
    emit(payload, as_json, lines)


SigmasOpt = Annotated[
    str | None,
    typer.Option("--sigmas-px", help="Comma-separated PSF sigmas, px (default 0.8..3, 8 values)."),
]
QesOpt = Annotated[
    str | None,
    typer.Option("--qe", help="Comma-separated mean QEs in (0, 1] (default 0.25..0.70 by 0.05)."),
]
MagStepOpt = Annotated[
    float, typer.Option("--mag-step", help="Magnitude grid step of the Monte Carlo, mag.")
]


def _study_lines(study, best: dict) -> list[str]:
    """Return the human-readable summary of a slew study."""
    rates = to_edge(study.rates_rad_s, DEG)
    qe, shape = study.best_qe()
    paper = [MAX_MAG, *study.paper_threshold]  # sec. 1.2 static threshold, then Table 2

    def row(label, q, values, last=""):
        cells = "".join("      -" if not np.isfinite(m) else f"{m:7.2f}" for m in values)
        return f"  {label:>8} {q:>5} {cells}  {last}".rstrip()

    lines = [
        f"{study.sensor_name}, {study.model} model: threshold m_t against slew rate, each PSF "
        f"width at its best mean QE ({study.n_trials} trials per point, seed {study.seed})",
        row("sigma px", "QE", [], "".join(f"{w:7.2f}" for w in rates) + " deg/s: m_t; worst"),
        row("paper", "", paper),
    ]
    for i, sigma in enumerate(study.sigmas_px):
        curve = study.threshold_ref[i] + 2.5 * np.log10(qe[i] / study.qe_ref)
        lines.append(row(f"{sigma:.2f}", f"{qe[i]:.2f}", curve, f"{shape[i]:.2f}"))
    verdict = "reproduces" if best["reproduces"] else "does not reproduce"
    lines.append(
        f"best physically sensible pair: sigma {best['sigma_px']:g} px, QE {best['qe_mean']:.2f}: "
        f"worst mismatch {best['worst_mismatch_mag']:.2f} mag; it {verdict} the paper at every "
        f"rate within 2 sigma ({', '.join(f'{t:.2f}' for t in best['tolerance_mag'])} mag)"
    )
    return lines


@slew_app.command("study")
def slew_study(
    sensor: SensorOpt = "st16",
    model: ModelOpt = "reed",
    sigmas_px: SigmasOpt = None,
    qe: QesOpt = None,
    trials: TrialsOpt = 20,
    mag_step: MagStepOpt = 0.05,
    seed: SeedOpt = 0,
    plot: PlotOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Sweep PSF sigma and mean QE: m_t at the paper's rates against its Table 2 (Dzamba 2014)."""
    sigmas = parse_floats(sigmas_px, "--sigmas-px", lo=0.1, hi=20.0) or DEFAULT_SIGMAS_PX
    qes = parse_floats(qe, "--qe", lo=0.01, hi=1.0) or DEFAULT_QE_MEANS
    if not 0.005 <= mag_step <= 0.5:
        raise InputError(f"--mag-step must be within [0.005, 0.5] mag, got {mag_step:g}")
    check_count(trials, "--trials", MAX_TRIALS_PER_POINT, SLEW_TRIAL_COST)
    sens = load_sensor(sensor)
    with progress_bar(not as_json) as bar:
        study = study_slew(
            sens,
            sigmas_px=sigmas,
            qe_means=qes,
            model=model,
            magnitudes=study_magnitudes(mag_step),
            n_trials=trials,
            criterion=0.5,
            rng=seed,
            progress=bar.task("PSF widths"),
        )
    payload = study.to_dict()
    lines = _study_lines(study, payload["best"])
    if plot is not None:
        ref = (sens.detector.psf_sigma_px, sens.detector.mean_qe)
        plotting.figure.save_png(plotting.slew_study.study_figure(study, ref), plot)
        payload["plot"] = str(plot)
        lines.append(f"figure: {plot}")
    emit(payload, as_json, lines)
