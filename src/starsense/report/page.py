"""Plain-HTML building blocks of the report: tables, figures, number formats, the page shell.

No templates and no JavaScript: every helper returns a string of HTML, with text escaped.
"""

from __future__ import annotations

import html
import math
from collections.abc import Iterable, Sequence

# figures are drawn by starsense.plotting; new_figure stays importable here for the sections
from starsense.plotting.figure import new_figure

__all__ = [
    "CSS",
    "esc",
    "figure_html",
    "fmt",
    "fmt_int",
    "fmt_ratio",
    "fmt_rel",
    "new_figure",
    "page",
    "table",
    "yes_no",
]

CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", Helvetica, Arial, sans-serif;
       max-width: 1100px; margin: 2em auto; padding: 0 1em; color: #1d232a; line-height: 1.45; }
h1 { margin-bottom: 0.1em; }
h2 { border-bottom: 2px solid #c9d3de; padding-bottom: 0.2em; margin-top: 2em; }
h3 { margin-top: 1.6em; }
.meta { color: #5b6773; font-size: 0.9em; margin-top: 0; }
.summary { background: #eef4fa; border: 1px solid #b8cbe0; border-radius: 6px;
           padding: 0.6em 1.2em; margin: 1.2em 0; }
.summary table { border: none; margin: 0.3em 0; }
.summary td { border: none; padding: 0.15em 1em 0.15em 0; vertical-align: top; }
.summary td:first-child { font-weight: 600; white-space: nowrap; }
table { border-collapse: collapse; margin: 0.8em 0; font-size: 0.92em; }
th, td { border: 1px solid #c9d3de; padding: 0.3em 0.6em; }
th { background: #f2f5f8; text-align: center; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
td.paper { color: #5b6773; }
td.bad { color: #a4262c; }
.ok { color: #1a7f37; font-weight: 600; }
.no { color: #a4262c; font-weight: 600; }
figure { margin: 1em 0; }
figure img { max-width: 100%; border: 1px solid #e1e6eb; }
figcaption { font-size: 0.9em; color: #3d4853; max-width: 900px; }
.note { font-size: 0.9em; color: #3d4853; }
nav ul { padding-left: 1.2em; }
code { background: #f2f5f8; padding: 0 0.2em; }
"""


def esc(text) -> str:
    """Return ``text`` as escaped HTML."""
    return html.escape(str(text))


def fmt(x, digits: int = 3) -> str:
    """Format a number with ``digits`` significant digits (e-notation when tiny or huge)."""
    if x is None:
        return "–"
    x = float(x)
    if math.isnan(x):
        return "n/a"
    if math.isinf(x):
        return "∞" if x > 0 else "−∞"
    if x != 0 and (abs(x) < 1e-3 or abs(x) >= 1e6):
        m, e = f"{x:.{digits - 1}e}".split("e")
        return f"{m.replace('-', '−')}×10<sup>{int(e):d}</sup>".replace("<sup>-", "<sup>−")
    if abs(x) >= 10**digits:
        return f"{x:,.0f}".replace("-", "−")
    return f"{x:.{digits}g}".replace("-", "−")


def fmt_int(n) -> str:
    """Format an integer with thousands separators."""
    return f"{int(n):,}"


def fmt_rel(ours, paper) -> str:
    """Format the relative difference ours/paper - 1, in percent."""
    if ours is None or not math.isfinite(float(ours)):
        return "–"
    return f"{(float(ours) / float(paper) - 1.0) * 100.0:+.1f} %".replace("-", "−")


def fmt_ratio(ours, paper) -> str:
    """Format ours/paper as a factor."""
    if ours is None or not math.isfinite(float(ours)):
        return "–"
    return f"{float(ours) / float(paper):.3g}"


def yes_no(flag: bool, yes: str = "yes", no: str = "no") -> str:
    """Return ``yes`` in green or ``no`` in red, as HTML."""
    return f'<span class="ok">{esc(yes)}</span>' if flag else f'<span class="no">{esc(no)}</span>'


def table(
    headers: Sequence[str],
    rows: Iterable[Sequence],
    *,
    header_rows: Sequence[Sequence[tuple[str, int]]] = (),
    classes: Sequence[str] | None = None,
) -> str:
    """Return an HTML table.

    Cells are HTML already (use :func:`esc` / :func:`fmt`); ``classes`` gives a CSS class per
    column ("num", "paper", ""). ``header_rows`` are extra header rows above ``headers`` given as
    (html, colspan) cells.
    """
    out = ["<table>", "<thead>"]
    for hr in header_rows:
        out.append(
            "<tr>" + "".join(f'<th colspan="{span}">{cell}</th>' for cell, span in hr) + "</tr>"
        )
    out.append("<tr>" + "".join(f"<th>{h}</th>" for h in headers) + "</tr>")
    out.append("</thead><tbody>")
    for row in rows:
        cells = []
        for i, cell in enumerate(row):
            cls = classes[i] if classes and i < len(classes) and classes[i] else ""
            cells.append(f'<td class="{cls}">{cell}</td>' if cls else f"<td>{cell}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</tbody></table>")
    return "\n".join(out)


def figure_html(filename: str, caption: str, alt: str) -> str:
    """Return a figure block.

    ``caption`` is HTML and must say what the figure shows and what its counterpart in the paper
    is.
    """
    return (
        f'<figure><img src="{esc(filename)}" alt="{esc(alt)}">'
        f"<figcaption>{caption}</figcaption></figure>"
    )


def page(title: str, *, meta_html: str, summary_rows, nav_items, body: str) -> str:
    """Return the whole HTML document.

    Parameters
    ----------
    title : str
        The document's title (plain text, escaped here).
    meta_html : str
        The line under the title (HTML).
    summary_rows : iterable of (str, str)
        The summary table's rows: label and value (HTML).
    nav_items : iterable of (str, str)
        The sections' keys and titles, for the navigation.
    body : str
        The sections (HTML).

    Returns
    -------
    str
    """
    summary = "".join(f"<tr><td>{label}</td><td>{value}</td></tr>" for label, value in summary_rows)
    nav = "".join(f'<li><a href="#{esc(key)}">{esc(t)}</a></li>' for key, t in nav_items)
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{esc(title)}</title>
<style>{CSS}</style>
</head>
<body>
<h1>{esc(title)}</h1>
<p class="meta">{meta_html}</p>
<div class="summary"><strong>Summary</strong>
<table>{summary}</table></div>
<nav><strong>Sections</strong><ul>{nav}</ul></nav>
{body}
</body>
</html>
"""
