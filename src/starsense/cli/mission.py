"""``starsense availability mission``: availability along an orbit, with the Sun, Moon and Earth.

Thin: parse the orbit, the attitude profile and the heads (degrees and km at this edge),
build the geometry, count the stars, print or write. Registered on the ``availability``
group by :mod:`starsense.cli.app`.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Annotated

import typer

from starsense import plotting
from starsense._io import check_output
from starsense._validate import check_count
from starsense.analysis.availability import catalog_stars
from starsense.analysis.mission import (
    Head,
    TimeGrid,
    TleOrbit,
    mission_availability,
    mission_geometry,
    parse_time,
)
from starsense.analysis.mission.specs import parse_attitude, parse_head, parse_orbit
from starsense.analysis.mission.timegrid import MAX_STEPS
from starsense.analysis.slew import MAX_TRIALS_PER_POINT, SLEW_TRIAL_COST
from starsense.catalog import load_catalog
from starsense.cli.availability_options import (
    FovOpt,
    HalfFovOpt,
    MaxMagOpt,
    ModelOpt,
    NMinOpt,
    ToleranceOpt,
    TrialsOpt,
    check_max_mag,
    check_n_min,
    field_of_view_option,
    sensor_threshold,
)
from starsense.cli.common import CatalogOpt, JsonOpt, SeedOpt, emit, option_float, progress_bar
from starsense.errors import InputError
from starsense.sensor import load_sensor

__all__ = ["mission"]

# the forms of starsense.analysis.mission.specs
ORBIT_HELP = (
    "sso:ALT_KM[:LTAN_H] (sun-synchronous, circular; LTAN default 6 = dawn-dusk), "
    "circular:ALT_KM:INC_DEG[:RAAN_DEG[:ARGLAT_DEG]], or "
    "kepler:A_KM,E,INC_DEG,RAAN_DEG,ARGP_DEG,MEAN_ANOMALY_DEG (elements at --start)."
)
ATTITUDE_HELP = (
    "inertial:RA,DEC,ROLL (deg) | nadir | nadir:yaw (yaw steering on) | sun | "
    "target:LAT,LON (deg, geodetic) | quaternions:FILE (CSV t_s,qx,qy,qz,qw, ICRS -> body)."
)
START_HELP = "Start, ISO 8601 UTC (default: the TLE epoch, else 2025-03-20T12:00)."
HEADS_HELP = (
    "Heads: SENSOR[@qx,qy,qz,qw] (mounting body -> head, scalar last) or "
    "SENSOR@SEQ:A[,B[,C]] (Euler angles, deg, a scipy sequence: x, xyz, ZYX...); no mounting: "
    "the head looks along body +z. Append =NAME to name the head (e.g. st16@0.7071068,0,0,"
    "0.7071068=+Y). Give several after one --heads, or repeat --heads."
)


def _orbit(orbit: str | None, tle: Path | None, start: str | None):
    """Return (orbit, start) from --orbit / --tle / --start."""
    if (orbit is None) == (tle is None):
        raise InputError("give exactly one of --orbit and --tle")
    if tle is not None:
        orb = TleOrbit.from_file(tle)
        return orb, parse_time(start, "--start") if start else orb.epoch
    t0 = parse_time(start or "2025-03-20T12:00:00", "--start")
    return parse_orbit(orbit, t0, "--orbit"), t0


def _heads(specs: list[str], fov: str, half_fov_deg, model, trials, seed, tolerance_json, bar):
    """Return the heads and the faintest static threshold among them (V)."""
    if not specs:
        raise InputError("give at least one head: --heads st16[@qx,qy,qz,qw] ...")
    parsed, seen = [], {}
    for spec in specs:  # every mounting checked before any slow work
        name, label, mounting = parse_head(spec, "--heads")
        seen[label] = seen.get(label, 0) + 1
        label = label if seen[label] == 1 else f"{label}#{seen[label]}"
        parsed.append((name, label, {} if mounting is None else {"mounting": mounting}))
    sensors = {name: load_sensor(name) for name, _, _ in parsed}
    thresholds = {
        name: sensor_threshold(
            sens,
            model=model,
            n_trials=trials,
            seed=seed,
            tolerance_json=tolerance_json,
            progress=bar.callback,
        )
        for name, sens in sensors.items()
    }
    heads = [
        Head(
            label,
            field_of_view_option(sensors[name], fov, half_fov_deg),
            thresholds[name][0],
            exclusion=sensors[name].exclusion,
            **kwargs,
        )
        for name, label, kwargs in parsed
    ]
    # the catalogue cut every head needs: the faintest static threshold of the heads
    return heads, max(rest for _, rest in thresholds.values())


def mission(
    heads: Annotated[list[str] | None, typer.Option("--heads", help=HEADS_HELP)] = None,
    more_heads: Annotated[
        list[str] | None, typer.Argument(help="More heads (after --heads).", show_default=False)
    ] = None,
    orbit: Annotated[str | None, typer.Option("--orbit", help=ORBIT_HELP)] = None,
    tle: Annotated[Path | None, typer.Option("--tle", help="TLE file (2 or 3 lines).")] = None,
    attitude: Annotated[str, typer.Option("--attitude", help=ATTITUDE_HELP)] = "nadir",
    start: Annotated[str | None, typer.Option("--start", help=START_HELP)] = None,
    duration_h: Annotated[float, typer.Option("--duration-h", help="Span, hours.")] = 24.0,
    step_s: Annotated[float, typer.Option("--step-s", help="Time step, seconds.")] = 1.0,
    catalog: CatalogOpt = "hipparcos",
    max_mag: MaxMagOpt = None,
    n_min: NMinOpt = 3,
    fov: FovOpt = "rectangular",
    half_fov_deg: HalfFovOpt = None,
    model: ModelOpt = "reed",
    trials: TrialsOpt = 20,
    tolerance_json: ToleranceOpt = None,
    seed: SeedOpt = 0,
    plot: Annotated[Path | None, typer.Option("--plot", help="Write the timeline (PNG).")] = None,
    as_json: JsonOpt = False,
) -> None:
    """Availability along a mission: orbit, attitude profile, bright bodies, several heads."""
    check_n_min(n_min)
    check_max_mag(max_mag)
    check_count(trials, "--trials", MAX_TRIALS_PER_POINT, SLEW_TRIAL_COST)
    # a century at most: a span past it is a typo (its step count is refused below anyway)
    hours = option_float(duration_h, "--duration-h", 0.0, 876_600.0, lo_open=True)
    step = option_float(step_s, "--step-s", 0.0, None, lo_open=True)
    n_steps = math.ceil(hours * 3600.0 / step - 1e-9)
    if not 2 <= n_steps <= MAX_STEPS:  # said in the options' units, not TimeGrid's seconds
        raise InputError(
            f"--duration-h {hours:g} at --step-s {step:g} gives {n_steps} steps; "
            f"need 2 to {MAX_STEPS:,}"
        )
    specs = [tok for value in [*(heads or []), *(more_heads or [])] for tok in value.split()]
    if plot is not None:  # the place, before the work (missing folders are created)
        check_output(plot, "--plot", make_parents=True)
    profile = parse_attitude(attitude, "--attitude")
    orb, t0 = _orbit(orbit, tle, start)
    with warnings.catch_warnings(record=True) as caught, progress_bar(not as_json) as bar:
        warnings.simplefilter("always", UserWarning)
        # the orbit and attitude first: their faults show before the heads' slew Monte Carlo
        grid = TimeGrid.span(t0, hours * 3600.0, step)
        geo = mission_geometry(grid, orb, profile)
        head_list, rest_mag = _heads(
            specs, fov, half_fov_deg, model, trials, seed, tolerance_json, bar
        )
        max_mag = rest_mag if max_mag is None else max_mag
        vectors, mags = catalog_stars(load_catalog(catalog), max_mag)
        meta = {
            "start": t0.isot,
            "orbit": getattr(orb, "label", ""),
            "attitude": profile.label,
            "duration_h": hours,
            "catalog": catalog,
            "max_mag": max_mag,
        }
        res = mission_availability(
            geo, head_list, vectors=vectors, magnitudes=mags, n_min=n_min, meta=meta
        )
    for w in caught:
        if issubclass(w.category, UserWarning):
            typer.echo(f"warning: {w.message}", err=True)
    payload, lines = res.to_dict(), res.lines()
    if plot is not None:
        path = plotting.availability.save_figure(
            plotting.mission.mission_timeline_figure(res), plot
        )
        payload["figures"] = [str(path)]
        lines.append(f"figure: {path}")
    emit(payload, as_json, lines)
