"""Figure of the slew study: m_t(w) against the paper's Table-2 thresholds over (PSF sigma, QE).

On the Agg canvas, outside pyplot.
"""

from __future__ import annotations

import matplotlib as mpl
import numpy as np
from matplotlib.figure import Figure

from starsense.analysis.slew_study import QE_SENSIBLE_RANGE, SlewStudy
from starsense.plotting.figure import new_figure
from starsense.references.dzamba2014 import MAX_MAG, TABLE2_IMPLIED_MT
from starsense.units import DEG, to_edge

__all__ = ["study_figure"]


def _curves(ax, study: SlewStudy, reference: tuple[float, float] | None) -> None:
    """Left panel: m_t against rate, each width at its best QE, beside the paper's points."""
    rates = to_edge(study.rates_rad_s, DEG)
    qe, shape = study.best_qe()
    cmap = mpl.colormaps["viridis"]
    n = len(study.sigmas_px)
    for i, sigma in enumerate(study.sigmas_px):
        if not np.isfinite(qe[i]):
            continue
        curve = study.thresholds([qe[i]])[i, 0]
        ax.plot(
            rates,
            curve,
            "o-",
            ms=3,
            lw=1,
            color=cmap(i / max(1, n - 1)),
            label=f"sigma {sigma:g} px, QE {qe[i]:.2f}: +/-{shape[i]:.2f} mag",
        )
    if reference is not None:
        sigma_ref, qe_ref = reference
        i = np.flatnonzero(np.isclose(study.sigmas_px, sigma_ref))
        if i.size:
            ax.plot(
                rates,
                study.thresholds([qe_ref])[i[0], 0],
                "k-",
                lw=2,
                label=f"preset as is: sigma {sigma_ref:g} px, QE {qe_ref:.2f}",
            )
    paper_w = np.array(sorted(TABLE2_IMPLIED_MT))
    lo = np.array([min(TABLE2_IMPLIED_MT[w]) for w in paper_w])
    hi = np.array([max(TABLE2_IMPLIED_MT[w]) for w in paper_w])
    mid = study.paper_threshold
    ax.errorbar(
        paper_w,
        mid,
        yerr=[mid - lo, hi - mid],
        fmt="rD",
        ms=7,
        capsize=4,
        label="paper, implied by Table 2 (bar: N_min = 2 vs 3)",
    )
    ax.plot([0.0], [MAX_MAG], "r*", ms=11, label="paper, static threshold (sec. 1.2)")
    ax.set_xlabel("cross-axis slew rate (deg/s)")
    ax.set_ylabel("threshold magnitude m_t")
    ax.set_title("m_t(w): each PSF width at the QE that fits it best")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)


def _heat_map(fig, ax, study: SlewStudy) -> None:
    """Right panel: worst |mismatch| over the paper's rates on the (sigma, QE) grid."""
    worst = study.worst()
    sig, qe = study.sigmas_px, study.qe_means
    mesh = ax.pcolormesh(
        np.arange(len(qe) + 1),
        np.arange(len(sig) + 1),
        worst,
        cmap="magma_r",
        vmin=0.0,
        vmax=min(1.0, np.nanmax(worst)),
    )
    for i in range(len(sig)):
        for j in range(len(qe)):
            if np.isfinite(worst[i, j]):
                ax.text(
                    j + 0.5,
                    i + 0.5,
                    f"{worst[i, j]:.2f}",
                    ha="center",
                    va="center",
                    fontsize=6,
                    color="w" if worst[i, j] > 0.5 else "k",
                )
    inside = np.flatnonzero((qe >= QE_SENSIBLE_RANGE[0]) & (qe <= QE_SENSIBLE_RANGE[1]))
    if inside.size:
        ax.axvline(inside[-1] + 1, color="c", lw=2, label=f"QE <= {QE_SENSIBLE_RANGE[1]:g}")
        ax.legend(fontsize=7, loc="upper right")
    ax.set_xticks(np.arange(len(qe)) + 0.5, [f"{q:.2f}" for q in qe], fontsize=7, rotation=90)
    ax.set_yticks(np.arange(len(sig)) + 0.5, [f"{s:g}" for s in sig], fontsize=7)
    ax.set_xlabel("mean QE over 400-800 nm")
    ax.set_ylabel("PSF sigma (px)")
    ax.set_title("worst |m_t - paper| at 1, 1.5, 2, 3 deg/s (mag)")
    fig.colorbar(mesh, ax=ax, label="mag")


def study_figure(study: SlewStudy, reference: tuple[float, float] | None = (1.5, 0.40)) -> Figure:
    """Draw the slew study: m_t(w) per PSF width and the worst-mismatch map (Dzamba 2014).

    Parameters
    ----------
    study : SlewStudy
        The sweep.
    reference : (float, float) or None
        (PSF sigma in px, mean QE) of the preset as shipped, drawn in black if its width was
        swept (the st16 preset's assumed 1.5 px and 0.40).

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig = new_figure(13.0, 5.2)
    left, right = fig.subplots(1, 2, width_ratios=[1.1, 1.0])
    _curves(left, study, reference)
    _heat_map(fig, right, study)
    fig.suptitle(
        f"{study.sensor_name}, {study.model} model: the unstated PSF width and QE "
        f"({study.n_trials} trials per point)"
    )
    return fig
