"""`starsense calibrate`: fit the camera model to solved frames and write a sensor TOML."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Annotated, NamedTuple

import numpy as np
import typer

from starsense._io import atomic_write, check_output
from starsense.analysis.characterize.residual import lens_residual_px, star_residuals_px2
from starsense.catalog import load_catalog
from starsense.cli.common import CatalogOpt, JsonOpt, SensorOpt, emit
from starsense.errors import InputError
from starsense.geometry.apparent import parse_time
from starsense.sensor import load_sensor
from starsense.sensor.dump import sensor_to_toml
from starsense.solve.calibration import PARAMETERS, FrameSolver, frame_stars
from starsense.solve.calibration import calibrate as calibrate_frames


class _Stars(NamedTuple):
    """A solved frame's matched stars and their V magnitudes (what the residual fit reads)."""

    stars: object  # FrameStars
    mags_v: np.ndarray


def _mags_v(sol, cat) -> np.ndarray:
    """Return the catalogue V magnitudes of a solution's matched stars (NaN without V)."""
    ids = np.array([c for _, c in sol.matches], dtype=np.int64)
    mags = cat.mags.get("V")
    return np.full(len(ids), np.nan) if mags is None else np.asarray(mags, float)[cat.index_of(ids)]


def _lens_residual(frames: list[_Stars], result) -> tuple[float, float, str]:
    """Return what the calibrated lens leaves, px per axis: value, 1-sigma (NaN: unknown), how.

    The floor of the stars' squared residuals against magnitude
    (:func:`~starsense.analysis.characterize.residual.lens_residual_px`: the centroid noise
    falls with a star's light, the lens's residual does not), as ``starsense characterize``
    writes it; with too few stars to part them, the whole rms per axis (an upper bound).
    """
    floor, sigma, rms = lens_residual_px(*star_residuals_px2(frames, result))
    if math.isfinite(floor):
        return floor, sigma, f"floor of the stars' residuals against magnitude (rms {rms:.3g} px)"
    return result.rms_px_after, math.nan, "rms per axis (too few stars to part noise from lens)"


def calibrate(
    frames: Annotated[list[Path], typer.Argument(help="Frames to solve and fit jointly.")],
    out: Annotated[Path, typer.Option("--out", help="Calibrated sensor TOML to write.")],
    sensor: SensorOpt = "st16",
    fit: Annotated[
        str,
        typer.Option(
            "--fit",
            help="Parameters to fit, comma-separated: focal_length, principal_point, k1, k2, "
            "p1, p2.",
        ),
    ] = "focal_length,principal_point,k1,k2,p1,p2",
    catalog: CatalogOpt = "hipparcos",
    time: Annotated[
        str | None,
        typer.Option("--time", help="UTC time of the frames (ISO 8601); else from each header."),
    ] = None,
    as_json: JsonOpt = False,
) -> None:
    """Fit focal length, principal point and Brown-Conrady distortion to the frames' stars.

    Every frame is solved with --sensor (one that does not identify with it, as through a lens
    that bends it more than that model allows, is solved with nothing known); the matched
    stars of those that solve are fitted jointly, each frame's attitude a nuisance parameter.
    The result is written to --out as a sensor TOML that `solve --sensor FILE` uses, with
    optics.distortion_residual_px the lens's residual it measured (the floor of the stars'
    residuals against magnitude: their centroid noise taken out), which the datasheet's budget
    and its rendered frames use. With a
    time (--time, FITS DATE-OBS, EXIF) the stars are fitted at their apparent places (proper
    motion, parallax, aberration). Exit status 2 when no frame solves or a parameter cannot be
    fitted (hold it fixed by leaving it out of --fit).
    """
    names = [p.strip() for p in fit.split(",") if p.strip()]
    bad = [p for p in names if p not in PARAMETERS]
    if bad or not names:
        raise InputError(f"--fit must name some of {', '.join(PARAMETERS)}; got {fit!r}")
    twice = sorted({p for p in names if names.count(p) > 1})
    if twice:
        raise InputError(f"--fit {fit}: {', '.join(twice)} listed twice; name each once")
    if out.suffix.lower() != ".toml":
        raise InputError(f"--out must be a .toml file, got {str(out)!r}")
    if not out.parent.is_dir():
        raise InputError(f"--out: directory {str(out.parent)!r} not found")
    check_output(out, "--out")  # a new or regular file, before the frames are solved
    when = None if time is None else parse_time(time, "--time")
    solver = FrameSolver(load_sensor(sensor), catalog=load_catalog(catalog))
    cat = solver.catalog
    stars, mags, skipped = [], [], {}
    for path in frames:
        sol = solver(path, when)
        if sol.solved:
            stars.append(frame_stars(sol, cat, str(path)))
            mags.append(_mags_v(sol, cat))
        else:
            skipped[str(path)] = sol.status
    if not stars:
        raise InputError(f"no frame solved with sensor {sensor!r}: {skipped}")
    result = calibrate_frames(stars, solver.solver.sensor, fit=names)
    lens_px, lens_sigma_px, how = _lens_residual(
        [_Stars(st, m) for st, m in zip(stars, mags, strict=True)], result
    )
    header = (
        f"starsense calibrate: {result.n_frames} frame(s), {result.n_stars} stars; residual rms "
        f"{result.rms_arcsec_before:.2f} -> {result.rms_arcsec_after:.2f} arcsec\n"
        f"fitted: {', '.join(result.fitted)}, from sensor {solver.solver.sensor.name}\n"
        f"distortion_residual_px: the lens's residual, {how}"
    )
    fitted = result.sensor
    optics = dataclasses.replace(fitted.optics, distortion_residual_px=float(lens_px))
    with atomic_write(out) as fh:
        fh.write(sensor_to_toml(fitted.with_(name=out.stem, optics=optics), header))
    payload = {
        **result.to_dict(),
        "distortion_residual_px": float(lens_px),
        "distortion_residual_sigma_px": None if math.isnan(lens_sigma_px) else lens_sigma_px,
        "skipped": skipped,
        "out": str(out),
    }
    d, s = result.values, result.sigmas
    emit(
        payload,
        as_json,
        [
            f"{result.n_frames} frame(s), {result.n_stars} stars ({result.n_rejected} rejected)"
            + (f"; not solved: {', '.join(skipped)}" if skipped else ""),
            f"  focal length {d['focal_length_px']:.2f} +- {s['focal_length_px']:.2f} px, "
            f"principal point offset ({d['principal_x_px']:.1f} +- {s['principal_x_px']:.1f}, "
            f"{d['principal_y_px']:.1f} +- {s['principal_y_px']:.1f}) px",
            "  " + ", ".join(f"{k} {d[k]:.3g} +- {s[k]:.2g}" for k in ("k1", "k2", "p1", "p2")),
            f"  residual rms {result.rms_arcsec_before:.2f} -> {result.rms_arcsec_after:.2f} "
            f"arcsec ({result.rms_px_after:.3g} px per axis)",
            f"  distortion_residual_px = {lens_px:.3g}"
            + ("" if math.isnan(lens_sigma_px) else f" +- {lens_sigma_px:.2g}")
            + f" ({how}); sensor written: {out}",
        ],
    )
