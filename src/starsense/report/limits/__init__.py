"""Report section: the physical limit of attitude accuracy (Fialho & Mortari 2019, sec. 3.3-3.5).

Computed from the catalogue the report was given, one module per group of parts:

1. Fig. 7: theta_rms of the N brightest stars for D = 1 m, t = 1 s, per colour system, with the
   power-law extrapolation to the 3e11 stars of the Galaxy (:mod:`.brightest`);
2. Table 2: the FOV-limited "ideal" sensor (D = 10 cm, t = 10 ms) at two targets and merged, with
   the per-axis errors of each head (:mod:`.fov`);
3. Fig. 8: theta_rms against the figure of merit D^2 t^1/2, with the user's real sensors
   (:mod:`.fov`);
4. sec. 3.3.2: degradation of small or short-exposure sensors by stars delivering < 1 photon
   (:mod:`.stars`);
5. Table 1: the black-body fits of five reference stars (:mod:`.stars`).

The paper's own numbers come from :mod:`starsense.references.fialho2019`; the figures from
:mod:`starsense.plotting.limits`.
"""

from __future__ import annotations

from starsense.references import fialho2019 as paper
from starsense.references.fialho2019 import TABLE2_MAS as TABLE2_PAPER_MAS
from starsense.report.limits.brightest import INTRO, brightest_part, sensor_part, summary_rows
from starsense.report.limits.fov import fov_part, merit_part
from starsense.report.limits.stars import low_photon_part, table1_part
from starsense.report.limits.tables import FovCell, FovRow, Table1Row, fov_table, table1_rows
from starsense.report.section import ReportContext, Section

__all__ = [
    "KEY",
    "TABLE2_PAPER_MAS",
    "TITLE",
    "FovCell",
    "FovRow",
    "Table1Row",
    "fov_table",
    "limit_section",
    "table1_rows",
]

TITLE = "The physical limit (Fialho & Mortari 2019)"
KEY = "limit"


def limit_section(ctx: ReportContext) -> Section:
    """Build the "physical limit" section (Fialho & Mortari 2019, sec. 3.3-3.5).

    Parameters
    ----------
    ctx : ReportContext
        The report's inputs: the black-body stars, this sensor's D and t, real sensors, seed.

    Returns
    -------
    Section
    """
    data: dict = {
        "g_paper_interval_rad_m2_s05": list(paper.G_INTERVAL),
        "paper_extrapolated_rad": list(paper.FIG7_EXTRAPOLATED_RAD),
    }
    fig7, curves = brightest_part(ctx)
    g_cat = fig7.data["g_rad_m2_s05"]
    own_part, own = sensor_part(ctx)
    table2, fov_rows = fov_part(ctx)
    primary = ctx.primary.colour
    g_primary = g_cat[primary] if primary in g_cat else next(iter(g_cat.values()))
    parts = [
        fig7,
        own_part,
        table2,
        merit_part(ctx, g_primary, fov_rows),
        low_photon_part(ctx),
        table1_part(ctx),
    ]
    html = [INTRO]
    figures: list[str] = []
    for part in parts:
        html.extend(part.html)
        data.update(part.data)
        figures.extend(part.figures)
    return Section(
        key=KEY,
        title=TITLE,
        html="\n".join(html),
        figures=tuple(figures),
        summary=summary_rows(ctx, curves, own),
        data=data,
    )
