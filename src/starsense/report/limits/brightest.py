"""Limit section, part 1: G from the catalogue over the N brightest stars (paper Fig. 7).

Also this report's own sensor as an ideal whole-sky sensor, and the section's summary lines.
"""

from __future__ import annotations

import math

from starsense.analysis.limits.brightest import BrightestCurve, brightest_curve
from starsense.analysis.limits.result import LimitResult
from starsense.analysis.limits.sky import sky_limit
from starsense.plotting.limits import brightest_curves_figure
from starsense.references import fialho2019 as paper
from starsense.report.limits.parts import Part
from starsense.report.limits.tables import in_interval
from starsense.report.page import esc, figure_html, fmt, fmt_int, table, yes_no
from starsense.report.section import ReportContext
from starsense.units import RAD_TO_MAS

__all__ = ["INTRO", "brightest_part", "sensor_part", "summary_rows"]

FIG7 = "limit_fig7_brightest.png"

INTRO = (
    "<p>An ideal spherical sensor of diameter D exposing for t, limited only by diffraction "
    "and photon noise, sees every catalogue star as a black body fitted to its colour and "
    "magnitude (eqs. 1, 9). Each star's centroid bound is F<sub>i</sub> ∝ D<sup>4</sup> t "
    "C<sub>i</sub> T<sub>i</sub><sup>5</sup> (eq. 19); the attitude covariance is the "
    "inverse of Σ F<sub>i</sub> (I − r<sub>i</sub>r<sub>i</sub><sup>T</sup>) (eqs. 20-21) "
    "and θ<sub>rms</sub> = √tr P = G D<sup>−2</sup> t<sup>−½</sup> (eqs. 22-24).</p>"
)

_FIG7_CAPTION = (
    "θ<sub>rms</sub> of an ideal whole-sky sensor with D = 1 m and t = 1 s, using only "
    "the N brightest stars of {name} (solid, one curve per colour "
    "system), and a power law fitted to the last decade of each curve (dashed) "
    "extrapolated to the 3×10<sup>11</sup> stars of the Galaxy (circles). The red band "
    "is the paper's interval 7×10<sup>−15</sup> &lt; G &lt; 10<sup>−13</sup> "
    "rad m<sup>2</sup> s<sup>½</sup>; the black triangles are the paper's own "
    "extrapolations (1.2×10<sup>−14</sup> and 5.8×10<sup>−14</sup> rad). Counterpart: "
    "paper Fig. 7 (Hipparcos, Tycho-2 and 2MASS curves)."
)

_FIG7_NOTE = (
    "<p class='note'>“in/outside” compares with the paper's interval "
    "[7×10<sup>−15</sup>, 10<sup>−13</sup>]. G from a catalogue is an upper bound of the "
    "true G: every further star only adds Fisher information. The paper's G is the value "
    "extrapolated to the whole Galaxy, so the last column is the one to compare with its "
    "1.2×10<sup>−14</sup> (lower curve) and 5.8×10<sup>−14</sup> (upper curve); the "
    "extrapolation over six decades of N from one catalogue's last decade is rough, as the "
    "paper says of its own. Stars are skipped when their magnitude or colour is "
    "missing.</p>"
)


def _in_out(g: float) -> str:
    return yes_no(in_interval(g), "in", "outside")


def brightest_part(ctx: ReportContext) -> tuple[Part, dict[str, BrightestCurve]]:
    """Build Fig. 7 and its table: theta_rms over the N brightest stars per colour system.

    Returns
    -------
    Part
        HTML, numbers ("curves", "g_rad_m2_s05") and the figure.
    dict of str -> BrightestCurve
        The curves, D = 1 m and t = 1 s, per colour system (G is each curve's last point).
    """
    ctx.progress("limit: θ_rms over the N brightest stars (Fig. 7)")
    curves = {
        name: brightest_curve(stars, diameter_m=1.0, exposure_s=1.0)
        for name, stars in ctx.stars.items()
    }
    g_cat = {name: float(c.theta_rms_rad[-1]) for name, c in curves.items()}
    fig7 = ctx.save_figure(brightest_curves_figure(curves, catalog_name=ctx.catalog_name), FIG7)
    part = Part(figures=[fig7])
    part.html.append("<h3>G from the catalogue: θ<sub>rms</sub> over the N brightest stars</h3>")
    part.html.append(
        figure_html(
            fig7,
            _FIG7_CAPTION.format(name=esc(ctx.catalog_name)),
            "theta_rms against the number of brightest stars, log-log",
        )
    )
    rows = [
        [
            esc(name),
            fmt_int(c.n_stars[-1]),
            fmt_int(ctx.stars[name].n_skipped),
            fmt(g_cat[name]) + " " + _in_out(g_cat[name]),
            f"{c.slope:.3f}",
            fmt(c.theta_extrapolated_rad) + " " + _in_out(c.theta_extrapolated_rad),
        ]
        for name, c in curves.items()
    ]
    headers = [
        "colour",
        "N stars used",
        "skipped",
        "G = θ<sub>rms</sub>(all N) (rad m<sup>2</sup> s<sup>½</sup>)",
        "fitted slope d log θ / d log N",
        "θ<sub>rms</sub> at N = 3×10<sup>11</sup> (rad)",
    ]
    part.html.append(table(headers, rows, classes=["", "num", "num", "num", "num", "num"]))
    part.html.append(_FIG7_NOTE)
    part.data["curves"] = {
        name: {
            "n_stars_used": int(c.n_stars[-1]),
            "n_skipped": int(ctx.stars[name].n_skipped),
            "g_rad_m2_s05": g_cat[name],
            "g_in_paper_interval": in_interval(g_cat[name]),
            "slope": c.slope,
            "theta_extrapolated_rad": c.theta_extrapolated_rad,
            "extrapolated_in_paper_interval": in_interval(c.theta_extrapolated_rad),
            "curve": c.to_dict(),
        }
        for name, c in curves.items()
    }
    part.data["g_rad_m2_s05"] = g_cat
    return part, curves


def sensor_part(ctx: ReportContext) -> tuple[Part, LimitResult]:
    """Compute this report's sensor as an ideal whole-sky sensor (numbers only, no HTML)."""
    own = sky_limit(ctx.primary, diameter_m=ctx.diameter_m, exposure_s=ctx.exposure_s)
    fom = ctx.diameter_m**2 * math.sqrt(ctx.exposure_s)
    data = {
        "diameter_m": ctx.diameter_m,
        "exposure_s": ctx.exposure_s,
        "figure_of_merit_m2_s05": fom,
        "colour": ctx.primary.colour,
        "theta_rms_rad": own.theta_rms_rad,
        "theta_rms_mas": own.theta_rms_rad * RAD_TO_MAS,
        "theta_rms_paper_interval_rad": [g / fom for g in paper.G_INTERVAL],
    }
    return Part(data={"sensor": data}), own


def _is_sensor(ctx: ReportContext) -> bool:
    """Whether the report's D and t are those of its sensor (not an ideal sensor's)."""
    sensor = ctx.sensor
    return (
        sensor is not None
        and math.isclose(ctx.diameter_m, sensor.optics.aperture_m)
        and math.isclose(ctx.exposure_s, sensor.exposure_s)
    )


def summary_rows(
    ctx: ReportContext, curves: dict[str, BrightestCurve], own: LimitResult
) -> tuple[tuple[str, str], ...]:
    """Return the section's lines of the report summary: G and this sensor's limit."""
    lo, hi = paper.G_INTERVAL
    fom = ctx.diameter_m**2 * math.sqrt(ctx.exposure_s)
    g_lines = "<br>".join(
        f"{esc(name)}: {fmt(float(c.theta_rms_rad[-1]))} "
        f"({yes_no(in_interval(float(c.theta_rms_rad[-1])), 'in', 'outside')}"
        f" the paper's interval); extrapolated to 3×10<sup>11</sup> stars: "
        f"{fmt(c.theta_extrapolated_rad)} "
        f"({yes_no(in_interval(c.theta_extrapolated_rad), 'in', 'outside')})"
        for name, c in curves.items()
    )
    return (
        (f"G (rad m<sup>2</sup> s<sup>½</sup>), paper: {fmt(lo)} … {fmt(hi)}", g_lines),
        (
            "This sensor's limit",
            (f"{esc(ctx.sensor.name)}: " if _is_sensor(ctx) else "")
            + f"D = {fmt(ctx.diameter_m)} m, t = {fmt(ctx.exposure_s)} s "
            f"(D<sup>2</sup> t<sup>½</sup> = {fmt(fom)} m<sup>2</sup> s<sup>½</sup>): "
            f"θ<sub>rms</sub> = {fmt(own.theta_rms_rad * RAD_TO_MAS)} mas "
            f"({fmt(own.theta_rms_rad)} rad) with {esc(ctx.catalog_name)} "
            f"({esc(ctx.primary.colour)}); {fmt(lo / fom * RAD_TO_MAS)} … "
            f"{fmt(hi / fom * RAD_TO_MAS)} mas for the paper's G interval",
        ),
    )
