"""Sensors back to TOML: the inverse of :mod:`starsense.sensor.load`.

:func:`sensor_to_toml` writes every field of ``[optics]``, ``[detector]`` and ``[detection]``
(floats with ``repr``, which round-trips exactly), so ``load_sensor`` of the text gives an equal
sensor. Comments (``header``) go on top. Attitude areas are not written: a sensor with them
raises, and the user copies the table from the original file.
"""

from __future__ import annotations

import dataclasses
import json
import math

from starsense.errors import InputError
from starsense.units import DEG, to_edge

__all__ = ["sensor_to_toml"]


def _value(v) -> str:
    """One TOML value: number, string, boolean or list of numbers."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise InputError(f"cannot write a non-finite sensor value to TOML: {v!r}")
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)  # a JSON string is a valid TOML basic string
    if isinstance(v, tuple | list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    raise InputError(f"cannot write {type(v).__name__} to TOML")


def sensor_to_toml(sensor, header: str = "") -> str:
    """Return the TOML text of a sensor, loadable by :func:`starsense.sensor.load_sensor`.

    Parameters
    ----------
    sensor : Sensor
        The sensor (without attitude areas).
    header : str
        Comment lines put on top (each prefixed with ``#``).

    Returns
    -------
    str
    """
    if sensor.attitude_areas is not None:
        raise InputError(
            f"sensor {sensor.name!r} has attitude areas, which are not written to TOML; "
            "copy its [attitude_areas] table by hand"
        )
    lines = [f"# {line}".rstrip() for line in header.splitlines()]
    lines += [
        f"name = {_value(sensor.name)}",
        f"description = {_value(sensor.description)}",
        f"exposure_s = {_value(float(sensor.exposure_s))}",
    ]
    for section in ("optics", "detector", "detection"):
        part = getattr(sensor, section)
        lines += ["", f"[{section}]"]
        for f in dataclasses.fields(part):
            lines.append(f"{f.name} = {_value(getattr(part, f.name))}")
    lines += _extra_tables(sensor)
    return "\n".join(lines) + "\n"


def _extra_tables(sensor) -> list[str]:
    """Return the optional tables: [exclusion] (degrees read back exactly), [quoted], [budget]."""
    if getattr(sensor, "mission", None) is not None:
        raise InputError(
            f"sensor {sensor.name!r} names a mission, which is not written to TOML; "
            "copy its [mission] table by hand"
        )
    lines = _psf_table(getattr(sensor, "psf", None))
    ex = getattr(sensor, "exclusion", None)
    if ex is not None:
        lines += ["", "[exclusion]"]
        for key, rad in (
            ("sun_deg", ex.sun_rad),
            ("moon_deg", ex.moon_rad),
            ("earth_limb_deg", ex.earth_limb_rad),
        ):
            if rad is not None:
                lines.append(f"{key} = {_value(float(to_edge(rad, DEG)))}")
        lines.append(f"atmosphere_km = {_value(float(to_edge(ex.atmosphere_m, 1e3)))}")
    for table in ("quoted", "budget"):
        pairs = getattr(sensor, table, ())
        if pairs:
            lines += ["", f"[{table}]"] + [f"{k} = {_value(v)}" for k, v in pairs]
    return lines


def _psf_table(psf) -> list[str]:
    """Return the [psf] table of a non-default PSF (an empirical one names its file only)."""
    if psf is None or psf == type(psf)():
        return []
    if psf.kind == "empirical":
        raise InputError(
            "an empirical PSF is not written to TOML (its samples live in a file): copy its "
            "[psf] table by hand"
        )
    keep = ("kind", "moffat_beta", "airy_obscuration", "fit_width", "radius_px")
    return ["", "[psf]", *(f"{k} = {_value(getattr(psf, k))}" for k in keep)]
