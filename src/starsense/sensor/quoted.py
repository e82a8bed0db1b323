"""The sensor TOML's optional ``[quoted]`` and ``[budget]`` tables, for the datasheet.

``[quoted]`` holds what the vendor (or a requirement) states, shown beside the prediction as
predicted / quoted; ``source`` says where the numbers come from. ``[budget]`` holds error terms
the model cannot compute (bias, thermo-elastic) and what sets the aberration term. Every key is
named with its unit; an unknown key is an error that names it.
"""

from __future__ import annotations

import math
from typing import Any

from starsense.errors import InputError

__all__ = ["BUDGET_KEYS", "QUOTED_KEYS", "parse_budget", "parse_quoted"]

#: quoted values the datasheet predicts: key -> (meaning, lower bound, upper bound)
QUOTED_KEYS: dict[str, tuple[str, float, float]] = {
    "nea_cross_arcsec": ("noise-equivalent angle cross-boresight, 1 sigma, arcsec", 0.0, 3600.0),
    "nea_roll_arcsec": ("noise-equivalent angle about the boresight, 1 sigma, arcsec", 0.0, 3600.0),
    "limiting_magnitude": ("static limiting magnitude", -2.0, 25.0),
    "lost_in_space_success": ("lost-in-space success rate at rest, 0..1", 0.0, 1.0),
    "lost_in_space_time_ms": ("lost-in-space time per frame, ms", 0.0, 1e6),
    "availability": ("sky availability for lost in space at rest, 0..1", 0.0, 1.0),
    "max_rate_deg_s": ("slew rate that keeps 90 % tracking availability, deg/s", 0.0, 1e3),
}
#: user-given budget terms and settings: key -> (meaning, lower bound, upper bound)
BUDGET_KEYS: dict[str, tuple[str, float, float]] = {
    "bias_cross_arcsec": ("bias cross-boresight (alignment, calibration), arcsec", 0.0, 3600.0),
    "bias_roll_arcsec": ("bias about the boresight, arcsec", 0.0, 36000.0),
    "thermoelastic_cross_arcsec": ("thermo-elastic error cross-boresight, arcsec", 0.0, 3600.0),
    "thermoelastic_roll_arcsec": ("thermo-elastic error about the boresight, arcsec", 0.0, 36000.0),
    "fov_spatial_cross_arcsec": (
        "distortion residual after calibration, cross, arcsec",
        0.0,
        3600.0,
    ),
    "fov_spatial_roll_arcsec": (
        "distortion residual after calibration, roll, arcsec",
        0.0,
        36000.0,
    ),
    "orbital_speed_m_s": ("observer's orbital speed for the aberration term, m/s", 0.0, 1e5),
}
_FLAGS = {"aberration_corrected": "the tracker corrects stellar aberration (true/false)"}


def _table(value: Any, where: str) -> dict:
    if not isinstance(value, dict):
        raise InputError(f"{where} must be a table")
    return value


def _numbers(table: dict, known: dict, where: str, extra: set[str]) -> list[tuple[str, Any]]:
    unknown = sorted(set(table) - set(known) - extra)
    if unknown:
        raise InputError(
            f"{where}: unknown key {unknown[0]!r}; "
            f"known keys: {', '.join(sorted({*known, *extra}))}"
        )
    out = []
    for key in sorted(table):
        value = table[key]
        if key in known:
            _, lo, hi = known[key]
            ok = isinstance(value, int | float) and not isinstance(value, bool)
            if not ok or not math.isfinite(value) or not lo <= value <= hi:
                raise InputError(
                    f"{where} {key} = {value!r} is out of range; "
                    f"must be a number in [{lo:g}, {hi:g}]"
                )
            value = float(value)
        out.append((key, value))
    return out


def parse_quoted(value: Any, source: str) -> tuple[tuple[str, Any], ...]:
    """Check a ``[quoted]`` table: known keys, numbers in range, and a ``source`` string."""
    where = f"{source}: [quoted]"
    table = _table(value, where)
    pairs = _numbers(table, QUOTED_KEYS, where, {"source"})
    if not isinstance(table.get("source"), str) or not table["source"].strip():
        raise InputError(f'{where} needs source = "where these numbers come from"')
    if len(pairs) < 2:
        raise InputError(f"{where} has a source but no values; known: {', '.join(QUOTED_KEYS)}")
    return tuple(pairs)


def parse_budget(value: Any, source: str) -> tuple[tuple[str, Any], ...]:
    """Check a ``[budget]`` table: known keys, numbers in range, ``aberration_corrected`` bool."""
    where = f"{source}: [budget]"
    table = _table(value, where)
    pairs = _numbers(table, BUDGET_KEYS, where, {*_FLAGS, "source"})
    if "source" in table and not isinstance(table["source"], str):
        raise InputError(f"{where} source must be text (in quotes), got {table['source']!r}")
    flag = table.get("aberration_corrected", False)
    if not isinstance(flag, bool):
        raise InputError(f"{where} aberration_corrected = {flag!r} must be true or false")
    return tuple(pairs)
