"""Figures outside pyplot: the Agg canvas, no display, no global state."""

from __future__ import annotations

from pathlib import Path

from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from starsense._io import atomic_path

__all__ = ["figure_and_axes", "new_figure", "save_pdf", "save_png"]


def new_figure(width_in: float = 8.0, height_in: float = 5.5) -> Figure:
    """Return a matplotlib figure on the Agg canvas, outside pyplot.

    Parameters
    ----------
    width_in, height_in : float
        Size, inches.

    Returns
    -------
    matplotlib.figure.Figure
        With a constrained layout.
    """
    fig = Figure(figsize=(width_in, height_in), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def figure_and_axes(ax: Axes | None, width_in: float, height_in: float) -> tuple[Figure, Axes]:
    """Return ``ax`` and its figure, or a new figure of the given size and its one axes."""
    if ax is not None:
        return ax.figure, ax
    fig = new_figure(width_in, height_in)
    return fig, fig.add_subplot()


def save_png(fig: Figure, path, dpi: int = 110) -> Path:
    """Write ``fig`` to the PNG file ``path`` atomically and return the path."""
    path = Path(path)
    with atomic_path(path, ".png") as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")
    return path


def save_pdf(fig: Figure, path) -> Path:
    """Write ``fig`` to the PDF file ``path`` atomically and return the path."""
    path = Path(path)
    with atomic_path(path, ".pdf") as tmp:
        fig.savefig(tmp, format="pdf")
    return path
