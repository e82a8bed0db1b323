"""Report section 1: the datasheet of the report's sensor, predicted and verified."""

from __future__ import annotations

from starsense.analysis.availability.threshold import ThresholdCurve
from starsense.analysis.datasheet import DatasheetSettings, build_datasheet
from starsense.analysis.sensor_detection import SensorDetection
from starsense.plotting.datasheet import nea_sky_figure
from starsense.report.page import esc, figure_html, fmt, table
from starsense.report.section import ReportContext, Section
from starsense.report.summary import summary_part

__all__ = ["datasheet_section"]


def _cell(x, digits: int = 3) -> str:
    return "n/a" if x is None else fmt(x, digits)


def _ratio(run: dict, axis: str) -> str:
    """Return a ratio and its 95 % interval over the frames: ``1.0 (0.91-1.2)``."""
    ci = run.get(f"{axis}_ratio_ci95")
    band = "" if ci is None else f" ({fmt(ci[0], 2)}-{fmt(ci[1], 2)})"
    return _cell(run[f"{axis}_ratio"], 2) + band


def _pct(x) -> str:
    return "n/a" if x is None else f"{100 * x:.1f} %"


def _main_rows(d: dict) -> list[list[str]]:
    nea, mc, lim = d["nea_arcsec"], d["monte_carlo"], d["limit_arcsec"]
    w, h = d["fov_deg"]
    stars = d["stars_in_fov"]
    rows = [
        ["Field of view", f"{w:.2f} x {h:.2f} deg", "", ""],
        ["Pixel scale", f"{d['pixel_scale_arcsec']:.2f} arcsec/px", "", ""],
        ["Limiting magnitude (50 % detected at rest)", _cell(d["limiting_magnitude"]), "", ""],
        [
            "Stars in the field (median / 5th percentile)",
            f"{stars['median']:g} / {stars['p05']:g}",
            "",
            "",
        ],
        [
            "NEA cross-boresight, 1 sigma (median / 95 %)",
            f"{_cell(nea['cross']['median'])} / {_cell(nea['cross']['p95'])} arcsec",
            f"{_cell(mc['cross_rms_arcsec'])} arcsec rms",
            _ratio(mc, "cross"),
        ],
        [
            "NEA about the boresight, 1 sigma (median / 95 %)",
            f"{_cell(nea['roll']['median'])} / {_cell(nea['roll']['p95'])} arcsec",
            f"{_cell(mc['roll_rms_arcsec'])} arcsec rms",
            _ratio(mc, "roll"),
        ],
        [
            "Physical limit for this D, t and field (cross / roll)",
            f"{_cell(lim['cross'])} / {_cell(lim['roll'])} arcsec",
            "",
            "",
        ],
        [
            "Lost in space at rest: solved, wrong",
            "",
            f"{mc['solved']}/{mc['frames']}, {mc['wrong']} wrong (rate &lt; "
            f"{mc['wrong_rate_upper95']:.2g}, 95 %)",
            "",
        ],
        [
            "Lost in space time per frame (median / 95 %)",
            "",
            f"{_cell(mc['median_ms'], 3)} / {_cell(mc['p95_ms'], 3)} ms",
            "",
        ],
    ]
    mr = d.get("monte_carlo_at_rate")
    if mr and mr["frames"]:  # the smeared frames against the prediction for streaks
        rows += [
            [
                f"Attitude error at {mr['rate_deg_s']:g} deg/s, rms (cross / roll)",
                f"{_cell(mr['cross_predicted_arcsec'])} / {_cell(mr['roll_predicted_arcsec'])}"
                " arcsec",
                f"{_cell(mr['cross_rms_arcsec'])} / {_cell(mr['roll_rms_arcsec'])} arcsec",
                f"{_ratio(mr, 'cross')} / {_ratio(mr, 'roll')}",
            ]
        ]
    av = d["availability"]
    for r, a, t in zip(
        av["rates_deg_s"], av["lost_in_space_at_rate"], av["tracking_at_rate"], strict=True
    ):
        rows.append(
            [
                f"Sky availability at {r:g} deg/s (lost in space / tracking)",
                f"{_pct(a)} / {_pct(t)}",
                "",
                "",
            ]
        )
    fast = av["fastest_rate_deg_s"]
    rows.append(
        [
            "Fastest rate keeping 90 % (lost in space / tracking)",
            f"{_cell(fast['lost_in_space']['90'])} / {_cell(fast['tracking']['90'])} deg/s",
            "",
            "",
        ]
    )
    return rows


def _share_slew(ctx: ReportContext, sheet) -> None:
    """Hand the datasheet's detection (limit, slew run, m_t(w)) to the later sections.

    The datasheet ran :func:`~starsense.analysis.sensor_detection.sensor_detection` with the
    Reed model and the report's trials and seed: the run :meth:`ReportContext.detection` makes.
    """
    if sheet.slew is not None and ctx.detection_cache is None:
        ctx.detection_cache = SensorDetection(
            sheet.limiting_magnitude, sheet.slew, ThresholdCurve.from_slew(sheet.slew)
        )
        ctx.slew_results.setdefault("reed", sheet.slew)


def datasheet_section(ctx: ReportContext) -> Section:
    """Return the datasheet of the report's sensor (analysis.datasheet.build_datasheet)."""
    sensor = ctx.sensor
    if sensor is None or ctx.catalog is None:
        return Section("datasheet", "Datasheet", "<p>No sensor or catalogue chosen.</p>")
    ctx.progress(f"datasheet of {sensor.name}")
    # half as many frames at the rate: the check of the prediction is the run at rest
    settings = DatasheetSettings(
        n_trials=ctx.datasheet_trials,
        seed=ctx.seed,
        n_slew_trials=ctx.slew_trials,
        n_rate_trials=max(1, ctx.datasheet_trials // 2),
    )
    sheet = build_datasheet(sensor, ctx.catalog, settings=settings)
    _share_slew(ctx, sheet)
    d = sheet.to_dict()
    if d.get("limiting_magnitude") is None:
        html = "".join(f"<p>{esc(w)}</p>" for w in d["warnings"])
        return Section("datasheet", f"Datasheet: {sensor.name}", html, data={"datasheet": d})
    figures = [ctx.save_figure(nea_sky_figure(sheet), "datasheet_nea_sky.png")]
    summary_html, summary_data = summary_part(ctx, sheet, settings)
    mc = d["monte_carlo"]
    budget = table(
        ["term", "cross-boresight (arcsec)", "about the boresight (arcsec)", "source"],
        [
            [esc(b["term"]), _cell(b["cross_arcsec"]), _cell(b["roll_arcsec"]), esc(b["source"])]
            for b in d["budget"]
        ],
        classes=["", "num", "num", ""],
    )
    quoted = ""
    if d["quoted"]:
        quoted = f"<h3>Predicted / quoted ({esc(d['quoted_source'])})</h3>" + table(
            ["value", "predicted", "quoted", "ratio"],
            [
                [esc(q["key"]), _cell(q["predicted"]), _cell(q["quoted"]), _cell(q["ratio"], 2)]
                for q in d["quoted"]
            ],
        )
    warn = "".join(f'<p class="no">{esc(w)}</p>' for w in d["warnings"])
    html = f"""
<p>What <b>{esc(sensor.name)}</b> does, predicted from the sensor model and the catalogue, and
checked on {mc["frames"]} rendered frames at random attitudes in the same run (render, detect,
identify, estimate). The ratio column is measured rms / predicted rms over the same frames
(target 0.8-1.25). Terms follow ECSS-E-ST-60-20C. The sections after this one show how each
number was obtained; the papers' reproductions close the report as its validation.</p>
{warn}
{
        table(
            ["", "predicted", "measured (rendered frames)", "measured / predicted"],
            _main_rows(d),
            classes=["", "num", "num", "num"],
        )
    }
<h3>Error budget</h3>
{budget}
{quoted}
{
        figure_html(
            figures[0],
            "Noise-equivalent angle cross-boresight over the sky (median in the "
            "table); red: no attitude (fewer than 2 stars).",
            "NEA sky map",
        )
    }
{summary_html}
"""
    nea = d["nea_arcsec"]
    summary = (
        (
            "Datasheet",
            f"{esc(sensor.name)}: NEA {_cell(nea['cross']['median'])} arcsec cross, "
            f"{_cell(nea['roll']['median'])} arcsec roll (1 sigma, sky median); measured / "
            f"predicted {_cell(mc['cross_ratio'], 2)} / {_cell(mc['roll_ratio'], 2)}; "
            f"lost in space {mc['solved']}/{mc['frames']} solved, {mc['wrong']} wrong",
        ),
    )
    data = {"datasheet": d, "summary": summary_data}
    return Section("datasheet", f"Datasheet: {sensor.name}", html, tuple(figures), summary, data)
