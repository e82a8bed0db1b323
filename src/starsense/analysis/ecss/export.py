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

__all__ = ["csv_columns", "statement_csv", "statement_lines"]

_TOTALS = ("total_bias", "total_noise", "total")


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
