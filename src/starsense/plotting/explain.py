"""Why a frame solved or did not: the frame with its detections, patterns and matches.

On the Agg canvas, outside pyplot; takes ``ax=None`` and returns the figure.
"""

from __future__ import annotations

import textwrap

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from starsense.plotting.figure import new_figure

__all__ = ["explain_figure", "explain_text", "matched_catalogue_px"]

#: residual arrows are drawn this many times their length (residuals are ~0.1-1 px)
ARROW_GAIN = 20.0
#: the counts printed under the frame, in pipeline order, with their labels
_COUNT_LABELS = (
    ("pixels_above_threshold", "pixels above threshold"),
    ("hot_pixels", "hot pixels removed"),
    ("candidates", "candidates"),
    ("rejected_size", "rejected: size"),
    ("rejected_faint", "rejected: faint"),
    ("rejected_shape", "rejected: shape"),
    ("saturated", "saturated"),
    ("detections", "detections"),
    ("patterns_tried", "patterns tried"),
    ("hypotheses_verified", "hypotheses verified"),
    ("best_false_match_probability", "best false-match probability"),
)


def matched_catalogue_px(solution, catalog) -> tuple[np.ndarray, np.ndarray]:
    """Return the matched detections' indices and their catalogue stars' pixel positions.

    The catalogue stars are projected with the solution's attitude through its sensor model
    (distortion included), else through the pinhole of its field.

    Parameters
    ----------
    solution : Solution
        A solved frame (its ``matches``, ``rotation``, ``image_shape``, ``focal_px``).
    catalog : Catalog
        The catalogue it was solved with (the ids of ``matches``).

    Returns
    -------
    detection_index : ndarray of int, shape (M,)
    xy : ndarray, shape (M, 2)
        Pixel positions (x = column, y = row) of the matched catalogue stars.
    """
    if not solution.matches or solution.rotation is None:
        return np.empty(0, int), np.empty((0, 2))
    det_i = np.array([d for d, _ in solution.matches], dtype=int)
    ids = np.array([c for _, c in solution.matches])
    v_cam = solution.rotation.apply(catalog.vectors[np.atleast_1d(catalog.index_of(ids))])
    if solution.sensor is not None:
        x, y = solution.sensor.project(v_cam)
        return det_i, np.column_stack([x, y])
    rows, cols = solution.image_shape
    f = solution.focal_px
    x = (cols - 1) / 2.0 + f * v_cam[:, 0] / v_cam[:, 2]
    y = (rows - 1) / 2.0 + f * v_cam[:, 1] / v_cam[:, 2]
    return det_i, np.column_stack([x, y])


def _stretch(image: np.ndarray) -> tuple[float, float]:
    """Display range: the 90th to the 99.99th percentile (the noise dark, the stars white)."""
    lo, hi = np.percentile(image, [90.0, 99.99])
    return float(lo), float(max(hi, lo + 1e-9))


def explain_figure(
    image,
    detections,
    solution,
    *,
    catalog=None,
    n_pattern: int = 12,
    title: str = "",
    ax: Axes | None = None,
) -> Figure:
    """Draw a frame with what the solver saw: detections, pattern stars, matches, the reason.

    Every detection is circled; the ``n_pattern`` brightest, from which the identification
    builds its patterns, are squared; for a solved frame each matched catalogue star is a
    cross with an arrow from its detection (``ARROW_GAIN`` times the residual); the status, its
    reason in words and the per-stage counts are written under the frame.

    Parameters
    ----------
    image : array_like, shape (rows, columns)
        The frame as solved, counts.
    detections : Detections
        Its detections (brightest first).
    solution : Solution
        The solve's answer.
    catalog : Catalog, optional
        The catalogue the frame was solved with (needed to draw the matches).
    n_pattern : int
        Detections the identifier builds patterns from.
    title : str
        Figure title (the file name).
    ax : matplotlib Axes, optional
        Draw here instead of a new figure.

    Returns
    -------
    matplotlib.figure.Figure
    """
    a = np.asarray(image, dtype=np.float32)
    rows, cols = a.shape
    text_ax = None
    if ax is None:  # the frame above, the reason and the counts below
        height = 8.0 * rows / cols
        fig = new_figure(9.0, height + 1.6)
        grid = fig.add_gridspec(2, 1, height_ratios=[height, 1.1])
        ax, text_ax = fig.add_subplot(grid[0]), fig.add_subplot(grid[1])
        text_ax.axis("off")
    fig = ax.figure
    lo, hi = _stretch(a)
    ax.imshow(a, cmap="gray", vmin=lo, vmax=hi, origin="upper", interpolation="nearest")
    order = np.argsort(-np.asarray(detections.integrated_counts), kind="stable")
    x, y = np.asarray(detections.x), np.asarray(detections.y)
    ax.scatter(x, y, s=60, facecolors="none", edgecolors="tab:cyan", lw=0.8, label="detections")
    top = order[:n_pattern]
    ax.scatter(
        x[top], y[top], s=160, marker="s", facecolors="none", edgecolors="tab:orange", lw=1.0,
        label=f"the {len(top)} brightest: pattern stars",
    )  # fmt: skip
    if catalog is not None and solution.solved:
        det_i, xy = matched_catalogue_px(solution, catalog)
        ax.scatter(xy[:, 0], xy[:, 1], s=50, marker="+", color="tab:green", lw=1.2,
                   label=f"{len(det_i)} matched catalogue stars")  # fmt: skip
        ax.quiver(
            x[det_i], y[det_i], ARROW_GAIN * (xy[:, 0] - x[det_i]),
            ARROW_GAIN * (xy[:, 1] - y[det_i]), angles="xy", scale_units="xy", scale=1,
            color="tab:red", width=0.002, label=f"residual x {ARROW_GAIN:g}",
        )  # fmt: skip
    ax.set_xlim(-0.5, cols - 0.5)
    ax.set_ylim(rows - 0.5, -0.5)
    ax.set_xlabel("column, px")
    ax.set_ylabel("row, px")
    ax.legend(loc="upper right", fontsize=7, framealpha=0.7)
    ax.set_title(title or "solve", fontsize=9)
    where = (text_ax, 0.0, 1.0) if text_ax is not None else (ax, 0.0, -0.08)
    where[0].text(
        where[1], where[2], explain_text(solution), transform=where[0].transAxes, va="top",
        ha="left", fontsize=7, family="monospace",
    )  # fmt: skip
    return fig


def explain_text(solution) -> str:
    """Return the status, its reason and the per-stage counts as a few lines of text.

    Parameters
    ----------
    solution : Solution

    Returns
    -------
    str
    """
    head = f"{solution.status}: {solution.message}"
    if solution.solved:
        head += (
            f" - RA {solution.ra_deg:.4f} deg, Dec {solution.dec_deg:.4f} deg, "
            f"roll {solution.roll_deg:.3f} deg, FOV {solution.fov_deg:.3f} deg, "
            f"{solution.rmse_arcsec:.1f} arcsec rms"
        )
    lines = textwrap.wrap(head, 120)
    c = solution.counts
    parts = [
        f"{label} {c[key]:.2g}" if isinstance(c[key], float) else f"{label} {c[key]:,}"
        for key, label in _COUNT_LABELS
        if key in c
    ]
    lines += textwrap.wrap("; ".join(parts), 120)
    for note in solution.notes:
        lines += textwrap.wrap(f"note: {note}", 120)
    return "\n".join(lines)
