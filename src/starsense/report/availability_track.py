"""Report section parts: along-track availability and the full-fidelity check.

Part of the availability section (:mod:`starsense.report.availability`): the along-track
dynamic availability of great-circle tracks (Dzamba & Enright 2014, sec. 4, Table 2,
Figs. 16-17), its sensitivity to the tracks' node, and rendered frames through the detector
against the threshold model.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from starsense.analysis.availability import (
    N_MIN_LOST_IN_SPACE,
    N_MIN_TRACKING,
    AvailabilityAnalysis,
    ThresholdCurve,
    fidelity_check,
)
from starsense.errors import InputError
from starsense.plotting.availability import track_figure
from starsense.references import dzamba2014 as paper
from starsense.report.page import esc, figure_html, table
from starsense.report.section import ReportContext
from starsense.units import DEG

if TYPE_CHECKING:
    from starsense.sensor import Sensor

__all__ = ["fidelity_part", "percent", "track_part"]

#: slew rates of Table 2 and Figs. 16-17, deg/s
TRACK_RATES_DEG_S = paper.TABLE2_RATES_DEG_S
#: RAs of the tracks' common node: the first gives Table 2, the others its sensitivity, deg
TRACK_NODES_DEG = (0.0, 45.0, 90.0, 135.0)
#: rendered frames per rate of the report's full-fidelity check, and its rates (deg/s)
FIDELITY_FRAMES = 25
FIDELITY_RATES_DEG_S = (1.0, 2.0, 3.0)


def percent(x: float | None) -> str:
    """Return a fraction as a percentage with one decimal, or a dash for None or NaN."""
    return "–" if x is None or not np.isfinite(x) else f"{100 * x:.1f}"


def _node_table(ctx, analysis, curve, tracks, node0, other_nodes, data) -> str:
    """Return the table of track statistics for other nodes (how much the node matters)."""
    by_node: dict[str, dict] = {}
    for node in other_nodes:
        ctx.progress(f"availability: tracks through the node at RA {node:g} deg")
        for w in TRACK_RATES_DEG_S:
            t = analysis.track(curve, w * DEG, n_min=N_MIN_LOST_IN_SPACE, node_rad=node * DEG)
            by_node.setdefault(f"{node:g}", {})[f"{w:g}"] = {
                str(k): t.stats(k) for k in (N_MIN_TRACKING, N_MIN_LOST_IN_SPACE)
            }
    node_rows = []
    for w, t in zip(TRACK_RATES_DEG_S, tracks, strict=True):
        cells = [f"{w:.2f}", f"{percent(t.stats(2)['mean'])} / {percent(t.stats(3)['mean'])}"]
        for node in other_nodes:
            st = by_node[f"{node:g}"][f"{w:g}"]
            cells.append(
                f"{percent(st['2']['mean'])} / {percent(st['3']['mean'])} "
                f"({percent(st['2']['min'])} / {percent(st['3']['min'])} – "
                f"{percent(st['2']['max'])} / {percent(st['3']['max'])})"
            )
        ref = paper.TABLE2.get(w)
        cells.append(f"{ref['mean'][0]:.1f} / {ref['mean'][1]:.1f}" if ref else "–")
        node_rows.append(cells)
    data["track_by_node"] = by_node
    return table(
        [
            "rate (deg/s)",
            f"mean, node {node0:g} deg",
            *[f"mean (min – max), node {n:g} deg" for n in other_nodes],
            "paper mean",
        ],
        node_rows,
        classes=["num"] * (2 + len(other_nodes)) + ["num paper"],
    )


def track_part(
    ctx: ReportContext,
    analysis: AvailabilityAnalysis,
    *,
    curve: ThresholdCurve,
    figures: list[str],
    data: dict,
) -> str:
    """Return the along-track part (Table 2, Figs. 16-17) and record figures and numbers.

    Parameters
    ----------
    ctx : ReportContext
        The report being built (progress, figure folder).
    analysis : AvailabilityAnalysis
        The stars in the field over the sky.
    curve : ThresholdCurve
        m_t(w), the detection threshold against slew rate.
    figures : list of str
        The section's figures: the two of this part are appended.
    data : dict
        The section's numbers: ``"track"`` and ``"track_by_node"`` are set.

    Returns
    -------
    str
        HTML.
    """
    ctx.progress("availability: along-track tracks")
    node0, *other_nodes = TRACK_NODES_DEG
    tracks = [
        analysis.track(curve, w * DEG, n_min=N_MIN_LOST_IN_SPACE, node_rad=node0 * DEG)
        for w in TRACK_RATES_DEG_S
    ]
    data["track"] = {f"{t.rate_deg_s:g}": t.to_dict() for t in tracks}
    for k, fig_no in ((N_MIN_TRACKING, 16), (N_MIN_LOST_IN_SPACE, 17)):
        figures.append(
            ctx.save_figure(track_figure(tracks, k), f"availability_fig{fig_no}_track_n{k}.png")
        )
    rows = []
    for t in tracks:
        s2, s3 = t.stats(2), t.stats(3)
        ref = paper.TABLE2.get(t.rate_deg_s)
        row = [f"{t.rate_deg_s:.2f}"]
        for col in ("spatial", "mean", "max", "min"):
            row.append(f"{percent(s2[col])} / {percent(s3[col])}")
            row.append(f"{ref[col][0]:.1f} / {ref[col][1]:.1f}" if ref else "–")
        rows.append(row)
    header = ["rate (deg/s)"]
    for col in ("spatial", "mean", "max", "min"):
        header += [f"{col}: ours", "paper"]
    node_table = _node_table(ctx, analysis, curve, tracks, node0, other_nodes, data)
    t0 = tracks[0]
    return f"""
<h3>Along-track dynamic availability</h3>
<p>Great-circle tracks of inclination {t0.inclinations_deg[0]:g} ... {t0.inclinations_deg[-1]:g}
deg ({len(t0.inclinations)} tracks) to the celestial equator, all through the node at RA
{t0.node_deg:g} deg, each sampled at {t0.n_samples:,} equally spaced orientations while the
sensor slews along it ({esc(curve.label)}). Table 2 of the paper beside ours,
N<sub>min</sub> = 2 / 3, in percent.</p>
{table(header, rows, classes=["num"] + ["num", "num paper"] * 4)}
<p class="note">The tracks of one family all cross at their two nodes, so the samples crowd
there (about 8 % of every track lies within one field radius of a node, against 0.9 % of the
sky): the mean over inclinations is a weighted sky average, not the spatial one, and it depends
on where the node lies on the sky. The paper does not give its node (nor the inclination step);
its along-track means exceed its spatial values at every rate. The statistics for other nodes
show how much the choice matters:</p>
{node_table}
{
        figure_html(
            figures[-2],
            "Along-track availability against inclination, N<sub>min</sub> = 2; "
            "dotted lines: spatial dynamic availability at the same rate. The paper's Fig. 16.",
            "along-track availability, N_min 2",
        )
    }
{
        figure_html(
            figures[-1],
            "The same for N<sub>min</sub> = 3; the paper's Fig. 17.",
            "along-track availability, N_min 3",
        )
    }
"""


def fidelity_part(
    ctx: ReportContext, sensor: Sensor, *, stars: object, curve: ThresholdCurve, data: dict
) -> str:
    """Return the full-fidelity check: rendered frames through the detector, per rate.

    Renders from the catalogue the report was built from (``ctx.catalog``); a report built
    from a star set alone has none, and the part says so.

    Parameters
    ----------
    ctx : ReportContext
        The report being built (catalogue, seed, progress).
    sensor : Sensor
        The sensor whose frames are rendered and detected.
    stars : object
        The report's primary star set (unused: the frames are rendered from ``ctx.catalog``).
    curve : ThresholdCurve
        m_t(w), the threshold model checked.
    data : dict
        The section's numbers: ``"fidelity"`` is set.

    Returns
    -------
    str
        HTML.
    """
    if not FIDELITY_RATES_DEG_S or FIDELITY_FRAMES < 1:
        return "<h3>Full-fidelity check</h3><p class='note'>Not run (no rates configured).</p>"
    ctx.progress("availability: full-fidelity check (rendered frames)")
    catalog = ctx.catalog
    if catalog is None:
        return (
            "<h3>Full-fidelity check</h3><p class='note'>Skipped: the catalogue object is "
            "needed to render frames (the report was built from a star set alone).</p>"
        )
    checks = []
    try:
        for rate in FIDELITY_RATES_DEG_S:
            ctx.progress(f"availability: rendered frames at {rate:g} deg/s")
            checks.append(
                fidelity_check(
                    sensor,
                    catalog,
                    curve,
                    rate_rad_s=rate * DEG,
                    n_trials=FIDELITY_FRAMES,
                    max_mag=paper.MAX_MAG,
                    rng=ctx.seed,
                )
            )
    except InputError as exc:
        return f"<h3>Full-fidelity check</h3><p class='note'>Skipped: {esc(exc)}.</p>"
    data["fidelity"] = [c.to_dict() for c in checks]
    rows = [
        [
            f"{c.rate_deg_s:g}",
            f"{c.threshold_mag:.2f}",
            percent(c.model_availability),
            percent(c.frame_availability),
            f"{c.model_counts.mean():.2f}",
            f"{c.frame_counts.mean():.2f}",
            str(c.optimistic),
            str(c.pessimistic),
        ]
        for c in checks
    ]
    header = [
        "rate (deg/s)",
        "m<sub>t</sub>",
        "model available (%)",
        "frames available (%)",
        "model stars / field",
        "detected stars / frame",
        "model optimistic",
        "model pessimistic",
    ]
    return f"""
<h3>Full-fidelity check</h3>
<p>{FIDELITY_FRAMES} frames per rate rendered at random attitudes while slewing about the camera
y axis (streaks along the rows; {esc(curve.label)}, stars &le; {paper.MAX_MAG} of
{esc(getattr(catalog, "name", ""))}), passed through the sensor's detector; a detection counts
when it lies on a true star's streak. The threshold model counts the stars &le; m<sub>t</sub>(w)
in the same (rectangular) detector field at the same attitude. N<sub>min</sub> = 3. The last two
columns count the frames where the model calls the attitude available and the frames do not
(optimistic) and the reverse (pessimistic); the model's counts miss partial stars at the edges,
stars near the threshold that noise lifts over it or pushes under, and streaks that merge.</p>
{table(header, rows, classes=["num"] * 8)}
"""
