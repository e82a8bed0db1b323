"""``starsense guide-stars simulate|select|field``: Lin et al. 2024, Tables 1, 3 and 4.

Thin: parse, check the options (messages name the option), convert degrees and arcseconds to
radians, call :mod:`starsense.analysis.guide_stars`, print. User errors are
:class:`~starsense.errors.InputError`; the main app prints them as one line and exits 2.
"""

from __future__ import annotations

import math
from typing import Annotated

import numpy as np
import typer

from starsense._validate import check_count, check_int, check_scalar, positive_float
from starsense.analysis.guide_stars import (
    CONFIGURATIONS,
    CRITERIA,
    METRICS,
    SIGMA_KINDS,
    field_accuracy,
    field_stars,
    lin_layout,
    select_guide_stars,
    simulate_table1,
)
from starsense.analysis.guide_stars.fields import FIELD_TRIAL_COST, MAX_FIELD_TRIALS
from starsense.analysis.guide_stars.table1 import MAX_TABLE1_TRIALS, TABLE1_TRIAL_COST
from starsense.catalog import load_catalog
from starsense.cli.common import (
    BRIGHTEST_MAG,
    CatalogOpt,
    JsonOpt,
    SeedOpt,
    emit,
    option_float,
    parse_floats,
    progress_bar,
)
from starsense.errors import InputError
from starsense.references import lin2024
from starsense.sensor import load_sensor
from starsense.units import ARCSEC, DEG

guide_stars_app = typer.Typer(
    help="Guide-star distribution for multi-area attitude determination (Lin et al. 2024).",
    no_args_is_help=True,
)


@guide_stars_app.callback()
def _group() -> None:
    """Guide-star distribution for multi-area attitude determination (Lin et al. 2024)."""


@guide_stars_app.command()
def simulate(
    sigmas: Annotated[
        str | None,
        typer.Option(
            "--sigmas-arcsec",
            help="Per-axis measurement errors, arcsec (default: the paper's 0.3 ... 0.01).",
        ),
    ] = None,
    configurations: Annotated[
        str | None,
        typer.Option(
            "--configurations",
            help="Comma-separated: one, two_adjacent, two_symmetric, three, four (default all).",
        ),
    ] = None,
    trials: Annotated[int, typer.Option("--trials", help="Placements per configuration.")] = 10_000,
    fov_deg: Annotated[
        float, typer.Option("--fov-deg", help="Science field side V, deg (paper: 1.138).")
    ] = lin2024.CAMERA_FOV_DEG,
    threshold: Annotated[
        float, typer.Option("--threshold-arcsec", help="Accuracy requirement, arcsec.")
    ] = lin2024.TABLE1_THRESHOLD_ARCSEC,
    metric: Annotated[
        str,
        typer.Option("--metric", help="pointing: cross-boresight error norm; total: with roll."),
    ] = "pointing",
    identify: Annotated[
        bool,
        typer.Option(
            "--identify/--no-identify",
            help="Triangle identification in the loop (a misidentified trial fails).",
        ),
    ] = True,
    sigma_kind: Annotated[
        str,
        typer.Option(
            "--sigma-kind",
            help="1sigma: sigmas are per-axis standard deviations; 3sigma: 3-sigma bounds.",
        ),
    ] = "1sigma",
    seed: SeedOpt = 0,
    as_json: JsonOpt = False,
) -> None:
    """Table 1: probability of accuracy better than the threshold, Monte Carlo and analytic."""
    sig = _sigmas(sigmas, list(lin2024.TABLE1_SIGMAS_ARCSEC))
    configs = _configs(configurations)
    _check_choices(configs, metric, sigma_kind)
    check_count(trials, "--trials", MAX_TABLE1_TRIALS, TABLE1_TRIAL_COST)
    check_scalar(fov_deg, "--fov-deg", 0, 90, lo_open=True, hi_open=True)
    option_float(threshold, "--threshold-arcsec", 0.0, 648_000.0, lo_open=True)  # half a turn
    with progress_bar() as update:
        tab = simulate_table1(
            [s * ARCSEC for s in sig],
            configs,
            n_trials=trials,
            fov_rad=fov_deg * DEG,
            threshold_rad=threshold * ARCSEC,
            metric=metric,
            rng=seed,
            identify=identify,
            sigma_kind=sigma_kind,
            progress=None if as_json else update,
        )
    payload = tab.as_dict()
    names = list(tab.probability_mc)
    lines = [
        f"P(accuracy < {tab.threshold_arcsec:g} arcsec), %, Monte Carlo / analytic "
        f"({tab.n_trials} trials, metric {tab.metric}, sigma {tab.sigma_kind}, "
        f"identification {'in the loop' if tab.identify else 'assumed'}, "
        f"{tab.elapsed_s:.1f} s)",
        "sigma    " + " ".join(f"{c:>15s}" for c in names),
    ]
    for i, s in enumerate(tab.sigma_arcsec):
        cells = " ".join(
            f"{100 * tab.probability_mc[c][i]:7.2f}/{100 * tab.probability_analytic[c][i]:<7.2f}"
            for c in names
        )
        lines.append(f"{s:<8g} {cells}")
    if tab.identify:
        lines.append(
            "identified correctly, %: "
            + ", ".join(f"{c} {100 * tab.identified[c].min():.2f}" for c in names)
            + " (lowest over sigma)"
        )
    emit(payload, as_json, lines)


CenterOpt = Annotated[
    str | None,
    typer.Option("--center-deg", help="Boresight RA,DEC in degrees (default: the paper's fields)."),
]
LensOpt = Annotated[
    float | None,
    typer.Option(
        "--lens-fov-deg",
        help="Lens-circle diameter, deg (the paper's pattern FOV: 1.6 or 0.4); the four areas "
        "are the segments around the inscribed square.",
    ),
]
CriterionOpt = Annotated[
    str,
    typer.Option(
        "--criterion",
        help="trace: smallest covariance trace; rules: most areas, then largest triangles; "
        "brightest.",
    ),
]


def _max_mag(value: float | None) -> float | None:
    """Check ``--max-mag``: NaN (every comparison false: no star kept) or -inf refused."""
    if value is not None and (math.isnan(value) or value == -math.inf):
        raise InputError(f"magnitude limit (--max-mag) must be a number, got {value!r}")
    if value is not None and value < BRIGHTEST_MAG:
        raise InputError(
            f"magnitude limit (--max-mag) = {value:g} is brighter than any star "
            f"(must be >= {BRIGHTEST_MAG:g})"
        )
    return value


MaxMagOpt = Annotated[
    float | None,
    typer.Option(
        "--max-mag", help="Faintest catalogue star used (default: all).", callback=_max_mag
    ),
]


def _center(text: str) -> tuple[float, float]:
    """Return the (RA, Dec) of ``--center-deg``, deg, checked."""
    ra, dec = parse_floats(text, "--center-deg", 2)
    check_scalar(dec, "--center-deg Dec", -90, 90)
    return ra, dec


def _configs(text: str | None) -> list[str] | None:
    """Return the configuration names of ``--configurations`` (None: all)."""
    if text is None:
        return None
    names = [c.strip() for c in text.split(",") if c.strip()]
    if not names:  # '' or ',' ran every configuration, as if the option were not given
        raise InputError(
            f"--configurations {text!r} names no configuration; give one or more of "
            f"{', '.join(CONFIGURATIONS)}, or leave the option out for all"
        )
    return names


#: the largest per-axis error the guide-star commands take, arcsec (a degree)
MAX_SIGMA_ARCSEC = 3600.0


def _sigmas(text: str | None, default: list[float] | None = None) -> list[float]:
    """Return the values of ``--sigmas-arcsec``, arcsec, each checked > 0."""
    sig = parse_floats(text, "--sigmas-arcsec") or default
    for s in sig:
        positive_float(s, "--sigmas-arcsec")
        # a degree at most: 1e308 overflowed the solves' norms (RuntimeWarnings, a silent 0 %)
        check_scalar(s, "--sigmas-arcsec", 0.0, MAX_SIGMA_ARCSEC)
    return sig


def _choice(value: str, allowed, option: str) -> None:
    """Raise InputError naming ``option`` unless ``value`` is one of ``allowed``."""
    if value not in allowed:
        raise InputError(f"{option} {value!r} is not known; choose one of {', '.join(allowed)}")


def _check_choices(configs: list[str] | None, metric: str, sigma_kind: str) -> None:
    """Check ``--configurations``, ``--metric`` and ``--sigma-kind``."""
    for c in configs or ():
        _choice(c, CONFIGURATIONS, "--configurations")
    _choice(metric, METRICS, "--metric")
    _choice(sigma_kind, SIGMA_KINDS, "--sigma-kind")


def _check_lens(lens_fov_deg: float | None) -> None:
    """Check ``--lens-fov-deg`` (the analysis accepts (0, 60) deg)."""
    if lens_fov_deg is not None:
        check_scalar(lens_fov_deg, "--lens-fov-deg", 0, 60, lo_open=True, hi_open=True)


def _areas(areas: str | None) -> tuple[int, ...] | None:
    """Return the area numbers ``--areas`` names (None: all)."""
    if areas is None:
        return None
    try:
        wanted = tuple(int(a) for a in areas.split(",") if a.strip())
    except ValueError:
        raise InputError(f"--areas expects comma-separated integers, got {areas!r}") from None
    if not wanted:  # '' or ',' used no area: "no stars", exit 1, as if the sky were empty
        raise InputError(
            f"--areas {areas!r} names no area; give one or more area numbers, or leave "
            "the option out for all"
        )
    if any(not a.strip() for a in areas.split(",")):  # '1,,2': a number left out?
        raise InputError(f"--areas {areas!r} has an empty item; give numbers between the commas")
    return wanted


@guide_stars_app.command()
def select(
    center: CenterOpt = None,
    lens_fov_deg: LensOpt = None,
    sensor: Annotated[
        str | None,
        typer.Option("--sensor", help="Use a sensor's [attitude_areas] (e.g. lin2024)."),
    ] = None,
    catalog: CatalogOpt = "hipparcos",
    areas: Annotated[
        str | None,
        typer.Option("--areas", help="Comma-separated area numbers to use (default: all)."),
    ] = None,
    n_stars: Annotated[int, typer.Option("--n-stars", help="Guide stars to choose.")] = 5,
    criterion: CriterionOpt = "trace",
    sigma: Annotated[
        float, typer.Option("--sigma-arcsec", help="Per-axis measurement error, arcsec.")
    ] = 0.1,
    roll_deg: Annotated[float, typer.Option("--roll-deg", help="Roll about the boresight.")] = 0.0,
    max_mag: MaxMagOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Choose guide stars in the attitude-determination areas of one pointing."""
    if center is None:
        raise InputError("--center-deg RA,DEC is required")
    if (sensor is None) == (lens_fov_deg is None):
        raise InputError("give exactly one of --lens-fov-deg and --sensor")
    ra, dec = _center(center)
    _check_lens(lens_fov_deg)
    _choice(criterion, CRITERIA, "--criterion")
    check_int(n_stars, "--n-stars", 3)
    positive_float(sigma, "--sigma-arcsec")
    check_scalar(roll_deg, "--roll-deg")
    if sensor is not None:
        sens = load_sensor(sensor)
        if sens.attitude_areas is None:
            raise InputError(f"sensor {sens.name!r} defines no [attitude_areas]")
        layout = sens.attitude_areas
    else:
        layout = lin_layout(lens_fov_deg * DEG)
    wanted = _areas(areas)
    cat = load_catalog(catalog)
    rows, xy, mag, band = field_stars(
        cat, (ra * DEG, dec * DEG), layout=layout, roll_rad=roll_deg * DEG, max_mag=max_mag
    )
    sel = select_guide_stars(
        xy,
        mag,
        layout=layout,
        areas=wanted,
        n_stars=n_stars,
        criterion=criterion,
        sigma_rad=sigma * ARCSEC,
    )
    which = layout.index(xy) if len(xy) else []
    stars = [
        {
            "id": int(cat.ids[rows[i]]),
            "ra_deg": float(np.degrees(cat.ra_rad[rows[i]])),
            "dec_deg": float(np.degrees(cat.dec_rad[rows[i]])),
            "mag": float(mag[i]),
            "area": layout.names[int(which[i]) - 1],
            "field_deg": [float(np.degrees(np.arctan(c))) for c in xy[i]],
        }
        for i in sel.indices
    ]
    payload = {
        "status": sel.status,
        "catalog": cat.name,
        "band": band,
        "criterion": sel.criterion,
        "n_candidates": sel.n_candidates,
        "areas_covered": sel.areas_covered,
        "triangle_ratio": None if not sel.ok else sel.triangle_ratio,
        "predicted_arcsec": None if not sel.ok else sel.predicted_rad / ARCSEC,
        "sigma_arcsec": sigma,
        "guide_stars": stars,
    }
    lines = [
        f"{sel.status}: {sel.n_candidates} {cat.name} stars in the areas; {len(stars)} chosen"
        f" by {sel.criterion}"
    ]
    if sel.ok:
        lines.append(
            f"areas covered {sel.areas_covered}, triangle ratio {sel.triangle_ratio:.3f}, "
            f"predicted accuracy {sel.predicted_rad / ARCSEC:.3g} arcsec rms at "
            f"sigma {sigma:g} arcsec"
        )
    for st in stars:
        lines.append(
            f"  {st['id']:>20d}  RA {st['ra_deg']:9.4f}  Dec {st['dec_deg']:+8.4f}  "
            f"{band} {st['mag']:6.2f}  area {st['area']}"
        )
    emit(payload, as_json, lines)
    if not sel.ok:
        raise typer.Exit(1)


@guide_stars_app.command("field")
def field_cmd(
    center: CenterOpt = None,
    lens_fov_deg: LensOpt = None,
    catalog: CatalogOpt = "hipparcos",
    sigmas: Annotated[
        str, typer.Option("--sigmas-arcsec", help="Average measurement errors, arcsec.")
    ] = "0.2,0.05",
    configurations: Annotated[
        str | None, typer.Option("--configurations", help="Comma-separated (default all).")
    ] = None,
    n_stars: Annotated[int, typer.Option("--n-stars", help="Guide stars per solve.")] = 5,
    criterion: CriterionOpt = "trace",
    trials: Annotated[int, typer.Option("--trials", help="Noisy solves per combination.")] = 2000,
    metric: Annotated[
        str, typer.Option("--metric", help="pointing or total (with roll).")
    ] = "pointing",
    sigma_kind: Annotated[
        str, typer.Option("--sigma-kind", help="1sigma or 3sigma (see simulate).")
    ] = "1sigma",
    max_mag: MaxMagOpt = None,
    seed: SeedOpt = 0,
    as_json: JsonOpt = False,
) -> None:
    """Tables 3-4: average accuracy per configuration for real star fields.

    Without --center-deg, the paper's four patterns: (150, 0) and (240, -80) at 1.6 and 0.4 deg.
    """
    sig = _sigmas(sigmas)
    if center is None:
        centers = [t["center_deg"] for t in lin2024.FIELD_TABLES.values()]
    else:
        centers = [_center(center)]
    _check_lens(lens_fov_deg)
    _check_choices(_configs(configurations), metric, sigma_kind)
    _choice(criterion, CRITERIA, "--criterion")
    check_int(n_stars, "--n-stars", 3)
    check_count(trials, "--trials", MAX_FIELD_TRIALS, FIELD_TRIAL_COST)
    fovs = lin2024.PATTERN_FOVS_DEG if lens_fov_deg is None else (lens_fov_deg,)
    cat = load_catalog(catalog)
    results = []
    lines = []
    for c in centers:
        for fov in fovs:
            res = field_accuracy(
                cat,
                (c[0] * DEG, c[1] * DEG),
                lens_fov_rad=fov * DEG,
                sigmas_rad=[s * ARCSEC for s in sig],
                configurations=_configs(configurations),
                n_stars=n_stars,
                criterion=criterion,
                max_mag=max_mag,
                n_trials=trials,
                metric=metric,
                sigma_kind=sigma_kind,
                rng=seed,
            )
            d = res.as_dict()
            paper = next(
                (t for t in lin2024.FIELD_TABLES.values() if tuple(t["center_deg"]) == tuple(c)),
                None,
            )
            d["paper_accuracy_arcsec"] = (
                {str(k): v for k, v in paper["accuracy_arcsec"].items()}
                if paper is not None and fov == lin2024.PATTERN_FOVS_DEG[0]
                else None
            )
            results.append(d)
            n_in = sum(res.stars_per_area)
            lines.append(
                f"({c[0]:g}, {c[1]:g}) lens {fov:g} deg, {cat.name} ({res.band}): "
                f"{n_in} stars in the areas {list(res.stars_per_area)}"
            )
            lines.append(
                "  mean accuracy, arcsec, at sigma "
                + " / ".join(f"{s:g}" for s in sig)
                + (" (paper)" if d["paper_accuracy_arcsec"] else "")
            )
            for k, acc in res.accuracy_arcsec.items():
                used, total = res.usable[k]
                ours = " / ".join("  --  " if not np.isfinite(a) else f"{a:6.3f}" for a in acc)
                ref = ""
                if d["paper_accuracy_arcsec"]:
                    ref = (
                        "  ("
                        + " / ".join(
                            f"{paper['accuracy_arcsec'].get(s, {}).get(k, float('nan')):g}"
                            for s in sig
                        )
                        + ")"
                    )
                lines.append(f"  {k:<14s} {ours}{ref}   [{used}/{total} combinations usable]")
            if any(u == 0 for u, _ in res.usable.values()):
                lines.append(
                    "  catalogue too shallow here: some configurations have no combination with "
                    "three stars (the paper used DSS images, far deeper)"
                )
    emit({"fields": results}, as_json, lines)
