"""``starsense datasheet --statement``: the ECSS statement in the datasheet, checked on its frames.

The statement is :func:`starsense.analysis.ecss.ecss_statement` on the datasheet's own sky
(the sheet just built: its limiting magnitude, slew run and attitudes); its coverage is
:mod:`starsense.analysis.ecss.coverage` on the datasheet's Monte Carlo frames, with the rates
the datasheet did not run rendered here (``--trials`` frames each).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path
from typing import Annotated

import typer

from starsense._io import atomic_write, check_output
from starsense.analysis.ecss import ecss_statement, parse_confidence
from starsense.analysis.ecss.coverage import coverage_rows, frame_errors_arcsec, frame_errors_at
from starsense.analysis.ecss.export import statement_csv, statement_lines, statement_rows
from starsense.analysis.ecss.statement import check_rates
from starsense.analysis.ecss.summary import vendor_summary
from starsense.cli.common import parse_floats
from starsense.errors import InputError
from starsense.plotting.figure import save_pdf
from starsense.plotting.summary import summary_page

__all__ = [
    "DEFAULT_STATEMENT_RATES_DEG_S",
    "BudgetCsvOpt",
    "ConfidenceOpt",
    "MassOpt",
    "PowerOpt",
    "StatementOpt",
    "StatementRatesOpt",
    "StatementRequest",
    "SummaryPdfOpt",
    "statement_request",
    "statement_section",
    "summary_lines",
]

#: the statement's rates when --rates is not given (and the fastest keeping 99 %), deg/s
DEFAULT_STATEMENT_RATES_DEG_S = (0.0, 0.5, 1.0, 2.0)

StatementOpt = Annotated[
    bool,
    typer.Option(
        "--statement",
        help="Add the ECSS-E-ST-60-20C performance statement (error classes per axis X, Y, Z "
        "and rate, at --confidence) and its coverage: the fraction of the Monte Carlo frames "
        "inside its 1-sigma and 3-sigma totals per axis and rate. Rates the datasheet's Monte "
        "Carlo did not run are rendered too, --trials frames each.",
    ),
]
ConfidenceOpt = Annotated[
    str | None,
    typer.Option(
        "--confidence",
        help="With --statement: probability each value is not exceeded, per axis: 0.95, 95, "
        "95%, 1sigma, 2sigma or 3sigma [default: 1sigma].",
    ),
]
StatementRatesOpt = Annotated[
    str | None,
    typer.Option(
        "--rates",
        help="With --statement: body rates, deg/s, comma-separated [default: 0,0.5,1,2 and "
        "the fastest rate keeping 99 % lost in space].",
    ),
]
BudgetCsvOpt = Annotated[
    Path | None,
    typer.Option(
        "--budget-csv",
        help="With --statement: write the statement as a pointing budget's CSV table to FILE.",
    ),
]

SummaryPdfOpt = Annotated[
    Path | None,
    typer.Option(
        "--summary-pdf",
        help="With --statement: write the vendor-style one-page summary (accuracy per axis at "
        "--confidence, tracking rate, lost in space, update rate, coverage, exclusion, mass, "
        "power) as a PDF page to FILE.",
    ),
]
MassOpt = Annotated[
    float | None,
    typer.Option("--mass-kg", help="With --statement: the unit's mass, kg, for the summary."),
]
PowerOpt = Annotated[
    float | None,
    typer.Option("--power-w", help="With --statement: the unit's power, W, for the summary."),
]


@dataclass(frozen=True)
class StatementRequest:
    """What ``--statement`` asked: confidence, rates (None: default), CSV, summary, mass, power."""

    confidence: float
    rates_deg_s: tuple | None
    budget_csv: Path | None
    summary_pdf: Path | None = None
    mass_kg: float | None = None
    power_w: float | None = None


def statement_request(
    statement: bool, options: tuple, *, single: bool, several: bool = False
) -> StatementRequest | None:
    """Check the statement's options before any work; None without ``--statement``.

    Parameters
    ----------
    statement : bool
        ``--statement`` given.
    options : tuple
        ``(--confidence, --rates, --budget-csv, --summary-pdf, --mass-kg, --power-w)`` as
        given (None: not given).
    single : bool
        Rendered frames (no ``--centroids-only``, ``--against``).
    several : bool
        Several sensors (``--compare``): each gets its statement; ``--budget-csv`` (one
        sensor's table) is refused.

    Returns
    -------
    StatementRequest or None
    """
    confidence, rates, budget_csv, summary_pdf, mass_kg, power_w = options
    names = ("--confidence", "--rates", "--budget-csv", "--summary-pdf", "--mass-kg", "--power-w")
    if not statement:
        for name, value in zip(names, options, strict=True):
            if value is not None:
                raise InputError(f"{name} needs --statement (it sets the statement's {name[2:]})")
        return None
    if not single:
        raise InputError(
            "--statement states sensors on rendered frames: not with --centroids-only or --against"
        )
    for name, value in (("--budget-csv", budget_csv), ("--summary-pdf", summary_pdf)):
        if several and value is not None:
            raise InputError(
                f"{name} writes one sensor's table: give one sensor, or --json (every "
                "sensor's statement) with --compare"
            )
    for name, value in (("--mass-kg", mass_kg), ("--power-w", power_w)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise InputError(f"{name} = {value} must be a positive number")
    p = parse_confidence("1sigma" if confidence is None else confidence)
    rate_list = None
    if rates is not None:
        rate_list = check_rates(parse_floats(rates, "--rates", lo=0.0, hi=30.0))
    if budget_csv is not None:
        check_output(budget_csv, "--budget-csv")
    if summary_pdf is not None:
        check_output(summary_pdf, "--summary-pdf")
    return StatementRequest(p, rate_list, budget_csv, summary_pdf, mass_kg, power_w)


def _default_rates(sheet) -> tuple[tuple[float, ...], str | None]:
    """Return the default rates and the fastest keeping 99 % lost in space (or a note)."""
    keep99 = sheet.availability.fastest_rate_deg_s.lost_in_space.p99
    if keep99 is None:
        return DEFAULT_STATEMENT_RATES_DEG_S, "no rate keeps 99 % lost in space: not stated"
    return check_rates((*DEFAULT_STATEMENT_RATES_DEG_S, keep99)), None


def _coverage_lines(rows: list[dict]) -> list[str]:
    lines = []
    for i in range(0, len(rows), 3):
        group = rows[i : i + 3]
        r = group[0]
        head = (
            f"  coverage of the 1-sigma / 3-sigma bound at {r['rate_deg_s']:g} deg/s "
            f"({r['frames']} right solutions of {r['frames_rendered']} frames, {r['frames_from']})"
        )
        if r["reason"]:
            lines.append(f"{head}: not known ({r['reason']})")
            continue
        lines.append(f"{head}: {_cells(group, '')}")
        if all(g["inside_1sigma_sky_ensemble"] is not None for g in group):
            cells = _cells(group, "_sky_ensemble")
            lines.append(f"    of the sky ensemble's (a random attitude's) bounds: {cells}")
    if any("*" in line for line in lines):
        lines.append(
            "  * more or fewer inside than chance on this many frames explains (exact binomial "
            "95 %): the bound misses"
        )
    return lines


def _cells(group: list[dict], suffix: str) -> str:
    """``X 68 % / 100 %, ...``: a fraction that chance does not explain is starred."""

    def one(g: dict, tag: str) -> str:
        star = "*" if g[f"consistent_{tag}{suffix}"] is False else ""
        return f"{100 * g[f'inside_{tag}{suffix}']:.0f} %{star}"

    return ", ".join(f"{g['axis']} {one(g, '1sigma')} / {one(g, '3sigma')}" for g in group)


def statement_section(
    sensor, catalog, settings, *, sheet, request: StatementRequest, client=None
) -> tuple[dict, list[str]]:
    """Return the datasheet's ``statement`` (JSON) and its text lines; write ``--budget-csv``.

    Parameters
    ----------
    sensor : Sensor
    catalog : Catalog
        The datasheet's.
    settings : DatasheetSettings
        The datasheet's.
    sheet : Datasheet
        The datasheet built with them (its sky, slew run and Monte Carlo frames).
    request : StatementRequest
    client : dask.distributed.Client, optional
        Renders the rates the datasheet did not run.

    Returns
    -------
    dict
        ``rows`` (:func:`starsense.analysis.ecss.export.statement_rows`), ``coverage``
        (:func:`starsense.analysis.ecss.coverage.coverage_rows`), ``frame_errors`` (per rate,
        each right solution's X, Y, Z error, arcsec), ``confidence``, ``rates_deg_s``, notes.
    list of str
    """
    notes = []
    rates = request.rates_deg_s
    if rates is None:
        rates, note = _default_rates(sheet)
        notes += [note] if note else []
    statement = ecss_statement(
        sensor,
        catalog,
        confidence=request.confidence,
        rates_deg_s=rates,
        settings=settings,
        sheet=sheet,
    )
    frames = frame_errors_at(
        sensor,
        catalog,
        settings,
        rates_deg_s=statement.rates_deg_s,
        have=sheet.frame_errors_rad,
        client=client,
    )
    coverage = coverage_rows(statement, frames)
    section = {
        "confidence": statement.confidence,
        "gaussian_factor": statement.gaussian_factor,
        "rates_deg_s": list(statement.rates_deg_s),
        "rows": statement_rows(statement),
        "coverage": coverage,
        "frame_errors": frame_errors_arcsec(frames),
        "notes": [*statement.notes, *notes],
    }
    lines = statement_lines(statement) + [f"  note: {n}" for n in notes]
    lines += _coverage_lines(coverage)
    section["summary"] = vendor_summary(
        sheet.to_dict(),
        section["rows"],
        confidence=statement.confidence,
        sensor=sensor,
        mass_kg=request.mass_kg,
        power_w=request.power_w,
    )
    lines += summary_lines(section["summary"])
    files = []
    if request.budget_csv is not None:
        with atomic_write(request.budget_csv) as fh:
            fh.write(statement_csv(statement))
        files.append(str(request.budget_csv))
    if request.summary_pdf is not None:
        note = f"starsense {version('starsense')}, seed {settings.seed}"
        page = summary_page(section["summary"], note=note)
        files.append(str(save_pdf(page, request.summary_pdf)))
    if files:
        section["files"] = files
        lines += [f"wrote {f}" for f in files]
    return section, lines


def summary_lines(summary: dict) -> list[str]:
    """Return the summary (:func:`~starsense.analysis.ecss.summary.vendor_summary`) as text."""
    out = [f"summary ({summary['sensor']}):"]
    for line in summary["lines"]:
        out.append(f"  {line['item']}: {line['value']} {line['unit']}".rstrip())
    return out
