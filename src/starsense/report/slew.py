"""Report section: slew tolerance of the chosen sensor (Dzamba & Enright 2014, Figs. 9-10)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from starsense.analysis.slew import SlewResult, simulate_slew
from starsense.report.page import esc, figure_html, fmt, new_figure, table
from starsense.report.section import ReportContext, Section

#: magnitudes of the paper's discussion, quoted in the section's table
QUOTED_MAGNITUDES = (3.0, 4.0, 5.0, 5.75)
MODELS = ("reed", "liebe")


def tolerance_figure(results: list[SlewResult]):
    fig = new_figure(7.5, 4.8)
    ax = fig.add_subplot()
    for res, style in zip(results, ("o-", "s--", "^-."), strict=False):
        tol = np.array([np.nan if r is None else r for r in res.tolerable_rate_deg_s])
        ax.plot(res.magnitudes, tol, style, label=f"{res.model} model", ms=4)
        capped = np.asarray(res.capped)
        if capped.any():
            ax.plot(res.magnitudes[capped], tol[capped], "k^", ms=6, mfc="none")
    ax.set_xlabel("stellar magnitude m")
    ax.set_ylabel("tolerable cross-axis slew rate (deg/s)")
    name = results[0].sensor_name if results else ""
    ax.set_title(f"{name}: fastest slew at which a star is still detected (cf. paper Fig. 10)")
    ax.grid(True, alpha=0.3)
    ax.legend(title="open triangles: detected at every rate simulated", fontsize=8)
    return fig


def intensity_figure(res: SlewResult):
    fig = new_figure(8.5, 4.8)
    ax = fig.add_subplot()
    cmap = __import__("matplotlib").colormaps["viridis"]
    n = len(res.magnitudes)
    step = max(1, n // 8)
    for k, i in enumerate(range(0, n, step)):
        ax.plot(
            res.rates_deg_s, res.mean_intensity_counts[i], "-",
            color=cmap(k / max(1, (n - 1) // step)), label=f"m = {res.magnitudes[i]:.2f}",
        )  # fmt: skip
    ax.axhline(res.threshold_counts, color="k", ls=":", lw=1, label="integrated threshold")
    ax.set_yscale("log")
    ax.set_xlabel("cross-axis slew rate (deg/s)")
    ax.set_ylabel("integrated intensity of detections (counts)")
    ax.set_title(f"{res.sensor_name}, {res.model} model: intensity against rate (cf. paper Fig. 9)")
    ax.grid(True, which="both", alpha=0.3)
    fig.legend(loc="outside right upper", fontsize=8)
    return fig


def plot_tolerance(results: list[SlewResult], path: Path) -> Path:
    path = Path(path)
    tolerance_figure(results).savefig(path, dpi=110, format="png")
    return path


def plot_intensity(res: SlewResult, path: Path) -> Path:
    path = Path(path)
    intensity_figure(res).savefig(path, dpi=110, format="png")
    return path


def _rate_at(res: SlewResult, m: float) -> str:
    i = int(np.argmin(np.abs(res.magnitudes - m)))
    if abs(res.magnitudes[i] - m) > 1e-9:
        return "-"
    r = res.tolerable_rate_deg_s[i]
    if r is None:
        return "not detected at rest"
    return (">= " if res.capped[i] else "") + f"{r:.2f}"


def slew_section(ctx: ReportContext) -> Section:
    """Figs. 9-10 for the report's sensor, both magnitude-only sensitivity models."""
    sensor = ctx.sensor
    if sensor is None:
        return Section("slew", "Slew tolerance", "<p>No sensor chosen.</p>")
    results = []
    for model in MODELS:
        ctx.progress(f"slew tolerance, {model} model")
        result = simulate_slew(sensor, model, n_trials=ctx.slew_trials, seed=ctx.seed)
        ctx.slew_results[model] = result
        results.append(result)
    figures = [ctx.save_figure(tolerance_figure(results), "slew_fig10_tolerance.png")]
    figures += [
        ctx.save_figure(intensity_figure(r), f"slew_fig9_intensity_{r.model}.png") for r in results
    ]
    rows = [
        [fmt(m, 4), *(_rate_at(r, m) for r in results)]
        for m in QUOTED_MAGNITUDES
        if any(abs(r.magnitudes - m).min() < 1e-9 for r in results)
    ]
    det = sensor.detector
    logic = sensor.detection
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
"""
    summary = tuple(
        (f"{esc(sensor.name)} tolerable slew, m = 5, {r.model}", _rate_at(r, 5.0) + " deg/s")
        for r in results
    )
    data = {r.model: {**r.tolerance_dict(), **r.intensity_dict()} for r in results}
    return Section("slew", "Slew tolerance (Dzamba & Enright 2014)", html, tuple(figures),
                   summary, data)  # fmt: skip
