"""Report section: star-tracker availability (Dzamba & Enright 2014, sec. 1, 3.1, 4).

One function per part of the section: the static part (Figs. 4-6), the spatial dynamic part
(Fig. 11, Table 2's spatial column), the along-track part (Table 2, Figs. 16-17) and the
full-fidelity check (rendered frames through the detector). The figures are drawn by
:mod:`starsense.plotting.availability`; the paper's numbers come from
:mod:`starsense.references.dzamba2014`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from starsense.analysis.availability import (
    N_MIN_CONSERVATIVE,
    N_MIN_LOST_IN_SPACE,
    N_MIN_TRACKING,
    AvailabilityAnalysis,
    StaticAvailability,
    ThresholdCurve,
    describe_fov,
    implied_threshold,
)
from starsense.analysis.datasheet import DatasheetSettings
from starsense.analysis.datasheet.predict import DEFAULT_RATES_RAD_S
from starsense.analysis.slew import simulate_slew
from starsense.geometry.fov import CircularFov
from starsense.identify.hashing import MIN_SOLVING_STARS
from starsense.plotting.availability import (
    dynamic_figure,
    sky_map_figure,
    static_curve_figure,
    threshold_figure,
)
from starsense.references import dzamba2014 as paper
from starsense.report.availability_track import fidelity_part, percent, track_part
from starsense.report.page import esc, figure_html, fmt, table
from starsense.report.section import ReportContext, Section
from starsense.units import DEG, RAD_TO_DEG

__all__ = ["availability_section"]

#: the datasheet's boresights and rates, so the sensor's own numbers are its datasheet's
SHEET_ORIENTATIONS = DatasheetSettings().n_orientations
SHEET_RATES_RAD_S = DEFAULT_RATES_RAD_S

#: slew rates of Fig. 11, deg/s
DYNAMIC_RATES_DEG_S = np.round(np.arange(0.0, 10.0001, 0.25), 6)


@dataclass
class _Parts:
    """What the parts of the section share: the analysis, its figures, numbers and summary."""

    analysis: AvailabilityAnalysis
    figures: list[str] = field(default_factory=list)
    data: dict = field(default_factory=dict)
    summary: list[tuple[str, str]] = field(default_factory=list)


def _slew_curve(ctx: ReportContext, model: str) -> ThresholdCurve:
    """Return the tolerable-slew threshold curve of ``model``.

    The slew section's result when it ran (same sensor, trials and seed), else a fresh Monte
    Carlo.
    """
    result = ctx.slew_results.get(model)
    if result is None:
        result = simulate_slew(ctx.sensor, model=model, n_trials=ctx.slew_trials, rng=ctx.seed)
        ctx.slew_results[model] = result
    return ThresholdCurve.from_slew(result)


def _field(ctx: ReportContext) -> tuple[CircularFov, str]:
    """Return the field of the analysis and a sentence saying what it is."""
    sensor = ctx.sensor
    if sensor.name == "st16":
        note = (
            f"a circular field of the paper's {paper.HALF_FOV_DEG} deg half-axis (our st16 "
            f"preset's minor half-axis is {min(sensor.half_fov_rad) * RAD_TO_DEG:.2f} deg)"
        )
        return CircularFov(paper.HALF_FOV_DEG * DEG), note
    note = "a circular field of the detector's minor half-axis"
    return CircularFov(min(sensor.half_fov_rad)), note


def _star_set(ctx: ReportContext, fov: CircularFov) -> tuple[AvailabilityAnalysis, str, str]:
    """Return the analysis of the report's primary star set, its band, and a note on skips."""
    stars = ctx.primary
    band = "V" if stars.colour == "B-V" else f"the {stars.colour} system's magnitude"
    skipped_note = (
        f" ({stars.n_skipped:,} catalogue stars without a magnitude or colour are not in "
        "the report's star set)"
        if stars.n_skipped
        else ""
    )
    analysis = AvailabilityAnalysis(
        stars.vectors,
        stars.magnitude,
        fov,
        max_mag=paper.MAX_MAG,
        rng=ctx.seed,
        catalog=ctx.catalog_name,
        band="V" if stars.colour == "B-V" else stars.colour,
    )
    return analysis, band, skipped_note


def _static_part(ctx: ReportContext, parts: _Parts, band: str, intro: str) -> str:
    """Return the spatial static part (Figs. 4-6) and record its figures and numbers."""
    name = ctx.sensor.name
    static = parts.analysis.static(N_MIN_LOST_IN_SPACE)
    parts.figures.append(
        ctx.save_figure(
            sky_map_figure(
                static.boresights,
                static.counts,
                f"{name}: stars in the field, static, m_t = {paper.MAX_MAG} (cf. Fig. 4)",
            ),
            "availability_fig4_map.png",
        )
    )
    parts.figures.append(
        ctx.save_figure(
            sky_map_figure(
                static.boresights,
                static.counts,
                f"{name}: star-sparse regions, static (cf. Fig. 5)",
                sparse=True,
            ),
            "availability_fig5_sparse.png",
        )
    )
    parts.figures.append(ctx.save_figure(static_curve_figure(static), "availability_fig6_mt.png"))
    parts.data["static"] = static.to_dict()
    parts.data["fov"] = describe_fov(parts.analysis.fov)
    return _static_html(static, parts.figures[-3:], intro)


def _static_html(static: StaticAvailability, figures: list[str], intro: str) -> str:
    claim = f"&gt; {100 * paper.STATIC_AVAILABILITY_N3:.1f}"
    rows = [
        [str(k), f"{100 * static.by_n_min[k]:.2f}", claim if k == N_MIN_LOST_IN_SPACE else "–"]
        for k in (N_MIN_TRACKING, N_MIN_LOST_IN_SPACE, N_MIN_CONSERVATIVE)
    ]
    return f"""
<p>Availability is the fraction of orientations at which at least N<sub>min</sub> stars
brighter than the detection threshold m<sub>t</sub> lie in the field (paper sec. 1.1):
N<sub>min</sub> = 2 to track, 3 to solve lost-in-space, 4 as a conservative allowance for
pattern ambiguity. {intro}</p>
<h3>Spatial static availability</h3>
{table(["N<sub>min</sub>", "ours (%)", "paper (%)"], rows, classes=["num", "num", "num paper"])}
<p>Stars in the field: min {static.counts.min()}, mean {static.counts.mean():.1f},
max {static.counts.max()}.</p>
{
        figure_html(
            figures[0],
            "Stars in the field per boresight (static, m<sub>t</sub> = "
            f"{paper.MAX_MAG}); Mollweide projection, RA increasing to the left with 0 h at "
            "the centre (astronomical convention), dashed: the galactic plane. The paper's "
            "Fig. 4.",
            "sky map of stars in the field",
        )
    }
{
        figure_html(
            figures[1],
            "The same with the colours reversed to show star-sparse regions; "
            "black contours enclose boresights with fewer than 3 stars. The paper's Fig. 5.",
            "sky map of star-sparse regions",
        )
    }
{
        figure_html(
            figures[2],
            "Spatial static availability against the detection threshold "
            "m<sub>t</sub>; the paper's Fig. 6.",
            "availability against threshold",
        )
    }
"""


def _implied_part(analysis: AvailabilityAnalysis, curves: list[ThresholdCurve]) -> str:
    """Return the thresholds Table 2's spatial column implies on our sky, beside ours."""
    rows = []
    for rate, vals in paper.TABLE2.items():
        n2, n3 = (v / 100 for v in vals["spatial"])
        ours = [f"{float(c([rate * DEG])[0]):.2f}" for c in curves]
        rows.append(
            [
                f"{rate:g}",
                percent(n2),
                fmt(implied_threshold(analysis, n2, 2), 3),
                percent(n3),
                fmt(implied_threshold(analysis, n3, 3), 3),
                *ours,
            ]
        )
    return f"""
<h3>Spatial dynamic availability</h3>
<p>The threshold becomes m<sub>t</sub>(w), the faintest magnitude still detected at slew rate
w: the tolerable-slew curve of the previous section (Fig. 10) read sideways, interpolated
linearly between simulated magnitudes and capped at the catalogue limit.
As a check of our sky against the paper's, the table gives the threshold at which our spatial
availability equals each value of the paper's Table 2 (spatial column): if the star
distributions agree, the thresholds implied by the N<sub>min</sub> = 2 and 3 values agree at
each rate, and they are the paper's own m<sub>t</sub>(w). Where our m<sub>t</sub>(w) differs
from the implied one, our availability differs from the paper's accordingly: the sky is the
same, the tolerable-slew curve is not.</p>
{
        table(
            [
                "rate (deg/s)",
                "paper N<sub>min</sub>=2 (%)",
                "implied m<sub>t</sub>",
                "paper N<sub>min</sub>=3 (%)",
                "implied m<sub>t</sub>",
                *[f"our m<sub>t</sub>, {esc(c.label)}" for c in curves],
            ],
            rows,
            classes=["num"] * (5 + len(curves)),
        )
    }
"""


def _dynamic_part(ctx: ReportContext, parts: _Parts, curves: list[ThresholdCurve]) -> str:
    """Return the spatial dynamic part (Figs. 10-11, 14) and record its figures and numbers."""
    analysis, name = parts.analysis, ctx.sensor.name
    rates = np.asarray(DYNAMIC_RATES_DEG_S, dtype=float) * DEG
    dyn = [analysis.dynamic(c, rates, N_MIN_LOST_IN_SPACE) for c in curves]
    parts.data["dynamic"] = {c.label: d.to_dict() for c, d in zip(curves, dyn, strict=True)}
    parts.figures.append(
        ctx.save_figure(threshold_figure(curves, rates), "availability_threshold_curves.png")
    )
    parts.figures.append(ctx.save_figure(dynamic_figure(dyn), "availability_fig11_dynamic.png"))
    reed = dyn[0]
    m1 = float(analysis.effective_threshold(curves[0]([1.0 * DEG]))[0])
    parts.figures.append(
        ctx.save_figure(
            sky_map_figure(
                analysis.boresights,
                analysis.sky_counts(m1),
                f"{name}: stars detectable at 1 deg/s (reed, m_t = {m1:.2f}; cf. Fig. 14)",
                sparse=True,
            ),
            "availability_fig14_sparse_1degs.png",
        )
    )
    quote_rows = []
    for rate, (p2, p3) in paper.FIG11_REED.items():
        j = int(np.argmin(np.abs(reed.rates_deg_s - rate)))
        quote_rows.append(
            [
                f"{rate:g}",
                percent(reed.by_n_min[2][j]),
                f"≈ {100 * p2:.0f}",
                percent(reed.by_n_min[3][j]),
                f"≈ {100 * p3:.0f}",
            ]
        )
    figures = parts.figures
    return f"""
{
        table(
            [
                "rate (deg/s)",
                "Reed N<sub>min</sub>=2 (%)",
                "paper",
                "Reed N<sub>min</sub>=3 (%)",
                "paper",
            ],
            quote_rows,
            classes=["num", "num", "num paper", "num", "num paper"],
        )
    }
{
        figure_html(
            figures[-3],
            "Detection threshold m<sub>t</sub>(w) from the slew simulation, "
            "for both sensitivity models.",
            "threshold against rate",
        )
    }
{
        figure_html(
            figures[-2],
            "Spatial dynamic availability against slew rate, N<sub>min</sub> = 2 "
            "(dashed) and 3 (solid), Reed and Liebe models; the paper's Fig. 11.",
            "availability against rate",
        )
    }
{
        figure_html(
            figures[-1],
            "Stars detectable in the field while slewing at 1 deg/s (Reed), "
            "colours reversed as in Fig. 5; black contours enclose boresights with fewer than "
            "3 stars. The paper's Fig. 14.",
            "sky map at 1 deg/s",
        )
    }
"""


def _own_part(ctx: ReportContext, parts: _Parts) -> str:
    """Return the sensor's own availability: its field, limit and m_t(w), as its datasheet.

    The datasheet's analysis (:func:`starsense.analysis.datasheet.build_datasheet`): the
    detector's rectangular field with a random roll per boresight, the catalogue's V stars to
    the sensor's limiting magnitude, its Reed m_t(w), the datasheet's boresights and seed, so
    the numbers are the datasheet's.
    """
    sensor = ctx.sensor
    det = ctx.detection()
    if det.curve is None:
        return f"<p>{esc(sensor.name)} detects no star at rest: nothing is available.</p>"
    if ctx.catalog is not None:
        analysis = AvailabilityAnalysis.from_catalog(
            ctx.catalog,
            sensor.fov(),
            det.limit_mag,
            band="V",
            n_orientations=SHEET_ORIENTATIONS,
            roll_rad=None,
            rng=ctx.seed,
        )
    else:
        stars = ctx.primary
        analysis = AvailabilityAnalysis(
            stars.vectors,
            stars.magnitude,
            sensor.fov(),
            max_mag=det.limit_mag,
            n_orientations=SHEET_ORIENTATIONS,
            roll_rad=None,
            rng=ctx.seed,
            catalog=ctx.catalog_name,
        )
    dyn = analysis.dynamic(det.curve, SHEET_RATES_RAD_S, MIN_SOLVING_STARS)
    lis, trk = dyn.by_n_min[MIN_SOLVING_STARS], dyn.by_n_min[N_MIN_TRACKING]
    parts.data["sensor"] = {
        "rates_deg_s": dyn.rates_deg_s.tolist(),
        "lost_in_space": [float(x) for x in lis],
        "tracking": [float(x) for x in trk],
        "threshold_mag": [float(x) for x in dyn.threshold_mag],
        "limiting_magnitude": det.limit_mag,
        "n_orientations": analysis.n_orientations,
        "fov": describe_fov(analysis.fov),
    }
    j1 = int(np.argmin(np.abs(dyn.rates_deg_s - 1.0)))
    parts.summary += [
        (
            f"{esc(sensor.name)} static availability (its field, V &le; "
            f"{dyn.threshold_mag[0]:.2f})",
            f"{100 * lis[0]:.2f} % lost in space (N<sub>min</sub> = {MIN_SOLVING_STARS}), "
            f"{100 * trk[0]:.2f} % "
            "tracking (N<sub>min</sub> = 2)",
        ),
        (
            f"{esc(sensor.name)} availability at {dyn.rates_deg_s[j1]:g} deg/s (Reed)",
            f"{percent(lis[j1])} % lost in space, {percent(trk[j1])} % tracking",
        ),
    ]
    rows = [
        [f"{w:g}", f"{m:.2f}", percent(a), percent(t)]
        for w, m, a, t in zip(dyn.rates_deg_s, dyn.threshold_mag, lis, trk, strict=True)
    ]
    head = [
        "rate (deg/s)",
        "m<sub>t</sub>",
        f"lost in space N&ge;{MIN_SOLVING_STARS} (%)",
        "tracking N&ge;2 (%)",
    ]
    return f"""
<h3>{esc(sensor.name)}: its own field and threshold</h3>
<p>The sensor's rectangular field ({esc(describe_fov(analysis.fov))}), a random roll per
boresight, {analysis.n_orientations:,} boresights, the catalogue's stars to its limiting
magnitude V = {det.limit_mag:.2f} (detected in half the renders at rest) and its Reed
tolerable-slew curve: the numbers of its datasheet (lost in space needs the solver's
4-star pattern and one more star, where the paper counts 3).</p>
{table(head, rows, classes=["num"] * 4)}
<h3>The paper's conditions</h3>
"""


def availability_section(ctx: ReportContext) -> Section:
    """Build the section: spatial static, spatial dynamic and along-track availability."""
    sensor = ctx.sensor
    if sensor is None:
        return Section("availability", "Availability", "<p>No sensor chosen.</p>")
    fov, fov_note = _field(ctx)
    ctx.progress("availability: stars in the field over the sky")
    analysis, band, skipped_note = _star_set(ctx, fov)
    parts = _Parts(analysis)
    intro = (
        f"Stars: {esc(ctx.catalog_name)}, {esc(band)} &le; {paper.MAX_MAG}\n"
        f"(<b>{analysis.n_stars:,}</b> stars{skipped_note}; the paper's Yale Bright Star cut "
        f"has {paper.BSC5_V575_STARS:,}).\nField:\n{fov_note}. {analysis.n_orientations:,} "
        "boresights on a spherical Fibonacci lattice (the paper\nuses the Marantis "
        "distribution). The stars in each field are found once and their magnitudes\nsorted, "
        "so availability at any threshold is a lookup."
    )
    html = [_own_part(ctx, parts), _static_part(ctx, parts, band, intro)]
    curves: list[ThresholdCurve] = []
    for model in ("reed", "liebe"):
        ctx.progress(f"availability: tolerable slew curve, {model} model")
        curves.append(_slew_curve(ctx, model))
    html.append(_implied_part(analysis, curves))
    html.append(_dynamic_part(ctx, parts, curves))
    html.append(track_part(ctx, analysis, curve=curves[0], figures=parts.figures, data=parts.data))
    html.append(fidelity_part(ctx, sensor, stars=ctx.primary, curve=curves[0], data=parts.data))
    return Section(
        "availability",
        "Availability (Dzamba & Enright 2014)",
        "\n".join(html),
        tuple(parts.figures),
        tuple(parts.summary),
        parts.data,
    )
