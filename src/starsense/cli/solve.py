"""`starsense solve`: one frame, a batch of frames and folders, or a list of centroids."""

from __future__ import annotations

import csv
import io
import json
import time
from concurrent.futures import ThreadPoolExecutor
from importlib import resources
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from starsense import plotting
from starsense.cli.attitude_json import with_attitude
from starsense.cli.common import (
    CatalogOpt,
    JsonOpt,
    emit,
    option_int,
    output_file,
    parse_floats,
    progress_bar,
)
from starsense.errors import InputError, StarsenseError
from starsense.geometry.apparent import C_M_S, parse_time
from starsense.solve.bayer import check_bayer
from starsense.solve.centroids import read_centroids
from starsense.solve.extraction import solution_detector
from starsense.solve.frames import FITS_SUFFIXES, PILLOW_SUFFIXES, load_image
from starsense.solve.solver import Solver
from starsense.units import DEG

#: the columns of the batch CSV table (without --json), in order
CSV_FIELDS = (
    "image", "status", "ra_deg", "dec_deg", "roll_deg", "fov_deg", "n_detections", "n_matched",
    "rmse_arcsec", "false_match_probability", "time_ms", "message",
)  # fmt: skip


def _image_suffixes() -> set[str]:
    return FITS_SUFFIXES | PILLOW_SUFFIXES


def expand_frames(paths: list[Path]) -> list[Path]:
    """Return the frames named: files as given, folders as their images (sorted, not recursive).

    Raises
    ------
    InputError
        A path that does not exist, or a folder holding no image.
    """
    suffixes = _image_suffixes()
    frames: list[Path] = []
    for p in paths:
        if p.is_dir():
            found = sorted(f for f in p.iterdir() if f.is_file() and f.suffix.lower() in suffixes)
            if not found:
                known = ", ".join(sorted(suffixes))
                raise InputError(f"{p}: no images in this folder (looked for {known})")
            frames.extend(found)
        elif p.exists():
            frames.append(p)
        else:
            raise InputError(f"image not found: {p}")
    return frames


def parse_image_size(text: str) -> tuple[int, int]:
    """Parse "WxH" (e.g. 1024x768) into (width, height), pixels."""
    parts = text.lower().replace(" ", "").split("x")
    if len(parts) != 2 or not all(p.isdigit() and int(p) > 0 for p in parts):
        raise InputError(
            f"--image-size must be WIDTHxHEIGHT in pixels (e.g. 1024x768), got {text!r}"
        )
    return int(parts[0]), int(parts[1])


#: which star extraction the Solver runs (starsense.solve.extraction)
ExtractionOpt = Annotated[
    str,
    typer.Option(
        "--extraction",
        help="auto (default: a quick extraction first, the robust one if that does not "
        "solve), quick or robust.",
    ),
]


RefineOpt = Annotated[
    str | None,
    typer.Option(
        "--refine",
        help="The attitude's last step: model (default with --sensor: the sensor's forward model "
        "fitted to the stars' pixels, sigmas from its Fisher information) or cog (centroids').",
    ),
]


def _solver(
    sensor, fov_deg, catalog, algorithm, apparent=True, observer_velocity_km_s=None, **options
):
    if sensor is not None and fov_deg is not None:
        raise InputError("give --sensor or --fov-deg, not both")
    if fov_deg is not None and not (0.5 <= fov_deg <= 120.0):
        raise InputError(f"--fov-deg must be within [0.5, 120] deg, got {fov_deg}")
    if sensor is None and fov_deg is None and algorithm == "triangle":
        raise InputError("the triangle algorithm needs a known field: give --sensor or --fov-deg")
    refine = options.get("refine")
    if refine is not None and refine not in ("model", "cog"):
        raise InputError(f"--refine must be model or cog, got {refine!r}")
    if refine == "model" and sensor is None:
        raise InputError("--refine model fits the sensor's forward model: give --sensor")
    v_obs = None
    if observer_velocity_km_s is not None:
        v_obs = 1e3 * np.asarray(
            parse_floats(observer_velocity_km_s, "--observer-velocity-km-s", 3)
        )
        if np.linalg.norm(v_obs) >= C_M_S:
            raise InputError(
                f"--observer-velocity-km-s = {observer_velocity_km_s} is "
                f"{np.linalg.norm(v_obs) / 1e3:,.0f} km/s, not below the speed of light "
                f"({C_M_S / 1e3:,.0f} km/s)"
            )
    return Solver(
        sensor,
        fov_rad=None if fov_deg is None else fov_deg * DEG,
        catalog=catalog,
        algorithm=algorithm,
        apparent=apparent,
        observer_velocity_m_s=v_obs,
        **options,
    )


def _summary(name: str, sol) -> list[str]:
    return [
        f"{name}: solved in {sol.time_ms:.0f} ms - RA {sol.ra_deg:.4f} deg, "
        f"Dec {sol.dec_deg:.4f} deg, roll {sol.roll_deg:.3f} deg, FOV {sol.fov_deg:.3f} deg",
        f"  {sol.n_matched} of {sol.n_detections} stars matched, residual "
        f"{sol.rmse_arcsec:.1f} arcsec rms, false-match probability "
        f"{sol.false_match_probability:.1e}",
    ]


def _notes(sol) -> list[str]:
    return [f"  note: {note}" for note in sol.notes]


def _explain(solver, image: Path, sol, out: Path, bayer: str | None) -> None:
    """Draw the frame, its detections, pattern stars, matches and the reason to ``out``."""
    frame = load_image(image, bayer=bayer)
    det = solution_detector(solver, sol)(frame)
    catalog = solver.catalog if sol.solved else None
    fig = plotting.explain.explain_figure(frame, det, sol, catalog=catalog, title=str(image))
    plotting.figure.save_png(fig, out)


def _solve_one(solver, image: Path, wcs: Path | None, as_json: bool, when=None, **opts) -> None:
    bayer, explain = opts.get("bayer"), opts.get("explain")
    try:
        sol = solver.solve_file(image, when, bayer=bayer)
    except InputError as exc:  # every message names the frame
        raise InputError(str(exc) if str(image) in str(exc) else f"{image}: {exc}") from None
    if explain is not None:
        _explain(solver, image, sol, explain, bayer)
    payload = with_attitude({"image": str(image), **sol.to_dict()}, sol)
    if explain is not None:
        payload["explain"] = str(explain)
    if when is not None and sol.apparent and sol.apparent.get("applied"):
        payload["apparent_places"]["time_source"] = "--time"
    if sol.solved:
        lines = _summary(str(image), sol)
        ap = payload.get("apparent_places")
        if ap and ap.get("applied"):
            lines.append(f"  apparent places at {ap['time_utc']} ({ap['time_source']})")
        if wcs is not None:
            payload["wcs"] = str(sol.write_wcs(wcs))
            lines.append(f"  WCS written: {wcs}")
        if explain is not None:
            lines.append(f"  explained: {explain}")
        emit(payload, as_json, lines + _notes(sol))
        return
    if sol.status == "no_stars":
        said = f" (explained: {explain})" if explain is not None else ""
        raise InputError(f"{image}: {sol.message}{said}")
    lines = _not_solved(str(image), sol) + _notes(sol)
    if explain is not None:
        lines.append(f"  explained: {explain}")
    emit(payload, as_json, lines)
    raise typer.Exit(1)


def _not_solved(name: str, sol) -> list[str]:
    """Lines for a frame that did not solve; a mirrored one also gets its flipped attitude."""
    lines = [f"{name}: not solved ({sol.status}): {sol.message}"]
    c = sol.counts
    if "candidates" in c:
        lines.append(
            f"  {c.get('pixels_above_threshold', 0):,} pixels above threshold, "
            f"{c['candidates']:,} candidates, {c.get('detections', 0):,} detections; "
            f"{c.get('patterns_tried', 0):,} patterns tried, best false-match probability "
            f"{c.get('best_false_match_probability', 1.0):.2g}"
        )
    if sol.status == "mirrored":
        lines.append(
            f"  flipped frame: RA {sol.ra_deg:.4f} deg, Dec {sol.dec_deg:.4f} deg, roll "
            f"{sol.roll_deg:.3f} deg, FOV {sol.fov_deg:.3f} deg, {sol.n_matched} of "
            f"{sol.n_detections} stars matched"
        )
    return lines


def _batch_row(solver, image: Path, when=None, bayer: str | None = None) -> dict:
    """Solve one frame of a batch; a frame that cannot be read gets status "unreadable"."""
    t0 = time.perf_counter()
    try:
        sol = solver.solve_file(image, when, bayer=bayer)
    except StarsenseError as exc:
        return {
            "image": str(image),
            "status": "unreadable",
            "message": str(exc),
            "time_ms": (time.perf_counter() - t0) * 1e3,
        }
    return with_attitude({"image": str(image), **sol.to_dict()}, sol)


def _csv_line(row: dict) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="")
    row = {**row, "message": " ".join([row.get("message") or "", *row.get("notes", ())]).strip()}
    writer.writerow(["" if row.get(k) is None else row.get(k) for k in CSV_FIELDS])
    return buf.getvalue()


def _solve_batch(solver, frames: list[Path], jobs: int, as_json: bool, when=None, bayer=None):
    if not as_json:
        typer.echo(",".join(CSV_FIELDS))
    n_solved = 0
    with progress_bar(True) as bar, ThreadPoolExecutor(max_workers=jobs) as pool:
        # the database, once, before the first frame; in a worker, whose buffers it warms
        pool.submit(solver.prepare).result()
        progress = bar.task("Solving", total=len(frames))
        for done, row in enumerate(
            pool.map(lambda f: _batch_row(solver, f, when, bayer), frames), start=1
        ):
            n_solved += row["status"] == "solved"
            typer.echo(json.dumps(row) if as_json else _csv_line(row))
            progress(done, len(frames))
    if n_solved < len(frames):
        raise typer.Exit(1)


def _solve_centroid_file(solver, path: Path, image_size: str | None, as_json: bool, **opts):
    """Solve a centroid list; ``opts``: ``when`` (the image's time), ``wcs`` (a file)."""
    cents = read_centroids(path)
    if image_size is not None:
        size = parse_image_size(image_size)
    elif cents.image_size is not None:
        size = cents.image_size
    else:
        raise InputError("--image-size WIDTHxHEIGHT is needed with --centroids")
    try:
        sol = solver.solve_centroids(
            cents.xy, size, brightness=cents.flux, obs_time=opts.get("when")
        )
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None
    payload = with_attitude({"centroids": str(path), **sol.to_dict()}, sol)
    if opts.get("when") is not None and sol.apparent and sol.apparent.get("applied"):
        payload["apparent_places"]["time_source"] = "--time"
    if sol.solved:
        lines = _summary(str(path), sol)
        wcs = opts.get("wcs")
        if wcs is not None:
            payload["wcs"] = str(sol.write_wcs(wcs))
            lines.append(f"  WCS written: {wcs}")
        emit(payload, as_json, lines)
        return
    emit(payload, as_json, _not_solved(str(path), sol))
    raise typer.Exit(1)


CentroidsOpt = Annotated[
    Path | None,
    typer.Option(
        "--centroids",
        help="Solve a centroid list instead of a frame: CSV (x, y[, flux]; (0, 0) is the "
        "centre of the top-left pixel, x along columns) or astrometry.net xylist FITS "
        "(X, Y[, FLUX], 1-based FITS pixels, converted). Brightest first unless a flux "
        "column is given.",
    ),
]
BayerOpt = Annotated[
    str | None,
    typer.Option(
        "--bayer",
        help="The frames are raw Bayer mosaics of this pattern (RGGB, BGGR, GRBG, GBRG): "
        "solved on their luminance, binned 2 x 2.",
    ),
]
ExplainOpt = Annotated[
    Path | None,
    typer.Option(
        "--explain",
        help="Draw the frame with its detections, pattern stars, matched catalogue stars "
        "(residual arrows) and the reason for a failure to this PNG; one frame only.",
        callback=output_file,
    ),
]


def solve(
    images: Annotated[
        list[Path] | None,
        typer.Argument(help="Frames (BMP, PNG, JPEG, TIFF, FITS; 8-32 bit) and folders of frames."),
    ] = None,
    sensor: Annotated[
        str | None, typer.Option("--sensor", help="Sensor preset or TOML (known optics).")
    ] = None,
    fov_deg: Annotated[
        float | None, typer.Option("--fov-deg", help="Horizontal field, deg (pinhole).")
    ] = None,
    algorithm: Annotated[
        str, typer.Option("--algorithm", help="hashing (default, FOV-free) or triangle.")
    ] = "hashing",
    catalog: CatalogOpt = "hipparcos",
    wcs: Annotated[
        Path | None,
        typer.Option(
            "--wcs",
            help="Write the solution's WCS (FITS header; TAN-SIP if distorted); one frame only.",
            callback=output_file,
        ),
    ] = None,
    time_utc: Annotated[
        str | None,
        typer.Option("--time", help="UTC time of the frame (ISO 8601); else from its header."),
    ] = None,
    no_apparent: Annotated[
        bool, typer.Option("--no-apparent", help="Catalogue places, even when a time is known.")
    ] = False,
    observer_velocity_km_s: Annotated[
        str | None,
        typer.Option("--observer-velocity-km-s", help="Observer's geocentric velocity X,Y,Z."),
    ] = None,
    centroids: CentroidsOpt = None,
    image_size: Annotated[
        str | None,
        typer.Option("--image-size", help="WIDTHxHEIGHT of the centroids' image, pixels."),
    ] = None,
    bayer: BayerOpt = None,
    explain: ExplainOpt = None,
    extraction: ExtractionOpt = "auto",
    refine: RefineOpt = None,
    jobs: Annotated[int, typer.Option("--jobs", help="Frames solved at once (threads).")] = 1,
    as_json: JsonOpt = False,
    schema: Annotated[
        bool, typer.Option("--schema", help="Print the JSON schema of a solution and exit.")
    ] = False,
) -> None:
    """Solve frames lost-in-space: RA, Dec, roll, FOV, matches, residuals, false-match odds.

    One frame prints its solution; several frames or folders are a batch (the database is
    loaded once): one JSON object per line and frame with --json, else a CSV table, and a frame
    that fails gets its status while the batch goes on. Without --sensor or --fov-deg the field
    is searched over 2.8-70 deg. When a frame's time is known (--time, FITS DATE-OBS, EXIF) the
    attitude is fitted to the stars' apparent places (proper motion, parallax, aberration): the
    true ICRS attitude. A frame whose mirror image solves gets status "mirrored" (a camera read
    out flipped) and the flipped frame's attitude. Exit status 0 when every frame solved, 1
    when one does not solve (mirrored included), 2 for bad input (including a single frame
    with no stars, a folder with no images).

    The JSON gives the attitude as quaternion_xyzw (ICRS -> camera, scalar last as in scipy's
    Rotation.from_quat, w >= 0) and rotation_matrix (v_camera = M v_icrs), and sigma_arcsec by
    camera axis (x, y, roll). --schema prints the JSON schema of a solution.
    """
    if schema:
        typer.echo((resources.files("starsense") / "data" / "solve.schema.json").read_text())
        return
    images = list(images or [])
    option_int(jobs, "--jobs", 1, 64)
    bayer = check_bayer(bayer)
    if explain is not None and explain.suffix.lower() != ".png":
        raise InputError(f"--explain writes a PNG figure: give a .png file, got {explain}")

    when = None if time_utc is None else parse_time(time_utc, "--time")
    solver = _solver(sensor, fov_deg, catalog, algorithm, not no_apparent,
                     observer_velocity_km_s, extraction=extraction, refine=refine)  # fmt: skip
    if centroids is not None:
        if images:
            raise InputError("give frames or --centroids, not both")
        for given, name in ((bayer, "--bayer"), (explain, "--explain")):
            if given is not None:
                raise InputError(f"{name} goes with a frame, not with --centroids")
        _solve_centroid_file(solver, centroids, image_size, as_json, when=when, wcs=wcs)
        return
    if image_size is not None:
        raise InputError("--image-size goes with --centroids")
    if not images:
        raise InputError("give a frame, a folder of frames or --centroids FILE")
    frames = expand_frames(images)
    if len(images) == 1 and len(frames) == 1 and not images[0].is_dir():
        _solve_one(solver, frames[0], wcs, as_json, when, bayer=bayer, explain=explain)
        return
    if wcs is not None:
        raise InputError("--wcs writes one frame's WCS: give a single frame")
    if explain is not None:
        raise InputError("--explain draws one frame: give a single frame")
    _solve_batch(solver, frames, jobs, as_json, when, bayer)
