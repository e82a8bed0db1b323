"""Black-body radiation: spectral exitance, photon flux and collected photons.

Every catalogue star is modelled as a black body of temperature ``T`` diluted by a geometric
factor ``C`` (Fialho & Mortari 2019, eq. 1). All quantities are SI: wavelengths in metres,
spectral exitance in W m^-2 m^-1, photon counts per metre of wavelength.
"""

from __future__ import annotations

import numpy as np
from scipy.special import zeta

# 2019 SI redefinition: exact values (BIPM SI brochure, 9th ed.), as used by the paper.
PLANCK_J_S = 6.62607015e-34
SPEED_OF_LIGHT_M_S = 299792458.0
BOLTZMANN_J_K = 1.380649e-23

ZETA3 = float(zeta(3.0))
ZETA5 = float(zeta(5.0))  # 1.0369277551... (paper, below eq. 19)

#: 12 zeta(5) pi^4 k^5 / (h^5 c^4): eq. 19's constant, in K^-5 m^-4 s^-1 rad^-2 (the centroid
#: Fisher information of a black body per unit dilution, T^5, D^4 and t)
FISHER_CONSTANT = (
    12.0 * ZETA5 * np.pi**4 * BOLTZMANN_J_K**5 / (PLANCK_J_S**5 * SPEED_OF_LIGHT_M_S**4)
)


def _broadcast(temperature_k, wavelength_m):
    t = np.asarray(temperature_k, dtype=float)
    lam = np.asarray(wavelength_m, dtype=float)
    return t[..., None], lam


def spectral_exitance(temperature_k, wavelength_m):
    """Spectral exitance of a black body, Fialho & Mortari 2019, eq. 2.

    Parameters
    ----------
    temperature_k : float or array (...)
        Temperature in kelvin.
    wavelength_m : array (L,)
        Wavelengths in metres.

    Returns
    -------
    array (..., L)
        Spectral exitance in W m^-2 m^-1.
    """
    t, lam = _broadcast(temperature_k, wavelength_m)
    x = PLANCK_J_S * SPEED_OF_LIGHT_M_S / (lam * BOLTZMANN_J_K * t)
    return 2.0 * np.pi * PLANCK_J_S * SPEED_OF_LIGHT_M_S**2 / lam**5 / np.expm1(x)


def photon_exitance(temperature_k, wavelength_m):
    """Spectral photon exitance of a black body (eq. 11 without the dilution C).

    Returns photons s^-1 m^-2 m^-1, shape (..., L).
    """
    t, lam = _broadcast(temperature_k, wavelength_m)
    x = PLANCK_J_S * SPEED_OF_LIGHT_M_S / (lam * BOLTZMANN_J_K * t)
    return 2.0 * np.pi * SPEED_OF_LIGHT_M_S / lam**4 / np.expm1(x)


def aperture_area_m2(diameter_m):
    """Cross-section of a circular aperture (or of the ideal spherical sensor), pi D^2 / 4."""
    return np.pi * np.asarray(diameter_m, dtype=float) ** 2 / 4.0


def photons_per_wavelength(dilution, temperature_k, wavelength_m, *, diameter_m, exposure_s):
    """Photons collected per unit wavelength, Fialho & Mortari 2019, eq. 12.

    Parameters
    ----------
    dilution : float or array (...)
        Geometric dilution factor C (dimensionless).
    temperature_k : float or array (...)
        Black-body temperature, K.
    wavelength_m : array (L,)
        Wavelengths, m.
    diameter_m, exposure_s : float
        Aperture diameter D (m) and exposure t (s).

    Returns
    -------
    array (..., L)
        Photons per metre of wavelength.
    """
    c = np.asarray(dilution, dtype=float)[..., None]
    return (
        c * exposure_s * aperture_area_m2(diameter_m) * photon_exitance(temperature_k, wavelength_m)
    )


def total_photons(dilution, temperature_k, *, diameter_m, exposure_s):
    """Return the expected photons over all wavelengths: eq. 12 integrated in closed form.

    With x = hc / (lambda k T), the integral of lambda^-4 / (e^x - 1) over lambda is
    2 zeta(3) (kT/hc)^3, so N = C t (pi D^2 / 4) 2 pi c 2 zeta(3) (kT/hc)^3
    = C t pi^2 D^2 c zeta(3) (kT/hc)^3.

    Parameters
    ----------
    dilution : float or array_like
        Geometric dilution factor C (dimensionless).
    temperature_k : float or array_like
        Black-body temperature, K.
    diameter_m : float or array_like
        Aperture diameter D, m.
    exposure_s : float or array_like
        Exposure t, s.

    Returns
    -------
    ndarray
        Photons (the Poisson mean iota of sec. 2.9), the broadcast shape of the inputs.
    """
    c = np.asarray(dilution, dtype=float)
    t = np.asarray(temperature_k, dtype=float)
    kt_hc = BOLTZMANN_J_K * t / (PLANCK_J_S * SPEED_OF_LIGHT_M_S)
    return (
        c
        * exposure_s
        * np.pi**2
        * np.asarray(diameter_m, dtype=float) ** 2
        * SPEED_OF_LIGHT_M_S
        * ZETA3
        * kt_hc**3
    )
