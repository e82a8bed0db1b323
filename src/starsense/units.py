"""Angle units: the one home of the conversion constants.

Angles are radians inside the package; degrees, arcseconds and milliarcseconds appear only at the
edges (CLI options, TOML files, reports, JSON), converted once with these constants::

    rate_rad_s = rate_deg_s * DEG
    text = f"{theta_rad / ARCSEC:.3f} arcsec"
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "ARCMIN",
    "ARCSEC",
    "DEG",
    "MAS",
    "RAD_TO_ARCSEC",
    "RAD_TO_DEG",
    "RAD_TO_MAS",
    "to_edge",
]

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


def to_edge(value_rad, unit: float):
    """Return an angle in the edge unit ``unit`` (``DEG``, ``ARCSEC``...) as the user wrote it.

    The inverse of the conversion ``x * unit`` made at the edge: the shortest decimal ``x`` with
    ``x * unit == value_rad``, so 0.2 arcsec or 0.3 deg/s given on the command line reads back as
    0.2 and 0.3 in JSON and text, not 0.20000000000000004. Any other value (one the analysis
    computed) is returned as ``value_rad / unit``.

    Parameters
    ----------
    value_rad : float or array_like
        Angle(s), rad, or angular rate(s), rad/s.
    unit : float
        The edge unit in radians (:data:`DEG`, :data:`ARCSEC`, ...).

    Returns
    -------
    float or ndarray
        A float for a scalar, else an array of the same shape.
    """
    values = np.asarray(value_rad, dtype=np.float64)
    out = np.array(values / unit, dtype=np.float64)  # owned and contiguous: flat is a view
    flat = out.reshape(-1)
    for i, (v, plain) in enumerate(zip(values.reshape(-1).tolist(), flat.tolist(), strict=True)):
        if not math.isfinite(plain):
            continue
        for digits in range(1, 18):
            x = float(f"{plain:.{digits}g}")
            if x * unit == v:
                flat[i] = x
                break
    return float(out) if out.ndim == 0 else out
