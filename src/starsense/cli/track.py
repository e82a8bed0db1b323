"""`starsense track`: a sequence of frames tracked, one line per frame (attitude, rate, status)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from starsense._io import json_text
from starsense.cli.attitude_json import with_attitude
from starsense.cli.common import CatalogOpt, JsonOpt, option_float, parse_floats
from starsense.errors import InputError
from starsense.solve.solver import Solver
from starsense.solve.tracking import Prior, Tracker
from starsense.solve.tracking.tracker import MIN_INTERVAL_S
from starsense.units import DEG


def _line(r) -> str:
    s = r.solution
    head = f"{r.image}: {s.status} ({r.mode})"
    if s.rotation is None:
        return f"{head}: {s.message}"
    rate = (
        "rate n/a"
        if r.rate_rad_s is None
        else ("rate " + ", ".join(f"{v:+.4f}" for v in np.degrees(r.rate_rad_s)) + " deg/s")
    )
    return (
        f"{head}: RA {s.ra_deg:.5f} Dec {s.dec_deg:.5f} roll {s.roll_deg:.4f} deg, {rate}, "
        f"{s.n_matched} of {s.n_detections} stars, {s.time_ms:.0f} ms"
    )


def track(
    frames: Annotated[list[Path], typer.Argument(help="Frames in time order (TIFF/PNG/FITS).")],
    sensor: Annotated[str, typer.Option("--sensor", help="Sensor preset or TOML (optics).")],
    interval_s: Annotated[
        float | None,
        typer.Option("--interval-s", help="Time between frames, s (needed for the rate)."),
    ] = None,
    prior_radec_roll_deg: Annotated[
        str | None,
        typer.Option(
            "--prior-radec-roll-deg",
            help="RA,DEC,ROLL of the first frame, deg (else it is solved lost-in-space).",
        ),
    ] = None,
    prior_sigma_deg: Annotated[
        float, typer.Option("--prior-sigma-deg", help="1-sigma of the prior, deg.")
    ] = 0.1,
    catalog: CatalogOpt = "hipparcos",
    as_json: JsonOpt = False,
) -> None:
    """Track a sequence: each frame from the last attitude, lost-in-space when that fails.

    One line per frame (with --json one JSON object per line): status, mode (tracking or
    lost_in_space), RA, Dec, roll (and in JSON quaternion_xyzw: ICRS -> camera, scalar last;
    rotation_matrix; sigma_arcsec by axis x, y, roll), body rate from consecutive frames, stars
    used, time. A
    missing or unreadable frame gets status "unreadable" and the rest go on. Exit status 0
    when some frame has an attitude, 1 when none has, 2 for bad input.
    """
    if interval_s is not None:
        # up to a day: 1e308 made the rate estimate's rotation fail deep in SciPy (a traceback)
        option_float(interval_s, "--interval-s", MIN_INTERVAL_S, 86_400.0)
    option_float(prior_sigma_deg, "--prior-sigma-deg", 0.0, 10.0, lo_open=True)
    prior = None
    if prior_radec_roll_deg is not None:
        ra, dec, roll = parse_floats(prior_radec_roll_deg, "--prior-radec-roll-deg", 3)
        option_float(dec, "--prior-radec-roll-deg (Dec)", -90.0, 90.0)
        prior = Prior.from_radec_roll(
            ra * DEG, dec * DEG, roll * DEG, sigma_rad=prior_sigma_deg * DEG
        )
    if not frames:
        raise InputError("give at least one frame")
    tracker = Tracker(Solver(sensor, catalog=catalog), interval_s=interval_s, prior=prior)
    any_attitude = False
    for path in frames:
        r = tracker.track_file(path)
        any_attitude |= r.has_attitude
        line = json_text(with_attitude(r.to_dict(), r.solution), indent=None)
        typer.echo(line if as_json else _line(r))
    if not any_attitude:
        raise typer.Exit(1)
