"""``starsense datasheet --against FRAMES``: the sensor's prediction held against real frames."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from starsense.analysis.characterize.against import against as against_frames
from starsense.catalog import load_catalog
from starsense.cli.common import emit, parse_floats
from starsense.errors import InputError
from starsense.sensor import load_sensor

__all__ = ["AgainstExposureOpt", "AgainstOpt", "MoreFramesOpt", "against_lines", "run_against"]

AgainstOpt = Annotated[
    list[Path] | None,
    typer.Option(
        "--against",
        help="Real frames of --sensor: measured against predicted, frame by frame (stars "
        "detected and matched, limiting magnitude, normalised residuals).",
    ),
]
AgainstExposureOpt = Annotated[
    str | None,
    typer.Option(
        "--exposure-s",
        help="With --against: the frames' exposure, s (one, or comma-separated one a frame); "
        "default the sensor's.",
    ),
]
MoreFramesOpt = Annotated[
    list[Path] | None,
    typer.Argument(
        help="More frames for --against (--against F1 F2 ..., or a shell glob).",
        show_default=False,
    ),
]

_LABELS = {
    "matched_per_frame": ("matched stars per frame", ".1f"),
    "detected_per_frame": ("detected stars per frame", ".1f"),
    "limiting_magnitude": ("limiting magnitude (50 % matched)", ".2f"),
    "normalised_residual_rms": ("normalised residual rms", ".2f"),
}


def _f(v, fmt: str) -> str:
    return "n/a" if v is None else format(v, fmt)


def against_lines(sensor_name: str, section: dict) -> list[str]:
    """Return the text report of the ``against`` section."""
    lines = [f"{sensor_name} against {len(section['frames'])} real frame(s): measured / predicted"]
    for key, (label, fmt) in _LABELS.items():
        q = section[key]
        lines.append(
            f"  {label}: {_f(q['measured'], fmt)} / {_f(q['predicted'], fmt)} "
            f"(ratio {_f(q['ratio'], '.2f')})"
        )
    for f in section["frames"]:
        lines.append(
            f"  {Path(f['name']).name}: matched {f['matched']['measured']} / "
            f"{f['matched']['predicted']:.1f}, detected {f['detected']['measured']} / "
            f"{f['detected']['predicted']:.1f}"
        )
    if section["skipped"]:
        lines.append(f"  not solved: {', '.join(section['skipped'])}")
    return lines


def run_against(
    sensor: str | None, against, more, exposure_s=None, *, catalog: str, seed: int, js: bool
) -> bool:
    """Run ``--against`` if asked: solve the frames, render their twins, print the comparison.

    Returns
    -------
    bool
        Whether it ran (False: no ``--against``, the datasheet runs).
    """
    if not against and not more:
        if exposure_s is not None:
            raise InputError("--exposure-s goes with --against (the frames' exposure)")
        return False
    if not against:
        raise InputError(f"unexpected argument {str(more[0])!r}: frames go after --against")
    frames = [*against, *(more or ())]
    if sensor is None:
        raise InputError("--against needs --sensor: the camera whose prediction is checked")
    for p in frames:
        if not p.is_file():
            raise InputError(f"--against: frame not found: {str(p)!r}")
    exposures = parse_floats(exposure_s, "--exposure-s", lo=0.0)
    if exposures is not None and (
        len(exposures) not in (1, len(frames)) or any(e <= 0 for e in exposures)
    ):
        raise InputError(
            f"--exposure-s {exposure_s}: give one exposure > 0 s, or one a frame ({len(frames)})"
        )
    sens = load_sensor(sensor)
    result = against_frames(
        sens,
        [str(p) for p in frames],
        catalog=load_catalog(catalog),
        exposures_s=exposures,
        seed=seed,
    )
    section = result.to_dict()
    emit({"sensor": sens.name, "against": section}, js, against_lines(sens.name, section))
    return True
