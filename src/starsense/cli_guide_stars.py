"""``starsense guide-stars simulate``: Lin et al. 2024, Table 1.

Thin: parse, call :func:`starsense.analysis.guide_stars.simulate_table1`, print. User errors are
:class:`~starsense.errors.InputError`; the main app prints them as one line and exits 2.
"""

from __future__ import annotations

from typing import Annotated

import typer

from starsense.cli_common import JsonOpt, SeedOpt, emit, parse_floats

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
    ] = 2048 * 2.0 / 3600.0,
    threshold: Annotated[
        float, typer.Option("--threshold-arcsec", help="Accuracy requirement, arcsec.")
    ] = 0.1,
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
    from starsense.analysis.guide_stars import PAPER_SIGMAS_ARCSEC, simulate_table1

    sig = parse_floats(sigmas, "--sigmas-arcsec") or list(PAPER_SIGMAS_ARCSEC)
    configs = (
        None
        if configurations is None
        else [c.strip() for c in configurations.split(",") if c.strip()]
    )
    tab = simulate_table1(
        sig,
        configs,
        n_trials=trials,
        fov_deg=fov_deg,
        threshold_arcsec=threshold,
        metric=metric,
        seed=seed,
        identify=identify,
        sigma_kind=sigma_kind,
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
