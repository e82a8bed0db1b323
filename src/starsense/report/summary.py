"""The report's vendor-style summary: the sensor's one page, in HTML and as ``summary.pdf``."""

from __future__ import annotations

from importlib.metadata import version

from starsense.analysis.ecss import ecss_statement
from starsense.analysis.ecss.export import statement_rows
from starsense.analysis.ecss.summary import vendor_summary
from starsense.plotting.figure import save_pdf
from starsense.plotting.summary import summary_page
from starsense.report.page import esc, table
from starsense.report.section import ReportContext
from starsense.units import DEG

__all__ = ["SUMMARY_PDF", "summary_part"]

#: the page's file in the report directory
SUMMARY_PDF = "summary.pdf"


def summary_part(ctx: ReportContext, sheet, settings) -> tuple[str, dict]:
    """Return the summary's HTML and JSON; write its PDF page into the report.

    The sensor's ECSS statement at rest and at the datasheet's rate (1 sigma, on the sheet's
    sky: :func:`~starsense.analysis.ecss.ecss_statement`), and the datasheet's availability and
    frames (:func:`~starsense.analysis.ecss.summary.vendor_summary`).

    Parameters
    ----------
    ctx : ReportContext
        The sensor, catalogue, mass and power (given or not).
    sheet : Datasheet
        The report's datasheet of the sensor.
    settings : DatasheetSettings
        Its settings.

    Returns
    -------
    str, dict
    """
    ctx.progress(f"performance summary of {ctx.sensor.name}")
    rates = (0.0, settings.rate_rad_s / DEG)
    statement = ecss_statement(
        ctx.sensor, ctx.catalog, rates_deg_s=rates, settings=settings, sheet=sheet
    )
    summary = vendor_summary(
        sheet.to_dict(),
        statement_rows(statement),
        confidence=statement.confidence,
        sensor=ctx.sensor,
        mass_kg=ctx.mass_kg,
        power_w=ctx.power_w,
    )
    note = f"starsense {version('starsense')}, seed {settings.seed}"
    save_pdf(summary_page(summary, note=note), ctx.work_dir / SUMMARY_PDF)
    rows = [
        [esc(line["item"]), esc(f"{line['value']} {line['unit']}".strip()), esc(line["source"])]
        for line in summary["lines"]
    ]
    html = f"""
<h3>Performance summary</h3>
<p>The first page of a vendor's datasheet, from the numbers above: accuracy per axis from the
ECSS statement's totals, the rest from the prediction and this run's frames; mass and power as
given. As a printable page: <a href="{SUMMARY_PDF}">{SUMMARY_PDF}</a>.</p>
{table(["", "value", "from"], rows, classes=["", "num", ""])}
"""
    return html, summary
