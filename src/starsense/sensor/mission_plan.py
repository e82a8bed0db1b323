"""The mission a sensor TOML names: its ``[mission]`` table (read by the report).

::

    [mission]
    name = "dawn-dusk demo"
    orbit = "sso:550:6"              # the forms of `starsense availability mission --orbit`
    attitude = "nadir"               # ... --attitude
    heads = ["x:135=+Y_up45", "x:-135=-Y_up45", "x:180=zenith"]   # mountings of this sensor
    start = "2025-03-20T00:00:00"
    duration_h = 24.0
    step_s = 10.0

Only the types and ranges are checked here; the orbit, attitude and mounting texts are parsed
by :mod:`starsense.analysis.mission.specs` when the analysis runs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from starsense._validate import name_keys
from starsense.errors import InputError
from starsense.sensor._fields import check_field

__all__ = ["MISSION_KEYS", "MissionPlan", "mission_from_table"]

MISSION_KEYS = ("name", "orbit", "attitude", "heads", "start", "duration_h", "step_s")


@dataclass(frozen=True, kw_only=True)
class MissionPlan:
    """A mission named by a sensor TOML (texts as written; hours and seconds).

    Attributes
    ----------
    orbit, attitude : str
        Orbit and attitude profile, in the command line's forms.
    heads : tuple of str
        Mountings of this sensor (``qx,qy,qz,qw`` or ``SEQ:ANGLES``, optionally ``=NAME``;
        empty: along body +z).
    start : str
        ISO 8601 UTC.
    duration_h, step_s : float
        Span (h) and step (s).
    name : str
    """

    orbit: str
    attitude: str = "nadir"
    heads: tuple[str, ...] = ("",)
    start: str = "2025-03-20T12:00:00"
    duration_h: float = 24.0
    step_s: float = 10.0
    name: str = ""


def mission_from_table(table: Any, source: str) -> MissionPlan:
    """Check the ``[mission]`` table of `source` and return its :class:`MissionPlan`."""
    where = f"{source}: [mission]"
    if not isinstance(table, dict):
        raise InputError(f"{where} must be a table")
    unknown = sorted(set(table) - set(MISSION_KEYS))
    if unknown:
        raise InputError(
            f"{where}: unknown key(s) {name_keys(unknown)}; known: {', '.join(MISSION_KEYS)}"
        )
    if "orbit" not in table:
        raise InputError(f'{where} needs orbit (e.g. orbit = "sso:550:6")')
    for key in ("name", "orbit", "attitude", "start"):
        if key in table and not isinstance(table[key], str):
            raise InputError(f"{where}: {key} must be a string, got {table[key]!r}")
    heads = table.get("heads", [""])
    if not isinstance(heads, list) or not heads or not all(isinstance(h, str) for h in heads):
        raise InputError(f"{where}: heads must be a non-empty list of strings, got {heads!r}")
    try:
        for key, hi in (("duration_h", 24.0 * 366), ("step_s", 86400.0)):
            if key in table:
                check_field("mission", key, table[key], 0.0, hi, lo_open=True)
    except InputError as exc:
        raise InputError(f"{source}: {exc}") from None
    kwargs = {k: table[k] for k in MISSION_KEYS if k in table and k != "heads"}
    for key in ("duration_h", "step_s"):
        if key in kwargs:
            kwargs[key] = float(kwargs[key])
    return MissionPlan(heads=tuple(heads), **kwargs)
