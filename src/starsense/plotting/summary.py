"""The vendor-style summary as one printable page (A4 portrait)."""

from __future__ import annotations

import textwrap

from matplotlib.figure import Figure

from starsense.plotting.figure import new_figure

__all__ = ["summary_page"]

#: A4 portrait, inches
_A4_IN = (8.27, 11.69)


def summary_page(summary: dict, *, note: str = "") -> Figure:
    """Return the summary (:func:`starsense.analysis.ecss.summary.vendor_summary`) as a page.

    Parameters
    ----------
    summary : dict
        ``sensor``, ``confidence`` and ``lines`` (``item``, ``value``, ``unit``, ``source``).
    note : str
        A line under the table (what produced it: version, seed).

    Returns
    -------
    matplotlib.figure.Figure
        A4 portrait; save it with :func:`starsense.plotting.figure.save_pdf`.
    """
    fig = new_figure(*_A4_IN)
    fig.set_layout_engine(None)
    fig.text(0.07, 0.95, f"{summary['sensor']}: performance summary", fontsize=16, weight="bold")
    fig.text(
        0.07,
        0.925,
        f"ECSS-E-ST-60-20C error totals per axis at {100 * summary['confidence']:.4g} % "
        "(X, Y across the boresight, Z about it)",
        fontsize=9,
    )
    y = 0.88
    for line in summary["lines"]:
        value = f"{line['value']} {line['unit']}".strip()
        fig.text(0.07, y, textwrap.fill(line["item"], 48), fontsize=10, va="top")
        fig.text(0.55, y, value, fontsize=10, va="top", weight="bold")
        y -= 0.021 * (1 + line["item"].count("\n") + len(line["item"]) // 49)
        fig.text(0.09, y, line["source"], fontsize=7, va="top", color="0.35")
        y -= 0.03
    if note:
        fig.text(0.07, 0.04, note, fontsize=7, color="0.35")
    return fig
