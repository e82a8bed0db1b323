"""The statement as a pointing budget's table (CSV) and as text.

The CSV has one row per error term, then the totals; its columns (documented in
``docs/guides/ecss.md``): ``term``, ``ecss_class``, ``distribution``, ``source``,
``gaussian``, ``counted``, ``confidence``, ``unit``, then per rate ``R`` (deg/s)
``acts_as_at_R_deg_s``, ``period_s_at_R_deg_s`` and ``x_arcsec_at_R_deg_s``,
``y_arcsec_at_R_deg_s``, ``z_arcsec_at_R_deg_s``. An empty cell is a value not known (the
source says why); the JSON's ``values`` hold the same numbers under ``{term}_{axis}_arcsec``.
"""

from __future__ import annotations

import csv
import io

from starsense.analysis.ecss.statement import AXES, Statement

__all__ = ["ROW_KEYS", "csv_columns", "statement_csv", "statement_lines", "statement_rows"]

_TOTALS = ("total_bias", "total_noise", "total")
#: the keys of a row of :func:`statement_rows` (``starsense datasheet --statement --json``)
ROW_KEYS = (
    "class",
    "axis",
    "rate_deg_s",
    "value_arcsec",
    "confidence",
    "distribution",
    "time_class",
    "source",
)
#: a total's time class: what it sums
_TOTAL_TIME = {"total_bias": "bias", "total_noise": "noise", "total": "bias_and_noise"}


def _rate_label(rate_deg_s: float) -> str:
    return f"{rate_deg_s:g}"


def csv_columns(rates_deg_s) -> list[str]:
    """Return the CSV's header for ``rates_deg_s`` (module docstring)."""
    cols = ["term", "ecss_class", "distribution", "source", "gaussian", "counted"]
    cols += ["confidence", "unit"]
    for r in rates_deg_s:
        lab = _rate_label(r)
        cols += [f"acts_as_at_{lab}_deg_s", f"period_s_at_{lab}_deg_s"]
        cols += [f"{a}_arcsec_at_{lab}_deg_s" for a in AXES]
    return cols


def _cell(x) -> str:
    return "" if x is None else repr(float(x))


def statement_csv(statement: Statement) -> str:
    """Return the statement as CSV text (module docstring)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(csv_columns(statement.rates_deg_s))
    conf = repr(statement.confidence)
    for t in statement.terms:
        row = [t["key"], t["ecss_class"], t["distribution"], t["source"]]
        row += [str(t["gaussian"]).lower(), str(t["counted"]).lower(), conf, "arcsec"]
        for at in t["at_rate"]:
            row += [at["acts_as"], _cell(at["period_s"])]
            row += [_cell(at[f"{a}_arcsec"]) for a in AXES]
        w.writerow(row)
    for name in _TOTALS:
        what = {"total_bias": "bias", "total_noise": "noise", "total": ""}[name]
        row = [name, "", "root sum square of the counted terms", "", "", "", conf, "arcsec"]
        for tot in statement.totals:
            row += [what, ""] + [_cell(tot[f"{name}_{a}_arcsec"]) for a in AXES]
        w.writerow(row)
    return buf.getvalue()


def statement_rows(statement: Statement) -> list[dict]:
    """Return the statement as flat rows: one per term (or total), axis and rate.

    Each row has exactly :data:`ROW_KEYS`: ``class`` the term's key (its ECSS class, or the
    class and the source within it: ``pixel_spatial_prnu``) or a total (``total_bias``,
    ``total_noise``, ``total``), ``axis`` X, Y or Z, ``rate_deg_s``, ``value_arcsec`` (at the
    confidence; None where not known, the source says why), ``confidence`` (probability),
    ``distribution``, ``time_class`` (``bias``, ``low_frequency``, ``high_frequency``,
    ``temporal_noise``; a total's ``bias``, ``noise`` or ``bias_and_noise``) and ``source``.

    Parameters
    ----------
    statement : Statement

    Returns
    -------
    list of dict
    """
    s, rows = statement, []
    for i, rate in enumerate(s.rates_deg_s):
        for t in s.terms:
            at = t["at_rate"][i]
            source = t["source"]  # a term left out of the totals says so (aberration)
            for a in AXES:
                values = (at[f"{a}_arcsec"], at["time_class"], t["distribution"], source)
                rows.append(_row(t["key"], a, rate, s.confidence, values))
        tot = s.totals[i]
        left = ", ".join(tot["not_known"]) or "none"
        for name in _TOTALS:
            source = (
                f"computed: root sum square of the counted terms acting as {_TOTAL_TIME[name]} "
                f"at this rate (not known, left out: {left})"
            )
            dist = "root sum square of the counted terms"
            for a in AXES:
                values = (tot[f"{name}_{a}_arcsec"], _TOTAL_TIME[name], dist, source)
                rows.append(_row(name, a, rate, s.confidence, values))
    return rows


def _row(name: str, axis: str, rate: float, confidence: float, values: tuple) -> dict:
    value, time_class, distribution, source = values
    return dict(
        zip(
            ROW_KEYS,
            (name, axis.upper(), rate, value, confidence, distribution, time_class, source),
            strict=True,
        )
    )


def _f(x) -> str:
    return "n/a" if x is None else f"{x:.3f}"


def statement_lines(statement: Statement) -> list[str]:
    """Return the statement as text lines (what ``starsense ecss`` prints)."""
    s = statement
    lines = [
        f"{s.sensor}: ECSS-E-ST-60-20C statement at {100 * s.confidence:.4g} % "
        f"(Gaussian factor {s.gaussian_factor:.3f}), arcsec X / Y / Z"
    ]
    for i, rate in enumerate(s.rates_deg_s):
        lines.append(f"  at {rate:g} deg/s:")
        for t in s.terms:
            at = t["at_rate"][i]
            counted = "" if t["counted"] else " (not in the total)"
            lines.append(
                f"    {t['key']:28s} {' / '.join(_f(at[f'{a}_arcsec']) for a in AXES):>26s}  "
                f"{at['acts_as']}{counted}; {t['source']}"
            )
        tot = s.totals[i]
        for name in _TOTALS:
            vals = " / ".join(_f(tot[f"{name}_{a}_arcsec"]) for a in AXES)
            lines.append(f"    {name:28s} {vals:>26s}")
        if tot["not_known"]:
            lines.append(f"    not known, left out of the totals: {', '.join(tot['not_known'])}")
    lines += [f"  note: {n}" for n in s.notes]
    return lines
