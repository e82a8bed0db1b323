"""Report section and figures: star-tracker availability (Dzamba & Enright 2014, sec. 1, 3.1, 4).

Figures (all on the Agg canvas, outside pyplot):

* :func:`sky_map_figure` — stars in the field per boresight, Mollweide projection, with the
  galactic plane (Figs. 4, 5, 14). Right ascension follows the astronomical convention: it
  increases to the **left** (east left, the sky seen from inside the celestial sphere), with
  0 h at the centre of the map and 12 h at both edges.
* :func:`static_curve_figure` — availability against the detection threshold m_t (Fig. 6).
* :func:`dynamic_figure` — spatial dynamic availability against slew rate (Fig. 11).
* :func:`track_figure` — along-track availability against track inclination (Figs. 16-17).
"""

from __future__ import annotations

import functools
import math
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from scipy.spatial import cKDTree

from starsense.analysis.availability import (
    N_MIN_CONSERVATIVE,
    N_MIN_LOST_IN_SPACE,
    N_MIN_TRACKING,
    PAPER_TABLE2,
    AvailabilityAnalysis,
    DynamicAvailability,
    StaticAvailability,
    ThresholdCurve,
    TrackAvailability,
    describe_fov,
    fidelity_check,
)
from starsense.errors import InputError
from starsense.geometry.attitude import radec_to_vectors
from starsense.geometry.fov import CircularFov
from starsense.report.page import esc, figure_html, fmt, new_figure, table
from starsense.report.section import ReportContext, Section

#: the ST-16 catalogue limit and static detection threshold (paper sec. 1.2)
PAPER_MAX_MAG = 5.75
#: the paper's "7.5 deg half-axis" field, used for the st16 sensor so numbers compare
PAPER_HALF_FOV_DEG = 7.5
#: the paper's static availability claim (sec. 1.2, N_min = 3, 10,000 orientations)
PAPER_STATIC_N3 = 0.999
#: slew rates of Fig. 11, deg/s
DYNAMIC_RATES_DEG_S = np.round(np.arange(0.0, 10.0001, 0.25), 6)
#: slew rates of Table 2 and Figs. 16-17, deg/s
TRACK_RATES_DEG_S = (1.0, 1.5, 2.0, 3.0)
#: paper sec. 3.1 quotes for the Reed model: rate -> (N_min 2, N_min 3), fractions
PAPER_FIG11_REED = {1.0: (0.90, 0.80), 2.0: (0.55, 0.30)}
#: RAs of the tracks' common node: the first gives Table 2, the others its sensitivity, deg
TRACK_NODES_DEG = (0.0, 45.0, 90.0, 135.0)
#: rendered frames per rate of the report's full-fidelity check, and its rates (deg/s)
FIDELITY_FRAMES = 25
FIDELITY_RATES_DEG_S = (1.0, 2.0, 3.0)


# ---------------------------------------------------------------------------------------------
# figure helpers


def save_figure(fig: Figure, path: Path | str, dpi: int = 110) -> Path:
    """Write a PNG atomically (temporary name beside it, then rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=dpi, format="png")
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def _map_x(ra_rad: np.ndarray) -> np.ndarray:
    """Mollweide abscissa of a right ascension: RA increases to the left, 0 h in the centre."""
    x = -np.asarray(ra_rad, dtype=float)
    return (x + np.pi) % (2.0 * np.pi) - np.pi


@functools.lru_cache(maxsize=1)
def galactic_plane_radec(n: int = 721) -> tuple[np.ndarray, np.ndarray]:
    """ICRS (RA, Dec) in rad of the galactic equator b = 0, l = 0 ... 360 deg (astropy)."""
    import astropy.units as u
    from astropy.coordinates import SkyCoord

    plane = SkyCoord(
        l=np.linspace(0.0, 360.0, n) * u.deg, b=np.zeros(n) * u.deg, frame="galactic"
    ).icrs
    return plane.ra.rad, plane.dec.rad


def _broken_line(ra: np.ndarray, dec: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Map abscissae with NaN inserted where the line wraps around the map's edge."""
    x = _map_x(ra)
    jumps = np.flatnonzero(np.abs(np.diff(x)) > np.pi) + 1
    return np.insert(x, jumps, np.nan), np.insert(np.asarray(dec, float), jumps, np.nan)


def _ra_ticks(ax) -> None:
    xt = np.radians(np.arange(-150, 151, 30))
    ax.set_xticks(xt)
    ax.set_xticklabels([f"{round((-math.degrees(x)) % 360 / 15)}h" for x in xt], fontsize=8)
    ax.tick_params(axis="y", labelsize=8)


def sky_map_figure(
    boresights: np.ndarray,
    counts: np.ndarray,
    title: str,
    *,
    sparse: bool = False,
    n_min: int = N_MIN_LOST_IN_SPACE,
    tracks: Sequence[np.ndarray] = (),
    resolution_deg: float = 1.0,
) -> Figure:
    """Stars in the field per boresight, Mollweide, with the galactic plane (Figs. 4, 5, 14).

    Parameters
    ----------
    boresights : array (M, 3)
        ICRS unit vectors of the orientations.
    counts : array (M,)
        Stars in the field at each orientation.
    sparse : bool
        Emphasise star-sparse regions (the paper's Figs. 5 and 14): colours reversed and
        saturated at ``2 n_min + 2`` stars, orientations with fewer than `n_min` stars outlined
        in black.
    tracks : sequence of arrays (K, 3)
        Boresight tracks to draw (e.g. great circles).
    resolution_deg : float
        Pixel size of the map image; each pixel takes the nearest orientation's count.
    """
    counts = np.asarray(counts)
    fig = new_figure(9.0, 5.2)
    ax = fig.add_subplot(projection="mollweide")
    nx = round(360.0 / resolution_deg)
    ny = round(180.0 / resolution_deg)
    lon_edges = np.linspace(-np.pi, np.pi, nx + 1)
    lat_edges = np.linspace(-np.pi / 2, np.pi / 2, ny + 1)
    lon_c = 0.5 * (lon_edges[1:] + lon_edges[:-1])
    lat_c = 0.5 * (lat_edges[1:] + lat_edges[:-1])
    lon_g, lat_g = np.meshgrid(lon_c, lat_c)
    vec = radec_to_vectors(np.mod(-lon_g.ravel(), 2 * np.pi), lat_g.ravel())
    _, idx = cKDTree(boresights).query(vec)
    image = counts[idx].reshape(ny, nx).astype(float)
    import matplotlib as mpl

    if sparse:
        top = 2 * n_min + 2
        cmap = mpl.colormaps["magma_r"]
        label = f"stars in field (colours reversed; >= {top} saturates)"
    else:
        top = max(int(np.percentile(counts, 99)), n_min + 1)
        cmap = mpl.colormaps["viridis"]
        label = f"stars in field (>= {top} saturates)"
    bounds = np.arange(-0.5, top + 1.0, 1.0)
    norm = mpl.colors.BoundaryNorm(bounds, cmap.N, extend="max")
    mesh = ax.pcolormesh(lon_edges, lat_edges, np.minimum(image, top), cmap=cmap, norm=norm,
                         shading="flat", rasterized=True)  # fmt: skip
    if sparse:
        ax.contour(lon_c, lat_c, image, levels=[n_min - 0.5], colors="k", linewidths=0.6)
    gx, gy = _broken_line(*galactic_plane_radec())
    ax.plot(gx, gy, color="tab:red" if not sparse else "tab:cyan", lw=1.4, ls="--",
            label="galactic plane (b = 0)")  # fmt: skip
    for k, track in enumerate(tracks):
        tx, ty = _broken_line(*_radec(track))
        ax.plot(tx, ty, color="lime", lw=1.0, label="tracks" if k == 0 else None)
    _ra_ticks(ax)
    ax.grid(True, alpha=0.35)
    ax.set_title(title, fontsize=10)
    ticks = np.arange(0, top + 1, max(1, top // 10))
    fig.colorbar(mesh, ax=ax, orientation="horizontal", shrink=0.6, pad=0.06, label=label,
                 ticks=ticks)  # fmt: skip
    ax.legend(loc="lower right", fontsize=7, framealpha=0.7)
    return fig


def _radec(vectors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    v = np.asarray(vectors, dtype=float)
    return np.mod(np.arctan2(v[:, 1], v[:, 0]), 2 * np.pi), np.arcsin(np.clip(v[:, 2], -1, 1))


def static_curve_figure(res: StaticAvailability) -> Figure:
    """Availability against the stellar detection threshold m_t, N_min = 1 ... 4 (Fig. 6)."""
    fig = new_figure(7.5, 4.6)
    ax = fig.add_subplot()
    styles = {1: ":", 2: "-", 3: "-", 4: "--"}
    for k, curve in sorted(res.curve.items()):
        ax.plot(res.mag_grid, 100 * curve, styles.get(k, "-."), label=f"N_min = {k}")
    ax.axvline(res.max_mag, color="k", lw=0.8, ls=":")
    ax.set_xlabel("stellar detection threshold m_t (V)")
    ax.set_ylabel("spatial static availability (%)")
    ax.set_title(
        f"Availability against m_t, {res.catalog}, {res.fov}, {res.n_orientations} "
        "orientations (cf. paper Fig. 6)",
        fontsize=9,
    )
    ax.set_ylim(0, 101)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def dynamic_figure(results: Sequence[DynamicAvailability]) -> Figure:
    """Spatial dynamic availability against slew rate, N_min = 2 and 3 (Fig. 11)."""
    fig = new_figure(7.5, 4.6)
    ax = fig.add_subplot()
    colours = ("tab:blue", "tab:orange", "tab:green", "tab:red")
    for res, colour in zip(results, colours, strict=False):
        for k, style in ((N_MIN_TRACKING, "--"), (N_MIN_LOST_IN_SPACE, "-")):
            if k in res.by_n_min:
                ax.plot(res.rates_deg_s, 100 * res.by_n_min[k], style, color=colour,
                        label=f"{res.curve.label}, N_min = {k}")  # fmt: skip
    ax.set_xlabel("slew rate |w| (deg/s)")
    ax.set_ylabel("spatial dynamic availability (%)")
    ax.set_ylim(0, 101)
    ax.set_title("Spatial dynamic availability (cf. paper Fig. 11)", fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def track_figure(results: Sequence[TrackAvailability], n_min: int) -> Figure:
    """Along-track availability against inclination at several rates, with the spatial
    dynamic availability at each rate as a horizontal line (Figs. 16, 17).
    """
    fig = new_figure(7.5, 4.6)
    ax = fig.add_subplot()
    cmap = __import__("matplotlib").colormaps["plasma"]
    for j, res in enumerate(results):
        colour = cmap(0.85 * j / max(1, len(results) - 1))
        ax.plot(res.inclinations_deg, 100 * res.by_n_min[n_min], "-", color=colour,
                label=f"{res.rate_deg_s:g} deg/s")  # fmt: skip
        ax.axhline(100 * res.spatial[n_min], color=colour, ls=":", lw=1)
    ax.set_xlabel("track inclination i (deg)")
    ax.set_ylabel("along-track dynamic availability (%)")
    ax.set_xlim(-90, 90)
    ax.set_ylim(0, 101)
    node = results[0].node_deg if results else 0.0
    fig_no = {N_MIN_TRACKING: "16", N_MIN_LOST_IN_SPACE: "17"}.get(n_min, "16-17")
    ax.set_title(
        f"Along-track availability, N_min = {n_min}, node RA {node:g} deg "
        f"(dotted: spatial; cf. paper Fig. {fig_no})",
        fontsize=9,
    )
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, title="slew rate")
    return fig


def track_nmin_figure(res: TrackAvailability) -> Figure:
    """Along-track availability against inclination at one rate, N_min = 2 and 3, with the
    spatial dynamic availability as horizontal lines (one rate of Figs. 16-17).
    """
    fig = new_figure(7.5, 4.6)
    ax = fig.add_subplot()
    for k, colour in zip(sorted(res.by_n_min), ("tab:blue", "tab:orange", "tab:green"),
                         strict=False):  # fmt: skip
        ax.plot(res.inclinations_deg, 100 * res.by_n_min[k], "-", color=colour,
                label=f"N_min = {k}")  # fmt: skip
        ax.axhline(100 * res.spatial[k], color=colour, ls=":", lw=1)
    ax.set_xlabel("track inclination i (deg)")
    ax.set_ylabel("along-track dynamic availability (%)")
    ax.set_xlim(-90, 90)
    ax.set_ylim(0, 101)
    ax.set_title(
        f"Along-track availability at {res.rate_deg_s:g} deg/s, node RA {res.node_deg:g} deg "
        "(dotted: spatial; cf. paper Figs. 16-17)",
        fontsize=9,
    )
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def threshold_figure(curves: Sequence[ThresholdCurve], rates_deg_s: np.ndarray) -> Figure:
    """m_t against slew rate for each threshold curve (Fig. 10 read sideways)."""
    fig = new_figure(7.0, 4.2)
    ax = fig.add_subplot()
    for c in curves:
        m = c(rates_deg_s)
        ax.plot(rates_deg_s, np.where(np.isfinite(m), m, np.nan), "-", label=c.label)
    ax.set_xlabel("slew rate |w| (deg/s)")
    ax.set_ylabel("detection threshold m_t(w)")
    ax.set_title("Faintest magnitude detected against slew rate", fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return fig


# ---------------------------------------------------------------------------------------------
# the report section


def _slew_curve(ctx: ReportContext, model: str) -> ThresholdCurve:
    """The tolerable-slew threshold curve of ``model``: the slew section's result when it ran
    (same sensor, trials and seed), else a fresh Monte Carlo.
    """
    from starsense.analysis.slew import simulate_slew

    result = ctx.slew_results.get(model)
    if result is None:
        result = simulate_slew(ctx.sensor, model, n_trials=ctx.slew_trials, seed=ctx.seed)
        ctx.slew_results[model] = result
    return ThresholdCurve.from_slew(result)


def implied_threshold(analysis: AvailabilityAnalysis, availability: float, n_min: int) -> float:
    """The m_t at which our spatial availability equals `availability` (bisection on the
    monotone curve): what a quoted availability implies for the threshold on our sky.
    """
    lo, hi = float(analysis.magnitudes.min()) - 1.0, float(analysis.max_mag)
    if analysis.sky.availability(hi, n_min) < availability:
        return math.nan
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if analysis.sky.availability(mid, n_min) >= availability:
            hi = mid
        else:
            lo = mid
    return hi


def _p(x: float | None) -> str:
    return "–" if x is None or not np.isfinite(x) else f"{100 * x:.1f}"


def availability_section(ctx: ReportContext) -> Section:
    """Spatial static, spatial dynamic and along-track availability of the report's sensor."""
    sensor = ctx.sensor
    if sensor is None:
        return Section("availability", "Availability", "<p>No sensor chosen.</p>")
    stars = ctx.primary
    band = "V" if stars.colour == "B-V" else f"the {stars.colour} system's magnitude"
    if sensor.name == "st16":
        fov = CircularFov(math.radians(PAPER_HALF_FOV_DEG))
        fov_note = (
            f"a circular field of the paper's {PAPER_HALF_FOV_DEG} deg half-axis (our st16 "
            f"preset's minor half-axis is {math.degrees(min(sensor.half_fov_rad)):.2f} deg)"
        )
    else:
        fov = CircularFov(min(sensor.half_fov_rad))
        fov_note = "a circular field of the detector's minor half-axis"
    ctx.progress("availability: stars in the field over the sky")
    catalog = getattr(ctx, "catalog", None)  # the catalogue itself, when the context has it
    if catalog is not None and "V" in getattr(catalog, "mags", {}):
        band = "V"
        analysis = AvailabilityAnalysis.from_catalog(
            catalog, fov, PAPER_MAX_MAG, seed=ctx.seed, band="V"
        )
        skipped_note = ""
    else:  # the black-body star set: stars without a colour are missing
        skipped_note = (
            f" ({stars.n_skipped:,} catalogue stars without a magnitude or colour are not in "
            "the report's star set)"
            if stars.n_skipped
            else ""
        )
        analysis = AvailabilityAnalysis(
            stars.vectors, stars.magnitude, fov, max_mag=PAPER_MAX_MAG, seed=ctx.seed,
            catalog=ctx.catalog_name, band="V" if stars.colour == "B-V" else stars.colour,
        )  # fmt: skip
    static = analysis.static(N_MIN_LOST_IN_SPACE)
    figures: list[str] = []
    figures.append(ctx.save_figure(sky_map_figure(
        static.boresights, static.counts,
        f"{sensor.name}: stars in the field, static, m_t = {PAPER_MAX_MAG} (cf. Fig. 4)",
    ), "availability_fig4_map.png"))  # fmt: skip
    figures.append(ctx.save_figure(sky_map_figure(
        static.boresights, static.counts,
        f"{sensor.name}: star-sparse regions, static (cf. Fig. 5)", sparse=True,
    ), "availability_fig5_sparse.png"))  # fmt: skip
    figures.append(ctx.save_figure(static_curve_figure(static), "availability_fig6_mt.png"))
    data: dict = {"static": static.to_dict(), "fov": describe_fov(fov)}

    static_rows = [
        [
            str(k),
            f"{100 * static.by_n_min[k]:.2f}",
            "&gt; 99.9" if k == N_MIN_LOST_IN_SPACE else "–",
        ]
        for k in (N_MIN_TRACKING, N_MIN_LOST_IN_SPACE, N_MIN_CONSERVATIVE)
    ]
    html = [
        f"""
<p>Availability is the fraction of orientations at which at least N<sub>min</sub> stars
brighter than the detection threshold m<sub>t</sub> lie in the field (paper sec. 1.1):
N<sub>min</sub> = 2 to track, 3 to solve lost-in-space, 4 as a conservative allowance for
pattern ambiguity. Stars: {esc(ctx.catalog_name)}, {esc(band)} &le; {PAPER_MAX_MAG}
(<b>{static.n_stars:,}</b> stars{skipped_note}; the paper's Yale Bright Star cut has 3,746).
Field:
{fov_note}. {static.n_orientations:,} boresights on a spherical Fibonacci lattice (the paper
uses the Marantis distribution). The stars in each field are found once and their magnitudes
sorted, so availability at any threshold is a lookup.</p>
<h3>Spatial static availability</h3>
{table(["N<sub>min</sub>", "ours (%)", "paper (%)"], static_rows,
       classes=["num", "num", "num paper"])}
<p>Stars in the field: min {static.counts.min()}, mean {static.counts.mean():.1f},
max {static.counts.max()}.</p>
{figure_html(figures[0], "Stars in the field per boresight (static, m<sub>t</sub> = "
             f"{PAPER_MAX_MAG}); Mollweide projection, RA increasing to the left with 0 h at "
             "the centre (astronomical convention), dashed: the galactic plane. The paper's "
             "Fig. 4.", "sky map of stars in the field")}
{figure_html(figures[1], "The same with the colours reversed to show star-sparse regions; "
             "black contours enclose boresights with fewer than 3 stars. The paper's Fig. 5.",
             "sky map of star-sparse regions")}
{figure_html(figures[2], "Spatial static availability against the detection threshold "
             "m<sub>t</sub>; the paper's Fig. 6.", "availability against threshold")}
"""
    ]  # fmt: skip

    # -- threshold curves from the slew simulation -------------------------------------------
    curves: list[ThresholdCurve] = []
    for model in ("reed", "liebe"):
        ctx.progress(f"availability: tolerable slew curve, {model} model")
        curves.append(_slew_curve(ctx, model))
    implied_rows = []
    for rate, vals in PAPER_TABLE2.items():
        n2, n3 = (v / 100 for v in vals["spatial"])
        ours = [f"{float(c([rate])[0]):.2f}" for c in curves]
        implied_rows.append([
            f"{rate:g}", _p(n2), fmt(implied_threshold(analysis, n2, 2), 3),
            _p(n3), fmt(implied_threshold(analysis, n3, 3), 3), *ours,
        ])  # fmt: skip
    html.append(
        f"""
<h3>Spatial dynamic availability</h3>
<p>The threshold becomes m<sub>t</sub>(w), the faintest magnitude still detected at slew rate
w: the tolerable-slew curve of the previous section (Fig. 10) read sideways, interpolated
linearly between simulated magnitudes and capped at the catalogue limit.
As a check of our sky against the paper's, the table gives the threshold at which our spatial
availability equals each value of the paper's Table 2 (spatial column): if the star
distributions agree, the thresholds implied by the N<sub>min</sub> = 2 and 3 values agree at
each rate, and they are the paper's own m<sub>t</sub>(w). Where our m<sub>t</sub>(w) differs
from the implied one, our availability differs from the paper's accordingly: the sky is the
same, the tolerable-slew curve is not.</p>
{table(["rate (deg/s)", "paper N<sub>min</sub>=2 (%)", "implied m<sub>t</sub>",
        "paper N<sub>min</sub>=3 (%)", "implied m<sub>t</sub>",
        *[f"our m<sub>t</sub>, {esc(c.label)}" for c in curves]],
       implied_rows, classes=["num"] * (5 + len(curves)))}
"""
    )  # fmt: skip
    summary = [
        (
            f"{esc(sensor.name)} static availability (N<sub>min</sub> = 3)",
            f"{100 * static.availability:.2f} % ({static.n_stars:,} stars, paper &gt; 99.9 %)",
        )
    ]
    dyn = [analysis.dynamic(c, DYNAMIC_RATES_DEG_S, N_MIN_LOST_IN_SPACE) for c in curves]
    data["dynamic"] = {c.label: d.to_dict() for c, d in zip(curves, dyn, strict=True)}
    figures.append(ctx.save_figure(threshold_figure(curves, DYNAMIC_RATES_DEG_S),
                                   "availability_threshold_curves.png"))  # fmt: skip
    figures.append(ctx.save_figure(dynamic_figure(dyn), "availability_fig11_dynamic.png"))
    reed = dyn[0]
    m1 = float(analysis._effective(curves[0]([1.0]))[0])
    figures.append(ctx.save_figure(sky_map_figure(
        static.boresights, analysis.sky_counts(m1),
        f"{sensor.name}: stars detectable at 1 deg/s (reed, m_t = {m1:.2f}; cf. Fig. 14)",
        sparse=True,
    ), "availability_fig14_sparse_1degs.png"))  # fmt: skip
    quote_rows = []
    for rate, (p2, p3) in PAPER_FIG11_REED.items():
        j = int(np.argmin(np.abs(reed.rates_deg_s - rate)))
        quote_rows.append([
            f"{rate:g}", _p(reed.by_n_min[2][j]), f"≈ {100 * p2:.0f}",
            _p(reed.by_n_min[3][j]), f"≈ {100 * p3:.0f}",
        ])  # fmt: skip
    j1 = int(np.argmin(np.abs(reed.rates_deg_s - 1.0)))
    summary.append((
        f"{esc(sensor.name)} spatial dynamic availability at 1 deg/s, Reed",
        f"{_p(reed.by_n_min[3][j1])} % (N<sub>min</sub> = 3), "
        f"{_p(reed.by_n_min[2][j1])} % (N<sub>min</sub> = 2); paper ≈ 80 / 90 %",
    ))  # fmt: skip
    html.append(
        f"""
{table(["rate (deg/s)", "Reed N<sub>min</sub>=2 (%)", "paper", "Reed N<sub>min</sub>=3 (%)",
        "paper"], quote_rows, classes=["num", "num", "num paper", "num", "num paper"])}
{figure_html(figures[-3], "Detection threshold m<sub>t</sub>(w) from the slew simulation, "
             "for both sensitivity models.", "threshold against rate")}
{figure_html(figures[-2], "Spatial dynamic availability against slew rate, N<sub>min</sub> = 2 "
             "(dashed) and 3 (solid), Reed and Liebe models; the paper's Fig. 11.",
             "availability against rate")}
{figure_html(figures[-1], "Stars detectable in the field while slewing at 1 deg/s (Reed), "
             "colours reversed as in Fig. 5; black contours enclose boresights with fewer than "
             "3 stars. The paper's Fig. 14.", "sky map at 1 deg/s")}
"""
    )  # fmt: skip
    html.append(_track_part(ctx, analysis, curves[0], figures, data))
    html.append(_fidelity_part(ctx, sensor, stars, curves[0], data))
    return Section(
        "availability",
        "Availability (Dzamba & Enright 2014)",
        "\n".join(html),
        tuple(figures),
        tuple(summary),
        data,
    )


def _track_part(ctx, analysis, curve, figures, data) -> str:
    ctx.progress("availability: along-track tracks")
    node0, *other_nodes = TRACK_NODES_DEG
    tracks = [
        analysis.track(curve, w, N_MIN_LOST_IN_SPACE, node_deg=node0) for w in TRACK_RATES_DEG_S
    ]
    data["track"] = {f"{t.rate_deg_s:g}": t.to_dict() for t in tracks}
    for k, fig_no in ((N_MIN_TRACKING, 16), (N_MIN_LOST_IN_SPACE, 17)):
        figures.append(ctx.save_figure(track_figure(tracks, k),
                                       f"availability_fig{fig_no}_track_n{k}.png"))  # fmt: skip
    rows = []
    for t in tracks:
        s2, s3 = t.stats(2), t.stats(3)
        paper = PAPER_TABLE2.get(t.rate_deg_s)
        row = [f"{t.rate_deg_s:.2f}"]
        for col in ("spatial", "mean", "max", "min"):
            row.append(f"{_p(s2[col])} / {_p(s3[col])}")
            row.append(f"{paper[col][0]:.1f} / {paper[col][1]:.1f}" if paper else "–")
        rows.append(row)
    header = ["rate (deg/s)"]
    for col in ("spatial", "mean", "max", "min"):
        header += [f"{col}: ours", "paper"]
    # how much the family's node moves the statistics
    node_rows = []
    by_node: dict[str, dict] = {}
    for node in other_nodes:
        ctx.progress(f"availability: tracks through the node at RA {node:g} deg")
        for w in TRACK_RATES_DEG_S:
            t = analysis.track(curve, w, N_MIN_LOST_IN_SPACE, node_deg=node)
            by_node.setdefault(f"{node:g}", {})[f"{w:g}"] = {
                str(k): t.stats(k) for k in (N_MIN_TRACKING, N_MIN_LOST_IN_SPACE)
            }
    for w, t in zip(TRACK_RATES_DEG_S, tracks, strict=True):
        cells = [f"{w:.2f}", f"{_p(t.stats(2)['mean'])} / {_p(t.stats(3)['mean'])}"]
        for node in other_nodes:
            st = by_node[f"{node:g}"][f"{w:g}"]
            cells.append(f"{_p(st['2']['mean'])} / {_p(st['3']['mean'])} "
                         f"({_p(st['2']['min'])} / {_p(st['3']['min'])} – "
                         f"{_p(st['2']['max'])} / {_p(st['3']['max'])})")  # fmt: skip
        paper = PAPER_TABLE2.get(w)
        cells.append(f"{paper['mean'][0]:.1f} / {paper['mean'][1]:.1f}" if paper else "–")
        node_rows.append(cells)
    data["track_by_node"] = by_node
    node_table = table(
        ["rate (deg/s)", f"mean, node {node0:g} deg",
         *[f"mean (min – max), node {n:g} deg" for n in other_nodes], "paper mean"],
        node_rows, classes=["num"] * (2 + len(other_nodes)) + ["num paper"],
    )  # fmt: skip
    t0 = tracks[0]
    return f"""
<h3>Along-track dynamic availability</h3>
<p>Great-circle tracks of inclination {t0.inclinations_deg[0]:g} ... {t0.inclinations_deg[-1]:g}
deg ({len(t0.inclinations_deg)} tracks) to the celestial equator, all through the node at RA
{t0.node_deg:g} deg, each sampled at {t0.n_samples:,} equally spaced orientations while the
sensor slews along it ({esc(curve.label)}). Table 2 of the paper beside ours,
N<sub>min</sub> = 2 / 3, in percent.</p>
{table(header, rows, classes=["num"] + ["num", "num paper"] * 4)}
<p class="note">The tracks of one family all cross at their two nodes, so the samples crowd
there (about 8 % of every track lies within one field radius of a node, against 0.9 % of the
sky): the mean over inclinations is a weighted sky average, not the spatial one, and it depends
on where the node lies on the sky. The paper does not give its node (nor the inclination step);
its along-track means exceed its spatial values at every rate. The statistics for other nodes
show how much the choice matters:</p>
{node_table}
{figure_html(figures[-2], "Along-track availability against inclination, N<sub>min</sub> = 2; "
             "dotted lines: spatial dynamic availability at the same rate. The paper's Fig. 16.",
             "along-track availability, N_min 2")}
{figure_html(figures[-1], "The same for N<sub>min</sub> = 3; the paper's Fig. 17.",
             "along-track availability, N_min 3")}
"""  # fmt: skip


def _fidelity_part(ctx, sensor, stars, curve, data) -> str:
    if not FIDELITY_RATES_DEG_S or FIDELITY_FRAMES < 1:
        return "<h3>Full-fidelity check</h3><p class='note'>Not run (no rates configured).</p>"
    ctx.progress("availability: full-fidelity check (rendered frames)")
    catalog = getattr(ctx, "catalog", None)
    if catalog is None:
        try:
            from starsense.catalog import load_catalog

            catalog = load_catalog(ctx.catalog_name)
        except (InputError, OSError) as exc:
            return (
                "<h3>Full-fidelity check</h3><p class='note'>Skipped: the catalogue object "
                f"is needed to render frames ({esc(exc)}).</p>"
            )
    checks = []
    try:
        for rate in FIDELITY_RATES_DEG_S:
            ctx.progress(f"availability: rendered frames at {rate:g} deg/s")
            checks.append(fidelity_check(
                sensor, catalog, curve, rate, n_frames=FIDELITY_FRAMES, max_mag=PAPER_MAX_MAG,
                seed=ctx.seed,
            ))  # fmt: skip
    except InputError as exc:
        return f"<h3>Full-fidelity check</h3><p class='note'>Skipped: {esc(exc)}.</p>"
    data["fidelity"] = [c.to_dict() for c in checks]
    rows = [
        [
            f"{c.rate_deg_s:g}",
            f"{c.threshold_mag:.2f}",
            _p(c.model_availability),
            _p(c.frame_availability),
            f"{c.model_counts.mean():.2f}",
            f"{c.frame_counts.mean():.2f}",
            str(c.optimistic),
            str(c.pessimistic),
        ]
        for c in checks
    ]
    header = ["rate (deg/s)", "m<sub>t</sub>", "model available (%)", "frames available (%)",
              "model stars / field", "detected stars / frame", "model optimistic",
              "model pessimistic"]  # fmt: skip
    return f"""
<h3>Full-fidelity check</h3>
<p>{FIDELITY_FRAMES} frames per rate rendered at random attitudes while slewing about the camera
y axis (streaks along the rows; {esc(curve.label)}, stars &le; {PAPER_MAX_MAG} of
{esc(getattr(catalog, "name", ""))}), passed through the sensor's detector; a detection counts
when it lies on a true star's streak. The threshold model counts the stars &le; m<sub>t</sub>(w)
in the same (rectangular) detector field at the same attitude. N<sub>min</sub> = 3. The last two
columns count the frames where the model calls the attitude available and the frames do not
(optimistic) and the reverse (pessimistic); the model's counts miss partial stars at the edges,
stars near the threshold that noise lifts over it or pushes under, and streaks that merge.</p>
{table(header, rows, classes=["num"] * 8)}
"""
