"""`starsense trade`: the datasheet's trade rows over a grid of designs, and the Pareto set.

``--vary KEY=SPEC`` (repeatable): KEY a sensor TOML field (``exposure_s``,
``optics.focal_length_m``, ``detector.pixel_pitch_m``, ...), SPEC a list (``0.05,0.1,0.2``) or
a range ``START:STOP:N``. ``--keep f_number`` / ``--keep fov`` couple keys (see
:mod:`starsense.analysis.trade.grid`).
"""

from __future__ import annotations

import contextlib
import csv
import io
from pathlib import Path
from typing import Annotated

import typer

from starsense._io import atomic_write, check_outputs_in, json_text
from starsense._validate import check_count
from starsense.analysis.datasheet.compare import ROW_KEYS, format_value
from starsense.analysis.inputs import FRAME_COST, MAX_FRAMES
from starsense.analysis.trade import (
    KEEP,
    MAX_DESIGNS_IN_PROCESS,
    MAX_DESIGNS_ON_CLUSTER,
    base_document,
    designs,
    parse_vary,
    prediction_settings,
    run_trade,
)
from starsense.analysis.trade.keys import OUTPUT_KEYS
from starsense.cli.common import (
    JsonOpt,
    ModelOpt,
    SeedOpt,
    option_float,
    option_int,
    output_dir,
    progress_bar,
)
from starsense.errors import InputError
from starsense.plotting.figure import save_png
from starsense.plotting.trade import FIGURE_STEMS, trade_figures
from starsense.scale.cluster import dask_client
from starsense.units import DEG

__all__ = ["trade"]

#: the columns of the text table: row key, header, format
_TEXT = (
    ("limiting_magnitude", "m_lim", ".2f"),
    ("stars_median", "stars", ".0f"),
    ("nea_cross", 'NEA x"', ".3f"),
    ("nea_roll", 'NEA r"', ".2f"),
    ("nea_over_limit_cross", "NEA/lim", ".1f"),
    ("availability_lis_rest", "LIS@0", ".3f"),
    ("availability_lis_rate", "LIS@w", ".3f"),
    ("fastest_99", "w99 d/s", ".2f"),
    ("ratio_cross", "meas/pred", ".2f"),
)


def _csv_text(study) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    fronts = sorted({k for r in study.rows for k in (r.pareto or {})})
    named = [OUTPUT_KEYS[k] for k in ROW_KEYS]
    writer.writerow(
        ["index", "design", *study.keys, *named, *(f"{k}_capped" for k in named)]
        + [f"pareto_{f}" for f in fronts]
        + ["verified", "error", "warnings"]
    )
    for r in study.rows:
        vals = [r.values.get(k) for k in study.keys]
        rows = r.rows or {}
        got = [rows.get(k, {}).get("value") for k in ROW_KEYS]
        cap = [rows.get(k, {}).get("capped", False) for k in ROW_KEYS]
        marks = [(r.pareto or {}).get(f, False) for f in fronts]
        writer.writerow(
            [
                r.index,
                r.name,
                *vals,
                *("" if v is None else v for v in got),
                *cap,
                *marks,
                r.verified,
                r.error or "",
                "; ".join(r.warnings),
            ]
        )
    return buf.getvalue()


def _jsonl(study) -> str:
    return "".join(json_text(r.to_dict(), indent=None) + "\n" for r in study.rows)


#: with --statement, the ECSS totals (X and Z, at rest and at the rate) after them
_TEXT_ECSS = (
    ("ecss_total_x_rest", 'X@0"', ".3f"),
    ("ecss_total_z_rest", 'Z@0"', ".2f"),
    ("ecss_total_x_rate", 'X@w"', ".3f"),
    ("ecss_total_z_rate", 'Z@w"', ".2f"),
)


def _lines(study) -> list[str]:
    heads = [k.split(".")[-1][:14] for k in study.keys]
    stated = any(r.rows and r.rows["ecss_total_x_rest"]["value"] is not None for r in study.rows)
    columns = _TEXT + (_TEXT_ECSS if stated else ())
    out = [
        "  #  "
        + "".join(f"{h:>15s}" for h in heads)
        + "".join(f"{h:>10s}" for _, h, _ in columns)
        + "  pareto"
    ]
    for r in study.rows:
        left = f"{r.index:3d}  " + "".join(f"{r.values[k]:>15.6g}" for k in study.keys)
        if r.rows is None:
            out.append(f"{left}  error: {r.error}")
            continue
        cells = [
            format_value(r.rows[k]["value"], f, capped=r.rows[k]["capped"]) for k, _, f in columns
        ]
        fronts = ",".join(k for k, on in (r.pareto or {}).items() if on) or "-"
        mark = "  !" if r.warnings else ""
        out.append(left + "".join(f"{c:>10s}" for c in cells) + f"  {fronts}{mark}")
    out.append(
        "pareto: nea_vs_rate = NEA cross vs fastest rate keeping 99 %; roll_vs_aperture = "
        'NEA roll vs aperture; ">= v": the end of the rate grid'
        + (
            "; X@0, Z@0, X@w, Z@w: the ECSS statement's 1-sigma totals at rest and at the rate"
            if stated
            else ""
        )
    )
    return out + _warning_lines(study)


#: the warnings printed under the text table (all of them are in --json and --csv)
_MAX_WARNING_LINES = 20


def _warning_lines(study) -> list[str]:
    """Say each design's datasheet warnings (``!`` in the table), as the datasheet does."""
    said = [(r.index, w) for r in study.rows for w in r.warnings]
    if not said:
        return []
    out = ["! warnings (the datasheet's, per design):"]
    out += [f"  #{i}: {w}" for i, w in said[:_MAX_WARNING_LINES]]
    if len(said) > _MAX_WARNING_LINES:
        out.append(f"  ... and {len(said) - _MAX_WARNING_LINES} more (all in --json and --csv)")
    return out


def _client(address: str | None):
    if address is None:
        return contextlib.nullcontext(None)
    return dask_client(address)


#: the tables ``--out`` gets (the figures follow, ``trade_{stem}.png``)
_TABLES = ("trade.jsonl", "trade.csv")
#: every file ``--out`` gets, checked before the work
_OUT_FILES = (*_TABLES, *(f"trade_{stem}.png" for stem in FIGURE_STEMS))


def _write_out(out: Path, study) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, text in zip(_TABLES, (_jsonl(study), _csv_text(study)), strict=True):
        with atomic_write(out / name) as fh:
            fh.write(text)
        paths.append(out / name)
    for stem, fig in trade_figures(study).items():
        paths.append(save_png(fig, out / f"trade_{stem}.png"))
    return paths


def trade(
    sensor: Annotated[
        str, typer.Option("--sensor", help="Base design: a preset (st16) or a sensor TOML file.")
    ] = "st16",
    vary: Annotated[
        list[str] | None,
        typer.Option(
            "--vary",
            help="KEY=LIST or KEY=START:STOP:N (a sensor TOML field, e.g. "
            "optics.focal_length_m=0.012:0.035:6); repeat it for a grid.",
        ),
    ] = None,
    keep: Annotated[
        list[str] | None,
        typer.Option("--keep", help=f"Keep a coupled quantity of the base: {', '.join(KEEP)}."),
    ] = None,
    rate_deg_s: Annotated[
        float, typer.Option("--rate-deg-s", help="The rate of the 'at rate' rows, deg/s.")
    ] = 1.0,
    frames: Annotated[
        int, typer.Option("--frames", help="Verify designs on N rendered frames per rate.")
    ] = 0,
    verify: Annotated[
        str, typer.Option("--verify", help="Which designs --frames verifies: all or pareto.")
    ] = "all",
    catalog: Annotated[
        str, typer.Option("--catalog", help="Catalogue (default: bundled Hipparcos).")
    ] = "hipparcos",
    workers: Annotated[int, typer.Option("--workers", help="Processes on this machine.")] = 2,
    dask: Annotated[
        str | None,
        typer.Option("--dask", help="Evaluate the designs on this Dask scheduler (or local:N)."),
    ] = None,
    model: ModelOpt = "reed",
    seed: SeedOpt = 0,
    statement: Annotated[
        bool,
        typer.Option(
            "--statement",
            help="Add each design's ECSS statement totals per axis (X, Y, Z; 1 sigma) at rest "
            "and at --rate-deg-s, as datasheet --statement states them (a few seconds a design).",
        ),
    ] = False,
    as_json: JsonOpt = False,
    as_csv: Annotated[bool, typer.Option("--csv", help="Print the rows as CSV.")] = False,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out", callback=output_dir, help="Folder for trade.jsonl, trade.csv, figures."
        ),
    ] = None,
) -> None:
    """Predict every design of a grid around a sensor; one row per design, Pareto set marked."""
    if not vary:
        raise InputError("--vary: give at least one KEY=SPEC")
    if as_json and as_csv:
        raise InputError("--json and --csv: choose one")
    option_float(rate_deg_s, "--rate-deg-s", 0.0, 30.0)
    check_count(frames, "--frames", MAX_FRAMES, FRAME_COST, 0)
    option_int(workers, "--workers", 1, 64)
    if verify not in ("all", "pareto"):
        raise InputError(f"--verify = {verify!r}: must be all or pareto")
    if out is not None:  # the files in the folder: new or regular files, before the work
        check_outputs_in(out, _OUT_FILES, "--out")
    base = base_document(sensor)
    grid = [parse_vary(v) for v in vary]
    cap = MAX_DESIGNS_IN_PROCESS if dask is None else MAX_DESIGNS_ON_CLUSTER
    todo = designs(base, grid, keep=tuple(keep or ()), max_designs=cap)
    settings = prediction_settings(rate_rad_s=rate_deg_s * DEG, rng=seed, model=model)
    with progress_bar(not (as_json or as_csv)) as bar, _client(dask) as client:
        study = run_trade(
            todo,
            catalog,
            settings=settings,
            n_frames=frames,
            verify=verify,
            workers=workers,
            client=client,
            progress=bar.callback,
            statement=statement,
        )
    failed = [r for r in study.rows if r.error is not None]
    if len(failed) == len(study.rows):  # nothing to compare: say so, write nothing, exit 2
        raise InputError(
            f"every design of the grid failed ({len(failed)} of {len(study.rows)}); "
            f"design {failed[0].index} ({failed[0].name}): {failed[0].error}"
        )
    written = _write_out(out, study) if out is not None else []
    if as_json:
        typer.echo(_jsonl(study), nl=False)
    elif as_csv:
        typer.echo(_csv_text(study), nl=False)
    else:
        for line in _lines(study):
            typer.echo(line)
        for p in written:
            typer.echo(f"wrote {p}")
