"""``starsense ecss``: a sensor's ECSS-E-ST-60-20C performance statement (pointing budget)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from starsense._io import atomic_write, check_output, json_text
from starsense.analysis.datasheet import DatasheetSettings
from starsense.analysis.ecss import ecss_statement, parse_confidence
from starsense.analysis.ecss.export import statement_csv, statement_lines
from starsense.analysis.ecss.statement import check_rates
from starsense.catalog import load_catalog
from starsense.cli.common import CatalogOpt, JsonOpt, ModelOpt, SeedOpt, emit, parse_floats
from starsense.errors import InputError
from starsense.sensor import load_sensor
from starsense.units import DEG

__all__ = ["ecss"]

#: the files --out writes, by suffix
_FORMATS = (".csv", ".json")


def ecss(
    sensor: Annotated[
        str, typer.Option("--sensor", help="Sensor preset (st16, esa_blackfly) or a TOML file.")
    ] = "st16",
    confidence: Annotated[
        str,
        typer.Option(
            "--confidence",
            help="Probability each value is not exceeded, per axis: 0.95, 95, 95%, 1sigma, "
            "2sigma or 3sigma (default 1sigma, 68.27 %).",
        ),
    ] = "1sigma",
    rates: Annotated[
        str | None,
        typer.Option(
            "--rates", help="Body rates, deg/s, comma-separated (default: 0 and --rate-deg-s)."
        ),
    ] = None,
    rate_deg_s: Annotated[
        float, typer.Option("--rate-deg-s", help="The datasheet's check rate, deg/s.")
    ] = 1.0,
    catalog: CatalogOpt = "hipparcos",
    n_orientations: Annotated[
        int, typer.Option("--n-orientations", help="Boresights of the sky statistics.")
    ] = 2000,
    n_slew_trials: Annotated[
        int, typer.Option("--n-slew-trials", help="Renders per (magnitude, rate) of the slew run.")
    ] = 20,
    model: ModelOpt = "reed",
    refine: Annotated[
        str, typer.Option("--refine", help="The solver: model (default, the fit) or cog.")
    ] = "model",
    seed: SeedOpt = 0,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out", help="Write the statement to FILE.csv (a pointing budget) or FILE.json."
        ),
    ] = None,
    as_json: JsonOpt = False,
) -> None:
    """State the sensor's ECSS-E-ST-60-20C performance: each error class per axis X, Y, Z, at
    a confidence, at rest and under slew (which errors act as bias and which as noise)."""  # noqa: D205, D209
    p = parse_confidence(confidence)
    rate_list = check_rates(
        parse_floats(rates, "--rates", lo=0.0, hi=30.0) if rates is not None else (0.0, rate_deg_s)
    )
    if out is not None:
        if out.suffix.lower() not in _FORMATS:
            raise InputError(f"--out {out}: the file must end in .csv or .json, not {out.suffix!r}")
        check_output(out, "--out")
    settings = DatasheetSettings(
        n_trials=0,
        rate_rad_s=rate_deg_s * DEG,
        seed=seed,
        n_orientations=n_orientations,
        n_slew_trials=n_slew_trials,
        model=model,
        refine=refine,
    )
    sens = load_sensor(sensor)
    statement = ecss_statement(
        sens, load_catalog(catalog), confidence=p, rates_deg_s=rate_list, settings=settings
    )
    payload = statement.to_dict()
    lines = statement_lines(statement)
    if out is not None:
        text = statement_csv(statement) if out.suffix.lower() == ".csv" else json_text(payload)
        with atomic_write(out) as fh:
            fh.write(text)
        payload = {**payload, "files": [str(out)]}
        lines.append(f"wrote {out}")
    emit(payload, as_json, lines)
