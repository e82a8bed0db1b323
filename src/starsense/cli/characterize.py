"""`starsense characterize`: measure a camera from its own night-sky frames; write its TOML."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer

from starsense._io import atomic_write, check_output
from starsense.analysis.characterize import camera_toml, characterize, measured_values
from starsense.catalog import load_catalog
from starsense.cli.common import EXPOSURE_MAX_S, CatalogOpt, JsonOpt, emit, parse_floats
from starsense.errors import InputError
from starsense.geometry.apparent import parse_time
from starsense.sensor import load_sensor

#: the report's lines: value name -> label
_LABELS = {
    "focal_length_px": "focal length",
    "principal_x_px": "principal point offset x",
    "principal_y_px": "principal point offset y",
    "k1": "distortion k1",
    "k2": "distortion k2",
    "p1": "distortion p1",
    "p2": "distortion p2",
    "distortion_residual_px": "residual after calibration",
    "psf_sigma_px": "PSF sigma",
    "psf_sigma_centre_px": "PSF sigma at the centre",
    "psf_sigma_corner_px": "PSF sigma in the corners",
    "zero_point": "zero point (V = 0)",
    "zero_point_scatter_mag": "zero-point scatter",
    "zero_point_slope": "slope of log10 flux vs V",
    "throughput_counts_per_photon": "QE x transmission x gain",
    "qe_mean": "QE (mean over the passband)",
    "sky_level_counts": "sky level",
    "noise_counts": "per-pixel noise",
    "gain_counts_per_e": "gain (photon transfer)",
    "read_noise_e": "read noise",
    "hot_pixel_fraction": "hot pixels",
    "warm_pixel_fraction": "warm pixels",
    "hot_pixel_e_s": "hot-pixel dark current",
}


def _report(ch, values: dict, not_told: dict, out: Path) -> list[str]:
    lines = [
        f"{len(ch.frames)} frame(s) solved, {ch.calibration.n_stars} matched stars"
        + (f"; not solved: {', '.join(ch.skipped)}" if ch.skipped else ""),
    ]
    for f in ch.frames:
        lines.append(
            f"  {Path(f.name).name}: {f.n_matched} matched, PSF sigma {f.psf_sigma_px:.3f} +- "
            f"{f.psf_sigma_err_px:.2g} px (reduced chi-square {f.reduced_chi2:.2f}), sky "
            f"{f.level_counts:.4g} counts, noise {f.noise_counts:.3g} counts"
        )
    for key, m in values.items():
        lines.append(f"  {_LABELS.get(key, key)}: {m.text()}")
    for key, why in not_told.items():
        lines.append(f"  not told: {key}: {why}")
    kept = "" if ch.base_given else " (no --sensor: pixel pitch, aperture are placeholders)"
    lines.append(f"sensor written: {out}{kept}")
    return lines


def characterize_command(
    frames: Annotated[list[Path], typer.Argument(help="Night-sky frames of one camera.")],
    out: Annotated[Path, typer.Option("--out", help="Sensor TOML to write.")],
    sensor: Annotated[
        str | None,
        typer.Option(
            "--sensor",
            help="Base sensor (preset or TOML): its values are kept for what the frames cannot "
            "tell; default: optics unknown.",
        ),
    ] = None,
    exposure_s: Annotated[
        str | None,
        typer.Option(
            "--exposure-s",
            help="Exposure, s: one for every frame, or comma-separated, one per frame.",
        ),
    ] = None,
    catalog: CatalogOpt = "hipparcos",
    time: Annotated[
        str | None,
        typer.Option("--time", help="UTC time of the frames (ISO 8601); else from each header."),
    ] = None,
    plot: Annotated[
        Path | None,
        typer.Option(
            "--plot",
            help="PNG: PSF across the field, zero point, photon transfer, noise and residual maps.",
        ),
    ] = None,
    as_json: JsonOpt = False,
) -> None:
    """Measure a camera from its frames: optics, PSF, zero point, noise, gain, hot pixels.

    The frames are solved (with --sensor, else with the optics unknown); the optics are
    calibrated on their matched stars (as `starsense calibrate`), the forward model is fitted
    to the stars' pixels with a free PSF width (overall and per zone of the field), their
    fluxes give the photometric zero point against the catalogue's V magnitudes, the
    background gives the sky level and per-pixel noise and, over several exposures, the gain
    by the photon transfer; pixels that stand out alone in every frame are hot. The sensor is
    written to --out with a `provenance` table (each value's uncertainty, unit, frames and
    method; the fields kept from --sensor; what the frames could not tell, and why). --json
    gives every value as {"value", "uncertainty", "unit"}. Exit status 2 on bad input or when
    no frame solves.
    """
    if out.suffix.lower() != ".toml":
        raise InputError(f"--out must be a .toml file, got {str(out)!r}")
    if not out.parent.is_dir():
        raise InputError(f"--out: directory {str(out.parent)!r} not found")
    check_output(out, "--out")  # before the frames are solved
    if plot is not None:
        check_output(plot, "--plot", make_parents=True)
    exposures = parse_floats(exposure_s, "--exposure-s", lo=0.0)
    if exposures is not None and any(not 0 < e <= EXPOSURE_MAX_S for e in exposures):
        raise InputError(
            f"--exposure-s must be in (0, {EXPOSURE_MAX_S:g}] s (a sensor's range), "
            f"got {exposure_s!r}"
        )
    if exposures is not None and len(exposures) not in (1, len(frames)):
        raise InputError(
            f"--exposure-s: {len(exposures)} values for {len(frames)} frames; give one, or one "
            "a frame"
        )
    for p in frames:
        if not p.is_file():
            raise InputError(f"frame not found: {str(p)!r}")
    when = None if time is None else parse_time(time, "--time")
    base = None if sensor is None else load_sensor(sensor)
    ch = characterize(
        [str(p) for p in frames],
        base,
        catalog=load_catalog(catalog),
        exposures_s=exposures,
        obs_time=when,
    )
    text = camera_toml(ch, out.stem)
    fig = None
    if plot is not None:  # drawn before anything is written: a failure leaves neither file
        from starsense.plotting.characterize import characterize_figure  # noqa: PLC0415

        fig = characterize_figure(ch)
    with atomic_write(out) as fh:
        fh.write(text)
    if fig is not None:
        from starsense.plotting.figure import save_png  # noqa: PLC0415

        save_png(fig, plot)
    values, not_told = measured_values(ch)
    payload = {
        "values": {k: m.to_dict() for k, m in values.items()},
        "not_told": not_told,
        "frames": [
            {
                "name": f.name,
                "matched": f.n_matched,
                "psf_sigma_px": _num(f.psf_sigma_px),
                "psf_sigma_err_px": _num(f.psf_sigma_err_px),
                "reduced_chi2": _num(f.reduced_chi2),
                "sky_level_counts": f.level_counts,
                "noise_counts": f.noise_counts,
            }
            for f in ch.frames
        ],
        "skipped": ch.skipped,
        "base": ch.base.name if ch.base_given else None,
        "out": str(out),
        "plot": None if plot is None else str(plot),
    }
    emit(payload, as_json, _report(ch, values, not_told, out))


def _num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None
