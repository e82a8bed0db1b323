"""The photometric zero point: each matched star's fitted light against its catalogue magnitude.

The forward model's fit gives each matched star's flux (electrons at the working gain, times
that gain: counts). With the catalogue's V magnitude ``m`` (the band the renderer's Reed model
uses, :mod:`starsense.photometry.sensitivity`), ``log10 F = log10 Z - 0.4 m``: ``Z`` the counts
of a magnitude-0 star. The zero point is the mean of ``log10 F + 0.4 m`` over the stars after
clipping at :data:`CLIP_SIGMA` (a blend, a variable, a star on a hot pixel), its 1-sigma the
scatter over the square root of the stars; the scatter itself (magnitudes) is the camera's
photometric noise plus the catalogue's colour terms. A free slope is fitted too, as a check on
linearity (a slope of -0.4 is a linear detector in the catalogue's band).

With the exposure, counts per second; with the aperture, the effective ``QE x transmission x
gain`` (counts per photon) against Reed's flux of a magnitude-0 star
(:data:`~starsense.photometry.sensitivity.REED_PHI0_PHOTONS_M2_S`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from starsense.photometry.blackbody import aperture_area_m2
from starsense.photometry.sensitivity import REED_PHI0_PHOTONS_M2_S

__all__ = ["CLIP_SIGMA", "ZeroPoint", "zero_point"]

#: stars further than this many standard deviations from the zero point are left out
CLIP_SIGMA = 3.0
#: fewest stars for a zero point
MIN_STARS = 3


@dataclass(frozen=True)
class ZeroPoint:
    """The zero point of a set of stars.

    Attributes
    ----------
    log10_counts, log10_sigma : float
        ``log10`` of the counts (per second when the exposures are known) of a V = 0 star, and
        its 1-sigma.
    per_second : bool
        Whether the zero point is per second (exposures given) or per frame.
    scatter_mag : float
        Rms of the kept stars about the zero point, mag.
    slope, slope_sigma : float
        The free fit's slope of ``log10 F`` against ``m`` (-0.4 for a linear detector).
    n_stars, n_clipped : int
    mags, log10_flux : ndarray
        The stars' magnitudes and ``log10`` counts (per second), for the figure.
    kept : ndarray of bool
    """

    log10_counts: float
    log10_sigma: float
    per_second: bool
    scatter_mag: float
    slope: float
    slope_sigma: float
    n_stars: int
    n_clipped: int
    mags: np.ndarray
    log10_flux: np.ndarray
    kept: np.ndarray

    @property
    def counts(self) -> float:
        """Counts (per second) of a V = 0 star."""
        return 10.0**self.log10_counts

    @property
    def counts_sigma(self) -> float:
        """Its 1-sigma."""
        return self.counts * math.log(10.0) * self.log10_sigma

    def throughput(self, aperture_m: float) -> tuple[float, float]:
        """Effective QE x transmission x gain, counts per photon, and its 1-sigma.

        Reed's magnitude-0 photon flux through the aperture's area; per second only.
        """
        if not self.per_second:
            return math.nan, math.nan
        photons = REED_PHI0_PHOTONS_M2_S * aperture_area_m2(aperture_m)
        return self.counts / photons, self.counts_sigma / photons


def zero_point(mags, fluxes_counts, exposures_s=None) -> ZeroPoint | None:
    """Fit the zero point of stars (module docstring); None when fewer than three are usable.

    Parameters
    ----------
    mags : array_like (N,)
        Catalogue V magnitudes.
    fluxes_counts : array_like (N,)
        Fitted fluxes, counts.
    exposures_s : array_like (N,), optional
        Each star's frame's exposure, s (the zero point is then per second).

    Returns
    -------
    ZeroPoint or None
    """
    m = np.asarray(mags, dtype=float)
    f = np.asarray(fluxes_counts, dtype=float)
    if exposures_s is not None:
        f = f / np.asarray(exposures_s, dtype=float)
    ok = np.isfinite(m) & np.isfinite(f) & (f > 0)
    if ok.sum() < MIN_STARS:
        return None
    m, lf = m[ok], np.log10(f[ok])
    y = lf + 0.4 * m
    kept = np.ones(y.size, dtype=bool)
    for _ in range(5):
        centre = float(np.median(y[kept]))
        spread = 1.4826 * float(np.median(np.abs(y[kept] - centre)))
        new = np.abs(y - centre) <= CLIP_SIGMA * max(spread, 1e-6)
        if new.sum() < MIN_STARS or np.array_equal(new, kept):
            break
        kept = new
    yk = y[kept]
    n = yk.size
    sd = float(np.std(yk, ddof=1)) if n > 1 else math.nan
    slope, slope_sigma = math.nan, math.nan
    if n > 3 and np.ptp(m[kept]) > 0:  # polyfit's covariance needs n > 3
        coef, cov = np.polyfit(m[kept], lf[kept], 1, cov=True)
        slope, slope_sigma = float(coef[0]), float(math.sqrt(cov[0, 0]))
    return ZeroPoint(
        log10_counts=float(np.mean(yk)),
        log10_sigma=sd / math.sqrt(n),
        per_second=exposures_s is not None,
        scatter_mag=2.5 * sd,
        slope=slope,
        slope_sigma=slope_sigma,
        n_stars=n,
        n_clipped=int((~kept).sum()),
        mags=m,
        log10_flux=lf,
        kept=kept,
    )
