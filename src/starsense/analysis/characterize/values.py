"""A measured value: the number, its 1-sigma uncertainty, its unit and where it came from."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Measured", "weighted_mean"]


@dataclass(frozen=True)
class Measured:
    """One value the frames tell about the camera.

    Attributes
    ----------
    value : float
        The estimate, in ``unit``.
    uncertainty : float
        Its 1-sigma uncertainty, in ``unit`` (NaN when not known).
    unit : str
        The unit ("px", "counts", "mag", "" for a pure number).
    frames : tuple of str
        The frames it was measured on.
    method : str
        How, in a few words (for the TOML's provenance and the report).
    """

    value: float
    uncertainty: float
    unit: str
    frames: tuple[str, ...] = ()
    method: str = ""

    def to_dict(self) -> dict:
        """``{"value", "uncertainty", "unit"}`` (what ``characterize --json`` prints)."""
        return {"value": self.value, "uncertainty": self.uncertainty, "unit": self.unit}

    def text(self, fmt: str = ".4g") -> str:
        """``value +- uncertainty unit`` for the report."""
        unit = f" {self.unit}" if self.unit else ""
        if not math.isfinite(self.uncertainty):
            return f"{self.value:{fmt}}{unit}"
        return f"{self.value:{fmt}} +- {self.uncertainty:.2g}{unit}"


def weighted_mean(values, sigmas) -> tuple[float, float, float]:
    """Inverse-variance mean of independent estimates, its sigma and the Birge ratio.

    The sigma is the formal one, raised by the Birge ratio ``sqrt(chi2 / (n - 1))`` when the
    estimates scatter more than their sigmas say (an error the sigmas do not hold: a PSF that
    differs from frame to frame, a star's colour).

    Parameters
    ----------
    values, sigmas : array_like (n,)
        The estimates and their 1-sigma (> 0, finite; others are left out).

    Returns
    -------
    mean, sigma, birge : float
        NaN when no estimate is usable; the Birge ratio is 1 for one estimate.
    """
    v = np.asarray(values, dtype=float)
    s = np.asarray(sigmas, dtype=float)
    ok = np.isfinite(v) & np.isfinite(s) & (s > 0)
    if not ok.any():
        return math.nan, math.nan, math.nan
    v, w = v[ok], 1.0 / s[ok] ** 2
    mean = float(np.sum(w * v) / np.sum(w))
    sigma = float(1.0 / math.sqrt(np.sum(w)))
    birge = 1.0
    if v.size > 1:
        birge = math.sqrt(float(np.sum(w * (v - mean) ** 2)) / (v.size - 1))
    return mean, sigma * max(birge, 1.0), birge
