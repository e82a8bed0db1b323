"""Report section: availability over the mission the sensor TOML names (its ``[mission]``).

Dzamba & Enright 2014, Fig. 1, last row; :mod:`starsense.analysis.mission`. The heads are the
report's sensor on the mountings the table lists; the threshold is the sensor's Reed
tolerable-slew curve on its own grid (:meth:`ReportContext.detection`, the datasheet's run), the
stars the report's primary star set to the sensor's threshold at rest.
"""

from __future__ import annotations

import numpy as np

from starsense.analysis.availability import ThresholdCurve, field_of_view
from starsense.analysis.mission import (
    Head,
    TimeGrid,
    mission_availability,
    mission_geometry,
    parse_time,
)
from starsense.analysis.mission.specs import parse_attitude, parse_head, parse_orbit
from starsense.errors import InputError
from starsense.plotting.mission import mission_timeline_figure
from starsense.report.page import esc, figure_html, fmt, table
from starsense.report.section import ReportContext, Section

__all__ = ["mission_section"]

KEY, TITLE = "mission", "Availability over a mission"


def _heads(ctx: ReportContext, plan, curve: ThresholdCurve) -> list[Head]:
    sensor = ctx.sensor
    fov = field_of_view(sensor)
    heads, seen = [], {}
    for entry in plan.heads:
        spec = sensor.name + (entry if entry[:1] in ("", "=") else "@" + entry)
        _, label, mounting = parse_head(spec, f"{sensor.name}: [mission] heads")
        seen[label] = seen.get(label, 0) + 1
        label = label if seen[label] == 1 else f"{label}#{seen[label]}"
        kwargs = {} if mounting is None else {"mounting": mounting}
        heads.append(Head(label, fov, curve, exclusion=sensor.exclusion, **kwargs))
    return heads


def _mission(ctx: ReportContext, plan) -> tuple:
    """Return (result, start, orbit, attitude profile) of the sensor's [mission] table."""
    sensor = ctx.sensor
    where = f"{sensor.name}: [mission]"
    start = parse_time(plan.start, f"{where} start")
    orbit = parse_orbit(plan.orbit, start, f"{where} orbit")
    profile = parse_attitude(plan.attitude, f"{where} attitude")
    det = ctx.detection()  # the sensor's own limit and m_t(w), as in its datasheet
    if det.curve is None:
        raise InputError(f"{where}: {sensor.name} detects no star at rest")
    heads = _heads(ctx, plan, det.curve)
    grid = TimeGrid.span(start, plan.duration_h * 3600.0, plan.step_s)
    stars = ctx.primary
    keep = stars.magnitude <= det.static_mag
    meta = {
        "start": start.isot,
        "orbit": orbit.label,
        "attitude": profile.label,
        "mission": plan.name,
    }
    res = mission_availability(
        mission_geometry(grid, orbit, profile),
        heads,
        vectors=stars.vectors[keep],
        magnitudes=stars.magnitude[keep],
        meta=meta,
    )
    return res, start, orbit, profile


def _rows(data: dict) -> list[list[str]]:
    """Return the table's rows: one per head, then any head (the combined availability)."""
    rows = [
        [
            esc(h["name"]),
            fmt(100 * h["available_fraction"], 4),
            fmt(100 * h["sun_blinded_fraction"], 3),
            fmt(100 * h["moon_blinded_fraction"], 3),
            fmt(100 * h["earth_blinded_fraction"], 3),
            str(h["outages"]),
            f"{h['longest_outage_s']:.0f}",
            fmt(h["mean_stars"], 3),
        ]
        for h in data["heads"]
    ]
    c = data["combined"]
    rows.append(
        [
            "<b>any head</b>",
            fmt(100 * c["available_fraction"], 4),
            "",
            "",
            "",
            str(c["outages"]),
            f"{c['longest_outage_s']:.0f}",
            "",
        ]
    )
    return rows


def mission_section(ctx: ReportContext) -> Section:
    """Availability per head and combined along the sensor TOML's mission, with its timeline."""
    sensor = ctx.sensor
    plan = None if sensor is None else sensor.mission
    if plan is None:
        return Section(
            KEY,
            TITLE,
            "<p>The sensor's TOML names no mission (no [mission] "
            "table): see <code>starsense availability mission</code>.</p>",
        )
    ctx.progress("availability over the mission")
    res, start, orbit, profile = _mission(ctx, plan)
    data = res.to_dict()
    figure = ctx.save_figure(mission_timeline_figure(res), "mission_timeline.png")
    rows = _rows(data)
    c = data["combined"]
    mean_rate = float(np.mean([h.rate_rad_s.mean() for h in res.heads])) * 180.0 / np.pi
    html = f"""
<p>Mission <b>{esc(plan.name or plan.orbit)}</b>: {esc(orbit.label)}; {esc(profile.label)};
{res.steps:,} steps of {plan.step_s:g} s from {esc(start.isot)} UTC. Heads: {esc(sensor.name)}
on the mountings of its [mission] table; exclusion {
        esc(str(sensor.exclusion and sensor.exclusion.to_dict()))
    }. Stars: {esc(ctx.catalog_name)} &le; {ctx.detection().static_mag:.2f} (the sensor's
threshold at rest); threshold
m<sub>t</sub>(w) from the Reed tolerable-slew curve at each head's cross-boresight rate (mean
{mean_rate:.3f} deg/s). A head has an attitude from the first step with 3 detected stars
(lost-in-space) until fewer than 2 are detected.</p>
{
        table(
            [
                "head",
                "available (%)",
                "Sun-blinded (%)",
                "Moon-blinded (%)",
                "Earth-blinded (%)",
                "outages",
                "longest outage (s)",
                "mean stars",
            ],
            rows,
            classes=["", "num", "num", "num", "num", "num", "num", "num"],
        )
    }
{
        figure_html(
            figure,
            "Stars detected per head against time, with the intervals the Sun, the "
            "Moon or the Earth blinds it, and which heads (and whether any) have an attitude "
            "(the along-mission row of Dzamba &amp; Enright's Fig. 1).",
            "mission timeline",
        )
    }
"""
    summary = (("Mission availability (any head)", f"{100 * c['available_fraction']:.2f} %"),)
    return Section(KEY, TITLE, html, (figure,), summary, data)
