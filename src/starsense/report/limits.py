"""Report section: the physical limit of attitude accuracy (Fialho & Mortari 2019, sec. 3.3-3.5).

Computed from the catalogue the report was given:

1. Fig. 7: theta_rms of the N brightest stars for D = 1 m, t = 1 s, per colour system, with the
   power-law extrapolation to the 3e11 stars of the Galaxy;
2. Table 2: the FOV-limited "ideal" sensor (D = 10 cm, t = 10 ms) at two targets and merged, with
   the per-axis errors of each head;
3. Fig. 8: theta_rms against the figure of merit D^2 t^1/2, with the user's real sensors;
4. sec. 3.3.2: degradation of small or short-exposure sensors by stars delivering < 1 photon;
5. Table 1: the black-body fits of five reference stars.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from starsense.analysis.limits import (
    G_PAPER_INTERVAL,
    BlackBodyStars,
    BrightestCurve,
    LimitResult,
    brightest_curve,
    centroid_fisher,
    covariance,
    fisher_matrix,
    fov_limit,
    in_cone,
    limit_line,
    low_photon_degradation,
    sky_limit,
    theta_rms,
)
from starsense.errors import SingularGeometryError
from starsense.photometry import fit_star
from starsense.report.figures import PAPER_EXTRAPOLATED, brightest_curves_figure
from starsense.report.page import (
    RAD_TO_ARCSEC,
    RAD_TO_MAS,
    esc,
    figure_html,
    fmt,
    fmt_int,
    fmt_ratio,
    fmt_rel,
    new_figure,
    table,
    yes_no,
)
from starsense.report.section import ReportContext, Section

TITLE = "The physical limit (Fialho & Mortari 2019)"
KEY = "limit"


#: Table 2's sensor: D = 10 cm, t = 10 ms
TABLE2_DIAMETER_M = 0.10
TABLE2_EXPOSURE_S = 0.010
#: Table 2 of the paper, mas: FOV diameter (deg) -> (target 1, target 2, both). Computed from the
#: 26,036,431 2MASS stars with J <= 12.575, black bodies from J and H.
TABLE2_PAPER_MAS = {
    360.0: (0.0073, 0.0073, 0.0051),
    90.0: (0.0369, 0.0202, 0.0152),
    25.0: (0.641, 0.120, 0.0754),
    10.0: (3.29, 1.231, 0.213),
    4.0: (31.6, 10.8, 0.720),
}
#: the two pointings of Table 2: (label, RA in hours, Dec in degrees)
TABLE2_TARGETS = (("target 1", 0.0, 0.0), ("target 2", 6.0, 0.0))
#: sec. 3.5: two "ideal" heads fit in a sphere of twice the diameter of one
TWO_HEAD_DIAMETER_FACTOR = 2.0

#: (D in m, t in s) of the low-photon table (sec. 3.3.2)
LOW_PHOTON_CASES = ((0.10, 0.010), (0.02, 0.10), (0.01, 0.010), (0.005, 0.001))
#: sec. 3.3.2: sensors with D^2 t >= 1e-4 m^2 s come close to the limit
PAPER_D2T_CRITERION_M2_S = 1e-4

#: Table 1's sensor: D = 10 cm, t = 100 ms
TABLE1_DIAMETER_M = 0.10
TABLE1_EXPOSURE_S = 0.100
#: Table 1, UBV half: name, m_V, B-V, T (K), C, sigma_min,BB (rad)
TABLE1_UBV = (
    ("Vega", 0.030, -0.001, 13231, 2.96e-17, 1.19e-10),
    ("1757132", 11.81, 0.26, 8580, 1.87e-21, 4.42e-8),
    ("Sun", -26.75, 0.65, 5711, 2.42e-5, 1.08e-15),
    ("KF06T2", 13.97, 1.18, 3951, 9.59e-21, 1.36e-7),
    ("VB8", 16.80, 2.01, 2613, 2.01e-20, 2.63e-7),
)
#: Table 1, 2MASS half: name, m_H, H-Ks, T (K), C, sigma_min,BB (rad)
TABLE1_HKS = (
    ("Vega", -0.004, -0.005, 10417, 4.80e-17, 1.70e-10),
    ("1757132", 11.23, 0.02, 8961, 1.94e-21, 3.89e-8),
    ("Sun", -28.24, 0.04, 8059, 1.41e-5, 5.94e-16),
    ("KF06T2", 11.26, 0.10, 6050, 3.72e-21, 7.50e-8),
    ("VB8", 9.17, 0.34, 3282, 1.05e-19, 6.50e-8),
)

FIG7 = "limit_fig7_brightest.png"
FIG_TABLE2 = "limit_table2_fov.png"
FIG8 = "limit_fig8_merit.png"


# ---------------------------------------------------------------------------------------------
# numbers


def radec_vector(ra_h: float, dec_deg: float) -> np.ndarray:
    """ICRS unit vector of (RA in hours, Dec in degrees)."""
    ra, dec = math.radians(15.0 * ra_h), math.radians(dec_deg)
    return np.array([math.cos(dec) * math.cos(ra), math.cos(dec) * math.sin(ra), math.sin(dec)])


def in_interval(g: float, interval=G_PAPER_INTERVAL) -> bool:
    return bool(interval[0] <= g <= interval[1])


@dataclass(frozen=True)
class FovCell:
    """One cell of the Table 2 reproduction: a head (or the merged heads) at one FOV.

    ``result`` is None when the stars in view do not determine the attitude (fewer than 2 stars,
    or all along one axis).
    """

    n_stars: int
    result: LimitResult | None

    @property
    def theta_mas(self) -> float | None:
        return None if self.result is None else self.result.theta_rms_rad * RAD_TO_MAS

    def html(self) -> str:
        if self.result is None:
            return f"singular ({self.n_stars} star{'s' if self.n_stars != 1 else ''})"
        return fmt(self.theta_mas)

    def to_dict(self) -> dict:
        if self.result is None:
            return {"n_stars": self.n_stars, "singular": True, "theta_rms_mas": None}
        d = self.result.to_dict()
        d["singular"] = False
        d["theta_rms_mas"] = self.theta_mas
        d["axis_sigma_mas"] = [float(x) * RAD_TO_MAS for x in self.result.axis_sigma_rad]
        return d


@dataclass(frozen=True)
class FovRow:
    fov_deg: float
    heads: tuple[FovCell, ...]
    merged: FovCell


def _merged(stars: BlackBodyStars, targets, fov_rad, diameter_m, exposure_s) -> FovCell:
    """Merged heads computed from the kernels, for when a head alone is singular (eq. 20-22)."""
    w = stars.fisher_unit * diameter_m**4 * exposure_s
    f, n = np.zeros((3, 3)), 0
    for t in targets:
        m = in_cone(stars.vectors, t, fov_rad)
        f = f + fisher_matrix(stars.vectors[m], w[m])
        n += int(m.sum())
    try:
        p = covariance(f, n)
    except SingularGeometryError:
        return FovCell(n, None)
    th = theta_rms(p)
    res = LimitResult(th, np.sqrt(np.diag(p)), p, n, th * diameter_m**2 * math.sqrt(exposure_s))
    return FovCell(n, res)


def fov_table(
    stars: BlackBodyStars,
    diameter_m: float = TABLE2_DIAMETER_M,
    exposure_s: float = TABLE2_EXPOSURE_S,
    fovs_deg=tuple(TABLE2_PAPER_MAS),
    targets=TABLE2_TARGETS,
) -> list[FovRow]:
    """Table 2: FOV-limited limit per head and merged (sec. 3.4), singular heads kept as such."""
    vecs = np.array([radec_vector(ra, dec) for _, ra, dec in targets])
    rows = []
    for fov in fovs_deg:
        fov_rad = math.radians(fov)
        try:
            heads, merged = fov_limit(stars, vecs, fov_rad, diameter_m, exposure_s)
            cells = tuple(FovCell(h.n_stars, h) for h in heads)
            both = FovCell(merged.n_stars, merged) if merged is not None else None
        except SingularGeometryError:
            cells = []
            for v in vecs:
                try:
                    (h,), _ = fov_limit(stars, v, fov_rad, diameter_m, exposure_s)
                    cells.append(FovCell(h.n_stars, h))
                except SingularGeometryError:
                    cells.append(FovCell(int(in_cone(stars.vectors, v, fov_rad).sum()), None))
            cells = tuple(cells)
            both = _merged(stars, vecs, fov_rad, diameter_m, exposure_s)
        rows.append(FovRow(float(fov), cells, both))
    return rows


@dataclass(frozen=True)
class Table1Row:
    colour: str
    name: str
    magnitude: float
    colour_index: float
    temperature_k: float
    dilution: float
    sigma_rad: float
    paper: tuple[float, float, float]  # T, C, sigma


def table1_rows() -> list[Table1Row]:
    """Table 1: black-body T, C and centroid bound sigma = F^-1/2 (eq. 19) of five stars."""
    rows = []
    for colour, ref in (("B-V", TABLE1_UBV), ("H-Ks", TABLE1_HKS)):
        for name, mag, ci, t_ref, c_ref, s_ref in ref:
            t, c = fit_star(mag, ci, colour)
            f = centroid_fisher(c, t, TABLE1_DIAMETER_M, TABLE1_EXPOSURE_S)
            rows.append(
                Table1Row(colour, name, mag, ci, t, c, float(1 / np.sqrt(f)), (t_ref, c_ref, s_ref))
            )
    return rows


# ---------------------------------------------------------------------------------------------
# figures


def _fig7(ctx: ReportContext, curves: dict[str, BrightestCurve]) -> str:
    fig = brightest_curves_figure(curves, catalog_name=ctx.catalog_name)
    return ctx.save_figure(fig, FIG7)


def _fig_table2(ctx: ReportContext, rows: list[FovRow]) -> str:
    fig = new_figure(7.5, 5.0)
    ax = fig.add_subplot()
    fovs = np.array([r.fov_deg for r in rows])
    styles = [
        ("target 1", "o", "tab:blue"),
        ("target 2", "s", "tab:orange"),
        ("both", "D", "tab:green"),
    ]
    for k, (label, marker, col) in enumerate(styles):
        cells = [r.heads[k] if k < len(r.heads) else r.merged for r in rows]
        ours = np.array([np.nan if c.theta_mas is None else c.theta_mas for c in cells])
        ok = np.isfinite(ours)
        ax.plot(fovs[ok], ours[ok], "-", marker=marker, color=col, label=f"{label}: this catalogue")
        paper = np.array([TABLE2_PAPER_MAS.get(r.fov_deg, (np.nan,) * 3)[k] for r in rows])
        okp = np.isfinite(paper)
        ax.plot(
            fovs[okp],
            paper[okp],
            ":",
            marker=marker,
            mfc="none",
            color=col,
            label=f"{label}: paper Table 2 (2MASS)",
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xticks(fovs, [f"{f:g}°" for f in fovs])
    ax.minorticks_off()
    ax.set_xlabel("FOV diameter")
    ax.set_ylabel(r"$\theta_\mathrm{rms}$ (mas)")
    ax.set_title(
        f"FOV-limited ideal sensor, D = {TABLE2_DIAMETER_M * 100:g} cm, "
        f"t = {TABLE2_EXPOSURE_S * 1000:g} ms (cf. paper Table 2)",
        fontsize=11,
    )
    ax.grid(True, which="major", alpha=0.35)
    ax.legend(fontsize=8, ncols=2)
    return ctx.save_figure(fig, FIG_TABLE2)


def _fig8(ctx: ReportContext, g_ours: float, rows: list[FovRow]) -> str:
    fig = new_figure(8.5, 6.0)
    ax = fig.add_subplot()
    x_single = TABLE2_DIAMETER_M**2 * math.sqrt(TABLE2_EXPOSURE_S)
    x_double = (TWO_HEAD_DIAMETER_FACTOR * TABLE2_DIAMETER_M) ** 2 * math.sqrt(TABLE2_EXPOSURE_S)
    x_user = ctx.diameter_m**2 * math.sqrt(ctx.exposure_s)
    xs = [x_single, x_double, x_user] + [s.figure_of_merit for s in ctx.sensors]
    x_lo = min(1e-5, min(xs) / 5.0)
    x_hi = max(1.0, max(xs) * 5.0)
    x = np.geomspace(x_lo, x_hi, 100)
    lo, hi = G_PAPER_INTERVAL
    ax.plot(
        x,
        limit_line(lo, x) * RAD_TO_ARCSEC,
        "-",
        color="black",
        lw=1.5,
        label=f"limit, paper's lower G = {lo:.0e}",
    )
    ax.plot(
        x,
        limit_line(hi, x) * RAD_TO_ARCSEC,
        "--",
        color="black",
        lw=1.5,
        label=f"limit, paper's upper G = {hi:.0e}",
    )
    ax.plot(
        x,
        limit_line(g_ours, x) * RAD_TO_ARCSEC,
        ":",
        color="tab:purple",
        lw=2,
        label=f"{ctx.catalog_name} ({ctx.primary.colour}) G = {g_ours:.2e}",
    )
    # FOV-limited ideal sensors of Table 2
    for k, (label, marker) in enumerate((("one head, target 1", "o"), ("one head, target 2", "^"))):
        th = [r.heads[k].theta_mas for r in rows]
        y = [t / 1000.0 for t in th if t is not None]
        ax.plot(
            [x_single] * len(y),
            y,
            marker,
            color="tab:blue",
            mfc="none" if k else None,
            ls="none",
            label=f"ideal FOV-limited, {label}",
        )
    th2 = [(r.fov_deg, r.merged.theta_mas) for r in rows if r.merged.theta_mas is not None]
    ax.plot(
        [x_double] * len(th2),
        [t / 1000.0 for _, t in th2],
        "s",
        color="tab:orange",
        ls="none",
        label="ideal FOV-limited, two heads (D doubled)",
    )
    for fov, t in th2:
        ax.annotate(
            f"{fov:g}°",
            (x_double, t / 1000.0),
            xytext=(6, 0),
            textcoords="offset points",
            va="center",
            fontsize=7,
            color="tab:orange",
        )
    for r in rows:
        t = r.heads[0].theta_mas
        if t is not None:
            ax.annotate(
                f"{r.fov_deg:g}°",
                (x_single, t / 1000.0),
                xytext=(-6, 0),
                textcoords="offset points",
                va="center",
                ha="right",
                fontsize=7,
                color="tab:blue",
            )
    ax.plot(
        [x_user],
        [g_ours / x_user * RAD_TO_ARCSEC],
        "*",
        color="tab:purple",
        mfc="none",
        mew=1.5,
        ms=16,
        ls="none",
        zorder=1,
        label=f"this sensor (D = {ctx.diameter_m:g} m, t = {ctx.exposure_s:g} s), whole sky",
    )
    if ctx.sensors:
        sx = [s.figure_of_merit for s in ctx.sensors]
        sy = [s.theta_rms_arcsec for s in ctx.sensors]
        ax.plot(sx, sy, "o", color="tab:red", ms=7, ls="none", label="real sensors (your table)")
        for s in ctx.sensors:
            ax.annotate(
                s.name,
                (s.figure_of_merit, s.theta_rms_arcsec),
                xytext=(5, 4),
                textcoords="offset points",
                fontsize=7,
                color="tab:red",
            )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(x_lo, x_hi)
    ax.set_xlabel(r"figure of merit $D^2 t^{1/2}$ (m$^2$ s$^{1/2}$)")
    ax.set_ylabel(r"$\theta_\mathrm{rms}$ (arcsec)")
    ax.set_title(r"Attitude error against $D^2 t^{1/2}$ (cf. paper Fig. 8)", fontsize=11)
    ax.grid(True, which="major", alpha=0.35)
    ax.grid(True, which="minor", alpha=0.12)
    ax.legend(fontsize=8, loc="lower left")
    return ctx.save_figure(fig, FIG8)


# ---------------------------------------------------------------------------------------------
# the section


def limit_section(ctx: ReportContext) -> Section:
    """Build the "physical limit" section (Fialho & Mortari 2019, sec. 3.3-3.5)."""
    primary = ctx.primary
    parts: list[str] = []
    data: dict = {
        "g_paper_interval_rad_m2_s05": list(G_PAPER_INTERVAL),
        "paper_extrapolated_rad": list(PAPER_EXTRAPOLATED),
    }

    parts.append(
        "<p>An ideal spherical sensor of diameter D exposing for t, limited only by diffraction "
        "and photon noise, sees every catalogue star as a black body fitted to its colour and "
        "magnitude (eqs. 1, 9). Each star's centroid bound is F<sub>i</sub> ∝ D<sup>4</sup> t "
        "C<sub>i</sub> T<sub>i</sub><sup>5</sup> (eq. 19); the attitude covariance is the "
        "inverse of Σ F<sub>i</sub> (I − r<sub>i</sub>r<sub>i</sub><sup>T</sup>) (eqs. 20-21) "
        "and θ<sub>rms</sub> = √tr P = G D<sup>−2</sup> t<sup>−½</sup> (eqs. 22-24).</p>"
    )

    # 1. Fig. 7 ------------------------------------------------------------------------------
    ctx.progress("limit: θ_rms over the N brightest stars (Fig. 7)")
    curves = {name: brightest_curve(stars, 1.0, 1.0) for name, stars in ctx.stars.items()}
    g_cat = {name: float(c.theta_rms_rad[-1]) for name, c in curves.items()}
    fig7 = _fig7(ctx, curves)
    parts.append("<h3>G from the catalogue: θ<sub>rms</sub> over the N brightest stars</h3>")
    parts.append(
        figure_html(
            fig7,
            f"θ<sub>rms</sub> of an ideal whole-sky sensor with D = 1 m and t = 1 s, using only "
            f"the N brightest stars of {esc(ctx.catalog_name)} (solid, one curve per colour "
            "system), and a power law fitted to the last decade of each curve (dashed) "
            "extrapolated to the 3×10<sup>11</sup> stars of the Galaxy (circles). The red band "
            "is the paper's interval 7×10<sup>−15</sup> &lt; G &lt; 10<sup>−13</sup> "
            "rad m<sup>2</sup> s<sup>½</sup>; the black triangles are the paper's own "
            "extrapolations (1.2×10<sup>−14</sup> and 5.8×10<sup>−14</sup> rad). Counterpart: "
            "paper Fig. 7 (Hipparcos, Tycho-2 and 2MASS curves).",
            "theta_rms against the number of brightest stars, log-log",
        )
    )
    rows = []
    for name, c in curves.items():
        stars = ctx.stars[name]
        rows.append(
            [
                esc(name),
                fmt_int(c.n_stars[-1]),
                fmt_int(stars.n_skipped),
                fmt(g_cat[name]) + " " + yes_no(in_interval(g_cat[name]), "in", "outside"),
                f"{c.slope:.3f}",
                fmt(c.theta_extrapolated_rad)
                + " "
                + yes_no(in_interval(c.theta_extrapolated_rad), "in", "outside"),
            ]
        )
    parts.append(
        table(
            [
                "colour",
                "N stars used",
                "skipped",
                "G = θ<sub>rms</sub>(all N) (rad m<sup>2</sup> s<sup>½</sup>)",
                "fitted slope d log θ / d log N",
                "θ<sub>rms</sub> at N = 3×10<sup>11</sup> (rad)",
            ],
            rows,
            classes=["", "num", "num", "num", "num", "num"],
        )
    )
    parts.append(
        "<p class='note'>“in/outside” compares with the paper's interval "
        "[7×10<sup>−15</sup>, 10<sup>−13</sup>]. G from a catalogue is an upper bound of the "
        "true G: every further star only adds Fisher information. The paper's G is the value "
        "extrapolated to the whole Galaxy, so the last column is the one to compare with its "
        "1.2×10<sup>−14</sup> (lower curve) and 5.8×10<sup>−14</sup> (upper curve); the "
        "extrapolation over six decades of N from one catalogue's last decade is rough, as the "
        "paper says of its own. Stars are skipped when their magnitude or colour is "
        "missing.</p>"
    )
    data["curves"] = {
        name: {
            "n_stars_used": int(c.n_stars[-1]),
            "n_skipped": int(ctx.stars[name].n_skipped),
            "g_rad_m2_s05": g_cat[name],
            "g_in_paper_interval": in_interval(g_cat[name]),
            "slope": c.slope,
            "theta_extrapolated_rad": c.theta_extrapolated_rad,
            "extrapolated_in_paper_interval": in_interval(c.theta_extrapolated_rad),
            "curve": c.to_dict(),
        }
        for name, c in curves.items()
    }
    data["g_rad_m2_s05"] = g_cat

    # the user's sensor -----------------------------------------------------------------------
    own = sky_limit(primary, ctx.diameter_m, ctx.exposure_s)
    fom = ctx.diameter_m**2 * math.sqrt(ctx.exposure_s)
    data["sensor"] = {
        "diameter_m": ctx.diameter_m,
        "exposure_s": ctx.exposure_s,
        "figure_of_merit_m2_s05": fom,
        "colour": primary.colour,
        "theta_rms_rad": own.theta_rms_rad,
        "theta_rms_mas": own.theta_rms_rad * RAD_TO_MAS,
        "theta_rms_paper_interval_rad": [g / fom for g in G_PAPER_INTERVAL],
    }

    # 2. Table 2 -------------------------------------------------------------------------------
    ctx.progress("limit: FOV-limited sensors (Table 2)")
    fov_rows = fov_table(primary)
    parts.append("<h3>FOV-limited ideal sensor (Table 2)</h3>")
    parts.append(
        f"<p>An ideal sensor with D = {TABLE2_DIAMETER_M * 100:g} cm and t = "
        f"{TABLE2_EXPOSURE_S * 1000:g} ms that sees only the stars in a cone of the given "
        "diameter, pointed at target 1 (RA 0 h, Dec 0°, near the First Point of Aries, few "
        "bright stars) or target 2 (RA 6 h, Dec 0°, Orion, many bright stars); “both” merges "
        "the two heads' Fisher matrices (a two-head tracker). Values in milli-arcseconds, "
        f"from {fmt_int(len(primary))} {esc(ctx.catalog_name)} stars ({esc(primary.colour)}); "
        "the paper's values beside ours.</p>"
    )
    rows = []
    for r in fov_rows:
        paper = TABLE2_PAPER_MAS.get(r.fov_deg)
        cells = [*r.heads, r.merged]
        row = [f"{r.fov_deg:g}°"]
        for k, cell in enumerate(cells):
            row.append(cell.html())
            row.append(fmt(paper[k]) if paper else "–")
            row.append(fmt_ratio(cell.theta_mas, paper[k]) if paper else "–")
        rows.append(row)
    head_names = [t[0] for t in TABLE2_TARGETS] + ["both"]
    parts.append(
        table(
            ["FOV"] + ["ours", "paper", "ours / paper"] * len(head_names),
            rows,
            header_rows=[[("", 1)] + [(esc(h), 3) for h in head_names]],
            classes=["", *["num", "num paper", "num paper"] * len(head_names)],
        )
    )
    ratios = [
        cell.theta_mas / TABLE2_PAPER_MAS[r.fov_deg][k]
        for r in fov_rows
        if r.fov_deg in TABLE2_PAPER_MAS
        for k, cell in enumerate((*r.heads, r.merged))
        if cell.theta_mas is not None
    ]
    spread = (
        f" Here ours/paper ranges from {min(ratios):.2g} to {max(ratios):.2g}." if ratios else ""
    )
    parts.append(
        "<p class='note'>The paper computed Table 2 from the 26 million 2MASS stars with "
        "J ≤ 12.575 (black bodies from J and H); ours come from "
        f"{fmt_int(len(primary))} {esc(ctx.catalog_name)} stars with black bodies from "
        f"{esc(primary.colour)}, so ours are expected to be larger: fewer stars carry less "
        "Fisher information. But the paper gives its own values a factor 2-3 of uncertainty "
        "from the black-body approximation of real spectra, which it finds larger than the "
        f"effect of catalogue size (sec. 3.4.1).{spread} A FOV with fewer than two stars "
        "(or stars all along one axis) cannot determine the attitude and is shown as "
        "“singular (n stars)”.</p>"
    )
    rows = []
    for r in fov_rows:
        for (label, _, _), cell in zip(TABLE2_TARGETS, r.heads, strict=True):
            if cell.result is None:
                rows.append(
                    [f"{r.fov_deg:g}°", esc(label), fmt_int(cell.n_stars), cell.html(), "", "", ""]
                )
                continue
            sx, sy, sz = cell.result.axis_sigma_rad * RAD_TO_MAS
            cross = math.sqrt((sx**2 + sy**2) / 2.0)
            rows.append(
                [
                    f"{r.fov_deg:g}°",
                    esc(label),
                    fmt_int(cell.n_stars),
                    fmt(sx),
                    fmt(sy),
                    fmt(cross),
                    fmt(sz),
                ]
            )
    parts.append(
        "<p>Per axis, for each head: the 1-σ errors about the two cross-boresight axes (east and "
        "north of the target), their rms, and about the boresight (roll), mas. The narrower "
        "the FOV, the larger roll is against cross-boresight — why two heads at right angles "
        "gain so much (sec. 3.5).</p>"
    )
    parts.append(
        table(
            ["FOV", "head", "stars in view", "σ east", "σ north", "σ cross (rms)", "σ roll"],
            rows,
            classes=["", "", "num", "num", "num", "num", "num"],
        )
    )
    fig_t2 = _fig_table2(ctx, fov_rows)
    parts.append(
        figure_html(
            fig_t2,
            "θ<sub>rms</sub> (mas) of the FOV-limited ideal sensor against its FOV diameter, for "
            "each target and both merged: ours (filled, solid) from this catalogue and the "
            "paper's (open, dotted) from 2MASS. Counterpart: paper Table 2 (also the “ideal” "
            "points of paper Fig. 8). Singular FOVs are left out.",
            "theta_rms against FOV diameter, ours and the paper's",
        )
    )
    data["fov_table"] = {
        "diameter_m": TABLE2_DIAMETER_M,
        "exposure_s": TABLE2_EXPOSURE_S,
        "colour": primary.colour,
        "targets": [{"label": lab, "ra_h": ra, "dec_deg": dec} for lab, ra, dec in TABLE2_TARGETS],
        "rows": [
            {
                "fov_deg": r.fov_deg,
                **{
                    lab: c.to_dict() for (lab, _, _), c in zip(TABLE2_TARGETS, r.heads, strict=True)
                },
                "both": r.merged.to_dict(),
                "paper_mas": list(TABLE2_PAPER_MAS.get(r.fov_deg, ())),
            }
            for r in fov_rows
        ],
    }

    # 3. Fig. 8 --------------------------------------------------------------------------------
    ctx.progress("limit: comparison with real sensors (Fig. 8)")
    g_primary = g_cat[primary.colour] if primary.colour in g_cat else next(iter(g_cat.values()))
    fig8 = _fig8(ctx, g_primary, fov_rows)
    parts.append("<h3>Against the figure of merit D<sup>2</sup> t<sup>½</sup> (Fig. 8)</h3>")
    parts.append(
        figure_html(
            fig8,
            "θ<sub>rms</sub> (arcsec) against D<sup>2</sup> t<sup>½</sup>. Lines: the limit "
            "θ = G / (D<sup>2</sup> t<sup>½</sup>) for the paper's lower (solid) and upper "
            f"(dashed) G and for G from {esc(ctx.catalog_name)} (dotted). Blue: the FOV-limited "
            f"ideal single head of Table 2 (D = {TABLE2_DIAMETER_M * 100:g} cm, "
            f"t = {TABLE2_EXPOSURE_S * 1000:g} ms; filled target 1, open target 2), orange: two "
            "heads merged, plotted with D doubled as the paper does; labels give the FOV. Star: "
            "this report's sensor as an ideal whole-sky sensor."
            + (" Red: the real sensors of your table." if ctx.sensors else "")
            + " Counterpart: paper Fig. 8 (which also shows ten commercial sensors).",
            "theta_rms against D^2 t^1/2 with limit lines and sensors",
        )
    )
    if ctx.sensors:
        rows = []
        for s in ctx.sensors:
            lim = g_primary / s.figure_of_merit * RAD_TO_ARCSEC
            rows.append(
                [
                    esc(s.name),
                    fmt(s.diameter_m),
                    fmt(s.exposure_s),
                    fmt(s.figure_of_merit),
                    fmt(s.sigma_cross_arcsec) if s.sigma_cross_arcsec is not None else "–",
                    fmt(s.sigma_roll_arcsec) if s.sigma_roll_arcsec is not None else "–",
                    fmt(s.theta_rms_arcsec),
                    fmt(lim),
                    fmt(s.theta_rms_arcsec / lim),
                    fmt(s.theta_rms_rad * s.figure_of_merit / G_PAPER_INTERVAL[1]),
                ]
            )
        parts.append(
            table(
                [
                    "sensor",
                    "D (m)",
                    "t (s)",
                    "D<sup>2</sup> t<sup>½</sup>",
                    "σ cross (″)",
                    "σ roll (″)",
                    "θ<sub>rms</sub> (″)",
                    "limit, this catalogue (″)",
                    "× above it",
                    "× above the paper's upper limit",
                ],
                rows,
                classes=["", *["num"] * 9],
            )
        )
        parts.append(
            "<p class='note'>θ<sub>rms</sub><sup>2</sup> = 2 σ<sub>cross</sub><sup>2</sup> + "
            "σ<sub>roll</sub><sup>2</sup> when the table gives per-axis errors (sec. 3.5).</p>"
        )
    else:
        parts.append(
            "<p class='note'>No sensors table was given. To place real sensors on this plot, "
            "pass a CSV with header <code>name,diameter_m,exposure_s,theta_rms_arcsec</code> or "
            "<code>name,diameter_m,exposure_s,sigma_cross_arcsec,sigma_roll_arcsec</code>; "
            "D is the diameter of the smallest sphere enclosing the optical head, baffle "
            "excluded (sec. 3.5). starsense ships no datasheet numbers.</p>"
        )
    data["sensors"] = [
        {
            **s.to_dict(),
            "figure_of_merit_m2_s05": s.figure_of_merit,
            "limit_arcsec": g_primary / s.figure_of_merit * RAD_TO_ARCSEC,
        }
        for s in ctx.sensors
    ]

    # 4. low photons ---------------------------------------------------------------------------
    parts.append("<h3>Small sensors and short exposures (sec. 3.3.2)</h3>")
    rows, low = [], []
    seeds = np.random.SeedSequence(ctx.seed).spawn(len(LOW_PHOTON_CASES))
    for (d, t), seed in zip(LOW_PHOTON_CASES, seeds, strict=True):
        ctx.progress(f"limit: low-photon degradation, D = {d:g} m, t = {t:g} s")
        res = low_photon_degradation(
            primary, d, t, n_trials=ctx.low_photon_trials, rng=np.random.default_rng(seed)
        )
        d2t = d * d * t
        rows.append(
            [
                fmt(d),
                fmt(t),
                fmt_int(len(res.expected_photons)),
                fmt_int(res.n_below_one_photon),
                f"{res.expected_observed_stars:,.1f}",
                fmt(res.theta_ideal_rad * RAD_TO_MAS),
                fmt(res.theta_poisson_rad * RAD_TO_MAS),
                f"{res.degradation:.4f} ({(res.degradation - 1) * 100:+.2g} %)".replace("-", "−")
                if math.isfinite(res.degradation)
                else "∞ (too few stars in some draws)",
                fmt(d2t) + " " + yes_no(d2t >= PAPER_D2T_CRITERION_M2_S, "≥ 10⁻⁴", "< 10⁻⁴"),
            ]
        )
        low.append(
            {
                "diameter_m": d,
                "exposure_s": t,
                "d2t_m2_s": d2t,
                "meets_paper_criterion": d2t >= PAPER_D2T_CRITERION_M2_S,
                "theta_ideal_mas": res.theta_ideal_rad * RAD_TO_MAS,
                "theta_poisson_mas": res.theta_poisson_rad * RAD_TO_MAS,
                **res.to_dict(),
            }
        )
    parts.append(
        "<p>A star delivering on average ι photons in an exposure is missed with probability "
        "e<sup>−ι</sup>. Drawing each star's photons from Poisson(ι) "
        f"({ctx.low_photon_trials} draws, seed {ctx.seed}) and weighting its Fisher information by "
        "the photons it actually delivered gives the mean bound of a real exposure. The paper "
        "argues that sensors with D<sup>2</sup> t ≥ 10<sup>−4</sup> m<sup>2</sup> s lose little "
        f"(sec. 3.3.2). Stars: {esc(ctx.catalog_name)}, {esc(primary.colour)}; θ in mas.</p>"
    )
    parts.append(
        table(
            [
                "D (m)",
                "t (s)",
                "stars",
                "stars &lt; 1 photon",
                "expected stars seen",
                "θ ideal (mas)",
                "θ with Poisson photons (mas)",
                "degradation ×",
                "D<sup>2</sup> t (m<sup>2</sup> s) vs paper",
            ],
            rows,
            classes=["num"] * 8 + [""],
        )
    )
    parts.append(
        "<p class='note'>In a bright-star catalogue the stars that carry most of the Fisher "
        "information deliver many photons even to a small sensor, so the degradation computed "
        "here stays small even where many stars deliver less than one photon. The paper's "
        "criterion concerns the faint stars of 2MASS (it asks for &gt; 10<sup>8</sup> stars "
        "observed on average), which this catalogue does not have.</p>"
    )
    data["low_photon"] = low

    # 5. Table 1 -------------------------------------------------------------------------------
    ctx.progress("limit: black-body fits of the reference stars (Table 1)")
    parts.append("<h3>Black-body fits of reference stars (Table 1)</h3>")
    t1 = table1_rows()
    rows = []
    for r in t1:
        rows.append(
            [
                esc(r.colour),
                esc(r.name),
                f"{r.magnitude:.3f}",
                f"{r.colour_index:+.3f}",
                f"{r.temperature_k:.0f}",
                f"{r.paper[0]:.0f}",
                fmt_rel(r.temperature_k, r.paper[0]),
                fmt(r.dilution),
                fmt(r.paper[1]),
                fmt_rel(r.dilution, r.paper[1]),
                fmt(r.sigma_rad),
                fmt(r.paper[2]),
                fmt_rel(r.sigma_rad, r.paper[2]),
            ]
        )
    parts.append(
        f"<p>Equivalent black body (T, dilution C) and centroid bound σ = F<sup>−½</sup> "
        f"(eq. 19) for D = {TABLE1_DIAMETER_M * 100:g} cm, t = {TABLE1_EXPOSURE_S * 1000:g} ms, "
        "from V with B−V (UBV) and from m<sub>H</sub> with H−K<sub>s</sub> (2MASS); σ in "
        "rad.</p>"
    )
    parts.append(
        table(
            [
                "colour",
                "star",
                "m",
                "colour index",
                "T (K)",
                "paper",
                "Δ",
                "C",
                "paper",
                "Δ",
                "σ (rad)",
                "paper",
                "Δ",
            ],
            rows,
            classes=[
                "",
                "",
                "num",
                "num",
                "num",
                "num paper",
                "num paper",
                "num",
                "num paper",
                "num paper",
                "num",
                "num paper",
                "num paper",
            ],
        )
    )
    parts.append(
        "<p class='note'>Our passbands (Bessell via sedpy) and Vega spectrum (CALSPEC stis_011) "
        "differ slightly from the paper's (Bessell &amp; Murphy 2012, stis_008). H−K<sub>s</sub> "
        "spans only 0.83 mag over 2,000-30,000 K, so its colours, rounded to 0.01 mag in the "
        "table, move T by up to ~1.5 %.</p>"
    )
    data["table1"] = [
        {
            "colour": r.colour,
            "star": r.name,
            "magnitude": r.magnitude,
            "colour_index": r.colour_index,
            "temperature_k": r.temperature_k,
            "dilution": r.dilution,
            "sigma_rad": r.sigma_rad,
            "paper": {"temperature_k": r.paper[0], "dilution": r.paper[1], "sigma_rad": r.paper[2]},
        }
        for r in t1
    ]

    # summary --------------------------------------------------------------------------------
    lo, hi = G_PAPER_INTERVAL
    g_lines = "<br>".join(
        f"{esc(name)}: {fmt(g_cat[name])} ({yes_no(in_interval(g_cat[name]), 'in', 'outside')}"
        f" the paper's interval); extrapolated to 3×10<sup>11</sup> stars: "
        f"{fmt(c.theta_extrapolated_rad)} "
        f"({yes_no(in_interval(c.theta_extrapolated_rad), 'in', 'outside')})"
        for name, c in curves.items()
    )
    summary = (
        (f"G (rad m<sup>2</sup> s<sup>½</sup>), paper: {fmt(lo)} … {fmt(hi)}", g_lines),
        (
            "This sensor's limit",
            f"D = {fmt(ctx.diameter_m)} m, t = {fmt(ctx.exposure_s)} s "
            f"(D<sup>2</sup> t<sup>½</sup> = {fmt(fom)} m<sup>2</sup> s<sup>½</sup>): "
            f"θ<sub>rms</sub> = {fmt(own.theta_rms_rad * RAD_TO_MAS)} mas "
            f"({fmt(own.theta_rms_rad)} rad) with {esc(ctx.catalog_name)} "
            f"({esc(primary.colour)}); {fmt(lo / fom * RAD_TO_MAS)} … "
            f"{fmt(hi / fom * RAD_TO_MAS)} mas for the paper's G interval",
        ),
    )
    return Section(
        key=KEY,
        title=TITLE,
        html="\n".join(parts),
        figures=(fig7, fig_t2, fig8),
        summary=summary,
        data=data,
    )
