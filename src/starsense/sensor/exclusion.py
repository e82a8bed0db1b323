"""Bright-body exclusion of a star-tracker head: the Sun, the Moon and the Earth's limb.

A head is blinded when the angle between its boresight and the Sun (or the Moon) is smaller than
the exclusion half-angle of that body, or when the angle between its boresight and the Earth's
limb, the limb raised by an atmosphere height, is smaller than the Earth-limb half-angle (a
boresight inside the Earth's disc is blinded whatever the half-angle). The TOML table
``[exclusion]`` gives the half-angles in degrees and the atmosphere in km; the object holds
radians and metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from starsense._validate import name_keys
from starsense.errors import InputError
from starsense.sensor._fields import check_field
from starsense.units import DEG

__all__ = ["EXCLUSION_KEYS", "Exclusion", "exclusion_from_table"]

#: TOML keys of the ``[exclusion]`` table -> the unit they are written in
EXCLUSION_KEYS = {
    "sun_deg": "deg",
    "moon_deg": "deg",
    "earth_limb_deg": "deg",
    "atmosphere_km": "km",
}
#: highest atmosphere height accepted, km (well above any airglow or the thermosphere's glow)
_MAX_ATMOSPHERE_KM = 1000.0


@dataclass(frozen=True, kw_only=True)
class Exclusion:
    """Exclusion half-angles of one head (None: that body is not considered).

    Attributes
    ----------
    sun_rad : float or None
        Sun exclusion half-angle, rad, in [0, pi].
    moon_rad : float or None
        Moon exclusion half-angle, rad, in [0, pi].
    earth_limb_rad : float or None
        Half-angle from the Earth's limb (raised by `atmosphere_m`), rad, in [0, pi].
    atmosphere_m : float
        Height of the bright atmosphere above the Earth's surface, m, in [0, 1e6].
    """

    sun_rad: float | None = None
    moon_rad: float | None = None
    earth_limb_rad: float | None = None
    atmosphere_m: float = 0.0

    def __post_init__(self) -> None:
        for key in ("sun_rad", "moon_rad", "earth_limb_rad"):
            value = getattr(self, key)
            if value is not None:
                check_field("exclusion", key, value, 0.0, math.pi)
        check_field("exclusion", "atmosphere_m", self.atmosphere_m, 0.0, _MAX_ATMOSPHERE_KM * 1e3)

    def to_dict(self) -> dict:
        """Return the half-angles in degrees and the atmosphere in km (JSON-ready)."""

        def deg(v):
            return None if v is None else v / DEG

        return {
            "sun_deg": deg(self.sun_rad),
            "moon_deg": deg(self.moon_rad),
            "earth_limb_deg": deg(self.earth_limb_rad),
            "atmosphere_km": self.atmosphere_m / 1e3,
        }


def exclusion_from_table(table: Any, source: str) -> Exclusion:
    """Build an :class:`Exclusion` from the TOML ``[exclusion]`` table (degrees and km).

    Parameters
    ----------
    table : dict
        The table: any of ``sun_deg``, ``moon_deg``, ``earth_limb_deg`` (half-angles, deg, in
        [0, 180]) and ``atmosphere_km`` (km, in [0, 1000]); a missing body is not considered.
    source : str
        File or preset, for messages.

    Returns
    -------
    Exclusion
    """
    where = f"{source}: [exclusion]"
    if not isinstance(table, dict):
        raise InputError(f"{where} must be a table")
    unknown = sorted(set(table) - set(EXCLUSION_KEYS))
    if unknown:
        raise InputError(
            f"{where}: unknown key(s) {name_keys(unknown)}; known: {', '.join(EXCLUSION_KEYS)}"
        )
    try:
        for key in ("sun_deg", "moon_deg", "earth_limb_deg"):
            if key in table:
                check_field("exclusion", key, table[key], 0.0, 180.0)
        if "atmosphere_km" in table:
            check_field(
                "exclusion", "atmosphere_km", table["atmosphere_km"], 0.0, _MAX_ATMOSPHERE_KM
            )
    except InputError as exc:
        raise InputError(f"{source}: {exc}") from None

    def rad(key):
        return None if key not in table else float(table[key]) * DEG

    return Exclusion(
        sun_rad=rad("sun_deg"),
        moon_rad=rad("moon_deg"),
        earth_limb_rad=rad("earth_limb_deg"),
        atmosphere_m=float(table.get("atmosphere_km", 0.0)) * 1e3,
    )
