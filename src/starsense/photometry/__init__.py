"""Photometry: black bodies, passbands and zero points, colour -> temperature, dilution."""

from starsense.photometry.blackbody import (
    photons_per_wavelength,
    spectral_exitance,
    total_photons,
)
from starsense.photometry.colour import COLOUR_SYSTEMS, ColourModel, fit_star
from starsense.photometry.passbands import BANDS, Passband, passband, vega_spectrum

__all__ = [
    "BANDS",
    "COLOUR_SYSTEMS",
    "ColourModel",
    "Passband",
    "fit_star",
    "passband",
    "photons_per_wavelength",
    "spectral_exitance",
    "total_photons",
    "vega_spectrum",
]
