"""Photometry: black bodies, passbands and zero points, colour -> temperature, catalogue stars."""

from starsense.photometry.blackbody import (
    photons_per_wavelength,
    spectral_exitance,
    total_photons,
)
from starsense.photometry.colour import COLOUR_SYSTEMS, ColourModel, fit_star
from starsense.photometry.passbands import BANDS, Passband, passband, vega_spectrum
from starsense.photometry.stars import BlackBodyStars, b_v_from_spectral_type

__all__ = [
    "BANDS",
    "COLOUR_SYSTEMS",
    "BlackBodyStars",
    "ColourModel",
    "Passband",
    "b_v_from_spectral_type",
    "fit_star",
    "passband",
    "photons_per_wavelength",
    "spectral_exitance",
    "total_photons",
    "vega_spectrum",
]
