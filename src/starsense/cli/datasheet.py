"""``starsense datasheet``: what the given sensor will do, predicted and verified in one run."""

from __future__ import annotations

import contextlib
import re
from importlib import resources
from pathlib import Path
from typing import Annotated

import typer

from starsense._io import atomic_write, check_output, check_outputs_in, json_text
from starsense._validate import check_count
from starsense.analysis.availability.pointings import MAX_ORIENTATIONS, ORIENTATION_COST
from starsense.analysis.centroid_trials import centroid_trials
from starsense.analysis.datasheet import Comparison, DatasheetSettings, build_datasheet
from starsense.analysis.datasheet.compare import comparison_rows
from starsense.analysis.inputs import FRAME_COST, MAX_FRAMES
from starsense.catalog import load_catalog
from starsense.cli.against import AgainstExposureOpt, AgainstOpt, MoreFramesOpt, run_against
from starsense.cli.common import (
    JsonOpt,
    ModelOpt,
    SeedOpt,
    emit,
    option_float,
    progress_bar,
)
from starsense.cli.datasheet_statement import (
    BudgetCsvOpt,
    ConfidenceOpt,
    MassOpt,
    PowerOpt,
    StatementOpt,
    StatementRatesOpt,
    SummaryPdfOpt,
    statement_request,
    statement_section,
)
from starsense.errors import InputError
from starsense.identify.hashing import MIN_SOLVING_STARS
from starsense.plotting.datasheet import nea_sky_figure
from starsense.plotting.figure import save_png
from starsense.scale import dask_client
from starsense.sensor import load_sensor
from starsense.units import DEG

__all__ = ["datasheet", "datasheet_lines", "safe_stem"]


def _f(value, fmt: str = ".2f", none: str = "n/a") -> str:
    return none if value is None else format(value, fmt)


def _pct(value) -> str:
    return "n/a" if value is None else f"{value:.1%}"


def _ratio(run: dict, axis: str) -> str:
    """Return a ratio and its 95 % interval over the frames: ``1.04 (0.91-1.19)``."""
    ci = run.get(f"{axis}_ratio_ci95")
    band = "" if ci is None else f" ({ci[0]:.2f}-{ci[1]:.2f})"
    return _f(run[f"{axis}_ratio"]) + band


def datasheet_lines(d: dict) -> list[str]:
    """Return the datasheet as text lines (what the command prints without ``--json``)."""
    if d.get("limiting_magnitude") is None:
        return [f"{d['sensor']}: {w}" for w in d.get("warnings", [])]
    nea, lim, mc, av = d["nea_arcsec"], d["limit_arcsec"], d["monte_carlo"], d["availability"]
    mr = d["monte_carlo_at_rate"]
    fast = av["fastest_rate_deg_s"]
    w, h = d["fov_deg"]
    lines = [
        f"{d['sensor']} datasheet ({d['schema']})",
        f"  field {w:.2f} x {h:.2f} deg, {d['pixel_scale_arcsec']:.2f} arcsec/px; limiting "
        f"magnitude {d['limiting_magnitude']:.2f} (50 % detected at rest)",
        f"  stars in the field: median {d['stars_in_fov']['median']:g}, 5th percentile "
        f"{d['stars_in_fov']['p05']:g}; photo-electrons: mag 0 {d['electrons']['magnitude_0']:.3g}"
        f", limit {d['electrons']['limiting_magnitude']:.3g}",
        f"  NEA (1 sigma) cross-boresight {_f(nea['cross']['median'])} arcsec (95 %: "
        f"{_f(nea['cross']['p95'])}), roll {_f(nea['roll']['median'])} arcsec (95 %: "
        f"{_f(nea['roll']['p95'])}); roll/cross {_f(d['roll_over_cross']['nea'])} (geometry "
        f"{_f(d['roll_over_cross']['geometry'])})",
        f"  physical limit (D, t, field of this sensor): cross {_f(lim['cross'], '.4f')}, roll "
        f"{_f(lim['roll'], '.4f')} arcsec; NEA / limit {_f(d['nea_over_limit']['cross'], '.0f')}"
        f" / {_f(d['nea_over_limit']['roll'], '.0f')}",
    ]
    for label, run in (("at rest", mc), (f"at {mr['rate_deg_s']:g} deg/s", mr)):
        lines.append(
            f"  lost in space {label}: {run['solved']}/{run['frames']} solved, {run['wrong']} "
            f"wrong (rate < {run['wrong_rate_upper95']:.2g}, 95 %), {_f(run['median_ms'], '.0f')}"
            f" ms median, {_f(run['p95_ms'], '.0f')} ms 95 %; rms cross "
            f"{_f(run['cross_rms_arcsec'])} / roll {_f(run['roll_rms_arcsec'])} arcsec "
            f"(predicted {_f(run['cross_predicted_arcsec'])} / "
            f"{_f(run['roll_predicted_arcsec'])}), measured/predicted {_ratio(run, 'cross')}"
            f" / {_ratio(run, 'roll')} (95 % over the frames)"
        )
    lines += [
        f"  availability (lost in space N>={MIN_SOLVING_STARS} / tracking N>=2): "
        + ", ".join(
            f"{r:g} deg/s {_pct(a)} / {_pct(t)}"
            for r, a, t in zip(
                av["rates_deg_s"], av["lost_in_space_at_rate"], av["tracking_at_rate"], strict=True
            )
        ),
        "  fastest rate keeping 50/90/99 % (deg/s): lost in space "
        + " / ".join(_f(fast["lost_in_space"][k]) for k in ("50", "90", "99"))
        + ", tracking "
        + " / ".join(_f(fast["tracking"][k]) for k in ("50", "90", "99")),
        "  budget (arcsec, cross / roll):",
    ]
    lines += [
        f"    {b['term']}: {_f(b['cross_arcsec'], '.3f')} / {_f(b['roll_arcsec'], '.3f')} "
        f"[{b['source']}]"
        for b in d["budget"]
    ]
    if d.get("quoted"):
        lines.append(f"  predicted / quoted ({d.get('quoted_source')}):")
        lines += [
            f"    {q['key']}: {_f(q['predicted'], '.3g')} / {q['quoted']:g} "
            f"(ratio {_f(q['ratio'])})"
            for q in d["quoted"]
        ]
    lines += [f"  note: {w}" for w in d.get("warnings", [])]
    return lines


def _compare_lines(comparison) -> list[str]:
    """Datasheets side by side (one column per sensor)."""
    width = max(12, *(len(name) for name in comparison.sensors))
    out = [f"{'':34s}" + "".join(f"{name:>{width + 2}s}" for name in comparison.sensors)]
    for row in comparison.rows:
        if row.key.startswith("ecss_") and all(v is None for v in row.values):
            continue  # no --statement: nothing stated to compare
        cells = row.cells()
        out.append(f"{row.label:34s}" + "".join(f"{c:>{width + 2}s}" for c in cells))
    return out


def safe_stem(name: str, taken: set[str] | None = None) -> str:
    """Return a file-name stem made from a sensor's ``name``, safe to join to any folder.

    Every character but letters, digits, ``.``, ``_`` and ``-`` becomes ``_``; leading dots are
    dropped (no ``..``, no hidden file); an empty result is ``sensor``. A stem already in
    ``taken`` gets ``-2``, ``-3``, ... (two sensors of one name write two files); the stem
    returned is added to ``taken``.

    Parameters
    ----------
    name : str
        The sensor's name (free text from its TOML).
    taken : set of str, optional
        Stems already used in this run (updated).

    Returns
    -------
    str
    """
    stem = re.sub(r"[^A-Za-z0-9._-]", "_", name).lstrip(".") or "sensor"
    if taken is None:
        return stem
    out, k = stem, 2
    while out in taken:
        out, k = f"{stem}-{k}", k + 1
    taken.add(out)
    return out


#: the files ``--out`` gets per sensor: ``{stem}_datasheet.json`` and its NEA sky map
_OUT_FILES = ("datasheet.json", "nea_sky.png")


def _write_out(out: Path, sheet, payload: dict, stem: str) -> list[str]:
    """Write ``{stem}_datasheet.json`` and the NEA sky map into ``out``; return the paths."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{stem}_{_OUT_FILES[0]}"
    with atomic_write(path) as fh:
        fh.write(json_text(payload, indent=1))
    written = [str(path)]
    if sheet.boresights is not None:
        written.append(str(save_png(nea_sky_figure(sheet), out / f"{stem}_{_OUT_FILES[1]}")))
    return written


RefineOpt = Annotated[
    str,
    typer.Option(
        "--refine",
        help="The solver predicted and checked: model (default: the forward model's fit, whose "
        "NEA is its Cramer-Rao bound) or cog (centroids' attitude, as flight software's).",
    ),
]


CentroidsOnlyOpt = Annotated[
    bool,
    typer.Option(
        "--centroids-only",
        help="Only lost in space on --trials simulated centroid sets (predicted noise, "
        "dropped and false stars; no image): wrong solutions and the 95 % bound.",
    ),
]


def datasheet(
    more_frames: MoreFramesOpt = None,
    sensor: Annotated[
        str | None,
        typer.Option(
            "--sensor",
            help="Sensor preset (st16, esa_blackfly) or a TOML file [default: st16]; with "
            "--compare, the first of the sensors compared.",
        ),
    ] = None,
    compare: Annotated[
        list[str] | None,
        typer.Option("--compare", help="Sensors (presets or TOML) side by side; repeat it."),
    ] = None,
    catalog: Annotated[
        str, typer.Option("--catalog", help="Catalogue (default: bundled Hipparcos).")
    ] = "hipparcos",
    rate_deg_s: Annotated[
        float, typer.Option("--rate-deg-s", help="Rate of the second Monte Carlo, deg/s.")
    ] = 1.0,
    trials: Annotated[int, typer.Option("--trials", help="Monte Carlo frames per rate.")] = 100,
    n_orientations: Annotated[
        int, typer.Option("--n-orientations", help="Boresights of the sky statistics.")
    ] = 2000,
    model: ModelOpt = "reed",
    seed: SeedOpt = 0,
    dask: Annotated[
        str | None,
        typer.Option("--dask", help="Run the Monte Carlo on this Dask scheduler (or local:N)."),
    ] = None,
    out: Annotated[
        Path | None, typer.Option("--out", help="Folder for the JSON and the figures.")
    ] = None,
    as_json: JsonOpt = False,
    schema: Annotated[
        bool, typer.Option("--schema", help="Print the JSON schema of the datasheet and exit.")
    ] = False,
    centroids_only: CentroidsOnlyOpt = False,
    refine: RefineOpt = "model",
    against: AgainstOpt = None,
    exposure_s: AgainstExposureOpt = None,
    statement: StatementOpt = False,
    confidence: ConfidenceOpt = None,
    rates: StatementRatesOpt = None,
    budget_csv: BudgetCsvOpt = None,
    summary_pdf: SummaryPdfOpt = None,
    mass_kg: MassOpt = None,
    power_w: PowerOpt = None,
) -> None:
    """Predict what the sensor does (accuracy, lost in space, slew, availability, limit) and
    verify it on rendered frames in the same run."""  # noqa: D205, D209
    if schema:
        typer.echo((resources.files("starsense") / "data" / "datasheet.schema.json").read_text())
        return
    _check_numbers(trials, n_orientations, rate_deg_s, seed=seed)
    frames = (against, more_frames, exposure_s)
    # --sensor with --compare is one more sensor of the comparison, first (never dropped)
    names = [n for n in (sensor, *(compare or ())) if n is not None] or ["st16"]
    rendered = not centroids_only and not against and not more_frames
    request = statement_request(
        statement,
        (confidence, rates, budget_csv, summary_pdf, mass_kg, power_w),
        single=rendered,
        several=len(names) > 1,
    )
    if run_against(sensor, *frames, catalog=catalog, seed=seed, js=as_json):
        return
    if out is not None:  # the place, before any work: a folder (created) we may write in
        check_output(out, "--out", directory=True)
    sensors = [load_sensor(n) for n in names]
    if out is not None and not centroids_only:  # the files in it, named by the sensors
        taken: set[str] = set()
        stems = [safe_stem(s.name, taken) for s in sensors]
        check_outputs_in(out, [f"{t}_{end}" for t in stems for end in _OUT_FILES], "--out")
    cat = load_catalog(catalog)
    if centroids_only:
        _centroids_only(sensors, cat, trials=trials, model=model, seed=seed, dask=dask, js=as_json)
        return
    settings = DatasheetSettings(
        n_trials=trials,
        rate_rad_s=rate_deg_s * DEG,
        seed=seed,
        n_orientations=n_orientations,
        model=model,
        refine=refine,
    )
    sheets, payloads, extra = _sheets(
        sensors, cat, settings, request=request, dask=dask, js=as_json
    )
    _emit_sheets(sheets, payloads, extra, out=out, js=as_json)


def _check_numbers(trials: int, n_orientations: int, rate_deg_s: float, *, seed: int) -> None:
    """Refuse a count, rate or seed out of range (before any work)."""
    check_count(trials, "--trials", MAX_FRAMES, FRAME_COST)
    check_count(n_orientations, "--n-orientations", MAX_ORIENTATIONS, ORIENTATION_COST)
    option_float(rate_deg_s, "--rate-deg-s", 0.0, 30.0)
    if seed < 0:
        raise InputError(f"--seed = {seed} is out of range; must be an integer >= 0")


def _emit_sheets(sheets, payloads, extra, *, out, js) -> None:
    """Write ``--out``'s files, then print one datasheet (and ``extra`` lines) or the comparison."""
    figures = []
    if out is not None:
        taken: set[str] = set()
        for s, p in zip(sheets, payloads, strict=True):
            figures += _write_out(Path(out), s, p, safe_stem(p["sensor"], taken))
    if len(sheets) > 1:
        comparison = Comparison(tuple(sheets), comparison_rows(payloads))
        payload = {"sensors": payloads, "rows": [r.to_dict() for r in comparison.rows]}
        lines = _compare_lines(comparison)
    else:
        payload = payloads[0]
        lines = datasheet_lines(payload) + extra
    if figures:
        payload = {**payload, "files": figures}
        lines += [f"wrote {f}" for f in figures]
    emit(payload, js, lines)


def _sheets(sensors, cat, settings, *, request, dask, js) -> tuple[list, list[dict], list[str]]:
    """Build each sensor's datasheet, and its statement if asked (``--statement``)."""
    sheets, sections, lines = [], [], []
    with progress_bar(not js) as bar, _client(dask) as client:
        for sens in sensors:
            sheet = build_datasheet(
                sens, cat, settings=settings, client=client, progress=bar.callback
            )
            sheets.append(sheet)
            section = None  # None: the sensor detects no star (its warnings say why)
            if request is not None and sheet.limiting_magnitude is not None:
                section, told = statement_section(
                    sens, cat, settings, sheet=sheet, request=request, client=client
                )
                lines = told if len(sheets) == 1 else lines  # text: the first sensor's
            sections.append(section)
    payloads = [s.to_dict() for s in sheets]
    if request is not None:
        for payload, section in zip(payloads, sections, strict=True):
            payload["statement"] = section
    return sheets, payloads, lines


def _centroids_only(sensors, cat, *, trials, model, seed, dask, js) -> None:
    """``--centroids-only``: the centroid-level lost-in-space run of each sensor."""
    results = []
    with progress_bar(not js) as bar, _client(dask) as client:
        tick = bar.callback
        for sens in sensors:
            results.append(
                centroid_trials(
                    sens,
                    cat,
                    n_trials=trials,
                    model=model,
                    rng=seed,
                    client=client,
                    progress=None if tick is None else lambda d, t: tick("lost in space", d, t),
                ).to_dict()
            )
    lines = [
        f"{r['sensor']} lost in space on simulated centroids: {r['trials']} trials, "
        f"{r['solved']} solved, {r['wrong']} wrong; false-identification rate < "
        f"{r['wrong_rate_upper95']:.2g} (95 %, Clopper-Pearson); solve median "
        f"{_f(r['solve_ms_median'])} ms; wall {r['wall_s']:.1f} s on {r['workers']} worker(s)"
        for r in results
    ]
    emit(results[0] if len(results) == 1 else {"sensors": results}, js, lines)


def _client(address: str | None):
    if address is None:
        return contextlib.nullcontext(None)

    return dask_client(address)
