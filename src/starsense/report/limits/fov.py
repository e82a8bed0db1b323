"""Limit section, parts 2 and 3: the FOV-limited ideal sensor (Table 2) and Fig. 8."""

from __future__ import annotations

import math

import numpy as np

from starsense.plotting.limits import fov_table_figure, merit_figure
from starsense.references import fialho2019 as paper
from starsense.report.limits.parts import Part
from starsense.report.limits.tables import FovRow, fov_table
from starsense.report.page import esc, figure_html, fmt, fmt_int, fmt_ratio, table
from starsense.report.section import ReportContext
from starsense.units import RAD_TO_ARCSEC, RAD_TO_MAS

__all__ = ["fov_part", "merit_part"]

FIG_TABLE2 = "limit_table2_fov.png"
FIG8 = "limit_fig8_merit.png"

_D_CM = paper.TABLE2_DIAMETER_M * 100
_T_MS = paper.TABLE2_EXPOSURE_S * 1000

_AXES_TEXT = (
    "<p>Per axis, for each head: the 1-σ errors about the two cross-boresight axes (east and "
    "north of the target), their rms, and about the boresight (roll), mas. The narrower "
    "the FOV, the larger roll is against cross-boresight — why two heads at right angles "
    "gain so much (sec. 3.5).</p>"
)

_NO_SENSORS = (
    "<p class='note'>No sensors table was given. To place real sensors on this plot, "
    "pass a CSV with header <code>name,diameter_m,exposure_s,theta_rms_arcsec</code> or "
    "<code>name,diameter_m,exposure_s,sigma_cross_arcsec,sigma_roll_arcsec</code>; "
    "D is the diameter of the smallest sphere enclosing the optical head, baffle "
    "excluded (sec. 3.5). starsense ships no datasheet numbers.</p>"
)


def fov_part(ctx: ReportContext) -> tuple[Part, list[FovRow]]:
    """Build Table 2 beside the paper's, the per-axis errors and their figure.

    Returns
    -------
    Part
        HTML, numbers ("fov_table") and the figure.
    list of FovRow
        The table, for Fig. 8.
    """
    primary = ctx.primary
    ctx.progress("limit: FOV-limited sensors (Table 2)")
    fov_rows = fov_table(primary)
    part = Part()
    part.html.append("<h3>FOV-limited ideal sensor (Table 2)</h3>")
    part.html.append(
        f"<p>An ideal sensor with D = {_D_CM:g} cm and t = "
        f"{_T_MS:g} ms that sees only the stars in a cone of the given "
        "diameter, pointed at target 1 (RA 0 h, Dec 0°, near the First Point of Aries, few "
        "bright stars) or target 2 (RA 6 h, Dec 0°, Orion, many bright stars); “both” merges "
        "the two heads' Fisher matrices (a two-head tracker). Values in milli-arcseconds, "
        f"from {fmt_int(len(primary))} {esc(ctx.catalog_name)} stars ({esc(primary.colour)}); "
        "the paper's values beside ours.</p>"
    )
    part.html.append(_ours_and_paper_table(fov_rows))
    part.html.append(_ours_and_paper_note(ctx, fov_rows))
    part.html.append(_AXES_TEXT)
    part.html.append(_axes_table(fov_rows))
    fig_t2 = ctx.save_figure(_table2_figure(fov_rows), FIG_TABLE2)
    part.figures.append(fig_t2)
    part.html.append(
        figure_html(
            fig_t2,
            "θ<sub>rms</sub> (mas) of the FOV-limited ideal sensor against its FOV diameter, for "
            "each target and both merged: ours (filled, solid) from this catalogue and the "
            "paper's (open, dotted) from 2MASS. Counterpart: paper Table 2 (also the “ideal” "
            "points of paper Fig. 8). Singular FOVs are left out.",
            "theta_rms against FOV diameter, ours and the paper's",
        )
    )
    targets = paper.TABLE2_TARGETS
    part.data["fov_table"] = {
        "diameter_m": paper.TABLE2_DIAMETER_M,
        "exposure_s": paper.TABLE2_EXPOSURE_S,
        "colour": primary.colour,
        "targets": [{"label": lab, "ra_h": ra, "dec_deg": dec} for lab, ra, dec in targets],
        "rows": [
            {
                "fov_deg": r.fov_deg,
                **{lab: c.to_dict() for (lab, _, _), c in zip(targets, r.heads, strict=True)},
                "both": r.merged.to_dict(),
                "paper_mas": list(paper.TABLE2_MAS.get(r.fov_deg, ())),
            }
            for r in fov_rows
        ],
    }
    return part, fov_rows


def _ours_and_paper_table(fov_rows: list[FovRow]) -> str:
    rows = []
    for r in fov_rows:
        ref = paper.TABLE2_MAS.get(r.fov_deg)
        row = [f"{r.fov_deg:g}°"]
        for k, cell in enumerate([*r.heads, r.merged]):
            row.append(cell.html())
            row.append(fmt(ref[k]) if ref else "–")
            row.append(fmt_ratio(cell.theta_mas, ref[k]) if ref else "–")
        rows.append(row)
    head_names = [t[0] for t in paper.TABLE2_TARGETS] + ["both"]
    return table(
        ["FOV"] + ["ours", "paper", "ours / paper"] * len(head_names),
        rows,
        header_rows=[[("", 1)] + [(esc(h), 3) for h in head_names]],
        classes=["", *["num", "num paper", "num paper"] * len(head_names)],
    )


def _ours_and_paper_note(ctx: ReportContext, fov_rows: list[FovRow]) -> str:
    ratios = [
        cell.theta_mas / paper.TABLE2_MAS[r.fov_deg][k]
        for r in fov_rows
        if r.fov_deg in paper.TABLE2_MAS
        for k, cell in enumerate((*r.heads, r.merged))
        if cell.theta_mas is not None
    ]
    spread = (
        f" Here ours/paper ranges from {min(ratios):.2g} to {max(ratios):.2g}." if ratios else ""
    )
    return (
        "<p class='note'>The paper computed Table 2 from the 26 million 2MASS stars with "
        "J ≤ 12.575 (black bodies from J and H); ours come from "
        f"{fmt_int(len(ctx.primary))} {esc(ctx.catalog_name)} stars with black bodies from "
        f"{esc(ctx.primary.colour)}, so ours are expected to be larger: fewer stars carry less "
        "Fisher information. But the paper gives its own values a factor 2-3 of uncertainty "
        "from the black-body approximation of real spectra, which it finds larger than the "
        f"effect of catalogue size (sec. 3.4.1).{spread} A FOV with fewer than two stars "
        "(or stars all along one axis) cannot determine the attitude and is shown as "
        "“singular (n stars)”.</p>"
    )


def _axes_table(fov_rows: list[FovRow]) -> str:
    rows = []
    for r in fov_rows:
        for (label, _, _), cell in zip(paper.TABLE2_TARGETS, r.heads, strict=True):
            if cell.result is None:
                rows.append(
                    [f"{r.fov_deg:g}°", esc(label), fmt_int(cell.n_stars), cell.html(), "", "", ""]
                )
                continue
            sx, sy, sz = cell.result.axis_sigma_rad * RAD_TO_MAS
            cross = math.sqrt((sx**2 + sy**2) / 2.0)
            sigmas = [fmt(sx), fmt(sy), fmt(cross), fmt(sz)]
            rows.append([f"{r.fov_deg:g}°", esc(label), fmt_int(cell.n_stars), *sigmas])
    return table(
        ["FOV", "head", "stars in view", "σ east", "σ north", "σ cross (rms)", "σ roll"],
        rows,
        classes=["", "", "num", "num", "num", "num", "num"],
    )


def _mas(cells) -> np.ndarray:
    """theta_rms (mas) of FovCells, NaN where singular."""
    return np.array([np.nan if c.theta_mas is None else c.theta_mas for c in cells])


def _table2_figure(fov_rows: list[FovRow]):
    fovs = [r.fov_deg for r in fov_rows]
    ours = np.column_stack(
        [_mas([r.heads[k] if k < len(r.heads) else r.merged for r in fov_rows]) for k in range(3)]
    )
    ref = np.array([paper.TABLE2_MAS.get(f, (np.nan,) * 3) for f in fovs], dtype=float)
    return fov_table_figure(fovs, ours, ref)


def merit_part(ctx: ReportContext, g_primary: float, fov_rows: list[FovRow]) -> Part:
    """Build Fig. 8: theta_rms against D^2 t^1/2, with the user's real sensors and their table.

    Parameters
    ----------
    ctx : ReportContext
        The report's inputs.
    g_primary : float
        G of the primary colour system, rad m^2 s^1/2.
    fov_rows : list of FovRow
        Table 2, for the ideal FOV-limited points.

    Returns
    -------
    Part
        HTML, numbers ("sensors") and the figure.
    """
    ctx.progress("limit: comparison with real sensors (Fig. 8)")
    fig = merit_figure(
        g_primary,
        g_label=f"{ctx.catalog_name} ({ctx.primary.colour})",
        fovs_deg=[r.fov_deg for r in fov_rows],
        heads_mas=np.column_stack([_mas([r.heads[k] for r in fov_rows]) for k in range(2)]),
        merged_mas=_mas([r.merged for r in fov_rows]),
        sensor=(ctx.diameter_m, ctx.exposure_s),
        sensors=[(s.name, s.figure_of_merit, s.theta_rms_arcsec) for s in ctx.sensors],
    )
    fig8 = ctx.save_figure(fig, FIG8)
    part = Part(figures=[fig8])
    part.html.append("<h3>Against the figure of merit D<sup>2</sup> t<sup>½</sup> (Fig. 8)</h3>")
    part.html.append(
        figure_html(
            fig8,
            "θ<sub>rms</sub> (arcsec) against D<sup>2</sup> t<sup>½</sup>. Lines: the limit "
            "θ = G / (D<sup>2</sup> t<sup>½</sup>) for the paper's lower (solid) and upper "
            f"(dashed) G and for G from {esc(ctx.catalog_name)} (dotted). Blue: the FOV-limited "
            f"ideal single head of Table 2 (D = {_D_CM:g} cm, "
            f"t = {_T_MS:g} ms; filled target 1, open target 2), orange: two "
            "heads merged, plotted with D doubled as the paper does; labels give the FOV. Star: "
            "this report's sensor as an ideal whole-sky sensor."
            + (" Red: the real sensors of your table." if ctx.sensors else "")
            + " Counterpart: paper Fig. 8 (which also shows ten commercial sensors).",
            "theta_rms against D^2 t^1/2 with limit lines and sensors",
        )
    )
    part.html.extend(_sensors_html(ctx, g_primary) if ctx.sensors else [_NO_SENSORS])
    part.data["sensors"] = [
        {
            **s.to_dict(),
            "figure_of_merit_m2_s05": s.figure_of_merit,
            "limit_arcsec": g_primary / s.figure_of_merit * RAD_TO_ARCSEC,
        }
        for s in ctx.sensors
    ]
    return part


def _sensors_html(ctx: ReportContext, g_primary: float) -> list[str]:
    rows = []
    for s in ctx.sensors:
        lim = g_primary / s.figure_of_merit * RAD_TO_ARCSEC
        rows.append(
            [
                esc(s.name),
                fmt(s.diameter_m),
                fmt(s.exposure_s),
                fmt(s.figure_of_merit),
                fmt(s.sigma_cross_arcsec) if s.sigma_cross_arcsec is not None else "–",
                fmt(s.sigma_roll_arcsec) if s.sigma_roll_arcsec is not None else "–",
                fmt(s.theta_rms_arcsec),
                fmt(lim),
                fmt(s.theta_rms_arcsec / lim),
                fmt(s.theta_rms_rad * s.figure_of_merit / paper.G_INTERVAL[1]),
            ]
        )
    headers = [
        "sensor",
        "D (m)",
        "t (s)",
        "D<sup>2</sup> t<sup>½</sup>",
        "σ cross (″)",
        "σ roll (″)",
        "θ<sub>rms</sub> (″)",
        "limit, this catalogue (″)",
        "× above it",
        "× above the paper's upper limit",
    ]
    return [
        table(headers, rows, classes=["", *["num"] * 9]),
        "<p class='note'>θ<sub>rms</sub><sup>2</sup> = 2 σ<sub>cross</sub><sup>2</sup> + "
        "σ<sub>roll</sub><sup>2</sup> when the table gives per-axis errors (sec. 3.5).</p>",
    ]
