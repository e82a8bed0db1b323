"""Limit section, parts 4 and 5: low-photon degradation (sec. 3.3.2) and Table 1's black bodies."""

from __future__ import annotations

import math

import numpy as np

from starsense.analysis.limits.photons import low_photon_degradation
from starsense.references import fialho2019 as paper
from starsense.report.limits.parts import Part
from starsense.report.limits.tables import table1_rows
from starsense.report.page import esc, fmt, fmt_int, fmt_rel, table, yes_no
from starsense.report.section import ReportContext
from starsense.units import RAD_TO_MAS

__all__ = ["LOW_PHOTON_CASES", "low_photon_part", "table1_part"]

#: (D in m, t in s) of the low-photon table (sec. 3.3.2)
LOW_PHOTON_CASES = ((0.10, 0.010), (0.02, 0.10), (0.01, 0.010), (0.005, 0.001))

_LOW_PHOTON_HEADERS = [
    "D (m)",
    "t (s)",
    "stars",
    "stars &lt; 1 photon",
    "expected stars seen",
    "θ ideal (mas)",
    "θ with Poisson photons (mas)",
    "degradation ×",
    "D<sup>2</sup> t (m<sup>2</sup> s) vs paper",
]

_LOW_PHOTON_NOTE = (
    "<p class='note'>In a bright-star catalogue the stars that carry most of the Fisher "
    "information deliver many photons even to a small sensor, so the degradation computed "
    "here stays small even where many stars deliver less than one photon. The paper's "
    "criterion concerns the faint stars of 2MASS (it asks for &gt; 10<sup>8</sup> stars "
    "observed on average), which this catalogue does not have.</p>"
)

_TABLE1_HEADERS = ["colour", "star", "m", "colour index", "T (K)", "paper", "Δ", "C", "paper"]
_TABLE1_HEADERS += ["Δ", "σ (rad)", "paper", "Δ"]
_TABLE1_CLASSES = ["", "", "num", "num", *["num", "num paper", "num paper"] * 3]

_TABLE1_NOTE = (
    "<p class='note'>Our passbands (Bessell via sedpy) and Vega spectrum (CALSPEC stis_011) "
    "differ slightly from the paper's (Bessell &amp; Murphy 2012, stis_008). H−K<sub>s</sub> "
    "spans only 0.83 mag over 2,000-30,000 K, so its colours, rounded to 0.01 mag in the "
    "table, move T by up to ~1.5 %.</p>"
)


def _degradation(x: float) -> str:
    if not math.isfinite(x):
        return "∞ (too few stars in some draws)"
    return f"{x:.4f} ({(x - 1) * 100:+.2g} %)".replace("-", "−")


def low_photon_part(ctx: ReportContext) -> Part:
    """Build the low-photon table: Poisson photon counts for small or short-exposure sensors.

    Returns
    -------
    Part
        HTML and numbers ("low_photon").
    """
    primary = ctx.primary
    part = Part()
    part.html.append("<h3>Small sensors and short exposures (sec. 3.3.2)</h3>")
    rows, low = [], []
    seeds = np.random.SeedSequence(ctx.seed).spawn(len(LOW_PHOTON_CASES))
    for (d, t), seed in zip(LOW_PHOTON_CASES, seeds, strict=True):
        ctx.progress(f"limit: low-photon degradation, D = {d:g} m, t = {t:g} s")
        res = low_photon_degradation(
            primary,
            diameter_m=d,
            exposure_s=t,
            n_trials=ctx.low_photon_trials,
            rng=np.random.default_rng(seed),
        )
        d2t = d * d * t
        meets = d2t >= paper.LOW_PHOTON_D2T_M2_S
        rows.append(
            [
                fmt(d),
                fmt(t),
                fmt_int(len(res.expected_photons)),
                fmt_int(res.n_below_one_photon),
                f"{res.expected_observed_stars:,.1f}",
                fmt(res.theta_ideal_rad * RAD_TO_MAS),
                fmt(res.theta_poisson_rad * RAD_TO_MAS),
                _degradation(res.degradation),
                fmt(d2t) + " " + yes_no(meets, "≥ 10⁻⁴", "< 10⁻⁴"),
            ]
        )
        low.append(
            {
                "diameter_m": d,
                "exposure_s": t,
                "d2t_m2_s": d2t,
                "meets_paper_criterion": meets,
                "theta_ideal_mas": res.theta_ideal_rad * RAD_TO_MAS,
                "theta_poisson_mas": res.theta_poisson_rad * RAD_TO_MAS,
                **res.to_dict(),
            }
        )
    part.html.append(
        "<p>A star delivering on average ι photons in an exposure is missed with probability "
        "e<sup>−ι</sup>. Drawing each star's photons from Poisson(ι) "
        f"({ctx.low_photon_trials} draws, seed {ctx.seed}) and weighting its Fisher information by "
        "the photons it actually delivered gives the mean bound of a real exposure. The paper "
        "argues that sensors with D<sup>2</sup> t ≥ 10<sup>−4</sup> m<sup>2</sup> s lose little "
        f"(sec. 3.3.2). Stars: {esc(ctx.catalog_name)}, {esc(primary.colour)}; θ in mas.</p>"
    )
    part.html.append(table(_LOW_PHOTON_HEADERS, rows, classes=["num"] * 8 + [""]))
    part.html.append(_LOW_PHOTON_NOTE)
    part.data["low_photon"] = low
    return part


def table1_part(ctx: ReportContext) -> Part:
    """Build Table 1: the black-body fits of the paper's five reference stars, ours and its.

    Returns
    -------
    Part
        HTML and numbers ("table1").
    """
    ctx.progress("limit: black-body fits of the reference stars (Table 1)")
    part = Part()
    part.html.append("<h3>Black-body fits of reference stars (Table 1)</h3>")
    t1 = table1_rows()
    rows = [
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
        for r in t1
    ]
    part.html.append(
        f"<p>Equivalent black body (T, dilution C) and centroid bound σ = F<sup>−½</sup> "
        f"(eq. 19) for D = {paper.TABLE1_DIAMETER_M * 100:g} cm, "
        f"t = {paper.TABLE1_EXPOSURE_S * 1000:g} ms, "
        "from V with B−V (UBV) and from m<sub>H</sub> with H−K<sub>s</sub> (2MASS); σ in "
        "rad.</p>"
    )
    part.html.append(table(_TABLE1_HEADERS, rows, classes=_TABLE1_CLASSES))
    part.html.append(_TABLE1_NOTE)
    part.data["table1"] = [
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
    return part
