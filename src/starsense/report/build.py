"""Build the HTML report: load the stars, run the section builders, write atomically.

The report is a directory holding ``index.html``, the PNG figures and ``report.json``. It is built
in a temporary directory beside ``out_dir`` and renamed into place only when every section has
succeeded, so a failure leaves the previous report (or nothing) and never a half-written one.
"""

from __future__ import annotations

import datetime
import json
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import starsense
from starsense._io import (
    check_output,
    deferred_signals,
    dir_mode,
    json_text,
    note_written,
    sweep_stale,
    temp_prefix,
)
from starsense.analysis.limits.centroid import check_aperture
from starsense.catalog import load_catalog
from starsense.errors import InputError
from starsense.photometry import COLOUR_SYSTEMS
from starsense.photometry.stars import BlackBodyStars
from starsense.report import page
from starsense.report.availability import availability_section
from starsense.report.datasheet import datasheet_section
from starsense.report.guide_stars import guide_stars_section
from starsense.report.limits import limit_section
from starsense.report.mission import mission_section
from starsense.report.section import ReportContext, Section
from starsense.report.sensors import SensorSpec, load_sensor_table
from starsense.report.slew import slew_section

#: the section builders, in page order: ``builder(ctx) -> Section``. The datasheet first (what
#: the sensor does), then how its numbers were obtained (slew tolerance, availability, over a
#: mission when the sensor TOML names one), then the
#: papers' reproductions as the validation appendix (the limit, the guide stars).
SECTION_BUILDERS: list[Callable[[ReportContext], Section]] = [
    datasheet_section,
    slew_section,
    availability_section,
    mission_section,
    limit_section,
    guide_stars_section,
]
#: the sections of the validation appendix (the first opens it)
APPENDIX_KEYS = ("limit", "guide_stars")

#: the default sensor of the report: the ideal sensor of the paper's Table 2 (D = 10 cm,
#: t = 10 ms)
DEFAULT_DIAMETER_M = 0.10
DEFAULT_EXPOSURE_S = 0.010

#: colour systems in the order the black-body fits are tried (the first found is the primary)
COLOUR_ORDER = ("B-V", "BT-VT", "J-H", "H-Ks", "J-Ks", "V-I", "BP-RP")

GENERATOR = "starsense.report"
INDEX = "index.html"
JSON_NAME = "report.json"


def _noop(message: str) -> None:
    pass


def build_report(
    out_dir,
    *,
    catalog_spec: str = "hipparcos",
    diameter_m: float | None = None,
    exposure_s: float | None = None,
    sensors_table=None,
    progress: Callable[[str], None] | None = None,
    catalog=None,
    stars=None,
    seed: int = 0,
    low_photon_trials: int = 100,
    sensor=None,
    slew_trials: int = 20,
    datasheet_trials: int = 40,
    mass_kg: float | None = None,
    power_w: float | None = None,
) -> Path:
    """Write the performance report to ``out_dir`` (index.html, PNG figures, report.json).

    Parameters
    ----------
    out_dir : str or Path
        Report directory. Created, or replaced if it holds an earlier starsense report; any other
        non-empty directory is refused (InputError) rather than overwritten.
    catalog_spec : str
        What to pass to :func:`starsense.catalog.load_catalog` (default: bundled Hipparcos hip2).
    diameter_m, exposure_s : float, optional
        Aperture D (m) and exposure t (s) of the limit in the summary (default: the sensor's;
        without a sensor the paper's Table 2 ideal sensor, D = 0.1 m, t = 0.01 s).
    sensors_table : str or Path or None
        CSV of real sensors for the Fig. 8 comparison (see :func:`load_sensor_table`).
    progress : callable(str) or None
        Called with a short status message before each step.
    catalog : Catalog-like or None
        Use this catalogue object instead of loading ``catalog_spec`` (columns ``name``,
        ``vectors``, ``mags``, ``colours``, optional ``extra``).
    stars : BlackBodyStars, sequence or mapping of them, or None
        Use these black-body stars directly (one per colour system); overrides the catalogue.
    seed : int
        Root seed of the stochastic parts.
    low_photon_trials : int
        Poisson draws per sensor in the low-photon table (sec. 3.3.2).
    sensor : starsense.sensor.Sensor or None
        The star tracker of the slew section (none: the section says so).
    slew_trials : int
        Monte Carlo trials per (magnitude, rate) in the slew section.
    datasheet_trials : int
        Rendered frames per rate in the datasheet's Monte Carlo check.
    mass_kg, power_w : float or None
        The unit's mass (kg) and power (W) for the performance summary (None: not given).

    Returns
    -------
    Path
        ``out_dir/index.html``.
    """
    t0 = time.perf_counter()
    say = progress or _noop
    if diameter_m is None:
        diameter_m = DEFAULT_DIAMETER_M if sensor is None else sensor.optics.aperture_m
    if exposure_s is None:
        exposure_s = DEFAULT_EXPOSURE_S if sensor is None else sensor.exposure_s
    check_aperture(diameter_m, exposure_s)
    out_dir = check_output(out_dir, "report directory", directory=True).resolve()
    _check_replaceable(out_dir)
    sensors: tuple[SensorSpec, ...] = ()
    if sensors_table is not None:
        say(f"reading sensors table {sensors_table}")
        sensors = tuple(load_sensor_table(sensors_table))

    name, n_catalog, star_sets, catalog = _load_stars(catalog_spec, catalog, stars, say)

    out_dir.parent.mkdir(parents=True, exist_ok=True)
    sweep_stale(out_dir)  # what a killed run left beside the report
    work = Path(tempfile.mkdtemp(prefix=f"{temp_prefix(out_dir)}tmp-", dir=out_dir.parent))
    try:
        ctx = ReportContext(
            work_dir=work,
            catalog_name=name,
            n_catalog=n_catalog,
            stars=star_sets,
            diameter_m=float(diameter_m),
            exposure_s=float(exposure_s),
            sensors=sensors,
            seed=seed,
            low_photon_trials=low_photon_trials,
            progress=say,
            sensor=sensor,
            slew_trials=slew_trials,
            datasheet_trials=datasheet_trials,
            mass_kg=mass_kg,
            power_w=power_w,
            catalog=catalog,
        )
        sections = [builder(ctx) for builder in SECTION_BUILDERS]
        say("writing the report")
        elapsed = time.perf_counter() - t0
        _write_index(work, ctx, sections, elapsed)
        _write_json(work, ctx, sections, elapsed)
        os.chmod(work, dir_mode())  # mkdtemp makes it 0700; a directory the user makes
        with deferred_signals():  # the old report, or the new one: never neither
            _swap_into_place(work, out_dir)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        raise
    say(f"report written to {out_dir / INDEX}")
    return out_dir / INDEX


# ---------------------------------------------------------------------------------------------
# stars


def _load_stars(catalog_spec, catalog, stars, say):
    """Return (catalogue name, rows, {colour: BlackBodyStars}, catalogue or None).

    From whichever was given; the catalogue is the one loaded (or given), None for stars alone.
    """
    if stars is not None:
        if isinstance(stars, BlackBodyStars):
            sets = [stars]
        elif isinstance(stars, Mapping):
            sets = list(stars.values())
        else:
            sets = list(stars)
        if not sets or not all(isinstance(s, BlackBodyStars) for s in sets):
            raise InputError("stars must be a BlackBodyStars or a non-empty sequence of them")
        name = getattr(catalog, "name", None) or "custom star set"
        by_colour = {s.colour: s for s in sets}
        first = sets[0]
        return str(name), len(first) + first.n_skipped, by_colour, catalog
    if catalog is None:
        say(f"loading catalogue {catalog_spec!r}")

        catalog = load_catalog(catalog_spec)
    say(f"fitting black bodies to {len(catalog):,} stars of {catalog.name}")
    primary = BlackBodyStars.from_catalog(catalog)
    by_colour = {primary.colour: primary}
    for colour in COLOUR_ORDER:
        if colour in by_colour or colour not in COLOUR_SYSTEMS:
            continue
        if colour not in catalog.colours:
            continue
        try:
            by_colour[colour] = BlackBodyStars.from_catalog(catalog, colour)
        except InputError:
            continue  # colour present but its magnitude band is not
    return str(catalog.name), len(catalog), by_colour, catalog


# ---------------------------------------------------------------------------------------------
# output


def _check_replaceable(out_dir: Path) -> None:
    """Refuse to replace anything but a missing/empty directory or an earlier report."""
    if not out_dir.exists():
        return
    if not out_dir.is_dir():
        raise InputError(
            f"{out_dir}: exists and is not a directory; choose another output directory"
        )
    if not any(out_dir.iterdir()):
        return
    marker = out_dir / JSON_NAME
    try:
        ok = json.loads(marker.read_text(encoding="utf-8")).get("generator") == GENERATOR
    except (OSError, ValueError, AttributeError):
        ok = False
    if not ok:
        raise InputError(
            f"{out_dir}: directory is not empty and holds no earlier starsense report; "
            "refusing to replace it (choose a new or empty directory)"
        )


def _swap_into_place(work: Path, out_dir: Path) -> None:
    """Rename ``work`` to ``out_dir``, replacing an earlier report with two renames."""
    if not out_dir.exists():
        work.rename(out_dir)
        note_written(out_dir)
        return
    old = Path(tempfile.mkdtemp(prefix=f"{temp_prefix(out_dir)}old-", dir=out_dir.parent))
    old.rmdir()
    out_dir.rename(old)
    try:
        work.rename(out_dir)
    except BaseException:
        old.rename(out_dir)  # put the earlier report back
        raise
    note_written(out_dir)
    shutil.rmtree(old, ignore_errors=True)


def _write_index(work: Path, ctx: ReportContext, sections: Sequence[Section], elapsed: float):
    primary = ctx.primary
    fits = ", ".join(
        f"{page.esc(c)}: {page.fmt_int(len(s))} used, {page.fmt_int(s.n_skipped)} skipped"
        for c, s in ctx.stars.items()
    )
    summary = [
        (
            "Catalogue",
            f"{page.esc(ctx.catalog_name)}: {page.fmt_int(ctx.n_catalog)} stars; "
            f"{page.fmt_int(len(primary))} used, {page.fmt_int(primary.n_skipped)} skipped "
            f"(no finite magnitude or {page.esc(primary.colour)}). Black-body fits per colour: "
            f"{fits}",
        )
    ]
    for s in sections:  # the sensor given; the papers' sensors stay in their appendix
        summary.extend(
            row for row in s.summary if s.key not in APPENDIX_KEYS or "This sensor" in row[0]
        )
    parts = []
    for s in sections:
        if s.key == APPENDIX_KEYS[0]:
            parts.append(
                '<h1 id="validation">Validation appendix: the papers\' reproductions</h1>\n'
                "<p>The sections below reproduce the published analyses the datasheet is built "
                "on, beside the published values.</p>"
            )
        parts.append(
            f'<section id="{page.esc(s.key)}">\n<h2>{page.esc(s.title)}</h2>\n{s.html}\n</section>'
        )
    body = "\n".join(parts)
    now = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    meta = (
        f"starsense {page.esc(starsense.__version__)} · generated {now} in {elapsed:.1f} s · "
        f'numbers in <a href="{JSON_NAME}">{JSON_NAME}</a>'
    )
    text = page.page(
        "starsense performance report",
        meta_html=meta,
        summary_rows=summary,
        nav_items=[(s.key, s.title) for s in sections],
        body=body,
    )
    (work / INDEX).write_text(text, encoding="utf-8")


def _write_json(work: Path, ctx: ReportContext, sections: Sequence[Section], elapsed: float):
    doc = {
        "generator": GENERATOR,
        "starsense_version": starsense.__version__,
        "generated_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "build_seconds": elapsed,
        "catalog": {
            "name": ctx.catalog_name,
            "n_stars": ctx.n_catalog,
            "colours": {
                c: {"n_used": len(s), "n_skipped": s.n_skipped} for c, s in ctx.stars.items()
            },
        },
        "sensor": {"diameter_m": ctx.diameter_m, "exposure_s": ctx.exposure_s},
        "seed": ctx.seed,
        "sections": {
            s.key: {"title": s.title, "figures": list(s.figures), **s.data} for s in sections
        },
    }
    (work / JSON_NAME).write_text(json_text(doc, indent=1), encoding="utf-8")
