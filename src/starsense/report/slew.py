"""Report section: slew tolerance of the chosen sensor (Dzamba & Enright 2014, Figs. 9-10)."""

from __future__ import annotations

import numpy as np

from starsense.analysis.sensor_detection import sensor_grids
from starsense.analysis.slew import SlewResult, simulate_slew
from starsense.plotting.slew import intensity_figure, tolerance_figure
from starsense.report.page import esc, figure_html, fmt, table
from starsense.report.section import ReportContext, Section
from starsense.report.slew_study import slew_study_part
from starsense.sensor import load_sensor

__all__ = ["MODELS", "slew_section"]

#: the sensitivity models of the section
MODELS = ("reed", "liebe")


def _rate_at(res: SlewResult, m: float) -> str:
    """Return the tolerable rate of magnitude `m` as text, deg/s."""
    i = int(np.argmin(np.abs(res.magnitudes - m)))
    if abs(res.magnitudes[i] - m) > 1e-9:
        return "-"
    r = res.tolerable_rate_deg_s[i]
    if r is None:
        return "not detected at rest"
    return (">= " if res.capped[i] else "") + f"{r:.2f}"


def _shown_magnitudes(results: list[SlewResult]) -> list[float]:
    """Return the table's magnitudes: whole and half magnitudes every run simulated."""
    common = set.intersection(*(set(np.round(r.magnitudes, 6).tolist()) for r in results))
    return sorted(m for m in common if abs(2.0 * m - round(2.0 * m)) < 1e-9)


def _one_brighter(res: SlewResult) -> float:
    """Return the simulated magnitude nearest one magnitude brighter than the run's limit."""
    seen = [
        m for m, r in zip(res.magnitudes, res.tolerable_rate_rad_s, strict=True) if r is not None
    ]
    top = max(seen) if seen else float(res.magnitudes[-1])
    return float(res.magnitudes[int(np.argmin(np.abs(res.magnitudes - (top - 1.0))))])


def _study(ctx: ReportContext, sensor):
    """Run the validation of the slew model on the paper's sensor (the st16 preset)."""
    reference = sensor if sensor.name == "st16" else load_sensor("st16")
    return slew_study_part(ctx, reference)


def slew_section(ctx: ReportContext) -> Section:
    """Figs. 9-10 for the report's sensor, both magnitude-only sensitivity models."""
    sensor = ctx.sensor
    if sensor is None:
        return Section("slew", "Slew tolerance", "<p>No sensor chosen.</p>")
    results = []
    for model in MODELS:
        ctx.progress(f"slew tolerance, {model} model")
        if model == "reed":
            ctx.detection()  # the datasheet's run (its own grid), shared with later sections
        result = ctx.slew_results.get(model)
        if result is None:  # the sensor's own grids for this model
            mags, rates = sensor_grids(sensor, model=model, n_trials=ctx.slew_trials, rng=ctx.seed)
            result = simulate_slew(
                sensor,
                model=model,
                magnitudes=mags,
                rates_rad_s=rates,
                n_trials=ctx.slew_trials,
                rng=ctx.seed,
            )
            ctx.slew_results[model] = result
        results.append(result)
    shown = _shown_magnitudes(results)
    figures = [ctx.save_figure(tolerance_figure(results), "slew_fig10_tolerance.png")]
    figures += [
        ctx.save_figure(intensity_figure(r), f"slew_fig9_intensity_{r.model}.png") for r in results
    ]
    rows = [[fmt(m, 4), *(_rate_at(r, m) for r in results)] for m in shown]
    det = sensor.detector
    logic = sensor.detection
    study_html, study_fig, study_data = _study(ctx, sensor)
    figures.append(study_fig)
    html = f"""
<p>Sensor <b>{esc(sensor.name)}</b>: {det.columns} x {det.rows} pixels of
{det.pixel_pitch_m * 1e6:.2f} um, f = {sensor.optics.focal_length_m * 1e3:.1f} mm,
D = {sensor.optics.aperture_m * 1e3:.1f} mm, exposure {sensor.exposure_s * 1e3:.0f} ms, PSF sigma
{det.psf_sigma_px} px, read noise {det.read_noise_e} e-, gain {det.gain_counts_per_e} counts/e-,
{det.bit_depth}-bit ADC. Detection logic: lit pixel &gt; {logic.lit_pixel_counts:g} counts,
at least {logic.min_pixels} contiguous lit pixels ({logic.connectivity}-connected), integrated
intensity &ge; {logic.min_integrated_counts:g} counts.</p>
<p>Each point is a Monte Carlo of {ctx.slew_trials} trials: a star streaked along the detector
rows by a cross-axis slew (eq. 12; the analytic streak of eqs. 13-22 integrated over each pixel),
shot and read noise, gain and quantisation, then the detection logic. A magnitude counts as
detected at a rate when at least half of the trials detect it; the tolerable rate is where that
fraction first drops below one half.</p>
{table(["m", "Reed (deg/s)", "Liebe (deg/s)"], rows, classes=["num", "num", "num"])}
{
        figure_html(
            figures[0],
            "Tolerable cross-axis slew rate against magnitude for the Reed "
            "(conservative) and Liebe (liberal) sensitivity models; the paper's Fig. 10.",
            "tolerable slew rate against magnitude",
        )
    }
{
        figure_html(
            figures[1],
            "Mean integrated intensity of the detections against slew rate, Reed "
            "model; the paper's Fig. 9. Bright stars saturate at rest: as the streak spreads "
            "their light over more pixels, light the ADC clipped is recovered and the integrated "
            "intensity can rise before it falls.",
            "integrated intensity against rate, Reed",
        )
    }
{
        figure_html(
            figures[2],
            "The same for the Liebe model: about 2.2 times the electrons of Reed "
            "at equal magnitude, so the curves shift by ~0.9 mag.",
            "integrated intensity against rate, Liebe",
        )
    }
{study_html}
"""
    # the summary speaks of this sensor: a star one magnitude brighter than its (Reed) limit
    m_sum = _one_brighter(results[0])
    summary = tuple(
        (
            f"{esc(sensor.name)} tolerable slew, m = {m_sum:g}, {r.model}",
            _rate_at(r, m_sum) + " deg/s",
        )
        for r in results
    )
    data = {r.model: {**r.tolerance_dict(), **r.intensity_dict()} for r in results}
    data["psf_qe_study"] = study_data
    return Section(
        "slew", "Slew tolerance (Dzamba & Enright 2014)", html, tuple(figures), summary, data
    )
