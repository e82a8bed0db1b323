"""Angle units: the one home of the conversion constants.

Angles are radians inside the package; degrees, arcseconds and milliarcseconds appear only at the
edges (CLI options, TOML files, reports, JSON), converted once with these constants::

    rate_rad_s = rate_deg_s * DEG
    text = f"{theta_rad / ARCSEC:.3f} arcsec"
"""

from __future__ import annotations

import math

__all__ = ["ARCMIN", "ARCSEC", "DEG", "MAS", "RAD_TO_ARCSEC", "RAD_TO_DEG", "RAD_TO_MAS"]

DEG = math.pi / 180.0
"""One degree in radians."""
ARCMIN = DEG / 60.0
"""One arcminute in radians."""
ARCSEC = DEG / 3600.0
"""One arcsecond in radians."""
MAS = ARCSEC / 1000.0
"""One milliarcsecond in radians."""

RAD_TO_DEG = 180.0 / math.pi
"""Degrees per radian."""
RAD_TO_ARCSEC = RAD_TO_DEG * 3600.0
"""Arcseconds per radian."""
RAD_TO_MAS = RAD_TO_ARCSEC * 1000.0
"""Milliarcseconds per radian."""
