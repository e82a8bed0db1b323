"""The mission availability timeline: stars per head, blinded intervals, available or not."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from starsense.analysis.mission.results import outages
from starsense.plotting.figure import new_figure

__all__ = ["mission_timeline_figure"]

_BODY_COLOURS = {"sun": "#f2b705", "moon": "#8c8c8c", "earth": "#3a7bd5"}


def _spans(ax, t_h, mask, step_h, colour, label, y0=0.0, y1=1.0, transform=None):
    """Shade the runs of `mask` (bool, per step) on `ax`; return whether any was drawn."""
    _, _, runs = outages(~np.asarray(mask, dtype=bool), 1.0)
    for k, (a, b) in enumerate(runs):
        ax.axvspan(
            t_h[a],
            t_h[b - 1] + step_h,
            ymin=y0,
            ymax=y1,
            color=colour,
            alpha=0.35,
            lw=0,
            label=label if k == 0 else None,
        )
    return len(runs) > 0


def mission_timeline_figure(result, max_points: int = 20_000) -> Figure:
    """Return the timeline of a mission run (one panel per head, then the availability strip).

    Each head's panel shows the stars detected against time (h) over shaded intervals where
    the Sun, the Moon or the Earth blinds it; the last panel shows which heads, and whether
    any, have an attitude.

    Parameters
    ----------
    result : MissionResult
        The run (:func:`starsense.analysis.mission.mission_availability`).
    max_points : int
        Steps drawn per curve at most (the counts are decimated by taking the minimum over
        each group of steps, so that a dip is never hidden).

    Returns
    -------
    matplotlib.figure.Figure
    """
    heads = result.heads
    fig = new_figure(9.0, 1.7 * len(heads) + 2.0)
    axes = fig.subplots(
        len(heads) + 1, 1, sharex=True, height_ratios=[3] * len(heads) + [1 + 0.4 * len(heads)]
    )
    t_h = result.t_s / 3600.0
    step_h = result.step_s / 3600.0
    group = max(1, -(-t_h.size // max_points))
    n_groups = -(-t_h.size // group)
    pad = n_groups * group - t_h.size
    for ax, h in zip(axes[:-1], heads, strict=False):
        stars = np.concatenate([h.stars, np.repeat(h.stars[-1:], pad)]).reshape(n_groups, group)
        ax.step(
            t_h[::group], stars.min(axis=1), where="post", color="k", lw=0.8, label="stars detected"
        )
        for body, colour in _BODY_COLOURS.items():
            _spans(ax, t_h, getattr(h, f"{body}_blinded"), step_h, colour, f"{body} blinded")
        n_min = result.meta.get("n_min", 3)
        ax.axhline(n_min, color="tab:red", lw=0.8, ls="--", label=f"N_min = {n_min}")
        ax.set_ylabel("stars")
        ax.set_title(
            f"{h.name}: available {100 * h.available.mean():.2f} %", fontsize=9, loc="left"
        )
        ax.legend(fontsize=7, loc="upper right", ncols=5)
    strip = axes[-1]
    rows = [(h.name, h.available) for h in heads] + [("any head", result.combined)]
    labelled = {"available": False, "not available": False}
    for i, (_, avail) in enumerate(rows):
        y0, y1 = (len(rows) - 1 - i) / len(rows), (len(rows) - i) / len(rows)
        for mask, colour, label in (
            (avail, "tab:green", "available"),
            (~avail, "tab:red", "not available"),
        ):
            drawn = _spans(
                strip, t_h, mask, step_h, colour, None if labelled[label] else label, y0, y1
            )
            labelled[label] |= drawn
    strip.set_yticks(
        [(len(rows) - 0.5 - i) / len(rows) for i in range(len(rows))],
        [r[0] for r in rows],
        fontsize=8,
    )
    strip.set_ylim(0, 1)
    strip.set_xlim(t_h[0], t_h[-1] + step_h)
    strip.set_xlabel(f"time from {result.meta.get('start', 'the start')} (h)")
    strip.legend(fontsize=7, loc="upper right", ncols=2)
    title = "; ".join(str(result.meta[k]) for k in ("orbit", "attitude") if k in result.meta)
    fig.suptitle(title or "mission availability", fontsize=10)
    return fig
