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

from starsense.cli.availability import (
    FovOpt,
    HalfFovOpt,
    MaxMagOpt,
    ModelOpt,
    NMinOpt,
    ToleranceOpt,
    TrialsOpt,
    _check_n_min,
    _field_of_view,
    _threshold_curve,
)
from starsense.cli.common import CatalogOpt, JsonOpt, SeedOpt, emit, option_float, progress_bar
from starsense.errors import InputError
from starsense.units import DEG

__all__ = ["mission"]

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


def _numbers(text: str, option: str, n_lo: int, n_hi: int) -> list[float]:
    parts = [p for p in text.split(",") if p.strip()] if text else []
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise InputError(f"{option} expects numbers, got {text!r}") from None
    if not n_lo <= len(values) <= n_hi or not all(math.isfinite(v) for v in values):
        want = f"{n_lo}" if n_lo == n_hi else f"{n_lo} to {n_hi}"
        raise InputError(f"{option} expects {want} finite numbers, got {text!r}")
    return values


def _orbit(orbit: str | None, tle: Path | None, start: str | None):
    """Return (orbit, start) from --orbit / --tle / --start."""
    from starsense.analysis.mission import KeplerOrbit, TleOrbit, parse_time, sun_synchronous

    if (orbit is None) == (tle is None):
        raise InputError("give exactly one of --orbit and --tle")
    if tle is not None:
        orb = TleOrbit.from_file(tle)
        return orb, parse_time(start, "--start") if start else orb.epoch
    t0 = parse_time(start or "2025-03-20T12:00:00", "--start")
    kind, _, rest = orbit.partition(":")
    if kind == "sso":
        vals = [float(v) for v in _numbers(rest.replace(":", ","), "--orbit sso", 1, 2)]
        alt = option_float(vals[0], "--orbit sso altitude (km)", 100.0, 6000.0)
        ltan = option_float(vals[1] if len(vals) > 1 else 6.0, "--orbit sso LTAN (h)", 0.0, 24.0,
                            hi_open=True)  # fmt: skip
        return sun_synchronous(alt * 1e3, ltan, t0), t0
    if kind == "circular":
        vals = [*_numbers(rest.replace(":", ","), "--orbit circular", 2, 4), 0.0, 0.0]
        alt = option_float(vals[0], "--orbit circular altitude (km)", 100.0, None)
        inc = option_float(vals[1], "--orbit circular inclination (deg)", 0.0, 180.0)
        label = f"circular {alt:g} km, i = {inc:g} deg"
        return KeplerOrbit(6378.137e3 + alt * 1e3, 0.0, inc * DEG, vals[2] * DEG, 0.0,
                           vals[3] * DEG, t0, label=label), t0  # fmt: skip
    if kind == "kepler":
        a, e, i, raan, argp, m = _numbers(rest, "--orbit kepler", 6, 6)
        option_float(e, "--orbit kepler eccentricity", 0.0, 1.0, hi_open=True)
        option_float(i, "--orbit kepler inclination (deg)", 0.0, 180.0)
        label = f"Keplerian a = {a:g} km, e = {e:g}, i = {i:g} deg"
        return KeplerOrbit(a * 1e3, e, i * DEG, raan * DEG, argp * DEG, m * DEG, t0,
                           label=label), t0  # fmt: skip
    raise InputError(f"--orbit must be sso:..., circular:... or kepler:..., got {orbit!r}")


def _profile(attitude: str):
    from starsense.analysis.mission import AttitudeProfile

    kind, _, rest = attitude.partition(":")
    if kind == "inertial":
        ra, dec, roll = _numbers(rest, "--attitude inertial:RA,DEC,ROLL", 3, 3)
        option_float(dec, "--attitude inertial Dec (deg)", -90.0, 90.0)
        return AttitudeProfile("inertial", ra=ra * DEG, dec=dec * DEG, roll=roll * DEG)
    if kind == "nadir" and rest in ("", "yaw"):
        return AttitudeProfile("nadir", yaw_steering=rest == "yaw")
    if kind == "sun" and not rest:
        return AttitudeProfile("sun")
    if kind == "target":
        lat, lon = _numbers(rest, "--attitude target:LAT,LON", 2, 2)
        option_float(lat, "--attitude target latitude (deg)", -90.0, 90.0)
        return AttitudeProfile("target", lat=lat * DEG, lon=lon * DEG)
    if kind == "quaternions" and rest:
        return AttitudeProfile("quaternions", path=rest)
    raise InputError(f"--attitude: {ATTITUDE_HELP} Got {attitude!r}")


def _mounting(spec: str, text: str):
    from starsense.analysis.mission import mounting_from_euler, mounting_from_quaternion

    where = f"--heads {spec}"
    seq, colon, angles = text.partition(":")
    if colon:
        vals = _numbers(angles, where, len(seq), len(seq))
        return mounting_from_euler(seq, [v * DEG for v in vals], where)
    return mounting_from_quaternion(_numbers(text, where, 4, 4), where)


def _heads(specs: list[str], fov: str, half_fov_deg, model, trials, seed, tolerance_json, bar):
    from starsense.analysis.mission import Head
    from starsense.sensor import load_sensor

    if not specs:
        raise InputError("give at least one head: --heads st16[@qx,qy,qz,qw] ...")
    sensors, curves, heads, seen = {}, {}, [], {}
    for spec in specs:
        body, _, given = spec.partition("=")
        name, at, mount = body.partition("@")
        if name not in sensors:
            sensors[name] = load_sensor(name)
            curves[name] = _threshold_curve(sensors[name], model, trials, seed, tolerance_json,
                                            bar.callback)  # fmt: skip
        sens = sensors[name]
        mounting = _mounting(spec, mount) if at else None
        base = given or spec
        seen[base] = seen.get(base, 0) + 1
        label = base if seen[base] == 1 else f"{base}#{seen[base]}"
        kwargs = {} if mounting is None else {"mounting": mounting}
        heads.append(Head(label, _field_of_view(sens, fov, half_fov_deg), curves[name],
                          exclusion=sens.exclusion, **kwargs))  # fmt: skip
    return heads


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
    max_mag: MaxMagOpt = 5.75,
    n_min: NMinOpt = 3,
    fov: FovOpt = "circular",
    half_fov_deg: HalfFovOpt = None,
    model: ModelOpt = "reed",
    trials: TrialsOpt = 20,
    tolerance_json: ToleranceOpt = None,
    seed: SeedOpt = 0,
    plot: Annotated[Path | None, typer.Option("--plot", help="Write the timeline (PNG).")] = None,
    as_json: JsonOpt = False,
) -> None:
    """Availability along a mission: orbit, attitude profile, bright bodies, several heads."""
    from starsense.analysis.availability import catalog_stars
    from starsense.analysis.mission import TimeGrid, mission_availability, mission_geometry
    from starsense.catalog import load_catalog

    _check_n_min(n_min)
    hours = option_float(duration_h, "--duration-h", 0.0, None, lo_open=True)
    step = option_float(step_s, "--step-s", 0.0, None, lo_open=True)
    specs = [tok for value in [*(heads or []), *(more_heads or [])] for tok in value.split()]
    profile = _profile(attitude)
    orb, t0 = _orbit(orbit, tle, start)
    with warnings.catch_warnings(record=True) as caught, progress_bar(not as_json) as bar:
        warnings.simplefilter("always", UserWarning)
        head_list = _heads(specs, fov, half_fov_deg, model, trials, seed, tolerance_json, bar)
        grid = TimeGrid.span(t0, hours * 3600.0, step)
        geo = mission_geometry(grid, orb, profile)
        vectors, mags = catalog_stars(load_catalog(catalog), max_mag)
        meta = {"start": t0.isot, "orbit": getattr(orb, "label", ""), "attitude": profile.label,
                "duration_h": hours, "catalog": catalog, "max_mag": max_mag}  # fmt: skip
        res = mission_availability(geo, head_list, vectors, mags, n_min, meta)
    for w in caught:
        if issubclass(w.category, UserWarning):
            typer.echo(f"warning: {w.message}", err=True)
    payload, lines = res.to_dict(), res.lines()
    if plot is not None:
        from starsense.plotting.availability import save_figure
        from starsense.plotting.mission import mission_timeline_figure

        path = save_figure(mission_timeline_figure(res), plot)
        payload["figures"] = [str(path)]
        lines.append(f"figure: {path}")
    emit(payload, as_json, lines)
