"""Per-star centroid Fisher information of an ideal sensor (Fialho & Mortari 2019, eqs. 17-19).

An ideal sensor of diameter D exposing for t, limited only by diffraction and photon noise,
measures a star's direction with a variance no smaller than 1 / F_i, where
F_i = 12 zeta(5) pi^4 k^5 / (h^5 c^4) D^4 t C_i T_i^5 (eq. 19) for a black body, or eq. 17
integrated over a passband x QE or over a measured spectrum.
"""

from __future__ import annotations

import numpy as np

from starsense.errors import InputError
from starsense.photometry.blackbody import (
    FISHER_CONSTANT,
    PLANCK_J_S,
    SPEED_OF_LIGHT_M_S,
    photons_per_wavelength,
)

__all__ = [
    "FISHER_CONSTANT",
    "centroid_fisher",
    "centroid_fisher_numeric",
    "centroid_fisher_spectrum",
    "check_aperture",
]


def check_aperture(diameter_m: float, exposure_s: float) -> None:
    """Raise InputError unless D > 0 and t > 0 are finite.

    Parameters
    ----------
    diameter_m : float
        Aperture D, m.
    exposure_s : float
        Exposure t, s.
    """
    for name, value in (("diameter_m", diameter_m), ("exposure_s", exposure_s)):
        if not np.isfinite(value) or value <= 0:
            raise InputError(f"{name} must be a finite number > 0, got {value!r}")


def centroid_fisher(dilution, temperature_k, *, diameter_m: float = 1.0, exposure_s: float = 1.0):
    """Compute the per-star centroid Fisher information in closed form (eq. 19).

    Parameters
    ----------
    dilution : array (N,)
        Dilution factors C.
    temperature_k : array (N,)
        Black-body temperatures, K.
    diameter_m, exposure_s : float
        Aperture D (m) and exposure t (s).

    Returns
    -------
    array (N,)
        F_i = 1 / sigma_min,i^2 in rad^-2.
    """
    check_aperture(diameter_m, exposure_s)
    t = np.asarray(temperature_k, dtype=float)
    return FISHER_CONSTANT * diameter_m**4 * exposure_s * np.asarray(dilution) * t**5


def centroid_fisher_numeric(
    dilution,
    temperature_k,
    *,
    wavelength_m,
    response=None,
    diameter_m: float = 1.0,
    exposure_s: float = 1.0,
):
    """Compute the per-star centroid Fisher information by integrating eq. 17 over wavelength.

    dF/dlambda = pi^2 D^2 / lambda^2 n_ph,lambda QE(lambda), with n_ph,lambda from eq. 12. With
    ``response`` = 1 over a wide enough grid this reproduces eq. 19; with a passband x QE curve it
    gives the bound of a non-ideal sensor that counts only the photons it detects.

    Parameters
    ----------
    dilution, temperature_k : array (N,)
        Dilution factors C and black-body temperatures (K).
    wavelength_m : array (L,)
        Integration grid, m.
    response : array (L,) or None
        Fraction of photons detected at each wavelength (QE x transmission), 0..1.
    diameter_m, exposure_s : float
        Aperture D (m) and exposure t (s).

    Returns
    -------
    array (N,)
        rad^-2.
    """
    check_aperture(diameter_m, exposure_s)
    lam = np.asarray(wavelength_m, dtype=float)
    n = photons_per_wavelength(
        dilution, temperature_k, lam, diameter_m=diameter_m, exposure_s=exposure_s
    )
    q = 1.0 if response is None else np.asarray(response, dtype=float)
    return np.trapezoid(np.pi**2 * diameter_m**2 / lam**2 * n * q, lam, axis=-1)


def centroid_fisher_spectrum(wavelength_m, irradiance, *, diameter_m: float, exposure_s: float):
    """Compute the centroid Fisher information of a measured spectrum (eq. 17; Table 1).

    Parameters
    ----------
    wavelength_m : array (L,)
        Wavelength grid, m.
    irradiance : array (L,)
        Spectral irradiance at the sensor, W m^-2 m^-1.
    diameter_m, exposure_s : float
        Aperture D (m) and exposure t (s).

    Returns
    -------
    float
        rad^-2.
    """
    check_aperture(diameter_m, exposure_s)
    lam = np.asarray(wavelength_m, dtype=float)
    photons = np.asarray(irradiance) * lam / (PLANCK_J_S * SPEED_OF_LIGHT_M_S)
    n = photons * np.pi * diameter_m**2 / 4.0 * exposure_s
    return float(np.trapezoid(np.pi**2 * diameter_m**2 / lam**2 * n, lam))
